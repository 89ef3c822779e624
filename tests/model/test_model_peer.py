"""The MuJoCo peer (optional extra ``peers``): it drops the same vehicle and agrees with the model
where both express the same physics; where MuJoCo's soft friction creeps, the model holds."""

import sys

import numpy as np
import pytest
from model_helpers import settle_on_slope

from slopelander.model import LandingConditions, Model, Outcome, simulate
from slopelander.model import kernel as k
from slopelander.model.conditions import conditions_array
from slopelander.peers.mujoco_drop import MujocoDrop, PeerError, matched_model

#: its tests share one matched peer model (matched, peer): one worker, file order (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("model/model_peer")

# the peer imports MuJoCo only when one is built
mujoco = pytest.importorskip("mujoco", reason="the MuJoCo peer needs the optional 'peers' extra (mujoco)")


@pytest.fixture(scope="module")
def matched():
    return matched_model()


@pytest.fixture(scope="module")
def peer(matched):
    return MujocoDrop(matched)


def test_level_drop_compresses_the_legs_as_the_model_does(matched, peer):
    """Level ground at 3 m/s, 1.7 N*m: both legs slip; MuJoCo's peak compression is within
    0.02 of the model's (measured 0.862 against 0.865)."""
    c = LandingConditions(slope_deg=0.0, speed=3.0)
    ours = simulate(c, matched, full_horizon=False).result
    mj = peer.land(c)
    assert mj.outcome == ours.outcome
    assert ours.compression_down > 0.5
    assert abs(mj.compression_down - ours.compression_down) < 0.02
    assert abs(mj.compression_up - ours.compression_up) < 0.02


def test_gentle_drop_lands_at_rest_in_both(matched, peer):
    """0 deg at 1 m/s: the joints hold, both call it under-used and both come to rest."""
    c = LandingConditions(slope_deg=0.0, speed=1.0)
    ours = simulate(c, matched, full_horizon=False).result
    mj = peer.land(c)
    assert ours.outcome == mj.outcome == Outcome.UNDER_USED
    assert mj.settle_time == pytest.approx(ours.settle_time, abs=0.1)
    assert mj.compression_down < 0.05


def test_steep_fast_drop_with_soft_legs_fails_alike(matched, peer):
    """45 deg at 3 m/s with 0.56 N*m: the legs give way and a joint hits the roof in both."""
    c = LandingConditions(slope_deg=45.0, speed=3.0, tau_up=0.56, tau_down=0.56)
    ours = simulate(c, matched, full_horizon=False).result
    mj = peer.land(c)
    assert ours.outcome == mj.outcome == Outcome.JOINT_TOUCH


def test_mujoco_creeps_where_the_model_holds(matched, peer):
    """A vehicle settled on a 34 deg slope (below atan 0.8 = 38.7 deg): the model's stiction
    holds it to the micrometre; MuJoCo's soft friction lets it slide (tens of mm in 5 s)."""
    s = settle_on_slope(matched, 34.0, tau=1.7)
    for _ in range(1000):  # the model's own settling slip first (legs splaying)
        s.step(1e-3, 0.0, 0.0)
    st = s.st.copy()
    mj_slide = peer.slide_at_rest(s.ctx, st, 4.0)
    b0 = s.body()
    for _ in range(3000):
        s.step(1e-3, 0.0, 0.0)
    b1 = s.body()
    assert abs(b1.x - b0.x) < 1e-6 and abs(b1.z - b0.z) < 1e-6
    assert mj_slide > 0.01


def test_the_peer_refuses_what_it_cannot_simulate(matched, peer):
    with pytest.raises(PeerError, match="no rotors"):
        peer.land(LandingConditions(slope_deg=20.0, reverse_percent=100.0))
    with pytest.raises(PeerError, match="rigid"):
        MujocoDrop(matched.rigid())
    with pytest.raises(PeerError, match=r"downhill_torque_growth.*matched_model"):
        MujocoDrop(Model.default())


def test_a_missing_mujoco_is_one_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "mujoco", None)  # makes `import mujoco` fail
    with pytest.raises(PeerError, match=r"slopelander\[peers\]"):
        MujocoDrop(matched_model())


def test_the_peer_starts_in_the_model_s_initial_state(matched, peer):
    """MuJoCo's own geometry puts the feet, joints and rotor hubs where the model's kinematics
    does (a check of the MJCF: leg angles, hinge axes, slope), and the peer's points agree."""
    c = LandingConditions(slope_deg=25.0, speed=2.0, pitch_deg=-5.0, angle_up_deg=30.0, tau_up=1.1)
    ctx = peer.start(c)
    st = np.zeros(k.N_STATE)
    ctx2 = np.zeros(k.N_CTX)
    ws = k.make_workspace()
    row = conditions_array([c]).view(np.float64).copy()
    p = matched.params.as_array()
    k.init_landing(p, matched.flags(), row, st, ctx2, ws)
    M, f, pts, vel, J = k.kinematics_views(ws)
    k.kinematics(p, st, M, f, pts, vel, J)
    m, d = peer.mjmodel, peer.data
    lift = peer.settings.radius / ctx[k.C_COS]
    for i, name in enumerate(("footC", "footD", "jointC", "jointD", "rotor1", "rotor2")):
        xyz = d.geom_xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)]
        assert xyz[0] == pytest.approx(pts[i, 0], abs=1e-9)
        assert xyz[2] == pytest.approx(pts[i, 1] + lift, abs=1e-9)
    dist, _ = peer.points(d.qpos[None].copy(), d.qvel[None].copy(), ctx)
    assert dist.min() == pytest.approx(0.0, abs=1e-9)
    assert ctx[k.C_TAU] == pytest.approx(2 * 1.1)  # the uphill (left) planar joint's torque
    assert m.dof_frictionloss[peer._fdof[0]] == pytest.approx(2 * 1.1)
