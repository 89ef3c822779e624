"""A motion-capture lab observing the truth in 3-D: what its C3D export of a drop holds.

:mod:`.mocap` records the pose a lab's software would export; this goes one step further back,
to the raw markers: a rigid cluster on the body and markers on the roof, placed in the capture
volume (Z up, the fall line at some heading, the roof anywhere), each marker jittered on its
own, frames at the cameras' rate with a random phase against the instant of contact, markers
hidden for a while (an occlusion), and optionally the body yawed out of the landing plane. The
importer (:mod:`slopelander.ident.mocap`) must get the truth back from these files alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

BODY_MARKERS: dict[str, tuple[float, float, float]] = {
    "FR_ARM": (0.120, -0.045, 0.030),
    "FL_ARM": (0.110, 0.060, 0.025),
    "REAR": (-0.125, 0.010, 0.035),
    "TOP": (0.010, -0.020, 0.090),
}
"""m, body frame (x forward, y left, z up, origin the centre of mass): four markers on the frame."""
ROOF_MARKERS: dict[str, tuple[float, float]] = {
    "ROOF1": (-0.45, -0.35),
    "ROOF2": (0.55, -0.30),
    "ROOF3": (0.50, 0.40),
    "ROOF4": (-0.40, 0.35),
}
"""m, (along the fall line, across it) from the landing point: markers on the roof's surface."""
ROOF_MARKER_HEIGHT = 0.007
"""m: a 14 mm marker on a flat base, its centre 7 mm above the surface."""


@dataclass(frozen=True)
class Occlusion:
    """Markers hidden from ``start`` s (from contact) for ``duration`` s."""

    markers: tuple[str, ...]
    start: float
    duration: float


@dataclass(frozen=True)
class LabTake:
    """How one drop is seen: where the roof stands in the capture volume and what goes wrong."""

    heading_deg: float = 30.0
    """Direction of the fall line in the capture's X-Y plane."""
    origin: tuple[float, float, float] = (0.8, -0.3, 0.9)
    """m: the landing point in capture coordinates."""
    yaw_deg: float = 0.0
    """The body turned about the vertical, out of the landing plane."""
    occlusions: tuple[Occlusion, ...] = field(default_factory=tuple)


def markers_of(states: np.ndarray, slope_deg: float, lab: LabTake) -> tuple[list[str], np.ndarray]:
    """Marker positions (frames, markers, 3) in capture coordinates (m, Z up) for the truth's
    planar states (x, z, pitch per frame) on a roof of ``slope_deg``."""
    h = math.radians(lab.heading_deg)
    ex = np.array([math.cos(h), math.sin(h), 0.0])
    ez = np.array([0.0, 0.0, 1.0])
    ey = np.cross(ez, ex)
    origin = np.array(lab.origin)
    n = len(states)
    c, s = np.cos(states[:, 2]), np.sin(states[:, 2])
    # body axes in capture coordinates: pitch in the landing plane, then the yaw about the vertical
    bx = c[:, None] * ex + s[:, None] * ez
    bz = -s[:, None] * ex + c[:, None] * ez
    by = np.broadcast_to(ey, (n, 3))
    rot = np.stack([bx, by, bz], axis=2)
    y = math.radians(lab.yaw_deg)
    yaw = np.array([[math.cos(y), -math.sin(y), 0.0], [math.sin(y), math.cos(y), 0.0], [0.0, 0.0, 1.0]])
    rot = yaw @ rot
    com = origin + states[:, 0, None] * ex + states[:, 1, None] * ez
    body = np.array(list(BODY_MARKERS.values()))
    pts = com[:, None, :] + np.einsum("fij,mj->fmi", rot, body)
    a = math.radians(slope_deg)
    along = math.cos(a) * ex - math.sin(a) * ez  # downhill along the surface
    normal = math.sin(a) * ex + math.cos(a) * ez
    roof = np.array(
        [origin + u * along + v * ey + ROOF_MARKER_HEIGHT * normal for u, v in ROOF_MARKERS.values()]
    )
    pts = np.concatenate([pts, np.broadcast_to(roof, (n, len(roof), 3))], axis=1)
    return [*BODY_MARKERS, *ROOF_MARKERS], pts


FOOT_MARKERS = ("FOOT_C", "FOOT_D")
"""One marker on each planar foot (legs C and D), in the landing plane."""
FOOT_MARKER_HEIGHT = 0.010
"""m: a foot marker's centre above the roof when its foot touches."""


def foot_offsets(model, cond) -> np.ndarray:
    """(2, 2): each foot tip's (x forward, z up) in the body frame at first contact, from the
    model's own kinematics (the legs are still at their set angles then)."""
    from slopelander.model import kernel as k
    from slopelander.model.reference import ReferenceLanding

    ref = ReferenceLanding(model, cond)
    M, f, pts, vel, J = k.kinematics_views(ref.ws)
    k.kinematics(ref.p, ref.st, M, f, pts, vel, J)
    q = ref.st[k.S_Q : k.S_Q + 3]
    c, s = math.cos(q[2]), math.sin(q[2])
    d = pts[k.PT_FOOT : k.PT_FOOT + 2] - q[:2]
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def feet_of(
    states: np.ndarray,
    slope_deg: float,
    lab: LabTake,
    offsets: np.ndarray,
    height: float = FOOT_MARKER_HEIGHT,
) -> np.ndarray:
    """The foot markers (frames, 2, 3) in capture coordinates: carried with the body (the legs
    at their set angles) until each reaches its height above the roof, then held there. Exact
    up to the first foot's touch, which is what the importer reads from them; after it the
    legs turn and the feet slide, which this marker model leaves out."""
    h = math.radians(lab.heading_deg)
    ex = np.array([math.cos(h), math.sin(h), 0.0])
    ez = np.array([0.0, 0.0, 1.0])
    a = math.radians(slope_deg)
    normal = math.sin(a) * ex + math.cos(a) * ez
    origin = np.array(lab.origin)
    c, s = np.cos(states[:, 2]), np.sin(states[:, 2])
    out = np.empty((len(states), 2, 3))
    for i, (bx, bz) in enumerate(offsets):
        x = states[:, 0] + c * bx - s * bz
        z = states[:, 1] + s * bx + c * bz
        pts = origin + x[:, None] * ex + z[:, None] * ez + height * normal
        above = (pts - origin) @ normal - height
        down = np.flatnonzero(above <= 0.0)
        if down.size:
            pts[down[0] :] = pts[down[0]]
        out[:, i] = pts
    return out


def frame_times(rng: np.random.Generator, rate: float, before: float, after: float) -> np.ndarray:
    """Frame times (s from the true contact) with a random phase against it."""
    dt = 1.0 / rate
    phase = float(rng.uniform(0.0, dt))
    return np.arange(math.ceil((-before - phase) / dt), math.floor((after - phase) / dt) + 1) * dt + phase


def observe(
    states: np.ndarray,
    t: np.ndarray,
    slope_deg: float,
    lab: LabTake,
    rng: np.random.Generator,
    marker_sd: float = 5e-4,
    feet: np.ndarray | None = None,
) -> tuple[list[str], np.ndarray]:
    """The markers as the cameras report them: jittered, with the occlusions as NaN.
    ``feet``: the feet's body-frame offsets (:func:`foot_offsets`), to add a marker on each."""
    labels, pts = markers_of(states, slope_deg, lab)
    if feet is not None:
        labels = [*labels, *FOOT_MARKERS]
        pts = np.concatenate([pts, feet_of(states, slope_deg, lab, feet)], axis=1)
    pts = pts + rng.normal(0.0, marker_sd, pts.shape)
    for occ in lab.occlusions:
        hide = (t >= occ.start) & (t < occ.start + occ.duration)
        for m in occ.markers:
            pts[hide, labels.index(m)] = np.nan
    return labels, pts


def write_take(path: Path, labels: list[str], pts: np.ndarray, rate: float) -> None:
    """The take as a C3D file (millimetres, Z up declared in POINT:Y_SCREEN)."""
    from slopelander.ident.mocap.formats import write_c3d

    write_c3d(path, labels, pts, rate, up="+Z")


EXAMPLE: dict[str, tuple[dict, LabTake]] = {
    "drop01": ({"slope_deg": 10.0, "speed": 1.6, "tau_up": 1.1, "tau_down": 1.1}, LabTake(30.0)),
    "drop02": (
        {"slope_deg": 18.0, "speed": 2.4, "tau_up": 1.7, "tau_down": 1.1},
        LabTake(-60.0, (1.1, 0.2, 0.7), occlusions=(Occlusion(("TOP",), 0.04, 0.06),)),
    ),
    "drop03": (
        {"slope_deg": 25.0, "speed": 2.0, "tau_up": 2.3, "tau_down": 1.7},
        LabTake(120.0, (0.3, 0.6, 1.0), occlusions=(Occlusion(("FR_ARM", "REAR"), 0.15, 0.025),)),
    ),
    "drop04": (
        {"slope_deg": 32.0, "speed": 2.8, "tau_up": 2.3, "tau_down": 2.3},
        LabTake(75.0, (0.9, -0.6, 1.1)),
    ),
    "drop05": (
        {"slope_deg": 5.0, "speed": 1.2, "tau_up": 0.56, "tau_down": 1.1},
        LabTake(200.0, (-0.2, 0.1, 0.5)),
    ),
    "drop06": (
        {"slope_deg": 38.0, "speed": 2.2, "tau_up": 1.7, "tau_down": 2.3},
        LabTake(10.0, (0.6, 0.0, 1.3)),
    ),
    "drop07": (
        {"slope_deg": 22.0, "speed": 2.0, "tau_up": 1.1, "tau_down": 1.7},
        LabTake(45.0, (0.5, 0.5, 0.9), yaw_deg=8.0),
    ),
}
"""The shipped example (docs/import.md): seven drops on roofs placed anywhere in the volume;
drop02 loses one marker for 60 ms (the pose still solves from three), drop03 two for 25 ms
(a gap), drop07 lands yawed 8 deg out of the landing plane (flagged)."""


def make_example(folder: Path, seed: int = 2026, rate: float = 200.0) -> None:
    """Write the example's takes (C3D), its markers file and takes table, and the truth the
    takes were made from (``truth/``, a dataset at the same frames, 0 = the true contact).
    The truth is the shipped model integrated by solve_ivp (:mod:`.physics`)."""
    from slopelander.ident.recording import Drop, write_drop
    from slopelander.ident.truth.physics import truth_states
    from slopelander.model import LandingConditions, Model

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    model = Model.default()
    rng = np.random.default_rng(seed)
    rows = ["take,tau_up,tau_down"]
    for name, (cond_d, lab) in EXAMPLE.items():
        cond = LandingConditions(**cond_d)
        t = frame_times(rng, rate, 0.15, 0.55)
        states, _ = truth_states(model, cond, t)
        labels, pts = observe(states, t, cond.slope_deg, lab, rng)
        write_take(folder / f"{name}.c3d", labels, pts, rate)
        rows.append(f"{name}.c3d,{cond.tau_up:g},{cond.tau_down:g}")
        truth = Drop(
            name,
            np.round(t, 6),
            states,
            cond,
            None,
            "truth: solve_ivp, shipped model",
            {"rates": {"method": "measured"}},
        )
        write_drop(truth, folder / "truth")
    (folder / "takes.csv").write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    import sys

    make_example(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/examples/mocap"))


def contact_errors(folder: Path, markers: Path, seeds: int, first_seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The shipped takes' landings seen again at ``seeds`` new frame phases and marker noises
    (from ``first_seed`` on), written as C3D under ``folder`` and imported: each landing's first
    contact error against the truth (s) and the half-width the import printed for it (s)."""
    from slopelander.ident.mocap.importer import import_takes
    from slopelander.ident.recording import load_dataset
    from slopelander.ident.truth.physics import truth_states
    from slopelander.model import LandingConditions, Model

    model = Model.default()
    grid = np.arange(-0.2, 0.56, 1 / 4000)
    dense = {n: truth_states(model, LandingConditions(**c), grid)[0] for n, (c, _) in EXAMPLE.items()}
    errs, sds = [], []
    for seed in range(seeds):
        rng = np.random.default_rng(first_seed + seed)
        takes = folder / f"seed{seed}"
        takes.mkdir(parents=True)
        true_tc = {}
        for name, (cd, lab) in EXAMPLE.items():
            t = frame_times(rng, 200.0, 0.15, 0.55)
            st = np.column_stack([np.interp(t, grid, dense[name][:, c]) for c in range(6)])
            labels, pts = observe(st, t, cd["slope_deg"], lab, rng)
            write_take(takes / f"{name}.c3d", labels, pts, 200.0)
            true_tc[name] = -t[0]
        out = folder / f"out{seed}"
        import_takes([takes], markers, out, keep_nonplanar=True)
        for d in load_dataset(out):
            errs.append(d.meta["quality"]["contact_time_in_take_s"] - true_tc[d.name])
            sds.append(d.meta["quality"]["contact_sd_s"])
    return np.array(errs), np.array(sds)
