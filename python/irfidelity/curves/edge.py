"""Slanted-edge MTF following ISO 12233:2023 e-SFR (the edge-based spatial frequency response).

A slightly tilted straight (or lens-curved) edge is sampled at a different sub-pixel phase in
every row, so binning all pixels by their distance to the edge gives an oversampled edge spread
function (ESF) without aliasing. The steps, one function each:

1. :func:`_orient` — make the edge run along the columns (transpose a horizontal edge) and find
   its polarity;
2. :func:`_locate_edge` — per row, the centroid of the Hamming-windowed two-tap derivative; a
   polynomial of the row fitted to the centroids (order 5 by default as ISO 12233:2023 / sfrmat5,
   1 = the straight line of ISO 12233:2014); the windows re-centred on the fit, the fit repeated;
3. :func:`_rows_for_esf` and :func:`_check_edge` — a centred block of rows spanning a whole
   number of phase cycles (as ISO); refuse an image without a usable edge (below);
4. :func:`_oversampled_esf` — every pixel of those rows binned at ``1/oversample`` pixel of its
   horizontal distance to the fitted edge, over the whole ROI;
5. :func:`_contrast` — the edge step against the pixel noise, and the plateaus on both sides;
6. :func:`~irfidelity.curves.mtf.mtf_from_esf` — derivative, window (centred on the fitted
   edge), DFT, the derivative's ``sinc`` divided out; frequencies scaled by ``1/cos(angle)``
   (angle of the straight-line fit) to cycles/pixel along the edge normal.

An image without a usable edge is a :class:`~irfidelity.errors.FidelityError` saying which of
these failed (measured on rendered edges, the real crops and the shipped thermal frames):

* no step between the two sides of the ROI, or too few rows with a rising derivative;
* the edge fit does not fit: the rows' centroids scatter around the fitted edge by more than
  ``EDGE_RESIDUAL_ALLOWANCE_PX`` = 0.5 px plus ``EDGE_RESIDUAL_NOISE_FACTOR`` = 3 times the
  scatter the pixel noise explains (:func:`_noise_scatter`; rendered edges at any noise level
  stay below 0.35 of that limit, the real crops leave 0.07-0.21 px; thermal scenes 10-80 px);
* fewer than ``MIN_CROSSING_FRACTION`` = 95 % of the rows cross the fitted edge with at least
  half the median row step (every rendered edge, down to SNR 5, and every real crop: 100 %), or
  fewer than ``MIN_ROWS`` = 8 rows;
* an angle outside the usable range: the edge shifts by less than one pixel over the ROI (too
  few sub-pixel phases to oversample) or runs more than 45° off the axis it is read along;
* the edge profile has no plateaus: more than ``MAX_RAMP_FRACTION`` = 50 % of the ESF lies
  between 10 % and 90 % of the step (a gradient across the ROI);
* the step is below ``MIN_SNR`` = 5 times the pixel noise (below 20 warns): below 5 the MTF50
  of rendered edges scatters by ±90 % and more between noise realisations;
* an MTF above ``MTF_LIMIT`` = 1.2 up to the Nyquist frequency. An optical system's MTF is at
  most 1; in-camera sharpening lifts it, typically to 1.05-1.15, in strongly sharpened cameras
  to about 1.2; a value above that is noise or a non-edge, not a camera property. (Beyond
  Nyquist the e-SFR is aliasing, with a spike at the sampling frequency wherever the phases are
  unevenly covered; it is returned but not checked.)

Problems that leave the result usable but doubtful are :class:`EdgeWarning`.

References: ISO 12233:2023 Annex D; P. D. Burns, "Slanted-edge MTF for digital camera and
scanner analysis", Proc. IS&T PICS (2000) 135-138; P. D. Burns, K. Masaoka, K. Parulski,
D. Wueller, "Updated camera spatial frequency response for ISO 12233", Proc. IS&T Electronic
Imaging (2022), doi:10.2352/EI.2022.34.9.IQSP-357 (the polynomial edge fit of sfrmat5).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import EdgeWarning, FidelityError
from .curve import Curve
from .mtf import apodization, mtf_from_esf

__all__ = ["EdgeWarning", "mtf_from_edge", "EdgeFit"]

#: an MTF above this up to the Nyquist frequency is refused (sharpening allowance, see above)
MTF_LIMIT = 1.2
#: the rows' edge locations may scatter around the fitted edge by this allowance (px, RMS) plus
#: this factor times the scatter pixel noise explains
EDGE_RESIDUAL_ALLOWANCE_PX = 0.5
EDGE_RESIDUAL_NOISE_FACTOR = 3.0
#: fraction of the rows that must cross the fitted edge with at least half the median step
MIN_CROSSING_FRACTION = 0.95
#: largest fraction of the ESF between 10 % and 90 % of the step (else a gradient, not an edge)
MAX_RAMP_FRACTION = 0.5
#: an edge step below this many times the pixel noise is refused (20 only warns)
MIN_SNR = 5
#: fewest rows an ESF is built from
MIN_ROWS = 8
#: edge angles (degrees from the pixel grid) at which the 4x phase pattern repeats too soon
CRITICAL_ANGLES = (math.degrees(math.atan(0.25)), math.degrees(math.atan(0.5)))  # 14.04°, 26.57°


def _warn(msg: str) -> None:
    warnings.warn(msg, EdgeWarning, stacklevel=4)  # the caller of mtf_from_edge


@dataclass(frozen=True)
class EdgeFit:
    """Where the edge runs in an oriented ROI: ``column = poly(row)``.

    Attributes
    ----------
    poly : numpy.polynomial.Polynomial
        The fitted edge (order ``edge_fit_order``).
    columns : numpy.ndarray
        ``poly`` at every row.
    slope : float
        Columns per row of the straight line fitted to the same centroids (the edge angle).
    centroids : numpy.ndarray
        Per-row edge location (NaN where a row has no positive derivative).
    residual_rms : float
        RMS distance of the centroids from ``poly``, pixels.
    noise_rms : float
        The part of that scatter pixel noise explains, pixels.
    """

    poly: np.polynomial.Polynomial
    columns: np.ndarray
    slope: float
    centroids: np.ndarray
    residual_rms: float
    noise_rms: float

    @property
    def angle_deg(self) -> float:
        """Angle of the edge from the columns, degrees."""
        return math.degrees(math.atan(self.slope))


def mtf_from_edge(image: Any, *, edge_fit_order: int = 5, oversample: int = 4, window: Any = "hamming",
                  orientation: str = "auto", max_freq: float | None = 1.0, correct: bool = True,
                  clip: tuple[float, float] | None = None, name: str | None = None,
                  channel: str | None = None) -> Curve:
    """Slanted-edge MTF of a region of interest holding one edge (ISO 12233:2023 e-SFR).

    Each pixel at column ``j`` of row ``i`` is binned at its distance ``j - e(i)`` to the
    fitted edge ``e`` (a polynomial of the row) in bins of ``1/oversample`` pixel; the binned
    means form the ESF. With ``Δ = cos(θ)/oversample`` the ESF spacing along the edge normal
    (``θ`` the edge angle from the straight-line fit),

    .. math::

        \\mathrm{MTF}(f_k) = \\frac{|\\mathrm{DFT}(w \\cdot \\Delta\\mathrm{ESF})_k|}
                                  {|\\mathrm{DFT}(w \\cdot \\Delta\\mathrm{ESF})_0|}
                             \\cdot \\frac{1}{\\mathrm{sinc}(f_k \\Delta)},
        \\qquad f_k = \\frac{k}{N \\Delta}

    in cycles per pixel along the edge normal.

    Parameters
    ----------
    image : 2-D array_like, or a path
        The ROI: integer (8/16-bit ...) or float pixels, one edge crossing it from side to
        side, either polarity (dark-to-bright or bright-to-dark). A path (str or
        ``os.PathLike``) is read with :func:`irfidelity.load_frame`; errors then name it.
    edge_fit_order : int
        Order of the polynomial fitted to the per-row edge locations, 1..5: 5 (default) as
        ISO 12233:2023 (follows an edge bent by lens distortion), 1 = the straight line of
        ISO 12233:2014, which misplaces a bowed edge in some rows and so blurs the ESF.
    oversample : int
        ESF bins per pixel (ISO: 4).
    window : "hamming" | "hann" | "tukey" | None
        Window applied to the LSF before the DFT, as long as the LSF and centred on the fitted
        edge (where the LSF peaks).
    orientation : "auto" | "vertical" | "horizontal"
        A vertical edge runs along the columns (intensity changes along a row). ``"auto"``
        picks the direction in which the ROI's sides differ most.
    max_freq : float or None
        Highest frequency returned, cycles/pixel (the first sample at or above it is
        included). None keeps everything up to the oversampled Nyquist frequency.
    correct : bool
        Divide out the derivative's transfer function (capped at 10).
    clip : (lo, hi), optional
        Values at or beyond which a pixel counts as clipped. Default: the integer dtype's
        range; none for float images.
    name : str, optional
        Label of the curve (default: the file name for a path).
    channel : str, optional
        The channel of a multi-channel image file (``"R"``, ``"Y"``, an EXR channel name, ...;
        :func:`irfidelity.load_frame`); only with a path.

    Returns
    -------
    Curve
        Frequency (``x_unit="cy/px"``, along the edge normal) vs MTF (``y_unit="1"``);
        ``meta`` holds ``angle_deg`` (straight-line fit), ``orientation``, ``polarity``,
        ``snr``, ``step``, ``esf``, ``lsf``, ``esf_dx``, ``edge_poly`` (coefficients,
        row -> column), ``edge_fit_order``, ``edge_residual_px``, ``empty_bins`` and
        ``rows_used``.

    Warns
    -----
    EdgeWarning
        Clipped pixels (>= 0.1 % of the ROI), low contrast (step < 20x the noise, or < 20
        grey levels for integer images), an edge angle within 1.5° of the grid or beyond 35°,
        within 0.5° of the critical angles 14.04° / 26.57°, or empty ESF bins (filled by
        interpolation).

    Raises
    ------
    FidelityError (a ValueError)
        Not a 2-D numeric array, non-finite pixels, ROI smaller than 8x8, or no usable edge
        (thresholds and their reasons in :mod:`irfidelity.curves.edge`): no step between the
        sides, an edge fit that does not fit (centroids scattering by more than 0.5 px plus
        three times what noise explains), fewer than 95 % of the rows crossing the edge, too
        few rows, an angle outside the usable range, an edge too close to the ROI border, no
        plateaus (a gradient), a step below 5x the pixel noise, or an MTF above 1.2 up to
        Nyquist — the message says which.

    References
    ----------
    .. [1] ISO 12233:2023, Photography — Electronic still picture imaging — Resolution and
       spatial frequency responses, Annex D.
    .. [2] P. D. Burns, "Slanted-edge MTF for digital camera and scanner analysis",
       Proc. IS&T PICS (2000) 135-138.
    .. [3] P. D. Burns, K. Masaoka, K. Parulski, D. Wueller, "Updated camera spatial
       frequency response for ISO 12233", Proc. IS&T Electronic Imaging (2022),
       doi:10.2352/EI.2022.34.9.IQSP-357.

    Examples
    --------
    >>> rows, cols = np.mgrid[0:64, 0:64]
    >>> distance = (cols - 32) * np.cos(0.1) - (rows - 32) * np.sin(0.1)  # 5.7° from vertical
    >>> from math import erf
    >>> edge = 0.1 + 0.8 * 0.5 * (1 + np.vectorize(erf)(distance / (1.0 * np.sqrt(2))))
    >>> c = mtf_from_edge(edge)
    >>> round(c.meta["angle_deg"], 1), c.x_unit
    (5.7, 'cy/px')
    """
    if isinstance(image, (str, os.PathLike)):
        path = os.fsdecode(os.fspath(image))
        try:
            return mtf_from_edge(_load_edge(path, channel), edge_fit_order=edge_fit_order, oversample=oversample,
                                 window=window, orientation=orientation, max_freq=max_freq, correct=correct,
                                 clip=clip, name=name or os.path.basename(path))
        except FidelityError as exc:
            raise type(exc)(exc if path in str(exc) else f"{path}: {exc}", option=exc.option) from None
    if channel is not None:
        raise FidelityError("channel= selects a channel of an image file; for an array, pass the 2-D array of "
                            "that channel", option="channel")
    pixels, is_integer = _edge_pixels(image)
    order, factor = _check_options(edge_fit_order, oversample)
    _warn_clipping(pixels, clip if clip is not None else _dtype_range(image))
    pixels, orientation = _orient(pixels, orientation)
    polarity = _polarity(pixels)
    fit = _locate_edge(pixels, polarity, order)
    rows = _rows_for_esf(fit, pixels.shape)
    _check_edge(pixels, fit, polarity, rows)
    _warn_angle(fit, factor)
    esf, empty = _oversampled_esf(pixels, fit, rows, factor)
    step, snr = _contrast(esf, pixels, polarity, factor, is_integer)
    dx = math.cos(math.atan(fit.slope)) / factor  # ESF spacing along the edge normal, pixels
    lsf_window = apodization(window, esf.size - 1, (esf.size - 2) / 2)  # centred on the fitted edge
    mtf = mtf_from_esf(esf, dx=dx, window=lsf_window, correct=correct)
    f, y = _up_to(mtf.x, mtf.y, max_freq)
    _check_mtf(f, y)
    meta = {"angle_deg": fit.angle_deg, "orientation": orientation, "polarity": int(polarity), "snr": snr,
            "step": step, "esf": esf, "lsf": np.diff(esf) * polarity, "esf_dx": dx,
            "edge_poly": fit.poly.convert().coef.tolist(), "edge_fit_order": order,
            "edge_residual_px": fit.residual_rms, "empty_bins": empty, "rows_used": int(rows.size)}
    return Curve(f, y, name=name or "slanted-edge MTF", x_unit="cy/px", y_unit="1", meta=meta)


# --------------------------------------------------------------------------- input
def _load_edge(path: str, channel: str | None) -> np.ndarray:
    from ..frames import load_frame  # only when a path is given

    return load_frame(path, channel=channel)


def _edge_pixels(image: Any) -> tuple[np.ndarray, bool]:
    raw = np.asarray(image)
    if raw.ndim != 2:
        raise FidelityError(f"the slanted-edge MTF needs a 2-D image (one channel), got shape {raw.shape}")
    if raw.dtype.kind not in "uif":
        raise FidelityError(f"the slanted-edge MTF needs integer or float pixels, got dtype {raw.dtype}")
    pixels = raw.astype(np.float64)
    if not np.isfinite(pixels).all():
        bad = np.argwhere(~np.isfinite(pixels))
        raise FidelityError(f"image has {len(bad)} non-finite pixels, first at (row, col) = "
                            f"({int(bad[0][0])}, {int(bad[0][1])})")
    if min(pixels.shape) < 8:
        raise FidelityError(f"edge ROI must be at least 8x8 pixels, got {pixels.shape[0]}x{pixels.shape[1]}")
    return pixels, raw.dtype.kind in "ui"


def _check_options(edge_fit_order: Any, oversample: Any) -> tuple[int, int]:
    whole = isinstance(edge_fit_order, (int, np.integer)) and not isinstance(edge_fit_order, bool)
    order = int(edge_fit_order) if whole else -1
    if not 1 <= order <= 5:
        raise FidelityError(f"edge_fit_order must be an integer 1..5, got {edge_fit_order!r}")
    whole = isinstance(oversample, (int, np.integer)) and not isinstance(oversample, bool)
    factor = int(oversample) if whole else -1
    if factor < 1:
        raise FidelityError(f"oversample must be a positive integer, got {oversample!r}")
    return order, factor


def _dtype_range(image: Any) -> tuple[float, float] | None:
    dtype = np.asarray(image).dtype
    if dtype.kind in "ui":
        info = np.iinfo(dtype)
        return float(info.min), float(info.max)
    return None


def _warn_clipping(pixels: np.ndarray, clip: tuple[float, float] | None) -> None:
    if clip is None:
        return
    lo, hi = (float(v) for v in clip)
    n_clipped = int(((pixels <= lo) | (pixels >= hi)).sum())
    if n_clipped >= 0.001 * pixels.size:
        _warn(f"{n_clipped} of {pixels.size} pixels ({n_clipped / pixels.size:.1%}) are clipped at {lo:g} "
              f"or {hi:g}: the ESF plateaus are distorted and the MTF is biased")


# --------------------------------------------------------------------------- 1. orient
def _side_width(shape: tuple[int, ...]) -> int:
    return max(1, min(shape) // 8)


def _orient(pixels: np.ndarray, orientation: str) -> tuple[np.ndarray, str]:
    """The ROI with the edge along the columns (intensity changing along each row)."""
    k = _side_width(pixels.shape)
    if orientation == "auto":
        across_columns = abs(pixels[:, :k].mean() - pixels[:, -k:].mean())
        across_rows = abs(pixels[:k, :].mean() - pixels[-k:, :].mean())
        orientation = "vertical" if across_columns >= across_rows else "horizontal"
    if orientation == "horizontal":
        return pixels.T, orientation
    if orientation != "vertical":
        raise FidelityError(f"orientation must be auto, vertical or horizontal, got {orientation!r}")
    return pixels, orientation


def _polarity(pixels: np.ndarray) -> float:
    """+1 for dark-to-bright along the rows, -1 for bright-to-dark."""
    k = _side_width(pixels.shape)
    step = pixels[:, -k:].mean() - pixels[:, :k].mean()
    if step == 0:
        raise FidelityError("no edge found: both sides of the ROI have the same mean level")
    return 1.0 if step > 0 else -1.0


# --------------------------------------------------------------------------- 2. locate the edge
def _hamming_rows(width: int, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sample positions of a row derivative (between pixels) and, per row, a Hamming window as
    wide as the row centred at ``centres``."""
    positions = np.arange(width) + 0.5  # a two-tap difference sits between its two pixels
    t = (positions[None, :] - centres[:, None]) / width
    return positions, np.where(np.abs(t) <= 0.5, 0.54 + 0.46 * np.cos(2 * np.pi * t), 0.0)


def _row_centroids(derivative: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Per row, the centroid of the derivative under the window centred at ``centres``; NaN
    where the windowed derivative has no positive sum."""
    positions, window = _hamming_rows(derivative.shape[1], centres)
    weighted = derivative * window
    total = weighted.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, (weighted * positions).sum(axis=1) / total, np.nan)


def _noise_scatter(derivative: np.ndarray, centres: np.ndarray, noise: float) -> float:
    """RMS scatter of the row centroids that pixel noise ``noise`` alone would cause.

    A row's centroid is ``c + Σ g_i d_i / Σ w_i d_i`` with ``g_i = w_i (x_i - c)``; as
    ``d_i = p_{i+1} - p_i``, the noise of the pixels enters through the differences of ``g``:
    ``σ_row = noise · ‖Δg‖ / Σ w_i d_i``.
    """
    positions, window = _hamming_rows(derivative.shape[1], centres)
    lever = window * (positions[None, :] - centres[:, None])
    spread = np.sqrt((np.diff(np.pad(lever, ((0, 0), (1, 1))), axis=1) ** 2).sum(axis=1))
    total = (window * derivative).sum(axis=1)
    rising = total > 0
    return float(np.sqrt(np.mean((noise * spread[rising] / total[rising]) ** 2)))


def _pixel_noise(pixels: np.ndarray) -> float:
    """Robust pixel noise: the median absolute row-to-row difference, scaled to a standard
    deviation (1.4826 MAD, /√2 for a difference of two pixels)."""
    return 1.4826 * float(np.median(np.abs(np.diff(pixels, axis=0)))) / math.sqrt(2)


def _locate_edge(pixels: np.ndarray, polarity: float, order: int) -> EdgeFit:
    """Fit ``column = poly(row)`` to the rows' derivative centroids: window on the centroid of
    the mean derivative, fit, window re-centred on the fit, fit again."""
    nrows, ncols = pixels.shape
    derivative = np.diff(pixels, axis=1) * polarity
    rows = np.arange(nrows, dtype=np.float64)
    mean_rise = np.clip(derivative.mean(axis=0), 0, None)
    start = ((mean_rise * (np.arange(ncols - 1) + 0.5)).sum() / mean_rise.sum() if mean_rise.sum() > 0
             else (ncols - 1) / 2)
    centres = np.full(nrows, start)
    for _ in range(2):
        centroids = _row_centroids(derivative, centres)
        found = np.isfinite(centroids)
        if found.sum() < max(order + 2, MIN_ROWS):
            raise FidelityError(f"no edge found: only {int(found.sum())} of {nrows} rows have a derivative "
                                f"with a positive peak across the ROI")
        poly = np.polynomial.Polynomial.fit(rows[found], centroids[found], order)
        centres = poly(rows)
    slope = float(np.polynomial.polynomial.polyfit(rows[found], centroids[found], 1)[1])
    residual = float(np.sqrt(np.mean((centroids[found] - centres[found]) ** 2)))
    return EdgeFit(poly=poly, columns=centres, slope=slope, centroids=centroids, residual_rms=residual,
                   noise_rms=_noise_scatter(derivative, centres, _pixel_noise(pixels)))


# --------------------------------------------------------------------------- 3. check it is an edge
def _rows_for_esf(fit: EdgeFit, shape: tuple[int, int]) -> np.ndarray:
    """The rows the ESF is built from.

    Rows whose edge runs closer to the ROI border than 8 px (or than the median row, if that
    is closer) are left out; an edge with less than 3 px of plateau on both sides in at least
    ``MIN_ROWS`` rows is refused. Of the remaining rows a centred block spanning a whole
    number of phase cycles (the edge shifting by a whole number of pixels, as ISO 12233) is
    used, so that every sub-pixel phase is equally represented.
    """
    nrows, ncols = shape
    margin = np.minimum(fit.columns, (ncols - 1) - fit.columns)
    required = float(margin.min())
    usable = np.ones(nrows, dtype=bool)
    if required < 8:
        required = float(min(8.0, np.median(margin)))
        usable = margin >= required
    candidates = np.flatnonzero(usable)
    if required < 3 or candidates.size < MIN_ROWS:
        raise FidelityError(f"the edge runs too close to the ROI border (median margin "
                            f"{max(float(np.median(margin)), 0):.1f} px): need at least 3 px of plateau on "
                            f"both sides in at least {MIN_ROWS} rows")
    first, last = int(candidates[0]), int(candidates[-1])
    span = last - first + 1
    cycles = math.floor(span * abs(fit.slope))
    if cycles >= 1:
        span = min(span, int(round(cycles / abs(fit.slope))))
    start = first + (last - first + 1 - span) // 2
    rows = np.arange(start, start + span)
    return rows[usable[rows]]


def _row_steps(pixels: np.ndarray, fit: EdgeFit, polarity: float, rows: np.ndarray) -> np.ndarray:
    """Each row's own step across the fitted edge: mean of the pixels 2..8 px beyond it minus
    the mean of those 2..8 px before it, in the edge's polarity."""
    distance = np.arange(pixels.shape[1])[None, :] - fit.columns[rows, None]
    values = pixels[rows]
    after = (distance >= 2) & (distance <= 8)
    before = (distance <= -2) & (distance >= -8)
    with np.errstate(invalid="ignore", divide="ignore"):
        step = ((values * after).sum(1) / after.sum(1) - (values * before).sum(1) / before.sum(1))
    return np.nan_to_num(step * polarity, nan=0.0)


def _check_edge(pixels: np.ndarray, fit: EdgeFit, polarity: float, rows: np.ndarray) -> None:
    """Refuse an ROI without a usable edge (thresholds in the module docstring)."""
    nrows = pixels.shape[0]
    limit = EDGE_RESIDUAL_ALLOWANCE_PX + EDGE_RESIDUAL_NOISE_FACTOR * fit.noise_rms
    if fit.residual_rms > limit:
        cause = ("no edge in the ROI, or an edge too curved for it" if fit.poly.degree() >= 5 else
                 "no edge in the ROI, or a curved edge: a fit of order 5 follows lens curvature")
        raise FidelityError(f"the edge fit does not fit: the rows' edge locations scatter by "
                            f"{fit.residual_rms:.2f} px (RMS) around the fitted edge, more than the {limit:.2f} px "
                            f"a straight or lens-curved edge leaves at this noise level ({cause})")
    steps = _row_steps(pixels, fit, polarity, rows)
    typical = float(np.median(steps))
    crossing = int((steps > 0.5 * typical).sum()) if typical > 0 else 0
    if crossing < MIN_CROSSING_FRACTION * rows.size:
        raise FidelityError(f"no edge found: only {crossing} of {rows.size} rows cross the fitted edge with "
                            f"at least half the typical step (need {MIN_CROSSING_FRACTION:.0%})")
    shift = abs(fit.slope) * nrows
    if shift < 1:
        raise FidelityError(f"edge angle {fit.angle_deg:.2f}° is outside the usable range: the edge shifts by "
                            f"{shift:.2f} px over {nrows} rows, less than the one pixel needed for every "
                            f"sub-pixel phase (tilt the edge ~5° from the pixel grid)")
    if abs(fit.angle_deg) > 45:
        raise FidelityError(f"edge angle {fit.angle_deg:.1f}° is outside the usable range (at most 45° from "
                            f"the axis the ROI is read along): choose the other orientation")


def _warn_angle(fit: EdgeFit, factor: int) -> None:
    angle = fit.angle_deg
    size = abs(angle)
    if size < 1.5:
        _warn(f"edge angle {angle:.2f}° is nearly aligned with the pixel grid (ISO 12233 asks for ~5°): "
              f"few sub-pixel phases")
    elif size > 35:
        _warn(f"edge angle {angle:.2f}° is near 45°: the phases repeat and the pixel footprint along "
              f"the normal widens; tilt the edge ~5° from the grid")
    for critical in CRITICAL_ANGLES:
        if abs(size - critical) < 0.5:
            _warn(f"edge angle {angle:.2f}° is within 0.5° of the critical angle {critical:.2f}° at which "
                  f"the {factor}x oversampling phases repeat")


# --------------------------------------------------------------------------- 4. oversampled ESF
def _oversampled_esf(pixels: np.ndarray, fit: EdgeFit, rows: np.ndarray, factor: int) -> tuple[np.ndarray, int]:
    """Mean pixel value per bin of ``1/factor`` px of horizontal distance to the fitted edge.

    The bins are centred on whole multiples of ``1/factor`` (so that mirroring the ROI mirrors
    the ESF) and span the whole ROI: ±(the farthest any used row reaches on either side). Empty
    bins are filled by linear interpolation, or beyond the outermost filled bin by its value
    (the plateau); empty bins within the distances every row covers mean too few sub-pixel
    phases and are counted, with a warning.
    """
    distance = np.arange(pixels.shape[1])[None, :] - fit.columns[rows, None]
    bins = np.rint(distance * factor).astype(np.int64)
    reach = int(max(-bins.min(), bins.max()))
    index = bins + reach
    nbins = 2 * reach + 1
    counts = np.bincount(index.ravel(), minlength=nbins)
    sums = np.bincount(index.ravel(), weights=pixels[rows].ravel(), minlength=nbins)
    filled = np.flatnonzero(counts)
    esf = np.interp(np.arange(nbins), filled, sums[filled] / counts[filled])
    covered_by_all = slice(int(index.min(axis=1).max()), int(index.max(axis=1).min()) + 1)
    gaps = int((counts[covered_by_all] == 0).sum())
    if gaps:
        _warn(f"{gaps} of {nbins} ESF bins received no pixel (too few sub-pixel phases); "
              f"filled by interpolation")
    return esf, gaps


# --------------------------------------------------------------------------- 5. contrast
def _contrast(esf: np.ndarray, pixels: np.ndarray, polarity: float, factor: int,
              is_integer: bool) -> tuple[float, float]:
    """Edge step (plateau difference of the ESF) and its ratio to the pixel noise (robust
    estimate from row-to-row differences); warns when the contrast is low."""
    plateau = max(factor, esf.size // 8)
    low, high = esf[:plateau].mean(), esf[-plateau:].mean()
    step = float((high - low) * polarity)
    if step <= 0:
        raise FidelityError("no edge found: the ESF does not rise across the fitted edge")
    level = (esf - low) / (high - low)
    ramp = float(((level > 0.1) & (level < 0.9)).mean())
    if ramp > MAX_RAMP_FRACTION:
        raise FidelityError(f"no edge found: {ramp:.0%} of the edge profile lies between 10 % and 90 % of the "
                            f"step, a gradient across the ROI rather than an edge between two plateaus")
    noise = _pixel_noise(pixels)
    snr = step / noise if noise > 0 else math.inf
    if snr < MIN_SNR:
        raise FidelityError(f"no usable edge: the edge step {step:.4g} is only {snr:.1f}x the pixel noise "
                            f"{noise:.3g} (at least {MIN_SNR} needed; below that the MTF is noise)")
    if snr < 20:
        _warn(f"low contrast: edge step {step:.4g} is only {snr:.1f}x the pixel noise {noise:.3g}")
    elif is_integer and step < 20:
        _warn(f"low contrast: edge step of {step:.3g} grey levels; quantisation dominates")
    return step, snr


# --------------------------------------------------------------------------- 6. MTF
def _check_mtf(f: np.ndarray, y: np.ndarray) -> None:
    """Refuse an MTF above ``MTF_LIMIT`` up to the Nyquist frequency (0.5 cy/px). Beyond it the
    e-SFR is aliasing and noise, with a spike at the sampling frequency (1 cy/px) wherever the
    sub-pixel phases are unevenly covered; a camera property cannot be read there."""
    below_nyquist = f <= 0.5
    if (y[below_nyquist] > MTF_LIMIT).any():
        i = int(np.argmax(np.where(below_nyquist, y, -np.inf)))
        raise FidelityError(f"no usable edge: the MTF reaches {y[i]:.2f} at {f[i]:.3g} cy/px, above "
                            f"{MTF_LIMIT} (the most sharpening lifts a camera's MTF); the ROI holds noise "
                            f"or a scene, not one edge")


def _up_to(f: np.ndarray, y: np.ndarray, max_freq: float | None) -> tuple[np.ndarray, np.ndarray]:
    if max_freq is None:
        return f, y
    limit = float(max_freq)
    if not limit > 0:
        raise FidelityError(f"max_freq must be > 0 or None, got {max_freq!r}")
    n_keep = int(np.searchsorted(f, limit * (1 - 1e-12))) + 1
    return f[:n_keep], y[:n_keep]
