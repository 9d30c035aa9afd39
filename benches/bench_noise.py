"""3-D noise: irfidelity's streamed decomposition vs numpy (and pyradi, if installed), and the
memory of a long recording streamed from files, in one run.

    python benches/bench_noise.py [--repeat N] [--frames T] [--size WxH] [--stream-frames N]
                                  [--skip-stream]

1. In memory: a ``T × H × W`` uint16 cube (default 100 × 512 × 640; a 3000-count level
   with row, column, fixed-pattern and temporal noise) and its float32 copy. irfidelity's
   ``noise3d(cube, corrected=False, spectra=False)`` (the classical decomposition, all seven
   σ, with the scene checks; its Rust pass ``noise_sums`` alone is shown too) against two numpy implementations of the same decomposition: "numpy parts" forms
   every part as an array and takes its standard deviation (how pyradi's ``ry3dnoise`` and
   most scripts do it), "numpy means" takes the four directional means and the total
   variance and forms the sums of squares from them (fewer passes). Ratios > 1: irfidelity
   is faster. pyradi's ``ry3dnoise`` runs as a third peer when it imports. The largest
   relative difference of the seven σ between irfidelity and numpy is printed too.
2. Streamed: ``--stream-frames`` (default 1000) 16-bit PNG frames of ``W × H`` written to a
   temporary directory; a subprocess runs ``noise3d(directory)`` (spectra included) and
   reports its peak RSS (``VmHWM``, Linux) and that of a subprocess that only imports
   irfidelity and numpy (the baseline). The cube as float64 would take ``8·T·H·W`` bytes.

A benchmark, not a test: numbers depend on the machine (cores, memory bandwidth, load).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

import numpy as np

import irfidelity as irf
from irfidelity.noise import noise_sums

PARTS = ("t", "v", "h", "tv", "th", "vh", "tvh")


def make_cube(frames: int, rows: int, cols: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    cube = np.empty((frames, rows, cols), np.uint16)
    fixed = 3000 + rng.normal(0, 4, (rows, 1)) + rng.normal(0, 2, (1, cols)) + rng.normal(0, 6, (rows, cols))
    for t in range(frames):  # frame by frame: no float64 cube in memory
        frame = fixed + rng.normal(0, 0.5) + rng.normal(0, 1, (rows, 1)) + rng.normal(0, 10, (rows, cols))
        cube[t] = np.round(frame)
    return cube


def numpy_parts(cube: np.ndarray) -> dict[str, float]:
    """Every part as an array, then its (population) standard deviation."""
    u = cube.astype(np.float64)
    u -= u.mean()
    nt = u.mean(axis=(1, 2))
    nv = u.mean(axis=(0, 2))
    nh = u.mean(axis=(0, 1))
    ntv = u.mean(axis=2) - nt[:, None] - nv[None, :]
    nth = u.mean(axis=1) - nt[:, None] - nh[None, :]
    nvh = u.mean(axis=0) - nv[:, None] - nh[None, :]
    u -= nt[:, None, None]
    u -= nv[None, :, None]
    u -= nh[None, None, :]
    u -= ntv[:, :, None]
    u -= nth[:, None, :]
    u -= nvh[None, :, :]
    parts = {"t": nt, "v": nv, "h": nh, "tv": ntv, "th": nth, "vh": nvh, "tvh": u}
    return {k: float(p.std()) for k, p in parts.items()}


def numpy_means(cube: np.ndarray) -> dict[str, float]:
    """Directional means and the total variance; the parts' sums of squares from them."""
    t, v, h = cube.shape
    n = cube.size
    m_tv = cube.mean(axis=2, dtype=np.float64)
    m_th = cube.mean(axis=1, dtype=np.float64)
    m_vh = cube.mean(axis=0, dtype=np.float64)
    m = m_tv.mean()
    m_t, m_v, m_h = m_tv.mean(axis=1), m_tv.mean(axis=0), m_th.mean(axis=0)
    ss = {"t": v * h * ((m_t - m) ** 2).sum(), "v": t * h * ((m_v - m) ** 2).sum(),
          "h": t * v * ((m_h - m) ** 2).sum(),
          "tv": h * ((m_tv - m_t[:, None] - m_v[None, :] + m) ** 2).sum(),
          "th": v * ((m_th - m_t[:, None] - m_h[None, :] + m) ** 2).sum(),
          "vh": t * ((m_vh - m_v[:, None] - m_h[None, :] + m) ** 2).sum()}
    total = cube.var(dtype=np.float64) * n
    ss["tvh"] = total - sum(ss.values())
    return {k: math.sqrt(max(ss[k], 0.0) / n) for k in PARTS}


def irfidelity_classical(cube: np.ndarray) -> dict[str, float]:
    return irf.noise.noise3d(cube, corrected=False, spectra=False, saturated="ignore").sigma


def pyradi_peer():
    try:
        import pyradi.ry3dnoise as ry  # type: ignore[import-not-found]
    except Exception as exc:  # pragma: no cover - benchmark only
        return None, f"{type(exc).__name__}: {exc}"

    def run(cube: np.ndarray) -> dict[str, float]:
        # ry3dnoise uses np.std(ddof=1) of each part; scaled here to population σ for the comparison
        getters = {"t": ry.getNT, "v": ry.getNV, "h": ry.getNH, "tv": ry.getNTV, "th": ry.getNTH,
                   "vh": ry.getNVH, "tvh": ry.getNTVH}
        out = {}
        for k, fn in getters.items():
            s, im = fn(cube)
            out[k] = float(s) * math.sqrt((im.size - 1) / im.size)
        return out

    return run, None


def best_time(fn: Callable[[], object], repeat: int) -> tuple[float, object]:
    out = fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def max_rel(a: dict[str, float], b: dict[str, float]) -> float:
    return max(abs(a[k] - b[k]) / max(abs(b[k]), 1e-300) for k in PARTS)


def in_memory(frames: int, rows: int, cols: int, repeat: int) -> None:
    print(f"\n## in memory: {frames} frames of {cols} x {rows} (best of {repeat})\n")
    cube16 = make_cube(frames, rows, cols)
    pyradi_run, why = pyradi_peer()
    print("| cube | irfidelity | (its Rust pass) | numpy parts | numpy means | numpy means / irfidelity "
          "| numpy parts / irfidelity | max rel. diff of σ | pyradi |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, cube in (("uint16", cube16), ("float32", cube16.astype(np.float32))):
        t_irf, ours = best_time(lambda cube=cube: irfidelity_classical(cube), repeat)
        t_pass, _ = best_time(lambda cube=cube: noise_sums(cube), repeat)
        t_means, means = best_time(lambda cube=cube: numpy_means(cube), repeat)
        t_parts, parts = best_time(lambda cube=cube: numpy_parts(cube), max(1, repeat // 2))
        py = "not installed"
        if pyradi_run is not None:
            t_py, pyv = best_time(lambda cube=cube: pyradi_run(cube), 1)
            py = f"{t_py:.2f} s ({t_py / t_irf:.1f}x), max rel. diff {max_rel(ours, pyv):.1e}"
        print(f"| {name} | {t_irf:.3f} s | {t_pass:.3f} s | {t_parts:.2f} s | {t_means:.2f} s | **{t_means / t_irf:.1f}x** | "
              f"{t_parts / t_irf:.1f}x | {max(max_rel(ours, parts), max_rel(ours, means)):.1e} | {py} |")
    if pyradi_run is None:
        print(f"\npyradi: {why}")


# Peak RSS of this process image: VmHWM (ru_maxrss would include the parent's memory at fork).
PEAK = "int(next(l for l in open('/proc/self/status') if l.startswith('VmHWM')).split()[1])"

STREAM_SCRIPT = f"""
import sys, time
import irfidelity as irf
from irfidelity.noise import noise_sums
t0 = time.perf_counter()
n = irf.noise.noise3d(sys.argv[1], saturated="ignore")
dt = time.perf_counter() - t0
print(n.frames, dt, {PEAK}, n.sigma["tvh"], n.sigma["vh"])
"""

BASELINE_SCRIPT = f"""
import numpy, irfidelity
print({PEAK})
"""


def streamed(frames: int, rows: int, cols: int) -> None:
    cv2 = __import__("cv2")
    print(f"\n## streamed from files: {frames} 16-bit PNG frames of {cols} x {rows}\n")
    with tempfile.TemporaryDirectory() as tmp:
        rng = np.random.default_rng(1)
        fixed = 3000 + rng.normal(0, 6, (rows, cols))
        t0 = time.perf_counter()
        for t in range(frames):
            frame = np.round(fixed + rng.normal(0, 10, (rows, cols))).astype(np.uint16)
            cv2.imwrite(str(Path(tmp) / f"frame_{t:05d}.png"), frame)
        print(f"(wrote the frames in {time.perf_counter() - t0:.0f} s)")
        base = int(subprocess.run([sys.executable, "-c", BASELINE_SCRIPT], capture_output=True, text=True,
                                  check=True).stdout.split()[0])
        runs = []
        for _ in range(2):
            out = subprocess.run([sys.executable, "-c", STREAM_SCRIPT, tmp], capture_output=True, text=True,
                                 check=True).stdout.split()
            runs.append((int(out[0]), float(out[1]), int(out[2]), float(out[3]), float(out[4])))
    cube_mb = 8 * frames * rows * cols / 2**20
    print("| run | frames | time | frames/s | peak RSS | baseline RSS (import only) | σ_tvh | σ_vh |")
    print("|---|---|---|---|---|---|---|---|")
    for i, (n, dt, rss, tvh, vh) in enumerate(runs, 1):
        print(f"| {i} | {n} | {dt:.1f} s | {n / dt:.0f} | **{rss / 1024:.0f} MB** | {base / 1024:.0f} MB | "
              f"{tvh:.3f} | {vh:.3f} |")
    print(f"\n(the same recording as a float64 numpy cube: {cube_mb:.0f} MB)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--size", default="640x512", help="W x H of a frame")
    ap.add_argument("--stream-frames", type=int, default=1000)
    ap.add_argument("--skip-stream", action="store_true")
    args = ap.parse_args(argv)
    cols, rows = (int(v) for v in args.size.lower().split("x"))
    print(f"irfidelity {irf.__version__}, numpy {np.__version__}, python {sys.version.split()[0]}")
    in_memory(args.frames, rows, cols, args.repeat)
    if not args.skip_stream:
        streamed(args.stream_frames, rows, cols)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
