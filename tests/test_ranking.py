"""Comparing simulators (issue 29, phase A): block-bootstrap intervals over frames, paired tests,
ranking with significance, sensor-noise intervals, and weights learned from experts.

Synthetic simulators of known order are made from the real recording
tests/data/thermal/cptv_v2_all100frames_uint16.tif (blur and noise of increasing strength);
coverage and false-positive rates are measured on AR(1) per-frame series of known mean.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import tifffile
from scipy.ndimage import gaussian_filter

import irfidelity as irf
from irfidelity import FidelityError
from irfidelity.errors import AHPConsistencyWarning
from irfidelity.bootstrap import (Resampling, block_length, bootstrap_ci, frame_series, linearize, noise_interval,
                                  paired_bootstrap, pool_numbers, psnr_noise_interval, sequence_pool)
from irfidelity.fuzzy import PAPER_COMPONENTS, ahp, combine_ahp, fit_weights
from irfidelity.judgements import read_judgements
from irfidelity.ranking import holm, rank

DATA = Path(__file__).parent / "data" / "thermal" / "cptv_v2_all100frames_uint16.tif"
WEIGHTS = "psnr=0.4,nmi=0.2,ssim=0.4"


def ar1(rng: np.random.Generator, frames: int, rho: float, series: int = 1) -> np.ndarray:
    """``series`` stationary AR(1) series of unit innovations: series × frames."""
    shocks = rng.standard_normal((series, frames))
    out = np.empty_like(shocks)
    out[:, 0] = shocks[:, 0] / math.sqrt(1 - rho * rho)
    for t in range(1, frames):
        out[:, t] = rho * out[:, t - 1] + shocks[:, t]
    return out


# --------------------------------------------------------------------------- simulators of the real recording
@pytest.fixture(scope="module")
def recording():
    """The real recording and four simulators: ``fine`` and ``twin`` (the same up to noise),
    ``mid`` and ``coarse`` (more blur and noise), each scored with score_sequence."""
    real = tifffile.imread(DATA)

    def simulate(blur: float, sigma: float, seed: int) -> np.ndarray:
        frames = real.astype(np.float64)
        if blur:
            frames = gaussian_filter(frames, (0, blur, blur))
        noisy = frames + np.random.default_rng(seed).normal(0, sigma, real.shape)
        return np.clip(np.rint(noisy), 0, 16383).astype(np.uint16)

    sims = {"fine": simulate(0, 3, 1), "twin": simulate(0, 3, 2), "mid": simulate(0.7, 6, 3),
            "coarse": simulate(1.5, 12, 4)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        reports = {name: irf.score_sequence(real, sim, weights=WEIGHTS, bits=14, peak="range", progress=False,
                                            workers=1) for name, sim in sims.items()}
    return SimpleNamespace(real=real, sims=sims, reports=reports)


def per_frame_components(report) -> dict:
    frames = report.frames
    return {"fidelity": [f["fidelity"] for f in frames],
            **{k: [f["components"][k] for f in frames] for k in ("psnr", "nmi", "ssim")}}


def test_rank_recovers_the_order_of_degraded_simulators_and_their_significance(recording):
    per_frame = {name: per_frame_components(rep) for name, rep in recording.reports.items()}
    r = rank(per_frame, weights=WEIGHTS)
    assert set(r.order[:2]) == {"fine", "twin"} and r.order[2:] == ["mid", "coarse"]
    for better, worse in [("fine", "mid"), ("twin", "mid"), ("mid", "coarse"), ("fine", "coarse")]:
        assert r.is_significant(better, worse), (better, worse)
        assert all(r.is_significant(better, worse, q) for q in ("psnr", "nmi", "ssim"))
        lo, hi = r.pairs[(better, worse)].ci["fidelity"]
        assert 0 < lo <= r.pairs[(better, worse)].difference["fidelity"] <= hi
    assert not r.is_significant("fine", "twin")
    assert not any(r.significance[tuple(r.order[:2])].values())
    assert r.stability is not None and r.stability.p_first["mid"] == 0 and r.stability.p_first["coarse"] == 0
    # the twins share the first place (frames resampled with the weights; weights alone gave fine 1.0)
    assert all(0.02 < r.stability.p_first[name] < 0.98 for name in ("fine", "twin")), r.stability.p_first
    for name in r.order:  # each simulator's own interval holds its frame-mean fidelity
        lo, hi = r.ci[name]["fidelity"]
        assert lo <= np.mean(per_frame[name]["fidelity"]) <= hi
    text = r.summary_text()
    assert "fine" in text and "significant" in text
    json.dumps(r.to_dict())


def test_sequence_pool_reproduces_the_sequence_pooled_fidelity(recording):
    real, sim, rep = recording.real, recording.sims["mid"], recording.reports["mid"]
    per_frame: dict[str, list] = {}
    for index, frame in enumerate(rep.frames):
        stats = irf.pair_stats(real[index], sim[index], need=("sse",))
        numbers = pool_numbers(frame, ("psnr", "nmi", "ssim")) | {"sse": stats.int_sums()["sse"]}
        for key, value in numbers.items():
            per_frame.setdefault(key, []).append(value)
    pool = sequence_pool(WEIGHTS, peak=rep.metrics["psnr_peak"])
    ci = bootstrap_ci(per_frame, pool=pool, level=0.95, resamples=999)
    assert ci.estimate["fidelity"] == pytest.approx(rep.fidelity, abs=1e-12)
    for component in ("psnr", "nmi", "ssim"):
        assert ci.estimate[component] == pytest.approx(rep.components[component], abs=1e-12)
        lo, hi = ci.ci[component]
        assert lo <= ci.estimate[component] <= hi
    lo, hi = ci.ci["fidelity"]
    assert lo < rep.fidelity < hi and hi - lo < 0.05


def test_pooled_psnr_is_recomputed_from_summed_errors_on_every_resample():
    rng = np.random.default_rng(7)
    sse = rng.uniform(50, 400, 60) * 1000  # frames of very different error: pooling matters
    n = np.full(60, 1000.0)
    peak = 255.0

    def psnr(sums, frames):
        return {"psnr_db": 10 * math.log10(peak * peak * sums["n"] / sums["sse"])}

    ci = bootstrap_ci({"sse": sse, "n": n}, pool=psnr, level=0.9, resamples=999)
    pooled = 10 * math.log10(peak * peak * n.sum() / sse.sum())
    mean_of_db = float(np.mean(10 * np.log10(peak * peak * n / sse)))
    assert ci.estimate["psnr_db"] == pytest.approx(pooled, rel=1e-12)
    assert abs(mean_of_db - pooled) > 0.3
    lo, hi = ci.ci["psnr_db"]
    assert lo < pooled < hi


# --------------------------------------------------------------------------- the bootstrap itself
def test_resample_sums_are_the_frames_of_circular_blocks():
    values = np.arange(10, dtype=np.float64)[:, None] ** [1, 2]
    resampling = Resampling.draw(10, 4, 50, np.random.default_rng(0))
    for row, starts in enumerate(resampling.starts):
        frames = np.concatenate([(s + np.arange(4)) % 10 for s in starts])[:10]
        np.testing.assert_allclose(resampling.sums(values)[row], values[frames].sum(axis=0))


def test_the_jackknife_linearisation_of_a_mean_is_the_centred_series():
    x = np.random.default_rng(1).normal(size=30)
    lin = linearize(frame_series({"x": x}), None)
    np.testing.assert_allclose(lin.influence["x"], x - x.mean(), atol=1e-12)


def test_block_length_follows_the_stated_rule():
    rng = np.random.default_rng(2)
    series = ar1(rng, 400, 0.5)[0]
    centred = series - series.mean()
    rho = abs(centred[1:] @ centred[:-1] / (centred @ centred))
    expected = math.ceil(2 * (6 * rho ** 2 / (1 - rho ** 2) ** 2) ** (1 / 3) * 400 ** (1 / 3))
    assert block_length(series) == expected
    assert block_length(np.full(50, 3.0)) == 1                      # constant: no correlation
    assert block_length(np.cumsum(rng.normal(size=90))) == 18       # a random walk: capped at n // 5
    assert block_length(series, ar1(rng, 400, 0.95)[0]) > expected  # the most correlated series decides
    with pytest.raises(FidelityError, match="equal length"):
        block_length(np.ones(5), np.ones(6))


def test_intervals_cover_the_true_mean_of_ar1_series_at_close_to_the_nominal_rate():
    """90 % intervals of the mean of 100 AR(1) frames (ρ = 0.6, like a recording's per-frame
    fidelity): covered in 85–95 % of 400 trials (measured 0.89)."""
    series = ar1(np.random.default_rng(11), 100, 0.6, 400)
    covered = [bootstrap_ci({"fidelity": 0.9 + 0.01 * x}, level=0.9, resamples=999, rng=i).ci["fidelity"]
               for i, x in enumerate(series)]
    rate = np.mean([lo <= 0.9 <= hi for lo, hi in covered])
    assert 0.85 <= rate <= 0.95, rate


def test_paired_test_false_positive_rate_is_close_to_nominal():
    """Two simulators equal up to noise: a shared scene term (AR(1), ρ = 0.9) plus each one's own
    AR(1) noise (ρ = 0.6). At level 0.95 the rate of 'significant' over 200 seeds stays within
    twice the nominal 5 % (measured 0.05)."""
    rng = np.random.default_rng(12)
    scene, noise_a, noise_b = ar1(rng, 100, 0.9, 200), ar1(rng, 100, 0.6, 200), ar1(rng, 100, 0.6, 200)
    hits = [paired_bootstrap({"fidelity": 0.8 + 0.02 * scene[i] + 0.005 * noise_a[i]},
                             {"fidelity": 0.8 + 0.02 * scene[i] + 0.005 * noise_b[i]},
                             level=0.95, resamples=999, rng=i).significant["fidelity"] for i in range(200)]
    assert np.mean(hits) <= 0.10, np.mean(hits)


def test_rank_family_wise_false_positive_rate_with_holm():
    """Three simulators equal up to noise: any pair called significant in at most twice 5 % of
    100 seeds (Holm over the three pairs)."""
    rng = np.random.default_rng(13)
    hits = 0
    for seed in range(100):
        scene = ar1(rng, 100, 0.8)[0]
        frames = {name: {"fidelity": 0.8 + 0.02 * scene + 0.005 * ar1(rng, 100, 0.5)[0]} for name in "ABC"}
        hits += any(rank(frames, resamples=499, rng=seed).significant.values())
    assert hits / 100 <= 0.10, hits


def test_paired_test_detects_a_real_step_and_reports_its_interval():
    rng = np.random.default_rng(14)
    scene = ar1(rng, 100, 0.8)[0]
    better = {"fidelity": 0.82 + 0.02 * scene + 0.003 * ar1(rng, 100, 0.5)[0]}
    worse = {"fidelity": 0.80 + 0.02 * scene + 0.003 * ar1(rng, 100, 0.5)[0]}
    test = paired_bootstrap(better, worse)
    assert test.significant["fidelity"] and test.p_value["fidelity"] < 0.01
    lo, hi = test.ci["fidelity"]
    assert 0 < lo < test.difference["fidelity"] < hi and abs(test.difference["fidelity"] - 0.02) < 0.002
    reverse = paired_bootstrap(worse, better)
    assert reverse.difference["fidelity"] == pytest.approx(-test.difference["fidelity"])


def test_a_constant_series_has_a_point_interval_and_constant_differences_are_significant():
    ci = bootstrap_ci({"fidelity": np.full(20, 0.7)}, resamples=99)
    assert ci.ci["fidelity"] == (pytest.approx(0.7), pytest.approx(0.7))
    test = paired_bootstrap({"f": np.full(20, 0.7)}, {"f": np.full(20, 0.6)}, resamples=99)
    assert test.significant["f"] and test.ci["f"] == (pytest.approx(0.1), pytest.approx(0.1))
    same = paired_bootstrap({"f": np.full(20, 0.7)}, {"f": np.full(20, 0.7)}, resamples=99)
    assert not same.significant["f"] and same.p_value["f"] == 1.0


@pytest.mark.parametrize("call, match", [
    (lambda: bootstrap_ci({"f": [0.1, float("nan"), 0.2]}), "frame 1 is nan"),
    (lambda: bootstrap_ci({"f": [0.1, 0.2, 0.3], "g": [0.1, 0.2]}), "one value per frame"),
    (lambda: bootstrap_ci({"f": [0.5]}), "at least 2 frames"),
    (lambda: bootstrap_ci({"f": [0.1, 0.2, 0.3]}, level=95), "level"),
    (lambda: bootstrap_ci({"f": [0.1, 0.2, 0.3]}, resamples=10), "resamples"),
    (lambda: bootstrap_ci({"f": [0.1, 0.2, 0.3]}, block=4), "block"),
    (lambda: bootstrap_ci({"f": [0.1, 0.2, 0.3]}, rng="x"), "rng"),
    (lambda: bootstrap_ci({"sse": [1.0, 0.0, 0.0], "n": [1.0, 1.0, 1.0]},
                          pool=lambda s, k: {"db": 10 * math.log10(1 / (s["sse"] / s["n"])) if s["sse"] else math.inf}),
     "finite"),
    (lambda: paired_bootstrap({"f": [0.1, 0.2, 0.3]}, {"f": [0.1, 0.2]}), "same frames"),
    (lambda: sequence_pool("psnr=1"), "peak"),
    (lambda: sequence_pool("mtf=0.5,psnr=0.5", peak=255.0), "camera="),
])
def test_bootstrap_errors_name_the_argument(call, match):
    with pytest.raises(FidelityError, match=match):
        call()


# --------------------------------------------------------------------------- ranking
def test_holm_matches_its_definition():
    p = {"a": 0.01, "b": 0.04, "c": 0.03, "d": 0.5}
    assert holm(p) == pytest.approx({"a": 0.04, "b": 0.09, "c": 0.09, "d": 0.5})


def test_rank_computes_fidelity_from_components_and_checks_its_inputs():
    rng = np.random.default_rng(15)
    frames = {name: {"psnr": 0.9 - step + 0.01 * rng.normal(size=40), "ssim": 0.8 - step + 0.01 * rng.normal(size=40)}
              for name, step in (("A", 0.0), ("B", 0.05))}
    r = rank(frames, weights="psnr=0.5,ssim=0.5", resamples=499)
    assert r.order == ["A", "B"] and r.significant[("A", "B")]
    expected = np.mean(0.5 * frames["A"]["psnr"] + 0.5 * frames["A"]["ssim"])
    assert r.estimate["A"]["fidelity"] == pytest.approx(expected)
    assert r.stability.ranking == ["A", "B"] and r.stability.p_first["A"] == 1.0
    with pytest.raises(FidelityError, match="no 'fidelity'"):
        rank(frames)
    with pytest.raises(FidelityError, match="same frames"):
        rank({"A": {"fidelity": np.ones(5)}, "B": {"fidelity": np.ones(6)}})
    with pytest.raises(FidelityError, match="correction"):
        rank(frames, weights="psnr=0.5,ssim=0.5", correction="bonferroni")
    with pytest.raises(FidelityError, match="at least two"):
        rank({"A": frames["A"]})
    with pytest.raises(FidelityError, match="no pair"):
        r.is_significant("A", "Z")


def test_rank_without_correction_uses_the_raw_p_values():
    rng = np.random.default_rng(16)
    frames = {n: {"fidelity": 0.8 + 0.01 * rng.normal(size=50)} for n in "ABC"}
    raw = rank(frames, correction="none", resamples=499)
    corrected = rank(frames, resamples=499)
    for pair, test in raw.pairs.items():
        assert raw.p_adjusted[pair]["fidelity"] == test.p_value["fidelity"]
        assert corrected.p_adjusted[pair]["fidelity"] >= test.p_value["fidelity"]


# --------------------------------------------------------------------------- one pair, sensor noise
def test_psnr_noise_interval_covers_the_noise_averaged_psnr():
    """95 % intervals from one noisy real frame cover the PSNR at the mean MSE over noise
    realisations in 92–98 % of 400 frames (measured 0.95)."""
    rng = np.random.default_rng(17)
    y, x = np.mgrid[0:64, 0:64]
    scene = 3000 + 300 * np.sin(x / 5.0) * np.cos(y / 7.0)
    sim = scene + 3 * np.cos(x / 3.0)
    sigma, peak = 4.0, 16383.0
    truth = irf.stats.psnr_from_mse(float(np.mean((scene - sim) ** 2)) + sigma ** 2, peak)
    hits = 0
    for _ in range(400):
        real = scene + rng.normal(0, sigma, scene.shape)
        lo, hi = psnr_noise_interval(float(np.mean((real - sim) ** 2)), scene.size, sigma, peak=peak).ci["psnr_db"]
        hits += lo <= truth <= hi
    assert 0.92 <= hits / 400 <= 0.98, hits


def test_noise_interval_through_the_metric_agrees_with_the_analytic_one():
    """Where the systematic difference dominates the noise, the Monte Carlo interval's width is
    within 20 % of the analytic one (PSNR in dB)."""
    rng = np.random.default_rng(18)
    y, x = np.mgrid[0:64, 0:64]
    real = 3000 + 300 * np.sin(x / 5.0) * np.cos(y / 7.0) + rng.normal(0, 2, (64, 64))
    sim = real + 20 * np.cos(x / 3.0)
    peak = 600.0
    mc = noise_interval(real, sim, 2.0, lambda r, s: irf.stats.psnr(r, s, peak=peak), draws=400, rng=1)
    analytic = psnr_noise_interval(float(np.mean((real - sim) ** 2)), real.size, 2.0, peak=peak)
    width_mc = mc.ci["value"][1] - mc.ci["value"][0]
    width_analytic = analytic.ci["psnr_db"][1] - analytic.ci["psnr_db"][0]
    assert width_mc == pytest.approx(width_analytic, rel=0.2)
    assert mc.ci["value"][0] < analytic.estimate["psnr_db"] < mc.ci["value"][1]
    with pytest.raises(FidelityError, match="sigma"):
        noise_interval(real, sim, -1.0, lambda r, s: 0.0)


def test_noise_interval_scores_integer_frames_through_evaluate():
    rng = np.random.default_rng(19)
    real = tifffile.imread(DATA)[0]
    sim = np.clip(real + rng.normal(0, 8, real.shape), 0, 16383).astype(np.uint16)

    def components(r, s):
        return irf.evaluate(r, s, peak=600.0, weights=WEIGHTS).components

    ci = noise_interval(real, sim, 2.0, components, draws=40)
    assert set(ci.ci) == {"psnr", "nmi", "ssim"} and ci.resamples == 40
    for name, (lo, hi) in ci.ci.items():
        assert lo <= ci.estimate[name] <= hi and hi - lo < 0.05
    with pytest.raises(FidelityError, match="n must"):
        psnr_noise_interval(1.0, 0, 1.0, peak=1.0)


# --------------------------------------------------------------------------- weights from experts
TRUE_WEIGHTS = np.array([0.10, 0.15, 0.30, 0.15, 0.30])  # mtf, sitf, psnr, nmi, ssim


def judged(rng: np.random.Generator, count: int, scale: float = 80.0, weights: np.ndarray = TRUE_WEIGHTS,
           expert: str | None = None) -> list[tuple]:
    """``count`` judgements of random items by a Bradley–Terry judge of the given weights."""
    out = []
    for _ in range(count):
        a, b = rng.uniform(0.4, 1.0, 5), rng.uniform(0.4, 1.0, 5)
        p = 0.5 * (1 + math.tanh(0.5 * scale * float(weights @ (a - b))))
        row = (dict(zip(PAPER_COMPONENTS, a)), dict(zip(PAPER_COMPONENTS, b)), "a" if rng.random() < p else "b")
        out.append(row if expert is None else row + (expert,))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fitted_weights_recover_the_judges_weights(seed):
    """200 judgements of a judge with s = 80 (a 0.01 fidelity difference is preferred 69 % of the
    time): every weight within 0.05."""
    fit = fit_weights(judged(np.random.default_rng(seed), 200))
    fitted = np.array([fit.weights[c] for c in PAPER_COMPONENTS])
    assert np.abs(fitted - TRUE_WEIGHTS).max() <= 0.05, fitted
    assert fit.weights.noise == 0 and isinstance(fit.weights, irf.Weights)
    assert 40 < fit.scale < 160
    assert fit.agreement["tau"] > 0.6 and fit.agreement["held_out_accuracy"] is None
    assert fit.log_likelihood < 0
    config = irf.ScoringConfig(weights=fit.weights)
    assert config.weights == fit.weights and irf.ScoringConfig.resolve(config.to_dict()).weights == fit.weights


def test_fit_accepts_reports_and_flags_inconsistent_experts():
    rng = np.random.default_rng(3)
    rows = []
    for name in ("ann", "bob", "cy", "dee"):
        rows += judged(rng, 50, expert=name)
    rows += [(a, b, "b" if p == "a" else "a", "eve") for a, b, p in judged(rng, 50)]  # contrarian
    x, y, z = (dict(zip(PAPER_COMPONENTS, rng.uniform(0.4, 1.0, 5))) for _ in range(3))
    rows += judged(rng, 47, expert="fay") + [(x, y, "a", "fay"), (y, z, "a", "fay"), (z, x, "a", "fay")]
    reports = [(SimpleNamespace(components=a), SimpleNamespace(components=b), p, e) for a, b, p, e in rows]
    fit = fit_weights(reports)
    assert set(fit.flagged) == {"eve", "fay"}
    assert "below chance" in fit.flagged["eve"][0] and fit.per_expert["eve"]["held_out_accuracy"] < 0.5
    assert fit.per_expert["fay"]["cyclic"] == 3 and fit.per_expert["fay"]["held_out_accuracy"] > 0.7
    for name in ("ann", "bob", "cy", "dee"):
        assert fit.per_expert[name]["held_out_accuracy"] > 0.7 and fit.per_expert[name]["tau"] > 0.4
    assert fit.per_expert["eve"]["tau"] < 0
    assert fit.agreement["experts"] == 6 and fit.agreement["judgements"] == 300
    assert 0.5 < fit.agreement["held_out_accuracy"] < 0.9
    json.dumps(fit.to_dict())


def test_the_ahp_prior_pulls_the_fit_toward_it():
    rng = np.random.default_rng(4)
    rows = judged(rng, 30)
    prior = irf.Weights.balanced()
    free = fit_weights(rows)
    pulled = fit_weights(rows, prior=prior, prior_strength=2000.0)
    distance = {name: np.abs(np.array([f.weights[c] for c in PAPER_COMPONENTS]) - 0.2).max()
                for name, f in (("free", free), ("pulled", pulled))}
    assert distance["pulled"] < 0.03 < distance["free"]
    same = fit_weights(rows, prior=prior, prior_strength=0.0)
    assert all(abs(same.weights[c] - free.weights[c]) < 1e-3 for c in PAPER_COMPONENTS)
    from_ahp = fit_weights(rows, prior=ahp(np.ones((5, 5))))
    assert from_ahp.prior.as_dict() == pytest.approx(prior.as_dict())


def test_fit_only_the_components_asked_for_and_deterministic_judges():
    rng = np.random.default_rng(5)
    rows = judged(rng, 200, scale=1e9)  # no noise at all: separable judgements stay finite
    fit = fit_weights(rows)
    assert np.abs(np.array([fit.weights[c] for c in PAPER_COMPONENTS]) - TRUE_WEIGHTS).max() <= 0.03
    assert math.isfinite(fit.scale) and fit.agreement["accuracy"] == 1.0
    partial = fit_weights(rows, components=["psnr", "ssim"])
    assert partial.components == ("psnr", "ssim") and partial.weights.mtf == 0
    assert partial.weights.psnr + partial.weights.ssim == pytest.approx(1.0)


@pytest.mark.parametrize("rows, match", [
    ([], "no judgements"),
    ([({"psnr": 0.9}, {"psnr": 0.8}, "c")], "'a' or 'b'"),
    ([({"psnr": 0.9}, {"ssim": 0.8}, "a")], "share no component"),
    ([({"psnr": 0.9}, {"psnr": float("nan")}, "a")], r"a number in \[0, 1\]"),
    ([({"psnr": 0.9}, {"psnr": 0.8}, "a", "ann"), ({"psnr": 0.9}, {"psnr": 0.8}, "a")], "every judgement names"),
    ([({"psnr": 0.9}, {"psnr": 0.9}, "a")], "coin toss"),
    ([({"psnr": 0.9}, 3, "a")], "report"),
])
def test_fit_errors_name_the_judgement(rows, match):
    with pytest.raises(FidelityError, match=match):
        fit_weights(rows)


def test_combine_ahp_takes_the_geometric_mean_and_each_experts_consistency():
    names = ["psnr", "nmi", "ssim"]
    ann = [[1, 3, 1], [1 / 3, 1, 1 / 3], [1, 3, 1]]
    bob = [[1, 1, 1 / 3], [1, 1, 1 / 3], [3, 3, 1]]
    odd = [[1, 5, 1 / 5], [1 / 5, 1, 5], [5, 1 / 5, 1]]  # psnr > nmi > ssim > psnr
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an inconsistent expert is listed, not warned about
        agreeing = combine_ahp({"ann": ann, "bob": bob}, names=names)
    assert agreeing.result.consistent and agreeing.inconsistent == ()
    with pytest.warns(AHPConsistencyWarning):  # the combination itself is inconsistent
        combined = combine_ahp({"ann": ann, "bob": bob, "odd": odd}, names=names)
    expected = np.cbrt(np.array(ann) * np.array(bob) * np.array(odd))
    np.testing.assert_allclose(combined.matrix, expected)
    np.testing.assert_allclose(np.array(combined.matrix) * np.array(combined.matrix).T, 1.0)
    assert combined.inconsistent == ("odd",)
    assert combined.experts["ann"].cr == pytest.approx(0.0, abs=1e-9) and combined.experts["odd"].cr > 1
    assert combined.weights == ahp(combined.matrix, names=names, on_inconsistent="ignore").weights
    single = combine_ahp([ann], names=names)
    assert single.weights.as_dict() == pytest.approx(ahp(ann, names=names).weights.as_dict(), abs=1e-12)
    assert list(single.experts) == ["expert 1"]
    with pytest.raises(FidelityError, match="'bad'.*reciprocal"):
        combine_ahp({"bad": [[1, 2, 1], [2, 1, 1], [1, 1, 1]]}, names=names)
    assert not combined.result.consistent
    json.dumps(combined.to_dict())


# --------------------------------------------------------------------------- the judgement CSV
def test_judgement_csv_round_trips_into_a_fit(tmp_path):
    rows = judged(np.random.default_rng(6), 200)
    path = tmp_path / "judged.csv"
    header = [f"{side}_{c}" for side in "ab" for c in PAPER_COMPONENTS] + ["preferred", "expert"]
    lines = [",".join(header)] + [
        ",".join([repr(float(a[c])) for c in PAPER_COMPONENTS] + [repr(float(b[c])) for c in PAPER_COMPONENTS]
                 + [p.upper(), f"expert {i % 3}"]) for i, (a, b, p) in enumerate(rows)]
    path.write_text("\n".join(lines) + "\n\n")
    read = read_judgements(path)
    assert len(read) == 200 and read[0][:3] == rows[0] and read[0][3] == "expert 0"
    direct = fit_weights([r + (f"expert {i % 3}",) for i, r in enumerate(rows)])
    assert fit_weights(read).weights.as_dict() == pytest.approx(direct.weights.as_dict(), abs=1e-12)


@pytest.mark.parametrize("text, match", [
    ("a_psnr,b_psnr\n0.9,0.8\n", "no 'preferred' column"),
    ("a_psnr,b_ssim,preferred\n0.9,0.8,a\n", "line 1, column 'a_psnr': has no partner column b_psnr"),
    ("a_psnr,b_psnr,preferred,note\n0.9,0.8,a,x\n", "line 1, column 'note': unknown column"),
    ("a_psnr,b_psnr,preferred\n0.9,0.8,a\n0.9,oops,b\n", "line 3, column 'b_psnr': 'oops' is not a number"),
    ("a_psnr,b_psnr,preferred\n0.9,0.8,c\n", "line 2, column 'preferred': expected 'a' or 'b'"),
    ("a_psnr,b_psnr,preferred,expert\n0.9,0.8,a,\n", "line 2, column 'expert': empty"),
    ("a_psnr,b_psnr,preferred\n0.9,0.8\n", "line 2: 2 cells, expected 3"),
    ("a_psnr,b_psnr,preferred\n", "no judgement rows"),
    ("", "empty file"),
])
def test_judgement_csv_errors_name_the_line_and_column(tmp_path, text, match):
    path = tmp_path / "j.csv"
    path.write_text(text)
    with pytest.raises(FidelityError, match=match) as error:
        read_judgements(path)
    assert str(path) in str(error.value)
    with pytest.raises(FidelityError, match="cannot read"):
        read_judgements(tmp_path / "missing.csv")


def test_fuzzy_reexports_the_expert_functions():
    from irfidelity import judgements
    assert irf.fuzzy.fit_weights is judgements.fit_weights and irf.fuzzy.combine_ahp is judgements.combine_ahp
    assert {"fit_weights", "combine_ahp"} <= set(irf.fuzzy.__all__)
