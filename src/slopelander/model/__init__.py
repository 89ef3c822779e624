"""The planar landing model of Bass, Tunney and Lussier Desbiens (RA-L 2022).

Pure physics: no files beyond the parameter set, no plotting, no MAVLink.

>>> from slopelander.model import LandingConditions, simulate
>>> simulate(LandingConditions(slope_deg=20, speed=2.0)).result.outcome   # doctest: +SKIP
<Outcome.IDEAL: 0>
"""

from slopelander.model.conditions import (
    CONDITION_DTYPE,
    CONDITION_FIELDS,
    ConditionError,
    LandingConditions,
    condition_grid,
    conditions_array,
)
from slopelander.model.effects import BUILTIN_EFFECTS, EffectError, UserEffect, load_effects
from slopelander.model.landing import (
    DEFAULT_DT,
    LandingResult,
    Model,
    Trajectory,
    simulate,
    simulate_batch,
)
from slopelander.model.outcome import (
    OUTCOME_COLORS,
    RESULT_DTYPE,
    RESULT_FIELDS,
    Outcome,
    OutcomeCriteria,
)
from slopelander.model.parameters import ModelParams, ParameterError

__all__ = [
    "BUILTIN_EFFECTS",
    "CONDITION_DTYPE",
    "CONDITION_FIELDS",
    "DEFAULT_DT",
    "OUTCOME_COLORS",
    "RESULT_DTYPE",
    "RESULT_FIELDS",
    "ConditionError",
    "EffectError",
    "LandingConditions",
    "LandingResult",
    "Model",
    "ModelParams",
    "Outcome",
    "OutcomeCriteria",
    "ParameterError",
    "Trajectory",
    "UserEffect",
    "condition_grid",
    "conditions_array",
    "load_effects",
    "simulate",
    "simulate_batch",
]
