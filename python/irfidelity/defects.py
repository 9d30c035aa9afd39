"""Errors a few pixels carry: a dead cluster, a hot border, a stuck column.

Global SSIM and MSE are sums over the frame, so a handful of pixels far off — a dead cluster of
0.2 % of a low-contrast frame — can decide them (SSIM 0.01 where the rest of the frame agrees).
:func:`concentrated_error` says when the largest :data:`TOP_SHARE` of the squared differences
carry more than :data:`MOST` of the total, and where those pixels are, so a report can name them
and the user can leave them out (``mask=``, ``--mask``, ``--roi``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["TOP_SHARE", "MOST", "concentrated_error"]

#: The share of the scored pixels whose squared differences are examined (the largest ones).
TOP_SHARE = 0.005

#: They dominate when they carry more than this share of the summed squared difference.
MOST = 0.5

#: Pixels within this distance of the frame's edge are "on the border".
_BORDER = 2


def _where(rows: np.ndarray, cols: np.ndarray) -> str:
    """The place of some pixels in words: a compact cluster, or scattered over a box."""
    y0, y1, x0, x1 = int(rows.min()), int(rows.max()), int(cols.min()), int(cols.max())
    box = f"rows {y0}–{y1}, columns {x0}–{x1}"
    if (y1 - y0 + 1) * (x1 - x0 + 1) <= 4 * rows.size:
        return f"a compact cluster at {box}"
    return f"scattered over {box}"


#: Pixels a band holds: the frames are examined band by band, so the memory this takes is a
#: few bands and the candidates, never copies of the whole frames.
BAND_PIXELS = 1 << 20


def _bands(rows: int, cols: int):
    """Row ranges ``(start, stop)`` of at most :data:`BAND_PIXELS` pixels (a row at least)."""
    step = max(1, BAND_PIXELS // max(cols, 1))
    for start in range(0, rows, step):
        yield start, min(start + step, rows)


def _band(real: np.ndarray, sim: np.ndarray, mask: Any, start: int, stop: int) -> tuple[np.ndarray, np.ndarray | None]:
    """The squared differences of rows ``start:stop`` (0 where not scored) and the scored pixels
    (None: all of them — integer frames without a mask)."""
    squared = np.subtract(sim[start:stop], real[start:stop], dtype=np.float64)
    np.multiply(squared, squared, out=squared)
    scored = None
    if real.dtype.kind == "f" or sim.dtype.kind == "f":
        scored = np.isfinite(real[start:stop]) & np.isfinite(sim[start:stop])
    if mask is not None:
        scored = mask[start:stop] if scored is None else scored & mask[start:stop]
    if scored is not None:
        squared[~scored] = 0.0
    return squared, scored


def _ring_sums(squared: np.ndarray, scored: np.ndarray | None, start: int, rows: int) -> tuple[float, int, list]:
    """Squared error, scored pixels and their bounding boxes within :data:`_BORDER` of the
    frame's edge, in rows ``start:start + len(squared)`` (slices: the interior is not touched)."""
    stop = start + squared.shape[0]
    top = min(stop, _BORDER)
    bottom = max(start, rows - _BORDER, top)  # rows [start, top) and [bottom, stop)
    inner = (max(start, _BORDER) - start, min(stop, rows - _BORDER) - start)  # band rows off the edge rows
    cols = squared.shape[1]
    parts = [(slice(0, max(0, top - start)), slice(None), 0), (slice(bottom - start, None), slice(None), 0)]
    if inner[1] > inner[0]:
        parts += [(slice(*inner), slice(0, _BORDER), 0), (slice(*inner), slice(cols - _BORDER, cols), cols - _BORDER)]
    total, count, box = 0.0, 0, []
    for row_part, col_part, first_col in parts:
        values = squared[row_part, col_part]
        if values.size == 0:
            continue
        first_row = start + (row_part.start or 0)
        if scored is None:  # every pixel: the slice's own extent
            total, count = total + float(values.sum()), count + values.size
            box.append((first_row, first_row + values.shape[0] - 1, first_col, first_col + values.shape[1] - 1))
            continue
        kept = scored[row_part, col_part]
        if not kept.any():
            continue
        total, count = total + float(values[kept].sum()), count + int(kept.sum())
        rr, cc = np.nonzero(kept)
        box.append((first_row + int(rr.min()), first_row + int(rr.max()), first_col + int(cc.min()),
                    first_col + int(cc.max())))
    return total, count, box


def _finding(pixels: int, count: int, share: float, rows: np.ndarray, cols: np.ndarray, where: str) -> dict:
    text = (f"{100 * share:.0f} % of the squared error comes from {pixels} pixels ({100 * pixels / count:.2g} % of "
            f"those scored), {where}: PSNR and global SSIM describe those pixels more than the frame; leave them out "
            f"with a mask (mask=, --mask, --roi) to score the rest")
    return {"pixels": pixels, "share": share, "rows": [int(rows.min()), int(rows.max())],
            "cols": [int(cols.min()), int(cols.max())], "text": text}


def concentrated_error(real: Any, sim: Any, mask: Any = None) -> dict | None:
    """Whether a few pixels carry most of the squared error, and where.

    Two places are examined: the largest :data:`TOP_SHARE` of the squared differences (a dead
    cluster, stuck pixels), and the frame's border, the pixels within 2 px of its edge (a hot
    or cold border); they dominate when they carry more than :data:`MOST` of the sum.

    Parameters
    ----------
    real, sim : 2-D arrays
        The frames as scored (the simulated one registered, when it was).
    mask : 2-D bool array, optional
        The scored pixels.

    Returns
    -------
    dict or None
        None when neither dominates (or there is no error). Otherwise ``pixels`` (how many
        carry it), ``share`` (of the summed squared difference), ``rows``, ``cols`` (their
        bounding box, inclusive: of the fewest largest ones that carry 90 % of the share) and
        ``text`` (one sentence).

    Examples
    --------
    >>> import numpy as np
    >>> from irfidelity.defects import concentrated_error
    >>> real = np.full((100, 100), 3000.0) + np.random.default_rng(0).normal(0, 2, (100, 100))
    >>> sim = real + np.random.default_rng(1).normal(0, 2, (100, 100))
    >>> sim[40:46, 70:76] = 0                                   # a dead 6×6 cluster
    >>> found = concentrated_error(real, sim)
    >>> found["rows"], found["cols"], round(found["share"], 3)
    ([40, 45], [70, 75], 1.0)
    """
    real, sim = np.asarray(real), np.asarray(sim)
    mask = None if mask is None else np.asarray(mask, dtype=bool)
    shape = real.shape
    total = ring_total = largest = 0.0
    count = ring_count = 0
    boxes: list = []
    bands = list(_bands(*shape))
    for start, stop in bands:
        squared, scored = _band(real, sim, mask, start, stop)
        total += float(squared.sum())  # pairwise summation: the decisions below are against 1/2
        largest = max(largest, float(squared.max()))
        count += squared.size if scored is None else int(scored.sum())
        band_total, band_count, band_boxes = _ring_sums(squared, scored, start, shape[0])
        ring_total, ring_count, boxes = ring_total + band_total, ring_count + band_count, boxes + band_boxes
    if count == 0 or not total > 0:
        return None
    top = max(1, math.ceil(TOP_SHARE * count))
    held = squared if len(bands) == 1 else None  # a frame of one band: its squares are at hand
    if _may_dominate(real, sim, mask, top, MOST * total, largest, held):
        values, flat = _largest(real, sim, mask, top, held)
        share = math.fsum(values) / total
        if share > MOST:
            carrying = int(np.searchsorted(np.cumsum(values), 0.9 * values.sum())) + 1
            rows, cols = np.unravel_index(flat[:carrying], shape)
            return _finding(top, count, share, rows, cols, _where(rows, cols))
    share = ring_total / total
    if share > MOST and ring_count < 0.1 * count:
        box = np.array(boxes)
        return _finding(ring_count, count, share, box[:, :2].ravel(), box[:, 2:].ravel(),
                        f"along the frame's border ({_BORDER} px wide)")
    return None


def _squares(real: np.ndarray, sim: np.ndarray, mask: Any, held: np.ndarray | None):
    """``(start row, squared differences)`` of each band, again (``held``: a one-band frame's)."""
    if held is not None:
        yield 0, held
        return
    for start, stop in _bands(*real.shape):
        yield start, _band(real, sim, mask, start, stop)[0]


def _may_dominate(real: np.ndarray, sim: np.ndarray, mask: Any, top: int, limit: float, largest: float,
                  held: np.ndarray | None) -> bool:
    """Whether the ``top`` largest squared differences can sum to more than ``limit``, by two
    bounds that need no search: ``top × largest``, and with τ = limit / (2·top) the sum of the
    values above τ plus ``top × τ`` (each of the ``top`` largest is above τ or at most τ)."""
    if top * largest <= limit:
        return False
    tau = limit / (2 * top)
    above = math.fsum(float(squared[squared > tau].sum()) for _, squared in _squares(real, sim, mask, held))
    return above + top * tau > limit


def _largest(real: np.ndarray, sim: np.ndarray, mask: Any, top: int,
             held: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``top`` largest squared differences, largest first, and their flat indices (ties
    broken by the smaller index), kept band by band (``held``: a one-band frame's squares)."""
    best_values, best_flat = np.empty(0), np.empty(0, dtype=np.int64)
    for start, squared in _squares(real, sim, mask, held):
        flat_band = squared.ravel()
        keep = min(top, flat_band.size)
        index = np.argpartition(flat_band, -keep)[-keep:]
        values = np.concatenate([best_values, flat_band[index]])
        flat = np.concatenate([best_flat, index + start * real.shape[1]])
        if values.size > top:
            chosen = np.argpartition(values, -top)[-top:]
            values, flat = values[chosen], flat[chosen]
        best_values, best_flat = values, flat
    order = np.lexsort((best_flat, -best_values))
    return best_values[order], best_flat[order]
