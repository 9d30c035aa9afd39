"""Bar targets: the time to analyse a 640 × 512 frame holding four bar targets, against peers
measured in the same run.

    python benches/bench_bars.py [--repeat N] [--size WxH]

The frame: four 7:1 four-bar targets (0.05, 0.1, 0.2 and 0.3 cy/px; three vertical, one
horizontal) seen through a Gaussian PSF (σ = 0.8 px) and the pixel aperture, 400 counts above
an 8000-count background, with 10 counts of noise, as uint16 (rendered once, not timed).

Timed, best of ``--repeat`` after a warm-up:

* **irfidelity** ``ctf_curve(frame, frequencies=[...])``: find the four targets in the frame,
  read each (bar modulation, fundamental ratio, SNR) — the whole analysis (target: ≤ 10 ms);
* the same with the targets' ROIs given (no search);
* **numpy, hand-rolled**: what a spreadsheet-style script does with the ROIs given — per
  target, the profile across the bars averaged over the central rows and its
  (max − min)/(max + min) after subtracting the background median of the ROI's border (no
  sub-pixel centre lines, no fundamental, no checks);
* **irfidelity slanted edge** ``mtf_from_edge`` on one 128 × 128 edge ROI (the other MTF
  measurement of the same camera), for scale.

Wall and CPU time (``time.process_time``: the machine's other processes inflate it less) are
printed, and each run's CPU time against the whole analysis's. The measured CTFs and fundamental ratios are printed with
the analytic system MTF ``exp(-2π²σ²f²) sinc(f)``. A benchmark, not a test: numbers depend on
the machine (cores, load).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one core: the analysis is serial
    os.environ[_var] = "1"

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

from _common import best  # noqa: E402
from irfidelity.curves import ctf_curve, mtf_from_edge  # noqa: E402
from irfidelity.targets import four_bar, gaussian_otf, slanted_edge  # noqa: E402

FREQUENCIES = (0.05, 0.1, 0.2, 0.3)
SIGMA = 0.8


def make_frame(width: int, height: int) -> np.ndarray:
    otf = gaussian_otf(SIGMA)
    places = ((0.25, 0.25, "vertical"), (0.25, 0.75, "horizontal"), (0.75, 0.25, "vertical"), (0.75, 0.75, "vertical"))
    frame = np.zeros((height, width))
    for f, (row, col, orientation) in zip(FREQUENCIES, places):
        frame += four_bar(f, (height, width), centre=(row * height, col * width), orientation=orientation, otf=otf,
                          levels=(0.0, 400.0))
    rng = np.random.default_rng(0)
    return np.round(frame + 8000 + rng.normal(0, 10, frame.shape)).astype(np.uint16)


def hand_rolled(frame: np.ndarray, rois: list[tuple[int, int, int, int]], orientations: list[str]) -> list[float]:
    out = []
    for (r0, r1, c0, c1), orientation in zip(rois, orientations):
        region = frame[r0:r1, c0:c1].astype(np.float64)
        if orientation == "horizontal":
            region = region.T
        border = np.concatenate((region[0], region[-1], region[:, 0], region[:, -1]))
        rows = region.shape[0]
        profile = region[int(0.3 * rows):int(0.7 * rows)].mean(axis=0) - np.median(border)
        inner = profile[profile.size // 4: 3 * profile.size // 4]
        out.append(float((inner.max() - inner.min()) / (inner.max() + inner.min())))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=50)
    parser.add_argument("--size", default="640x512")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))
    frame = make_frame(width, height)
    edge = np.round(slanted_edge((128, 128), angle=5.0, otf=gaussian_otf(SIGMA), levels=(8000, 8400))).astype(np.uint16)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the 0.3 cy/px bars are 1.7 px wide: the modulation warns
        curve = ctf_curve(frame, frequencies=FREQUENCIES)
        readings = curve.meta["readings"]
        rois = [r.roi for r in readings]
        sides = [r.orientation for r in readings]
        runs = {"irfidelity ctf_curve (targets found)": lambda: ctf_curve(frame, frequencies=FREQUENCIES),
                "irfidelity ctf_curve (ROIs given)": lambda: ctf_curve(frame, frequencies=FREQUENCIES, rois=rois),
                "numpy hand-rolled max/min (ROIs given)": lambda: hand_rolled(frame, rois, sides),
                "irfidelity mtf_from_edge (128 x 128)": lambda: mtf_from_edge(edge)}
        wall = {name: best(fn, args.repeat) for name, fn in runs.items()}
        cpu = {name: best(fn, args.repeat, clock=time.process_time) for name, fn in runs.items()}

    print(f"frame {width} x {height} uint16, four targets at {', '.join(f'{f:g}' for f in FREQUENCIES)} cy/px, "
          f"Gaussian PSF sigma {SIGMA} px, noise 10 counts on 400; best of {args.repeat}, one thread")
    print(f"{'':42s}{'wall ms':>9s}{'cpu ms':>9s}{'ratio':>8s}   (ratio: its CPU time / the analysis's)")
    found = cpu["irfidelity ctf_curve (targets found)"]
    for name in runs:
        print(f"{name:42s}{1e3 * wall[name]:9.2f}{1e3 * cpu[name]:9.2f}{cpu[name] / found:8.2f}")
    print("target: the whole analysis (targets found) within 10 ms of CPU:", "yes" if found <= 0.010 else "NO")
    naive = hand_rolled(frame, rois, sides)
    print(f"\n{'f cy/px':>8s}{'orient':>12s}{'CTF':>8s}{'numpy':>8s}{'fund.':>8s}{'MTF':>8s}")
    for r, n in zip(readings, naive):
        truth = math.exp(-2 * math.pi ** 2 * SIGMA ** 2 * r.frequency ** 2) * np.sinc(r.frequency)
        print(f"{r.frequency:8.3g}{r.orientation:>12s}{r.ctf:8.3f}{n:8.3f}{r.mtf:8.3f}{truth:8.3f}")


if __name__ == "__main__":
    main()
