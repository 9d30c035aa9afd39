"""Registration does not depend on the frames' units, and refuses what it cannot tell apart
(issue 25, "no silent wrong answer from legal input").

A real frame in counts and the same frame scaled into float32 near 1e-30, 1e30, 1e36 and 1e38
(its largest values), and into float64 near 1e300 and in the subnormal range (1e-308): the
transform found, its confidence and the fidelity scored after it are those of the counts (the
metrics refuse subnormal frames, saying why). A
1-px checkerboard shifted by a column is its own negative, so a shift cannot be told from an
inversion: refused, while a real frame with inverted grey levels still registers.

Data: tests/data/thermal/flirpy_frame_000000_raw16.png (see tests/data/README.md).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.ndimage as ndi

import irfidelity as irf
from irfidelity.errors import RegistrationError

THERMAL = Path(__file__).parent / "data" / "thermal"

#: (dtype, largest value) of the scaled copies.
SCALES = [(np.float32, 1e-30), (np.float32, 1e30), (np.float32, 1e36), (np.float32, 1e38),
          (np.float64, 1e-308), (np.float64, 1e300)]
#: The known transforms, simulated → real: (model, dy, dx, angle in degrees).
CASES = [("translation", 2.37, -1.61, 0.0), ("rigid", 1.3, -0.7, 1.5)]


@pytest.fixture(scope="module")
def flir() -> np.ndarray:
    """A real 640×512 FLIR frame in counts, lightly smoothed (σ = 0.7 px: an optics blur, so
    that a resampled copy is exact up to the spline's error)."""
    return ndi.gaussian_filter(irf.load_frame(THERMAL / "flirpy_frame_000000_raw16.png").astype(np.float64), 0.7)


def true_matrix(shape, dy, dx, angle) -> np.ndarray:
    h, w = shape
    m = cv2.getRotationMatrix2D(((w - 1) / 2, (h - 1) / 2), angle, 1.0)
    m[:, 2] += (dx, dy)
    return m


def seen_through(scene: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``out(p) = scene(M·p)``: the scene as the simulated camera sees it."""
    rc = np.array([[m[1, 1], m[1, 0]], [m[0, 1], m[0, 0]]])
    return ndi.affine_transform(scene, rc, (m[1, 2], m[0, 2]), order=5, mode="reflect")


def corner_error(found: np.ndarray, truth: np.ndarray, shape) -> float:
    h, w = shape
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float).T
    return float(np.linalg.norm((np.asarray(found) - truth) @ corners, axis=0).max())


def scaled(frame: np.ndarray, dtype, largest: float, peak: float) -> np.ndarray:
    """``frame`` with ``peak`` mapped to ``largest``, in ``dtype`` (scaled in two steps so
    that neither overflows nor, in float64, loses the subnormal digits early)."""
    return (frame.astype(np.float64) / peak * largest).astype(dtype)


@pytest.fixture(scope="module")
def pairs(flir):
    """Per case: the real frame, the simulated one, the truth, and the registration of the pair
    in counts (float32 and float64 alike)."""
    out = {}
    for model, dy, dx, angle in CASES:
        m = true_matrix(flir.shape, dy, dx, angle)
        sim = seen_through(flir, m)
        out[model] = (flir, sim, m)
    return out


def test_the_pair_in_counts_registers(pairs):
    for model, (real, sim, m) in pairs.items():
        reg = irf.register(real.astype(np.float32), sim.astype(np.float32), model=model)
        assert corner_error(reg.matrix, m, real.shape) < 0.1, (model, reg)


@pytest.mark.parametrize("dtype,largest", SCALES, ids=[f"{np.dtype(d).name}-{v:g}" for d, v in SCALES])
@pytest.mark.parametrize("model", [c[0] for c in CASES])
def test_any_scale_registers_as_the_counts_do(pairs, dtype, largest, model):
    real, sim, _ = pairs[model]
    peak = float(real.max())
    reference = irf.register(real.astype(dtype), sim.astype(dtype), model=model)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # not even an unsure warning
        reg = irf.register(scaled(real, dtype, largest, peak), scaled(sim, dtype, largest, peak), model=model)
    assert math.isfinite(reg.confidence) and 0.0 <= reg.confidence <= 1.0
    assert corner_error(reg.matrix, reference.matrix, real.shape) < 1e-3, (reg, reference)
    assert abs(reg.angle - reference.angle) < 1e-3
    assert abs(reg.confidence - reference.confidence) < 0.01
    assert (reg.method, reg.inverted) == (reference.method, reference.inverted)


def test_the_fidelity_after_registration_does_not_depend_on_the_scale(pairs):
    real, sim, _ = pairs["rigid"]
    peak = float(real.max())
    # PSNR's peak: the real frame's range, the one that scales with the frames
    counts = irf.evaluate(real.astype(np.float32), sim.astype(np.float32), register="rigid", peak="range")
    big = irf.evaluate(scaled(real, np.float32, 1e36, peak), scaled(sim, np.float32, 1e36, peak), register="rigid",
                       peak="range")
    misaligned = irf.evaluate(real.astype(np.float32), sim.astype(np.float32), peak="range")
    assert counts.fidelity > misaligned.fidelity + 0.1  # the registration is what is tested
    assert abs(big.fidelity - counts.fidelity) < 1e-6, (big.fidelity, counts.fidelity)


def test_subnormal_frames_register_and_the_metrics_say_why_they_refuse(pairs):
    """Frames near 1e-308 register as the counts do (above); the metrics after it then refuse
    them for what they are, values whose squares underflow float64, never as NaN/Inf or as an
    ambiguous match."""
    real, sim, _ = pairs["translation"]
    peak = float(real.max())
    tiny_real, tiny_sim = scaled(real, np.float64, 1e-308, peak), scaled(sim, np.float64, 1e-308, peak)
    with pytest.raises(irf.errors.RangeError) as err:
        irf.evaluate(tiny_real, tiny_sim, register="translation")
    message = str(err.value)
    assert "underflow" in message and "rescale" in message, message
    assert "NaN" not in message and "Inf" not in message, message


def test_confidence_is_never_nan():
    """Frames from which nothing can be measured are refused with a reason, never returned with
    a NaN confidence: random values spanning float64's whole range, and a frame of alternating
    ±f64::MAX with a structure underneath."""
    rng = np.random.default_rng(3)
    wild = np.exp(rng.uniform(-700, 700, (64, 80))) * rng.choice([-1.0, 1.0], (64, 80))
    yy, xx = np.indices((64, 80))
    extreme = np.where((yy // 8 + xx // 8) % 2 == 0, np.finfo(np.float64).max, -np.finfo(np.float64).max)
    for real, sim in [(wild, np.roll(wild, 3, axis=1)), (extreme, np.roll(extreme, 2, axis=0))]:
        for model in ("translation", "rigid"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    reg = irf.register(real, sim, model=model)
                except RegistrationError:
                    continue
            assert math.isfinite(reg.confidence) and 0.0 <= reg.confidence <= 1.0


# --------------------------------------------------------------------------- polarity
def checkerboard(rows: int, cols: int, shift: int, low: float = 1000.0, high: float = 2000.0) -> np.ndarray:
    yy, xx = np.indices((rows, cols))
    return np.where((yy + xx + shift) % 2 == 0, high, low)


@pytest.mark.parametrize("method", ["auto", "phase", "nmi"])
@pytest.mark.parametrize("model", ["translation", "rigid"])
@pytest.mark.parametrize("shape", [(64, 64), (120, 160)])
def test_a_checkerboard_shifted_a_column_is_refused_as_periodic(shape, model, method):
    real, sim = checkerboard(*shape, 0), checkerboard(*shape, 1)
    with pytest.raises(RegistrationError, match="ambiguous") as err:
        irf.register(real, sim, model=model, method=method)
    assert "periodic" in str(err.value) and "inversion" in str(err.value)


@pytest.mark.parametrize("method", ["auto", "phase", "nmi"])
def test_a_checkerboard_over_a_scene_is_found_or_refused_never_inverted(flir, method):
    """A real scene with a 1-px checkerboard on it, shifted by a column: while the scene
    dominates, its true shift with the original polarity; once the board dominates, refused
    as periodic. Never the neighbouring shift with inverted grey levels."""
    yy, xx = np.indices((128, 161))
    for amplitude, refused in [(5.0, False), (400.0, True)]:
        frame = flir[:128, :161] + np.where((yy + xx) % 2 == 0, amplitude, -amplitude)
        real, sim = frame[:, :-1], frame[:, 1:]
        if refused:
            with pytest.raises(RegistrationError, match="periodic"):
                irf.register(real, sim, method=method)
            continue
        reg = irf.register(real, sim, method=method)
        assert not reg.inverted and abs(reg.shift[0]) < 0.2 and abs(reg.shift[1] - 1.0) < 0.2, reg


@pytest.mark.parametrize("method", ["auto", "nmi", "phase"])
def test_an_inverted_real_frame_still_registers(flir, method):
    m = true_matrix(flir.shape, -3.3, 2.45, 0.0)
    sim = 9000.0 - 0.7 * seen_through(flir, m)
    reg = irf.register(flir, sim, method=method)
    assert reg.inverted
    assert corner_error(reg.matrix, m, flir.shape) < 0.2, reg
    assert reg.confidence > irf.registration.LOW_CONFIDENCE
