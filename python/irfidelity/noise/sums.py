"""The streamed pass: :class:`NoiseSums` (mergeable sufficient statistics of a recording)
and :func:`noise_sums` (one pass over a 3-D array or a frame sequence, in Rust).

A pass keeps per-pixel temporal sums and per-frame row and column sums, O(V·H + T·(V+H))
memory, never the cube; it is planned against the memory budget ``max_bytes`` in Rust
(fewer workers, or fewer frames decoded at once, when that fits and more would not;
docs/design.md §14). Integer frames are summed exactly, so merging the sums of
disjoint frame ranges equals one pass over all of them, bit for bit; Dask spreads a long
recording this way (map :func:`noise_sums` over frame ranges, reduce with
:meth:`NoiseSums.merge` in frame order).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .. import _core
from ..budget import resolve
from ..errors import FidelityError, FrameError, ShapeError
from ..frames import FRAME_DTYPES, FrameSequence
from ..stats import peak_and_valid

__all__ = ["NoiseSums", "noise_sums", "Region"]

PARTS = ("t", "v", "h", "tv", "th", "vh", "tvh")


#: ``(row_start, row_stop, col_start, col_stop)``, Python slice bounds of a region.
Region = tuple[int, int, int, int]

#: Frames per call when a source must be read in Python (.npy frames): bounded memory.
_PY_CHUNK = 16

#: Called with the analysed region's ``(rows, cols)`` and the sample type before a pass
#: allocates anything (how :func:`irfidelity.noise.noise3d` plans what follows the pass).
Planner = Callable[[tuple[int, int], np.dtype], None]


def sums_bytes(pixels: int, dtype: np.dtype) -> int:
    """Bytes of the per-pixel sums of a pass's result: exact sums of integer frames (Σx in
    64 bits, Σx² in 64, or 128 for uint32), compensated sums and the pivot of float frames."""
    if np.dtype(dtype).kind in "ui":
        return pixels * (8 + (16 if np.dtype(dtype) == np.uint32 else 8))
    return pixels * 40


class NoiseSums:
    """Sufficient statistics of a T × V × H recording for the 3-D noise decomposition.

    Made by :func:`noise_sums`; turned into components by :func:`irfidelity.noise.noise3d`.
    ``a.merge(b)`` is the sums of ``a``'s frames followed by ``b``'s (same region and
    sample type): equal to one pass over both, exactly for integer frames. Picklable.

    Attributes
    ----------
    frames, rows, cols : int
        T, V, H of the analysed region.
    dtype : str
        Sample type of the frames.
    bits : int or None
        The bit depth the values were checked against.
    """

    __slots__ = ("_raw", "bits")

    def __init__(self, raw: _core.NoiseSums, *, bits: int | None = None) -> None:
        self._raw = raw
        self.bits = bits

    @property
    def frames(self) -> int:
        return int(self._raw.frames)

    @property
    def rows(self) -> int:
        return int(self._raw.rows)

    @property
    def cols(self) -> int:
        return int(self._raw.cols)

    @property
    def dtype(self) -> str:
        return str(self._raw.dtype)

    def merge(self, other: NoiseSums) -> NoiseSums:
        """Sums of this recording's frames followed by ``other``'s."""
        if not isinstance(other, NoiseSums):
            raise FidelityError(f"can only merge NoiseSums with NoiseSums, got {type(other).__name__}")
        if self.bits != other.bits:
            raise FidelityError(f"cannot merge sums checked against bits={self.bits} and bits={other.bits}")
        return NoiseSums(self._raw.merge(other._raw), bits=self.bits)

    def decomposition(self) -> dict[str, Any]:
        """``{"mean", "ss": {part: Σ N_x² over the cube}, "ss_total"}`` (floats)."""
        return dict(self._raw.decomposition())

    def exact_ss(self) -> dict[str, int] | None:
        """Integer frames: ``N²·SS`` of every part and of the total as exact ints (their
        seven parts add up to the total); None for float frames."""
        raw = self._raw.exact_ss()
        return None if raw is None else dict(raw)

    def pixel_mean(self) -> np.ndarray:
        """Temporal mean of every pixel, shape (rows, cols)."""
        return self._raw.pixel_mean()

    def pixel_var(self) -> np.ndarray:
        """Temporal (population) variance of every pixel, shape (rows, cols)."""
        return self._raw.pixel_var()

    def row_means(self) -> np.ndarray:
        """Mean of every row of every frame, shape (frames, rows)."""
        return self._raw.row_means()

    def col_means(self) -> np.ndarray:
        """Mean of every column of every frame, shape (frames, cols)."""
        return self._raw.col_means()

    def value_range(self) -> dict[str, Any]:
        """``{"min", "max"}``; integer frames also ``{"lo", "hi", "at_lo", "at_hi"}``: the
        valid range and how many samples sit at each end (saturated or clipped)."""
        return dict(self._raw.value_range())

    def to_bytes(self) -> bytes:
        return bytes(self._raw.to_bytes())

    @classmethod
    def from_bytes(cls, data: bytes, *, bits: int | None = None) -> NoiseSums:
        return cls(_core.NoiseSums.from_bytes(data), bits=bits)

    def __reduce__(self) -> tuple[Any, ...]:
        return (_restore, (self.to_bytes(), self.bits))

    def __repr__(self) -> str:
        return f"NoiseSums({self.frames} frames of {self.rows} x {self.cols} {self.dtype})"


def _restore(data: bytes, bits: int | None) -> NoiseSums:
    return NoiseSums.from_bytes(data, bits=bits)


def _limits(dtype: np.dtype, bits: int | None) -> tuple[int, int] | None:
    if bits is not None and dtype.kind == "f":
        raise FidelityError("`bits` applies to integer frames; float frames have no bit depth")
    _, valid = peak_and_valid(dtype, bits, None)
    return valid


def _window(region: Region | None, rows: int, cols: int) -> tuple[int, int, int, int] | None:
    """``region`` (slice bounds) -> the kernel's ``(row0, col0, rows, cols)``."""
    if region is None:
        return None
    try:
        r0, r1, c0, c1 = (int(v) for v in region)
    except (TypeError, ValueError):
        raise FidelityError(f"roi must be (row_start, row_stop, col_start, col_stop), got {region!r}") from None
    if not (0 <= r0 < r1 <= rows and 0 <= c0 < c1 <= cols):
        raise ShapeError(f"roi {region!r} is empty or outside the {rows} x {cols} frames")
    return (r0, c0, r1 - r0, c1 - c0)


def _check_dtype(dtype: np.dtype, what: str) -> None:
    if dtype not in FRAME_DTYPES:
        raise ShapeError(f"{what}: unsupported dtype {dtype}; frames are one of "
                         + ", ".join(str(d) for d in FRAME_DTYPES))


def _workers(workers: int | None) -> int:
    if workers is None:
        return 0
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise FidelityError(f"workers must be a positive integer or None, got {workers!r}")
    return int(workers)


def _region(roi: Region | None, rows: int, cols: int) -> tuple[int, int]:
    window = _window(roi, rows, cols)
    return (rows, cols) if window is None else (window[2], window[3])


def _from_array(cube: np.ndarray, bits: int | None, roi: Region | None, workers: int, max_bytes: int | None,
                planner: Planner | None = None) -> NoiseSums:
    if cube.ndim != 3:
        raise ShapeError(f"frames: expected a 3-D array (frames, rows, cols), got shape {cube.shape}")
    _check_dtype(cube.dtype, "frames")
    if cube.shape[0] == 0 or cube.shape[1] == 0 or cube.shape[2] == 0:
        raise ShapeError(f"frames: empty array of shape {cube.shape}")
    if planner is not None:
        planner(_region(roi, cube.shape[1], cube.shape[2]), cube.dtype)
    cube = np.ascontiguousarray(cube)
    if not cube.dtype.isnative:
        cube = cube.astype(cube.dtype.newbyteorder("="))
    raw = _core.noise_sums_array(cube, limits=_limits(cube.dtype, bits),
                                 window=_window(roi, cube.shape[1], cube.shape[2]), workers=workers,
                                 max_bytes=resolve(max_bytes))
    return NoiseSums(raw, bits=bits)


def as_sequence(frames: Any, channel: str | None) -> FrameSequence:
    """A :class:`FrameSequence` of ``frames`` (directory, glob, list of paths, file)."""
    if isinstance(frames, FrameSequence):
        return frames
    if isinstance(frames, (str, os.PathLike)) or (isinstance(frames, Sequence) and not isinstance(frames, np.ndarray)):
        return FrameSequence(frames, channel=channel)
    raise FidelityError(f"frames must be a 3-D array, a directory, glob, file or list of paths, a FrameSequence "
                        f"or NoiseSums; got {type(frames).__name__}")


def _from_sequence(seq: FrameSequence, bits: int | None, roi: Region | None, workers: int, max_bytes: int | None,
                   planner: Planner | None = None) -> NoiseSums:
    sources = seq.sources
    paths = [path for path, _ in sources if path is not None]
    if len(paths) < len(sources):
        # a FrameSequence over an array
        return _from_array(np.stack([seq[i] for i in range(len(seq))]), bits, roi, workers, max_bytes, planner)
    first = seq[0]
    _check_dtype(first.dtype, seq.names[0])
    limits = _limits(first.dtype, bits)
    window = _window(roi, *first.shape)
    if planner is not None:
        planner(_region(roi, *first.shape), first.dtype)
    del first
    if any(str(path).lower().endswith(".npy") for path in paths):
        return _chunked(seq, bits, roi, workers, max_bytes)
    budget = max_bytes if max_bytes is not None else seq.max_bytes
    raw = _core.noise_sums_paths(paths, [g for _, g in sources], channel=seq.channel,
                                 max_pixels=seq.max_pixels, max_bytes=resolve(budget), limits=limits, window=window,
                                 workers=workers)
    return NoiseSums(raw, bits=bits)


def _chunked(seq: FrameSequence, bits: int | None, roi: Region | None, workers: int,
             max_bytes: int | None) -> NoiseSums:
    """Frames the Rust decoders do not read (.npy): a few at a time, merged in order."""
    total: NoiseSums | None = None
    shape = None
    for start in range(0, len(seq), _PY_CHUNK):
        block = []
        for i in range(start, min(start + _PY_CHUNK, len(seq))):
            frame = seq[i]
            if shape is None:
                shape = (frame.shape, frame.dtype)
            elif (frame.shape, frame.dtype) != shape:
                raise ShapeError(f"{seq.names[i]}: frame of shape {frame.shape} and dtype {frame.dtype}, but the "
                                 f"first frame is {shape[0]} {shape[1]}; all frames must have one shape and dtype")
            block.append(frame)
        part = _from_array(np.stack(block), bits, roi, workers, max_bytes)
        total = part if total is None else total.merge(part)
    assert total is not None
    return total


def noise_sums(frames: Any, *, bits: int | None = None, roi: Region | None = None,
               channel: str | None = None, workers: int | None = None, max_bytes: int | None = None,
               _planner: Planner | None = None) -> NoiseSums:
    """One streamed pass over a recording: the sums the 3-D noise decomposition needs.

    Parameters
    ----------
    frames : numpy.ndarray, path, sequence of paths or FrameSequence
        A 3-D array ``(frames, rows, cols)`` of uint8, uint16, int16, uint32, float16,
        float32 or float64; or a directory, glob, list of paths or multi-page TIFF (read
        through :class:`~irfidelity.FrameSequence`, decoded in Rust on ``workers`` threads
        with the GIL released; one decoded frame per worker in memory).
    bits : int, optional
        Bit depth of integer frames: values above ``2**bits - 1`` are an error naming the
        frame and position, and values at ``0`` or ``2**bits - 1`` are counted as clipped.
    roi : (row_start, row_stop, col_start, col_stop), optional
        Analyse this region of every frame (e.g. the blackbody's aperture).
    channel : str, optional
        Channel of multi-channel files.
    workers : int, optional
        Threads (default: all cores). The result does not depend on it.
    max_bytes : int, optional
        The pass's memory budget (default :data:`irfidelity.budget.DEFAULT_MAX_BYTES`; for a
        :class:`~irfidelity.FrameSequence`, its ``max_bytes`` when set): the per-pixel sums of
        every worker and the frames decoded at once (an array given is the caller's and not
        counted). Fewer workers, or fewer frames at once, run when that fits and more would
        not; a :class:`FidelityError` when one worker reading one frame at a time does not fit.

    Returns
    -------
    NoiseSums

    Raises
    ------
    ShapeError
        Frames of different shapes or dtypes (naming the frame), or a bad ``roi``.
    RangeError
        NaN/Inf (count and first position), or integers outside ``bits``.
    FrameError
        An unreadable frame file.
    FidelityError
        The pass does not fit ``max_bytes``.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> cube = np.random.default_rng(0).integers(1000, 1100, (8, 16, 16), dtype=np.uint16)
    >>> a = irf.noise.noise_sums(cube[:3]); b = irf.noise.noise_sums(cube[3:])
    >>> a.merge(b).exact_ss() == irf.noise.noise_sums(cube).exact_ss()
    True
    """
    w = _workers(workers)
    if bits is not None and (isinstance(bits, bool) or not isinstance(bits, (int, np.integer))):
        raise FidelityError(f"bits must be an integer, got {bits!r}")
    if isinstance(frames, np.ndarray):
        return _from_array(frames, bits, roi, w, max_bytes, _planner)
    seq = as_sequence(frames, channel)
    if len(seq) == 0:
        raise FrameError("no frames")
    return _from_sequence(seq, bits, roi, w, max_bytes, _planner)
