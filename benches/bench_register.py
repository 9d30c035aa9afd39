"""Registration accuracy and speed: irfidelity vs scikit-image and OpenCV on real thermal frames.

Cases: real frames from ``tests/data/thermal`` seen through known transforms, then made to
differ as a simulator would — blurred (a different MTF), gain/offset-changed, noised — while the
real frame gets its own noise:

- ``640×512 Lepton↑``: a 160×120 Lepton frame upscaled ×4 (cubic spline) — smooth at this scale;
- ``640×512 XT-R``: a native 640×512 DJI Zenmuse XT-R frame (lightly smoothed, σ = 0.7 px,
  so that the known transform is exact up to the resampling error of a 5th-order spline);
- ``160×120 Lepton``: the Lepton frame itself (σ = 0.7 px).

Transforms: shifts up to ±8 px (±4 px at 160×120); rigid adds a rotation within ±3°; similarity
adds a scale within ±2 %. The error of a result is the worst displacement over the four frame
corners between the found and the true map (pixels).

Peers: scikit-image ``phase_cross_correlation`` (upsample_factor 10 and 100; and 100 on
Hann-windowed frames) and OpenCV
``phaseCorrelate`` (Hanning window) for translation; OpenCV ``findTransformECC`` (MOTION_EUCLIDEAN
for rigid, MOTION_AFFINE for similarity — ECC has no similarity model — started from
the identity, 100 iterations or 1e-6) for rotation and scale. irfidelity:
``irf.register(method="phase")`` and ``method="auto"``.

Time per call: the best of ``--repeat`` calls. By default everything runs on one thread (the
Rust pool, OpenCV, OpenBLAS/OpenMP behind numpy and scikit-image) and the time is the process's
CPU time — core-for-core ratios that a busy machine disturbs little. ``--threads N`` lets every
library use N threads and measures wall time instead.

Usage: ``python benches/bench_register.py [--quick] [--repeat R] [--threads N] [--docs]``.
``--docs`` writes the table to the "Registration" section of docs/performance.md and the
error-vs-time figure to docs/registration.png; otherwise both go to bench-out/.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import re
import sys
import time
import warnings


def _threads_from_argv() -> int:
    """``--threads`` must be known before numpy, OpenCV and the Rust pool start their threads."""
    for i, a in enumerate(sys.argv):
        if a == "--threads" and i + 1 < len(sys.argv):
            return int(sys.argv[i + 1])
        if a.startswith("--threads="):
            return int(a.split("=", 1)[1])
    return 1


THREADS = _threads_from_argv()
for var in ("RAYON_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = str(THREADS)

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import scipy.ndimage as ndi  # noqa: E402
from skimage.filters import window  # noqa: E402
from skimage.registration import phase_cross_correlation  # noqa: E402

import irfidelity as irf  # noqa: E402

cv2.setNumThreads(THREADS)
CLOCK = time.process_time if THREADS == 1 else time.perf_counter

ROOT = pathlib.Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data" / "thermal"


# --------------------------------------------------------------------------- cases
def frames() -> dict[str, np.ndarray]:
    lepton = irf.load_frame(DATA / "cptv_v2_frame000.png").astype(np.float64)
    xtr = irf.load_frame(DATA / "readthermal_zenmuse_xtr_raw16.png").astype(np.float64)
    return {
        "640×512 Lepton↑": ndi.zoom(lepton, (512 / 120, 640 / 160), order=3, mode="reflect", grid_mode=True),
        "640×512 XT-R": ndi.gaussian_filter(xtr, 0.7),
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


def make_case(scene, model, rng):
    h, w = scene.shape
    reach = 8.0 if w >= 640 else 4.0
    dy, dx = rng.uniform(-reach, reach, 2)
    angle = rng.uniform(-3, 3) if model != "translation" else 0.0
    scale = rng.uniform(0.98, 1.02) if model == "similarity" else 1.0
    m = true_matrix(scene.shape, dy, dx, angle, scale)
    std = scene.std()
    sim = ndi.gaussian_filter(seen_through(scene, m), rng.uniform(0.5, 1.2))
    sim = rng.uniform(0.7, 1.4) * sim + rng.uniform(-200, 200) + rng.normal(0, rng.uniform(0.05, 0.2) * std, sim.shape)
    real = scene + rng.normal(0, 0.05 * std, scene.shape)
    return real.astype(np.float32), sim.astype(np.float32), m


def corner_error(found: np.ndarray, truth: np.ndarray, shape) -> float:
    h, w = shape
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float).T
    return float(np.linalg.norm((np.asarray(found) - truth) @ corners, axis=0).max())


# --------------------------------------------------------------------------- methods
def shift_matrix(dy, dx):
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])


def irf_method(model, method):
    def run(real, sim):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", irf.RegistrationWarning)
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


def timed(fn, real, sim, repeat):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = CLOCK()
        try:
            out = fn(real, sim)
        except (cv2.error, irf.FidelityError) as exc:  # a failure counts as an infinite error
            out = exc
        best = min(best, CLOCK() - t0)
    return out, best


# --------------------------------------------------------------------------- run
def run(n_cases: int, repeat: int, seed: int = 2026):
    rows = []
    for fname, scene in frames().items():
        for model, methods in METHODS.items():
            rng = np.random.default_rng(seed)
            cases = [make_case(scene, model, rng) for _ in range(n_cases)]
            for mname, fn in methods.items():
                errs, times = [], []
                for real, sim, truth in cases:
                    found, t = timed(fn, real, sim, repeat)
                    errs.append(np.inf if isinstance(found, Exception) else corner_error(found, truth, real.shape))
                    times.append(t)
                rows.append(dict(frame=fname, model=model, method=mname, worst=max(errs),
                                 median=float(np.median(errs)), time_ms=1e3 * float(np.median(times)),
                                 failed=sum(np.isinf(errs))))
                print(f"{fname:16} {model:11} {mname:22} worst {max(errs):8.4f} px  median {np.median(errs):7.4f} px"
                      f"  {1e3 * np.median(times):8.2f} ms", flush=True)
    return rows


def ratios(rows):
    """Time ratio of each peer to ``irfidelity phase`` on the same frame and model."""
    ref = {(r["frame"], r["model"]): r["time_ms"] for r in rows if r["method"] == "irfidelity phase"}
    return {(r["frame"], r["model"], r["method"]): r["time_ms"] / ref[(r["frame"], r["model"])] for r in rows}


def table(rows) -> str:
    rat = ratios(rows)
    out = ["| frames | model | method | worst corner error (px) | median (px) | time / call (ms) | time ÷ irfidelity phase |",
           "|---|---|---|---|---|---|---|"]
    for r in rows:
        err = "failed" if np.isinf(r["worst"]) else f"{r['worst']:.3f}"
        if r["failed"] and not np.isinf(r["median"]):
            err += f" ({r['failed']} failed)"
        out.append(f"| {r['frame']} | {r['model']} | {r['method']} | {err} | {r['median']:.3f} | {r['time_ms']:.1f} | "
                   f"{rat[(r['frame'], r['model'], r['method'])]:.2f} |")
    return "\n".join(out)


def figure(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frames_ = list(dict.fromkeys(r["frame"] for r in rows))
    models = list(METHODS)
    fig, axes = plt.subplots(len(frames_), len(models), figsize=(4.2 * len(models), 3.4 * len(frames_)), squeeze=False)
    styles = {"irfidelity phase": ("o", "C0"), "irfidelity auto": ("s", "C1"), "skimage pcc ×10": ("v", "C2"),
              "skimage pcc ×100": ("^", "C3"), "skimage pcc ×100 Hann": ("<", "C7"), "OpenCV phaseCorrelate": ("D", "C4"), "OpenCV ECC euclidean": ("P", "C5"),
              "OpenCV ECC affine": ("X", "C6")}
    for i, f in enumerate(frames_):
        for j, mo in enumerate(models):
            ax = axes[i][j]
            for r in rows:
                if r["frame"] == f and r["model"] == mo:
                    marker, color = styles[r["method"]]
                    worst = r["worst"] if np.isfinite(r["worst"]) else 100.0
                    ax.loglog(r["time_ms"], worst, marker, color=color, label=r["method"], ms=8)
                    ax.loglog(r["time_ms"], max(r["median"], 1e-4), marker, color=color, ms=5, alpha=0.4)
            ax.set_title(f"{f}, {mo}", fontsize=9)
            ax.set_xlabel("time per call (ms)")
            ax.set_ylabel("corner error (px): worst (large), median (faint)")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def write_docs(text: str, path: pathlib.Path):
    section = "## Registration\n\n" + text.strip() + "\n"
    if path.exists():
        old = path.read_text()
        if "## Registration\n" in old:
            new = re.sub(r"## Registration\n.*?(?=\n## |\Z)", section.rstrip("\n") + "\n", old, flags=re.S)
        else:
            new = old.rstrip("\n") + "\n\n" + section
    else:
        new = "# Performance\n\nNumbers written by the benches in `benches/`; machine and date in each section.\n\n" + section
    path.write_text(new)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="3 cases per frame and model, 1 timing repeat")
    ap.add_argument("--cases", type=int, default=None, help="cases per frame and model (default 8)")
    ap.add_argument("--repeat", type=int, default=None, help="timed calls per case, best kept (default 3; quick 1)")
    ap.add_argument("--threads", type=int, default=1, help="threads for every library (default 1: CPU time, core for core)")
    ap.add_argument("--docs", action="store_true", help="write docs/performance.md (Registration) and docs/registration.png")
    args = ap.parse_args()
    n = args.cases or (3 if args.quick else 8)
    repeat = args.repeat or (2 if args.quick else 3)
    cv2.setRNGSeed(0)
    rows = run(n, repeat)
    md = table(rows)
    print()
    print(md)
    out_dir = ROOT / ("docs" if args.docs else "bench-out")
    out_dir.mkdir(exist_ok=True)
    figure(rows, out_dir / "registration.png")
    import platform

    clock = "CPU time, one thread for every library" if THREADS == 1 else f"wall time, {THREADS} threads per library"
    header = (f"`benches/bench_register.py` ({n} cases per frame and model, best of {repeat} calls, {clock}; "
              f"{platform.machine()}, {platform.processor() or 'cpu'}, Python {platform.python_version()}, "
              f"OpenCV {cv2.__version__}, scikit-image {__import__('skimage').__version__}; "
              f"{time.strftime('%Y-%m-%d')}). Error: worst displacement of a frame corner between the found and "
              f"the true transform. Figure: [registration.png](registration.png).\n\n")
    if args.docs:
        write_docs(header + md, out_dir / "performance.md")
    else:
        (out_dir / "registration.md").write_text(header + md + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
