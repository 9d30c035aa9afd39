"""Slanted-edge MTF following ISO 12233 e-SFR (the edge-based spatial frequency response).

A slightly tilted straight edge (ideally 2-10° off the pixel grid) is sampled at a
different sub-pixel phase in every row, so projecting all pixels onto the edge
normal gives an oversampled edge spread function (ESF) without aliasing. Steps, as
in ISO 12233:2014/2017 (sfrmat3):

1. per-row derivative (two-tap ``[-1, 1]``), edge location by the centroid of the
   Hamming-windowed derivative, window re-centred on the fitted edge, repeated;
2. polynomial fit of the edge location against the row (order 1 by default);
3. every pixel binned at ``1/oversample`` pixel of its horizontal distance to the
   fitted edge -> oversampled ESF;
4. derivative -> LSF, Hamming window centred on the LSF, DFT, normalised;
5. the derivative's transfer function ``sinc(f·dx)`` divided out; frequencies
   scaled by ``1/cos(angle)`` to cycles/pixel along the edge normal.

Problems that make the result unreliable are reported with :class:`EdgeWarning`.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from .curves import CY_PX, Curve
from .mtf import _diff_correction, _window
from .errors import FidelityError

__all__ = ["EdgeWarning", "mtf_from_edge"]

#: edge angles (degrees from the pixel grid) at which the 4x phase pattern repeats too soon
CRITICAL_ANGLES = (math.degrees(math.atan(0.25)), math.degrees(math.atan(0.5)))  # 14.04°, 26.57°


class EdgeWarning(UserWarning):
    """A slanted-edge measurement that ran, but whose conditions make the MTF doubtful:
    clipped pixels, low contrast, an edge angle near 0°/45° or a critical angle,
    too few sub-pixel phases."""


def _warn(msg: str) -> None:
    warnings.warn(msg, EdgeWarning, stacklevel=3)


def _hamming_rows(pos: np.ndarray, centres: np.ndarray, width: float) -> np.ndarray:
    t = (pos[None, :] - centres[:, None]) / width
    return np.where(np.abs(t) <= 0.5, 0.54 + 0.46 * np.cos(2 * np.pi * t), 0.0)


def mtf_from_edge(image: Any, *, oversample: int = 4, window: Any = "hamming", fit_order: int = 1,
                  orientation: str = "auto", max_freq: float | None = 1.0, correct: bool = True,
                  clip: tuple[float, float] | None = None, name: str | None = None) -> Curve:
    """Slanted-edge MTF of a region of interest holding one straight edge (ISO 12233 e-SFR).

    Parameters
    ----------
    image : 2-D array_like
        The ROI: integer (8/16-bit ...) or float pixels, one edge crossing it from
        side to side, either polarity (dark-to-bright or bright-to-dark).
    oversample : int
        ESF bins per pixel (ISO: 4).
    window : "hamming" | "tukey" | "hann" | None
        Window applied to the LSF before the DFT, centred on the LSF.
    fit_order : int
        Order of the polynomial fitted to the edge locations (1 = straight edge;
        up to 5 for an edge bent by lens distortion).
    orientation : "auto" | "vertical" | "horizontal"
        A vertical edge runs along the columns (intensity changes along a row).
        ``"auto"`` picks the direction in which the ROI's sides differ most.
    max_freq : float or None
        Highest frequency returned, cycles/pixel (the first sample at or above it is
        included). None keeps everything up to the oversampled Nyquist frequency.
    correct : bool
        Divide out the derivative's transfer function (capped at 10).
    clip : (lo, hi), optional
        Values at or beyond which a pixel counts as clipped. Default: the integer
        dtype's range; none for float images.

    Returns
    -------
    Curve
        Frequency (cycles/pixel, along the edge normal) vs MTF, ``x_unit="cy/px"``;
        ``meta`` holds ``angle_deg``, ``orientation``, ``polarity``, ``snr``,
        ``esf``, ``lsf``, ``edge_poly`` (coefficients, rows -> column) and ``empty_bins``.

    Warns
    -----
    EdgeWarning
        Clipped pixels (>= 0.1 % of the ROI), low contrast (step < 20x the noise, or
        < 20 grey levels for integer images), edge angle within 1.5° of the grid or
        beyond 35° (toward 45°), within 0.5° of the critical angles 14.04° / 26.57°,
        fewer than one full pixel of edge shift over the ROI, or empty ESF bins
        (filled by interpolation).

    Raises
    ------
    FidelityError (a ValueError)
        Not a 2-D numeric array, non-finite pixels, ROI smaller than 8x8, no edge
        (no step between the sides), or an edge too close to the ROI border.
    """
    a0 = np.asarray(image)
    if a0.ndim != 2:
        raise FidelityError(f"mtf_from_edge needs a 2-D image (one channel), got shape {a0.shape}")
    if a0.dtype.kind not in "uif":
        raise FidelityError(f"mtf_from_edge needs integer or float pixels, got dtype {a0.dtype}")
    os_ = int(oversample)
    if os_ != oversample or os_ < 1:
        raise FidelityError(f"oversample must be a positive integer, got {oversample!r}")
    order = int(fit_order)
    if order != fit_order or not 1 <= order <= 5:
        raise FidelityError(f"fit_order must be an integer 1..5, got {fit_order!r}")
    a = a0.astype(np.float64)
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))
        raise FidelityError(f"image has {len(bad)} non-finite pixels, first at (row, col) = {tuple(bad[0])}")
    if min(a.shape) < 8:
        raise FidelityError(f"edge ROI must be at least 8x8 pixels, got {a.shape}")

    # 1. clipping
    if clip is None and a0.dtype.kind in "ui":
        info = np.iinfo(a0.dtype)
        clip = (float(info.min), float(info.max))
    if clip is not None:
        lo_c, hi_c = (float(v) for v in clip)
        n_clip = int(((a <= lo_c) | (a >= hi_c)).sum())
        if n_clip >= 0.001 * a.size:
            _warn(f"{n_clip} of {a.size} pixels ({n_clip / a.size:.1%}) are clipped at {lo_c:g} or {hi_c:g}: "
                  f"the ESF plateaus are distorted and the MTF is biased")

    # 2. orientation: make the edge vertical (intensity changes along axis 1)
    k = max(1, min(a.shape) // 8)
    dv = abs(a[:, :k].mean() - a[:, -k:].mean())
    dh = abs(a[:k, :].mean() - a[-k:, :].mean())
    if orientation == "auto":
        orientation = "vertical" if dv >= dh else "horizontal"
    if orientation == "horizontal":
        a = a.T
    elif orientation != "vertical":
        raise FidelityError(f"orientation must be 'auto', 'vertical' or 'horizontal', got {orientation!r}")
    nrows, ncols = a.shape
    step_sides = a[:, -k:].mean() - a[:, :k].mean()
    if step_sides == 0:
        raise FidelityError("no edge found: both sides of the ROI have the same mean level")
    pol = 1.0 if step_sides > 0 else -1.0

    # 3. edge location per row: centroid of the windowed derivative, fit, re-centre, refit
    d = np.diff(a, axis=1) * pol
    pos = np.arange(ncols - 1) + 0.5
    rows = np.arange(nrows, dtype=np.float64)
    md = np.clip(d.mean(axis=0), 0, None)
    c0 = float((md * pos).sum() / md.sum()) if md.sum() > 0 else (ncols - 1) / 2
    centres = np.full(nrows, c0)
    poly = None
    for _ in range(3):
        wd = d * _hamming_rows(pos, centres, float(ncols - 1))
        s = wd.sum(axis=1)
        good = s > 0
        if good.sum() < order + 2:
            raise FidelityError("no edge found: the derivative along the rows has no positive peak")
        loc = (wd[good] * pos).sum(axis=1) / s[good]
        poly = np.polynomial.Polynomial.fit(rows[good], loc, order)
        centres = poly(rows)
    assert poly is not None
    slope = float(poly.deriv()(rows.mean()))
    angle = math.degrees(math.atan(slope))
    aa = abs(angle)
    if aa < 1.5:
        _warn(f"edge angle {angle:.2f}° is nearly aligned with the pixel grid (ISO 12233 asks for ~5°): "
              f"too few sub-pixel phases")
    elif aa > 35:
        _warn(f"edge angle {angle:.2f}° is near 45°: the phases repeat and the pixel footprint along "
              f"the normal widens; tilt the edge ~5° from the grid")
    for crit in CRITICAL_ANGLES:
        if abs(aa - crit) < 0.5:
            _warn(f"edge angle {angle:.2f}° is within 0.5° of the critical angle {crit:.2f}° at which "
                  f"the {os_}x oversampling phases repeat")
    shift = abs(centres[-1] - centres[0])
    if shift < 1 and aa >= 1.5:
        _warn(f"the edge shifts by only {shift:.2f} px over the {nrows} rows: fewer than one full "
              f"cycle of sub-pixel phases")

    # 4. oversampled ESF over a distance range +-half that every used row covers; rows whose
    #    edge runs closer than that to the ROI border (steep edges in small ROIs) are left out
    margin = np.minimum(centres, (ncols - 1) - centres)
    half = float(margin.min())
    used = np.ones(nrows, dtype=bool)
    if half < 8:
        half = float(min(8.0, np.median(margin)))
        used = margin >= half
    if half < 3 or used.sum() < 8:
        raise FidelityError(f"the edge runs too close to the ROI border (median margin "
                            f"{max(float(np.median(margin)), 0):.1f} px): need at least 3 px of "
                            f"plateau on both sides in at least 8 rows")
    kmax = int(math.floor(half * os_))
    dist = np.arange(ncols)[None, :] - centres[used, None]
    kb = np.rint(dist * os_).astype(np.int64)
    keep = np.abs(kb) <= kmax
    idx = (kb[keep] + kmax).ravel()
    nb = 2 * kmax + 1
    counts = np.bincount(idx, minlength=nb)
    sums = np.bincount(idx, weights=a[used][keep].ravel(), minlength=nb)
    filled = counts > 0
    empty = int(nb - filled.sum())
    esf = np.empty(nb)
    esf[filled] = sums[filled] / counts[filled]
    if empty:
        bins = np.arange(nb)
        esf[~filled] = np.interp(bins[~filled], bins[filled], esf[filled])
        _warn(f"{empty} of {nb} ESF bins received no pixel (too few sub-pixel phases); "
              f"filled by interpolation")

    # contrast / noise
    m = max(os_, nb // 8)
    step = (esf[-m:].mean() - esf[:m].mean()) * pol
    if step <= 0:
        raise FidelityError("no edge found: the ESF does not rise across the fitted edge")
    noise = 1.4826 * float(np.median(np.abs(np.diff(a, axis=0)))) / math.sqrt(2)
    snr = step / noise if noise > 0 else math.inf
    if snr < 20:
        _warn(f"low contrast: edge step {step:.4g} is only {snr:.1f}x the pixel noise {noise:.3g}")
    elif a0.dtype.kind in "ui" and step < 20:
        _warn(f"low contrast: edge step of {step:.3g} grey levels; quantisation dominates")

    # 5. LSF, window, DFT, derivative correction, frequency along the normal
    lsf = np.diff(esf) * pol
    pl = np.clip(lsf, 0, None)
    lc = float((pl * np.arange(lsf.size)).sum() / pl.sum()) if pl.sum() > 0 else (lsf.size - 1) / 2
    w = lsf * _window(window, lsf.size, lc)
    spec = np.abs(np.fft.rfft(w))
    if not spec[0] > 0:
        raise FidelityError("no edge found: the LSF sums to zero")
    cos_a = math.cos(math.atan(slope))
    dx = cos_a / os_  # ESF spacing along the edge normal, pixels
    f = np.arange(spec.size) / (lsf.size * dx)
    mtf = spec / spec[0]
    if correct:
        mtf = mtf * _diff_correction(f, dx, 10.0)
    if max_freq is not None:
        mf = float(max_freq)
        if not mf > 0:
            raise FidelityError(f"max_freq must be > 0 or None, got {max_freq!r}")
        n_keep = int(np.searchsorted(f, mf * (1 - 1e-12))) + 1
        f, mtf = f[:n_keep], mtf[:n_keep]
    meta = {"angle_deg": angle, "orientation": orientation, "polarity": int(pol), "snr": snr,
            "step": float(step), "esf": esf, "lsf": lsf, "esf_dx": dx,
            "edge_poly": poly.convert().coef.tolist(), "empty_bins": empty,
            "rows_used": int(used.sum())}
    return Curve(f, mtf, name=name or "slanted-edge MTF", x_unit=CY_PX, meta=meta)
