"""The gain: the transfer at zero frequency, from the whole frame's lowest frequencies.

A tile's lowest frequencies mix ±2/tile cy/px of the spectrum, over which a blur already
lowers the transfer; the block-mean frames' whole-frame spectrum reaches frequencies ten times
lower. ``ln G(f) = ln gain − a·f²`` (exact for Gaussian MTFs, the first terms of any smooth
one) is fitted to its rings and extrapolated to f = 0."""

from __future__ import annotations

import math

import numpy as np

from .rings import ratio
from .spectra import TransferSpectra

__all__ = ["GAIN_BAND", "gain"]

#: The rings fitted lie below this frequency (cy/px of the frame), at least three of them.
GAIN_BAND = 0.04


def _hann(n: int) -> np.ndarray:
    """The window of the Rust passes, ``sin²(π(i + 1)/(n + 1))``."""
    return np.sin(np.pi * (np.arange(n) + 1) / (n + 1)) ** 2


def gain(spectra: TransferSpectra, shift: tuple[float, float], real_variance: float | None
         ) -> tuple[float, float] | None:
    """``(gain, standard error)`` from the block-mean spectrum (the displacement ``shift``
    removed, the real camera's white noise ``real_variance`` subtracted when known), fitted over
    rings 2.. up to :data:`GAIN_BAND`, weighted by each ring's power. None when those rings do
    not all show one sign of correlation (a flat scene, or unrelated frames)."""
    rows, cols = spectra.low_shape
    q = spectra.factor
    fy, fx = np.fft.fftfreq(rows)[:, None] / q, np.fft.rfftfreq(cols)[None, :] / q
    step = 1.0 / (q * min(rows, cols))
    ring = np.rint(np.hypot(fy, fx) / step).astype(np.int64).ravel()
    weight = np.full(spectra.low_real.shape, 2.0)
    weight[:, 0] = 1.0
    if cols % 2 == 0:
        weight[:, -1] = 1.0
    top = max(4, int(GAIN_BAND / step))
    cross = (spectra.low_cross * np.exp(2j * np.pi * (fy * shift[0] + fx * shift[1]))).real
    power = spectra.low_real
    if real_variance is not None:
        power = power - real_variance / q ** 2 * float((_hann(rows) ** 2).sum() * (_hann(cols) ** 2).sum())
    num = np.bincount(ring, (weight * cross).ravel(), minlength=top + 1)[2:top + 1]
    den = np.bincount(ring, (weight * power).ravel(), minlength=top + 1)[2:top + 1]
    values = ratio(num, den)
    sign = float(np.sign(np.nansum(num)))
    use = np.isfinite(values) & (sign * values > 0)
    if use.sum() < 3 or use.sum() < 0.8 * np.isfinite(values).sum():
        return None
    x = (np.arange(2, top + 1) * step)[use] ** 2
    return _extrapolate(x, np.log(sign * values[use]), den[use], sign)


def _extrapolate(x: np.ndarray, y: np.ndarray, weight: np.ndarray, sign: float) -> tuple[float, float]:
    """``sign·exp(b)`` of the weighted least-squares line ``y = b + m·x`` (weights ∝ 1/variance)
    and its standard error from the residuals."""
    design = np.stack([np.ones_like(x), x], axis=1)
    normal = design.T @ (weight[:, None] * design)
    b, m = np.linalg.solve(normal, design.T @ (weight * y))
    residual = y - b - m * x
    scale = float((weight * residual ** 2).sum()) / max(len(x) - 2, 1)
    se = math.sqrt(max(scale * float(np.linalg.inv(normal)[0, 0]), 0.0))
    value = sign * math.exp(float(b))
    return value, abs(value) * se
