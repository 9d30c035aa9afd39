"""The one output schema: names, units and order of everything a report holds.

A single pair (:class:`~irfidelity.FidelityReport`) and a sequence
(:class:`~irfidelity.SequenceReport`, whose top level is the pooled result and whose
``frames`` are per-frame results) use the same keys for the same quantities. JSON nests
them (``components.psnr``, ``metrics.psnr_db``); CSV flattens them by one rule:
``components.X`` is the column ``f_X`` (the paper's f_i), ``metrics.Y`` the column ``Y``.
The table in ``docs/schema.md`` is :func:`markdown_table` (a test checks they agree).
"""

from __future__ import annotations

import math
from typing import Any, Iterable

import numpy as np

from . import _core
from .fuzzy import COMPONENTS

__all__ = ["METRICS", "FRAME_COLUMNS", "REGISTRATION", "REGISTRATION_COLUMNS", "REGION_COLUMNS", "metric_names",
           "csv_columns", "registration_values", "to_json", "from_json"]

#: Raw metrics behind each component: (key, unit, meaning), in report and CSV order.
METRICS: dict[str, tuple[tuple[str, str, str], ...]] = {
    "mtf": (
        ("mtf50_real", "curve x unit", "MTF50 of the real camera (eq. 4's a)"),
        ("mtf50_sim", "curve x unit", "MTF50 of the simulated camera (eq. 4's b)"),
        ("mtf50_unit", "", "the unit of the MTF50s (cy/px, cy/mrad, lp/mm; empty when unknown)"),
        ("mtf_mu", "1", "mu = 2|a||b|/(a²+b²) of the MTF50s (eq. 4)"),
        ("mtf_rho", "1", "Pearson correlation of the curves at common points (eq. 2)"),
        ("mtf_ccc", "1", "Lin's concordance of the curves (not in eq. 15)"),
        ("mtf_area", "1", "normalised area between the curves (not in eq. 15)"),
    ),
    "sitf": (
        ("sitf_slope_real", "signal / K", "slope of the real SiTF's linear region"),
        ("sitf_slope_sim", "signal / K", "slope of the simulated SiTF's linear region"),
        ("sitf_slope_unit", "", "the unit of the slopes (signal unit / temperature unit; empty when unknown)"),
        ("sitf_mu", "1", "mu of the slopes (eq. 4)"),
        ("sitf_rho", "1", "Pearson correlation of the curves (eq. 2)"),
        ("sitf_ccc", "1", "Lin's concordance of the curves (not in eq. 15)"),
        ("sitf_area", "1", "normalised area between the curves (not in eq. 15)"),
    ),
    "psnr": (
        ("mse", "frame units²", "mean squared error E[(S − R)²] (eq. 5)"),
        ("psnr_db", "dB", "10·log10(peak²/MSE) (eq. 5); inf for identical frames"),
        ("psnr_peak", "frame units", "the peak used (see config.peak)"),
    ),
    "nmi": (
        ("nmi", "1", "MI / ((H(R)+H(S))/2) (eq. 10)"),
        ("mi", "bit", "mutual information H(R)+H(S)−H(R,S) (eq. 9)"),
        ("h_real", "bit", "entropy of the real frame's histogram (eq. 7)"),
        ("h_sim", "bit", "entropy of the simulated frame's histogram (eq. 7)"),
        ("h_joint", "bit", "joint entropy (eq. 8)"),
    ),
    "ssim": (
        ("ssim", "1", "global SSIM l^α·c^β·s^γ (eq. 14)"),
        ("ssim_luminance", "1", "l (eq. 11)"),
        ("ssim_contrast", "1", "c (eq. 12)"),
        ("ssim_structure", "1", "s (eq. 13)"),
    ),
}

#: The seven parts of the 3-D noise model (frames × rows × columns), and the noise spectra compared.
NOISE_PARTS = ("t", "v", "h", "tv", "th", "vh", "tvh")
NOISE_SPECTRA = ("fixed_row", "fixed_col", "temporal_row", "temporal_col")


def _noise_metrics() -> tuple[tuple[str, str, str], ...]:
    rows = [("noise_mu", "1", "mu of the seven component σ (eq. 4 for a vector of levels)"),
            ("noise_rho", "1", "weighted Bhattacharyya overlap of the noise spectra's shapes"),
            ("noise_total_mu", "1", "eq. 4 on the total noise σ alone (not in the component)"),
            ("noise_units", "", "'frame' (levels in frame units) or 'temperature' (divided by the SiTF slopes)")]
    for who, camera in (("real", "real"), ("sim", "simulated")):
        rows += [(f"noise_sigma_{part}_{who}", "frame units", f"σ_{part} of the {camera} camera's 3-D noise")
                 for part in NOISE_PARTS]
        rows += [(f"noise_total_{who}", "frame units", f"total noise σ of the {camera} camera"),
                 (f"noise_netd_{who}", "SiTF x unit", f"σ_tvh / |SiTF slope| of the {camera} camera (empty without a SiTF)"),
                 (f"noise_mean_{who}", "frame units", f"mean level of the {camera} noise recording"),
                 (f"noise_frames_{who}", "frames", f"frames in the {camera} noise recording")]
    rows += [(f"noise_overlap_{name}", "1", f"Bhattacharyya coefficient of the {name.replace('_', ' ')} spectra")
             for name in NOISE_SPECTRA]
    return tuple(rows)


METRICS["noise"] = _noise_metrics()

#: In a temperature unit (``config.unit``): the errors of the simulated temperatures, reported
#: whether or not the opt-in ``radiometry`` component is weighted (irfidelity.temperature).
METRICS["radiometry"] = (
    ("temperature_unit", "", "'K' or 'C': the unit the frames were scored in (config.unit)"),
    ("temperature_bias", "K", "mean(S − R) of the temperatures (a difference: K and °C alike)"),
    ("temperature_rmse", "K", "√mean((S − R)²)"),
    ("temperature_mae", "K", "mean abs(S − R)"),
    ("temperature_within", "1", "fraction of pixel pairs with abs(S − R) ≤ temperature_tolerance"),
    ("temperature_tolerance", "K", "the tolerance: config.temperature_tolerance, the real camera's NETD, or 1 K"),
)
METRICS["mrtd"] = (
    ("mrtd_real", "K", "geometric-mean MRTD of the real camera over the common frequencies (eq. 4's a)"),
    ("mrtd_sim", "K", "geometric-mean MRTD of the simulated camera over the common frequencies (eq. 4's b)"),
    ("mrtd_ratio", "1", "mrtd_sim / mrtd_real"),
    ("mrtd_mu", "1", "mu of the MRTD levels beyond the tolerance (eq. 4 on log ΔT)"),
    ("mrtd_rho", "1", "Pearson correlation of the log MRTD curves (eq. 2)"),
    ("mrtd_max_deviation", "%", "largest |MRTD_sim / MRTD_real − 1| at the feature points"),
    ("mrtd_tolerance", "%", "MRTD level difference forgiven (mrtd_options.tolerance)"),
    ("mrtd_f_min", "curve x unit", "lowest frequency compared (both curves cover it)"),
    ("mrtd_f_max", "curve x unit", "highest frequency compared"),
    ("mrtd_f_unit", "", "the unit of the frequencies (cy/px, cy/mrad, lp/mm; empty when unknown)"),
)

#: Per-frame columns before the metrics: (key, unit, meaning).
FRAME_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("index", "", "position of the pair in the (paired) sequence, 0 for a single pair"),
    ("real", "", "the real frame's name (file name, 'file.tif[page]', or '[i]' for arrays)"),
    ("sim", "", "the simulated frame's name"),
    ("rows", "px", "frame height"),
    ("cols", "px", "frame width"),
    ("dtype", "", "sample type of the frames"),
    ("n", "pixel pairs", "pixel pairs counted"),
    ("masked", "pixel pairs", "pairs left out by a mask (or outside a registration's overlap)"),
    ("nonfinite", "pixel pairs", "pairs left out for NaN/Inf values (config.nonfinite = 'mask')"),
)

#: Per-frame columns after the components.
RESULT_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("fidelity", "1", "Σ k_i·f_i (eq. 15)"),
    ("grade", "", "overall grade (docs/interpretation.md)"),
    ("error", "", "why the frame could not be scored (empty when it was)"),
)

#: A single pair's ``registration`` (``evaluate(..., register=MODEL)``; JSON only):
#: :meth:`irfidelity.registration.Registration.to_dict`.
REGISTRATION: tuple[tuple[str, str, str], ...] = (
    ("model", "", " or ".join(", ".join(f"'{m}'" for m in _core.REGISTRATION_MODELS).rsplit(", ", 1))),
    ("method", "", "the method whose result was kept: 'phase' or 'nmi'"),
    ("matrix", "px", "2×3 affine matrix, simulated → real pixel coordinates (x = column, y = row)"),
    ("shift", "px", "(dy, dx) of the frame centre: real ≈ shift(sim, (dy, dx)), scikit-image's sign"),
    ("angle", "degree", "rotation, counter-clockwise as displayed (cv2.getRotationMatrix2D's sense)"),
    ("scale", "1", "uniform scale"),
    ("confidence", "1", "distinctness of the match, 1 − best rival / best (a warning below registration.LOW_CONFIDENCE)"),
    ("overlap", "1", "fraction of the real frame the warped simulated frame covers"),
    ("shape", "px", "(rows, cols) registered"),
    ("inverted", "", "the frames' grey levels correlate negatively"),
)

#: With registration (``config.register``), a row's registration as CSV columns, after the
#: frame columns: (column, key of ``registration``, unit, meaning). A sequence registered per
#: frame (``register_each``) has each frame's own; otherwise every row has the one applied.
REGISTRATION_COLUMNS: tuple[tuple[str, str, str, str], ...] = (
    ("reg_dy", "shift[0]", "px", "registration shift along rows (real ≈ shift(sim, (dy, dx)))"),
    ("reg_dx", "shift[1]", "px", "registration shift along columns"),
    ("reg_angle", "angle", "degree", "registration rotation (counter-clockwise as displayed)"),
    ("reg_scale", "scale", "1", "registration scale"),
    ("reg_confidence", "confidence", "1", "distinctness of the registration's match"),
    ("reg_overlap", "overlap", "1", "fraction of the real frame the warped simulated frame covers"),
)

#: A single pair's ``regions`` (``evaluate(..., regions=...)``): each region's entry holds these
#: keys beside ``components``, ``component_grades``, ``membership``, ``metrics`` (its own: n,
#: the image metrics, the temperature errors), ``verdict``, ``ceiling`` and ``relative``. In
#: CSV, after the pair's columns, per region (labels ascending) ``region_<name>_<key>``:
#: label, pixels, n, its metrics, ``f_<component>`` of its image components, fidelity, grade.
REGION_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("label", "", "the region's label in the label image (1..255)"),
    ("pixels", "px", "pixels carrying the label (n: those scored, within mask= and a registration's overlap)"),
    ("fidelity", "1", "Σ k_i·f_i (eq. 15) with the region's image components and the pair's camera components"),
    ("grade", "", "the region's grade (docs/interpretation.md)"),
)

IMAGE_COMPONENTS = ("psnr", "nmi", "ssim")
CURVE_COMPONENTS = ("mtf", "sitf")


def metric_names(components: Iterable[str]) -> list[str]:
    """The raw metric keys of the given components, in schema order."""
    wanted = set(components)
    return [key for comp in COMPONENTS if comp in wanted for key, _, _ in METRICS.get(comp, ())]


def csv_columns(components: Iterable[str], registered: bool = False, temperature: bool = False) -> list[str]:
    """CSV columns of a frame row (single pair or sequence) scoring ``components``, with the
    registration's columns when ``registered`` and the temperature errors when ``temperature``
    (scored in a unit, ``config.unit``)."""
    comps = [c for c in COMPONENTS if c in set(components)]
    reported = comps + ["radiometry"] if temperature and "radiometry" not in comps else comps
    return ([k for k, _, _ in FRAME_COLUMNS] + ([k for k, _, _, _ in REGISTRATION_COLUMNS] if registered else [])
            + metric_names(reported) + [f"f_{c}" for c in comps] + [k for k, _, _ in RESULT_COLUMNS])


def registration_values(registration: dict | None) -> dict[str, Any]:
    """The :data:`REGISTRATION_COLUMNS` values of a registration dict (None when absent)."""
    if not registration:
        return {}
    dy, dx = registration["shift"]
    return {"reg_dy": dy, "reg_dx": dx, "reg_angle": registration["angle"], "reg_scale": registration["scale"],
            "reg_confidence": registration["confidence"], "reg_overlap": registration["overlap"]}


def to_json(value: Any) -> Any:
    """JSON-ready value: non-finite floats as the strings "inf", "-inf", "nan"; numpy scalars
    as Python numbers; tuples as lists."""
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if math.isfinite(value):
            return value
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, dict):
        return {str(k): to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    return value


def from_json(value: Any) -> Any:
    """Inverse of :func:`to_json` for the non-finite floats."""
    if isinstance(value, str) and value in ("inf", "-inf", "nan"):
        return float(value)
    if isinstance(value, dict):
        return {k: from_json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [from_json(v) for v in value]
    return value


def markdown_table() -> str:
    """The schema as the markdown of docs/schema.md."""
    lines = ["| JSON key | CSV column | unit | meaning |", "|---|---|---|---|"]
    for key, unit, meaning in FRAME_COLUMNS:
        lines.append(f"| `frames[].{key}` | `{key}` | {unit} | {meaning} |")
    for column, key, unit, meaning in REGISTRATION_COLUMNS:
        lines.append(f"| `frames[].registration.{key}` | `{column}` | {unit} | {meaning} |")
    for comp in COMPONENTS:
        for key, unit, meaning in METRICS[comp]:
            lines.append(f"| `metrics.{key}` | `{key}` | {unit} | {meaning} |")
    for comp in COMPONENTS:
        lines.append(f"| `components.{comp}` | `f_{comp}` | 1 | fidelity component f_i in [0, 1] |")
    for key, unit, meaning in RESULT_COLUMNS:
        lines.append(f"| `{key}` | `{key}` | {unit} | {meaning} |")
    for key, unit, meaning in REGISTRATION:
        lines.append(f"| `registration.{key}` | – | {unit} | {meaning} |")
    for key, unit, meaning in REGION_COLUMNS:
        lines.append(f"| `regions.NAME.{key}` | `region_NAME_{key}` | {unit} | {meaning} |")
    lines.append("| `regions.NAME.metrics.Y` | `region_NAME_Y` | | the region's own metric Y (n, image metrics, "
                 "temperature errors) |")
    lines.append("| `regions.NAME.components.X` | `region_NAME_f_X` | 1 | the region's image component X |")
    return "\n".join(lines)
