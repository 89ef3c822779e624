"""Each drop's clock, fitted within a window: a recording whose frames lag its t = 0."""

from __future__ import annotations

import json

import numpy as np
import pytest

from slopelander.ident.clocks import align_windows
from slopelander.ident.compare import compare
from slopelander.ident.fit import FitError, Identifier
from slopelander.ident.synth import NoiseModel, paper_drops, synthesize
from slopelander.model import Model
from tests.ident.conftest import slopelander

TRUTH = {"ground_stiffness": 3.0e4, "friction_kinetic": 0.65}


def _lagged(lag: float, seed: int = 0, noisy: bool = True, n: int = 8):
    truth = Model.default().with_params(**TRUTH)
    noise = NoiseModel(latency=lag) if noisy else NoiseModel(0.0, 0.0, lag)
    return synthesize(truth, paper_drops(n, seed=7), noise, seed=seed, duration=0.6)


def test_the_windows_come_from_the_recorded_contact_or_the_setting():
    drops = _lagged(0.0, n=3)
    assert align_windows(drops) == [0.0, 0.0, 0.0]  # nothing recorded: observed at t
    drops[1].meta["quality"] = {"contact_sd_s": 0.0012}  # as `slopelander import` writes it
    drops[2].meta["quality"] = {"contact_sd_s": "n/a"}
    assert align_windows(drops) == pytest.approx([0.0, 0.0036, 0.0])
    assert align_windows(drops, 0.004) == [0.004] * 3
    for bad in (-0.001, 0.2, float("nan"), True):
        with pytest.raises(ValueError, match=r"0\.\.0\.05 s"):
            align_windows(drops, bad)


def test_compare_finds_a_noiseless_recordings_lag_and_its_error_vanishes():
    """Frames that show the body 3 ms before their time stamps: observed at t the model is
    off by the lag's motion; aligned within 5 ms it finds each drop's 3 ms (to 0.1 ms: the model is
    sampled at 400 Hz and interpolated) and matches."""
    drops = _lagged(0.003, noisy=False, n=4)
    model = Model.default().with_params(**TRUTH)
    at_t = compare(model, drops, align=[0.0] * 4)
    fitted = compare(model, drops, align=[0.005] * 4)
    assert [d.lag for d in at_t.drops] == [0.0] * 4
    assert np.allclose([d.lag for d in fitted.drops], 0.003, atol=1e-4), [d.lag for d in fitted.drops]
    assert fitted.nrmse < 0.1 * at_t.nrmse, (fitted.nrmse, at_t.nrmse)


def test_a_fit_with_its_clocks_aligned_holds_the_truth_a_lag_moved_away():
    """Seed 0 of `benchmarks/interval_coverage.py`'s 2 ms lag: at t the fit puts k_g at 31,414
    +- 869 (the truth outside); with each clock fitted within 5 ms it finds the lags and k_g's
    interval holds 30,000."""
    drops = _lagged(0.002)
    kw = {"cma_evals": 60, "ls_evals": 15, "workers": 1, "seed": 0}
    at_t = Identifier(Model.default(), list(TRUTH), **kw).fit(drops).result_
    aligned = Identifier(Model.default(), list(TRUTH), align_s=0.005, **kw).fit(drops).result_
    k = "ground_stiffness"
    assert abs(at_t.values[k] - TRUTH[k]) > at_t.ci95[k]  # the lag's bias, as before
    assert at_t.lags == {}
    for name, truth in TRUTH.items():
        assert abs(aligned.values[name] - truth) <= aligned.ci95[name], (name, aligned.values, aligned.ci95)
    lags = np.array(list(aligned.lags.values()))
    assert len(lags) == 8 and np.all(np.abs(lags - 0.002) < 0.001), lags


def test_a_window_out_of_range_is_refused_before_any_work():
    drops = _lagged(0.0, n=3)
    with pytest.raises(FitError, match=r"align_s: the alignment window must be 0\.\.0\.05 s"):
        Identifier(Model.default(), ["friction_kinetic"], align_s=-1.0).fit(drops)
    done = slopelander("compare", "no-such-folder", "--align-ms", "-2")
    assert done.returncode in (1, 2) and "Traceback" not in done.stderr
    assert "--align-ms" in done.stderr, done.stderr


def test_compare_writes_each_drops_clock_and_finds_the_synthesizers_lag(tmp_path):
    """`slopelander synth` records with a 2 ms lag (its noise model's latency); `compare
    --align-ms 4` finds it in every drop and writes window and lag to its JSON; without the
    option a synthetic drop (no contact interval recorded) is compared at its own t."""
    run = slopelander
    ds = tmp_path / "ds"
    assert run("synth", "--out", str(ds), "--drops", "3", "--duration", "0.4", "--seed", "4").returncode == 0
    for extra, window in ((("--align-ms", "4"), 0.004), ((), 0.0)):
        out = tmp_path / f"c{window}.json"
        done = run("compare", str(ds), "--json", str(out), *extra)
        assert done.returncode == 0, done.stderr
        clocks = json.loads(out.read_text())["clocks"]
        assert len(clocks) == 3 and all(c["window_s"] == window for c in clocks.values())
        lags = [c["lag_s"] for c in clocks.values()]
        if window:
            assert all(abs(lag - 0.002) < 5e-4 for lag in lags), lags
        else:
            assert lags == [0.0] * 3
