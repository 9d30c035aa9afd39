"""Registration: accuracy on real thermal frames seen through known transforms (against the
targets of docs/registration.md and scikit-image), the conventions against scikit-image,
SciPy and OpenCV, inverted polarity, refusals, NaN masks, apply() and dtypes."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.ndimage as ndi
from skimage.registration import phase_cross_correlation

import irfidelity as irf
from irfidelity.errors import FidelityError, RegistrationError, ShapeError
from irfidelity.registration import RegistrationWarning

THERMAL = Path(__file__).parent / "data" / "thermal"


@pytest.fixture(scope="module")
def lepton() -> np.ndarray:
    """A real 160×120 Lepton frame, lightly smoothed (σ = 0.7 px: an optics blur, so that a
    resampled copy is exact up to the 5th-order spline's error)."""
    return ndi.gaussian_filter(irf.load_frame(THERMAL / "cptv_v2_frame000.png").astype(np.float64), 0.7)


@pytest.fixture(scope="module")
def xtr() -> np.ndarray:
    """A real 640×512 DJI Zenmuse XT-R frame, lightly smoothed."""
    return ndi.gaussian_filter(irf.load_frame(THERMAL / "readthermal_zenmuse_xtr_raw16.png").astype(np.float64), 0.7)


def true_matrix(shape, dy, dx, angle=0.0, scale=1.0) -> np.ndarray:
    """Simulated → real map: rotation and scale about the centre (OpenCV sense), then a shift."""
    h, w = shape
    m = cv2.getRotationMatrix2D(((w - 1) / 2, (h - 1) / 2), angle, scale)
    m[:, 2] += (dx, dy)
    return m


def seen_through(scene: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``out(p) = scene(M·p)``: the scene as the simulated camera sees it."""
    rc = np.array([[m[1, 1], m[1, 0]], [m[0, 1], m[0, 0]]])
    return ndi.affine_transform(scene, rc, (m[1, 2], m[0, 2]), order=5, mode="reflect")


def simulated_pair(scene, m, seed, *, blur=0.9, gain=1.3, offset=150.0, noise=0.1):
    """The real frame (scene + its own noise) and a simulated one that differs as a simulator
    would: another blur, gain and offset, and its own noise (``noise`` × the scene's std)."""
    rng = np.random.default_rng(seed)
    std = scene.std()
    sim = gain * ndi.gaussian_filter(seen_through(scene, m), blur) + offset
    sim = sim + rng.normal(0, noise * std, scene.shape)
    real = scene + rng.normal(0, 0.05 * std, scene.shape)
    return real.astype(np.float32), sim.astype(np.float32)


def corner_error(found: np.ndarray, truth: np.ndarray, shape) -> float:
    """Worst displacement (px) of a frame corner between two maps."""
    h, w = shape
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float).T
    return float(np.linalg.norm((np.asarray(found) - truth) @ corners, axis=0).max())


# --------------------------------------------------------------------------- accuracy
TRANSLATIONS = [(2.37, -5.61), (-6.82, 3.15), (0.5, 0.5)]


def test_translation_at_640x512_is_within_a_tenth_of_a_pixel_and_beats_scikit_image(xtr):
    ours, theirs = [], []
    for seed, (dy, dx) in enumerate(TRANSLATIONS):
        m = true_matrix(xtr.shape, dy, dx)
        real, sim = simulated_pair(xtr, m, seed)
        for method in ("phase", "auto"):
            reg = irf.register(real, sim, model="translation", method=method)
            ours.append(corner_error(reg.matrix, m, real.shape))
            assert reg.confidence > irf.registration.LOW_CONFIDENCE and 0.9 < reg.overlap <= 1.0
        (sy, sx), _, _ = phase_cross_correlation(real, sim, upsample_factor=100)
        theirs.append(corner_error(true_matrix(real.shape, sy, sx), m, real.shape))
    assert max(ours) <= 0.1, ours
    assert max(ours) <= max(theirs), (ours, theirs)


@pytest.mark.parametrize("model", ["translation", "rigid", "similarity"])
def test_a_black_border_the_simulator_rendered_does_not_pull_the_refinement(xtr, model):
    """A simulated view resampled without edge handling has a zero border where the scene
    ran out; no transform matches it, and least squares dragged the refined transform 0.7 px
    towards aligning it. The refinement weighs such pixels down (Huber's function)."""
    m = true_matrix(xtr.shape, 1.3, -0.7)
    rng = np.random.default_rng(4)
    sim = ndi.shift(xtr, (-1.3, 0.7), order=3, mode="constant", cval=0.0) + rng.normal(0, 5, xtr.shape)
    assert (sim[-1] < 100).all() and (sim[:, 0] < 100).all()  # the black border
    real = xtr + rng.normal(0, 5, xtr.shape)
    reg = irf.register(real, sim, model=model, method="auto")
    # without the weights: 0.75 px for every model
    assert corner_error(reg.matrix, m, real.shape) <= (0.15 if model == "similarity" else 0.1), reg


@pytest.mark.parametrize("model, angle, scale", [("rigid", 2.2, 1.0), ("rigid", -2.9, 1.0),
                                                 ("similarity", -1.4, 1.018), ("similarity", 0.8, 0.983)])
def test_rotation_and_scale_at_640x512_within_0_15_px(xtr, model, angle, scale):
    m = true_matrix(xtr.shape, -3.4, 5.2, angle, scale)
    real, sim = simulated_pair(xtr, m, seed=7)
    reg = irf.register(real, sim, model=model, method="phase")
    assert corner_error(reg.matrix, m, real.shape) <= 0.15, reg
    assert reg.angle == pytest.approx(angle, abs=0.02) and reg.scale == pytest.approx(scale, abs=2e-4)


@pytest.mark.parametrize("model, angle, scale", [("translation", 0.0, 1.0), ("rigid", 2.5, 1.0),
                                                 ("similarity", -1.5, 1.015)])
def test_lepton_size_frames_within_0_2_px(lepton, model, angle, scale):
    errors = []
    for seed, (dy, dx) in enumerate([(1.63, -2.41), (-3.2, 0.77)]):
        m = true_matrix(lepton.shape, dy, dx, angle, scale)
        real, sim = simulated_pair(lepton, m, seed)
        for method in ("phase", "auto"):
            errors.append(corner_error(irf.register(real, sim, model=model, method=method).matrix, m, real.shape))
    assert max(errors) <= 0.2, errors


# --------------------------------------------------------------------------- conventions
def test_shift_sign_follows_scikit_image_and_scipy(lepton):
    sim = ndi.shift(lepton, (-2.25, 3.5), order=3, mode="nearest")
    reg = irf.register(lepton, sim, method="auto")  # refined: the shifted-back frame is compared pixel by pixel
    (sy, sx), _, _ = phase_cross_correlation(lepton, sim, upsample_factor=100)
    assert reg.shift == pytest.approx((sy, sx), abs=0.1)
    assert reg.shift == pytest.approx((2.25, -3.5), abs=0.05)
    back = ndi.shift(sim, reg.shift, order=3)
    inner = np.s_[8:-8, 8:-8]
    assert np.abs(back[inner] - lepton[inner]).max() < 0.02 * np.ptp(lepton)


def test_matrix_and_angle_follow_opencv(lepton):
    m = true_matrix(lepton.shape, 1.5, -2.0, angle=3.0)
    real, sim = simulated_pair(lepton, m, seed=3, blur=0.01, gain=1.0, offset=0.0, noise=0.0)
    reg = irf.register(real, sim, model="rigid")
    assert reg.angle == pytest.approx(3.0, abs=0.05) and reg.scale == pytest.approx(1.0, abs=1e-3)
    assert np.allclose(reg.matrix, m, atol=0.05)
    # OpenCV: warpAffine(sim, M) ≈ real
    warped = cv2.warpAffine(sim, reg.matrix, sim.shape[::-1], flags=cv2.INTER_CUBIC)
    inner = np.s_[12:-12, 12:-12]
    assert np.abs(warped[inner] - real[inner]).max() < 0.03 * np.ptp(real)
    # and apply() agrees with it (bilinear: the same kernel as INTER_LINEAR)
    aligned, valid = reg.apply(sim, order=1)
    warped = cv2.warpAffine(sim, reg.matrix, sim.shape[::-1], flags=cv2.INTER_LINEAR)
    assert valid[inner].all()
    assert np.abs(aligned[inner] - warped[inner]).max() < 0.01 * np.ptp(real)


# --------------------------------------------------------------------------- other grey levels
@pytest.mark.parametrize("method", ["nmi", "auto"])
def test_inverted_non_linear_grey_levels(lepton, method):
    m = true_matrix(lepton.shape, -3.3, 2.45)
    seen = seen_through(lepton, m)
    unit = (seen - seen.min()) / np.ptp(seen)
    sim = 4000.0 - 3000.0 * unit**1.8  # an emissivity/polarity the real camera does not share
    reg = irf.register(lepton, sim, model="translation", method=method)
    assert reg.inverted
    assert corner_error(reg.matrix, m, lepton.shape) <= 0.2, reg


# --------------------------------------------------------------------------- refusals
def test_flat_frame_is_refused_with_the_reason(lepton):
    with pytest.raises(RegistrationError, match="simulated frame is flat"):
        irf.register(lepton, np.full_like(lepton, 2700.0))
    assert issubclass(RegistrationError, FidelityError)


def test_all_nan_frame_is_refused(lepton):
    with pytest.raises(RegistrationError, match="valid pixels"):
        irf.register(np.full_like(lepton, np.nan), lepton)


def test_shift_beyond_max_shift_is_refused_and_allowed_when_raised(lepton):
    sim = ndi.shift(lepton, (0.0, -9.0), order=1, mode="nearest")
    with pytest.raises(RegistrationError, match="max_shift=4"):
        irf.register(lepton, sim, max_shift=4)
    assert irf.register(lepton, sim, max_shift=12).shift[1] == pytest.approx(9.0, abs=0.1)


def test_frames_of_different_scenes_are_refused(lepton, xtr):
    other = ndi.zoom(xtr[:240, :320], 0.5, order=1)
    with pytest.raises(RegistrationError, match="ambiguous|no overlap"):
        irf.register(lepton, other, method="phase")


def test_periodic_four_bar_target_is_ambiguous_not_an_identity():
    rows, cols = 96, 128
    x = np.arange(cols)
    bars = lambda shift: np.tile(1000 + 200 * (0.5 - np.abs(((x - shift) / 8.0) % 1.0 - 0.5)), (rows, 1))  # noqa: E731
    real, sim = bars(0.0), bars(-3.0)
    for method in ("phase", "auto"):
        with pytest.raises(RegistrationError, match="ambiguous"):
            irf.register(real, sim, method=method)


def test_low_confidence_warns(lepton):
    # noise five times the scene's contrast: the peak is still right, but barely distinct
    noise = np.random.default_rng(3).normal(0, lepton.std(), lepton.shape)
    sim = ndi.shift(lepton, (1.0, 2.0), order=1, mode="nearest") + 5.0 * noise
    with pytest.warns(RegistrationWarning, match="unsure registration"):
        reg = irf.register(lepton, sim, method="phase")
    assert irf.registration.LOW_CONFIDENCE > reg.confidence >= 0.1
    assert reg.shift == pytest.approx((-1.0, -2.0), abs=0.5)


def test_bad_arguments(lepton):
    with pytest.raises(ShapeError):
        irf.register(lepton, lepton[:100])
    with pytest.raises(FidelityError, match="model"):
        irf.register(lepton, lepton, model="affine")
    with pytest.raises(FidelityError, match="method"):
        irf.register(lepton, lepton, method="ecc")
    with pytest.raises(FidelityError, match="max_shift"):
        irf.register(lepton, lepton, max_shift=-1)


# --------------------------------------------------------------------------- NaN and masks
def test_nan_and_masked_pixels_are_excluded(lepton):
    m = true_matrix(lepton.shape, 1.5, -2.25)
    real, sim = simulated_pair(lepton, m, seed=11)
    sim[40:60, 70:95] = np.nan                 # a dead area of the simulated frame
    real[:, :6] = 65535.0                      # a burned-in overlay in the real one, masked
    mask = np.ones(lepton.shape, bool)
    mask[:, :6] = False
    reg = irf.register(real, sim, mask=mask)
    assert corner_error(reg.matrix, m, lepton.shape) <= 0.2
    assert np.all(np.isfinite(reg.matrix))


def test_apply_returns_the_mask_of_computable_pixels(lepton):
    reg = irf.registration.Registration.from_dict({"model": "translation", "method": "phase",
                                                   "matrix": [[1, 0, 2.5], [0, 1, -1.25]], "confidence": 1.0,
                                                   "overlap": 0.9, "shape": list(lepton.shape)})
    sim = lepton.copy()
    sim[50, 80] = np.nan
    for order in (1, 3):
        out, valid = reg.apply(sim, order=order)
        assert out.dtype == np.float64 and valid.dtype == bool and out.shape == sim.shape
        assert np.all(np.isnan(out[~valid])) and np.all(np.isfinite(out[valid]))
        assert not valid[:, :2].any() and not valid[-1:, :].any()     # uncovered border
        assert not valid[48, 82] and valid[70, 100]                    # the NaN's taps
    # bilinear is scipy's order 1; Keys' bicubic (not scipy's B-spline) reproduces quadratics
    out, valid = reg.apply(lepton, order=1)
    ref = ndi.shift(lepton, (-1.25, 2.5), order=1)
    assert np.abs(out[valid] - ref[valid]).max() < 1e-9 * np.abs(lepton).max()
    y, x = np.indices(lepton.shape, dtype=float)
    surface = 0.3 * x**2 - 0.2 * x * y + 0.5 * y**2 + 3 * x
    out, valid = reg.apply(surface, order=3)
    exact = 0.3 * (x - 2.5) ** 2 - 0.2 * (x - 2.5) * (y + 1.25) + 0.5 * (y + 1.25) ** 2 + 3 * (x - 2.5)
    assert np.abs(out[valid] - exact[valid]).max() < 1e-9 * np.abs(surface).max()


def test_apply_snaps_near_whole_pixel_translations(lepton):
    reg = irf.registration.Registration.from_dict({"model": "translation", "method": "phase",
                                                   "matrix": [[1, 0, 3.008], [0, 1, -1.0]], "confidence": 1.0,
                                                   "overlap": 0.9, "shape": list(lepton.shape)})
    out, valid = reg.apply(lepton)
    assert np.array_equal(out[valid], np.roll(lepton, (-1, 3), axis=(0, 1))[valid])
    assert valid.sum() == (lepton.shape[0] - 1) * (lepton.shape[1] - 3)
    assert irf.registration.INTEGER_SNAP < 0.02  # docs/registration.md: snapping more biases PSNR
    nudged = irf.registration.Registration.from_dict({**reg.to_dict(), "matrix": [[1, 0, 3.03], [0, 1, -1.0]]})
    out, valid = nudged.apply(lepton)
    assert not np.array_equal(out[valid], np.roll(lepton, (-1, 3), axis=(0, 1))[valid])


def test_registration_round_trips_through_a_dict(lepton):
    reg = irf.register(lepton, ndi.shift(lepton, (1.2, -0.7), order=3, mode="nearest"))
    again = irf.registration.Registration.from_dict(reg.to_dict())
    assert np.array_equal(again.matrix, reg.matrix) and again.shift == reg.shift and again.method == reg.method


# --------------------------------------------------------------------------- dtypes, threads
def test_every_dtype_gives_the_same_shift(lepton):
    sim = ndi.shift(lepton, (-1.75, 2.4), order=3, mode="nearest")
    unit = lambda a: (a - lepton.min()) / np.ptp(lepton)  # noqa: E731
    pairs = {
        "uint8": ((unit(lepton) * 250).astype(np.uint8), (unit(sim) * 250).astype(np.uint8)),
        "uint16": (lepton.round().astype(np.uint16), sim.round().astype(np.uint16)),
        "float32": (lepton.astype(np.float32), sim.astype(np.float32)),
        "float16": (unit(lepton).astype(np.float16), unit(sim).astype(np.float16)),
    }
    for name, (r, s) in pairs.items():
        reg = irf.register(r, s)
        assert reg.shift == pytest.approx((1.75, -2.4), abs=0.1), name
        out, valid = reg.apply(s)
        assert out.dtype == np.float64 and valid.mean() > 0.9, name


def test_registration_releases_the_gil(xtr):
    real, sim = simulated_pair(xtr, true_matrix(xtr.shape, 2.0, 3.0, 2.0), seed=1)
    done = threading.Event()
    ticks = 0

    def work():
        for _ in range(3):
            irf.register(real, sim, model="rigid", method="phase")
        done.set()

    worker = threading.Thread(target=work)
    start = time.perf_counter()
    worker.start()
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    worker.join()
    # the main thread kept running during the Rust calls: ~1 tick per ms if free, 0 if blocked
    assert ticks > 0.2 * 1e3 * (time.perf_counter() - start), ticks
