"""Command-line flags that say what is scored and how it is judged: ``--mask``, ``--roi``,
``--real-ref``, ``--regions`` with ``--region-names`` (single pairs) and ``--tolerance``."""

from __future__ import annotations

import argparse
import re
from typing import Any

import numpy as np

from ..errors import FidelityError
from ..tolerances import Tolerances, parse_tolerance
from .output import UsageError

__all__ = ["pair_flags", "tolerance_flags", "parse_roi", "region_flags", "parse_region_names"]

_ROI = re.compile(r"^\s*(\d*):(\d*)\s*,\s*(\d*):(\d*)\s*$")


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


def parse_roi(text: str, shape: tuple[int, int]) -> tuple[slice, slice]:
    """``"Y0:Y1,X0:X1"`` (an end left out: the frame's edge) as two slices within ``shape``.

    Examples
    --------
    >>> parse_roi("10:20,:32", (120, 160))
    (slice(10, 20, None), slice(0, 32, None))
    """
    m = _ROI.match(text)
    if m is None:
        raise UsageError(f"--roi: expected Y0:Y1,X0:X1 (rows, then columns; 0-based, end excluded), got {text!r}")
    y0, y1, x0, x1 = (int(v) if v else None for v in m.groups())
    rows = slice(y0 or 0, shape[0] if y1 is None else y1)
    cols = slice(x0 or 0, shape[1] if x1 is None else x1)
    for what, s, size in (("rows", rows, shape[0]), ("columns", cols, shape[1])):
        if not s.start < s.stop <= size:
            raise UsageError(f"--roi {text!r}: {what} {s.start}:{s.stop} are not a non-empty range within the "
                             f"frame's {size} {what}")
    return rows, cols


def _mask_file(path: str, shape: tuple[int, int]) -> np.ndarray:
    from ..frames import load_frame

    try:
        values = np.asarray(load_frame(path))
    except FidelityError as exc:
        raise UsageError(f"--mask: {exc}") from None
    if values.shape != shape:
        raise UsageError(f"--mask {path!r}: shape {values.shape} differs from the frames' {shape}")
    return values != 0


def pair_flags(a: argparse.Namespace, real_channel: str | None) -> dict[str, Any]:
    """``evaluate``'s ``mask`` (from ``--mask`` and ``--roi``, both: their intersection) and
    ``real_ref``."""
    options: dict[str, Any] = {"real_ref": a.real_ref}
    if a.mask is None and a.roi is None:
        return options
    from ..frames import load_frame

    shape = np.shape(load_frame(a.real, channel=real_channel))
    mask = np.ones(shape, dtype=bool) if a.mask is None else _mask_file(a.mask, shape)
    if a.roi is not None:
        rows, cols = parse_roi(a.roi, shape)
        inside = np.zeros(shape, dtype=bool)
        inside[rows, cols] = True
        mask &= inside
    if not mask.any():
        raise UsageError("--mask/--roi leave no pixel to score")
    options["mask"] = mask
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
