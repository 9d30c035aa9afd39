"""SiTF: the linear portion of the signal-vs-temperature curve, NETD, and component f2
(paper §1.1, Fig. 2).

The SiTF curve of an infrared camera is a sideways "S": a floor (no signal), a
linear response, and saturation. The paper's characteristic value for the SiTF
similarity (eq. 4) is the slope of the linear portion. :func:`sitf_fit` finds it;
:func:`sitf_similarity` is component f2; :func:`netd` is the classic noise figure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import FidelityError
from .curve import Curve, as_curve
from .similarity import CurveSimilarity, finite_number, align_units, similarity_of

__all__ = ["SiTFFit", "sitf_fit", "netd", "sitf_similarity"]


@dataclass(frozen=True)
class SiTFFit:
    """Straight line fitted to the linear portion of a SiTF curve.

    Attributes
    ----------
    slope, intercept : float
        ``signal ≈ slope·x + intercept`` on the window (slope may be negative:
        inverted polarity).
    lo, hi : float
        The x window of the linear portion.
    r2 : float
        Coefficient of determination of the line on the window's points ("band"),
        or of the logistic on all points ("logistic").
    linearity_error : float
        Largest absolute deviation of the window's points from the line, as a
        fraction of the line's rise over the window, ``|slope|·(hi - lo)``.
    n : int
        Number of curve points in the window.
    method : str
        ``"band"``, ``"window"`` (explicit window) or ``"logistic"``.
    floor, ceiling : float
        Lowest and highest signal of the curve (the span the band fractions refer to).
    """

    slope: float
    intercept: float
    lo: float
    hi: float
    r2: float
    linearity_error: float
    n: int
    method: str
    floor: float
    ceiling: float

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def _least_squares_line(x: np.ndarray, y: np.ndarray) -> tuple[float, float, np.ndarray]:
    xm, ym = x.mean(), y.mean()
    dx = x - xm
    sxx = float(dx @ dx)
    slope = float(dx @ (y - ym)) / sxx
    intercept = float(ym - slope * xm)
    return slope, intercept, y - (slope * x + intercept)


def _r2(y: np.ndarray, resid: np.ndarray) -> float:
    ss_tot = float(((y - y.mean()) ** 2).sum())
    ss_res = float((resid ** 2).sum())
    if ss_tot == 0:
        return 1.0 if ss_res == 0 else 0.0
    return 1.0 - ss_res / ss_tot


def _linearity_error(resid: np.ndarray, slope: float, lo: float, hi: float) -> float:
    m = float(np.abs(resid).max()) if resid.size else 0.0
    rise = abs(slope) * (hi - lo)
    if rise == 0:
        return 0.0 if m == 0 else math.inf
    return m / rise


def _longest_run(mask: np.ndarray) -> tuple[int, int]:
    """[start, stop) of the longest run of True (first one on ties); (0, 0) if none."""
    if not mask.any():
        return 0, 0
    m = np.concatenate(([False], mask, [False])).astype(np.int8)
    d = np.diff(m)
    starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k])


def sitf_fit(curve: Any, *, lo_frac: float = 0.1, hi_frac: float = 0.9, method: str = "band",
             window: tuple[float, float] | None = None) -> SiTFFit:
    r"""Slope of the linear portion of a SiTF curve (paper §1.1, Fig. 2; used in eq. 4).

    ``method="band"`` (default): the linear portion is the longest run of consecutive points
    whose signal lies in the band

    .. math::

        y_{floor} + lo\_frac \cdot span \le y \le y_{floor} + hi\_frac \cdot span,
        \qquad span = y_{ceiling} - y_{floor}

    (floor/ceiling = lowest/highest signal); a least-squares line is fitted to those points.

    ``method="logistic"``: a four-parameter logistic ``y = A + B / (1 + exp(-(x - x0)/s))``
    is fitted to all points (Levenberg-Marquardt, numpy only); the slope is its central slope
    ``B / (4 s)`` and the window is where the logistic passes ``lo_frac`` and ``hi_frac`` of
    its span. A cross-check for the band rule.

    ``window=(lo, hi)``: fit the line to the points with ``lo <= x <= hi`` (overrides
    ``method``; used to reuse the real curve's window on the simulated one).

    Parameters
    ----------
    curve : Curve or (x, y)
        Signal (y) against temperature or temperature difference (x).
    lo_frac, hi_frac : float
        Band limits as fractions of the floor-to-ceiling span, ``0 <= lo < hi <= 1``.
    method : "band" | "logistic"
    window : (lo, hi), optional

    Returns
    -------
    SiTFFit
        Slope in y units per x unit (e.g. counts/K).

    Raises
    ------
    FidelityError (a ValueError)
        A flat curve (no response), fewer than 3 points in the band or window (no linear
        region, e.g. a curve that jumps from floor to saturation), or a logistic fit that does
        not converge.

    References
    ----------
    .. [1] Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547, §1.1, Fig. 2.

    Examples
    --------
    >>> x = np.arange(10.0)
    >>> y = np.clip(40 * (x - 2), 0, 200)  # floor, slope 40 counts/K, saturation
    >>> fit = sitf_fit(Curve(x, y))
    >>> fit.slope, fit.lo, fit.hi
    (40.0, 3.0, 6.0)
    """
    c = as_curve(curve, "SiTF curve")
    lo_f, hi_f = float(lo_frac), float(hi_frac)
    if not (0 <= lo_f < hi_f <= 1):
        raise FidelityError(f"need 0 <= lo_frac < hi_frac <= 1, got {lo_frac!r}, {hi_frac!r}")
    if window is not None:
        return _fit_window(c, window)
    floor, ceiling = float(c.y.min()), float(c.y.max())
    if ceiling == floor:
        raise FidelityError(f"SiTF curve is flat (signal {floor:g} everywhere): no linear region")
    if method == "band":
        return _fit_band(c, lo_f, hi_f)
    if method == "logistic":
        return _fit_logistic(c, lo_f, hi_f)
    raise FidelityError(f"method must be band or logistic, got {method!r}")


def _line_fit(x: np.ndarray, y: np.ndarray, lo: float, hi: float, method: str, floor: float,
              ceiling: float) -> SiTFFit:
    slope, intercept, resid = _least_squares_line(x, y)
    return SiTFFit(slope, intercept, lo, hi, _r2(y, resid), _linearity_error(resid, slope, lo, hi), int(x.size),
                   method, floor, ceiling)


def _fit_window(c: Curve, window: Any) -> SiTFFit:
    try:
        lo, hi = (float(v) for v in window)
    except (TypeError, ValueError):
        raise FidelityError(f"window must be a pair (lo, hi), got {window!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise FidelityError(f"window must be finite with lo < hi, got {window!r}")
    inside = (c.x >= lo) & (c.x <= hi)
    n = int(inside.sum())
    if n < 3:
        raise FidelityError(f"only {n} curve points lie in the window [{lo:g}, {hi:g}] "
                            f"(curve x range {c.x[0]:g}..{c.x[-1]:g}); need at least 3")
    return _line_fit(c.x[inside], c.y[inside], lo, hi, "window", float(c.y.min()), float(c.y.max()))


def _fit_band(c: Curve, lo_f: float, hi_f: float) -> SiTFFit:
    floor, ceiling = float(c.y.min()), float(c.y.max())
    span = ceiling - floor
    in_band = (c.y >= floor + lo_f * span) & (c.y <= floor + hi_f * span)
    i0, i1 = _longest_run(in_band)
    if i1 - i0 < 3:
        raise FidelityError(
            f"SiTF curve has no linear region: {i1 - i0} consecutive point(s) between "
            f"{lo_f:.0%} and {hi_f:.0%} of the floor-to-ceiling span ({floor:g}..{ceiling:g}); "
            f"need at least 3 (curve saturated, a step, or sampled too coarsely)")
    x, y = c.x[i0:i1], c.y[i0:i1]
    return _line_fit(x, y, float(x[0]), float(x[-1]), "band", floor, ceiling)


def _logistic(u: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A + B / (1 + exp(-(u - u0)/s))`` with ``p = (A, B, u0, ln s)``, and its Jacobian."""
    level, rise, centre, log_width = p
    width = math.exp(log_width)
    z = np.clip((u - centre) / width, -700, 700)
    g = 1.0 / (1.0 + np.exp(-z))
    jac = np.empty((u.size, 4))
    jac[:, 0] = 1.0
    jac[:, 1] = g
    dg = rise * g * (1 - g)
    jac[:, 2] = -dg / width
    jac[:, 3] = -dg * z
    return level + rise * g, jac


def _levenberg_marquardt(u: np.ndarray, v: np.ndarray, p: np.ndarray) -> np.ndarray | None:
    """Least-squares logistic parameters from the start ``p``; None if it does not converge."""
    damping = 1e-3
    f, jac = _logistic(u, p)
    cost = float(((f - v) ** 2).sum())
    for _ in range(500):
        jtj = jac.T @ jac
        step = np.linalg.solve(jtj + damping * np.diag(np.diag(jtj) + 1e-12), -(jac.T @ (f - v)))
        f_new, jac_new = _logistic(u, p + step)
        cost_new = float(((f_new - v) ** 2).sum())
        if cost_new <= cost:
            small = (abs(cost - cost_new) <= 1e-15 + 1e-12 * cost
                     and np.abs(step).max() < 1e-10 + 1e-8 * np.abs(p).max())
            p, f, jac, cost = p + step, f_new, jac_new, cost_new
            damping = max(damping / 3, 1e-12)
            if small:
                return p if np.isfinite(p).all() else None
        else:
            damping *= 4
            if damping > 1e12:  # no further descent possible: a minimum to machine precision
                return p if np.isfinite(p).all() else None
    return None


def _fit_logistic(c: Curve, lo_f: float, hi_f: float) -> SiTFFit:
    x, y = c.x, c.y
    if x.size < 5:
        raise FidelityError(f"the logistic fit has 4 parameters and needs at least 5 points, got {x.size}")
    floor, ceiling = float(y.min()), float(y.max())
    # fit in unit-scaled coordinates for conditioning
    x_mid, x_span = float(x.mean()), float(x[-1] - x[0])
    u, v = (x - x_mid) / x_span, (y - floor) / (ceiling - floor)
    rising = np.corrcoef(u, v)[0, 1] >= 0
    start = np.array([0.0 if rising else 1.0, 1.0 if rising else -1.0, u[int(np.argmin(np.abs(v - 0.5)))],
                      math.log(0.1)])
    p = _levenberg_marquardt(u, v, start)
    if p is None:
        raise FidelityError("the logistic fit of the SiTF curve did not converge; use the band method")
    level, rise, centre, log_width = p
    width = math.exp(log_width) * x_span
    rise, level, centre = rise * (ceiling - floor), level * (ceiling - floor) + floor, centre * x_span + x_mid
    slope = rise / (4 * width)
    intercept = level + rise / 2 - slope * centre
    z_lo = math.log(lo_f / (1 - lo_f)) if lo_f > 0 else -math.inf
    z_hi = math.log(hi_f / (1 - hi_f)) if hi_f < 1 else math.inf
    ends = sorted((centre + width * z_lo, centre + width * z_hi))
    lo, hi = max(ends[0], float(x[0])), min(ends[1], float(x[-1]))
    inside = (x >= lo) & (x <= hi)
    resid_line = y[inside] - (slope * x[inside] + intercept)
    model = _logistic(u, p)[0] * (ceiling - floor) + floor
    return SiTFFit(float(slope), float(intercept), float(lo), float(hi), _r2(y, y - model),
                   _linearity_error(resid_line, slope, lo, hi), int(inside.sum()), "logistic", floor, ceiling)


def netd(noise_rms: float, fit: SiTFFit | float) -> float:
    """Noise-equivalent temperature difference: temporal noise / |SiTF slope|.

    Parameters
    ----------
    noise_rms : float
        Temporal noise (RMS, signal units), >= 0.
    fit : SiTFFit or float
        The fitted SiTF (its slope is used) or a slope in signal units per kelvin.

    Returns
    -------
    float
        In the x unit of the SiTF curve (e.g. K): ``NETD = σ_noise / |SiTF slope|``.

    Examples
    --------
    >>> netd(12.0, 40.0)  # 12 counts RMS at 40 counts/K
    0.3
    """
    n = finite_number(noise_rms, "noise_rms", nonneg=True)
    slope = fit.slope if isinstance(fit, SiTFFit) else finite_number(fit, "slope")
    if slope == 0:
        raise FidelityError("SiTF slope is 0: the camera does not respond, NETD is undefined")
    return n / abs(slope)


def sitf_similarity(real: Any, sim: Any, *, window: Any = "real", lo_frac: float = 0.1,
                    hi_frac: float = 0.9, method: str = "band", points: Any = 64,
                    alpha: float = 1.0, beta: float = 1.0) -> CurveSimilarity:
    """Component f2: :func:`~irfidelity.curves.curve_similarity` of two SiTF curves with
    ``a, b`` = the slopes of their linear portions (paper §1.2, eq. 4).

    Units: both axes must agree or convert without further input (absolute K ↔ °C, V ↔ mV; a
    ΔT axis is the same in K and °C); the simulated curve is converted to the real curve's
    units first, then both are fitted. Half-known units, or a ΔT axis against an absolute
    temperature axis, or counts against volts, are errors naming both units; unknown on both
    sides is allowed with a :class:`~irfidelity.curves.units.CurveUnitsWarning`.

    Parameters
    ----------
    real, sim : Curve or (x, y)
    window : "real" | "each" | (lo, hi)
        ``"real"`` (default): find the linear window on the real curve (:func:`sitf_fit` with
        ``lo_frac``, ``hi_frac``, ``method``) and fit the simulated curve by least squares over
        the same (lo, hi), so both slopes refer to the same temperature range. ``"each"``: fit
        each curve on its own window. A pair: fit both on that window (in the real curve's
        x unit).
    lo_frac, hi_frac, method
        As in :func:`sitf_fit`.
    points, alpha, beta
        As in :func:`~irfidelity.curves.curve_similarity` (the shape term uses the whole
        overlap of the two curves).

    Returns
    -------
    CurveSimilarity
        ``a``, ``b`` = the slopes in the real curve's units (y unit per x unit).

    References
    ----------
    .. [1] Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547, §1.2, eqs. (1)-(4).

    Examples
    --------
    >>> t_c = np.linspace(20, 60, 41)
    >>> real = Curve(t_c, 1000 + 40 * t_c, x_unit="degC", y_unit="counts")
    >>> sim = Curve(t_c + 273.15, 1000 + 36 * t_c, x_unit="K", y_unit="counts")
    >>> s = sitf_similarity(real, sim)
    >>> round(s.a, 6), round(s.b, 6), round(s.mu, 4), s.notes
    (40.0, 36.0, 0.9945, ('simulated x axis converted from K to degC',))
    """
    r_c, s_c = as_curve(real, "real SiTF"), as_curve(sim, "simulated SiTF")
    s_c, notes = align_units(r_c, s_c, what="SiTF curves", examples="dT_K, temperature_C, counts, signal_mV")

    def fit(c: Curve, who: str, **kw: Any) -> SiTFFit:
        try:
            return sitf_fit(c, lo_frac=lo_frac, hi_frac=hi_frac, method=method, **kw)
        except FidelityError as exc:
            raise FidelityError(f"{who} SiTF: {exc}") from None

    if isinstance(window, str):
        if window == "real":
            fr = fit(r_c, "real")
            fs = fit(s_c, "simulated", window=(fr.lo, fr.hi))
        elif window == "each":
            fr, fs = fit(r_c, "real"), fit(s_c, "simulated")
        else:
            raise FidelityError(f"window must be real, each or a pair (lo, hi), got {window!r}")
    else:
        fr, fs = fit(r_c, "real", window=window), fit(s_c, "simulated", window=window)
    return similarity_of(r_c, s_c, a=fr.slope, b=fs.slope, points=points, alpha=alpha, beta=beta, notes=notes)
