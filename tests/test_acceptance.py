"""Acceptance specifications (irfidelity.acceptance, ``irfidelity score --spec``): parsing with
errors naming the key and the file, pass and fail on real frames, required components that
were not assessed, the spec's tolerances applied before scoring, the command line's lines, JSON
block and exit statuses, single pairs and sequences.

Data: real FLIR Lepton frames (tests/data/thermal, 14-bit counts; see tests/data/README.md).
The next real frame is the simulator that grades excellent; a copy of the real frame with
seeded Gaussian noise at 10 % of the scene's range is one whose PSNR grades fair (the RMS
tolerance for good is 6.8 % of the range, for fair 14 %). Requirements use the image
components, whose availability the frames decide, and ``noise``, which needs recordings.
"""

from __future__ import annotations

import json
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.acceptance import Acceptance, Requirement, SpecError, check
from irfidelity.cli import main
from irfidelity.errors import FidelityError
from irfidelity.image_writers import write_image
from irfidelity.tolerances import Tolerances

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
REAL = str(DATA / "cptv_v2_frame000.png")
NEXT = str(DATA / "cptv_v2_frame001.png")
IMAGE_WEIGHTS = "psnr=0.4,nmi=0.3,ssim=0.3"  # mtf and sitf weight 0: not assessed, whatever the scene

SPEC = """\
# acceptance.toml
name = "LWIR trainer, detection range study"
grade = "good"
[require.psnr]
rms_error = [0.03, 0.06, 0.12]
grade = "good"
[require.ssim]
grade = "fair"
"""


def write(tmp_path: pathlib.Path, text: str, name: str = "acceptance.toml") -> str:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


@pytest.fixture(scope="module")
def noisy(tmp_path_factory) -> str:
    """The real frame with seeded noise at 10 % of its range: PSNR grades fair."""
    real = irf.load_frame(REAL).astype(np.float64)
    rng = np.random.default_rng(7)
    sim = np.clip(real + rng.normal(0.0, 0.10 * np.ptp(real), real.shape), 0, 2 ** 14 - 1)
    path = tmp_path_factory.mktemp("noisy") / "noisy.png"
    write_image(path, sim, "png")
    return str(path)


def score(sim: str, spec: Acceptance, **options) -> irf.FidelityReport:
    options.setdefault("weights", IMAGE_WEIGHTS)
    return irf.evaluate(REAL, sim, bits=14, peak="range", **spec.overrides(), **options)


# --------------------------------------------------------------------------- parsing
def test_the_documented_spec_reads(tmp_path):
    spec = Acceptance.from_toml(write(tmp_path, SPEC))
    assert spec.name == "LWIR trainer, detection range study" and spec.grade == "good"
    assert spec.requirements == (Requirement("psnr", "good", (0.03, 0.06, 0.12)), Requirement("ssim", "fair"))
    assert spec.source.endswith("acceptance.toml")
    assert spec.tolerances == {"rms_error": (0.03, 0.06, 0.12)}
    assert Acceptance.from_dict(spec.to_dict()) == spec


def test_short_form_and_the_overall_grade_as_default():
    spec = Acceptance.from_dict({"grade": "fair", "require": {"nmi": {}, "ssim": "good"}})
    assert spec.requirements == (Requirement("nmi", "fair"), Requirement("ssim", "good"))
    assert Acceptance.from_dict({"grade": "good"}).requirements == ()  # the overall grade alone


@pytest.mark.parametrize("text, needles", [
    ("grade = 'good'\ncolour = 'red'\n", ["colour: unknown key", "name, grade, require"]),
    ("[require.contrast]\ngrade = 'good'\n", ["require.contrast: unknown key", "mtf, sitf, psnr"]),
    ("[require.mtf]\ngrade = 'good'\nsitf_slope = [0.05, 0.1, 0.2]\n",
     ["require.mtf.sitf_slope: unknown key", "grade, mtf50"]),
    ("[require.psnr]\ngrade = 'grand'\n", ["require.psnr.grade", "excellent, good, fair, poor", "'grand'"]),
    ("grade = 'Good'\n", ["grade: expected a grade", "'Good'"]),
    ("[require.psnr]\nrms_error = [0.1, 0.05, 0.2]\ngrade = 'good'\n", ["require.psnr.rms_error", "ascending"]),
    ("[require.mtf]\nmtf50 = [0.05, 0.1]\ngrade = 'good'\n", ["require.mtf.mtf50", "three"]),
    ("[require.psnr]\nrms_error = [0.03, 0.06, 0.12]\n", ["require.psnr: no grade"]),
    ("require = 'psnr'\n", ["require: expected a table"]),
    ("name = ''\ngrade = 'good'\n", ["name: expected a non-empty text"]),
    ("name = 'nothing'\n", ["nothing is required"]),
    ("[require.psnr\ngrade = 'good'\n", ["not a valid TOML"]),
])
def test_bad_specs_name_the_file_and_the_key(tmp_path, text, needles):
    path = write(tmp_path, text)
    with pytest.raises(SpecError) as info:
        Acceptance.from_toml(path)
    assert isinstance(info.value, FidelityError)
    message = str(info.value)
    assert message.startswith(path + ": ") and "\n" not in message
    for needle in needles:
        assert needle in message, message


def test_a_missing_or_oversized_file(tmp_path):
    with pytest.raises(SpecError, match=r"nowhere\.toml: cannot read the acceptance specification"):
        Acceptance.from_toml(tmp_path / "nowhere.toml")
    big = write(tmp_path, "# " + "x" * (1 << 16) + "\ngrade = 'good'\n")
    with pytest.raises(SpecError, match="too large"):
        Acceptance.from_toml(big)


# --------------------------------------------------------------------------- checking real frames
def test_the_next_real_frame_is_accepted():
    spec = Acceptance.from_dict({"grade": "good", "require": {"psnr": "good", "nmi": "good", "ssim": "good"}})
    result = check(score(NEXT, spec), spec)
    assert result.passed and result.reason.startswith("every requirement met")
    psnr = result["psnr"]
    assert (psnr.status, psnr.grade, psnr.required, psnr.basis) == ("pass", "excellent", "good", "range")
    assert psnr.unit == "RMS error / the scene's range" and psnr.at_most is True
    assert psnr.measure < psnr.limit == pytest.approx(0.068)
    assert "RMS error" in psnr.reason and "the tolerance for good is 6.8 %" in psnr.reason
    assert result["overall"].grade == "excellent" and result["overall"].passed


def test_a_noisy_simulator_fails_with_the_measure_and_the_limit(noisy):
    spec = Acceptance.from_dict({"require": {"psnr": "good", "ssim": "poor"}})
    rep = score(noisy, spec)
    result = check(rep, spec)
    assert not result.passed
    psnr = result["psnr"]
    assert (psnr.status, psnr.grade) == ("fail", rep.component_grades["psnr"]) and psnr.grade == "fair"
    assert psnr.measure == pytest.approx(rep.verdict["components"]["psnr"]["measure"])
    assert 0.068 < psnr.measure < 0.14 and psnr.limit == pytest.approx(0.068)
    assert psnr.reason.startswith("psnr fair, required good: RMS error")
    assert result["ssim"].passed and result["ssim"].limit is None  # poor: anything assessed meets it
    assert result.reason == "psnr fair (required good)"


def test_the_specs_tolerances_decide_the_grade(noisy):
    """Looser RMS limits accept the noisy simulator; the report's own verdict uses them too."""
    loose = Acceptance.from_dict({"require": {"psnr": {"grade": "good", "rms_error": [0.05, 0.15, 0.3]}}})
    rep = score(noisy, loose)
    assert rep.config.tolerances.rms_error == (0.05, 0.15, 0.3)
    assert rep.component_grades["psnr"] == "good" and check(rep, loose).passed
    strict = Acceptance.from_dict({"require": {"psnr": {"grade": "good", "rms_error": [0.001, 0.002, 0.004]}}})
    result = check(score(NEXT, strict), strict)
    assert not result.passed and result["psnr"].grade == "poor" and result["psnr"].limit == 0.002


def test_a_report_graded_with_other_limits_is_refused():
    spec = Acceptance.from_dict({"require": {"psnr": {"grade": "good", "rms_error": [0.01, 0.02, 0.05]}}})
    rep = irf.evaluate(REAL, NEXT, bits=14, peak="range", weights=IMAGE_WEIGHTS)
    with pytest.raises(SpecError, match=r"graded with rms_error = \[0.032, 0.068, 0.14\].*spec.overrides"):
        check(rep, spec)


def test_overrides_keep_the_configurations_other_tolerances():
    spec = Acceptance.from_dict({"require": {"psnr": {"grade": "good", "rms_error": [0.01, 0.02, 0.05]}}})
    config = irf.ScoringConfig(tolerances={"mtf50": [0.03, 0.08, 0.15]})
    tol = spec.overrides(config)["tolerances"]
    assert tol.mtf50 == (0.03, 0.08, 0.15) and tol.rms_error == (0.01, 0.02, 0.05)
    assert spec.apply(config).tolerances == tol and Acceptance.from_dict({"grade": "good"}).overrides(config) == {}
    assert spec.overrides()["tolerances"].ssim == Tolerances().ssim


# --------------------------------------------------------------------------- not assessed
def test_a_required_component_with_weight_0_is_not_assessed():
    spec = Acceptance.from_dict({"require": {"mtf": "fair", "psnr": "fair"}})
    result = check(score(NEXT, spec), spec)
    assert not result.passed and result["psnr"].passed
    mtf = result["mtf"]
    assert (mtf.status, mtf.grade, mtf.measure) == ("not assessed", None, None)
    assert mtf.reason.startswith("mtf is required but was not assessed: weight 0; it needs MTF curves")
    assert "real_mtf/sim_mtf" in mtf.reason and "a positive weight" in mtf.reason


def test_required_noise_without_recordings_is_not_assessed():
    spec = Acceptance.from_dict({"require": {"noise": "good", "psnr": "good"}})
    rep = score(NEXT, spec, weights="psnr=0.3,nmi=0.2,ssim=0.3,noise=0.2")
    assert "noise" in rep.skipped
    noise = check(rep, spec)["noise"]
    assert noise.status == "not assessed"
    assert noise.reason.startswith("noise is required but was not assessed: ")
    assert "real_noise/sim_noise" in noise.reason and "weight 0.2 dropped" not in noise.reason
    assert "positive weight" not in noise.reason  # it has one: the recordings are what is missing


def test_spec_limits_for_nmi_need_a_ceiling():
    """Without a ceiling NMI is graded by the calibrated absolute boundaries, not the spec's limits."""
    spec = Acceptance.from_dict({"require": {"nmi": {"grade": "fair", "nmi": [0.8, 0.6, 0.4]}}})
    result = check(score(NEXT, spec), spec)
    assert result["nmi"].status == "not assessed" and "no ceiling was measured" in result["nmi"].reason
    assert "--real-ref" in result["nmi"].reason
    plain = Acceptance.from_dict({"require": {"nmi": "fair"}})  # the configuration's: graded as the report is
    nmi = check(score(NEXT, plain), plain)["nmi"]
    assert nmi.passed and nmi.basis == "absolute" and "absolute" in nmi.unit


def test_with_a_ceiling_the_spec_limits_for_nmi_apply():
    spec = Acceptance.from_dict({"require": {"nmi": {"grade": "fair", "nmi": [0.8, 0.6, 0.4]}}})
    rep = score(NEXT, spec, real_ref=str(DATA / "cptv_v2_frame002.png"))
    nmi = check(rep, spec)["nmi"]
    assert nmi.basis == "ceiling" and nmi.unit == "NMI / the ceiling" and nmi.limit == 0.4
    assert nmi.measure == pytest.approx(rep.relative["nmi"])
    assert nmi.status == ("pass" if nmi.measure >= 0.4 else "fail")


def test_a_sequence_report(tmp_path):
    frames = irf.load_frame(REAL), irf.load_frame(NEXT), irf.load_frame(str(DATA / "cptv_v2_frame002.png"))
    real, sim = np.stack(frames[:2]), np.stack(frames[1:])
    spec = Acceptance.from_dict({"grade": "fair", "require": {"psnr": "good", "noise": "fair"}})
    rep = irf.score_sequence(real, sim, bits=14, peak="range", weights=IMAGE_WEIGHTS, progress=False,
                             **spec.overrides())
    result = check(rep, spec)
    assert result["psnr"].passed and result["overall"].passed and result.failed_frames == ()
    assert result["noise"].status == "not assessed" and not result.passed
    assert json.loads(json.dumps(result.to_dict()))["requirements"]["psnr"]["passed"] is True


# --------------------------------------------------------------------------- the command line
def test_cli_accepted_exit_0_with_lines_and_json(tmp_path, capsys):
    spec = write(tmp_path, SPEC)
    assert main(["score", REAL, NEXT, "--bits", "14", "--peak", "range", "--weights", IMAGE_WEIGHTS,
                 "--spec", spec]) == 0
    out = capsys.readouterr().out
    assert "acceptance: LWIR trainer, detection range study" in out
    assert "  PASS  psnr       excellent (required good): RMS error" in out and "  PASS  ssim" in out
    assert "  PASS  overall    excellent (required good)\n" in out
    assert out.rstrip().splitlines()[-1].startswith("ACCEPTED: every requirement met")
    assert main(["score", REAL, NEXT, "--bits", "14", "--peak", "range", "--weights", IMAGE_WEIGHTS,
                 "--spec", spec, "--json", "-"]) == 0
    data = json.loads(capsys.readouterr().out)
    block = data["acceptance"]
    assert block["accepted"] is True and block["spec"] == spec and block["tolerances"] == {
        "rms_error": [0.03, 0.06, 0.12]}
    assert data["config"]["tolerances"]["rms_error"] == [0.03, 0.06, 0.12]  # applied before scoring
    assert block["requirements"]["psnr"]["limit"] == 0.06 and block["grade"]["grade"] == data["grade"]


def test_cli_not_accepted_exit_4(tmp_path, noisy, capsys):
    spec = write(tmp_path, "[require.psnr]\ngrade = 'good'\n[require.noise]\ngrade = 'good'\n")
    rc = main(["score", REAL, noisy, "--bits", "14", "--peak", "range", "--weights", IMAGE_WEIGHTS, "--spec", spec,
               "--json", str(tmp_path / "r.json")])
    assert rc == 4
    out = capsys.readouterr().out
    assert "  FAIL  psnr       fair (required good): RMS error" in out
    assert "  FAIL  noise      not assessed (required good): weight 0" in out and "--real-noise/--sim-noise" in out
    last = out.rstrip().splitlines()[-1]
    assert last == "NOT ACCEPTED: psnr fair (required good); noise not assessed (required good)"
    block = json.loads((tmp_path / "r.json").read_text())["acceptance"]
    assert block["accepted"] is False and block["requirements"]["noise"]["status"] == "not assessed"
    assert block["requirements"]["psnr"]["status"] == "fail"


def test_cli_without_spec_has_no_acceptance_block(capsys):
    assert main(["score", REAL, NEXT, "--bits", "14", "--peak", "range", "--json", "-"]) == 0
    assert "acceptance" not in json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("text, needles", [
    ("[require.psnr\n", ["not a valid TOML", "(--spec)"]),
    ("[require.contrast]\ngrade = 'good'\n", ["require.contrast: unknown key"]),
    ("[require.psnr]\ngrade = 'grand'\n", ["require.psnr.grade", "'grand'"]),
    (None, ["cannot read the acceptance specification"]),
])
def test_cli_spec_errors_exit_2_with_one_line(tmp_path, text, needles):
    spec = str(tmp_path / "missing.toml") if text is None else write(tmp_path, text)
    p = subprocess.run([sys.executable, "-m", "irfidelity.cli", "score", REAL, NEXT, "--bits", "14", "--spec", spec],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and "Traceback" not in p.stderr and p.stdout == ""
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("irfidelity score: error: " + spec), p.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


def test_cli_tolerance_that_contradicts_the_spec_is_refused(tmp_path, capsys):
    spec = write(tmp_path, SPEC)
    args = ["score", REAL, NEXT, "--bits", "14", "--peak", "range", "--spec", spec]
    assert main(args + ["--tolerance", "rms_error=0.01,0.02,0.05"]) == 2
    assert "sets rms_error = [0.03, 0.06, 0.12]" in capsys.readouterr().err
    assert main(args + ["--weights", IMAGE_WEIGHTS, "--tolerance", "rms_error=0.03,0.06,0.12",
                        "--tolerance", "ssim=0.9,0.8,0.5"]) == 0  # the same limits, or another tolerance


def test_cli_sequence(tmp_path, capsys):
    rdir, sdir = tmp_path / "real", tmp_path / "sim"
    rdir.mkdir()
    sdir.mkdir()
    for i in range(3):  # real frame i against real frame i + 1
        shutil.copy(DATA / f"cptv_v2_frame00{i}.png", rdir / f"f{i}.png")
        shutil.copy(DATA / f"cptv_v2_frame00{i + 1}.png", sdir / f"f{i}.png")
    args = ["score", str(rdir), str(sdir), "--bits", "14", "--peak", "range", "--weights", IMAGE_WEIGHTS,
            "--no-progress", "--spec"]
    assert main(args + [write(tmp_path, "grade = 'good'\n[require.psnr]\n")]) == 0
    assert "ACCEPTED: every requirement met" in capsys.readouterr().out
    assert main(args + [write(tmp_path, "[require.noise]\ngrade = 'fair'\n", "noise.toml"), "--json", "-"]) == 4
    block = json.loads(capsys.readouterr().out)["acceptance"]
    assert block["accepted"] is False and block["failed_frames"] == []
    assert block["requirements"]["noise"]["reason"].startswith("noise is required but was not assessed")


def test_made_directly_the_same_checks_apply():
    with pytest.raises(SpecError, match="require.contrast: unknown component"):
        Requirement("contrast", "good")
    with pytest.raises(SpecError, match=r"require.mtf.mtf50: expected three"):
        Requirement("mtf", "good", (0.1, 0.2))
    assert Requirement("mtf", "good", [0.05, 0.1, 0.2]).limits == (0.05, 0.1, 0.2)
    with pytest.raises(SpecError, match="require.psnr: required twice"):
        Acceptance(requirements=(Requirement("psnr", "good"), Requirement("psnr", "fair")))
