"""The planar landing model of Bass, Tunney and Lussier Desbiens (RA-L 2022).

Pure physics: no files beyond the parameter set, no plotting, no MAVLink. Names are imported on
first use, so validating a parameter file does not load numba.

>>> from slopelander.model import LandingConditions, simulate
>>> simulate(LandingConditions(slope_deg=20, speed=2.0)).result.outcome   # doctest: +SKIP
<Outcome.IDEAL: 0>
"""

_EXPORTS = {
    "CONDITION_DTYPE": "slopelander.model.conditions",
    "CONDITION_FIELDS": "slopelander.model.conditions",
    "ConditionError": "slopelander.model.conditions",
    "LandingConditions": "slopelander.model.conditions",
    "condition_grid": "slopelander.model.conditions",
    "default_conditions": "slopelander.model.conditions",
    "conditions_array": "slopelander.model.conditions",
    "BUILTIN_EFFECTS": "slopelander.model.effects",
    "EffectError": "slopelander.model.effects",
    "EffectParameter": "slopelander.model.effects",
    "EffectState": "slopelander.model.effects",
    "UserEffect": "slopelander.model.effects",
    "load_effects": "slopelander.model.effects",
    "DEFAULT_DT": "slopelander.model.landing",
    "LandingResult": "slopelander.model.landing",
    "Model": "slopelander.model.landing",
    "Trajectory": "slopelander.model.landing",
    "simulate": "slopelander.model.landing",
    "simulate_batch": "slopelander.model.landing",
    "OUTCOME_COLORS": "slopelander.model.outcome",
    "OUTCOME_NAMES": "slopelander.model.outcome",
    "outcome_names": "slopelander.model.outcome",
    "RESULT_DTYPE": "slopelander.model.outcome",
    "RESULT_FIELDS": "slopelander.model.outcome",
    "Outcome": "slopelander.model.outcome",
    "OutcomeCriteria": "slopelander.model.outcome",
    "ModelParams": "slopelander.model.parameters",
    "ParameterError": "slopelander.model.parameters",
}


def __getattr__(name: str):
    # imported on first use: checking a parameter file or an effect list needs no numba
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


__all__ = [
    "BUILTIN_EFFECTS",
    "CONDITION_DTYPE",
    "CONDITION_FIELDS",
    "DEFAULT_DT",
    "OUTCOME_COLORS",
    "OUTCOME_NAMES",
    "RESULT_DTYPE",
    "RESULT_FIELDS",
    "ConditionError",
    "EffectError",
    "EffectParameter",
    "EffectState",
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
    "default_conditions",
    "load_effects",
    "outcome_names",
    "simulate",
    "simulate_batch",
]
