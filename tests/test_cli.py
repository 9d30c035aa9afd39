"""Command line: `irfidelity score` / `irfidelity demo` (exit codes, JSON = API, no tracebacks)."""

from __future__ import annotations

import csv
import json
import pathlib
import shutil
import subprocess
import sys
import types

import numpy as np
import pytest

from irfidelity.cli import main
from irfidelity.evaluation import evaluate
from irfidelity.fuzzy import Weights

DATA = pathlib.Path(__file__).parent / "data"
REAL = str(DATA / "thermal" / "ptw_bb150C_frame000.png")
SIM = str(DATA / "thermal" / "ptw_bb150C_frame001.png")
SMALL = str(DATA / "thermal" / "cptv_v2_frame000.png")
EDGE_R = str(DATA / "curves" / "sfr_edge_x2084_y0616_F2.png")
EDGE_S = str(DATA / "curves" / "sfr_edge_x2088_y0616_F2_8.png")


def run(*args, check_rc=None):
    p = subprocess.run([sys.executable, "-m", "irfidelity.cli", *args], capture_output=True, text=True, timeout=120)
    if check_rc is not None:
        assert p.returncode == check_rc, (p.returncode, p.stdout, p.stderr)
    return p


def assert_user_error(p, *needles):
    assert p.returncode == 2, (p.stdout, p.stderr)
    assert "Traceback" not in p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    for n in needles:
        assert n in lines[0], lines[0]


# --------------------------------------------------------------------------- score
def test_a_warning_is_printed_once(capsys):
    """The summary prints a warning as a note; stderr repeats it only when no summary is printed."""
    assert main(["score", SMALL, SMALL.replace("000", "001")]) == 0
    out, err = capsys.readouterr()
    assert out.count("PeakWarning") == 1 and "PeakWarning" not in err
    assert main(["score", SMALL, SMALL.replace("000", "001"), "--json", "-"]) == 0
    out, err = capsys.readouterr()
    assert err.count("PeakWarning") == 1 and "irfidelity: warning" in err


def test_score_table():
    p = run("score", REAL, SIM, "--bits", "14", check_rc=0)
    out = p.stdout
    for word in ("psnr", "nmi", "ssim", "fidelity", "grade", "scene:", "not assessed: noise"):
        assert word in out
    assert "Traceback" not in p.stderr


def test_json_equals_api(tmp_path):
    p = run("score", REAL, SIM, "--bits", "14", "--weights", "image_quality", "--json", "-", check_rc=0)
    got = json.loads(p.stdout)
    api = evaluate(REAL, SIM, bits=14, weights="image_quality", missing="renormalize").to_dict()
    assert got == json.loads(json.dumps(api))
    # to a file, with a CSV row too
    out = tmp_path / "r.json"
    run("score", REAL, SIM, "--bits", "14", "--json", str(out), "--csv", str(tmp_path / "r.csv"), check_rc=0)
    assert json.loads(out.read_text())["fidelity"] == pytest.approx(
        evaluate(REAL, SIM, bits=14, missing="renormalize").fidelity, rel=0, abs=0)
    rows = list(csv.DictReader(open(tmp_path / "r.csv")))
    assert len(rows) == 1 and float(rows[0]["fidelity"]) == json.loads(out.read_text())["fidelity"]


def test_edges_and_curves(tmp_path):
    x = np.linspace(0, 1, 20)
    np.savetxt(tmp_path / "r.csv", np.column_stack([x, 5 * x]), delimiter=",")
    np.savetxt(tmp_path / "s.csv", np.column_stack([x, 4.5 * x + 0.1]), delimiter=",")
    p = run("score", REAL, SIM, "--bits", "14", "--real-edge", EDGE_R, "--sim-edge", EDGE_S, "--edge-channel", "R",
            "--real-sitf", str(tmp_path / "r.csv"), "--sim-sitf", str(tmp_path / "s.csv"), "--missing", "raise",
            "--json", "-", check_rc=0)
    d = json.loads(p.stdout)
    assert set(d["components"]) == {"mtf", "sitf", "psnr", "nmi", "ssim"} and d["skipped"] == {}
    assert d["metrics"]["sitf_slope_real"] == pytest.approx(5)


@pytest.mark.parametrize("args,needles", [
    (["score", REAL, "no/such/file.png"], ["no/such/file.png"]),
    (["score", REAL, SMALL], ["differ in shape", REAL, SMALL]),
    (["score", REAL, SIM, "--weights", "mtf=2"], ["--weights", "sum to 1"]),
    (["score", REAL, SIM, "--weights", "fast"], ["--weights", "fast"]),
    (["score", REAL, SIM, "--bits", "12"], ["outside the valid range", REAL]),
    (["score", REAL, SIM, "--bits", "x"], ["--bits"]),
    (["score", REAL, SIM, "--bins", "0"], ["--bins"]),
    (["score", REAL, SIM, "--bits", "12", "--peak", "3"], ["outside the valid range", REAL]),  # bits still bound
    (["score", REAL, SIM, "--real-mtf", "a.csv"], ["--sim-mtf", "--sim-edge"]),
    (["score", REAL, SIM, "--real-edge", "a.png", "--real-mtf", "b.csv"], ["--real-mtf", "--real-edge"]),
    (["score", REAL, SIM, "--real-sitf-columns", "T,counts"], ["--real-sitf-columns", "--real-sitf"]),
    (["score", REAL, SIM, "--peak", "-3"], ["--peak", "positive"]),
    (["score", REAL, SIM, "--pages", "1:4"], ["--pages", "sequences"]),
    (["score", REAL, SIM, "--config", "nope.toml"], ["nope.toml"]),
    (["score", REAL, SIM, "--real-sitf", "a.csv", "--sim-sitf", "b.csv"], ["a.csv"]),
    (["score", REAL, SIM, "--missing", "raise", "--weights", "psnr=0.5,noise=0.5"], ["real_noise/sim_noise", "--missing"]),
    (["score", REAL, SIM, "--real-edge", EDGE_R, "--sim-edge", EDGE_S], ["channel", EDGE_R]),
    (["score", REAL], ["SIM"]),
    (["score", str(DATA / "thermal"), SIM], ["directory"]),
    (["frobnicate"], ["frobnicate"]),
])
def test_user_errors_exit_2(args, needles):
    assert_user_error(run(*args), *needles)


def test_corrupt_file_exit_2(tmp_path):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    assert_user_error(run("score", str(bad), SIM), "bad.png")


@pytest.mark.parametrize("args", [["--help"], ["score", "--help"], ["demo", "--help"]])
def test_help(args):
    p = run(*args, check_rc=0)
    assert "usage:" in p.stdout


def test_no_command():
    assert run().returncode == 2


# --------------------------------------------------------------------------- demo
def test_demo():
    p = run("demo", check_rc=0)
    assert "fidelity" in p.stdout and "Traceback" not in p.stderr
    line = [s for s in p.stdout.splitlines() if s.startswith("fidelity")][0]
    fid = float(line.split()[1])
    assert 0 < fid < 1
    d = json.loads(run("demo", "--json", "-", check_rc=0).stdout)
    assert d["fidelity"] == pytest.approx(fid, abs=5e-5)
    assert set(d["components"]) == {"mtf", "sitf", "psnr", "nmi", "ssim"}


def test_demo_is_deterministic():
    from irfidelity.demo import run_demo

    a, b = run_demo(out=None), run_demo(out=None)
    assert a.to_dict() == b.to_dict()
    assert a.metrics["mtf50_sim"] < a.metrics["mtf50_real"]  # the model blurs


def test_camera_model_blur_matches_reference():
    from irfidelity.demo import gaussian_blur

    rng = np.random.default_rng(3)
    img = rng.random((20, 30))
    sigma = 1.3
    r = 4
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    pad = np.pad(img, r, mode="reflect")
    ref = np.array([[np.sum(np.outer(k, k) * pad[i:i + 2 * r + 1, j:j + 2 * r + 1]) for j in range(30)]
                    for i in range(20)])
    assert np.allclose(gaussian_blur(img, sigma), ref, atol=1e-12)
    assert gaussian_blur(np.full((9, 9), 7.0), 2.0) == pytest.approx(np.full((9, 9), 7.0))


# --------------------------------------------------------------------------- sequences (engine faked)
@pytest.fixture
def fake_sequence(monkeypatch):
    calls = []

    class Rep:
        def __init__(self, failed):
            self.failed = failed

        def to_dict(self):
            return {"failed": self.failed, "frames": []}

        config = None

        def summary_text(self):
            return f"{len(self.failed)} failed"

    def score_sequence(real, sim, **kw):
        calls.append((real, sim, kw))
        return Rep(kw.pop("_failed", [] if "ok" in real else [3]))

    mod = types.ModuleType("irfidelity.sequence")
    mod.score_sequence = score_sequence
    monkeypatch.setitem(sys.modules, "irfidelity.sequence", mod)
    return calls


def test_sequence_branch(fake_sequence, tmp_path, capsys):
    (tmp_path / "ok_r").mkdir()
    (tmp_path / "ok_s").mkdir()
    rc = main(["score", str(tmp_path / "ok_r"), str(tmp_path / "ok_s"), "--bits", "14", "--workers", "2",
               "--no-progress", "--csv", str(tmp_path / "f.csv"), "--resume", "--weights", "image_quality"])
    assert rc == 0
    real, sim, kw = fake_sequence[0]
    cfg = kw["config"]
    assert cfg.bits == 14 and kw["workers"] == 2 and kw["progress"] is False and kw["resume"] is True
    assert kw["csv"] == str(tmp_path / "f.csv") and cfg.bins == 256 and cfg.real_channel is None
    assert cfg.weights == Weights.image_quality()  # the sequence drops components without inputs itself
    assert "0 failed" in capsys.readouterr().out


def test_sequence_usage_errors(fake_sequence, tmp_path, capsys):
    assert main(["score", str(tmp_path), SIM]) == 2
    assert "REAL is a sequence" in capsys.readouterr().err
    assert main(["score", str(tmp_path), str(tmp_path), "--real-sitf", "a.csv"]) == 2
    assert "--sim-sitf" in capsys.readouterr().err
    assert fake_sequence == []


def test_sequence_takes_the_camera(fake_sequence, tmp_path, capsys):
    # curves and edges go to score_sequence (they count for every frame), in any mix
    rc = main(["score", str(tmp_path), str(tmp_path), "--real-sitf", "a.csv", "--sim-sitf", "b.csv",
               "--real-mtf", "r.csv", "--sim-edge", EDGE_S, "--edge-channel", "R", "--no-progress"])
    assert rc == 3  # the fake reports a failed frame for paths without "ok"
    _, _, kw = fake_sequence[0]
    assert (kw["real_sitf"], kw["sim_sitf"], kw["real_mtf"], kw["sim_mtf"]) == ("a.csv", "b.csv", "r.csv", EDGE_S)
    assert kw["config"].edge_channel == "R" and kw["config"].weights.mtf == pytest.approx(0.2)


def test_sequence_with_curves_end_to_end(tmp_path):
    # the real engine: 3 frame pairs, an SiTF pair and the edge crops
    rdir, sdir = tmp_path / "r", tmp_path / "s"
    rdir.mkdir()
    sdir.mkdir()
    for i in range(3):
        shutil.copy(REAL, rdir / f"f{i}.png")
        shutil.copy(SIM, sdir / f"f{i}.png")
    x = np.linspace(0, 1, 20)
    np.savetxt(tmp_path / "r.csv", np.column_stack([x, 5 * x]), delimiter=",")
    np.savetxt(tmp_path / "s.csv", np.column_stack([x, 4.5 * x + 0.1]), delimiter=",")
    p = run("score", str(rdir), str(sdir), "--bits", "14", "--real-edge", EDGE_R, "--sim-edge", EDGE_S,
            "--edge-channel", "R", "--real-sitf", str(tmp_path / "r.csv"), "--sim-sitf", str(tmp_path / "s.csv"),
            "--missing", "raise", "--no-progress", "--json", "-", check_rc=0)
    d = json.loads(p.stdout)
    pair = evaluate(REAL, SIM, bits=14, real_mtf=EDGE_R, sim_mtf=EDGE_S, edge_channel="R",
                    real_sitf=str(tmp_path / "r.csv"), sim_sitf=str(tmp_path / "s.csv"))
    assert {k: d["components"][k] for k in ("mtf", "sitf")} == {k: pair.components[k] for k in ("mtf", "sitf")}
    assert d["metrics"]["sitf_slope_real"] == pytest.approx(5)
    assert [f["fidelity"] for f in d["frames"]] == [pair.fidelity] * 3
    assert d["fidelity"] == pytest.approx(pair.fidelity, rel=1e-12)
