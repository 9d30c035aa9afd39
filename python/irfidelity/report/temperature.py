"""The report's "Temperatures" section (a pair scored in a unit, ``config.unit``): both frames
in °C on one colour bar, the difference in K, and the histogram of the temperature errors with
the tolerance band shaded."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from . import figures
from .html import Raw, colour_bar, image, missing, panels, section

__all__ = ["temperatures", "CELSIUS_OFFSET"]

#: 0 °C in kelvin.
CELSIUS_OFFSET = 273.15


def _ticks(lo: float, hi: float, mid: float | None = None) -> list[tuple[float, str]]:
    mid = (lo + hi) / 2 if mid is None else mid
    span = hi - lo if hi > lo else 1.0
    return [(0.0, f"{lo:.4g}"), ((mid - lo) / span, f"{mid:.4g}"), (1.0, f"{hi:.4g}")]


def error_histogram_figure(errors: np.ndarray, tolerance: float) -> bytes:
    """Histogram of the per-pixel temperature errors (simulated − real, K), the tolerance
    band ±``tolerance`` shaded, the bias marked."""
    fig = figures._figure(9.0, 2.8, left=0.08, right=0.98, bottom=0.18, top=0.95)
    ax = fig.add_subplot()
    lo, hi = np.percentile(errors, (0.5, 99.5))
    reach = max(abs(float(lo)), abs(float(hi)), 2.0 * tolerance)
    ax.hist(np.clip(errors, -reach, reach), bins=101, range=(-reach, reach), color=figures.PALETTE[0], alpha=0.85,
            weights=np.full(errors.size, 1.0 / errors.size))
    ax.axvspan(-tolerance, tolerance, color="#999999", alpha=0.2, lw=0, label=f"±{tolerance:.3g} K (tolerance)")
    ax.axvline(float(np.mean(errors)), color="#000000", lw=1.2, label=f"bias {np.mean(errors):+.3g} K")
    ax.set_xlabel("simulated − real (K); the outermost bins hold everything beyond them")
    ax.set_ylabel("fraction of pixels")
    ax.legend(fontsize="small")
    return figures._png(fig)


def temperatures(d: Mapping, real: np.ndarray, sim: np.ndarray, mask: np.ndarray | None) -> Raw:
    """The section, or a note saying why it is missing (a report scored without a unit has none)."""
    unit = (d.get("config") or {}).get("unit")
    metrics = d.get("metrics") or {}
    to_celsius = CELSIUS_OFFSET if unit == "K" else 0.0
    real_c = np.asarray(real, dtype=np.float64) - to_celsius
    sim_c = np.asarray(sim, dtype=np.float64) - to_celsius
    diff = sim_c - real_c
    if mask is not None:
        diff[~mask] = np.nan
    errors = diff[np.isfinite(diff)]
    if errors.size == 0:
        return missing("Temperatures", "no pixel pair with finite temperatures", anchor="temperatures")
    lo, hi = figures.frame_range(real_c, sim_c)
    body: str = panels([(figures.raster(real_c, "inferno", lo, hi), "real frame in degrees Celsius", "real (°C)"),
                   (figures.raster(sim_c, "inferno", lo, hi), "simulated frame in degrees Celsius", "simulated (°C)")])
    body += colour_bar(figures.colour_stops("inferno"), _ticks(lo, hi), "temperature (°C, one scale for both)")
    limit = figures.difference_limit(diff)
    body += panels([(figures.raster(diff, "RdBu_r", -limit, limit), "temperature difference in kelvin",
                     "simulated − real (K)")], single=True)
    body += colour_bar(figures.colour_stops("RdBu_r"), _ticks(-limit, limit, 0.0), "simulated − real (K)")
    tolerance = float(metrics.get("temperature_tolerance") or 1.0)
    caption = _caption(unit, metrics, tolerance)
    body += image(error_histogram_figure(errors, tolerance), "histogram of the temperature errors", caption=caption)
    return section("Temperatures", body, anchor="temperatures")


def _caption(unit: Any, metrics: Mapping[str, Any], tolerance: float) -> str:
    parts = [f"Scored in {unit}; shown in °C (0 °C = {CELSIUS_OFFSET} K), differences in K (equal to °C "
             f"differences). Red: simulator warmer, blue: colder."]
    if "temperature_bias" in metrics:
        parts.append(f"Bias {metrics['temperature_bias']:+.4g} K, RMSE {metrics['temperature_rmse']:.4g} K, MAE "
                     f"{metrics['temperature_mae']:.4g} K; {100 * metrics['temperature_within']:.1f} % of pixels "
                     f"within ±{tolerance:.4g} K.")
    if "psnr_peak" in metrics:
        parts.append(f"PSNR peak: the real frame's temperature range, {metrics['psnr_peak']:.4g} K.")
    return " ".join(parts)

