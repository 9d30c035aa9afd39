"""The fuzzy layer (paper §3): weights K, the fidelity sum (eq. 15), grades, AHP, comparison.

* :class:`Weights` — the weight set ``K = {k1..k5}`` of the paper (``k_i >= 0``,
  ``Σ k_i = 1``), with presets for the two mission types the paper names and
  :meth:`Weights.from_ahp` (analytic hierarchy process) for principled weights.
* :func:`fidelity_sum` — eq. (15), ``Σ k_i·f_i``.
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
import re
import warnings
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, cast

import numpy as np

from .errors import AHPConsistencyWarning, FidelityError

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
]

#: The paper's components, in its order f1..f5.
PAPER_COMPONENTS: tuple[str, ...] = ("mtf", "sitf", "psnr", "nmi", "ssim")

#: Every component: the paper's five, then the opt-in ``noise``, ``radiometry`` and ``mrtd``
#: (weight 0 by default).
COMPONENTS = PAPER_COMPONENTS + ("noise", "radiometry", "mrtd")


def ordered_components(components: Mapping[str, float]) -> dict:
    """The given components in the paper's order (mtf, sitf, psnr, nmi, ssim), then noise, radiometry, mrtd."""
    return {k: components[k] for k in COMPONENTS if k in components}

_TOL = 1e-9


# --------------------------------------------------------------------------- weights
def _number(v: Any, name: str) -> float:
    if isinstance(v, bool):
        raise FidelityError(f"weight {name} must be a number, got {v!r}")
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise FidelityError(f"weight {name} must be a number, got {v!r}") from None
    if not math.isfinite(f):
        raise FidelityError(f"weight {name} must be finite, got {v!r}")
    if f < 0:
        raise FidelityError(f"weight {name} must be >= 0, got {v!r}")
    return f


@dataclass(frozen=True, init=False)
class Weights:
    """The weight set ``K`` of eq. (15): one non-negative weight per component.

    Rules (each violation raises :class:`~irfidelity.FidelityError`, a ``ValueError``,
    naming the rule): every weight is a finite number, every weight is ``>= 0``, and the
    weights sum to 1 within 1e-9. A weight of 0 means the component is not computed at
    all by :func:`irfidelity.evaluate`.

    The default (``Weights()``) is the paper's: 1/5 each of its five components, and 0 for the
    opt-in ``noise`` (the camera's 3-D noise, :mod:`irfidelity.noise`), ``radiometry`` (temperature
    errors, :mod:`irfidelity.temperature`) and ``mrtd`` (the MRTD curves, docs/bars.md).

    Examples
    --------
    >>> Weights.parse("psnr=0.5,ssim=0.5").as_dict()["nmi"]
    0.0
    >>> Weights.normalized(mtf=2, sitf=2, psnr=1).mtf
    0.4
    """

    mtf: float = 0.2
    sitf: float = 0.2
    psnr: float = 0.2
    nmi: float = 0.2
    ssim: float = 0.2
    noise: float = 0.0
    radiometry: float = 0.0
    mrtd: float = 0.0

    def __init__(self, mtf: float = 0.2, sitf: float = 0.2, psnr: float = 0.2, nmi: float = 0.2,
                 ssim: float = 0.2, noise: float = 0.0, radiometry: float = 0.0, mrtd: float = 0.0,
                 **unknown: Any) -> None:
        if unknown:
            raise FidelityError(f"unknown weight name(s) {sorted(unknown)}; expected some of {list(COMPONENTS)}",
                                option="weights")
        given = (mtf, sitf, psnr, nmi, ssim, noise, radiometry, mrtd)
        vals = {name: _number(value, name) for name, value in zip(COMPONENTS, given)}
        for name, value in vals.items():
            object.__setattr__(self, name, value)
        try:
            total = math.fsum(vals.values())
        except OverflowError:
            total = math.inf
        if abs(total - 1.0) > _TOL:
            raise FidelityError(
                f"weights must sum to 1 (within 1e-9), got {total!r} "
                f"({', '.join(f'{k}={v:g}' for k, v in vals.items())}); "
                f"scale raw importances with Weights.normalized, or 'normalize' in a weights string",
                option="weights")

    # -- construction ---------------------------------------------------------------
    @classmethod
    def normalized(cls, **raw: float) -> Weights:
        """Weights proportional to raw importances; unnamed components get 0.

        ``Weights.normalized(mtf=3, psnr=1)`` → mtf 0.75, psnr 0.25, the rest 0.
        """
        unknown = set(raw) - set(COMPONENTS)
        if unknown:
            raise FidelityError(f"unknown weight name(s) {sorted(unknown)}; expected some of {list(COMPONENTS)}")
        vals = {k: _number(raw.get(k, 0.0), k) for k in COMPONENTS}
        try:
            total = math.fsum(vals.values())
        except OverflowError:  # scale down first: the ratios are what matter
            vals = {k: v / 2.0 ** 1000 for k, v in vals.items()}
            total = math.fsum(vals.values())
        if total <= 0:
            raise FidelityError("weights must not all be 0: at least one component needs a positive weight")
        return cls(**{k: v / total for k, v in vals.items()})

    @classmethod
    def balanced(cls) -> Weights:
        """The paper's demonstration weights: 1/5 each (also the default)."""
        return cls()

    @classmethod
    def performance(cls) -> Weights:
        """A mission emphasising system performance (paper §3, larger k1, k2):
        MTF 0.35, SiTF 0.35, PSNR / NMI / SSIM 0.1 each."""
        return cls(mtf=0.35, sitf=0.35, psnr=0.1, nmi=0.1, ssim=0.1)

    @classmethod
    def image_quality(cls) -> Weights:
        """A mission emphasising image quality (paper §3, larger k3..k5):
        MTF / SiTF 0.1 each, PSNR 0.3, NMI 0.2, SSIM 0.3 (NMI a little lower: it depends
        on the binning and equals 1 for any one-to-one grey-level relation)."""
        return cls(mtf=0.1, sitf=0.1, psnr=0.3, nmi=0.2, ssim=0.3)

    PRESETS = ("balanced", "performance", "image_quality")

    @classmethod
    def parse(cls, text: str) -> Weights:
        """Weights from a string (the CLI's ``--weights``).

        ``"balanced"``, ``"performance"``, ``"image_quality"`` (or ``image-quality``), or
        ``"mtf=0.3,sitf=0.3,psnr=0.2,nmi=0.1,ssim=0.1"``: components not named get 0 and
        the given values must sum to 1 (add ``normalize`` as an item, e.g.
        ``"mtf=3,psnr=1,normalize"``, to scale raw importances instead).
        """
        if not isinstance(text, str):
            raise FidelityError(f"weights must be a string, got {type(text).__name__}")
        s = text.strip()
        key = s.lower().replace("-", "_")
        if key in cls.PRESETS:
            return getattr(cls, key)()
        if "=" not in s:
            raise FidelityError(f"weights {text!r}: expected a preset ({', '.join(cls.PRESETS)}) "
                                f"or name=value pairs such as 'mtf=0.2,sitf=0.2,psnr=0.2,nmi=0.2,ssim=0.2'")
        raw: dict[str, float] = {}
        norm = False
        for item in re.split(r"[,;\s]+", s):
            if not item:
                continue
            if item.lower() in ("normalize", "normalise"):
                norm = True
                continue
            name, sep, val = item.partition("=")
            name = name.strip().lower()
            if not sep or name not in COMPONENTS:
                raise FidelityError(f"weights {text!r}: bad item {item!r}; expected name=value with name "
                                    f"one of {', '.join(COMPONENTS)}")
            if name in raw:
                raise FidelityError(f"weights {text!r}: {name} given twice")
            try:
                raw[name] = float(val)
            except ValueError:
                raise FidelityError(f"weights {text!r}: {name}={val!r} is not a number") from None
        if not raw:
            raise FidelityError(f"weights {text!r}: no name=value pairs")
        if norm:
            return cls.normalized(**raw)
        return cls(**{k: raw.get(k, 0.0) for k in COMPONENTS})

    @classmethod
    def coerce(cls, w: Any) -> Weights:
        """``None`` → balanced; a Weights; a preset/“name=value” string; a mapping (must sum to 1)."""
        if w is None:
            return cls()
        if isinstance(w, Weights):
            return w
        if isinstance(w, str):
            return cls.parse(w)
        if isinstance(w, Mapping):
            unknown = set(w) - set(COMPONENTS)
            if unknown:
                raise FidelityError(f"unknown weight name(s) {sorted(unknown)}; expected some of {list(COMPONENTS)}")
            return cls(**{k: w.get(k, 0.0) for k in COMPONENTS})
        raise FidelityError(f"weights must be a Weights, a preset name, a 'name=value' string or a mapping, "
                            f"got {type(w).__name__}")

    @classmethod
    def from_ahp(cls, matrix: Any, *, names: Iterable[str] = PAPER_COMPONENTS, on_inconsistent: str = "warn",
                 threshold: float = 0.1) -> Weights:
        """Weights from an AHP pairwise-comparison matrix (see :func:`ahp`).

        ``matrix[i][j]`` says how much more important component ``names[i]`` is than
        ``names[j]`` (Saaty's 1–9 scale; reciprocal: ``m[j][i] = 1/m[i][j]``). The
        weights are the normalised principal eigenvector; components not in ``names``
        get 0. If Saaty's consistency ratio exceeds ``threshold`` (0.1):
        ``on_inconsistent="warn"`` (default) issues :class:`AHPConsistencyWarning` and
        still returns the weights, ``"raise"`` raises FidelityError, ``"ignore"`` does
        neither. Use :func:`ahp` to get the ratio itself.
        """
        return ahp(matrix, names=names, on_inconsistent=on_inconsistent, threshold=threshold).weights

    # -- views ----------------------------------------------------------------------
    def as_dict(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in COMPONENTS}

    def __getitem__(self, name: str) -> float:
        if name not in COMPONENTS:
            raise KeyError(name)
        return getattr(self, name)

    def active(self) -> tuple[str, ...]:
        """Components with a positive weight, in the paper's order."""
        return tuple(k for k in COMPONENTS if getattr(self, k) > 0)

    def __str__(self) -> str:
        return ", ".join(f"{k}={getattr(self, k):.4g}" for k in COMPONENTS)


def fidelity_sum(weights: Weights, components: Mapping[str, float]) -> float:
    """Eq. (15): ``Σ k_i·f_i`` over the given components (paper order, :func:`math.fsum`).

    Every component with a positive weight must be present.

    Examples
    --------
    >>> from irfidelity.fuzzy import fidelity_sum
    >>> fidelity_sum("psnr=0.5,ssim=0.5", {"psnr": 0.9, "ssim": 0.7})
    0.8
    """
    w = Weights.coerce(weights)
    missing = [k for k in w.active() if k not in components]
    if missing:
        raise FidelityError(f"component(s) {missing} have a positive weight but no value")
    return math.fsum(w[k] * float(components[k]) for k in COMPONENTS if k in components and w[k] > 0)


# --------------------------------------------------------------------------- AHP
#: Saaty's random consistency index RI(n) (Saaty 1980), n = 1..10.
RANDOM_INDEX = {1: 0.0, 2: 0.0, 3: 0.58, 4: 0.90, 5: 1.12, 6: 1.24, 7: 1.32, 8: 1.41, 9: 1.45, 10: 1.49}


@dataclass(frozen=True)
class AHPResult:
    """Outcome of :func:`ahp`.

    Attributes
    ----------
    weights : Weights
        Normalised principal eigenvector (0 for components not in ``names``).
    priorities : dict
        The eigenvector over ``names`` only.
    lambda_max : float
        Principal eigenvalue (``>= n``; ``== n`` for a consistent matrix).
    ci, cr : float
        Consistency index ``(λmax − n)/(n − 1)`` and ratio ``CI / RI(n)`` (0 for n <= 2).
    consistent : bool
        ``cr <= threshold``.
    """

    weights: Weights
    priorities: dict
    lambda_max: float
    ci: float
    cr: float
    consistent: bool

    def to_dict(self) -> dict:
        return {"weights": self.weights.as_dict(), "priorities": dict(self.priorities),
                "lambda_max": self.lambda_max, "ci": self.ci, "cr": self.cr, "consistent": self.consistent}


def ahp(matrix: Any, *, names: Iterable[str] = PAPER_COMPONENTS, on_inconsistent: str = "warn",
        threshold: float = 0.1, rtol: float = 0.02) -> AHPResult:
    """Analytic hierarchy process: weights from a pairwise-comparison matrix.

    Parameters
    ----------
    matrix : n×n array_like
        Positive, finite, ones on the diagonal, reciprocal (``m[i][j]·m[j][i] = 1``
        within ``rtol``, so ``0.33`` for 1/3 is accepted). Row/column order = ``names``.
    names : iterable of component names
        Which components the matrix compares (default all five, in the paper's order).
    on_inconsistent : "warn" | "raise" | "ignore"
        What to do when ``CR > threshold`` (see :meth:`Weights.from_ahp`).

    The weights are the principal right eigenvector, normalised to sum 1; the
    consistency ratio is ``CR = ((λmax − n)/(n − 1)) / RI(n)`` with Saaty's random
    indices (n <= 10).

    Examples
    --------
    PSNR and SSIM equally important, each three times as important as NMI:

    >>> from irfidelity.fuzzy import ahp
    >>> r = ahp([[1, 3, 1], [1 / 3, 1, 1 / 3], [1, 3, 1]], names=["psnr", "nmi", "ssim"])
    >>> {name: round(k, 3) for name, k in r.priorities.items()}, r.consistent
    ({'psnr': 0.429, 'nmi': 0.143, 'ssim': 0.429}, True)
    >>> r.weights["mtf"]                                   # not compared: weight 0
    0.0

    Judgements that contradict each other (psnr > nmi > ssim > psnr):

    >>> r = ahp([[1, 5, 1 / 5], [1 / 5, 1, 5], [5, 1 / 5, 1]], names=["psnr", "nmi", "ssim"],
    ...         on_inconsistent="ignore")
    >>> r.consistent, round(r.cr, 2)
    (False, 2.76)
    """
    names = tuple(names)
    bad = [n for n in names if n not in COMPONENTS]
    if bad or len(set(names)) != len(names) or not names:
        raise FidelityError(f"AHP names must be distinct component names from {list(COMPONENTS)}, got {list(names)}")
    if on_inconsistent not in ("warn", "raise", "ignore"):
        raise FidelityError(f"on_inconsistent must be 'warn', 'raise' or 'ignore', got {on_inconsistent!r}")
    try:
        m = np.array(matrix, dtype=np.float64)
    except (TypeError, ValueError):
        raise FidelityError("AHP matrix must be a square array of positive numbers") from None
    n = len(names)
    if m.shape != (n, n):
        raise FidelityError(f"AHP matrix must be {n}x{n} (one row/column per name {list(names)}), got shape {m.shape}")
    if not np.isfinite(m).all() or (m <= 0).any():
        raise FidelityError("AHP matrix entries must be positive and finite")
    for i in range(n):
        if abs(m[i, i] - 1) > rtol:
            raise FidelityError(f"AHP matrix diagonal must be 1; m[{i}][{i}] = {m[i, i]!r}")
        for j in range(i + 1, n):
            if abs(m[i, j] * m[j, i] - 1) > rtol:
                raise FidelityError(
                    f"AHP matrix must be reciprocal: m[{i}][{j}]·m[{j}][{i}] = {m[i, j]:g}·{m[j, i]:g} "
                    f"= {m[i, j] * m[j, i]:.4g}, expected 1 ({names[i]} vs {names[j]})")
    if n == 1:
        vec = np.ones(1)
        lam = 1.0
    else:
        vals, vecs = np.linalg.eig(m)
        i = int(np.argmax(vals.real))
        lam = float(vals[i].real)
        vec = np.abs(vecs[:, i].real)
    vec = vec / vec.sum()
    ci = max(0.0, (lam - n) / (n - 1)) if n > 1 else 0.0
    ri = RANDOM_INDEX.get(n)
    if ri is None:
        raise FidelityError(f"AHP random index is tabulated for n <= 10, got n = {n}")
    cr = ci / ri if ri > 0 else 0.0
    ok = cr <= threshold
    if not ok:
        msg = (f"AHP consistency ratio CR = {cr:.3f} exceeds {threshold:g} (λmax = {lam:.4f}, n = {n}): "
               f"the pairwise judgements are inconsistent; revise the matrix")
        if on_inconsistent == "raise":
            raise FidelityError(msg)
        if on_inconsistent == "warn":
            warnings.warn(msg, AHPConsistencyWarning, stacklevel=3)
    pri = {k: float(v) for k, v in zip(names, vec)}
    w = Weights.normalized(**pri)
    return AHPResult(weights=w, priorities=pri, lambda_max=lam, ci=float(ci), cr=float(cr), consistent=ok)


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


# Weights from experts (judgements.py imports this module's names, so it comes last).
from .judgements import combine_ahp, fit_weights  # noqa: E402

__all__ += ["fit_weights", "combine_ahp"]
