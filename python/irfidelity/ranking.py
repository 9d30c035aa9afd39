"""Which simulator is closer, and are we sure? :func:`rank` orders simulators scored on the same
frames and says which differences are significant and how stable the order is under weight changes.

Significance comes from the paired block bootstrap of :mod:`irfidelity.bootstrap` (every
simulator resampled with the same blocks of frames), corrected for the number of pairs by
Holm's step-down method; stability from :func:`irfidelity.fuzzy.compare` (Dirichlet samples of
the weights around ``K``). docs/ranking.md has what the figures mean.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any, Mapping

import numpy as np

from .bootstrap import (DEFAULT_RESAMPLES, Pool, PairedTest, check_level, compare_replicates, difference_influences,
                        frame_series, linearize, plan_resampling, resample, studentized_interval)
from .errors import FidelityError
from .fuzzy import COMPONENTS, Comparison, Weights, compare

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
        The order's stability under weight changes (:func:`irfidelity.fuzzy.compare` on the
        pooled components): ``p_first``, ``mean_rank``. None when no weights were given.
    level : float
    correction : str
    block, resamples, frames : int
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
            "resamples": self.resamples, "frames": self.frames}

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
            lines.append("P(first) under weight changes: " +
                         ", ".join(f"{n} {self.stability.p_first[n]:.3f}" for n in self.stability.ranking))
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


def _stability(estimate: Mapping[str, Mapping[str, float]], weights: Weights | None, samples: int,
               concentration: float, seed: int | None) -> Comparison | None:
    if weights is None:
        return None
    reports = {name: SimpleNamespace(components={k: v for k, v in values.items() if k in COMPONENTS},
                                     weights=weights) for name, values in estimate.items()}
    return compare(reports, weights=weights, samples=samples, concentration=concentration, seed=seed)


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
        ``K``: enables the stability test (:func:`irfidelity.fuzzy.compare` on the pooled
        components) and the per-frame fidelity when absent.
    level : float
        Confidence level of the intervals; a difference is significant when its adjusted
        p-value is below ``1 − level``.
    correction : "holm" or "none"
        Multiple-comparison correction over the ``k(k−1)/2`` pairs, for each quantity.
    resamples, block, rng
        As in :func:`~irfidelity.bootstrap.bootstrap_ci`; one set of resamples serves every
        simulator (the block length: :func:`~irfidelity.bootstrap.block_length` of every
        simulator's linearisations and of every pair's differences).
    samples, concentration
        Weight samples for the stability test (as in :func:`irfidelity.fuzzy.compare`; its
        seed is ``rng`` when an integer, else 0).

    Returns
    -------
    Ranking

    Examples
    --------
    Three simulators of one scene; B and C differ only by noise:

    >>> import numpy as np
    >>> from irfidelity.ranking import rank
    >>> rng = np.random.default_rng(3)
    >>> scene = 0.02 * np.sin(np.arange(100) / 6.0)
    >>> frames = {name: {"fidelity": mean + scene + rng.normal(0, 0.003, 100)}
    ...           for name, mean in (("A", 0.93), ("B", 0.90), ("C", 0.90))}
    >>> r = rank(frames)
    >>> r.order[0], r.is_significant("A", "B"), r.is_significant("B", "C")
    ('A', True, False)
    """
    if not isinstance(per_frame, Mapping) or len(per_frame) < 2:
        raise FidelityError("rank needs a mapping of at least two simulators {name: {series: per-frame values}}")
    level = check_level(level)
    if correction not in CORRECTIONS:
        raise FidelityError(f"correction must be one of {CORRECTIONS}, got {correction!r}", option="correction")
    w = None if weights is None else Weights.coerce(weights)
    names = [str(n) for n in per_frame]
    series = {}
    for name, given in zip(names, per_frame.values()):
        if not isinstance(given, Mapping):
            raise FidelityError(f"per_frame[{name!r}] must be a mapping {{series: per-frame values}}")
        series[name] = frame_series(given if pool is not None else _with_fidelity(given, w, name),
                                    f"per_frame[{name!r}]")
    lengths = {n: s.frames for n, s in series.items()}
    if len(set(lengths.values())) != 1:
        raise FidelityError(f"every simulator must be scored on the same frames; frame counts {lengths}")
    lins = {n: linearize(s, pool) for n, s in series.items()}
    for n, lin in lins.items():
        if "fidelity" not in lin.estimate:
            raise FidelityError(f"pool gives no 'fidelity' for {n!r}: it must return the fidelity")
    frames = next(iter(lengths.values()))
    resampling = plan_resampling(difference_influences(list(lins.values())), frames, block, resamples, rng)
    draws = {n: resample(s, resampling, pool) for n, s in series.items()}
    estimate = {n: dict(lin.estimate) for n, lin in lins.items()}
    order = sorted(names, key=lambda n: -estimate[n]["fidelity"])
    ci = {n: {q: studentized_interval(lins[n].estimate[q], draws[n][q], lins[n].influence[q], resampling, level)
              for q in lins[n].estimate} for n in names}
    pairs: dict[tuple, PairedTest] = {}
    for i, a in enumerate(order):
        for b in order[i + 1:]:
            pairs[(a, b)] = compare_replicates((lins[a], draws[a]), (lins[b], draws[b]), resampling, level)
    quantities = list(lins[order[0]].estimate)
    p_adjusted: dict[tuple, dict] = {pair: {} for pair in pairs}
    for q in quantities:
        raw = {pair: test.p_value[q] for pair, test in pairs.items()}
        for pair, p in (holm(raw) if correction == "holm" else raw).items():
            p_adjusted[pair][q] = p
    alpha = 1 - level
    significance = {pair: {q: p < alpha for q, p in ps.items()} for pair, ps in p_adjusted.items()}
    seed = int(rng) if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) else 0
    return Ranking(order=order, estimate=estimate, ci=ci, pairs=pairs, p_adjusted=p_adjusted,
                   significance=significance, significant={pair: s["fidelity"] for pair, s in significance.items()},
                   stability=_stability(estimate, w, samples, concentration, seed), level=level,
                   correction=correction, block=resampling.block, resamples=resampling.resamples, frames=frames)

