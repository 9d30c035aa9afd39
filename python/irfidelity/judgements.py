"""Weights from experts: :func:`fit_weights` learns ``K`` from pairwise preferences,
:func:`combine_ahp` pools several experts' AHP matrices, :func:`read_judgements` reads the
judgement CSV (docs/ranking.md).

The model (Bradley–Terry on component differences): an expert prefers item ``a`` to ``b``
with probability ``σ(s·Σ_i w_i (f_i(a) − f_i(b)))``, ``σ`` the logistic function, ``w`` the
weights (``w_i >= 0``, ``Σ w_i = 1``) and ``s > 0`` a free scale (how decisive the experts
are). With ``v = s·w`` the negative log-likelihood is convex in ``v >= 0``, so the fit is a
projected Newton method on ``v`` (numpy only) and ``w = v / Σv``, ``s = Σv``. Two penalties
join the likelihood: ``1e-4·s²``, which keeps ``s`` finite when the judgements are perfectly
separable and does not favour any ``w``; and, with a ``prior``, ``prior_strength·‖w − w_prior‖²``
(a Gaussian prior on each weight of standard deviation ``1/√(2·prior_strength)``: 0.32 at the
default :data:`DEFAULT_PRIOR_STRENGTH`, 5).

The prior's strength is fixed while the likelihood grows with the number of judgements, so the
prior decides the weights when judgements are few and fades as they accumulate. The default
is weak on purpose: weights live on [0, 1] with a typical size of 0.2, and a standard deviation
of 0.32 keeps the fit off wild corners when few judgements say anything about a component,
without overriding what they do say. With 30 judgements of a judge who looks only at SSIM and
a balanced prior, the fitted SSIM weight is 0.65–0.91 over five sets of judgements (0.79–1.00
without a prior; 0.41–0.51 at the former default 50, which swamped them); docs/ranking.md has
the figures.

An expert whose held-out judgements the negated weights predict better than the weights
(held-out accuracy below 0.5) judges by the opposite criterion: the fit names them in
``opposed`` and warns (:class:`~irfidelity.errors.JudgementWarning`) rather than averaging their
judgements in silently; ``exclude=`` fits without them.
"""

from __future__ import annotations

import csv
import math
import os
import warnings
from dataclasses import dataclass
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from .errors import FidelityError, JudgementWarning
from .weights import COMPONENTS, PAPER_COMPONENTS, AHPResult, Weights, ahp

__all__ = ["fit_weights", "FittedWeights", "combine_ahp", "CombinedAHP", "read_judgements"]

#: Penalty on the squared scale s² (see the module notes).
SCALE_PENALTY = 1e-4

#: ``prior_strength`` when none is given: a prior standard deviation of 0.32 per weight (module notes).
DEFAULT_PRIOR_STRENGTH = 5.0

_MAX_ITERATIONS = 200

#: A fit whose every predicted preference is within this logit of a coin toss explains nothing.
_NO_SIGNAL = 1e-6


# --------------------------------------------------------------------------- judgements
@dataclass(frozen=True)
class Judgements:
    """Judgements as arrays: ``difference[j] = f(a_j) − f(b_j)`` over ``components``, ``sign[j]``
    +1 when ``a_j`` was preferred, −1 when ``b_j``; ``keys`` identify the items (their values)."""

    components: tuple
    difference: np.ndarray
    sign: np.ndarray
    experts: tuple
    keys: tuple

    def subset(self, rows: np.ndarray) -> Judgements:
        return Judgements(self.components, self.difference[rows], self.sign[rows],
                          tuple(self.experts[i] for i in rows), tuple(self.keys[i] for i in rows))


def _item_components(item: Any, where: str) -> Mapping:
    values = getattr(item, "components", item)
    if not isinstance(values, Mapping):
        raise FidelityError(f"{where} must be a report (with .components) or a mapping {{component: value}}, "
                            f"got {type(item).__name__}")
    return values


def _item_vector(values: Mapping, components: tuple, where: str) -> tuple:
    out = []
    for name in components:
        if name not in values:
            raise FidelityError(f"{where} has no value for component {name!r}")
        value = values[name]
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
                or not 0 <= value <= 1:
            raise FidelityError(f"{where}: component {name} must be a number in [0, 1] (a component's range), "
                                f"got {value!r}")
        out.append(float(value))
    return tuple(out)


def _choose_components(items: list[Mapping], components: Iterable[str] | None) -> tuple:
    if components is not None:
        chosen = tuple(components)
        bad = [c for c in chosen if c not in COMPONENTS]
        if bad or not chosen or len(set(chosen)) != len(chosen):
            raise FidelityError(f"components must be distinct names from {list(COMPONENTS)}, got {list(chosen)}",
                                option="components")
        return chosen
    shared = tuple(c for c in COMPONENTS if all(c in item for item in items))
    if not shared:
        raise FidelityError("the judged items share no component; give components=")
    return shared


def parse_judgements(judgements: Iterable[Any], components: Iterable[str] | None = None) -> Judgements:
    """Validate ``(a, b, preferred[, expert])`` tuples into :class:`Judgements`."""
    if isinstance(judgements, (str, bytes)) or not isinstance(judgements, Iterable):
        raise FidelityError("judgements must be a list of (a, b, preferred[, expert]) tuples")
    rows = list(judgements)
    if not rows:
        raise FidelityError("no judgements to fit")
    pairs, signs, experts = [], [], []
    for j, row in enumerate(rows):
        if not isinstance(row, Sequence) or isinstance(row, str) or len(row) not in (3, 4):
            raise FidelityError(f"judgement {j}: expected (a, b, preferred[, expert]), got {row!r}")
        preferred = row[2]
        if preferred not in ("a", "b"):
            raise FidelityError(f"judgement {j}: preferred must be 'a' or 'b', got {preferred!r}")
        expert = row[3] if len(row) == 4 else None
        if expert is not None and (not isinstance(expert, str) or not expert.strip()):
            raise FidelityError(f"judgement {j}: the expert must be a non-empty name, got {expert!r}")
        pairs.append((_item_components(row[0], f"judgement {j} item a"),
                      _item_components(row[1], f"judgement {j} item b")))
        signs.append(1.0 if preferred == "a" else -1.0)
        experts.append(expert)
    named = [e is not None for e in experts]
    if any(named) and not all(named):
        raise FidelityError(f"judgement {named.index(not named[0])}: either every judgement names its expert "
                            f"or none does")
    chosen = _choose_components([item for pair in pairs for item in pair], components)
    keys = [(_item_vector(a, chosen, f"judgement {j} item a"), _item_vector(b, chosen, f"judgement {j} item b"))
            for j, (a, b) in enumerate(pairs)]
    difference = np.array([np.subtract(a, b) for a, b in keys])
    return Judgements(chosen, difference, np.array(signs), tuple(experts), tuple(keys))


# --------------------------------------------------------------------------- the fit
@dataclass(frozen=True)
class Objective:
    """Penalised negative log-likelihood of ``v = s·w`` (module notes), with gradient and a
    positive semi-definite Hessian (Gauss–Newton for the prior term)."""

    judgements: Judgements
    prior: np.ndarray | None
    strength: float

    def value(self, v: np.ndarray) -> float:
        margin = self.judgements.sign * (self.judgements.difference @ v)
        total = float(np.logaddexp(0.0, -margin).sum()) + SCALE_PENALTY * float(v.sum()) ** 2
        if self.prior is not None and v.sum() > 0:
            total += self.strength * float(((v / v.sum() - self.prior) ** 2).sum())
        return total

    def derivatives(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d, y = self.judgements.difference, self.judgements.sign
        margin = y * (d @ v)
        wrong = 0.5 * (1.0 - np.tanh(0.5 * margin))  # σ(−margin), overflow-free
        gradient = -(d.T @ (y * wrong)) + 2 * SCALE_PENALTY * v.sum()
        hessian = (d.T * (wrong * (1 - wrong))) @ d + 2 * SCALE_PENALTY
        if self.prior is not None and v.sum() > 0:
            scale = v.sum()
            w = v / scale
            jacobian = (np.eye(len(v)) - w[:, None]) / scale  # ∂w_j / ∂v_i
            gradient = gradient + 2 * self.strength * jacobian.T @ (w - self.prior)
            hessian = hessian + 2 * self.strength * jacobian.T @ jacobian
        return gradient, hessian


def _newton_step(gradient: np.ndarray, hessian: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Projected Newton direction: Newton on the free coordinates, scaled gradient on those held at 0."""
    held = (v <= 0) & (gradient > 0)
    free = ~held
    step = np.zeros_like(v)
    ridge = 1e-12 * max(float(np.trace(hessian)), 1e-300)
    if free.any():
        step[free] = -np.linalg.solve(hessian[np.ix_(free, free)] + ridge * np.eye(int(free.sum())), gradient[free])
    step[held] = -gradient[held] / max(float(np.max(np.diag(hessian))), 1e-300)
    return step


def _minimize(objective: Objective, start: np.ndarray) -> np.ndarray:
    """``v >= 0`` minimising ``objective`` (projected Newton with Armijo backtracking)."""
    v, current = start, objective.value(start)
    with np.errstate(over="ignore", invalid="ignore"):  # a step too long is not finite: it is shortened
        for _ in range(_MAX_ITERATIONS):
            gradient, hessian = objective.derivatives(v)
            projected = np.where(v > 0, gradient, np.minimum(gradient, 0.0))
            if float(np.max(np.abs(projected))) * max(1.0, float(v.sum())) <= 1e-10 * (1.0 + abs(current)):
                break
            step, t = _newton_step(gradient, hessian, v), 1.0
            while True:
                trial = np.maximum(v + t * step, 0.0)
                value = objective.value(trial) if np.isfinite(trial).all() else math.inf
                if (math.isfinite(value) and value <= current + 1e-4 * float(gradient @ (trial - v))) or t < 1e-12:
                    break
                t *= 0.5
            if not value <= current or current - value <= 1e-15 * (1.0 + abs(current)):
                if value <= current:
                    v = trial
                break
            v, current = trial, value
    return v


@dataclass(frozen=True)
class Fit:
    weights: np.ndarray  # over the judged components, sums to 1
    scale: float


def _fit(judgements: Judgements, prior: np.ndarray | None, strength: float) -> Fit | None:
    """The fitted weights and scale, or None when the judgements carry no preference (every
    fitted logit below :data:`_NO_SIGNAL`: scale 0)."""
    start_w = np.full(len(judgements.components), 1.0 / len(judgements.components)) if prior is None else prior
    spread = float(np.mean(np.abs(judgements.difference @ start_w)))
    if spread == 0:
        spread = float(np.mean(np.abs(judgements.difference))) or 1.0
    v = _minimize(Objective(judgements, prior, strength), start_w / spread)
    if float(np.max(np.abs(judgements.difference @ v))) < _NO_SIGNAL:
        return None
    return Fit(v / v.sum(), float(v.sum()))


# --------------------------------------------------------------------------- agreement
def _concordance(judgements: Judgements, weights: np.ndarray) -> np.ndarray:
    """Per judgement: +1 when the weighted difference agrees with the preference, −1 against, 0 tied."""
    return np.sign(judgements.sign * (judgements.difference @ weights))


def _cyclic(judgements: Judgements) -> int:
    """Judgements lying on a cycle of one expert's preferences (``a ≻ b`` and ``b ≻ a`` on the same
    items, or ``a ≻ b ≻ c ≻ a``, ...): the edges ``winner → loser`` whose loser reaches the winner."""
    edges = [(a, b) if s > 0 else (b, a) for (a, b), s in zip(judgements.keys, judgements.sign)]
    beaten: dict[tuple, set] = {}
    for winner, loser in edges:
        beaten.setdefault(winner, set()).add(loser)

    def reaches(source: tuple, target: tuple) -> bool:
        seen, todo = {source}, [source]
        while todo:
            node = todo.pop()
            if node == target:
                return True
            for nxt in beaten.get(node, ()):
                if nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        return False

    return sum(reaches(loser, winner) for winner, loser in edges)


def _held_out(judgements: Judgements, prior: np.ndarray | None, strength: float) -> dict[str, float]:
    """Leave-one-expert-out: each expert's judgements predicted by the fit on the others'
    (a tied prediction counts half; an uninformative fit predicts ties)."""
    experts = np.array(judgements.experts, dtype=object)
    out = {}
    for expert in dict.fromkeys(judgements.experts):
        own = np.flatnonzero(experts == expert)
        others = np.flatnonzero(experts != expert)
        fit = _fit(judgements.subset(others), prior, strength)
        held = judgements.subset(own)
        concord = np.zeros(len(own)) if fit is None else _concordance(held, fit.weights)
        out[expert] = float(np.mean((concord + 1) / 2))
    return out


def _is_opposed(held_out_accuracy: float | None) -> bool:
    """Whether the negated held-out weights predict the expert better than the weights (ties count
    half, so the negated weights' accuracy is ``1 − accuracy``)."""
    return held_out_accuracy is not None and held_out_accuracy < 0.5


def _opposite_reason(accuracy: float) -> str:
    """The flag of an expert whose held-out judgements the negated weights predict better."""
    return (f"judges by the opposite criterion: the weights fitted on the other experts' judgements predict "
            f"{accuracy:.0%} of this expert's, the negated weights {1 - accuracy:.0%} (held-out accuracy below "
            f"chance, 0.5)")


def _experts(judgements: Judgements, weights: np.ndarray, prior: np.ndarray | None,
             strength: float) -> tuple[dict, dict, float | None]:
    """``per_expert``, ``flagged`` and the pooled held-out accuracy (None with fewer than two experts)."""
    names = list(dict.fromkeys(judgements.experts))
    if names == [None]:
        return {}, {}, None
    held = _held_out(judgements, prior, strength) if len(names) >= 2 else {}
    experts = np.array(judgements.experts, dtype=object)
    per_expert, flagged = {}, {}
    for name in names:
        own = judgements.subset(np.flatnonzero(experts == name))
        cyclic = _cyclic(own)
        accuracy = held.get(name)
        per_expert[name] = {"judgements": len(own.sign), "tau": float(np.mean(_concordance(own, weights))),
                            "held_out_accuracy": accuracy, "cyclic": cyclic}
        reasons = []
        if accuracy is not None and _is_opposed(accuracy):
            reasons.append(_opposite_reason(accuracy))
        if cyclic:
            reasons.append(f"{cyclic} judgement(s) on a cycle of this expert's own preferences")
        if reasons:
            flagged[name] = tuple(reasons)
    counts = [int(np.count_nonzero(experts == n)) for n in held]
    pooled = None if not held else float(np.average([held[n] for n in held], weights=counts))
    return per_expert, flagged, pooled


def _warn_opposed(per_expert: Mapping[str, Mapping], opposed: tuple) -> None:
    """A JudgementWarning naming the experts who judge by the opposite criterion."""
    if not opposed:
        return
    who = ", ".join(f"{e!r} (held-out accuracy {per_expert[e]['held_out_accuracy']:.2f}, "
                    f"{per_expert[e]['judgements']} judgements)" for e in opposed)
    warnings.warn(f"expert(s) {who} judge by the opposite criterion: the negated weights predict their judgements "
                  f"better than the weights fitted on the others'. Their judgements are averaged into the fitted "
                  f"weights; review them, or fit without them (exclude={list(opposed)!r})", JudgementWarning,
                  stacklevel=3)


def _without_experts(judgements: Judgements, exclude: Iterable[str] | None) -> tuple[Judgements, tuple]:
    """The judgements less those of the ``exclude`` experts (each must have judged), and the names left out."""
    if exclude is None:
        return judgements, ()
    names = (exclude,) if isinstance(exclude, str) else tuple(exclude)
    unknown = [n for n in names if n not in judgements.experts]
    if unknown or not all(isinstance(n, str) for n in names):
        known = sorted({e for e in judgements.experts if e is not None})
        raise FidelityError(f"exclude: {unknown or list(names)} are not experts of the judgements (experts: "
                            f"{known or 'none named'})", option="exclude")
    kept = np.flatnonzero([e not in names for e in judgements.experts])
    if kept.size == 0:
        raise FidelityError(f"exclude: leaving out {list(names)} leaves no judgement to fit", option="exclude")
    return judgements.subset(kept), tuple(dict.fromkeys(names))


# --------------------------------------------------------------------------- public fit
@dataclass(frozen=True)
class FittedWeights:
    """Result of :func:`fit_weights`.

    Attributes
    ----------
    weights : Weights
        The fitted ``K`` (0 for components not judged), usable wherever weights are
        (``ScoringConfig(weights=fit.weights)``, :func:`irfidelity.evaluate`, ...).
    scale : float
        ``s``: how decisive the judgements are (the logit of a preference per unit of
        weighted component difference).
    log_likelihood : float
        ``Σ log P(judgement)`` at the fit (without the penalties).
    agreement : dict
        ``tau``: Kendall's τ between the fitted utility ``Σ w_i f_i`` and the judgements
        (concordant minus discordant judged pairs over all, ties 0); ``accuracy``: the share of
        judgements the fitted weights reproduce; ``held_out_accuracy``: leave-one-expert-out,
        each expert's judgements predicted by the fit on the others' (None with fewer than two
        named experts); ``judgements``, ``experts``.
    per_expert : dict
        ``{expert: {"judgements", "tau", "held_out_accuracy", "cyclic"}}`` (empty when no
        judgement names its expert).
    flagged : dict
        ``{expert: (reason, ...)}`` for the inconsistent experts: held-out accuracy below 0.5
        (they judge by the opposite criterion: see ``opposed``), or any judgement on a cycle of
        the expert's own preferences (the same two items judged both ways, or
        ``a ≻ b ≻ c ≻ a``). A flag is a prompt to review the expert's judgements; the fit
        keeps them.
    components : tuple of str
        The components fitted.
    prior : Weights or None
    prior_strength : float
    opposed : tuple of str
        The experts who judge by the opposite criterion: the negated weights fitted on the
        other experts' judgements predict theirs better than the weights do (held-out accuracy
        below 0.5). Their judgements are in the fit, which warns
        (:class:`~irfidelity.errors.JudgementWarning`); ``fit_weights(..., exclude=opposed)``
        fits without them.
    excluded : tuple of str
        The experts left out of the fit (``exclude=``).
    """

    weights: Weights
    scale: float
    log_likelihood: float
    agreement: dict
    per_expert: dict
    flagged: dict
    components: tuple
    prior: Weights | None
    prior_strength: float
    opposed: tuple = ()
    excluded: tuple = ()

    def to_dict(self) -> dict:
        return {"weights": self.weights.as_dict(), "scale": self.scale, "log_likelihood": self.log_likelihood,
                "agreement": dict(self.agreement), "per_expert": {k: dict(v) for k, v in self.per_expert.items()},
                "flagged": {k: list(v) for k, v in self.flagged.items()}, "components": list(self.components),
                "prior": None if self.prior is None else self.prior.as_dict(), "prior_strength": self.prior_strength,
                "opposed": list(self.opposed), "excluded": list(self.excluded)}


def _prior_vector(prior: Any, components: tuple) -> tuple[Weights | None, np.ndarray | None]:
    if prior is None:
        return None, None
    weights = Weights.coerce(getattr(prior, "weights", prior))
    vector = np.array([weights[c] for c in components])
    if vector.sum() <= 0:
        raise FidelityError(f"the prior gives no weight to the judged components {list(components)}",
                            option="prior")
    return weights, vector / vector.sum()


def _check_strength(prior_strength: Any) -> float:
    """``prior_strength`` as a finite float >= 0, else FidelityError naming it."""
    number = isinstance(prior_strength, (int, float, np.integer, np.floating)) and not isinstance(prior_strength, bool)
    strength = float(prior_strength) if number else math.nan
    if not (math.isfinite(strength) and strength >= 0):
        raise FidelityError(f"prior_strength must be a finite number >= 0, got {prior_strength!r}",
                            option="prior_strength")
    return strength


def fit_weights(judgements: Iterable[Any], *, prior: Any = None, prior_strength: float = DEFAULT_PRIOR_STRENGTH,
                components: Iterable[str] | None = None, exclude: Iterable[str] | None = None) -> FittedWeights:
    """Learn the weights ``K`` from experts' pairwise preferences.

    Parameters
    ----------
    judgements : iterable of ``(a, b, preferred)`` or ``(a, b, preferred, expert)``
        ``a`` and ``b``: reports (anything with ``.components``) or ``{component: value}``
        mappings; ``preferred``: ``"a"`` or ``"b"``; ``expert``: a name (all judgements name
        one, or none does). :func:`read_judgements` reads them from a CSV.
    prior : Weights (or anything :meth:`Weights.coerce` accepts, or an AHP result), optional
        Weights to pull the fit toward, e.g. ``ahp(...)`` or :func:`combine_ahp`'s.
    prior_strength : float
        ``λ`` of the penalty ``λ·‖w − w_prior‖²`` (the prior's standard deviation per weight
        is ``1/√(2λ)``: 0.32 at the default :data:`DEFAULT_PRIOR_STRENGTH`, 5). It does not
        grow with the judgements, so the prior's pull fades as they accumulate (module notes).
    components : iterable of str, optional
        The components to fit; default those every judged item has. The others get weight 0.
    exclude : iterable of str, optional
        Experts whose judgements are left out (e.g. a previous fit's ``opposed``).

    Returns
    -------
    FittedWeights
        ``.weights``, ``.scale``, ``.log_likelihood``, ``.agreement``, ``.per_expert``,
        ``.flagged``, ``.opposed`` (the module notes give the model).

    Warns
    -----
    JudgementWarning
        When an expert judges by the opposite criterion (``.opposed``): their judgements are
        in the fit.

    A judgement whose two items have the same components carries no information (it adds
    ``log 2`` to the likelihood); a component that never differs within a judgement cannot be
    fitted and gets weight 0 (or what the prior says). Judgements that no weights explain
    better than a coin (fitted scale 0) are an error without a prior; with one, the prior's
    weights are returned.

    Examples
    --------
    Judgements made by someone who only looks at SSIM:

    >>> from irfidelity.fuzzy import fit_weights
    >>> items = [{"psnr": p, "ssim": s} for p, s in [(0.9, 0.5), (0.6, 0.8), (0.7, 0.6), (0.8, 0.9)]]
    >>> pairs = [(a, b) for i, a in enumerate(items) for b in items[i + 1:]]
    >>> fit = fit_weights([(a, b, "a" if a["ssim"] > b["ssim"] else "b") for a, b in pairs])
    >>> round(fit.weights.ssim, 2), round(fit.weights.psnr, 2), fit.agreement["tau"]
    (1.0, 0.0, 1.0)

    Two experts who look at SSIM and one who prefers the lower SSIM every time:

    >>> import warnings
    >>> sharper = lambda a, b: "a" if a["ssim"] > b["ssim"] else "b"
    >>> rows = [(a, b, sharper(a, b), e) for e in ("ann", "bob") for a, b in pairs]
    >>> rows += [(a, b, "b" if sharper(a, b) == "a" else "a", "cy") for a, b in pairs]
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     fit = fit_weights(rows)
    >>> fit.opposed, caught[0].category.__name__
    (('cy',), 'JudgementWarning')
    >>> round(fit_weights(rows, exclude=fit.opposed).weights.ssim, 2)
    1.0
    """
    parsed, excluded = _without_experts(parse_judgements(judgements, components), exclude)
    strength = _check_strength(prior_strength)
    prior_weights, prior_vector = _prior_vector(prior, parsed.components)
    fit = _fit(parsed, prior_vector, strength)
    if fit is None:
        if prior_vector is None:
            raise FidelityError("the judgements prefer no weighting over a coin toss (fitted scale 0): "
                                "check the preferred column, or give a prior")
        fit = Fit(prior_vector, 0.0)
    margin = parsed.sign * (parsed.difference @ (fit.scale * fit.weights))
    concord = _concordance(parsed, fit.weights)
    per_expert, flagged, held_out = _experts(parsed, fit.weights, prior_vector, strength)
    opposed = tuple(e for e, row in per_expert.items() if _is_opposed(row["held_out_accuracy"]))
    _warn_opposed(per_expert, opposed)
    agreement = {"tau": float(np.mean(concord)), "accuracy": float(np.mean(concord > 0)),
                 "held_out_accuracy": held_out, "judgements": len(parsed.sign), "experts": len(per_expert)}
    weights = Weights.normalized(**{c: float(w) for c, w in zip(parsed.components, fit.weights)})
    return FittedWeights(weights=weights, scale=fit.scale, log_likelihood=-float(np.logaddexp(0.0, -margin).sum()),
                         agreement=agreement, per_expert=per_expert, flagged=flagged, components=parsed.components,
                         prior=prior_weights, prior_strength=strength, opposed=opposed, excluded=excluded)


# --------------------------------------------------------------------------- several AHP matrices
@dataclass(frozen=True)
class CombinedAHP:
    """Result of :func:`combine_ahp`.

    Attributes
    ----------
    weights : Weights
        From the combined matrix.
    matrix : list of lists
        The element-wise geometric mean of the experts' matrices (reciprocal again).
    result : AHPResult
        :func:`irfidelity.fuzzy.ahp` of the combined matrix (its ``cr`` and ``consistent``).
    experts : dict
        ``{expert: AHPResult}``: each expert's own weights and consistency ratio.
    inconsistent : tuple of str
        Experts whose consistency ratio exceeds the threshold.
    """

    weights: Weights
    matrix: list
    result: AHPResult
    experts: dict
    inconsistent: tuple

    def to_dict(self) -> dict:
        return {"weights": self.weights.as_dict(), "matrix": [list(r) for r in self.matrix],
                "result": self.result.to_dict(), "experts": {k: v.to_dict() for k, v in self.experts.items()},
                "inconsistent": list(self.inconsistent)}


def combine_ahp(matrices: Mapping[str, Any] | Sequence[Any], *, names: Iterable[str] = PAPER_COMPONENTS,
                threshold: float = 0.1, on_inconsistent: str = "warn") -> CombinedAHP:
    """Several experts' AHP matrices combined by the element-wise geometric mean.

    The geometric mean keeps the matrix reciprocal (Aczél & Saaty 1983), so the combined
    judgements are a valid AHP matrix; its weights are :func:`irfidelity.fuzzy.ahp`'s.

    Parameters
    ----------
    matrices : {expert: matrix} or list of matrices
        Each as :func:`irfidelity.fuzzy.ahp` takes it, over the same ``names`` (a list names
        its experts ``"expert 1"``, ``"expert 2"``, ...).
    names : component names of the rows and columns
    threshold : float
        Saaty's consistency-ratio limit, for each expert and for the combination.
    on_inconsistent : "warn", "raise" or "ignore"
        What an inconsistent *combined* matrix does (as in :func:`irfidelity.fuzzy.ahp`);
        inconsistent experts are listed in ``.inconsistent`` either way.

    Examples
    --------
    >>> from irfidelity.fuzzy import combine_ahp
    >>> names = ["psnr", "ssim"]
    >>> c = combine_ahp({"ann": [[1, 4], [1 / 4, 1]], "bob": [[1, 1], [1, 1]]}, names=names)
    >>> c.matrix, round(c.weights.psnr, 3)
    ([[1.0, 2.0], [0.5, 1.0]], 0.667)
    """
    if isinstance(matrices, Mapping):
        named = {str(k): v for k, v in matrices.items()}
    elif isinstance(matrices, Sequence) and not isinstance(matrices, str):
        named = {f"expert {i + 1}": m for i, m in enumerate(matrices)}
    else:
        raise FidelityError("matrices must be a mapping {expert: matrix} or a list of matrices")
    if not named:
        raise FidelityError("combine_ahp needs at least one matrix")
    names = tuple(names)
    experts = {}
    for expert, matrix in named.items():
        try:
            experts[expert] = ahp(matrix, names=names, on_inconsistent="ignore", threshold=threshold)
        except FidelityError as exc:
            raise FidelityError(f"AHP matrix of {expert!r}: {exc}") from None
    logs = np.mean([np.log(np.array(m, dtype=np.float64)) for m in named.values()], axis=0)
    combined = np.exp(logs)
    result = ahp(combined, names=names, on_inconsistent=on_inconsistent, threshold=threshold)
    return CombinedAHP(weights=result.weights, matrix=combined.tolist(), result=result, experts=experts,
                       inconsistent=tuple(e for e, r in experts.items() if not r.consistent))


# --------------------------------------------------------------------------- the CSV
def _csv_error(path: str, line: int, column: str | None, message: str) -> FidelityError:
    where = f"{path}, line {line}" + ("" if column is None else f", column {column!r}")
    return FidelityError(f"{where}: {message}")


def _csv_columns(path: str, header: list[str]) -> tuple[tuple, bool]:
    """The judged components and whether an ``expert`` column is present."""
    stripped = [h.strip() for h in header]
    seen: set[str] = set()
    sides: dict[str, list[str]] = {"a": [], "b": []}
    for column in stripped:
        if column in seen:
            raise _csv_error(path, 1, column, "column given twice")
        seen.add(column)
        side, _, component = column.partition("_")
        if column in ("preferred", "expert"):
            continue
        if side not in sides or component not in COMPONENTS:
            raise _csv_error(path, 1, column, f"unknown column; expected a_<component> and b_<component> "
                                              f"(components {', '.join(COMPONENTS)}), preferred and optional expert")
        sides[side].append(component)
    if "preferred" not in seen:
        raise _csv_error(path, 1, None, "no 'preferred' column")
    for side, other in (("a", "b"), ("b", "a")):
        for component in sides[side]:
            if component not in sides[other]:
                raise _csv_error(path, 1, f"{side}_{component}", f"has no partner column {other}_{component}")
    if not sides["a"]:
        raise _csv_error(path, 1, None, "no component columns (a_<component>, b_<component>)")
    return tuple(c for c in COMPONENTS if c in sides["a"]), "expert" in seen


def _csv_number(path: str, line: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _csv_error(path, line, column, f"{text!r} is not a number") from None
    if not 0 <= value <= 1:
        raise _csv_error(path, line, column, f"{text!r} is outside [0, 1], a component's range")
    return value


#: The most judgement rows a file may hold: far beyond any panel of experts, and the fit's
#: memory (a few hundred bytes a row) stays within tens of megabytes.
MAX_JUDGEMENTS = 100_000


def read_judgements(path: str | os.PathLike) -> list[tuple]:
    """Judgements from a CSV file, for :func:`fit_weights`.

    The format: a header row, then one judgement per row. Columns ``a_<component>`` and
    ``b_<component>`` hold the two items' component values (the same components for both,
    any of mtf, sitf, psnr, nmi, ssim, noise; numbers, normally in [0, 1]); ``preferred`` is
    ``a`` or ``b`` (case and surrounding spaces ignored); an optional ``expert`` column names
    who judged (non-empty on every row). Column order is free; blank rows are skipped; no
    other columns are allowed. A mistake is a FidelityError naming the file, the line and the
    column.

    Returns
    -------
    list of tuples
        ``({component: value}, {component: value}, "a" | "b"[, expert])``.

    Examples
    --------
    >>> from irfidelity.judgements import read_judgements
    >>> with open("judged.csv", "w") as f:
    ...     _ = f.write("a_psnr,a_ssim,b_psnr,b_ssim,preferred,expert\\n0.9,0.7,0.8,0.9,b,ann\\n")
    >>> read_judgements("judged.csv")
    [({'psnr': 0.9, 'ssim': 0.7}, {'psnr': 0.8, 'ssim': 0.9}, 'b', 'ann')]
    """
    name = os.fspath(path)
    try:
        with open(name, newline="", encoding="utf-8") as handle:
            reader = csv.reader(handle)
            header = next(reader, None)
            if header is None:
                raise FidelityError(f"{name}: empty file; expected a header row a_<component>,...,preferred")
            components, has_expert = _csv_columns(name, header)
            index = {h.strip(): i for i, h in enumerate(header)}
            out: list[tuple] = []
            for row in reader:
                if any(cell.strip() for cell in row):
                    if len(out) == MAX_JUDGEMENTS:
                        raise FidelityError(f"{name}: more than {MAX_JUDGEMENTS} judgement rows (line "
                                            f"{reader.line_num}); fit a sample of them")
                    out.append(_csv_row(name, reader.line_num, row, index, components, has_expert))
    except csv.Error as exc:  # a field beyond the csv module's limit, a NUL byte, ...
        raise FidelityError(f"{name}: line {reader.line_num}: not a CSV row ({exc})") from None
    except OSError as exc:
        raise FidelityError(f"{name}: cannot read the judgements ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise FidelityError(f"{name}: not a UTF-8 text file") from None
    if not out:
        raise FidelityError(f"{name}: no judgement rows after the header")
    return out


def _csv_row(path: str, line: int, row: list[str], index: dict, components: tuple, has_expert: bool) -> tuple:
    if len(row) != len(index):
        raise _csv_error(path, line, None, f"{len(row)} cells, expected {len(index)} (one per header column)")
    cell = {column: row[i].strip() for column, i in index.items()}
    items = tuple({c: _csv_number(path, line, f"{side}_{c}", cell[f"{side}_{c}"]) for c in components}
                  for side in ("a", "b"))
    preferred = cell["preferred"].lower()
    if preferred not in ("a", "b"):
        raise _csv_error(path, line, "preferred", f"expected 'a' or 'b', got {cell['preferred']!r}")
    if not has_expert:
        return (*items, preferred)
    if not cell["expert"]:
        raise _csv_error(path, line, "expert", "empty; name the expert on every row")
    return (*items, preferred, cell["expert"])
