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


STATE_MISTAKES = textwrap.dedent(
    """
    import numba
    from slopelander.model.effects import EffectState, UserEffect


    @numba.njit
    def keep(t, st, ctx, up, h):
        return


    @numba.njit
    def one_number(t, st, ctx, up, leg, angle):
        return 0.01


    @numba.njit
    def pad(t, st, ctx, up, leg, angle):
        return 0.01, 0.0


    A = UserEffect("mem_a", "memory", update=keep, states={"level": EffectState(0.0, "1")})
    B = UserEffect("mem_b", "memory too", update=keep, states={"level": (1.0, "1")})
    BIG = UserEffect("mem_big", "much memory", update=keep, states={f"s{i}": (0.0, "1") for i in range(5)})
    BIG2 = UserEffect("mem_big2", "more memory", update=keep, states={f"t{i}": (0.0, "1") for i in range(5)})
    FLAT = UserEffect("flat_pad", "one number", contact_geometry=one_number)
    PAD_A = UserEffect("pad_a", "a pad", contact_geometry=pad)
    PAD_B = UserEffect("pad_b", "another pad", contact_geometry=pad)
    EFFECTS = [A, B, BIG, BIG2, FLAT, PAD_A, PAD_B]
    """
)


def test_states_and_contact_geometry_mistakes_are_named(tmp_path, model):
    """Memory and contact-geometry declarations are checked like parameters: names unique over
    the model, initial values numbers, at most 8 states in a model, one contact geometry, and
    a geometry law must return (reach, along)."""
    import numba

    from slopelander.model.effects import EffectState, UserEffect

    path = tmp_path / "states.py"
    path.write_text(STATE_MISTAKES)
    a, b, big, big2, flat, pad_a, pad_b = load_effects(path)
    with pytest.raises(EffectError, match="'mem_a' and 'mem_b' both declare 'level'"):
        model.with_user_effect(a).with_user_effect(b)
    with pytest.raises(EffectError, match="declare 10 states together; a model holds 8"):
        model.with_user_effect(big).with_user_effect(big2)
    with pytest.raises(EffectError, match="'pad_a', 'pad_b' each set the contact geometry"):
        model.with_user_effect(pad_a).with_user_effect(pad_b)
    with pytest.raises(EffectError, match=r"'flat_pad'.*contact_geometry it must return a tuple \(reach m"):
        simulate(LandingConditions(), model.with_user_effect(flat))

    @numba.njit
    def keep(t, st, ctx, up, h):
        return

    with pytest.raises(EffectError, match="state 'x': initial value 'one' is not a number"):
        UserEffect("bad", "", update=keep, states={"x": EffectState("one", "1")})
    with pytest.raises(EffectError, match="'gain' is both a parameter and a state"):
        UserEffect("bad", "", update=keep, parameters={"gain": (0.5, "1")}, states={"gain": (0.0, "1")})
    with pytest.raises(EffectError, match="state 'ground_damping' has the name of a built-in parameter"):
        UserEffect("bad", "", update=keep, states={"ground_damping": (0.0, "1")})
