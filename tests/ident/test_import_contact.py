"""First contact from the body's deceleration alone (no foot markers): over takes of the truth
simulator at new frame phases and marker noise, the printed contact time is centred on the
truth's and its +- (a 68 % half-width) holds the truth at about that rate."""

from __future__ import annotations

import numpy as np
import pytest

from slopelander.ident.mocap.importer import import_takes
from slopelander.ident.recording import load_dataset
from slopelander.ident.truth.lab import EXAMPLE, frame_times, observe, write_take
from slopelander.ident.truth.physics import truth_states
from slopelander.model import LandingConditions, Model
from tests.ident.test_import_walkthrough import ROOT

#: its tests share the imported takes (a module fixture): one worker runs them
pytestmark = pytest.mark.xdist_group("ident/test_import_contact")

MARKERS = ROOT / "docs" / "examples" / "mocap" / "markers.yaml"
SEEDS = 3


@pytest.fixture(scope="module")
def contact_errors(tmp_path_factory) -> tuple[np.ndarray, np.ndarray]:
    """Contact-time errors (s) and printed half-widths over the shipped takes' seven landings,
    each seen again at SEEDS new frame phases and noise draws (the benchmark's setting)."""
    model = Model.default()
    grid = np.arange(-0.2, 0.56, 1 / 4000)
    dense = {n: truth_states(model, LandingConditions(**c), grid)[0] for n, (c, _) in EXAMPLE.items()}
    errs, sds = [], []
    for seed in range(SEEDS):
        rng = np.random.default_rng(500 + seed)
        folder = tmp_path_factory.mktemp(f"takes{seed}")
        true_tc = {}
        for name, (cd, lab) in EXAMPLE.items():
            t = frame_times(rng, 200.0, 0.15, 0.55)
            st = np.column_stack([np.interp(t, grid, dense[name][:, c]) for c in range(6)])
            labels, pts = observe(st, t, cd["slope_deg"], lab, rng)
            write_take(folder / f"{name}.c3d", labels, pts, 200.0)
            true_tc[name] = -t[0]
        out = folder / "out"
        import_takes([folder], MARKERS, out, keep_nonplanar=True)
        for d in load_dataset(out):
            errs.append(d.meta["quality"]["contact_time_in_take_s"] - true_tc[d.name])
            sds.append(d.meta["quality"]["contact_sd_s"])
    return np.array(errs), np.array(sds)


def test_contact_time_is_not_systematically_early(contact_errors):
    """A hinge fit that assumes the deceleration starts as a step placed contact 1.6 ms early on
    these landings; the printed time must be centred within 0.6 ms (frames are 5 ms apart)."""
    e, _ = contact_errors
    assert abs(e.mean()) < 0.6e-3, f"mean contact error {1e3 * e.mean():+.2f} ms"


def test_printed_interval_holds_the_truth_at_its_stated_rate(contact_errors):
    """The +- is a 68 % half-width: it must hold the truth in 50-90 % of the takes (21 takes
    cannot tell 68 % closer), and twice it in at least 85 % (about 95 %)."""
    e, sd = contact_errors
    inside = np.mean(np.abs(e) <= sd)
    inside2 = np.mean(np.abs(e) <= 2 * sd)
    assert 0.5 <= inside <= 0.9, f"the truth inside the printed +- in {100 * inside:.0f} % of takes"
    assert inside2 >= 0.85, f"the truth inside twice the printed +- in {100 * inside2:.0f} % of takes"
