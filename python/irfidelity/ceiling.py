"""The ceiling: how close two real frames of one scene come — the camera's own repeatability.

Two real frames of a still scene differ by the sensor's temporal noise, so no simulator can be
expected to come closer to a real frame than another real frame does. The image components of
real-vs-real are the ceiling (``report.ceiling``); the simulator's components divided by them
are ``report.relative``, and NMI and SSIM are graded relative to it
(:mod:`irfidelity.tolerances`), which makes their grades independent of the scene's contrast.

* one pair: ``real_ref=`` a second real frame of the same scene (:func:`pair_ceiling`);
* a sequence: consecutive real frames t and t + 1 (:func:`sequence_ceiling`; the median over
  up to :data:`CEILING_PAIRS` pairs spread over the sequence). A moving scene adds its motion to
  the difference, so the ceiling of a panning sequence is lower than the sensor's repeatability;
* the real camera's 3-D noise (``real_noise=``): the components a second real frame would reach,
  the temporal noise added to the real frame (:mod:`irfidelity.noise.repeatability`).

Where a report's ceiling came from is its ``ceiling_source`` (:data:`CEILING_SOURCES`). A pair
takes ``ceiling=`` before ``real_ref=`` before the noise; a sequence takes the noise, when the
real camera's is given, before its consecutive frames (a moving scene's are not the camera's
repeatability).
"""

from __future__ import annotations

import statistics
from typing import Any

import numpy as np

from . import stats as _stats
from .config import ScoringConfig
from .errors import FidelityError
from .image_components import image_components

__all__ = ["CEILING_COMPONENTS", "CEILING_PAIRS", "CEILING_SOURCES", "pair_ceiling", "ceiling_peak",
           "sequence_ceiling", "relative_to"]

#: The components that have a ceiling (the image components; psnr's is reported, not graded).
CEILING_COMPONENTS = ("psnr", "nmi", "ssim")

#: Where a ceiling came from, and the words a verdict says it with.
CEILING_SOURCES = {"given": "given", "real_ref": "two real frames", "sequence": "consecutive real frames",
                   "noise3d": "from the real camera's 3-D noise"}

#: Consecutive real pairs a sequence's ceiling is measured on (spread over the sequence).
CEILING_PAIRS = 8


def pair_ceiling(real: np.ndarray, real_ref: np.ndarray, components: tuple[str, ...], config: ScoringConfig,
                 mask: Any = None, peak: float | None = None) -> dict[str, float]:
    """The image components of two real frames of the scene, with the scoring settings
    (``peak``: the PSNR peak the simulator's pair used).

    Examples
    --------
    >>> import numpy as np
    >>> from irfidelity import ScoringConfig
    >>> from irfidelity.ceiling import pair_ceiling
    >>> rng = np.random.default_rng(0)
    >>> scene = np.add.outer(np.arange(64), np.arange(64)) * 4.0
    >>> a, b = scene + rng.normal(0, 20, scene.shape), scene + rng.normal(0, 20, scene.shape)
    >>> c = pair_ceiling(a, b, ("nmi", "ssim"), ScoringConfig(peak=512.0))
    >>> round(c["ssim"], 3), round(c["nmi"], 3)
    (0.965, 0.477)
    """
    wanted = tuple(k for k in CEILING_COMPONENTS if k in components)
    r, ref = np.asarray(real), np.asarray(real_ref)
    if r.shape != ref.shape:
        raise FidelityError(f"real_ref has shape {ref.shape}, the real frame {r.shape}: the ceiling needs a second "
                            "real frame of the same scene and size", option="real_ref")
    numeric_peak = ceiling_peak(r, config, peak, mask) if "psnr" in wanted else peak if peak is not None else \
        config.numeric_peak
    st = _stats.pair_stats(r, ref, bits=config.bits, peak=numeric_peak, bins=config.bins,
                           hist_range=config.hist_range, mask=mask, need=wanted, nonfinite=config.nonfinite)
    values, _ = image_components(st, wanted, config)
    return values


def ceiling_peak(real: np.ndarray, config: ScoringConfig, peak: float | None, mask: Any = None) -> float | None:
    """The PSNR peak of a ceiling: ``peak`` (the simulator's pair's), the configured number, the
    real frame's range over the scored pixels (``mask``) with ``peak="range"``, or None (the frame
    type's default)."""
    if peak is not None:
        return peak
    if config.numeric_peak is not None:
        return config.numeric_peak
    if config.peak == "range":
        return _stats.real_range(real, mask, config.nonfinite) or None
    return None


def sequence_ceiling(real: Any, components: tuple[str, ...], config: ScoringConfig,
                     peak: float | None = None, mask: Any = None) -> dict[str, float] | None:
    """The median ceiling over up to :data:`CEILING_PAIRS` pairs of consecutive real frames
    (t, t + 1) spread over the sequence ``real`` (a :class:`~irfidelity.FrameSequence`), over
    the pixels of ``mask`` when given (the run's); None for fewer than two frames or when no
    pair decodes."""
    count = len(real)
    if count < 2:
        return None
    starts = sorted({int(round(i)) for i in np.linspace(0, count - 2, min(CEILING_PAIRS, count - 1))})
    found: list[dict[str, float]] = []
    for t in starts:
        try:
            found.append(pair_ceiling(real[t], real[t + 1], components, config, mask=mask, peak=peak))
        except FidelityError:
            continue  # an unreadable frame is the scoring's error row, not the ceiling's
    if not found:
        return None
    return {k: float(statistics.median(c[k] for c in found)) for k in found[0]}


def relative_to(ceiling: dict[str, float] | None, components: dict[str, float]) -> dict[str, float] | None:
    """``{component: value / ceiling}`` for the components with a positive ceiling."""
    if not ceiling:
        return None
    return {k: components[k] / c for k, c in ceiling.items() if k in components and c > 0}
