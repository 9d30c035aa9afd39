"""A registered pair ready for the image statistics (paper §2.4, docs/registration.md).

With ``config.register`` set, a single pair is registered and a sequence is registered once
(on its first readable pair); then every pair is scored through that registration: the real
frame as float64, the simulated frame resampled onto it (:meth:`Registration.apply`), and
the overlap as the mask, so pixels the simulated frame does not cover never count. The bit
depth is checked on the integer frames first, since the resampled ones are floats.

Memory (docs/design.md §14): :func:`aligned_pair` plans its peak before resampling (both
frames as given, the real one as float64, the resampled one with its overlap, the scored
mask: :data:`ALIGNED_BYTES` a pixel besides the frames) against ``max_bytes``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import budget
from .config import ScoringConfig
from .errors import RangeError

__all__ = ["find_registration", "aligned_pair", "check_levels", "ALIGNED_BYTES"]

#: Bytes a pixel a registered pair holds besides its two frames: the real frame as float64
#: (8), the resampled simulated frame and its overlap (9), the scored mask (1), and the
#: masks of scoring it (:data:`irfidelity.evaluation.SCORING_BYTES`).
ALIGNED_BYTES = 21


def check_levels(frame: np.ndarray, valid: tuple[int, int] | None, which: str) -> None:
    """Integer samples within ``valid`` (what the kernel checks on unregistered frames)."""
    if valid is None or frame.size == 0 or frame.dtype.kind not in "ui":
        return
    lo, hi = int(frame.min()), int(frame.max())
    if lo < valid[0] or hi > valid[1]:
        bad = lo if lo < valid[0] else hi
        raise RangeError(f"{which} frame: value {bad} outside the valid range {valid[0]} .. {valid[1]} (set bits to "
                         f"the camera's bit depth, or leave it unset)", option="bits")


def find_registration(real: np.ndarray, sim: np.ndarray, config: ScoringConfig, mask: Any = None,
                      max_bytes: int | None = None) -> Any:
    """The registration of ``sim`` onto ``real`` that ``config`` asks for (model, method),
    within the memory budget ``max_bytes``."""
    from .registration import register

    return register(real, sim, model=config.register, method=config.register_method,
                    mask=None if mask is None else np.asarray(mask, dtype=bool), max_bytes=max_bytes)


def check_aligned(real: np.ndarray, sim: np.ndarray, mask: Any, max_bytes: int | None) -> None:
    """The plan of :func:`aligned_pair` (and of the statistics of its result) against
    ``max_bytes``: the frames and mask as given, and :data:`ALIGNED_BYTES` a pixel."""
    held = budget.nbytes(real, sim, None if mask is None else np.asarray(mask))
    budget.check("resampling and scoring a registered pair", real.shape, held + ALIGNED_BYTES * real.size, max_bytes)


def aligned_pair(real: Any, sim: Any, registration: Any, mask: Any = None,
                 valid: tuple[int, int] | None = None,
                 max_bytes: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(real as float64, sim resampled onto it, mask of the scored pixels)``.

    The mask is the overlap (where every interpolation tap lies inside the simulated frame)
    and ``mask`` when given. ``valid``: the allowed integer levels, checked before resampling.
    The peak is checked against ``max_bytes`` first (:func:`check_aligned`).
    """
    real, sim = np.asarray(real), np.asarray(sim)
    check_aligned(real, sim, mask, max_bytes)
    check_levels(real, valid, "real")
    check_levels(sim, valid, "sim")
    keep_sim = None if mask is None else np.asarray(mask, dtype=bool)
    aligned, overlap = registration.apply(sim, mask=keep_sim, max_bytes=max_bytes)
    keep = overlap if keep_sim is None else overlap & keep_sim
    return real.astype(np.float64), aligned, keep
