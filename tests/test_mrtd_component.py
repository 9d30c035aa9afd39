"""The opt-in `mrtd` component (docs/bars.md, section 5): MRTD curves of two cameras compared on
log ΔT, inputs from curves or bar frames, the report's bar section, and the CLI (`score
--real-bars/--sim-bars`, `targets`)."""

from __future__ import annotations

import json
import os

import numpy as np
import png
import pytest
import tifffile

import irfidelity as irf
from irfidelity.bar_frames import BarFrames, bar_curves
from irfidelity.cli import main
from irfidelity.curves import Curve, ctf_curve, mrtd, mrtd_similarity, mtf_from_ctf
from irfidelity.errors import FidelityError
from irfidelity.image_writers import write_image
from irfidelity.schema import csv_columns
from irfidelity.targets import four_bar, gaussian_otf, slanted_edge

FREQUENCIES = (0.05, 0.08, 0.11, 0.14)
DELTA_T = (0.02, 0.04, 0.08, 0.15, 0.3, 0.6)
SHAPE = (96, 96)


def bar_set(netd: float, seed: int, sigma: float = 1.0) -> tuple[list[np.ndarray], list[float], list[float]]:
    """Frames of a camera with a Gaussian PSF and white noise of ``netd`` (signal 1 per K)."""
    rng = np.random.default_rng(seed)
    frames, freqs, dts = [], [], []
    for f in FREQUENCIES:
        for dt in DELTA_T:
            clean = four_bar(f, SHAPE, otf=gaussian_otf(sigma), levels=(0.0, dt))
            frames.append(clean + rng.normal(0.0, netd, SHAPE))
            freqs.append(f)
            dts.append(dt)
    return frames, freqs, dts


@pytest.fixture(scope="module")
def cameras() -> dict[str, BarFrames]:
    return {"low": BarFrames(*bar_set(0.05, 1)), "high": BarFrames(*bar_set(0.10, 2))}


def bar_directory(folder, frames, freqs, dts) -> str:
    os.makedirs(folder, exist_ok=True)
    lines = ["file,frequency_cy_per_px,delta_t_K"]
    for i, (frame, f, dt) in enumerate(zip(frames, freqs, dts)):
        name = f"bars_{i:02d}.npy"
        write_image(os.path.join(folder, name), frame, "npy")
        lines.append(f"{name},{f},{dt}")
    with open(os.path.join(folder, "bars.csv"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return str(folder)


def model_mrtd(netd: float, sigma: float = 1.0) -> Curve:
    f = np.linspace(0.0, 0.3, 31)
    return mrtd(Curve(f, np.exp(-2 * np.pi ** 2 * sigma ** 2 * f ** 2), x_unit="cy/px"), netd=netd, frame_rate=30.0)


# --------------------------------------------------------------------------- the similarity
def test_model_curves_of_twice_the_netd_score_exactly_eq4():
    s = mrtd_similarity(model_mrtd(0.04), model_mrtd(0.08))
    assert s.ratio == pytest.approx(2.0, rel=1e-12) and s.rho == pytest.approx(1.0, abs=1e-12)
    assert s.value == pytest.approx(0.8, abs=1e-12)  # 2·1·2/(1 + 4)
    assert s.max_deviation == pytest.approx(100.0, rel=1e-9)
    assert mrtd_similarity(model_mrtd(0.04), model_mrtd(0.04)).value == 1.0
    # the tolerance forgives a level difference up to it, and only the excess beyond it
    assert mrtd_similarity(model_mrtd(0.04), model_mrtd(0.08), tolerance=100).value == pytest.approx(1.0, abs=1e-12)
    beyond = mrtd_similarity(model_mrtd(0.04), model_mrtd(0.08), tolerance=25).value
    assert beyond == pytest.approx(1 / np.cosh(np.log(2 / 1.25)), abs=1e-12)
    # a blurrier simulator: an MRTD rising faster, which rho sees as well as mu
    blurred = mrtd_similarity(model_mrtd(0.04), model_mrtd(0.04, sigma=1.4))
    assert blurred.rho < 0.999 and blurred.mu < 0.9 and blurred.value < blurred.mu


def test_similarity_refuses_what_is_not_an_mrtd():
    good = model_mrtd(0.04)
    with pytest.raises(FidelityError, match="positive temperature difference"):
        mrtd_similarity(good, good.replace(y=-good.y))
    with pytest.raises(FidelityError, match="do not overlap"):
        mrtd_similarity(good, good.replace(x=good.x + 10))
    with pytest.raises(FidelityError, match="temperature difference in K"):
        mrtd_similarity(good, good.with_units(y_unit="counts"))
    with pytest.raises(FidelityError, match="tolerance"):
        mrtd_similarity(good, good, tolerance=-1)


# --------------------------------------------------------------------------- evaluate
def test_identical_cameras_score_one_and_twice_the_netd_lower(cameras):
    same = irf.evaluate(real_mrtd=cameras["low"], sim_mrtd=cameras["low"], weights="mrtd=1")
    assert same.components == {"mrtd": 1.0} and same.fidelity == 1.0
    noisy = irf.evaluate(real_mrtd=cameras["low"], sim_mrtd=cameras["high"], weights="mrtd=1")
    m = noisy.metrics
    assert 1.6 < m["mrtd_ratio"] < 2.4  # the measured MRTD scales with the NETD
    assert m["mrtd_rho"] > 0.98
    assert 0.7 < noisy.components["mrtd"] < 0.9
    assert (m["mrtd_f_min"], m["mrtd_f_max"], m["mrtd_f_unit"]) == (0.05, 0.14, "cy/px")
    # every key the schema lists for the component, in the report and its CSV columns
    assert [k for k in csv_columns(["mrtd"]) if k.startswith("mrtd_")] == list(m)
    assert "f_mrtd" in csv_columns(["mrtd"])
    loose = irf.evaluate(real_mrtd=cameras["low"], sim_mrtd=cameras["high"], weights="mrtd=1",
                         mrtd_options={"tolerance": 150})
    assert loose.components["mrtd"] == pytest.approx(loose.metrics["mrtd_rho"])


def test_the_component_is_opt_in_and_skipped_without_inputs(cameras):
    ramp = np.arange(64, dtype=np.uint16).reshape(8, 8)
    default = irf.evaluate(ramp, ramp + 1, peak="range", real_mrtd=cameras["low"], sim_mrtd=cameras["high"])
    assert "mrtd" not in default.components and "mrtd" not in default.skipped  # weight 0: not read
    assert irf.Weights().mrtd == 0.0
    dropped = irf.evaluate(ramp, ramp + 1, peak="range", weights="psnr=0.5,mrtd=0.5")
    assert "mrtd" not in dropped.components and "real_mrtd/sim_mrtd" in dropped.skipped["mrtd"]
    assert dropped.weights.psnr == 1.0
    with pytest.raises(FidelityError, match="real_mrtd/sim_mrtd"):
        irf.evaluate(ramp, ramp + 1, peak="range", weights="psnr=0.5,mrtd=0.5", missing="raise")
    with pytest.raises(FidelityError, match="sim_mrtd"):
        irf.evaluate(real_mrtd=cameras["low"], weights="mrtd=1")


def test_a_sequence_compares_the_mrtd_once_for_every_frame(tmp_path):
    ramp = np.arange(64, dtype=np.uint16).reshape(8, 8)
    frames = np.stack([ramp, ramp.T, ramp[::-1]])
    rep = irf.score_sequence(frames, frames, peak="range", weights="psnr=0.5,mrtd=0.5", progress=False,
                             real_mrtd=model_mrtd(0.04), sim_mrtd=model_mrtd(0.08))
    assert rep.components["mrtd"] == pytest.approx(0.8, abs=1e-12)
    assert [f["components"]["mrtd"] for f in rep.to_dict()["frames"]] == [rep.components["mrtd"]] * 3
    rep.to_csv(tmp_path / "s.csv")
    header = (tmp_path / "s.csv").read_text().splitlines()[0].split(",")
    assert "f_mrtd" in header and "mrtd_ratio" in header


def test_mrtd_inputs_from_curves_and_csv(tmp_path):
    real, sim = model_mrtd(0.04), model_mrtd(0.08)
    path = tmp_path / "sim_mrtd.csv"
    path.write_text("freq_cy_per_px,MRTD_K\n" + "".join(f"{x},{y}\n" for x, y in zip(sim.x, sim.y)))
    rep = irf.evaluate(real_mrtd=real, sim_mrtd=str(path), weights="mrtd=1")
    assert rep.components["mrtd"] == pytest.approx(0.8, abs=1e-9)
    assert rep.inputs["sim_mrtd"] == str(path)


def test_mtf_inputs_from_bars_and_from_a_ctf_curve():
    freqs = [0.05, 0.1, 0.15, 0.2, 0.25]
    bars = BarFrames([four_bar(f, SHAPE, otf=gaussian_otf(1.0)) for f in freqs], freqs, [1.0] * 5)
    measured = bar_curves(bars, quantities=("mtf",))
    assert list(measured) == ["mtf"] and measured["mtf"].meta["quantity"] == "mtf"
    edge_real = slanted_edge((96, 96), otf=gaussian_otf(1.0))
    rep = irf.evaluate(real_mtf=edge_real, sim_mtf=bars, weights="mtf=1")
    assert rep.sources["curves"]["sim_mtf"].x.tolist() == freqs
    np.testing.assert_allclose(rep.sources["curves"]["sim_mtf"].y, measured["mtf"].y)
    assert rep.components["mtf"] > 0.95  # the same camera seen through an edge and through bars
    # a CTF curve of ctf_curve is converted to an MTF by Coltman's series (noise-free bars)
    freqs = np.arange(1, 9) * 0.03
    ctf = ctf_curve([four_bar(f, (140, 140), otf=gaussian_otf(1.0)) for f in freqs], frequencies=freqs)
    assert ctf.meta["quantity"] == "ctf"
    with pytest.warns(irf.FidelityWarning):
        rep = irf.evaluate(real_mtf=ctf, sim_mtf=ctf, weights="mtf=1")
    with pytest.warns(irf.FidelityWarning):
        expected = mtf_from_ctf(ctf)
    np.testing.assert_array_equal(rep.sources["curves"]["real_mtf"].y, expected.y)
    assert not np.array_equal(expected.y, ctf.y)


# --------------------------------------------------------------------------- bar directories
def test_bar_directory_round_trip_and_errors(tmp_path, cameras):
    frames, freqs, dts = bar_set(0.05, 1)
    folder = bar_directory(tmp_path / "bars", frames, freqs, dts)
    read = BarFrames.read(folder)
    assert read.frequencies == tuple(freqs) and read.delta_t == tuple(dts) and read.unit == "cy/px"
    rep = irf.evaluate(real_mrtd=folder, sim_mrtd=cameras["low"], weights="mrtd=1")
    assert rep.components["mrtd"] == 1.0  # the same frames, from files and from arrays
    with pytest.raises(FidelityError, match="no bars.csv"):
        BarFrames.read(tmp_path)
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "bars.csv").write_text("file,frequency\nx.npy,0.1\n")
    with pytest.raises(FidelityError, match="no delta_t column"):
        BarFrames.read(tmp_path / "bad")
    (tmp_path / "bad" / "bars.csv").write_text("file,frequency,delta_t\nmissing.npy,0.1,1\n")
    with pytest.raises(FidelityError, match="row 2: bar frame 'missing.npy': no such file"):
        BarFrames.read(tmp_path / "bad")
    with pytest.raises(FidelityError, match="one finite number per frame"):
        BarFrames(frames[:2], [0.1], [1.0, 2.0])


# --------------------------------------------------------------------------- report
def test_report_plots_ctf_mtf_and_mrtd_of_both_cameras(cameras):
    edge = slanted_edge((96, 96), otf=gaussian_otf(1.0))
    rep = irf.evaluate(real_mrtd=cameras["low"], sim_mrtd=cameras["high"], real_mtf=edge, sim_mtf=edge,
                       weights="mtf=0.5,mrtd=0.5")
    curves = rep.sources["curves"]
    for side in ("real", "sim"):
        for kind in ("mrtd", "ctf", "bar_mtf", "mtf"):
            assert isinstance(curves[f"{side}_{kind}"], Curve), (side, kind)
    html = rep.to_html()
    start = html.index('<section id="bars">')
    bars_section = html[start:html.index("</section>", start)]
    assert "data:image/png;base64," in bars_section and "mrtd_ratio" in bars_section
    plain = irf.evaluate(np.zeros((8, 8)), np.zeros((8, 8)) + 1, peak=10.0, weights="psnr=1").to_html()
    assert 'id="bars" class="missing"' in plain and "no MRTD inputs were compared" in plain


# --------------------------------------------------------------------------- CLI
def test_cli_scores_bar_directories(tmp_path, capsys):
    real = bar_directory(tmp_path / "real", *bar_set(0.05, 1))
    sim = bar_directory(tmp_path / "sim", *bar_set(0.10, 2))
    frame = tmp_path / "frame.npy"
    np.save(frame, np.arange(64.0).reshape(8, 8))
    out = tmp_path / "r.json"
    code = main(["score", str(frame), str(frame), "--peak", "64", "--weights", "psnr=0.5,mrtd=0.5",
                 "--real-bars", real, "--sim-bars", sim, "--json", str(out), "--report", str(tmp_path / "r.html")])
    assert code == 0, capsys.readouterr().err
    got = json.loads(out.read_text())
    api = irf.evaluate(str(frame), str(frame), peak=64.0, weights="psnr=0.5,mrtd=0.5", real_mrtd=real, sim_mrtd=sim)
    assert got["components"]["mrtd"] == pytest.approx(api.components["mrtd"], abs=1e-12)
    assert 0.7 < got["components"]["mrtd"] < 0.9
    assert '<section id="bars">' in (tmp_path / "r.html").read_text()


@pytest.mark.parametrize("args, needle", [
    (["--real-bars", "{tmp}/nowhere", "--sim-bars", "{tmp}"], "--real-bars '{tmp}/nowhere': no such directory"),
    (["--real-bars", "{tmp}", "--sim-bars", "{tmp}"], "no bars.csv listing the bar frames"),
    (["--real-bars", "{bars}"], "needs the sim one too: give --sim-bars"),
])
def test_cli_bar_mistakes_are_one_line(tmp_path, capsys, args, needle):
    bars = tmp_path / "bars"
    bars.mkdir()
    (bars / "bars.csv").write_text("file,frequency,delta_t\n")
    frame = tmp_path / "frame.npy"
    np.save(frame, np.zeros((8, 8)))
    fill = {"tmp": str(tmp_path), "bars": str(bars)}
    code = main(["score", str(frame), str(frame), "--peak", "1", "--weights", "psnr=0.5,mrtd=0.5",
                 *[a.format(**fill) for a in args]])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and needle.format(**fill) in err[0], err


def test_cli_targets_writes_the_rendered_images(tmp_path, capsys):
    out = tmp_path / "t"
    assert main(["targets", str(out), "--frequency", "0.05,0.1", "--size", "96,100", "--blur", "1.0"]) == 0
    written = capsys.readouterr().out.split()
    assert [os.path.basename(p) for p in written] == ["four_bar_0.05.png", "four_bar_0.1.png", "bars.csv"]
    got = irf.load_frame(str(out / "four_bar_0.1.png"))
    want = four_bar(0.1, (96, 100), otf=gaussian_otf(1.0), levels=(16384, 49152))
    assert got.dtype == np.uint16 and np.array_equal(got, np.rint(want).astype(np.uint16))
    assert BarFrames.read(out).delta_t == (32768.0, 32768.0)
    assert main(["targets", str(out), "--kind", "three-bar", "--frequency", "0.1", "--format", "tiff"]) == 0
    tif = irf.load_frame(str(out / "three_bar_0.1.tif"))
    np.testing.assert_allclose(tif, irf.targets.three_bar(0.1, (128, 128)).astype(np.float32), atol=0)
    # peers read both files the same
    np.testing.assert_array_equal(tifffile.imread(out / "three_bar_0.1.tif"), tif)
    width, height, rows, info = png.Reader(filename=str(out / "four_bar_0.1.png")).read()
    assert info["bitdepth"] == 16 and np.array_equal(np.array(list(rows), dtype=np.uint16), got)
    assert main(["targets", str(out), "--kind", "edge", "--format", "npy", "--angle", "4"]) == 0
    np.testing.assert_array_equal(np.load(out / "edge.npy"), slanted_edge((128, 128), angle=4.0))
    capsys.readouterr()


@pytest.mark.parametrize("args, needle", [
    (["--frequency", "0.6"], "Nyquist"),
    (["--frequency", "0.1", "--levels", "0,70000"], "do not fit a 16-bit image"),
    (["--frequency", "a"], "--frequency: expected numbers"),
    (["--size", "12"], "--size: expected ROWS,COLS"),
    ([], "--frequency: give the bar frequencies"),
    (["--frequency", "0.1", "--blur", "0"], "--blur: expected a Gaussian sigma > 0"),
])
def test_cli_targets_mistakes_are_one_line(tmp_path, capsys, args, needle):
    code = main(["targets", str(tmp_path / "t"), *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and needle in err[0], err


def test_mrtd_options_are_checked_and_saved(tmp_path):
    cfg = irf.ScoringConfig(mrtd_options={"tolerance": 10, "frame_rate": 30}, weights="psnr=0.8,mrtd=0.2")
    cfg.save(tmp_path / "c.toml")
    assert irf.ScoringConfig.load(tmp_path / "c.toml") == cfg
    with pytest.raises(FidelityError, match="unknown option.*'tolerence'.*tolerance"):
        irf.ScoringConfig(mrtd_options={"tolerence": 10})
    with pytest.raises(FidelityError, match="mrtd_options.frame_rate: expected a finite number > 0"):
        irf.ScoringConfig(mrtd_options={"frame_rate": -1})
    with pytest.raises(FidelityError, match="mrtd_options.tolerance"):
        irf.ScoringConfig(mrtd_options={"tolerance": float("nan")})
