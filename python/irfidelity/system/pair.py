"""The public entry: :func:`transfer` of a frame pair (frames, masks, registration, units)."""

from __future__ import annotations

import math
import os
from typing import Any, Mapping

import numpy as np

from .. import budget
from ..errors import FidelityError, ShapeError
from .result import Transfer, estimate
from .spectra import transfer_spectra

__all__ = ["transfer", "real_noise_variance", "aligned", "cropped"]


def real_noise_variance(real_noise: Any) -> float:
    """The real camera's white temporal noise variance in frame units from its 3-D noise
    (a :class:`~irfidelity.noise.Noise3D`, a mapping of σ such as ``Noise3D.sigma``, or one σ):
    ``σ_tvh² + σ_tv² + σ_th²`` (the temporal parts a tile's spectrum sees; σ_t is the frame
    mean's flicker, removed with each tile's mean)."""
    sigma = getattr(real_noise, "sigma", real_noise)
    if isinstance(sigma, Mapping):
        try:
            parts = [float(sigma[k]) for k in ("tvh", "tv", "th") if k in sigma]
        except (TypeError, ValueError):
            parts = []
        if not parts or "tvh" not in sigma or not all(math.isfinite(p) and p >= 0 for p in parts):
            raise FidelityError(f"real_noise: expected a Noise3D, one σ, or a mapping of σ with 'tvh' (and 'tv', 'th'); "
                                f"got {dict(sigma)!r}", option="real_noise")
        return float(sum(p * p for p in parts))
    if isinstance(sigma, (int, float, np.floating, np.integer)) and not isinstance(sigma, bool) \
            and math.isfinite(float(sigma)) and float(sigma) > 0:
        return float(sigma) ** 2
    raise FidelityError(f"real_noise: expected a Noise3D, one σ > 0 in frame units, or a mapping of σ; got {real_noise!r}",
                        option="real_noise")


def _frame(x: Any, which: str, channel: str | None, max_bytes: int | None) -> np.ndarray:
    if isinstance(x, (str, os.PathLike)):
        from ..frames import load_frame

        return load_frame(x, channel=channel, max_bytes=max_bytes)
    frame = np.asarray(x)
    if frame.ndim != 2:
        raise ShapeError(f"{which}: expected a 2-D frame, got shape {frame.shape}", option=which)
    return frame


def _in_unit(loaded: list, sources: tuple, unit: str, max_bytes: int | None) -> None:
    """The frames of ``loaded`` converted to ``unit`` in place, one at a time, each conversion
    within what the others leave of ``max_bytes``."""
    from ..config import ScoringConfig
    from ..temperature import to_temperature

    config = ScoringConfig(unit=unit)
    for i, (source, which) in enumerate(zip(sources, ("real", "sim", "real_ref"))):
        if loaded[i] is not None:
            held = budget.nbytes(*loaded[:i], *loaded[i + 1:])
            loaded[i] = to_temperature(loaded[i], source, which, config, max_bytes, held=held)


def aligned(real: np.ndarray, sim: np.ndarray, register: Any, mask: np.ndarray | None,
             max_bytes: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, Any]:
    """The frames registered: a translation as the whole-pixel overlap (the sub-pixel rest is
    taken out of the phase, no resampling); rotation and scale by resampling (Keys bicubic,
    whose own smoothing then counts in the ratio); with the mask of the pixels kept."""
    from ..registration import Registration, register as find

    reg = register if isinstance(register, Registration) else find(real, sim, model=str(register), mask=mask)
    if reg.model != "translation":
        aligned, valid = reg.apply(sim, order=3, max_bytes=max_bytes)
        keep = valid if mask is None else valid & mask
        return real, aligned, keep, reg
    dy, dx = (int(round(v)) for v in reg.shift)
    rows, cols = real.shape
    ry, sy = (slice(dy, rows), slice(0, rows - dy)) if dy >= 0 else (slice(0, rows + dy), slice(-dy, rows))
    rx, sx = (slice(dx, cols), slice(0, cols - dx)) if dx >= 0 else (slice(0, cols + dx), slice(-dx, cols))
    return real[ry, rx], sim[sy, sx], None if mask is None else mask[ry, rx], reg


def cropped(frames: list, mask: np.ndarray | None) -> tuple[list, np.ndarray | None]:
    """The frames and mask cut to the mask's bounding box (tiles then fit the scored region)."""
    if mask is None:
        return frames, None
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    return [None if f is None else f[box] for f in frames], mask[box]


def transfer(real: Any, sim: Any, *, mask: Any = None, roi: Any = None, real_ref: Any = None, real_noise: Any = None,
             register: Any = None, unit: str | None = None, tile: int | None = None,
             reference_frequency: float | None = None, channel: str | None = None,
             max_bytes: int | None = None) -> Transfer:
    """The simulator's MTF, gain, offset and noise relative to the real camera's, from one scene.

    Parameters
    ----------
    real, sim : 2-D arrays or frame paths
        The real frame and the simulated frame of the same scene (one shape).
    mask, roi : optional
        The pixels used (:mod:`irfidelity.masks`): a tile is used only when all of its pixels
        are scored and finite.
    real_ref : 2-D array or frame path, optional
        A second real frame of the scene: half the spectrum of the two real frames' difference
        is the real camera's noise, subtracted so it does not bias the ratio, and the
        denominator of ``noise_ratio``.
    real_noise : Noise3D, mapping of σ, or float, optional
        The real camera's 3-D noise (:func:`real_noise_variance`) instead of ``real_ref``.
    register : None, "translation", "rigid", "similarity" or Registration, optional
        Register the simulated frame first (:func:`irfidelity.register`). A translation is
        taken as the whole-pixel overlap with no resampling; small shifts need no registration
        at all (``Transfer.shift``).
    unit : "K" or "C", optional
        Convert both frames to temperature first (radiometric files, docs/radiometry.md).
    tile : int, optional
        The tile side (even, 8..256; default :func:`tile_size`).
    reference_frequency : float, optional
        The real camera's MTF50 in cy/px, where the ratio is read as an MTF50 mismatch
        (default :data:`REFERENCE_FREQUENCY`).
    channel : str, optional
        The channel of multi-channel frame files.
    max_bytes : int, optional
        The memory budget of decoding and resampling (:mod:`irfidelity.budget`); the spectra
        themselves hold a few tiles per worker, whatever the frame size.

    Returns
    -------
    Transfer

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> from scipy import ndimage
    >>> rng = np.random.default_rng(0)
    >>> scene = ndimage.gaussian_filter(rng.normal(0, 50, (256, 256)), 2)   # a textured scene
    >>> real = 3000 + scene + rng.normal(0, 1, scene.shape)
    >>> sim = 100 + 1.1 * ndimage.gaussian_filter(3000 + scene, 1.0) + rng.normal(0, 1, scene.shape)
    >>> t = irf.transfer(real, sim, real_noise=1.0)
    >>> round(t.gain, 2), round(t.ratio_at(0.1), 2)       # truth: 1.1 and exp(-2π²·0.1²) = 0.82
    (1.1, 0.83)

    References
    ----------
    Bendat & Piersol, *Random Data*, 4th ed. (2010), ch. 9 (frequency response from
    cross-spectra, coherence, random errors); Welch, IEEE Trans. Audio Electroacoust. 15(2)
    (1967); the "two-image" on-orbit MTF method of remote sensing (e.g. Helder et al.,
    Remote Sens. Environ. 88 (2003)).
    """
    loaded: list[Any] = [_frame(real, "real", channel, max_bytes), _frame(sim, "sim", channel, max_bytes),
                         None if real_ref is None else _frame(real_ref, "real_ref", channel, max_bytes)]
    if unit is not None:
        _in_unit(loaded, (real, sim, real_ref), unit, max_bytes)
    frames, ref = loaded[:2], loaded[2]
    if frames[0].shape != frames[1].shape or (ref is not None and ref.shape != frames[0].shape):
        raise ShapeError(f"real {frames[0].shape}, sim {frames[1].shape}"
                         + ("" if ref is None else f" and real_ref {ref.shape}") + ": expected one shape")
    from ..masks import scoring_mask

    scored = scoring_mask(mask, roi, frames[0].shape)
    keep = None if scored is None else scored.values
    if register is not None:
        r, s, keep, reg = aligned(frames[0], frames[1], register, keep, max_bytes)
        if ref is not None:
            ref = ref[tuple(slice(0, n) for n in r.shape)] if reg.model == "translation" and r.shape != ref.shape \
                else ref
        frames = [r, s]
    (r, s, ref), keep = cropped([frames[0], frames[1], ref], keep)
    variance, source = (None, None)
    if ref is not None:
        source = "real_ref"
    elif real_noise is not None:
        variance, source = real_noise_variance(real_noise), "real_noise"
    spectra = transfer_spectra(r, s, mask=keep, real_ref=ref, tile=tile, max_bytes=max_bytes)
    return estimate(spectra, real_variance=variance, noise_source=source, reference_frequency=reference_frequency)
