"""Scoring in a temperature unit against scoring counts: per-pair time of ``irf.evaluate``.

    python benches/bench_units.py [--repeat N]

For each radiometric file of tests/data (a FLIR FFF frame and a DJI Zenmuse XT-R R-JPEG, both
640x512 uint16 counts), the simulated frame is the real one with a 1 % gain and noise (σ 8
counts), given once as counts and once as kelvin (its counts through the file's calibration).
The two calls are timed alternately, ``--repeat`` times each:

* counts: ``irf.evaluate(real_file, sim_counts)``;
* kelvin: ``irf.evaluate(real_file, sim_kelvin, unit="K")`` — the real counts converted to
  kelvin, every statistic on float64 temperatures, and the temperature errors (the
  ``radiometry`` component).

Prints the median and best time of each and their ratio, kelvin ÷ counts (issue 38's goal:
≤ 1.3). Both calls also compute the scene transfer and the defects check, as ``evaluate`` does
by default. A benchmark, not a test: numbers depend on the machine (cores, other load).
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings
from pathlib import Path

import numpy as np

import irfidelity as irf

DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "radiometric"
FILES = ("flirpy_frame_000000.fff", "readthermal_zenmuse_xtr.jpg")
GOAL = 1.3  # kelvin ÷ counts
# the files' scenes are what they are (a low PSNR peak, a small scene range): not the point here
warnings.simplefilter("ignore", irf.FidelityWarning)


def alternated(calls: dict, repeat: int) -> dict:
    """Each call's times, taking the calls in turn ``repeat`` times (after one warm-up each), so
    a change of load on the machine falls on all of them."""
    for call in calls.values():
        call()
    times: dict = {name: [] for name in calls}
    for _ in range(repeat):
        for name, call in calls.items():
            start = time.perf_counter()
            call()
            times[name].append(time.perf_counter() - start)
    return times


def timed(path: Path, repeat: int) -> dict:
    """The alternated times of scoring ``path``'s simulated frame as counts and as kelvin."""
    counts = irf.load_frame(path)
    noise = np.random.default_rng(38).normal(0, 8, counts.shape)
    sim_counts = np.clip(np.rint(counts * 1.01 + noise), 0, 65535).astype(counts.dtype)
    sim_kelvin = irf.read_radiometry(path).temperature(sim_counts, unit="K")
    return alternated({"counts": lambda: irf.evaluate(path, sim_counts),
                       "kelvin": lambda: irf.evaluate(path, sim_kelvin, unit="K")}, repeat)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=40, help="timed calls of each (default 40)")
    args = parser.parse_args()
    print(f"irfidelity {irf.__version__}, numpy {np.__version__}; alternated calls, {args.repeat} of each")
    print(f"{'file':32s} {'counts ms':>16s} {'kelvin ms':>16s} {'kelvin/counts':>14s}")
    for name in FILES:
        times = timed(DATA / name, args.repeat)
        median = {k: statistics.median(v) for k, v in times.items()}
        least = {k: min(v) for k, v in times.items()}
        cells = [f"{median[k] * 1e3:6.1f} ({least[k] * 1e3:5.1f})" for k in ("counts", "kelvin")]
        ratio, best_ratio = median["kelvin"] / median["counts"], least["kelvin"] / least["counts"]
        print(f"{name:32s} {cells[0]:>16s} {cells[1]:>16s} {ratio:8.2f} ({best_ratio:.2f})")
    print(f"times: median (best); ratio: of the medians (of the bests); goal ≤ {GOAL}")


if __name__ == "__main__":
    main()
