"""What every decode of a file by the Rust core takes and gives: the page number and decoding
limits it takes, checked before the core sees them (an error names the file and the argument),
and the sample types a decoded frame may have. Frames (:mod:`irfidelity.frames`) and
radiometric records (:mod:`irfidelity.radiometry`) are decoded with them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import _core
from .errors import FrameError

__all__ = ["FRAME_DTYPES", "check_page", "check_limit"]

#: dtypes a frame may have (the dtypes the metrics accept).
FRAME_DTYPES = tuple(np.dtype(t) for t in _core.SUPPORTED_DTYPES)

_LARGEST = 2**63 - 1  # what the decoders count in


def check_page(path: str, page: Any) -> int:
    """A page number: an integer in 0..2^63-1."""
    if isinstance(page, bool) or not isinstance(page, (int, np.integer)) or not 0 <= page <= _LARGEST:
        raise FrameError(f"{path}: page must be an integer in 0..2^63-1, got {page!r}", option="page")
    return int(page)


def check_limit(path: str, name: str, value: Any) -> int | None:
    """A decoding limit (``max_pixels``, ``max_bytes``): None or an integer in 1..2^63-1."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value <= _LARGEST:
        raise FrameError(f"{path}: {name} must be an integer in 1..2^63-1, got {value!r}", option=name)
    return int(value)
