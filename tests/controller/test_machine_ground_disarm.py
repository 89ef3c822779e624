"""LANDED's own disarm (``MavActions.disarm_on_ground``) against the simulated vehicle: unforced,
so the autopilot takes it on the ground and refuses it in the air (AP_Arming_Copter::disarm, as
src/slopelander_sitl/vehicle/arducopter_rules.py mirrors it). That refusal is what makes it safe to send
when the
on-board script is idle and will not disarm."""

from __future__ import annotations

from slopelander.controller.actions import MavActions
from slopelander.controller.config import load_config
from slopelander_sitl.guided import arm_in_guided
from slopelander_sitl.rig import Rig


def test_the_companions_disarm_is_refused_in_the_air_and_made_on_the_ground():
    with Rig(slope_deg=20.0) as rig:
        act = MavActions(rig.link, load_config())
        rig.take_off(2.0)
        act.disarm_on_ground()
        handle = act.pending["disarm_on_ground"]
        rig.fly_until(lambda: handle.done, 10.0, "answer the disarm")
        assert not handle.ok and rig.armed()  # flying: refused, still armed
        rig.wait(1.0)
        assert rig.armed() and rig.height() > 1.5
    with Rig(slope_deg=20.0) as rig:
        act = MavActions(rig.link, load_config())
        arm_in_guided(rig.link, rig.poll)
        assert rig.armed()
        act.disarm_on_ground()  # armed on the pad, never taken off: the land detector says landed
        handle = act.pending["disarm_on_ground"]
        rig.fly_until(lambda: handle.done, 10.0, "answer the disarm")
        assert handle.ok
        rig.fly_until(lambda: not rig.armed(), 5.0, "disarm")
