"""Windowed SSIM map and MS-SSIM: irfidelity vs scikit-image (and a scipy MS-SSIM), in one run.

Peers: ``skimage.metrics.structural_similarity(real, sim, gaussian_weights=True, sigma=1.5,
use_sample_covariance=False, data_range=L, full=True)`` (the map and its mean, what a user
would otherwise run) and, for MS-SSIM, which scikit-image does not have, five scales of
scipy.ndimage Gaussian moments with 2×2 averaging (the reference of tests/test_maps.py).
Frames: a real 640×512 thermal frame (FLIR, 16-bit counts) and its simulated camera (blur,
gain, noise), as uint16 and float32; a real 160×120 Lepton frame (4 MS-SSIM scales).

Each round times both sides (best of ``--repeat`` calls) and prints their ratio; the summary
gives the range of ratios over ``--rounds`` rounds. irfidelity uses the Rust pool (both cores
by default, ``--threads 1`` for core for core); scipy and scikit-image use one core.

Usage: ``python benches/bench_maps.py [--threads N] [--rounds R] [--repeat K]``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path


def parse():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=0, help="Rust threads (default 0: all cores)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=15)
    return ap.parse_args()


args = parse()
if args.threads:
    os.environ["RAYON_NUM_THREADS"] = str(args.threads)  # before the pool is first used

import numpy as np  # noqa: E402
from scipy.ndimage import gaussian_filter  # noqa: E402
from skimage.metrics import structural_similarity  # noqa: E402

import irfidelity as irf  # noqa: E402
from _common import best  # noqa: E402
from irfidelity.demo import simulate_camera  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "thermal"
WEIGHTS = np.array([0.0448, 0.2856, 0.3001, 0.2363, 0.1333])


def skimage_map(r, s, peak):
    return structural_similarity(r, s, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                                 data_range=peak, full=True)


def scipy_ms_ssim(real, sim, peak, scales):
    c1, c2 = (0.01 * peak) ** 2, (0.03 * peak) ** 2
    x, y = real.astype(np.float64), sim.astype(np.float64)
    terms = []
    for j in range(scales):
        f = lambda a: gaussian_filter(a, 1.5, truncate=3.5, mode="reflect")  # noqa: E731
        mx, my = f(x), f(y)
        cs = (2 * (f(x * y) - mx * my) + c2) / (f(x * x) - mx**2 + f(y * y) - my**2 + c2)
        full = (2 * mx * my + c1) / (mx**2 + my**2 + c1) * cs
        terms.append((full if j == scales - 1 else cs)[5:-5, 5:-5].mean())
        x, y = (np.pad(a, ((0, a.shape[0] % 2), (0, a.shape[1] % 2)), mode="edge") for a in (x, y))
        x, y = ((a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]) / 4 for a in (x, y))
    w = WEIGHTS[:scales] / WEIGHTS[:scales].sum()
    return float(np.prod(np.maximum(terms, 0.0) ** w))


def cases():
    big = irf.load_frame(DATA / "flirpy_frame_000000_raw16.png")  # 640×512, uint16 counts
    sim = simulate_camera(big, sigma=1.0, gain=0.98, offset=20.0, noise=3.0, seed=0)
    yield "640×512 uint16", big, sim, float(2**16 - 1)
    scale = 1.0 / 100.0
    yield "640×512 float32", (big * scale).astype(np.float32), (sim * scale).astype(np.float32), 655.35
    lepton = irf.load_frame(DATA / "cptv_v2_frame000.png")  # 160×120, 14-bit counts
    yield "160×120 uint16", lepton, simulate_camera(lepton, sigma=1.0, gain=0.98, offset=45, noise=6, bits=14), 16383.0


def main():
    threads = args.threads or os.cpu_count()
    print(f"irfidelity {irf.__version__}; Rust threads = {threads}; cores = {os.cpu_count()}; "
          f"rounds = {args.rounds}, best of {args.repeat}")
    ratios: dict[str, list[float]] = {}
    agreement = 0.0
    for rnd in range(args.rounds):
        print(f"\nround {rnd + 1}")
        print(f"{'case':<34}{'irfidelity ms':>15}{'peer ms':>11}{'ratio':>9}{'|mean diff|':>14}")
        for name, r, s, peak in cases():
            ours = irf.maps.ssim_map(r, s, peak=peak)
            # scikit-image filters float32 in float32: its reference value is on float64 frames
            ref_mean, _ = skimage_map(r.astype(np.float64), s.astype(np.float64), peak)
            agreement = max(agreement, abs(ours.mean - ref_mean))
            # the lambdas are timed below, within this iteration: they see this case's r, s, peak
            rows = [(f"ssim_map {name}", lambda: irf.maps.ssim_map(r, s, peak=peak),  # noqa: B023
                     lambda: skimage_map(r, s, peak), abs(ours.mean - ref_mean))]  # noqa: B023
            scales = irf.maps._core.max_scales(*r.shape, 11)
            ms = irf.maps.ms_ssim(r, s, peak=peak)
            rows.append((f"ms_ssim {name} ({scales} scales)", lambda: irf.maps.ms_ssim(r, s, peak=peak),  # noqa: B023
                         lambda: scipy_ms_ssim(r, s, peak, scales),  # noqa: B023
                         abs(ms - scipy_ms_ssim(r, s, peak, scales))))
            for label, fast, peer, diff in rows:
                t_ours, t_peer = best(fast, args.repeat), best(peer, max(3, args.repeat // 3))
                ratios.setdefault(label, []).append(t_peer / t_ours)
                print(f"{label:<34}{t_ours * 1e3:>15.3f}{t_peer * 1e3:>11.2f}{t_peer / t_ours:>8.1f}×{diff:>14.2e}")
    print(f"\nsummary over {args.rounds} rounds (peer time / irfidelity time); largest |mean − scikit-image| "
          f"{agreement:.1e}")
    print("| case | ratio range |\n|---|---|")
    for label, rs in ratios.items():
        print(f"| {label} | {min(rs):.1f}–{max(rs):.1f}× |")


if __name__ == "__main__":
    main()
