"""Scoring in a physical unit (``unit="K"|"C"``): conversion of both sides, the temperature
errors in every output, the opt-in ``radiometry`` component, the PSNR peak, sequences pooled
exactly, the command line and the HTML report.

Oracles: an independent float64 implementation of the errors below (Python floats summed with
``math.fsum``, pixel by pixel), and the term-by-term numpy implementation of the FLIR model in
test_radiometry.py.
"""

from __future__ import annotations

import csv
import html
import io
import json
import math
import pathlib

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

import irfidelity as irf
from irfidelity.cli import main
from irfidelity.errors import FidelityError, FrameError
from irfidelity.schema import csv_columns
from irfidelity.temperature import DEFAULT_TOLERANCE, radiometry_component
from test_radiometry import AX8, FFF_LE, ZERO_C, thermimage_raw2temp

DATA = pathlib.Path(__file__).parent / "data"
LEPTON = DATA / "thermal" / "cptv_v2_frame000.png"
WEIGHTS = "psnr=0.3,nmi=0.2,ssim=0.3,radiometry=0.2"


def reference_errors(real, sim, tolerance, mask=None) -> dict:
    """Bias, RMSE, MAE and the fraction within tolerance, pixel by pixel in Python floats."""
    r, s = np.asarray(real, dtype=np.float64).ravel(), np.asarray(sim, dtype=np.float64).ravel()
    keep = np.ones(r.size, bool) if mask is None else np.asarray(mask, bool).ravel()
    diffs = [float(b) - float(a) for a, b, k in zip(r, s, keep) if k and math.isfinite(b - a)]
    n = len(diffs)
    bias = math.fsum(diffs) / n
    rmse = math.sqrt(math.fsum(d * d for d in diffs) / n)
    return {"n": n, "bias": bias, "rmse": rmse, "mae": math.fsum(abs(d) for d in diffs) / n,
            "within": sum(abs(d) <= tolerance for d in diffs) / n,
            "component": 0.9 ** ((bias * bias + rmse * rmse) / (2 * tolerance * tolerance))}


def scene(seed=0, shape=(48, 64)) -> np.ndarray:
    """A smooth float64 temperature scene in kelvin."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:shape[0], 0:shape[1]]
    return 295.0 + 8.0 * np.sin(x / 7.0) * np.cos(y / 9.0) + gaussian_filter(rng.normal(0, 3, shape), 2)


def assert_errors(metrics, ref, unit="K"):
    assert metrics["temperature_unit"] == unit
    assert metrics["n"] == ref["n"]
    assert metrics["temperature_bias"] == pytest.approx(ref["bias"], rel=1e-12, abs=1e-12)
    assert metrics["temperature_rmse"] == pytest.approx(ref["rmse"], rel=1e-12)
    assert metrics["temperature_mae"] == pytest.approx(ref["mae"], rel=1e-12)
    assert metrics["temperature_within"] == ref["within"]


# ------------------------------------------------------------------------------ single pairs


def test_errors_equal_the_reference_with_a_mask():
    real = scene()
    sim = real * 1.01 - 2.0 + np.random.default_rng(1).normal(0, 0.4, real.shape)
    mask = np.ones(real.shape, bool)
    mask[:5] = False
    rep = irf.evaluate(real, sim, unit="K", weights=WEIGHTS, mask=mask, temperature_tolerance=0.5)
    ref = reference_errors(real, sim, 0.5, mask)
    assert_errors(rep.metrics, ref)
    assert rep.metrics["temperature_tolerance"] == 0.5
    assert rep.components["radiometry"] == pytest.approx(ref["component"], rel=1e-12)
    assert rep.fidelity == pytest.approx(math.fsum(rep.weights[k] * rep.components[k] for k in rep.components))


def test_errors_of_strided_frames_over_several_blocks_equal_the_reference():
    """One Rust pass a block of rows at a time: a frame larger than one block, a strided view
    (copied a block at a time), NaN and ±inf on either side, a mask."""
    from irfidelity.temperature import TemperatureErrors

    rng = np.random.default_rng(7)
    real = 300 + rng.normal(0, 2, (1100, 1001))
    sim = real + rng.normal(0.3, 0.6, real.shape)
    real[3, 4], sim[700, 10], sim[1099, 1000] = np.nan, np.inf, -np.inf
    mask = rng.random(real.shape) > 0.2
    for r, s, m in ((real, sim, mask), (real[:, ::2], sim[:, ::2], mask[:, ::2]), (real, sim, None)):
        errors = TemperatureErrors.of_frames(r, s, tolerance=0.5, unit="K", mask=m)
        ref = reference_errors(r, s, 0.5, m)
        assert (errors.n, errors.within / errors.n) == (ref["n"], ref["within"])
        assert errors.bias == pytest.approx(ref["bias"], rel=1e-12)
        assert errors.rmse == pytest.approx(ref["rmse"], rel=1e-12)
        assert errors.mae == pytest.approx(ref["mae"], rel=1e-12)


def test_the_error_profiles_temperature_sums_are_the_temperature_errors_pass():
    """evaluate takes a pair's temperature errors from the defects' error profile (one read of
    the pair): the same chunks joined the same way as ``_core.temperature_errors``, to the bit."""
    from irfidelity import _core
    from irfidelity.defects import error_profile
    from irfidelity.temperature import TemperatureErrors

    rng = np.random.default_rng(8)
    real = 300 + rng.normal(0, 2, (700, 530))                   # several chunks
    sim = real + rng.normal(0.3, 0.6, real.shape)
    real[3, 4], sim[600, 10], sim[699, 529] = np.nan, np.inf, -np.inf
    mask = rng.random(real.shape) > 0.2
    for m in (mask, None):
        got = error_profile(real, sim, m, tolerance=0.5).errors
        assert got == _core.temperature_errors(real, sim, m, tolerance=0.5)
        want = TemperatureErrors.of_frames(real, sim, mask=m, tolerance=0.5, unit="K")
        assert TemperatureErrors.of_sums(got, tolerance=0.5, unit="K") == want
    assert error_profile(real, sim, mask).errors is None                        # no tolerance asked
    assert error_profile(real.astype(np.float32), sim.astype(np.float32), tolerance=0.5).errors is None
    # evaluate's errors, from the profile without defects and from their own pass with them
    clean = np.nan_to_num(sim, posinf=300.0, neginf=300.0)
    real_clean = np.nan_to_num(real, nan=300.0)
    dead = clean.copy()
    dead[100:103, 200:203] = 250.0                                           # a dead 3x3 cluster
    for pair in ((real_clean, clean), (real_clean, dead)):
        rep = irf.evaluate(*pair, unit="K", weights=WEIGHTS, temperature_tolerance=0.5)
        kept = None if rep.verdict["defects"] is None else rep.sources["mask"]
        errors = TemperatureErrors.of_frames(*pair, mask=kept, tolerance=0.5, unit="K")
        assert (rep.verdict["defects"] is None) == (pair[1] is clean)
        assert {k: rep.metrics[k] for k in errors.metrics()} == errors.metrics()


def test_psnr_peak_is_the_real_temperature_range():
    real, sim = scene(2), scene(3)
    rep = irf.evaluate(real, sim, unit="C", weights="psnr=1")
    span = float(real.max() - real.min())
    assert rep.metrics["psnr_peak"] == span
    mse = math.fsum((float(b) - float(a)) ** 2 for a, b in zip(real.ravel(), sim.ravel())) / real.size
    assert rep.metrics["psnr_db"] == pytest.approx(10 * math.log10(span**2 / mse), rel=1e-10)
    assert "temperature range" in rep.summary_text()
    # an explicit peak is kept (in the unit)
    assert irf.evaluate(real, sim, unit="C", weights="psnr=1", peak=40.0).metrics["psnr_peak"] == 40.0


def test_a_2_kelvin_offset_moves_radiometry_and_leaves_ssim():
    real = scene(4)
    sim = real + np.random.default_rng(5).normal(0, 0.2, real.shape)
    base = irf.evaluate(real, sim, unit="K", weights=WEIGHTS)
    shifted = irf.evaluate(real, sim + 2.0, unit="K", weights=WEIGHTS)
    assert base.components["radiometry"] > 0.98
    assert shifted.components["radiometry"] == pytest.approx(
        reference_errors(real, sim + 2.0, DEFAULT_TOLERANCE)["component"], rel=1e-12)
    assert shifted.components["radiometry"] < 0.7
    # SSIM's contrast and structure do not see an offset; its luminance term barely does at ~300 K
    for key in ("ssim_contrast", "ssim_structure"):
        assert shifted.metrics[key] == pytest.approx(base.metrics[key], abs=1e-12)
    assert shifted.components["ssim"] == pytest.approx(base.components["ssim"], abs=1e-4)
    assert shifted.metrics["temperature_bias"] == pytest.approx(base.metrics["temperature_bias"] + 2.0, abs=1e-9)


def test_gain_and_offset_errors_rank_below_a_blur():
    """The issue's case: a 0.95 gain with an offset ranked first on image components alone."""
    real = scene(6, (96, 128))
    gain_offset = 0.95 * real + 16.0
    blur = gaussian_filter(real, 0.8)
    image_only = {name: irf.evaluate(real, sim, unit="K", weights="nmi=0.5,ssim=0.5").fidelity
                  for name, sim in (("gain", gain_offset), ("blur", blur))}
    with_radiometry = {name: irf.evaluate(real, sim, unit="K", weights="nmi=0.3,ssim=0.3,radiometry=0.4").fidelity
                       for name, sim in (("gain", gain_offset), ("blur", blur))}
    assert image_only["gain"] > image_only["blur"]
    assert with_radiometry["gain"] < with_radiometry["blur"]


def test_radiometric_file_against_a_float_simulation():
    cal = irf.read_radiometry(FFF_LE)
    counts = irf.load_frame(FFF_LE)
    celsius = thermimage_raw2temp(counts, cal)
    sim = celsius + 0.25
    rep = irf.evaluate(str(FFF_LE), sim, unit="C", weights=WEIGHTS)
    ref = reference_errors(celsius, sim, 1.0)
    assert_errors(rep.metrics, ref, unit="C")
    assert rep.metrics["temperature_bias"] == pytest.approx(0.25, abs=1e-4)
    # in kelvin the errors are the same, the frames 273.15 higher
    kelvin = irf.evaluate(str(FFF_LE), sim + ZERO_C, unit="K", weights=WEIGHTS)
    assert kelvin.metrics["temperature_bias"] == pytest.approx(0.25, abs=1e-4)
    np.testing.assert_allclose(kelvin.sources["real"], celsius + ZERO_C, rtol=0, atol=1e-4)


def test_overrides_reach_the_conversion():
    cal = irf.read_radiometry(FFF_LE)
    counts = irf.load_frame(FFF_LE)
    changed = cal.replace(emissivity=0.8, reflected_temperature=10.0, object_distance=5.0, relative_humidity=40.0)
    expected = thermimage_raw2temp(counts, changed)
    calibration = {"emissivity": 0.8, "reflected_temperature": 10.0, "object_distance": 5.0,
                   "relative_humidity": 40.0}
    rep = irf.evaluate(str(FFF_LE), expected, unit="C", weights=WEIGHTS, calibration=calibration)
    assert abs(rep.metrics["temperature_bias"]) < 1e-4 and rep.metrics["temperature_rmse"] < 1e-4
    assert rep.config.calibration == calibration
    with pytest.raises(FidelityError, match="emissivity"):
        irf.evaluate(str(FFF_LE), expected, unit="C", calibration={"emissivity": 1.5})


def test_integer_frames_without_a_calibration_are_refused():
    counts = np.full((8, 8), 3000, np.uint16)
    with pytest.raises(FrameError, match=r"real frame: integer counts \(uint16\) without a radiometric calibration"):
        irf.evaluate(counts, counts.astype(np.float64), unit="K")
    with pytest.raises(FrameError, match=r"cptv_v2_frame000\.png.*cannot be scored in K"):
        irf.evaluate(str(LEPTON), str(LEPTON), unit="K")


def test_user_calibrations():
    counts = irf.load_frame(LEPTON)
    linear = irf.evaluate(str(LEPTON), counts * 0.04 + 180.0, unit="K", calibration={"gain": 0.04, "offset": 180.0},
                          weights=WEIGHTS)
    assert linear.metrics["temperature_rmse"] < 1e-9 and linear.components["radiometry"] == pytest.approx(1.0)
    planck = {k: getattr(irf.read_radiometry(FFF_LE), k) for k in irf.radiometry.CALIBRATION_FIELDS[:5]}
    own = irf.radiometry.Radiometry(**planck)
    expected = thermimage_raw2temp(counts.astype(np.float64) + 15000, own)
    rep = irf.evaluate((counts + 15000).astype(np.uint16), expected, unit="C", calibration=planck, weights=WEIGHTS)
    assert rep.metrics["temperature_rmse"] < 1e-4
    # a file's own calibration wins over a user calibration
    cal = irf.read_radiometry(FFF_LE)
    rep = irf.evaluate(str(FFF_LE), thermimage_raw2temp(irf.load_frame(FFF_LE), cal), unit="C",
                       calibration={"gain": 1.0}, weights=WEIGHTS)
    assert rep.metrics["temperature_rmse"] < 1e-4


@pytest.mark.parametrize("options, field, match", [
    ({"unit": "F"}, "unit", "expected 'K', 'C'"),
    ({"unit": "K", "calibration": {"emisivity": 0.9}}, "calibration", "unknown field"),
    ({"unit": "K", "calibration": {"gain": 1.0, "planck_b": 1400}}, "calibration", "not both"),
    ({"unit": "K", "calibration": {"offset": 3.0}}, "calibration", "needs a gain"),
    ({"unit": "K", "calibration": {"gain": 0}}, "calibration", "must not be 0"),
    ({"unit": "K", "calibration": {"gain": "a"}}, "calibration", "must be a number"),
    ({"unit": "K", "temperature_tolerance": 0}, "temperature_tolerance", "positive"),
    ({"calibration": {"emissivity": 0.9}}, "calibration", "set unit"),
    ({"temperature_tolerance": 0.5}, "temperature_tolerance", "set unit"),
    ({"unit": "K", "bits": 14}, "bits", "leave bits unset"),
])
def test_configuration_errors_name_the_field(options, field, match):
    with pytest.raises(FidelityError, match=match) as info:
        irf.ScoringConfig(**options)
    assert info.value.option == field


def test_configuration_round_trips(tmp_path):
    cfg = irf.ScoringConfig(unit="C", calibration={"emissivity": 0.98, "gain": 0.5}, temperature_tolerance=0.3,
                            weights=WEIGHTS)
    for name in ("c.toml", "c.json"):
        cfg.save(tmp_path / name)
        assert irf.ScoringConfig.load(tmp_path / name) == cfg
    rep = irf.evaluate(scene(), scene(1), config=cfg)
    back = irf.FidelityReport.from_dict(json.loads(json.dumps(rep.to_dict())))
    assert back == rep and back.metrics["temperature_unit"] == "C"


def test_tolerance_defaults_and_component_formula():
    real = scene()
    rep = irf.evaluate(real, real + 1.0, unit="K", weights="ssim=0.5,radiometry=0.5")
    assert rep.metrics["temperature_tolerance"] == DEFAULT_TOLERANCE == 1.0
    assert rep.components["radiometry"] == pytest.approx(0.9)  # a pure offset of one tolerance
    assert radiometry_component(0.0, 0.0, 0.5) == 1.0
    assert radiometry_component(3.0, 3.0, 1.0) == pytest.approx(0.9**9)
    assert radiometry_component(1e200, 1e200, 1.0) == 0.0
    # without a unit the component has no input and is dropped like any other
    plain = irf.evaluate(real, real + 1.0, weights="ssim=0.5,radiometry=0.5", peak="range")
    assert "radiometry" in plain.skipped and "temperature_bias" not in plain.metrics


def test_non_finite_temperatures_are_not_silent():
    real = scene()
    sim = real.copy()
    sim[3, 4] = np.nan
    with pytest.raises(irf.errors.RangeError, match="NaN"):
        irf.evaluate(real, sim, unit="K")
    rep = irf.evaluate(real, sim, unit="K", nonfinite="mask", weights=WEIGHTS)
    assert rep.metrics["n"] == real.size - 1
    assert_errors(rep.metrics, reference_errors(real, sim, 1.0))


# ------------------------------------------------------------------------------------ outputs


def test_metrics_in_schema_csv_and_text(tmp_path):
    rep = irf.evaluate(scene(), scene(1), unit="K", weights="psnr=0.5,ssim=0.5")
    cols = csv_columns(rep.components, temperature=True)
    for key in ("temperature_unit", "temperature_bias", "temperature_rmse", "temperature_mae", "temperature_within",
                "temperature_tolerance"):
        assert key in cols
        assert key in irf.schema.markdown_table()
    assert "f_radiometry" not in cols
    assert "temperatures (K): bias" in rep.summary_text()
    real_path, sim_path = tmp_path / "real.npy", tmp_path / "sim.npy"
    np.save(real_path, scene())
    np.save(sim_path, scene() + 0.5)
    out = tmp_path / "row.csv"
    assert main(["score", str(real_path), str(sim_path), "--unit", "K", "--weights", WEIGHTS, "--csv", str(out),
                 "--temperature-tolerance", "0.6"]) == 0
    row = next(csv.DictReader(io.StringIO(out.read_text())))
    assert float(row["temperature_bias"]) == pytest.approx(0.5, abs=1e-12)
    assert float(row["temperature_within"]) == 1.0 and float(row["temperature_tolerance"]) == 0.6
    assert float(row["f_radiometry"]) == pytest.approx(0.9 ** ((0.25 + 0.25) / (2 * 0.36)), rel=1e-12)


def test_cli_overrides_and_errors(tmp_path, capsys):
    cal = irf.read_radiometry(FFF_LE).replace(emissivity=0.98, reflected_temperature=20.0, object_distance=5.0,
                                             relative_humidity=40.0)
    sim = tmp_path / "sim.npy"
    np.save(sim, thermimage_raw2temp(irf.load_frame(FFF_LE), cal))
    rc = main(["score", str(FFF_LE), str(sim), "--unit", "C", "--emissivity", "0.98", "--reflected-temperature", "20",
               "--object-distance", "5", "--humidity", "40", "--json", "-"])
    assert rc == 0
    report = json.loads(capsys.readouterr().out)
    assert abs(report["metrics"]["temperature_bias"]) < 1e-4
    assert report["config"]["calibration"] == {"emissivity": 0.98, "reflected_temperature": 20.0,
                                               "object_distance": 5.0, "relative_humidity": 40.0}
    assert main(["score", str(FFF_LE), str(sim), "--unit", "C", "--emissivity", "1.5"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--emissivity" in err and "Traceback" not in err
    assert main(["score", str(LEPTON), str(LEPTON), "--unit", "K"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cptv_v2_frame000.png" in err and "--calibration" in err
    assert main(["score", str(LEPTON), str(sim), "--unit", "K", "--calibration", "gain=0.04,offset=x"]) == 2
    assert "--calibration" in capsys.readouterr().err


def test_html_report_shows_temperatures(tmp_path):
    real = scene()
    rep = irf.evaluate(real, real + 0.7, unit="K", weights=WEIGHTS)
    page = rep.to_html(tmp_path / "r.html")
    assert 'id="temperatures"' in page
    assert "temperature (°C, one scale for both)" in page and "simulated − real (K)" in page
    assert "histogram of the temperature errors" in page
    assert "PSNR peak: the real frame's temperature range" in html.unescape(page)
    plain = irf.evaluate(real, real + 0.7, peak="range").to_html()
    assert 'id="temperatures"' not in plain


# ---------------------------------------------------------------------------------- sequences


def test_sequence_frames_and_pooled_errors_are_exact():
    reals = np.stack([scene(i) for i in range(3)])
    sims = reals + np.stack([np.full(reals.shape[1:], off) for off in (0.2, -0.5, 1.5)])
    sims += np.random.default_rng(9).normal(0, 0.3, sims.shape)
    rep = irf.score_sequence(reals, sims, unit="K", weights=WEIGHTS, progress=False)
    for i, frame in enumerate(rep.frames):
        single = irf.evaluate(reals[i], sims[i], unit="K", weights=WEIGHTS)
        for key in ("temperature_bias", "temperature_rmse", "temperature_mae", "temperature_within"):
            assert frame["metrics"][key] == single.metrics[key]
        assert frame["components"]["radiometry"] == single.components["radiometry"]
    ref = reference_errors(reals, sims, 1.0)
    assert_errors(rep.metrics, ref)  # the metrics: every pixel pair together
    # the component: 0.9 to the mean of the frames' own exponents, within the frames' components
    frames = [reference_errors(r, s, 1.0) for r, s in zip(reals, sims)]
    exponent = math.fsum((f["bias"] ** 2 + f["rmse"] ** 2) / 2 for f in frames) / len(frames)
    assert rep.components["radiometry"] == pytest.approx(0.9 ** exponent, rel=1e-12)
    assert min(f["component"] for f in frames) <= rep.components["radiometry"] <= max(f["component"] for f in frames)
    assert rep.components["radiometry"] < ref["component"]  # the frames' opposite offsets do not cancel
    assert "temperature_bias" in rep.columns


def test_sequence_of_radiometric_files(tmp_path):
    seq = tmp_path / "real.seq"
    seq.write_bytes(FFF_LE.read_bytes() * 3)
    cal = irf.read_radiometry(FFF_LE)
    celsius = thermimage_raw2temp(irf.load_frame(FFF_LE), cal)
    sims = np.stack([celsius + 0.1 * k for k in range(3)])
    rep = irf.score_sequence(seq, sims, unit="C", weights=WEIGHTS, progress=False, workers=1)
    assert not rep.failed
    assert [f["metrics"]["temperature_bias"] for f in rep.frames] == pytest.approx([0.0, 0.1, 0.2], abs=1e-4)
    assert rep.metrics["temperature_bias"] == pytest.approx(0.1, abs=1e-4)
    out = tmp_path / "frames.csv"
    sim_dir = tmp_path / "sim"
    sim_dir.mkdir()
    for k in range(3):
        np.save(sim_dir / f"f{k}.npy", sims[k])
    assert main(["score", str(seq), str(sim_dir), "--unit", "C", "--weights", WEIGHTS, "--csv", str(out),
                 "--no-progress", "--pair-by", "order"]) == 0
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert [float(r["temperature_bias"]) for r in rows] == pytest.approx([0.0, 0.1, 0.2], abs=1e-4)


def test_sequence_frames_without_a_calibration_are_error_rows():
    reals = np.stack([scene(0), scene(1)])
    rep = irf.score_sequence(reals, reals.astype(np.float64) + 0.5, unit="K", weights=WEIGHTS, progress=False)
    assert not rep.failed
    counts = np.full((2, 8, 8), 100, np.uint16)
    rep = irf.score_sequence(counts, counts.astype(np.float64), unit="K", progress=False)
    assert rep.failed == [0, 1]
    assert all("real [" in f["error"] and "without a radiometric calibration" in f["error"] for f in rep.frames)


def test_ax8_shipped_example_scores_in_celsius():
    rep = irf.evaluate(str(AX8), str(AX8), unit="C", weights=WEIGHTS)
    assert rep.metrics["temperature_rmse"] == 0.0 and rep.components["radiometry"] == 1.0


def test_guide_and_demo_radiometric_examples_run(capsys):
    import re
    import warnings

    readme = (pathlib.Path(__file__).parent.parent / "docs" / "guide.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", readme, re.S)
    first = next(b for b in blocks if "read_radiometry" in b)
    scoring = next(b for b in blocks if 'unit="C", calibration=' in b)
    namespace: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        exec(compile(first + scoring, "docs/guide.md", "exec"), namespace)
    rep = namespace["rep"]
    assert rep.metrics["temperature_bias"] == pytest.approx(0.8, abs=1e-9)
    assert rep.components["radiometry"] == pytest.approx(0.9 ** (0.64 / 1.0), rel=1e-9)
    assert "bias +0.80 K" in capsys.readouterr().out

    from irfidelity.demo import RADIOMETRIC_MODEL, run_radiometric_demo

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        demo = run_radiometric_demo(out=print)
    assert demo.metrics["temperature_bias"] == pytest.approx(RADIOMETRIC_MODEL["offset"], abs=0.05)
    assert 0 < demo.components["radiometry"] < 1 and demo.notes == []
    assert "temperatures (C): bias" in capsys.readouterr().out


def test_resumed_sequence_keeps_the_temperature_errors(tmp_path):
    reals = np.stack([scene(i) for i in range(3)])
    sims = reals + np.stack([np.full(reals.shape[1:], off) for off in (0.2, -0.5, 1.5)])
    out = tmp_path / "frames.csv"
    first = irf.score_sequence(reals, sims, unit="K", weights=WEIGHTS, progress=False, csv=out)
    again = irf.score_sequence(reals, sims, unit="K", weights=WEIGHTS, progress=False, csv=out, resume=True)
    assert again.run["resumed"] == 3
    assert again.metrics == first.metrics and again.components == first.components
    assert [f["metrics"] for f in again.frames] == [f["metrics"] for f in first.frames]


def test_a_dask_client_is_refused_in_a_unit():
    reals = np.stack([scene(0), scene(1)])
    with pytest.raises(FidelityError, match=r"scored in a unit \(config.unit\) are converted and scored locally"):
        irf.score_sequence(reals, reals, unit="K", client=object(), progress=False)
