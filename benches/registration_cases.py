"""Registration cases and methods shared by ``bench_register.py`` and ``work_precision.py``:
real thermal frames from ``tests/data/thermal`` seen through known transforms and made to
differ as a simulator would, irfidelity and its peers (scikit-image, OpenCV) on them, and the
worst frame-corner displacement of each result. Importing this sets no thread counts: the
caller does that before numpy and OpenCV start.
"""

from __future__ import annotations

import itertools
import pathlib
import time
import warnings

import cv2
import numpy as np
import scipy.ndimage as ndi
from skimage.filters import window
from skimage.registration import phase_cross_correlation

import irfidelity as irf

DATA = pathlib.Path(__file__).resolve().parent.parent / "tests" / "data" / "thermal"


# --------------------------------------------------------------------------- cases
def frames() -> dict[str, np.ndarray]:
    lepton = irf.load_frame(DATA / "cptv_v2_frame000.png").astype(np.float64)
    xtr = irf.load_frame(DATA / "readthermal_zenmuse_xtr_raw16.png").astype(np.float64)
    duo = irf.load_frame(DATA / "flirpy_frame_000000_raw16.png").astype(np.float64)
    return {
        "640×512 Lepton↑": ndi.zoom(lepton, (512 / 120, 640 / 160), order=3, mode="reflect", grid_mode=True),
        "640×512 XT-R": ndi.gaussian_filter(xtr, 0.7),
        "640×512 Duo Pro R": ndi.gaussian_filter(duo, 0.7),
        "160×120 Lepton": ndi.gaussian_filter(lepton, 0.7),
    }


def true_matrix(shape, dy, dx, angle=0.0, scale=1.0) -> np.ndarray:
    """Simulated → real map: rotation/scale about the centre (OpenCV sense), then the shift."""
    h, w = shape
    m = cv2.getRotationMatrix2D(((w - 1) / 2, (h - 1) / 2), angle, scale)
    m[0, 2] += dx
    m[1, 2] += dy
    return m


def seen_through(scene: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``out(p) = scene(M·p)``: the scene as the simulated camera sees it (5th-order spline)."""
    rc = np.array([[m[1, 1], m[1, 0]], [m[0, 1], m[0, 0]]])
    return ndi.affine_transform(scene, rc, (m[1, 2], m[0, 2]), order=5, mode="reflect")


def random_matrix(shape, model, rng) -> np.ndarray:
    """A transform of the model: shifts up to ±8 px (±4 px below 640 columns), rotations within
    ±3°, scales within ±2 %."""
    reach = 8.0 if shape[1] >= 640 else 4.0
    dy, dx = rng.uniform(-reach, reach, 2)
    angle = rng.uniform(-3, 3) if model != "translation" else 0.0
    scale = rng.uniform(0.98, 1.02) if model == "similarity" else 1.0
    return true_matrix(shape, dy, dx, angle, scale)


def make_case(scene, model, rng):
    """A typical simulator: blurred (σ 0.5–1.2 px), gain (0.7–1.4) and offset (±200) changed,
    noised (5–20 % of the scene's std); the real frame has its own noise (5 %)."""
    m = random_matrix(scene.shape, model, rng)
    std = scene.std()
    sim = ndi.gaussian_filter(seen_through(scene, m), rng.uniform(0.5, 1.2))
    sim = rng.uniform(0.7, 1.4) * sim + rng.uniform(-200, 200) + rng.normal(0, rng.uniform(0.05, 0.2) * std, sim.shape)
    real = scene + rng.normal(0, 0.05 * std, scene.shape)
    return real.astype(np.float32), sim.astype(np.float32), m


def make_close_case(scene, model, rng):
    """A simulator close to the camera: as sharp within 0.5 px of blur, the same grey levels,
    little noise (0.2–1 % of the scene's range), whole counts; the real frame has its own
    noise (0.2 % of the range). Here misregistration, not the simulator, limits PSNR."""
    m = random_matrix(scene.shape, model, rng)
    span = float(scene.max() - scene.min())
    sim = ndi.gaussian_filter(seen_through(scene, m), rng.uniform(0.0, 0.5))
    sim = np.round(sim + rng.normal(0, rng.uniform(0.002, 0.01) * span, sim.shape))
    real = np.round(scene + rng.normal(0, 0.002 * span, scene.shape))
    return real.astype(np.float32), sim.astype(np.float32), m


#: The simulated frames a registration is tried on (see each function).
SIMULATORS = {"typical": make_case, "close": make_close_case}


def corner_error(found: np.ndarray, truth: np.ndarray, shape) -> float:
    h, w = shape
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float).T
    return float(np.linalg.norm((np.asarray(found) - truth) @ corners, axis=0).max())


def registered(sim: np.ndarray, matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``sim`` resampled onto the real frame's pixels by ``matrix`` (irfidelity's bicubic warp)."""
    reg = irf.registration.Registration.from_dict({"model": "similarity", "method": "phase",
                                                   "matrix": np.asarray(matrix).tolist(), "confidence": 1.0,
                                                   "overlap": 1.0, "shape": list(sim.shape)})
    return reg.apply(sim)


def psnr_cost(real: np.ndarray, sim: np.ndarray, found: np.ndarray, truth: np.ndarray) -> float:
    """What the registration error costs the metrics, in dB: PSNR (peak = the real frame's range)
    of the real frame against the simulated one registered by ``found``, minus the same with the
    true transform. Both after the least-squares grey-level gain and offset (the cases change
    them, and a calibrated simulator would not), over the pixels both warps cover."""
    by_found, valid_found = registered(sim, found)
    by_truth, valid_truth = registered(sim, truth)
    valid = valid_found & valid_truth
    target = real[valid].astype(np.float64)
    peak = float(real.max() - real.min())

    def matched_psnr(aligned):
        x = aligned[valid]
        design = np.stack([x, np.ones_like(x)], axis=1)
        coef, *_ = np.linalg.lstsq(design, target, rcond=None)
        return 10 * np.log10(peak ** 2 / np.mean((target - design @ coef) ** 2))

    return float(matched_psnr(by_found) - matched_psnr(by_truth))


# --------------------------------------------------------------------------- methods
def shift_matrix(dy, dx):
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])


def irf_method(model, method):
    def run(real, sim):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", irf.registration.RegistrationWarning)
            return irf.register(real, sim, model=model, method=method).matrix
    return run


def skimage_pcc(upsample, hann=False):
    """scikit-image as documented; ``hann``: both frames mean-subtracted and Hann-windowed
    first, as its gallery advises for non-periodic images."""
    def run(real, sim):
        if hann:
            w = window("hann", real.shape)
            real, sim = (real - real.mean()) * w, (sim - sim.mean()) * w
        (dy, dx), _, _ = phase_cross_correlation(real, sim, upsample_factor=upsample)
        return shift_matrix(dy, dx)
    return run


def cv_phase(real, sim):
    window = cv2.createHanningWindow(real.shape[::-1], cv2.CV_32F)
    (sx, sy), _ = cv2.phaseCorrelate(sim, real, window)  # shift of the 2nd argument from the 1st
    return shift_matrix(sy, sx)


def cv_ecc(motion):
    """ECC from the identity, as OpenCV's examples use it. (Started from ``phaseCorrelate``'s
    shift it does worse here: that shift is wrong by pixels once the frames also turn, and
    ECC then settles in a wrong local optimum.)"""
    def run(real, sim):
        criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-6)
        _, warp = cv2.findTransformECC(real, sim, np.eye(2, 3, dtype=np.float32), motion, criteria, None, 5)
        return np.linalg.inv(np.vstack([warp.astype(np.float64), [0, 0, 1]]))[:2]  # warp maps real → sim
    return run


METHODS = {
    "translation": {
        "irfidelity phase": irf_method("translation", "phase"),
        "irfidelity auto": irf_method("translation", "auto"),
        "skimage pcc ×10": skimage_pcc(10),
        "skimage pcc ×100": skimage_pcc(100),
        "skimage pcc ×100 Hann": skimage_pcc(100, hann=True),
        "OpenCV phaseCorrelate": cv_phase,
    },
    "rigid": {
        "irfidelity phase": irf_method("rigid", "phase"),
        "irfidelity auto": irf_method("rigid", "auto"),
        "OpenCV ECC euclidean": cv_ecc(cv2.MOTION_EUCLIDEAN),
    },
    "similarity": {
        "irfidelity phase": irf_method("similarity", "phase"),
        "irfidelity auto": irf_method("similarity", "auto"),
        "OpenCV ECC affine": cv_ecc(cv2.MOTION_AFFINE),
    },
}


def timed(fn, real, sim, repeat, clock=time.perf_counter):
    """The result of the last call (or its exception) and the shortest time of ``repeat`` calls."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = clock()
        try:
            out = fn(real, sim)
        except (cv2.error, irf.FidelityError) as exc:  # a failure counts as an infinite error
            out = exc
        best = min(best, clock() - t0)
    return out, best


# --------------------------------------------------------------------------- run
def run(n_cases: int, repeat: int, clock=time.perf_counter, seed: int = 2026, verbose: bool = True,
        models: tuple[str, ...] = tuple(METHODS), simulators: tuple[str, ...] = ("typical",)):
    """One row per frame, simulator (of ``simulators``), model (of ``models``) and method:
    worst and median corner error, worst PSNR cost, median time."""
    rows = []
    for (fname, scene), simulator, model in itertools.product(frames().items(), simulators, models):
        methods = METHODS[model]
        rng = np.random.default_rng(seed)
        cases = [SIMULATORS[simulator](scene, model, rng) for _ in range(n_cases)]
        for mname, fn in methods.items():
            errs, costs, times = [], [], []
            for real, sim, truth in cases:
                found, t = timed(fn, real, sim, repeat, clock)
                failed = isinstance(found, Exception)
                errs.append(np.inf if failed else corner_error(found, truth, real.shape))
                costs.append(np.inf if failed else abs(psnr_cost(real, sim, found, truth)))
                times.append(t)
            rows.append(dict(frame=fname, simulator=simulator, model=model, method=mname, worst=max(errs),
                             median=float(np.median(errs)), psnr_cost=max(costs),
                             time_ms=1e3 * float(np.median(times)), failed=sum(np.isinf(errs))))
            if verbose:
                print(f"{fname:18} {simulator:8} {model:11} {mname:22} worst {max(errs):8.4f} px  "
                      f"median {np.median(errs):7.4f} px  PSNR cost {max(costs):7.4f} dB  {1e3 * np.median(times):8.2f} ms",
                      flush=True)
    return rows
