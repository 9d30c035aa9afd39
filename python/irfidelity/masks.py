"""Which pixel pairs are scored: a mask image and/or a region of interest, on the real frame's grid.

``mask`` is a 2-D array (non-zero = scored) or the path of a mask image (PNG, TIFF, ``.npy``;
non-zero = scored); ``roi`` a rectangle, ``"Y0:Y1,X0:X1"`` (rows, then columns, 0-based, end
excluded; an end left out is the frame's edge) or ``(y0, y1, x0, x1)`` as the other ROIs of
the library (:func:`irfidelity.noise.noise3d`, :func:`irfidelity.curves.ctf_from_bars`). Given
both, the pixels scored are their intersection. :func:`scoring_mask` checks them against the
frames' shape (a wrong shape, an ROI outside the frame or a mask that leaves no pixel is a
:class:`~irfidelity.FidelityError` naming ``mask`` or ``roi``) and returns a
:class:`ScoringMask`: the values as one C-contiguous bool array (1 byte a pixel, held once
for a whole sequence) and what a report records of it.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import FidelityError, ShapeError

__all__ = ["ScoringMask", "MaskSpec", "parse_roi", "scoring_mask"]

_ROI_TEXT = re.compile(r"^\s*(\d*):(\d*)\s*,\s*(\d*):(\d*)\s*$")
_ROI_FORM = "Y0:Y1,X0:X1 (rows, then columns; 0-based, end excluded) or (y0, y1, x0, x1)"


def _roi_bounds(roi: Any) -> tuple[int | None, int | None, int | None, int | None]:
    """The four bounds of ``roi`` as given (None: the frame's edge)."""
    if isinstance(roi, str):
        m = _ROI_TEXT.match(roi)
        if m is None:
            raise FidelityError(f"roi: expected {_ROI_FORM}, got {roi!r}", option="roi")
        return tuple(int(v) if v else None for v in m.groups())  # type: ignore[return-value]
    values = list(roi) if isinstance(roi, (tuple, list)) else []
    if len(values) != 4 or not all(v is None or (isinstance(v, (int, np.integer)) and not isinstance(v, bool))
                                   for v in values):
        raise FidelityError(f"roi: expected {_ROI_FORM}, got {roi!r}", option="roi")
    return tuple(None if v is None else int(v) for v in values)  # type: ignore[return-value]


def parse_roi(roi: Any, shape: tuple[int, int]) -> tuple[slice, slice]:
    """``roi`` (``"Y0:Y1,X0:X1"`` or ``(y0, y1, x0, x1)``) as two slices within ``shape``.

    Examples
    --------
    >>> parse_roi("10:20,:32", (120, 160))
    (slice(10, 20, None), slice(0, 32, None))
    >>> parse_roi((0, 500, 0, 10), (120, 160))
    Traceback (most recent call last):
    ...
    irfidelity.errors.FidelityError: roi (0, 500, 0, 10): rows 0:500 are not a non-empty range within the frame's 120 rows
    """
    y0, y1, x0, x1 = _roi_bounds(roi)
    rows = slice(y0 or 0, shape[0] if y1 is None else y1)
    cols = slice(x0 or 0, shape[1] if x1 is None else x1)
    for what, s, size in (("rows", rows, shape[0]), ("columns", cols, shape[1])):
        if not 0 <= s.start < s.stop <= size:
            raise FidelityError(f"roi {roi!r}: {what} {s.start}:{s.stop} are not a non-empty range within the "
                                f"frame's {size} {what}", option="roi")
    return rows, cols


def _mask_values(mask: Any, shape: tuple[int, int], channel: str | None) -> tuple[np.ndarray, str]:
    """The mask as bools (non-zero = scored) and where it came from (its path, or "array")."""
    if isinstance(mask, (str, os.PathLike)):
        from .frames import load_frame

        source = os.fsdecode(os.fspath(mask))
        try:
            values = _npy_mask(source) if source.lower().endswith(".npy") else None
            if values is None:
                values = np.asarray(load_frame(mask, channel=channel))
        except FidelityError as exc:
            raise type(exc)(f"mask: {exc}", option="mask") from None
    else:
        source, values = "array", np.asarray(mask)
    if values.shape != tuple(shape):
        where = f" {source!r}" if source != "array" else ""
        raise ShapeError(f"mask{where} has shape {values.shape}, the frames {tuple(shape)}: the mask is on the real "
                         f"frame's grid", option="mask")
    if values.dtype.kind not in "biuf":
        raise FidelityError(f"mask: expected a bool or numeric array (non-zero = scored), got dtype {values.dtype}",
                            option="mask")
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        where = f" {source!r}" if source != "array" else ""
        raise FidelityError(f"mask{where} holds {np.count_nonzero(~np.isfinite(values))} values that are not finite: "
                            f"expected 0 (left out) or a finite non-zero value (scored)", option="mask")
    return values != 0, source


def _npy_mask(path: str) -> np.ndarray | None:
    """A bool ``.npy`` mask (frames never are bool, so the frame reader refuses it); None for
    other dtypes, which the frame reader reads with its checks."""
    try:
        values = np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise FidelityError(f"{path}: not a readable .npy file ({exc})", option="mask") from None
    return values if values.dtype == np.bool_ else None  # read when the shape has been checked


@dataclass(frozen=True, eq=False)
class ScoringMask:
    """The pixels scored: ``values`` (bool, C-contiguous, the frames' shape), the ROI it
    came from (``(y0, y1, x0, x1)`` or None) and the mask's source (a path, ``"array"``, or
    None for an ROI alone)."""

    values: np.ndarray
    roi: tuple[int, int, int, int] | None = None
    source: str | None = None
    _digest: list = field(default_factory=list, repr=False)

    @property
    def pixels(self) -> int:
        """The number of pixels scored."""
        return int(np.count_nonzero(self.values))

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.values.shape)

    def digest(self) -> str:
        """A digest of the shape and the values (what a resumed run must share)."""
        if not self._digest:
            h = hashlib.blake2b(digest_size=16)
            h.update(repr(self.shape).encode())
            h.update(np.packbits(self.values, axis=None).tobytes())
            self._digest.append(h.hexdigest())
        return self._digest[0]

    def describe(self) -> dict:
        """What a report records: the pixels scored (of the frame's), the ROI, the mask's source."""
        return {"pixels": self.pixels, "of": int(self.values.size), "shape": list(self.shape),
                "roi": None if self.roi is None else list(self.roi), "mask": self.source}

    def note(self) -> str:
        """One sentence saying what was scored."""
        parts = []
        if self.source is not None:
            parts.append("the mask" if self.source == "array" else f"the mask {self.source}")
        if self.roi is not None:
            y0, y1, x0, x1 = self.roi
            parts.append(f"the ROI rows {y0}:{y1}, columns {x0}:{x1}")
        return (f"scored within {' and '.join(parts)}: {self.pixels} of {self.values.size} pixels "
                f"({100.0 * self.pixels / self.values.size:.3g} %) of every frame")


def scoring_mask(mask: Any, roi: Any, shape: tuple[int, int], channel: str | None = None) -> ScoringMask | None:
    """The pixels scored in frames of ``shape``, from ``mask`` and ``roi`` (None: every pixel).

    Examples
    --------
    >>> import numpy as np
    >>> m = scoring_mask(None, "2:4,:", (6, 8))
    >>> m.pixels, m.roi
    (16, (2, 4, 0, 8))
    >>> hot = np.zeros((6, 8)); hot[:, :2] = 1
    >>> scoring_mask(hot, (0, 3, 0, 8), (6, 8)).pixels
    6
    """
    if mask is None and roi is None:
        return None
    shape = (int(shape[0]), int(shape[1]))
    values, source = (np.ones(shape, dtype=bool), None) if mask is None else _mask_values(mask, shape, channel)
    box = None
    if roi is not None:
        rows, cols = parse_roi(roi, shape)
        box = (rows.start, rows.stop, cols.start, cols.stop)
        inside = np.zeros(shape, dtype=bool)
        inside[rows, cols] = True
        values = values & inside
    if not values.any():
        given = " and ".join(name for name, v in (("mask", mask), ("roi", roi)) if v is not None)
        raise FidelityError(f"{given} leave no pixel to score", option="mask" if mask is not None else "roi")
    return ScoringMask(np.ascontiguousarray(values, dtype=bool), box, source)


class MaskSpec:
    """``mask`` and ``roi`` as given to a sequence run, resolved once against the frames'
    shape (:meth:`resolve`: the same :class:`ScoringMask` for every plan of the run)."""

    def __init__(self, mask: Any = None, roi: Any = None, channel: str | None = None):
        self.mask, self.roi, self.channel = mask, roi, channel
        self._resolved: dict[tuple[int, int], ScoringMask | None] = {}

    @property
    def given(self) -> bool:
        return self.mask is not None or self.roi is not None

    def resolve(self, shape: tuple[int, int]) -> ScoringMask | None:
        key = (int(shape[0]), int(shape[1]))
        if key not in self._resolved:
            self._resolved[key] = scoring_mask(self.mask, self.roi, key, self.channel)
        return self._resolved[key]
