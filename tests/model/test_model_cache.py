"""The compiled model is cached across processes, and a user effect's mistakes are named."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from slopelander.model import EffectError, LandingConditions, load_effects, simulate

ROOT = Path(__file__).resolve().parents[2]

PROBE = (
    "from slopelander.model import LandingConditions, simulate, simulate_batch; "
    "simulate(LandingConditions(slope_deg=30, speed=2)); "
    "simulate_batch([LandingConditions(slope_deg=20, speed=1.5)] * 4)"
)


def _probe() -> str:
    env = dict(os.environ, NUMBA_DEBUG_CACHE="1", PYTHONPATH=f"{ROOT / 'src'}{os.pathsep}{ROOT}")
    r = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return r.stdout + r.stderr


def test_second_process_loads_everything_from_the_cache():
    _probe()  # warms the cache if this checkout's code changed
    out = _probe()
    assert "[cache] data loaded" in out
    assert "[cache] data saved" not in out, out


BAD_EFFECT = textwrap.dedent(
    """
    import numba
    from slopelander.model.effects import UserEffect


    @numba.njit
    def leaky(t, st, ctx, up, out):
        out[2] -= up[0] * st.no_such_field
        return


    EFFECTS = [UserEffect("leaky", "a mistake", leaky, {"leak": (1.0, "1")})]
    """
)


def test_typing_error_names_the_effect_and_the_line(tmp_path, model):
    path = tmp_path / "bad_effects.py"
    path.write_text(BAD_EFFECT)
    (effect,) = load_effects(path)
    with pytest.raises(EffectError) as info:
        simulate(LandingConditions(), model.with_user_effect(effect))
    msg = str(info.value)
    assert f"{path}:8:" in msg and "'leaky'" in msg and "no_such_field" in msg
    assert "\n" not in msg  # one line, not numba's pages


USER_PROBE = (
    "import sys\n"
    "from slopelander.model import LandingConditions, Model, load_effects, simulate, simulate_batch\n"
    "from slopelander.model.stepper import Stepper\n"
    "m = Model.default()\n"
    "for f in sys.argv[1:]:\n"
    "    m = m.with_user_effect(load_effects(f'{ROOT}/docs/examples/{f}.py')[0])\n"
    "simulate(LandingConditions(slope_deg=30, speed=2), m)\n"
    "simulate_batch([LandingConditions(slope_deg=20, speed=1.5)] * 4, m)\n"
    "s = Stepper(m, slope_deg=10.0); s.step(0.01, 0.0, 0.0); s.energy()\n"
)


def test_user_effects_run_on_one_cached_integrator_whatever_the_effects():
    """One compiled integrator serves every model with user effects (the shipped model has its
    own, without seams): once it is cached, a model with other user effects (two other seams in
    use) compiles nothing into numba's cache, first run or later; only the users' small
    functions are compiled, in memory."""
    env = dict(os.environ, NUMBA_DEBUG_CACHE="1", PYTHONPATH=f"{ROOT / 'src'}{os.pathsep}{ROOT}")
    code = f"ROOT = {str(ROOT)!r}\n" + USER_PROBE

    def run(*effects: str) -> str:
        r = subprocess.run(
            [sys.executable, "-c", code, *effects], env=env, capture_output=True, text=True, timeout=600
        )
        assert r.returncode == 0, r.stderr
        return r.stdout + r.stderr

    run("effect_point_force")  # warms the cache if this checkout's code changed
    for _ in range(2):
        out = run("effect_joint_torque", "effect_foot_friction")
        assert "[cache] data loaded" in out
        assert "[cache] data saved" not in out, out
