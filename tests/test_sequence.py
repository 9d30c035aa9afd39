"""Sequences (issue 6): score_sequence over files (Rust engine), arrays (Python loop) and a
Dask cluster; per-frame values vs the single-pair API, exact pooled PSNR, failed frames,
CSV streaming and resume after an interruption.

Data: the real 100-frame Lepton recording (multi-page uint16 TIFF) and 12 consecutive
Lepton frames as 16-bit PNG (tests/data/thermal, see tests/data/README.md). "Simulated"
sequences are the real frames plus seeded noise and a gain, written into tmp_path.
"""

from __future__ import annotations

import csv
import math
import pathlib
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from fractions import Fraction

import numpy as np
import pytest

import irfidelity as irf
from irfidelity import _core
from irfidelity.errors import FidelityError
from irfidelity.evaluation import evaluate
from irfidelity.metrics import psnr_from_mse
from irfidelity.sequence import SequenceReport, score_sequence
from irfidelity.sequence.plan import SequenceRequest
from irfidelity.stats import PairRequest
from scene_off import NO_SCENE

tifffile = pytest.importorskip("tifffile")
cv2 = pytest.importorskip("cv2")

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
STACK = DATA / "cptv_v2_all100frames_uint16.tif"
PNGS = [DATA / f"cptv_v2_frame{i:03d}.png" for i in range(12)]


def _simulate(frames: np.ndarray, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = frames.astype(np.int64) * 1.01 - 20 + rng.normal(0, 6, frames.shape)
    return np.clip(np.rint(x), 0, 16383).astype(np.uint16)


@pytest.fixture(scope="module")
def lepton(tmp_path_factory):
    """(real tif path, sim tif path, real array, sim array) for the 100-frame recording."""
    real = tifffile.imread(STACK)
    assert real.shape == (100, 120, 160) and real.dtype == np.uint16
    sim = _simulate(real, 1)
    d = tmp_path_factory.mktemp("lepton")
    path = d / "sim.tif"
    tifffile.imwrite(path, sim, compression="zlib")
    return STACK, path, real, sim


@pytest.fixture()
def png_dirs(tmp_path):
    """Directories of 12 real and 12 simulated 16-bit PNG frames."""
    rdir, sdir = tmp_path / "real", tmp_path / "sim"
    rdir.mkdir()
    sdir.mkdir()
    real = []
    for i, p in enumerate(PNGS):
        shutil.copy(p, rdir / f"frame_{i}.png")
        real.append(cv2.imread(str(p), cv2.IMREAD_UNCHANGED))
    sim = _simulate(np.stack(real), 7)
    for i, s in enumerate(sim):
        assert cv2.imwrite(str(sdir / f"frame_{i}.png"), s)
    return rdir, sdir, np.stack(real), sim


def _frame_metrics(frame: dict) -> dict:
    keys = ("n", "mse", "psnr_db", "ssim", "ssim_luminance", "ssim_contrast", "ssim_structure", "nmi", "mi",
            "h_real", "h_sim", "h_joint")
    return {k: frame["metrics"][k] for k in keys if k in frame["metrics"]}


# --------------------------------------------------------------------------- per frame
@pytest.mark.parametrize("workers", [1, 2])
def test_per_frame_values_equal_the_single_pair_api(lepton, workers):
    real_path, sim_path, real, sim = lepton
    rep = score_sequence(real_path, sim_path, bits=14, workers=workers, progress=False, **NO_SCENE)
    assert isinstance(rep, SequenceReport)
    assert len(rep.frames) == 100 and rep.failed == []
    assert [f["index"] for f in rep.frames] == list(range(100))
    assert rep.frames[3]["real"] == "cptv_v2_all100frames_uint16.tif[3]"
    assert rep.frames[3]["sim"] == "sim.tif[3]"
    for i in (0, 1, 37, 99):
        f = rep.frames[i]
        st = irf.pair_stats(real[i], sim[i], bits=14)
        want = st.metrics()
        assert _frame_metrics(f) == want, i  # identical, not approximately
        one = evaluate(real[i], sim[i], bits=14, ceiling=rep.ceiling, **NO_SCENE)  # against the sequence's ceiling
        assert f["components"] == one.components
        assert f["grade"] == one.grade and f["component_grades"] == one.component_grades
        assert f["fidelity"] == one.fidelity
        assert (f["rows"], f["cols"], f["dtype"]) == (120, 160, "uint16")
        assert f["error"] is None


def test_arrays_and_files_agree(lepton):
    real_path, sim_path, real, sim = lepton
    a = score_sequence(real[:20], sim[:20], bits=14, progress=False, **NO_SCENE)  # the scene of 20 frames, not 100
    b = score_sequence(real_path, sim_path, bits=14, progress=False, **NO_SCENE)
    assert a.frames[:20] == [dict(f, real=f"[{i}]", sim=f"[{i}]") for i, f in enumerate(b.frames[:20])]
    # list of 2-D arrays
    c = score_sequence(list(real[:3]), list(sim[:3]), bits=14, progress=False, **NO_SCENE)
    assert [f["fidelity"] for f in c.frames] == [f["fidelity"] for f in a.frames[:3]]


# --------------------------------------------------------------------------- pooled
def test_pooled_psnr_is_exact_from_summed_errors(lepton):
    real_path, sim_path, real, sim = lepton
    rep = score_sequence(real_path, sim_path, bits=14, progress=False)
    # reference with Python ints: ΣSSE and ΣN over all frames
    sse = sum(int(((r.astype(np.int64) - s.astype(np.int64)) ** 2).sum()) for r, s in zip(real, sim))
    n = real.size
    peak = 2**14 - 1
    assert rep.metrics["n"] == n and rep.pooling["n"] == n and rep.pooling["frames"] == 100
    assert rep.metrics["mse"] == float(Fraction(sse, n))  # one rounding of the exact ratio
    assert rep.metrics["psnr_db"] == psnr_from_mse(float(Fraction(sse, n)), peak)
    exact = 10 * math.log10(Fraction(peak * peak * n, sse))
    assert rep.metrics["psnr_db"] == pytest.approx(exact, rel=1e-15, abs=0)
    # not a mean of dB values
    mean_db = np.mean([f["metrics"]["psnr_db"] for f in rep.frames])
    assert rep.metrics["psnr_db"] != mean_db
    assert rep.frame_stats["metrics"]["psnr_db"]["mean"] == pytest.approx(mean_db, rel=1e-15)


def test_pooled_errors_equal_one_pass_and_nmi_ssim_are_pixel_means(lepton):
    """With shared histogram edges too: the pooled squared error is that of the whole recording;
    NMI and SSIM are the pixel-weighted means of the frames' (not of one merged histogram or
    of the pooled moments), so they lie within the frames' values."""
    real_path, sim_path, real, sim = lepton
    rep = score_sequence(real_path, sim_path, bits=14, hist_range="full", workers=2, progress=False)
    whole = irf.pair_stats(real.reshape(-1, 160), sim.reshape(-1, 160), bits=14, hist_range="full")
    want = whole.metrics()
    assert {k: rep.metrics[k] for k in ("n", "mse", "psnr_db")} == {k: want[k] for k in ("n", "mse", "psnr_db")}
    assert rep.pooling["nmi"] == rep.pooling["ssim"] == "pixel_mean"
    for key in ("nmi", "mi", "h_joint", "ssim", "ssim_contrast"):
        frames = [f["metrics"][key] for f in rep.frames]
        assert rep.metrics[key] == pytest.approx(math.fsum(frames) / len(frames), rel=1e-15), key
        assert min(frames) <= rep.metrics[key] <= max(frames)


def test_default_hist_range_pools_nmi_as_pixel_mean(lepton):
    real_path, sim_path, real, sim = lepton
    rep = score_sequence(real_path, sim_path, bits=14, progress=False)
    assert rep.pooling["nmi"] == "pixel_mean"
    assert rep.metrics["nmi"] == pytest.approx(np.mean([f["metrics"]["nmi"] for f in rep.frames]), rel=1e-15)
    s = rep.frame_stats["fidelity"]
    assert s["p5"] <= s["p50"] <= s["p95"] and s["min"] <= s["mean"] <= s["max"]
    assert set(rep.frame_stats["metrics"]) >= {"mse", "psnr_db", "ssim", "nmi"}
    assert set(rep.frame_stats["components"]) == {"mtf", "sitf", "psnr", "nmi", "ssim"}  # mtf, sitf from the scene
    assert {rep.metrics[f"{k}_source"] for k in ("mtf", "sitf")} == {"scene"}
    text = rep.summary_text()
    assert "100 scored, 0 failed" in text and "fidelity" in text and "paired by page" in text
    d = rep.to_dict()
    assert d["failed"] == [] and len(d["frames"]) == 100 and d["weights"]["mtf"] == 0.2
    assert d["transfer"]["tiles"] > 0 and d["transfer"]["noise_source"] == "sequence"
    assert d["irfidelity"] == irf.__version__ and d["config"]["bits"] == 14
    back = SequenceReport.from_dict(d)
    assert back.to_dict() == d


def test_only_the_plan_is_computed(lepton):
    real_path, sim_path, _, _ = lepton
    rep = score_sequence(real_path, sim_path, bits=14, weights="psnr=1", progress=False)
    f = rep.frames[0]
    assert "psnr_db" in f["metrics"] and "ssim" not in f["metrics"] and "nmi" not in f["metrics"]
    assert set(f["components"]) == {"psnr"}
    assert rep.columns == ["index", "real", "sim", "rows", "cols", "dtype", "n", "masked", "nonfinite", "mse",
                           "psnr_db", "psnr_peak", "f_psnr", "fidelity", "grade", "error"]
    # the engine itself skips moments and histograms
    out = _core.score_pairs([str(real_path)], [str(real_path)], [0], [1],
                            request=SequenceRequest(PairRequest(sse=True, moments=False, bins=None)))
    (_, st, err, shape, dtype, extent, registration, fingerprints), = out
    assert extent is None and registration is None and fingerprints is None  # not asked for
    assert err is None and st.has_sse and not st.has_moments and not st.has_hist


# --------------------------------------------------------------------------- errors
def test_mismatched_counts_fail_before_any_work(lepton, tmp_path):
    real_path, _, real, sim = lepton
    out = tmp_path / "rows.csv"
    with pytest.raises(FidelityError, match=r"100 frames and the simulated sequence 99"):
        score_sequence(real, sim[:99], csv=out, progress=False)  # arrays have no names to pair by
    assert not out.exists()
    with pytest.raises(FidelityError, match="3 frames and the simulated sequence 2"):
        _core.score_pairs(["a", "b", "c"], ["a", "b"], request=SequenceRequest())


def test_truncated_frame_fails_alone(png_dirs, tmp_path):
    rdir, sdir, real, sim = png_dirs
    bad = sdir / "frame_5.png"
    data = bad.read_bytes()
    bad.write_bytes(data[: len(data) // 3])
    out = tmp_path / "rows.csv"
    rep = score_sequence(rdir, sdir, bits=14, workers=2, csv=out, progress=False)
    assert rep.failed == [5]
    assert "frame_5.png" in rep.frames[5]["error"]
    assert rep.frames[5]["fidelity"] is None and rep.frames[5]["metrics"] == {}
    for i in range(12):
        if i != 5:
            assert rep.frames[i]["error"] is None
            assert _frame_metrics(rep.frames[i]) == irf.pair_stats(real[i], sim[i], bits=14).metrics()
    assert rep.pooling["frames"] == 11 and rep.pooling["n"] == 11 * real[0].size
    rows = list(csv.DictReader(open(out)))
    assert sorted(int(r["index"]) for r in rows) == list(range(12))
    assert [r["error"] != "" for r in sorted(rows, key=lambda r: int(r["index"]))] == [i == 5 for i in range(12)]
    assert "1 failed" in rep.summary_text()


def test_shape_and_range_errors_are_rows(png_dirs):
    rdir, sdir, real, sim = png_dirs
    cv2.imwrite(str(sdir / "frame_2.png"), sim[2][:, :100].copy())
    rep = score_sequence(rdir, sdir, bits=14, progress=False)
    assert rep.failed == [2] and "shape" in rep.frames[2]["error"]
    rep = score_sequence(rdir, sdir, bits=11, progress=False)  # values above 2047 everywhere
    assert rep.failed == list(range(12))
    assert "outside the valid range [0, 2047]" in rep.frames[0]["error"]
    assert rep.pooling["frames"] == 0 and rep.fidelity is None and rep.grade is None


def test_bad_arguments(lepton):
    real_path, sim_path, _, _ = lepton
    with pytest.raises(FidelityError, match="resuming needs the CSV"):
        score_sequence(real_path, sim_path, resume=True, progress=False)
    with pytest.raises(FidelityError, match="bits must be"):
        score_sequence(real_path, sim_path, bits=17, progress=False)
    with pytest.raises(FidelityError, match="hist_range"):
        score_sequence(real_path, sim_path, hist_range="everything", progress=False)


# --------------------------------------------------------------------------- CSV and resume
def _rows(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_csv_rows_match_report_and_to_csv(lepton, tmp_path):
    real_path, sim_path, _, _ = lepton
    out = tmp_path / "stream.csv"
    rep = score_sequence(real_path, sim_path, bits=14, csv=out, workers=2, progress=False)
    streamed = sorted(_rows(out), key=lambda r: int(r["index"]))
    rep.to_csv(tmp_path / "after.csv")
    written = _rows(tmp_path / "after.csv")
    assert streamed == written
    assert len(written) == 100
    assert float(written[7]["fidelity"]) == rep.frames[7]["fidelity"]
    assert float(written[7]["psnr_db"]) == rep.frames[7]["metrics"]["psnr_db"]
    assert written[7]["grade"] == rep.frames[7]["grade"]


def test_resume_after_an_interruption(lepton, tmp_path):
    real_path, sim_path, _, _ = lepton
    full = score_sequence(real_path, sim_path, bits=14, progress=False)
    out = tmp_path / "rows.csv"

    class Stop(Exception):
        pass

    def stop_after_30(done, total):
        if done >= 30:
            raise Stop

    with pytest.raises(Stop):
        score_sequence(real_path, sim_path, bits=14, csv=out, workers=2, progress=stop_after_30)
    first = _rows(out)
    assert 30 <= len(first) < 100
    # a row cut off mid-write by a kill, without its newline
    with open(out, "a") as f:
        f.write("99,cptv_v2_all100frames_uint16.tif[99],sim.tif[99],120,160,uint16,19200,3.5")
    seen = []
    rep = score_sequence(real_path, sim_path, bits=14, csv=out, resume=True, progress=lambda d, t: seen.append(d))
    assert seen[0] == len(first) + 1 and seen[-1] == 100  # only the rest was scored
    rows = _rows(out)
    idx = [int(r["index"]) for r in rows]
    assert sorted(idx) == list(range(100))  # no duplicate, no missing row
    assert rep.frames == full.frames
    assert rep.metrics == full.metrics and rep.fidelity == full.fidelity
    assert rep.run["resumed"] == len(first)
    # resuming a finished run scores nothing
    again = score_sequence(real_path, sim_path, bits=14, csv=out, resume=True, progress=False)
    assert again.metrics == full.metrics and len(_rows(out)) == 100 and again.run["resumed"] == 100


def test_resume_rescores_failed_frames_without_duplicates(png_dirs, tmp_path):
    rdir, sdir, _, sim = png_dirs
    good = (sdir / "frame_3.png").read_bytes()
    (sdir / "frame_3.png").write_bytes(good[:200])
    out = tmp_path / "rows.csv"
    assert score_sequence(rdir, sdir, bits=14, csv=out, progress=False).failed == [3]
    (sdir / "frame_3.png").write_bytes(good)  # fixed
    rep = score_sequence(rdir, sdir, bits=14, csv=out, resume=True, progress=False)
    assert rep.failed == []
    rows = _rows(out)
    assert sorted(int(r["index"]) for r in rows) == list(range(12))
    assert all(r["error"] == "" for r in rows)


def test_resume_refuses_other_settings(lepton, tmp_path):
    real_path, sim_path, _, _ = lepton
    out = tmp_path / "rows.csv"
    score_sequence(real_path, sim_path, bits=14, csv=out, progress=False, weights="psnr=0.5,ssim=0.5")
    with pytest.raises(FidelityError, match="cannot resume"):
        score_sequence(real_path, sim_path, bits=14, csv=out, resume=True, progress=False)
    with pytest.raises(FidelityError, match="cannot resume"):
        score_sequence(real_path, sim_path, bits=12, csv=out, resume=True, progress=False,
                       weights="psnr=0.5,ssim=0.5")


_KILL_SCRIPT = textwrap.dedent(
    """
    import sys, time
    from irfidelity.sequence import score_sequence
    def slow(done, total):
        time.sleep(0.03)
    score_sequence(sys.argv[1], sys.argv[2], bits=14, csv=sys.argv[3], workers=2, progress=slow)
    """
)


def test_resume_after_kill(lepton, tmp_path):
    real_path, sim_path, _, _ = lepton
    out = tmp_path / "killed.csv"
    proc = subprocess.Popen([sys.executable, "-c", _KILL_SCRIPT, str(real_path), str(sim_path), str(out)])
    try:
        deadline = time.time() + 60
        while time.time() < deadline:
            if out.exists() and out.read_text().count("\n") >= 25:
                break
            time.sleep(0.01)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait()
    n_before = out.read_text().count("\n") - 1
    assert 0 < n_before < 100, "the run was not interrupted"
    rep = score_sequence(real_path, sim_path, bits=14, csv=out, resume=True, progress=False)
    idx = sorted(int(r["index"]) for r in _rows(out))
    assert idx == list(range(100))
    full = score_sequence(real_path, sim_path, bits=14, progress=False)
    assert rep.frames == full.frames and rep.metrics == full.metrics


# --------------------------------------------------------------------------- progress
def test_progress_reaches_python_and_tqdm_is_optional(lepton, monkeypatch):
    real_path, sim_path, _, _ = lepton
    calls = []
    out = _core.score_pairs([str(real_path)] * 40, [str(sim_path)] * 40, list(range(40)), list(range(40)),
                            workers=2, progress=calls.append, request=SequenceRequest(PairRequest(bins=256)))
    assert len(out) == 40 and calls and calls[-1] == 40 and calls == sorted(calls)
    # progress=True without tqdm: no bar, no error
    import builtins

    real_import = builtins.__import__

    def no_tqdm(name, *a, **k):
        if name.startswith("tqdm"):
            raise ImportError(name)
        return real_import(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_tqdm)
    rep = score_sequence(real_path, sim_path, bits=14, progress=True)
    assert rep.failed == []


def test_callback_errors_stop_the_engine(lepton):
    real_path, sim_path, _, _ = lepton
    got = []

    def on_result(batch):
        got.extend(batch)
        raise RuntimeError("stop")

    with pytest.raises(RuntimeError, match="stop"):
        _core.score_pairs([str(real_path)] * 100, [str(sim_path)] * 100, list(range(100)), list(range(100)),
                          workers=1, on_result=on_result, request=SequenceRequest())
    assert 1 <= len(got) < 100


# --------------------------------------------------------------------------- Dask
def test_dask_local_cluster_gives_identical_results(lepton, tmp_path):
    distributed = pytest.importorskip("distributed")
    real_path, sim_path, _, _ = lepton
    local = score_sequence(real_path, sim_path, bits=14, hist_range="full", progress=False)
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None,
                                  silence_logs=40) as cluster, distributed.Client(cluster) as client:
        out = tmp_path / "dask.csv"
        remote = score_sequence(real_path, sim_path, bits=14, hist_range="full", client=client, chunk_size=8,
                                csv=out, progress=False)
    assert remote.frames == local.frames
    assert remote.metrics == local.metrics and remote.fidelity == local.fidelity
    assert sorted(int(r["index"]) for r in _rows(out)) == list(range(100))
    # the workers fingerprinted the files they decoded: a resume trusts their records
    resumed = score_sequence(real_path, sim_path, bits=14, hist_range="full", csv=out, resume=True, progress=False)
    assert resumed.run["resumed"] == 100 and resumed.frames == local.frames and resumed.notes == local.notes


_SIGINT_SCRIPT = textwrap.dedent(
    """
    import os
    import signal
    import sys
    import time
    from irfidelity.sequence import score_sequence
    # Ctrl-C as a terminal delivers it, whatever the test process left behind (an ignored or
    # blocked SIGINT is inherited by a child): said on stderr when it had to be restored
    inherited = (signal.getsignal(signal.SIGINT), signal.pthread_sigmask(signal.SIG_BLOCK, []))
    if inherited != (signal.default_int_handler, set()):
        print(f"inherited SIGINT handler and blocked signals: {inherited}", file=sys.stderr)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    real = [sys.argv[1]] * 10  # 1000 frame pairs
    sim = [sys.argv[2]] * 10
    sent = []

    def interrupt():
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)

    def progress(done, total):  # Ctrl-C once 30 frames are done (sent here: a thread may run too late)
        if done >= 30 and not sent:
            interrupt()

    try:
        score_sequence(real, sim, bits=14, csv=sys.argv[3], workers=2, progress=progress)
    except KeyboardInterrupt:
        print(f"interrupted after {time.monotonic() - sent[0]:.3f} s", flush=True)
        sys.exit(130)
    print("finished", flush=True)
    """
)


def test_ctrl_c_stops_the_run_and_resume_completes_it(lepton, tmp_path):
    real_path, sim_path, _, _ = lepton
    out = tmp_path / "sigint.csv"
    proc = subprocess.run([sys.executable, "-c", _SIGINT_SCRIPT, str(real_path), str(sim_path), str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 130 and "interrupted after" in proc.stdout, (proc.stdout, proc.stderr)
    assert float(proc.stdout.split()[2]) < 10
    rows = _rows(out)
    assert 29 <= len(rows) < 1000  # 30 frames were done when the signal was sent
    idx = [int(r["index"]) for r in rows]
    assert len(set(idx)) == len(idx)
    # resume the same (long) run, but only check the rows: no duplicate, no missing
    rep = score_sequence([real_path] * 10, [sim_path] * 10, bits=14, csv=out, resume=True, progress=False)
    assert rep.failed == [] and rep.run["resumed"] == len(rows)
    assert sorted(int(r["index"]) for r in _rows(out)) == list(range(1000))


# --------------------------------------------------------------------------- camera curves
def _sitf_pair():
    t = np.linspace(-20, 60, 41)
    return (t, np.clip(40 * t + 3000, 2400, 4800)), (t, np.clip(43 * t + 2990, 2400, 4800))


def _mtf_pair():
    f = np.linspace(0, 0.5, 26)
    return (f, np.exp(-((f / 0.3) ** 2))), (f, np.exp(-((f / 0.25) ** 2)))


def test_camera_components_enter_every_frame_and_the_pool(png_dirs, tmp_path):
    rdir, sdir, real, sim = png_dirs
    (rm, sm), (rs, ss) = _mtf_pair(), _sitf_pair()
    curves = dict(real_mtf=rm, sim_mtf=sm, real_sitf=rs, sim_sitf=ss)
    out = tmp_path / "rows.csv"
    rep = score_sequence(rdir, sdir, bits=14, progress=False, csv=out, missing="raise", **curves)
    assert rep.failed == [] and rep.skipped == {}
    pair = [evaluate(real[i], sim[i], bits=14, **curves) for i in range(len(real))]
    assert {k: rep.components[k] for k in ("mtf", "sitf")} == {"mtf": pair[0].components["mtf"],
                                                                 "sitf": pair[0].components["sitf"]}
    assert rep.metrics["sitf_slope_real"] == pytest.approx(40) and rep.metrics["mtf50_sim"] > 0
    for f, one in zip(rep.frames, pair):
        assert f["components"] == one.components  # all five, the curves' the same in every frame
        assert f["fidelity"] == one.fidelity
    assert list(rep.components) == ["mtf", "sitf", "psnr", "nmi", "ssim"]
    assert rep.fidelity == pytest.approx(sum(rep.weights[k] * v for k, v in rep.components.items()), rel=1e-15)
    rows = _rows(out)
    assert {float(r["f_mtf"]) for r in rows} == {rep.components["mtf"]}
    assert float(rows[0]["fidelity"]) == next(f for f in rep.frames if f["index"] == int(rows[0]["index"]))["fidelity"]
    assert "MTF50 real" in rep.summary_text()
    # resume keeps the rows (same curves); other curves are other settings
    again = score_sequence(rdir, sdir, bits=14, progress=False, csv=out, resume=True, missing="raise", **curves)
    assert again.run["resumed"] == len(real) and again.fidelity == rep.fidelity
    with pytest.raises(FidelityError, match="other settings"):
        score_sequence(rdir, sdir, bits=14, progress=False, csv=out, resume=True,
                       **dict(curves, sim_sitf=rs))


def test_curves_are_planned_and_fail_before_any_frame(png_dirs, tmp_path):
    rdir, sdir, _, _ = png_dirs
    (rs, ss) = _sitf_pair()
    calls = []
    # weight 0: the curve inputs are not even read (a missing file is no error)
    rep = score_sequence(rdir, sdir, bits=14, progress=False, weights="psnr=0.5,ssim=0.5",
                         real_mtf=tmp_path / "nope.csv", sim_mtf=tmp_path / "nope.csv")
    assert "mtf" not in rep.components and "mtf50_real" not in rep.metrics
    # a bad curve: FidelityError before any frame is scored
    with pytest.raises(FidelityError, match="nope.csv"):
        score_sequence(rdir, sdir, bits=14, progress=lambda d, n: calls.append(d), csv=tmp_path / "x.csv",
                       real_sitf=rs, sim_sitf=tmp_path / "nope.csv")
    assert calls == [] and not (tmp_path / "x.csv").exists()
    with pytest.raises(FidelityError, match="real_sitf"):
        score_sequence(rdir, sdir, bits=14, progress=False, sim_sitf=ss)
    with pytest.raises(FidelityError, match="per-frame components"):
        score_sequence(rdir, sdir, bits=14, progress=False, weights="sitf=1", real_sitf=rs, sim_sitf=ss)


def _reference_columns(rows):
    """The numbers of each key, row by row (the definition FrameColumns reads faster)."""
    columns = {}
    for row in rows:
        for k, v in row.items():
            if isinstance(v, (int, float)):
                columns.setdefault(k, []).append(float(v))
    return columns


@pytest.mark.parametrize("rows", [
    [{"a": 1.5, "b": 2, "c": "scene", "d": True}, {"a": 2.5, "b": 3, "c": "scene", "d": False}],
    [{"a": 1.0, "b": None}, {"a": 2.0, "b": 4.0}, {"a": 3.0, "b": "x"}],  # mixed kinds in one key
    [{"a": 1.0, "b": "1.5"}, {"a": 2.0, "b": "2.5"}],  # number-like strings are not numbers
    [{"a": 1.0}, {"b": 2.0}, {"a": 3.0, "b": 4.0}],  # keys that differ between rows
    [{"a": 2 ** 70}, {"a": 1.0}],  # an integer past int64
    [{"a": 1.0, "v": [1, 2]}, {"a": 2.0, "v": [3, 4]}],  # lists are not numbers
    [{"a": 1.0, "v": [1, 2]}, {"a": 2.0, "v": [3]}],  # nor ragged ones
])
def test_frame_columns_read_every_number_and_only_numbers(rows):
    from irfidelity.sequence.entry import FrameEntry
    from irfidelity.sequence.pooling import FrameColumns

    frames = [FrameEntry(i, components={"x": float(i)}, metrics=row) for i, row in enumerate(rows)]
    frames.append(FrameEntry(len(rows), error="unreadable"))  # a failed frame is left out
    columns = FrameColumns(frames)
    want = _reference_columns(rows)
    assert list(columns.groups["metrics"]) == list(want)
    for key, values in want.items():
        assert columns.groups["metrics"][key].tolist() == values
    # a key every frame shares from the plan is its value in each frame
    fixed = FrameColumns(frames[:-1], {"metrics": {"a": rows[0].get("a")}} if "a" in rows[0] else None)
    if "a" in rows[0] and all("a" in r for r in rows):
        assert fixed.groups["metrics"]["a"].tolist() == [float(rows[0]["a"])] * len(rows)
