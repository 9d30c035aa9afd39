"""The weight set ``K`` of eq. (15) (paper §3): the components it weighs, :class:`Weights`,
the fidelity sum :func:`fidelity_sum`, and weights from a pairwise-comparison matrix by the
analytic hierarchy process (:func:`ahp`). :mod:`irfidelity.fuzzy`, the fuzzy layer, exports
them with its grades and comparisons; weights learned from experts (:mod:`irfidelity.judgements`)
build on them.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

import numpy as np

from .errors import AHPConsistencyWarning, FidelityError

__all__ = [
    "COMPONENTS",
    "PAPER_COMPONENTS",
    "ordered_components",
    "Weights",
    "fidelity_sum",
    "RANDOM_INDEX",
    "AHPResult",
    "ahp",
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
