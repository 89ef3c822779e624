"""The demo's picture shows the slope measured before PRESET: the points behind it (outliers
marked), the fitted line with its 2-sigma wedge, the numbers, and the survey pass as a band."""

from __future__ import annotations

import math

import matplotlib.pyplot as plt

from slopelander.controller.slope_estimate import estimate
from slopelander.plots.flight import flight_figure
from tests.docs.test_flight_picture import DEMO, _history, _telemetry
from tests.slope.test_slope_estimate import pass_with_errors


def drawn_estimate(slope_deg: float = 35.0):
    pts = pass_with_errors(slope_deg, 2.0, seed=5)
    pts[40] = (pts[40][0], pts[40][1], pts[40][2] + 0.8)  # a spike: an outlier the fit weighs down
    est = estimate(pts, 5.5)
    assert est.ok, est.describe()
    return est


def test_the_picture_draws_the_estimate_its_points_and_the_survey() -> None:
    est = drawn_estimate()
    history = _history(DEMO)
    slope = {"record": est.record(), "survey": (-8.0, 4.0), "true_slope_deg": 35.0}
    fig = flight_figure(_telemetry(history[-1]["t"] + 3), history, "a flight", slope=slope)
    fig.canvas.draw()
    try:
        ax = next(a for a in fig.axes if a.get_gid() == "slope-estimate")
        title = ax.get_title()
        assert f"{est.slope_deg:.1f} ± {est.sigma_deg:.1f}°" in title and "survey pass 12.0 s" in title
        assert "scenario 35°" in title
        inliers, outliers = ax.collections[0], ax.collections[1]
        assert len(inliers.get_offsets()) + len(outliers.get_offsets()) == est.n_points
        assert len(outliers.get_offsets()) == est.n_points - est.n_inliers >= 1
        assert est.points[40][3] < 0.1  # the spike is among them
        # the fitted line has the measured slope (equal axes: it looks its angle)
        fit = next(line for line in ax.get_lines() if line.get_label().startswith("fit"))
        (x0, x1), (h0, h1) = fit.get_xdata(), fit.get_ydata()
        assert (
            abs(math.degrees(math.atan(-(h1 - h0) / (x1 - x0))) - est.slope_deg) < 1e-3
        )  # the record keeps 3 decimals
        # the survey pass is a band of the whole flight, named in its strip, and nothing overprints
        strip = next(a for a in fig.axes if a.get_gid() == "state-strip")
        assert strip.get_xlim()[0] <= -8.0
        names = [t.get_text() for t in strip.texts if t.get_gid() == "state-label" and t.get_visible()]
        assert "SURVEY" in names
        renderer = fig.canvas.get_renderer()
        for legend in [leg for a in fig.axes if (leg := a.get_legend()) is not None]:
            box = legend.get_window_extent(renderer)
            for other in fig.axes:
                assert not box.overlaps(other.get_window_extent(renderer)), legend.get_texts()[0].get_text()
    finally:
        plt.close(fig)


def test_a_refused_estimate_is_drawn_with_its_reason() -> None:
    hover = [(i * 0.05, 5.5 + 0.01 * math.sin(i), 0.0) for i in range(100)]
    est = estimate(hover, 5.5)
    assert not est.ok
    history = _history(DEMO)
    fig = flight_figure(_telemetry(36.0), history, slope={"record": est.record(), "survey": None})
    try:
        ax = next(a for a in fig.axes if a.get_gid() == "slope-estimate")
        assert ax.get_title().startswith("slope not measured: too little seen")
        assert not any(line.get_label().startswith("fit") for line in ax.get_lines())
    finally:
        plt.close(fig)
