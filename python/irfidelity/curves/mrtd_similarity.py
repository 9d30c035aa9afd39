"""The ``mrtd`` component: the similarity of two cameras' MRTD curves (docs/bars.md, section 5).

The MRTD spans decades and matters as a ratio (a camera twice as noisy has twice the MRTD at
every frequency), so the curves are compared on ``log ΔT``, like the curve components (paper
eqs. 1-4): over the frequencies both curves cover, at uniform feature points,

* the characteristic values ``a``, ``b`` are the geometric means of the real and simulated MRTD
  (``exp`` of the mean ``log ΔT``): ``μ = 2ab/(a² + b²) = 1/cosh(log(b/a))`` (eq. 4);
* ``ρ`` is the Pearson correlation of the two ``log ΔT`` curves (eq. 2): their shape;
* the component is ``μ^α |ρ|^β`` (eq. 3).

A tolerance in % of ΔT forgives a level difference up to it: ``μ = 1/cosh(max(0, |log(b/a)| −
log(1 + tolerance/100)))``. Identical curves score 1; a camera with twice the NETD (twice the
MRTD) scores ``μ = 0.8`` with no tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import FidelityError
from .curve import Curve, as_curve
from .similarity import CurveSimilarity, align_units, feature_points, finite_number, similarity_of
from .units import CameraGeometry

__all__ = ["MRTDSimilarity", "mrtd_similarity"]


@dataclass(frozen=True)
class MRTDSimilarity(CurveSimilarity):
    """:class:`~irfidelity.curves.CurveSimilarity` of two MRTD curves on ``log ΔT``.

    ``a``, ``b`` are the geometric-mean MRTDs (K) over the common frequencies ``points``;
    ``ccc`` and ``area`` are those of the ``log ΔT`` curves.

    Attributes
    ----------
    ratio : float
        ``b / a``: the simulated camera's MRTD level against the real one's.
    max_deviation : float
        Largest ``|MRTD_sim / MRTD_real − 1|`` at the feature points, in %.
    tolerance : float
        The tolerance applied, in % of ΔT.
    """

    ratio: float = 1.0
    max_deviation: float = 0.0
    tolerance: float = 0.0


def _in_kelvin(c: Curve, what: str) -> Curve:
    """The curve with ``y`` labelled a temperature difference in K: an MRTD is one, so a curve
    whose ``y`` carries no unit, or K or °C (a difference in either is the same), is taken as it."""
    if c.y_unit not in (None, "K", "degC", "delta_K"):
        raise FidelityError(f"{what}: an MRTD is a temperature difference in K, got a curve in {c.y_unit!r}")
    return c.with_units(y_unit="delta_K")


def _log_curve(c: Curve, what: str) -> Curve:
    """The curve with ``log ΔT`` for ``y`` (every MRTD must be finite and > 0)."""
    if not (np.isfinite(c.y).all() and (c.y > 0).all()):
        bad = int(np.argmax(~(np.isfinite(c.y) & (c.y > 0))))
        raise FidelityError(f"{what}: an MRTD must be a positive temperature difference, got {c.y[bad]!r} at "
                            f"{c.x[bad]:g} {c.x_unit or ''}".rstrip())
    return c.replace(y=np.log(c.y), y_unit=None)


def mrtd_similarity(real: Any, sim: Any, *, tolerance: float = 0.0, points: Any = 64, alpha: float = 1.0,
                    beta: float = 1.0, camera: CameraGeometry | None = None) -> MRTDSimilarity:
    """Component ``mrtd``: similarity of the real and simulated MRTD curves (module docstring).

    Parameters
    ----------
    real, sim : Curve or (x, y)
        MRTD curves (``y`` in K, a ``y`` without unit taken as K; e.g. from :func:`~irfidelity.curves.mrtd` or
        :func:`~irfidelity.curves.measured_mrtd`). A simulated curve in another frequency unit
        is converted with ``camera``, as for the MTF.
    tolerance : float
        Level difference forgiven, in % of ΔT (>= 0).
    points, alpha, beta
        As in :func:`~irfidelity.curves.curve_similarity`; the feature points span the
        frequencies both curves cover.
    camera : CameraGeometry, optional

    Returns
    -------
    MRTDSimilarity

    Raises
    ------
    FidelityError
        An MRTD that is not > 0, curves with no common frequencies, units that disagree.

    Examples
    --------
    >>> f = np.linspace(0.05, 0.4, 8)
    >>> real = Curve(f, 0.02 * np.exp(8 * f), x_unit="cy/px", y_unit="delta_K")
    >>> s = mrtd_similarity(real, real.replace(y=2 * real.y))   # twice the NETD
    >>> round(s.value, 6), round(s.ratio, 6), round(s.rho, 6)
    (0.8, 2.0, 1.0)
    >>> round(mrtd_similarity(real, real.replace(y=1.05 * real.y), tolerance=10).value, 6)
    1.0
    """
    tol = finite_number(tolerance, "tolerance", nonneg=True)
    r_c = _in_kelvin(as_curve(real, "real MRTD"), "real MRTD")
    s_c = _in_kelvin(as_curve(sim, "simulated MRTD"), "simulated MRTD")
    s_c, notes = align_units(r_c, s_c, camera=camera, what="MRTD curves", axes=("x",),
                             examples="freq_cy_per_px, freq_cy_per_mrad, lp_mm")
    r_log, s_log = _log_curve(r_c, "real MRTD"), _log_curve(s_c, "simulated MRTD")
    p = feature_points(r_log, s_log, points)
    r_mean = float(np.interp(p, r_log.x, r_log.y).mean())
    s_mean = float(np.interp(p, s_log.x, s_log.y).mean())
    gap = max(0.0, abs(s_mean - r_mean) - math.log1p(tol / 100.0))
    level = similarity_of(r_log, s_log, a=1.0, b=math.exp(gap), points=p, alpha=alpha, beta=beta, notes=notes)
    deviation = np.exp(np.interp(p, s_log.x, s_log.y) - np.interp(p, r_log.x, r_log.y)) - 1.0
    return MRTDSimilarity(value=level.value, mu=level.mu, rho=level.rho, ccc=level.ccc, area=level.area,
                          a=math.exp(r_mean), b=math.exp(s_mean), points=p, x_unit=r_c.x_unit, y_unit=r_c.y_unit,
                          notes=level.notes, ratio=math.exp(s_mean - r_mean),
                          max_deviation=float(np.abs(deviation).max() * 100.0), tolerance=tol)
