"""The array layouts live in a numba-free module: files validate without the compiler, user
code names slots, and a compiled integrator built against old layouts is not reused."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from numba import njit

from slopelander.model import LandingConditions, simulate, state
from slopelander.model import layout as lay

ROOT = Path(__file__).resolve().parents[2]


def test_parameter_file_and_effects_validate_without_numba(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        (ROOT / "src/slopelander/model/default_parameters.yaml")
        .read_text()
        .replace("  - rotors\n", "  - rotors\n  - rigid_gear\n")
    )
    code = (
        "import sys; sys.modules['numba'] = None\n"  # any import of numba now fails
        "from slopelander.model import ModelParams, EffectError, layout\n"
        "from slopelander.model.effects import flags_for\n"
        "p = ModelParams.default(); assert flags_for(p.effects)[layout.F_FLEX] == 1\n"
        f"try:\n    ModelParams.load({str(bad)!r})\nexcept EffectError as e:\n    print('rejected:', e)\n"
    )
    env = dict(os.environ, PYTHONPATH=f"{ROOT / 'src'}{os.pathsep}{ROOT}")
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "rejected:" in r.stdout and "'rigid_gear' locks the joints" in r.stdout


@njit
def _read(st, ctx):
    return np.array(
        [
            state.pitch(st),
            state.pitch_rate(st),
            state.leg_angle(st, 1),
            state.joint_angle(st, 0),
            state.foot_normal_force(st, 1),
            state.foot_slip_speed(st, 0),
            state.time(st),
            float(state.downhill_leg(ctx)),
            state.torque_setting(ctx, 1),
        ]
    )


def test_accessors_read_the_named_slots():
    st = np.arange(lay.N_STATE, dtype=float)
    ctx = np.arange(lay.N_CTX, dtype=float)
    got = _read(st, ctx)
    want = [
        lay.S_Q + 2,
        lay.S_V + 2,
        lay.S_Q + 4,
        lay.S_QE,
        lay.S_NF + 1,
        lay.S_SLIP,
        lay.S_T,
        lay.C_DOWN,
        lay.C_TAU + 1,
    ]
    assert got.tolist() == [float(w) for w in want]


def test_slip_speed_and_joint_rate_are_recorded(model):
    """The slots user laws read are filled: a foot sliding downhill has a positive slip speed
    while its normal force is positive, and a compressing joint a negative rate."""
    tr = simulate(
        LandingConditions(slope_deg=30.0, speed=2.5, tau_up=0.56, tau_down=0.56), model, sample_rate=2400.0
    )
    raw = tr.raw
    down = 1
    sliding = raw[:, lay.S_NF + down] > 1.0
    assert sliding.any()
    assert raw[sliding, lay.S_SLIP + down].max() > 0.1
    assert raw[:, lay.S_QED + down].min() < -1.0
    # the joint rate is the rate of the joint angle
    dq = np.gradient(raw[:, lay.S_QE + down], raw[:, lay.S_T])
    i = int(np.argmin(raw[:, lay.S_QED + down]))
    assert abs(dq[i] - raw[i, lay.S_QED + down]) < 0.2 * abs(raw[i, lay.S_QED + down])


def test_stale_compiled_code_is_dropped_when_the_layout_changes(tmp_path):
    mod = tmp_path / "kern.py"
    mod.write_text("")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    stale = cache / "kern.step-10.py312.nbi"
    stale.write_text("old")
    other = cache / "other.step-10.py312.nbi"
    other.write_text("kept")
    lay.drop_stale_cache(str(mod))
    assert not stale.exists() and other.exists()
    assert (cache / "kern.layout").read_text() == lay.layout_digest()
    stale.write_text("same layout")
    lay.drop_stale_cache(str(mod))
    assert stale.exists()  # same layouts: the cache is kept
