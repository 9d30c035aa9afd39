"""Sequence throughput (issue 6): frames per second of ``irf.score_sequence``.

Workloads (generated into a temporary directory from the real Lepton recording in
tests/data/thermal, upscaled to 640x512 with cubic interpolation; the "simulated" frame is
the real one with a 1 % gain, an offset and Gaussian noise):

* 16-bit grayscale PNG,
* single-channel EXR: float32 / float16, ZIP / PIZ (written with the ``OpenEXR`` package).

Measured in the same run:

* irfidelity, all image components (PSNR, NMI with 256 bins, global SSIM), 1 vs 2 workers;
* a Python pipeline doing the same work: decode (cv2 for PNG, the OpenEXR package with one
  thread for EXR) + scikit-image ``peak_signal_noise_ratio`` and
  ``normalized_mutual_information(bins=256)`` + a numpy float64 global SSIM;
* the PSNR-only plan (``weights="psnr=1"``) vs ffmpeg's ``psnr`` filter on the same PNG
  sequence (skipped with a message if ffmpeg is not installed);
* registered sequences, on a PNG workload whose simulated frames are also displaced by
  (1.3, −0.7) px: registered once (``register="translation"``), every pair registered
  (``register_each``, translation and rigid), against a Python pipeline registering every
  pair: decode + scikit-image ``phase_cross_correlation(upsample_factor=100)`` + scipy
  ``ndimage.shift`` (cubic spline) + the same metrics over the overlap.

Usage: ``python benches/bench_sequence.py [--pairs N] [--quick] [--keep DIR]``
(default 200 pairs cycling over 100 distinct frames; ``--quick``: 40 pairs, PNG and
float32-ZIP only). Besides frames/s, CPU ms per frame is printed: it is what to compare
when other processes share the machine. irfidelity rates are the best of two interleaved
1-worker / 2-worker runs.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import resource
import shutil
import subprocess
import sys
import tempfile
import warnings
import time

import numpy as np

import irfidelity  # noqa: F401  (import check before the slow part)
from irfidelity.errors import PeakWarning
from irfidelity.sequence import score_sequence

HERE = pathlib.Path(__file__).resolve().parent
STACK = HERE.parent / "tests" / "data" / "thermal" / "cptv_v2_all100frames_uint16.tif"
ROWS, COLS = 512, 640
PEAK = 65535.0
#: (dy, dx) by which the "png16-moved" workload displaces the simulated view.
MOVED = (1.3, -0.7)
# the 16-bit peak, as ffmpeg's psnr filter uses: the warning that it pins the psnr component
# near 1 on these frames is expected here
warnings.filterwarnings("ignore", category=PeakWarning)


#: Distinct frames written per workload; longer runs cycle through them (every pair is
#: still decoded and scored; it only keeps the generation time down).
UNIQUE = 100


def _frames(count: int):
    import cv2
    import tifffile

    stack = tifffile.imread(STACK)
    rng = np.random.default_rng(2024)
    for i in range(count):
        src = stack[i % len(stack)].astype(np.float32)
        real = cv2.resize(src, (COLS, ROWS), interpolation=cv2.INTER_CUBIC)
        real = np.clip(np.rint(real), 0, 16383)
        sim = np.clip(np.rint(real * 1.01 - 25 + rng.normal(0, 8, real.shape)), 0, 16383)
        yield i, real.astype(np.uint16), sim.astype(np.uint16)


def _write_exr(path: str, data: np.ndarray, compression) -> None:
    import OpenEXR

    header = {"compression": compression, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"Y": data}) as f:
        f.write(path)


def generate(root: pathlib.Path, pairs: int, exr_kinds) -> dict:
    """Write the workloads; returns {name: (real paths, sim paths)} with `pairs` entries each."""
    from concurrent.futures import ThreadPoolExecutor

    import cv2
    import OpenEXR

    comp = {"zip": OpenEXR.ZIP_COMPRESSION, "piz": OpenEXR.PIZ_COMPRESSION}
    names = ["png16", "png16-moved"] + [f"exr-{dt}-{c}" for dt, c in exr_kinds]
    for name in names:
        for side in ("real", "sim"):
            (root / name / side).mkdir(parents=True, exist_ok=True)
    unique = min(pairs, UNIQUE)

    def write(item):
        i, real, sim = item
        moved = cv2.warpAffine(sim.astype(np.float32), np.float32([[1, 0, MOVED[1]], [0, 1, MOVED[0]]]),
                               (COLS, ROWS), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
        cv2.imwrite(str(root / "png16-moved" / "real" / f"f_{i:04d}.png"), real)
        cv2.imwrite(str(root / "png16-moved" / "sim" / f"f_{i:04d}.png"), np.clip(np.rint(moved), 0, 16383)
                    .astype(np.uint16))
        for side, img in (("real", real), ("sim", sim)):
            cv2.imwrite(str(root / "png16" / side / f"f_{i:04d}.png"), img)
            for dt, c in exr_kinds:
                arr = img.astype(np.float32 if dt == "f32" else np.float16)
                _write_exr(str(root / f"exr-{dt}-{c}" / side / f"f_{i:04d}.exr"), arr, comp[c])

    with ThreadPoolExecutor(os.cpu_count() or 1) as ex:
        list(ex.map(write, _frames(unique)))
    out = {}
    for name in names:
        ext = "png" if name.startswith("png16") else "exr"
        out[name] = tuple([str(root / name / side / f"f_{i % unique:04d}.{ext}") for i in range(pairs)]
                          for side in ("real", "sim"))
    return out


# --------------------------------------------------------------------------- baseline
def _read_exr(path: str) -> np.ndarray:
    import OpenEXR

    with OpenEXR.File(path, separate_channels=True, num_threads=1) as f:
        return f.channels()["Y"].pixels


def _ssim_global(a: np.ndarray, b: np.ndarray) -> float:
    a = a.astype(np.float64)
    b = b.astype(np.float64)
    ma, mb = a.mean(), b.mean()
    da, db = a - ma, b - mb
    va, vb, cov = (da * da).mean(), (db * db).mean(), (da * db).mean()
    lum = 2 * ma * mb / (ma * ma + mb * mb)
    con = 2 * math.sqrt(va * vb) / (va + vb)
    struct = cov / math.sqrt(va * vb)
    return lum * con * struct


class Timer:
    """Wall time and CPU time (this process and its children) of a block."""

    def __enter__(self):
        self.r0 = resource.getrusage(resource.RUSAGE_SELF)
        self.c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self.t0
        r1 = resource.getrusage(resource.RUSAGE_SELF)
        c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        self.cpu = sum(getattr(b, f) - getattr(a, f) for a, b in ((self.r0, r1), (self.c0, c1))
                       for f in ("ru_utime", "ru_stime"))


def baseline(paths, png: bool) -> tuple[float, float]:
    """(frames/s, CPU ms/frame) of decode + scikit-image PSNR and NMI(256 bins) + numpy global SSIM."""
    import cv2
    from skimage.metrics import normalized_mutual_information, peak_signal_noise_ratio

    real, sim = paths
    with Timer() as tm:
        for rp, sp in zip(real, sim):
            if png:
                r = cv2.imread(rp, cv2.IMREAD_UNCHANGED)
                s = cv2.imread(sp, cv2.IMREAD_UNCHANGED)
            else:
                r = _read_exr(rp)
                s = _read_exr(sp)
            if r.dtype == np.float16:  # scikit-image's histogram needs float32/64
                r, s = r.astype(np.float32), s.astype(np.float32)
            peak_signal_noise_ratio(r, s, data_range=PEAK)
            normalized_mutual_information(r, s, bins=256)
            _ssim_global(r, s)
    return len(real) / tm.wall, tm.cpu / len(real) * 1e3


def irf_rate(paths, workers: int, weights=None, **options) -> tuple[float, float]:
    """(frames/s, CPU ms/frame) of score_sequence on lists of paths (no CSV, no bar)."""
    real, sim = paths
    n = len(real)
    with Timer() as tm:
        rep = score_sequence(real, sim, peak=PEAK, workers=workers, weights=weights, progress=False, **options)
    assert not rep.failed, rep.summary_text()
    return n / tm.wall, tm.cpu / n * 1e3


def best_of(paths, weights=None, runs: int = 2, **options) -> tuple[float, float, float, float]:
    """Best of `runs` interleaved 1-worker / 2-worker runs:
    (fps 1w, CPU ms/frame 1w, fps 2w, CPU ms/frame 2w)."""
    one, two, cpu1, cpu2 = 0.0, 0.0, math.inf, math.inf
    for _ in range(runs):
        f1, c1 = irf_rate(paths, 1, weights, **options)
        f2, c2 = irf_rate(paths, 2, weights, **options)
        one, two, cpu1, cpu2 = max(one, f1), max(two, f2), min(cpu1, c1), min(cpu2, c2)
    return one, cpu1, two, cpu2


def baseline_registered(paths) -> tuple[float, float]:
    """(frames/s, CPU ms/frame) of decode + scikit-image phase correlation (×100) + a cubic
    spline shift + PSNR, NMI(256 bins) and global SSIM over the overlap, for every pair."""
    import cv2
    import scipy.ndimage as ndi
    from skimage.metrics import normalized_mutual_information, peak_signal_noise_ratio
    from skimage.registration import phase_cross_correlation

    real, sim = paths
    with Timer() as tm:
        for rp, sp in zip(real, sim):
            r = cv2.imread(rp, cv2.IMREAD_UNCHANGED).astype(np.float64)
            s = cv2.imread(sp, cv2.IMREAD_UNCHANGED).astype(np.float64)
            shift, _, _ = phase_cross_correlation(r, s, upsample_factor=100)
            aligned = ndi.shift(s, shift, order=3, mode="constant", cval=np.nan)
            keep = np.isfinite(aligned)
            r, aligned = r[keep], aligned[keep]
            peak_signal_noise_ratio(r, aligned, data_range=PEAK)
            normalized_mutual_information(r, aligned, bins=256)
            _ssim_global(r, aligned)
    return len(real) / tm.wall, tm.cpu / len(real) * 1e3


def registered_rows(paths) -> None:
    """Registered sequences: once, and every pair (translation, rigid), against the Python
    pipeline registering every pair."""
    py, cpu_py = baseline_registered(paths)
    print(f"{'registration':<22} {'irf 1w':>7} {'irf 2w':>7} {'2w/1w':>6} {'2w/py':>6}   CPU ms/frame: "
          f"{'irf 1w':>6} {'py/irf':>6}")
    for label, options in (("none", {}), ("once, translation", {"register": "translation"}),
                           ("each, translation", {"register": "translation", "register_each": True}),
                           ("each, rigid", {"register": "rigid", "register_each": True})):
        one, cpu_one, two, _ = best_of(paths, **options)
        print(f"{label:<22} {one:7.1f} {two:7.1f} {two / one:6.2f} {two / py:6.1f}                {cpu_one:6.2f} "
              f"{cpu_py / cpu_one:6.1f}")
    print(f"{'python, each':<22} {py:7.1f}   (CPU {cpu_py:.1f} ms/frame: decode + skimage pcc ×100 + ndimage.shift "
          f"+ metrics)")


def ffmpeg_rate(d: pathlib.Path, pairs: int) -> tuple[float, float] | None:
    """ffmpeg's psnr filter over the same `pairs` PNG pairs (the image2 inputs looped like the lists)."""
    exe = shutil.which("ffmpeg")
    if exe is None:
        return None
    unique = min(pairs, UNIQUE)
    loops = ["-stream_loop", str(-(-pairs // unique) - 1)]
    cmd = [exe, "-v", "error", "-nostats"]
    for side in ("real", "sim"):
        cmd += loops + ["-f", "image2", "-i", str(d / side / "f_%04d.png")]
    cmd += ["-lavfi", "[0:v][1:v]psnr=stats_file=-", "-frames:v", str(pairs), "-f", "null", "-"]
    with Timer() as tm:
        res = subprocess.run(cmd, check=True, capture_output=True, text=True)
    scored = sum(1 for line in res.stdout.splitlines() if line.startswith("n:"))
    if scored != pairs:
        raise RuntimeError(f"ffmpeg scored {scored} frame pairs, expected {pairs}")
    return pairs / tm.wall, tm.cpu / pairs * 1e3


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=None, help="frame pairs per workload (default 200; --quick 40)")
    ap.add_argument("--quick", action="store_true", help="40 pairs, PNG and float32-ZIP EXR only")
    ap.add_argument("--keep", type=pathlib.Path, default=None, help="generate into (and keep) this directory")
    args = ap.parse_args(argv)
    pairs = args.pairs or (40 if args.quick else 200)
    exr_kinds = [("f32", "zip")] if args.quick else [("f32", "zip"), ("f32", "piz"), ("f16", "zip"), ("f16", "piz")]
    root = args.keep or pathlib.Path(tempfile.mkdtemp(prefix="irf_bench_seq_"))
    print(f"cores: {os.cpu_count()}  pairs per workload: {pairs}  frames: {COLS}x{ROWS}")
    t = time.perf_counter()
    dirs = generate(root, pairs, exr_kinds)
    print(f"generated {len(dirs)} workloads in {time.perf_counter() - t:.1f} s under {root}\n")
    try:
        load = os.getloadavg()[0]
        if load > 0.5:
            print(f"note: load average {load:.1f} before the run; wall-clock rates (and the 2w/1w scaling) are "
                  "affected by other processes, CPU ms/frame much less")
        print("all image components (PSNR + NMI 256 bins + global SSIM)")
        print(f"{'workload':<13} {'irf 1w':>7} {'irf 2w':>7} {'2w/1w':>6} {'python':>7} {'2w/py':>6} {'1w/py':>6}"
              f"   CPU ms/frame: {'irf 1w':>6} {'irf 2w':>6} {'python':>6} {'py/irf':>6}")
        for name, paths in dirs.items():
            if name == "png16-moved":
                continue
            one, cpu_one, two, cpu_two = best_of(paths)
            py, cpu_py = baseline(paths, png=name == "png16")
            print(f"{name:<13} {one:7.1f} {two:7.1f} {two / one:6.2f} {py:7.1f} {two / py:6.1f} {one / py:6.1f}"
                  f"                 {cpu_one:6.2f} {cpu_two:6.2f} {cpu_py:6.1f} {cpu_py / cpu_one:6.1f}")
        print("(CPU ms/frame: the whole process, workers and the Python side; 2w above 1w = what running")
        print(" two workers at once costs per frame)")
        print("(frames/s; python = cv2/OpenEXR decode + scikit-image PSNR, NMI(bins=256) + numpy float64 SSIM)")
        print("\nPSNR-only plan on the 16-bit PNG sequence")
        one, cpu_one, two, _ = best_of(dirs["png16"], weights="psnr=1")
        ff = ffmpeg_rate(root / "png16", pairs)
        line = f"irf 1w {one:.1f} frames/s ({cpu_one:.1f} CPU ms/frame)  irf 2w {two:.1f} frames/s"
        if ff is None:
            print(line + "  ffmpeg: not installed (apt-get install -y ffmpeg), row skipped")
        else:
            print(line + f"  ffmpeg psnr {ff[0]:.1f} frames/s ({ff[1]:.1f} CPU ms/frame)  "
                  f"irf2w/ffmpeg {two / ff[0]:.2f}  irf1w/ffmpeg {one / ff[0]:.2f}")
        print(f"\nregistered sequences: 16-bit PNG, the simulated view displaced by {MOVED} px, all image components")
        registered_rows(dirs["png16-moved"])
    finally:
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
