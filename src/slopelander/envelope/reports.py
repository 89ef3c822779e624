"""One function per map of the paper's Sec. V: compute it, write PNG + NPZ + CSV, summarise.

These are what ``slopelander map KIND`` calls; each returns the numbers it printed, so a script
(or ``docs/reproduction.md``) gets the same figures as the command line.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from slopelander.envelope import plots
from slopelander.envelope.axes import MapAxes
from slopelander.envelope.maps import LandingMap, envelope_area, summary
from slopelander.envelope.presets import STRATEGIES, Strategy, choose_presets
from slopelander.envelope.robustness import robustness_map
from slopelander.envelope.uncertainty import (
    parameter_sets,
    success_fraction,
    uncertainty_maps,
    write_parameter_sets,
)
from slopelander.model import Model

MAP_KINDS = ("symmetric", "asymmetric", "angle", "rvt", "rigid", "uncertainty", "robustness")


def _strategy(name: str, refine: bool, optimal_angle: bool, thrust_end: dict | None = None) -> Strategy:
    return STRATEGIES[name].with_options(refine=refine, optimal_angle=optimal_angle, **(thrust_end or {}))


def _write(m: LandingMap, out: Path, stem: str | None = None, *, presets_figure: bool = False) -> dict:
    stem = stem or m.kind
    npz, csv_path = m.save(out, stem)
    png = (plots.plot_preset_maps if presets_figure else plots.plot_outcome_map)(m, out / f"{stem}.png")
    return {"png": str(png), "npz": str(npz), "csv": str(csv_path), **summary(m)}


def _finish(out: Path, kind: str, result: dict[str, Any]) -> dict[str, Any]:
    path = out / f"{kind}_summary.json"
    path.write_text(json.dumps(result, indent=2, default=float) + "\n")
    result["summary_file"] = str(path)
    return result


def make_map(
    kind: str,
    out: str | Path,
    *,
    model: Model | None = None,
    axes: MapAxes | None = None,
    refine: bool = False,
    optimal_angle: bool = False,
    thrust_end: dict | None = None,
    config: str = "rvt",
    sets: int = 3,
    seed: int = 0,
    draws: int = 10,
    client=None,
    progress: bool | None = None,
) -> dict[str, Any]:
    """Compute the map ``kind`` (one of :data:`MAP_KINDS`) into directory ``out``.

    ``config`` names the presets that the uncertainty and robustness maps fly (a key of
    :data:`~slopelander.envelope.presets.STRATEGIES`); ``sets`` and ``seed`` shape the
    parameter sets; ``draws`` is the robustness draws per cell. ``thrust_end``
    (``reverse_duration``, ``reverse_ramp``: s) ends the reverse thrust of the strategies that
    have one; without it the thrust is held to the model's horizon.
    """
    if kind not in MAP_KINDS:
        raise ValueError(f"unknown map {kind!r}; known: {', '.join(MAP_KINDS)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    model = model or Model.default()
    axes = axes or MapAxes.build()
    kw = {"client": client, "progress": progress}
    result: dict[str, Any] = {
        "kind": kind,
        "grid": [len(axes.slopes), len(axes.speeds)],
        "slope_step_deg": axes.slope_step,
        "speed_step_mps": axes.speed_step,
    }

    if kind in ("symmetric", "asymmetric", "angle", "rvt"):
        m = choose_presets(model, axes, _strategy(kind, refine, optimal_angle, thrust_end), **kw)
        result.update(
            _write(m, out, presets_figure=kind != "symmetric"),
            description=m.meta["description"],
            landings=m.meta["landings_simulated"],
        )
        if kind != "symmetric":
            plots.plot_outcome_map(m, out / f"{kind}_outcome.png")
        return _finish(out, kind, result)

    if kind == "rigid":
        maps = {
            "rigid gear (LG)": choose_presets(model, axes, "rigid", **kw),
            "rigid gear + RVT (LG+RVT)": choose_presets(
                model, axes, _strategy("rigid_rvt", False, False, thrust_end), **kw
            ),
            "FSA (asym. torques + uphill angle)": choose_presets(
                model, axes, _strategy("angle", refine, optimal_angle, thrust_end), **kw
            ),
            "FSA + RVT": choose_presets(
                model, axes, _strategy("rvt", refine, optimal_angle, thrust_end), **kw
            ),
        }
        for label, m in maps.items():
            result[label] = _write(m, out, f"envelope_{m.kind}")
        areas = [envelope_area(m) for m in maps.values()]
        rigid_area, fsa_rvt_area = areas[0], areas[3]
        result["area_ratio_fsa_rvt_vs_rigid"] = fsa_rvt_area / rigid_area if rigid_area else math.inf
        result["area_ratio_fsa_rvt_vs_rigid_rvt"] = fsa_rvt_area / areas[1] if areas[1] else math.inf
        png = plots.plot_envelopes(
            maps, out / "envelopes.png", static_friction=model.params["friction_static"]
        )
        result["png"] = str(png)
        return _finish(out, kind, result)

    if kind == "uncertainty":
        params = parameter_sets(model.params, sets, seed)
        result["parameter_files"] = [str(p) for p in write_parameter_sets(params, out)]
        nominal, maps = uncertainty_maps(
            model, axes, _strategy(config, refine, optimal_angle, thrust_end), params, **kw
        )
        result["nominal"] = _write(nominal, out, f"uncertainty_{config}_nominal")
        for i, m in enumerate(maps, 1):
            result[f"set{i}"] = {k: v for k, v in _write(m, out).items()}
        frac = success_fraction(maps)
        result["cells_landed_by_all_sets"] = int((frac == 1).sum())
        result["cells_landed_by_some_sets"] = int(((frac > 0) & (frac < 1)).sum())
        result["png"] = str(
            plots.plot_uncertainty(maps, out / f"uncertainty_{config}.png", title=f"uncertainty ({config})")
        )
        return _finish(out, kind, result)

    # robustness
    presets = choose_presets(model, axes, _strategy(config, refine, optimal_angle, thrust_end), **kw)
    r = robustness_map(presets, model, draws=draws, seed=seed, **kw)
    npz, csv_path = r.save(out, "robustness")
    png = plots.plot_robustness(r, out / "robustness.png")
    result.update(
        png=str(png),
        npz=str(npz),
        csv=str(csv_path),
        presets=presets.kind,
        description=presets.meta["description"],
        overall_success_rate=r.meta["overall"],
        nominal_cells=r.meta["nominal_cells"],
        draws_per_cell=draws,
        seed=seed,
        landings=r.meta["landings"],
    )
    return _finish(out, kind, result)
