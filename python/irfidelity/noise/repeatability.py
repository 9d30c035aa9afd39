"""The ceiling from the real camera's 3-D noise: how close a second real frame of a still scene would be.

Two frames ``a`` and ``b`` of a still scene share the scene and the fixed pattern (σ_v, σ_h,
σ_vh); they differ by the temporal parts of the 3-D noise only. In the model of
:func:`irfidelity.noise.noise3d` every part is an independent random effect with the variance
``σ_p²`` (frame units), so the difference ``d = b − a`` of two independent frames is ::

    d[v, h] = Δ_t + Δ_tv[v] + Δ_th[h] + Δ_tvh[v, h],    var(Δ_p) = 2 σ_p²   (p = t, tv, th, tvh)

a per-frame offset, a row pattern, a column pattern and pixel noise, each √2 × the camera's σ.

The real frame given already carries one realisation of that noise, so ``a + d`` with ``d``
independent of ``a`` is not a second frame: its variance is that of ``a`` plus ``2σ²`` and its
covariance with ``a`` that of ``a`` (a real second frame has the same variance as ``a`` and the
covariance ``var(a) − σ_s²``, ``σ_s² = σ_tv² + σ_th² + σ_tvh²``). That bias is of second order in
``σ_s²/var(a)`` but grows to SSIM 2/3 instead of 1/2 when the noise is the scene. The second
frame is therefore made as ::

    b' = ā + κ (a − ā) + e,    κ = 1 − σ_s²/var(a),
    var(e_t) = 2 σ_t²,  var(e_p) = (1 + κ) σ_p²  (p = tv, th, tvh)

which has the real second frame's mean, variance, covariance with ``a`` and mean squared
difference ``2 Σ σ_p²`` exactly (in expectation); it is exact for a Gaussian scene and noise,
and beyond the second moments (the NMI of a strongly non-Gaussian scene) its bias is that of
replacing the noise-free scene by its linear estimate ``ā + κ (a − ā)``. Integer frames are
rounded to their type, the pixel variance lowered by the 1/12 that rounding adds (Sheppard).

* SSIM and PSNR follow in closed form from these moments (:func:`noise_ceiling`): the contrast
  term is 1, the structure term κ, the luminance term its mean over the frame offset
  ``δ ~ N(0, 2(σ_t² + σ_tv²/V + σ_th²/H + σ_tvh²/(VH)))`` (Gauss–Hermite), and the mean squared
  difference is ``2 (σ_t² + σ_tv² + σ_th² + σ_tvh²)``;
* NMI has no closed form: it is that of ``a`` and one seeded realisation ``b'``
  (:func:`second_frame`, seed :data:`NOISE_SEED`), so the same frame and noise give the same
  ceiling.
"""

from __future__ import annotations

import math
import statistics
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from .. import budget
from .. import stats as _stats
from ..ceiling import CEILING_COMPONENTS, CEILING_PAIRS, ceiling_peak, pair_ceiling
from ..config import ScoringConfig
from ..errors import FidelityError, NoiseWarning
from ..metrics import psnr_from_mse, ssim_from_moments
from ..normalize import normalize_psnr

__all__ = ["NOISE_SEED", "TEMPORAL_PARTS", "temporal_sigma", "second_frame", "noise_ceiling",
           "sequence_noise_ceiling"]

#: The seed of the realisation behind a noise ceiling's NMI.
NOISE_SEED = 27

#: The parts of the 3-D noise that differ between two frames (the others are the fixed pattern).
TEMPORAL_PARTS = ("t", "tv", "th", "tvh")

#: Gauss–Hermite nodes of the luminance term's mean over the frame offset.
_NODES = 24

#: Bytes a pixel the realisation holds besides the frame: the float64 frame, the pixel noise
#: and the copy in the frame's type.
_REALISATION_BYTES = 24


def temporal_sigma(noise: Any) -> dict[str, float]:
    """σ of the temporal parts ``t, tv, th, tvh`` (frame units) of a :class:`~irfidelity.noise.Noise3D`,
    or of a mapping of them (parts left out are 0).

    Examples
    --------
    >>> from irfidelity.noise.repeatability import temporal_sigma
    >>> temporal_sigma({"tvh": 2.0, "v": 5.0})                # σ_v is fixed pattern: common to both frames
    {'t': 0.0, 'tv': 0.0, 'th': 0.0, 'tvh': 2.0}
    """
    from .model import Noise3D

    sigma = noise.sigma if isinstance(noise, Noise3D) else noise
    if not isinstance(sigma, Mapping) or not any(p in sigma for p in TEMPORAL_PARTS):
        raise FidelityError(f"the real camera's noise must be a Noise3D (irfidelity.noise.noise3d of a uniform "
                            f"source) or a mapping of the temporal σ {list(TEMPORAL_PARTS)}, got {type(noise).__name__}",
                            option="real_noise")
    out = {}
    for part in TEMPORAL_PARTS:
        value = sigma.get(part, 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0 <= value < math.inf):
            raise FidelityError(f"σ_{part} of the real camera's noise must be a finite number >= 0, got {value!r}",
                                option="real_noise")
        out[part] = float(value)
    return out


def _spatial_variance(sigma: Mapping[str, float]) -> float:
    """The temporal noise's variance over one frame, σ_tv² + σ_th² + σ_tvh²."""
    return math.fsum(sigma[p] ** 2 for p in ("tv", "th", "tvh"))


def _frame(real: Any) -> np.ndarray:
    frame = np.asarray(real)
    if frame.ndim != 2:
        raise FidelityError(f"the noise ceiling needs a 2-D real frame, got shape {frame.shape}", option="real")
    return frame


def _frame_moments(real: np.ndarray, config: ScoringConfig, mask: Any) -> tuple[float, float]:
    """Mean and population variance of the real frame over its scored pixels."""
    st = _stats.pair_stats(real, real, mask=mask, need=("ssim",), nonfinite=config.nonfinite)
    moments = st.moments()
    return float(moments["mean_real"]), float(moments["var_real"])


def _shrink(sigma: Mapping[str, float], variance: float) -> float:
    """κ = 1 − σ_s²/var(a): the covariance of two real frames relative to one's variance."""
    noise = _spatial_variance(sigma)
    if noise == 0:
        return 1.0
    if noise >= variance:
        warnings.warn(f"the real camera's temporal noise (σ² {noise:.4g}) is at least the real frame's variance "
                      f"({variance:.4g}): the noise is in other units or gain, or the scene has no detail; the "
                      f"noise ceiling is that of two uncorrelated frames", NoiseWarning, stacklevel=3)
        return 0.0
    return 1.0 - noise / variance


def second_frame(real: np.ndarray, noise: Any, config: ScoringConfig | None = None, *, mask: Any = None,
                 seed: int = NOISE_SEED, max_bytes: int | None = None) -> np.ndarray:
    """A seeded second real frame of the scene of ``real``: ``ā + κ (real − ā) + e`` (module notes),
    in the type of ``real``.

    Parameters
    ----------
    real : 2-D array
        The real frame.
    noise : Noise3D or mapping
        The real camera's 3-D noise, in the frame's units (:func:`temporal_sigma`).
    config : ScoringConfig, optional
        Its ``bits`` bound integer frames; ``nonfinite`` as in scoring.
    mask : 2-D bool array, optional
        The scored pixels (the mean and variance are theirs).
    seed : int
        The realisation's seed.
    max_bytes : int, optional
        The memory budget (docs/design.md §14).

    Examples
    --------
    >>> import numpy as np
    >>> from irfidelity.noise.repeatability import second_frame
    >>> rng = np.random.default_rng(1)
    >>> real = (1000 + 100 * rng.standard_normal((256, 256))).astype(np.uint16)
    >>> other = second_frame(real, {"tvh": 4.0})
    >>> other.dtype, round(float(np.std(other.astype(float) - real)), 1)   # √2 · 4 = 5.66
    (dtype('uint16'), 5.6)
    """
    cfg = config if config is not None else ScoringConfig()
    frame = _frame(real)
    sigma = temporal_sigma(noise)
    mean, variance = _frame_moments(frame, cfg, mask)
    return _realisation(frame, sigma, cfg, mean, _shrink(sigma, variance), seed, max_bytes)


def _realisation(frame: np.ndarray, sigma: Mapping[str, float], cfg: ScoringConfig, mean: float, kappa: float,
                 seed: int, max_bytes: int | None) -> np.ndarray:
    """``mean + κ (frame − mean) + e`` in the frame's type (module notes)."""
    budget.check("the noise ceiling's second frame", frame.shape, _REALISATION_BYTES * frame.size, max_bytes)
    rng = np.random.default_rng(seed)
    is_int = frame.dtype.kind in "ui"
    out = frame.astype(np.float64)
    out -= mean
    out *= kappa
    out += mean + rng.normal(0.0, math.sqrt(2.0) * sigma["t"])
    rows, cols = frame.shape
    out += rng.normal(0.0, math.sqrt(1 + kappa) * sigma["tv"], (rows, 1))
    out += rng.normal(0.0, math.sqrt(1 + kappa) * sigma["th"], (1, cols))
    pixel_variance = (1 + kappa) * sigma["tvh"] ** 2 - (1 / 12 if is_int else 0.0)
    if pixel_variance > 0:
        pixels = rng.standard_normal(frame.shape)
        pixels *= math.sqrt(pixel_variance)
        out += pixels
        del pixels
    if not is_int:
        return out.astype(frame.dtype, copy=False)
    _, valid = _stats.peak_and_valid(frame.dtype, cfg.bits, cfg.numeric_peak)
    info = np.iinfo(frame.dtype)
    low, high = valid if valid is not None else (info.min, info.max)
    np.rint(out, out=out)
    np.clip(out, low, high, out=out)
    return out.astype(frame.dtype)


def _luminance_offset_variance(sigma: Mapping[str, float], shape: tuple[int, int]) -> float:
    """The variance of the difference of two frames' means."""
    rows, cols = shape
    return 2.0 * (sigma["t"] ** 2 + sigma["tv"] ** 2 / rows + sigma["th"] ** 2 / cols
                  + sigma["tvh"] ** 2 / (rows * cols))


def _expected_ssim(mean: float, variance: float, kappa: float, offset_variance: float,
                   config: ScoringConfig) -> float:
    """E[SSIM] of two frames with equal variance, covariance κ·variance and means differing by
    δ ~ N(0, offset_variance): the luminance term averaged over δ (Gauss–Hermite)."""
    nodes, weights = np.polynomial.hermite_e.hermegauss(_NODES)
    spread = math.sqrt(offset_variance)
    values = [ssim_from_moments(mean, mean + spread * float(x), variance, variance, kappa * variance,
                                alpha=config.ssim_exponents[0], beta=config.ssim_exponents[1],
                                gamma=config.ssim_exponents[2]).value for x in nodes]
    return max(math.fsum(float(w) * v for w, v in zip(weights, values)) / math.sqrt(2 * math.pi), 0.0)


def noise_ceiling(real: Any, noise: Any, components: tuple[str, ...], config: ScoringConfig | None = None, *,
                  mask: Any = None, peak: float | None = None, seed: int = NOISE_SEED,
                  max_bytes: int | None = None) -> dict[str, float]:
    """The ceiling of ``real`` from the real camera's 3-D noise: the image components a second
    real frame of the scene would reach (module notes).

    Parameters
    ----------
    real : 2-D array
        The real frame (in the units the noise was measured in).
    noise : Noise3D or mapping
        The real camera's 3-D noise (:func:`irfidelity.noise.noise3d` of a uniform source), or the
        temporal σ ``{"t", "tv", "th", "tvh"}`` (:func:`temporal_sigma`).
    components : tuple of str
        The components wanted; those of :data:`irfidelity.ceiling.CEILING_COMPONENTS` are given.
    config : ScoringConfig, optional
        The scoring settings (peak, bins, SSIM exponents, PSNR anchors).
    mask : 2-D bool array, optional
        The scored pixels.
    peak : float, optional
        The PSNR peak the simulator's pair used.
    seed : int
        The seed of the realisation behind NMI.
    max_bytes : int, optional
        The memory budget of the realisation (NMI only).

    Returns
    -------
    dict
        ``{"psnr"|"nmi"|"ssim": value}``: psnr and ssim in closed form, nmi from one seeded realisation.

    Examples
    --------
    >>> import numpy as np
    >>> from irfidelity import ScoringConfig
    >>> from irfidelity.noise.repeatability import noise_ceiling
    >>> rng = np.random.default_rng(0)
    >>> scene = np.add.outer(np.arange(64), np.arange(64)) * 4.0
    >>> real = scene + rng.normal(0, 20, scene.shape)          # a real frame: the scene and its noise
    >>> c = noise_ceiling(real, {"tvh": 20.0}, ("nmi", "ssim"), ScoringConfig(peak=512.0))
    >>> round(c["ssim"], 3), round(c["nmi"], 3)                # a second real frame: 0.965, 0.477
    (0.965, 0.457)
    """
    cfg = config if config is not None else ScoringConfig()
    frame = _frame(real)
    wanted = tuple(k for k in CEILING_COMPONENTS if k in components)
    sigma = temporal_sigma(noise)
    out: dict[str, float] = {}
    if "psnr" in wanted:
        numeric = ceiling_peak(frame, cfg, peak, mask)
        if numeric is None and frame.dtype.kind in "ui":
            numeric = _stats.peak_and_valid(frame.dtype, cfg.bits, None)[0]  # 2**bits − 1, else the type's
        if numeric is None:
            raise FidelityError("the PSNR ceiling of float frames needs a peak (the largest possible value)",
                                option="peak")
        mse = 2.0 * math.fsum(s ** 2 for s in sigma.values())
        out["psnr"] = float(normalize_psnr(psnr_from_mse(mse, numeric), anchors=cfg.psnr_anchors))
    if "nmi" in wanted or "ssim" in wanted:
        mean, variance = _frame_moments(frame, cfg, mask)
        kappa = _shrink(sigma, variance)
    if "nmi" in wanted:
        other = _realisation(frame, sigma, cfg, mean, kappa, seed, max_bytes)
        out["nmi"] = pair_ceiling(frame, other, ("nmi",), cfg, mask=mask)["nmi"]
    if "ssim" in wanted:
        out["ssim"] = _expected_ssim(mean, variance, kappa, _luminance_offset_variance(sigma, frame.shape), cfg)
    return {k: out[k] for k in wanted}


def sequence_noise_ceiling(real: Any, noise: Any, components: tuple[str, ...], config: ScoringConfig,
                           peak: float | None = None, mask: Any = None) -> dict[str, float] | None:
    """The median noise ceiling of up to :data:`~irfidelity.ceiling.CEILING_PAIRS` real frames
    spread over the sequence ``real`` (over ``mask`` when given); None when no frame decodes."""
    count = len(real)
    found: list[dict[str, float]] = []
    for t in sorted({int(round(i)) for i in np.linspace(0, count - 1, min(CEILING_PAIRS, count))}):
        try:
            found.append(noise_ceiling(real[t], noise, components, config, mask=mask, peak=peak))
        except FidelityError:
            continue  # an unreadable frame is the scoring's error row, not the ceiling's
    if not found:
        return None
    return {k: float(statistics.median(c[k] for c in found)) for k in found[0]}
