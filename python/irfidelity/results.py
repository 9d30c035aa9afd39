"""The report of one scene: :class:`FidelityReport`, and the text shared by every report.

A report holds the verdict (fidelity, grade, components, raw metrics) and how it was made
(the :class:`~irfidelity.ScoringConfig`, the irfidelity version, the effective weights,
what was skipped and why, notes, inputs). Its JSON form follows :mod:`irfidelity.schema`,
the same keys a sequence report uses for its pooled result and for each frame.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Mapping

from .config import ScoringConfig
from .errors import FidelityError
from .fuzzy import COMPONENTS, PAPER_COMPONENTS, Weights
from . import readback
from .readback import Fields, check_json, shared_fields
from .schema import from_json, to_json

__all__ = ["FidelityReport", "component_lines", "recorded_warnings", "reading_report", "verdict_lines"]


@contextlib.contextmanager
def reading_report(cls: type, data: Any) -> Iterator[dict]:
    """The decoded dict of a report's JSON form; a FidelityError naming the report class for
    anything that is not one."""
    if not isinstance(data, Mapping):
        raise FidelityError(f"not a {cls.__name__} dict: got {type(data).__name__}")
    check_json(data, "report")
    try:
        yield from_json(dict(data))
    except KeyError as exc:
        raise FidelityError(f"not a {cls.__name__} dict: missing key {exc}") from None
    except (TypeError, ValueError, AttributeError) as exc:
        if isinstance(exc, FidelityError):
            raise
        raise FidelityError(f"not a {cls.__name__} dict: {exc}") from None


@contextlib.contextmanager
def recorded_warnings() -> Iterator[list[str]]:
    """Collect the warnings raised inside as report notes (``"Category: message"``), and
    re-issue them on leaving, so callers still see them."""
    notes: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield notes
    for w in caught:
        notes.append(f"{w.category.__name__}: {w.message}")
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def version() -> str:
    from . import __version__

    return __version__


_RAW = {
    "mtf": lambda m: f"MTF50 real {m['mtf50_real']:.4g}, sim {m['mtf50_sim']:.4g} {m.get('mtf50_unit') or ''}; "
                     f"mu {m['mtf_mu']:.4f}, rho {m['mtf_rho']:.4f}",
    "sitf": lambda m: f"slope real {m['sitf_slope_real']:.4g}, sim {m['sitf_slope_sim']:.4g} "
                      f"{m.get('sitf_slope_unit') or ''}; mu {m['sitf_mu']:.4f}, rho {m['sitf_rho']:.4f}",
    "psnr": lambda m: f"PSNR {m['psnr_db']:.3f} dB (peak {m['psnr_peak']:g}), MSE {m['mse']:.6g}",
    "nmi": lambda m: f"MI {m['mi']:.4f}, H(R) {m['h_real']:.4f}, H(S) {m['h_sim']:.4f}, H(R,S) {m['h_joint']:.4f}",
    "noise": lambda m: f"σ_tvh real {m['noise_sigma_tvh_real']:.4g}, sim {m['noise_sigma_tvh_sim']:.4g}; "
                       f"mu {m['noise_mu']:.4f}, rho {m['noise_rho']:.4f}",
    "ssim": lambda m: f"SSIM {m['ssim']:.4f} = l {m['ssim_luminance']:.4f} · c {m['ssim_contrast']:.4f} · "
                      f"s {m['ssim_structure']:.4f}",
}


def component_lines(components: Mapping[str, float], component_grades: Mapping[str, str],
                    metrics: Mapping[str, Any], weights: Weights, skipped: Mapping[str, str]) -> list[str]:
    """The component table of a text summary: weight, value, own grade, raw metrics."""
    lines = [f"{'component':<10} {'weight':>7} {'value':>8}  {'grade':<9} raw"]
    for k in COMPONENTS:
        if k not in components and k not in skipped and k not in PAPER_COMPONENTS:
            continue  # an opt-in component nobody asked for
        if k in components:
            try:
                raw = _RAW[k](metrics)
            except (KeyError, TypeError, ValueError):
                raw = ""
            lines.append(f"{k:<10} {weights[k]:>7.4f} {components[k]:>8.4f}  {component_grades.get(k, ''):<9} {raw}")
        else:
            lines.append(f"{k:<10} {'-':>7} {'-':>8}  {'':<9} skipped: {skipped.get(k, '')}")
    return lines


@dataclass
class FidelityReport:
    """The fidelity of one scene (paper eq. 15) with everything it came from.

    Attributes
    ----------
    fidelity : float
        ``Σ k_i·f_i`` over the computed components, with ``weights`` (eq. 15).
    grade : str
        Overall grade (rule: :class:`~irfidelity.fuzzy.GradeScale`).
    components : dict
        ``{name: f_i}`` for the computed components only (positive weight, inputs given).
    component_grades : dict
        ``{name: grade}`` of each computed component.
    membership : dict
        ``B = K·R``: ``{grade: membership}``.
    metrics : dict
        Raw values behind the components (:data:`irfidelity.schema.METRICS`), with ``n``.
    weights : Weights
        The weights eq. (15) used: the configured ones, or renormalised ones when a
        component without inputs was dropped.
    skipped : dict
        ``{name: reason}`` for every component not computed.
    config : ScoringConfig
        What decided the score.
    version : str
        The irfidelity version that made the report.
    grading : dict
        The full evaluation matrix ``R`` and memberships.
    notes : list of str
        Warnings raised while computing.
    inputs : dict
        Short descriptions of the inputs (paths, shapes).
    registration : dict or None
        The registration applied before the image components (``config.register``):
        :meth:`irfidelity.Registration.to_dict` — model, method, matrix, shift, angle, scale,
        confidence, overlap. The image components then count the overlap only.
    verdict : dict
        Why the grade is what it is (:meth:`irfidelity.verdict.Verdict.to_dict`): ``grade``,
        ``decided_by`` (the component that set it), ``reason`` (one sentence), ``rule`` and
        each component's grade, limits and measure in engineering units; ``defect``: None, or
        where the few pixels are that carry most of the squared error
        (:func:`irfidelity.defects.concentrated_error`).
    ceiling : dict or None
        With ``real_ref``: the image components of the two real frames (:mod:`irfidelity.ceiling`).
    relative : dict or None
        Each image component divided by its ceiling.

    Examples
    --------
    >>> import json, numpy as np, irfidelity as irf
    >>> real = np.arange(64, dtype=np.uint16).reshape(8, 8)    # a scene spanning 63 counts
    >>> rep = irf.evaluate(real, real + 1, bits=14, peak="range", weights="psnr=0.5,ssim=0.5")
    >>> round(rep.fidelity, 3), rep.grade, rep.component_grades
    (0.978, 'excellent', {'psnr': 'excellent', 'ssim': 'excellent'})
    >>> rep.skipped                                              # not computed, and why
    {'mtf': 'weight 0', 'sitf': 'weight 0', 'nmi': 'weight 0'}
    >>> irf.FidelityReport.from_dict(json.loads(json.dumps(rep.to_dict()))) == rep
    True
    """

    fidelity: float
    grade: str
    components: dict
    weights: Weights
    metrics: dict = field(default_factory=dict)
    component_grades: dict = field(default_factory=dict)
    membership: dict = field(default_factory=dict)
    skipped: dict = field(default_factory=dict)
    config: ScoringConfig = field(default_factory=ScoringConfig)
    version: str = field(default_factory=version)
    grading: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    inputs: dict = field(default_factory=dict)
    registration: dict | None = None
    verdict: dict = field(default_factory=dict)
    ceiling: dict | None = None
    relative: dict | None = None
    sources: dict = field(default_factory=dict, repr=False, compare=False)

    def to_html(self, path: str | os.PathLike | None = None) -> str:
        """A self-contained HTML report (figures embedded, no network): the verdict, the frames
        and their difference, the SSIM map, the joint histogram, the curves. Written to
        ``path`` when given; returned either way. Needs matplotlib (``irfidelity[report]``).

        The frames and curves are those this report was computed from; a report read back with
        :meth:`from_dict` has only its numbers, and the page says which sections are missing.
        """
        from .report import render_pair_html, write_html

        src = self.sources
        html = render_pair_html(self, real=src.get("real"), sim=src.get("sim"), mask=src.get("mask"),
                                curves=src.get("curves"))
        return write_html(html, path)

    def _repr_html_(self) -> str:
        from .report import render_pair_html

        src = self.sources
        return render_pair_html(self, real=src.get("real"), sim=src.get("sim"), mask=src.get("mask"),
                                curves=src.get("curves"), fragment=True)

    def to_dict(self) -> dict:
        """JSON-ready dict (non-finite floats as "inf"/"-inf"/"nan"); :meth:`from_dict` inverts it."""
        return to_json({
            "irfidelity": self.version,
            "fidelity": self.fidelity,
            "grade": self.grade,
            "components": dict(self.components),
            "component_grades": dict(self.component_grades),
            "membership": dict(self.membership),
            "metrics": dict(self.metrics),
            "weights": self.weights.as_dict(),
            "skipped": dict(self.skipped),
            "config": self.config.to_dict(),
            "grading": dict(self.grading),
            "notes": list(self.notes),
            "inputs": dict(self.inputs),
            "registration": self.registration,
            "verdict": dict(self.verdict),
            "ceiling": self.ceiling,
            "relative": self.relative,
        })

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> FidelityReport:
        """A report from :meth:`to_dict`'s output; FidelityError naming what is wrong otherwise."""
        with reading_report(cls, data) as d:
            fields = Fields(d, "report")
            return cls(fidelity=fields.require("fidelity", readback.fraction),
                       grade=fields.require("grade", readback.text),
                       grading=fields.get("grading", readback.grading, {}),
                       registration=fields.get("registration", readback.optional(readback.registration)),
                       **verdict_fields(fields), **shared_fields(fields))

    @property
    def grades(self) -> tuple:
        """Grade names, best first."""
        return tuple(self.membership)

    def summary_text(self) -> str:
        """Human-readable table: components, weights, grades, fidelity, how it was made."""
        lines = component_lines(self.components, self.component_grades, self.metrics, self.weights, self.skipped)
        lines.append(f"{'fidelity':<10} {'':>7} {self.fidelity:>8.4f}  (eq. 15, Σ k_i·f_i)")
        lines += verdict_lines(self.grade, self.verdict, self.ceiling, self.relative)
        if self.registration:
            lines.append(registration_line(self.registration))
        lines.append(settings_line(self.config, self.version))
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary_text()


def verdict_lines(grade: str | None, verdict: Mapping[str, Any], ceiling: Mapping[str, float] | None,
                  relative: Mapping[str, float] | None) -> list[str]:
    """The grade with its reason in one sentence, and the ceiling when one was measured."""
    reason = verdict.get("reason") if verdict else None
    lines = [f"{'grade':<10} {'':>7} {grade:>8}  {reason or ''}".rstrip()]
    defect = verdict.get("defect") if verdict else None
    if isinstance(defect, Mapping) and defect.get("text"):
        lines.append(f"defect: {defect['text']}")
    if ceiling:
        parts = [f"{k} {v:.4f} (simulator {100 * relative[k]:.1f} %)" if relative and k in relative else
                 f"{k} {v:.4f}" for k, v in ceiling.items()]
        lines.append("ceiling (real vs real): " + ", ".join(parts))
    return lines


def verdict_fields(fields: Fields) -> dict[str, Any]:
    """``verdict``, ``ceiling`` and ``relative`` of a report read back (absent in older ones)."""
    numbers = readback.optional(readback.mapping_of(readback.number))
    return {"verdict": fields.get("verdict", readback.mapping_of(readback.anything), {}),
            "ceiling": fields.get("ceiling", numbers), "relative": fields.get("relative", numbers)}


def registration_line(reg: Mapping[str, Any]) -> str:
    """One line: the transform found, how distinct the match was and the overlap scored (or,
    for a sequence registered per frame, the spread of the frames' transforms)."""
    if reg.get("each"):
        return _per_frame_registration_line(reg)
    dy, dx = reg["shift"]
    parts = [f"registration ({reg['model']}, {reg['method']}): shift dy {dy:+.3f} px, dx {dx:+.3f} px"]
    if reg["model"] != "translation":
        parts.append(f"angle {reg['angle']:+.3f}°")
    if reg["model"] == "similarity":
        parts.append(f"scale {reg['scale']:.5f}")
    parts.append(f"confidence {reg['confidence']:.3f}, overlap {100 * reg['overlap']:.1f} % of the real frame")
    return ", ".join(parts)


def _per_frame_registration_line(reg: Mapping[str, Any]) -> str:
    def spread(key: str, unit: str, fmt: str) -> str:
        s = reg.get(key) or {}
        if not s:
            return f"{key} –"
        return f"{key} {s['min']:{fmt}} .. {s['max']:{fmt}}{unit} (median {s['p50']:{fmt}})"

    parts = [f"registration per frame ({reg['model']}, {reg['method']}): {reg['frames']} frames",
             spread("shift_dy", " px", "+.3f"), spread("shift_dx", " px", "+.3f")]
    if reg["model"] != "translation":
        parts.append(spread("angle", "°", "+.3f"))
    if reg["model"] == "similarity":
        parts.append(spread("scale", "", ".5f"))
    parts.append(spread("confidence", "", ".3f"))
    unsure = reg.get("unsure") or []
    if unsure:
        shown = ", ".join(str(i) for i in unsure[:10]) + (", ..." if len(unsure) > 10 else "")
        parts.append(f"{len(unsure)} unsure (confidence < {reg.get('low_confidence')}): frames {shown}")
    return ", ".join(parts)


def _peak_text(config: ScoringConfig) -> str:
    if isinstance(config.peak, float):
        return f"{config.peak:g}"
    if config.peak == "range":
        return "the real frame's max − min"
    return "2^bits − 1" if config.bits else "the dtype's maximum"


def settings_line(config: ScoringConfig, version: str) -> str:
    """One line naming the settings a reader needs to reproduce the numbers."""
    parts = [f"irfidelity {version}", f"bits {config.bits}" if config.bits else None,
             f"PSNR peak {_peak_text(config)}", f"bins {config.bins}", f"hist_range {config.hist_range}",
             f"registration {config.register}" if config.register else None]
    return "settings: " + ", ".join(p for p in parts if p)
