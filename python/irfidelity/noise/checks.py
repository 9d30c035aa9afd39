"""What makes a 3-D noise measurement misleading, detected from the sums: a scene that is
not uniform (a gradient, an object), and samples at the limits of the valid range.

The 3-D noise model describes a camera looking at a uniform source. Whatever the scene adds
to the temporal-mean frame lands in the fixed-pattern parts (v, h, vh). Two measures of the
fixed pattern ``F`` (the temporal-mean frame minus its mean), each as a fraction of the
total noise variance:

* ``plane``: the variance of the least-squares plane through ``F`` (a gradient: vignetting,
  a tilted blackbody, ambient drift across the frame), reported when its row or column
  slope is significant (F test at level :data:`SIGNIFICANCE` against the scatter of the
  row or column means, so random row offsets do not pass for a gradient);
* ``low_frequency``: after removing that plane, the variance of ``F`` averaged over
  ``w × w`` tiles, ``w = max(3, min(V, H) // 8)``, beyond what random row offsets, column
  offsets and pixel noise leave in such averages (``1/w``, ``1/w`` and ``1/w²`` of their
  variances): an object or large-scale structure. Reported when the tile averages are also
  at least :data:`LOW_FREQUENCY_RATIO` times that expectation.

Either at or above :data:`UNIFORMITY_LIMIT` gives a :class:`NoiseWarning`.
"""

from __future__ import annotations

import functools
import math
import warnings
from typing import Any

import numpy as np

from ..errors import NoiseWarning, RangeError
from .quantiles import f_ppf

__all__ = ["NoiseWarning", "UNIFORMITY_LIMIT", "uniformity", "plane_fit", "check_clipped"]

#: Fraction of the total noise variance above which a scene is reported as not uniform.
UNIFORMITY_LIMIT = 0.10
#: Level of the F test that a gradient is not a chance alignment of random row/column offsets.
SIGNIFICANCE = 0.001
#: Box averages at least this many times what random fixed-pattern noise would leave.
LOW_FREQUENCY_RATIO = 2.0


def plane_fit(mean_map: np.ndarray) -> np.ndarray:
    """The least-squares plane ``a + b·row + c·col`` through a 2-D map (same shape).

    On a full grid the row and column slopes separate: ``b`` is the slope of the map's row
    means against the row index, ``c`` that of its column means.
    """
    rows, cols = mean_map.shape
    v = np.arange(rows) - (rows - 1) / 2
    h = np.arange(cols) - (cols - 1) / 2
    b = float(v @ mean_map.mean(axis=1)) / float(v @ v) if rows > 1 else 0.0
    c = float(h @ mean_map.mean(axis=0)) / float(h @ h) if cols > 1 else 0.0
    return float(mean_map.mean()) + b * v[:, None] + c * h[None, :]


def _box_means(a: np.ndarray, w: int) -> np.ndarray:
    """Means of the ``w × w`` tiles of ``a`` (a partial last row or column of tiles is left out)."""
    rows, cols = (a.shape[0] // w) * w, (a.shape[1] // w) * w
    return a[:rows, :cols].reshape(rows // w, w, cols // w, w).mean(axis=(1, 3))


@functools.lru_cache(maxsize=64)
def _f_critical(points: int) -> float:
    """Critical F of a line through ``points`` values (1 and ``points − 2`` degrees of freedom)."""
    return f_ppf(1 - SIGNIFICANCE, 1, points - 2)


def _line_fit(profile: np.ndarray) -> tuple[np.ndarray, float, float, float]:
    """``(centred abscissae, slope, regression SS, F statistic)`` of a line through a
    centred profile."""
    n = profile.size
    x = np.arange(n) - (n - 1) / 2
    xx = float(x @ x)
    slope = float(x @ profile) / xx if xx > 0 else 0.0
    reg = slope * slope * xx
    res = float(profile @ profile) - reg
    if n < 3:
        return x, slope, reg, 0.0
    return x, slope, reg, (math.inf if res <= 0 else reg / (res / (n - 2)))


def uniformity(mean_map: np.ndarray, total_variance: float) -> dict[str, Any]:
    """The two measures of the module notes, as fractions of ``total_variance``.

    ``plane``: the plane's variance; ``plane_significant``: whether its row or column slope
    passes an F test at level :data:`SIGNIFICANCE` against the scatter of the row (column)
    means about their line — random row or column offsets line up with some slope by chance.
    ``low_frequency``: the variance of the ``box × box`` tile averages beyond what independent
    row offsets, column offsets and pixels would leave (``var(rows)/w + var(cols)/w +
    var(rest)/w²``); ``low_frequency_ratio``: observed over that expectation.

    A plane has no row-column interaction, so everything follows from the row and column
    means, the sum of squares and the tile means of the fixed pattern (three passes).
    """
    fixed = mean_map - mean_map.mean()
    rows, cols = fixed.shape
    row_means, col_means = fixed.mean(axis=1), fixed.mean(axis=0)
    v, slope_v, reg_v, f_v = _line_fit(row_means)
    h, slope_h, reg_h, f_h = _line_fit(col_means)
    significant = any(points >= 3 and f > _f_critical(points) for points, f in ((rows, f_v), (cols, f_h)))
    plane_ss = cols * reg_v + rows * reg_h
    # the pattern less its plane: row offsets, column offsets and the rest (pixels)
    row_offsets = row_means - slope_v * v
    col_offsets = col_means - slope_h * h
    # (einsum, not a BLAS dot: OpenBLAS threads stall when the cores are busy)
    pixels_ss = (float(np.einsum("ij,ij->", fixed, fixed)) - plane_ss - cols * float(row_offsets @ row_offsets)
                 - rows * float(col_offsets @ col_offsets))
    w = max(3, min(rows, cols) // 8)
    observed = expected = 0.0
    if min(rows, cols) >= w:
        tile_v = v[: rows // w * w].reshape(-1, w).mean(axis=1)
        tile_h = h[: cols // w * w].reshape(-1, w).mean(axis=1)
        tiles = _box_means(fixed, w) - slope_v * tile_v[:, None] - slope_h * tile_h[None, :]
        observed = float(np.mean(tiles * tiles))
        expected = (float(np.mean(row_offsets ** 2) + np.mean(col_offsets ** 2)) / w
                    + max(pixels_ss, 0.0) / (rows * cols) / w**2)
    scale = 1 / total_variance if total_variance > 0 else 0.0
    return {"plane": plane_ss / (rows * cols) * scale, "plane_significant": bool(significant),
            "low_frequency": max(observed - expected, 0.0) * scale,
            "low_frequency_ratio": observed / expected if expected > 0 else (math.inf if observed > 0 else 1.0),
            "box": w}


def warn_if_not_uniform(share: dict[str, Any], *, detrended: bool) -> None:
    """A :class:`NoiseWarning` naming the measure and what to do."""
    if not detrended and share["plane"] >= UNIFORMITY_LIMIT and share["plane_significant"]:
        warnings.warn(
            f"the scene is not uniform: a gradient (plane) across the frame holds {share['plane']:.0%} of the "
            f"noise variance and is counted as row/column noise (v, h); pass detrend='plane' to remove it, "
            f"or measure a uniform source", NoiseWarning, stacklevel=3)
    if share["low_frequency"] >= UNIFORMITY_LIMIT and share["low_frequency_ratio"] >= LOW_FREQUENCY_RATIO:
        warnings.warn(
            f"the scene is not uniform: large-scale structure ({share['box']}x{share['box']}-pixel averages; an "
            f"object or shading) holds {share['low_frequency']:.0%} of the noise variance and is counted as "
            f"fixed-pattern noise; restrict the analysis to a uniform region with roi=(r0, r1, c0, c1)",
            NoiseWarning, stacklevel=3)


def check_clipped(value_range: dict[str, Any], samples: int, policy: str) -> dict[str, Any] | None:
    """Counts of samples at the ends of the valid range; a warning or an error when any.

    ``policy``: ``"warn"`` (a :class:`NoiseWarning`), ``"raise"`` (:class:`RangeError`) or
    ``"ignore"``. Returns None for float frames (no valid range).
    """
    if "at_hi" not in value_range:
        return None
    counts = {k: int(value_range[k]) for k in ("lo", "hi", "at_lo", "at_hi")}
    bad = counts["at_lo"] + counts["at_hi"]
    if bad and policy != "ignore":
        msg = (f"{counts['at_hi']} samples at the saturation level {counts['hi']} and {counts['at_lo']} at the "
               f"floor {counts['lo']} ({bad / samples:.3%} of {samples}): clipped pixels have no noise, so "
               f"every component is underestimated; lower the source temperature or the integration time, "
               f"or crop them out with roi=")
        if policy == "raise":
            raise RangeError(msg)
        warnings.warn(msg, NoiseWarning, stacklevel=3)
    return counts
