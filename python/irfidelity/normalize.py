"""Mapping raw metric values to [0, 1] fidelity components (paper §2.1, eq. 6)."""

from __future__ import annotations

import functools
import math

from .errors import FidelityError

__all__ = ["psnr_curve_params", "normalize_psnr", "DEFAULT_PSNR_ANCHORS", "PSNR_RANGE_DB", "EXPONENT_RANGE"]

#: The paper's anchors: 30 dB ↦ 0.9 and 45 dB ↦ 0.99 (k = ln2/ln1.5 ≈ 1.70951, a ≈ 18.4178).
DEFAULT_PSNR_ANCHORS = ((30.0, 0.9), (45.0, 0.99))


#: The PSNRs (dB) eq. (6) is fitted over: both anchors, and the curve's scale ``a`` (where it
#: passes 1 − 1/e), lie in this range. Outside it no frame pair lands on the rising part.
PSNR_RANGE_DB = (0.01, 1000.0)

#: The shape exponent ``k`` the anchors may give: below it the curve is nearly flat, above it
#: nearly a step (the paper's anchors give k ≈ 1.71).
EXPONENT_RANGE = (0.01, 1000.0)


def _anchor_points(anchors) -> tuple[float, float, float, float]:
    try:
        (x1, y1), (x2, y2) = ((float(x), float(y)) for x, y in anchors)
    except (TypeError, ValueError, OverflowError):
        raise FidelityError(f"anchors must be two (psnr_db, value) pairs, got {anchors!r}",
                            option="psnr_anchors") from None
    lo_db, hi_db = PSNR_RANGE_DB
    if not (lo_db <= x1 < x2 <= hi_db):
        raise FidelityError(f"anchor PSNRs must satisfy {lo_db:g} <= x1 < x2 <= {hi_db:g} dB, got {x1}, {x2}",
                            option="psnr_anchors")
    if not (0 < y1 < y2 < 1):
        raise FidelityError(f"anchor values must satisfy 0 < y1 < y2 < 1, got {y1}, {y2}", option="psnr_anchors")
    return x1, y1, x2, y2


def psnr_curve_params(anchors=DEFAULT_PSNR_ANCHORS) -> tuple[float, float]:
    """Parameters ``(a, k)`` of ``y = 1 − exp(−(x/a)^k)`` (eq. 6) through two anchor points.

    With ``L_i = −ln(1 − y_i)``: ``k = ln(L2/L1) / ln(x2/x1)`` and ``a = x1 / L1^(1/k)``.
    Anchors need ``x1 < x2`` within :data:`PSNR_RANGE_DB` and ``0 < y1 < y2 < 1``, and must
    give ``k`` within :data:`EXPONENT_RANGE` and ``a`` within :data:`PSNR_RANGE_DB`, so that
    the curve rises over PSNRs frames can have; otherwise a FidelityError says which.

    Examples
    --------
    >>> a, k = psnr_curve_params(((30.0, 0.9), (45.0, 0.99)))
    >>> round(a, 4), round(k, 5)
    (18.4178, 1.70951)
    """
    try:
        return _curve_params(anchors)
    except TypeError:  # unhashable anchors (lists): computed, not remembered
        return _curve_params.__wrapped__(anchors)


@functools.lru_cache(maxsize=32)
def _curve_params(anchors) -> tuple[float, float]:
    """:func:`psnr_curve_params` of hashable anchors, remembered: every normalised PSNR and
    every grade cut needs them, and configurations share a handful of anchor pairs."""
    x1, y1, x2, y2 = _anchor_points(anchors)
    l1, l2 = -math.log1p(-y1), -math.log1p(-y2)
    log_x_ratio, log_l_ratio = math.log(x2) - math.log(x1), math.log(l2) - math.log(l1)
    k = log_l_ratio / log_x_ratio if log_x_ratio > 0 else math.inf
    k_lo, k_hi = EXPONENT_RANGE
    if not (k_lo <= k <= k_hi):
        shape = "nearly a step" if k > k_hi else "nearly flat"
        raise FidelityError(f"anchors {anchors!r} give eq. (6) the exponent k = {k:.4g}, outside {k_lo:g}..{k_hi:g}: "
                            f"the curve would be {shape}", option="psnr_anchors")
    log_a = math.log(x1) - math.log(l1) / k
    lo_db, hi_db = PSNR_RANGE_DB
    if not (math.log(lo_db) <= log_a <= math.log(hi_db)):
        raise FidelityError(f"anchors {anchors!r} put eq. (6)'s scale a = {math.exp(min(log_a, 700.0)):.4g} dB outside "
                            f"{lo_db:g}..{hi_db:g} dB: the curve would stay near "
                            f"{'0' if log_a > math.log(hi_db) else '1'} for every PSNR", option="psnr_anchors")
    return math.exp(log_a), k


def normalize_psnr(db: float, *, anchors=DEFAULT_PSNR_ANCHORS) -> float:
    """Normalised PSNR, the fidelity component f3 (paper eq. 6).

    ``y = 1 − exp(−(x/a)^k)`` with ``a, k`` fixed by two anchors (default 30 dB → 0.9,
    45 dB → 0.99). ``+inf`` dB (identical frames) → 1; ``x <= 0`` dB → 0 (possible for
    float frames whose error exceeds the peak). NaN is an error.

    Examples
    --------
    >>> round(normalize_psnr(21.072), 4)   # the paper's Table 1
    0.716
    """
    x = float(db)
    if math.isnan(x):
        raise FidelityError("PSNR is NaN; cannot normalise")
    if x == math.inf:
        return 1.0
    if x <= 0:
        return 0.0
    a, k = psnr_curve_params(anchors)
    power = k * (math.log(x) - math.log(a))  # ln((x/a)^k), without overflowing
    return 1.0 if power > 709.0 else -math.expm1(-math.exp(power))
