"""A foot whose grip fades with slip speed: mu = mu_k / (1 + slip_weakening * |v|).

Hidden in the truth of tests/ident/test_diagnose_user_effects.py; the analysed model has to
find it from this file among the built-in candidates.
"""

import numba

from slopelander.model.effects import EffectParameter, UserEffect


@numba.njit
def slip_weakening(t, st, ctx, up, leg, slip_speed, normal_force, mu):
    return mu / (1.0 + up[0] * abs(slip_speed))


EFFECTS = [
    UserEffect(
        "slip_weakening",
        "foot friction falls as the foot slides faster",
        foot_friction=slip_weakening,
        parameters={"slip_weakening": EffectParameter(0.5, "s/m", 0.0, 2.0, "assumed", neutral=0.0)},
    )
]
