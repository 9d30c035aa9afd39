"""From statistics to a verdict: which components to compute, their values, fidelity, grade.

Shared by :func:`irfidelity.evaluate` (one pair) and :func:`irfidelity.score_sequence`
(every frame and the pooled statistics), so both give the same numbers for the same pair:

* :func:`plan_components` decides what to compute before anything is read (a component with
  weight 0, or without inputs, is not computed; docs/design.md, "plan only what is needed");
* :func:`image_components` turns a :class:`~irfidelity.PairStats` into f3..f5 (eqs. 5–14;
  :mod:`irfidelity.image_components`);
* :func:`score_components` adds eq. (15) and the fuzzy grade: a :class:`Score`;
* :func:`psnr_peak` resolves the configured peak for a frame and warns when it pins f3.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any, Mapping

from .config import ScoringConfig
from .errors import FidelityError, PeakWarning
from .fuzzy import COMPONENTS, PAPER_COMPONENTS, Grading, Weights, fidelity_sum, ordered_components
from .image_components import image_components
from .normalize import normalize_psnr
from .schema import CURVE_COMPONENTS, IMAGE_COMPONENTS
from .verdict import Verdict, judge

__all__ = ["plan_components", "plan_with_scene", "image_components", "score_components", "Score", "psnr_peak",
           "pinned_psnr_floor", "IMAGE_COMPONENTS", "CURVE_COMPONENTS"]

_INPUTS = {"mtf": "real_mtf/sim_mtf", "sitf": "real_sitf/sim_sitf", "psnr": "real/sim", "nmi": "real/sim",
           "ssim": "real/sim", "noise": "real_noise/sim_noise or real_ref", "radiometry": "real/sim scored in a unit (unit=K or C)",
           "mrtd": "real_mrtd/sim_mrtd"}


# --------------------------------------------------------------------------- plan
def plan_with_scene(config: ScoringConfig, given: Mapping[str, bool], scene: tuple[str, ...], *,
                    have_images: bool, absent: Mapping[str, str] | None = None
                    ) -> tuple[Weights, tuple[str, ...], dict]:
    """:func:`plan_components` with curves, noise recordings and MRTD inputs as ``given``
    (``{"mtf", "sitf", "noise", "mrtd": bool}``), the components the frames' scene stands in for
    (``scene``) as inputs too, but those in ``absent`` (``{component: why}``: the scene could not
    give them) not; their reasons replace the plan's."""
    absent = {k: why for k, why in (absent or {}).items() if config.weights[k] > 0}
    have = {k: (given[k] or k in scene) and k not in absent for k in ("mtf", "sitf", "noise")}
    try:
        weights, image, skipped = plan_components(
            config.weights, config.missing, have_images=have_images, have_mtf=have["mtf"], have_sitf=have["sitf"],
            have_noise=have["noise"], have_unit=config.unit is not None, have_mrtd=given["mrtd"])
    except FidelityError as exc:
        why = "; ".join(f"{k}: {reason}" for k, reason in absent.items())
        raise type(exc)(f"{exc}" + (f" (from the frames: {why})" if why else ""), option=exc.option) from None
    for k, reason in absent.items():
        if k in skipped:
            skipped[k] = f"not assessed: {reason}; weight {config.weights[k]:g} dropped and the rest renormalised"
    return weights, image, skipped


def plan_components(weights: Weights, missing: str, *, have_images: bool, have_mtf: bool,
                    have_sitf: bool, have_noise: bool = False, have_unit: bool = False, have_mrtd: bool = False
                    ) -> tuple[Weights, tuple[str, ...], dict]:
    """Decide what to compute, before computing anything.

    Parameters
    ----------
    weights : Weights
    missing : "raise" | "renormalize"
        A component with positive weight but no inputs: raise FidelityError naming the
        missing inputs, or drop it and rescale the remaining weights to sum 1.
    have_images, have_mtf, have_sitf, have_noise, have_mrtd : bool
        Whether frames, MTF inputs, SiTF inputs, noise recordings and MRTD inputs were given.
    have_unit : bool
        Whether the frames are scored in a temperature unit (the ``radiometry`` component's input).

    Returns
    -------
    (weights, image_components, skipped)
        The weights eq. (15) uses (dropped components 0); the image components to compute
        (subset of ``("psnr", "nmi", "ssim")``, empty: no image pass at all); and
        ``{component: reason}`` for every component not computed (the opt-in ``noise`` and
        ``radiometry`` and ``mrtd`` only when weighted).
    """
    have = {"mtf": have_mtf, "sitf": have_sitf, "psnr": have_images, "nmi": have_images, "ssim": have_images,
            "noise": have_noise, "radiometry": have_images and have_unit, "mrtd": have_mrtd}
    skipped: dict[str, str] = {}
    kept: dict[str, float] = {}
    absent = []
    for k in COMPONENTS:
        if weights[k] == 0:
            if k in PAPER_COMPONENTS:
                skipped[k] = "weight 0"
        elif not have[k]:
            absent.append(k)
        else:
            kept[k] = weights[k]
    if absent and missing == "raise":
        inputs = " and ".join(dict.fromkeys(_INPUTS[k] for k in absent))
        raise FidelityError(f"component(s) {', '.join(absent)} have a positive weight but no input: give "
                            f"{inputs}, set their weight to 0, or let missing components be dropped "
                            f"(missing = renormalize)", option="missing")
    for k in absent:
        skipped[k] = f"no input ({_INPUTS[k]} not given); weight {weights[k]:g} dropped and the rest renormalised"
    if not kept:
        raise FidelityError("nothing to compute: every component with a positive weight lacks its inputs "
                            f"({', '.join(dict.fromkeys(_INPUTS[k] for k in absent))})", option="weights")
    effective = Weights.normalized(**kept) if absent else weights
    return effective, tuple(k for k in IMAGE_COMPONENTS if effective[k] > 0), skipped


# --------------------------------------------------------------------------- the verdict
@dataclass(frozen=True)
class Score:
    """One scored pair (or pooled statistics): components, fidelity (eq. 15) and grade.

    Attributes
    ----------
    fidelity : float
    components : dict
        ``{component: f_i}`` in the paper's order.
    metrics : dict
        The raw values behind them (:data:`irfidelity.schema.METRICS`).
    grading : Grading
        Memberships, each component's grade and the overall grade.
    verdict : Verdict
        Why the grade is what it is (:mod:`irfidelity.verdict`).
    """

    fidelity: float
    components: dict
    metrics: dict
    grading: Grading
    verdict: Verdict

    @property
    def grade(self) -> str:
        return self.grading.grade

    def to_dict(self) -> dict:
        return {"fidelity": self.fidelity, "grade": self.grading.grade, "components": dict(self.components),
                "component_grades": dict(self.grading.component_grades),
                "membership": dict(self.grading.membership), "metrics": dict(self.metrics)}


def score_components(components: Mapping[str, float], metrics: Mapping[str, Any], weights: Weights,
                     config: ScoringConfig, *, scene_range: float | None = None,
                     ceiling: Mapping[str, float] | None = None, ceiling_source: str | None = None,
                     unassessed: Mapping[str, str] | None = None) -> Score:
    """Eq. (15) and the grade of a set of components, judged by the configured tolerances
    (``scene_range``: the real frame's max − min; ``ceiling``: NMI and SSIM of two real
    frames, and ``ceiling_source`` where they came from; ``unassessed``: what could not be
    assessed and why, said in the verdict; :func:`irfidelity.verdict.judge`)."""
    comps = ordered_components(components)
    verdict = judge(comps, metrics, weights, config, scene_range=scene_range, ceiling=ceiling,
                    ceiling_source=ceiling_source, unassessed=unassessed)
    return Score(fidelity=fidelity_sum(weights, comps), components=comps, metrics=dict(metrics),
                 grading=verdict.grading(weights), verdict=verdict)


# --------------------------------------------------------------------------- PSNR peak
def pinned_psnr_floor(peak: float, scene_range: float, config: ScoringConfig) -> float:
    """The smallest f3 a simulated frame can get while its RMS error stays within the real
    frame's range: the normalised PSNR at MSE = range², i.e. at ``20·log10(peak/range)`` dB."""
    if scene_range <= 0:
        return 0.0
    return normalize_psnr(20.0 * math.log10(peak / scene_range), anchors=config.psnr_anchors)


#: f3 floors at or above this (the paper's 30 dB anchor, f3 = 0.9) pin the component.
PINNED_FLOOR = 0.9


def psnr_peak(config: ScoringConfig, default_peak: float | None, scene_range: float | None,
              where: str) -> float:
    """The PSNR peak for one frame: the configured number, ``2**bits - 1`` / the dtype's
    maximum (``default_peak``), or the real frame's range for ``peak="range"``.

    Warns (:class:`~irfidelity.PeakWarning`) when the peak pins f3 near 1 (see
    :func:`pinned_psnr_floor`); ``where`` names the frame in messages.
    """
    if config.peak == "range":
        if scene_range is None or not scene_range > 0:
            raise FidelityError(f"{where}: the PSNR peak 'range' needs a real frame with more than one value "
                                f"(its range is {scene_range!r})", option="peak")
        return float(scene_range)
    peak = config.peak if config.peak is not None else default_peak
    assert not isinstance(peak, str)  # ScoringConfig allows no string but "range"
    if peak is None:
        raise FidelityError("PSNR of float frames needs a peak: a number (the largest possible value) or "
                            "'range' (the real frame's max − min)", option="peak")
    if scene_range is not None:
        floor = pinned_psnr_floor(peak, scene_range, config)
        if floor >= PINNED_FLOOR:
            warnings.warn(PeakWarning(
                f"{where}: the PSNR peak {peak:g} is {peak / scene_range:.0f}× the real frame's range "
                f"{scene_range:g}, so the psnr component cannot fall below {floor:.3f} for any simulated "
                f"frame whose errors stay within that range; the peak 'range' (max − min of the real frame) "
                f"lets it move", option="peak"), stacklevel=3)
    return float(peak)
