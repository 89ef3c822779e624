"""One landing cut out of a DataFlash log, small enough to send or to ship: whole messages as the
autopilot wrote them, kept or dropped, never rewritten.

    python -m slopelander.ident.flightlog.trim flight.bin landing.bin [--landing N]

Kept: the format messages (FMT, FMTU) of the kept types, UNIT, MULT, the version, the parameters
of the IMU filters, the rangefinder, logging and the loop rate; from a second before the first
surface point of the slope estimate on, the slow signals ``compare`` reads (attitude, estimator,
rangefinder, outputs, the script's and companion's messages); the first IMU and the loop-rate
attitude from :data:`FAST_BEFORE_S` before first contact to :data:`FAST_AFTER_S` after it; SITL's
own state (SIM2, where a simulator wrote it) for :data:`TRUTH_S` around contact, as a check.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
from pathlib import Path

FORMATS = {"FMT", "FMTU", "UNIT", "MULT", "VER"}
SLOW = {"ATT", "XKF1", "NKF1", "RFND", "RCOU", "NVF", "MSG", "ARM", "EV", "MODE"}
FAST = {"IMU", "ANG"}
PARAM_PREFIXES = ("INS_ACCEL_FILTER", "INS_GYRO_FILTER", "RNGFND1_", "LOG_", "SCHED_LOOP_RATE")
FAST_BEFORE_S = 0.5
FAST_AFTER_S = 2.0
TRUTH_S = 0.1
SLOW_AFTER_S = 4.0


def trim(src: str | Path, dst: str | Path, landing: int = 1) -> dict[str, int]:
    """Write landing ``landing`` of the DataFlash log ``src`` to ``dst``; the messages kept, by type."""
    from pymavlink import DFReader

    from slopelander.ident.flightlog.conditions import Given, landing_conditions
    from slopelander.ident.flightlog.landings import contact_time, find_landings
    from slopelander.ident.flightlog.reader import DATAFLASH, FlightLogError, log_kind, read_log

    src, dst = Path(src), Path(dst)
    if log_kind(src) != DATAFLASH:
        raise FlightLogError(src, "not a DataFlash log: only those are trimmed")
    log = read_log(src)
    found = find_landings(log)
    if not 1 <= landing <= len(found):
        raise FlightLogError(src, f"--landing {landing}: the log holds {len(found)} landing(s)")
    ev = found[landing - 1]
    contact, _ = contact_time(log, ev)
    cond = landing_conditions(log, ev, contact, Given())
    seen = [p[0] for p in cond.slope.points] if cond.slope is not None else []
    slow0 = (min(seen) if seen else ev.cut - 5.0) - 1.0
    slow1 = min(ev.end, contact + SLOW_AFTER_S)
    fast0, fast1 = contact - FAST_BEFORE_S, min(ev.end, contact + FAST_AFTER_S)

    kept = FORMATS | SLOW | FAST | {"PARM", "SIM2"}

    def keep(m) -> bool:
        kind = m.get_type()
        if kind == "FMT":
            return str(m.Name) in kept
        if kind == "FMTU":
            fmt = r.formats.get(int(m.FmtType))
            return fmt is not None and fmt.name in kept
        if kind in FORMATS:
            return True
        if kind == "PARM":
            return str(m.Name).startswith(PARAM_PREFIXES)
        t = getattr(m, "TimeUS", 0) * 1e-6
        if kind in FAST:
            return getattr(m, "I", 0) == 0 and fast0 <= t <= fast1
        if kind == "SIM2":
            return abs(t - contact) <= TRUTH_S
        if kind in SLOW:
            return getattr(m, "C", 0) == 0 and slow0 <= t <= slow1
        return False

    counts: dict[str, int] = {}
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        r = DFReader.DFReader_binary(str(src))
        r._rewind()
        data = r.data_map
        with open(dst, "wb") as out:
            while True:
                m = r._parse_next()
                if m is None:
                    break
                if keep(m):
                    end = r.offset
                    out.write(data[end - m.fmt.len : end])
                    counts[m.get_type()] = counts.get(m.get_type(), 0) + 1
        r.close()
    return counts


def main(argv: list[str] | None = None) -> int:
    from slopelander.errors import SlopelanderError

    ap = argparse.ArgumentParser(prog="python -m slopelander.ident.flightlog.trim", description=__doc__)
    ap.add_argument("log", type=Path, help="a DataFlash log (.bin)")
    ap.add_argument("out", type=Path, help="the trimmed log to write")
    ap.add_argument("--landing", type=int, default=1, help="which landing (default the first)")
    a = ap.parse_args(argv)
    try:
        counts = trim(a.log, a.out, a.landing)
    except SlopelanderError as exc:
        print(f"trim: error: {exc}", file=sys.stderr)
        return 1
    size = a.out.stat().st_size
    kinds = ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
    print(f"wrote {a.out} ({size / 1000:.0f} kB): {kinds}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
