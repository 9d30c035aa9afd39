"""Where the default NMI and SSIM tolerances (fractions of the ceiling) come from.

For each real recording in tests/data, frames t and t + 1 are the camera against itself (the
ceiling). A simulator whose only fault is temporal noise q times the camera's is frame t + 1
plus independent white noise of σ·sqrt(q² − 1) (σ, the camera's temporal noise, from the
difference of the two frames: std(t + 1 − t)/√2). Its NMI and SSIM against frame t, divided by
the ceiling's, are printed for q = 1.1, 1.25, 2, 3 — the noise-ratio limits of excellent, good
and fair and a step beyond — as medians over frames 0, 10, ..., 80. The defaults of
``Tolerances.nmi`` and ``Tolerances.ssim`` follow the most sensitive recording, so that such a
simulator grades alike on NMI, SSIM and the noise ratio (docs/interpretation.md).

Usage: ``python benches/calibrate_tolerances.py`` (about ten seconds).
"""

from __future__ import annotations

import pathlib

import numpy as np

import irfidelity as irf
from irfidelity.ceiling import pair_ceiling

DATA = pathlib.Path(__file__).resolve().parent.parent / "tests" / "data" / "thermal"
RECORDINGS = ("cptv_v2_all100frames_uint16.tif", "ptw_lwir_all100frames_uint16.tif",
              "ptw_mwir_all100frames_uint16.tif")
RATIOS = (1.1, 1.25, 2.0, 3.0)


def relative(real: np.ndarray, successor: np.ndarray, q: float, rng: np.random.Generator) -> tuple[float, float]:
    """(NMI, SSIM) of a simulator with q times the camera's noise, as fractions of the ceiling."""
    sigma = float(np.std(successor - real)) / np.sqrt(2)
    config = irf.ScoringConfig(peak=float(real.max() - real.min()))
    ceiling = pair_ceiling(real, successor, ("nmi", "ssim"), config)
    sim = successor + rng.normal(0, sigma * np.sqrt(q * q - 1), real.shape)
    value = pair_ceiling(real, sim, ("nmi", "ssim"), config)
    return value["nmi"] / ceiling["nmi"], value["ssim"] / ceiling["ssim"]


def main() -> None:
    rng = np.random.default_rng(0)
    print(f"{'recording':<36} {'q':>5} {'NMI/ceiling':>12} {'SSIM/ceiling':>13}")
    for name in RECORDINGS:
        frames = irf.FrameSequence(DATA / name)
        for q in RATIOS:
            values = [relative(frames[t].astype(np.float64), frames[t + 1].astype(np.float64), q, rng)
                      for t in range(0, 90, 10)]
            nmi, ssim = np.median(np.array(values), axis=0)
            print(f"{name:<36} {q:>5g} {nmi:>12.3f} {ssim:>13.3f}")


if __name__ == "__main__":
    main()
