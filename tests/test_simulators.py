"""Several simulators against one real recording (issue 29): ``score_simulators`` (one engine
pass, each real frame decoded once), ``report.ci``, the comparison report and the ``rank`` and
``weights fit`` commands."""

from __future__ import annotations

import csv
import json
import pathlib
import subprocess
import sys
import warnings

import numpy as np
import pytest
import tifffile
from scipy.ndimage import gaussian_filter

import irfidelity as irf
from irfidelity import _core
from irfidelity.errors import FidelityError
from irfidelity.sequence import RunOptions
from irfidelity.sequence.intervals import sequence_intervals
from irfidelity.sequence.plan import SequenceRequest
from irfidelity.simulators import compare_reports

DATA = pathlib.Path(__file__).parent / "data" / "thermal" / "cptv_v2_all100frames_uint16.tif"
WEIGHTS = "psnr=0.4,nmi=0.2,ssim=0.4"
OPTIONS = dict(weights=WEIGHTS, bits=14, peak="range", progress=False)


def degraded(real: np.ndarray, blur: float, sigma: float, seed: int) -> np.ndarray:
    frames = real.astype(np.float64)
    if blur:
        frames = gaussian_filter(frames, (0, blur, blur))
    noisy = frames + np.random.default_rng(seed).normal(0, sigma, real.shape)
    return np.clip(np.rint(noisy), 0, 16383).astype(np.uint16)


@pytest.fixture(scope="module")
def stacks(tmp_path_factory):
    """The real recording and four simulators as multi-page TIFFs (files the engine decodes):
    ``fine`` and ``twin`` the same up to noise, ``mid`` and ``coarse`` more blur and noise."""
    root = tmp_path_factory.mktemp("simulators")
    real = tifffile.imread(DATA)
    sims = {"fine": degraded(real, 0, 3, 1), "twin": degraded(real, 0, 3, 2), "mid": degraded(real, 0.7, 6, 3),
            "coarse": degraded(real, 1.5, 12, 4)}
    paths = {}
    for name, frames in sims.items():
        paths[name] = str(root / f"{name}.tif")
        tifffile.imwrite(paths[name], frames)
    return str(DATA), paths, sims


@pytest.fixture(scope="module")
def compared(stacks):
    real, paths, _ = stacks
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        return irf.score_simulators(real, paths, workers=2, ci=True, **OPTIONS)


# --------------------------------------------------------------------------- the shared pass
def test_shared_pass_gives_the_reports_of_separate_runs(stacks, compared):
    real, paths, _ = stacks
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        for name in ("fine", "coarse"):
            alone = irf.score_sequence(real, paths[name], workers=1, **OPTIONS)
            rep = compared.reports[name]
            assert rep.fidelity == alone.fidelity and rep.components == alone.components
            assert [f["fidelity"] for f in rep.frames] == [f["fidelity"] for f in alone.frames]


def test_order_of_degraded_simulators_is_recovered_and_significant(compared):
    order = compared.order
    assert set(order[:2]) == {"fine", "twin"} and order[2:] == ["mid", "coarse"]
    for better, worse in (("fine", "mid"), ("twin", "mid"), ("mid", "coarse"), ("fine", "coarse")):
        assert compared.significant[(better, worse)], (better, worse)
    twins = ("fine", "twin") if ("fine", "twin") in compared.significant else ("twin", "fine")
    assert not compared.significant[twins]
    # nor does P(first) crown one of them (it resamples the frames with the weights)
    assert all(0.02 < compared.stability.p_first[name] < 0.98 for name in twins), compared.stability.p_first
    # the ranking's estimates are the reports' pooled results (the frames every simulator scored)
    for name, rep in compared.reports.items():
        assert compared.ranking.estimate[name]["fidelity"] == pytest.approx(rep.fidelity, abs=1e-12)
    assert compared.frames == [f["real"] for f in compared.reports["fine"].frames]


def test_arrays_are_ranked_the_same_way(stacks, compared):
    _, _, sims = stacks
    real = tifffile.imread(DATA)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        arrays = irf.score_simulators(real, sims, workers=1, **OPTIONS)
    assert arrays.order == compared.order
    for name in sims:
        assert arrays.reports[name].fidelity == pytest.approx(compared.reports[name].fidelity, abs=1e-12)


def test_score_shared_matches_score_pairs_and_checks_its_tasks():
    request = SequenceRequest(pair=irf.stats.PairRequest(bins=64))
    real_paths, real_pages = [str(DATA)] * 4, [0, 1, 2, 3]
    sim_pages = [5, 6, 7, 8, 9, 10, 11, 12]
    out = _core.score_shared(real_paths, real_pages, [str(DATA)] * 8, sim_pages, [0, 1, 2, 3] * 2, [0] * 8,
                             requests=[request], workers=2)
    alone = _core.score_pairs([str(DATA)] * 8, [str(DATA)] * 8, real_pages * 2, sim_pages, request=request)
    for (k, stats, err, *_), (j, want, _, *_) in zip(out, alone):
        assert k == j and err is None and stats.to_bytes() == want.to_bytes()
    with pytest.raises(FidelityError, match="owner 9"):
        _core.score_shared(real_paths, real_pages, [str(DATA)], [0], [9], [0], requests=[request])


# --------------------------------------------------------------------------- intervals
def test_report_ci_holds_the_pooled_values_and_round_trips(compared):
    rep = compared.reports["mid"]
    assert set(rep.ci) == {"fidelity", "psnr", "nmi", "ssim"}
    assert rep.ci["fidelity"][0] < rep.fidelity < rep.ci["fidelity"][1]
    for component, (lo, hi) in rep.ci.items():
        value = rep.fidelity if component == "fidelity" else rep.components[component]
        assert lo <= value <= hi, component
    assert rep.pooling["ci"]["level"] == 0.95 and "pooled as the sequence pools" in rep.pooling["ci"]["method"]
    back = irf.SequenceReport.from_dict(json.loads(json.dumps(rep.to_dict())))
    assert back.ci == rep.ci
    assert "intervals at 0.95" in rep.summary_text()
    assert 'id="intervals"' in rep.to_html()


def test_score_sequence_ci_option_pools_float_frames_as_the_sequence():
    rng = np.random.default_rng(5)
    real = rng.normal(100.0, 10.0, (20, 16, 16)).astype(np.float32)
    sim = (real + rng.normal(0, 1.0, real.shape)).astype(np.float32)
    rep = irf.score_sequence(real, sim, weights="psnr=0.5,ssim=0.5", peak=100.0, progress=False, ci=0.9)
    assert rep.pooling["ci"]["level"] == 0.9 and "pooled as the sequence pools" in rep.pooling["ci"]["method"]
    for component, (lo, hi) in rep.ci.items():
        assert lo <= (rep.fidelity if component == "fidelity" else rep.components[component]) <= hi, component
    assert irf.score_sequence(real, sim, weights="psnr=1", peak=100.0, progress=False).ci is None
    with pytest.raises(FidelityError, match="level"):
        irf.score_sequence(real, sim, weights="psnr=1", peak=100.0, progress=False, ci=1.5)


def test_intervals_need_two_scored_frames():
    real = np.arange(64, dtype=np.uint16).reshape(1, 8, 8)
    rep = irf.score_sequence(real, real + 1, weights="psnr=1", bits=14, peak="range", progress=False, ci=True)
    assert rep.ci is None and any("no interval" in note for note in rep.notes)
    with pytest.raises(FidelityError, match="at least 2"):
        sequence_intervals(rep)


# --------------------------------------------------------------------------- CSV, resume, errors
def test_per_simulator_csv_and_resume(stacks, tmp_path):
    real, paths, _ = stacks
    two = {name: paths[name] for name in ("fine", "mid")}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        first = irf.score_simulators(real, two, csv=tmp_path / "frames", resamples=199, **OPTIONS)
        again = irf.score_simulators(real, two, csv=str(tmp_path / "frames"), resume=True, resamples=199, **OPTIONS)
    for name in two:
        with open(tmp_path / "frames" / f"{name}.csv", newline="") as fh:
            assert len(list(csv.DictReader(fh))) == 100
        assert again.reports[name].run["resumed"] == 100
        assert again.reports[name].fidelity == first.reports[name].fidelity


@pytest.mark.parametrize("call, match", [
    (lambda real, p: irf.score_simulators(real, {"a": p["fine"]}, **OPTIONS), "at least two"),
    (lambda real, p: irf.score_simulators(real, p, csv="x", resume=False, sim_mtf={"nobody": None}, **OPTIONS),
     "sim_mtf"),
    (lambda real, p: irf.score_simulators(real, {"a/b": p["fine"], "c": p["mid"]}, csv="out", **OPTIONS),
     "cannot name CSV files"),
    (lambda real, p: irf.score_simulators(real, p, resume=True, **OPTIONS), "resuming needs"),
    (lambda real, p: irf.score_simulators(real, p, level=2.0, **OPTIONS), "level"),
    (lambda real, p: irf.score_simulators(real, p, client=object(), **OPTIONS), "no Dask client"),
    (lambda real, p: irf.score_simulators(real, p, run=RunOptions(progress=False), workers=2, weights=WEIGHTS),
     "workers"),
])
def test_mistakes_are_clear_errors(stacks, call, match):
    real, paths, _ = stacks
    with pytest.raises(FidelityError, match=match):
        call(real, paths)


def test_a_failed_frame_is_left_out_of_the_ranking_with_a_note(tmp_path):
    real = tifffile.imread(DATA)[:12]
    real_dir, a_dir, b_dir = (tmp_path / d for d in ("real", "a", "b"))
    for d in (real_dir, a_dir, b_dir):
        d.mkdir()
    import cv2

    for i, frame in enumerate(real):
        cv2.imwrite(str(real_dir / f"f{i:02d}.png"), frame)
        cv2.imwrite(str(a_dir / f"f{i:02d}.png"), degraded(frame[None], 0, 3, i)[0])
        cv2.imwrite(str(b_dir / f"f{i:02d}.png"), degraded(frame[None], 1.0, 8, i)[0])
    (b_dir / "f03.png").write_bytes(b"not a png")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        result = irf.score_simulators(str(real_dir), {"a": str(a_dir), "b": str(b_dir)}, resamples=199, **OPTIONS)
    assert result.reports["b"].failed == [3] and not result.reports["a"].failed
    assert len(result.frames) == 11 and "f03.png" not in result.frames
    assert any("every simulator scored" in note for note in result.notes)
    assert result.order == ["a", "b"]


# --------------------------------------------------------------------------- the comparison report
def test_comparison_html_csv_and_json(compared, tmp_path):
    html = compared.to_html(tmp_path / "rank.html")
    assert (tmp_path / "rank.html").read_text(encoding="utf-8") == html
    for needle in ("What decided the order", "Fidelity frame by frame",
                   "Stability under the frames&#x27; sampling and weight changes",
                   "mid is closer than coarse: significant", "not significant", "data:image/png;base64"):
        assert needle in html, needle
    for name, rep in compared.reports.items():  # the grade column: each simulator's own grade
        assert f"<td>{name}</td><td>{rep.grade}</td>" in html, name
    compared.to_csv(tmp_path / "rank.csv")
    with open(tmp_path / "rank.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["simulator"] for r in rows] == compared.order
    assert [r["grade"] for r in rows] == [compared.reports[n].grade for n in compared.order]
    assert all(float(r["fidelity_lo"]) <= float(r["fidelity"]) <= float(r["fidelity_hi"]) for r in rows)
    data = json.loads(json.dumps(compared.to_dict()))
    assert data["order"] == compared.order and set(data["reports"]) == set(compared.reports)
    assert compare_reports(compared.reports, resamples=199).order == compared.order


# --------------------------------------------------------------------------- the command line
def run(*args):
    return subprocess.run([sys.executable, "-m", "irfidelity.cli", *args], capture_output=True, text=True,
                          timeout=300)


def assert_user_error(p, *needles):
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in p.stderr, p.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


def test_cli_rank(stacks, tmp_path):
    real, paths, _ = stacks
    p = run("rank", real, paths["coarse"], paths["fine"], "--names", "coarse,fine", "--bits", "14", "--peak", "range",
            "--weights", WEIGHTS, "--resamples", "199", "--no-progress", "--json", str(tmp_path / "r.json"),
            "--report", str(tmp_path / "r.html"), "--csv", str(tmp_path / "r.csv"))
    assert p.returncode == 0, p.stderr
    assert "fine − coarse" in p.stdout and "significant" in p.stdout
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["order"] == ["fine", "coarse"]
    assert "What decided the order" in (tmp_path / "r.html").read_text(encoding="utf-8")


def test_cli_rank_mistakes(stacks, tmp_path):
    real, paths, _ = stacks
    assert_user_error(run("rank", real, paths["fine"]), "at least two")
    assert_user_error(run("rank", real, paths["fine"], paths["mid"], "--names", "a"), "--names")
    assert_user_error(run("rank", real, paths["fine"], str(tmp_path / "absent")), "absent", "no such file")
    assert_user_error(run("rank", real, paths["fine"], paths["mid"], "--level", "5"), "--level")


def test_cli_weights_fit(tmp_path):
    rng = np.random.default_rng(7)
    truth = np.array([0.5, 0.2, 0.3])
    lines = ["a_psnr,a_nmi,a_ssim,b_psnr,b_nmi,b_ssim,preferred,expert"]
    for i in range(200):
        a, b = rng.uniform(0.6, 1.0, 3), rng.uniform(0.6, 1.0, 3)
        preferred = "a" if rng.random() < 1 / (1 + np.exp(-80 * truth @ (a - b))) else "b"
        lines.append(",".join(f"{v:.4f}" for v in (*a, *b)) + f",{preferred},{'ann' if i % 2 else 'bob'}")
    path = tmp_path / "judged.csv"
    path.write_text("\n".join(lines) + "\n")
    p = run("weights", "fit", str(path), "--json", "-")
    assert p.returncode == 0, p.stderr
    fitted = json.loads(p.stdout)["weights"]
    assert max(abs(fitted[k] - w) for k, w in zip(("psnr", "nmi", "ssim"), truth)) <= 0.1
    p = run("weights", "fit", str(path), "--save-config", str(tmp_path / "mission.toml"))
    assert p.returncode == 0 and "fitted weights" in p.stdout
    assert irf.ScoringConfig.load(tmp_path / "mission.toml").weights["psnr"] == pytest.approx(fitted["psnr"], abs=1e-9)
    path.write_text("a_psnr,b_psnr,preferred\n0.9,oops,a\n")
    assert_user_error(run("weights", "fit", str(path)), "judged.csv", "line 2", "b_psnr")
    assert_user_error(run("weights", "fit", str(tmp_path / "none.csv")), "none.csv")


def test_each_simulators_curves_enter_its_ranked_fidelity():
    rng = np.random.default_rng(11)
    scene = rng.normal(3000, 200, (30, 24, 24))
    frames = lambda sigma: np.clip(scene + rng.normal(0, sigma, scene.shape), 0, 16383).astype(np.uint16)  # noqa: E731
    x = [0, 0.125, 0.25, 0.375, 0.5]
    mtf = lambda fall: irf.Curve(x, np.exp(-fall * np.array(x)), x_unit="cycles/pixel")  # noqa: E731
    result = irf.score_simulators(frames(5), {"sharp": frames(20), "soft": frames(20)}, real_mtf=mtf(3.0),
                                  sim_mtf={"sharp": mtf(3.1), "soft": mtf(6.0)}, peak="range", progress=False,
                                  weights="mtf=0.5,psnr=0.25,ssim=0.25", resamples=199)
    for name, rep in result.reports.items():
        assert result.ranking.estimate[name]["mtf"] == pytest.approx(rep.components["mtf"], abs=1e-12)
        assert result.ranking.estimate[name]["fidelity"] == pytest.approx(rep.fidelity, abs=1e-12)
    assert result.order == ["sharp", "soft"] and result.reports["sharp"].components["mtf"] > 0.9


def test_the_real_sides_warning_comes_once():
    rng = np.random.default_rng(2)
    real = rng.integers(3000, 3100, (6, 16, 16)).astype(np.uint16)
    sims = {name: (real + k).astype(np.uint16) for k, name in enumerate("abc", start=1)}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        irf.score_simulators(real, sims, bits=14, weights="psnr=1", progress=False, resamples=99)
    peak = [w for w in caught if issubclass(w.category, irf.errors.PeakWarning)]
    assert len(peak) == 1, [str(w.message) for w in caught]


def test_cli_score_ci(stacks, tmp_path):
    real, paths, _ = stacks
    p = run("score", real, paths["mid"], "--bits", "14", "--peak", "range", "--weights", WEIGHTS, "--ci",
            "--no-progress", "--json", str(tmp_path / "s.json"))
    assert p.returncode == 0, p.stderr
    data = json.loads((tmp_path / "s.json").read_text())
    lo, hi = data["ci"]["fidelity"]
    assert lo < data["fidelity"] < hi and "intervals at 0.95" in p.stdout
    single = str(DATA.parent / "cptv_v2_frame000.png")
    assert_user_error(run("score", single, single, "--ci"), "--ci applies to sequences")


def test_run_options_and_a_unit_as_in_score_sequence():
    """``run=RunOptions(...)`` as score_sequence takes it; frames scored in a unit rank pooled
    as the sequence pools, the radiometry component from each frame's errors."""
    rng = np.random.default_rng(3)
    real = gaussian_filter(rng.normal(300.0, 4.0, (12, 24, 24)), (0, 2, 2))
    sims = {"close": real + rng.normal(0.1, 0.05, real.shape), "biased": real + 1.5 + rng.normal(0, 0.05, real.shape)}
    weights = "ssim=0.5,radiometry=0.5"
    result = irf.score_simulators(real, sims, unit="K", weights=weights, run=RunOptions(progress=False, workers=1),
                                  resamples=199, ci=True)
    assert result.order == ["close", "biased"]
    for name, rep in result.reports.items():
        alone = irf.score_sequence(real, sims[name], unit="K", weights=weights, progress=False, workers=1)
        assert rep.fidelity == pytest.approx(alone.fidelity, abs=1e-12)
        assert "radiometry" in rep.components and set(rep.ci) == {"fidelity", "ssim", "radiometry"}
        assert "pooled as the sequence pools" in rep.pooling["ci"]["method"]
        for component, (lo, hi) in rep.ci.items():
            assert lo <= (rep.fidelity if component == "fidelity" else rep.components[component]) <= hi, component
        assert irf.SequenceReport.from_dict(rep.to_dict()).ci == rep.ci


def test_the_real_recordings_plan_is_made_once_for_every_simulator(stacks, monkeypatch):
    """The ceiling of consecutive real frames and the real camera's own transfer are computed
    for the first simulator's plan and reused (irfidelity.reuse); the reports, the scene's
    components among them, are those of separate runs."""
    import irfidelity.sequence.plan as plan
    import irfidelity.system.scene as scene

    real, paths, _ = stacks
    chosen = {name: paths[name] for name in ("fine", "mid", "coarse")}
    options = dict(bits=14, peak="range", progress=False, workers=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        alone = {name: irf.score_sequence(real, path, **options) for name, path in chosen.items()}
        calls = {"ceiling": 0, "spectra": 0}

        def counted(name, function):
            def wrapper(*args, **kwargs):
                calls[name] += 1
                return function(*args, **kwargs)
            return wrapper

        monkeypatch.setattr(plan, "sequence_ceiling", counted("ceiling", plan.sequence_ceiling))
        monkeypatch.setattr(scene, "pair_spectra", counted("spectra", scene.pair_spectra))
        shared = irf.score_simulators(real, chosen, resamples=99, **options)
    assert calls["ceiling"] == 1
    transfer_pairs = calls["spectra"] - 3 * scene.SEQUENCE_PAIRS  # each simulator's own pairs
    assert transfer_pairs == scene.SEQUENCE_PAIRS, calls  # the real camera's own, once
    for name, rep in shared.reports.items():
        assert rep.fidelity == alone[name].fidelity and rep.components == alone[name].components
        assert rep.metrics.get("mtf_ratio") == alone[name].metrics.get("mtf_ratio")
        assert "mtf" in rep.components and "sitf" in rep.components
