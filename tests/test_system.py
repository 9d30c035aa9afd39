"""The pair as a system (irfidelity.system, docs/interpretation.md): the transfer recovers a
known simulator from real scenes, and the verdict without camera curves follows the simulator,
not the scene, on five real cameras' frames.

Data: real frames of five thermal cameras shipped in tests/data (DJI Zenmuse XT-R, FLIR Duo Pro
R, a FLIR radiometric JPEG, a FLIR FFF, a FLIR Lepton; see tests/data/README.md). The simulators
are those frames through known degradations.
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from scipy import ndimage

import irfidelity as irf
from irfidelity import _core
from irfidelity.errors import FidelityError, ShapeError
from irfidelity.system import TransferSpectra, estimate, mtf50_mismatch, transfer_spectra

DATA = pathlib.Path(__file__).resolve().parent / "data"
GRADES = ("excellent", "good", "fair", "poor")

#: The five cameras' frames: name -> path (and page of a multi-page file).
CAMERAS = {"DJI XT-R": ("thermal/readthermal_zenmuse_xtr_raw16.png", None),
           "FLIR Duo Pro R": ("thermal/flirpy_frame_000000_raw16.png", None),
           "FLIR JPEG": ("radiometric/readthermal_flir_example_raw16.png", None),
           "FLIR FFF": ("radiometric/flirpy_frame_000000_le_raw16.png", None),
           "FLIR Lepton": ("thermal/cptv_v2_all100frames_uint16.tif", 30)}


def camera(name: str) -> np.ndarray:
    path, page = CAMERAS[name]
    if page is None:
        return irf.load_frame(DATA / path)
    import tifffile

    return tifffile.imread(DATA / path)[page]


@pytest.fixture(scope="module")
def frames():
    return {name: camera(name) for name in CAMERAS}


def as_counts(values: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(values), 0, 65535).astype(np.uint16)


def blur(frame: np.ndarray, sigma: float) -> np.ndarray:
    return as_counts(ndimage.gaussian_filter(frame.astype(np.float64), sigma) if sigma else frame)


def gain(frame: np.ndarray, g: float) -> np.ndarray:
    f = frame.astype(np.float64)
    return as_counts(f.mean() + g * (f - f.mean()))


# --------------------------------------------------------------------------- the estimate
def test_a_known_simulator_is_recovered_with_the_real_noise_known(frames):
    """Blur 1 px, gain 1.1, an offset and twice the real noise on the DJI frame: the MTF ratio
    within 0.03 of exp(−2π²σ²f²) over 0.05–0.2 cy/px, the gain within 0.5 %, the noise ratio
    within 10 %, the offset within its error."""
    rng = np.random.default_rng(0)
    scene = frames["DJI XT-R"].astype(np.float64)
    sigma = 0.02 * scene.std()
    real, ref = (scene + rng.normal(0, sigma, scene.shape) for _ in range(2))
    sim = 1.1 * ndimage.gaussian_filter(scene, 1.0) + 25.0 + rng.normal(0, 2 * sigma, scene.shape)
    t = irf.transfer(real, sim, real_ref=ref)
    inside = (t.frequency >= 0.05) & (t.frequency <= 0.2)
    truth = np.exp(-2 * np.pi ** 2 * t.frequency ** 2)
    assert np.max(np.abs(t.mtf_ratio[inside] - truth[inside])) < 0.03
    assert t.gain == pytest.approx(1.1, rel=5e-3) and t.noise_ratio == pytest.approx(2.0, rel=0.1)
    assert t.offset == pytest.approx(25.0, abs=5 * t.offset_err + 1)
    assert t.bias == pytest.approx(float(sim.mean() - real.mean()))
    assert t.band is not None and t.band[1] >= 0.2 and t.noise_source == "real_ref"
    assert t.mtf50_mismatch == pytest.approx(mtf50_mismatch(float(np.exp(-2 * np.pi ** 2 * 0.25 ** 2))), abs=0.02)
    d = t.to_dict()
    assert d["gain"] == t.gain and len(d["mtf_ratio"]) == len(t.frequency)


def test_the_real_noise_from_its_3d_noise_equals_a_second_frame(frames):
    rng = np.random.default_rng(1)
    scene = frames["FLIR FFF"].astype(np.float64)
    real, ref = (scene + rng.normal(0, 3.0, scene.shape) for _ in range(2))
    sim = scene + rng.normal(0, 6.0, scene.shape)
    by_ref = irf.transfer(real, sim, real_ref=ref)
    by_noise = irf.transfer(real, sim, real_noise={"tvh": 3.0})
    assert by_noise.noise_source == "real_noise" and by_noise.real_noise == pytest.approx(3.0, rel=1e-9)
    assert by_ref.noise_ratio == pytest.approx(2.0, rel=0.1) and by_noise.noise_ratio == pytest.approx(2.0, rel=0.1)
    unknown = irf.transfer(real, sim)
    assert unknown.noise_ratio is None and unknown.noise_source is None and unknown.notes


def test_a_displaced_simulation_reads_as_displaced_not_blurred(frames):
    """A translation turns only the cross-spectrum's phase: measured, and taken out tile by tile."""
    scene = frames["DJI XT-R"].astype(np.float64)
    spectrum = np.fft.fft2(scene)
    fy, fx = np.fft.fftfreq(scene.shape[0])[:, None], np.fft.fftfreq(scene.shape[1])[None, :]
    moved = np.real(np.fft.ifft2(spectrum * np.exp(-2j * np.pi * (fy * 1.3 + fx * -2.6))))
    t = irf.transfer(scene, moved)
    assert t.shift == pytest.approx((-1.3, 2.6), abs=0.05)  # real ≈ ndimage.shift(sim, shift)
    assert t.mtf50_mismatch < 0.03 and t.gain == pytest.approx(1.0, abs=0.01)


def test_the_kernel_equals_numpy_on_one_tile():
    rng = np.random.default_rng(2)
    real, sim = rng.normal(0, 1, (2, 32, 32))
    out = _core.cross_spectra(real, sim, tile=32, step=32, groups=1)
    w = np.sin(np.pi * (np.arange(32) + 1) / 33) ** 2
    window = np.outer(w, w)
    a = np.fft.rfft2((real - real.mean()) * window)
    b = np.fft.rfft2((sim - sim.mean()) * window)
    assert out["tiles"] == [1] and out["window_energy"] == pytest.approx((window ** 2).sum())
    np.testing.assert_allclose(out["real"][0], np.abs(a) ** 2, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(out["sim"][0], np.abs(b) ** 2, rtol=1e-4, atol=1e-6)
    # the cross-spectrum is turned by the tile's own displacement: its size is kept
    np.testing.assert_allclose(np.hypot(out["cross_re"][0], out["cross_im"][0]), np.abs(np.conj(a) * b),
                               rtol=1e-3, atol=1e-4)


def test_spectra_of_frames_merge_and_bad_input_is_refused(frames):
    real = frames["FLIR Lepton"]
    one = transfer_spectra(real, blur(real, 1.0))
    two = transfer_spectra(real, blur(real, 1.0))
    merged = one.merge(two)
    assert isinstance(merged, TransferSpectra) and merged.tiles.sum() == 2 * one.tiles.sum()
    assert estimate(merged).mtf50_mismatch == pytest.approx(estimate(one).mtf50_mismatch, abs=1e-9)
    with pytest.raises(ShapeError):
        one.merge(transfer_spectra(real[:100], real[:100]))
    with pytest.raises(ShapeError, match="one shape"):
        irf.transfer(real, real[:10])
    with pytest.raises(FidelityError, match="no 64 x 64 tile"):
        irf.transfer(real[:40, :40], real[:40, :40], tile=64)
    with pytest.raises(FidelityError, match="tile"):
        _core.cross_spectra(real, real, tile=7, step=3, groups=2)
    with pytest.raises(FidelityError, match="real_noise"):
        irf.transfer(real, real, real_noise={"t": 1.0})


def test_a_flat_pair_has_no_gain_and_says_so():
    flat = np.full((128, 128), 1000, dtype=np.uint16)
    t = irf.transfer(flat, flat)
    assert t.gain is None and t.mtf50_mismatch is None and "contrast" in t.unread
    rep = irf.evaluate(flat, flat, bits=16)
    assert "mtf" not in rep.components and "sitf" not in rep.components
    assert "not assessed: mtf" in rep.verdict["reason"] and "contrast" in rep.skipped["sitf"]


# --------------------------------------------------------------------------- the verdict follows the simulator
@pytest.mark.parametrize("name", list(CAMERAS))
def test_blur_and_gain_grade_alike_on_every_camera(frames, name):
    """Default settings, no curves: blur σ 1.5 px is not excellent and σ 3 px fair or worse; a
    15 % gain error fair or worse, a 2 % one good or better; the perfect copy excellent."""
    real = frames[name]
    grade = {label: irf.evaluate(real, sim, bits=16, peak="range").grade for label, sim in (
        ("same", real.copy()), ("blur 1.5", blur(real, 1.5)), ("blur 3", blur(real, 3.0)),
        ("gain 1.15", gain(real, 1.15)), ("gain 1.02", gain(real, 1.02)))}
    assert grade["same"] == "excellent"
    assert grade["blur 1.5"] != "excellent" and GRADES.index(grade["blur 3"]) >= GRADES.index("fair")
    assert GRADES.index(grade["gain 1.15"]) >= GRADES.index("fair")
    assert GRADES.index(grade["gain 1.02"]) <= GRADES.index("good"), grade


def test_the_same_fault_grades_within_one_grade_across_cameras(frames):
    for fault in (lambda f: blur(f, 1.0), lambda f: gain(f, 1.1)):
        grades = [GRADES.index(irf.evaluate(f, fault(f), bits=16, peak="range").grade) for f in frames.values()]
        assert max(grades) - min(grades) <= 1, grades


#: Ladders whose grade and fidelity never improve as the fault grows.
LADDERS = {
    "blur": ((0, 0.5, 1, 1.5, 2, 3), lambda f, s: ndimage.gaussian_filter(f, s) if s else f),
    "gain": ((1, 1.05, 1.1, 1.15, 1.3), lambda f, s: f.mean() + s * (f - f.mean())),
    "noise": ((0, 0.005, 0.01, 0.02, 0.04, 0.08),
              lambda f, s: f + s * np.ptp(f) * np.random.default_rng(3).standard_normal(f.shape)),
    "column pattern": ((0, 0.005, 0.01, 0.02, 0.04, 0.08),
                       lambda f, s: f + s * np.ptp(f) * np.random.default_rng(4).standard_normal(f.shape[1])),
    "whole-pixel shift": ((0, 1, 2, 4), lambda f, s: np.roll(f, (s, s), axis=(0, 1))),
}

#: Offset ladders in odd and even counts: NMI's bins must not read the offset's phase, which
#: shared edges do (the default binning locks the edges by the offset, docs/design.md).
OFFSETS = {
    "offset": ((0, 1, 2, 3, 5, 10, 15, 20, 50), lambda f, s: f + s),
    "offset of a noisy copy": ((0, 1, 2, 5, 10, 20),
                               lambda f, s: f + s + 0.01 * np.ptp(f) * np.random.default_rng(6).standard_normal(f.shape)),
}


@pytest.mark.parametrize("ladder", list(LADDERS))
@pytest.mark.parametrize("name", ["DJI XT-R", "FLIR Duo Pro R", "FLIR FFF", "FLIR Lepton"])
def test_grade_and_fidelity_never_improve_down_a_ladder(frames, name, ladder):
    steps, degrade = LADDERS[ladder]
    real = frames[name]
    reps = [irf.evaluate(real, as_counts(degrade(real.astype(np.float64), s)), bits=16, peak="range")
            for s in steps]
    grades = [GRADES.index(r.grade) for r in reps]
    fidelity = [r.fidelity for r in reps]
    assert all(a <= b for a, b in zip(grades, grades[1:])), [r.grade for r in reps]
    assert all(b <= a + 1e-9 for a, b in zip(fidelity, fidelity[1:])), fidelity


@pytest.mark.parametrize("ladder", list(OFFSETS))
@pytest.mark.parametrize("name", ["DJI XT-R", "FLIR Duo Pro R", "FLIR FFF", "FLIR Lepton"])
def test_grade_and_fidelity_fall_strictly_down_an_offset_ladder(frames, name, ladder):
    steps, degrade = OFFSETS[ladder]
    real = frames[name]
    reps = [irf.evaluate(real, as_counts(degrade(real.astype(np.float64), s)), bits=16, peak="range")
            for s in steps]
    grades = [GRADES.index(r.grade) for r in reps]
    fidelity = [r.fidelity for r in reps]
    assert all(a <= b for a, b in zip(grades, grades[1:])), [r.grade for r in reps]
    assert all(b < a for a, b in zip(fidelity, fidelity[1:])), fidelity
    assert len({r.components["nmi"] for r in reps}) == 1  # the offset's phase is not read


# --------------------------------------------------------------------------- defects, sources, sequences
def test_a_dead_cluster_is_named_and_left_out(frames):
    real = frames["FLIR Duo Pro R"]
    sim = real.copy()
    sim[250:253, 300:303] = 0
    rep = irf.evaluate(real, sim, bits=16, peak="range")
    found = rep.verdict["defects"]
    assert found["pixels"] == 9 and found["clusters"][0]["frame"] == "simulated"
    assert found["clusters"][0]["kind"] == "dark" and found["clusters"][0]["rows"] == [250, 252]
    assert "9 dark pixels in the simulated frame at rows 250–252" in rep.verdict["reason"]
    assert rep.grade == "excellent" and rep.metrics["n"] == real.size - 9  # the rest is the real frame


def test_the_transfer_fills_defects_instead_of_losing_their_tiles(frames):
    from irfidelity.defects import find_defects

    real = frames["FLIR Duo Pro R"]
    sim = real.copy()
    sim[250:253, 300:303] = 0
    found = find_defects(real, sim)
    same, filled = found.repaired(real, sim)
    assert same is real and filled is not sim and filled.dtype == sim.dtype
    box = real[248:255, 298:305].astype(np.float64)
    assert (filled[250:253, 300:303] == np.rint(np.median(box[~found.mask[248:255, 298:305]]))).all()
    assert (filled[~found.mask] == sim[~found.mask]).all()
    rep = irf.evaluate(real, sim, bits=16, peak="range")
    assert rep.transfer["skipped"] == 0 and rep.transfer["gain"] == pytest.approx(1.0, abs=1e-3)


def _dead(frame: np.ndarray, fraction: float) -> np.ndarray:
    out = frame.copy()
    order = np.random.default_rng(5).permutation(frame.size)  # nested sets: each rung adds pixels
    out.flat[order[:int(round(fraction * frame.size))]] = 0
    return out


def test_dead_pixels_of_a_moving_scene_are_named_and_more_never_score_better():
    """Two Lepton frames of a scene that moved (a quiet camera: 72 % of the differences are 0, the
    rest heavy-tailed) with the later one's pixels dying: a few are named and left out, the
    transfer fills them and keeps its tiles, and when there are too many to be defects the
    simulated frame's noise hides the MTF ratio: a whole mismatch, not a skipped component whose
    weight would lift the others."""
    import tifffile

    recording = tifffile.imread(DATA / "thermal/cptv_v2_all100frames_uint16.tif")
    real, later = recording[30], recording[31]
    reps = [irf.evaluate(real, _dead(later, f), bits=14, peak="range", real_ref=later)
            for f in (0, 1e-4, 1e-3, 5e-3, 0.02)]
    assert [r.verdict["defects"] and r.verdict["defects"]["pixels"] for r in reps[:4]] == [None, 2, 19, 96]
    assert all(set(r.components) == {"mtf", "sitf", "psnr", "nmi", "ssim"} for r in reps)
    assert all(r.grade == "excellent" for r in reps[:4]) and reps[-1].grade == "poor"
    fidelity = [r.fidelity for r in reps]
    # leaving out more pixels moves the rest's score by < 1e-4; the fault itself never scores better
    assert all(b <= a + 1e-4 for a, b in zip(fidelity, fidelity[1:])), fidelity
    last = reps[-1]
    assert last.components["mtf"] == 0.0 and last.transfer["unread_cause"] == "simulator"
    assert "noise hides" in last.verdict["components"]["mtf"]["text"]
    assert "the simulated frame's noise hides it" in last.summary_text()


def test_a_noisy_simulator_is_forgiven_only_a_perfect_simulators_doubt(frames):
    """The grade takes the estimate less 2 standard errors, but no more than the real camera
    against itself shows (a perfect simulator's doubt): the simulator's own noise widens the
    error, and forgiving that would grade a noisier simulator better."""
    from dataclasses import replace

    from irfidelity.system.scene import graded_mismatch

    real = frames["FLIR FFF"]
    t = irf.transfer(real, gain(real, 1.1))
    noisy = replace(t, gain=1.1, gain_err=0.05, mtf50_mismatch=0.2, mtf50_mismatch_err=0.1)
    ceiling = replace(t, gain=1.0, gain_err=0.001, mtf50_mismatch=0.01, mtf50_mismatch_err=0.002)
    assert graded_mismatch("sitf", noisy, None) == pytest.approx(0.0, abs=1e-12)  # 0.0909 less 2 × 0.0455
    assert graded_mismatch("sitf", noisy, ceiling) == pytest.approx(1 - 1 / 1.1 - 2 * 0.001)
    assert graded_mismatch("mtf", noisy, None) == pytest.approx(0.0)
    assert graded_mismatch("mtf", noisy, ceiling) == pytest.approx(0.2 - 2 * 0.002 - 0.01)
    hidden = replace(t, mtf50_mismatch=None, mtf50_mismatch_err=None, unread="hidden", unread_cause="simulator")
    assert graded_mismatch("mtf", hidden, None) == 1.0
    assert graded_mismatch("mtf", replace(hidden, unread_cause="scene"), None) is None


def test_a_blurred_small_target_is_not_a_defect(frames):
    real = frames["FLIR Lepton"]
    assert irf.evaluate(real, blur(real, 6.0), bits=16, peak="range").verdict["defects"] is None


def test_sources_checks_and_what_was_not_assessed(frames):
    real = frames["DJI XT-R"]
    rep = irf.evaluate(real, blur(real, 1.0), bits=16, peak="range")
    assert {rep.verdict["components"][k]["source"] for k in ("mtf", "sitf")} == {"scene"}
    assert rep.verdict["components"]["psnr"]["source"] is None
    assert "not assessed: noise" in rep.verdict["reason"] and rep.verdict["unassessed"]["noise"]
    rng = np.random.default_rng(5)
    noisy = as_counts(real + rng.normal(0, 20, real.shape))
    checked = irf.evaluate(real, noisy, bits=16, peak="range", real_ref=as_counts(real + rng.normal(0, 5, real.shape)))
    assert "checked but not weighted: noise" in checked.verdict["reason"]
    assert checked.verdict["checks"]["noise"]["weighted"] is False
    weighted = irf.evaluate(real, noisy, bits=16, peak="range", weights="psnr=0.5,noise=0.5", real_noise=5.0)
    assert weighted.metrics["noise_source"] == "scene" and weighted.component_grades["noise"] == "poor"
    assert irf.FidelityReport.from_dict(rep.to_dict()).transfer == rep.to_dict()["transfer"]


def test_curves_and_the_scene_side_by_side(frames):
    real = frames["FLIR FFF"]
    x = np.linspace(0, 0.5, 51)
    rep = irf.evaluate(real, blur(real, 1.0), bits=16, peak="range", real_mtf=(x, np.exp(-4 * x ** 2)),
                       sim_mtf=(x, np.exp(-4 * x ** 2)))
    assert rep.metrics["mtf_source"] == "curves" and rep.components["mtf"] > 0.999  # the curves say equal
    assert rep.metrics["scene_mtf50_mismatch"] > 0.3  # ... the scene says blurred
    assert "scene (cross-check of the curves)" in rep.summary_text()


def test_a_sequence_pools_the_transfer_and_grades_against_the_camera_itself():
    import tifffile

    recording = tifffile.imread(DATA / "thermal/cptv_v2_all100frames_uint16.tif")
    same = irf.score_sequence(recording[30:42], recording[31:43], bits=14, progress=False, pair_by="order")
    assert same.grade == "excellent" and same.transfer["noise_source"] == "sequence"
    blurred = np.stack([blur(f, 1.5) for f in recording[31:43]])
    worse = irf.score_sequence(recording[30:42], blurred, bits=14, progress=False, pair_by="order")
    assert worse.grade == "poor" and worse.verdict["decided_by"] == "mtf"
    assert worse.frames[0]["components"]["mtf"] == worse.components["mtf"]  # a camera property


def test_a_panning_camera_s_frame_differences_are_taken_with_the_motion_out():
    """A scene moving between frames (a panning camera) makes consecutive real frames differ by
    the scene as well as by noise: taken whole as the camera's noise, it was subtracted from the
    real spectrum and a perfect simulator graded poor on the MTF. With the displacement taken
    out, the perfect simulator grades excellent, a blurred one still poor, and the noise is read
    near its true ratio (1)."""
    import tifffile

    still = tifffile.imread(DATA / "thermal/cptv_v2_all100frames_uint16.tif")[40].astype(np.float64)
    rng = np.random.default_rng(14)
    for step in (1, 3):  # pixels a frame
        scene = np.stack([np.roll(still, step * k, axis=1) for k in range(10)])
        real, sim = (np.clip(np.rint(scene + rng.normal(0, 3, scene.shape)), 0, 16383).astype(np.uint16)
                     for _ in range(2))
        report = irf.score_sequence(real, sim, bits=14, progress=False, pair_by="order")
        graded = report.verdict["components"]
        assert graded["mtf"]["grade"] == "excellent" and report.transfer["noise_source"] == "sequence", graded["mtf"]
        assert 0.95 < report.metrics["scene_noise_ratio"] < 1.05, report.metrics["scene_noise_ratio"]
        blurred = np.stack([blur(f, 1.5) for f in sim])
        worse = irf.score_sequence(real, blurred, bits=14, progress=False, pair_by="order")
        assert worse.verdict["components"]["mtf"]["grade"] == "poor"


@pytest.mark.parametrize("scale", [1e-30, 1e33])
def test_float_frames_of_any_scale_give_the_same_transfer(frames, scale):
    """Float32 tiles of frames near 1e37 would overflow and near 1e-30 flush to zero: the kernel
    scales them by a power of two first and returns the sums in frame units."""
    real = frames["FLIR FFF"].astype(np.float64)
    sim = 1.1 * ndimage.gaussian_filter(real, 1.0) + 5
    counts = irf.transfer(real, sim)
    scaled = irf.transfer((real * scale).astype(np.float32), (sim * scale).astype(np.float32))
    assert scaled.gain == pytest.approx(counts.gain, rel=1e-5)
    assert scaled.mtf50_mismatch == pytest.approx(counts.mtf50_mismatch, abs=1e-4)
    assert scaled.offset == pytest.approx(counts.offset * scale, rel=1e-3)
