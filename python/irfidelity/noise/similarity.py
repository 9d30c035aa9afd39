"""The ``noise`` component: how closely a simulator's noise matches the real camera's, in the
form of the paper's curve similarity (eq. 3), ``value = μ^α · ρ^β``.

* ``μ`` compares the noise *levels*: the seven component standard deviations as vectors
  ``a`` (real) and ``b`` (simulated), ``μ = 2·a·b / (|a|² + |b|²)``. For one component this
  is eq. 4, ``2|a||b|/(a² + b²)``; with seven it is 1 only when every component matches, so
  white noise of the right total but none of the camera's row or column pattern scores
  below 1. ``|a|² = Σ σ_x²`` is the total noise variance. When both recordings carry a SiTF
  slope the levels are divided by it (temperature units, NETD-like), so cameras with
  different gains compare on equal terms.
* ``ρ`` compares the *shapes* of the four 1-D spectra (fixed-pattern row and column,
  temporal row and column): each is normalised to a distribution over frequency, resampled
  to ``bins`` equal bands of ``0 .. 0.5`` cy/px, and compared by its Bhattacharyya
  coefficient ``Σ √(p·q)`` (1 for equal shapes); ``ρ`` is their weighted mean, the fixed
  spectra weighted by the fixed-pattern share of the noise variance (mean of both
  recordings), the temporal ones by the rest. The paper's Pearson correlation is not used:
  it is undefined for a flat (white) spectrum, the commonest noise spectrum, and two
  estimated white spectra correlate only by chance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..curves.similarity import similarity_mu
from ..errors import FidelityError
from ..schema import METRICS, NOISE_PARTS, NOISE_SPECTRA

__all__ = ["NoiseSimilarity", "noise_similarity", "NOISE_METRICS"]

FIXED = ("v", "h", "vh")


@dataclass(frozen=True)
class NoiseSimilarity:
    """Result of :func:`noise_similarity`.

    Attributes
    ----------
    value : float
        ``mu**alpha * rho**beta`` in [0, 1]; the component ``noise``.
    mu : float
        Level term, ``2·a·b/(|a|²+|b|²)`` of the component-σ vectors.
    rho : float
        Shape term, the weighted mean Bhattacharyya coefficient of the spectra.
    levels_real, levels_sim : dict
        The component levels compared (σ, or σ / |SiTF slope|).
    units : str
        ``"frame"`` or ``"temperature"`` (levels divided by the SiTF slopes).
    overlap, weights : dict
        Per spectrum: its Bhattacharyya coefficient and its weight in ``rho``.
    bins : int
        Frequency bands the spectra were resampled to.
    alpha, beta : float
        The exponents used.
    total_mu : float
        Eq. 4 on the total noise σ alone (for reference: what a single-level μ would be).
    real, sim : Noise3D
        The compared results.
    """

    value: float
    mu: float
    rho: float
    levels_real: dict[str, float]
    levels_sim: dict[str, float]
    units: str
    overlap: dict[str, float]
    weights: dict[str, float]
    bins: int
    alpha: float
    beta: float
    total_mu: float
    real: Any = field(repr=False, compare=False)
    sim: Any = field(repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (without the two Noise3D results; see :meth:`metrics`)."""
        return {k: v for k, v in self.__dict__.items() if k not in ("real", "sim")}

    def metrics(self) -> dict[str, Any]:
        """Flat raw metrics for a fidelity report, keyed and ordered as :data:`NOISE_METRICS`."""
        values: dict[str, Any] = {"noise_mu": self.mu, "noise_rho": self.rho, "noise_total_mu": self.total_mu,
                                  "noise_units": self.units}
        for who, n in (("real", self.real), ("sim", self.sim)):
            for part in NOISE_PARTS:
                values[f"noise_sigma_{part}_{who}"] = n.sigma[part]
            values[f"noise_total_{who}"] = n.total
            values[f"noise_netd_{who}"] = n.netd
            values[f"noise_mean_{who}"] = n.mean
            values[f"noise_frames_{who}"] = n.frames
        for name in NOISE_SPECTRA:
            values[f"noise_overlap_{name}"] = self.overlap[name]
        return {key: values[key] for key, _, _ in NOISE_METRICS}


#: The ``noise`` component's raw metrics: (key, unit, meaning), in report order.
NOISE_METRICS = METRICS["noise"]


def _levels(noise: Any, who: str, units: str) -> dict[str, float]:
    sigma = getattr(noise, "sigma", None)
    if not isinstance(sigma, dict) or set(sigma) != set(NOISE_PARTS):
        raise FidelityError(f"{who} noise must be a Noise3D (irfidelity.noise.noise3d), got {type(noise).__name__}")
    scale = 1.0 if units == "frame" else abs(noise.sitf_slope)
    return {k: float(sigma[k]) / scale for k in NOISE_PARTS}


def _spectrum_length(freq: np.ndarray) -> int:
    """Signal length behind a one-sided frequency axis (``rfftfreq``)."""
    return int(round(1 / freq[1])) if freq.size > 1 else 1


def _bands_of(noise: Any, name: str, bins: int) -> np.ndarray:
    sp = noise.spectra
    power = getattr(sp, name)
    freq = sp.freq_row if name.endswith("row") else sp.freq_col
    length = _spectrum_length(freq)
    centres = np.arange(power.size) / length
    half = 0.5 / length
    lo, hi = np.clip(centres - half, 0.0, 0.5), np.clip(centres + half, 0.0, 0.5)
    edges = np.linspace(0.0, 0.5, bins + 1)
    out = np.zeros(bins)
    for p, a, b in zip(power, lo, hi):
        if b > a:
            out += p * np.clip(np.minimum(edges[1:], b) - np.maximum(edges[:-1], a), 0.0, None) / (b - a)
    return out


def _bhattacharyya(p: np.ndarray, q: np.ndarray) -> float:
    sp, sq = float(p.sum()), float(q.sum())
    if sp <= 0 and sq <= 0:
        return 1.0
    if sp <= 0 or sq <= 0:
        return 0.0
    return float(min(1.0, np.sqrt((p / sp) * (q / sq)).sum()))


def _fixed_share(levels: dict[str, float]) -> float:
    total = sum(v * v for v in levels.values())
    return sum(levels[k] ** 2 for k in FIXED) / total if total > 0 else 0.5


def noise_similarity(real_noise: Any, sim_noise: Any, *, alpha: float = 1.0, beta: float = 1.0,
                     bins: int = 16) -> NoiseSimilarity:
    """The ``noise`` component: similarity of a simulator's 3-D noise to the real camera's.

    ``value = mu**alpha * rho**beta`` (the form of the paper's eq. 3) with

    * ``mu = 2 Σ aₓbₓ / Σ (aₓ² + bₓ²)`` over the seven components x of the 3-D noise model,
      ``a`` = the real camera's σₓ and ``b`` the simulator's (eq. 4 generalised to a vector
      of levels; divided by each camera's SiTF slope when both were measured with ``sitf=``);
    * ``rho = Σ_k w_k Σ_f √(p_k(f)·q_k(f))``, the Bhattacharyya coefficients of the shapes of
      the fixed-pattern row/column and temporal row/column spectra over ``bins`` frequency
      bands of 0 .. 0.5 cy/px, weighted by the fixed-pattern share of the noise variance
      (fixed spectra) and the rest (temporal spectra).

    Parameters
    ----------
    real_noise, sim_noise : Noise3D
        From :func:`irfidelity.noise.noise3d` on frames of a uniform source (both with spectra,
        the same estimator (``corrected``) and the same units).
    alpha, beta : float
        Exponents, >= 0 (the paper's eq. 3 uses 1).
    bins : int
        Frequency bands for comparing spectra of frames of different sizes, >= 2.

    Returns
    -------
    NoiseSimilarity
        ``.value`` in [0, 1], 1 when levels and spectral shapes agree.

    Raises
    ------
    FidelityError
        Not Noise3D results, no spectra (computed from merged sums without frames),
        different estimators, or a SiTF slope on only one of them.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> rng = np.random.default_rng(1)
    >>> real = irf.noise.noise3d(rng.normal(100, 2, (8, 32, 32)))
    >>> sim = irf.noise.noise3d(rng.normal(100, 2, (8, 32, 32)))
    >>> irf.noise.noise_similarity(real, sim).value > 0.95
    True

    References
    ----------
    Acta Photonica Sinica 41(5):547 (2012), eqs. 3-4 (curve similarity); D'Agostino & Webb,
    Proc. SPIE 1488 (1991) (3-D noise); Bhattacharyya, Bull. Calcutta Math. Soc. 35 (1943).
    """
    for who, noise in (("real", real_noise), ("simulated", sim_noise)):
        if getattr(noise, "spectra", None) is None:
            raise FidelityError(f"{who} noise has no spectra: compute it with irfidelity.noise.noise3d(frames, "
                                f"spectra=True) (merged NoiseSums carry no frames for the temporal spectra)")
        if noise.spectra.temporal_row is None:
            raise FidelityError(f"{who} noise has no temporal spectra (computed from sums without frames)")
    if real_noise.corrected != sim_noise.corrected:
        raise FidelityError("one noise result is corrected and the other classical; use the same `corrected`")
    slopes = (real_noise.sitf_slope, sim_noise.sitf_slope)
    if (slopes[0] is None) != (slopes[1] is None):
        raise FidelityError("only one noise result has a SiTF slope; give sitf= to both or to neither")
    units = "frame" if slopes[0] is None else "temperature"
    try:
        al, be = float(alpha), float(beta)
    except (TypeError, ValueError):
        raise FidelityError(f"alpha and beta must be numbers, got {alpha!r}, {beta!r}") from None
    if not (al >= 0 and be >= 0 and math.isfinite(al) and math.isfinite(be)):
        raise FidelityError(f"alpha and beta must be finite and >= 0, got {alpha!r}, {beta!r}")
    if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 2:
        raise FidelityError(f"bins must be an integer >= 2, got {bins!r}")
    a, b = _levels(real_noise, "real", units), _levels(sim_noise, "simulated", units)
    va, vb = np.array([a[k] for k in NOISE_PARTS]), np.array([b[k] for k in NOISE_PARTS])
    scale = max(float(va.max()), float(vb.max()))
    if scale == 0:
        mu = 1.0
    else:
        va, vb = va / scale, vb / scale
        mu = min(1.0, float(2 * (va @ vb) / (va @ va + vb @ vb)))
    fixed = (_fixed_share(a) + _fixed_share(b)) / 2
    weights = {"fixed_row": fixed / 2, "fixed_col": fixed / 2,
               "temporal_row": (1 - fixed) / 2, "temporal_col": (1 - fixed) / 2}
    overlap = {k: _bhattacharyya(_bands_of(real_noise, k, int(bins)), _bands_of(sim_noise, k, int(bins)))
               for k in NOISE_SPECTRA}
    rho = float(min(1.0, sum(weights[k] * overlap[k] for k in NOISE_SPECTRA)))
    value = float(min(1.0, mu ** al * rho ** be))
    total_mu = similarity_mu(math.sqrt(float(va @ va)), math.sqrt(float(vb @ vb))) if scale else 1.0
    return NoiseSimilarity(value=value, mu=mu, rho=rho, levels_real=a, levels_sim=b, units=units,
                           overlap=overlap, weights=weights, bins=int(bins), alpha=al, beta=be, total_mu=total_mu,
                           real=real_noise, sim=sim_noise)
