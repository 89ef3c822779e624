"""The picture of a simulated (or real) flight: what the companion saw, state by state."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

STATE_COLOURS = {
    "PRESET": "#dddddd",
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


def _bands(ax, history: list[dict], t_end: float, label: bool = False) -> None:
    for i, h in enumerate(history):
        t1 = history[i + 1]["t"] if i + 1 < len(history) else t_end
        ax.axvspan(h["t"], t1, color=STATE_COLOURS.get(h["to"], "#eeeeee"), alpha=0.6, lw=0)
        if label:
            ax.text(
                (h["t"] + t1) / 2,
                1.0,
                h["to"],
                transform=ax.get_xaxis_transform(),
                rotation=90,
                ha="center",
                va="top",
                fontsize=7,
            )


def plot_flight(tele, history: list[dict], path: Path, title: str = "") -> Path:
    """Height and range, vertical speed, acceleration, motor outputs, leg torques and angles, pitch;
    the landing states as coloured bands. ``tele`` is a :class:`slopelander.demo.Telemetry`."""
    t0 = history[0]["t"] - 3.0 if history else (tele.t[0] if tele.t else 0.0)
    t_end = max([*tele.t[-1:], *(h["t"] for h in history)], default=t0 + 1) + 0.5

    def cut(ts, ys):
        pairs = [(t, y) for t, y in zip(ts, ys, strict=False) if t >= t0]
        return [p[0] for p in pairs], [p[1] for p in pairs]

    fig, axes = plt.subplots(6, 1, figsize=(11, 13), sharex=True, constrained_layout=True)
    ax = axes[0]
    ax.plot(*cut(tele.t, tele.height), label="height above the pad (m)")
    ax.plot(*cut(tele.range_t, tele.range_m), label="downward range (m)")
    ax.set_ylabel("m")
    ax.legend(loc="upper right", fontsize=8)
    _bands(ax, history, t_end, label=True)
    ax = axes[1]
    ax.plot(*cut(tele.t, tele.vz_up), color="C2")
    ax.set_ylabel("vertical speed\n(m/s, up +)")
    ax = axes[2]
    ax.plot(*cut(tele.accel_t, tele.accel), color="C3", lw=0.8)
    ax.set_ylabel("|accel| (m/s²)\nRAW_IMU")
    ax = axes[3]
    ts, servos = cut(tele.servo_t, tele.servo)
    for i in range(4):
        ax.plot(ts, [s[i] for s in servos], lw=0.9, label=f"motor {i + 1}")
    ax.axhline(1500, color="k", lw=0.6, ls=":")
    ax.set_ylabel("motor PWM (µs)\n1500 stop, <1500 reverse")
    ax.legend(loc="upper right", fontsize=7, ncol=4)
    ax = axes[4]
    lt, torques = cut(tele.legs_t, tele.leg_torque)
    _, angles = cut(tele.legs_t, tele.leg_angle)
    for i in range(4):
        ax.plot(lt, [q[i] for q in torques], lw=1.0, label=f"leg {i} torque")
    ax.set_ylabel("leg friction\ntorque (N·m)")
    ax2 = ax.twinx()
    for i in range(4):
        ax2.plot(lt, [a[i] for a in angles], lw=0.8, ls="--")
    ax2.set_ylabel("leg angle (deg, dashed)")
    ax.legend(loc="upper left", fontsize=7, ncol=4)
    ax = axes[5]
    ax.plot(*cut(tele.pitch_t, tele.pitch_deg), color="C4")
    ax.set_ylabel("pitch (deg,\nnose up +)")
    ax.set_xlabel("vehicle time (s)")
    for ax in axes[1:]:
        _bands(ax, history, t_end)
    axes[0].set_xlim(t0, t_end)
    if title:
        fig.suptitle(title)
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
