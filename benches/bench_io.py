"""Decode throughput of irfidelity vs OpenEXR (C++), tifffile and OpenCV, in one run.

    python benches/bench_io.py [--repeat N] [--size WxH] [--one-core]

Prints MB/s of decoded pixels and frames/s for each decoder on the same files, and the
ratio irfidelity / other (> 1: irfidelity is faster). Test files are built in a temporary
directory from the real thermal frames in tests/data (tiled up to --size with a little
noise so the codecs have realistic work): a 16-bit PNG, float16 and float32 single-channel
EXRs in ZIP and PIZ, plus the real 100-page deflate TIFF. By default irfidelity decodes an EXR
frame's blocks on every core (the OpenEXR Python binding uses one); ``--one-core`` pins the
whole process to one CPU with one decoding thread, for a core-for-core comparison. A benchmark,
not a test: numbers depend on the machine (cores, CPU).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")

import numpy as np

from irfidelity.frames import load_frame, page_count

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"


def optional(name: str):
    try:
        return __import__(name)
    except Exception:  # pragma: no cover - benchmark only
        return None


OpenEXR = optional("OpenEXR")
tifffile = optional("tifffile")
cv2 = optional("cv2")


def best_time(fn: Callable[[], object], repeat: int) -> float:
    out = fn()  # warm up (page cache, thread pools)
    if out is None or (isinstance(out, tuple) and not out[0]):
        # cv2.imread returns None (imreadmulti (False, ...)) when a codec is disabled
        raise RuntimeError("decoder returned no image (codec disabled in this build?)")
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times) if repeat < 5 else statistics.median(sorted(times)[: max(3, repeat // 2)])


def make_inputs(tmp: Path, width: int, height: int) -> list[dict]:
    base = load_frame(DATA / "thermal/cptv_v2_frame000.png").astype(np.float64)
    reps = (-(-height // base.shape[0]), -(-width // base.shape[1]))
    rng = np.random.default_rng(1)
    counts = np.tile(base, reps)[:height, :width] + rng.normal(0, 2, (height, width))
    counts16 = np.clip(counts, 0, 65535).astype(np.uint16)
    cases: list[dict] = []

    png_path = tmp / "frame16.png"
    if cv2 is not None:
        cv2.imwrite(str(png_path), counts16)
    else:
        import png as pypng

        with open(png_path, "wb") as fh:
            pypng.Writer(width, height, greyscale=True, bitdepth=16).write(fh, counts16.tolist())
    cases.append({"name": f"PNG 16-bit {width}x{height}", "path": png_path, "kind": "png", "frames": 1})

    if OpenEXR is not None:
        for dtype, scale in ((np.float16, 1 / 1000), (np.float32, 1.0)):
            for comp in ("ZIP", "PIZ"):
                p = tmp / f"frame_{np.dtype(dtype).name}_{comp}.exr"
                data = (counts * scale).astype(dtype)
                OpenEXR.File({"compression": getattr(OpenEXR, f"{comp}_COMPRESSION")}, {"Y": data}).write(str(p))
                cases.append({"name": f"EXR {np.dtype(dtype).name} {comp} {width}x{height}", "path": p, "kind": "exr", "frames": 1})

    tif = DATA / "thermal/cptv_v2_all100frames_uint16.tif"
    cases.append({"name": "TIFF deflate 100 pages 160x120", "path": tif, "kind": "tiff", "frames": page_count(tif)})
    return cases


def decoders(case: dict) -> dict[str, Callable[[], object]]:
    path, kind, n = str(case["path"]), case["kind"], case["frames"]
    out: dict[str, Callable[[], object]] = {}
    if kind == "tiff":
        out["irfidelity"] = lambda: [load_frame(path, page=i) for i in range(n)]
        if tifffile is not None:
            out["tifffile"] = lambda: tifffile.imread(path, key=range(n))
        if cv2 is not None:
            out["opencv"] = lambda: cv2.imreadmulti(path, flags=cv2.IMREAD_UNCHANGED)
        return out
    out["irfidelity"] = lambda: load_frame(path)
    if kind == "exr" and OpenEXR is not None:

        def openexr_read() -> np.ndarray:
            with OpenEXR.File(path, separate_channels=True) as f:
                return f.channels()["Y"].pixels

        out["OpenEXR"] = openexr_read
    if kind == "png":
        pypng = optional("png")
        if pypng is not None:
            out["pypng"] = lambda: np.vstack(list(pypng.Reader(filename=path).read()[2]))
    if cv2 is not None:
        out["opencv"] = lambda: cv2.imread(path, cv2.IMREAD_UNCHANGED)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--size", default="1920x1080", help="WxH of the generated PNG/EXR frames")
    ap.add_argument("--one-core", action="store_true", help="one CPU, one decoding thread for everyone")
    args = ap.parse_args(argv)
    if args.one_core:
        # before the first decode builds irfidelity's (rayon) thread pool
        os.environ["RAYON_NUM_THREADS"] = "1"
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
        if cv2 is not None:
            cv2.setNumThreads(1)
    width, height = (int(v) for v in args.size.lower().split("x"))
    print(f"# {os.cpu_count()} CPUs, python {sys.version.split()[0]}, numpy {np.__version__}")
    print(f"# OpenEXR {getattr(OpenEXR, '__version__', '-')}, tifffile {getattr(tifffile, '__version__', '-')}, "
          f"opencv {getattr(cv2, '__version__', '-')}")
    with tempfile.TemporaryDirectory() as d:
        cases = make_inputs(Path(d), width, height)
        header = f"{'file':36s} {'decoder':11s} {'MB/s':>9s} {'frames/s':>10s} {'irfidelity/this':>16s}"
        print(header)
        print("-" * len(header))
        for case in cases:
            first = load_frame(case["path"])
            nbytes = first.nbytes * case["frames"]
            speeds: dict[str, float] = {}
            for name, fn in decoders(case).items():
                try:
                    t = best_time(fn, args.repeat)
                except Exception as e:  # a reference decoder lacking a codec
                    print(f"{case['name']:36s} {name:11s} failed: {type(e).__name__}: {e}")
                    continue
                speeds[name] = nbytes / t / 1e6
                fps = case["frames"] / t
                ratio = speeds["irfidelity"] / speeds[name] if "irfidelity" in speeds else float("nan")
                print(f"{case['name']:36s} {name:11s} {speeds[name]:9.1f} {fps:10.1f} {ratio:16.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
