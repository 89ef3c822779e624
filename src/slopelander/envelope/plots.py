"""Figures of the landing maps as PNG files, in the paper's colour code (Sec. V-A, Fig. 8).

Every figure puts the surface slope (deg) on x and the vertical impact speed (m/s) on y, as the
paper does, says which model and which presets it shows, and carries a legend for its colours.
Every colour and pattern means one thing in every figure: the outcome colours (with "slid" light
purple, not the paper's white, so no cell looks like missing data), grey hatching for cells whose
level landing fails with every candidate preset, dots for cells where parameter sets disagree.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.patches import Patch, Rectangle

from slopelander.envelope.maps import LandingMap, envelope_area
from slopelander.model import OUTCOME_COLORS, Outcome

_CODES = list(Outcome)
OUTCOME_CMAP = ListedColormap([OUTCOME_COLORS[o] for o in _CODES])
OUTCOME_NORM = BoundaryNorm(np.arange(len(_CODES) + 1) - 0.5, len(_CODES))


NO_LANDING_LABEL = "no level landing (no candidate preset lands)"
DISAGREE_LABEL = "parameter sets disagree (colour: the most common outcome)"
_HATCH = {"facecolor": "white", "edgecolor": "#8a8a8a", "hatch": "////", "linewidth": 0}


def no_landing_handle() -> Patch:
    return Patch(**{**_HATCH, "linewidth": 0.5}, label=NO_LANDING_LABEL)


def _hatched_background(ax, m: LandingMap) -> None:
    """Grey hatching wherever a masked panel shows nothing: the cells no preset lands."""
    s, v = _edges(m.axes.slopes), _edges(m.axes.speeds)
    ax.add_patch(Rectangle((s[0], v[0]), s[-1] - s[0], v[-1] - v[0], zorder=0, **_HATCH))


def _edges(v: np.ndarray) -> np.ndarray:
    step = v[1] - v[0] if v.size > 1 else 1.0
    return np.concatenate([v - step / 2, [v[-1] + step / 2]])


def _model_line(m: LandingMap) -> str:
    model = m.meta.get("model", {})
    src = Path(str(model.get("source") or "default")).name
    effects = model.get("effects", [])
    return f"model: {src}; effects: {', '.join(effects) if effects else 'none'}"


def _axes_labels(ax, y: bool = True) -> None:
    ax.set_xlabel("surface slope (deg)")
    if y:
        ax.set_ylabel("vertical impact speed (m/s)")


def outcome_legend(ax, loc: str = "upper left", extra: tuple[Patch, ...] = ()) -> None:
    handles = [
        Patch(facecolor=OUTCOME_COLORS[o], edgecolor="black", linewidth=0.5, label=o.label) for o in _CODES
    ]
    ax.legend(
        handles=[*handles, *extra],
        loc=loc,
        bbox_to_anchor=(1.01, 1.0),
        fontsize=8,
        title="outcome",
        title_fontsize=8,
        frameon=False,
    )


def _outcome_panel(ax, m: LandingMap, outcome: np.ndarray | None = None, y: bool = True) -> None:
    codes = m.outcome if outcome is None else outcome
    ax.pcolormesh(
        _edges(m.axes.slopes),
        _edges(m.axes.speeds),
        codes.T,
        cmap=OUTCOME_CMAP,
        norm=OUTCOME_NORM,
        edgecolors="none",
    )
    _axes_labels(ax, y)


def _save(fig, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def plot_outcome_map(m: LandingMap, path: str | Path, title: str | None = None) -> Path:
    """Fig. 8 / Fig. 10 style: the outcome of every cell."""
    fig, ax = plt.subplots(figsize=(8.5, 4.8))
    _outcome_panel(ax, m)
    outcome_legend(ax)
    ax.set_title(f"{title or m.kind}: {m.meta.get('description', '')}\n{_model_line(m)}", fontsize=9)
    return _save(fig, path)


def plot_preset_maps(m: LandingMap, path: str | Path, title: str | None = None) -> Path:
    """Fig. 9 style: chosen uphill and downhill torques (and uphill angle), plus the outcome."""
    strategy = m.meta.get("strategy", {})
    panels = [("tau_up", "uphill torque tau_C", "N*m"), ("tau_down", "downhill torque tau_D", "N*m")]
    if strategy.get("angle") in ("linear", "optimal"):
        panels.append(("angle_up_deg", "uphill leg angle q_C", "deg"))
    fig, axes = plt.subplots(
        1, len(panels) + 1, figsize=(5.0 * (len(panels) + 1), 4.6), constrained_layout=True
    )
    failed = ~m.landed()
    for n, (ax, (name, label, unit)) in enumerate(zip(axes, panels, strict=False)):
        v = np.ma.masked_array(m.fields[name], mask=failed)
        levels = np.unique(np.round(m.fields[name][~failed], 4)) if (~failed).any() else np.array([0.0])
        if strategy.get("torques") == "levels" and name.startswith("tau") and levels.size <= 8:
            all_levels = np.asarray(strategy.get("levels", levels), float)
            cmap = plt.get_cmap("viridis", all_levels.size)
            bounds = np.concatenate(
                [[all_levels[0] - 0.3], (all_levels[1:] + all_levels[:-1]) / 2, [all_levels[-1] + 0.3]]
            )
            norm = BoundaryNorm(bounds, all_levels.size)
            im = ax.pcolormesh(_edges(m.axes.slopes), _edges(m.axes.speeds), v.T, cmap=cmap, norm=norm)
            cb = fig.colorbar(im, ax=ax, ticks=all_levels)
        else:
            im = ax.pcolormesh(_edges(m.axes.slopes), _edges(m.axes.speeds), v.T, cmap="viridis")
            cb = fig.colorbar(im, ax=ax)
        cb.set_label(unit)  # the panel title names the quantity: a long label collides
        _hatched_background(ax, m)
        ax.set_title(f"{label} ({unit})", fontsize=9)
        _axes_labels(ax, y=n == 0)
    _outcome_panel(axes[-1], m, y=False)
    axes[-1].set_title("outcome with the chosen presets", fontsize=9)
    outcome_legend(axes[-1])
    fig.legend(handles=[no_landing_handle()], loc="outside lower left", fontsize=8, frameon=False)
    fig.suptitle(f"{title or m.kind}: {m.meta.get('description', '')}\n{_model_line(m)}", fontsize=10)
    return _save(fig, path)


def plot_envelopes(
    maps: dict[str, LandingMap],
    path: str | Path,
    *,
    static_friction: float | None = None,
    title: str = "Landing envelopes: ideal (green) landings only, as the paper's Fig. 11",
) -> Path:
    """Fig. 11: the green (ideal) zone of several maps side by side, each with its area."""
    n = len(maps)
    cols = 2 if n > 1 else 1
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(
        rows,
        cols,
        figsize=(6.0 * cols, 3.9 * rows),
        squeeze=False,
        constrained_layout=True,
        sharex=True,
        sharey=True,
    )
    green = ListedColormap(["#ffffff", OUTCOME_COLORS[Outcome.IDEAL]])
    limit = math.degrees(math.atan(static_friction)) if static_friction else None
    for ax, (label, m) in zip(axes.ravel(), maps.items(), strict=False):
        ax.pcolormesh(
            _edges(m.axes.slopes),
            _edges(m.axes.speeds),
            m.ideal().astype(float).T,
            cmap=green,
            vmin=0,
            vmax=1,
            edgecolors="none",
        )
        if limit is not None:
            ax.axvline(limit, color="black", linestyle=":", linewidth=1.2)
        ax.set_title(f"{label}\narea {envelope_area(m):.1f} deg*m/s", fontsize=9)
        _axes_labels(ax)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    handles = [
        Patch(
            facecolor=OUTCOME_COLORS[Outcome.IDEAL], edgecolor="black", linewidth=0.5, label="ideal landing"
        ),
        Patch(facecolor="#ffffff", edgecolor="black", linewidth=0.5, label="not ideal (any other outcome)"),
    ]
    if limit is not None:
        handles.append(
            plt.Line2D(
                [],
                [],
                color="black",
                linestyle=":",
                label=f"static friction limit atan(mu_s = {static_friction:g}) = {limit:.0f} deg",
            )
        )
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=8, frameon=False)
    src = Path(str(next(iter(maps.values())).meta.get("model", {}).get("source") or "default")).name
    fig.suptitle(
        f"{title}\nmodel: {src}; rigid gear = the same vehicle with its joints locked, on stiff "
        "rebounding skids, damaged above its foot-load limit (effect rigid_gear)",
        fontsize=10,
    )
    return _save(fig, path)


def modal_outcome(maps: list[LandingMap]) -> tuple[np.ndarray, np.ndarray]:
    """Per cell, the outcome most parameter sets give (a tie goes to the worse outcome), and
    whether the sets disagree."""
    codes = np.stack([m.outcome for m in maps])  # (sets, slopes, speeds)
    counts = np.stack([(codes == o).sum(axis=0) for o in _CODES])  # (outcomes, slopes, speeds)
    best = counts.max(axis=0)
    # the worst outcome among those with the top count: search from the worst end
    modal = len(_CODES) - 1 - np.argmax((counts == best)[::-1], axis=0)
    disagree = (codes != codes[0]).any(axis=0)
    return modal, disagree


def plot_uncertainty(maps: list[LandingMap], path: str | Path, title: str | None = None) -> Path:
    """The paper's gradient, with only colours the legend names: each cell shows the outcome most
    parameter sets give, dotted where the sets disagree."""
    m0 = maps[0]
    modal, disagree = modal_outcome(maps)
    fig, ax = plt.subplots(figsize=(8.5, 4.8))
    _outcome_panel(ax, m0, modal)
    ds, dv = m0.axes.slope_step, m0.axes.speed_step
    for i, j in np.argwhere(disagree):
        ax.add_patch(
            Rectangle(
                (m0.axes.slopes[i] - ds / 2, m0.axes.speeds[j] - dv / 2),
                ds,
                dv,
                fill=False,
                hatch="...",
                edgecolor="black",
                linewidth=0,
            )
        )
    outcome_legend(
        ax,
        extra=(
            Patch(facecolor="white", edgecolor="black", hatch="...", linewidth=0.5, label=DISAGREE_LABEL),
        ),
    )
    ax.set_title(
        f"{title or m0.kind}: {len(maps)} parameter sets (Table II mean +- sigma), "
        f"{int(disagree.sum())} cells where they disagree\n{m0.meta.get('description', '')}",
        fontsize=9,
    )
    return _save(fig, path)


def plot_robustness(r: LandingMap, path: str | Path) -> Path:
    """Fig. 12 style: success rate per cell under random attitude at impact."""
    fig, ax = plt.subplots(figsize=(8.5, 4.8))
    nominal = r.fields["nominal"] > 0
    rate = np.ma.masked_array(100 * r.fields["success_rate"], mask=~nominal)
    _hatched_background(ax, r)
    im = ax.pcolormesh(_edges(r.axes.slopes), _edges(r.axes.speeds), rate.T, cmap="RdYlGn", vmin=0, vmax=100)
    cb = fig.colorbar(im, ax=ax)
    cb.set_label("landings that succeed (%)")
    _axes_labels(ax)
    ax.legend(
        handles=[no_landing_handle()],
        loc="upper left",
        bbox_to_anchor=(0.0, -0.12),
        fontsize=8,
        frameon=False,
    )
    meta = r.meta
    ax.set_title(
        f"Robustness: pitch +-{meta['pitch_range_deg']:g} deg, pitch rate +-{meta['pitch_rate_range_dps']:g} "
        f"deg/s at impact, {meta['draws_per_cell']} draws per cell (seed {meta['seed']})\n"
        f"presets: {meta.get('description', '')}\n"
        f"overall {100 * meta['overall']:.1f} % over the nominal envelope",
        fontsize=9,
    )
    return _save(fig, path)
