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

from . import _core
from .frames import FRAME_DTYPES

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

    One Rust pass over the frames (GIL released, no copy of them) gives the total, the border's
    sums and the largest square; the largest squares are searched for only when three bounds
    cannot rule out that they dominate (``_core.error_profile``). Squared differences are
    float64, exact for frames of 16-bit integers or narrower.

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
        carry it: the largest :data:`TOP_SHARE` of the squared differences, those not zero; the
        border's scored pixels), ``share`` (of the summed squared difference), ``rows``, ``cols`` (their
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
    real, sim = _frames(real, sim)
    mask = None if mask is None else np.ascontiguousarray(mask, dtype=bool)
    total, count, (ring_total, ring_count, ring_box), top = _core.error_profile(
        real, sim, mask, top_share=TOP_SHARE, most=MOST, border=_BORDER)
    if count == 0 or not total > 0:
        return None
    if top is not None:
        values, flat = top
        share = math.fsum(values) / total
        if share > MOST:
            carrying = int(np.searchsorted(np.cumsum(values), 0.9 * values.sum())) + 1
            rows, cols = np.unravel_index(flat[:carrying], real.shape)
            return _finding(len(values), count, share, rows, cols, _where(rows, cols))
    share = ring_total / total
    if share > MOST and ring_count < 0.1 * count:
        rows, cols = np.array(ring_box[:2]), np.array(ring_box[2:])
        return _finding(ring_count, count, share, rows, cols, f"along the frame's border ({_BORDER} px wide)")
    return None


def _frames(real: Any, sim: Any) -> tuple[np.ndarray, np.ndarray]:
    """The frames as the Rust pass takes them: C-contiguous, the simulated one of the real one's
    dtype or float64 (a registered pair's resampled frame); other pairs as float64."""
    real, sim = np.ascontiguousarray(real), np.ascontiguousarray(sim)
    if real.dtype not in FRAME_DTYPES or sim.dtype not in (real.dtype, np.float64):
        real, sim = real.astype(np.float64), sim.astype(np.float64)
    return real, sim
