"""The fuzzy layer (paper §3): weights K, the fidelity sum (eq. 15), grades, AHP, comparison.

* :class:`Weights` — the weight set ``K = {k1..k5}`` of the paper (``k_i >= 0``,
  ``Σ k_i = 1``), with presets for the two mission types the paper names and
  :meth:`Weights.from_ahp` (analytic hierarchy process) for principled weights;
  :func:`fidelity_sum` — eq. (15), ``Σ k_i·f_i``; :func:`ahp` (all from :mod:`irfidelity.weights`).
* :func:`fit_weights` and :func:`combine_ahp` — weights from experts' preferences or their
  pooled AHP matrices (from :mod:`irfidelity.judgements`).
* :class:`GradeScale` — fuzzy comprehensive evaluation beyond eq. (15): every
  component gets a membership in each grade (default excellent / good / fair / poor),
  the rows form the evaluation matrix ``R``, and ``B = K·R`` is the membership of the
  simulator in each grade; the grade of maximum membership is reported.
* :func:`compare` — ranks several simulators and tells how stable the ranking is when
  the weights vary (Dirichlet samples around ``K``).

Nothing in this module touches frames or curves; it works on component values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, cast

import numpy as np

from .errors import AHPConsistencyWarning, FidelityError
from .judgements import combine_ahp, fit_weights
from .weights import COMPONENTS, PAPER_COMPONENTS, AHPResult, Weights, ahp, fidelity_sum, ordered_components

__all__ = [
    "COMPONENTS",
    "PAPER_COMPONENTS",
    "ordered_components",
    "Weights",
    "AHPResult",
    "AHPConsistencyWarning",
    "ahp",
    "fidelity_sum",
    "GradeScale",
    "Grading",
    "Comparison",
    "compare",
    "fit_weights",
    "combine_ahp",
]


# --------------------------------------------------------------------------- grades
#: Default grade boundaries per component (ascending: poor|fair, fair|good, good|excellent).
#: psnr: the paper's dB scale, f3 = 0.6 / 0.8 / 0.9 at 17.2 / 23.4 / 30 dB (30 dB: the paper's
#: "indistinguishable"). nmi, ssim: the values they take for the same degradation, white noise
#: at those PSNRs relative to the scene's range, median over the real thermal frames of
#: tests/data (benches/calibrate_grades.py). radiometry: 0.9 / 0.9^4 / 0.9^9, the values of a pure
#: offset of 1, 2 and 3 temperature tolerances (:mod:`irfidelity.temperature`). mtf, sitf, noise,
#: mrtd: judgement (a comparison of camera properties has no noise scale to calibrate against),
#: docs/interpretation.md.
DEFAULT_CUTS = {
    "mtf": (0.70, 0.85, 0.95),
    "sitf": (0.70, 0.85, 0.95),
    "psnr": (0.60, 0.80, 0.90),
    "nmi": (0.05, 0.07, 0.145),
    "ssim": (0.20, 0.50, 0.82),
    "noise": (0.70, 0.85, 0.95),
    "radiometry": (0.387, 0.656, 0.90),
    "mrtd": (0.70, 0.85, 0.95),
}

#: Half-width of the fuzzy transition around each boundary, per component (at most half the
#: smallest gap between boundaries, so every value's memberships still sum to 1).
DEFAULT_WIDTHS = {"mtf": 0.04, "sitf": 0.04, "psnr": 0.04, "nmi": 0.01, "ssim": 0.04, "noise": 0.04,
                  "radiometry": 0.04, "mrtd": 0.04}


def _ramp_up(x: float, c: float, w: float) -> float:
    """0 below c − w, 1 above c + w, linear in between (a step when w = 0)."""
    if w == 0:
        return 1.0 if x >= c else 0.0
    return min(1.0, max(0.0, (x - (c - w)) / (2 * w)))


@dataclass(frozen=True)
class Grading:
    """Fuzzy comprehensive evaluation of one set of components.

    Attributes
    ----------
    grades : tuple of str
        Grade names, best first.
    matrix : dict
        ``R``: ``{component: {grade: membership}}`` (each row sums to 1).
    membership : dict
        ``B = K·R``: ``{grade: membership}`` (sums to 1).
    component_grades : dict
        ``{component: grade}``: each weighted component's own grade (the grade of maximum
        membership in its row of ``R``; ties go to the worse grade).
    grade : str
        The overall grade (:meth:`GradeScale.evaluate` states the rule).
    """

    grades: tuple
    matrix: dict
    membership: dict
    component_grades: dict
    grade: str

    def to_dict(self) -> dict:
        return {"grades": list(self.grades), "matrix": {k: dict(v) for k, v in self.matrix.items()},
                "membership": dict(self.membership), "component_grades": dict(self.component_grades),
                "grade": self.grade}


def _max_membership(row: Mapping[str, float], grades: tuple) -> str:
    """The grade of largest membership; ties go to the worse grade."""
    return max(reversed(grades), key=lambda g: row[g])


def _grade_names(value: Any) -> tuple:
    """The grade names: a list of at least 2 distinct non-empty strings, best first."""
    names = tuple(value) if isinstance(value, (list, tuple)) else ()
    if len(names) < 2 or len(set(names)) != len(names) or not all(isinstance(x, str) and x for x in names):
        raise FidelityError(f"grades must be a list of at least 2 distinct non-empty names, got {value!r}",
                            option="grades")
    return names


def _grade_number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise FidelityError(f"{what} must be a number, got {value!r}", option="grades")
    return float(value)


def _grade_widths(value: Any) -> dict:
    """One half-width per component from a number or a ``{component: number}`` mapping."""
    if isinstance(value, Mapping):
        unknown = sorted(str(k) for k in value if k not in COMPONENTS)
        if unknown:
            raise FidelityError(f"grade width for unknown component(s) {unknown}; the components are "
                                f"{', '.join(COMPONENTS)}", option="grades")
        given = {name: value.get(name, DEFAULT_WIDTHS[name]) for name in COMPONENTS}
    else:
        given = dict.fromkeys(COMPONENTS, value)
    widths = {}
    for name, w in given.items():
        width = _grade_number(w, f"grade width of {name} (a number or one per component)")
        if not (math.isfinite(width) and width >= 0):
            raise FidelityError(f"grade width of {name} must be finite and >= 0, got {w!r}", option="grades")
        widths[name] = width
    return widths


def _grade_cuts(value: Any, grades: tuple, widths: Mapping[str, float]) -> dict:
    """Each component's ascending boundaries, ``len(grades) - 1`` of them, in (0, 1)."""
    if not isinstance(value, Mapping):
        raise FidelityError(f"grade cuts must be a mapping {{component: [boundaries]}}, got {value!r}",
                            option="grades")
    unknown = sorted(str(k) for k in value if k not in COMPONENTS)
    if unknown:
        raise FidelityError(f"grade cuts for unknown component(s) {unknown}; the components are "
                            f"{', '.join(COMPONENTS)}", option="grades")
    cuts = {}
    for name in COMPONENTS:
        given = value.get(name)
        if given is None and len(grades) == len(DEFAULT_CUTS[name]) + 1:
            given = DEFAULT_CUTS[name]  # e.g. scales written before the noise component existed
        if given is None:
            raise FidelityError(f"grade cuts missing for component {name!r}", option="grades")
        if not isinstance(given, (list, tuple, np.ndarray)):
            raise FidelityError(f"grade cuts for {name} must be a list of numbers, got {given!r}", option="grades")
        c = tuple(_grade_number(v, f"a grade cut for {name}") for v in given)
        if len(c) != len(grades) - 1:
            raise FidelityError(f"grade cuts for {name}: need {len(grades) - 1} boundaries for grades {grades}, "
                                f"got {len(c)}", option="grades")
        w = widths[name]
        if not all(0 < v < 1 for v in c) or any(b - a < 2 * w - 1e-12 for a, b in zip(c, c[1:])):
            raise FidelityError(f"grade cuts for {name} must lie in (0, 1), ascending, at least "
                                f"2*width = {2 * w:g} apart; got {c}", option="grades")
        cuts[name] = c
    return cuts


@dataclass(frozen=True)
class GradeScale:
    """Grade set and membership functions for the fuzzy comprehensive evaluation.

    Each component value ``f`` in [0, 1] gets a membership in every grade from a
    trapezoidal fuzzy partition of [0, 1]: for the component's ascending boundaries
    ``c_1 < … < c_{m−1}`` (m grades) and half-width ``width`` = w, grade ``j`` (counted
    from the worst) has the trapezoid

        μ_j(f) = ramp(f; c_j) − ramp(f; c_{j+1}),   ramp(f; c) = clip((f − c + w) / 2w, 0, 1)

    i.e. 1 well inside ``[c_j, c_{j+1}]``, falling linearly to 0 across ``c ± w`` — so
    the memberships of every value sum to 1 (a Ruspini partition) and ``B = K·R`` sums
    to 1 as well. With ``width = 0`` the grading is crisp; ``width`` is one number or one
    per component (default :data:`DEFAULT_WIDTHS`).

    Default grades: ``("excellent", "good", "fair", "poor")``; default boundaries
    (:data:`DEFAULT_CUTS`): normalised PSNR 0.60 / 0.80 / 0.90 (17.2 / 23.4 / 30 dB; 30 dB
    is the paper's "indistinguishable" anchor); NMI 0.05 / 0.07 / 0.145 and SSIM
    0.20 / 0.50 / 0.82, the values these take on real thermal frames for white noise at
    those same PSNRs relative to the scene's range (so every image component grades one
    degradation alike); MTF and SiTF 0.70 / 0.85 / 0.95 (judgement).
    docs/interpretation.md has the derivation; pass your own ``cuts`` for a mission.

    The overall grade (:meth:`evaluate`) is not the grade of maximum membership in ``B``
    alone, which can call a pair "excellent" while a weighted component is poor. It is

    1. the *weighted-average* grade of ``B``: with grades scored 0 (worst) .. m−1 (best),
       the score ``Σ_g B_g·score(g)`` rounded to the nearest grade (halves to the worse);
    2. capped one grade above the worst weighted component's own grade (a weakest-link
       rule: one poor component keeps the whole at "fair" or below).

    Examples
    --------
    >>> from irfidelity.fuzzy import GradeScale
    >>> scale = GradeScale()
    >>> scale.memberships("psnr", 0.95)                    # well above the 0.90 boundary
    {'excellent': 1.0, 'good': 0.0, 'fair': 0.0, 'poor': 0.0}
    >>> g = scale.evaluate("psnr=0.5,ssim=0.5", {"psnr": 0.95, "ssim": 0.3})
    >>> g.component_grades, g.grade                        # the weakest link caps the grade
    ({'psnr': 'excellent', 'ssim': 'fair'}, 'good')
    """

    grades: tuple = ("excellent", "good", "fair", "poor")
    cuts: Mapping[str, tuple] = field(default_factory=lambda: dict(DEFAULT_CUTS))
    width: float | Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_WIDTHS))

    def __post_init__(self) -> None:
        grades = _grade_names(self.grades)
        object.__setattr__(self, "grades", grades)
        widths = _grade_widths(self.width)
        object.__setattr__(self, "width", widths)
        object.__setattr__(self, "cuts", _grade_cuts(self.cuts, grades, widths))

    def memberships(self, component: str, value: float) -> dict:
        """Row of ``R`` for one component value: ``{grade: membership}`` (sums to 1)."""
        c = self.cuts[component]
        x = float(value)
        width = cast(Mapping[str, float], self.width)  # one per component since __post_init__
        ups = [1.0] + [_ramp_up(x, ci, width[component]) for ci in c] + [0.0]
        # ups[j] = membership in "grade j or better" counted from the worst; grade j (worst=0)
        worst_first = [ups[j] - ups[j + 1] for j in range(len(c) + 1)]
        return dict(zip(self.grades, reversed(worst_first)))

    def evaluate(self, weights: Weights, components: Mapping[str, float]) -> Grading:
        """``R`` from the components, ``B = K·R``, each component's grade and the overall
        grade by the rule in the class notes."""
        w = Weights.coerce(weights)
        R = {k: self.memberships(k, components[k]) for k in COMPONENTS if k in components and w[k] > 0}
        if not R:
            raise FidelityError("no component with a positive weight to grade")
        B = {g: math.fsum(w[k] * R[k][g] for k in R) for g in self.grades}
        own = {k: _max_membership(row, self.grades) for k, row in R.items()}
        score = {g: len(self.grades) - 1 - i for i, g in enumerate(self.grades)}  # best = m−1
        average = math.fsum(B[g] * score[g] for g in self.grades)
        nearest = math.ceil(average - 0.5)  # halves go to the worse grade
        cap = min(score[g] for g in own.values()) + 1
        by_score = {v: g for g, v in score.items()}
        return Grading(grades=self.grades, matrix=R, membership=B, component_grades=own,
                       grade=by_score[min(nearest, cap, len(self.grades) - 1)])


# --------------------------------------------------------------------------- compare
@dataclass(frozen=True)
class Comparison:
    """Result of :func:`compare` (and the stability of :func:`irfidelity.ranking.rank`).

    Attributes
    ----------
    ranking : list of str
        Simulators by fidelity under ``weights``, best first.
    fidelity : dict
        ``{name: Σ k_i f_i}`` under ``weights``.
    p_first : dict
        ``{name: probability of ranking first}`` over the draws (ties share): weight vectors
        drawn around ``weights`` and, when ``frames`` > 0, with each weight vector the frames
        resampled in blocks of ``block``.
    mean_rank : dict
        ``{name: average rank (1 = best)}`` over the draws.
    weights : Weights
    samples : int
        Draws (weight vectors, each with its frame resample when ``frames`` > 0).
    concentration : float
    components : tuple of str
        The components compared (positive weight).
    frames, block : int
        The frames resampled with each weight vector and the block length (0 when only the
        weights vary, as in :func:`compare`).
    """

    ranking: list
    fidelity: dict
    p_first: dict
    mean_rank: dict
    weights: Weights
    samples: int
    concentration: float
    components: tuple
    frames: int = 0
    block: int = 0

    def to_dict(self) -> dict:
        return {"ranking": list(self.ranking), "fidelity": dict(self.fidelity), "p_first": dict(self.p_first),
                "mean_rank": dict(self.mean_rank), "weights": self.weights.as_dict(), "samples": self.samples,
                "concentration": self.concentration, "components": list(self.components), "frames": self.frames,
                "block": self.block}

    def summary_text(self) -> str:
        lines = [f"{'simulator':<24} {'fidelity':>9} {'P(first)':>9} {'mean rank':>10}"]
        for n in self.ranking:
            lines.append(f"{n:<24} {self.fidelity[n]:>9.4f} {self.p_first[n]:>9.3f} {self.mean_rank[n]:>10.2f}")
        frames = (f", each with a block resample of the {self.frames} frames (blocks of {self.block})"
                  if self.frames else "")
        lines.append(f"weights: {self.weights}; {self.samples} Dirichlet samples, concentration "
                     f"{self.concentration:g}{frames}")
        return "\n".join(lines)


def check_draws(samples: Any, concentration: Any) -> tuple[int, float]:
    """``samples`` as a positive int (an integral float is accepted) and ``concentration`` as a
    finite float > 0, else FidelityError naming the argument."""
    number = isinstance(samples, (int, float, np.integer, np.floating)) and not isinstance(samples, bool)
    if not (number and math.isfinite(samples) and float(samples).is_integer() and samples >= 1):
        raise FidelityError(f"samples must be a positive integer, got {samples!r}", option="samples")
    conc = float(concentration) if isinstance(concentration, (int, float, np.integer, np.floating)) \
        and not isinstance(concentration, bool) else math.nan
    if not (math.isfinite(conc) and conc > 0):
        raise FidelityError(f"concentration must be finite and > 0, got {concentration!r}", option="concentration")
    return int(samples), conc


def weight_draws(weights: Weights, components: tuple, samples: int, concentration: float,
                 rng: np.random.Generator) -> np.ndarray:
    """``samples`` × ``len(components)`` weight vectors from ``Dirichlet(concentration · K)`` over the
    ``components`` (their mean is ``K``); all ones for a single component."""
    if len(components) == 1:
        return np.ones((samples, 1))
    return rng.dirichlet(concentration * np.array([weights[k] for k in components]), size=samples)


def first_and_mean_rank(scores: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """From ``scores`` (draws × simulators): each simulator's share of the draws where it scores
    highest (ties within 1e-12 share the draw) and its mean rank (1 = best)."""
    top = scores.max(axis=1, keepdims=True)
    is_top = np.isclose(scores, top, rtol=0, atol=1e-12)
    p_first = (is_top / is_top.sum(axis=1, keepdims=True)).mean(axis=0)
    order = np.argsort(-scores, axis=1, kind="stable")
    ranks = np.empty_like(order, dtype=np.float64)
    ranks[np.arange(scores.shape[0])[:, None], order] = np.arange(1, scores.shape[1] + 1)[None, :]
    return p_first, ranks.mean(axis=0)


def compare(reports: Mapping[str, Any], *, weights: Any = None, samples: int = 2000,
            concentration: float = 50.0, seed: int | None = 0) -> Comparison:
    """Rank simulators scored on the same mission, and test the ranking's stability under weight changes.

    Parameters
    ----------
    reports : {name: FidelityReport}
        At least one report (anything with ``.components`` and ``.weights`` works).
    weights : Weights, optional
        ``K``. Default: the reports' weights, which must then all be equal.
    samples : int
        Number of weight vectors drawn from ``Dirichlet(concentration · K)`` (over the
        components with positive weight; the others stay 0). The mean of the samples is
        ``K``; a larger ``concentration`` keeps them closer to ``K`` (each weight's
        standard deviation is ``sqrt(k(1−k)/(concentration+1))``, e.g. 0.057 for
        k = 0.2 and concentration 50).
    seed : int or None
        Seed of numpy's default generator (reproducible by default).

    Every simulator must have a value for every component with positive weight;
    otherwise FidelityError names the report and the component (scores over different
    component sets are not comparable).

    Only the weights vary here: two simulators that differ by noise get ``p_first`` 1 and 0
    whenever one is ahead on every component. Simulators scored on the same frames are
    ranked with the frames' sampling too by :func:`irfidelity.ranking.rank` (and
    :func:`irfidelity.score_simulators`).

    Examples
    --------
    Two simulators of one scene, with temporal noise of σ = 5 and σ = 40 counts:

    >>> import numpy as np, irfidelity as irf
    >>> from irfidelity.fuzzy import compare
    >>> y, x = np.mgrid[0:64, 0:64]
    >>> real = (3000 + 300 * np.sin(x / 5.0) * np.cos(y / 7.0)).astype(np.uint16)
    >>> rng = np.random.default_rng(0)
    >>> sims = {"A": real + rng.normal(0, 5, real.shape), "B": real + rng.normal(0, 40, real.shape)}
    >>> reports = {name: irf.evaluate(real, sim.astype(np.uint16), bits=14, peak="range")
    ...            for name, sim in sims.items()}
    >>> c = compare(reports)
    >>> c.ranking, c.p_first                    # A first under every sampled weight vector
    (['A', 'B'], {'A': 1.0, 'B': 0.0})
    """
    if not isinstance(reports, Mapping) or not reports:
        raise FidelityError("compare needs a non-empty mapping {name: FidelityReport}")
    names = [str(k) for k in reports]
    if weights is None:
        ws = {r.weights for r in reports.values()}
        if len(ws) != 1:
            raise FidelityError("the reports were scored with different weights; pass weights= to compare them")
        w = Weights.coerce(next(iter(ws)))
    else:
        w = Weights.coerce(weights)
    comps = w.active()
    for n, r in reports.items():
        miss = [k for k in comps if k not in r.components]
        if miss:
            raise FidelityError(f"report {n!r} has no value for component(s) {miss} (positive weight); "
                                f"compare simulators on the same components")
    ns, conc = check_draws(samples, concentration)
    F = np.array([[float(r.components[k]) for k in comps] for r in reports.values()])  # sims × comps
    base = {n: math.fsum(w[k] * f for k, f in zip(comps, row)) for n, row in zip(names, F)}
    ranking = sorted(names, key=lambda n: -base[n])
    W = weight_draws(w, comps, ns, conc, np.random.default_rng(seed))
    p_first, mean_rank = first_and_mean_rank(W @ F.T)  # samples × sims
    return Comparison(ranking=ranking, fidelity=base, p_first={n: float(p) for n, p in zip(names, p_first)},
                      mean_rank={n: float(r) for n, r in zip(names, mean_rank)}, weights=w, samples=ns,
                      concentration=conc, components=comps)
