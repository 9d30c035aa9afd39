"""Labelled regions (issue 27): each region of a label image scored on its own, beside the whole."""

from __future__ import annotations

import json
import pathlib
import pickle

import functools

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.errors import PeakWarning
from irfidelity.cli import main
from irfidelity.readback import ReportError
from scene_off import NO_SCENE

#: regions score the image components (and curves); the scene's transfer is the whole pair's
evaluate = functools.partial(irf.evaluate, **NO_SCENE)

DATA = pathlib.Path(__file__).parent / "data" / "thermal"

#: The components a region has of its own.
IMAGE = ("psnr", "nmi", "ssim")


@pytest.fixture(scope="module")
def pair() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two real frames of a blackbody scene, and labels: 1 the hot target (the top tenth of the
    real frame's levels), 2 the background of the lower half, 0 the rest."""
    real = irf.load_frame(DATA / "ptw_bb150C_frame000.png")
    sim = irf.load_frame(DATA / "ptw_bb150C_frame001.png")
    labels = np.zeros(real.shape, dtype=np.uint8)
    labels[real > np.percentile(real, 90)] = 1
    labels[(labels == 0) & (np.arange(real.shape[0])[:, None] >= real.shape[0] // 2)] = 2
    return real, sim, labels


def _same_result(entry: dict, want: irf.FidelityReport, *, assessed_alike: bool = True) -> None:
    """A region's entry equals the report of ``evaluate(mask=that region)`` (but for what the
    verdict says was not assessed, unless ``assessed_alike``: the pair's is the whole pair's)."""
    assert entry["components"] == want.components
    assert entry["fidelity"] == want.fidelity and entry["grade"] == want.grade
    assert entry["component_grades"] == want.component_grades and entry["membership"] == want.membership
    assert entry["metrics"] == {k: v for k, v in want.metrics.items() if k in entry["metrics"]}
    assert {"n"} | {c for c in ("nmi", "ssim") if c in want.components} <= set(entry["metrics"])
    if assessed_alike:
        assert entry["verdict"]["reason"] == want.verdict["reason"]
    else:
        assert entry["verdict"]["reason"].split("; not assessed")[0] == want.verdict["reason"].split("; not assessed")[0]


@pytest.mark.parametrize("peak", [None, "range"])
def test_each_region_equals_evaluate_with_its_mask(pair, peak):
    real, sim, labels = pair
    rep = evaluate(real, sim, regions=irf.Regions(labels, names=["target", "background"]), bits=14, peak=peak)
    assert list(rep.regions) == ["target", "background"]
    for label, name in ((1, "target"), (2, "background")):
        entry = rep.regions[name]
        assert entry["label"] == label and entry["pixels"] == int((labels == label).sum())
        _same_result(entry, evaluate(real, sim, mask=labels == label, bits=14, peak=peak))
    # the regions differ: the target's grey levels are not the background's
    assert rep.regions["target"]["metrics"]["mse"] != rep.regions["background"]["metrics"]["mse"]


def test_label_zero_is_scored_nowhere(pair):
    real, sim, labels = pair
    rep = evaluate(real, sim, regions=labels, bits=14, peak="range")
    whole = evaluate(real, sim, mask=labels != 0, bits=14, peak="range")
    assert (rep.fidelity, rep.components, rep.metrics) == (whole.fidelity, whole.components, whole.metrics)
    assert rep.metrics["n"] == sum(e["metrics"]["n"] for e in rep.regions.values()) == int((labels != 0).sum())
    spoiled = sim.copy()
    spoiled[labels == 0] = 0          # what label 0 holds changes nothing
    again = evaluate(real, spoiled, regions=labels, bits=14, peak="range")
    assert again.regions == rep.regions and again.fidelity == rep.fidelity


def test_without_regions_nothing_changes(pair):
    real, sim, _ = pair
    rep = evaluate(real, sim, bits=14)
    assert rep.regions == {} and "regions" not in rep.to_dict()
    assert "region " not in rep.summary_text()


def test_names_by_order_by_label_by_masks_and_by_default(pair):
    real, sim, labels = pair
    assert irf.Regions(labels).names == {1: "1", 2: "2"}
    assert irf.Regions(labels, names={"bg": 2, "hot": 1}).names == {1: "hot", 2: "bg"}
    assert irf.Regions(labels, names={2: "bg", 1: "hot"}).names == {1: "hot", 2: "bg"}
    by_masks = evaluate(real, sim, regions={"hot": labels == 1, "bg": labels == 2}, bits=14)
    by_labels = evaluate(real, sim, regions=irf.Regions(labels, names=["hot", "bg"]), bits=14)
    assert by_masks.regions == by_labels.regions and list(by_masks.regions) == ["hot", "bg"]
    assert irf.Regions(labels == 1).names == {1: "1"}          # a bool image is label 1
    regions = irf.Regions(labels, names=["hot", "bg"])
    assert pickle.loads(pickle.dumps(regions)) == regions and "hot: label 1" in repr(regions)


def test_mask_restricts_the_whole_and_every_region(pair):
    real, sim, labels = pair
    mask = np.ones(real.shape, dtype=bool)
    mask[:, : real.shape[1] // 3] = False
    rep = evaluate(real, sim, mask=mask, regions=labels, bits=14, peak="range")
    for label in (1, 2):
        _same_result(rep.regions[str(label)], evaluate(real, sim, mask=mask & (labels == label), bits=14,
                                                           peak="range"))
    assert rep.metrics["n"] == int((mask & (labels != 0)).sum())


@pytest.mark.filterwarnings("ignore::irfidelity.errors.CurveUnitsWarning")
def test_camera_components_are_the_pairs(pair):
    real, sim, labels = pair
    f = np.linspace(0, 0.5, 26)
    rep = evaluate(real, sim, real_mtf=(f, np.exp(-((f / 0.2) ** 2))), sim_mtf=(f, np.exp(-((f / 0.17) ** 2))),
                       regions=labels, bits=14, weights="mtf=0.4,psnr=0.2,ssim=0.4")
    for label, entry in rep.regions.items():
        assert entry["components"]["mtf"] == rep.components["mtf"]
        assert "mtf50_real" not in entry["metrics"]         # the camera's metrics stay the pair's
        _same_result(entry, evaluate(real, sim, real_mtf=(f, np.exp(-((f / 0.2) ** 2))),
                                         sim_mtf=(f, np.exp(-((f / 0.17) ** 2))), mask=labels == int(label),
                                         bits=14, weights="mtf=0.4,psnr=0.2,ssim=0.4"),
                     assessed_alike=False)  # the pair's scene cross-check found no real noise; a region's none


def test_each_region_has_its_own_ceiling(pair):
    real, sim, labels = pair
    ref = irf.load_frame(DATA / "ptw_bb150C_frame001.png")
    rep = evaluate(real, sim, regions=labels, real_ref=ref, bits=14)
    assert "real_ref" not in rep.sources
    for label, entry in rep.regions.items():
        want = evaluate(real, sim, mask=labels == int(label), real_ref=ref, bits=14)
        assert entry["ceiling"] == want.ceiling and entry["relative"] == want.relative
        _same_result(entry, want)
    given = evaluate(real, sim, regions=labels, ceiling={"nmi": 0.5, "ssim": 0.99}, bits=14)
    assert all(e["ceiling"] == {"nmi": 0.5, "ssim": 0.99} for e in given.regions.values())


def test_registered_regions_on_the_real_grid_within_the_overlap(pair):
    ndimage = pytest.importorskip("scipy.ndimage")
    real, _, labels = pair
    sim = ndimage.shift(real.astype(np.float64), (2.5, -1.5), order=1, mode="nearest").round().astype(np.uint16)
    plain = evaluate(real, sim, bits=14, register="translation")
    rep = evaluate(real, sim, regions=labels, bits=14, register="translation")
    assert rep.registration == plain.registration          # searched as without regions
    scored, aligned = rep.sources["mask"], rep.sources["sim"]
    assert not scored[labels == 0].any() and rep.metrics["n"] == int(scored.sum())
    assert rep.metrics["n"] == sum(e["metrics"]["n"] for e in rep.regions.values())
    for label, entry in rep.regions.items():
        within = (labels == int(label)) & scored
        want = irf.pair_stats(real.astype(np.float64), aligned, peak=16383.0, mask=within)
        assert entry["metrics"]["n"] == want.n and want.mse() > 0
        assert entry["metrics"]["mse"] == want.mse() and entry["metrics"]["nmi"] == want.nmi().value
        assert entry["metrics"]["ssim"] == want.ssim().value
    # the border the shift leaves uncovered is not scored
    assert rep.regions["2"]["metrics"]["n"] < rep.regions["2"]["pixels"]


def test_regions_in_a_temperature_unit(pair):
    real, sim, labels = pair
    kelvin_real, kelvin_sim = real.astype(np.float64) / 50 + 250, sim.astype(np.float64) / 50 + 250
    options = dict(unit="K", weights="psnr=0.3,ssim=0.3,radiometry=0.4")
    rep = evaluate(kelvin_real, kelvin_sim, regions=labels, **options)
    for label, entry in rep.regions.items():
        assert "radiometry" in entry["components"] and "temperature_rmse" in entry["metrics"]
        _same_result(entry, evaluate(kelvin_real, kelvin_sim, mask=labels == int(label), **options))


def test_json_round_trip_summary_and_pickle(pair):
    real, sim, labels = pair
    rep = evaluate(real, sim, regions=irf.Regions(labels, names=["target", "background"]), bits=14,
                       peak="range")
    data = json.loads(json.dumps(rep.to_dict()))
    assert list(data["regions"]) == ["target", "background"]
    back = irf.FidelityReport.from_dict(data)
    assert back == rep and back.regions == rep.regions
    assert pickle.loads(pickle.dumps(rep)) == rep
    lines = [line for line in rep.summary_text().splitlines() if line.startswith("region ")]
    assert len(lines) == 2 and lines[0].startswith("region target (label 1, ")
    assert f"fidelity {rep.regions['target']['fidelity']:.4f}" in lines[0]
    data["regions"]["target"]["fidelity"] = "high"
    with pytest.raises(ReportError, match=r"regions\.target\.fidelity"):
        irf.FidelityReport.from_dict(data)
    del data["regions"]["background"]["label"]
    data["regions"]["target"]["fidelity"] = 0.5
    with pytest.raises(ReportError, match=r"regions\.background: missing key\(s\) label"):
        irf.FidelityReport.from_dict(data)


def test_html_report_has_the_region_table(pair):
    pytest.importorskip("matplotlib")
    real, sim, labels = pair
    rep = evaluate(real, sim, regions=irf.Regions(labels, names=["target", "background"]), bits=14)
    page = rep.to_html()
    table = page[page.index('<section id="regions">'):]
    table = table[: table.index("</section>")]
    assert "<b>target</b>" in table and "<b>background</b>" in table
    assert f"<td>{rep.regions['target']['pixels']}</td>" in table
    assert '<section id="regions">' not in evaluate(real, sim, bits=14).to_html()


@pytest.mark.parametrize("regions, needle", [
    (np.full((240, 320), 1.0), "integer labels"),
    (np.full((240, 320), 300, dtype=np.int32), "label 300 at row 0, column 0 is outside 0..255"),
    (np.zeros((240, 320), dtype=np.uint8), "no pixel carries a label"),
    (np.ones((10, 10), dtype=np.uint8), r"the label image has shape \(10, 10\), the frames \(240, 320\)"),
    ({"a": np.ones((240, 320), bool), "b": np.ones((240, 320), bool)}, "regions 'a' and 'b' overlap"),
    ({"a": np.zeros((240, 320), bool)}, "region 'a' has no pixels"),
    ({"a": np.ones((240, 320), np.uint8)}, "expected a 2-D bool array"),
])
def test_bad_regions_are_named(pair, regions, needle):
    real, sim, _ = pair
    with pytest.raises(irf.FidelityError, match=needle) as caught:
        evaluate(real, sim, regions=regions, bits=14)
    assert caught.value.option == "regions"


def test_bad_names_and_empty_regions_are_named(pair):
    real, sim, labels = pair
    with pytest.raises(irf.FidelityError, match=r"region 'sky' \(label 3\) has no pixels"):
        irf.Regions(labels, names={"hot": 1, "bg": 2, "sky": 3})
    with pytest.raises(irf.FidelityError, match="label 2 .* has no name"):
        irf.Regions(labels, names=["hot"])
    with pytest.raises(irf.FidelityError, match="names must differ"):
        irf.Regions(labels, names=["x", "x"])
    with pytest.raises(irf.FidelityError, match="a region's name is letters"):
        irf.Regions(labels, names=["hot target", "bg"])
    mask = labels != 1
    with pytest.raises(irf.FidelityError, match=r"region '1' \(label 1\) has no pixel left to score"):
        evaluate(real, sim, mask=mask, regions=labels, bits=14)
    with pytest.raises(irf.FidelityError, match="no labelled pixel lies within mask="):
        evaluate(real, sim, mask=labels == 0, regions=labels, bits=14)
    with pytest.raises(irf.FidelityError, match="without real and sim"):
        evaluate(regions=labels, real_mtf=([0, 1], [1, 0]), sim_mtf=([0, 1], [1, 0]))
    with pytest.raises(irf.FidelityError, match="none is weighted"):
        evaluate(real, sim, regions=labels, real_mtf=([0, 0.5, 1], [1, 0.4, 0]),
                     sim_mtf=([0, 0.5, 1], [1, 0.4, 0]), weights="mtf=1")


# --------------------------------------------------------------------------- command line
@pytest.fixture
def files(pair, tmp_path):
    cv2 = pytest.importorskip("cv2")
    real, sim, labels = pair
    paths = {"real": tmp_path / "real.npy", "sim": tmp_path / "sim.npy", "png": tmp_path / "labels.png",
             "npy": tmp_path / "labels.npy"}
    np.save(paths["real"], real)
    np.save(paths["sim"], sim)
    np.save(paths["npy"], labels.astype(np.int64))
    cv2.imwrite(str(paths["png"]), labels)
    return {k: str(v) for k, v in paths.items()}


def test_cli_regions_json_csv_and_summary(pair, files, tmp_path, capsys):
    real, sim, labels = pair
    base = ["score", files["real"], files["sim"], "--bits", "14", "--peak", "range"]
    out, csv = tmp_path / "r.json", tmp_path / "r.csv"
    assert main([*base, "--regions", files["png"], "--region-names", "target,background", "--json", str(out),
                 "--csv", str(csv)]) == 0
    summary = capsys.readouterr().out
    assert "region target (label 1, " in summary and "region background (label 2, " in summary
    data = json.loads(out.read_text())
    want = irf.evaluate(real, sim, regions=irf.Regions(labels, names=["target", "background"]), bits=14,
                        peak="range")
    assert data["regions"] == json.loads(json.dumps(want.to_dict()))["regions"]
    header, row = (line.split(",") for line in csv.read_text().splitlines())
    values = dict(zip(header, row))
    assert header[-1] == "region_background_grade" and header.index("grade") < header.index("region_target_label")
    assert float(values["region_target_f_ssim"]) == pytest.approx(want.regions["target"]["components"]["ssim"],
                                                                  rel=1e-12)
    assert int(values["region_background_n"]) == want.regions["background"]["metrics"]["n"]
    assert main([*base, "--regions", files["npy"], "--region-names", "background=2,target=1", "--json",
                 str(out)]) == 0
    assert json.loads(out.read_text())["regions"] == data["regions"]


@pytest.mark.parametrize("flags, needle", [
    (["--regions", "{tmp}/nope.png"], "--regions"),
    (["--regions", "{float}"], "integer labels"),
    (["--regions", "{small}"], "the label image has shape (4, 4)"),
    (["--regions", "{png}", "--region-names", "a,b,c"], "region 'c' (label 3) has no pixels"),
    (["--regions", "{png}", "--region-names", "a"], "label 2"),
    (["--regions", "{png}", "--region-names", "a=1,b"], "give every name a label"),
    (["--regions", "{png}", "--region-names", "a=x,b=2"], "must be an integer"),
    (["--region-names", "a,b"], "--regions PATH, which is not given"),
    (["--regions", "{png}", "--roi", "0:2,0:2"], "no labelled pixel lies within mask="),
])
def test_cli_region_errors_are_one_line(files, tmp_path, capsys, flags, needle):
    np.save(tmp_path / "float.npy", np.ones((240, 320)))
    np.save(tmp_path / "small.npy", np.ones((4, 4), dtype=np.uint8))
    where = {"tmp": str(tmp_path), "float": str(tmp_path / "float.npy"), "small": str(tmp_path / "small.npy"),
             "png": files["png"]}
    argv = ["score", files["real"], files["sim"], "--bits", "14", *(f.format(**where) for f in flags)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err and "Traceback" not in err


def test_cli_regions_refused_for_sequences(files, tmp_path, capsys):
    assert main(["score", str(DATA / "cptv_v2_all100frames_uint16.tif"), str(DATA / "cptv_v2_all100frames_uint16.tif"),
                 "--regions", files["png"]]) == 2
    assert "--regions applies to single pairs" in capsys.readouterr().err


def test_regions_are_planned_against_the_pair_budget(pair):
    """The label image and one region's mask at a time (a byte a pixel each) on top of the pair's plan."""
    real, sim, labels = pair
    n = real.size
    evaluate(real, sim, mask=labels != 0, bits=14, max_bytes=8 * n)       # the pair alone fits
    with pytest.raises(irf.FidelityError, match="scoring regions of 240 x 320 pixel frames"):
        evaluate(real, sim, regions=labels, bits=14, max_bytes=9 * n)
    assert evaluate(real, sim, regions=labels, bits=14, max_bytes=10 * n).regions


def test_regions_reuse_the_noise_ceiling_and_say_so(pair):
    real, sim, labels = pair
    rep = evaluate(real, sim, regions=labels, real_noise={"tvh": 2.0}, bits=14)
    assert rep.ceiling_source == "noise3d"
    for entry in rep.regions.values():
        assert entry["ceiling"] == rep.ceiling
        assert entry["verdict"]["ceiling_source"] == "noise3d"


def test_the_peak_warning_is_the_pairs_alone(pair):
    real, sim, labels = pair
    real, sim = real // 8, sim // 8  # a range far below the uint16 peak
    with pytest.warns(PeakWarning) as caught:
        rep = evaluate(real, sim, regions=labels)
    assert len([w for w in caught if issubclass(w.category, PeakWarning)]) == 1
    assert sum("PeakWarning" in n for n in rep.notes) == 1
