"""Write one grey frame: 16-bit PNG, float32 or 16-bit TIFF, or NPY — with the standard
library and numpy only (the rendered bar targets and edges of ``irfidelity targets``).

PNG: greyscale, bit depth 16 (PNG specification, ISO/IEC 15948), one zlib stream, filter 0.
TIFF: baseline, uncompressed, one strip, little-endian (TIFF 6.0); float32 frames carry
SampleFormat 3 (IEEE floating point).
"""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np

from .errors import FidelityError

__all__ = ["write_image", "FORMATS"]

#: The formats and their file extensions.
FORMATS = {"png": ".png", "tiff": ".tif", "npy": ".npy"}


def _uint16(frame: np.ndarray, what: str) -> np.ndarray:
    """The frame rounded to uint16; values outside 0..65535 are an error (never clipped)."""
    lo, hi = float(frame.min()), float(frame.max())
    if lo < -0.5 or hi >= 65535.5:
        raise FidelityError(f"{what}: values {lo:g}..{hi:g} do not fit a 16-bit image (0..65535); choose levels "
                            f"within it, or write NPY or TIFF (float)", option="levels")
    return np.rint(frame).astype(np.uint16)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png16_bytes(frame: np.ndarray) -> bytes:
    """A 16-bit greyscale PNG of a uint16 frame."""
    h, w = frame.shape
    rows = np.zeros((h, 1 + 2 * w), dtype=np.uint8)  # filter byte 0, then big-endian samples
    rows[:, 1:] = frame.astype(">u2").view(np.uint8).reshape(h, 2 * w)
    header = struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(rows.tobytes(), 6))
            + _chunk(b"IEND", b""))


def tiff_bytes(frame: np.ndarray) -> bytes:
    """A baseline little-endian TIFF of a uint16 or float32 frame (one uncompressed strip)."""
    h, w = frame.shape
    is_float = frame.dtype == np.float32
    data = np.ascontiguousarray(frame.astype("<f4" if is_float else "<u2")).tobytes()
    entries = [(256, 4, w), (257, 4, h), (258, 3, 32 if is_float else 16), (259, 3, 1), (262, 3, 1),
               (273, 4, 0), (277, 3, 1), (278, 4, h), (279, 4, len(data)), (339, 3, 3 if is_float else 1)]
    ifd_size = 2 + 12 * len(entries) + 4
    offset = 8 + ifd_size  # the pixels follow the one directory
    ifd = struct.pack("<H", len(entries))
    for tag, kind, value in entries:
        value = offset if tag == 273 else value
        packed = struct.pack("<HH", value, 0) if kind == 3 else struct.pack("<I", value)
        ifd += struct.pack("<HHI", tag, kind, 1) + packed
    return b"II*\x00" + struct.pack("<I", 8) + ifd + struct.pack("<I", 0) + data


def write_image(path: str | os.PathLike, frame: np.ndarray, fmt: str) -> None:
    """Write ``frame`` (2-D) as ``fmt``: "png" (16-bit, values rounded, 0..65535), "tiff"
    (float32) or "npy" (float64).

    Examples
    --------
    >>> import tempfile
    >>> from irfidelity import load_frame
    >>> path = os.path.join(tempfile.mkdtemp(), "ramp.png")
    >>> write_image(path, np.arange(12.0).reshape(3, 4) * 1000, "png")
    >>> load_frame(path)[2].tolist(), load_frame(path).dtype.name
    ([8000, 9000, 10000, 11000], 'uint16')
    """
    frame = np.asarray(frame, dtype=np.float64)
    where = os.fsdecode(os.fspath(path))
    if frame.ndim != 2 or min(frame.shape) < 1:
        raise FidelityError(f"{where}: expected a 2-D frame, got shape {frame.shape}")
    if not np.isfinite(frame).all():
        raise FidelityError(f"{where}: the frame holds NaN or Inf")
    if fmt == "npy":
        np.save(path, frame, allow_pickle=False)
        return
    if fmt == "png":
        payload = png16_bytes(_uint16(frame, where))
    elif fmt == "tiff":
        payload = tiff_bytes(frame.astype(np.float32))
    else:
        raise FidelityError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}", option="format")
    with open(path, "wb") as fh:
        fh.write(payload)
