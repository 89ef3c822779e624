"""The compare report: Markdown with one Fig.-7-style PNG per drop (phases shaded, worst
windows marked), so a user sees where the model fails before asking why."""

from __future__ import annotations

import math
from pathlib import Path

from slopelander.ident.compare import Comparison, DropComparison, Window
from slopelander.ident.phases import PHASES, phase_spans
from slopelander.ident.recording import STATES

PHASE_COLORS = ("#ffffff", "#fde0dd", "#deebf7", "#e5f5e0", "#f0f0f0", "#fff2cc")
_LABELS = ("x (m)", "z (m)", "pitch (deg)", "x rate (m/s)", "z rate (m/s)", "pitch rate (deg/s)")
_SCALE = (1.0, 1.0, 180 / math.pi, 1.0, 1.0, 180 / math.pi)


def plot_drop(d: DropComparison, windows: list[Window], path: Path) -> Path:
    """Measured vs simulated states of one drop, phases shaded, worst windows outlined."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 2, figsize=(10, 7.5), sharex=True)
    spans = phase_spans(d.t, d.labels)
    for i, ax in enumerate(axes.T.ravel()):
        for p, a, b in spans:
            ax.axvspan(a, b, color=PHASE_COLORS[p], lw=0)
        for w in windows:
            if w.drop == d.name:
                ax.axvspan(w.start, w.end, fill=False, edgecolor="red", lw=1.2, hatch="//", alpha=0.6)
        ax.plot(d.t, d.measured[:, i] * _SCALE[i], ".", ms=2.5, color="k", label="measured")
        ax.plot(d.t, d.simulated[:, i] * _SCALE[i], "-", lw=1.3, color="C0", label="simulated")
        ax.set_ylabel(_LABELS[i])
        ax.set_title(f"{STATES[i]}: NRMSE {d.per_state[i]:.3f}", fontsize=9)
    for ax in axes[-1]:
        ax.set_xlabel("time from first contact (s)")
    handles = [matplotlib.patches.Patch(color=c, label=p) for p, c in zip(PHASES, PHASE_COLORS, strict=True)]
    handles += [matplotlib.patches.Patch(fill=False, edgecolor="red", hatch="//", label="worst window")]
    axes[0, 0].legend(loc="best", fontsize=7)
    fig.legend(handles=handles, loc="lower center", ncol=6, fontsize=8, frameon=False)
    obs = d.observed.label if d.observed is not None else "not recorded"
    pred = d.predicted.label if d.predicted is not None else "-"
    fig.suptitle(f"{d.name}: NRMSE {d.nrmse:.3f}; outcome observed {obs}, predicted {pred}")
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def write_report(
    c: Comparison, folder: str | Path, title: str = "Model vs measured drops", model_note: str = ""
) -> Path:
    """``report.md`` plus ``<drop>.png`` per drop in ``folder``; returns the Markdown path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    windows = c.worst_windows(5)
    lines = [f"# {title}", ""]
    if model_note:
        lines += [model_note, ""]
    ok, known = c.outcome_matches()
    lines += [
        f"Overall NRMSE **{c.nrmse:.4f}** (angular states x2) over {len(c.drops)} drops; "
        f"predicted outcome matches the observed one in {ok} of {known} drops.",
        "",
        "## NRMSE per state",
        "",
        "| " + " | ".join(STATES) + " |",
        "|" + "---:|" * len(STATES),
        "| " + " | ".join(f"{v:.4f}" for v in c.per_state) + " |",
        "",
        "## Per drop",
        "",
        "| drop | slope (deg) | speed (m/s) | NRMSE | observed | predicted | match |",
        "|---|---:|---:|---:|---|---|---|",
    ]
    for d in c.drops:
        obs = d.observed.label if d.observed is not None else "-"
        pred = d.predicted.label if d.predicted is not None else "-"
        match = "-" if d.outcome_match is None else ("yes" if d.outcome_match else "**no**")
        cs = d.conditions
        lines.append(
            f"| {d.name} | {cs.slope_deg:.1f} | {cs.speed:.2f} | {d.nrmse:.4f} | {obs} | {pred} | {match} |"
        )
    phase = c.per_phase()
    share = c.phase_share()
    lines += ["", "## Where it fails", "", "| phase | NRMSE | share of the residual |", "|---|---:|---:|"]
    for p in PHASES:
        if p in phase:
            lines.append(f"| {p} | {phase[p]:.4f} | {100 * share[p]:.1f} % |")
    ss = c.state_share()
    lines += [
        "",
        "Share of the weighted squared residual per state: "
        + ", ".join(f"{k} {100 * v:.0f} %" for k, v in ss.items())
        + ".",
        "",
        f"Worst {WINDOW_TEXT} windows:",
        "",
        "| drop | from (s) | to (s) | phase | state | share |",
        "|---|---:|---:|---|---|---:|",
    ]
    for w in windows:
        lines.append(
            f"| {w.drop} | {w.start:.3f} | {w.end:.3f} | {w.phase} | {w.state} | {100 * w.share:.1f} % |"
        )
    lines += ["", "## Drops", ""]
    for d in c.drops:
        png = plot_drop(d, windows, folder / f"{d.name}.png")
        lines += [f"![{d.name}]({png.name})", ""]
    out = folder / "report.md"
    out.write_text("\n".join(lines) + "\n")
    return out


WINDOW_TEXT = "50 ms"
