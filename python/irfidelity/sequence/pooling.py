"""The pooled result of a sequence: the metrics of the merged statistics of every scored frame.

PSNR comes from ΣSSE/ΣN (not a mean of dB values) and SSIM from the pooled moments, exactly
for integer frames. Statistics are merged in frame-index order whatever order frames finish
in, so float results do not depend on scheduling. NMI pools only when every frame was binned
on the same edges (``hist_range="full"``, an explicit ``(lo, hi)`` or ``bins="levels"``);
with the default ``"data"`` each frame is binned over its own range and the pooled NMI is the
mean of the frames' NMI.

A frame's range (max − min of its real frame) scales its error: the pooled RMS error relative
to the range is ``sqrt(Σ SSE_i/range_i² / Σ N_i)``, each frame's squared error relative to its own
range, so it lies within the frames' values; with ``peak="range"`` the pooled PSNR is
``10·log10(Σ N_i / Σ SSE_i/range_i²)``, the pixel-weighted mean of the frames' ``MSE/peak²``, and
lies within the frames' PSNRs too (its ``psnr_peak`` is the effective range: the RMS of the
pooled errors over the pooled relative RMS error).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..registration import LOW_CONFIDENCE
from ..scoring import Score, image_components, psnr_peak, score_components
from ..stats import PairStats, merge_all
from ..temperature import pooled_metrics, temperature_scores
from .plan import SequencePlan

__all__ = ["Pool", "frame_statistics", "registration_summary"]

_PERCENTILES = (5, 50, 95)


class Pool:
    """Merges frame statistics in index order as they arrive."""

    def __init__(self, plan: SequencePlan):
        self.plan = plan
        self.pending: dict[int, PairStats | None] = {}
        self.next = 0
        self.merged: PairStats | None = None
        self.extent: tuple[float, float] | None = None  # the real frames' (min, max)
        self.relative_sse = 0.0  # Σ SSE_i / range_i² over the frames with a range
        self.relative_n = 0  # Σ N_i over those frames

    def add(self, index: int, stats: PairStats | None, real_extent: tuple[float, float] | None = None) -> None:
        """Stats of frame ``index`` (None for a failed frame)."""
        self.pending[index] = None if stats is None else stats.with_peak(None)
        if stats is not None and real_extent is not None:
            lo, hi = real_extent
            self.extent = (lo, hi) if self.extent is None else (min(self.extent[0], lo), max(self.extent[1], hi))
            if hi > lo and stats.n and "psnr" in self.plan.image:
                self.relative_sse += stats.mse() * stats.n / (hi - lo) ** 2
                self.relative_n += stats.n
        run = [] if self.merged is None else [self.merged]
        while self.next in self.pending:
            item = self.pending.pop(self.next)
            if item is not None:
                run.append(item)
            self.next += 1
        if len(run) > (self.merged is not None):
            self.merged = merge_all(run, histograms=self.plan.keep_hist)

    def scene_range(self) -> float | None:
        """The range that makes the pooled MSE's relative error the frames' pooled one (see the
        module notes); the real sequence's whole range when there is no error to weigh."""
        if self.merged is None or "psnr" not in self.plan.image:
            return None
        mse = self.merged.mse()
        if self.relative_n and self.relative_sse > 0 and mse > 0:
            return math.sqrt(mse * self.relative_n / self.relative_sse)
        return None if self.extent is None else self.extent[1] - self.extent[0]

    def _peak(self) -> float | None:
        plan = self.plan
        if "psnr" not in plan.image:
            return None
        if plan.config.peak != "range":
            return plan.peak
        return psnr_peak(plan.config, plan.default_peak, self.scene_range(), where="the real sequence")

    def result(self, frames: list[dict]) -> tuple[Score | None, dict]:
        """The pooled score (None when no frame was scored) and how it was pooled."""
        plan = self.plan
        scored = [f for f in frames if f["error"] is None]
        pooling: dict[str, Any] = {"frames": len(scored), "n": 0, "nmi": None}
        if self.merged is None or self.merged.n == 0:
            return None, pooling
        pooling["n"] = int(self.merged.n)
        hist_pooled = "nmi" in plan.image and plan.keep_hist
        image = tuple(c for c in plan.image if c != "nmi" or hist_pooled)
        stats = self.merged.with_peak(self._peak())
        comps, metrics = image_components(stats, image, plan.config)
        if "nmi" in plan.image:
            pooling["nmi"] = "histogram" if hist_pooled else "frame_mean"
            if not hist_pooled:
                for key in ("nmi", "mi", "h_real", "h_sim", "h_joint"):
                    metrics[key] = math.fsum(f["metrics"][key] for f in scored) / len(scored)
                comps["nmi"] = metrics["nmi"]
        errors = pooled_metrics(f["metrics"] for f in scored)
        if errors is not None:  # scored in a unit: from the frames' sums
            temperature_comps, temperature_metrics = temperature_scores(errors, plan.weights)
            comps, metrics = comps | temperature_comps, metrics | temperature_metrics
        score = score_components(comps | plan.camera_components, metrics | plan.camera_metrics, plan.weights,
                                 plan.config, scene_range=self.scene_range() or plan.scene_range,
                                 ceiling=plan.ceiling, ceiling_source=plan.ceiling_source)
        return score, pooling


def _percentiles(values: list[float]) -> dict:
    a = np.asarray(values, dtype=float)
    a = a[~np.isnan(a)]
    if a.size == 0:
        return {}
    method = "linear" if np.all(np.isfinite(a)) else "nearest"
    ps = np.percentile(a, _PERCENTILES, method=method)
    out = {"mean": float(np.mean(a))}
    out.update({f"p{q}": float(v) for q, v in zip(_PERCENTILES, ps)})
    out.update(min=float(a.min()), max=float(a.max()))
    return out


def frame_statistics(frames: list[dict]) -> dict:
    """Mean, percentiles, min and max over the scored frames of the fidelity, each component
    and each metric: ``{"fidelity": {...}, "components": {name: {...}}, "metrics": {name: {...}}}``."""
    scored = [f for f in frames if f["error"] is None]
    out: dict[str, Any] = {"fidelity": _percentiles([f["fidelity"] for f in scored]), "components": {},
                           "metrics": {}}
    for group in ("components", "metrics"):
        keys = dict.fromkeys(k for f in scored for k, v in f[group].items() if isinstance(v, (int, float)))
        for k in keys:
            stats = _percentiles([f[group][k] for f in scored if isinstance(f[group].get(k), (int, float))])
            if stats:
                out[group][k] = stats
    return out


def registration_summary(plan: SequencePlan, frames: list[dict]) -> dict | None:
    """``report.registration`` of a sequence: the one registration applied to every pair
    (:meth:`~irfidelity.Registration.to_dict`), or with ``register_each`` the spread of the frames' own —
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
