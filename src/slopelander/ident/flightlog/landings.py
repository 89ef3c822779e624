"""Where the landings are in a log, and when the feet met the roof.

A landing is the on-board script's cut (``SL_STATE`` 11, docs/onboard-script.md) followed by its
reverse thrust (12), its hold (13) or its faulted hold (31); a cut the script gave back (to 0,
"false cut") is not one.
A log without the script's announcements (firmware that does not log NAMED_VALUE_FLOAT) is read
from the motor outputs alone: all four at the ESCs' neutral 1500 ± 30 µs after flying forward is
a cut, all four below it is reverse thrust; the outputs' log rate then limits the timing.

First contact is read from the accelerometer, whose magnitude is at its lowest just before it:
the thrust of the descent (1 g) or, after the cut, the free fall it decays to. A contact is a rise
of the magnitude above its running minimum by :data:`MIN_RISE` (or eight times its noise, when
that is larger); its moment is where the filtered signal first leaves its smooth trend, walking
back from that rise (:func:`first_contact`). The autopilot's 2-pole filter has no dead time: its
output bends within a sample of the contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slopelander.ident.flightlog.reader import FlightLog, FlightLogError

IDLE, ARMED, CUT, RVT, HOLD, FAULT_HELD = 0, 10, 11, 12, 13, 31
NEUTRAL_US = 1500
DEADBAND_US = 30
"""µs either side of 1500 the ESCs read as stopped (docs/onboard-script.md)."""
BEFORE_CUT_S = 0.5
"""How long before the cut first contact is looked for: a foot may meet the roof before the
rangefinder's two samples reach the cut height (the uphill foot of a level body, on a steep roof)."""
NO_IMPACT_S = 1.0
"""How long after the cut contact is looked for when the script never reversed."""
WINDOW_S = 10.0
"""The longest a landing runs after its cut (then the next take-off, or the log's end)."""
MIN_RISE = 1.0
"""m/s^2: the least rise of the filtered accelerometer's magnitude that is called a contact."""
NOISE_SPAN_S = (1.5, 0.5)
TREND_SAMPLES = 8
"""Samples before the rise (less the two nearest it) whose bend the trend is allowed."""
TREND_MARGIN = 1.25
"""A sample bends away from the trend when it bends this many times more than those samples."""
"""The accelerometer's noise is measured from this long before the cut to this long before it."""


@dataclass(frozen=True)
class LandingEvents:
    """One landing's moments on the log's clock (s)."""

    number: int
    cut: float
    cut_source: str
    reverse: float | None
    """When the script started reverse thrust (RVT), or None."""
    reverse_left: float | None
    """When it left RVT, or None if the log ends in it."""
    reverse_left_to: int | None
    hold: float | None
    end: float
    """The end of the landing's part of the log."""
    end_why: str
    since: float = -math.inf
    """The end of the previous landing's part (-inf for the first): this landing's roof was
    surveyed after it, so its slope is measured from the points taken since."""


def _changes(log: FlightLog) -> list[tuple[float, int]]:
    out: list[tuple[float, int]] = []
    for t, code in zip(log.states.t, log.states.v[:, 0], strict=True):
        c = round(float(code))
        if not out or out[-1][1] != c:
            out.append((float(t), c))
    return out


def find_landings(log: FlightLog) -> list[LandingEvents]:
    """Every landing in ``log``, in order. Raises :class:`FlightLogError` when there is none,
    saying what the log holds instead."""
    if len(log.states):
        found = _from_states(log)
        if found:
            return found
        codes = sorted({c for _, c in _changes(log)})
        cuts = sum(1 for _, c in _changes(log) if c == CUT)
        more = f"; {cuts} cut(s) the script gave back (false cuts)" if cuts else ""
        raise FlightLogError(
            log.path,
            f"no landing in this log: the on-board script's states ({log.states.source}) never went "
            f"from the cut (11) to reverse thrust (12) or a hold (13, 31); states seen: "
            f"{', '.join(map(str, codes))}{more}{_tail(log)}",
        )
    found = _from_outputs(log)
    if found:
        return found
    if not len(log.outputs):
        raise FlightLogError(
            log.path,
            "no landing in this log: it holds neither the on-board script's SL_STATE nor the motor "
            f"outputs ({'RCOU' if log.kind == 'DataFlash' else 'SERVO_OUTPUT_RAW'}){_tail(log)}",
        )
    raise FlightLogError(
        log.path,
        "no landing in this log: no SL_STATE from the on-board script, and the motor outputs never "
        f"stop at {NEUTRAL_US} µs after flying forward{_tail(log)}",
    )


def _tail(log: FlightLog) -> str:
    return f"; {log.truncated}" if log.truncated else ""


def _end(log: FlightLog, cut: float, after: float, next_cut: float | None) -> tuple[float, str]:
    """The end of a landing's window: a take-off (outputs forward again), the next cut, the
    window's length, or the log's end, whichever comes first."""
    limit = cut + WINDOW_S
    why = f"{WINDOW_S:g} s after the cut"
    if next_cut is not None and next_cut < limit:
        limit, why = next_cut, "the next cut"
    o = log.outputs
    forward = (o.t > after) & (o.t < limit) & np.all(o.v > NEUTRAL_US + DEADBAND_US, axis=1)
    if forward.any():
        limit, why = float(o.t[np.argmax(forward)]), "the next take-off"
    if log.end < limit:
        limit, why = log.end, "the log's end"
    return limit, why


def _from_states(log: FlightLog) -> list[LandingEvents]:
    ch = _changes(log)
    cuts = [i for i, (_, c) in enumerate(ch) if c == CUT and (i == 0 or ch[i - 1][1] != CUT)]
    out: list[LandingEvents] = []
    for k, i in enumerate(cuts):
        since = out[-1].end if out else -math.inf
        t_cut = ch[i][0]
        after = ch[i + 1 : cuts[k + 1]] if k + 1 < len(cuts) else ch[i + 1 :]
        if not after or after[0][1] not in (RVT, HOLD, FAULT_HELD):
            continue  # a false cut (back to IDLE), or the log ends in CUT
        rvt = after[0][0] if after[0][1] == RVT else None
        left = left_to = hold = None
        if rvt is not None and len(after) > 1:
            left, left_to = after[1]
        hold = next((t for t, c in after if c == HOLD), None)
        next_cut = ch[cuts[k + 1]][0] if k + 1 < len(cuts) else None
        end, why = _end(log, t_cut, hold or left or rvt or t_cut, next_cut)
        out.append(
            LandingEvents(
                len(out) + 1, t_cut, log.states.source + " 11", rvt, left, left_to, hold, end, why, since
            )
        )
    return out


def _from_outputs(log: FlightLog) -> list[LandingEvents]:
    o = log.outputs
    if len(o) < 2:
        return []
    stopped = np.all(np.abs(o.v - NEUTRAL_US) <= DEADBAND_US, axis=1)
    reverse = np.all(o.v < NEUTRAL_US - DEADBAND_US, axis=1)
    forward = np.all(o.v > NEUTRAL_US + DEADBAND_US, axis=1)
    out = []
    flying = False
    i = 0
    while i < len(o):
        if forward[i]:
            flying = True
        elif flying and (stopped[i] or reverse[i]):
            t_cut = float(o.t[i])
            j = i
            while j < len(o) and stopped[j]:
                j += 1
            rvt = float(o.t[j]) if j < len(o) and reverse[j] else None
            left = left_to = None
            if rvt is not None:
                while j < len(o) and reverse[j]:
                    j += 1
                left = float(o.t[j]) if j < len(o) else None
                if left is not None and stopped[j]:
                    left_to = HOLD  # back to neutral: the script's ramp ended there
            end, why = _end(log, t_cut, left or rvt or t_cut, None)
            src = f"{o.source} leaving forward thrust"
            hold = left if left_to == HOLD else None
            since = out[-1].end if out else -math.inf
            out.append(LandingEvents(len(out) + 1, t_cut, src, rvt, left, left_to, hold, end, why, since))
            flying = False
            i = max(j, i + 1)
            continue
        i += 1
    return out


def accel_noise(log: FlightLog, cut: float) -> float:
    """The filtered accelerometer magnitude's sample-to-sample noise (m/s^2, robust) over the
    descent before the cut."""
    s = log.imu.between(cut - NOISE_SPAN_S[0], cut - NOISE_SPAN_S[1])
    if len(s) < 10:
        return 0.0
    d = np.diff(np.linalg.norm(s.v[:, 3:6], axis=1))
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))


def first_contact(t: np.ndarray, accel: np.ndarray, noise: float = 0.0) -> tuple[int, float] | None:
    """Index of the last sample before first contact in the filtered specific force ``accel``
    (rows x, y, z; sampled at ``t``) and the rise threshold that found it, or None.

    The contact is where the magnitude first rises more than the threshold (:data:`MIN_RISE`, or
    8 noise) above its running minimum; its onset is then found walking back while each sample
    departs from the straight line through the two before it (its bend) by more than 3 noise,
    0.05 m/s^2, or :data:`TREND_MARGIN` times the largest bend of the :data:`TREND_SAMPLES`
    samples before: before contact the filtered signal follows a smooth trend (the descent's
    steady thrust, or the thrust decaying after the cut), and a foot's force bends it at once."""
    if len(t) < 4:
        return None
    a = np.linalg.norm(accel, axis=1)
    rise = max(MIN_RISE, 8.0 * noise)
    settle = max(0.05, 3.0 * noise)
    above = np.nonzero(a - np.minimum.accumulate(a) > rise)[0]
    if not above.size:
        return None
    bend = np.zeros(len(t))
    bend[2:] = np.linalg.norm(accel[2:] - 2.0 * accel[1:-1] + accel[:-2], axis=1)
    i = int(above[0])
    # how much the trend itself bends before: the thrust's decay after the cut is no straight line
    before = bend[max(2, i - 2 - TREND_SAMPLES) : max(2, i - 2)]
    if before.size:
        settle = max(settle, TREND_MARGIN * float(before.max()))
    while i > 2 and bend[i] > settle:
        i -= 1
    return i, rise


def contact_time(log: FlightLog, ev: LandingEvents) -> tuple[float, float]:
    """First contact of landing ``ev`` (s, log clock): half a sample after the last sample before
    it (:func:`first_contact`); and the rise threshold used (m/s^2). Raises
    :class:`FlightLogError` when the accelerometer shows none, or the log ends first."""
    if not len(log.imu):
        raise FlightLogError(log.path, f"landing {ev.number}: no accelerometer samples ({log.imu.source})")
    t0 = ev.cut - BEFORE_CUT_S
    t1 = (ev.reverse + 0.05) if ev.reverse is not None else ev.cut + NO_IMPACT_S
    t1 = min(t1, ev.end)
    s = log.imu.between(t0, t1)
    if len(s) < 4:
        raise FlightLogError(
            log.path,
            f"landing {ev.number}: no accelerometer samples between {t0:.2f} and {t1:.2f} s "
            f"(the log's {log.imu.source} ends at {log.imu.t[-1]:.2f} s{_tail(log)})",
        )
    found = first_contact(s.t, s.v[:, 3:6], accel_noise(log, ev.cut))
    if found is None:
        raise FlightLogError(
            log.path,
            f"landing {ev.number}: the accelerometer shows no contact between {t0:.2f} and {t1:.2f} s "
            f"(no rise of {MIN_RISE:g} m/s^2 or more above its level)",
        )
    i, rise = found
    dt = float(s.t[i + 1] - s.t[i]) if i + 1 < len(s.t) else 0.0
    return float(s.t[i]) + 0.5 * dt, rise
