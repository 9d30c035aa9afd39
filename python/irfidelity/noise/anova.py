"""Variance components of the 3-D noise model from the seven sums of squares.

The directional-average decomposition of a T × V × H cube is a balanced three-way analysis
of variance with one observation per cell. With ``SS_x = Σ N_x²`` over the cube:

* classical (D'Agostino & Webb): ``σ_x² = SS_x / N``, the population variance of part
  ``N_x``; biased for finite T, V, H (part ``t`` holds ``σ_tvh²/(V·H)``, ``tvh`` is scaled
  by ``(1−1/T)(1−1/V)(1−1/H)``, ...);
* corrected: under the random-effects model ``x = μ + t + v + h + tv + th + vh + tvh``
  (independent zero-mean effects) the mean squares ``MS_x = SS_x / df_x`` have the
  expected values

  ``E[MS_tvh] = σ_tvh²``, ``E[MS_tv] = σ_tvh² + H·σ_tv²`` (and th, vh alike),
  ``E[MS_t] = σ_tvh² + H·σ_tv² + V·σ_th² + V·H·σ_t²`` (and v, h alike),

  so ``σ̂_t² = (MS_t − MS_tv − MS_th + MS_tvh)/(V·H)`` etc. are unbiased: the estimators of
  Haefner et al., Applied Optics 54(15):4907 (2015), written with ANOVA mean squares.

Confidence intervals: ``df·MS/E[MS]`` is χ²(df) under normality, so ``σ_tvh²`` has an
exact interval; every other component is a difference of mean squares and gets the
modified large-sample interval of Ting et al. (1990), which keeps its coverage when a
component is small or zero (Satterthwaite's approximation does not: 76–87 % for a nominal
95 % in our simulations). See ``docs/noise.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..schema import NOISE_PARTS
from .quantiles import chi2_ppf, f_ppf

__all__ = ["Anova", "anova", "PARTS"]

PARTS = NOISE_PARTS

#: Corrected variance of part x: Σ coefficient·MS_k, divided by its replication.
_CORRECTED = {
    "t": {"t": 1, "tv": -1, "th": -1, "tvh": 1},
    "v": {"v": 1, "tv": -1, "vh": -1, "tvh": 1},
    "h": {"h": 1, "th": -1, "vh": -1, "tvh": 1},
    "tv": {"tv": 1, "tvh": -1},
    "th": {"th": 1, "tvh": -1},
    "vh": {"vh": 1, "tvh": -1},
    "tvh": {"tvh": 1},
}


def replication(frames: int, rows: int, cols: int) -> dict[str, int]:
    """How many cells share one value of each part (``V·H`` frames' worth for t, ...)."""
    t, v, h = frames, rows, cols
    return {"t": v * h, "v": t * h, "h": t * v, "tv": h, "th": v, "vh": t, "tvh": 1}


def degrees_of_freedom(frames: int, rows: int, cols: int, *, plane: bool = False) -> dict[str, int]:
    """ANOVA degrees of freedom; a fitted plane takes one more from v and from h."""
    t, v, h = frames - 1, rows - 1, cols - 1
    return {"t": t, "v": v - plane, "h": h - plane, "tv": t * v, "th": t * h, "vh": v * h, "tvh": t * v * h}


@dataclass(frozen=True)
class Anova:
    """Variance components of one recording.

    Attributes
    ----------
    classical : dict
        ``SS_x / N`` per part (population variances of the directional-average parts).
    corrected : dict
        Unbiased estimates per part; may be negative when a component is small.
    mean_squares, df : dict
        ``MS_x = SS_x / df_x`` and the degrees of freedom.
    """

    classical: dict[str, float]
    corrected: dict[str, float]
    mean_squares: dict[str, float]
    df: dict[str, int]
    replication: dict[str, int]

    def interval(self, part: str, confidence: float) -> tuple[float, float]:
        """Confidence interval of the corrected variance of ``part`` (see the module notes)."""
        return variance_interval(
            {k: c / self.replication[part] for k, c in _CORRECTED[part].items()},
            self.mean_squares, self.df, confidence)


def anova(ss: dict[str, float], frames: int, rows: int, cols: int, *, plane: bool = False) -> Anova:
    """Classical and corrected variance components from the sums of squares ``ss``."""
    df = degrees_of_freedom(frames, rows, cols, plane=plane)
    n = frames * rows * cols
    rep = replication(frames, rows, cols)
    ms = {k: ss[k] / df[k] for k in PARTS}
    classical = {k: ss[k] / n for k in PARTS}
    corrected = {k: sum(c * ms[m] for m, c in _CORRECTED[k].items()) / rep[k] for k in PARTS}
    return Anova(classical, corrected, ms, df, rep)


def variance_interval(coefficients: dict[str, float], ms: dict[str, float], df: dict[str, int],
                      confidence: float) -> tuple[float, float]:
    """Two-sided interval for ``γ = Σ c_k·E[MS_k]`` (a variance component, ``γ ≥ 0``).

    The modified large-sample (MLS) interval of Ting, Burdick, Graybill, Jeyaratnam & Lu
    (1990) for a linear combination of expected mean squares with coefficients of either
    sign (Burdick & Graybill 1992, §3.2). For one mean square it is the exact χ²
    interval. Ends below 0 are set to 0.
    """
    alpha = (1 - confidence) / 2
    plus = [(c * ms[k], df[k]) for k, c in coefficients.items() if c > 0]
    minus = [(-c * ms[k], df[k]) for k, c in coefficients.items() if c < 0]
    estimate = sum(a for a, _ in plus) - sum(a for a, _ in minus)
    var_lo = var_hi = 0.0
    for a, n in plus:
        var_lo += (_g(alpha, n) * a) ** 2
        var_hi += (_h(alpha, n) * a) ** 2
    for a, n in minus:
        var_lo += (_h(alpha, n) * a) ** 2
        var_hi += (_g(alpha, n) * a) ** 2
    for a, n in plus:
        for b, m in minus:
            var_lo += _g_cross(alpha, n, m) * a * b
            var_hi += _h_cross(alpha, n, m) * a * b
    for group, star, var in ((plus, _g_star, "lo"), (minus, _h_star, "hi")):
        k = len(group)
        for i in range(k):
            for j in range(i + 1, k):
                term = star(alpha, group[i][1], group[j][1], k) * group[i][0] * group[j][0]
                if var == "lo":
                    var_lo += term
                else:
                    var_hi += term
    lo = estimate - math.sqrt(max(var_lo, 0.0))
    hi = estimate + math.sqrt(max(var_hi, 0.0))
    return max(lo, 0.0), max(hi, 0.0)


# The MLS constants; F(p; a, b) is the p quantile of F(a, b), F(p; a, ∞) = χ²_p(a)/a, and
# alpha the area in each tail (upper points F(1 − alpha; ·) in the lower bound's terms).
def _g(alpha: float, n: float) -> float:
    return 1 - n / chi2_ppf(1 - alpha, n)


def _h(alpha: float, n: float) -> float:
    return n / chi2_ppf(alpha, n) - 1


def _g_cross(alpha: float, n: float, m: float) -> float:
    f = f_ppf(1 - alpha, n, m)
    return ((f - 1) ** 2 - (_g(alpha, n) * f) ** 2 - _h(alpha, m) ** 2) / f


def _h_cross(alpha: float, n: float, m: float) -> float:
    f = f_ppf(alpha, n, m)
    return ((1 - f) ** 2 - (_h(alpha, n) * f) ** 2 - _g(alpha, m) ** 2) / f


def _g_star(alpha: float, n: float, m: float, count: int) -> float:
    g = 1 - (n + m) / chi2_ppf(1 - alpha, n + m)
    return (g * g * (n + m) ** 2 / (n * m) - _g(alpha, n) ** 2 * n / m - _g(alpha, m) ** 2 * m / n) / (count - 1)


def _h_star(alpha: float, n: float, m: float, count: int) -> float:
    h = (n + m) / chi2_ppf(alpha, n + m) - 1
    return (h * h * (n + m) ** 2 / (n * m) - _h(alpha, n) ** 2 * n / m - _h(alpha, m) ** 2 * m / n) / (count - 1)
