"""One scene, one fidelity: :func:`evaluate` and :class:`FidelityReport` (paper eq. 15).

**Plan first, compute second** (DESIGN §2): :func:`plan_components` decides, from the
weights and from which inputs exist, which components are computed; only then is any
work done. A component with weight 0 is not computed at all: no histogram pass unless
NMI is weighted, no moments unless SSIM is, no ``pair_stats`` call without an image
component, no curve work without a curve weight. One pass of the Rust kernel computes
every image statistic the plan needs; :func:`image_components` turns it into f3..f5.

The sequence engine (:mod:`irfidelity.sequence`) uses the same two functions.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from . import stats as _stats
from .curves import Curve, mtf_similarity
from .errors import FidelityError
from .fuzzy import COMPONENTS, GradeScale, Weights, fidelity_sum, ordered_components
from .normalize import DEFAULT_PSNR_ANCHORS, normalize_psnr

__all__ = ["FidelityReport", "evaluate", "plan_components", "image_components", "curve_components",
           "IMAGE_COMPONENTS", "CURVE_COMPONENTS"]

IMAGE_COMPONENTS = ("psnr", "nmi", "ssim")
CURVE_COMPONENTS = ("mtf", "sitf")
_INPUTS = {"mtf": "real_mtf/sim_mtf", "sitf": "real_sitf/sim_sitf", "psnr": "real/sim", "nmi": "real/sim",
           "ssim": "real/sim"}
_MISSING = {"raise": "raise", "renormalize": "renormalize", "renormalise": "renormalize"}


# --------------------------------------------------------------------------- plan
def plan_components(weights: Any, *, have_images: bool, have_mtf: bool, have_sitf: bool,
                    missing: str = "raise") -> tuple[Weights, set, dict]:
    """Decide what to compute, before computing anything.

    Parameters
    ----------
    weights : Weights, preset string, mapping or None (balanced)
    have_images, have_mtf, have_sitf : bool
        Whether the real/simulated frames, MTF inputs and SiTF inputs were given.
    missing : "raise" | "renormalize"
        A component with positive weight but no inputs: raise FidelityError naming the
        missing inputs (e.g. ``"real_mtf/sim_mtf"``), or drop it and rescale the
        remaining weights to sum 1.

    Returns
    -------
    (weights_effective, need, skipped)
        ``weights_effective``: the weights eq. (15) uses (dropped components 0);
        ``need``: the ``need`` argument for :func:`irfidelity.pair_stats` (subset of
        ``{"psnr", "nmi", "ssim"}``; empty → no image pass at all);
        ``skipped``: ``{component: reason}`` for every component not computed.
    """
    w = Weights.coerce(weights)
    mode = _MISSING.get(missing) if isinstance(missing, str) else None
    if mode is None:
        raise FidelityError(f"missing must be 'raise' or 'renormalize', got {missing!r}")
    have = {"mtf": bool(have_mtf), "sitf": bool(have_sitf), "psnr": bool(have_images), "nmi": bool(have_images),
            "ssim": bool(have_images)}
    skipped: dict[str, str] = {}
    kept: dict[str, float] = {}
    absent = []
    for k in COMPONENTS:
        if w[k] == 0:
            skipped[k] = "weight 0"
        elif not have[k]:
            absent.append(k)
        else:
            kept[k] = w[k]
    if absent:
        if mode == "raise":
            need_in = sorted({_INPUTS[k] for k in absent}, key=lambda s: list(_INPUTS.values()).index(s))
            raise FidelityError(
                f"component(s) {', '.join(absent)} have a positive weight but no input: give "
                f"{' and '.join(need_in)}, set their weight to 0, or use missing='renormalize'")
        for k in absent:
            skipped[k] = f"no input ({_INPUTS[k]} not given); weight {w[k]:g} dropped and the rest renormalised"
        if not kept:
            raise FidelityError("nothing to compute: every component with a positive weight lacks its inputs "
                                f"({', '.join(sorted({_INPUTS[k] for k in absent}))})")
        w = Weights.normalized(**kept)
    need = {k for k in IMAGE_COMPONENTS if w[k] > 0}
    return w, need, skipped


def image_components(stats: Any, weights: Any, *, psnr_anchors=DEFAULT_PSNR_ANCHORS,
                     ssim_exponents=(1.0, 1.0, 1.0)) -> tuple[dict, dict]:
    """Components f3 (normalised PSNR), f4 (NMI), f5 (max(SSIM, 0)) from a PairStats.

    Only components with a positive weight are computed (and only their raw metrics
    reported), so ``stats`` need only hold what the plan asked for.

    Returns
    -------
    (components, metrics)
        ``components``: ``{"psnr"|"nmi"|"ssim": f}``; ``metrics``: the raw values,
        ``n`` and: ``mse, psnr_db`` (PSNR); ``nmi, mi, h_real, h_sim, h_joint, bins``
        (NMI); ``ssim, ssim_luminance, ssim_contrast, ssim_structure`` (SSIM).
    """
    w = Weights.coerce(weights)
    comps: dict[str, float] = {}
    mets: dict[str, Any] = {}
    if not any(w[k] > 0 for k in IMAGE_COMPONENTS):
        return comps, mets
    mets["n"] = int(stats.n)
    if stats.masked:
        mets["masked"] = int(stats.masked)
    if stats.nonfinite:
        mets["nonfinite"] = int(stats.nonfinite)
    if w.psnr > 0:
        mse = stats.mse()
        db = stats.psnr()
        mets["mse"] = float(mse)
        mets["psnr_db"] = float(db)
        comps["psnr"] = float(normalize_psnr(db, anchors=psnr_anchors))
    if w.nmi > 0:
        v = stats.nmi()
        mets.update(nmi=float(v.value), mi=float(v.mi), h_real=float(v.h_real), h_sim=float(v.h_sim),
                    h_joint=float(v.h_joint), bins=v.bins)
        comps["nmi"] = float(v.value)
    if w.ssim > 0:
        try:
            a, b, g = (float(x) for x in ssim_exponents)
        except (TypeError, ValueError):
            raise FidelityError(f"ssim_exponents must be three numbers (alpha, beta, gamma), got {ssim_exponents!r}") from None
        s = stats.ssim(a, b, g)
        mets.update(ssim=float(s.value), ssim_luminance=float(s.luminance), ssim_contrast=float(s.contrast),
                    ssim_structure=float(s.structure))
        comps["ssim"] = max(float(s.value), 0.0)
    return comps, mets


# --------------------------------------------------------------------------- report
def _enc(v: Any) -> Any:
    """JSON-ready value: non-finite floats as strings "inf", "-inf", "nan"."""
    if isinstance(v, float) and not math.isfinite(v):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, (np.floating,)):
        return _enc(float(v))
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, dict):
        return {k: _enc(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_enc(x) for x in v]
    return v


def _dec(v: Any) -> Any:
    if v in ("inf", "-inf", "nan") and isinstance(v, str):
        return float(v)
    if isinstance(v, dict):
        return {k: _dec(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_dec(x) for x in v]
    return v


@dataclass
class FidelityReport:
    """The fidelity of one scene (paper eq. 15) with everything it came from.

    Attributes
    ----------
    fidelity : float
        ``Σ k_i·f_i`` over the computed components, with ``weights`` (eq. 15).
    components : dict
        ``{name: f_i}`` for the computed components only (positive weight, inputs given).
    weights : Weights
        The weights eq. (15) used: the requested ones, or renormalised ones when
        ``missing="renormalize"`` dropped a component.
    metrics : dict
        Raw values behind the components: ``psnr_db, mse, nmi, mi, h_real, h_sim,
        h_joint, bins, ssim, ssim_luminance, ssim_contrast, ssim_structure, n``;
        ``mtf50_real, mtf50_sim, mtf_mu, mtf_rho, mtf_ccc, mtf_area``;
        ``sitf_slope_real, sitf_slope_sim, sitf_mu, sitf_rho, sitf_ccc, sitf_area``.
        Only for computed components.
    skipped : dict
        ``{name: reason}`` for every component not computed (weight 0, or dropped).
    requested_weights : Weights
        The weights asked for.
    grade, membership, grading
        Fuzzy comprehensive evaluation (:class:`~irfidelity.fuzzy.GradeScale`):
        the grade of maximum membership, ``B = K·R`` as ``{grade: b}``, and the
        full :class:`~irfidelity.fuzzy.Grading` (``.matrix`` = R) as a dict.
    notes : list of str
        Warnings raised while computing (e.g. slanted-edge :class:`EdgeWarning`).
    inputs : dict
        Short descriptions of the inputs (paths, shapes).
    """

    fidelity: float
    components: dict
    weights: Weights
    metrics: dict = field(default_factory=dict)
    skipped: dict = field(default_factory=dict)
    requested_weights: Weights | None = None
    grade: str | None = None
    membership: dict = field(default_factory=dict)
    grading: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    inputs: dict = field(default_factory=dict)

    @property
    def grades(self) -> tuple:
        """Grade names, best first."""
        return tuple(self.membership)

    def to_dict(self) -> dict:
        """JSON-ready dict (non-finite floats as "inf"/"-inf"/"nan"); :meth:`from_dict` inverts it."""
        return _enc({
            "fidelity": self.fidelity,
            "grade": self.grade,
            "membership": dict(self.membership),
            "components": dict(self.components),
            "weights": self.weights.as_dict(),
            "requested_weights": (self.requested_weights or self.weights).as_dict(),
            "metrics": dict(self.metrics),
            "skipped": dict(self.skipped),
            "grading": dict(self.grading),
            "notes": list(self.notes),
            "inputs": dict(self.inputs),
        })

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FidelityReport:
        d = _dec(dict(d))
        try:
            return cls(fidelity=float(d["fidelity"]), components=dict(d["components"]),
                       weights=Weights(**d["weights"]), metrics=dict(d.get("metrics", {})),
                       skipped=dict(d.get("skipped", {})),
                       requested_weights=Weights(**d["requested_weights"]) if d.get("requested_weights") else None,
                       grade=d.get("grade"), membership=dict(d.get("membership", {})),
                       grading=dict(d.get("grading", {})), notes=list(d.get("notes", [])),
                       inputs=dict(d.get("inputs", {})))
        except KeyError as exc:
            raise FidelityError(f"not a FidelityReport dict: missing key {exc}") from None

    def summary_text(self) -> str:
        """Human-readable table: components, weights, fidelity, grade."""
        lines = [f"{'component':<10} {'weight':>7} {'value':>8}  raw"]
        raw = {
            "mtf": lambda m: f"MTF50 real {m['mtf50_real']:.4g}, sim {m['mtf50_sim']:.4g}; mu {m['mtf_mu']:.4f}, rho {m['mtf_rho']:.4f}",
            "sitf": lambda m: f"slope real {m['sitf_slope_real']:.4g}, sim {m['sitf_slope_sim']:.4g}; mu {m['sitf_mu']:.4f}, rho {m['sitf_rho']:.4f}",
            "psnr": lambda m: f"PSNR {m['psnr_db']:.3f} dB, MSE {m['mse']:.6g}",
            "nmi": lambda m: f"MI {m['mi']:.4f}, H(R) {m['h_real']:.4f}, H(S) {m['h_sim']:.4f}, H(R,S) {m['h_joint']:.4f}",
            "ssim": lambda m: f"SSIM {m['ssim']:.4f} = l {m['ssim_luminance']:.4f} · c {m['ssim_contrast']:.4f} · s {m['ssim_structure']:.4f}",
        }
        for k in COMPONENTS:
            if k in self.components:
                try:
                    r = raw[k](self.metrics)
                except (KeyError, TypeError, ValueError):
                    r = ""
                lines.append(f"{k:<10} {self.weights[k]:>7.4f} {self.components[k]:>8.4f}  {r}")
            else:
                lines.append(f"{k:<10} {'-':>7} {'-':>8}  skipped: {self.skipped.get(k, '')}")
        lines.append(f"{'fidelity':<10} {'':>7} {self.fidelity:>8.4f}  (eq. 15, Σ k_i·f_i)")
        if self.grade is not None:
            b = ", ".join(f"{g} {v:.3f}" for g, v in self.membership.items())
            lines.append(f"{'grade':<10} {'':>7} {self.grade:>8}  membership B = K·R: {b}")
        for n in self.notes:
            lines.append(f"note: {n}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary_text()


# --------------------------------------------------------------------------- inputs
_CURVE_EXT = (".csv", ".txt", ".tsv", ".dat")


def _describe(x: Any) -> Any:
    if isinstance(x, (str, os.PathLike)):
        return os.fspath(x)
    if isinstance(x, Curve):
        return f"Curve({len(x)} points{', ' + repr(x.name) if x.name else ''})"
    if isinstance(x, np.ndarray):
        return f"array {x.shape} {x.dtype}"
    return type(x).__name__


def _load_frame(x: Any, name: str, channel: Any) -> Any:
    if isinstance(x, (str, os.PathLike)):
        from .frames import load_frame

        return load_frame(x, channel=channel)
    return x


def _as_curve(x: Any, what: str, *, edge_ok: bool, channel: str | None = None) -> Curve:
    """A Curve from a Curve, an (x, y) pair, a CSV path, or (MTF only) an edge image/path."""
    if isinstance(x, Curve):
        return x
    if isinstance(x, (str, os.PathLike)):
        p = os.fspath(x)
        if p.lower().endswith(_CURVE_EXT):
            return Curve.from_csv(p, name=what)
        if not edge_ok:
            raise FidelityError(f"{what}: {p!r} is not a curve file ({', '.join(_CURVE_EXT)})")
        from .curves import mtf_from_edge
        from .frames import load_frame

        img = load_frame(p, channel=channel)
        try:
            return mtf_from_edge(img, name=what)
        except FidelityError as exc:
            raise FidelityError(f"{what} ({p}): {exc}") from None
    if isinstance(x, np.ndarray) and x.ndim == 2 and edge_ok and min(x.shape) > 2:
        from .curves import mtf_from_edge

        try:
            return mtf_from_edge(x, name=what)
        except FidelityError as exc:
            raise FidelityError(f"{what}: {exc}") from None
    try:
        cx, cy = x
    except (TypeError, ValueError):
        kinds = "a Curve, an (x, y) pair, a CSV path" + (" or an edge image (array or path)" if edge_ok else "")
        raise FidelityError(f"{what} must be {kinds}, got {type(x).__name__}") from None
    return Curve(cx, cy, name=what)


def _pair(real: Any, sim: Any, rname: str, sname: str) -> bool:
    if (real is None) != (sim is None):
        given, absent = (rname, sname) if sim is None else (sname, rname)
        raise FidelityError(f"{given} was given without {absent}: give both or neither")
    return real is not None


# --------------------------------------------------------------------------- curves
def curve_components(weights: Any, real_mtf: Any = None, sim_mtf: Any = None, real_sitf: Any = None,
                     sim_sitf: Any = None, *, edge_channel: str | None = None,
                     mtf_options: Mapping[str, Any] | None = None,
                     sitf_options: Mapping[str, Any] | None = None) -> tuple[dict, dict, dict, list]:
    """Components f1 (MTF, eqs. 1–4) and f2 (SiTF) of the curves whose weight is positive.

    Curves with weight 0 are not read at all. Inputs as in :func:`evaluate`.

    Returns
    -------
    (components, metrics, inputs, notes)
        ``components``: ``{"mtf"|"sitf": f}``; ``metrics``: ``mtf50_real, mtf50_sim, mtf_mu,
        mtf_rho, mtf_ccc, mtf_area`` and ``sitf_slope_real, ...``; ``inputs``: short
        descriptions; ``notes``: warnings raised on the way (also re-issued).
    """
    w = Weights.coerce(weights)
    components: dict[str, float] = {}
    metrics: dict[str, Any] = {}
    inputs: dict[str, Any] = {}
    notes: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if w.mtf > 0:
            rc = _as_curve(real_mtf, "real MTF", edge_ok=True, channel=edge_channel)
            sc = _as_curve(sim_mtf, "simulated MTF", edge_ok=True, channel=edge_channel)
            s = mtf_similarity(rc, sc, **dict(mtf_options or {}))
            components["mtf"] = float(s.value)
            metrics.update(mtf50_real=s.a, mtf50_sim=s.b, mtf_mu=s.mu, mtf_rho=s.rho, mtf_ccc=s.ccc,
                           mtf_area=s.area)
            inputs.update(real_mtf=_describe(real_mtf), sim_mtf=_describe(sim_mtf))
        if w.sitf > 0:
            from .curves import sitf_similarity

            rc = _as_curve(real_sitf, "real SiTF", edge_ok=False)
            sc = _as_curve(sim_sitf, "simulated SiTF", edge_ok=False)
            s = sitf_similarity(rc, sc, **dict(sitf_options or {}))
            components["sitf"] = float(s.value)
            metrics.update(sitf_slope_real=s.a, sitf_slope_sim=s.b, sitf_mu=s.mu, sitf_rho=s.rho,
                           sitf_ccc=s.ccc, sitf_area=s.area)
            inputs.update(real_sitf=_describe(real_sitf), sim_sitf=_describe(sim_sitf))
    for wm in caught:
        notes.append(f"{wm.category.__name__}: {wm.message}")
        warnings.warn_explicit(wm.message, wm.category, wm.filename, wm.lineno)
    return components, metrics, inputs, notes


# --------------------------------------------------------------------------- evaluate
def evaluate(real: Any = None, sim: Any = None, *, real_mtf: Any = None, sim_mtf: Any = None,
             real_sitf: Any = None, sim_sitf: Any = None, weights: Any = None, bits: int | None = None,
             peak: float | None = None, bins: int | str = 256, hist_range: Any = "data",
             missing: str = "raise", psnr_anchors=DEFAULT_PSNR_ANCHORS, ssim_exponents=(1.0, 1.0, 1.0),
             mask: Any = None, channel: str | None = None, edge_channel: str | None = None,
             nonfinite: str = "raise",
             mtf_options: Mapping[str, Any] | None = None, sitf_options: Mapping[str, Any] | None = None,
             grades: GradeScale | None = None) -> FidelityReport:
    """Fidelity of a simulator on one scene (paper eq. 15) with its five components.

    Parameters
    ----------
    real, sim : 2-D arrays or frame paths, optional
        The real and simulated frame (paths are loaded with
        :func:`irfidelity.load_frame`, ``channel`` selecting the channel).
        Needed by psnr, nmi, ssim.
    real_mtf, sim_mtf : Curve, (x, y), CSV path, or edge image (2-D array or image path)
        MTF curves of both cameras; an edge image goes through
        :func:`irfidelity.mtf_from_edge`. Component f1 = :func:`irfidelity.mtf_similarity`.
    real_sitf, sim_sitf : Curve, (x, y) or CSV path
        SiTF curves. Component f2 = :func:`irfidelity.sitf_similarity`.
    weights : Weights, preset name, "name=value,…" string, mapping, or None (1/5 each)
    bits, peak : PSNR peak (``2**bits − 1``, or ``peak``); float frames need ``peak``.
    bins, hist_range : histogram for NMI (see :func:`irfidelity.pair_stats`).
    missing : "raise" | "renormalize"
        A positive weight without inputs: FidelityError naming the inputs, or drop the
        component and rescale the others (recorded in ``.skipped``).
    psnr_anchors : the two (dB, value) anchors of eq. (6).
    ssim_exponents : (alpha, beta, gamma) of eq. (14).
    mask, nonfinite : passed to :func:`irfidelity.pair_stats`.
    channel : channel of the frame files (multi-channel EXR/PNG/TIFF).
    edge_channel : channel of edge image files given as ``real_mtf``/``sim_mtf``
        (e.g. ``"R"`` for an RGBA PNG).
    mtf_options, sitf_options : extra keyword arguments for
        :func:`irfidelity.mtf_similarity` / :func:`irfidelity.sitf_similarity`.
    grades : GradeScale, optional
        Grade set and membership functions (default: excellent/good/fair/poor).

    Returns
    -------
    FidelityReport

    Notes
    -----
    f3 = normalised PSNR (eq. 6), f4 = NMI (eq. 10), f5 = max(SSIM, 0) (eq. 14).
    Nothing is computed for a component with weight 0 (not even loaded from disk,
    for curves), and the image statistics come from one Rust pass that computes only
    what the weighted image components need.
    """
    have_images = _pair(real, sim, "real", "sim")
    have_mtf = _pair(real_mtf, sim_mtf, "real_mtf", "sim_mtf")
    have_sitf = _pair(real_sitf, sim_sitf, "real_sitf", "sim_sitf")
    requested = Weights.coerce(weights)
    w, need, skipped = plan_components(requested, have_images=have_images, have_mtf=have_mtf,
                                       have_sitf=have_sitf, missing=missing)
    components, metrics, inputs, notes = curve_components(
        w, real_mtf, sim_mtf, real_sitf, sim_sitf, edge_channel=edge_channel, mtf_options=mtf_options,
        sitf_options=sitf_options)

    if need:
        r = _load_frame(real, "real", channel)
        s_ = _load_frame(sim, "sim", channel)
        inputs.update(real=_describe(real), sim=_describe(sim))
        st = _stats.pair_stats(r, s_, bits=bits, peak=peak, bins=bins, hist_range=hist_range, mask=mask,
                               need=sorted(need), nonfinite=nonfinite)
        ic, im = image_components(st, w, psnr_anchors=psnr_anchors, ssim_exponents=ssim_exponents)
        components.update(ic)
        metrics.update(im)

    fid = fidelity_sum(w, components)
    gs = grades if grades is not None else GradeScale()
    g = gs.evaluate(w, components)
    # components / metrics in the paper's order
    components = ordered_components(components)
    return FidelityReport(fidelity=fid, components=components, weights=w, metrics=metrics, skipped=skipped,
                          requested_weights=requested, grade=g.grade, membership=dict(g.membership),
                          grading=g.to_dict(), notes=notes, inputs=inputs)
