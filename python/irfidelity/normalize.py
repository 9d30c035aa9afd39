"""Mapping raw metric values to [0, 1] fidelity components (paper §2.1, eq. 6)."""

from __future__ import annotations

import math

from .errors import FidelityError

__all__ = ["psnr_curve_params", "normalize_psnr", "DEFAULT_PSNR_ANCHORS"]

#: The paper's anchors: 30 dB ↦ 0.9 and 45 dB ↦ 0.99 (k = ln2/ln1.5 ≈ 1.70951, a ≈ 18.4178).
DEFAULT_PSNR_ANCHORS = ((30.0, 0.9), (45.0, 0.99))


def psnr_curve_params(anchors=DEFAULT_PSNR_ANCHORS) -> tuple[float, float]:
    """Parameters ``(a, k)`` of ``y = 1 − exp(−(x/a)^k)`` (eq. 6) through two anchor points.

    With ``L_i = −ln(1 − y_i)``: ``k = ln(L2/L1) / ln(x2/x1)`` and ``a = x1 / L1^(1/k)``.
    Anchors need ``0 < x1 < x2`` and ``0 < y1 < y2 < 1``.
    """
    try:
        (x1, y1), (x2, y2) = ((float(x), float(y)) for x, y in anchors)
    except (TypeError, ValueError) as exc:
        raise FidelityError(f"anchors must be two (psnr_db, value) pairs, got {anchors!r}") from exc
    if not (0 < x1 < x2 and math.isfinite(x2)):
        raise FidelityError(f"anchor PSNRs must satisfy 0 < x1 < x2 (finite), got {x1}, {x2}")
    if not (0 < y1 < y2 < 1):
        raise FidelityError(f"anchor values must satisfy 0 < y1 < y2 < 1, got {y1}, {y2}")
    l1, l2 = -math.log1p(-y1), -math.log1p(-y2)
    k = math.log(l2 / l1) / math.log(x2 / x1)
    a = x1 / l1 ** (1.0 / k)
    return a, k


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
    return -math.expm1(-((x / a) ** k))
