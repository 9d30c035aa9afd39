"""Trustworthy by default (issue 14): one scoring configuration, one output schema, the PSNR
peak, the grade, multi-page TIFFs as sequences, and command-line messages in the CLI's words.

Data: real Lepton frames (single 16-bit PNGs and the 100-frame TIFF stack) and two real PTW
blackbody frames, tests/data/thermal (see tests/data/README.md).
"""

from __future__ import annotations

import csv
import json
import pathlib
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.config import ScoringConfig
from irfidelity.errors import FidelityError, PeakWarning
from irfidelity.fuzzy import GradeScale, Weights
from irfidelity.schema import csv_columns
from scene_off import NO_SCENE

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
STACK = DATA / "cptv_v2_all100frames_uint16.tif"
REAL = DATA / "ptw_bb150C_frame000.png"
SIM = DATA / "ptw_bb150C_frame001.png"
LEPTON = [DATA / f"cptv_v2_frame{i:03d}.png" for i in range(3)]


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "irfidelity.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=180, cwd=cwd)


# --------------------------------------------------------------------------- configuration
def test_config_round_trips_through_toml_and_json(tmp_path):
    cfg = ScoringConfig(weights="performance", bits=14, peak="range", bins="levels", hist_range=(0, 16383),
                        psnr_anchors=((20, 0.5), (40, 0.9)), ssim_exponents=(1, 2, 0.5), missing="raise",
                        real_channel="Y", sim_channel="R", ifov_mrad=0.6, register="rigid", max_delay=3,
                        grades=GradeScale(width=0.005), mtf_options={"points": 32})
    for name in ("c.toml", "c.json"):
        cfg.save(tmp_path / name)
        assert ScoringConfig.load(tmp_path / name) == cfg
    assert ScoringConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg


def test_keywords_override_the_config_and_reports_embed_it(tmp_path):
    (tmp_path / "s.toml").write_text('bits = 14\nbins = 64\n[weights]\npsnr = 0.5\nssim = 0.5\n'
                                     'mtf = 0\nsitf = 0\nnmi = 0\n')
    rep = irf.evaluate(LEPTON[0], LEPTON[1], config=tmp_path / "s.toml", bins=32)
    assert rep.config.bits == 14 and rep.config.bins == 32 and set(rep.components) == {"psnr", "ssim"}
    d = rep.to_dict()
    assert d["irfidelity"] == irf.__version__
    assert d["config"]["bits"] == 14 and d["config"]["peak"] is None and d["metrics"]["psnr_peak"] == 16383
    same = irf.evaluate(LEPTON[0], LEPTON[1], config=ScoringConfig.from_dict(d["config"]))
    assert same.to_dict() == d


def test_config_errors_name_the_field(tmp_path):
    with pytest.raises(FidelityError, match="bins: expected") as info:
        ScoringConfig(bins=0)
    assert info.value.option == "bins"
    with pytest.raises(FidelityError, match="unknown scoring option.*bogus"):
        irf.evaluate(LEPTON[0], LEPTON[1], bogus=1)
    (tmp_path / "bad.toml").write_text("bits = \n")
    with pytest.raises(FidelityError, match="bad.toml: not a valid TOML"):
        ScoringConfig.load(tmp_path / "bad.toml")
    (tmp_path / "bad2.toml").write_text('missing = "drop"\n')
    with pytest.raises(FidelityError, match="bad2.toml: missing: expected one of renormalize, raise"):
        ScoringConfig.load(tmp_path / "bad2.toml")


def test_cli_reads_and_writes_the_config(tmp_path):
    (tmp_path / "s.toml").write_text('bits = 14\npeak = "range"\n')
    p = cli("score", LEPTON[0], LEPTON[1], "--config", tmp_path / "s.toml", "--json", tmp_path / "r.json",
            "--save-config", tmp_path / "used.toml")
    assert p.returncode == 0, p.stderr
    d = json.loads((tmp_path / "r.json").read_text())
    assert d["config"]["peak"] == "range" and d["config"]["bits"] == 14
    assert ScoringConfig.load(tmp_path / "used.toml").peak == "range"
    assert "PSNR peak the real frame's max − min" in p.stdout


# --------------------------------------------------------------------------- one schema
def test_single_pair_and_sequence_share_names(tmp_path):
    # with the scene's transfer: a sequence's frames carry the run's, and the camera's own beside it
    pair = irf.evaluate(LEPTON[0], LEPTON[1], bits=14).to_dict()
    seq = irf.score_sequence(LEPTON[:2], LEPTON[1:3], bits=14, progress=False, pair_by="order").to_dict()
    frame = seq["frames"][0]
    assert set(pair["components"]) == set(frame["components"]) == set(seq["components"])
    assert set(frame["metrics"]) - set(pair["metrics"]) == {"scene_gain_ceiling", "scene_mtf50_mismatch_ceiling"}
    # without it, a frame is the pair
    pair = irf.evaluate(LEPTON[0], LEPTON[1], bits=14, **NO_SCENE).to_dict()
    seq = irf.score_sequence(LEPTON[:2], LEPTON[1:3], bits=14, progress=False, pair_by="order", **NO_SCENE).to_dict()
    shared = ("irfidelity", "fidelity", "grade", "components", "component_grades", "membership", "metrics",
              "weights", "skipped", "config", "notes", "inputs")
    assert set(shared) <= set(pair) and set(shared) <= set(seq)
    frame = seq["frames"][0]
    assert set(pair["components"]) == set(frame["components"]) == set(seq["components"])
    assert set(pair["metrics"]) == set(frame["metrics"])
    assert frame["fidelity"] == pair["fidelity"] and frame["metrics"] == pair["metrics"]
    assert frame["grade"] == pair["grade"] and frame["component_grades"] == pair["component_grades"]
    assert irf.ScoringConfig().missing == "renormalize"  # one default everywhere
    # the CSVs: same columns for a single pair and a sequence
    (tmp_path / "no_scene.toml").write_text("[transfer_options]\nscene = false\n")
    assert cli("score", LEPTON[0], LEPTON[1], "--bits", "14", "--config", tmp_path / "no_scene.toml",
               "--csv", tmp_path / "one.csv").returncode == 0
    irf.score_sequence(LEPTON[:2], LEPTON[1:3], bits=14, progress=False, pair_by="order", csv=tmp_path / "seq.csv",
                       **NO_SCENE)
    one = list(csv.DictReader(open(tmp_path / "one.csv")))
    many = list(csv.DictReader(open(tmp_path / "seq.csv")))
    assert list(one[0]) == list(many[0]) == csv_columns(["psnr", "nmi", "ssim"])
    assert {k: v for k, v in one[0].items() if k not in ("real", "sim")} == \
        {k: v for k, v in many[0].items() if k not in ("real", "sim")}


def test_schema_doc_lists_every_column():
    doc = (pathlib.Path(__file__).parent.parent / "docs" / "schema.md").read_text()
    from irfidelity.schema import markdown_table

    assert markdown_table() in doc  # regenerate: python -c "import irfidelity.schema as s; print(s.markdown_table())"
    for col in csv_columns(["mtf", "sitf", "psnr", "nmi", "ssim"]):
        assert f"`{col}`" in doc


def test_sequence_report_round_trips():
    rep = irf.score_sequence(STACK, STACK, bits=14, progress=False, weights="psnr=0.5,ssim=0.5")
    d = json.loads(json.dumps(rep.to_dict(), allow_nan=False))
    back = irf.SequenceReport.from_dict(d)
    assert back.to_dict() == rep.to_dict() and back.grade == rep.grade == "excellent"


# --------------------------------------------------------------------------- PSNR peak
def test_peak_far_above_the_scene_warns_and_range_lets_psnr_move():
    real = irf.load_frame(LEPTON[0])
    noisy = np.clip(real.astype(np.int64) + np.random.default_rng(0).normal(0, 30, real.shape), 0,
                    16383).astype(np.uint16)
    with pytest.warns(PeakWarning, match="psnr component cannot fall below"):
        pinned = irf.evaluate(real, noisy, bits=14, weights="psnr=1")
    assert pinned.components["psnr"] > 0.9 and pinned.metrics["psnr_peak"] == 16383
    assert any("PeakWarning" in n for n in pinned.notes)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PeakWarning)
        moved = irf.evaluate(real, noisy, bits=14, weights="psnr=1", peak="range")
    span = float(real.max()) - float(real.min())
    assert moved.metrics["psnr_peak"] == span and moved.components["psnr"] < pinned.components["psnr"] - 0.2
    assert moved.metrics["psnr_db"] == pytest.approx(20 * np.log10(span) - 10 * np.log10(moved.metrics["mse"]))
    # sequences of arrays: each frame's own range, the pooled PSNR over the whole real range
    stack = np.stack([real, real])
    seq = irf.score_sequence(stack, np.stack([noisy, noisy]), bits=14, weights="psnr=1", peak="range",
                             progress=False)
    assert seq.frames[0]["metrics"]["psnr_peak"] == span and seq.metrics["psnr_peak"] == span
    with pytest.raises(FidelityError, match="range"):
        irf.evaluate(np.full((4, 4), 7, np.uint16), np.ones((4, 4), np.uint16), weights="psnr=1", peak="range")


# --------------------------------------------------------------------------- grade
def test_a_poor_component_keeps_the_grade_from_excellent():
    comps = {"mtf": 0.99, "sitf": 0.99, "psnr": 0.999, "nmi": 0.03, "ssim": 0.99}
    scale = GradeScale()
    grading = scale.evaluate(Weights(), comps)
    # the maximum of B alone would say "excellent" (0.8 of the weight is excellent)
    assert max(grading.membership, key=grading.membership.get) == "excellent"
    assert grading.component_grades["nmi"] == "poor"
    assert grading.grade == "fair"  # one grade above the worst component
    comps["nmi"] = 0.06  # fair
    assert scale.evaluate(Weights(), comps).grade == "good"
    assert scale.evaluate(Weights.parse("mtf=0.5,ssim=0.5"), comps).grade == "excellent"  # nmi not weighted
    # the weighted average: mostly fair components are fair even if one is excellent
    many_fair = {"mtf": 0.75, "sitf": 0.75, "psnr": 0.7, "nmi": 0.06, "ssim": 0.99}
    assert scale.evaluate(Weights(), many_fair).grade == "fair"


def test_reports_show_each_component_grade():
    rep = irf.evaluate(REAL, SIM, bits=14)
    assert set(rep.component_grades) == set(rep.components)
    text = rep.summary_text()
    for k, g in rep.component_grades.items():
        assert re.search(rf"^{k}\s+\S+\s+\S+\s+{g}", text, re.M), text


# --------------------------------------------------------------------------- multi-page TIFFs
def test_multipage_tiffs_are_sequences_on_the_command_line(tmp_path):
    p = cli("score", STACK, STACK, "--bits", "14", "--csv", tmp_path / "all.csv", "--no-progress")
    assert p.returncode == 0, p.stderr
    assert len(list(csv.DictReader(open(tmp_path / "all.csv")))) == 100
    p = cli("score", STACK, STACK, "--bits", "14", "--pages", "10:20", "--csv", tmp_path / "some.csv",
            "--no-progress")
    rows = list(csv.DictReader(open(tmp_path / "some.csv")))
    assert p.returncode == 0 and [r["real"] for r in rows] == [f"{STACK.name}[{i}]" for i in range(10, 20)]
    # a multi-page TIFF against a directory of frames
    d = tmp_path / "frames"
    d.mkdir()
    tifffile = pytest.importorskip("tifffile")
    stack = tifffile.imread(STACK)
    for i in range(100):
        tifffile.imwrite(d / f"f_{i:03d}.tif", stack[i])
    p = cli("score", STACK, d, "--bits", "14", "--no-progress", "--json", tmp_path / "r.json")
    assert p.returncode == 0, p.stderr
    assert json.loads((tmp_path / "r.json").read_text())["fidelity"] == 1.0


def test_evaluate_refuses_a_multipage_tiff():
    with pytest.raises(FidelityError, match="multi-page TIFF of 100 frames"):
        irf.evaluate(STACK, STACK, bits=14)


# --------------------------------------------------------------------------- CLI wording
_PYTHON_SYNTAX = re.compile(r"\w+=\(|\w+=(True|False|None)\b|\.astype\(|np\.\w|\bchannel=|\bcolumns=|resume=|"
                            r"`\w+`|\w+=\.\.\.")


@pytest.mark.parametrize("args", [
    ["score", LEPTON[0], LEPTON[1], "--bits", "3"],
    ["score", LEPTON[0], REAL],
    ["score", LEPTON[0], LEPTON[1], "--missing", "raise", "--weights", "psnr=0.5,noise=0.5"],
    ["score", LEPTON[0], LEPTON[1], "--channel", "Q"],
    ["score", LEPTON[0], LEPTON[1], "--weights", "mtf=2"],
    ["score", LEPTON[0], LEPTON[1], "--real-sitf", DATA.parent / "curves" / "pyradi_jade_lwir_calibration_sitf.csv",
     "--sim-sitf", DATA.parent / "curves" / "pyradi_jade_lwir_calibration_sitf.csv"],
    ["score", DATA, DATA, "--resume", "--no-progress"],
])
def test_cli_messages_name_flags_not_python(args):
    p = cli(*args)
    assert p.returncode == 2, (p.stdout, p.stderr)
    line = p.stderr.strip().splitlines()[-1]
    assert not _PYTHON_SYNTAX.search(line), line
    assert "np.float64" not in line and "Traceback" not in p.stderr


def test_plain_progress_line_without_tqdm(tmp_path):
    code = ("import sys, builtins\n"
            "real_import = builtins.__import__\n"
            "def no_tqdm(name, *a, **k):\n"
            "    if name.startswith('tqdm'):\n"
            "        raise ImportError(name)\n"
            "    return real_import(name, *a, **k)\n"
            "builtins.__import__ = no_tqdm\n"
            "from irfidelity.cli import main\n"
            f"sys.exit(main(['score', {str(STACK)!r}, {str(STACK)!r}, '--bits', '14']))\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "scoring: 100/100 frames (100 %)" in p.stderr


def test_file_sequences_take_the_range_peak_and_per_side_channels(tmp_path):
    tifffile = pytest.importorskip("tifffile")
    cv2 = pytest.importorskip("cv2")
    stack = tifffile.imread(STACK)[:4]
    noisy = np.clip(stack.astype(np.int64) + np.random.default_rng(1).normal(0, 20, stack.shape), 0,
                    16383).astype(np.uint16)
    rdir, sdir = tmp_path / "r", tmp_path / "s"
    rdir.mkdir()
    sdir.mkdir()
    for i in range(4):
        assert cv2.imwrite(str(rdir / f"f{i}.png"), stack[i])
        rgb = np.stack([noisy[i], stack[i], stack[i]], axis=-1)[..., ::-1]  # R = the noisy frame
        assert cv2.imwrite(str(sdir / f"f{i}.png"), np.ascontiguousarray(rgb))
    files = irf.score_sequence(rdir, sdir, bits=14, peak="range", sim_channel="R", progress=False)
    arrays = irf.score_sequence(stack, noisy, bits=14, peak="range", progress=False)
    assert files.failed == [] and [f["metrics"] for f in files.frames] == [f["metrics"] for f in arrays.frames]
    spans = [float(f.max()) - float(f.min()) for f in stack]
    assert [f["metrics"]["psnr_peak"] for f in files.frames] == spans
    # pooled: each frame's squared error relative to its own range (docs/interpretation.md)
    relative = sum(f["metrics"]["mse"] / f["metrics"]["psnr_peak"] ** 2 for f in files.frames) / len(spans)
    assert files.metrics["psnr_db"] == pytest.approx(-10 * np.log10(relative), abs=1e-9)
    assert min(spans) <= files.metrics["psnr_peak"] <= max(spans)
    assert files.metrics == arrays.metrics
