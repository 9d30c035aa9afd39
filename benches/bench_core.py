"""All frame-pair statistics of one pair: irfidelity vs scikit-image + numpy.

Both sides compute the same metrics of one pair: MSE, PSNR, the global SSIM (with its
luminance, contrast and structure terms) and a 256-bin NMI. Peers (what a user would
otherwise run): ``skimage.metrics.mean_squared_error`` and PSNR from it,
``skimage.metrics.normalized_mutual_information(bins=256)`` and a numpy-float64 global SSIM
(means, variances, covariance). irfidelity: one ``pair_stats`` call computing the squared
error, the SSIM moments and the 256-bin joint histogram and entropies (exact sums for uint16),
on shared edges (``hist_range="data"``, the paper's) and, in the "each" column, on each
frame's own edges locked by the offset (``hist_range="each"``, the default: what ``evaluate``
and sequences use).
The run checks that both sides agree on MSE, PSNR and SSIM (scikit-image's NMI is Studholme's
``(H(R) + H(S)) / H(R, S)`` over its own bins: the same work, another number).

Pairs:

- real: a 640×512 frame of 16-bit counts from ``tests/data/thermal`` (DJI Zenmuse XT-R; FLIR
  Duo Pro R) against a simulated copy: :func:`irfidelity.demo.simulate_camera` (Gaussian blur
  σ = 1 px, gain 0.98, offset 45, noise σ = 1 % of the frame's range, whole counts);
- synthetic: uint16 values uniform over 2000..14000 against a copy with uniform errors of up to
  ±40, and float32 normal values (300 ± 30) against a copy with N(0, 2) errors, at 640×512 and
  2048×2048.

For the real pairs it also times the whole of :func:`irfidelity.evaluate` on the pair
(unregistered, and registered with ``register="translation", register_method="phase"``; the
simulated copy is shifted by (1.4, −2.6) px for the latter): what a user waits for per pair.
No peer does that work in one call, so these rows give times only (for comparisons between
builds: run the script once with each on ``PYTHONPATH``). The last real-pair row times the
resampling alone (``_core.warp_frame`` of the DJI frame by that shift, bicubic and bilinear).

Usage: ``python benches/bench_core.py [--threads N] [--repeat R] [--pairs real|synthetic|all]``.
By default the Rust pool is limited to one thread (``RAYON_NUM_THREADS=1``) so the ratio is
core-for-core, and times are the process's CPU time (best of the repeats), which the other jobs
of a shared machine disturb less than wall time; ``--threads N`` (N > 1) times wall time.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import sys
import time

PAIRS = ("real", "synthetic", "all")


def parse():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=1, help="Rust threads (default 1: core-for-core)")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--pairs", choices=PAIRS, default="all", help="which frame pairs to time (default all)")
    return ap.parse_args()


args = parse()
os.environ["RAYON_NUM_THREADS"] = str(args.threads)  # before the pool is first used
CLOCK = time.process_time if args.threads == 1 else time.perf_counter

import numpy as np  # noqa: E402
import skimage  # noqa: E402
from skimage.metrics import mean_squared_error, normalized_mutual_information  # noqa: E402

import irfidelity as irf  # noqa: E402
from _common import best  # noqa: E402
from irfidelity import _core  # noqa: E402
from irfidelity.demo import simulate_camera  # noqa: E402

#: A translation by (1.4, −2.6) px as a 2×3 matrix (the shift the registered rows undo).
SHIFT = (1.0, 0.0, 1.4, 0.0, 1.0, -2.6)
THERMAL = pathlib.Path(__file__).resolve().parent.parent / "tests" / "data" / "thermal"
REAL_FRAMES = {"DJI XT-R": "readthermal_zenmuse_xtr_raw16.png", "FLIR Duo Pro R": "flirpy_frame_000000_raw16.png"}


def numpy_ssim(r, s):
    """Global SSIM (paper eqs. 11–14, no constants) and its three terms, in float64."""
    a, b = r.astype(np.float64), s.astype(np.float64)
    ma, mb = a.mean(), b.mean()
    da, db = a - ma, b - mb
    va, vb, cov = (da * da).mean(), (db * db).mean(), (da * db).mean()
    sd = np.sqrt(va * vb)
    luminance, contrast, structure = 2 * ma * mb / (ma * ma + mb * mb), 2 * sd / (va + vb), cov / sd
    return luminance * contrast * structure, luminance, contrast, structure


def real_pair(name: str):
    real = irf.load_frame(THERMAL / REAL_FRAMES[name])
    noise = 0.01 * float(real.max() - real.min())
    sim = simulate_camera(real, sigma=1.0, gain=0.98, offset=45.0, noise=noise, bits=16, seed=0)
    return f"real {name} uint16 {real.shape[1]}x{real.shape[0]}", real, sim, dict(bits=16), 65535.0


def synthetic_pair(dtype, shape, seed=0):
    rng = np.random.default_rng(seed)
    name = f"synthetic {np.dtype(dtype).name} {shape[1]}x{shape[0]}"
    if dtype == np.uint16:
        base = rng.integers(2000, 14000, size=shape)
        r = base.astype(np.uint16)
        s = np.clip(base + rng.integers(-40, 41, size=shape), 0, 16383).astype(np.uint16)
        return name, r, s, dict(bits=14), 16383.0
    r = rng.normal(300.0, 30.0, size=shape).astype(np.float32)
    s = (r + rng.normal(0, 2.0, size=shape)).astype(np.float32)
    return name, r, s, dict(peak=1000.0), 1000.0


def pairs(which: str) -> list:
    out = []
    if which in ("real", "all"):
        out += [real_pair(name) for name in REAL_FRAMES]
    if which in ("synthetic", "all"):
        out += [synthetic_pair(dtype, shape) for dtype in (np.uint16, np.float32) for shape in ((512, 640), (2048, 2048))]
    return out


def time_pair(r, s, kw, peak):
    """Best times of irfidelity (shared "data" edges, and each frame's own: the scorer's
    default) and of the peers, after checking that they agree."""

    def ours(hist_range="data"):
        st = irf.pair_stats(r, s, bins=256, hist_range=hist_range, **kw)
        ssim = st.ssim()
        return st.mse(), st.psnr(), (ssim.value, ssim.luminance, ssim.contrast, ssim.structure), st.nmi().value

    def peers():
        mse = mean_squared_error(r, s)
        return mse, 10 * math.log10(peak * peak / mse), numpy_ssim(r, s), normalized_mutual_information(r, s, bins=256)

    (mse, psnr, ssim, _), (mse_peer, psnr_peer, ssim_peer, _) = ours(), peers()
    assert math.isclose(mse, mse_peer, rel_tol=1e-9) and math.isclose(psnr, psnr_peer, abs_tol=1e-9)
    assert np.allclose(ssim, ssim_peer, rtol=1e-9, atol=0), (ssim, ssim_peer)
    return (best(ours, args.repeat, CLOCK), best(lambda: ours("each"), args.repeat, CLOCK),
            best(peers, max(2, args.repeat // 3), CLOCK))


def time_evaluate(r, s, kw):
    """Best times of the whole :func:`irfidelity.evaluate` on the pair: unregistered, and
    registered by phase correlation with the simulated frame shifted; and of the verdict's
    defects check alone (None for a build without it)."""
    import warnings

    import scipy.ndimage as ndi

    try:
        from irfidelity.defects import concentrated_error
    except ImportError:
        concentrated_error = None

    shifted = ndi.shift(s.astype(np.float64), (1.4, -2.6), order=3, mode="nearest").round().astype(s.dtype)

    def quiet(fn):
        def run():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return fn()
        return run

    plain = quiet(lambda: irf.evaluate(r, s, **kw))
    registered = quiet(lambda: irf.evaluate(r, shifted, register="translation", register_method="phase", **kw))
    defects = None if concentrated_error is None else best(lambda: concentrated_error(r, s), args.repeat, CLOCK)
    return best(plain, args.repeat, CLOCK), best(registered, args.repeat, CLOCK), defects


def main():
    clock = "CPU time" if CLOCK is time.process_time else "wall time"
    print(f"irfidelity {irf.__version__}; Rust threads = {args.threads} ({clock}); numpy {np.__version__}; "
          f"scikit-image {skimage.__version__}; cores = {os.cpu_count()}")
    print(f"{'pair':<40}{'irfidelity ms':>15}{'peers ms':>12}{'ratio':>9}{'irf ns/px':>11}"
          f"{'each ms':>10}{'ratio':>9}")
    per_px = {}
    for name, r, s, kw, peak in pairs(args.pairs):
        t_ours, t_each, t_peer = time_pair(r, s, kw, peak)
        per_px[name] = t_ours / r.size
        print(f"{name:<40}{t_ours * 1e3:>15.2f}{t_peer * 1e3:>12.1f}{t_peer / t_ours:>8.1f}x{t_ours / r.size * 1e9:>11.2f}"
              f"{t_each * 1e3:>10.2f}{t_peer / t_each:>8.1f}x")
    for name, r, s, kw, _ in pairs("real") if args.pairs in ("real", "all") else []:
        t_plain, t_registered, t_defects = time_evaluate(r, s, kw)
        defects = "" if t_defects is None else f" (of which the defects check {t_defects * 1e3:.2f} ms)"
        print(f"evaluate {name}: unregistered {t_plain * 1e3:.2f} ms{defects}, registered (translation, phase) "
              f"{t_registered * 1e3:.2f} ms")
    for name, r, s, kw, _ in (pairs("real") if args.pairs in ("real", "all") else [])[:1]:
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            # best() calls the lambdas at once, in this iteration (B023 does not apply)
            tiny = best(lambda: irf.evaluate(r[:8, :8].copy(), s[:8, :8].copy(), **kw),  # noqa: B023
                        args.repeat, CLOCK)
        print(f"evaluate an 8x8 crop of {name} (the fixed cost of a call): {tiny * 1e3:.2f} ms")
        warps = []
        for label, frame, order in (("uint16 bicubic", r, 3), ("uint16 bilinear", r, 1),
                                    ("float32 bicubic", r.astype(np.float32), 3)):
            t = best(lambda: _core.warp_frame(frame, SHIFT, order, r.shape), args.repeat, CLOCK)  # noqa: B023
            warps.append(f"{label} {t * 1e3:.2f} ms")
        print(f"resampling {name} by (1.4, -2.6) px (_core.warp_frame):", ", ".join(warps))
    for dtype in ("uint16", "float32"):
        small, large = (per_px.get(f"synthetic {dtype} {size}") for size in ("640x512", "2048x2048"))
        if small and large:
            print(f"linearity {dtype}: time per pixel 2048x2048 / 640x512 = {large / small:.2f} (1.0 = linear)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
