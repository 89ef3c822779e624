"""Parameter uncertainty: maps from several parameter sets (paper Fig. 8's colour gradient).

The paper flew each map with the three parameter sets of its three genetic-algorithm fits,
which it does not publish; Table II gives only their mean and standard deviation. We stand in
for them with ``n`` sets built so that, for each of the seven identified parameters, the sets'
mean and sample standard deviation equal Table II exactly: the values are mean + sigma * z for
standardised normal quantiles z (for three sets: -1, 0, +1), assigned to the sets in an order
shuffled per parameter with a fixed seed (a Latin design, so no set is "all low").
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.stats import norm

from slopelander.envelope.axes import MapAxes
from slopelander.envelope.maps import LandingMap, fly_presets
from slopelander.envelope.presets import Strategy, choose_presets
from slopelander.model import Model, ModelParams

TABLE_II_SIGMA: dict[str, float] = {
    "flex_stiffness": 0.78,  # k_q, N*m/rad
    "flex_damping": 0.017,  # b_q, N*m*s/rad
    "ground_stiffness": 7.77e3,  # k_g, N/m
    "ground_damping": 72.0,  # b_g, N*s/m
    "friction_kinetic": 0.023,  # mu_k
    "factor_tau": 5.6e-4,  # 1/N
    "factor_mu": 0.02,  # s/m
}
"""Table II's GA standard deviations, by model parameter name."""


def standard_scores(n: int) -> np.ndarray:
    """n values with mean 0 and sample standard deviation 1 (normal quantiles, rescaled)."""
    if n < 2:
        return np.zeros(max(n, 0))
    z = norm.ppf((np.arange(n) + 0.5) / n)
    return (z - z.mean()) / z.std(ddof=1)


def parameter_sets(base: ModelParams, n: int = 3, seed: int = 0) -> list[ModelParams]:
    """``n`` parameter sets around ``base`` with Table II's spread on the identified parameters."""
    if n < 1:
        raise ValueError(f"need at least one parameter set, got {n}")
    rng = np.random.default_rng(seed)
    z = standard_scores(n)
    columns = {name: rng.permutation(z) for name in TABLE_II_SIGMA}
    sets = []
    for i in range(n):
        values = {name: base[name] + TABLE_II_SIGMA[name] * columns[name][i] for name in TABLE_II_SIGMA}
        p = base.with_values(provenance="derived", **values)
        notes = {
            name: f"Table II mean {base[name]:.4g} {columns[name][i]:+.2f} sigma "
            f"(set {i + 1} of {n}, Latin design seed {seed}; stands in for a GA fit)"
            for name in TABLE_II_SIGMA
        }
        p = _with_notes(p, notes)
        sets.append(p)
    return sets


def _with_notes(p: ModelParams, notes: dict[str, str]) -> ModelParams:
    d = p.to_dict()
    for name, note in notes.items():
        d["parameters"][name]["note"] = note
    return ModelParams.from_dict(d, p.source)


def write_parameter_sets(sets: list[ModelParams], directory: str | Path) -> list[Path]:
    """Write each set as a parameter YAML file (``params_set1.yaml``, ...)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, p in enumerate(sets, 1):
        path = directory / f"params_set{i}.yaml"
        p.save(path)
        paths.append(path)
    return paths


def uncertainty_maps(
    model: Model,
    axes: MapAxes,
    strategy: Strategy | str,
    sets: list[ModelParams],
    *,
    client=None,
    progress: bool | None = None,
) -> tuple[LandingMap, list[LandingMap]]:
    """The nominal map of ``strategy`` and the same presets flown by each parameter set.

    Presets are chosen once, with ``model`` (what a lookup table would hold), then flown by
    every set: the spread is what an uncertain model does to a fixed table.
    """
    nominal = choose_presets(model, axes, strategy, client=client, progress=progress)
    maps = []
    for i, p in enumerate(sets, 1):
        m = Model(p, model.effects, model.user_effects, model.dt, model.criteria)
        maps.append(fly_presets(nominal, m, kind=f"{nominal.kind}_set{i}", client=client, progress=progress))
    return nominal, maps


def success_fraction(maps: list[LandingMap], success: str = "landed") -> np.ndarray:
    """Per cell, the fraction of parameter sets whose landing succeeds."""
    return np.mean([m.mask(success) for m in maps], axis=0)
