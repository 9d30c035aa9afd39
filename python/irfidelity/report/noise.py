"""The sensor-noise section: both cameras' 3-D noise components side by side, the NETD when
a SiTF gave one, the similarity's parts, and the noise spectra overlaid (when the Noise3D
objects that were compared are at hand)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..schema import NOISE_PARTS, NOISE_SPECTRA
from . import figures
from .html import Raw, image, key_values, missing, number, section, table
from .sections import as_float

__all__ = ["noise"]

TITLE = "Sensor noise (component noise)"


def _ratio(real: float | None, sim: float | None) -> Raw:
    if real is None or sim is None or real == 0:
        return number(None)
    return number(sim / real)


def _levels_table(metrics: Mapping) -> Raw | None:
    """σ of each part, the total and the NETD: real, simulated and their ratio."""
    rows = []
    keys = [(f"σ_{part}", f"noise_sigma_{part}") for part in NOISE_PARTS]
    keys += [("total σ", "noise_total"), ("NETD (σ_tvh / |SiTF slope|)", "noise_netd")]
    for label, key in keys:
        real, sim = as_float(metrics.get(f"{key}_real")), as_float(metrics.get(f"{key}_sim"))
        if real is None and sim is None:
            continue
        rows.append([label, number(real), number(sim), _ratio(real, sim)])
    return table(["", "real", "simulated", "simulated / real"], rows) if rows else None


def _similarity(metrics: Mapping) -> dict[str, Any]:
    keys = ["noise_mu", "noise_rho", "noise_total_mu", "noise_units"]
    keys += [f"noise_overlap_{name}" for name in NOISE_SPECTRA]
    keys += [f"noise_frames_{who}" for who in ("real", "sim")]
    return {k: metrics[k] for k in keys if metrics.get(k) is not None}


def _spectra_figure(curves: Mapping) -> Raw:
    """Row spectra of the fixed pattern and of the temporal noise, real against simulated."""
    real_s, sim_s = (getattr(curves.get(f"{who}_noise"), "spectra", None) for who in ("real", "sim"))
    if real_s is None or sim_s is None:
        return Raw("")
    entries = []
    for kind in ("fixed_row", "temporal_row"):
        for name, s, style in zip(("real", "simulated"), (real_s, sim_s), (figures.REAL_STYLE, figures.SIM_STYLE)):
            y = getattr(s, kind)
            if y is not None:
                entries.append({"name": f"{kind.replace('_', ' ')}, {name}", "x": s.freq_row, "y": y,
                                "style": {**style, "marker": "" if kind.startswith("temporal") else style["marker"]}})
    if not entries:
        return Raw("")
    png = figures.curves_figure("noise", entries, x_label="frequency along a row (cycles/pixel)",
                                y_label="power (frame units²)")
    return image(png, "Noise spectra of the real and simulated cameras",
                 caption="One-sided row spectra: the fixed pattern (with markers) and the temporal noise (no markers); "
                         "real solid, simulated dashed. Their shapes' overlap is noise_rho.")


def noise(curves: Mapping, metrics: Mapping) -> Raw:
    """The section, or a note saying no noise recordings were compared."""
    levels = _levels_table(metrics)
    if levels is None:
        return missing(TITLE, "no noise recordings were compared (real_noise=/sim_noise=, or the CLI's "
                              "--real-noise/--sim-noise)", anchor="noise")
    similarity = _similarity(metrics)
    body = levels + (key_values(similarity, header=("quantity", "value")) if similarity else "")
    return section(TITLE, body + _spectra_figure(curves), anchor="noise")
