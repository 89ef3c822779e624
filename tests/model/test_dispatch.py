"""The integrator called through its cached overload gives what numba's own dispatch gives."""

from dataclasses import astuple

import numpy as np
from numba import njit

from slopelander.model import LandingConditions, Model, dispatch, simulate


@njit
def _first(a):
    return a[0, 1]


def test_a_landing_through_the_cached_overload_equals_numbas_dispatch():
    m = Model.default()
    c = LandingConditions(slope_deg=30.0, speed=1.5)
    first = simulate(c, m)
    again = simulate(c, m)  # the second call goes straight to the compiled entry point
    km, _ = m.kernel()
    assert any(key[0] == id(km.run_landing) for key in dispatch._ENTRIES)
    np.testing.assert_array_equal(first.states, again.states)
    assert first.result == again.result


def test_arguments_numba_types_differently_get_their_own_overload():
    c = np.arange(6.0).reshape(2, 3)
    f = np.asfortranarray(c)
    assert dispatch._key((c,)) != dispatch._key((f,))
    ro = c.copy()
    ro.flags.writeable = False
    assert dispatch._key((c,)) != dispatch._key((ro,))
    assert dispatch._key((1,)) != dispatch._key((1.0,))
    for a in (c, f, ro, c[:, ::2]):
        assert dispatch.call(_first, a) == a[0, 1]
        assert dispatch.call(_first, a) == a[0, 1]  # through the cached entry
    assert len({k for k in dispatch._ENTRIES if k[0] == id(_first)}) == 4


def test_the_stepper_with_its_seam_table_boxed_steps_as_the_kernel_with_the_tuple():
    from pathlib import Path

    from slopelander.model import kernel as k
    from slopelander.model import load_effects
    from slopelander.model.stepper import Stepper

    examples = Path(__file__).resolve().parents[2] / "docs" / "examples"
    model = Model.default().with_user_effect(load_effects(examples / "effect_joint_torque.py")[0])
    boxed, plain = Stepper(model, slope_deg=20.0), Stepper(model, slope_deg=20.0)
    assert boxed._box is not None and plain._sx is not None
    for i in range(600):  # a fall onto the roof: contact, friction, the legs' joints
        u = 0.3 if i < 300 else 0.0
        boxed.step(1 / 1200, u, u)
        n = max(1, int(np.ceil((1 / 1200) / plain.model.dt - 1e-9)))
        k.advance(plain._p, plain._fl, plain.ctx, plain.st, (1 / 1200) / n, n, u, u, plain._ws, plain._sx)
    assert boxed.in_contact()
    np.testing.assert_array_equal(boxed.st, plain.st)


def test_a_model_without_user_effects_passes_no_seam_table_and_steps_as_one_with_a_neutral_law():
    """The built-in model runs the integrator compiled without seams (its table is None); a
    user law that returns the torque it is given changes no bit of a landing."""
    from pathlib import Path

    from slopelander.model import load_effects

    examples = Path(__file__).resolve().parents[2] / "docs" / "examples"
    neutral = load_effects(examples / "effect_joint_torque.py")[0].with_values(joint_viscous_gain=0.0)
    m = Model.default()
    assert m.kernel()[1] is None
    with_law = m.with_user_effect(neutral)
    assert with_law.kernel()[1] is not None
    c = LandingConditions(slope_deg=35.0, speed=2.5, tau_up=1.1, tau_down=1.1)
    a, b = simulate(c, m), simulate(c, with_law)
    np.testing.assert_array_equal(a.raw, b.raw)
    np.testing.assert_equal(astuple(a.result), astuple(b.result))  # NaN settle times equal
