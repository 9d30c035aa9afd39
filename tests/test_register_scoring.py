"""Registration inside scoring (paper §2.4): ``evaluate(..., register=MODEL)`` aligns the
simulated frame to the real one and scores the overlap only; the CLI's ``--register``; and
sequences registered once on their first pair (tests/test_sequence_alignment.py: per frame, and
the frame delay)."""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys
import warnings

import cv2
import numpy as np
import pytest
import scipy.ndimage as ndi

import irfidelity as irf
from irfidelity.errors import RangeError
from irfidelity.report import render_pair_html
from scene_off import NO_SCENE

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
LEPTON = DATA / "cptv_v2_frame000.png"


def simulated_views() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A real Lepton frame, a simulated camera's view of it (blur, gain, offset, noise), and
    the same view displaced by 3 px and turned by 1°."""
    real = irf.load_frame(LEPTON)
    rng = np.random.default_rng(1)
    sim = ndi.gaussian_filter(real.astype(float), 0.6) * 1.01 + 3 + rng.normal(0, 4, real.shape)
    sim = np.clip(sim, 0, 65535).round().astype(np.uint16)
    rows, cols = real.shape
    m = cv2.getRotationMatrix2D(((cols - 1) / 2, (rows - 1) / 2), 1.0, 1.0)
    m[:, 2] += (3, 0)
    moved = cv2.warpAffine(sim.astype(np.float32), m, (cols, rows), flags=cv2.INTER_CUBIC,
                           borderMode=cv2.BORDER_REFLECT)
    return real, sim, moved.round().astype(np.uint16)


def quiet_evaluate(*args, **kwargs) -> irf.FidelityReport:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        return irf.evaluate(*args, **kwargs)


def test_registration_restores_the_score_of_a_displaced_simulated_frame():
    real, sim, moved = simulated_views()
    # the scene's transfer aligns each tile on its own (geometry is not resolution): alike
    with_scene = [quiet_evaluate(real, s, bits=16, peak="range") for s in (sim, moved)]
    assert abs(with_scene[0].components["mtf"] - with_scene[1].components["mtf"]) < 0.02
    assert with_scene[1].transfer["local_shift"] > with_scene[0].transfer["local_shift"]  # the rotation
    aligned = quiet_evaluate(real, sim, bits=16, peak="range", **NO_SCENE)
    displaced = quiet_evaluate(real, moved, bits=16, peak="range", **NO_SCENE)
    registered = quiet_evaluate(real, moved, bits=16, peak="range", register="rigid", **NO_SCENE)
    # unregistered, the image metrics measure the misalignment
    assert displaced.fidelity < aligned.fidelity - 0.08
    assert displaced.components["ssim"] < aligned.components["ssim"] - 0.1
    # registered, the score is the aligned one's within a percent
    assert abs(registered.fidelity - aligned.fidelity) < 0.01
    assert abs(registered.components["nmi"] - aligned.components["nmi"]) < 0.02
    reg = registered.registration
    assert reg["model"] == "rigid" and reg["confidence"] > 0.5
    dy, dx = reg["shift"]  # real ≈ shift(sim, (dy, dx)): the view moved +3 px in x
    assert abs(dx + 3) < 0.15 and abs(dy) < 0.15 and abs(reg["angle"] + 1) < 0.1
    # only the overlap is scored (less the interpolation's margin at its edge)
    assert 0.9 * reg["overlap"] * real.size < registered.metrics["n"] <= reg["overlap"] * real.size
    assert displaced.registration is None and aligned.config.register is None


def test_the_image_statistics_are_those_of_the_overlap_exactly():
    real, _, moved = simulated_views()
    rep = quiet_evaluate(real, moved, bits=16, register="translation")
    reg = irf.registration.Registration.from_dict(rep.registration)
    aligned, valid = reg.apply(moved)
    assert not valid.all() and np.isnan(aligned[~valid]).all()  # a border outside the overlap
    st = irf.pair_stats(real.astype(np.float64), aligned, peak=65535.0, mask=valid)
    assert rep.metrics["n"] == st.n == int(valid.sum())
    assert rep.metrics["mse"] == st.mse() and rep.metrics["nmi"] == st.nmi().value and rep.metrics["ssim"] == st.ssim().value
    # counting the border (filled with the frame's mean) would have changed every metric
    filled = np.where(valid, aligned, np.nanmean(aligned))
    assert irf.pair_stats(real.astype(np.float64), filled, peak=65535.0).mse() != st.mse()


def test_a_mask_and_the_overlap_combine():
    real, _, moved = simulated_views()
    mask = np.ones(real.shape, bool)
    mask[:20] = False
    whole = quiet_evaluate(real, moved, bits=16, register="translation")
    masked = quiet_evaluate(real, moved, bits=16, register="translation", mask=mask)
    assert masked.metrics["n"] < whole.metrics["n"] - 20 * real.shape[1] // 2


def test_the_report_records_and_shows_the_registration(tmp_path):
    real, _, moved = simulated_views()
    rep = quiet_evaluate(real, moved, bits=16, register="rigid")
    again = irf.FidelityReport.from_dict(json.loads(json.dumps(rep.to_dict())))
    assert again.registration == rep.to_dict()["registration"] and again.fidelity == rep.fidelity
    text = rep.summary_text()
    assert "registration (rigid, " in text and "overlap" in text and "angle" in text
    page = render_pair_html(rep.to_dict())
    assert '<section id="registration">' in page and "confidence" in page


def test_bit_depth_is_checked_before_registration():
    real, _, moved = simulated_views()
    assert real.max() > 2047
    with pytest.raises(RangeError, match="real frame: value .* outside the valid range 0 .. 2047"):
        quiet_evaluate(real, moved, bits=11, register="translation")


def test_an_ambiguous_pair_is_an_error_not_an_identity():
    x = np.arange(128)
    bars = [np.tile(1000 + 200 * (0.5 - np.abs(((x - shift) / 8.0) % 1.0 - 0.5)), (96, 1)) for shift in (0.0, -3.0)]
    with pytest.raises(irf.errors.RegistrationError, match="ambiguous"):  # periodic bars: every period matches
        quiet_evaluate(*bars, peak=1000.0, register="translation")


def test_a_sequence_is_registered_once_and_every_pair_scored_as_evaluate_scores_it(tmp_path):
    real, sim, moved = simulated_views()
    rng = np.random.default_rng(7)
    sims = [moved, np.clip(moved.astype(int) + rng.integers(-20, 20, moved.shape), 0, 65535).astype(np.uint16)]
    for side, frames in (("real", [real, real]), ("sim", sims)):
        (tmp_path / side).mkdir()
        for i, frame in enumerate(frames):
            cv2.imwrite(str(tmp_path / side / f"f{i}.png"), frame)
    for peak in ("range", None):
        options = dict(bits=16, register="rigid", progress=False, **NO_SCENE, **({} if peak is None else {"peak": peak}))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", irf.FidelityWarning)
            from_files = irf.score_sequence(tmp_path / "real", tmp_path / "sim", **options)  # the Rust engine
            from_arrays = irf.score_sequence(np.stack([real, real]), np.stack(sims), **options)
        first = quiet_evaluate(real, moved, bits=16, register="rigid", **NO_SCENE,
                               **({} if peak is None else {"peak": peak}))
        assert from_files.registration == from_arrays.registration == first.registration
        reg = irf.registration.Registration.from_dict(first.registration)
        for i, s in enumerate(sims):
            aligned, valid = reg.apply(s)
            st = irf.pair_stats(real.astype(np.float64), aligned, peak=65535.0, mask=valid)
            for rep in (from_files, from_arrays):
                frame = rep.frames[i]
                assert frame["error"] is None and frame["metrics"]["n"] == st.n == int(valid.sum())
                assert frame["metrics"]["mse"] == st.mse() and frame["metrics"]["nmi"] == st.nmi().value
            assert from_files.frames[0]["fidelity"] == first.fidelity
        assert "found on the first pair" in from_files.summary_text()
    back = irf.SequenceReport.from_dict(json.loads(json.dumps(from_files.to_dict())))
    assert back.registration == from_files.registration


def test_a_sequence_whose_first_pair_cannot_be_registered_fails_before_scoring():
    x = np.arange(128)
    bars = [np.tile(1000 + 200 * (0.5 - np.abs(((x - shift) / 8.0) % 1.0 - 0.5)), (96, 1)) for shift in (0.0, -3.0)]
    with pytest.raises(irf.errors.RegistrationError, match=r"registering the first readable pair \(\[0\] and \[0\]\)"):
        irf.score_sequence(np.stack([bars[0]] * 2), np.stack([bars[1]] * 2), peak=1000.0, register="translation",
                           progress=False)


def cli(*args):
    return subprocess.run([sys.executable, "-m", "irfidelity.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=180)


def test_cli_registers_pairs_and_sequences(tmp_path):
    real, _, moved = simulated_views()
    cv2.imwrite(str(tmp_path / "real.png"), real)
    cv2.imwrite(str(tmp_path / "moved.png"), moved)
    out = tmp_path / "r.json"
    p = cli("score", tmp_path / "real.png", tmp_path / "moved.png", "--bits", "16", "--register", "rigid",
            "--json", out)
    assert p.returncode == 0, p.stderr
    assert "registration (rigid" in p.stdout
    d = json.loads(out.read_text())
    assert d["registration"]["model"] == "rigid" and d["metrics"]["n"] < real.size
    stack = DATA / "cptv_v2_all100frames_uint16.tif"
    p = cli("score", stack, stack, "--pages", "0:3", "--register", "translation", "--json", out, "--csv",
            tmp_path / "f.csv")
    assert p.returncode == 0, p.stderr
    d = json.loads(out.read_text())
    assert d["registration"]["shift"] == [0.0, 0.0] and len(d["frames"]) == 3  # the same frames: no shift
    p = cli("score", stack, stack, "--pages", "0:3", "--register", "translation", "--max-delay", "2")
    assert p.returncode == 2 and "Traceback" not in p.stderr  # 3 frames cannot show a delay of 2
    assert "--max-delay" in p.stderr and "too large for sequences of 3 and 3 frames" in p.stderr


def test_the_schema_lists_every_registration_field():
    from irfidelity.schema import REGISTRATION

    real, _, moved = simulated_views()
    reg = irf.register(real, moved, model="similarity")
    assert list(reg.to_dict()) == [key for key, _, _ in REGISTRATION]
