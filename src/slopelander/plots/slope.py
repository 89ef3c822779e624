"""The slope the companion measured before PRESET, drawn from the landing record's estimate: the
rangefinder's points on the surface (height against north), those the robust fit weighed down as
outliers, the fitted line, its 2-sigma wedge and the spot; the scenario's true slope when known."""

from __future__ import annotations

import math

import numpy as np

#: a point whose weight is below this is drawn as an outlier (slope_estimate.OUTLIER_WEIGHT)
OUTLIER_WEIGHT = 0.1


def describe(rec: dict, survey_s: float | None = None, true_slope_deg: float | None = None) -> str:
    """One line: the measured slope and its sigma, or why there is none."""
    if rec.get("slope_deg") is None or rec.get("refusal"):
        text = f"slope not measured: {rec.get('refusal')}"
    else:
        text = (
            f"slope measured {rec['slope_deg']:.1f} ± {rec['sigma_deg']:.1f}° (1σ) from "
            f"{rec['n_inliers']}/{rec['n_points']} points"
        )
        if rec.get("refusal"):
            text += f", refused: {rec['refusal']}"
    if survey_s:
        text += f", survey pass {survey_s:.1f} s"
    if true_slope_deg is not None:
        text += f"; scenario {true_slope_deg:g}°"
    return text


def draw_slope_estimate(
    ax, rec: dict, survey_s: float | None = None, true_slope_deg: float | None = None, legend: bool = True
) -> None:
    """Draw the estimate ``rec`` (``SlopeEstimate.record()``) on ``ax``: north (m) across, height
    (m, up) up, equal scales so the slope looks its angle."""
    pts = np.array(rec.get("points") or [], float).reshape(-1, 4)
    ax.set_title(describe(rec, survey_s, true_slope_deg), fontsize=10)
    ax.set_xlabel("north (m): the landing direction")
    ax.set_ylabel("surface height\n(m, local frame)")
    spot = rec.get("spot_x_m")
    if spot is not None:
        ax.axvline(spot, color="k", lw=0.8, ls=":", label="spot (vehicle at the start)")
    if pts.size == 0:
        ax.text(0.5, 0.5, "no rangefinder point near the spot", transform=ax.transAxes, ha="center")
        return
    x, h, w = pts[:, 1], pts[:, 2], pts[:, 3]
    good = w >= OUTLIER_WEIGHT
    ax.scatter(x[good], h[good], s=6, c="C0", alpha=0.6, lw=0, label="rangefinder points")
    if (~good).any():
        ax.scatter(x[~good], h[~good], s=14, c="C3", marker="x", lw=0.8, label="outliers (weight < 0.1)")
    slope = rec.get("slope_deg")
    if slope is not None and good.any():
        # the fitted line passes through the weighted centroid (a least-squares line does)
        xm = float(np.average(x[good], weights=w[good]))
        hm = float(np.average(h[good], weights=w[good]))
        xs = np.array([x.min(), x.max()])

        def line(deg: float) -> np.ndarray:
            return hm - math.tan(math.radians(deg)) * (xs - xm)

        ax.plot(xs, line(slope), color="C1", lw=1.5, label=f"fit: {slope:.1f}°")
        sigma = rec.get("sigma_deg")
        if sigma:
            ax.fill_between(
                xs, line(slope - 2 * sigma), line(slope + 2 * sigma), color="C1", alpha=0.2, lw=0,
                label=f"±2σ ({2 * sigma:.1f}°)",
            )  # fmt: skip
        if true_slope_deg is not None:
            ax.plot(
                xs,
                line(true_slope_deg),
                color="k",
                lw=0.8,
                ls="--",
                label=f"true {true_slope_deg:g}° (through the fit)",
            )
    ax.set_aspect("equal", adjustable="datalim")
    if legend:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.28), ncol=6, fontsize=8, borderaxespad=0)
