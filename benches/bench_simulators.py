"""Several simulators in one pass (issue 29): the cost of ``irf.score_simulators`` with three
simulators against three separate ``irf.score_sequence`` runs, in the same run.

Workload (generated into a temporary directory from the real Lepton recording in
tests/data/thermal, upscaled to 640x480 with cubic interpolation): a real sequence of 16-bit
grayscale PNGs and three simulated ones (Gaussian blur 0.5 / 1.0 / 1.5 px and Gaussian noise
4 / 8 / 12 counts), all image components (PSNR, NMI with 256 bins, global SSIM).

Printed, each the best of ``--repeat`` runs after a warm-up, wall and CPU time:

* ``one``: ``score_sequence(real, sim_A)``;
* ``three separate``: the three ``score_sequence`` runs one after the other;
* ``shared``: ``score_simulators(real, {A, B, C}, resamples=99)`` — the scoring pass, and the
  ranking's bootstrap timed apart (``compare_reports`` on the same reports);
* the CPU of the ranking (2000 resamples) of three simulators over 1000 frames, and of one
  report's ``ci``;
* the ratio ``shared scoring / (3 × one)`` (target ≤ 0.75) and the floor that sharing the
  real side's decode allows: ``(3 × one − 2 × decode) / (3 × one)``, with ``decode`` half the
  time the engine takes to score every real frame against itself (sum of squared errors
  only: two decodes and almost nothing else) on the same number of threads.

Usage: ``python benches/bench_simulators.py [--frames N] [--repeat R] [--workers W] [--weights W|default]``
(default 100 frames, 2 repeats, all cores). CPU time is what to compare when other processes
share the machine; the ranking at the end uses the default 2000 resamples.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time
import warnings

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _common import best  # noqa: E402

import irfidelity as irf  # noqa: E402
from irfidelity import _core  # noqa: E402
from irfidelity.sequence.plan import SequenceRequest  # noqa: E402
from irfidelity.simulators import compare_reports  # noqa: E402
from irfidelity.stats import PairRequest  # noqa: E402

STACK = HERE.parent / "tests" / "data" / "thermal" / "cptv_v2_all100frames_uint16.tif"
ROWS, COLS = 480, 640
SIMULATORS = {"A": (0.5, 4.0), "B": (1.0, 8.0), "C": (1.5, 12.0)}  # blur (px), noise (counts)
WEIGHTS = "psnr=0.4,nmi=0.2,ssim=0.4"


def write_workload(root: pathlib.Path, frames: int) -> dict:
    import cv2
    import tifffile

    stack = tifffile.imread(STACK)
    rng = np.random.default_rng(29)
    dirs = {name: root / name for name in ("real", *SIMULATORS)}
    for d in dirs.values():
        d.mkdir()
    for i in range(frames):
        real = cv2.resize(stack[i % len(stack)].astype(np.float32), (COLS, ROWS), interpolation=cv2.INTER_CUBIC)
        cv2.imwrite(str(dirs["real"] / f"f{i:05d}.png"), np.clip(np.rint(real), 0, 16383).astype(np.uint16))
        for name, (blur, sigma) in SIMULATORS.items():
            sim = cv2.GaussianBlur(real, (0, 0), blur) + rng.normal(0, sigma, real.shape)
            cv2.imwrite(str(dirs[name] / f"f{i:05d}.png"), np.clip(np.rint(sim), 0, 16383).astype(np.uint16))
    return {name: str(d) for name, d in dirs.items()}


def decode_twice(paths: list[str], workers: int) -> None:
    """The engine decoding every real frame twice (each against itself), with the cheapest
    statistic (the sum of squared errors): half of it is the real side's decode."""
    request = SequenceRequest(pair=PairRequest(sse=True, moments=False, bins=None))
    _core.score_pairs(paths, paths, request=request, workers=workers)


def ranking_cost(frames: int = 1000) -> None:
    """CPU of the ranking (2000 resamples) and of one report's ``ci`` on ``frames`` small frames
    of three simulators (the bootstrap's cost grows with frames and simulators, not pixels)."""
    from irfidelity.sequence.intervals import sequence_intervals

    rng = np.random.default_rng(1)
    real = rng.integers(1000, 3000, (frames, 16, 16)).astype(np.uint16)
    sims = {k: (real + rng.integers(0, 5 * (i + 1), real.shape)).astype(np.uint16) for i, k in enumerate("ABC")}
    reports = irf.score_simulators(real, sims, peak="range", weights=WEIGHTS, progress=False, resamples=99).reports
    rank = best(lambda: compare_reports(reports), 1, time.process_time)
    ci = best(lambda: sequence_intervals(reports["A"]), 1, time.process_time)
    print(f"CPU: ranking 3 simulators x {frames} frames, 2000 resamples {rank:.3f} s; one report's ci {ci:.3f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--weights", default=WEIGHTS, help=f"the scoring weights (default {WEIGHTS}; "
                        "'default' for the scorer's, with mtf and sitf from the scene)")
    args = parser.parse_args()
    warnings.simplefilter("ignore", irf.FidelityWarning)
    options = dict(bits=14, progress=False, workers=args.workers)
    if args.weights != "default":
        options["weights"] = args.weights
    with tempfile.TemporaryDirectory() as tmp:
        dirs = write_workload(pathlib.Path(tmp), args.frames)
        sims = {name: dirs[name] for name in SIMULATORS}
        real_paths = sorted(str(p) for p in pathlib.Path(dirs["real"]).iterdir())
        results = {}
        for clock, label in ((time.perf_counter, "wall"), (time.process_time, "CPU")):
            one = best(lambda: irf.score_sequence(dirs["real"], sims["A"], **options), args.repeat, clock)
            separate = best(lambda: [irf.score_sequence(dirs["real"], s, **options) for s in sims.values()],
                            args.repeat, clock)
            shared_total = best(lambda: results.__setitem__(
                "shared", irf.score_simulators(dirs["real"], sims, resamples=99, **options)), args.repeat, clock)
            ranking = best(lambda: compare_reports(results["shared"].reports, resamples=99), args.repeat, clock)
            decode = best(lambda: decode_twice(real_paths, args.workers), args.repeat, clock) / 2
            shared = shared_total - ranking
            floor = (3 * one - 2 * decode) / (3 * one)
            print(f"{label}: {args.frames} frames of {COLS}x{ROWS} 16-bit PNG, {args.workers} workers")
            print(f"  one simulator            {one:7.3f} s")
            print(f"  three separate runs      {separate:7.3f} s  ({separate / (3 * one):.2f} x 3 x one)")
            print(f"  shared: scoring          {shared:7.3f} s  ({shared / (3 * one):.2f} x 3 x one; target <= 0.75)")
            print(f"  shared: ranking (99 res.) {ranking:6.3f} s")
            print(f"  real frames decoded alone {decode:6.3f} s  -> floor of sharing the decode: {floor:.2f}")
        print(compare_reports(results["shared"].reports).summary_text())
    ranking_cost()


if __name__ == "__main__":
    main()
