"""A flight log to time series: an ArduPilot DataFlash log or a MAVLink telemetry log, read with
pymavlink, recognised by its first bytes (not its name), every signal in SI units on the
autopilot's boot clock (s).

What is read, and from which message (DataFlash / tlog), is in docs/flight-logs.md. The
accelerometer and gyro values both kinds of log hold are the autopilot's low-pass filtered ones
(``INS_ACCEL_FILTER``, ``INS_GYRO_FILTER``): :attr:`FlightLog.filters` says with what, read from
the log's parameters where it has them.
"""

from __future__ import annotations

import contextlib
import io
import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from slopelander.errors import SlopelanderError

DATAFLASH = "DataFlash"
TLOG = "tlog"
GRAVITY = 9.80665
"""m/s^2: ArduPilot's GRAVITY_MSS, the scale of RAW_IMU's milli-g."""
DOWNWARD = 25
"""MAV_SENSOR_ROTATION_PITCH_270: a rangefinder looking down."""
RANGE_GOOD = 4
"""RangeFinder::Status::Good in a DataFlash RFND message."""
DEFAULT_FILTER_HZ = 20.0
"""ArduPilot's default INS_ACCEL_FILTER and INS_GYRO_FILTER, for a log that does not say."""
DEFAULT_SAMPLE_HZ = 1000.0
"""The sensor rate the filter is assumed to run at when the log does not say (the IMU's AHz)."""
_EPOCH_US = (946_684_800e6, 4_102_444_800e6)
"""A tlog record's time (µs since 1970) lies within 2000..2100."""


class FlightLogError(SlopelanderError, ValueError):
    """A flight log that cannot be used: names the file and what is missing."""

    def __init__(self, path: str | Path, why: str) -> None:
        super().__init__(f"{path}: {why}")
        self.path = str(path)


@dataclass(frozen=True)
class Series:
    """Samples of one signal: times (s, boot clock, increasing) and values (rows, columns)."""

    t: np.ndarray
    v: np.ndarray
    source: str
    """The message (and field) it was read from, e.g. ``IMU[0]``."""

    @classmethod
    def empty(cls, columns: int, source: str) -> Series:
        return cls(np.zeros(0), np.zeros((0, columns)), source)

    @classmethod
    def of(cls, rows: list[tuple], source: str, columns: int) -> Series:
        """From (t, value, ...) rows, sorted by time, repeated times kept once (the last)."""
        if not rows:
            return cls.empty(columns, source)
        a = np.asarray(rows, dtype=float)
        order = np.argsort(a[:, 0], kind="stable")
        a = a[order]
        keep = np.append(np.diff(a[:, 0]) > 0, True)
        a = a[keep]
        return cls(a[:, 0].copy(), a[:, 1:].copy(), source)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def rate_hz(self) -> float:
        """The median sample rate (0 for fewer than two samples)."""
        if len(self.t) < 2:
            return 0.0
        return float(1.0 / np.median(np.diff(self.t)))

    def at(self, t: np.ndarray | float, column: int) -> np.ndarray:
        """Column ``column`` linearly interpolated at ``t`` (held at the ends)."""
        return np.interp(t, self.t, self.v[:, column])

    def between(self, t0: float, t1: float) -> Series:
        m = (self.t >= t0) & (self.t <= t1)
        return Series(self.t[m], self.v[m], self.source)


@dataclass(frozen=True)
class FlightLog:
    """Everything the landing comparison reads from one log."""

    path: Path
    kind: str
    imu: Series
    """gyro x, y, z (rad/s), specific force x, y, z (m/s^2), body axes forward-right-down."""
    attitude: Series
    """roll, pitch, yaw (rad), ArduPilot's Euler angles (pitch positive nose up)."""
    ekf: Series
    """velocity north, east, down (m/s), position north, east, down (m) and roll, pitch, yaw (rad)
    of the estimator: a range reading is placed with the attitude and position of one message."""
    ranges: Series
    """downward range (m) and whether it saw a surface in range (1) or not (0)."""
    outputs: Series
    """motor outputs 1-4 (µs)."""
    states: Series
    """the on-board script's ``SL_STATE`` announcements (its state code)."""
    texts: list[tuple[float, str]] = field(default_factory=list)
    armed: list[tuple[float, bool]] = field(default_factory=list)
    """(time, armed) at each change."""
    params: dict[str, float] = field(default_factory=dict)
    filters: dict[str, object] = field(default_factory=dict)
    """accel_hz, gyro_hz, sample_hz: the autopilot's IMU filters, and ``source`` (where from)."""
    truncated: str | None = None
    """How the file ends when it ends inside a message, else None."""

    @property
    def end(self) -> float:
        """The last time any signal was logged (s)."""
        ends = [s.t[-1] for s in (self.imu, self.attitude, self.ekf, self.outputs) if len(s)]
        return max(ends) if ends else -math.inf


def log_kind(path: str | Path) -> str | None:
    """:data:`DATAFLASH` or :data:`TLOG` from the file's first bytes, or None for anything else.

    A DataFlash log starts with a message header (0xA3 0x95) whose type is FMT (0x80); a tlog
    record is an 8-byte big-endian time in µs since 1970, then a MAVLink frame (0xFE or 0xFD)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
    except OSError:
        return None
    if head[:3] == b"\xa3\x95\x80":
        return DATAFLASH
    if len(head) >= 10 and head[8] in (0xFE, 0xFD):
        (usec,) = struct.unpack(">Q", head[:8])
        if _EPOCH_US[0] <= usec <= _EPOCH_US[1]:
            return TLOG
    return None


def read_log(path: str | Path) -> FlightLog:
    """Read ``path`` (either kind: :func:`log_kind`). Raises :class:`FlightLogError` for a file
    that is neither, or that pymavlink cannot read."""
    path = Path(path)
    if not path.is_file():
        raise FlightLogError(path, "no such file")
    if path.stat().st_size == 0:
        raise FlightLogError(path, "the file is empty")
    kind = log_kind(path)
    if kind is None:
        with open(path, "rb") as fh:
            head = fh.read(8)
        raise FlightLogError(
            path,
            f"not a DataFlash log or a MAVLink telemetry log: it starts with {head!r}, not a DataFlash "
            "header (A3 95 80) or a tlog record (an 8-byte time, then a MAVLink frame)",
        )
    chatter = io.StringIO()  # pymavlink prints what it skips; the caller gets it in one line
    try:
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter):
            return _read_dataflash(path) if kind == DATAFLASH else _read_tlog(path)
    except FlightLogError:
        raise
    except Exception as exc:  # a damaged file may fail anywhere inside pymavlink
        said = chatter.getvalue().strip().splitlines()
        detail = f" ({said[-1]})" if said else ""
        raise FlightLogError(path, f"pymavlink cannot read this {kind} log: {exc}{detail}") from None


# -- DataFlash ------------------------------------------------------------------------------
_DF_TYPES = ["IMU", "ATT", "ANG", "XKF1", "NKF1", "RFND", "RCOU", "NVF", "MSG", "ARM", "EV", "PARM"]


def _text(value) -> str:
    if isinstance(value, bytes):
        value = value.decode("ascii", "replace")
    return str(value).rstrip("\x00")


@dataclass
class _DataflashRows:
    """The rows of each series as a DataFlash log's messages are read, before they become Series."""

    imu: list[tuple] = field(default_factory=list)
    att: list[tuple] = field(default_factory=list)
    ang: list[tuple] = field(default_factory=list)
    ekf: list[tuple] = field(default_factory=list)
    ekf2: list[tuple] = field(default_factory=list)
    rng: list[tuple] = field(default_factory=list)
    out: list[tuple] = field(default_factory=list)
    states: list[tuple] = field(default_factory=list)
    texts: list[tuple[float, str]] = field(default_factory=list)
    arm: list[tuple[float, bool]] = field(default_factory=list)
    ev: list[tuple[float, bool]] = field(default_factory=list)
    sample_hz: list[float] = field(default_factory=list)


def _df_imu(rows: _DataflashRows, m: Any, t: float) -> None:
    """The first IMU (as RAW_IMU in a tlog), and its sample rate when logged."""
    if getattr(m, "I", 0) != 0:
        return
    rows.imu.append((t, m.GyrX, m.GyrY, m.GyrZ, m.AccX, m.AccY, m.AccZ))
    ahz = getattr(m, "AHz", None)
    if ahz:
        rows.sample_hz.append(float(ahz))


def _df_attitude(rows: _DataflashRows, m: Any, t: float) -> None:
    """ATT or ANG (the fast attitude): roll, pitch, yaw in radians."""
    row = (t, math.radians(m.Roll), math.radians(m.Pitch), math.radians(m.Yaw))
    (rows.att if m.get_type() == "ATT" else rows.ang).append(row)


def _df_ekf(rows: _DataflashRows, m: Any, t: float) -> None:
    """The first EKF core's velocity, position and attitude (XKF1, or NKF1 of the older EKF)."""
    if getattr(m, "C", 0) != 0:
        return
    angles = (math.radians(m.Roll), math.radians(m.Pitch), math.radians(m.Yaw))
    (rows.ekf if m.get_type() == "XKF1" else rows.ekf2).append(
        (t, m.VN, m.VE, m.VD, m.PN, m.PE, m.PD, *angles)
    )


def _df_range(rows: _DataflashRows, m: Any, t: float) -> None:
    """The downward rangefinder's distance and whether its status was good."""
    if getattr(m, "Orient", DOWNWARD) != DOWNWARD:
        return
    rows.rng.append((t, m.Dist, 1.0 if getattr(m, "Stat", RANGE_GOOD) == RANGE_GOOD else 0.0))


def _df_outputs(rows: _DataflashRows, m: Any, t: float) -> None:
    """The four motors' outputs."""
    rows.out.append((t, m.C1, m.C2, m.C3, m.C4))


def _df_named_value(rows: _DataflashRows, m: Any, t: float) -> None:
    """The on-board script's state, announced as SL_STATE."""
    if _text(m.Name) == "SL_STATE":
        rows.states.append((t, m.Value))


def _df_text(rows: _DataflashRows, m: Any, t: float) -> None:
    """A text message of the autopilot's."""
    rows.texts.append((t, _text(m.Message)))


def _df_arm(rows: _DataflashRows, m: Any, t: float) -> None:
    """An arming state change."""
    rows.arm.append((t, bool(m.ArmState)))


def _df_event(rows: _DataflashRows, m: Any, t: float) -> None:
    """LogEvent ARMED or DISARMED: the arming changes of older firmware."""
    if m.Id in (10, 11):
        rows.ev.append((t, m.Id == 10))


_DF_ROWS: dict[str, Callable[[_DataflashRows, Any, float], None]] = {
    "IMU": _df_imu,
    "ATT": _df_attitude,
    "ANG": _df_attitude,
    "XKF1": _df_ekf,
    "NKF1": _df_ekf,
    "RFND": _df_range,
    "RCOU": _df_outputs,
    "NVF": _df_named_value,
    "MSG": _df_text,
    "ARM": _df_arm,
    "EV": _df_event,
}
"""What each DataFlash message adds to the rows (PARM: DFReader keeps the parameters itself)."""


def _read_dataflash(path: Path) -> FlightLog:
    from pymavlink import DFReader

    r = DFReader.DFReader_binary(str(path))
    truncated = _dataflash_tail(r)
    rows = _DataflashRows()
    while True:
        m = r.recv_match(type=_DF_TYPES)
        if m is None:
            break
        kind = m.get_type()
        if kind == "PARM":
            continue  # DFReader keeps them in r.params
        _DF_ROWS[kind](rows, m, m.TimeUS * 1e-6)
    # the attitude at the higher rate: ANG (loop rate with LOG_BITMASK's fast attitude) or ATT
    attitude = (
        Series.of(rows.ang, "ANG", 3) if len(rows.ang) > len(rows.att) else Series.of(rows.att, "ATT", 3)
    )
    params = {str(k): float(v) for k, v in r.params.items() if isinstance(v, (int, float))}
    sample_hz = float(np.median(rows.sample_hz)) if rows.sample_hz else None
    filters = _filters(params, sample_hz, "the log's parameters")
    r.close()
    return FlightLog(
        path=path,
        kind=DATAFLASH,
        imu=Series.of(rows.imu, "IMU[0]", 6),
        attitude=attitude,
        ekf=Series.of(rows.ekf, "XKF1", 9) if rows.ekf else Series.of(rows.ekf2, "NKF1", 9),
        ranges=Series.of(rows.rng, "RFND", 2),
        outputs=Series.of(rows.out, "RCOU", 4),
        states=Series.of(rows.states, "NVF SL_STATE", 1),
        texts=rows.texts,
        armed=_changes(rows.arm or rows.ev),
        params=params,
        filters=filters,
        truncated=truncated,
    )


def _dataflash_tail(r) -> str | None:
    """How the file ends when its last message is incomplete (the indexer's offsets, no pass)."""
    last_end, last_type = 0, None
    for mtype, fmt in r.formats.items():
        count = r.counts[mtype] if mtype < len(r.counts) else 0
        if count:
            end = r.offsets[mtype][count - 1] + fmt.len
            if end > last_end:
                last_end, last_type = end, fmt.name
    if last_end > r.data_len:
        start = last_end - r.formats[r.name_to_id[last_type]].len
        return f"the file ends inside its last message ({last_type}, at byte {start} of {r.data_len})"
    return None


def _filters(params: dict[str, float], sample_hz: float | None, source: str) -> dict[str, object]:
    if "INS_ACCEL_FILTER" not in params:
        source = f"not in the log: ArduPilot's defaults ({DEFAULT_FILTER_HZ:g} Hz) assumed"
    if not sample_hz:
        source += f", at {DEFAULT_SAMPLE_HZ:g} Hz"
    return {
        "accel_hz": params.get("INS_ACCEL_FILTER", DEFAULT_FILTER_HZ),
        "gyro_hz": params.get("INS_GYRO_FILTER", DEFAULT_FILTER_HZ),
        "sample_hz": sample_hz or DEFAULT_SAMPLE_HZ,
        "source": source,
    }


def _changes(rows: list[tuple[float, bool]]) -> list[tuple[float, bool]]:
    out: list[tuple[float, bool]] = []
    for t, v in sorted(rows):
        if not out or out[-1][1] != v:
            out.append((t, v))
    return out


# -- tlog -----------------------------------------------------------------------------------
_TLOG_TYPES = [
    "HEARTBEAT",
    "RAW_IMU",
    "HIGHRES_IMU",
    "ATTITUDE",
    "LOCAL_POSITION_NED",
    "DISTANCE_SENSOR",
    "SERVO_OUTPUT_RAW",
    "NAMED_VALUE_FLOAT",
    "STATUSTEXT",
    "PARAM_VALUE",
]


def _xyz(m, name: str) -> tuple:
    return getattr(m, f"x{name}"), getattr(m, f"y{name}"), getattr(m, f"z{name}")


def _raw_imu(m) -> tuple[float | None, tuple | None]:
    g, a = 1e-3, GRAVITY * 1e-3  # mrad/s, milli-g
    return m.time_usec * 1e-6, (m.xgyro * g, m.ygyro * g, m.zgyro * g, m.xacc * a, m.yacc * a, m.zacc * a)


def _distance(m) -> tuple[float | None, tuple | None]:
    if m.orientation != DOWNWARD:
        return None, None
    good = m.min_distance < m.current_distance < m.max_distance and m.signal_quality != 1
    return m.time_boot_ms * 1e-3, (m.current_distance / 100.0, 1.0 if good else 0.0)


def _servo(m) -> tuple[float | None, tuple | None]:
    if getattr(m, "port", 0) != 0:
        return None, None
    return m.time_usec * 1e-6, (m.servo1_raw, m.servo2_raw, m.servo3_raw, m.servo4_raw)


def _named(m) -> tuple[float | None, tuple | None]:
    return m.time_boot_ms * 1e-3, ((m.value,) if _text(m.name) == "SL_STATE" else None)


#: the timed messages a tlog is read for: message -> (the series it feeds, its reader giving the
#: vehicle time (None: not this autopilot's sensor) and the row (None: nothing to keep))
_TLOG_TIMED = {
    "RAW_IMU": ("raw", _raw_imu),
    "HIGHRES_IMU": (
        "hi",
        lambda m: (m.time_usec * 1e-6, (m.xgyro, m.ygyro, m.zgyro, m.xacc, m.yacc, m.zacc)),
    ),
    "ATTITUDE": ("att", lambda m: (m.time_boot_ms * 1e-3, (m.roll, m.pitch, m.yaw))),
    "LOCAL_POSITION_NED": ("ekf", lambda m: (m.time_boot_ms * 1e-3, (m.vx, m.vy, m.vz, m.x, m.y, m.z))),
    "DISTANCE_SENSOR": ("rng", _distance),
    "SERVO_OUTPUT_RAW": ("out", _servo),
    "NAMED_VALUE_FLOAT": ("states", _named),
}


class _TlogUntimed:
    """What a tlog's untimed messages say, stamped with the newest vehicle time seen before them
    (STATUSTEXT and HEARTBEAT carry none)."""

    def __init__(self) -> None:
        from pymavlink import mavutil

        self.texts: list[tuple[float, str]] = []
        self.armed: list[tuple[float, bool]] = []
        self.params: dict[str, float] = {}
        self._invalid = mavutil.mavlink.MAV_AUTOPILOT_INVALID
        self._armed_flag = mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED

    def add(self, kind: str, m, now: float) -> None:
        if kind == "STATUSTEXT":
            self.texts.append((now, _text(m.text)))
        elif kind == "HEARTBEAT" and m.autopilot != self._invalid:
            self.armed.append((now, bool(m.base_mode & self._armed_flag)))
        elif kind == "PARAM_VALUE":
            self.params[_text(m.param_id)] = float(m.param_value)


def _read_tlog(path: Path) -> FlightLog:
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(str(path), dialect="ardupilotmega", robust_parsing=True)
    rows: dict[str, list[tuple]] = {bucket: [] for bucket, _ in _TLOG_TIMED.values()}
    untimed = _TlogUntimed()
    now = -math.inf  # the newest vehicle time seen
    try:
        while (m := conn.recv_match(type=_TLOG_TYPES)) is not None:
            if m.get_srcComponent() != 1:  # the autopilot's own messages
                continue
            kind = m.get_type()
            if kind not in _TLOG_TIMED:
                untimed.add(kind, m, now)
                continue
            bucket, read = _TLOG_TIMED[kind]
            t, row = read(m)
            if row is not None:
                rows[bucket].append((t, *row))
            if t is not None:
                now = max(now, t)
    finally:
        conn.close()
    raw, hi = rows["raw"], rows["hi"]
    imu = Series.of(hi, "HIGHRES_IMU", 6) if len(hi) > len(raw) else Series.of(raw, "RAW_IMU", 6)
    attitude = Series.of(rows["att"], "ATTITUDE", 3)
    params = untimed.params
    return FlightLog(
        path=path,
        kind=TLOG,
        imu=imu,
        attitude=attitude,
        ekf=_with_attitude(Series.of(rows["ekf"], "LOCAL_POSITION_NED", 6), attitude),
        ranges=Series.of(rows["rng"], "DISTANCE_SENSOR", 2),
        outputs=Series.of(rows["out"], "SERVO_OUTPUT_RAW", 4),
        states=Series.of(rows["states"], "NAMED_VALUE_FLOAT SL_STATE", 1),
        texts=[(t, s) for t, s in untimed.texts if math.isfinite(t)],
        armed=_changes([(t, v) for t, v in untimed.armed if math.isfinite(t)]),
        params=params,
        filters=_filters(params, None, "the log's PARAM_VALUE messages"),
    )


def _with_attitude(pos: Series, att: Series) -> Series:
    """LOCAL_POSITION_NED's rows with ATTITUDE's roll, pitch and yaw at their times (yaw
    interpolated on the circle); NaN where no attitude was logged within 0.1 s."""
    if not len(pos):
        return Series.empty(9, pos.source)
    if not len(att):
        return Series(pos.t, np.column_stack([pos.v, np.full((len(pos), 3), np.nan)]), pos.source)
    roll, pitch = (np.interp(pos.t, att.t, att.v[:, k]) for k in (0, 1))
    sin, cos = (np.interp(pos.t, att.t, f(att.v[:, 2])) for f in (np.sin, np.cos))
    yaw = np.arctan2(sin, cos)
    i = np.clip(np.searchsorted(att.t, pos.t), 1, len(att.t) - 1)
    near = np.minimum(np.abs(att.t[i] - pos.t), np.abs(att.t[i - 1] - pos.t)) <= 0.1
    extra = np.where(near[:, None], np.column_stack([roll, pitch, yaw]), np.nan)
    return Series(pos.t, np.column_stack([pos.v, extra]), pos.source + " + ATTITUDE")
