"""Command-line flags that say what is scored and how it is judged: ``--mask``, ``--roi``,
``--real-ref``, ``--regions`` with ``--region-names`` (single pairs) and ``--tolerance``."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from ..errors import FidelityError
from ..masks import parse_roi, scoring_mask
from ..tolerances import Tolerances, parse_tolerance
from .output import UsageError

__all__ = ["pair_flags", "tolerance_flags", "parse_roi", "region_flags", "parse_region_names"]


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


def parse_region_names(text: str) -> list[str] | dict[str, int]:
    """``--region-names``: ``"target,background"`` (labels 1, 2, ...) or ``"NAME=LABEL,..."``.

    Examples
    --------
    >>> parse_region_names("target,background")
    ['target', 'background']
    >>> parse_region_names("hot=3, sky=1")
    {'hot': 3, 'sky': 1}
    """
    items = [item.strip() for item in text.split(",")]
    if not all(items):
        raise UsageError(f"--region-names: expected NAME,NAME,... or NAME=LABEL,..., got {text!r}")
    with_labels = ["=" in item for item in items]
    if not any(with_labels):
        return items
    if not all(with_labels):
        raise UsageError(f"--region-names {text!r}: give every name a label (NAME=LABEL,...) or none (NAME,NAME,... "
                         "for labels 1, 2, ...)")
    names: dict[str, int] = {}
    for item in items:
        name, _, label = (part.strip() for part in item.partition("="))
        if not label.isdigit():
            raise UsageError(f"--region-names {text!r}: the label of {name!r} must be an integer, got {label!r}")
        if name in names:
            raise UsageError(f"--region-names {text!r}: {name!r} is named twice")
        names[name] = int(label)
    return names


def _label_file(path: str) -> np.ndarray:
    """A label image: a PNG or TIFF frame, or a ``.npy`` array of any integer (or bool) type."""
    from ..frames import load_frame

    try:
        if path.lower().endswith(".npy"):
            return np.load(path, allow_pickle=False)
        return np.asarray(load_frame(path))
    except FidelityError as exc:
        raise UsageError(f"--regions: {exc}") from None
    except (OSError, ValueError) as exc:
        raise UsageError(f"--regions {path!r}: not a readable label image ({exc})") from None


def region_flags(a: argparse.Namespace) -> dict[str, Any]:
    """``evaluate``'s ``regions`` from ``--regions`` and ``--region-names`` (empty without them)."""
    from ..regions import Regions

    if a.regions is None:
        if a.region_names is not None:
            raise UsageError("--region-names names the labels of --regions PATH, which is not given")
        return {}
    names = None if a.region_names is None else parse_region_names(a.region_names)
    try:
        return {"regions": Regions(_label_file(a.regions), names=names)}
    except FidelityError as exc:
        text = str(exc).removeprefix("regions: ")
        raise UsageError(f"--regions {a.regions!r}: {text}") from None
