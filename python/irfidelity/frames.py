"""Loading frames: single files and lazy sequences.

OpenEXR, PNG and TIFF files are decoded by the Rust core (``irfidelity._core``) with the
GIL released; ``.npy`` files are read with numpy. Every failure -- missing, unreadable,
truncated, corrupt, unsupported or oversized file -- raises
:class:`irfidelity.errors.FrameError` whose message names the path and the reason.

Decoded frames keep the file's own sample type: ``uint8``/``uint16`` PNG, ``uint8``,
``uint16``, ``int16``, ``uint32``, ``float16``, ``float32``, ``float64`` TIFF, and
``float16``/``float32``/``uint32`` EXR (float16 stays float16).
"""

from __future__ import annotations

import functools
import glob as _glob
import os
import re
import stat
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, NamedTuple, Self, Union, overload

import numpy as np

from . import _core, budget
from .decoding import FRAME_DTYPES, check_limit, check_page
from .errors import FidelityError, FrameError, RangeError
from .radiometry import UNITS, read_radiometry

__all__ = ["load_frame", "FrameSequence", "list_channels", "page_count", "page_chain", "PageChain", "natural_key",
           "display_name"]

PathLike = Union[str, "os.PathLike[str]"]

#: File extensions a directory or glob source picks up (case-insensitive).
FRAME_EXTENSIONS = (".exr", ".png", ".tif", ".tiff", ".npy", ".fff", ".seq")

#: Extensions of files that may hold several frames (pages), each a frame of a sequence.
MULTIPAGE_EXTENSIONS = (".tif", ".tiff", ".seq", ".csq")


@functools.lru_cache(maxsize=64)
def dtype_name(dtype: np.dtype) -> str:
    """``dtype.name``, remembered: numpy works it out in Python on every access (5 µs, several
    times per scored pair)."""
    return dtype.name


_GLOB_CHARS = re.compile(r"[*?\[]")


def default_max_pixels() -> int:
    """The pixel limit of a decode given no ``max_pixels``: :func:`irfidelity.budget.pixel_limit`'s
    within one, else the core's (one 8192 x 8192 frame)."""
    return budget.max_pixels(None)


def _is_npy(path: str) -> bool:
    return path.lower().endswith(".npy")


def default_max_bytes() -> int:
    """The default decoding budget of one frame, in bytes (every allocation of a decode)."""
    return int(_core.default_max_bytes())


def _load_npy(path: str, channel: str | None, page: int, limit: int) -> np.ndarray:
    if channel is not None:
        raise FrameError(f"{path}: .npy files have no channels (got channel={channel!r})")
    try:
        mode = os.stat(path).st_mode
    except OSError as e:
        raise FrameError(f"{path}: cannot open: {e.strerror or e}") from None
    if stat.S_ISDIR(mode):
        raise FrameError(f"{path}: is a directory, not an image file")
    if not stat.S_ISREG(mode):
        # opening a FIFO for reading blocks until a writer appears
        raise FrameError(f"{path}: not a regular file (a FIFO, socket or device); frames are read from regular files")
    try:
        # mmap reads the header only, so a lying shape is refused before allocating
        mapped = np.load(path, mmap_mode="r", allow_pickle=False)
    except FileNotFoundError as e:
        raise FrameError(f"{path}: cannot open: {e.strerror or e}") from None
    except IsADirectoryError:
        raise FrameError(f"{path}: is a directory, not an image file") from None
    except (OSError, ValueError, EOFError, TypeError, OverflowError, MemoryError) as e:
        raise FrameError(f"{path}: corrupt or invalid .npy file: {e}") from None
    if not isinstance(mapped, np.ndarray):
        raise FrameError(f"{path}: not a single numpy array (.npz archives are not frames)")
    if mapped.dtype not in FRAME_DTYPES:
        raise FrameError(
            f"{path}: unsupported dtype {mapped.dtype}; frames are one of "
            + ", ".join(str(d) for d in FRAME_DTYPES)
        )
    if mapped.ndim == 3:
        if page >= mapped.shape[0]:
            raise FrameError(f"{path}: page {page} out of range ({mapped.shape[0]} frames)")
        mapped = mapped[page]
    elif mapped.ndim == 2:
        if page != 0:
            raise FrameError(f"{path}: page {page} out of range (a 2-D array has one frame)")
    else:
        raise FrameError(f"{path}: expected a 2-D frame (or a 3-D stack), got shape {mapped.shape}")
    rows, cols = mapped.shape
    if rows == 0 or cols == 0:
        raise FrameError(f"{path}: empty image ({cols} x {rows} pixels)")
    if rows * cols > limit:
        raise FrameError(
            f"{path}: image of {cols} x {rows} pixels exceeds the limit of {limit} pixels; raise max_pixels "
            f"(--max-pixels) to load it"
        )
    try:
        return np.array(mapped, copy=True, order="C")
    except (OSError, ValueError) as e:  # truncated data section
        raise FrameError(f"{path}: corrupt or truncated .npy file: {e}") from None


def load_frame(
    path: PathLike,
    *,
    channel: str | None = None,
    page: int = 0,
    max_pixels: int | None = None,
    max_bytes: int | None = None,
    unit: str | None = None,
    **overrides: float,
) -> np.ndarray:
    """Load one frame as a 2-D numpy array in the file's own sample type, or in kelvin or °C.

    Parameters
    ----------
    path : str or os.PathLike
        An OpenEXR, PNG or TIFF file, a FLIR FFF or SEQ file or a radiometric JPEG (FLIR or
        DJI; recognised by their magic bytes), or a ``.npy`` file holding a 2-D array (or a
        3-D stack, indexed by ``page``). FLIR files give their raw counts (uint16).
    channel : str, optional
        Channel to decode. EXR: a channel name such as ``"Y"``, ``"R"``, ``"left.Y"``
        (``"part.channel"`` in multi-part files; a bare name works when unique).
        PNG/TIFF: ``"Y"``, ``"R"``, ``"G"``, ``"B"``, ``"A"`` or an index ``"0"``, ``"1"``...
        Default: the only channel, or ``"Y"`` if present; files with several colour
        channels and no ``"Y"`` raise :class:`FrameError` listing the channels.
    page : int, default 0
        Page of a multi-page TIFF, frame of a FLIR SEQ (or of a 3-D ``.npy`` stack). A page costs one
        directory read whatever its place: the file's chain of pages is walked once and kept.
        In a TIFF whose chain of pages breaks (a truncated file, a chain that loops back;
        :func:`page_chain`), the pages before the break load as usual (page 0 too) and a page
        from the break on raises :class:`FrameError` naming where and why the chain breaks.
    max_pixels : int, optional
        Refuse files whose header claims more pixels (default: one 8192 x 8192 frame, or
        the limit of an enclosing :func:`irfidelity.budget.pixel_limit`). Checked before the
        pixel buffer is allocated.
    max_bytes : int, optional
        The decoding budget in bytes: everything the decode allocates (all channels of a
        block, samples, decompression scratch, metadata), planned from the headers before
        allocating (default :func:`default_max_bytes`, 640 MiB). A file that would need more
        is a :class:`FrameError` naming the budget.
    unit : {"C", "K"}, optional
        Return temperatures (float64) in this unit instead of counts: a radiometric file's
        counts are converted with its calibration (:func:`irfidelity.read_radiometry`); a
        float frame is taken as already in this unit and returned as it is.
    **overrides : float
        With ``unit``: calibration fields replacing the file's (``emissivity=0.98``,
        ``reflected_temperature=20``, ...; see :class:`irfidelity.radiometry.Radiometry`).

    Returns
    -------
    numpy.ndarray
        2-D array (rows, cols): the data window for EXR. dtype ``uint8``, ``uint16``,
        ``int16``, ``uint32``, ``float16``, ``float32`` or ``float64``.

    Raises
    ------
    FrameError
        The file is missing, unreadable, truncated, corrupt, unsupported (deep or
        subsampled EXR, palette TIFF, ...) or larger than ``max_pixels`` / ``max_bytes``; the message
        names the path and the reason. With ``unit``: integer counts without a calibration,
        or no count within the calibration's domain.
    FidelityError
        With ``unit``: an override that is unknown or out of its range, naming the field.

    Examples
    --------
    The FLIR Lepton frame shipped with the package (14-bit counts in a 16-bit PNG):

    >>> from importlib import resources
    >>> import irfidelity as irf
    >>> from irfidelity.frames import list_channels
    >>> with resources.as_file(resources.files("irfidelity") / "data" / "cptv_v2_frame000.png") as path:
    ...     frame, channels = irf.load_frame(path), list_channels(path)
    >>> frame.shape, frame.dtype.name, channels
    ((120, 160), 'uint16', ['Y'])
    >>> irf.load_frame("missing.png")
    Traceback (most recent call last):
    ...
    irfidelity.errors.FrameError: missing.png: cannot open: ...

    A radiometric JPEG (FLIR AX8, shipped with the package) as counts and as temperatures:

    >>> with resources.as_file(resources.files("irfidelity") / "data" / "readthermal_flir_ax8.jpg") as path:
    ...     counts, kelvin = irf.load_frame(path), irf.load_frame(path, unit="K")
    >>> counts.dtype.name, kelvin.dtype.name, bool(250 < kelvin.mean() < 330)
    ('uint16', 'float64', True)
    """
    try:
        spath = os.fspath(path)
    except TypeError:
        raise FrameError(f"{path!r}: not a path") from None
    if isinstance(spath, bytes):
        spath = os.fsdecode(spath)
    page = check_page(spath, page)
    max_pixels = budget.max_pixels(check_limit(spath, "max_pixels", max_pixels))
    max_bytes = check_limit(spath, "max_bytes", max_bytes)
    if channel is not None and not isinstance(channel, str):
        raise FrameError(f"{spath}: channel must be a string, got {channel!r}")
    if _is_npy(spath):
        frame = _load_npy(spath, channel, page, max_pixels)
    else:
        frame = _core.load_frame(spath, channel, page, max_pixels, max_bytes=max_bytes)
    if unit is None and not overrides:
        return frame
    return _in_unit(spath, frame, page, max_bytes, unit, overrides)


def _in_unit(path: str, frame: np.ndarray, page: int, max_bytes: int | None, unit: str | None,
             overrides: dict[str, float]) -> np.ndarray:
    """A loaded frame in a temperature unit (``load_frame``'s ``unit``)."""
    if unit not in UNITS:
        given = f"got {unit!r}" if unit is not None else f"calibration overrides ({', '.join(overrides)}) need one"
        raise FidelityError(f"{path}: unit must be 'C' or 'K'; {given}", option="unit")
    if frame.dtype.kind == "f":
        if overrides:
            raise FidelityError(f"{path}: a float frame is taken as already in {unit}; calibration overrides "
                                f"({', '.join(overrides)}) apply to radiometric counts only", option="unit")
        return frame
    if _is_npy(path):
        raise FrameError(f"{path}: integer counts without a radiometric calibration cannot become temperatures "
                         f"(unit={unit!r}): only FLIR files (FFF, SEQ, CSQ, radiometric JPEG) carry one")
    try:
        calibration = read_radiometry(path, page=page, max_bytes=max_bytes)
    except FrameError as exc:
        raise FrameError(f"{exc}; integer counts without one cannot become temperatures (unit={unit!r})") from None
    budget.check_float64_copy(f"{path}: conversion to temperature", frame, max_bytes)
    try:
        return np.asarray(calibration.temperature(frame, unit, **overrides), dtype=np.float64)
    except RangeError as exc:
        raise FrameError(str(exc)) from None


def list_channels(path: PathLike) -> list[str]:
    """Channel names that ``channel=`` accepts for this file.

    EXR: the channel names (``"part.channel"`` in multi-part files); PNG/TIFF: e.g.
    ``["Y"]``, ``["Y", "A"]``, ``["R", "G", "B"]``; ``.npy``: ``["Y"]``.
    """
    spath = os.fspath(path)
    if _is_npy(spath):
        load_frame(spath)
        return ["Y"]
    return list(_core.list_channels(spath))


class PageChain(NamedTuple):
    """The pages of a frame file (:func:`page_chain`)."""

    #: Pages that can be found: a TIFF's pages (a FLIR recording's frames) up to the end of the
    #: chain or to where it breaks.
    pages: int
    #: Why the chain of pages breaks after ``pages`` pages (naming the file, the page and the
    #: reason), or None when nothing is missing.
    broken: str | None


def page_chain(path: PathLike) -> PageChain:
    """The pages of a frame file that can be found, and why the rest cannot.

    A multi-page TIFF links its pages in a chain of directories (IFDs), each pointing to the
    next. The chain is walked once (and kept for decoding the pages). When it breaks before
    its end -- the file is truncated (``"truncated at page k: ..."``), a directory points back
    to an earlier one (``"the IFD chain loops back at page k: ..."``) or into the header, or
    there are more than 10 million pages -- the pages before the break can still be read,
    and ``broken`` says why page ``k = pages`` and any after it cannot. A FLIR recording (SEQ,
    CSQ) is its frames one after another: a recording cut short or with a damaged frame header
    breaks the same way (``"frame k (at byte b): ..."``).

    Parameters
    ----------
    path : str or os.PathLike
        A TIFF, FLIR (FFF, SEQ, CSQ), OpenEXR, PNG or ``.npy`` file.

    Returns
    -------
    PageChain
        ``(pages, broken)``: 1 page for EXR and PNG, the first axis of a 3-D ``.npy``
        (else 1); ``broken`` is None unless a TIFF's chain or a FLIR recording's frames break.

    Raises
    ------
    FrameError
        The file cannot be read, or not even its first page can be found.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np, irfidelity as irf
    >>> path = os.path.join(tempfile.mkdtemp(), "stack.npy")
    >>> np.save(path, np.zeros((3, 4, 4), np.uint16))
    >>> irf.frames.page_chain(path)
    PageChain(pages=3, broken=None)
    """
    spath = os.fspath(path)
    if _is_npy(spath):
        try:
            a = np.load(spath, mmap_mode="r", allow_pickle=False)
        except (OSError, ValueError, EOFError, TypeError) as e:
            raise FrameError(f"{spath}: corrupt or invalid .npy file: {e}") from None
        return PageChain(int(a.shape[0]) if getattr(a, "ndim", 0) == 3 else 1, None)
    pages, broken = _core.page_chain(spath)
    return PageChain(int(pages), broken)


def page_count(path: PathLike) -> int:
    """Number of pages: TIFF IFDs, the first axis of a 3-D ``.npy``, else 1.

    A TIFF whose chain of pages breaks before its end (a truncated file, a loop) raises
    :class:`FrameError` naming where and why: its number of pages is not known.
    :func:`page_chain` gives the pages before the break, and :class:`FrameSequence` reads
    them, with the break as a frame that fails to load.
    """
    pages, broken = page_chain(path)
    if broken is not None:
        raise FrameError(broken)
    return pages


def display_name(name: str) -> str:
    """A file name as valid text: bytes that are not UTF-8 (kept by Python as surrogate
    escapes) are shown as ``\\xNN``, so reports, CSV and JSON can always be written."""
    try:
        return name.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    except UnicodeEncodeError:  # a lone surrogate that no file system byte produced
        return name.encode("utf-8", "backslashreplace").decode("utf-8")


def natural_key(text: str) -> list[Any]:
    """Sort key that orders embedded numbers by value: ``frame_2`` before ``frame_10``."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", text)]


def _is_tiff(path: str) -> bool:
    return path.lower().endswith(MULTIPAGE_EXTENSIONS)


Entry = tuple[str | None, int, str]  # (path, page, display name); path None for an array


class _Column(Sequence[Any]):
    """A read-only view of one field of a sequence's entries: indexing costs O(1) (the
    properties are read once per frame while a run goes, so they must not copy the list)."""

    __slots__ = ("_entries", "_field")

    def __init__(self, entries: list[Entry], field: Callable[[Entry], Any]) -> None:
        self._entries, self._field = entries, field

    def __len__(self) -> int:
        return len(self._entries)

    @overload
    def __getitem__(self, index: int) -> Any: ...

    @overload
    def __getitem__(self, index: slice) -> list[Any]: ...

    def __getitem__(self, index: int | slice) -> Any:
        if isinstance(index, slice):
            return [self._field(e) for e in self._entries[index]]
        return self._field(self._entries[index])

    def __iter__(self) -> Iterator[Any]:
        return map(self._field, self._entries)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (list, tuple, _Column)):
            return list(self) == list(other)
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return repr(list(self))


class FrameSequence(Sequence[np.ndarray]):
    """A lazy, indexable sequence of frames.

    Parameters
    ----------
    source : str, os.PathLike, sequence of paths, or numpy.ndarray
        * a directory: its ``.exr``, ``.png``, ``.tif``, ``.tiff`` and ``.npy`` files;
        * a glob pattern (``"run1/frame_*.png"``);
        * a list or tuple of paths;
        * one file: a multi-page TIFF gives one frame per page, other files one frame;
        * a 3-D array ``(frames, rows, cols)``.

        Files are ordered naturally (``frame_2`` before ``frame_10``); an explicit list
        keeps its order. Multi-page TIFFs inside a directory, glob or list are expanded
        into their pages (one walk over the file's chain of pages, kept for decoding them);
        pixels are only decoded when a frame is accessed. A TIFF whose chain of pages
        breaks (a truncated file, a chain that loops back; :func:`page_chain`) gives the
        pages before the break and one more frame, ``"file.tif[k]"`` at the break, whose
        loading raises :class:`FrameError` naming the file and why the chain breaks there:
        a sequence run reports it as a failed frame, never drops the rest silently.
    channel : str, optional
        Channel passed to :func:`load_frame` for every file.
    max_pixels, max_bytes : int, optional
        Decoding limits passed to :func:`load_frame`.

    Notes
    -----
    ``len(seq)``, ``seq[i]`` (a 2-D array), ``seq[a:b]`` (a new ``FrameSequence``),
    iteration, and ``seq.names`` (display names such as ``"frame_0003.png"`` or
    ``"stack.tif[3]"``) are supported. ``names``, ``entries`` and ``sources`` are read-only
    views (``list(seq.names)`` for a list). Errors raise :class:`FrameError` naming the path.

    Examples
    --------
    >>> import os, numpy as np, irfidelity as irf
    >>> os.mkdir("run")
    >>> for i in (1, 2, 10):
    ...     np.save(f"run/frame_{i}.npy", np.full((3, 5), i, dtype=np.uint16))
    >>> seq = irf.FrameSequence("run")               # natural order: frame_2 before frame_10
    >>> seq
    FrameSequence(3 frames: frame_1.npy, frame_2.npy, frame_10.npy)
    >>> [int(frame[0, 0]) for frame in seq], seq[1:].names
    ([1, 2, 10], ['frame_2.npy', 'frame_10.npy'])
    >>> irf.FrameSequence(np.zeros((4, 3, 5), dtype=np.uint16))      # a 3-D array
    FrameSequence(4 frames: [0], [1], [2], ...)
    """

    def __init__(
        self,
        source: PathLike | Sequence[PathLike] | np.ndarray,
        *,
        channel: str | None = None,
        max_pixels: int | None = None,
        max_bytes: int | None = None,
    ) -> None:
        self.channel = channel
        self.max_pixels = budget.max_pixels(max_pixels)  # resolved here: a worker process has no context
        self.max_bytes = max_bytes
        self._array: np.ndarray | None = None
        # entries: (path, page, display name); for arrays: (None, index, name)
        self._entries: list[Entry]
        if isinstance(source, np.ndarray):
            if source.ndim != 3:
                raise FrameError(f"array source: expected a 3-D array (frames, rows, cols), got shape {source.shape}")
            self._array = source
            self._entries = [(None, i, f"[{i}]") for i in range(source.shape[0])]
        elif isinstance(source, (str, os.PathLike)):
            self._entries = self._from_path(os.fspath(source))
        elif isinstance(source, Iterable):
            paths = [os.fspath(p) for p in source]
            if not paths:
                raise FrameError("empty list of frame paths")
            self._entries = self._expand(paths, label_dirs=True)
        else:
            raise FrameError(f"{source!r}: not a directory, glob, file, list of paths or 3-D array")

    @classmethod
    def _subset(cls, parent: FrameSequence, entries: list[Entry]) -> Self:
        new = cls.__new__(cls)
        new.channel = parent.channel
        new.max_pixels = parent.max_pixels
        new.max_bytes = parent.max_bytes
        new._array = parent._array
        new._entries = entries
        return new

    def _from_path(self, spath: str) -> list[Entry]:
        if os.path.isdir(spath):
            names = [
                n
                for n in os.listdir(spath)
                if n.lower().endswith(FRAME_EXTENSIONS) and os.path.isfile(os.path.join(spath, n))
            ]
            if not names:
                raise FrameError(f"{spath}: directory holds no frame files ({', '.join(FRAME_EXTENSIONS)})")
            names.sort(key=natural_key)
            return self._expand([os.path.join(spath, n) for n in names], label_dirs=False)
        if os.path.isfile(spath):
            return self._expand([spath], label_dirs=False)
        if _GLOB_CHARS.search(spath):
            hits = [p for p in _glob.glob(spath) if os.path.isfile(p)]
            if not hits:
                raise FrameError(f"{spath}: glob pattern matches no files")
            hits.sort(key=natural_key)
            return self._expand(hits, label_dirs=False)
        raise FrameError(f"{spath}: no such file or directory")

    def _expand(self, paths: list[str], *, label_dirs: bool) -> list[Entry]:
        out: list[Entry] = []
        for p in paths:
            base = display_name(os.path.basename(p) or p)
            if _is_tiff(p):
                try:
                    n, broken = page_chain(p)
                except FrameError:
                    n, broken = 1, None  # not even page 0 is found: one frame, whose decode says why
                if broken is not None:
                    n += 1  # the page at the break: its decode names why the chain breaks
                if n > 1:
                    out.extend((p, i, f"{base}[{i}]") for i in range(n))
                    continue
            out.append((p, 0, base))
        return out

    # --- Sequence protocol -------------------------------------------------------

    def __len__(self) -> int:
        return len(self._entries)

    def _load(self, entry: Entry) -> np.ndarray:
        path, page, _ = entry
        if path is None:
            assert self._array is not None
            return np.asarray(self._array[page])
        return load_frame(path, channel=self.channel, page=page, max_pixels=self.max_pixels,
                          max_bytes=self.max_bytes)

    @overload
    def __getitem__(self, index: int) -> np.ndarray: ...

    @overload
    def __getitem__(self, index: slice) -> FrameSequence: ...

    def __getitem__(self, index: int | slice) -> np.ndarray | FrameSequence:
        if isinstance(index, slice):
            return FrameSequence._subset(self, self._entries[index])
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
            raise TypeError(f"FrameSequence indices must be integers or slices, not {type(index).__name__}")
        i = int(index)
        n = len(self._entries)
        if i < -n or i >= n:
            raise IndexError(f"frame index {i} out of range for a sequence of {n} frames")
        return self._load(self._entries[i])

    def take(self, indices: Iterable[int]) -> FrameSequence:
        """A new sequence of the frames at these positions (0-based; negative from the end)."""
        n = len(self._entries)
        picked = []
        for i in indices:
            i = int(i)
            if i < -n or i >= n:
                raise IndexError(f"frame index {i} out of range for a sequence of {n} frames")
            picked.append(self._entries[i])
        return FrameSequence._subset(self, picked)

    def __iter__(self) -> Iterator[np.ndarray]:
        for entry in self._entries:
            yield self._load(entry)

    @property
    def names(self) -> Sequence[str]:
        """Display name of each frame: file name, ``"file.tif[3]"`` for TIFF pages, ``"[i]"`` for arrays."""
        return _Column(self._entries, _name)

    @property
    def entries(self) -> Sequence[Entry]:
        """``(path, page, display name)`` of each frame (path None for a 3-D array source)."""
        return _Column(self._entries, _whole)

    @property
    def is_files(self) -> bool:
        """True when the frames come from files (not a 3-D array)."""
        return self._array is None

    @property
    def sources(self) -> Sequence[tuple[str | None, int]]:
        """``(path, page)`` of each frame (``(None, i)`` for a 3-D array source)."""
        return _Column(self._entries, _source)

    def __repr__(self) -> str:
        head = ", ".join(self.names[:3])
        more = ", ..." if len(self) > 3 else ""
        return f"FrameSequence({len(self)} frames: {head}{more})"


def _name(entry: Entry) -> str:
    return entry[2]


def _whole(entry: Entry) -> Entry:
    return entry


def _source(entry: Entry) -> tuple[str | None, int]:
    return entry[0], entry[1]
