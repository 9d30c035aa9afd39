"""SiTF: the linear portion of the signal-vs-ΔT curve, NETD, and component f2 (paper §1.1, Fig. 2).

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

from .curves import CurveSimilarity, _as_curve, _finite, curve_similarity
from .errors import FidelityError

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


def _line(x: np.ndarray, y: np.ndarray) -> tuple[float, float, np.ndarray]:
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


def _lin_err(resid: np.ndarray, slope: float, lo: float, hi: float) -> float:
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
    """Slope of the linear portion of a SiTF curve (paper §1.1, Fig. 2; used in eq. 4).

    ``method="band"`` (default): the linear portion is the longest run of consecutive
    points whose signal lies between ``floor + lo_frac·span`` and
    ``floor + hi_frac·span`` (floor/ceiling = lowest/highest signal, span = their
    difference); a least-squares line is fitted to those points.

    ``method="logistic"``: a four-parameter logistic
    ``y = A + B / (1 + exp(-(x - x0)/s))`` is fitted to all points (Levenberg-Marquardt,
    numpy only); the slope is its central slope ``B / (4 s)`` and the window is where
    the logistic passes ``lo_frac`` and ``hi_frac`` of its span. A cross-check for the
    band rule.

    ``window=(lo, hi)``: fit the line to the points with ``lo <= x <= hi`` (overrides
    ``method``; used to reuse the real curve's window on the simulated one).

    Parameters
    ----------
    curve : Curve or (x, y)
        Signal (y) against temperature difference (x).
    lo_frac, hi_frac : float
        Band limits as fractions of the floor-to-ceiling span, ``0 <= lo < hi <= 1``.

    Returns
    -------
    SiTFFit

    Raises
    ------
    FidelityError (a ValueError)
        A flat curve (no response), fewer than 3 points in the band or window (no
        linear region, e.g. a curve that jumps from floor to saturation), or a
        logistic fit that does not converge.
    """
    c = _as_curve(curve, "SiTF curve")
    lo_f, hi_f = float(lo_frac), float(hi_frac)
    if not (0 <= lo_f < hi_f <= 1):
        raise FidelityError(f"need 0 <= lo_frac < hi_frac <= 1, got {lo_frac!r}, {hi_frac!r}")
    x, y = c.x, c.y
    floor, ceil = float(y.min()), float(y.max())
    span = ceil - floor
    if window is not None:
        try:
            wlo, whi = (float(v) for v in window)
        except (TypeError, ValueError):
            raise FidelityError(f"window must be a pair (lo, hi), got {window!r}") from None
        if not (math.isfinite(wlo) and math.isfinite(whi) and wlo < whi):
            raise FidelityError(f"window must be finite with lo < hi, got {window!r}")
        sel = (x >= wlo) & (x <= whi)
        n = int(sel.sum())
        if n < 3:
            raise FidelityError(f"only {n} curve points lie in the window [{wlo:g}, {whi:g}] "
                                f"(curve x range {x[0]:g}..{x[-1]:g}); need at least 3")
        xs, ys = x[sel], y[sel]
        slope, icpt, res = _line(xs, ys)
        return SiTFFit(slope, icpt, wlo, whi, _r2(ys, res), _lin_err(res, slope, wlo, whi), n,
                       "window", floor, ceil)
    if span == 0:
        raise FidelityError(f"SiTF curve is flat (signal {floor:g} everywhere): no linear region")
    if method == "band":
        inb = (y >= floor + lo_f * span) & (y <= floor + hi_f * span)
        i0, i1 = _longest_run(inb)
        if i1 - i0 < 3:
            raise FidelityError(
                f"SiTF curve has no linear region: {i1 - i0} consecutive point(s) between "
                f"{lo_f:.0%} and {hi_f:.0%} of the floor-to-ceiling span ({floor:g}..{ceil:g}); "
                f"need at least 3 (curve saturated, a step, or sampled too coarsely)")
        xs, ys = x[i0:i1], y[i0:i1]
        slope, icpt, res = _line(xs, ys)
        lo, hi = float(xs[0]), float(xs[-1])
        return SiTFFit(slope, icpt, lo, hi, _r2(ys, res), _lin_err(res, slope, lo, hi), i1 - i0,
                       "band", floor, ceil)
    if method == "logistic":
        return _logistic_fit(x, y, lo_f, hi_f, floor, ceil)
    raise FidelityError(f"method must be 'band' or 'logistic', got {method!r}")


def _logistic_fit(x: np.ndarray, y: np.ndarray, lo_f: float, hi_f: float,
                  floor: float, ceil: float) -> SiTFFit:
    if x.size < 5:
        raise FidelityError(f"the logistic fit has 4 parameters and needs at least 5 points, got {x.size}")
    # work in unit-scaled coordinates for conditioning
    xc, xs = float(x.mean()), float(x[-1] - x[0])
    yc, ysc = floor, ceil - floor
    u, v = (x - xc) / xs, (y - yc) / ysc
    inc = np.corrcoef(u, v)[0, 1] >= 0 if np.ptp(v) > 0 else True
    A0, B0 = (0.0, 1.0) if inc else (1.0, -1.0)
    i_mid = int(np.argmin(np.abs(v - 0.5)))
    p = np.array([A0, B0, u[i_mid], math.log(0.1)])

    def model(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        A, B, x0, ls = p
        s = math.exp(ls)
        z = np.clip((u - x0) / s, -700, 700)
        g = 1.0 / (1.0 + np.exp(-z))
        J = np.empty((u.size, 4))
        J[:, 0] = 1.0
        J[:, 1] = g
        gp = B * g * (1 - g)
        J[:, 2] = -gp / s
        J[:, 3] = -gp * z
        return A + B * g, J

    lam = 1e-3
    f, J = model(p)
    cost = float(((f - v) ** 2).sum())
    converged = False
    for _ in range(500):
        JTJ = J.T @ J
        g = J.T @ (f - v)
        step = np.linalg.solve(JTJ + lam * np.diag(np.diag(JTJ) + 1e-12), -g)
        pn = p + step
        fn, Jn = model(pn)
        cn = float(((fn - v) ** 2).sum())
        if cn <= cost:
            small = abs(cost - cn) <= 1e-15 + 1e-12 * cost and np.abs(step).max() < 1e-10 + 1e-8 * np.abs(p).max()
            p, f, J, cost = pn, fn, Jn, cn
            lam = max(lam / 3, 1e-12)
            if small:
                converged = True
                break
        else:
            lam *= 4
            if lam > 1e12:
                converged = True  # no further descent possible: at a minimum to machine precision
                break
    if not converged or not np.isfinite(p).all():
        raise FidelityError("logistic fit of the SiTF curve did not converge; use method='band'")
    A, B, x0, ls = p
    s = math.exp(ls) * xs
    Bd, Ad, x0d = B * ysc, A * ysc + yc, x0 * xs + xc
    slope = Bd / (4 * s)
    icpt = Ad + Bd / 2 - slope * x0d
    z_lo, z_hi = math.log(lo_f / (1 - lo_f)) if lo_f > 0 else -math.inf, \
        math.log(hi_f / (1 - hi_f)) if hi_f < 1 else math.inf
    ends = sorted((x0d + s * z_lo, x0d + s * z_hi))
    lo, hi = max(ends[0], float(x[0])), min(ends[1], float(x[-1]))
    sel = (x >= lo) & (x <= hi)
    res_line = y[sel] - (slope * x[sel] + icpt)
    r2 = _r2(y, y - (f * ysc + yc))
    return SiTFFit(float(slope), float(icpt), float(lo), float(hi), r2,
                   _lin_err(res_line, slope, lo, hi), int(sel.sum()), "logistic", floor, ceil)


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
        In the x unit of the SiTF curve (e.g. K).
    """
    n = _finite(noise_rms, "noise_rms", nonneg=True)
    slope = fit.slope if isinstance(fit, SiTFFit) else _finite(fit, "slope")
    if slope == 0:
        raise FidelityError("SiTF slope is 0: the camera does not respond, NETD is undefined")
    return n / abs(slope)


def sitf_similarity(real: Any, sim: Any, *, window: Any = "real", lo_frac: float = 0.1,
                    hi_frac: float = 0.9, method: str = "band", points: Any = 64,
                    alpha: float = 1.0, beta: float = 1.0) -> CurveSimilarity:
    """Component f2: :func:`~irfidelity.curves.curve_similarity` of two SiTF curves.

    ``a, b`` are the slopes of the linear portions (paper §1.2, eq. 4).

    Parameters
    ----------
    window : "real" | "each" | (lo, hi)
        ``"real"`` (default): find the linear window on the real curve
        (:func:`sitf_fit` with ``lo_frac``, ``hi_frac``, ``method``) and fit the
        simulated curve by least squares over the same (lo, hi), so both slopes refer
        to the same temperature range. ``"each"``: fit each curve on its own window.
        A pair: fit both on that window.
    points, alpha, beta
        As in :func:`~irfidelity.curves.curve_similarity` (the shape term uses the
        whole overlap of the two curves).
    """
    r_c, s_c = _as_curve(real, "real SiTF"), _as_curve(sim, "simulated SiTF")

    def fit(c: Any, who: str, **kw: Any) -> SiTFFit:
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
            raise FidelityError(f"window must be 'real', 'each' or (lo, hi), got {window!r}")
    else:
        fr, fs = fit(r_c, "real", window=window), fit(s_c, "simulated", window=window)
    return curve_similarity(r_c, s_c, a=fr.slope, b=fs.slope, points=points, alpha=alpha, beta=beta)
