"""The vehicle's landing record over MAVLink: at the decision of each landing (at rest, slid,
flipped, or 2 s after first contact, as the model decides), the conditions at first contact,
the thrust profile after it and the outcome, as NAMED_VALUE_FLOAT (``TD_*``, ``LD_*``) and one
STATUSTEXT. A test or a log replays the same landing in the model alone from these numbers."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from slopelander.model.judge import LandingJudge

if TYPE_CHECKING:
    from slopelander_sitl.vehicle.vehicle import Vehicle

# name (at most 10 characters) -> what it holds; LD_DONE comes last
FIELDS = (
    "TD_SLOPE",  # deg, the surface the legs met
    "TD_VZ",  # m/s, z up, just before first contact
    "TD_VX",  # m/s, +x toward the roof's downhill side
    "TD_PITCH",  # deg, nose up
    "TD_RATE",  # deg/s
    "TD_TAU_UP",  # N*m per real joint, uphill pair
    "TD_TAU_DN",  # downhill pair
    "TD_ANG_UP",  # deg, friction-joint angle, uphill
    "TD_ANG_DN",
    "TD_LEG_UP",  # deg, leg angle (differs from the joint's only while the leg flexes)
    "TD_LEG_DN",
    "TD_W_REAR",  # rotor speed, signed fraction of full, rear (-x) pair
    "TD_W_FRONT",
    "TD_REV_PCT",  # first reverse command after contact, percent
    "TD_REV_DLY",  # s from first contact to it (-1: none)
    "TD_REV_CHG",  # 1 if the reverse command changed before the decision
    "TD_FWD",  # largest forward rotor command after contact (0..1)
    "LD_OUTCOME",  # slopelander.model.Outcome code
    "LD_SLIDE",  # m along the slope, + downhill
    "LD_PFINAL",  # deg
    "LD_PMIN",  # deg, furthest toward downhill
    "LD_C_UP",  # peak compression fraction, uphill joint
    "LD_C_DN",
    "LD_SETTLE",  # s from contact to rest (-1: never)
    "LD_DONE",  # vehicle time of the decision (s): the record is complete
)


def values(judge: LandingJudge, t_decided: float) -> dict[str, float]:
    i, pr, r = judge.impact, judge.profile, judge.result
    assert i is not None and r is not None
    return {
        "TD_SLOPE": i.slope_deg,
        "TD_VZ": i.vz,
        "TD_VX": i.vx,
        "TD_PITCH": i.pitch_deg,
        "TD_RATE": i.pitch_rate_dps,
        "TD_TAU_UP": i.tau_up,
        "TD_TAU_DN": i.tau_down,
        "TD_ANG_UP": i.angle_up_deg,
        "TD_ANG_DN": i.angle_down_deg,
        "TD_LEG_UP": i.leg_up_deg,
        "TD_LEG_DN": i.leg_down_deg,
        "TD_W_REAR": i.rotor_speed[0],
        "TD_W_FRONT": i.rotor_speed[1],
        "TD_REV_PCT": pr.reverse_percent,
        "TD_REV_DLY": -1.0 if math.isnan(pr.reverse_delay) else pr.reverse_delay,
        "TD_REV_CHG": float(pr.reverse_changed),
        "TD_FWD": pr.forward_after_contact,
        "LD_OUTCOME": float(int(r.outcome)),
        "LD_SLIDE": r.slide,
        "LD_PFINAL": r.final_pitch_deg,
        "LD_PMIN": r.min_pitch_deg,
        "LD_C_UP": r.compression_up,
        "LD_C_DN": r.compression_down,
        "LD_SETTLE": -1.0 if math.isnan(r.settle_time) else r.settle_time,
        "LD_DONE": t_decided,
    }


def send(v: Vehicle, judge: LandingJudge) -> None:
    vals = values(judge, v.t)
    for name in FIELDS:
        v.send_named_float(name, vals[name])
    r = judge.result
    v.statustext(f"Landing: {r.outcome.name.lower()} slide {r.slide:+.2f} m", 6)
