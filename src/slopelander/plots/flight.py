"""The picture of a simulated (or real) flight: what the companion saw, state by state.

Two columns: the whole flight on the left, the landing (from just before the cut to the vehicle at
rest) zoomed on the right, since the landing lasts about 1 s of a 30 s flight. State names sit in a
strip of their own above each column, on as many lines as it takes for no two to overprint, and
every legend sits outside the data. When the landing began with a measured slope, the survey pass
shows as its own band and a last row draws the estimate (plots/slope.py)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

STATE_COLOURS = {
    "PRESET": "#dddddd",
    "SURVEY": "#fce5cd",
    "LEGS_WAIT": "#cccccc",
    "CHECKS": "#bbbbbb",
    "DESCEND": "#cfe2f3",
    "ARMED": "#9fc5e8",
    "CUT": "#ffe599",
    "REVERSE": "#f4cccc",
    "SETTLED": "#d9ead3",
    "LANDED": "#b6d7a8",
    "TAKEOFF": "#d9d2e9",
    "RESET": "#b4a7d6",
    "READY": "#e6e6fa",
    "ABORTED": "#ea9999",
    "ESTOP": "#e06666",
    "LINK_LOST": "#e06666",
}
LABEL_LINES = 4  # lines of state names in a strip
BEFORE_CUT_S = 0.8  # the zoomed landing starts this long before the motors are cut
AFTER_REST_S = 0.5  # and ends this long after the vehicle is judged at rest (or the landing ends)


def landing_window(history: list[dict], t_end: float) -> tuple[float, float] | None:
    """Vehicle times the zoomed panel shows: from before the cut to just after the vehicle was
    judged at rest, or to the state that ended the landing; None when the motors were never cut."""
    cut = next((h["t"] for h in history if h["to"] == "CUT"), None)
    if cut is None:
        return None
    after = [h for h in history if h["t"] > cut]
    stop = next((h["t"] for h in after if h["to"] not in ("CUT", "REVERSE", "SETTLED")), None)
    return cut - BEFORE_CUT_S, min(t_end, (stop if stop is not None else t_end) + AFTER_REST_S)


def _spans(history: list[dict], t_end: float) -> list[tuple[str, float, float]]:
    return [
        (h["to"], h["t"], history[i + 1]["t"] if i + 1 < len(history) else t_end)
        for i, h in enumerate(history)
    ]


def _bands(ax, spans: list[tuple[str, float, float]]) -> None:
    for state, t0, t1 in spans:
        ax.axvspan(t0, t1, color=STATE_COLOURS.get(state, "#eeeeee"), alpha=0.6, lw=0)


def _strip(ax, spans: list[tuple[str, float, float]], lo: float, hi: float) -> None:
    """State names over their bands; placed for real once the layout is known (_place_labels)."""
    _bands(ax, spans)
    ax.set_xlim(lo, hi)
    ax.set_ylim(0, 1)
    ax.set_yticks([])
    ax.tick_params(axis="x", labelbottom=False, length=0)
    for state, t0, t1 in spans:
        a, b = max(t0, lo), min(t1, hi)
        if b < a or (t1 == t0 and not lo <= t0 <= hi):
            continue
        text = ax.text((a + b) / 2, 0.5, state, ha="center", va="center", fontsize=8, clip_on=False)
        text.set_gid("state-label")


def _place_labels(fig: Figure, ax) -> None:
    """Put each state name on the lowest line where it overlaps no name already placed, kept
    inside its strip (a name near the edge is aligned to the edge)."""
    renderer = fig.canvas.get_renderer()
    box = ax.get_window_extent(renderer)
    placed: list[list] = [[] for _ in range(LABEL_LINES)]
    labels = [t for t in ax.texts if t.get_gid() == "state-label"]
    for text in sorted(labels, key=lambda t: t.get_position()[0]):
        ext = text.get_window_extent(renderer)
        if ext.x0 < box.x0:
            text.set_horizontalalignment("left")
            text.set_x(ax.transData.inverted().transform((box.x0 + 1, 0))[0])
        elif ext.x1 > box.x1:
            text.set_horizontalalignment("right")
            text.set_x(ax.transData.inverted().transform((box.x1 - 1, 0))[0])
        ext = text.get_window_extent(renderer)
        line = next(
            (n for n in range(LABEL_LINES) if all(ext.x0 > e.x1 + 3 or ext.x1 < e.x0 - 3 for e in placed[n])),
            None,
        )
        if line is None:  # more names crowd one moment than the strip has lines: keep the first
            text.set_visible(False)
            continue
        text.set_y(1 - (line + 0.5) / LABEL_LINES)
        placed[line].append(text.get_window_extent(renderer))


def flight_figure(tele, history: list[dict], title: str = "", slope: dict | None = None) -> Figure:
    """Height and range, vertical speed, acceleration, motor outputs, leg torques and angles, pitch;
    the landing states as coloured bands; the landing zoomed beside the whole flight.
    ``tele`` is a :class:`slopelander.controller.telemetry.Telemetry`. ``slope``: the measured slope, as
    ``{"record": SlopeEstimate.record(), "survey": (t0, t1) or None, "true_slope_deg": x or None}``
    (the survey pass's vehicle times): drawn in a last row, the pass as a SURVEY band."""
    t0 = history[0]["t"] - 3.0 if history else (tele.t[0] if tele.t else 0.0)
    survey = (slope or {}).get("survey")
    if survey:
        t0 = min(t0, survey[0] - 1.0)
    t_end = max([*tele.t[-1:], *(h["t"] for h in history)], default=t0 + 1) + 0.5
    spans = ([("SURVEY", *survey)] if survey else []) + _spans(history, t_end)
    window = landing_window(history, t_end)
    columns = [(t0, t_end)] + ([window] if window else [])

    ratios = [0.75, 2, 1.4, 1.4, 1.6, 1.6, 1.4] + ([2.6] if slope else [])
    fig = plt.figure(figsize=(16 if window else 11, 14 + (4 if slope else 0)), layout="constrained")
    grid = fig.add_gridspec(
        len(ratios),
        len(columns),
        height_ratios=ratios,
        width_ratios=[2.2, 1.3][: len(columns)],
    )
    for col, (lo, hi) in enumerate(columns):
        strip = fig.add_subplot(grid[0, col])
        axes = [fig.add_subplot(grid[row, col], sharex=strip) for row in range(1, 7)]
        _strip(strip, spans, lo, hi)
        strip.set_gid("state-strip")
        strip.set_title(
            "whole flight" if col == 0 else f"the landing, zoomed ({lo:.1f}–{hi:.1f} s)", fontsize=10
        )
        _draw_rows(tele, axes, spans, lo, hi, legends=col == len(columns) - 1, ylabels=col == 0)
        if col == 0 and window:
            for ax in axes:
                ax.axvspan(*window, fill=False, edgecolor="k", lw=0.8, ls="--")
    if slope:
        from slopelander.plots.slope import draw_slope_estimate

        ax = fig.add_subplot(grid[len(ratios) - 1, :])
        ax.set_gid("slope-estimate")
        draw_slope_estimate(ax, slope["record"], _length(survey), slope.get("true_slope_deg"))
    if title:
        fig.suptitle(title)
    fig.canvas.draw()  # lay out once, then place the names where they fit
    fig.set_layout_engine("none")
    for ax in fig.axes:
        if ax.get_gid() == "state-strip":
            _place_labels(fig, ax)
    return fig


def _draw_rows(tele, axes, spans, lo: float, hi: float, legends: bool, ylabels: bool) -> None:
    def cut(ts, ys):
        pairs = [(t, y) for t, y in zip(ts, ys, strict=False) if lo - 1 <= t <= hi + 1]
        return [p[0] for p in pairs], [p[1] for p in pairs]

    outside = {"loc": "upper left", "bbox_to_anchor": (1.01, 1.0), "fontsize": 8, "borderaxespad": 0}
    ax = axes[0]
    ax.plot(*cut(tele.t, tele.height), label="height above\nthe pad (m)")
    ax.plot(*cut(tele.range_t, tele.range_m), label="downward\nrange (m)")
    ax = axes[1]
    ax.plot(*cut(tele.t, tele.vz_up), color="C2")
    ax = axes[2]
    ax.plot(*cut(tele.accel_t, tele.accel), color="C3", lw=0.8)
    ax = axes[3]
    ts, servos = cut(tele.servo_t, tele.servo)
    for i in range(4):
        ax.plot(ts, [s[i] for s in servos], lw=0.9, label=f"motor {i + 1}")
    ax.axhline(1500, color="k", lw=0.6, ls=":")
    ax = axes[4]
    lt, torques = cut(tele.legs_t, tele.leg_torque)
    _, angles = cut(tele.legs_t, tele.leg_angle)
    for i in range(4):
        ax.plot(lt, [q[i] for q in torques], lw=1.0, color=f"C{i}", label=f"leg {i}")
    twin = ax.twinx()
    for i in range(4):
        twin.plot(lt, [a[i] for a in angles], lw=0.8, ls="--", color=f"C{i}")
    ax = axes[5]
    ax.plot(*cut(tele.pitch_t, tele.pitch_deg), color="C4")
    ax.set_xlabel("vehicle time (s)")
    for ax in axes:
        _bands(ax, spans)
    axes[0].set_xlim(lo, hi)
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    if ylabels:
        for ax, label in zip(
            axes,
            [
                "m",
                "vertical speed\n(m/s, up +)",
                "|accel| (m/s²)\nRAW_IMU",
                "motor PWM (µs)\n1500 stop,\n<1500 reverse",
                "leg friction\ntorque (N·m)",
                "pitch (deg,\nnose up +)",
            ],
            strict=True,
        ):
            ax.set_ylabel(label)
    if legends:
        twin.set_ylabel("leg angle (deg)")
        axes[0].legend(**outside)
        axes[3].legend(**outside)
        handles = [*axes[4].get_lines(), Line2D([], [], color="k", lw=0.8, ls="--")]
        labels = [*(f"leg {i} torque" for i in range(4)), "leg angle\n(right axis)"]
        twin.legend(handles, labels, **{**outside, "bbox_to_anchor": (1.12, 1.0)})


def _length(span) -> float | None:
    return None if not span else span[1] - span[0]


def plot_flight(tele, history: list[dict], path: Path, title: str = "", slope: dict | None = None) -> Path:
    """Draw :func:`flight_figure` into a PNG at ``path``."""
    fig = flight_figure(tele, history, title, slope)
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
