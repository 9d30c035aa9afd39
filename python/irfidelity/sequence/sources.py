"""Sequence inputs as :class:`~irfidelity.FrameSequence`: directories, globs, lists of paths,
multi-page TIFFs, 3-D arrays and lists of 2-D arrays; :class:`FramePairs` reloads their pairs."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import FidelityError
from ..frames import FrameSequence

__all__ = ["as_sequence", "FramePairs"]


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


class FramePairs:
    """``pairs(index) -> (real frame, simulated frame)``: reloads the frames of a paired
    sequence (for a report's thumbnails). Picklable: it holds the two sequences (paths, or the
    arrays they were given as) and the pairing, never an open file or a closure."""

    def __init__(self, real: FrameSequence, sim: FrameSequence, pairs: Sequence[tuple[int | None, int | None]]):
        self.real, self.sim, self.pairs = real, sim, tuple(pairs)

    def __call__(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        r, s = self.pairs[index]
        if r is None or s is None:
            raise FidelityError(f"frame {index} has no partner")
        return self.real[r], self.sim[s]
