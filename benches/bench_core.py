"""All frame-pair statistics of one pair: irfidelity vs scikit-image + numpy.

Peer set (what a user would otherwise run): ``skimage.metrics.peak_signal_noise_ratio`` +
``skimage.metrics.normalized_mutual_information(bins=256)`` + a numpy-float64 global SSIM
(means, variances, covariance). irfidelity: one ``pair_stats`` call computing MSE/PSNR,
the SSIM moments and the 256-bin joint histogram/entropies (exact sums for uint16).

Usage: ``python benches/bench_core.py [--threads N] [--repeat R]``. By default the Rust pool
is limited to one thread (``RAYON_NUM_THREADS=1``) so the ratio is core-for-core.
"""

from __future__ import annotations

import argparse
import os
import sys


def parse():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=1, help="Rust threads (default 1: core-for-core)")
    ap.add_argument("--repeat", type=int, default=7)
    return ap.parse_args()


args = parse()
os.environ["RAYON_NUM_THREADS"] = str(args.threads)  # before the pool is first used

import numpy as np  # noqa: E402
from skimage.metrics import normalized_mutual_information, peak_signal_noise_ratio  # noqa: E402

import irfidelity as irf  # noqa: E402
from _common import best  # noqa: E402


def numpy_ssim(r, s):
    a, b = r.astype(np.float64), s.astype(np.float64)
    ma, mb = a.mean(), b.mean()
    da, db = a - ma, b - mb
    va, vb, cov = (da * da).mean(), (db * db).mean(), (da * db).mean()
    return (2 * ma * mb / (ma * ma + mb * mb)) * (2 * np.sqrt(va * vb) / (va + vb)) * (cov / np.sqrt(va * vb))


def pair(dtype, shape, seed=0):
    rng = np.random.default_rng(seed)
    if dtype == np.uint16:
        base = rng.integers(2000, 14000, size=shape)
        r = base.astype(np.uint16)
        s = np.clip(base + rng.integers(-40, 41, size=shape), 0, 16383).astype(np.uint16)
        return r, s, dict(bits=14), 16383
    r = rng.normal(300.0, 30.0, size=shape).astype(np.float32)
    s = (r + rng.normal(0, 2.0, size=shape)).astype(np.float32)
    return r, s, dict(peak=1000.0), 1000.0


def main():
    print(f"irfidelity {irf.__version__}; Rust threads = {args.threads}; numpy {np.__version__}; cores = {os.cpu_count()}")
    print(f"{'case':<22}{'irfidelity ms':>15}{'peers ms':>12}{'ratio':>9}{'irf ns/px':>11}")
    per_px = {}
    for dtype in (np.uint16, np.float32):
        for shape in ((512, 640), (2048, 2048)):
            r, s, kw, peak = pair(dtype, shape)

            def ours():
                st = irf.pair_stats(r, s, bins=256, **kw)
                return st.psnr(), st.ssim().value, st.nmi().value

            def peers():
                return (
                    peak_signal_noise_ratio(r, s, data_range=peak),
                    normalized_mutual_information(r, s, bins=256),
                    numpy_ssim(r, s),
                )

            t_ours = best(ours, args.repeat)
            t_peer = best(peers, max(2, args.repeat // 3))
            npx = r.size
            per_px[(dtype, shape)] = t_ours / npx
            name = f"{np.dtype(dtype).name} {shape[1]}x{shape[0]}"
            print(f"{name:<22}{t_ours * 1e3:>15.2f}{t_peer * 1e3:>12.1f}{t_peer / t_ours:>8.1f}x{t_ours / npx * 1e9:>11.2f}")
    for dtype in (np.uint16, np.float32):
        small, large = per_px[(dtype, (512, 640))], per_px[(dtype, (2048, 2048))]
        print(f"linearity {np.dtype(dtype).name}: time per pixel 2048x2048 / 640x512 = {large / small:.2f} (1.0 = linear)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
