"""Sequence inputs as :class:`~irfidelity.FrameSequence`: directories, globs, lists of paths,
multi-page TIFFs, 3-D arrays and lists of 2-D arrays."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import FidelityError
from ..frames import FrameSequence

__all__ = ["as_sequence"]


def as_sequence(x: Any, which: str, channel: str | None = None, max_pixels: int | None = None,
                max_bytes: int | None = None) -> FrameSequence:
    """``x`` as a FrameSequence (``which`` names the side in messages)."""
    if isinstance(x, FrameSequence):
        return x
    if isinstance(x, np.ndarray):
        if x.ndim != 3:
            raise FidelityError(f"{which}: an array sequence must be 3-D (frames, rows, cols), got shape {x.shape}",
                                option=which)
        return FrameSequence(x)
    if isinstance(x, (list, tuple)) and x and all(isinstance(e, np.ndarray) for e in x):
        shapes = {e.shape for e in x}
        if len(shapes) != 1 or len(next(iter(shapes))) != 2:
            raise FidelityError(f"{which}: a list of arrays must hold 2-D frames of one shape, got {sorted(shapes)}",
                                option=which)
        return FrameSequence(np.stack(x))
    return FrameSequence(x, channel=channel, max_pixels=max_pixels, max_bytes=max_bytes)
