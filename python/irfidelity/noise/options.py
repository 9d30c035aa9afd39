"""How :func:`~irfidelity.noise.noise3d` measures: :class:`NoiseOptions`, checked once when made."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..curves.sitf import SiTFFit
from ..errors import FidelityError
from .sums import Region

__all__ = ["NoiseOptions"]

_DETRENDS = (None, "plane")
_CLIPPED = ("warn", "raise", "ignore")


def _slope(sitf: Any) -> float | None:
    if sitf is None:
        return None
    if isinstance(sitf, SiTFFit):
        return float(sitf.slope)
    try:
        slope = float(sitf)
    except (TypeError, ValueError):
        raise FidelityError(f"sitf must be a SiTFFit (irfidelity.curves.sitf_fit) or a slope, got {type(sitf).__name__}") from None
    if not math.isfinite(slope) or slope == 0:
        raise FidelityError(f"the SiTF slope must be finite and non-zero, got {sitf!r}")
    return slope


def _level(confidence: Any) -> float:
    try:
        level = float(confidence)
    except (TypeError, ValueError):
        raise FidelityError(f"confidence must be a number in (0, 1), got {confidence!r}") from None
    if not 0 < level < 1:
        raise FidelityError(f"confidence must lie in (0, 1), got {confidence!r}")
    return level


@dataclass(frozen=True)
class NoiseOptions:
    """The settings of a 3-D noise measurement (each described in :func:`irfidelity.noise.noise3d`,
    which takes them as ``options=NoiseOptions(...)`` or as keywords).

    Examples
    --------
    >>> from irfidelity.noise import NoiseOptions
    >>> NoiseOptions(bits=14, detrend="plane").spectra_pairs
    16
    >>> NoiseOptions(detrend="linear")
    Traceback (most recent call last):
    ...
    irfidelity.errors.FidelityError: detrend must be None or 'plane', got 'linear'
    """

    bits: int | None = None
    corrected: bool = True
    confidence: float = 0.95
    detrend: str | None = None
    roi: Region | None = None
    sitf: Any = None
    spectra: bool = True
    spectra_pairs: int = 16
    saturated: str = "warn"
    channel: str | None = None
    workers: int | None = None
    max_bytes: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.corrected, bool):
            raise FidelityError(f"corrected must be True or False, got {self.corrected!r}")
        if self.detrend not in _DETRENDS:
            raise FidelityError(f"detrend must be None or 'plane', got {self.detrend!r}")
        if self.saturated not in _CLIPPED:
            raise FidelityError(f"saturated must be one of {_CLIPPED}, got {self.saturated!r}")
        pairs = self.spectra_pairs
        if isinstance(pairs, bool) or not isinstance(pairs, (int, np.integer)) or pairs < 1:
            raise FidelityError(f"spectra_pairs must be a positive integer, got {pairs!r}")
        object.__setattr__(self, "confidence", _level(self.confidence))  # frozen: the checked value
        _slope(self.sitf)

    @property
    def sitf_slope(self) -> float | None:
        """The SiTF slope (signal units per kelvin), or None."""
        return _slope(self.sitf)
