"""A user's own effect, in a file of theirs, changes the landing without touching the package."""

import textwrap

import pytest

from slopelander.model import EffectError, LandingConditions, load_effects, simulate

EFFECT_FILE = textwrap.dedent(
    """
    import numba
    from slopelander.model import kernel as k
    from slopelander.model.effects import UserEffect

    @numba.njit
    def pitch_drag(t, st, ctx, up, out):
        out[2] -= up[0] * st[k.S_V + 2]

    EFFECTS = [UserEffect("pitch_drag", "air damping of pitch", pitch_drag,
                          {"pitch_drag_coefficient": (0.5, "N*m*s/rad")})]
    """
)


def test_user_effect_from_file_damps_pitch(tmp_path, model):
    path = tmp_path / "my_effects.py"
    path.write_text(EFFECT_FILE)
    (effect,) = load_effects(path)
    assert effect.name == "pitch_drag"
    c = LandingConditions(slope_deg=30.0, speed=2.0, pitch_rate_dps=-60.0)
    base = simulate(c, model, full_horizon=False).result
    damped = simulate(c, model.with_user_effect(effect), full_horizon=False).result
    assert damped.min_pitch_deg > base.min_pitch_deg + 1.0  # it tips over less
    # parameters by name, and zero drag is the base model again
    zero = simulate(
        c, model.with_user_effect(effect.with_values(pitch_drag_coefficient=0.0)), full_horizon=False
    ).result
    assert zero == base


def test_bad_effect_files(tmp_path):
    with pytest.raises(EffectError, match="no such effect file"):
        load_effects(tmp_path / "missing.py")
    broken = tmp_path / "broken.py"
    broken.write_text("def oops(:\n")
    with pytest.raises(EffectError, match="failed to load: SyntaxError"):
        load_effects(broken)
    empty = tmp_path / "empty.py"
    empty.write_text("x = 1\n")
    with pytest.raises(EffectError, match="defines no UserEffect"):
        load_effects(empty)
