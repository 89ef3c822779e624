"""Map figures: every colour in a legend, one meaning per colour, no white "slid" cells, no
colliding labels. The maps are built by hand (no simulation) so each case is known."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.colors import to_hex, to_rgba

from slopelander.envelope import plots
from slopelander.envelope.axes import MapAxes
from slopelander.envelope.maps import LandingMap
from slopelander.model import OUTCOME_COLORS, Outcome

AXES = MapAxes.build(10.0, 0.5, slope_max=60.0, speed_min=0.5, speed_max=3.0)  # 7 x 6


def _map(kind: str, outcome: np.ndarray, **meta) -> LandingMap:
    n_s, n_v = AXES.shape
    rng = np.random.default_rng(len(kind))
    levels = [0.56, 1.1, 1.7, 2.3]
    fields = {
        "outcome": outcome.astype(float),
        "tau_up": rng.choice(levels, (n_s, n_v)),
        "tau_down": rng.choice(levels, (n_s, n_v)),
        "angle_up_deg": np.linspace(37.5, 20, n_s)[:, None] * np.ones(n_v),
        "angle_down_deg": np.full((n_s, n_v), 37.5),
    }
    meta = {
        "description": "hand-made",
        "model": {"source": None, "effects": []},
        "strategy": {"torques": "levels", "levels": levels, "angle": "linear"},
        **meta,
    }
    return LandingMap(kind, AXES, fields, meta)


def _every_outcome() -> np.ndarray:
    n_s, n_v = AXES.shape
    return (np.arange(n_s)[:, None] + np.zeros(n_v, int)) % len(Outcome)


def _mesh_colours(ax) -> set[str]:
    ax.figure.canvas.draw()
    return {to_hex(c) for coll in ax.collections for c in coll.get_facecolors()}


def _legend_colours(ax) -> set[str]:
    legend = ax.get_legend()
    return {to_hex(h.get_facecolor()) for h in legend.legend_handles}


def test_slid_is_not_white_and_every_outcome_colour_is_distinct() -> None:
    colours = [to_hex(c) for c in OUTCOME_COLORS.values()]
    assert "#ffffff" not in colours
    assert len(set(colours)) == len(colours) == len(Outcome)


def test_the_modal_outcome_takes_the_worse_on_a_tie_and_flags_disagreement() -> None:
    base = np.zeros(AXES.shape, int)
    a, b, c = base.copy(), base.copy(), base.copy()
    a[0, 0], b[0, 0], c[0, 0] = Outcome.IDEAL, Outcome.FLIP, Outcome.FLIP  # 2 of 3 flip
    a[1, 1], b[1, 1], c[1, 1] = Outcome.IDEAL, Outcome.SLID, Outcome.UNDER_USED  # three-way tie
    maps = [_map("s", x) for x in (a, b, c)]
    modal, disagree = plots.modal_outcome(maps)
    assert modal[0, 0] == Outcome.FLIP and modal[1, 1] == Outcome.SLID
    assert disagree.sum() == 2 and disagree[0, 0] and disagree[1, 1]
    assert (modal[~disagree] == Outcome.IDEAL).all()


def test_the_uncertainty_map_uses_only_colours_its_legend_names(tmp_path: Path) -> None:
    a = _every_outcome()
    maps = [_map(f"set{i}", x) for i, x in enumerate((a, np.roll(a, 2, axis=0), a))]
    captured = {}
    real_save = plots._save

    def keep(fig, path):
        captured["fig"] = fig
        fig.canvas.draw()
        captured["ax"] = fig.axes[0]
        captured["mesh"] = _mesh_colours(fig.axes[0])
        captured["legend"] = _legend_colours(fig.axes[0])
        labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        captured["labels"] = labels
        return real_save(fig, path)

    plots._save = keep
    try:
        plots.plot_uncertainty(maps, tmp_path / "u.png")
    finally:
        plots._save = real_save
    assert captured["mesh"] <= captured["legend"]
    assert captured["mesh"] <= {to_hex(c) for c in OUTCOME_COLORS.values()}
    assert plots.DISAGREE_LABEL in captured["labels"]
    assert any(p.get_hatch() for p in captured["ax"].patches)  # the sets disagree somewhere


@pytest.mark.parametrize("figure", ["presets", "robustness"])
def test_cells_without_a_landing_are_hatched_and_named_not_grey(figure: str, tmp_path: Path) -> None:
    outcome = _every_outcome()
    m = _map("asymmetric", outcome)
    if figure == "robustness":
        landed = m.landed()
        m.fields.update(success_rate=np.where(landed, 0.7, 0.0), nominal=landed.astype(float))
        m.meta.update(pitch_range_deg=10, pitch_rate_range_dps=60, draws_per_cell=2, seed=0, overall=0.7)
    figs: list = []
    real_save = plots._save

    def keep(fig, path):
        fig.canvas.draw()
        figs.append(fig)
        return real_save(fig, path)

    plots._save = keep
    try:
        (plots.plot_preset_maps if figure == "presets" else plots.plot_robustness)(m, tmp_path / "p.png")
    finally:
        plots._save = real_save
    fig = figs[0]
    texts = [
        t.get_text()
        for lg in [*fig.legends, *(a.get_legend() for a in fig.axes)]
        if lg
        for t in lg.get_texts()
    ]
    assert plots.NO_LANDING_LABEL in texts
    joint_grey = to_rgba(OUTCOME_COLORS[Outcome.JOINT_TOUCH])
    for ax in fig.axes:
        assert to_rgba(ax.get_facecolor()) != joint_grey
        hatched = [p for p in ax.patches if p.get_hatch()]
        if ax.collections and ax.get_title() and "outcome" not in ax.get_title():
            assert hatched, ax.get_title()


def test_colourbar_labels_do_not_collide_with_the_next_panel(tmp_path: Path) -> None:
    m = _map("angle", _every_outcome())
    figs: list = []
    real_save = plots._save

    def keep(fig, path):
        figs.append(fig)
        fig.savefig(path, dpi=110, bbox_inches="tight")  # lay out as the file is
        return Path(path)

    plots._save = keep
    try:
        plots.plot_preset_maps(m, tmp_path / "p.png")
    finally:
        plots._save = real_save
    fig = figs[0]
    renderer = fig.canvas.get_renderer()
    colourbars = [a for a in fig.axes if a.get_label() == "<colorbar>"]
    panels = [a for a in fig.axes if a.get_label() != "<colorbar>"]
    assert len(colourbars) == 3 and len(panels) == 4
    for cb in colourbars:
        label = cb.yaxis.label.get_window_extent(renderer)
        ticks = [t.get_window_extent(renderer) for t in cb.get_yticklabels() if t.get_text()]
        for ax in panels:
            others = [ax.yaxis.label.get_window_extent(renderer)] if ax.get_ylabel() else []
            others += [t.get_window_extent(renderer) for t in ax.get_yticklabels() if t.get_text()]
            for box in [label, *ticks]:
                assert not any(box.overlaps(o) for o in others), (cb.get_ylabel(), ax.get_title())
    plt.close(fig)
