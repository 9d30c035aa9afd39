"""Loose ends a new user hit (issue 26), each with its regression test: bits and a numeric peak
compose; irf.stats.psnr takes peak="range"; mtf_from_edge takes a path; per-side edge channels; CLI
messages name flags, not keyword arguments; the report's notes say what to pass."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.cli import main
from irfidelity.config import ScoringConfig
from irfidelity.curves import mtf_from_edge
from irfidelity.errors import FidelityError, FrameError, RangeError, ShapeError
from irfidelity.judgements import fit_weights

DATA = pathlib.Path(__file__).parent / "data"
REAL = str(DATA / "thermal" / "ptw_bb150C_frame000.png")
SIM = str(DATA / "thermal" / "ptw_bb150C_frame001.png")
RGBA_EDGE = str(DATA / "curves" / "sfr_edge_x2084_y0616_F2.png")
RGBA_EDGE_SIM = str(DATA / "curves" / "sfr_edge_x2088_y0616_F2_8.png")


def frames() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(26)
    real = rng.integers(1000, 3000, size=(48, 64)).astype(np.uint16)
    return real, (real.astype(np.int64) + rng.integers(-20, 21, size=real.shape)).astype(np.uint16)


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out = capsys.readouterr()
    return rc, out.out, out.err


@pytest.fixture
def grey_sim_edge(tmp_path) -> str:
    """A one-channel simulated edge image (the G channel of an RGBA crop, as .npy)."""
    path = tmp_path / "sim_edge.npy"
    np.save(path, irf.load_frame(RGBA_EDGE_SIM, channel="G"))
    return str(path)


# --------------------------------------------------------------------------- bits and peak
def test_bits_and_a_numeric_peak_compose():
    real, sim = frames()
    cfg = ScoringConfig(bits=12, peak=100)
    assert (cfg.bits, cfg.peak) == (12, 100.0)
    rep = irf.evaluate(real, sim, config=cfg, weights="psnr=1")
    assert rep.metrics["psnr_peak"] == 100.0
    assert rep.metrics["psnr_db"] == pytest.approx(irf.stats.psnr(real, sim, peak=100))
    assert irf.stats.psnr(real, sim, bits=12, peak=100) == pytest.approx(irf.stats.psnr(real, sim, peak=100))
    too_big = real.copy()
    too_big[5, 7] = 4096  # bits still bounds the values
    with pytest.raises(RangeError, match="4096"):
        irf.evaluate(too_big, sim, bits=12, peak=100, weights="psnr=1")
    with pytest.raises(RangeError):
        irf.stats.psnr(too_big, sim, bits=12, peak=100)


def test_bits_bound_the_full_histogram_range_when_a_peak_is_given():
    real, sim = frames()
    _, edges, _ = irf.pair_stats(real, sim, bits=12, peak=100, bins=16, hist_range="full").joint_histogram()
    _, bits_only, _ = irf.pair_stats(real, sim, bits=12, bins=16, hist_range="full").joint_histogram()
    np.testing.assert_array_equal(edges, bits_only)
    assert edges[0] == 0 and edges[-1] >= 4095


def test_bits_and_peak_in_a_sequence():
    real, sim = frames()
    stack_r, stack_s = np.stack([real, real]), np.stack([sim, sim])
    rep = irf.score_sequence(stack_r, stack_s, bits=12, peak=100, progress=False, weights="psnr=1")
    assert rep.metrics["psnr_peak"] == 100.0
    assert rep.metrics["psnr_db"] == pytest.approx(irf.stats.psnr(real, sim, peak=100))


def test_cli_peak_and_bits(capsys):
    rc, out, err = cli(capsys, "score", REAL, SIM, "--bits", "16", "--peak", "100", "--json", "-")
    assert rc == 0, err
    report = json.loads(out)
    assert report["metrics"]["psnr_peak"] == 100.0 and report["config"]["bits"] == 16
    assert main(["score", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    assert "--peak overrides the peak; --bits still bounds the values" in help_text


# --------------------------------------------------------------------------- psnr range
def test_psnr_range_matches_evaluate():
    real, sim = frames()
    expected = irf.evaluate(real, sim, peak="range", weights="psnr=1").metrics["psnr_db"]
    assert irf.stats.psnr(real, sim, peak="range") == pytest.approx(expected, rel=1e-12)
    span = float(real.max()) - float(real.min())
    assert irf.stats.psnr(real, sim, peak="range") == pytest.approx(irf.stats.psnr(real, sim, peak=span), rel=1e-12)


def test_psnr_range_counts_the_masked_pixels_only():
    real, sim = frames()
    mask = np.zeros(real.shape, bool)
    mask[10:30, 5:50] = True
    span = float(real[mask].max()) - float(real[mask].min())
    assert irf.stats.psnr(real, sim, peak="range", mask=mask) == pytest.approx(
        irf.stats.psnr(real, sim, peak=span, mask=mask))
    expected = irf.evaluate(real, sim, peak="range", mask=mask, weights="psnr=1").metrics["psnr_db"]
    assert irf.stats.psnr(real, sim, peak="range", mask=mask) == pytest.approx(expected, rel=1e-12)


def test_psnr_range_on_float_frames_and_errors():
    real, sim = (f.astype(np.float32) / 7 for f in frames())
    assert irf.stats.psnr(real, sim, peak="range") == pytest.approx(
        irf.stats.psnr(real, sim, peak=float(real.max()) - float(real.min())), rel=1e-9)
    with pytest.raises(FidelityError, match="more than one value") as info:
        irf.stats.psnr(np.ones((8, 8)), np.zeros((8, 8)), peak="range")
    assert info.value.option == "peak"
    with pytest.raises(FidelityError, match="a positive number or 'range'"):
        irf.stats.psnr(real, sim, peak="max")


# --------------------------------------------------------------------------- edges
def test_mtf_from_edge_reads_a_path():
    from_path = mtf_from_edge(RGBA_EDGE, channel="G")
    from_array = mtf_from_edge(irf.load_frame(RGBA_EDGE, channel="G"))
    np.testing.assert_array_equal(from_path.y, from_array.y)
    assert from_path.name == "sfr_edge_x2084_y0616_F2.png"
    assert mtf_from_edge(pathlib.Path(RGBA_EDGE), channel="G", name="mine").name == "mine"


def test_mtf_from_edge_path_errors_name_the_file():
    with pytest.raises(FrameError, match="sfr_edge_x2084_y0616_F2.png: several channels .*channel="):
        mtf_from_edge(RGBA_EDGE)
    with pytest.raises(FidelityError, match="ptw_bb150C_frame000.png: .*edge"):
        mtf_from_edge(REAL)
    with pytest.raises(FidelityError, match="channel= selects a channel of an image file"):
        mtf_from_edge(irf.load_frame(RGBA_EDGE, channel="G"), channel="G")


def test_each_side_has_its_edge_channel(grey_sim_edge):
    real, sim = irf.load_frame(REAL), irf.load_frame(SIM)
    rep = irf.evaluate(real, sim, bits=16, real_mtf=RGBA_EDGE, sim_mtf=grey_sim_edge, real_edge_channel="G")
    expected = irf.curves.mtf_similarity(mtf_from_edge(RGBA_EDGE, channel="G"), mtf_from_edge(grey_sim_edge))
    assert rep.components["mtf"] == pytest.approx(expected.value)
    with pytest.raises(FrameError, match="sim_edge.npy: .npy files have no channels"):
        irf.evaluate(real, sim, bits=16, real_mtf=RGBA_EDGE, sim_mtf=grey_sim_edge, edge_channel="G")


def test_edge_channel_is_both_sides_unless_a_side_has_its_own():
    from irfidelity.camera import edge_channel

    cfg = ScoringConfig(edge_channel="R", sim_edge_channel="Y")
    assert (edge_channel(cfg, "real"), edge_channel(cfg, "sim")) == ("R", "Y")
    assert edge_channel(ScoringConfig(real_edge_channel="G"), "sim") is None


def test_configs_with_edge_channel_still_load(tmp_path):
    path = tmp_path / "old.toml"
    path.write_text('edge_channel = "G"\nbits = 14\n', encoding="utf-8")
    cfg = ScoringConfig.load(path)
    assert (cfg.edge_channel, cfg.real_edge_channel, cfg.sim_edge_channel) == ("G", None, None)
    both = cfg.replace(real_edge_channel="R", sim_edge_channel="Y")
    both.save(tmp_path / "new.toml")
    assert ScoringConfig.load(tmp_path / "new.toml") == both


def test_cli_real_edge_channel(capsys, grey_sim_edge):
    rc, out, err = cli(capsys, "score", REAL, SIM, "--bits", "16", "--real-edge", RGBA_EDGE, "--sim-edge",
                       grey_sim_edge, "--real-edge-channel", "G", "--json", "-")
    assert rc == 0, err
    assert json.loads(out)["config"]["real_edge_channel"] == "G"
    assert "mtf" in json.loads(out)["components"]


# --------------------------------------------------------------------------- CLI wording
def test_cli_names_the_edge_channel_flag(capsys, grey_sim_edge):
    rc, _, err = cli(capsys, "score", REAL, SIM, "--bits", "16", "--real-edge", RGBA_EDGE, "--sim-edge",
                     grey_sim_edge)
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert "--real-edge-channel" in err and "channel=" not in err


def test_cli_names_the_frame_channel_flag(capsys):
    rc, _, err = cli(capsys, "score", REAL, RGBA_EDGE)
    assert rc == 2 and "--sim-channel" in err and "channel=" not in err, err
    rc, _, err = cli(capsys, "score", RGBA_EDGE, RGBA_EDGE_SIM, "--sim-channel", "G")
    assert rc == 2 and "--real-channel" in err and "channel=" not in err, err


def test_dtype_advice_in_the_api_and_the_cli(tmp_path, capsys):
    real, sim = frames()
    with pytest.raises(ShapeError, match=r"sim\.astype\(real\.dtype\)"):
        irf.stats.psnr(real, sim.astype(np.float32), peak=100)
    np.save(tmp_path / "real.npy", real)
    np.save(tmp_path / "sim.npy", sim.astype(np.float32))
    rc, _, err = cli(capsys, "score", str(tmp_path / "real.npy"), str(tmp_path / "sim.npy"), "--peak", "100")
    assert rc == 2 and "astype" not in err and "sample type" in err, err


def test_cli_rewrites_only_the_advice():
    from irfidelity.cli.output import cli_wording

    assert cli_wording("plain message") == "plain message"
    assert "--channel" in cli_wording("x.png: several channels (R, G); choose one with channel=...")


# --------------------------------------------------------------------------- report notes
def test_report_notes_say_what_to_pass():
    pytest.importorskip("matplotlib")
    real, sim = frames()
    page = irf.evaluate(real, sim, weights="image_quality", missing="renormalize").to_html()
    assert "curves={" not in page and "pass curves" not in page
    for needle in ("real_mtf= and sim_mtf=", "--real-mtf/--sim-mtf", "real_sitf= and sim_sitf=", "--real-sitf"):
        assert needle in page


def test_a_bool_npy_mask_is_read_and_a_mask_of_nan_is_refused(tmp_path, capsys):
    shape = irf.load_frame(REAL).shape
    keep = np.ones(shape, dtype=bool)
    keep[:10] = False
    np.save(tmp_path / "bool.npy", keep)
    np.save(tmp_path / "nan.npy", np.full(shape, np.nan))
    rep = irf.evaluate(REAL, SIM, bits=14, mask=tmp_path / "bool.npy")
    assert rep.metrics["n"] + rep.metrics["masked"] == keep.size and rep.metrics["masked"] >= (~keep).sum()
    assert main(["score", REAL, SIM, "--bits", "14", "--mask", str(tmp_path / "bool.npy")]) == 0
    capsys.readouterr()
    assert main(["score", REAL, SIM, "--bits", "14", "--mask", str(tmp_path / "nan.npy")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not finite" in err and "--mask" in err, err


@pytest.mark.parametrize("flags, needle", [
    (["--levels", "0,1e308", "--format", "tiff"], "--levels 0,1e308"),
    (["--levels", "0,nan", "--format", "npy"], "--levels 0,nan"),
    (["--size", "30000,30000", "--format", "npy"], "--size 30000,30000"),
    (["--size", "0,10"], "--size 0,10"),
])
def test_targets_refuse_sizes_and_levels_they_cannot_write(tmp_path, capsys, flags, needle):
    assert main(["targets", str(tmp_path / "out"), "--frequency", "0.1", *flags]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err, err
    assert not list((tmp_path).glob("out/*.*"))  # nothing written


def test_rank_refuses_resamples_beyond_its_bound(capsys):
    lepton = str(DATA / "thermal" / "cptv_v2_all100frames_uint16.tif")
    assert main(["rank", lepton, lepton, lepton, "--names", "a,b", "--no-progress", "--resamples", "100000000"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "99..1000000" in err and "--resamples" in err, err


def test_the_conversion_to_temperature_is_planned_against_max_bytes():
    fff = DATA / "radiometric" / "flirpy_frame_000000.fff"
    assert irf.load_frame(fff, unit="C", max_bytes=4_000_000).dtype == np.float64  # counts + kelvin: 3.3 MB
    with pytest.raises(FidelityError, match=r"conversion to temperature of 512 x 640 .*max_bytes"):
        irf.load_frame(fff, unit="C", max_bytes=2_000_000)  # the counts decode within it; their kelvin not


def test_weights_fit_answers_a_huge_field_and_too_many_rows_in_one_line(tmp_path, capsys, monkeypatch):
    import irfidelity.judgements as judgements

    header = "a_psnr,a_ssim,b_psnr,b_ssim,preferred\n"
    huge = tmp_path / "huge.csv"
    huge.write_text(header + "0.9,0.7,0.8,0.9," + "b" * 200_000 + "\n")
    many = tmp_path / "many.csv"
    many.write_text(header + "0.9,0.7,0.8,0.9,b\n" * 11)
    monkeypatch.setattr(judgements, "MAX_JUDGEMENTS", 10)
    for path, needle in ((huge, "line 2: not a CSV row"), (many, "more than 10 judgement rows")):
        assert main(["weights", "fit", str(path)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and needle in err and str(path) in err, err


def test_weights_fit_names_a_value_outside_the_components_range_and_stays_quiet(tmp_path, capsys):
    header = "a_psnr,a_ssim,b_psnr,b_ssim,preferred\n"
    huge = tmp_path / "huge.csv"
    huge.write_text(header + "1e308,0.7,0.8,0.9,b\n0.5,0.7,0.8,0.9,a\n")
    assert main(["weights", "fit", str(huge)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "line 2, column 'a_psnr'" in err and "outside [0, 1]" in err, err
    with pytest.raises(FidelityError, match=r"component psnr must be a number in \[0, 1\]"):
        fit_weights([({"psnr": 2.0, "ssim": 0.5}, {"psnr": 0.5, "ssim": 0.5}, "a")] * 3)
    # judgements no non-negative weighting can follow: one line, no warning from the fit's long steps
    contrary = tmp_path / "contrary.csv"
    contrary.write_text(header + "0.9,0.7,0.8,0.9,b\n0.5,0.7,0.8,0.9,a\n0.9,0.2,0.1,0.9,b\n0.3,0.2,0.1,0.9,a\n")
    assert main(["weights", "fit", str(contrary)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no weighting over a coin toss" in err, err[:2000]


def test_rank_takes_the_decode_limit_and_budget_and_says_why_nothing_was_scored(capsys):
    lepton = str(DATA / "thermal" / "cptv_v2_all100frames_uint16.tif")
    assert main(["rank", lepton, lepton, lepton, "--names", "a,b", "--no-progress", "--max-pixels", "100"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "simulator 'a'" in err and "100 failed" in err, err
    assert "exceeds the limit of 100 pixels; raise max_pixels (--max-pixels)" in err, err
    assert main(["rank", lepton, lepton, lepton, "--names", "a,b", "--no-progress", "--max-memory", "100k"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "simulator 'a'" in err[0] and "memory budget of" in err[0] and "--max-memory" in err[0], err
