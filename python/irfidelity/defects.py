"""Errors a few pixels carry: a dead cluster, a hot border, a stuck column.

Global SSIM and MSE are sums over the frame, so a handful of pixels far off — a dead cluster of
0.2 % of a low-contrast frame — can decide them (SSIM 0.01 where the rest of the frame agrees).
:func:`concentrated_error` says when the largest :data:`TOP_SHARE` of the squared differences
carry more than :data:`MOST` of the total, and where those pixels are, so a report can name them
and the user can leave them out (``mask=``, ``--mask``, ``--roi``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from . import _core
from .frames import FRAME_DTYPES

__all__ = ["TOP_SHARE", "MOST", "concentrated_error", "Defects", "ErrorProfile", "error_profile", "find_defects"]

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


def _span(name: str, ends: Any) -> str:
    """``row 85`` or ``rows 85–87``."""
    return f"{name} {ends[0]}" if ends[0] == ends[1] else f"{name}s {ends[0]}–{ends[1]}"


def _finding(pixels: int, count: int, share: float, rows: np.ndarray, cols: np.ndarray, where: str) -> dict:
    text = (f"{100 * share:.0f} % of the squared error comes from {pixels} pixels ({100 * pixels / count:.2g} % of "
            f"those scored), {where}: PSNR and global SSIM describe those pixels more than the frame; leave them out "
            f"with a mask (mask=, --mask, --roi) to score the rest")
    return {"pixels": pixels, "share": share, "rows": [int(rows.min()), int(rows.max())],
            "cols": [int(cols.min()), int(cols.max())], "text": text}


class ErrorProfile(NamedTuple):
    """Where a pair's squared error sits (:func:`error_profile`): its ``total`` over the ``scored``
    pixels, the ``largest`` square, the ``border``'s ``(total, count, box or None)``, the
    ``top`` largest squares ``(values, flat indices)`` when bounds could not rule out that
    they carry more than :data:`MOST` of the total (None otherwise), and with a tolerance on
    float64 frames the temperature errors' sums ``(n, Σd, Σd², Σ|d|, within)`` (None otherwise;
    :meth:`irfidelity.temperature.TemperatureErrors.of_sums`), and with ``spread`` the defects'
    threshold sample: its size and ``(median, MAD, 99th percentile, RMS deviation)`` (None when
    empty); None otherwise."""

    total: float
    scored: int
    largest: float
    border: tuple[float, int, list[int] | None]
    top: tuple[np.ndarray, np.ndarray] | None
    errors: tuple[int, float, float, float, int] | None
    spread: tuple[int, tuple[float, float, float, float] | None] | None


def error_profile(real: Any, sim: Any, mask: Any = None, *, tolerance: float | None = None,
                  spread: bool = False) -> ErrorProfile:
    """The squared error of a pair and where it sits, in one Rust pass (``_core.error_profile``):
    what :func:`find_defects` and :func:`concentrated_error` both read, so a caller that runs
    both on one pair can take it once; with ``tolerance`` (frames in temperature), the same
    pass also sums the temperature errors, and with ``spread`` it draws the sample of
    :func:`find_defects`' threshold."""
    real, sim = _frames(real, sim)
    mask = None if mask is None else np.ascontiguousarray(mask, dtype=bool)
    return ErrorProfile(*_core.error_profile(real, sim, mask, top_share=TOP_SHARE, most=MOST, border=_BORDER,
                                             tolerance=tolerance,
                                             spread_step=_spread_step(real.size) if spread else None))


def concentrated_error(real: Any, sim: Any, mask: Any = None, *, profile: ErrorProfile | None = None) -> dict | None:
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
    profile : ErrorProfile, optional
        :func:`error_profile` of these frames and mask, when the caller has it.

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
    real = np.asarray(real)
    total, count, _, (ring_total, ring_count, ring_box), top, _, _ = error_profile(real, sim, mask) \
        if profile is None else profile
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
    if share > MOST and ring_count < 0.1 * count and ring_box is not None:  # (a border with error has a box)
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


# --------------------------------------------------------------------------- defect clusters
#: A pixel is a defect candidate when its difference lies this many robust standard deviations
#: (1.4826 × the median absolute deviation) from the median difference.
OUTLIER = 10.0

#: ... and this many times the 99th percentile of the differences' absolute deviations.
TAIL = 3.0

#: A cluster of at most this many pixels (a 5×5 block) can be a defect (dead, hot or stuck
#: pixels); larger regions of error are the simulation's, not a pixel defect's.
MAX_CLUSTER = 25

#: More candidates than this share of the scored pixels: the error is widespread, not defects.
MAX_CANDIDATES = 0.005

#: A cluster is a defect when the median error around it is below this share of its own, and
#: the other frame departs from its own surroundings there by less than this share of the
#: defective frame's departure: a dead pixel sits in a scene the other frame shows smooth, a
#: small hot target blurred by the simulator still stands out in both.
ISOLATED = 0.2

#: A cluster is no defect when the other frame, within its box (2 px around it), departs the
#: same way by more than this share of the defective frame's departure: the same small target,
#: displaced.
DISPLACED = 0.5

#: Differences drawn for the robust scale (a regular subsample of the frame).
_SCALE_SAMPLES = 16384


@dataclass(frozen=True)
class Defects:
    """Clusters of defective pixels in either frame, found before the image components.

    Attributes
    ----------
    mask : bool ndarray
        True at the defective pixels: left out of the image components and of the transfer.
    clusters : tuple of dict
        Each: ``frame`` ("simulated" or "real": the frame whose pixels depart from their
        surroundings), ``kind`` ("dark": dead or stuck low; "bright": hot or stuck high),
        ``pixels``, ``rows``, ``cols`` (bounding box, inclusive), ``share`` (of the pair's
        summed squared difference).
    share : float
        The share of the summed squared difference the clusters carry.
    """

    mask: np.ndarray
    clusters: tuple
    share: float

    @property
    def pixels(self) -> int:
        return int(sum(c["pixels"] for c in self.clusters))

    def text(self) -> str:
        """One sentence naming the clusters (the largest first, at most three)."""
        parts = [f"{c['pixels']} {c['kind']} pixel{'s' if c['pixels'] > 1 else ''} in the {c['frame']} frame at "
                 f"{_span('row', c['rows'])}, {_span('column', c['cols'])}" for c in self.clusters[:3]]
        more = f" and {len(self.clusters) - 3} more clusters" if len(self.clusters) > 3 else ""
        return (f"defective pixels left out of the image components and the transfer: {'; '.join(parts)}{more} "
                f"({100 * self.share:.3g} % of the squared error)")

    def repaired(self, real: np.ndarray, sim: np.ndarray, frames: tuple = ("real", "simulated")
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The frames with each cluster of ``frames`` filled, in the frame it departs in, by the
        median of that frame's other pixels within 2 px (a camera's bad-pixel replacement), for
        measures over whole tiles (the transfer), which would lose every tile holding a pixel left
        out. A frame is copied only when it has a cluster to fill."""
        out = {"real": real, "simulated": sim}
        for c in self.clusters:
            if c["frame"] not in frames:
                continue
            if out[c["frame"]] is (real if c["frame"] == "real" else sim):
                out[c["frame"]] = np.array(out[c["frame"]], copy=True)
            box = (slice(max(c["rows"][0] - 2, 0), c["rows"][1] + 3), slice(max(c["cols"][0] - 2, 0), c["cols"][1] + 3))
            values, bad = out[c["frame"]][box], self.mask[box]
            fill = np.median(values[~bad].astype(np.float64))
            values[bad] = np.rint(fill) if values.dtype.kind in "iu" else fill
        return out["real"], out["simulated"]

    def finding(self) -> dict:
        """JSON-ready: ``pixels``, ``share``, ``clusters``, ``text``."""
        return {"pixels": self.pixels, "share": self.share, "clusters": [dict(c) for c in self.clusters],
                "text": self.text()}


def _spread_step(pixels: int) -> int:
    """The step of the threshold's sample: every step-th pixel of every step-th row, about
    :data:`_SCALE_SAMPLES` of them."""
    return max(1, int(math.sqrt(pixels / _SCALE_SAMPLES)))


def _outlier_threshold(real: np.ndarray, sim: np.ndarray, mask: np.ndarray | None,
                       sampled: tuple[int, tuple[float, float, float, float] | None] | None = None
                       ) -> tuple[float, float]:
    """The median of ``sim − real`` over a regular subsample, and how far from it a difference
    makes a candidate: :data:`OUTLIER` robust standard deviations (1.4826 × the median absolute
    deviation, at least the frames' resolution: half a count for integer frames), and at least
    :data:`TAIL` × the 99th percentile of the absolute deviations. The percentile raises it for a
    heavy-tailed difference (a scene that moved between two frames of a quiet camera, whose
    deviation is mostly 0) and leaves a Gaussian one at 10 σ (3 × 2.58 σ); defects, fewer than
    :data:`MAX_CANDIDATES` of the pixels, do not reach it. ``sampled``: the spread an
    :func:`error_profile` drew (``spread=True``), when the caller has it."""
    # sim[::step, ::step] − real[::step, ::step] where scored and finite; numpy's median and quantile
    spread = _core.robust_spread(real, sim, mask, step=_spread_step(real.size)) if sampled is None else sampled[1]
    if spread is None:
        return 0.0, math.inf
    median, deviation, tail, rms = spread
    floor = 0.5 if real.dtype.kind in "iu" and sim.dtype.kind in "iu" else 1e-9 * (abs(median) + rms + 1e-300)
    return median, max(OUTLIER * max(1.4826 * deviation, floor), TAIL * tail)


def _clusters(rows: np.ndarray, cols: np.ndarray) -> list[np.ndarray]:
    """The 8-connected clusters of the given pixels, as arrays of their positions."""
    where = {(int(r), int(c)): i for i, (r, c) in enumerate(zip(rows, cols))}
    seen = np.zeros(len(rows), dtype=bool)
    out = []
    for start in range(len(rows)):
        if seen[start]:
            continue
        seen[start] = True
        members, stack = [], [start]
        while stack:
            i = stack.pop()
            members.append(i)
            r, c = int(rows[i]), int(cols[i])
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    j = where.get((r + dr, c + dc))
                    if j is not None and not seen[j]:
                        seen[j] = True
                        stack.append(j)
        out.append(np.array(members))
    return out


def _cluster(real: np.ndarray, sim: np.ndarray, scored: np.ndarray, members: tuple, median: float) -> dict | None:
    """A cluster's description when it is a defect: small, and isolated (the error around it a
    small share of its own); None otherwise."""
    rows, cols = members
    if rows.size > MAX_CLUSTER:
        return None
    y0, y1 = max(int(rows.min()) - 2, 0), int(rows.max()) + 3
    x0, x1 = max(int(cols.min()) - 2, 0), int(cols.max()) + 3
    around = scored[y0:y1, x0:x1].copy()
    around[rows - y0, cols - x0] = False
    if not around.any():
        return None
    box_real, box_sim = real[y0:y1, x0:x1].astype(np.float64), sim[y0:y1, x0:x1].astype(np.float64)
    inside = np.abs(sim[rows, cols].astype(np.float64) - real[rows, cols] - median)
    outside = np.abs(box_sim[around] - box_real[around] - median)
    if not np.median(outside) <= ISOLATED * np.median(inside):
        return None
    departs = {name: float(np.median(frame[rows, cols].astype(np.float64)) - np.median(box[around]))
               for name, frame, box in (("simulated", sim, box_sim), ("real", real, box_real))}
    frame = max(departs, key=lambda k: abs(departs[k]))
    other = "real" if frame == "simulated" else "simulated"
    if abs(departs[other]) > ISOLATED * abs(departs[frame]):
        return None
    # a small target the other frame shows a pixel or two away (a displaced view) is no defect
    box_other = box_real if other == "real" else box_sim
    sign = 1.0 if departs[frame] > 0 else -1.0
    if (sign * (box_other - np.median(box_other[around]))).max() > DISPLACED * abs(departs[frame]):
        return None
    return {"frame": frame, "kind": "bright" if departs[frame] > 0 else "dark", "pixels": int(rows.size),
            "rows": [int(rows.min()), int(rows.max())], "cols": [int(cols.min()), int(cols.max())]}


def find_defects(real: Any, sim: Any, mask: Any = None, *, profile: ErrorProfile | None = None) -> Defects | None:
    """Clusters of dead, hot or stuck pixels in either frame, before the image components.

    A pixel is a candidate when ``sim − real`` lies more than :data:`OUTLIER` robust standard
    deviations from its median, and more than :data:`TAIL` times the 99th percentile of the
    deviations; candidates join into 8-connected clusters, and a cluster is a
    defect when it has at most :data:`MAX_CLUSTER` pixels, is isolated (the median error around
    it, within 2 px, under :data:`ISOLATED` of its own) and departs from its surroundings in one
    frame only (the other's departure under :data:`ISOLATED` of it): a blurred edge or a
    misplaced target leaves error around it, a blurred small target still stands out in both
    frames, and both are the simulation's, not a defect. More candidates than
    :data:`MAX_CANDIDATES` of the scored pixels is widespread error: no defects are reported.
    The frame whose cluster departs from its own surroundings is the defective one.

    One Rust pass (:func:`error_profile` with ``spread=True``, or ``profile`` when given) gives
    the largest difference and the threshold's sample; only when the largest exceeds the
    threshold does a second (``_core.far_pixels``) list the candidates, without a frame-sized
    temporary.

    Returns
    -------
    Defects or None

    Examples
    --------
    >>> import numpy as np
    >>> from irfidelity.defects import find_defects
    >>> rng = np.random.default_rng(0)
    >>> real = (3000 + 40 * np.sin(np.arange(64 * 80) / 50)).reshape(64, 80) + rng.normal(0, 2, (64, 80))
    >>> sim = real + rng.normal(0, 2, real.shape)
    >>> sim[20:23, 30:33] = 0                                   # a dead 3×3 cluster
    >>> found = find_defects(real, sim)
    >>> found.clusters[0]["frame"], found.clusters[0]["kind"], found.clusters[0]["rows"], found.pixels
    ('simulated', 'dark', [20, 22], 9)
    """
    real, sim = _frames(real, sim)
    given = None if mask is None else np.ascontiguousarray(mask, dtype=bool)
    if profile is None:
        profile = error_profile(real, sim, given, spread=True)
    median, threshold = _outlier_threshold(real, sim, given, profile.spread)  # drawn now when the profile has none
    total, count, largest = profile.total, profile.scored, profile.largest
    if count == 0 or not math.sqrt(largest) > threshold - abs(median):
        return None
    flat = _core.far_pixels(real, sim, given, median=median, threshold=threshold,
                            most=int(math.floor(MAX_CANDIDATES * count)))
    if flat is None or flat.size == 0:
        return None
    rows, cols = np.unravel_index(flat, real.shape)
    far = np.zeros(real.shape, dtype=bool)
    far.flat[flat] = True
    scored = np.ones(real.shape, dtype=bool) if given is None else given
    found = [c for members in _clusters(rows, cols)
             if (c := _cluster(real, sim, scored, (rows[members], cols[members]), median)) is not None]
    if not found:
        return None
    defect = np.zeros(real.shape, dtype=bool)
    for c in found:
        box = far[c["rows"][0]:c["rows"][1] + 1, c["cols"][0]:c["cols"][1] + 1]
        defect[c["rows"][0]:c["rows"][1] + 1, c["cols"][0]:c["cols"][1] + 1] |= box
    squares = lambda where: float(np.sum((sim[where].astype(np.float64) - real[where]) ** 2))  # noqa: E731
    for c in found:
        span = (slice(c["rows"][0], c["rows"][1] + 1), slice(c["cols"][0], c["cols"][1] + 1))
        c["share"] = squares(tuple(np.add(np.nonzero(far[span]), [[span[0].start], [span[1].start]]))) / total
    found.sort(key=lambda c: -c["share"])
    return Defects(defect, tuple(found), squares(defect) / total)
