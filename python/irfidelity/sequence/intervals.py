"""How sure a sequence's score is: ``report.ci``, the block-bootstrap intervals of the pooled
fidelity and of every component (docs/ranking.md says what they mean).

The per-frame numbers come from each scored frame's entry (:func:`irfidelity.bootstrap.pool_numbers`:
pixel pairs, squared error — the exact integer sum when the run kept it —, the frame's SSIM
and NMI weighted by its pixel pairs, its radiometry exponent) and the curve components;
:func:`irfidelity.bootstrap.sequence_pool` pools a resample of them the way the sequence pools
(:mod:`irfidelity.sequence.pooling`), so the intervals are those of the reported values. Frames
without those numbers fall back to the frame means of the per-frame fidelity and components,
and the intervals say so (``method``).
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

from ..bootstrap import DEFAULT_RESAMPLES, POOL_INPUTS, Intervals, Pool, bootstrap_ci, pool_numbers, sequence_pool
from ..camera import KINDS
from ..errors import FidelityError
from ..fuzzy import COMPONENTS

__all__ = ["FrameNumbers", "frame_numbers", "sequence_intervals", "CURVES"]

#: Components measured once from the camera inputs: the same for every frame.
CURVES = KINDS


class FrameNumbers:
    """The per-frame numbers of a report's scored frames and the pool that pools them.

    Attributes
    ----------
    names : list of str
        The real frame of each kept frame (``frames[i]["real"]``), in index order.
    numbers : dict
        ``{name: [value per kept frame]}``.
    pool : callable or None
        :func:`irfidelity.bootstrap.sequence_pool` reading the curve components from the
        numbers; None when the numbers are frame-mean series (``fidelity`` and components).
    """

    def __init__(self, names: list, numbers: dict, pool: Pool | None):
        self.names, self.numbers, self.pool = names, numbers, pool

    def subset(self, names: list) -> FrameNumbers:
        """The numbers of the given real frames (each one of :attr:`names`), in that order."""
        row = {name: i for i, name in enumerate(self.names)}
        rows = [row[name] for name in names]
        return FrameNumbers(list(names), {k: [v[i] for i in rows] for k, v in self.numbers.items()}, self.pool)


def _curve_pool(report: Any, curves: tuple) -> Pool:
    """``sequence_pool`` of the report, its curve components read from the summed numbers
    (the fidelity is linear in them: eq. 15)."""
    weights = report.weights
    peak = 1.0 if _relative(report) else report.metrics.get("psnr_peak")
    image = sequence_pool(weights, config=report.config, peak=peak,
                          camera={k: 0.0 for k in curves})
    if not curves:
        return image

    def pool(sums: Mapping[str, float], frames: int) -> dict:
        out = dict(image(sums, frames))
        for k in curves:
            out[k] = sums[k] / frames
            out["fidelity"] += weights[k] * out[k]
        return out

    return pool


def _relative(report: Any) -> bool:
    """With ``peak="range"`` a sequence pools each frame's squared error relative to its own
    range (:mod:`irfidelity.sequence.pooling`): the numbers then hold ``SSE_i / range_i²`` and
    pool with the peak 1, the same for every simulator of a comparison."""
    return report.config.peak == "range" and "psnr" in report.components


def frame_numbers(report: Any, exact: bool = True) -> FrameNumbers:
    """The per-frame numbers of a :class:`~irfidelity.SequenceReport`'s scored frames.

    With ``exact`` and the numbers of :func:`~irfidelity.bootstrap.pool_numbers` in every scored
    frame's entry: those (the squared error as the exact integer sum when the run kept it, or
    relative to the frame's range with ``peak="range"``) and the curve components, pooled by
    ``sequence_pool``. Otherwise the per-frame ``fidelity`` and components, pooled as frame
    means.
    """
    scored = [f for f in report.frames if not f.get("error") and f.get("fidelity") is not None]
    if not scored:
        failed = [f for f in report.frames if f.get("error")]
        why = f" ({len(failed)} failed; frame {failed[0]['index']}: {failed[0]['error']})" if failed else ""
        raise FidelityError(f"the report has no scored frame{why}: no interval")
    names = [f["real"] if f.get("real") is not None else f["index"] for f in scored]
    curves = tuple(k for k in CURVES if k in report.components)
    rows = _pooled_rows(report, scored, curves) if exact else None
    if rows is not None:
        numbers: dict[str, list] = {}
        for row in rows:
            for key, value in (row | {k: report.components[k] for k in curves}).items():
                numbers.setdefault(key, []).append(value)
        return FrameNumbers(names, numbers, _curve_pool(report, curves))
    keys = [k for k in COMPONENTS if k in report.components]
    numbers = {"fidelity": [f["fidelity"] for f in scored],
               **{k: [f["components"].get(k, report.components[k]) for f in scored] for k in keys}}
    return FrameNumbers(names, numbers, None)


def _pooled_rows(report: Any, scored: list, curves: tuple) -> list[dict] | None:
    """Each scored frame's :func:`~irfidelity.bootstrap.pool_numbers`, or None when a frame lacks them."""
    pooled = [k for k in report.components if k not in curves]
    if not set(pooled) <= set(POOL_INPUTS):
        return None
    sums = report.sources.get("sums") or {}  # exact integer sums of integer frames
    relative = _relative(report)
    rows = []
    for f in scored:
        try:
            row = pool_numbers(f, pooled)
            if "psnr" in pooled and relative:
                row["sse"] /= float(f["metrics"]["psnr_peak"]) ** 2
            elif "psnr" in pooled and f["index"] in sums:
                row["sse"] = sums[f["index"]]["sse"]
        except (KeyError, TypeError, ValueError, ZeroDivisionError, FidelityError):
            return None
        rows.append(row)
    return rows


def sequence_intervals(report: Any, *, level: float = 0.95, resamples: int = DEFAULT_RESAMPLES,
                       block: int | None = None, rng: Any = 0) -> Intervals:
    """Block-bootstrap intervals of a sequence's pooled fidelity and components.

    Parameters
    ----------
    report : SequenceReport
        From :func:`irfidelity.score_sequence`, or read back from its JSON (whose frames have
        the numbers too, the squared error then as ``mse·n``).
    level, resamples, block, rng
        As in :func:`irfidelity.bootstrap.bootstrap_ci`.

    Returns
    -------
    Intervals
        ``.ci`` is what ``report.ci`` holds: ``{"fidelity": (lo, hi), component: (lo, hi)}``;
        ``.note`` (and a :class:`~irfidelity.errors.ShortRecordingWarning`) when the frames are
        too few for honest intervals.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> from irfidelity.sequence.intervals import sequence_intervals
    >>> rng = np.random.default_rng(0)
    >>> real = rng.integers(1000, 3000, (40, 16, 16)).astype(np.uint16)
    >>> sim = (real + rng.integers(0, 40, real.shape)).astype(np.uint16)
    >>> rep = irf.score_sequence(real, sim, weights="psnr=0.5,ssim=0.5", peak="range", progress=False)
    >>> ci = sequence_intervals(rep, resamples=199)
    >>> lo, hi = ci.ci["fidelity"]
    >>> bool(lo <= rep.fidelity <= hi), sorted(ci.ci)
    (True, ['fidelity', 'psnr', 'ssim'])
    """
    numbers = frame_numbers(report)
    if len(numbers.names) < 2:
        raise FidelityError(f"an interval needs at least 2 scored frames, the report has {len(numbers.names)}")
    intervals = bootstrap_ci(numbers.numbers, pool=numbers.pool, level=level, resamples=resamples, block=block,
                             rng=rng)
    how = "pooled as the sequence pools" if numbers.pool is not None else "of the frame means"
    return dataclasses.replace(intervals, method=f"{intervals.method}, {how}")
