"""Multi-page TIFF page access (issue 25): time against the number of pages, and tifffile.

    python benches/bench_pages.py [--sizes 1001,5001,20001,60001] [--repeat N] [--workers N]

For each size, a TIFF of that many tiny pages (4x4 uint16, one IFD each, written with
tifffile) is made in a temporary directory, and timed in the same run:

* counting its pages: ``irf.frames.page_chain`` (one walk over the IFD chain), against
  ``len(tifffile.TiffFile(path).pages)``;
* reading every page: ``irf.load_frame(path, page=i)`` for each i, against tifffile's
  ``TiffFile(path).asarray()`` (all pages in one call);
* scoring the file against itself: ``irf.score_sequence(path, path)`` (every page decoded
  twice, on ``--workers`` threads, plus each frame's scoring in Python), with every image
  component and with the PSNR-only plan (``weights="psnr=1"``: the least work per frame).

irfidelity keeps each file's chain of pages (keyed by the file's identity): before every
timed call the file's change time is bumped, so each call walks the chain afresh. Prints
seconds, µs per page, and the ratios to tifffile (> 1: irfidelity is slower). Time per page
that stays flat from the smallest to the largest size is what linear page access means.
A benchmark, not a test: numbers depend on the machine (cores, other load).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import tempfile
import time
from typing import Callable

import numpy as np
import tifffile

import irfidelity as irf
from irfidelity.frames import page_chain


def make_stack(path: pathlib.Path, pages: int) -> None:
    data = np.random.default_rng(0).integers(0, 4096, (pages, 4, 4), dtype=np.uint16)
    tifffile.imwrite(path, data, photometric="minisblack")


def timed(fn: Callable[[], object], repeat: int, path: pathlib.Path | None = None) -> float:
    """Best of ``repeat`` calls; with ``path``, its change time is bumped before each call
    (irfidelity then walks the chain of pages again instead of using the one it kept)."""
    best = float("inf")
    for _ in range(repeat):
        if path is not None:
            os.utime(path)
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def measure(path: pathlib.Path, pages: int, repeat: int, workers: int) -> dict[str, float]:
    def read_all() -> None:
        for i in range(pages):
            irf.load_frame(path, page=i)

    def count_tifffile() -> int:
        with tifffile.TiffFile(path) as tif:
            return len(tif.pages)

    def score(weights: str | None) -> None:
        rep = irf.score_sequence(path, path, bits=12, weights=weights, progress=False, workers=workers)
        assert len(rep.frames) == pages and not rep.failed

    assert page_chain(path) == (pages, None) and count_tifffile() == pages
    return {
        "count": timed(lambda: page_chain(path), repeat, path),
        "count_tifffile": timed(count_tifffile, repeat),
        "read": timed(read_all, repeat, path),
        "read_tifffile": timed(lambda: tifffile.imread(path), repeat),
        "score": timed(lambda: score(None), max(1, repeat // 2), path),
        "score_psnr": timed(lambda: score("psnr=1"), max(1, repeat // 2), path),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1001,5001,20001,60001", help="page counts, comma-separated")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    sizes = [int(s) for s in a.sizes.split(",")]
    print(f"{'pages':>7} | {'count s':>8} {'tifffile':>8} {'ratio':>6} | {'read s':>7} {'µs/page':>7} "
          f"{'tifffile':>8} {'ratio':>6} | {'score s':>7} {'µs/page':>7} | {'psnr s':>7} {'µs/page':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        for pages in sizes:
            path = pathlib.Path(tmp) / f"stack{pages}.tif"
            make_stack(path, pages)
            m = measure(path, pages, a.repeat, a.workers)
            print(f"{pages:>7} | {m['count']:>8.4f} {m['count_tifffile']:>8.4f} "
                  f"{m['count'] / m['count_tifffile']:>6.2f} | {m['read']:>7.3f} {1e6 * m['read'] / pages:>7.1f} "
                  f"{m['read_tifffile']:>8.3f} {m['read'] / m['read_tifffile']:>6.2f} | "
                  f"{m['score']:>7.3f} {1e6 * m['score'] / pages:>7.1f} | "
                  f"{m['score_psnr']:>7.3f} {1e6 * m['score_psnr'] / pages:>7.1f}", flush=True)
            path.unlink()


if __name__ == "__main__":
    main()
