"""The pooled result of a sequence: every pooled component lies within its frames' values.

Each component pools so that the pooled value lies within ``[min, max]`` of the scored frames'
values by construction (``docs/design.md`` §11, "Pooled values inside their frames"):

* **psnr** (and the RMS error it is graded by) from the frames' squared errors:
  ``ΣSSE_i/ΣN_i`` for a fixed peak, exactly for integer frames (one rounding of the exact
  ratio); with ``peak="range"`` each frame's squared error relative to its own real frame's
  range, ``10·log10(Σ N_i / Σ SSE_i/range_i²)``. Both are pixel-weighted means of the frames'
  ``MSE/peak²``, and PSNR is monotone in it. The RMS error relative to the range pools as
  ``sqrt(Σ SSE_i/range_i² / Σ N_i)`` with any peak (``psnr_peak`` is then the effective range:
  the RMS of the pooled errors over the pooled relative RMS error).
* **ssim** and **nmi**: the pixel-weighted mean ``Σ N_i·x_i / Σ N_i`` of the frames' values, and
  the same for their raw metrics (``ssim_luminance``, ``mi``, ``h_joint``, ...). Not the SSIM
  of the pooled moments nor the NMI of a pooled joint histogram: those treat the frames as one
  image, so on a moving or panning scene the spread between frames counts as contrast (or as
  joint-histogram spread), and the value can lie outside every frame's — on a pan of the test
  recording the moment-pooled SSIM was 0.879 against frames' 0.905–0.914.
* **radiometry**: ``0.9`` to the pixel-weighted mean of the frames' exponents
  ``(bias_i² + rmse_i²)/(2·tolerance²)`` (:func:`irfidelity.temperature.pooled_radiometry`),
  so opposite offsets of two frames do not cancel; the ``temperature_*`` metrics are those of
  all pixel pairs together.
* the camera components (mtf, sitf, noise, mrtd) are measured once for the camera, not per
  frame: the pooled value is that value.

Sums are exact (integer sums, :func:`math.fsum`) and rounded once; a weighted mean is kept
within its frames' values against that last rounding. Statistics are merged in frame-index
order whatever order frames finish in, so float results do not depend on scheduling.

Frames weigh by their pixel pairs ``N_i`` (they differ when registration overlaps or masks
do), the weight ΣSSE/ΣN gives them, so that every component weighs the frames alike.

The pooled fidelity is eq. 15 of the pooled components. SSIM, NMI and the camera components
are linear in the frames' values, normalised PSNR and radiometry are not (a log and a power of
a mean), so the pooled fidelity is the pixel-weighted mean of the frames' fidelities plus the
weighted departure of those two components from their own pixel-weighted means, and lies
outside the frames' fidelities by at most those components' weighted spread over the frames
(docs/interpretation.md has how far it went).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np

from ..registration import LOW_CONFIDENCE
from ..scoring import Score, image_components, psnr_peak, score_components
from ..stats import PairStats, merge_all
from ..system.scene import unassessed
from ..temperature import pooled_temperature_scores
from .entry import FrameEntry
from .plan import SequencePlan

__all__ = ["Pool", "FrameColumns", "pixel_mean", "frame_statistics", "registration_summary"]

#: The raw metrics pooled, like their component, as the pixel-weighted mean of the frames'.
MEAN_METRICS = {"nmi": ("nmi", "mi", "h_real", "h_sim", "h_joint"),
                "ssim": ("ssim", "ssim_luminance", "ssim_contrast", "ssim_structure")}

_PERCENTILES = (5, 50, 95)


class Pool:
    """Merges frame statistics in index order as they arrive."""

    def __init__(self, plan: SequencePlan):
        self.plan = plan
        self.pending: dict[int, PairStats | None] = {}
        self.next = 0
        self.merged: PairStats | None = None
        self.extent: tuple[float, float] | None = None  # the real frames' (min, max)
        self.relative_terms: list[float] = []  # SSE_i / range_i² of the frames with a range (fsum: any order)
        self.relative_n = 0  # Σ N_i over those frames

    def add(self, index: int, stats: PairStats | None, real_extent: tuple[float, float] | None = None) -> None:
        """Stats of frame ``index`` (None for a failed frame)."""
        self.pending[index] = None if stats is None else stats.with_peak(None)
        if stats is not None and real_extent is not None:
            lo, hi = real_extent
            self.extent = (lo, hi) if self.extent is None else (min(self.extent[0], lo), max(self.extent[1], hi))
            if hi > lo and stats.n and "psnr" in self.plan.image:
                self.relative_terms.append(stats.mse() * stats.n / (hi - lo) ** 2)
                self.relative_n += stats.n
        run = [] if self.merged is None else [self.merged]
        while self.next in self.pending:
            item = self.pending.pop(self.next)
            if item is not None:
                run.append(item)
            self.next += 1
        if len(run) > (self.merged is not None):
            self.merged = merge_all(run, histograms=False)  # no pooled component reads a histogram

    def scene_range(self) -> float | None:
        """The range that makes the pooled MSE's relative error the frames' pooled one (see the
        module notes); the real sequence's whole range when there is no error to weigh."""
        if self.merged is None or "psnr" not in self.plan.image:
            return None
        mse = self.merged.mse()
        relative_sse = math.fsum(self.relative_terms)  # correctly rounded: the same in any finishing order
        if self.relative_n and relative_sse > 0 and mse > 0:
            return math.sqrt(mse * self.relative_n / relative_sse)
        return None if self.extent is None else self.extent[1] - self.extent[0]

    def _peak(self) -> float | None:
        plan = self.plan
        if "psnr" not in plan.image:
            return None
        if plan.config.peak != "range":
            return plan.peak
        return psnr_peak(plan.config, plan.default_peak, self.scene_range(), where="the real sequence")

    def result(self, scored: FrameColumns) -> tuple[Score | None, dict]:
        """The pooled score (None when no frame was scored) and how it was pooled."""
        plan = self.plan
        pooling: dict[str, Any] = {"frames": len(scored), "n": 0}
        if self.merged is None or self.merged.n == 0:
            return None, pooling
        pooling["n"] = int(self.merged.n)
        psnr = tuple(c for c in plan.image if c == "psnr")
        comps, metrics = image_components(self.merged.with_peak(self._peak()), psnr, plan.config)
        counts = scored.counts()
        for component in (c for c in plan.image if c in MEAN_METRICS):
            pooling[component] = "pixel_mean"
            comps[component] = pixel_mean(scored.column("components", component), counts)
            metrics.update({key: pixel_mean(scored.column("metrics", key), counts) for key in MEAN_METRICS[component]})
        temperature = None if plan.config.unit is None else pooled_temperature_scores(
            (f.metrics for f in scored.frames), plan.weights)
        if temperature is not None:  # scored in a unit
            comps, metrics = comps | temperature[0], metrics | temperature[1]
        all_metrics = metrics | plan.camera_metrics
        score = score_components(comps | plan.camera_components, all_metrics, plan.weights,
                                 plan.config, scene_range=self.scene_range() or plan.scene_range,
                                 ceiling=plan.ceiling, ceiling_source=plan.ceiling_source,
                                 unassessed=unassessed(plan.skipped, all_metrics))
        return score, pooling


def pixel_mean(values: np.ndarray, counts: np.ndarray) -> float:
    """``Σ N_i·x_i / Σ N_i`` of the frames' ``values`` weighted by their pixel pairs ``counts``
    (``metrics["n"]``): an exact sum (:func:`math.fsum`) rounded once, kept within
    ``[min, max]`` of the frames' values against that rounding."""
    products = (counts.astype(float) * values).tolist()  # each N_i·x_i rounded once, as in Python
    mean = math.fsum(products) / int(counts.sum())
    return min(max(mean, float(values.min())), float(values.max()))


class FrameColumns:
    """The scored frames of a sequence, and each number of their ``components`` and
    ``metrics`` as a float64 column in frame order (made once, read by the pooling and the
    frame statistics). ``fixed`` holds the values every scored frame shares (the camera's
    components and metrics, by group): their columns are not read frame by frame."""

    def __init__(self, frames: Sequence[FrameEntry], fixed: Mapping[str, Mapping[str, Any]] | None = None):
        self.frames = [f for f in frames if f.error is None]
        self.fixed = {group: dict((fixed or {}).get(group, {})) for group in ("components", "metrics")}
        self.groups = {"components": _numeric_columns([f.components for f in self.frames], self.fixed["components"]),
                       "metrics": _numeric_columns([f.metrics for f in self.frames], self.fixed["metrics"])}

    def __len__(self) -> int:
        return len(self.frames)

    def column(self, group: str, key: str) -> np.ndarray:
        """The values of ``frame[group][key]``, one for each frame."""
        values = self.groups[group][key]
        if len(values) != len(self.frames):
            raise ValueError(f"internal: {len(values)} of {len(self.frames)} frames have {group}[{key!r}]")
        return values

    def counts(self) -> np.ndarray:
        """Each frame's pixel pairs ``metrics["n"]`` (int64)."""
        return self.column("metrics", "n").astype(np.int64)  # counts below 2^53: exact in float64


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float))


def _numeric_columns(rows: list[Mapping], fixed: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Each key's numbers (``int`` or ``float``, bools as 0/1) over ``rows`` as float64, keys in
    order of first use; a row without the key, or with another kind of value, is left out.
    A key of ``fixed`` has that value in every row."""
    keys = list(rows[0]) if rows else []
    if not keys or set(map(len, rows)) != {len(keys)}:
        return _filtered_columns(rows)
    varying = [k for k in keys if k not in fixed]
    try:
        table = _number_table(rows, varying)
    except KeyError:  # rows with different keys
        return _filtered_columns(rows)
    out = {}
    for key in keys:
        if key in fixed:
            if _is_number(fixed[key]):
                out[key] = np.full(len(rows), float(fixed[key]))
        elif key in table:
            out[key] = table[key]
        else:
            numbers = [v for v in (row[key] for row in rows) if _is_number(v)]
            if numbers:
                out[key] = np.asarray(numbers, dtype=float)
    return out


def _number_table(rows: list[Mapping], keys: list[str]) -> dict[str, np.ndarray]:
    """The columns of ``keys`` in which every row holds a number, read in one pass when all of
    them do (else key by key); a KeyError when a row lacks a key."""
    if len(keys) > 1:
        table = _numbers(list(map(operator.itemgetter(*keys), rows)), (len(rows), len(keys)))
        if table is not None:
            return dict(zip(keys, table.T))
    out = {}
    for key in keys:
        column = _numbers([row[key] for row in rows], (len(rows),))
        if column is not None:
            out[key] = column
    return out


def _numbers(values: list, shape: tuple[int, ...]) -> np.ndarray | None:
    """``values`` as float64 of ``shape`` when every value is a number (bools as 0/1), else
    None (a string, None, a list or an integer past int64 among them)."""
    try:
        array = np.array(values)
    except ValueError:  # ragged: lists of different lengths
        return None
    return array.astype(float) if array.dtype.kind in "biuf" and array.shape == shape else None


def _filtered_columns(rows: list[Mapping]) -> dict[str, np.ndarray]:
    """:func:`_numeric_columns` of rows whose keys differ, value by value."""
    columns: dict[str, list] = {}
    for row in rows:
        for k, v in row.items():
            if _is_number(v):
                columns.setdefault(k, []).append(v)
    return {k: np.asarray(v, dtype=float) for k, v in columns.items()}


def _percentiles(values: Sequence[Any] | np.ndarray) -> dict:
    a = np.asarray(values, dtype=float)
    a = a[~np.isnan(a)]
    if a.size == 0:
        return {}
    method: Literal["linear", "nearest"] = "linear" if np.all(np.isfinite(a)) else "nearest"
    ps = np.percentile(a, _PERCENTILES, method=method)
    out = {"mean": float(np.mean(a))}
    out.update({f"p{q}": float(v) for q, v in zip(_PERCENTILES, ps)})
    out.update(min=float(a.min()), max=float(a.max()))
    return out


def frame_statistics(scored: FrameColumns) -> dict:
    """Mean, percentiles, min and max over the scored frames of the fidelity, each component
    and each metric: ``{"fidelity": {...}, "components": {name: {...}}, "metrics": {name: {...}}}``."""
    out: dict[str, Any] = {"fidelity": _percentiles([f.fidelity for f in scored.frames])}
    for group, columns in scored.groups.items():
        fixed = scored.fixed[group]
        out[group] = {k: stats for k, values in columns.items()
                      if (stats := _percentiles(values[:1] if k in fixed else values))}
    return out


def registration_summary(plan: SequencePlan, frames: Sequence[Mapping]) -> dict | None:
    """``report.registration`` of a sequence: the one registration applied to every pair
    (:meth:`~irfidelity.registration.Registration.to_dict`), or with ``register_each`` the spread of the frames' own —
    ``model``, ``method`` (asked), ``frames`` registered, ``unsure`` (indices below
    ``low_confidence``), and mean/percentiles/min/max of
    ``shift_dy``, ``shift_dx``, ``angle``, ``scale``, ``confidence``, ``overlap``."""
    cfg = plan.config
    if cfg.register is None:
        return None
    if not cfg.register_each:
        return None if plan.registration is None else plan.registration.to_dict()
    regs = [(f["index"], f["registration"]) for f in frames if f["error"] is None and f.get("registration")]
    values = {"shift_dy": [r["shift"][0] for _, r in regs], "shift_dx": [r["shift"][1] for _, r in regs]}
    values.update({k: [r[k] for _, r in regs] for k in ("angle", "scale", "confidence", "overlap")})
    return {"model": cfg.register, "method": cfg.register_method, "each": True, "frames": len(regs),
            "low_confidence": LOW_CONFIDENCE, "unsure": [i for i, r in regs if r["confidence"] < LOW_CONFIDENCE],
            **{k: _percentiles(v) for k, v in values.items()}}
