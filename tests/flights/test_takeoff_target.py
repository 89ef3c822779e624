"""Where a NAV_TAKEOFF climbs to: above home, which arming resets, never above the rangefinder's
terrain.

A take-off on real ArduCopter whose rangefinder fails in the climb: the parameter files make the
take-off's target an altitude above home, not above the terrain the rangefinder measures.

The ArduPilot rule (ArduCopter/mode_guided.cpp, ``ModeGuided::do_user_takeoff_start``): with
``WPNAV_RFND_USE`` 1 (stock) and the rangefinder healthy at the command, a NAV_TAKEOFF's altitude
is taken *above terrain*, the terrain being the rangefinder's. The climb then runs
``AC_WPNav::update_wpnav``, which fails while the rangefinder is unhealthy (out of range, no data,
a beam tilted off the ground), and 5 s of such failures in GUIDED or RTL (``FS_TERRAIN_TIMEOUT_MS``,
ArduCopter/events.cpp ``failsafe_terrain_check``) fire "Failsafe: Terrain data missing" and RTL.
A 200-landing soak on ArduCopter saw it take a vehicle whose legs did not loosen from its
take-off back down to the roof, armed, motors running. With ``WPNAV_RFND_USE`` 0 (the parameter
files) the target is above home, which ArduCopter resets to where it arms (the roof, for the
companion's take-off), so the take-off climbs whatever the rangefinder does.

Here the rangefinder's range is cut to 0.6 m (``RNGFND1_MAX``, read by the driver at each reading)
once the vehicle has left the pad: above it every reading is out of range, as from a beam that
lost the ground. Both settings are flown: the stock one must show the failsafe (the rule is real
on this binary), the shipped one must climb on to its target in GUIDED.
"""

from __future__ import annotations

import pytest
from pymavlink import mavutil

from slopelander_sitl.guided import arm_in_guided
from slopelander_sitl.rig import TRACK_MESSAGES, Rig, config
from tests.flights.conftest import autopilot_available
from tests.flights.test_flight_edges import set_param

ON_ARDUCOPTER = [pytest.mark.xdist_group("arducopter"), pytest.mark.timeout(1200)]

GUIDED, RTL, LAND = 4, 6, 9
SLOPE_DEG = 20.0
TAKEOFF_M = 2.0  # within the rangefinder's 3 m: the stock rule takes it above terrain
CUT_RANGE_M = 0.6  # the rangefinder's maximum once off the pad: out of range above it


def _parm(name: str) -> float:
    from tests.firmware.test_parameter_files import FIRMWARE, parse_parm

    return {n: v for _, n, v, _ in parse_parm(FIRMWARE / "sitl-json.parm")}[name]


@pytest.mark.parametrize(
    "rfnd_use", [pytest.param("shipped", marks=ON_ARDUCOPTER), pytest.param(1, marks=ON_ARDUCOPTER)]
)
def test_a_take_off_whose_rangefinder_fails_climbs_on(rfnd_use) -> None:
    """Landed on a 20 deg roof (the tilted beam reads the roof in range, so the stock rule takes the
    take-off above terrain), armed again, a 2 m take-off; 0.3 m up the rangefinder's range is cut
    to 0.6 m. Stock: the terrain failsafe and RTL; shipped: on to 2 m over where it armed, GUIDED."""
    autopilot_available("ardupilot")
    cfg = config()
    decode = TRACK_MESSAGES | {"PARAM_VALUE"}
    with Rig(slope_deg=SLOPE_DEG, seed=77, autopilot="ardupilot", decode=decode) as rig:
        p, _ = rig.plan(cfg)
        rig.take_off(3.0)
        rig.go_over_roof(1.5)
        flight = rig.land((p.tau_up, p.tau_down), cfg, timeout_s=60.0, rest_s=1.0)
        assert flight.end == "LANDED" and not rig.armed(), flight.history[-3:]
        if rfnd_use != "shipped":
            set_param(rig, "WPNAV_RFND_USE", rfnd_use)
        rested = rig.track.ranges[-1][1] if rig.track.ranges else None
        arm_in_guided(rig.link, rig.poll)
        z0 = rig.height()
        rig.wait_command(
            rig.link.command(mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, TAKEOFF_M), "take-off"
        )
        rig.fly_until(lambda: rig.height() > z0 + 0.3, 10.0, "leave the roof")
        set_param(rig, "RNGFND1_MAX", CUT_RANGE_M)
        rig.wait(9.0)
        mode, rose = rig.mode(), rig.height() - z0
        texts = [str(t) for t in rig.link.statustext]
    said = " | ".join(texts[-8:])
    print(f"WPNAV_RFND_USE {rfnd_use}: mode {mode}, rose {rose:.2f} m (range at rest {rested}) || {said}")
    terrain = any("Terrain data missing" in t for t in texts)
    if rfnd_use == "shipped":
        assert _parm("WPNAV_RFND_USE") == 0
        assert not terrain and mode == GUIDED, said
        assert rose == pytest.approx(TAKEOFF_M, abs=0.3)
    else:  # the stock setting: the rule the parameter files avoid, seen on this binary
        assert terrain and mode in (RTL, LAND), (mode, said)


def land_then_arm_again(rig: Rig, cfg) -> None:
    """A landing by the companion on the rig's roof, ended disarmed there, then armed again in
    GUIDED where it lies: the start of a take-off from the roof."""
    p, _ = rig.plan(cfg)
    rig.take_off(3.0)
    rig.go_over_roof(1.5)
    flight = rig.land((p.tau_up, p.tau_down), cfg, timeout_s=60.0, rest_s=1.0)
    assert flight.end == "LANDED" and not rig.armed(), flight.history[-3:]
    arm_in_guided(rig.link, rig.poll)


def over_roof(rig: Rig) -> float:
    """The vehicle's height (m) over the roof below it, by its reported position."""
    return rig.height() - rig.surface_z(rig.track.pos[-1][1])


ROOF_OVER_PAD_M = 0.5  # slopelander_sitl.rig.ROOF_Z_M: a flat roof this much above the pad
RETAKEOFF_M = 1.0


def test_a_take_off_after_arming_on_the_roof_climbs_above_where_it_armed(autopilot: str) -> None:
    """Landed and disarmed on a flat roof 0.5 m above the pad, armed again there: a 1 m take-off
    ends about 1 m over the roof, not 1 m over the pad (0.5 m over the roof). ArduCopter resets home
    where it arms (AP_Arming_Copter::arm); the simulated vehicle mirrors it
    (slopelander_sitl/vehicle/vehicle.py ``arm_home``), and this holds the two together."""
    cfg = config()
    with Rig(slope_deg=0.0, seed=78, autopilot=autopilot) as rig:
        land_then_arm_again(rig, cfg)
        rested = over_roof(rig)
        rig.wait_command(
            rig.link.command(mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, RETAKEOFF_M), "take-off"
        )
        rig.wait(8.0)
        over = over_roof(rig)
    print(f"{autopilot}: at rest {rested:.2f} m, after the take-off {over:.2f} m over the roof")
    assert over - rested == pytest.approx(RETAKEOFF_M, abs=0.25), (rested, over)
