"""Where the default grade boundaries of the image components come from.

The normalised PSNR has boundaries fixed by the paper's scale: f3 = 0.6 / 0.8 / 0.9 are
17.2 / 23.4 / 30 dB (30 dB is the paper's "indistinguishable" anchor). For the other image
components to grade the same degradation alike, each real thermal frame in tests/data is
"simulated" as itself plus white Gaussian noise at those three PSNRs *relative to the scene's
range* (the peak "range": noise σ = range / 10^(dB/20)), and NMI (256 bins) and global SSIM
are measured. The median over frames and seeds of each is that component's boundary.

Usage: ``python benches/calibrate_grades.py [--seeds N]``. Prints a table and the boundaries.
"""

from __future__ import annotations

import argparse
import pathlib
import statistics

import numpy as np

import irfidelity as irf

DATA = pathlib.Path(__file__).resolve().parent.parent / "tests" / "data" / "thermal"
LEVELS_DB = (17.2, 23.4, 30.0)


def frames() -> list[tuple[str, np.ndarray]]:
    out = []
    for path in sorted(DATA.glob("*.png")):
        frame = irf.load_frame(path).astype(np.float64)
        if frame.max() > frame.min():
            out.append((path.name, frame))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    values: dict[tuple[str, float], list[float]] = {}
    print(f"{'frame':<36} {'dB':>5} {'NMI':>7} {'SSIM':>7}")
    for name, real in frames():
        span = real.max() - real.min()
        for db in LEVELS_DB:
            for seed in range(args.seeds):
                noise = np.random.default_rng(seed).normal(0.0, span / 10 ** (db / 20), real.shape)
                sim = real + noise
                nmi, ssim = irf.stats.nmi(real, sim).value, irf.stats.ssim(real, sim).value
                values.setdefault(("nmi", db), []).append(nmi)
                values.setdefault(("ssim", db), []).append(ssim)
                if seed == 0:
                    print(f"{name:<36} {db:>5.1f} {nmi:>7.3f} {ssim:>7.3f}")
    print("\nmedian over frames and seeds (poor|fair, fair|good, good|excellent):")
    for comp in ("nmi", "ssim"):
        cuts = [statistics.median(values[(comp, db)]) for db in LEVELS_DB]
        print(f"  {comp}: " + " / ".join(f"{c:.3f}" for c in cuts))


if __name__ == "__main__":
    main()
