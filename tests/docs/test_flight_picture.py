"""The demo's picture can be read: no state name overprints another, no legend hides data or a
state, and the landing (about 1 s of a 30 s flight) has its own zoomed panel."""

from __future__ import annotations

import math
from itertools import combinations

import matplotlib.pyplot as plt
import pytest

from slopelander.controller.telemetry import Telemetry
from slopelander.plots.flight import flight_figure, landing_window, plot_flight

# the transitions of a recorded `slopelander demo` (transitions.jsonl, 35 deg roof)
DEMO = [
    (6.272, "PRESET"), (6.272, "LEGS_WAIT"), (15.812, "CHECKS"), (15.812, "DESCEND"),
    (17.06, "ARMED"), (19.19, "CUT"), (19.22, "REVERSE"), (19.735, "SETTLED"), (20.74, "LANDED"),
    (22.77, "TAKEOFF"), (25.432, "RESET"), (33.42, "READY"),
]  # fmt: skip
# an abort soon after a link loss: four changes within 0.1 s, the motors never cut
ABORTED = [(6.0, "PRESET"), (6.0, "LEGS_WAIT"), (9.0, "CHECKS"), (9.0, "DESCEND"), (9.05, "LINK_LOST"),
           (9.1, "ABORTED")]  # fmt: skip


def _history(rows):
    out, prev = [], None
    for t, state in rows:
        out.append({"t": t, "from": prev, "to": state, "reason": ""})
        prev = state
    return out


def _telemetry(t_end: float) -> Telemetry:
    tele = Telemetry()
    for k in range(int(t_end * 50)):
        t = k / 50
        tele.t.append(t)
        tele.height.append(3 - 0.1 * t)
        tele.vz_up.append(math.sin(t))
        tele.range_t.append(t)
        tele.range_m.append(2 + math.cos(t))
        tele.accel_t.append(t)
        tele.accel.append(9.8 + math.sin(7 * t))
        tele.pitch_t.append(t)
        tele.pitch_deg.append(-40 * (t > 19.3))
        tele.servo_t.append(t)
        tele.servo.append([1850, 1850, 1850, 1850] if t < 19.19 else [1000] * 4)
        tele.legs_t.append(t)
        tele.leg_torque.append([1.1, 1.1, 1.1, 1.1])
        tele.leg_angle.append([25.7, 37.5, 25.7, 37.5])
    return tele


@pytest.fixture(params=["demo", "aborted"])
def drawn(request):
    history = _history(DEMO if request.param == "demo" else ABORTED)
    fig = flight_figure(_telemetry(history[-1]["t"] + 3), history, title="a flight")
    fig.canvas.draw()
    yield fig, history
    plt.close(fig)


def _labels(ax):
    return [t for t in ax.texts if t.get_gid() == "state-label" and t.get_visible()]


def test_no_state_name_overprints_another_and_each_stays_in_its_strip(drawn) -> None:
    fig, _ = drawn
    renderer = fig.canvas.get_renderer()
    strips = [ax for ax in fig.axes if ax.get_gid() == "state-strip"]
    assert strips
    for strip in strips:
        box = strip.get_window_extent(renderer)
        extents = [t.get_window_extent(renderer) for t in _labels(strip)]
        for a, b in combinations(extents, 2):
            assert not a.overlaps(b)
        for e in extents:
            assert box.x0 <= e.x0 and e.x1 <= box.x1 and box.y0 <= e.y0 and e.y1 <= box.y1


def test_the_whole_flight_names_every_state(drawn) -> None:
    fig, history = drawn
    overview = next(ax for ax in fig.axes if ax.get_gid() == "state-strip")
    assert sorted(t.get_text() for t in _labels(overview)) == sorted(h["to"] for h in history)


def test_no_legend_lies_over_a_plot(drawn) -> None:
    fig, _ = drawn
    renderer = fig.canvas.get_renderer()
    legends = [leg for ax in fig.axes if (leg := ax.get_legend()) is not None]
    assert legends
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            assert not box.overlaps(ax.get_window_extent(renderer)), legend.get_texts()[0].get_text()


def test_the_landing_has_its_own_zoomed_panel() -> None:
    history = _history(DEMO)
    lo, hi = landing_window(history, 40.0)
    assert lo < 19.19 and hi > 20.74 and hi - lo < 4
    fig = flight_figure(_telemetry(36.4), history)
    strips = [ax for ax in fig.axes if ax.get_gid() == "state-strip"]
    assert len(strips) == 2
    whole, zoom = (ax.get_xlim() for ax in strips)
    assert whole[0] <= 6.272 and whole[1] >= 33.42
    assert zoom == pytest.approx((lo, hi)) and (zoom[1] - zoom[0]) < 0.15 * (whole[1] - whole[0])
    assert {"CUT", "REVERSE", "SETTLED", "LANDED"} <= {t.get_text() for t in _labels(strips[1])}
    plt.close(fig)


def test_a_flight_without_a_cut_has_no_zoom_and_is_still_written(tmp_path) -> None:
    history = _history(ABORTED)
    assert landing_window(history, 12.0) is None
    path = plot_flight(_telemetry(12.0), history, tmp_path / "flight.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
