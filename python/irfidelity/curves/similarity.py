"""Similarity of a measured and a simulated characteristic curve (paper §1.2, eqs. 1-4), and
the unit check that precedes every comparison."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import FidelityError
from .curve import Curve, as_curve
from .units import FREQUENCY, UNITS, CameraGeometry, conversion_hint, convert, warn_unknown

__all__ = ["CurveSimilarity", "curve_similarity", "similarity_mu", "feature_points", "align_units"]


@dataclass(frozen=True)
class CurveSimilarity:
    """Result of :func:`curve_similarity` (paper eqs. 1-4).

    Attributes
    ----------
    value : float
        ``mu**alpha * |rho|**beta`` (eq. 3), in [0, 1].
    mu : float
        ``2|a||b| / (a² + b²)`` (eq. 4); 1 when ``|a| == |b|`` (also a = b = 0).
    rho : float
        Pearson correlation of the two curves at the feature points (eq. 2); 1 for two
        constant curves, 0 when exactly one is constant.
    ccc : float
        Lin's concordance correlation ``2 cov / (var_r + var_s + (mean_r - mean_s)²)`` in
        [-1, 1]: unlike ``rho`` it penalises offset and scale, so it separates falling MTFs
        that ``rho`` rates as near-identical. 1 for two equal constants.
    area : float
        Normalised area between the curves, ``∫|r - s| / ∫(|r| + |s|)`` over the feature
        points (trapezoids), in [0, 1]; 0 = identical.
    a, b : float
        The characteristic values used in ``mu`` (real, simulated), in the units of the
        compared curves.
    points : numpy.ndarray
        The feature abscissae.
    x_unit, y_unit : str or None
        Units of the compared curves (the real curve's; None = unknown on both).
    notes : tuple of str
        Conversions made and units left unknown, for reports.
    """

    value: float
    mu: float
    rho: float
    ccc: float
    area: float
    a: float
    b: float
    points: np.ndarray
    x_unit: str | None = None
    y_unit: str | None = None
    notes: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "mu": self.mu, "rho": self.rho, "ccc": self.ccc,
                "area": self.area, "a": self.a, "b": self.b, "points": self.points.tolist(),
                "x_unit": self.x_unit, "y_unit": self.y_unit, "notes": list(self.notes)}


def finite_number(v: Any, what: str, *, nonneg: bool = False) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise FidelityError(f"{what} must be a number, got {v!r}") from None
    if not math.isfinite(f) or (nonneg and f < 0):
        raise FidelityError(f"{what} must be finite{' and >= 0' if nonneg else ''}, got {v!r}")
    return f


def similarity_mu(a: float, b: float) -> float:
    """Eq. (4) of the paper: the agreement of two characteristic values.

    ``mu = 2|a||b| / (a² + b²)``, computed overflow-safe; a = b = 0 gives 1.

    Examples
    --------
    >>> similarity_mu(0.2, 0.4)
    0.8
    """
    fa, fb = abs(finite_number(a, "a")), abs(finite_number(b, "b"))
    m = max(fa, fb)
    if m == 0:
        return 1.0
    fa, fb = fa / m, fb / m
    return float(min(1.0, 2 * fa * fb / (fa * fa + fb * fb)))


def _trapz(y: np.ndarray, x: np.ndarray) -> float:
    return float(np.sum((y[1:] + y[:-1]) * np.diff(x)) / 2)


#: Most feature points a curve comparison samples (a count or an explicit array): far more
#: than any measured curve resolves, and a bound on the memory a comparison takes.
MAX_FEATURE_POINTS = 1 << 16


def feature_points(real: Any, sim: Any, points: Any = 64) -> np.ndarray:
    """Feature abscissae over the overlap of both curves' x ranges (paper §1.2).

    ``points`` is a count (2 .. :data:`MAX_FEATURE_POINTS`; uniform over the overlap, end
    points included) or an explicit array of as many values that must lie inside the overlap.

    Examples
    --------
    >>> feature_points(([0, 1, 2], [1, 0.5, 0.2]), ([1, 2, 3], [0.9, 0.4, 0.1]), 5).tolist()
    [1.0, 1.25, 1.5, 1.75, 2.0]
    """
    r, s = as_curve(real, "real curve"), as_curve(sim, "simulated curve")
    lo, hi = max(r.x[0], s.x[0]), min(r.x[-1], s.x[-1])
    if not lo < hi:
        raise FidelityError(f"the curves' x ranges do not overlap: real {r.x[0]:g}..{r.x[-1]:g}, "
                            f"simulated {s.x[0]:g}..{s.x[-1]:g}")
    if np.ndim(points) == 0:
        try:
            n = int(points)
        except (TypeError, ValueError, OverflowError):
            raise FidelityError(f"points must be an integer or an array, got {points!r}") from None
        if n != points or not 2 <= n <= MAX_FEATURE_POINTS:
            raise FidelityError(f"points must be an integer in 2..{MAX_FEATURE_POINTS}, got {points!r}")
        return np.linspace(lo, hi, n)
    try:
        p = np.asarray(points, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise FidelityError(f"points must be an integer or an array of numbers, got {points!r}") from None
    if not 2 <= p.size <= MAX_FEATURE_POINTS or not np.isfinite(p).all():
        raise FidelityError(f"explicit feature points must be 2..{MAX_FEATURE_POINTS} finite values")
    if p.min() < lo or p.max() > hi:
        raise FidelityError(f"feature points must lie within the overlap {lo:g}..{hi:g} of both curves "
                            f"(got {p.min():g}..{p.max():g}); curves are never extrapolated")
    return p


def _describe_unit(unit: str | None) -> str:
    if unit is None:
        return "an unknown unit"
    known = UNITS.get(unit)
    return f"{unit} ({known.meaning})" if known else unit


def align_units(real: Curve, sim: Curve, *, camera: CameraGeometry | None = None, convert_sim: bool = True,
                what: str = "curves", axes: tuple[str, ...] = ("x", "y"),
                examples: str = "freq_cy_per_px, dT_K, temperature_C, counts") -> tuple[Curve, list[str]]:
    """The simulated curve in the real curve's units, and notes on what was done.

    For each axis: equal units pass; an axis unknown on both passes with the note "units
    unknown" and one :class:`~irfidelity.curves.units.CurveUnitsWarning`; known on one side
    only ("half-known") is an error; two known units are converted (when ``convert_sim``) or
    an error naming both and how to convert. ``examples`` are header names quoted in messages.

    Raises
    ------
    FidelityError
        Half-known or different units that cannot (or may not) be converted.
    """
    notes: list[str] = []
    unknown = []
    for axis in axes:
        ru, su = getattr(real, f"{axis}_unit"), getattr(sim, f"{axis}_unit")
        if ru == su:
            if ru is None:
                unknown.append(axis)
            continue
        if ru is None or su is None:
            known, side = (su, "simulated") if ru is None else (ru, "real")
            other = "real" if side == "simulated" else "simulated"
            raise FidelityError(
                f"{what}: the {side} {axis} axis is in {_describe_unit(known)}, the {other} one in an "
                f"unknown unit: cannot compare them; name the unit in the {other} curve's CSV header "
                f"(e.g. {examples}; the table is in irfidelity.curves.units)")
        if not convert_sim:
            raise FidelityError(f"{what}: the real {axis} axis is in {_describe_unit(ru)}, the simulated one "
                                f"in {_describe_unit(su)}; {conversion_hint(su, ru)}")
        try:
            values = convert(getattr(sim, axis), su, ru, camera=camera)
        except FidelityError as exc:
            raise FidelityError(f"{what}: the real {axis} axis is in {_describe_unit(ru)}, the simulated one "
                                f"in {_describe_unit(su)}; {conversion_hint(su, ru)}") from exc
        sim = sim.replace(**{axis: values, f"{axis}_unit": ru})
        unit = UNITS.get(ru)
        via = f" with {camera.describe((su, ru))}" if camera and unit and unit.quantity == FREQUENCY else ""
        notes.append(f"simulated {axis} axis converted from {su} to {ru}{via}")
    if unknown:
        axes_text = " and ".join(f"{a} axes" if i == len(unknown) - 1 else a for i, a in enumerate(unknown))
        note = f"units unknown: the {axes_text} of both {what} carry no unit, assumed to agree"
        notes.append(note)
        warn_unknown(f"{note} (name the units in the CSV headers, e.g. {examples})")
    return sim, notes


def curve_similarity(real: Any, sim: Any, *, a: float, b: float, points: Any = 64,
                     alpha: float = 1.0, beta: float = 1.0) -> CurveSimilarity:
    """Similarity of a measured and a simulated characteristic curve (paper eqs. 1-4).

    Both curves are sampled by linear interpolation at common feature points ``p_i``;

    .. math::

        \\rho = \\frac{\\sum_i (r_i - \\bar r)(s_i - \\bar s)}
                     {\\sqrt{\\sum_i (r_i - \\bar r)^2 \\sum_i (s_i - \\bar s)^2}}
        \\quad (2), \\qquad
        \\mu = \\frac{2|a||b|}{a^2 + b^2} \\quad (4), \\qquad
        f = \\mu^{\\alpha} |\\rho|^{\\beta} \\quad (3)

    with the characteristic values ``a`` (real) and ``b`` (simulated).

    Parameters
    ----------
    real, sim : Curve or (x, y)
        Both axes must have the same units, or units unknown on both (then a
        :class:`~irfidelity.curves.units.CurveUnitsWarning`). This function does not convert,
        as ``a`` and ``b`` are the caller's: convert first (:meth:`Curve.to_units`) or use
        :func:`~irfidelity.curves.mtf_similarity` / :func:`~irfidelity.curves.sitf_similarity`,
        which convert and then compute ``a`` and ``b``.
    a, b : float
        Characteristic values (MTF50 for MTF curves, linear slope for SiTF curves).
    points : int or array_like
        Number of feature points, uniform over the overlap of both x ranges, or the points
        themselves (inside the overlap).
    alpha, beta : float
        Exponents of eq. (3), >= 0 (the paper uses 1).

    Returns
    -------
    CurveSimilarity
        Never NaN: two constant curves give rho = 1, one gives 0; a = b = 0 gives mu = 1.

    Raises
    ------
    FidelityError (a ValueError)
        Disjoint x ranges, points outside the overlap, different or half-known units,
        non-finite or negative parameters.

    References
    ----------
    .. [1] A fuzzy-logic-based theoretical framework for quantitative fidelity evaluation of
       infrared camera simulators, Acta Photonica Sinica 41(5):547 (2012),
       doi:10.3788/gzxb20124105.0547, eqs. (1)-(4).
    .. [2] L. I-K. Lin, A concordance correlation coefficient to evaluate reproducibility,
       Biometrics 45(1):255 (1989), doi:10.2307/2532051.

    Examples
    --------
    >>> c = Curve([0, 0.5, 1.0], [1.0, 0.6, 0.1], x_unit="cy/px", y_unit="1")
    >>> s = curve_similarity(c, c, a=0.2, b=0.4)
    >>> round(s.mu, 6), round(s.rho, 6), round(s.value, 6)
    (0.8, 1.0, 0.8)
    """
    r_c, s_c = as_curve(real, "real curve"), as_curve(sim, "simulated curve")
    s_c, notes = align_units(r_c, s_c, convert_sim=False)
    return similarity_of(r_c, s_c, a=a, b=b, points=points, alpha=alpha, beta=beta, notes=notes)


def similarity_of(real: Curve, sim: Curve, *, a: float, b: float, points: Any, alpha: float, beta: float,
                  notes: list[str]) -> CurveSimilarity:
    """Eqs. (1)-(4) on two curves whose units already agree (see :func:`curve_similarity`)."""
    al = finite_number(alpha, "alpha", nonneg=True)
    be = finite_number(beta, "beta", nonneg=True)
    mu = similarity_mu(a, b)
    p = feature_points(real, sim, points)
    r = np.interp(p, real.x, real.y)
    s = np.interp(p, sim.x, sim.y)
    rho, ccc = _correlations(r, s)
    denom = _trapz(np.abs(r) + np.abs(s), p)
    area = _trapz(np.abs(r - s), p) / denom if denom > 0 else 0.0
    value = (mu ** al) * (abs(rho) ** be)
    return CurveSimilarity(value=float(min(1.0, value)), mu=mu, rho=rho, ccc=ccc,
                           area=float(min(1.0, max(0.0, area))), a=float(a), b=float(b), points=p,
                           x_unit=real.x_unit, y_unit=real.y_unit, notes=tuple(notes))


def _correlations(r: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """Pearson rho (eq. 2) and Lin's CCC; constant curves: both constant -> rho 1, one -> 0."""
    r_const = bool(np.ptp(r) == 0)
    s_const = bool(np.ptp(s) == 0)
    if r_const and s_const:
        return 1.0, (1.0 if r[0] == s[0] else 0.0)
    if r_const or s_const:
        return 0.0, 0.0
    # scale to O(1) before forming moments (huge or tiny units stay finite)
    scale = max(np.abs(r).max(), np.abs(s).max())
    r, s = r / scale, s / scale
    dr, ds = r - r.mean(), s - s.mean()
    srr, sss, srs = float(dr @ dr), float(ds @ ds), float(dr @ ds)
    if srr == 0 or sss == 0:  # spread lost to rounding: treat as constant
        return 0.0, 0.0
    rho = max(-1.0, min(1.0, srs / math.sqrt(srr * sss)))
    n = r.size
    mean_gap = float(r.mean() - s.mean())
    ccc = 2 * srs / n / (srr / n + sss / n + mean_gap * mean_gap)
    return float(rho), float(max(-1.0, min(1.0, ccc)))
