"""The verdict on a score: each component's grade from its tolerance, one overall grade, and why.

One rule (docs/interpretation.md, "Grades"). A weighted component meets a grade when its value
reaches that grade's limit converted to its scale (:func:`irfidelity.tolerances.component_cuts`);
its grade is the best one it meets. The overall grade is the worst component grade: the best
grade whose tolerances every weighted component meets, as a specification is met. The verdict
names the component that set it and how far it is from the tolerance of the next better grade
(for "excellent": the component closest to its limit). The fidelity (eq. 15) is not changed.

The memberships of the fuzzy evaluation follow from the same grades: each component's row of
``R`` is 1 in its grade, so ``B = K·R`` is the share of the weight in each grade, and the overall
grade is the worst grade with a share — printed beside the grade, it cannot contradict it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Mapping

from .ceiling import CEILING_SOURCES
from .errors import FidelityError
from .fuzzy import COMPONENTS, Grading, Weights, fidelity_sum
from .tolerances import COMPONENT_OF, KINDS, component_cuts, mu_of_ratio

__all__ = ["ComponentVerdict", "Grader", "Verdict", "judge", "mu_ratio"]

_TOLERANCE_OF = {component: name for name, component in COMPONENT_OF.items()}

#: A value this close below a cut meets it: a component exactly at a limit (an MTF50 exactly 10 %
#: low) is not pushed into the worse grade by the rounding of ρ or μ.
_ROUNDING = 1e-12


def mu_ratio(mu: float) -> float:
    """The ratio ``r <= 1`` with ``2r/(1 + r²) = mu`` (the inverse of eq. 4), 0 for ``mu <= 0``."""
    m = min(max(float(mu), 0.0), 1.0)
    return 0.0 if m == 0 else (1.0 - math.sqrt((1.0 - m) * (1.0 + m))) / m


@dataclass(frozen=True)
class ComponentVerdict:
    """One weighted component judged against its tolerance.

    Attributes
    ----------
    component : str
    value : float
        The component's value f_i.
    grade : str
        The best grade whose cut the value reaches.
    cuts : (float, float, float)
        The limits of excellent, good and fair on the component's scale.
    basis : str
        What the cuts rest on: "tolerance", "range", "peak", "ceiling" or "absolute".
    measure : float
        The component in the tolerance's unit (mismatch, noise or MRTD ratio, RMS fraction,
        temperature tolerances, fraction of the ceiling; the value itself for "absolute").
    limits : (float, float, float)
        The tolerance's limits in that unit.
    text : str
        The measure in words ("MTF50 18 % below the real camera's").
    source : str or None
        Where a camera component's input came from: "curves", "edge images", "bar frames",
        "CTF curves", "noise recordings", or "scene" (the frame pair's transfer,
        :mod:`irfidelity.system`); None for the image components.
    weighted : bool
        False for a component measured and graded as a check but not weighted (the scene's
        noise when ``noise`` has weight 0): it does not set the grade.
    """

    component: str
    value: float
    grade: str
    cuts: tuple
    basis: str
    measure: float
    limits: tuple
    text: str
    source: str | None = None
    weighted: bool = True

    @property
    def at_most(self) -> bool:
        return self.basis != "absolute" and KINDS[_TOLERANCE_OF[self.component]] == "most"

    def excess(self, level: int) -> float:
        """How far the measure is from the limit of grade ``level`` (0 = excellent): above 1
        beyond it, below 1 within it."""
        limit = self.limits[level]
        if self.at_most:
            return self.measure / limit if limit > 0 else math.inf
        return limit / self.measure if self.measure > 0 else math.inf

    def limit_text(self, level: int) -> str:
        limit = self.limits[level]
        name = _TOLERANCE_OF[self.component]
        if self.basis == "absolute":
            return f"{self.component} ≥ {limit:.3g} (the calibrated boundary; no ceiling was measured)"
        if name in ("mtf50", "sitf_slope"):
            return f"a mismatch of {_percent(limit)}"
        if name in ("noise_ratio", "mrtd_ratio"):
            return f"{limit:.3g}× either way"
        if name == "radiometry":
            return f"{limit:.3g} temperature tolerance{'' if limit == 1 else 's'}"
        if name == "rms_error":
            return f"{_percent(limit)} of {'the scene' + chr(39) + 's range' if self.basis == 'range' else 'the PSNR peak'}"
        return f"{_percent(limit)} of the ceiling"

    def to_dict(self) -> dict:
        return {"value": self.value, "grade": self.grade, "cuts": list(self.cuts), "basis": self.basis,
                "measure": self.measure, "limits": list(self.limits), "text": self.text, "source": self.source,
                "weighted": self.weighted}


def _percent(x: float) -> str:
    return f"{100 * x:.3g} %"


def _ratio_text(what: str, real: float, sim: float) -> str:
    """``what`` of the simulator against the real camera's, in words, with the mismatch."""
    r = sim / real
    if r <= 1:
        return f"{what} {_percent(1 - r)} below the real camera's"
    return f"{what} {_percent(r - 1)} above the real camera's (a mismatch of {_percent(1 - 1 / r)}, 1 − smaller/larger)"


def _curve_measure(kind: str, value: float, metrics: Mapping[str, Any], alpha: float) -> tuple[float, str]:
    """The effective mismatch ``1 − r`` of f1 (f2) — exact for curves of the real shape — and
    its words from the MTF50s (slopes) and the shape's correlation."""
    effective = 1.0 - mu_ratio(value ** (1.0 / alpha) if alpha > 0 else 1.0)
    keys = ("mtf50_real", "mtf50_sim", "MTF50") if kind == "mtf" else ("sitf_slope_real", "sitf_slope_sim",
                                                                        "SiTF slope")
    real, sim = metrics.get(keys[0]), metrics.get(keys[1])
    if not (isinstance(real, (int, float)) and isinstance(sim, (int, float)) and real > 0 and sim > 0):
        return effective, f"effective mismatch {_percent(effective)}"
    text = _ratio_text(keys[2], float(real), float(sim))
    rho = metrics.get(f"{kind}_rho")
    mismatch = 1.0 - min(real, sim) / max(real, sim)
    if isinstance(rho, (int, float)) and effective > mismatch + 1e-4:
        text += f"; with the curves' shape (ρ {rho:.3f}) an effective mismatch of {_percent(effective)}"
    return effective, text


def _mrtd_measure(value: float, metrics: Mapping[str, Any], alpha: float) -> tuple[float, str]:
    """The effective MRTD ratio ``larger/smaller`` of the mrtd component — exact for an MRTD
    of the real shape — and its words from the level ratio and the forgiven tolerance."""
    ratio = 1.0 / max(mu_ratio(value ** (1.0 / alpha) if alpha > 0 else 1.0), 1e-300)
    level, forgiven = metrics.get("mrtd_ratio"), metrics.get("mrtd_tolerance")
    if not (isinstance(level, (int, float)) and level > 0):
        return ratio, f"effective MRTD ratio {ratio:.3g}"
    text = f"MRTD {level:.3g}× the real camera's"
    if isinstance(forgiven, (int, float)) and forgiven > 0:
        text += f" ({forgiven:.3g} % of it forgiven by mrtd_options.tolerance)"
    if abs(ratio - max(level, 1.0 / level)) > 1e-4:
        text += f"; effective ratio {ratio:.3g}"
    return ratio, text


def _radiometry_measure(value: float, metrics: Mapping[str, Any]) -> tuple[float, str]:
    """The temperature error ``sqrt((bias² + RMSE²)/2)`` in temperature tolerances, and its words."""
    from .temperature import radiometry_component

    one = radiometry_component(1.0, 1.0, 1.0)  # the component at one tolerance: value = one ** (e²)
    errors = math.sqrt(math.log(value) / math.log(one)) if value > 0 else math.inf
    bias, rmse, tol = (metrics.get(f"temperature_{k}") for k in ("bias", "rmse", "tolerance"))
    if not all(isinstance(v, (int, float)) for v in (bias, rmse, tol)):
        return errors, f"temperature error {errors:.3g} temperature tolerances"
    return errors, (f"temperature bias {bias:+.3g} K, RMSE {rmse:.3g} K: {errors:.3g} temperature tolerances "
                    f"(of {tol:.3g} K)")


def _plus_minus(value: Any, error: Any, percent: bool = False) -> str:
    """``value ± error`` in words (the error left out when unknown)."""
    text = _percent(value) if percent else f"{value:.4g}"
    if isinstance(error, (int, float)) and math.isfinite(error):
        text += f" ± {_percent(error) if percent else f'{error:.1g}'}"
    return text


def _graded_at(estimate: Any, graded: float, words: str, own: Any = None) -> str:
    """", graded at X" when the graded measure differs from the estimate: the doubt taken off,
    and what the real camera shows against itself (``own``, a second real frame's)."""
    if not isinstance(estimate, (int, float)) or abs(graded - estimate) <= 1e-3 * max(abs(estimate), 1e-12):
        return ""
    why = "2 standard errors toward a match"
    if isinstance(own, (int, float)) and own > 0:
        why += f", less the {_percent(own)} the real camera shows against itself"
    return f", graded at {words} ({why})"


def _scene_measure(component: str, value: float, metrics: Mapping[str, Any], alpha: float) -> tuple[float, str]:
    """The measure of a camera component graded from the scene's transfer, and its words."""
    m = metrics
    if component == "noise":
        ratio = 1.0 / max(mu_ratio(value), 1e-300)
        estimate = m.get("scene_noise_ratio")
        graded = ratio if not isinstance(estimate, (int, float)) or estimate >= 1 else 1.0 / ratio
        return ratio, (f"noise {_plus_minus(estimate, m.get('scene_noise_ratio_err'))}× the real camera's (from the "
                       f"scene)" + _graded_at(estimate, graded, f"{graded:.3g}×"))
    effective = 1.0 - mu_ratio(value ** (1.0 / alpha) if alpha > 0 else 1.0)
    if component == "mtf":
        low, high = m.get("scene_band_low"), m.get("scene_band_high")
        estimate = m.get("scene_mtf50_mismatch")
        if estimate is None:  # unread, by the simulator's doing (Transfer.unread_cause)
            return effective, (f"no MTF ratio to read: the simulated frame's noise hides it where the scene carries "
                               f"detail (over {low:.3g}–{high:.3g} cy/px), counted as an MTF50 mismatch of "
                               f"{_percent(effective)}")
        return effective, (f"simulated MTF {_ratio_words(m.get('scene_mtf_ratio'), m.get('scene_mtf_ratio_err'))} "
                           f"the real camera's at {m.get('scene_reference_frequency', 0):.3g} cy/px (from the scene, "
                           f"trusted over {low:.3g}–{high:.3g} cy/px): an MTF50 mismatch of "
                           f"{_plus_minus(estimate, m.get('scene_mtf50_mismatch_err'), True)}"
                           + _graded_at(estimate, effective, _percent(effective), m.get("scene_mtf50_mismatch_ceiling")))
    gain = m.get("scene_gain")
    if not isinstance(gain, (int, float)) or gain <= 0:
        return effective, "inverted grey levels: the simulated frame falls where the real one rises (gain ≤ 0)"
    estimate = 1.0 - min(gain, 1.0 / gain)
    return effective, (f"gain {_plus_minus(gain, m.get('scene_gain_err'))} on the scene ("
                       + _ratio_text("SiTF slope", 1.0, float(gain)) + ")"
                       + _graded_at(estimate, effective, f"a mismatch of {_percent(effective)}", _own_gain(m)))


def _own_gain(metrics: Mapping[str, Any]) -> float | None:
    """The gain mismatch of the real camera against itself, when measured."""
    own = metrics.get("scene_gain_ceiling")
    return 1.0 - min(own, 1.0 / own) if isinstance(own, (int, float)) and own > 0 else None


def _ratio_words(ratio: Any, error: Any) -> str:
    """A ratio and its error in words: "0.812 ± 0.004×", or "below 0.001×" when it is lost."""
    if not isinstance(ratio, (int, float)):
        return "?×"
    if ratio < 1e-3:
        return "below 0.001×"
    text = f"{ratio:.3g}"
    if isinstance(error, (int, float)) and math.isfinite(error):
        text += f" ± {error:.1g}"
    return text + "×"


def _measure(component: str, value: float, basis: str, metrics: Mapping[str, Any], config: Any,
             span: float | None, ceiling: float | None, source: str | None) -> tuple[float, str]:
    if component in ("mtf", "sitf", "noise") and metrics.get(f"{component}_source") == "scene":
        options = {"mtf": config.mtf_options, "sitf": config.sitf_options}.get(component, {})
        return _scene_measure(component, value, metrics, float(options.get("alpha", 1.0)))
    if component in ("mtf", "sitf"):
        options = config.mtf_options if component == "mtf" else config.sitf_options
        return _curve_measure(component, value, metrics, float(options.get("alpha", 1.0)))
    if component == "noise":
        real, sim = metrics.get("noise_sigma_tvh_real"), metrics.get("noise_sigma_tvh_sim")
        ratio = 1.0 / max(mu_ratio(value), 1e-300)
        if isinstance(real, (int, float)) and isinstance(sim, (int, float)) and real > 0 and sim > 0:
            return ratio, f"temporal noise σ_tvh {sim / real:.3g}× the real camera's (effective ratio {ratio:.3g})"
        return ratio, f"effective noise ratio {ratio:.3g}"
    if component == "mrtd":
        return _mrtd_measure(value, metrics, float(config.mrtd_options.get("alpha", 1.0)))
    if component == "radiometry":
        return _radiometry_measure(value, metrics)
    if component == "psnr":
        rms = math.sqrt(max(float(metrics.get("mse", 0.0)), 0.0))
        fraction = rms / span if span else math.inf
        where = "the scene's range" if basis == "range" else "the PSNR peak"
        return fraction, f"RMS error {_percent(fraction)} of {where} ({rms:.4g} of {span:.4g})"
    if basis == "absolute":
        return value, f"{component} {value:.3f}"
    share = value / ceiling if ceiling else 0.0
    words = CEILING_SOURCES.get(source or "", "real vs real")
    return share, f"{component} {value:.3f}, {_percent(share)} of the ceiling {ceiling:.3f} ({words})"


@dataclass(frozen=True)
class Verdict:
    """The grade of a score and why (the module notes state the rule).

    Attributes
    ----------
    grades : tuple of str
        Grade names, best first.
    grade : str
        The overall grade: the worst component grade.
    decided_by : str
        The component that set it.
    reason : str
        One sentence: the grade, the component that set it, by how much it missed the
        tolerance of the next better grade.
    components : dict
        ``{component: ComponentVerdict}``.
    ceiling_source : str or None
        Where the ceiling NMI and SSIM were graded against came from: a key of
        :data:`irfidelity.ceiling.CEILING_SOURCES` ("given", "real_ref", "sequence", "noise3d").
    checks : dict
        ``{component: ComponentVerdict}`` graded but not weighted (they do not set the grade).
    unassessed : dict
        ``{component: why}``: what could not be assessed.
    """

    grades: tuple
    grade: str
    decided_by: str
    reason: str
    components: dict
    ceiling_source: str | None = None
    checks: dict = field(default_factory=dict)
    unassessed: dict = field(default_factory=dict)

    def grading(self, weights: Weights) -> Grading:
        """The fuzzy evaluation these grades give: ``R`` one-hot, ``B`` the weight per grade."""
        grades = {k: c.grade for k, c in self.components.items()}
        matrix = {k: {g: float(g == grade) for g in self.grades} for k, grade in grades.items()}
        return Grading(grades=self.grades, matrix=matrix, membership=membership(grades, weights, self.grades),
                       component_grades=grades, grade=self.grade)

    def to_dict(self) -> dict:
        return {"grade": self.grade, "decided_by": self.decided_by, "reason": self.reason,
                "rule": "the worst grade of the weighted components, each graded by its tolerance",
                "components": {k: c.to_dict() for k, c in self.components.items()},
                "ceiling_source": self.ceiling_source, "checks": {k: c.to_dict() for k, c in self.checks.items()},
                "unassessed": dict(self.unassessed)}


def _grade_names(config: Any) -> tuple:
    names = tuple(config.grades.grades)
    if len(names) != 4:
        raise FidelityError(f"the tolerances separate four grades (best first, e.g. excellent, good, fair, poor); "
                            f"grades has {len(names)}: {list(names)}", option="grades")
    return names


def _reason(names: tuple, grade: str, decider: ComponentVerdict) -> str:
    level = names.index(grade)
    if level == 0:
        return (f"{grade}: every weighted component is within its tolerance for {names[0]}; closest to its limit: "
                f"{decider.component} ({decider.text}; the tolerance is {decider.limit_text(0)})")
    better = names[level - 1]
    return (f"{grade}: {decider.component} set the grade — {decider.text}; the tolerance for {better} is "
            f"{decider.limit_text(level - 1)}")


def judge(components: Mapping[str, float], metrics: Mapping[str, Any], weights: Weights, config: Any, *,
          scene_range: float | None = None, ceiling: Mapping[str, float] | None = None,
          ceiling_source: str | None = None, unassessed: Mapping[str, str] | None = None) -> Verdict:
    """Grade every weighted component by its tolerance, and the whole by the weakest one.

    Parameters
    ----------
    components, metrics : mapping
        The component values and raw metrics of a score.
    weights : Weights
        The weights used (components with weight 0 are not judged).
    config : ScoringConfig
        Its ``tolerances``, ``grades`` (the four names), PSNR anchors and curve exponents.
    scene_range : float, optional
        The real frame's max − min: the RMS tolerance is relative to it (else to the peak).
    ceiling : mapping, optional
        ``{"nmi": value, "ssim": value}`` of two real frames; without one NMI and SSIM are
        graded by the calibrated absolute boundaries.
    ceiling_source : str, optional
        Where the ceiling came from (:data:`irfidelity.ceiling.CEILING_SOURCES`), said in the reason.
    unassessed : mapping, optional
        ``{component: why}`` for what could not be assessed; said at the end of the reason.

    The scene's noise ratio (``metrics["scene_noise_ratio"]``) is graded as a check when the
    ``noise`` component has weight 0: named in the reason, it does not set the grade.

    Examples
    --------
    >>> import irfidelity as irf
    >>> from irfidelity.verdict import judge
    >>> cfg = irf.ScoringConfig(weights="mtf=0.5,psnr=0.5")
    >>> v = judge({"mtf": 0.92, "psnr": 0.95}, {"mtf50_real": 0.30, "mtf50_sim": 0.20, "mse": 1.0,
    ...           "psnr_peak": 100.0}, cfg.weights, cfg, scene_range=100.0)
    >>> v.grade, v.decided_by
    ('poor', 'mtf')
    >>> v.reason
    "poor: mtf set the grade — MTF50 33.3 % below the real camera's; the tolerance for fair is a mismatch of 20 %"
    """
    context = _Context(Grader(weights, config, ceiling), metrics, scene_range, ceiling_source)
    names = context.grader.names
    judged = {k: context.judge(k, float(components[k])) for k in context.grader.judged(components)}
    checks = {}
    if weights["noise"] <= 0 and isinstance(metrics.get("scene_noise_ratio"), (int, float)):
        ratio = float(metrics["scene_noise_ratio"])
        checks["noise"] = replace(context.judge("noise", mu_of_ratio(ratio) if ratio > 0 else 0.0, "scene"),
                                  weighted=False)
    worst = max(names.index(c.grade) for c in judged.values())
    level = max(worst - 1, 0)
    candidates = [c for c in judged.values() if names.index(c.grade) == worst]
    decider = max(candidates, key=lambda c: c.excess(level))
    reason = _reason(names, names[worst], decider) + _aside(checks, dict(unassessed or {}))
    return Verdict(grades=names, grade=names[worst], decided_by=decider.component, reason=reason, components=judged,
                   ceiling_source=ceiling_source if ceiling else None, checks=checks,
                   unassessed=dict(unassessed or {}))


@dataclass(frozen=True)
class _Context:
    """What grading a component in words needs besides its value."""

    grader: Grader
    metrics: Mapping[str, Any]
    scene_range: float | None
    ceiling_source: str | None

    def judge(self, k: str, value: float, source: str | None = None) -> ComponentVerdict:
        """``k`` at ``value`` against its tolerance (:func:`judge`)."""
        grader, metrics = self.grader, self.metrics
        config, peak = grader.config, metrics.get("psnr_peak")
        roof = None if grader.ceiling is None else grader.ceiling.get(k)
        cuts, basis = grader.cuts(k, peak, self.scene_range)
        grade = grader.names[grade_level(value, cuts)]
        span = self.scene_range if basis == "range" else (None if peak is None else float(peak))
        measured = {**metrics, "noise_source": "scene"} if source == "scene" else metrics
        measure, text = _measure(k, value, basis, measured, config, span, roof, self.ceiling_source)
        limits = cuts if basis == "absolute" else config.tolerances.limits(_TOLERANCE_OF[k])
        origin = source or metrics.get(f"{k}_source")
        return ComponentVerdict(k, value, grade, tuple(cuts), basis, measure, tuple(limits), text,
                                source=origin if isinstance(origin, str) else None)


def grade_level(value: float, cuts: tuple) -> int:
    """The best grade (0 = the first, the strictest) whose cut ``value`` reaches; 3 when it
    reaches none."""
    for level, cut in enumerate(cuts):
        if value >= cut - _ROUNDING:
            return level
    return 3


def membership(component_grades: Mapping[str, str], weights: Weights | Mapping[str, float], names: tuple) -> dict:
    """``B = K·R`` with ``R`` one-hot in each component's grade: the share of the weight in each
    grade (sums to 1)."""
    graded: dict[str, list[float]] = {g: [] for g in names}
    for k, grade in component_grades.items():
        graded[grade].append(weights[k])
    share = {g: math.fsum(w) for g, w in graded.items()}
    total = math.fsum(share.values()) or 1.0
    return {g: v / total for g, v in share.items()}


class Grader:
    """The grades of scores under one configuration, weights and ceiling, without the words.

    Each component's cuts (:func:`irfidelity.tolerances.component_cuts`) are found once; the
    PSNR's depend on the peak and the scene's range, and are kept for the last
    :data:`_PSNR_CUTS_KEPT` of those. :func:`judge` grades with it and adds the words; a
    sequence grades its frames with :meth:`summary` alone, which gives the same grades,
    memberships and fidelity.
    """

    def __init__(self, weights: Weights, config: Any, ceiling: Mapping[str, float] | None = None):
        self.names = _grade_names(config)
        self.weights, self.config, self.ceiling = weights, config, ceiling
        self.active = tuple(weights.active())
        self._weight = {k: weights[k] for k in COMPONENTS}
        self._cuts: dict[str, tuple[tuple, str]] = {}
        self._psnr_cuts: dict[tuple, tuple[tuple, str]] = {}
        self._judged_of: dict[tuple, list[str]] = {}  # the graded components of each set of names
        self._judged_cuts: dict[tuple, list[tuple]] = {}  # their cuts, by (names, peak, scene range)

    def cuts(self, k: str, peak: Any, scene_range: float | None) -> tuple[tuple, str]:
        """The cuts of ``k`` and their basis (``peak`` and ``scene_range`` matter to psnr only)."""
        psnr_key = (peak, scene_range)
        found = self._psnr_cuts.get(psnr_key) if k == "psnr" else self._cuts.get(k)
        if found is not None:
            return found
        config = self.config
        options = {"mtf": config.mtf_options, "sitf": config.sitf_options, "mrtd": config.mrtd_options}.get(k, {})
        found = component_cuts(k, config.tolerances, alpha=float(options.get("alpha", 1.0)),
                               peak=None if peak is None else float(peak), scene_range=scene_range,
                               anchors=config.psnr_anchors, ceiling=None if self.ceiling is None else self.ceiling.get(k))
        if k != "psnr":
            self._cuts[k] = found
        else:
            if len(self._psnr_cuts) >= _PSNR_CUTS_KEPT:
                self._psnr_cuts.clear()
            self._psnr_cuts[psnr_key] = found
        return found

    def judged(self, components: Mapping[str, float]) -> list[str]:
        """The components graded: those with a positive weight, in the paper's order."""
        judged = [k for k in COMPONENTS if k in components and self._weight[k] > 0]
        if not judged:
            raise FidelityError("no component with a positive weight to grade")
        return judged

    def summary(self, components: Mapping[str, float], metrics: Mapping[str, Any],
                scene_range: float | None = None) -> dict:
        """``fidelity``, ``grade``, ``component_grades`` and ``membership`` of a score, as
        :func:`irfidelity.scoring.score_components` gives them."""
        peak, names, weight = metrics.get("psnr_peak"), self.names, self._weight
        given = tuple(components)
        judged = self._judged_of.get(given)
        if judged is None:
            judged = self.judged(components)
            if len(judged) != len(self.active):
                fidelity_sum(self.weights, components)  # raises, naming the components without a value
            self._judged_of[given] = judged
        values = [float(components[k]) for k in judged]
        cuts = self._judged_cuts.get((given, peak, scene_range))
        if cuts is None:
            if len(self._judged_cuts) >= _PSNR_CUTS_KEPT:
                self._judged_cuts.clear()
            cuts = [self.cuts(k, peak, scene_range)[0] for k in judged]
            self._judged_cuts[(given, peak, scene_range)] = cuts
        levels = [grade_level(v, cut) for v, cut in zip(values, cuts)]
        grades = {k: names[level] for k, level in zip(judged, levels)}
        return {"fidelity": math.fsum([weight[k] * v for k, v in zip(judged, values)]),
                "grade": names[max(levels)], "component_grades": grades,
                "membership": membership(grades, weight, names)}


#: How many (peak, scene range) pairs a :class:`Grader` keeps the PSNR cuts of.
_PSNR_CUTS_KEPT = 4096


def _aside(checks: Mapping[str, ComponentVerdict], unassessed: Mapping[str, str]) -> str:
    """What the verdict adds after its reason: checks graded but not weighted, and what could
    not be assessed and why."""
    text = "".join(f"; checked but not weighted: {c.component} {c.grade} ({c.text})" for c in checks.values())
    if unassessed:
        text += "; not assessed: " + "; ".join(f"{k} — {why}" for k, why in unassessed.items())
    return text
