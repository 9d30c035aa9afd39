"""Image-quality metrics from sufficient statistics (paper §2, eqs. 5 and 7–14).

These functions take the numbers a :class:`~irfidelity.PairStats` holds (MSE, moments,
entropies) and apply the paper's formulas with the limits of docs/design.md §4, so that no
degenerate frame pair produces NaN. The array-level functions ``irf.stats.psnr`` etc. live
in :mod:`irfidelity.stats`, which computes the statistics first.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from .errors import FidelityError

__all__ = ["SSIM", "NMI", "psnr_from_mse", "ssim_from_moments", "nmi_from_entropies", "signed_power"]


@dataclass(frozen=True)
class SSIM:
    """Global SSIM and its three factors (eqs. 11–14).

    Attributes
    ----------
    value : float
        ``l**alpha * c**beta * s**gamma`` in [-1, 1] (eq. 14).
    luminance, contrast, structure : float
        l (eq. 11), c (eq. 12), s (eq. 13).
    """

    value: float
    luminance: float
    contrast: float
    structure: float

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class NMI:
    """Normalised mutual information and the entropies it comes from (eqs. 7–10).

    ``value = MI / ((h_real + h_sim) / 2)`` with ``MI = h_real + h_sim - h_joint`` clipped
    at 0. A value of 1 means a one-to-one grey-level relation between the frames, *not*
    equality: a frame and its negative also have NMI = 1.
    """

    value: float
    h_real: float
    h_sim: float
    h_joint: float
    mi: float
    bins: object  # int or "levels"

    def to_dict(self) -> dict:
        return asdict(self)


def psnr_from_mse(mse: float, peak: float) -> float:
    """PSNR in dB, eq. 5: ``10·log10(peak² / MSE)``; ``+inf`` when MSE == 0.

    One logarithm of the ratio when it is representable; ``20·log10(peak) − 10·log10(MSE)``
    when ``peak²`` or the ratio would overflow or underflow (float frames near 3e38).
    """
    if not (peak > 0 and math.isfinite(peak)):
        raise FidelityError(f"peak must be a positive finite number, got {peak!r}")
    if mse < 0 or math.isnan(mse):
        raise FidelityError(f"MSE must be >= 0, got {mse!r}")
    if mse == 0:
        return math.inf
    ratio = peak * peak / mse
    if math.isfinite(ratio) and ratio > 0:
        return 10.0 * math.log10(ratio)  # one log: error ~ ulp(PSNR)
    return 20.0 * math.log10(peak) - 10.0 * math.log10(mse)  # peak² or the ratio over/underflows


def signed_power(x: float, p: float) -> float:
    """``x**p`` for the SSIM factors: ``sign(x)·|x|**p``, so a negative factor with a
    fractional exponent stays real (docs/design.md §4); ``0**0 = 1``."""
    if p == 1:
        return x
    if x == 0:
        return 1.0 if p == 0 else 0.0
    return math.copysign(abs(x) ** p, x)


def check_exponents(alpha: float, beta: float, gamma: float) -> None:
    """Raise unless the SSIM exponents are finite numbers >= 0."""
    for name, p in (("alpha", alpha), ("beta", beta), ("gamma", gamma)):
        if not (math.isfinite(p) and p >= 0):
            raise FidelityError(f"{name} must be a finite number >= 0, got {p!r}")


def _ratio_2ab(a: float, b: float, c: float) -> float:
    """``(2ab + c)/(a² + b² + c)`` without overflow or cancellation; 1 when all are 0."""
    if a == 0 and b == 0 and c == 0:
        return 1.0
    if c == 0:
        # scale by an exact power of two so the squares cannot overflow or underflow
        e = math.frexp(max(abs(a), abs(b)))[1]
        a, b = math.ldexp(a, -e), math.ldexp(b, -e)
        return 2.0 * a * b / (a * a + b * b)
    return (2.0 * a * b + c) / (a * a + b * b + c)


def ssim_from_moments(
    mean_real: float,
    mean_sim: float,
    var_real: float,
    var_sim: float,
    cov: float,
    *,
    alpha: float = 1.0,
    beta: float = 1.0,
    gamma: float = 1.0,
    c1: float = 0.0,
    c2: float = 0.0,
    c3: float | None = None,
) -> SSIM:
    """Global SSIM from whole-image moments (eqs. 11–14).

    ``l = (2 μr μs + C1)/(μr² + μs² + C1)``, ``c = (2 σr σs + C2)/(σr² + σs² + C2)``,
    ``s = (σrs + C3)/(σr σs + C3)``; the paper uses no stabilising constants (all 0, the
    default; ``c3=None`` means ``C2/2`` as in Wang et al. 2004).

    Limits (docs/design.md §4): both means 0 → l = 1; both σ = 0 → c = s = 1; exactly one σ = 0 →
    s = 0. Factors are clipped to [-1, 1] against rounding; exponents apply sign-preserving.
    """
    check_exponents(alpha, beta, gamma)
    return SSIM(*ssim_terms(mean_real, mean_sim, var_real, var_sim, cov, alpha, beta, gamma, c1, c2, c3))


def ssim_terms(mean_real: float, mean_sim: float, var_real: float, var_sim: float, cov: float, alpha: float,
               beta: float, gamma: float, c1: float, c2: float, c3: float | None) -> tuple[float, float, float, float]:
    """:func:`ssim_from_moments` as ``(value, luminance, contrast, structure)``, the exponents
    taken as checked (a configuration checks them once)."""
    c3 = c2 / 2.0 if c3 is None else c3
    lum = _ratio_2ab(mean_real, mean_sim, c1)
    var_real, var_sim = max(var_real, 0.0), max(var_sim, 0.0)
    sd_r, sd_s = math.sqrt(var_real), math.sqrt(var_sim)
    # sqrt(fl(v·v)) == v: equal variances give c == s == 1 exactly (σr·σs would not)
    e = math.frexp(max(var_real, var_sim))[1] if max(var_real, var_sim) > 0 else 0
    vr, vs = math.ldexp(var_real, -e), math.ldexp(var_sim, -e)  # exact power-of-two scaling
    sd_prod = math.ldexp(math.sqrt(vr * vs), e)
    den_c = var_real + var_sim + c2
    con = 1.0 if den_c == 0 else (2.0 * sd_prod + c2) / den_c
    den_s = sd_prod + c3
    if sd_r == 0 and sd_s == 0 and c3 == 0:
        struct = 1.0
    elif den_s == 0:
        struct = 0.0
    else:
        struct = (cov + c3) / den_s
    lum, con, struct = min(max(lum, -1.0), 1.0), min(max(con, -1.0), 1.0), min(max(struct, -1.0), 1.0)
    value = signed_power(lum, alpha) * signed_power(con, beta) * signed_power(struct, gamma)
    return value, lum, con, struct


def nmi_from_entropies(h_real: float, h_sim: float, h_joint: float, *, bins: object = None) -> NMI:
    """NMI from entropies: ``MI = H(R) + H(S) − H(R,S)`` (eq. 9), ``NMI = MI/((H(R)+H(S))/2)``
    (eq. 10; the right-hand side printed in the paper is a misprint).

    Both frames constant (``H(R) = H(S) = 0``) → 1; one constant → 0. MI is clipped at 0
    and NMI at 1 against rounding.
    """
    mi = max(h_real + h_sim - h_joint, 0.0)
    total = h_real + h_sim
    value = 1.0 if total == 0 else min(2.0 * mi / total, 1.0)
    return NMI(value=value, h_real=h_real, h_sim=h_sim, h_joint=h_joint, mi=mi, bins=bins)
