"""One landing of a flight log beside the model: pitch, pitch rate and the body's acceleration
against the time from first contact, with the script's moments marked."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

if TYPE_CHECKING:
    from slopelander.ident.flightlog.compare import LandingComparison


def plot_comparison(r: LandingComparison, path: Path) -> Path:
    """Write the PNG of ``r`` to ``path`` and return it."""
    me, mo, ev, c = r.measured, r.model, r.events, r.cond.conditions
    fig, axes = plt.subplots(4, 1, figsize=(10, 10), sharex=True, constrained_layout=True)
    model_kw = {"color": "tab:orange", "lw": 1.6, "ls": "--", "label": "model"}
    log_kw = {"color": "tab:blue", "lw": 1.2, "label": f"log ({r.log.kind})"}
    panels = [
        ("pitch, deg", me.t_att, me.pitch_deg, mo.pitch_deg),
        ("pitch rate, deg/s", me.t_imu, me.gyro_dps[:, 1], mo.pitch_rate_dps),
        ("acceleration forward, m/s²", me.t_imu, me.accel[:, 0], mo.accel[:, 0]),
        ("acceleration down, m/s²", me.t_imu, me.accel[:, 2], mo.accel[:, 1]),
    ]
    moments = [("cut", ev.cut), ("reverse", ev.reverse), ("reverse ends", ev.reverse_left)]
    for ax, (label, t, logged, model) in zip(axes, panels, strict=True):
        ax.plot(t, logged, **log_kw)
        keep = mo.t <= r.span
        ax.plot(mo.t[keep], model[keep], **model_kw)
        ax.set_ylabel(label)
        ax.axvline(0.0, color="k", lw=0.8)
        for k, (name, when) in enumerate(moments):
            if when is not None and -0.3 <= when - r.contact <= r.span:
                ax.axvline(when - r.contact, color="grey", lw=0.8, ls=":")
                if ax is axes[0]:  # staggered: the cut and the reverse thrust are often ms apart
                    where = (when - r.contact, 0.92 - 0.09 * k)
                    ax.annotate(f" {name}", where, xycoords=("data", "axes fraction"), fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("time from first contact, s")
    axes[-1].set_xlim(-0.3, r.span)
    thrust = f", reverse {c.reverse_percent:g} %" if c.reverse_percent else ""
    fig.suptitle(
        f"{r.log.path.name} landing {ev.number}: {c.slope_deg:.1f}° roof, {c.speed:.2f} m/s impact, "
        f"legs {c.tau_up:g}/{c.tau_down:g} N·m{thrust} (model: {r.model.outcome.label})",
        fontsize=10,
    )
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
