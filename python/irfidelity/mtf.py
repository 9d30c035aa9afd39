"""MTF curves: from a line or edge spread function, the paper's "middle spatial
frequency" MTF50 (Fig. 1, with its optional sixth-order smoothing) and the MTF component
f1 = :func:`mtf_similarity` (eqs. 1-4 with a, b = MTF50).

The slanted-edge MTF (ISO 12233 e-SFR) is in :mod:`irfidelity.edge`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .curves import CY_PX, Curve, CurveSimilarity, _as_curve, curve_similarity
from .errors import FidelityError

__all__ = ["mtf_from_lsf", "mtf_from_esf", "mtf50", "mtf_similarity"]


def _window(kind: Any, n: int, center: float) -> np.ndarray:
    """Window of ``n`` samples whose symmetry centre is at sample position ``center``.

    ``kind``: None/"none", "hamming", "hann", "tukey" (alpha 0.5) or an array of n weights.
    The width is the full record, so the window reaches its minimum at ``center +- n/2``.
    """
    if kind is None or (isinstance(kind, str) and kind.lower() in ("none", "rect", "boxcar")):
        return np.ones(n)
    if not isinstance(kind, str):
        w = np.asarray(kind, dtype=np.float64)
        if w.shape != (n,) or not np.isfinite(w).all():
            raise FidelityError(f"window array must be finite with shape ({n},), got {w.shape}")
        return w
    t = (np.arange(n) - center) / n  # in [-1, 1]; |t| <= 1/2 inside the window
    inside = np.abs(t) <= 0.5
    k = kind.lower()
    if k == "hamming":
        w = 0.54 + 0.46 * np.cos(2 * np.pi * t)
    elif k in ("hann", "hanning"):
        w = 0.5 + 0.5 * np.cos(2 * np.pi * t)
    elif k == "tukey":
        a = 0.5
        u = np.abs(t) * 2  # 0 at centre, 1 at the edge of the window
        w = np.where(u <= 1 - a, 1.0, 0.5 * (1 + np.cos(np.pi * (u - 1 + a) / a)))
    else:
        raise FidelityError(f"window must be None, 'hamming', 'hann', 'tukey' or an array, got {kind!r}")
    return np.where(inside, w, 0.0)


def _centroid(v: np.ndarray) -> float:
    a = np.abs(v)
    s = a.sum()
    return float((a * np.arange(v.size)).sum() / s) if s > 0 else (v.size - 1) / 2


def _check_dx(dx: float) -> float:
    d = float(dx)
    if not (math.isfinite(d) and d > 0):
        raise FidelityError(f"dx must be finite and > 0, got {dx!r}")
    return d


def mtf_from_lsf(lsf: Any, *, dx: float = 1.0, pad: int | None = None, window: Any = None,
                 name: str | None = None, x_unit: str | None = None) -> Curve:
    """MTF as the normalised modulus of the DFT of a line spread function (paper §1.1).

    ``MTF(f_k) = |DFT(w·lsf)|_k / |DFT(w·lsf)|_0`` at ``f_k = k / (N·dx)``,
    ``k = 0 .. N//2`` (up to the Nyquist frequency ``1/(2 dx)``).

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
        Apodisation centred on the LSF centroid (ISO 12233 uses Hamming).

    Returns
    -------
    Curve
        ``x`` = frequency, ``y`` = MTF with ``y[0] == 1``; unit ``"cy/px"`` when
        ``dx == 1`` unless ``x_unit`` says otherwise.

    Raises
    ------
    FidelityError
        Non-finite samples, too few samples, or an LSF whose sum is zero (no
        zero-frequency response to normalise by).
    """
    v = np.asarray(lsf, dtype=np.float64)
    if v.ndim != 1 or v.size < 3:
        raise FidelityError(f"lsf must be 1-D with at least 3 samples, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise FidelityError(f"lsf has {int((~np.isfinite(v)).sum())} non-finite samples")
    d = _check_dx(dx)
    w = v * _window(window, v.size, _centroid(v))
    n = v.size if pad is None else int(pad)
    if n < v.size:
        raise FidelityError(f"pad must be >= len(lsf) = {v.size}, got {pad!r}")
    spec = np.abs(np.fft.rfft(w, n=n))
    if not spec[0] > 0:
        raise FidelityError("lsf sums to zero: the MTF cannot be normalised at zero frequency")
    f = np.arange(spec.size) / (n * d)
    if x_unit is None and d == 1.0:
        x_unit = CY_PX
    return Curve(f, spec / spec[0], name=name or "MTF", x_unit=x_unit)


def _diff_correction(f: np.ndarray, dx: float, cap: float) -> np.ndarray:
    """1 / |H(f)| of the two-tap derivative [1, -1]/dx, H = sinc(f·dx), capped at ``cap``."""
    h = np.abs(np.sinc(f * dx))
    with np.errstate(divide="ignore"):
        c = np.where(h > 0, 1.0 / np.maximum(h, 1e-300), np.inf)
    return np.minimum(c, cap)


def mtf_from_esf(esf: Any, *, dx: float = 1.0, pad: int | None = None, window: Any = None,
                 correct: bool = True, max_correction: float = 10.0, name: str | None = None,
                 x_unit: str | None = None) -> Curve:
    """MTF from an edge spread function: derivative -> LSF -> :func:`mtf_from_lsf`.

    The LSF is the first difference ``esf[i+1] - esf[i]`` (ISO 12233's two-tap
    derivative). Its transfer function ``sinc(f·dx)`` is divided out when
    ``correct`` is true, the correction factor capped at ``max_correction`` (it is at
    most pi/2 up to Nyquist, so the cap only matters for padded grids).

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
        Upper bound of the correction factor (>= 1).
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
    y = c.y * _diff_correction(c.x, _check_dx(dx), cap)
    return Curve(c.x, y, name=c.name, x_unit=c.x_unit)


# --------------------------------------------------------------------------- MTF50
def _smooth_poly(curve: Curve, degree: int = 6):
    """Least-squares polynomial of ``degree`` with p(0) = 1, in a Chebyshev basis on [0, x_max].

    Returns a callable. The constraint is built in: p(x) = 1 + (x/x_max)·q(x), q of
    degree ``degree - 1``.
    """
    x, y = curve.x, curve.y
    if x[0] < 0:
        raise FidelityError("smooth=True needs frequencies >= 0")
    if x.size < degree + 1:
        raise FidelityError(f"smooth=True fits a degree-{degree} polynomial and needs at least "
                            f"{degree + 1} points, the curve has {x.size}")
    xm = x[-1]
    t = 2 * x / xm - 1  # Chebyshev domain [-1, 1] for [0, x_max]
    u = x / xm
    basis = np.polynomial.chebyshev.chebvander(t, degree - 1) * u[:, None]
    coef, *_ = np.linalg.lstsq(basis, y - 1.0, rcond=None)

    def p(xq: np.ndarray) -> np.ndarray:
        xq = np.asarray(xq, dtype=np.float64)
        return 1.0 + (xq / xm) * np.polynomial.chebyshev.chebval(2 * xq / xm - 1, coef)

    return p


def mtf50(curve: Any, *, smooth: bool = False, level: float = 0.5) -> float:
    """The paper's "middle spatial frequency": where the MTF first falls to 0.5 (§1.1, Fig. 1).

    Found by linear interpolation between the last sample above ``level`` and the
    first at or below it. With ``smooth=True`` the paper's sixth-order polynomial
    fit is applied first (least squares in a Chebyshev basis on ``[0, f_max]``,
    constrained to MTF(0) = 1) and its first crossing is located on the curve's own
    frequency range (never extrapolated).

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
        If the MTF never falls to ``level`` within the curve's range, or is already
        below it at the first frequency. No frequency is invented.
    """
    c = _as_curve(curve, "MTF curve")
    lv = float(level)
    if not 0 < lv < 1:
        raise FidelityError(f"level must be in (0, 1), got {level!r}")
    x = c.x
    if smooth:
        p = _smooth_poly(c)
        xs = np.linspace(x[0], x[-1], max(4096, 8 * x.size))
        ys = p(xs)
        i = _first_crossing(xs, ys, lv, c)
        # refine by bisection on the polynomial (monotone bracket [xs[i-1], xs[i]])
        lo, hi = xs[i - 1], xs[i]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if p(mid) > lv:
                lo = mid
            else:
                hi = mid
        return float(0.5 * (lo + hi))
    y = c.y
    i = _first_crossing(x, y, lv, c)
    if i == 0:
        return float(x[0])
    x0, x1, y0, y1 = x[i - 1], x[i], y[i - 1], y[i]
    return float(x0 + (y0 - lv) * (x1 - x0) / (y0 - y1))


def _first_crossing(x: np.ndarray, y: np.ndarray, lv: float, c: Curve) -> int:
    below = y <= lv
    if not below.any():
        raise FidelityError(
            f"MTF never falls to {lv:g} within its range {x[0]:g}..{x[-1]:g} "
            f"(minimum {y.min():.4g}); the middle spatial frequency is undefined for this curve"
            + (f" ({c.name})" if c.name else ""))
    i = int(np.argmax(below))
    if i == 0 and y[0] < lv:
        raise FidelityError(f"MTF is already {y[0]:.4g} < {lv:g} at the first frequency {x[0]:g}; "
                            f"the crossing lies outside the curve's range")
    return i


# --------------------------------------------------------------------------- similarity
def mtf_similarity(real: Any, sim: Any, *, smooth: bool = False, points: Any = 64,
                   alpha: float = 1.0, beta: float = 1.0) -> CurveSimilarity:
    """Component f1: :func:`curve_similarity` of two MTF curves with ``a, b`` = their MTF50.

    The paper (§1.2) replaces the means of eq. (4) by each curve's middle spatial
    frequency (:func:`mtf50`, optionally on the sixth-order polynomial smoothing).

    Raises
    ------
    FidelityError
        If either MTF never falls to 0.5 (its MTF50 is undefined), or see
        :func:`curve_similarity`.
    """
    r_c, s_c = _as_curve(real, "real MTF"), _as_curve(sim, "simulated MTF")
    try:
        a = mtf50(r_c, smooth=smooth)
    except FidelityError as exc:
        raise FidelityError(f"real MTF: {exc}") from None
    try:
        b = mtf50(s_c, smooth=smooth)
    except FidelityError as exc:
        raise FidelityError(f"simulated MTF: {exc}") from None
    return curve_similarity(r_c, s_c, a=a, b=b, points=points, alpha=alpha, beta=beta)
