"""The bar-target section: CTF, MTF (from edges or curves, and from bars) and MRTD of both
cameras side by side, with the ``mrtd`` component's quantities (docs/bars.md)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..schema import METRICS
from . import figures
from .html import Raw, image, key_values, missing, section
from .sections import curve_xy

__all__ = ["bars"]

TITLE = "Bar targets: CTF, MTF and MRTD (component mrtd)"

#: (panel title, y label, logarithmic y, the curves drawn: (key suffix, label))
_PANELS = (
    ("CTF (bar modulation)", "CTF", False, (("ctf", "bars"),)),
    ("MTF", "MTF", False, (("mtf", "MTF input"), ("bar_mtf", "bars (fundamental)"))),
    ("MRTD", "MRTD (K)", True, (("mrtd", "MRTD"),)),
)

_SIDES = (("real", "real", figures.REAL_STYLE), ("sim", "simulated", figures.SIM_STYLE))


def _entries(curves: Mapping, kinds: tuple) -> list[dict[str, Any]]:
    """The panel's curves present, each side in its style (a second kind without markers)."""
    out = []
    for n, (kind, label) in enumerate(kinds):
        for side, name, style in _SIDES:
            xy = curve_xy(curves.get(f"{side}_{kind}"))
            if xy is not None:
                shown = {**style, "marker": style["marker"] if n == 0 else "^"}
                out.append({"name": f"{name}, {label}" if len(kinds) > 1 else name, "x": xy[0], "y": xy[1],
                            "style": shown})
    return out


def _x_label(curves: Mapping) -> str:
    for key in ("real_mrtd", "real_ctf", "real_bar_mtf"):
        unit = getattr(curves.get(key), "x_unit", None)
        if unit:
            return f"spatial frequency ({unit})"
    return "spatial frequency"


def bars(curves: Mapping, metrics: Mapping) -> Raw:
    """The section, or a note saying no MRTD inputs were compared."""
    if not any(curves.get(f"{side}_{kind}") is not None for side in ("real", "sim")
               for kind in ("mrtd", "ctf", "bar_mtf")):
        return missing(TITLE, "no MRTD inputs were compared (real_mrtd=/sim_mrtd= of evaluate: MRTD curves or bar "
                              "frames, with a weight on mrtd; on the command line --real-bars/--sim-bars)",
                       anchor="bars")
    panels = [{"title": title, "y_label": y_label, "log": log, "curves": _entries(curves, kinds)}
              for title, y_label, log, kinds in _PANELS]
    panels = [p for p in panels if p["curves"]]
    png = figures.panels_figure(panels, x_label=_x_label(curves))
    body = image(png, "CTF, MTF and MRTD of the real and simulated cameras",
                 caption="Real solid, simulated dashed. MTF: circles the MTF compared by component f1 (slanted edge "
                         "or curve), triangles the fundamental-amplitude MTF of the bar frames. MRTD on a log scale: "
                         "measured on bar frames or given as curves.")
    values = {key: metrics[key] for key, _, _ in METRICS["mrtd"] if metrics.get(key) is not None}
    return section(TITLE, body + (key_values(values, header=("quantity", "value")) if values else ""), anchor="bars")
