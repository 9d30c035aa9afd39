"""``irfidelity targets OUT``: write bar-target and slanted-edge images (docs/bars.md, section 6).

One file per frequency (``four_bar_0.1.png``, ...), or one slanted edge (``edge.png``), with
``bars.csv`` listing the bar images (frequency, and ΔT = bar level − background level) in the
format ``irfidelity score --real-bars/--sim-bars`` reads.
"""

from __future__ import annotations

import argparse
import math
import os

import numpy as np

from ..errors import FidelityError
from ..frames import default_max_pixels
from .output import UsageError

__all__ = ["targets_command", "KINDS"]

#: The target kinds and their bar counts (None: the slanted edge).
KINDS = {"four-bar": 4, "three-bar": 3, "edge": None}


def _numbers(text: str, what: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UsageError(f"--{what}: expected numbers separated by commas, got {text!r}") from None


def _shape(text: str) -> tuple[int, int]:
    parts = text.lower().replace("x", ",").split(",")
    try:
        rows, cols = (int(p) for p in parts)
    except ValueError:
        raise UsageError(f"--size: expected ROWS,COLS (e.g. 128,128), got {text!r}") from None
    limit = default_max_pixels()
    if not (rows > 0 and cols > 0 and rows * cols <= limit):
        raise UsageError(f"--size {rows},{cols}: expected at least one pixel and at most {limit} "
                         f"(the largest frame irfidelity reads by default)")
    return rows, cols


def _otf(a: argparse.Namespace):
    from ..targets import gaussian_otf

    if a.blur is None:
        return None
    if not a.blur > 0:
        raise UsageError(f"--blur: expected a Gaussian sigma > 0 (pixels), got {a.blur!r}")
    return gaussian_otf(a.blur)


#: The largest level the float formats write (float32 TIFF, float64 .npy); PNG's 16 bits are
#: checked with the frame.
LEVEL_LIMITS = {"tiff": float(np.finfo(np.float32).max), "npy": float(np.finfo(np.float64).max)}


def _levels(a: argparse.Namespace) -> tuple[float, float]:
    if a.levels is not None:
        values = _numbers(a.levels, "levels")
        if len(values) != 2:
            raise UsageError(f"--levels: expected BACKGROUND,BAR, got {a.levels!r}")
        if not all(math.isfinite(v) for v in values):
            raise UsageError(f"--levels {a.levels}: expected two finite numbers")
        top = LEVEL_LIMITS.get(a.format, math.inf)
        if not all(abs(v) <= top for v in values):
            raise UsageError(f"--levels {a.levels}: a {a.format} target holds levels within ±{top:g}")
        return values[0], values[1]
    return (16384.0, 49152.0) if a.format == "png" else (0.0, 1.0)


def _images(a: argparse.Namespace) -> list[tuple[str, float | None, np.ndarray]]:
    """(file name, frequency, frame) of each image to write."""
    from .. import targets
    from ..image_writers import FORMATS

    shape, levels, otf, ext = _shape(a.size), _levels(a), _otf(a), FORMATS[a.format]
    if a.kind == "edge":
        edge = targets.slanted_edge(shape, angle=a.angle, levels=levels, orientation=a.orientation, otf=otf)
        return [(f"edge{ext}", None, edge)]
    if a.frequency is None:
        raise UsageError(f"--frequency: give the bar frequencies of the {a.kind} targets (cycles/pixel), e.g. "
                         f"0.05,0.1,0.2")
    bars = KINDS[a.kind]
    assert bars is not None  # an edge was returned above
    out: list[tuple[str, float | None, np.ndarray]] = []
    for f in _numbers(a.frequency, "frequency"):
        if not 0 < f < 0.5:
            raise UsageError(f"--frequency {f:g}: expected a bar frequency in (0, 0.5) cycles/pixel; at or above "
                             f"the Nyquist frequency 0.5 the written image would alias the bars")
        frame = targets.bar_target(f, shape, bars=bars, orientation=a.orientation, phase=a.phase,
                                   levels=levels, otf=otf)
        out.append((f"{a.kind.replace('-', '_')}_{f:g}{ext}", f, frame))
    return out


def targets_command(a: argparse.Namespace) -> list[str]:
    """Write the images the arguments ask for; returns their paths (printed one a line)."""
    from ..image_writers import write_image

    try:
        images = _images(a)
    except FidelityError as exc:
        raise UsageError(str(exc)) from None
    if os.path.exists(a.out) and not os.path.isdir(a.out):
        raise UsageError(f"OUT {a.out!r} is a file; give a directory (created when missing)")
    os.makedirs(a.out, exist_ok=True)
    written = []
    for name, _, frame in images:
        path = os.path.join(a.out, name)
        write_image(path, frame, a.format)
        written.append(path)
    bar_images = [(name, f) for name, f, _ in images if f is not None]
    if bar_images:
        background, bar = _levels(a)
        path = os.path.join(a.out, "bars.csv")
        with open(path, "w", encoding="utf-8", newline="\n") as fh:
            fh.write("file,frequency_cy_per_px,delta_t\n")
            fh.writelines(f"{name},{f:g},{bar - background:g}\n" for name, f in bar_images)
        written.append(path)
    for path in written:
        print(path)
    return written
