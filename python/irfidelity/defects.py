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


def _band(real: np.ndarray, sim: np.ndarray, mask: Any, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """The squared differences of rows ``start:stop`` (0 where not scored) and the scored pixels."""
    r = real[start:stop].astype(np.float64)
    s = sim[start:stop].astype(np.float64)
    scored = np.isfinite(r) & np.isfinite(s)
    if mask is not None:
        scored &= mask[start:stop]
    return np.where(scored, (s - r) ** 2, 0.0), scored


def _ring(start: int, stop: int, shape: tuple[int, int]) -> np.ndarray:
    """The border pixels (within :data:`_BORDER` of the frame's edge) of rows ``start:stop``."""
    rows = np.arange(start, stop)
    ring = np.zeros((stop - start, shape[1]), dtype=bool)
    ring[(rows < _BORDER) | (rows >= shape[0] - _BORDER)] = True
    ring[:, :_BORDER] = ring[:, -_BORDER:] = True
    return ring


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
    totals, ring_totals, count, ring_count = [], [], 0, 0
    ring_rows, ring_cols = [], []
    for start, stop in _bands(*shape):
        squared, scored = _band(real, sim, mask, start, stop)
        ring = _ring(start, stop, shape) & scored
        totals.append(math.fsum(squared.ravel()))
        ring_totals.append(math.fsum(squared[ring]))
        count += int(scored.sum())
        ring_count += int(ring.sum())
        if ring.any():
            where_rows, where_cols = np.nonzero(ring)
            ring_rows += [start + int(where_rows.min()), start + int(where_rows.max())]
            ring_cols += [int(where_cols.min()), int(where_cols.max())]
    total = math.fsum(totals)
    if count == 0 or not total > 0:
        return None
    top = max(1, math.ceil(TOP_SHARE * count))
    values, flat = _largest(real, sim, mask, top)
    share = math.fsum(values) / total
    if share > MOST:
        carrying = int(np.searchsorted(np.cumsum(values), 0.9 * values.sum())) + 1
        rows, cols = np.unravel_index(flat[:carrying], shape)
        return _finding(top, count, share, rows, cols, _where(rows, cols))
    share = math.fsum(ring_totals) / total
    if share > MOST and ring_count < 0.1 * count:
        return _finding(ring_count, count, share, np.array(ring_rows), np.array(ring_cols),
                        f"along the frame's border ({_BORDER} px wide)")
    return None


def _largest(real: np.ndarray, sim: np.ndarray, mask: Any, top: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``top`` largest squared differences, largest first, and their flat indices (ties
    broken by the smaller index), kept band by band."""
    best_values, best_flat = np.empty(0), np.empty(0, dtype=np.int64)
    for start, stop in _bands(*real.shape):
        squared, _ = _band(real, sim, mask, start, stop)
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
