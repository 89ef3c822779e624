"""The rules that end ArduCopter's fast boot (src/slopelander_sitl/ardupilot/fast_boot.py), message by
message.
tests/json_physics/test_real_ardupilot.py holds them to the real binary."""

from __future__ import annotations

from types import SimpleNamespace as Msg

from slopelander_sitl.ardupilot.fast_boot import CAP_S, GIVE_UP_S, POSITION_FLAGS, PREARM_CHECK, FastBoot


def at(boot: FastBoot, s: float, prearm: bool | None = None, position: bool | None = None) -> None:
    boot.heard("SYSTEM_TIME", Msg(time_boot_ms=int(s * 1000)))
    if prearm is not None:
        boot.heard("SYS_STATUS", Msg(onboard_control_sensors_health=PREARM_CHECK if prearm else 0))
    if position is not None:
        boot.heard("EKF_STATUS_REPORT", Msg(flags=POSITION_FLAGS if position else 1 | 2 | 4))


def confirm(boot: FastBoot, value: float, name: str = "SIM_SPEEDUP") -> None:
    boot.heard("PARAM_VALUE", Msg(param_id=name, param_value=value))


def test_the_pre_arm_bit_alone_does_not_end_it_a_position_must_come_too():
    boot = FastBoot(1.0)
    at(boot, 24.0, prearm=True, position=False)  # on the pad: checks pass at 20-25 s ...
    assert boot.pending is None
    at(boot, 41.0, position=True)  # ... GUIDED arms once the EKF uses GPS
    assert boot.pending == ("SIM_SPEEDUP", 1.0)
    assert not boot.done
    confirm(boot, 1.0)
    assert boot.done and boot.done_at == 41.0 and "pre-arm checks pass" in boot.why
    assert boot.pending is None


def test_only_arducopters_confirmation_of_the_flight_speedup_ends_it():
    boot = FastBoot(1.0)
    at(boot, 41.0, prearm=True, position=True)
    confirm(boot, 20.0)  # an old value
    confirm(boot, 1.0, name="SIM_RATE_HZ")  # another parameter
    assert not boot.done and boot.pending == ("SIM_SPEEDUP", 1.0)
    confirm(boot, 1.0)
    assert boot.done


def test_a_vehicle_leaning_on_a_roof_goes_on_at_the_cap_once_it_has_a_position():
    boot = FastBoot(1.0)
    at(boot, 41.0, prearm=False, position=True)
    assert boot.pending is None
    at(boot, CAP_S)
    assert boot.pending == ("SIM_SPEEDUP", 1.0)
    confirm(boot, 1.0)
    assert "still failing" in boot.why


def test_a_vehicle_without_a_position_goes_on_at_the_give_up_time():
    boot = FastBoot(2.0)
    at(boot, 60.0, prearm=True, position=False)
    assert boot.pending is None
    at(boot, GIVE_UP_S)
    assert boot.pending == ("SIM_SPEEDUP", 2.0)
    confirm(boot, 2.0)
    assert boot.done and "no EKF position" in boot.why


def test_a_position_lost_before_the_confirmation_keeps_the_boot_going():
    boot = FastBoot(1.0)
    at(boot, 41.0, prearm=True, position=True)
    at(boot, 41.1, position=False)
    confirm(boot, 1.0)  # confirmed, but the vehicle could no longer arm: asked again later
    assert not boot.done and boot.pending is None
    at(boot, 41.5, position=True)
    confirm(boot, 1.0)
    assert boot.done
