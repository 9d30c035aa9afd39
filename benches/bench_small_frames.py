"""Many small frames: pairs per second of ``irf.score_sequence`` on a long 160x120 recording.

    python benches/bench_small_frames.py [--frames 60001] [--workers 2] [--peer-pairs 2000] [--keep DIR]

The workload is two multi-page TIFFs of ``--frames`` 160x120 uint16 frames (one page each),
made from the real Lepton recording in tests/data/thermal: each real frame is a recording
frame with its own Gaussian noise (σ 4 counts), each simulated frame the real one with a 1 %
gain, an offset of −25 counts and noise (σ 8). 60,001 frames make two files of 2.3 GB each.

Measured in the same run:

* irfidelity with every image component (PSNR, NMI with 256 bins, global SSIM) and with the
  PSNR-only plan (``weights="psnr=1"``): wall and CPU time, pairs/s, CPU µs a pair;
* a Python pipeline doing the same work on the first ``--peer-pairs`` pairs: tifffile page
  reads + scikit-image ``peak_signal_noise_ratio`` and
  ``normalized_mutual_information(bins=256)`` + a numpy float64 global SSIM; its pairs/s,
  and irfidelity's against it (> 1: irfidelity is faster).

Issue 38's goal: ≥ 10,000 pairs/s on two cores with every image component. A benchmark, not a
test: numbers depend on the machine (cores, other load).
"""

from __future__ import annotations

import argparse
import pathlib
import shutil
import tempfile
import time
import warnings

import numpy as np

import irfidelity as irf
from irfidelity.errors import PeakWarning

STACK = pathlib.Path(__file__).resolve().parent.parent / "tests" / "data" / "thermal" / "cptv_v2_all100frames_uint16.tif"
GOAL = 10_000.0  # pairs/s, every image component, two cores
# the 14-bit peak pins the psnr component near 1 on these frames: expected here
warnings.filterwarnings("ignore", category=PeakWarning)


def generate(root: pathlib.Path, frames: int) -> tuple[pathlib.Path, pathlib.Path]:
    import tifffile

    real_path, sim_path = root / f"real_{frames}.tif", root / f"sim_{frames}.tif"
    if real_path.exists() and sim_path.exists():
        return real_path, sim_path
    stack = tifffile.imread(STACK).astype(np.float32)
    rng = np.random.default_rng(38)
    with tifffile.TiffWriter(real_path) as real_out, tifffile.TiffWriter(sim_path) as sim_out:
        for i in range(frames):
            real = stack[i % len(stack)] + rng.normal(0, 4, stack.shape[1:])
            sim = real * 1.01 - 25 + rng.normal(0, 8, real.shape)
            real_out.write(np.clip(np.rint(real), 0, 16383).astype(np.uint16), photometric="minisblack")
            sim_out.write(np.clip(np.rint(sim), 0, 16383).astype(np.uint16), photometric="minisblack")
    return real_path, sim_path


def irfidelity_run(real: pathlib.Path, sim: pathlib.Path, frames: int, workers: int, weights: str | None) -> dict:
    wall, cpu = time.perf_counter(), time.process_time()
    report = irf.score_sequence(real, sim, bits=14, weights=weights, workers=workers, progress=False)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    assert len(report.frames) == frames and not report.failed, "every pair scored"
    return {"wall": wall, "cpu": cpu, "rate": frames / wall, "cpu_us": 1e6 * cpu / frames}


def global_ssim(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a.astype(np.float64), b.astype(np.float64)
    ma, mb = a.mean(), b.mean()
    va, vb, cov = a.var(), b.var(), ((a - ma) * (b - mb)).mean()
    return (2 * ma * mb) * (2 * cov) / ((ma * ma + mb * mb) * (va + vb))


def peer_run(real: pathlib.Path, sim: pathlib.Path, pairs: int) -> dict:
    import tifffile
    from skimage.metrics import normalized_mutual_information, peak_signal_noise_ratio

    wall = time.perf_counter()
    with tifffile.TiffFile(real) as real_file, tifffile.TiffFile(sim) as sim_file:
        for i in range(pairs):
            r, s = real_file.pages[i].asarray(), sim_file.pages[i].asarray()
            peak_signal_noise_ratio(r, s, data_range=16383)
            normalized_mutual_information(r, s, bins=256)
            global_ssim(r, s)
    wall = time.perf_counter() - wall
    return {"wall": wall, "rate": pairs / wall}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=60_001, help="frames per recording (default 60,001)")
    ap.add_argument("--workers", type=int, default=2, help="irfidelity's decoding/scoring threads (default 2)")
    ap.add_argument("--peer-pairs", type=int, default=2000, help="pairs the Python pipeline scores (default 2000)")
    ap.add_argument("--keep", type=pathlib.Path, default=None, help="generate into (and reuse) this directory")
    args = ap.parse_args()
    root = args.keep or pathlib.Path(tempfile.mkdtemp(prefix="irf_small_"))
    root.mkdir(parents=True, exist_ok=True)
    try:
        t0 = time.perf_counter()
        real, sim = generate(root, args.frames)
        print(f"{args.frames} pairs of 160x120 uint16 pages ({time.perf_counter() - t0:.1f} s to make)")
        every = irfidelity_run(real, sim, args.frames, args.workers, None)
        psnr = irfidelity_run(real, sim, args.frames, args.workers, "psnr=1")
        peer = peer_run(real, sim, min(args.peer_pairs, args.frames))
        for name, run in (("every image component", every), ("PSNR only", psnr)):
            print(f"irfidelity, {name:22s}: {run['wall']:7.2f} s wall, {run['cpu']:7.2f} s CPU, "
                  f"{run['rate']:8.0f} pairs/s, {run['cpu_us']:6.0f} µs CPU a pair")
        print(f"Python pipeline ({min(args.peer_pairs, args.frames)} pairs)  : {peer['rate']:8.0f} pairs/s")
        print(f"ratio, every component: {every['rate'] / peer['rate']:.2f}x the Python pipeline; "
              f"{every['rate'] / GOAL:.2f} of the goal ({GOAL:,.0f} pairs/s)")
    finally:
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
