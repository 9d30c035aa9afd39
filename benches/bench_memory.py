"""Peak memory of each operation with the default memory budget (docs/design.md §14).

    python benches/bench_memory.py [--sizes 640x512,8192x8192] [--workers 2]

Each operation runs in a fresh child process on two uint16 frames (a smooth random scene and
a shifted copy, in memory; PNG files for decoding and the 3-D noise of 8 frames) and prints
the child's peak RSS (its high-water mark ``VmHWM``: interpreter, frames and operation — the
same as ``ru_maxrss`` except that ``ru_maxrss`` of a child also counts its parent's memory
at the fork), the operation's own peak above what the child held before it (the high-water
mark reset through ``/proc/self/clear_refs``; Linux), and what happened: ``ok``, or the
library's refusal (over the budget, before allocating). With the
default 2 GiB budget an 8192 x 8192 registration and its 3-D noise are refused; the others
take their bounded paths. A benchmark, not a test: numbers depend on the machine (threads,
allocator).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

CHILD = r"""
import json, sys
job = json.loads(sys.argv[1])
import numpy as np, irfidelity as irf

def status(key):
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith(key))

def start():  # the resident size now, with the high-water mark reset to it (Linux clear_refs)
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    return status("VmRSS:")

rows, cols = job["shape"]
real = sim = None
if job["op"] in ("register", "evaluate", "evaluate registered", "ssim_map", "to_html"):
    real, sim = np.load(job["real"]), np.load(job["sim"])
peak = status("VmHWM:")
before = start()
out = {"status": "ok"}
try:
    if job["op"] == "decode":
        irf.load_frame(job["png"][0])
    elif job["op"] == "register":
        irf.register(real, sim)
    elif job["op"] == "evaluate":
        irf.evaluate(real, sim)
    elif job["op"] == "evaluate registered":
        irf.evaluate(real, sim, register="translation")
    elif job["op"] == "ssim_map":
        irf.maps.ssim_map(real, sim)
    elif job["op"] == "noise3d (8 frames)":
        irf.noise.noise3d(job["png"], workers=job["workers"])
    elif job["op"] == "to_html":
        report = irf.evaluate(real, sim)
        peak = max(peak, status("VmHWM:"))
        before = start()
        report.to_html()
except irf.errors.FidelityError as exc:
    out["status"] = "refused: " + type(exc).__name__
out.update(peak=max(peak, status("VmHWM:")), added=status("VmHWM:") - before)
print(json.dumps(out))
"""

OPS = ["decode", "register", "evaluate", "evaluate registered", "ssim_map", "noise3d (8 frames)", "to_html"]


def scene(rows: int, cols: int, shift: tuple[int, int] = (2, -3)) -> tuple[np.ndarray, np.ndarray]:
    """A smooth random uint16 scene (bilinear upsampling of a coarse grid, plus noise) and a shifted copy."""
    rng = np.random.default_rng(0)
    grid = rng.random((rows // 16 + 3, cols // 16 + 3))
    y = np.arange(rows + 16) / 16.0
    x = np.arange(cols + 16) / 16.0
    gy, gx = np.floor(y).astype(int), np.floor(x).astype(int)
    ty, tx = (y - gy)[:, None], (x - gx)[None, :]
    big = np.empty((rows + 16, cols + 16), dtype=np.uint16)
    for start in range(0, rows + 16, 512):  # by bands: bounded temporaries at 8192 x 8192
        band = slice(start, min(start + 512, rows + 16))
        a, b = gy[band][:, None], gx[None, :]
        t = ty[band]
        top = grid[a, b] * (1 - tx) + grid[a, b + 1] * tx
        bottom = grid[a + 1, b] * (1 - tx) + grid[a + 1, b + 1] * tx
        big[band] = (1000 + 3000 * (top * (1 - t) + bottom * t) + rng.normal(0, 5, top.shape)).astype(np.uint16)
    real = big[8:8 + rows, 8:8 + cols]
    sim = big[8 - shift[0]:8 - shift[0] + rows, 8 - shift[1]:8 - shift[1] + cols]
    return np.ascontiguousarray(real), np.ascontiguousarray(sim)


def measure(op: str, shape: tuple[int, int], files: dict, workers: int) -> dict:
    job = {"op": op, "shape": shape, "workers": workers, **files}
    env = dict(os.environ, RAYON_NUM_THREADS=str(workers), OPENBLAS_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, "-c", CHILD, json.dumps(job)], capture_output=True, text=True, env=env,
                          timeout=1800)
    if proc.returncode != 0:
        return {"status": f"child died ({proc.returncode}): {proc.stderr.strip().splitlines()[-1:]}", "peak": 0,
                "added": 0}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", default="640x512,8192x8192", help="WxH,WxH,...")
    parser.add_argument("--workers", type=int, default=2, help="threads (RAYON_NUM_THREADS, noise3d workers)")
    a = parser.parse_args()
    import cv2

    print(f"{'operation':22} {'frames':>11} {'peak RSS':>10} {'added':>10}  outcome")
    for size in a.sizes.split(","):
        cols, rows = (int(v) for v in size.lower().split("x"))
        real, sim = scene(rows, cols)
        with tempfile.TemporaryDirectory() as tmp:
            files = {"real": f"{tmp}/real.npy", "sim": f"{tmp}/sim.npy",
                     "png": [f"{tmp}/f{i}.png" for i in range(8)]}
            np.save(files["real"], real)
            np.save(files["sim"], sim)
            for i, path in enumerate(files["png"]):
                cv2.imwrite(path, real if i % 2 == 0 else sim)
            del real, sim
            for op in OPS:
                rec = measure(op, (rows, cols), files, a.workers)
                print(f"{op:22} {cols:>5}x{rows:<5} {rec['peak'] / 2**20:8.0f} MB {rec['added'] / 2**20:7.0f} MB  "
                      f"{rec['status']}", flush=True)


if __name__ == "__main__":
    main()
