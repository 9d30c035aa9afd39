"""MTF curves: from a line or edge spread function, the paper's "middle spatial frequency"
MTF50 (Fig. 1, with its optional sixth-order smoothing) and the MTF component
f1 = :func:`mtf_similarity` (eqs. 1-4 with a, b = MTF50).

The slanted-edge MTF (ISO 12233 e-SFR) is in :mod:`irfidelity.curves.edge`.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..errors import FidelityError
from .curve import Curve, as_curve
from .similarity import CurveSimilarity, align_units, similarity_of
from .units import CameraGeometry, convert

__all__ = ["mtf_from_lsf", "mtf_from_esf", "mtf50", "mtf_similarity", "apodization"]

#: the derivative's transfer function is divided out up to this factor (as ISO 12233's sfrmat)
MAX_DERIVATIVE_CORRECTION = 10.0


def apodization(kind: Any, n: int, centre: float) -> np.ndarray:
    """Window of ``n`` samples, symmetric about sample position ``centre``, as wide as the record.

    ``kind``: None/"none" (rectangular), "hamming" ``0.54 + 0.46 cos 2πt``, "hann"
    ``0.5 + 0.5 cos 2πt``, "tukey" (flat top, cosine tapers over the outer half, α = 0.5) with
    ``t = (i - centre) / n``; zero for ``|t| > 1/2``. An array of ``n`` finite weights is used
    as given.

    Examples
    --------
    >>> apodization("hann", 4, 2.0).tolist()
    [0.0, 0.5, 1.0, 0.5]
    """
    if kind is None or (isinstance(kind, str) and kind.lower() in ("none", "rect", "boxcar")):
        return np.ones(n)
    if not isinstance(kind, str):
        w = np.asarray(kind, dtype=np.float64)
        if w.shape != (n,) or not np.isfinite(w).all():
            raise FidelityError(f"window array must be finite with shape ({n},), got {w.shape}")
        return w
    t = (np.arange(n) - centre) / n
    inside = np.abs(t) <= 0.5
    k = kind.lower()
    if k == "hamming":
        w = 0.54 + 0.46 * np.cos(2 * np.pi * t)
    elif k in ("hann", "hanning"):
        w = 0.5 + 0.5 * np.cos(2 * np.pi * t)
    elif k == "tukey":
        taper = 0.5
        u = np.abs(t) * 2  # 0 at the centre, 1 at the window's ends
        w = np.where(u <= 1 - taper, 1.0, 0.5 * (1 + np.cos(np.pi * (u - 1 + taper) / taper)))
    else:
        raise FidelityError(f"window must be none, hamming, hann, tukey or an array, got {kind!r}")
    return np.where(inside, w, 0.0)


def _peak(v: np.ndarray) -> float:
    """Position of the largest ``|v|`` (the mean position if it occurs more than once)."""
    magnitude = np.abs(v)
    return float(np.flatnonzero(magnitude == magnitude.max()).mean())


def _positive_spacing(dx: float) -> float:
    d = float(dx)
    if not (math.isfinite(d) and d > 0):
        raise FidelityError(f"dx must be finite and > 0, got {dx!r}")
    return d


def mtf_from_lsf(lsf: Any, *, dx: float = 1.0, pad: int | None = None, window: Any = None,
                 name: str | None = None, x_unit: str | None = None) -> Curve:
    """MTF as the normalised modulus of the DFT of a line spread function (paper §1.1).

    .. math::

        \\mathrm{MTF}(f_k) = \\frac{|\\mathrm{DFT}(w \\cdot \\mathrm{lsf})_k|}
                                  {|\\mathrm{DFT}(w \\cdot \\mathrm{lsf})_0|},
        \\qquad f_k = \\frac{k}{N\\,dx},\\; k = 0 \\ldots \\lfloor N/2 \\rfloor

    (up to the Nyquist frequency ``1/(2 dx)``), ``w`` the window centred on the LSF.

    Parameters
    ----------
    lsf : array_like
        1-D LSF samples (at least 3, finite) with spacing ``dx``.
    dx : float
        Sample spacing; frequencies come out in cycles per unit of ``dx``
        (``dx = 1`` -> cycles/pixel).
    pad : int, optional
        Zero-pad to this total length ``N`` (>= len(lsf)) for a finer frequency grid.
    window : None | "hamming" | "hann" | "tukey" | array
        Apodisation (:func:`apodization`) centred on the LSF peak, as ISO 12233 (which uses
        Hamming in its 2014 edition, a Tukey window in sfrmat5).
    name, x_unit : str, optional
        Label and frequency unit of the result.

    Returns
    -------
    Curve
        ``x`` = frequency, ``y`` = MTF with ``y[0] == 1`` (``y_unit="1"``); ``x_unit="cy/px"``
        when ``dx == 1`` unless ``x_unit`` says otherwise.

    Raises
    ------
    FidelityError
        Non-finite samples, too few samples, or an LSF whose sum is zero (no zero-frequency
        response to normalise by).

    References
    ----------
    .. [1] Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547, §1.1.
    .. [2] ISO 12233:2023, Photography — Electronic still picture imaging — Resolution and
       spatial frequency responses, Annex D (e-SFR).

    Examples
    --------
    >>> c = mtf_from_lsf([0.25, 0.5, 0.25], pad=8)  # a [1, 2, 1]/4 blur: MTF = cos²(πf)
    >>> c.x.tolist(), c.y.round(4).tolist()
    ([0.0, 0.125, 0.25, 0.375, 0.5], [1.0, 0.8536, 0.5, 0.1464, 0.0])
    """
    v = np.asarray(lsf, dtype=np.float64)
    if v.ndim != 1 or v.size < 3:
        raise FidelityError(f"lsf must be 1-D with at least 3 samples, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise FidelityError(f"lsf has {int((~np.isfinite(v)).sum())} non-finite samples")
    d = _positive_spacing(dx)
    n = v.size if pad is None else int(pad)
    if n < v.size:
        raise FidelityError(f"pad must be >= len(lsf) = {v.size}, got {pad!r}")
    spectrum = np.abs(np.fft.rfft(v * apodization(window, v.size, _peak(v)), n=n))
    if not spectrum[0] > 0:
        raise FidelityError("lsf sums to zero: the MTF cannot be normalised at zero frequency")
    f = np.arange(spectrum.size) / (n * d)
    if x_unit is None and d == 1.0:
        x_unit = "cy/px"
    return Curve(f, spectrum / spectrum[0], name=name or "MTF", x_unit=x_unit, y_unit="1")


def derivative_correction(f: np.ndarray, dx: float, cap: float = MAX_DERIVATIVE_CORRECTION) -> np.ndarray:
    """``1 / |H(f)|`` of the two-tap derivative ``[1, -1]/dx``, ``H = sinc(f·dx)``, capped at ``cap``."""
    h = np.abs(np.sinc(f * dx))
    with np.errstate(divide="ignore"):
        c = np.where(h > 0, 1.0 / np.maximum(h, 1e-300), np.inf)
    return np.minimum(c, cap)


def mtf_from_esf(esf: Any, *, dx: float = 1.0, pad: int | None = None, window: Any = None,
                 correct: bool = True, max_correction: float = MAX_DERIVATIVE_CORRECTION,
                 name: str | None = None, x_unit: str | None = None) -> Curve:
    """MTF from an edge spread function: derivative -> LSF -> :func:`mtf_from_lsf`.

    The LSF is the first difference ``esf[i+1] - esf[i]``; its transfer function
    ``sinc(f·dx)`` is divided out when ``correct`` is true:

    .. math::

        \\mathrm{MTF}(f) = \\frac{|\\mathrm{DFT}(w \\cdot \\Delta \\mathrm{esf})(f)|}
                                {|\\mathrm{DFT}(w \\cdot \\Delta \\mathrm{esf})(0)|}
                           \\cdot \\min\\!\\left(\\frac{1}{|\\mathrm{sinc}(f\\,dx)|}, c_{max}\\right)

    (the factor is at most π/2 up to Nyquist, so the cap only matters for padded grids).
    Either edge polarity is accepted (a falling ESF gives the same MTF).

    Parameters
    ----------
    esf : array_like
        1-D ESF samples (at least 4) with spacing ``dx``.
    dx, pad, window, name, x_unit
        As in :func:`mtf_from_lsf` (``pad`` refers to the LSF length).
    correct : bool
        Divide out the derivative's transfer function.
    max_correction : float
        Upper bound ``c_max`` of the correction factor (>= 1).

    References
    ----------
    .. [1] ISO 12233:2023, Annex D; P. D. Burns, "Slanted-edge MTF for digital camera and
       scanner analysis", Proc. IS&T PICS (2000) 135-138.

    Examples
    --------
    >>> c = mtf_from_esf([0, 0, 0.25, 0.75, 1, 1], correct=False)  # LSF [0, .25, .5, .25, 0]
    >>> c.y.round(4).tolist()
    [1.0, 0.6545, 0.0955]
    """
    v = np.asarray(esf, dtype=np.float64)
    if v.ndim != 1 or v.size < 4:
        raise FidelityError(f"esf must be 1-D with at least 4 samples, got shape {v.shape}")
    cap = float(max_correction)
    if not (cap >= 1):
        raise FidelityError(f"max_correction must be >= 1, got {max_correction!r}")
    lsf = np.diff(v)
    if lsf.sum() < 0:
        lsf = -lsf
    c = mtf_from_lsf(lsf, dx=dx, pad=pad, window=window, name=name, x_unit=x_unit)
    if not correct:
        return c
    return c.replace(y=c.y * derivative_correction(c.x, _positive_spacing(dx), cap))


# --------------------------------------------------------------------------- MTF50
def _smoothing_polynomial(curve: Curve, degree: int = 6) -> Callable[[Any], np.ndarray]:
    """Least-squares polynomial of ``degree`` with p(0) = 1, in a Chebyshev basis on [0, x_max].

    The constraint is built in: p(x) = 1 + (x/x_max)·q(x), q of degree ``degree - 1``.
    """
    x, y = curve.x, curve.y
    if x[0] < 0:
        raise FidelityError("the smoothed MTF50 needs frequencies >= 0")
    if x.size < degree + 1:
        raise FidelityError(f"the smoothed MTF50 fits a degree-{degree} polynomial and needs at least "
                            f"{degree + 1} points, the curve has {x.size}")
    x_max = x[-1]
    basis = np.polynomial.chebyshev.chebvander(2 * x / x_max - 1, degree - 1) * (x / x_max)[:, None]
    coef, *_ = np.linalg.lstsq(basis, y - 1.0, rcond=None)

    def p(xq: Any) -> np.ndarray:
        xq = np.asarray(xq, dtype=np.float64)
        return 1.0 + (xq / x_max) * np.polynomial.chebyshev.chebval(2 * xq / x_max - 1, coef)

    return p


def mtf50(curve: Any, *, smooth: bool = False, level: float = 0.5) -> float:
    """The paper's "middle spatial frequency": where the MTF first falls to 0.5 (§1.1, Fig. 1).

    Found by linear interpolation between the last sample above ``level`` and the first at or
    below it:

    .. math::

        f_{50} = f_{i-1} + (f_i - f_{i-1}) \\frac{M_{i-1} - 0.5}{M_{i-1} - M_i}

    With ``smooth=True`` the paper's sixth-order polynomial fit is applied first (least squares
    in a Chebyshev basis on ``[0, f_max]``, constrained to MTF(0) = 1) and its first crossing is
    located on the curve's own frequency range (never extrapolated).

    Parameters
    ----------
    curve : Curve or (x, y)
        MTF normalised to 1 at zero frequency.
    smooth : bool
        Use the sixth-order polynomial fit.
    level : float
        Crossing level in (0, 1); 0.5 gives MTF50.

    Returns
    -------
    float
        Frequency in the curve's x unit.

    Raises
    ------
    FidelityError (a ValueError)
        If the MTF never falls to ``level`` within the curve's range, or is already below it
        at the first frequency. No frequency is invented.

    References
    ----------
    .. [1] Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547, §1.1 and Fig. 1.

    Examples
    --------
    >>> mtf50(([0, 0.1, 0.2, 0.3], [1.0, 0.7, 0.4, 0.2]))  # between 0.1 and 0.2
    0.16666666666666669
    """
    c = as_curve(curve, "MTF curve")
    lv = float(level)
    if not 0 < lv < 1:
        raise FidelityError(f"level must be in (0, 1), got {level!r}")
    if smooth:
        return _smoothed_crossing(c, lv)
    x, y = c.x, c.y
    i = _first_crossing(x, y, lv, c)
    if i == 0:
        return float(x[0])
    x0, x1, y0, y1 = x[i - 1], x[i], y[i - 1], y[i]
    return float(x0 + (y0 - lv) * (x1 - x0) / (y0 - y1))


def _smoothed_crossing(c: Curve, level: float) -> float:
    p = _smoothing_polynomial(c)
    xs = np.linspace(c.x[0], c.x[-1], max(4096, 8 * c.x.size))
    i = _first_crossing(xs, p(xs), level, c)
    # refine by bisection on the polynomial (monotone bracket [xs[i-1], xs[i]])
    lo, hi = xs[i - 1], xs[i]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if p(mid) > level:
            lo = mid
        else:
            hi = mid
    return float(0.5 * (lo + hi))


def _first_crossing(x: np.ndarray, y: np.ndarray, level: float, c: Curve) -> int:
    below = y <= level
    if not below.any():
        raise FidelityError(
            f"MTF never falls to {level:g} within its range {x[0]:g}..{x[-1]:g} "
            f"(minimum {y.min():.4g}); the middle spatial frequency is undefined for this curve"
            + (f" ({c.name})" if c.name else ""))
    i = int(np.argmax(below))
    if i == 0 and y[0] < level:
        raise FidelityError(f"MTF is already {y[0]:.4g} < {level:g} at the first frequency {x[0]:g}; "
                            f"the crossing lies outside the curve's range")
    return i


# --------------------------------------------------------------------------- similarity
def _as_ratio(c: Curve) -> Curve:
    """An MTF's modulation as a ratio: unknown is taken as ratio (an MTF is normalised), % converts."""
    if c.y_unit is None:
        return c.with_units(y_unit="1")
    if c.y_unit == "%":
        return c.replace(y=convert(c.y, "%", "1"), y_unit="1")
    return c


def mtf_similarity(real: Any, sim: Any, *, smooth: bool = False, points: Any = 64,
                   alpha: float = 1.0, beta: float = 1.0, camera: CameraGeometry | None = None) -> CurveSimilarity:
    """Component f1: :func:`~irfidelity.curves.curve_similarity` of two MTF curves with
    ``a, b`` = their MTF50.

    The paper (§1.2) replaces the means of eq. (4) by each curve's middle spatial frequency
    (:func:`mtf50`, optionally on the sixth-order polynomial smoothing):
    ``f1 = μ(MTF50_real, MTF50_sim)^α · |ρ|^β``.

    The frequency axes must be in the same unit or be converted: a simulated curve in another
    unit (cy/px, cy/mrad, lp/mm) is converted to the real curve's unit with the ``camera``
    constants; a unit known on one side only is an error; unknown on both is allowed, with a
    :class:`~irfidelity.curves.units.CurveUnitsWarning` and the note "units unknown". An MTF's
    modulation is a ratio (a curve in % is divided by 100).

    Parameters
    ----------
    real, sim : Curve or (x, y)
    smooth : bool
        MTF50 from the sixth-order polynomial smoothing.
    points, alpha, beta
        As in :func:`~irfidelity.curves.curve_similarity`.
    camera : CameraGeometry, optional
        Camera constants for frequency conversions (``--ifov``, ``--pixel-pitch``,
        ``--focal-length`` on the command line).

    Returns
    -------
    CurveSimilarity
        ``a``, ``b`` = the MTF50s in the real curve's frequency unit (``x_unit``).

    Raises
    ------
    FidelityError
        If either MTF never falls to 0.5 (its MTF50 is undefined), frequency units that are
        half-known or cannot be converted (the message names both and the constant needed),
        or see :func:`~irfidelity.curves.curve_similarity`.

    References
    ----------
    .. [1] Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547, §1.2, eqs. (1)-(4).

    Examples
    --------
    >>> f = np.linspace(0, 0.5, 51)
    >>> real = Curve(f, np.exp(-8 * f**2), x_unit="cy/px")
    >>> sim = Curve(f / 0.1, np.exp(-10 * f**2), x_unit="cy/mrad")  # IFOV 0.1 mrad
    >>> s = mtf_similarity(real, sim, camera=CameraGeometry(ifov_mrad=0.1))
    >>> round(s.a, 4), round(s.b, 4), s.x_unit, s.notes
    (0.2944, 0.2633, 'cy/px', ('simulated x axis converted from cy/mrad to cy/px with IFOV 0.1 mrad',))
    """
    r_c = _as_ratio(as_curve(real, "real MTF"))
    s_c = _as_ratio(as_curve(sim, "simulated MTF"))
    s_c, notes = align_units(r_c, s_c, camera=camera, what="MTF curves", axes=("x",),
                             examples="freq_cy_per_px, freq_cy_per_mrad, lp_mm")
    try:
        a = mtf50(r_c, smooth=smooth)
    except FidelityError as exc:
        raise FidelityError(f"real MTF: {exc}") from None
    try:
        b = mtf50(s_c, smooth=smooth)
    except FidelityError as exc:
        raise FidelityError(f"simulated MTF: {exc}") from None
    return similarity_of(r_c, s_c, a=a, b=b, points=points, alpha=alpha, beta=beta, notes=notes)
