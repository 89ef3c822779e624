"""One landing as a picture: snapshots on the slope (paper Fig. 7 top) and the six states."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from slopelander.model import OUTCOME_COLORS, Trajectory
from slopelander.model.landing import pitch_margin_text


def _snapshot_indices(tr: Trajectory, n: int = 5) -> list[int]:
    """Impact, then evenly spread through the part of the landing where things happen."""
    t = tr.t
    end = tr.result.settle_time if math.isfinite(tr.result.settle_time) else tr.result.t_end
    end = min(max(end, 0.1), t[-1])
    return sorted({int(np.argmin(np.abs(t - x))) for x in np.linspace(0.0, end, n)})


def landing_title(tr: Trajectory) -> str:
    """What was flown and how it ended; rigid gear names no friction torque (its joints are locked)."""
    c = tr.conditions
    if tr.model.rigid_gear:
        gear = f"rigid gear, legs locked at {c.angle_up_deg:g}°/{c.angle_down_deg:g}°"
    else:
        gear = (
            f"FSA legs, τ up/down {c.tau_up:g}/{c.tau_down:g} N·m, "
            f"legs {c.angle_up_deg:g}°/{c.angle_down_deg:g}°"
        )
    thrust = f", {c.reverse_percent:g} % reverse thrust" if c.reverse_percent else ""
    margin = pitch_margin_text(tr.pitch_margin_deg, tr.model.criteria.flip_pitch_deg)
    outcome = tr.result.outcome.label
    return f"{c.slope_deg:g}° slope, {c.speed:g} m/s impact, {gear}{thrust}\n→  {outcome}, {margin}"


def plot_landing(tr: Trajectory, path: str | Path) -> Path:
    """Write a PNG of the landing to ``path`` and return it."""
    path = Path(path)
    fig = landing_figure(tr)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def landing_figure(tr: Trajectory) -> plt.Figure:
    """Snapshots on the slope over the six states against time."""
    fig = plt.figure(figsize=(12, 8.5), constrained_layout=True)
    grid = fig.add_gridspec(3, 3, height_ratios=[1.5, 1, 1])
    ax = fig.add_subplot(grid[0, :])
    idx = _snapshot_indices(tr)
    a = math.radians(tr.slope_deg)
    xs = []
    cmap = plt.get_cmap("viridis")
    for n, i in enumerate(idx):
        o = tr.outline(i)
        col = cmap(n / max(1, len(idx) - 1))
        r, j, f = o["rotors"], o["joints"], o["feet"]
        ax.plot(r[:, 0], r[:, 1], "-", color=col, lw=3, solid_capstyle="round")
        ax.plot(
            [r[0, 0], j[0, 0], j[1, 0], r[1, 0]], [r[0, 1], j[0, 1], j[1, 1], r[1, 1]], "-", color=col, lw=1.2
        )
        for leg in range(2):
            ax.plot([j[leg, 0], f[leg, 0]], [j[leg, 1], f[leg, 1]], "-", color=col, lw=2)
        ax.plot(*o["centre"], "o", color=col, ms=4)
        ax.annotate(
            f"{1000 * tr.t[i]:.0f} ms",
            o["centre"] + np.array([0.0, 0.06]),
            color=col,
            ha="center",
            fontsize=8,
        )
        xs.extend([r[:, 0].min(), r[:, 0].max(), f[:, 0].min(), f[:, 0].max()])
    lo, hi = min(xs) - 0.15, max(xs) + 0.15
    gx = np.array([lo, hi])
    ax.fill_between(gx, -gx * math.tan(a), -gx * math.tan(a) - 1.0, color="#d9c7a7", zorder=0)
    ax.plot(gx, -gx * math.tan(a), color="#8c6d3f", lw=1.5)
    ax.set_aspect("equal")
    ax.set_xlim(lo, hi)
    zs = -gx * math.tan(a)
    ax.set_ylim(min(zs) - 0.05, max(zs.max(), max(tr.raw[:, 1])) + 0.25)
    ax.set_xlabel("x (m, downhill)")
    ax.set_ylabel("z (m)")
    res = tr.result
    ax.set_title(landing_title(tr), color="black")
    ax.text(
        0.01,
        0.03,
        res.outcome.label,
        transform=ax.transAxes,
        fontsize=11,
        bbox={"facecolor": OUTCOME_COLORS[res.outcome], "edgecolor": "black", "alpha": 0.9},
    )

    s = tr.states
    labels = [
        ("x (m)", s[:, 0]),
        ("z (m)", s[:, 1]),
        ("pitch (deg)", np.degrees(s[:, 2])),
        ("x rate (m/s)", s[:, 3]),
        ("z rate (m/s)", s[:, 4]),
        ("pitch rate (deg/s)", np.degrees(s[:, 5])),
    ]
    for n, (label, y) in enumerate(labels):
        axs = fig.add_subplot(grid[1 + n // 3, n % 3])
        axs.plot(tr.t, y, color="#1f4e79")
        for i in idx:
            axs.axvline(tr.t[i], color="0.85", lw=0.8, zorder=0)
        axs.set_ylabel(label)
        if label == "pitch (deg)":
            flip = tr.model.criteria.flip_pitch_deg
            side = -1.0 if y.min() < -abs(y.max()) else 1.0
            axs.axhline(side * flip, color="#b22222", ls="--", lw=1)
            axs.text(
                tr.t[-1],
                side * flip,
                "flip criterion",
                color="#b22222",
                fontsize=8,
                ha="right",
                va="bottom" if side < 0 else "top",
            )
        axs.grid(alpha=0.3)
        if n >= 3:
            axs.set_xlabel("time since impact (s)")
    return fig
