"""The pair as a system: how well ``irf.transfer`` recovers a known simulator, and what it costs.

    python benches/transfer.py [--repeat N] [--noise F] [--seed S] [--figure PATH]

1. Accuracy. Five real thermal frames shipped in tests/data (DJI Zenmuse XT-R 640×512,
   FLIR Duo Pro R 640×512, FLIR radiometric JPEG 240×320, FLIR FFF 320×240, FLIR Lepton
   160×120) are the scenes. For each, the real frame is the scene plus white noise of σ =
   ``--noise`` × the scene's standard deviation (default 0.02), a second real frame the
   scene plus another draw of it (``real_ref``: the real noise known), and a simulated
   frame the scene through a known simulator: Gaussian blur of σ_b px, a gain, an offset,
   its own white noise (a multiple of the real σ) and, in one case, a fixed column pattern.
   Printed: the largest error of the MTF ratio against the truth ``exp(−2π²σ_b²f²)`` over
   0.05–0.2 cy/px within the trusted band (and without ``real_ref``), the gain's error, the
   noise ratio's error. Goals (the issue): MTF ratio within 0.05, gain within 0.5 %, noise
   ratio within 10 %.
2. Time on the 640×512 pair: ``irf.transfer`` against ``irf.pair_stats`` (all statistics)
   in the same run, alternated, best of ``--repeat`` (CPU time): the goal is within 4×.

3. ``--figure PATH``: the MTF ratio against frequency for three simulators of the DJI scene,
   with and without a second real frame, the truth and the trusted band (docs/transfer.png).

A benchmark, not a test: the noise draws and the machine decide the last digits.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np
from scipy import ndimage

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from _common import best

import irfidelity as irf

DATA = pathlib.Path(__file__).resolve().parents[1] / "tests" / "data"

#: (name, file, page) of the scenes.
SCENES = [("DJI XT-R 640×512", "thermal/readthermal_zenmuse_xtr_raw16.png", None),
          ("FLIR Duo Pro R 640×512", "thermal/flirpy_frame_000000_raw16.png", None),
          ("FLIR JPEG 240×320", "radiometric/readthermal_flir_example_raw16.png", None),
          ("FLIR FFF 320×240", "radiometric/flirpy_frame_000000_le_raw16.png", None),
          ("FLIR Lepton 160×120", "thermal/cptv_v2_all100frames_uint16.tif", 30)]

#: Simulators: (name, blur σ px, gain, offset × std, noise × real σ, column pattern × std).
CASES = [("perfect", 0.0, 1.0, 0.0, 1.0, 0.0), ("blur 0.7", 0.7, 1.0, 0.01, 1.0, 0.0),
         ("blur 1.5, gain 1.15", 1.5, 1.15, 0.02, 2.0, 0.0), ("blur 1, gain 0.9", 1.0, 0.9, -0.05, 0.5, 0.0),
         ("gain 1.02, noise ×3", 0.0, 1.02, 0.0, 3.0, 0.0), ("blur 1, column pattern", 1.0, 1.0, 0.0, 1.0, 0.05)]


def scene(file: str, page: int | None) -> np.ndarray:
    if page is None:
        return irf.load_frame(DATA / file).astype(np.float64)
    import tifffile

    return tifffile.imread(DATA / file)[page].astype(np.float64)


def measure(frame: np.ndarray, case: tuple, noise: float, rng: np.random.Generator) -> dict:
    _, blur, gain, offset, sim_noise, pattern = case
    sd = float(frame.std())
    sigma = noise * sd
    real = frame + rng.normal(0, sigma, frame.shape)
    ref = frame + rng.normal(0, sigma, frame.shape)
    sim = gain * (ndimage.gaussian_filter(frame, blur) if blur else frame) + offset * sd
    sim = sim + rng.normal(0, sim_noise * sigma, frame.shape) + pattern * sd * rng.standard_normal(frame.shape[1])
    out = {}
    for mode, kwargs in (("real_ref", {"real_ref": ref}), ("unknown", {})):
        t = irf.transfer(real, sim, **kwargs)
        truth = np.exp(-2 * np.pi ** 2 * blur ** 2 * t.frequency ** 2)
        inside = (t.frequency >= 0.05) & (t.frequency <= 0.2)
        if t.band is not None:
            inside &= (t.frequency >= t.band[0]) & (t.frequency <= t.band[1])
        out[mode] = {"mtf": float(np.max(np.abs(t.mtf_ratio[inside] - truth[inside]))) if inside.any() else None,
                     "gain": None if t.gain is None else 100 * (t.gain / gain - 1),
                     "noise": None if t.noise_ratio is None or pattern else 100 * (t.noise_ratio / sim_noise - 1),
                     "band": t.band}
    return out


def accuracy(noise: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    print(f"accuracy: real noise σ = {noise:g} × the scene's std; errors in the trusted band, 0.05–0.2 cy/px")
    print(f"{'scene':<24} {'simulator':<24} {'MTF err':>8} {'(no ref)':>8} {'gain %':>8} {'noise %':>8} band (cy/px)")
    worst = {"mtf": 0.0, "gain": 0.0, "noise": 0.0}
    for name, file, page in SCENES:
        frame = scene(file, page)
        for case in CASES:
            m = measure(frame, case, noise, rng)
            ref, alone = m["real_ref"], m["unknown"]
            for k in worst:
                if ref[k] is not None:
                    worst[k] = max(worst[k], abs(ref[k]))
            fmt = lambda v, f: "-" if v is None else format(v, f)  # noqa: E731
            band = "-" if ref["band"] is None else f"{ref['band'][0]:.3f}–{ref['band'][1]:.3f}"
            print(f"{name:<24} {case[0]:<24} {fmt(ref['mtf'], '8.3f')} {fmt(alone['mtf'], '8.3f')} "
                  f"{fmt(ref['gain'], '+8.2f')} {fmt(ref['noise'], '+8.1f')} {band}")
    print(f"worst with real_ref: MTF ratio {worst['mtf']:.3f} (goal 0.05), gain {worst['gain']:.2f} % (goal 0.5 %), "
          f"noise ratio {worst['noise']:.1f} % (goal 10 %)")


def timing(repeat: int) -> None:
    real = irf.load_frame(DATA / "thermal/readthermal_zenmuse_xtr_raw16.png")
    sim = np.clip(ndimage.gaussian_filter(real.astype(np.float64), 1.0) * 1.05, 0, 65535).astype(np.uint16)
    ratios = []
    for _ in range(3):  # alternated
        stats = best(lambda: irf.pair_stats(real, sim, bits=16), repeat, time.process_time)
        transfer = best(lambda: irf.transfer(real, sim), repeat, time.process_time)
        ratios.append(transfer / stats)
        print(f"640×512 uint16, CPU time: pair_stats {1e3 * stats:.2f} ms, transfer {1e3 * transfer:.2f} ms "
              f"({transfer / stats:.2f}× pair_stats)")
    print(f"transfer / pair_stats: {min(ratios):.2f}–{max(ratios):.2f}× (goal ≤ 4×)")


def figure(path: str, noise: float, seed: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(seed)
    frame = scene(*SCENES[0][1:])
    sd = float(frame.std())
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, with_ref in zip(axes, (True, False)):
        for blur, colour in ((0.0, "tab:green"), (0.7, "tab:blue"), (1.5, "tab:red")):
            real = frame + rng.normal(0, noise * sd, frame.shape)
            ref = frame + rng.normal(0, noise * sd, frame.shape)
            sim = (ndimage.gaussian_filter(frame, blur) if blur else frame) + rng.normal(0, noise * sd, frame.shape)
            t = irf.transfer(real, sim, real_ref=ref if with_ref else None)
            ax.errorbar(t.frequency, t.mtf_ratio, yerr=t.mtf_ratio_err, fmt=".", color=colour, ms=4,
                        label=f"blur σ {blur} px: MTF50 mismatch {100 * (t.mtf50_mismatch or 0):.0f} %")
            ax.plot(t.frequency, np.exp(-2 * np.pi ** 2 * blur ** 2 * t.frequency ** 2), color=colour, lw=1)
            if t.band is not None:
                ax.axvspan(t.band[1], 0.5, color="0.9", zorder=0)
        ax.axvline(t.reference_frequency, color="0.5", ls=":", lw=1)
        ax.set_xlabel("frequency (cy/px)")
        ax.set_title("real noise known (real_ref)" if with_ref else "real noise unknown (one pair)")
        ax.set_ylim(-0.05, 1.2)
        ax.legend(fontsize=8, loc="lower left")
    axes[0].set_ylabel("MTF ratio, simulated / real")
    fig.suptitle("irf.transfer on the DJI XT-R frame: points estimated, lines the truth; grey beyond the band")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"figure written to {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--noise", type=float, default=0.02)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--figure", help="write the MTF-ratio figure to this PNG and stop")
    args = parser.parse_args()
    if args.figure:
        figure(args.figure, args.noise, args.seed)
        return
    accuracy(args.noise, args.seed)
    timing(args.repeat)


if __name__ == "__main__":
    main()
