"""The memory budget (docs/design.md §14), Python side.

``max_bytes`` bounds everything one frame pair's work holds at its peak: both frames (as
decoded or given), their float64 copies, registration, resampling, statistics, maps and
report images. Every step plans its peak from the frame shape and checks it before
allocating; over budget is an error naming the operation, the frame size, the bytes
needed and the budget (:func:`check`, the same check and message as the Rust core's). A
run's ``max_memory`` is divided among its workers (:func:`per_pair`). Before any budget, a
decode refuses a frame of more than ``max_pixels`` pixels (:data:`DEFAULT_MAX_PIXELS`, or
:func:`pixel_limit`'s for every decode within it).
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import os
import re
from typing import Any, Iterator

from . import _core
from .errors import FidelityError

__all__ = ["DEFAULT_MAX_BYTES", "DEFAULT_MAX_PIXELS", "BLOCK_PIXELS", "SCORING_BYTES", "WIDENED_BYTES", "pixel_limit",
           "max_pixels", "resolve", "per_pair", "parse_size", "check", "check_float64_copy", "nbytes", "cpu_workers",
           "row_blocks"]

#: The default per-pair budget, bytes (``rust/io/mod.rs``: 2 GiB).
DEFAULT_MAX_BYTES: int = int(_core.default_max_bytes())

#: The default pixel limit of a decode (``rust/io/mod.rs``: one 8192 x 8192 frame).
DEFAULT_MAX_PIXELS: int = int(_core.default_max_pixels())

_PIXEL_LIMIT: contextvars.ContextVar[int | None] = contextvars.ContextVar("irfidelity_pixel_limit", default=None)

#: Pixels per block of a pass that works a block of rows at a time instead of on frame-sized
#: temporaries (8 MiB of float64).
BLOCK_PIXELS = 1 << 20

#: Bytes a pixel that scoring a pair holds besides its frames: the masks of the real frame's
#: range (finite values, and those within the mask); float16 frames add their float32 copies
#: in the kernel (:data:`WIDENED_BYTES`).
SCORING_BYTES = 3
WIDENED_BYTES = 8

_UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}
_MOST = (1 << 64) - 1
_LARGEST = 1 << 63  # the core takes budgets in 1..2^63-1


def _positive_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise FidelityError(f"{name} must be a positive number of bytes, got {value!r}", option=name)
    return int(value)


def resolve(max_bytes: int | None) -> int:
    """The per-pair budget in bytes: ``max_bytes``, or :data:`DEFAULT_MAX_BYTES` for None."""
    return DEFAULT_MAX_BYTES if max_bytes is None else _positive_int(max_bytes, "max_bytes")


def cpu_workers() -> int:
    """The threads a run uses when ``workers`` is not given (the cores this process may use)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def per_pair(max_bytes: int | None, max_memory: int | None, workers: int | None) -> int | None:
    """The per-pair budget of a run of ``workers`` threads (None: :func:`cpu_workers`):
    ``max_memory // workers``, or the smaller of that and ``max_bytes`` when both are given;
    ``max_bytes`` without ``max_memory`` (None: the default).

    Examples
    --------
    >>> per_pair(None, 4 << 30, 2) == 2 << 30
    True
    >>> per_pair(1 << 30, 4 << 30, 2) == 1 << 30
    True
    """
    if max_bytes is not None:
        max_bytes = _positive_int(max_bytes, "max_bytes")
    if max_memory is None:
        return max_bytes
    share = _positive_int(max_memory, "max_memory") // (workers or cpu_workers())
    if share < 1:
        raise FidelityError(f"max_memory of {max_memory} bytes leaves nothing to each of {workers} workers",
                            option="max_memory")
    return share if max_bytes is None else min(share, max_bytes)


def parse_size(text: str) -> int:
    """A size in bytes from ``"2G"``, ``"512M"``, ``"64k"``, ``"1.5GiB"`` or plain bytes (``"1000"``);
    K, M, G, T are powers of 1024.

    Examples
    --------
    >>> parse_size("2G"), parse_size("512M"), parse_size("1000")
    (2147483648, 536870912, 1000)
    """
    found = re.fullmatch(r"\s*(\d+(?:\.\d*)?|\.\d+)\s*([kmgt]?)(?:i?b)?\s*", str(text), re.IGNORECASE)
    if found is None:
        raise FidelityError(f"expected a size such as 2G, 512M or a number of bytes, got {text!r}", option="max_memory")
    value = float(found.group(1)) * _UNITS[found.group(2).lower()]
    if not (math.isfinite(value) and value >= 1):
        raise FidelityError(f"expected a size of at least 1 byte, got {text!r}", option="max_memory")
    if value >= _LARGEST:
        raise FidelityError(f"expected a size below 8 EiB (2^63 bytes), got {text!r}", option="max_memory")
    return int(value)


def nbytes(*arrays: Any) -> int:
    """Bytes of the arrays given (None counts nothing)."""
    return sum(int(getattr(a, "nbytes", 0)) for a in arrays if a is not None)


def check(operation: str, shape: tuple[int, ...], bytes_needed: float, max_bytes: int | None, *,
          kind: str = "value") -> None:
    """Raise when ``operation`` on frames of ``shape`` would hold ``bytes_needed`` at its
    peak, more than ``max_bytes`` (None: the default): a :class:`FidelityError`
    (``kind="registration"``: :class:`RegistrationError`) naming the operation, the frame size,
    the bytes needed, the budget and how to raise it."""
    needed = min(int(math.ceil(bytes_needed)), _MOST)  # beyond counting is beyond any budget
    _core.check_budget(operation, (int(shape[0]), int(shape[1])), needed, resolve(max_bytes), kind)


def check_float64_copy(operation: str, values: Any, max_bytes: int | None, held: int = 0) -> None:
    """:func:`check` for making a float64 copy of ``values`` (a conversion to temperature) while
    ``values`` and ``held`` more bytes (the pair's other frames) stay in memory."""
    beside = " beside the pair's other frames" if held else ""
    check(operation + beside, values.shape, held + values.nbytes + 8 * values.size, max_bytes)


def row_blocks(shape: tuple[int, ...], pixels: int = BLOCK_PIXELS) -> list[slice]:
    """Slices of whole rows (the first axis) of about ``pixels`` pixels each, covering ``shape``:
    the blocks of a pass whose temporaries stay that small, whatever the frame size."""
    rows = int(shape[0]) if shape else 1
    per_row = max(1, math.prod(int(n) for n in shape[1:]))
    step = max(1, pixels // per_row)
    return [slice(start, start + step) for start in range(0, rows, step)]


@contextlib.contextmanager
def pixel_limit(max_pixels: int) -> Iterator[None]:
    """Within the block, decodes given no ``max_pixels`` allow frames of up to ``max_pixels``
    pixels instead of :data:`DEFAULT_MAX_PIXELS` (what ``--max-pixels`` does for a command):
    every path a call decodes, its real_ref, masks and curves included.

    >>> import irfidelity as irf
    >>> with irf.budget.pixel_limit(16384 * 16384):
    ...     irf.budget.max_pixels(None)
    268435456
    """
    if isinstance(max_pixels, bool) or not isinstance(max_pixels, int) or not 1 <= max_pixels < _LARGEST:
        raise FidelityError(f"max_pixels must be a number of pixels in 1..2^63-1, got {max_pixels!r}",
                            option="max_pixels")
    token = _PIXEL_LIMIT.set(int(max_pixels))
    try:
        yield
    finally:
        _PIXEL_LIMIT.reset(token)


def max_pixels(given: int | None) -> int:
    """The pixel limit of a decode: ``given``, else :func:`pixel_limit`'s, else the default."""
    if given is not None:
        return given
    limit = _PIXEL_LIMIT.get()
    return DEFAULT_MAX_PIXELS if limit is None else limit
