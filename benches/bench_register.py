"""Registration accuracy and speed: irfidelity vs scikit-image and OpenCV on real thermal frames.

Cases: real frames from ``tests/data/thermal`` seen through known transforms, then made to
differ as a simulator would, by one of two simulators (``registration_cases.SIMULATORS``), while
the real frame gets its own noise:

- ``typical``: blurred (σ 0.5–1.2 px, a different MTF), gain (0.7–1.4) and offset (±200)
  changed, noised (5–20 % of the scene's std);
- ``close``: a simulator close to the camera — within 0.5 px of blur, the same grey levels,
  0.2–1 % of the scene's range of noise, whole counts — where misregistration, not the
  simulator, limits PSNR.

Frames:

- ``640×512 Lepton↑``: a 160×120 Lepton frame upscaled ×4 (cubic spline) — smooth at this scale;
- ``640×512 XT-R``: a native 640×512 DJI Zenmuse XT-R frame (lightly smoothed, σ = 0.7 px,
  so that the known transform is exact up to the resampling error of a 5th-order spline);
- ``640×512 Duo Pro R``: a native 640×512 FLIR Duo Pro R frame, a low-contrast scene (116
  counts from coldest to hottest; σ = 0.7 px as above);
- ``160×120 Lepton``: the Lepton frame itself (σ = 0.7 px).

Transforms: shifts up to ±8 px (±4 px at 160×120); rigid adds a rotation within ±3°; similarity
adds a scale within ±2 %. The error of a result is the worst displacement over the four frame
corners between the found and the true map (pixels). Its *PSNR cost* is what it does to the
metrics: the PSNR of the real frame against the simulated one registered by the found map,
minus the same with the true map (both after the least-squares grey-level gain and offset;
the largest absolute difference over the cases, in dB).

Peers: scikit-image ``phase_cross_correlation`` (upsample_factor 10 and 100; and 100 on
Hann-windowed frames) and OpenCV
``phaseCorrelate`` (Hanning window) for translation; OpenCV ``findTransformECC`` (MOTION_EUCLIDEAN
for rigid, MOTION_AFFINE for similarity — ECC has no similarity model — started from
the identity, 100 iterations or 1e-6) for rotation and scale. irfidelity:
``irf.register(method="phase")`` and ``method="auto"``.

Time per call: the best of ``--repeat`` calls. By default everything runs on one thread (the
Rust pool, OpenCV, OpenBLAS/OpenMP behind numpy and scikit-image) and the time is the process's
CPU time — core-for-core ratios that a busy machine disturbs little. ``--threads N`` lets every
library use N threads and measures wall time instead.

``--against PATH``: another build of irfidelity (a checkout whose ``python/irfidelity`` holds its
built extension, such as an older commit) runs in a subprocess, and each irfidelity method is
timed on each case by both builds in turn (the best of ``--rounds`` alternations of ``--repeat``
calls each), so that a busy machine disturbs both alike; the table then gives, per frame and
method, both builds' worst errors and times and the ratio this build ÷ PATH's (median over the
cases, with their range). The peers are not run.

Usage: ``python benches/bench_register.py [--quick] [--repeat R] [--threads N] [--models M,...]
[--simulators S,...] [--docs] [--against PATH [--rounds K]]``.
The table goes to bench-out/registration.md, the error-vs-time figure to
bench-out/registration.png (``--docs``: docs/registration.png). The "Registration" section of
docs/performance.md gives the ranges over several runs of this table.
"""

from __future__ import annotations

import argparse
import itertools
import os
import pathlib
import pickle
import subprocess
import sys
import time


def _threads_from_argv() -> int:
    """``--threads`` must be known before numpy, OpenCV and the Rust pool start their threads."""
    for i, a in enumerate(sys.argv):
        if a == "--threads" and i + 1 < len(sys.argv):
            return int(sys.argv[i + 1])
        if a.startswith("--threads="):
            return int(a.split("=", 1)[1])
    return 1


THREADS = _threads_from_argv()
for var in ("RAYON_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = str(THREADS)

import cv2  # noqa: E402
import numpy as np  # noqa: E402

cv2.setNumThreads(THREADS)
CLOCK = time.process_time if THREADS == 1 else time.perf_counter

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benches"))

from registration_cases import METHODS, SIMULATORS, corner_error, frames, irf_method, run, timed  # noqa: E402


def group(row) -> tuple[str, str, str]:
    """The cases a row was measured on: frame, simulator, model."""
    return row["frame"], row["simulator"], row["model"]


def ratios(rows):
    """Time ratio of each method to ``irfidelity phase`` on the same cases."""
    ref = {group(r): r["time_ms"] for r in rows if r["method"] == "irfidelity phase"}
    return {(*group(r), r["method"]): r["time_ms"] / ref[group(r)] for r in rows}


def table(rows) -> str:
    rat = ratios(rows)
    out = ["| frames | simulator | model | method | worst corner error (px) | median (px) | worst PSNR cost (dB) "
           "| time / call (ms) | time ÷ irfidelity phase |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        err = "failed" if np.isinf(r["worst"]) else f"{r['worst']:.3f}"
        if r["failed"] and not np.isinf(r["median"]):
            err += f" ({r['failed']} failed)"
        cost = "–" if np.isinf(r["psnr_cost"]) else f"{r['psnr_cost']:.3f}"
        out.append(f"| {r['frame']} | {r['simulator']} | {r['model']} | {r['method']} | {err} | {r['median']:.3f} | {cost} "
                   f"| {r['time_ms']:.1f} | {rat[(*group(r), r['method'])]:.2f} |")
    return "\n".join(out)


def figure(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    frames_ = list(dict.fromkeys((r["frame"], r["simulator"]) for r in rows))
    models = list(dict.fromkeys(r["model"] for r in rows))
    fig, axes = plt.subplots(len(frames_), len(models), figsize=(4.2 * len(models), 3.4 * len(frames_)), squeeze=False)
    styles = {"irfidelity phase": ("o", "C0"), "irfidelity auto": ("s", "C1"), "skimage pcc ×10": ("v", "C2"),
              "skimage pcc ×100": ("^", "C3"), "skimage pcc ×100 Hann": ("<", "C7"), "OpenCV phaseCorrelate": ("D", "C4"), "OpenCV ECC euclidean": ("P", "C5"),
              "OpenCV ECC affine": ("X", "C6")}
    for i, (f, simulator) in enumerate(frames_):
        for j, mo in enumerate(models):
            ax = axes[i][j]
            for r in rows:
                if group(r) == (f, simulator, mo):
                    marker, color = styles[r["method"]]
                    worst = r["worst"] if np.isfinite(r["worst"]) else 100.0
                    ax.loglog(r["time_ms"], worst, marker, color=color, label=r["method"], ms=8)
                    ax.loglog(r["time_ms"], max(r["median"], 1e-4), marker, color=color, ms=5, alpha=0.4)
            ax.set_title(f"{f}, {simulator} simulator, {mo}", fontsize=9)
            ax.set_xlabel("time per call (ms)")
            ax.set_ylabel("corner error (px)")
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.yaxis.set_minor_formatter(NullFormatter())
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
    fig.suptitle("Registration: worst corner error (large marker; median faint) against time per call; "
                 "failed = 100 px", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.4 / fig.get_figheight()))  # room for the title
    fig.savefig(path, dpi=72)


def choose(ap, flag: str, given: str, known) -> tuple[str, ...]:
    """The comma-separated names of ``given``, each one of ``known`` (else a usage error)."""
    names = tuple(name for name in given.split(",") if name)
    if not names or set(names) - set(known):
        ap.error(f"{flag}: expected some of {','.join(known)}, got {given!r}")
    return names


#: The other build's side of ``--against``: reads pickled ``(real, sim, model, method, repeat)``
#: from stdin, answers the found matrix (None when refused) and the best time of ``repeat`` calls.
WORKER = r"""
import pickle, sys, time, warnings
sys.path.insert(0, sys.argv[1])
import irfidelity as irf
clock = time.process_time if sys.argv[2] == "cpu" else time.perf_counter
inp, out = sys.stdin.buffer, sys.stdout.buffer
pickle.dump(irf.__file__, out)
out.flush()
while True:
    try:
        real, sim, model, method, repeat = pickle.load(inp)
    except EOFError:
        break
    best, found = float("inf"), None
    for _ in range(repeat):
        t0 = clock()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                found = irf.register(real, sim, model=model, method=method).matrix
            except irf.FidelityError:
                found = None
        best = min(best, clock() - t0)
    pickle.dump((found, best), out)
    out.flush()
"""


class OtherBuild:
    """irfidelity of the checkout ``root``, registering in a subprocess."""

    def __init__(self, root: pathlib.Path):
        package = root.resolve() / "python"
        self.proc = subprocess.Popen([sys.executable, "-c", WORKER, str(package), "cpu" if THREADS == 1 else "wall"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self.location = pickle.load(self.proc.stdout)
        if not self.location.startswith(str(package)):
            raise SystemExit(f"--against {root}: imported irfidelity from {self.location}, not from {package}")

    def timed(self, real, sim, model, method, repeat):
        pickle.dump((real, sim, model, method, repeat), self.proc.stdin)
        self.proc.stdin.flush()
        return pickle.load(self.proc.stdout)

    def close(self):
        self.proc.stdin.close()
        self.proc.wait()


def compare(other: OtherBuild, n: int, repeat: int, rounds: int, models, simulators) -> str:
    """The table of this build against ``other``: per frame, simulator, model and irfidelity
    method, both builds' worst corner errors and median times, and the time ratio."""
    out = [f"this build: {pathlib.Path(__import__('irfidelity').__file__).parent}; against: "
           f"{pathlib.Path(other.location).parent}\n",
           "| frames | simulator | model | method | worst error this / against (px) | time this / against (ms) "
           "| time ratio this ÷ against: median [range over cases] |",
           "|---|---|---|---|---|---|---|"]
    for (fname, scene), simulator, model in itertools.product(frames().items(), simulators, models):
        rng = np.random.default_rng(2026)
        cases = [SIMULATORS[simulator](scene, model, rng) for _ in range(n)]
        for method in ("phase", "auto"):
            fn = irf_method(model, method)
            errs, times, ratios_ = ([], []), ([], []), []
            for real, sim, truth in cases:
                mine, theirs = (None, np.inf), (None, np.inf)
                for _ in range(rounds):  # alternating, so that both see the same load
                    found, t = timed(fn, real, sim, repeat, CLOCK)
                    mine = (found, min(mine[1], t))
                    found, t = other.timed(real, sim, model, method, repeat)
                    theirs = (found, min(theirs[1], t))
                for side, (found, t) in enumerate((mine, theirs)):
                    ok = found is not None and not isinstance(found, Exception)
                    errs[side].append(corner_error(found, truth, real.shape) if ok else np.inf)
                    times[side].append(t)
                ratios_.append(mine[1] / theirs[1])
            row = (f"| {fname} | {simulator} | {model} | irfidelity {method} | {max(errs[0]):.4f} / {max(errs[1]):.4f} "
                   f"| {1e3 * np.median(times[0]):.2f} / {1e3 * np.median(times[1]):.2f} "
                   f"| {np.median(ratios_):.3f} [{min(ratios_):.3f}–{max(ratios_):.3f}] |")
            print(row, flush=True)
            out.append(row)
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="3 cases per frame and model, 1 timing repeat")
    ap.add_argument("--cases", type=int, default=None, help="cases per frame and model (default 8)")
    ap.add_argument("--repeat", type=int, default=None, help="timed calls per case, best kept (default 3; quick 1)")
    ap.add_argument("--threads", type=int, default=1, help="threads for every library (default 1: CPU time, core for core)")
    ap.add_argument("--models", default=",".join(METHODS),
                    help=f"comma-separated models to run (default all: {','.join(METHODS)})")
    ap.add_argument("--simulators", default=",".join(SIMULATORS),
                    help=f"comma-separated simulated-frame kinds (default all: {','.join(SIMULATORS)})")
    ap.add_argument("--docs", action="store_true", help="write the figure to docs/registration.png")
    ap.add_argument("--against", type=pathlib.Path, default=None,
                    help="a checkout with another build of irfidelity: time both builds' methods in turn")
    ap.add_argument("--rounds", type=int, default=3, help="alternations per case with --against (default 3)")
    args = ap.parse_args()
    models = choose(ap, "--models", args.models, METHODS)
    simulators = choose(ap, "--simulators", args.simulators, SIMULATORS)
    n = args.cases or (3 if args.quick else 8)
    repeat = args.repeat or (2 if args.quick else 3)
    if args.against is not None:
        other = OtherBuild(args.against)
        try:
            md = compare(other, n, repeat, args.rounds, models, simulators)
        finally:
            other.close()
        out_dir = ROOT / "bench-out"
        out_dir.mkdir(exist_ok=True)
        (out_dir / "registration-against.md").write_text(md + "\n")
        return 0
    cv2.setRNGSeed(0)
    rows = run(n, repeat, CLOCK, models=models, simulators=simulators)
    md = table(rows)
    print()
    print(md)
    out_dir = ROOT / "bench-out"
    out_dir.mkdir(exist_ok=True)
    figure(rows, (ROOT / "docs" if args.docs else out_dir) / "registration.png")
    import platform

    clock = "CPU time, one thread for every library" if THREADS == 1 else f"wall time, {THREADS} threads per library"
    header = (f"`benches/bench_register.py` ({n} cases per frame and model, best of {repeat} calls, {clock}; "
              f"{platform.machine()}, {platform.processor() or 'cpu'}, Python {platform.python_version()}, "
              f"OpenCV {cv2.__version__}, scikit-image {__import__('skimage').__version__}; "
              f"{time.strftime('%Y-%m-%d')}). Error: worst displacement of a frame corner between the found and "
              f"the true transform. Figure: [registration.png](registration.png).\n\n")
    (out_dir / "registration.md").write_text(header + md + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
