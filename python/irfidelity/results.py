"""What every report holds (:class:`ReportBase`), the report of one scene
(:class:`FidelityReport`), and the text shared by every report.

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
from typing import Any, Mapping, Self

from .ceiling import CEILING_SOURCES
from .config import ScoringConfig
from .errors import FidelityError
from .fuzzy import COMPONENTS, PAPER_COMPONENTS, Weights
from . import readback
from ._version import __version__
from .readback import Fields, check_json, shared_fields
from .schema import from_json, to_json

__all__ = ["ReportBase", "FidelityReport", "component_lines", "recorded_warnings", "reading_report", "verdict_lines"]


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


_RAW = {
    "mtf": lambda m: f"MTF50 real {m['mtf50_real']:.4g}, sim {m['mtf50_sim']:.4g} {m.get('mtf50_unit') or ''}; "
                     f"mu {m['mtf_mu']:.4f}, rho {m['mtf_rho']:.4f}",
    "sitf": lambda m: f"slope real {m['sitf_slope_real']:.4g}, sim {m['sitf_slope_sim']:.4g} "
                      f"{m.get('sitf_slope_unit') or ''}; mu {m['sitf_mu']:.4f}, rho {m['sitf_rho']:.4f}",
    "psnr": lambda m: f"PSNR {m['psnr_db']:.3f} dB (peak {m['psnr_peak']:g}), MSE {m['mse']:.6g}",
    "nmi": lambda m: f"MI {m['mi']:.4f}, H(R) {m['h_real']:.4f}, H(S) {m['h_sim']:.4f}, H(R,S) {m['h_joint']:.4f}",
    "noise": lambda m: f"σ_tvh real {m['noise_sigma_tvh_real']:.4g}, sim {m['noise_sigma_tvh_sim']:.4g}; "
                       f"mu {m['noise_mu']:.4f}, rho {m['noise_rho']:.4f}",
    "radiometry": lambda m: f"bias {m['temperature_bias']:+.4g} K, RMSE {m['temperature_rmse']:.4g} K "
                            f"against the tolerance {m['temperature_tolerance']:.4g} K",
    "mrtd": lambda m: f"MRTD real {m['mrtd_real']:.4g} K, sim {m['mrtd_sim']:.4g} K (×{m['mrtd_ratio']:.3g}); "
                      f"mu {m['mrtd_mu']:.4f}, rho {m['mrtd_rho']:.4f}",
    "ssim": lambda m: f"SSIM {m['ssim']:.4f} = l {m['ssim_luminance']:.4f} · c {m['ssim_contrast']:.4f} · "
                      f"s {m['ssim_structure']:.4f}",
}


#: The raw text of a camera component graded from the scene's transfer (irfidelity.system).
_SCENE_RAW = {
    "mtf": lambda m: (f"scene: MTF ratio {m['scene_mtf_ratio']:.3g} at {m['scene_reference_frequency']:.3g} cy/px, "
                      f"MTF50 mismatch {100 * m['scene_mtf50_mismatch']:.3g} %, band {m['scene_band_low']:.3g}–"
                      f"{m['scene_band_high']:.3g} cy/px") if m["scene_mtf50_mismatch"] is not None else (
                      f"scene: no MTF ratio to read, the simulated frame's noise hides it (band "
                      f"{m['scene_band_low']:.3g}–{m['scene_band_high']:.3g} cy/px)"),
    "sitf": lambda m: f"scene: gain {m['scene_gain']:.4g} ± {m['scene_gain_err']:.1g}, offset {m['scene_offset']:.4g}",
    "noise": lambda m: f"scene: noise ratio {m['scene_noise_ratio']:.3g} ± {m['scene_noise_ratio_err']:.1g}",
}


def _raw(k: str, metrics: Mapping[str, Any]) -> str:
    """The raw metrics of a component in words ('' when they are missing)."""
    table = _SCENE_RAW if metrics.get(f"{k}_source") == "scene" else _RAW
    try:
        return table[k](metrics)
    except (KeyError, TypeError, ValueError):
        return ""


def scene_line(metrics: Mapping[str, Any]) -> str | None:
    """One line: the scene's transfer beside camera curves (a cross-check), or None."""
    if metrics.get("scene_gain") is None or all(metrics.get(f"{k}_source") == "scene" for k in ("mtf", "sitf")):
        return None
    mismatch = metrics.get("scene_mtf50_mismatch")
    mtf = "not read" if mismatch is None else f"MTF50 mismatch {100 * mismatch:.3g} %"
    return f"scene (cross-check of the curves): {mtf}, gain {metrics['scene_gain']:.4g}"


def component_lines(components: Mapping[str, float], component_grades: Mapping[str, str],
                    metrics: Mapping[str, Any], weights: Weights, skipped: Mapping[str, str]) -> list[str]:
    """The component table of a text summary: weight, value, own grade, raw metrics."""
    lines = [f"{'component':<10} {'weight':>7} {'value':>8}  {'grade':<9} raw"]
    for k in COMPONENTS:
        if k not in components and k not in skipped and k not in PAPER_COMPONENTS:
            continue  # an opt-in component nobody asked for
        if k in components:
            raw = _raw(k, metrics)
            lines.append(f"{k:<10} {weights[k]:>7.4f} {components[k]:>8.4f}  {component_grades.get(k, ''):<9} {raw}")
        else:
            lines.append(f"{k:<10} {'-':>7} {'-':>8}  {'':<9} skipped: {skipped.get(k, '')}")
    if "temperature_bias" in metrics:
        lines.append(temperature_line(metrics))
    cross_check = scene_line(metrics)
    if cross_check:
        lines.append(cross_check)
    return lines


def temperature_line(metrics: Mapping[str, Any]) -> str:
    """One line: the errors of the simulated temperatures (scored in a unit)."""
    m = metrics
    return (f"temperatures ({m['temperature_unit']}): bias (sim − real) {m['temperature_bias']:+.4g} K, "
            f"RMSE {m['temperature_rmse']:.4g} K, MAE {m['temperature_mae']:.4g} K, "
            f"{100 * m['temperature_within']:.1f} % of pixels within ±{m['temperature_tolerance']:.4g} K")


@dataclass(kw_only=True)
class ReportBase:
    """What every report holds: the verdict and how it was made.

    A single pair's :class:`FidelityReport` and a sequence's
    :class:`~irfidelity.SequenceReport` (its pooled result) share these fields, their JSON
    keys (:meth:`to_dict`, :meth:`from_dict`) and their lines of :meth:`summary_text`.

    Attributes
    ----------
    fidelity : float or None
        ``Σ k_i·f_i`` over the computed components, with ``weights`` (eq. 15); None when
        nothing was scored (a sequence whose every frame failed).
    grade : str or None
        Overall grade: the worst grade of the weighted components, each graded by its
        tolerance (:func:`irfidelity.verdict.judge`).
    components : dict
        ``{name: f_i}`` for the computed components only (positive weight, inputs given).
    component_grades : dict
        ``{name: grade}`` of each computed component.
    membership : dict
        ``B = K·R``: ``{grade: membership}``, best grade first.
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
    notes : list of str
        Warnings raised while computing.
    inputs : dict
        Short descriptions of the inputs (paths, shapes).
    registration : dict or None
        The registration applied before the image components (``config.register``).
    verdict : dict
        Why the grade is what it is (:meth:`irfidelity.verdict.Verdict.to_dict`): ``grade``,
        ``decided_by`` (the component that set it), ``reason`` (one sentence), ``rule`` and
        each component's grade, limits and measure in engineering units; for a single pair
        ``defect``: None, or where the few pixels are that carry most of the squared error
        (:func:`irfidelity.defects.concentrated_error`).
    ceiling : dict or None
        The image components of two real frames of the scene, the camera's own repeatability
        (:mod:`irfidelity.ceiling`; a pair's with ``real_ref``, a sequence's from consecutive
        real frames).
    relative : dict or None
        Each image component divided by its ceiling.
    transfer : dict or None
        The frame pair's transfer relative to the real camera
        (:meth:`irfidelity.system.Transfer.to_dict`: the MTF ratio against frequency, its band,
        gain, offset, noise ratio), when it was measured: the input of ``mtf``, ``sitf`` and
        ``noise`` without camera curves, and a cross-check beside them.
    sources : dict
        What the report was computed from, for :meth:`to_html` (frames, curves); not part of
        the JSON form, not compared. Picklable, as the whole report is.
    """

    weights: Weights
    fidelity: float | None = None
    grade: str | None = None
    components: dict = field(default_factory=dict)
    component_grades: dict = field(default_factory=dict)
    membership: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    skipped: dict = field(default_factory=dict)
    config: ScoringConfig = field(default_factory=ScoringConfig)
    version: str = __version__
    notes: list = field(default_factory=list)
    inputs: dict = field(default_factory=dict)
    registration: dict | None = None
    verdict: dict = field(default_factory=dict)
    ceiling: dict | None = None
    relative: dict | None = None
    transfer: dict | None = None
    sources: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def grades(self) -> tuple:
        """Grade names, best first."""
        return tuple(self.membership)

    @property
    def ceiling_source(self) -> str | None:
        """Where :attr:`ceiling` came from (``verdict["ceiling_source"]``): "given", "real_ref",
        "sequence" or "noise3d" (:data:`irfidelity.ceiling.CEILING_SOURCES`); None without one."""
        source = self.verdict.get("ceiling_source") if self.ceiling else None
        return source if isinstance(source, str) else None

    # ------------------------------------------------------------------ JSON form
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
            "notes": list(self.notes),
            "inputs": dict(self.inputs),
            "registration": self.registration,
            "verdict": dict(self.verdict),
            "ceiling": self.ceiling,
            "relative": self.relative,
            **({"transfer": self.transfer} if self.transfer is not None else {}),
            **self._own_dict(),
        })

    def _own_dict(self) -> dict:
        """The JSON keys of a subclass's own fields."""
        return {}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        """A report from :meth:`to_dict`'s output; FidelityError naming what is wrong otherwise."""
        with reading_report(cls, data) as d:
            fields = Fields(d, "report")
            return cls(**shared_fields(fields), **cls._own_fields(fields))

    @classmethod
    def _own_fields(cls, fields: Fields) -> dict[str, Any]:
        """A subclass's own fields (and ``fidelity``, ``grade``, ``registration``, whose checks
        differ), read and checked."""
        return {}

    # ------------------------------------------------------------------ text and HTML
    def _verdict_lines(self) -> list[str]:
        """The component table, the fidelity, the grade with its reason, the ceiling."""
        lines = component_lines(self.components, self.component_grades, self.metrics, self.weights, self.skipped)
        lines.append(f"{'fidelity':<10} {'':>7} {self.fidelity:>8.4f}  (eq. 15, Σ k_i·f_i)")
        return lines + verdict_lines(self.grade, self.verdict, self.ceiling, self.relative)

    def _made_lines(self) -> list[str]:
        """How the report was made: the settings line, then the notes."""
        return [settings_line(self.config, self.version)] + [f"note: {n}" for n in self.notes]

    def summary_text(self) -> str:
        """Human-readable summary."""
        raise NotImplementedError

    def __str__(self) -> str:
        return self.summary_text()

    def _render(self, *, fragment: bool = False, **options: Any) -> str:
        """The HTML page (or, with ``fragment``, a fragment for notebooks)."""
        raise NotImplementedError

    def _repr_html_(self) -> str:
        return self._render(fragment=True)


@dataclass(kw_only=True)
class FidelityReport(ReportBase):
    """The fidelity of one scene (paper eq. 15) with everything it came from.

    Attributes
    ----------
    fidelity, grade, components, component_grades, membership, metrics, weights, skipped
        The verdict (:class:`ReportBase`).
    config, version, notes, inputs
        How it was made (:class:`ReportBase`).
    matrix : dict
        The evaluation matrix ``R``: ``{component: {grade: membership}}``.
    grading : dict
        ``R`` with the memberships and grades it gives (``grades``, ``matrix``,
        ``membership``, ``component_grades``, ``grade``), derived from the fields above.
    registration : dict or None
        The registration applied before the image components (``config.register``):
        :meth:`irfidelity.registration.Registration.to_dict` — model, method, matrix, shift, angle, scale,
        confidence, overlap. The image components then count the overlap only.
    regions : dict
        With ``evaluate(..., regions=...)``, ``{name: entry}`` per labelled region (labels
        ascending; empty otherwise): ``label``, ``pixels``, ``fidelity``, ``grade``,
        ``components`` (the region's image components and the pair's camera components),
        ``component_grades``, ``membership``, ``metrics`` (the region's own), ``verdict``,
        ``ceiling``, ``relative`` (:mod:`irfidelity.regions`). The pair's own fields describe
        the union of the regions.

    Examples
    --------
    >>> import json, pickle, numpy as np, irfidelity as irf
    >>> real = np.arange(64, dtype=np.uint16).reshape(8, 8)    # a scene spanning 63 counts
    >>> rep = irf.evaluate(real, real + 1, bits=14, peak="range", weights="psnr=0.5,ssim=0.5")
    >>> round(rep.fidelity, 3), rep.grade, rep.component_grades
    (0.978, 'excellent', {'psnr': 'excellent', 'ssim': 'excellent'})
    >>> rep.skipped                                              # not computed, and why
    {'mtf': 'weight 0', 'sitf': 'weight 0', 'nmi': 'weight 0'}
    >>> irf.FidelityReport.from_dict(json.loads(json.dumps(rep.to_dict()))) == rep
    True
    >>> pickle.loads(pickle.dumps(rep)) == rep                   # for Dask, Ray, multiprocessing
    True
    """

    fidelity: float
    grade: str
    matrix: dict = field(default_factory=dict)
    regions: dict = field(default_factory=dict)

    @property
    def grading(self) -> dict:
        """The fuzzy evaluation: ``R`` (``matrix``), ``B`` (``membership``), the grades."""
        return {"grades": list(self.membership), "matrix": {k: dict(v) for k, v in self.matrix.items()},
                "membership": dict(self.membership), "component_grades": dict(self.component_grades),
                "grade": self.grade}

    def to_html(self, path: str | os.PathLike | None = None, *, max_bytes: int | None = None) -> str:
        """A self-contained HTML report (figures embedded, no network): the verdict, the frames
        and their difference, the SSIM map, the joint histogram, the curves. Written to
        ``path`` when given; returned either way. Needs matplotlib (``irfidelity[report]``).

        The frames and curves are those this report was computed from; a report read back with
        :meth:`from_dict` has only its numbers, and the page says which sections are missing.
        ``max_bytes``: the memory budget (:func:`irfidelity.report.render_pair_html`).
        """
        from .report import write_html

        return write_html(self._render(max_bytes=max_bytes), path)

    def _render(self, *, fragment: bool = False, **options: Any) -> str:
        from .report import render_pair_html

        src = self.sources
        return render_pair_html(self, real=src.get("real"), sim=src.get("sim"), mask=src.get("mask"),
                                curves=src.get("curves"), sim_unregistered=src.get("sim_unregistered"),
                                fragment=fragment, **options)

    def _own_dict(self) -> dict:
        return {"grading": self.grading, **({"regions": self.regions} if self.regions else {})}

    @classmethod
    def _own_fields(cls, fields: Fields) -> dict[str, Any]:
        grading = fields.get("grading", readback.grading, {})
        return {"fidelity": fields.require("fidelity", readback.fraction),
                "grade": fields.require("grade", readback.text),
                "matrix": grading.get("matrix", {}),
                "registration": fields.get("registration", readback.optional(readback.registration)),
                "regions": fields.get("regions", readback.mapping_of(readback.region), {})}

    def summary_text(self) -> str:
        """Human-readable table: components, weights, grades, fidelity, how it was made."""
        lines = self._verdict_lines() + [region_line(name, entry) for name, entry in self.regions.items()]
        if self.registration:
            lines.append(registration_line(self.registration))
        return "\n".join(lines + self._made_lines())


def region_line(name: str, entry: Mapping[str, Any]) -> str:
    """One line: a labelled region's size, image components, fidelity and grade."""
    from .regions import OWN_COMPONENTS

    own = "; ".join(f"{k} {v:.4f}" for k, v in entry["components"].items() if k in OWN_COMPONENTS)
    n = entry.get("metrics", {}).get("n", entry["pixels"])
    return (f"region {name} (label {entry['label']}, {n} px scored): fidelity {entry['fidelity']:.4f} "
            f"{entry['grade']}; {own}")


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
        source = CEILING_SOURCES.get(str(verdict.get("ceiling_source"))) if verdict else None
        lines.append("ceiling (real vs real)" + (f", {source}" if source else "") + ": " + ", ".join(parts))
    return lines


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
    if config.numeric_peak is not None:
        return f"{config.numeric_peak:g}"
    if config.peak == "range":
        return "the real frame's temperature range (max − min)" if config.unit else "the real frame's max − min"
    return "2^bits − 1" if config.bits else "the dtype's maximum"


def settings_line(config: ScoringConfig, version: str) -> str:
    """One line naming the settings a reader needs to reproduce the numbers."""
    parts = [f"irfidelity {version}", f"bits {config.bits}" if config.bits else None,
             f"PSNR peak {_peak_text(config)}", f"bins {config.bins}", f"hist_range {config.hist_range}",
             f"registration {config.register}" if config.register else None,
             f"unit {config.unit}" if config.unit else None]
    return "settings: " + ", ".join(p for p in parts if p)
