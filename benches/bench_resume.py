"""Resuming a finished sequence run (issue 25): time, CPU and peak memory of the resume
against the fresh run it continues, for a short and a long run.

Workload: N pairs of 32x32 uint16 PNG frames of seeded noise (14-bit), written into a
temporary directory, scored with every image component and ``hist_range="full"``: each
frame's record carries a 256x256 joint histogram (512 kB before packing), which is what a
resume reads, checks and pools; the pixels cost next to nothing.

Each run is a child process (``RAYON_NUM_THREADS=2``; Linux: peak RSS is ``VmHWM``): the fresh run writes the CSV and its
``.pairstats``; the resume of the finished run then takes every record. Printed per N: wall
seconds, CPU ms per frame (user + system: what to compare when other processes share the
machine), peak RSS, and the resume / fresh ratios; and the growth of each run's peak RSS from
the shortest N to the longest.

Usage: ``python benches/bench_resume.py [--frames 100 5000] [--keep DIR]``
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

CHILD = r"""
import json, resource, sys, time
from irfidelity.sequence import score_sequence
t = time.perf_counter()
rep = score_sequence(sys.argv[1], sys.argv[2], bits=14, hist_range="full", progress=False, csv=sys.argv[3],
                     resume=sys.argv[4] == "resume")
usage = resource.getrusage(resource.RUSAGE_SELF)
with open("/proc/self/status") as fh:  # VmHWM: this process's peak RSS (ru_maxrss may keep the parent's)
    peak = next(int(line.split()[1]) / 1024 for line in fh if line.startswith("VmHWM:"))
print(json.dumps({"wall": time.perf_counter() - t, "cpu": usage.ru_utime + usage.ru_stime,
                  "rss_mb": peak, "resumed": rep.run["resumed"]}))
"""


def write_frames(root: pathlib.Path, count: int) -> tuple[pathlib.Path, pathlib.Path]:
    import cv2

    rng = np.random.default_rng(1)
    dirs = root / "real", root / "sim"
    for d in dirs:
        d.mkdir(parents=True, exist_ok=True)
    for i in range(count):
        real = rng.integers(0, 16384, (32, 32), dtype=np.uint16)
        sim = np.clip(real.astype(np.int64) + rng.integers(-40, 40, real.shape), 0, 16383).astype(np.uint16)
        for d, frame in zip(dirs, (real, sim)):
            cv2.imwrite(str(d / f"f{i:05d}.png"), frame)
    return dirs


def run(real: pathlib.Path, sim: pathlib.Path, csv: pathlib.Path, mode: str) -> dict:
    env = {**os.environ, "RAYON_NUM_THREADS": "2"}
    proc = subprocess.run([sys.executable, "-c", CHILD, str(real), str(sim), str(csv), mode], capture_output=True,
                          text=True, env=env, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"{mode} run failed: {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="+", default=[100, 5000])
    parser.add_argument("--keep", type=pathlib.Path, help="write the frames here (and reuse them)")
    args = parser.parse_args()
    base = args.keep or pathlib.Path(tempfile.mkdtemp(prefix="irf_bench_resume_"))
    rows = {}
    print(f"{'frames':>7} {'run':>7} {'wall s':>8} {'CPU ms/frame':>13} {'peak RSS MB':>12} {'sidecar MB':>11}")
    for count in args.frames:
        root = base / f"n{count}"
        real, sim = (root / "real", root / "sim") if (root / "sim").is_dir() else write_frames(root, count)
        csv = root / "rows.csv"
        fresh = run(real, sim, csv, "fresh")
        side_mb = os.path.getsize(str(csv) + ".pairstats") / 1e6
        resumed = run(real, sim, csv, "resume")
        assert resumed["resumed"] == count, resumed
        rows[count] = fresh, resumed
        for name, r in (("fresh", fresh), ("resume", resumed)):
            print(f"{count:>7} {name:>7} {r['wall']:>8.2f} {1e3 * r['cpu'] / count:>13.2f} {r['rss_mb']:>12.1f} "
                  f"{side_mb:>11.2f}")
        print(f"{count:>7} resume / fresh: wall {resumed['wall'] / fresh['wall']:.2f}, "
              f"CPU {resumed['cpu'] / fresh['cpu']:.2f}")
    lo, hi = min(rows), max(rows)
    if lo != hi:
        for k, name in enumerate(("fresh", "resume")):
            print(f"peak RSS growth {lo} -> {hi} frames, {name}: {rows[hi][k]['rss_mb'] - rows[lo][k]['rss_mb']:+.1f} MB")


if __name__ == "__main__":
    main()
