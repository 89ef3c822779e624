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
from dataclasses import dataclass, field
from pathlib import Path

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


def _read_dataflash(path: Path) -> FlightLog:
    from pymavlink import DFReader

    r = DFReader.DFReader_binary(str(path))
    truncated = _dataflash_tail(r)
    imu, att, ang, ekf, ekf2, rng, out, states = [], [], [], [], [], [], [], []
    texts: list[tuple[float, str]] = []
    arm_rows: list[tuple[float, bool]] = []
    ev_rows: list[tuple[float, bool]] = []
    sample_hz: list[float] = []
    while True:
        m = r.recv_match(type=_DF_TYPES)
        if m is None:
            break
        kind = m.get_type()
        if kind == "PARM":
            continue  # DFReader keeps them in r.params
        t = m.TimeUS * 1e-6
        if kind == "IMU":
            if getattr(m, "I", 0) != 0:
                continue  # the first IMU, as RAW_IMU in a tlog
            imu.append((t, m.GyrX, m.GyrY, m.GyrZ, m.AccX, m.AccY, m.AccZ))
            ahz = getattr(m, "AHz", None)
            if ahz:
                sample_hz.append(float(ahz))
        elif kind in ("ATT", "ANG"):
            row = (t, math.radians(m.Roll), math.radians(m.Pitch), math.radians(m.Yaw))
            (att if kind == "ATT" else ang).append(row)
        elif kind in ("XKF1", "NKF1"):
            if getattr(m, "C", 0) != 0:
                continue  # the first core
            angles = (math.radians(m.Roll), math.radians(m.Pitch), math.radians(m.Yaw))
            (ekf if kind == "XKF1" else ekf2).append((t, m.VN, m.VE, m.VD, m.PN, m.PE, m.PD, *angles))
        elif kind == "RFND":
            if getattr(m, "Orient", DOWNWARD) != DOWNWARD:
                continue
            rng.append((t, m.Dist, 1.0 if getattr(m, "Stat", RANGE_GOOD) == RANGE_GOOD else 0.0))
        elif kind == "RCOU":
            out.append((t, m.C1, m.C2, m.C3, m.C4))
        elif kind == "NVF":
            if _text(m.Name) == "SL_STATE":
                states.append((t, m.Value))
        elif kind == "MSG":
            texts.append((t, _text(m.Message)))
        elif kind == "ARM":
            arm_rows.append((t, bool(m.ArmState)))
        elif kind == "EV" and m.Id in (10, 11):  # LogEvent ARMED, DISARMED (older firmware)
            ev_rows.append((t, m.Id == 10))
    # the attitude at the higher rate: ANG (loop rate with LOG_BITMASK's fast attitude) or ATT
    attitude = Series.of(ang, "ANG", 3) if len(ang) > len(att) else Series.of(att, "ATT", 3)
    params = {str(k): float(v) for k, v in r.params.items() if isinstance(v, (int, float))}
    filters = _filters(params, float(np.median(sample_hz)) if sample_hz else None, "the log's parameters")
    r.close()
    return FlightLog(
        path=path,
        kind=DATAFLASH,
        imu=Series.of(imu, "IMU[0]", 6),
        attitude=attitude,
        ekf=Series.of(ekf, "XKF1", 9) if ekf else Series.of(ekf2, "NKF1", 9),
        ranges=Series.of(rng, "RFND", 2),
        outputs=Series.of(out, "RCOU", 4),
        states=Series.of(states, "NVF SL_STATE", 1),
        texts=texts,
        armed=_changes(arm_rows or ev_rows),
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


def _read_tlog(path: Path) -> FlightLog:
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(str(path), dialect="ardupilotmega", robust_parsing=True)
    raw, hi, att, ekf, rng, out, states = [], [], [], [], [], [], []
    texts: list[tuple[float, str]] = []
    armed: list[tuple[float, bool]] = []
    params: dict[str, float] = {}
    now = -math.inf  # the newest vehicle time seen: STATUSTEXT and HEARTBEAT carry none
    invalid = mavutil.mavlink.MAV_AUTOPILOT_INVALID
    armed_flag = mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    try:
        while True:
            m = conn.recv_match(type=_TLOG_TYPES)
            if m is None:
                break
            if m.get_srcComponent() != 1:  # the autopilot's own messages
                continue
            kind = m.get_type()
            if kind == "RAW_IMU":
                t = m.time_usec * 1e-6
                g, a = 1e-3, GRAVITY * 1e-3  # mrad/s, milli-g
                raw.append((t, m.xgyro * g, m.ygyro * g, m.zgyro * g, m.xacc * a, m.yacc * a, m.zacc * a))
            elif kind == "HIGHRES_IMU":
                t = m.time_usec * 1e-6
                hi.append((t, m.xgyro, m.ygyro, m.zgyro, m.xacc, m.yacc, m.zacc))
            elif kind == "ATTITUDE":
                t = m.time_boot_ms * 1e-3
                att.append((t, m.roll, m.pitch, m.yaw))
            elif kind == "LOCAL_POSITION_NED":
                t = m.time_boot_ms * 1e-3
                ekf.append((t, m.vx, m.vy, m.vz, m.x, m.y, m.z))
            elif kind == "DISTANCE_SENSOR":
                if m.orientation != DOWNWARD:
                    continue
                t = m.time_boot_ms * 1e-3
                good = m.min_distance < m.current_distance < m.max_distance and m.signal_quality != 1
                rng.append((t, m.current_distance / 100.0, 1.0 if good else 0.0))
            elif kind == "SERVO_OUTPUT_RAW":
                if getattr(m, "port", 0) != 0:
                    continue
                t = m.time_usec * 1e-6
                out.append((t, m.servo1_raw, m.servo2_raw, m.servo3_raw, m.servo4_raw))
            elif kind == "NAMED_VALUE_FLOAT":
                t = m.time_boot_ms * 1e-3
                if _text(m.name) == "SL_STATE":
                    states.append((t, m.value))
            elif kind == "STATUSTEXT":
                texts.append((now, _text(m.text)))
                continue
            elif kind == "HEARTBEAT":
                if m.autopilot != invalid:
                    armed.append((now, bool(m.base_mode & armed_flag)))
                continue
            elif kind == "PARAM_VALUE":
                params[_text(m.param_id)] = float(m.param_value)
                continue
            now = max(now, t)
    finally:
        conn.close()
    imu = Series.of(hi, "HIGHRES_IMU", 6) if len(hi) > len(raw) else Series.of(raw, "RAW_IMU", 6)
    attitude = Series.of(att, "ATTITUDE", 3)
    where = "the log's PARAM_VALUE messages"
    return FlightLog(
        path=path,
        kind=TLOG,
        imu=imu,
        attitude=attitude,
        ekf=_with_attitude(Series.of(ekf, "LOCAL_POSITION_NED", 6), attitude),
        ranges=Series.of(rng, "DISTANCE_SENSOR", 2),
        outputs=Series.of(out, "SERVO_OUTPUT_RAW", 4),
        states=Series.of(states, "NAMED_VALUE_FLOAT SL_STATE", 1),
        texts=[(t, s) for t, s in texts if math.isfinite(t)],
        armed=_changes([(t, v) for t, v in armed if math.isfinite(t)]),
        params=params,
        filters=_filters(params, None, where),
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
