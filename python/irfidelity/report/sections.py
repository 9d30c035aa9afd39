"""Sections shared by the single-pair and the sequence report, written against the JSON-ready
report dict (``report.to_dict()``) and optional curves, and robust to missing keys: a
section whose data is absent is replaced by a note saying what is not shown and why."""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime, UTC
from typing import Any

import numpy as np

from .._version import __version__
from ..ceiling import CEILING_SOURCES
from ..errors import FidelityError
from . import figures
from .html import Raw, image, key_values, missing, number, paragraph, section, table, text

__all__ = ["as_dict", "header", "verdict", "components", "settings", "mtf", "sitf", "registration", "footer",
           "ORDER"]

#: The paper's component order; other components (e.g. ``noise``) follow in their own order.
ORDER = ("mtf", "sitf", "psnr", "nmi", "ssim")

# Raw metrics of each component, in the order they are shown; a component not listed shows
# the metrics whose names start with its own.
RAW_METRICS = {
    "mtf": ("mtf50_real", "mtf50_sim", "mtf_mu", "mtf_rho", "mtf_ccc", "mtf_area"),
    "sitf": ("sitf_slope_real", "sitf_slope_sim", "sitf_mu", "sitf_rho", "sitf_ccc", "sitf_area"),
    "psnr": ("psnr_db", "mse"),
    "nmi": ("nmi", "mi", "h_real", "h_sim", "h_joint", "bins"),
    "ssim": ("ssim", "ssim_luminance", "ssim_contrast", "ssim_structure"),
}


def as_dict(report: Any) -> dict:
    """The report as a dict: a mapping as is, or an object's ``to_dict()``."""
    if isinstance(report, Mapping):
        return dict(report)
    to_dict = getattr(report, "to_dict", None)
    if callable(to_dict):
        out = to_dict()
        if isinstance(out, Mapping):
            return dict(out)
    raise FidelityError(f"report must be a dict (report.to_dict()) or have to_dict(), got {type(report).__name__}")


def mapping(d: Mapping, key: str) -> dict:
    """``d[key]`` when it is a mapping, else an empty dict (a missing or malformed entry)."""
    v = d.get(key)
    return dict(v) if isinstance(v, Mapping) else {}


def component_names(*dicts: Mapping) -> list[str]:
    names = {k for d in dicts for k in d}
    return [k for k in ORDER if k in names] + sorted(k for k in names if k not in ORDER)


def as_float(v: Any) -> float | None:
    """A float from a JSON-ready value (``"inf"``/``"nan"`` strings included), or None."""
    if isinstance(v, bool) or v is None:
        return None
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def header(title: str, subtitle: str | None) -> Raw:
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    sub = f"<p class=\"sub\">{text(subtitle)}</p>" if subtitle else ""
    return Raw(f"<header><h1>{text(title)}</h1>{sub}<p class=\"sub\">irfidelity {text(__version__)}, {text(when)}"
               "</p></header>")


def verdict(d: Mapping, *, score_key: str = "fidelity", label: str = "Fidelity") -> Raw:
    """The fidelity, its grade and the fuzzy membership vector."""
    score = d.get(score_key)
    if as_float(score) is None:
        return missing("Verdict", f"the report has no {score_key!r} value", anchor="verdict")
    parts = [f'<div class="verdict"><div><div>{text(label)} (eq. 15, Σ k·f)</div>'
             f'<div class="score">{number(score, 4)}</div></div>']
    if d.get("grade") is not None:
        parts.append(f'<div>grade <span class="grade">{text(d["grade"])}</span></div>')
    parts.append("</div>")
    reason, defect = mapping(d, "verdict").get("reason"), mapping(mapping(d, "verdict"), "defect").get("text")
    parts += [paragraph(line) for line in (reason, defect) if isinstance(line, str)]
    ceiling, relative = mapping(d, "ceiling"), mapping(d, "relative")
    if ceiling:
        words = CEILING_SOURCES.get(str(mapping(d, "verdict").get("ceiling_source")), "two real frames of the scene")
        parts.append(paragraph(f"The camera against itself ({words}): the ceiling of each image "
                               "component, and the simulator's value as a fraction of it."))
        parts.append(table(["", *ceiling], [["ceiling", *ceiling.values()],
                                            ["simulator / ceiling", *(relative.get(k) for k in ceiling)]]))
    membership = mapping(d, "membership")
    if membership:
        parts.append(paragraph("The share of the weight in each grade (B = K·R, each component in its own grade; "
                               "the grade is the worst one with a share):"))
        parts.append(table(list(membership), [list(membership.values())]))
    return section("Verdict", "".join(parts), anchor="verdict")


def _raw_metrics(name: str, metrics: Mapping) -> Raw:
    keys = RAW_METRICS.get(name) or tuple(k for k in metrics if k.startswith(f"{name}_") or k == name)
    shown = [f"{text(k)} {number(metrics[k], 5)}" for k in keys if k in metrics]
    return Raw("; ".join(shown))


def components(d: Mapping, *, metrics_key: str = "metrics") -> Raw:
    """Components with their weights, contributions and raw metrics; skipped ones with why."""
    comps, weights, skipped = mapping(d, "components"), mapping(d, "weights"), mapping(d, "skipped")
    metrics = mapping(d, metrics_key)
    names = component_names(comps, weights, skipped)
    if not names:
        return missing("Components", "the report has no components, weights or skipped components",
                       anchor="components")
    grades = mapping(d, "component_grades")
    rows = []
    for name in names:
        w, f = as_float(weights.get(name)), as_float(comps.get(name))
        contribution = w * f if w is not None and f is not None else None
        raw = _raw_metrics(name, metrics) if name in comps else text(f"skipped: {skipped.get(name, 'not computed')}")
        rows.append([Raw(f"<b>{text(name)}</b>"), weights.get(name), comps.get(name), contribution,
                     grades.get(name), raw])
    body: list[str] = [table(["component", "weight k", "value f", "k·f", "grade", "raw metrics"], rows)]
    requested = mapping(mapping(d, "config"), "weights")
    if requested and requested != weights:
        body.append(paragraph("Configured weights (before renormalising over the computed components):"))
        body.append(table(list(requested), [list(requested.values())]))
    notes = d.get("notes")
    if isinstance(notes, (list, tuple)) and notes:
        body.append("".join(paragraph(n, cls="note") for n in notes))
    return section("Components", "".join(body), anchor="components")


def settings(d: Mapping, *extra: tuple[str, Mapping]) -> Raw:
    """What produced the numbers: the settings/configuration, the inputs, the grading matrix."""
    parts: list[str] = []
    if d.get("irfidelity"):
        parts.append(paragraph(f"Made by irfidelity {d['irfidelity']}."))
    for key, title in (("config", "Configuration"), ("inputs", "Inputs")):
        block: Mapping = mapping(d, key)
        if block:
            parts.append(f"<h3>{text(title)}</h3>" + key_values(block))
    for title, block in extra:
        if block:
            parts.append(f"<h3>{text(title)}</h3>" + key_values(block))
    matrix = mapping(mapping(d, "grading"), "matrix")
    if matrix:
        grades = list(next(iter(matrix.values()), {}) or {})
        rows = [[Raw(f"<b>{text(c)}</b>")] + [dict(m).get(g) if isinstance(m, Mapping) else None for g in grades]
                for c, m in matrix.items()]
        parts.append("<h3>Grading matrix R (membership of each component in each grade)</h3>"
                     + table(["component"] + grades, rows))
    if not parts:
        return missing("Settings", "the report records no settings, inputs or grading", anchor="settings")
    return section("Settings", "".join(parts), anchor="settings")


# --------------------------------------------------------------------------- curves
def curve_xy(c: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """``(x, y)`` of a Curve-like object, an ``(x, y)`` pair or a ``{"x", "y"}`` mapping."""
    if c is None:
        return None
    if isinstance(c, Mapping):
        x, y = c.get("x"), c.get("y")
    elif hasattr(c, "x") and hasattr(c, "y"):
        x, y = c.x, c.y
    else:
        try:
            x, y = c
        except (TypeError, ValueError):
            return None
    try:
        x, y = np.asarray(x, dtype=np.float64).ravel(), np.asarray(y, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        return None
    return (x, y) if x.size and x.size == y.size else None


def _fit(f: Any) -> tuple[float, float, float, float] | None:
    keys = ("slope", "intercept", "lo", "hi")
    if isinstance(f, Mapping):
        vals = [as_float(f.get(k)) for k in keys]
    elif f is not None:
        vals = [as_float(getattr(f, k, None)) for k in keys]
    else:
        return None
    return None if any(v is None for v in vals) else tuple(vals)  # type: ignore[return-value]


def _unit(c: Any, default: str) -> str:
    u = getattr(c, "x_unit", None) if not isinstance(c, Mapping) else c.get("x_unit")
    return f"{default} ({u})" if u else default


def mtf(curves: Mapping, metrics: Mapping) -> Raw:
    """Both MTF curves overlaid, MTF50 marked."""
    title = "MTF curves (component f1)"
    real_c, sim_c = curves.get("real_mtf"), curves.get("sim_mtf")
    real_xy, sim_xy = curve_xy(real_c), curve_xy(sim_c)
    if real_xy is None or sim_xy is None:
        return missing(title, "no MTF curves were given (real_mtf= and sim_mtf= of evaluate or score_sequence: "
                              "curves, CSV files or slanted-edge images; on the command line --real-mtf/--sim-mtf "
                              "or --real-edge/--sim-edge)", anchor="mtf")
    notes = []
    entries = []
    for (name, style, key), (x, y) in zip(
        [("real", figures.REAL_STYLE, "mtf50_real"), ("simulated", figures.SIM_STYLE, "mtf50_sim")], (real_xy, sim_xy)
    ):
        at = as_float(metrics.get(key))
        if at is None:
            try:
                from ..curves import mtf50

                at = float(mtf50((x, y)))
            except (FidelityError, ValueError) as exc:
                notes.append(f"MTF50 of the {name} curve not marked: {exc}")
        entries.append({"name": name, "x": x, "y": y, "style": style, "mark": None if at is None else (at, 0.5)})
    png = figures.curves_figure("mtf", entries, x_label=_unit(real_c, "spatial frequency"), y_label="MTF")
    body = image(png, "MTF curves of the real and simulated cameras",
                 caption="Real (solid, circles) and simulated (dashed, squares) MTF; diamonds and dotted lines: "
                         "MTF50, the paper's 'middle spatial frequency'.")
    return section(title, body + "".join(paragraph(n, cls="note") for n in notes), anchor="mtf")


def sitf(curves: Mapping, metrics: Mapping) -> Raw:
    """Both SiTF curves with their fitted linear portions and slopes."""
    title = "SiTF curves (component f2)"
    real_c, sim_c = curves.get("real_sitf"), curves.get("sim_sitf")
    real_xy, sim_xy = curve_xy(real_c), curve_xy(sim_c)
    if real_xy is None or sim_xy is None:
        return missing(title, "no SiTF curves were given (real_sitf= and sim_sitf= of evaluate or score_sequence: "
                              "curves or CSV files; on the command line --real-sitf/--sim-sitf)", anchor="sitf")
    notes = []
    entries = []
    for (name, style, key), (x, y) in zip(
        [("real", figures.REAL_STYLE, "real_sitf_fit"), ("simulated", figures.SIM_STYLE, "sim_sitf_fit")],
        (real_xy, sim_xy),
    ):
        fit = _fit(curves.get(key))
        if fit is None:
            try:
                from ..curves import sitf_fit

                fit = _fit(sitf_fit((x, y)))
                notes.append(f"The {name} linear portion was fitted here with irfidelity.curves.sitf_fit's defaults; "
                             "the slope scored (in the caption) follows the configuration's sitf_options.")
            except (FidelityError, ValueError) as exc:
                notes.append(f"No linear fit of the {name} SiTF: {exc}")
        entries.append({"name": name, "x": x, "y": y, "style": style, "fit": fit})
    slopes = [(k, metrics[k]) for k in ("sitf_slope_real", "sitf_slope_sim") if k in metrics]
    png = figures.curves_figure("sitf", entries, x_label=_unit(real_c, "target temperature difference"),
                                y_label="signal")
    caption = "Real (solid) and simulated (dashed) SiTF; wide translucent segments: the fitted linear portions."
    if slopes:
        caption += " Scored slopes: " + ", ".join(f"{k} = {v:.5g}" if isinstance(v, float) else f"{k} = {v}"
                                                  for k, v in slopes) + "."
    body = image(png, "SiTF curves of the real and simulated cameras", caption=caption)
    return section(title, body + "".join(paragraph(n, cls="note") for n in notes), anchor="sitf")


def registration(d: Mapping, given: Any = None) -> Raw:
    """The registration applied before the image metrics, when there was one."""
    title = "Registration"
    reg = given if given is not None else d.get("registration")
    if reg is None:
        return missing(title, "no registration was applied (or recorded in the report)", anchor="registration")
    fields = ("model", "method", "shift", "angle", "scale", "confidence", "overlap")
    if isinstance(reg, Mapping):
        values = {k: reg[k] for k in reg if k != "matrix"}
        matrix = reg.get("matrix")
    else:
        values = {k: getattr(reg, k) for k in fields if hasattr(reg, k)}
        matrix = getattr(reg, "matrix", None)
    values = {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in values.items()}
    body = key_values(values, header=("quantity", "value")) if values else ""
    try:
        m = np.asarray(matrix, dtype=np.float64)
    except (TypeError, ValueError):
        m = None
    if m is not None and m.shape == (2, 3):
        body += paragraph("Affine matrix (simulated pixel coordinates x = column, y = row → real):")
        body += table(["", "x", "y", "1"], [["x′", *m[0]], ["y′", *m[1]]])
    if not body:
        return missing(title, "the registration record is empty", anchor="registration")
    return section(title, body, anchor="registration")


def footer(left_out: list[str]) -> Raw:
    note = ""
    if left_out:
        note = "Sections not shown: " + ", ".join(str(text(t)) for t in left_out) + ". "
    return Raw(f"<footer>{note}Self-contained report: figures embedded, no network resources. "
               "References: Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547 (fidelity "
               "framework); Wang et al., IEEE TIP 13(4):600 (2004) (SSIM map); Wang, Simoncelli &amp; Bovik, "
               "Asilomar 2003 (MS-SSIM).</footer>")
