"""Plan only what is needed: PSNR-only vs the full image plan on a large frame pair.

    python benches/bench_plan.py [--size 4096] [--repeat 5] [--bits 14]

Scores a synthetic 4096x4096 uint16 pair (a smooth scene + noise, 14-bit) with
``irf.evaluate`` twice: weights "psnr=1" (the plan asks the Rust kernel for the squared
error only: no moments, no histogram pass) and the three image components with weight
1/3 each (squared error + moments + joint histogram). Prints the best-of-N wall times
and their ratio, and the same for the bare ``pair_stats`` calls.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from irfidelity.evaluation import evaluate
from irfidelity.stats import pair_stats


def best_of(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=4096)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--bits", type=int, default=14)
    a = ap.parse_args()
    n, top = a.size, (1 << a.bits) - 1
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:n, 0:n] / n
    scene = 3000 + 2000 * np.sin(6 * xx) * np.cos(4 * yy)
    real = np.clip(scene + rng.normal(0, 30, (n, n)), 0, top).astype(np.uint16)
    sim = np.clip(0.98 * scene + 40 + rng.normal(0, 30, (n, n)), 0, top).astype(np.uint16)
    del yy, xx, scene

    full = "psnr=1,nmi=1,ssim=1,normalize"
    t_psnr = best_of(lambda: evaluate(real, sim, weights="psnr=1", bits=a.bits), a.repeat)
    t_full = best_of(lambda: evaluate(real, sim, weights=full, bits=a.bits), a.repeat)
    k_psnr = best_of(lambda: pair_stats(real, sim, bits=a.bits, need=("psnr",)), a.repeat)
    k_full = best_of(lambda: pair_stats(real, sim, bits=a.bits), a.repeat)
    print(f"{n}x{n} uint16 pair ({a.bits}-bit), best of {a.repeat}, {os.cpu_count()} CPUs")
    print(f"evaluate  PSNR-only plan : {t_psnr * 1e3:8.1f} ms")
    print(f"evaluate  full image plan: {t_full * 1e3:8.1f} ms   (psnr + nmi + ssim)")
    print(f"ratio full / PSNR-only   : {t_full / t_psnr:8.2f}x")
    print(f"pair_stats need=psnr     : {k_psnr * 1e3:8.1f} ms")
    print(f"pair_stats need=all      : {k_full * 1e3:8.1f} ms")
    print(f"ratio                    : {k_full / k_psnr:8.2f}x")


if __name__ == "__main__":
    main()
