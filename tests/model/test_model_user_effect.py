"""A user's own effect, in a file of theirs, changes the landing without touching the package."""

import textwrap

import pytest

from slopelander.model import EffectError, LandingConditions, ParameterError, load_effects, simulate

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


SEAM_MISTAKES = textwrap.dedent(
    """
    import numba
    from slopelander.model.effects import EffectParameter, UserEffect


    @numba.njit
    def law(t, st, ctx, up, point, depth, rate):
        return depth * up[0]


    @numba.njit
    def other_law(t, st, ctx, up, point, depth, rate):
        return depth, 1.0, 0.0


    WRONG = UserEffect("wrong_return", "returns one number", normal_force=law,
                       parameters={"k_wrong": EffectParameter(1.0, "N/m", 0.0, 10.0)})
    A = UserEffect("law_a", "a law", normal_force=other_law)
    B = UserEffect("law_b", "another law", normal_force=other_law)
    EFFECTS = [WRONG, A, B]
    """
)


def test_seam_mistakes_are_named(tmp_path, model, monkeypatch):
    monkeypatch.setenv("SLOPELANDER_CACHE_DIR", str(tmp_path / "cache"))
    path = tmp_path / "seams.py"
    path.write_text(SEAM_MISTAKES)
    wrong, a, b = load_effects(path)
    with pytest.raises(EffectError) as info:
        simulate(LandingConditions(), model.with_user_effect(wrong))
    msg = str(info.value)
    assert "'wrong_return'" in msg and "normal_force it must return a tuple (force N" in msg
    assert "\n" not in msg
    with pytest.raises(EffectError, match="'law_a', 'law_b' each set the normal-force law"):
        model.with_user_effect(a).with_user_effect(b)


def test_declarations_are_checked():
    import numba

    from slopelander.model.effects import EffectParameter, UserEffect

    @numba.njit
    def f(t, st, ctx, up, out):
        return

    with pytest.raises(EffectError, match="plugs into no seam"):
        UserEffect("nothing", "no function")
    with pytest.raises(EffectError, match="has the name of a built-in parameter"):
        UserEffect("clash", "", force=f, parameters={"ground_damping": (1.0, "N*s/m")})
    with pytest.raises(ParameterError, match=r"'gain'.*outside 0\.0\.\.1\.0"):
        UserEffect("bad", "", force=f, parameters={"gain": EffectParameter(2.0, "1", 0.0, 1.0)})
    with pytest.raises(ParameterError, match="provenance must be one of"):
        UserEffect("bad", "", force=f, parameters={"gain": EffectParameter(0.5, "1", 0.0, 1.0, "guessed")})
    with pytest.raises(EffectError, match=r"must be compiled with numba\.njit"):
        UserEffect("plain", "", joint_torque=lambda *a: 0.0)
    e = UserEffect("ok", "", force=f, parameters={"gain": (0.5, "1", 0.0, 1.0)})
    assert e.parameters["gain"] == EffectParameter(0.5, "1", 0.0, 1.0)
    with pytest.raises(ParameterError, match="outside"):
        e.with_values(gain=-1.0)


SEAM_LIMITS = textwrap.dedent(
    """
    import numba
    from slopelander.model.effects import UserEffect


    @numba.njit
    def push(t, st, ctx, up, out):
        out[0] += up[0]


    @numba.njit
    def whole_newtons(t, st, ctx, up, leg, angle, rate, tau):
        return 0  # an int: the seam's float is made of it


    PUSHES = [UserEffect(f"push_{i}", "a push", force=push, parameters={f"push_{i}_n": (0.0, "N")})
              for i in range(5)]
    FREE = UserEffect("free_joints", "no joint torque", joint_torque=whole_newtons)
    EFFECTS = [*PUSHES, FREE]
    """
)


def test_seam_limits_and_return_types(tmp_path, model):
    """A seam takes four effects' laws, the fifth is refused by name; a law returning an int
    is converted to the seam's float (joints that hold nothing: the legs fold to their stop)."""
    from slopelander.model.seams import SLOTS

    path = tmp_path / "limits.py"
    path.write_text(SEAM_LIMITS)
    effects = load_effects(path)
    pushes = [e for e in effects if e.name.startswith("push_")]
    (free,) = [e for e in effects if e.name == "free_joints"]
    assert SLOTS == 4 and len(pushes) == 5
    crowded = model
    for e in pushes:
        crowded = crowded.with_user_effect(e)
    with pytest.raises(EffectError, match="'push_4': more than 4 effects plug into the force seam"):
        simulate(LandingConditions(), crowded)
    c = LandingConditions(slope_deg=10.0, speed=2.0)
    base = simulate(c, model, full_horizon=False).result
    loose = simulate(c, model.with_user_effect(free), full_horizon=False).result
    assert loose.compression_down > base.compression_down + 0.2
