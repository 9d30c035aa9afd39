"""Command-line flags that say what is scored and how it is judged: ``--mask``, ``--roi``,
``--real-ref`` (single pairs) and ``--tolerance``."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from ..errors import FidelityError
from ..masks import parse_roi, scoring_mask
from ..tolerances import Tolerances, parse_tolerance
from .output import UsageError

__all__ = ["pair_flags", "tolerance_flags", "parse_roi"]


def tolerance_flags(given: list[str], base: Tolerances) -> Tolerances:
    """``base`` with the limits of each ``--tolerance NAME=E,G,F`` replaced."""
    limits = base.to_dict()
    for text in given:
        try:
            name, values = parse_tolerance(text)
        except FidelityError as exc:
            raise UsageError(f"--tolerance: {exc}") from None
        limits[name] = list(values)
    return Tolerances.from_dict(limits)


def pair_flags(a: argparse.Namespace, real_channel: str | None) -> dict[str, Any]:
    """``evaluate``'s ``mask`` (from ``--mask`` and ``--roi``, both: their intersection) and
    ``real_ref``."""
    options: dict[str, Any] = {"real_ref": a.real_ref}
    if a.mask is None and a.roi is None:
        return options
    from ..frames import load_frame

    shape = np.shape(load_frame(a.real, channel=real_channel))
    options["mask"] = scoring_mask(a.mask, a.roi, shape).values  # type: ignore[union-attr]
    return options
