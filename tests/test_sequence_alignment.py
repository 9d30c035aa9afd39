"""Sequences aligned in space and time: every pair registered on its own (``register_each``)
and the frame delay between the two sequences (``max_delay``), on real thermal recordings."""

from __future__ import annotations

import csv
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
from irfidelity.errors import FidelityError
from irfidelity.registration import DEFAULT_METHOD
from irfidelity.report import render_sequence_html
from scene_off import NO_SCENE

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
LEPTON_STACK = DATA / "cptv_v2_all100frames_uint16.tif"


def stack(path: pathlib.Path, count: int) -> np.ndarray:
    return np.stack([irf.load_frame(path, page=i) for i in range(count)])


def simulated(frame: np.ndarray, rng: np.random.Generator, shift=(0.0, 0.0)) -> np.ndarray:
    """A simulated camera's view of a real frame: blurred, gain/offset changed, noised, seen
    from a viewpoint displaced so that ``real ≈ shift(sim, shift)``."""
    view = ndi.gaussian_filter(frame.astype(float), 0.6) * 1.02 + 4
    view = ndi.shift(view, (-shift[0], -shift[1]), order=3, mode="nearest") + rng.normal(0, 3, frame.shape)
    return np.clip(view, 0, 65535).round().astype(np.uint16)


def quietly(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        return fn(*args, **kwargs)


def write_pngs(folder: pathlib.Path, frames, prefix: str = "f") -> None:
    folder.mkdir()
    for i, frame in enumerate(frames):
        cv2.imwrite(str(folder / f"{prefix}{i:03d}.png"), frame)


# ---- registration per frame -------------------------------------------------------------

@pytest.fixture(scope="module")
def moving_view():
    """Six real Lepton frames and their simulated views, each from its own viewpoint."""
    rng = np.random.default_rng(3)
    real = stack(LEPTON_STACK, 6)
    shifts = [tuple(rng.uniform(-3, 3, 2)) for _ in real]
    return real, [simulated(f, rng, s) for f, s in zip(real, shifts)], shifts


def test_every_pair_is_registered_on_its_own_and_scored_as_evaluate_scores_it(tmp_path, moving_view):
    real, sims, shifts = moving_view
    write_pngs(tmp_path / "real", real)
    write_pngs(tmp_path / "sim", sims)
    options = dict(register="translation", register_each=True, bits=16, peak="range", progress=False, **NO_SCENE)
    from_files = quietly(irf.score_sequence, tmp_path / "real", tmp_path / "sim", csv=tmp_path / "f.csv", **options)
    from_arrays = quietly(irf.score_sequence, real, np.stack(sims), **options)
    assert not from_files.failed and not from_arrays.failed
    for i, (dy, dx) in enumerate(shifts):
        alone = quietly(irf.evaluate, real[i], sims[i], register="translation", bits=16, peak="range", **NO_SCENE)
        for rep in (from_files, from_arrays):
            frame = rep.frames[i]
            assert frame["registration"] == alone.registration
            assert frame["fidelity"] == alone.fidelity and frame["metrics"] == alone.metrics
        found = from_files.frames[i]["registration"]["shift"]
        assert abs(found[0] - dy) < 0.1 and abs(found[1] - dx) < 0.1, (found, (dy, dx))
    # the report: the spread of the frames' registrations, and each row's own in the CSV
    summary = from_files.registration
    assert summary["each"] and summary["frames"] == 6 and summary["model"] == "translation"
    assert summary["shift_dx"]["min"] == min(f["registration"]["shift"][1] for f in from_files.frames)
    assert f"registration per frame (translation, {DEFAULT_METHOD}): 6 frames" in from_files.summary_text()
    rows = list(csv.DictReader(open(tmp_path / "f.csv")))
    assert [float(r["reg_dx"]) for r in rows] == [f["registration"]["shift"][1] for f in from_files.frames]
    assert all(float(r["reg_confidence"]) > 0.5 for r in rows)
    back = irf.SequenceReport.from_dict(json.loads(json.dumps(from_files.to_dict())))
    assert back.registration == summary and back.frames[2]["registration"] == from_files.frames[2]["registration"]
    page = render_sequence_html(back.to_dict())
    assert '<section id="registration"><h2>Registration per frame</h2>' in page and "6 frames registered" in page


@pytest.mark.parametrize("each", [False, True], ids=["registered-once", "registered-each"])
def test_the_peak_range_is_that_of_the_pixels_scored(tmp_path, moving_view, each):
    real, sims, _ = moving_view
    real = real.copy()
    real[:, :2, :] = real.max() + 500  # a hot border outside the overlap (the views move ≥ 3 px up)
    sims = [ndi.shift(s, (-6, 0), order=0, mode="nearest") for s in sims]
    write_pngs(tmp_path / "real", real)
    write_pngs(tmp_path / "sim", sims)
    options = dict(register="translation", register_each=each, bits=16, peak="range", progress=False, **NO_SCENE)
    for source in ((tmp_path / "real", tmp_path / "sim"), (real, np.stack(sims))):
        rep = quietly(irf.score_sequence, *source, **options)
        for i in (0, 3):
            reg = irf.registration.Registration.from_dict(rep.frames[i]["registration"])
            assert not reg.apply(sims[i])[1][:2].any()  # the hot border is not scored
            alone = quietly(irf.evaluate, real[i], sims[i], register="translation", bits=16, peak="range", **NO_SCENE)
            if each:
                assert rep.frames[i]["metrics"] == alone.metrics
            assert rep.frames[i]["metrics"]["psnr_peak"] <= float(real[i, 2:].max()) - float(real[i, 2:].min())


def test_a_pair_that_cannot_be_registered_is_its_own_error_row(tmp_path, moving_view):
    real, sims, _ = moving_view
    sims = list(sims)
    sims[2] = np.full_like(sims[2], 3000)  # a blank simulated frame: nothing to align
    write_pngs(tmp_path / "real", real)
    write_pngs(tmp_path / "sim", sims)
    for source in ((tmp_path / "real", tmp_path / "sim"), (real, np.stack(sims))):
        rep = quietly(irf.score_sequence, *source, register="translation", register_each=True, bits=16,
                      progress=False)
        assert rep.failed == [2] and "flat" in rep.frames[2]["error"]
        assert rep.registration["frames"] == 5 and rep.fidelity is not None


def test_a_resumed_run_keeps_each_frames_registration(tmp_path, moving_view):
    real, sims, _ = moving_view
    write_pngs(tmp_path / "real", real)
    write_pngs(tmp_path / "sim", sims)
    options = dict(register="rigid", register_each=True, bits=16, progress=False, csv=tmp_path / "f.csv")
    first = quietly(irf.score_sequence, tmp_path / "real", tmp_path / "sim", **options)
    again = quietly(irf.score_sequence, tmp_path / "real", tmp_path / "sim", resume=True, **options)
    assert again.run["resumed"] == 6
    assert again.frames == first.frames and again.registration == first.registration


def test_registering_each_pair_needs_a_model():
    with pytest.raises(FidelityError, match="register_each: registers every pair with the model of register") as err:
        irf.ScoringConfig(register_each=True)
    assert err.value.option == "register_each"


# ---- the frame delay --------------------------------------------------------------------
# The recordings in tests/data are of still scenes (their frames differ by sensor noise), and
# a still scene has no delay to find. So the moving sequences are a camera panning over a
# real 640×512 XT-R frame along a random walk; the simulated camera sees the same path with
# its own blur, gain, offset and noise, and optionally from a displaced viewpoint.

XTR = DATA / "readthermal_zenmuse_xtr_raw16.png"


def panning(count: int, delay: int, view_shift=(0.0, 0.0), seed: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """``(real, sim)`` of ``count`` 128×160 frames where real frame ``i`` shows what simulated
    frame ``i + delay`` shows."""
    scene = irf.load_frame(XTR).astype(float)
    rng = np.random.default_rng(seed)
    path = np.cumsum(rng.integers(-4, 5, (count + abs(delay), 2)), axis=0) + (150, 200)
    noise = 0.05 * scene.std()

    def frame(t: int, simulated_view: bool) -> np.ndarray:
        y, x = path[t]
        if simulated_view:
            around = ndi.gaussian_filter(scene[y - 8:y + 136, x - 8:x + 168], 0.7)
            view = ndi.shift(around, (-view_shift[0], -view_shift[1]), order=3)[8:136, 8:168] * 1.1 + 20
        else:
            view = scene[y:y + 128, x:x + 160]
        return np.clip(view + rng.normal(0, noise, view.shape), 0, 65535).round().astype(np.uint16)

    start_real, start_sim = max(delay, 0), max(-delay, 0)
    real = np.stack([frame(start_real + i, False) for i in range(count)])
    sim = np.stack([frame(start_sim + i, True) for i in range(count)])
    return real, sim


@pytest.mark.parametrize("view_shift", [(0.0, 0.0), (1.5, -2.0)], ids=["same-view", "displaced-view"])
@pytest.mark.parametrize("delay", [3, -2, 0])
def test_the_delay_between_two_sequences_is_found_and_frames_paired_by_it(delay, view_shift):
    real, sim = panning(60, delay, view_shift)
    rep = quietly(irf.score_sequence, real, sim, max_delay=5, peak="range", progress=False, **NO_SCENE)
    assert rep.delay["frames"] == delay and rep.delay["confidence"] > 0.5
    paired = [f for f in rep.frames if f["index"] not in rep.unpaired]
    assert len(paired) == 60 - abs(delay) and not rep.failed
    assert len(rep.delay["unpaired"]["real"]) == len(rep.delay["unpaired"]["sim"]) == abs(delay)
    # the frames the delay leaves at the ends are rows with the reason, not failures
    assert len(rep.frames) == 60 + abs(delay) and len(rep.unpaired) == 2 * abs(delay)
    for i in rep.unpaired:
        f = rep.frames[i]
        missing = "simulated" if f["sim"] is None else "real"
        assert f["error"] == f"{f['real'] or f['sim']}: no {missing} frame pairs with it at delay {delay:+d}"
        assert f["fidelity"] is None and f["real"] in rep.delay["unpaired"]["real"] + [None]
    # every pair is the right one: the pair scored alone gives the same numbers
    first = paired[0]
    real_index, sim_index = (0, delay) if delay >= 0 else (-delay, 0)
    assert (first["real"], first["sim"]) == (f"[{real_index}]", f"[{sim_index}]")
    alone = quietly(irf.evaluate, real[real_index], sim[sim_index], peak="range", **NO_SCENE)
    assert first["fidelity"] == alone.fidelity
    if delay:  # paired without the delay, the metrics measure the motion, not the simulator
        unaligned = quietly(irf.score_sequence, real, sim, peak="range", progress=False, **NO_SCENE)
        assert unaligned.fidelity < rep.fidelity - 0.03
    assert "delay: " in rep.summary_text() and "paired by delay" in rep.summary_text()
    page = render_sequence_html(rep.to_dict())
    assert '<section id="delay"><h2>Frame delay</h2>' in page and f"confidence {rep.delay['confidence']:.3f}" in page


def test_a_sequence_that_shows_no_delay_is_an_error_naming_why():
    lepton = stack(LEPTON_STACK, 70)  # a still scene: two stretches of it differ by noise only
    with pytest.raises(FidelityError, match="change too little") as err:
        irf.score_sequence(lepton[:30], lepton[40:70], max_delay=4, peak="range", progress=False)
    assert err.value.option == "max_delay"
    x = np.arange(80)
    periodic = np.stack([np.tile(1000 + 100 * np.sin(2 * np.pi * (x - 4 * t) / 16.0), (60, 1)) for t in range(30)])
    with pytest.raises(FidelityError, match="match almost as well at another delay"):
        irf.score_sequence(periodic, periodic, max_delay=5, peak="range", progress=False)
    with pytest.raises(FidelityError, match="too large for sequences of 6 and 6 frames"):
        irf.score_sequence(lepton[:6], lepton[:6], max_delay=3, peak="range", progress=False)
    with pytest.raises(FidelityError, match="pair_by: frames paired by name have no delay"):
        irf.ScoringConfig(max_delay=2, pair_by="name")


def test_delay_and_registration_together_from_files_on_the_cli(tmp_path):
    real, sim = panning(40, 2, view_shift=(1.5, -2.0))
    write_pngs(tmp_path / "real", real, prefix="real_")
    write_pngs(tmp_path / "sim", sim, prefix="render_")
    out = tmp_path / "r.json"
    p = subprocess.run([sys.executable, "-m", "irfidelity.cli", "score", tmp_path / "real", tmp_path / "sim",
                        "--max-delay", "4", "--register", "translation", "--peak", "range", "--json", out,
                        "--csv", tmp_path / "f.csv"], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    d = json.loads(out.read_text())
    assert d["delay"]["frames"] == 2 and d["run"]["pair_by"] == "delay"
    # exit status 0: every paired frame scored; the 4 frames left at the ends are rows, not failures
    assert len(d["frames"]) == 42 and not d["failed"] and d["unpaired"] == [38, 39, 40, 41]
    assert d["frames"][0]["real"] == "real_000.png" and d["frames"][0]["sim"] == "render_002.png"
    dy, dx = d["registration"]["shift"]
    assert abs(dy - 1.5) < 0.1 and abs(dx + 2.0) < 0.1
    assert "delay: +2 frames" in p.stdout and "38 scored, 0 failed, 4 without a partner at the delay" in p.stdout
    rows = list(csv.DictReader(open(tmp_path / "f.csv")))
    assert len(rows) == 42 and {r["reg_dy"] for r in rows[:38]} == {repr(dy)}
    assert [(r["real"], r["sim"], r["error"], r["fidelity"]) for r in rows[38:]] == [
        ("real_038.png", "", "real_038.png: no simulated frame pairs with it at delay +2", ""),
        ("real_039.png", "", "real_039.png: no simulated frame pairs with it at delay +2", ""),
        ("", "render_000.png", "render_000.png: no real frame pairs with it at delay +2", ""),
        ("", "render_001.png", "render_001.png: no real frame pairs with it at delay +2", "")]


def test_thin_frames_find_their_delay_and_too_small_ones_are_refused(tmp_path):
    real, sim = panning(60, 3)
    line_real, line_sim = real[:, 64:65, :], sim[:, 64:65, :]  # a line-scan camera: 1 x 160 frames
    rep = quietly(irf.score_sequence, line_real, line_sim, max_delay=5, peak="range", progress=False)
    assert rep.delay["frames"] == 3 and not rep.failed
    tiny = real[:, 64:65, 10:13]  # 1 x 3: nothing left to compare once offset and gain are out
    with pytest.raises(FidelityError, match=r"the real frames of 1 x 3 pixels are too small to compare") as err:
        irf.score_sequence(tiny, tiny, max_delay=2, progress=False)
    assert err.value.option == "max_delay"
    write_pngs(tmp_path / "real", tiny)
    write_pngs(tmp_path / "sim", tiny)
    p = subprocess.run([sys.executable, "-m", "irfidelity.cli", "score", tmp_path / "real", tmp_path / "sim",
                        "--max-delay", "2", "--no-progress"], capture_output=True, text=True, timeout=300)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and "too small to compare" in p.stderr and "Traceback" not in p.stderr
