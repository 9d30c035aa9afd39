"""Which simulator is closer, and are we sure? :func:`rank` orders simulators scored on the same
frames and says which differences are significant and how sure the order is (P(first), over the
frames' sampling and weight changes).

Significance comes from the paired block bootstrap of :mod:`irfidelity.bootstrap` (every
simulator resampled with the same blocks of frames), corrected for the number of pairs by
Holm's step-down method. Stability (``P(first)``, the mean rank) comes from the same resamples:
each is paired with a weight vector drawn from a Dirichlet distribution around ``K``, every
simulator's pooled components on the resample are weighted by it, and the simulator with the
highest fidelity is first. So two simulators that differ only by noise share the draws instead
of one of them being first under every weight vector. docs/ranking.md has what the figures mean.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .bootstrap import (DEFAULT_RESAMPLES, Linearized, Pool, PairedTest, Resampling, as_generator, check_level,
                        compare_replicates, difference_influences, frame_series, linearize, plan_resampling, resample,
                        studentized_interval)
from .errors import FidelityError
from .fuzzy import Comparison, Weights, check_draws, first_and_mean_rank, weight_draws

__all__ = ["rank", "Ranking", "holm"]

CORRECTIONS = ("holm", "none")


def holm(p_values: Mapping[Any, float]) -> dict:
    """Holm's step-down adjusted p-values (family-wise error at most the level for any dependence).

    The ``i``-th smallest of ``m`` p-values becomes ``max_{j<=i} min(1, (m − j + 1)·p_(j))``.

    Examples
    --------
    >>> from irfidelity.ranking import holm
    >>> holm({"A|B": 0.01, "A|C": 0.04, "B|C": 0.03})
    {'A|B': 0.03, 'A|C': 0.06, 'B|C': 0.06}
    """
    m = len(p_values)
    adjusted, running = {}, 0.0
    for i, key in enumerate(sorted(p_values, key=lambda k: p_values[k])):
        running = max(running, min(1.0, (m - i) * p_values[key]))
        adjusted[key] = running
    return {key: adjusted[key] for key in p_values}


@dataclass(frozen=True)
class Ranking:
    """Result of :func:`rank`.

    Attributes
    ----------
    order : list of str
        Simulators by pooled fidelity, best first.
    estimate : dict
        ``{name: {quantity: value}}`` pooled over every frame (``fidelity`` and the components).
    ci : dict
        ``{name: {quantity: (lo, hi)}}``: each simulator's own intervals at ``level``.
    pairs : dict
        ``{(a, b): PairedTest}`` for every pair, ``a`` ranked above ``b``: the difference
        ``a − b`` of every quantity, its interval and unadjusted p-value.
    p_adjusted : dict
        ``{(a, b): {quantity: p}}`` after the ``correction`` over the pairs (for each quantity
        separately).
    significance : dict
        ``{(a, b): {quantity: p_adjusted < 1 − level}}``.
    significant : dict
        ``{(a, b): bool}``: is the fidelity difference significant (``significance[..]["fidelity"]``).
    stability : Comparison or None
        The order's stability under the frames' sampling and weight changes: ``p_first`` (each
        simulator's share of the joint draws in which its pooled fidelity is highest, ties
        shared) and ``mean_rank`` over ``samples`` draws, each a block resample of the frames
        (those of the intervals and tests) with a weight vector from
        ``Dirichlet(concentration·K)``. None when no weights were given.
    level : float
    correction : str
    block, resamples, frames : int
    note : str or None
        Why the frames are too few for honest intervals, tests and P(first)
        (:func:`irfidelity.bootstrap.short_recording_note`), or None.
    """

    order: list
    estimate: dict
    ci: dict
    pairs: dict
    p_adjusted: dict
    significance: dict
    significant: dict
    stability: Comparison | None
    level: float
    correction: str
    block: int
    resamples: int
    frames: int
    note: str | None = None

    def is_significant(self, a: str, b: str, quantity: str = "fidelity") -> bool:
        """Whether simulators ``a`` and ``b`` (either order) differ significantly in ``quantity``."""
        key = (a, b) if (a, b) in self.significance else (b, a)
        if key not in self.significance:
            raise FidelityError(f"no pair ({a!r}, {b!r}); simulators are {self.order}")
        return self.significance[key][quantity]

    def to_dict(self) -> dict:
        return {
            "order": list(self.order), "estimate": {n: dict(v) for n, v in self.estimate.items()},
            "ci": {n: {q: list(v) for q, v in c.items()} for n, c in self.ci.items()},
            "pairs": [{"a": a, "b": b, **test.to_dict(), "p_adjusted": dict(self.p_adjusted[(a, b)]),
                       "significance": dict(self.significance[(a, b)])} for (a, b), test in self.pairs.items()],
            "stability": None if self.stability is None else self.stability.to_dict(),
            "level": self.level, "correction": self.correction, "block": self.block,
            "resamples": self.resamples, "frames": self.frames, "note": self.note}

    def summary_text(self) -> str:
        lines = [f"{'simulator':<24} {'fidelity':>9} {'interval':>19}"]
        for name in self.order:
            lo, hi = self.ci[name]["fidelity"]
            lines.append(f"{name:<24} {self.estimate[name]['fidelity']:>9.4f} [{lo:.4f}, {hi:.4f}]")
        for (a, b), test in self.pairs.items():
            verdict = "significant" if self.significant[(a, b)] else "not significant"
            p = self.p_adjusted[(a, b)]["fidelity"]
            lines.append(f"{a} − {b}: {test.difference['fidelity']:+.4f}, p = {p:.3g} ({self.correction}): {verdict}")
        lines.append(f"level {self.level:g}; {self.resamples} resamples of {self.frames} frames in blocks of "
                     f"{self.block}")
        if self.stability is not None:
            lines.append("P(first) over frame resamples and weight draws: " +
                         ", ".join(f"{n} {self.stability.p_first[n]:.3f}" for n in self.stability.ranking))
        if self.note is not None:
            lines.append(f"note: {self.note}")
        return "\n".join(lines)


def _with_fidelity(per_frame: Mapping[str, Any], weights: Weights | None, name: str) -> Mapping[str, Any]:
    """The per-frame series, with ``fidelity`` computed from the components when absent."""
    if "fidelity" in per_frame:
        return per_frame
    if weights is None:
        raise FidelityError(f"per_frame[{name!r}] has no 'fidelity' series: give it, or weights= to compute it "
                            f"from the components")
    missing = [k for k in weights.active() if k not in per_frame]
    if missing:
        raise FidelityError(f"per_frame[{name!r}] has no 'fidelity' and no series for weighted component(s) "
                            f"{missing}")
    series = {k: np.asarray(per_frame[k], dtype=np.float64) for k in weights.active()}
    fidelity = sum(weights[k] * v for k, v in series.items())
    return {"fidelity": fidelity, **per_frame}


def _weighted_draws(draws: Mapping[str, Mapping[str, np.ndarray]], components: tuple) -> np.ndarray:
    """Every simulator's pooled value of each weighted component on every resample: resamples ×
    simulators × components."""
    for name, quantities in draws.items():
        missing = [k for k in components if k not in quantities]
        if missing:
            raise FidelityError(f"per_frame[{name!r}] gives no {missing}: P(first) weighs every weighted component "
                                f"on each resample; give their per-frame series (or a pool that returns them)")
    return np.stack([np.column_stack([draws[n][k] for k in components]) for n in draws], axis=1)


def _stability(estimate: Mapping[str, Mapping[str, float]], draws: Mapping[str, Mapping[str, np.ndarray]],
               weights: Weights | None, resampling: Resampling, samples: int, concentration: float,
               generator: np.random.Generator) -> Comparison | None:
    """P(first) and mean rank over ``samples`` joint draws: draw ``j`` weighs every simulator's
    pooled components on frame resample ``j mod resamples`` by weight vector ``j``."""
    if weights is None:
        return None
    components = weights.active()
    values = _weighted_draws(draws, components)[np.arange(samples) % resampling.resamples]
    scores = np.einsum("jsc,jc->js", values, weight_draws(weights, components, samples, concentration, generator))
    p_first, mean_rank = first_and_mean_rank(scores)
    names = list(draws)
    fidelity = {n: math.fsum(weights[k] * estimate[n][k] for k in components) for n in names}
    return Comparison(ranking=sorted(names, key=lambda n: -fidelity[n]), fidelity=fidelity,
                      p_first={n: float(p) for n, p in zip(names, p_first)},
                      mean_rank={n: float(r) for n, r in zip(names, mean_rank)}, weights=weights, samples=samples,
                      concentration=concentration, components=components, frames=resampling.frames,
                      block=resampling.block)


def _frame_series(per_frame: Mapping[str, Any], pool: Pool | None, weights: Weights | None) -> dict:
    """Each simulator's validated per-frame numbers, ``{name: FrameSeries}``, on the same frames."""
    if not isinstance(per_frame, Mapping) or len(per_frame) < 2:
        raise FidelityError("rank needs a mapping of at least two simulators {name: {series: per-frame values}}")
    series = {}
    for name, given in zip(map(str, per_frame), per_frame.values()):
        if not isinstance(given, Mapping):
            raise FidelityError(f"per_frame[{name!r}] must be a mapping {{series: per-frame values}}")
        series[name] = frame_series(given if pool is not None else _with_fidelity(given, weights, name),
                                    f"per_frame[{name!r}]")
    lengths = {n: s.frames for n, s in series.items()}
    if len(set(lengths.values())) != 1:
        raise FidelityError(f"every simulator must be scored on the same frames; frame counts {lengths}")
    return series


def _pair_tests(order: list, lins: Mapping[str, Linearized], draws: Mapping[str, dict], resampling: Resampling,
                level: float, correction: str) -> tuple[dict, dict]:
    """Every pair's paired test (``a`` ranked above ``b``) and its p-values after ``correction``,
    each quantity corrected over the pairs."""
    pairs: dict[tuple, PairedTest] = {}
    for i, a in enumerate(order):
        for b in order[i + 1:]:
            pairs[(a, b)] = compare_replicates((lins[a], draws[a]), (lins[b], draws[b]), resampling, level)
    p_adjusted: dict[tuple, dict] = {pair: {} for pair in pairs}
    for q in lins[order[0]].estimate:
        raw = {pair: test.p_value[q] for pair, test in pairs.items()}
        for pair, p in (holm(raw) if correction == "holm" else raw).items():
            p_adjusted[pair][q] = p
    return pairs, p_adjusted


def rank(per_frame: Mapping[str, Mapping[str, Any]], *, pool: Pool | None = None, weights: Any = None,
         level: float = 0.95, correction: str = "holm", resamples: int = DEFAULT_RESAMPLES,
         block: int | None = None, rng: Any = 0, samples: int = 2000, concentration: float = 50.0) -> Ranking:
    """Order simulators scored on the same frames, with significance and stability.

    Parameters
    ----------
    per_frame : {simulator: {name: 1-D array}}
        Each simulator's per-frame numbers, over the same real frames in the same order
        (:func:`irfidelity.bootstrap.bootstrap_ci` says what they can be). Without ``pool`` the
        quantities are frame means and must include ``fidelity``, or ``weights`` and the
        weighted components to compute it frame by frame.
    pool : callable, optional
        As in :func:`~irfidelity.bootstrap.bootstrap_ci` (e.g.
        :func:`~irfidelity.bootstrap.sequence_pool`); it must return ``fidelity``.
    weights : Weights or anything :meth:`Weights.coerce` accepts, optional
        ``K``: enables the stability (P(first), mean rank: it needs every weighted component,
        per frame or from the pool) and the per-frame fidelity when absent.
    level : float
        Confidence level of the intervals; a difference is significant when its adjusted
        p-value is below ``1 − level``.
    correction : "holm" or "none"
        Multiple-comparison correction over the ``k(k−1)/2`` pairs, for each quantity.
    resamples, block, rng
        As in :func:`~irfidelity.bootstrap.bootstrap_ci`; one set of resamples serves every
        simulator (the block length: :func:`~irfidelity.bootstrap.block_length` of every
        simulator's linearisations and of every pair's differences). ``rng`` also draws the
        stability's weight vectors, after the resamples.
    samples, concentration
        The stability's joint draws: draw ``j`` takes frame resample ``j mod resamples`` (the
        resamples of the intervals and tests, so each is used once at the defaults) and a weight
        vector from ``Dirichlet(concentration·K)`` (as in :func:`irfidelity.fuzzy.compare`);
        each simulator's fidelity on the draw is its pooled components on the resample weighted
        by the vector. ``stability.p_first`` is each simulator's share of the draws in which it
        is first.

    Returns
    -------
    Ranking
        ``ranking.note`` (and a :class:`~irfidelity.errors.ShortRecordingWarning`) when the
        frames are too few for honest intervals (:func:`irfidelity.bootstrap.short_recording_note`).

    Examples
    --------
    Three simulators of one scene; B and C differ only by noise:

    >>> import numpy as np
    >>> from irfidelity.ranking import rank
    >>> rng = np.random.default_rng(4)
    >>> scene = 0.02 * np.convolve(rng.normal(size=102), np.ones(3) / 3, "valid")
    >>> frames = {name: {"fidelity": mean + scene + rng.normal(0, 0.003, 100)}
    ...           for name, mean in (("A", 0.93), ("B", 0.90), ("C", 0.90))}
    >>> r = rank(frames)
    >>> r.order[0], r.is_significant("A", "B"), r.is_significant("B", "C")
    ('A', True, False)

    With weights, P(first) counts the frames' sampling with the weights' changes: two
    simulators equal up to noise share the draws (weights alone would put the one ahead on
    both components first under every weight vector):

    >>> frames = {name: {"psnr": 0.90 + scene + rng.normal(0, 0.003, 100),
    ...                  "ssim": 0.90 + rng.normal(0, 0.003, 100)} for name in ("B", "C")}
    >>> p = rank(frames, weights="psnr=0.5,ssim=0.5").stability.p_first
    >>> round(p["B"], 2), round(p["C"], 2)
    (0.67, 0.33)
    """
    level = check_level(level)
    if correction not in CORRECTIONS:
        raise FidelityError(f"correction must be one of {CORRECTIONS}, got {correction!r}", option="correction")
    samples, concentration = check_draws(samples, concentration)
    w = None if weights is None else Weights.coerce(weights)
    series = _frame_series(per_frame, pool, w)
    lins = {n: linearize(s, pool) for n, s in series.items()}
    for n, lin in lins.items():
        if "fidelity" not in lin.estimate:
            raise FidelityError(f"pool gives no 'fidelity' for {n!r}: it must return the fidelity")
    frames = next(iter(series.values())).frames
    generator = as_generator(rng)  # the resamples, then the stability's weight vectors
    resampling = plan_resampling(difference_influences(list(lins.values())), frames, block, resamples, generator)
    draws = {n: resample(s, resampling, pool) for n, s in series.items()}
    estimate = {n: dict(lin.estimate) for n, lin in lins.items()}
    order = sorted(series, key=lambda n: -estimate[n]["fidelity"])
    ci = {n: {q: studentized_interval(lins[n].estimate[q], draws[n][q], lins[n].influence[q], resampling, level)
              for q in lins[n].estimate} for n in series}
    pairs, p_adjusted = _pair_tests(order, lins, draws, resampling, level, correction)
    significance = {pair: {q: p < 1 - level for q, p in ps.items()} for pair, ps in p_adjusted.items()}
    return Ranking(order=order, estimate=estimate, ci=ci, pairs=pairs, p_adjusted=p_adjusted,
                   significance=significance, significant={pair: s["fidelity"] for pair, s in significance.items()},
                   stability=_stability(estimate, draws, w, resampling, samples, concentration, generator),
                   level=level, correction=correction, block=resampling.block, resamples=resampling.resamples,
                   frames=frames, note=resampling.note)
