"""What a frame's row was computed from, so a resumed run scores again a frame whose input
changed.

A record stores, for both frames of its pair, the fingerprint of what was scored, taken by
the backend that scored it (never afterwards, which could pair a new file with old
statistics):

* frames the Rust engine decodes (files, locally or on Dask): ``[path, page, size,
  mtime_ns, xxh3]`` of the file, of the bytes it decoded (``rust/fingerprint.rs``);
* frames scored as arrays (arrays and ``.npy`` files): ``[dtype, shape, blake2b]`` of the
  array scored (:func:`array_fingerprint`).

On resume, :class:`Fingerprints` computes the same of the inputs as they are now.
"""

from __future__ import annotations

import hashlib
import os
from typing import Any

import numpy as np

from .. import _core
from ..errors import FidelityError
from ..frames import Entry, FrameSequence

__all__ = ["Fingerprints", "array_fingerprint", "file_fingerprint"]


def array_fingerprint(frame: np.ndarray) -> list:
    """``[dtype, shape, blake2b]`` of the array scored."""
    frame = np.ascontiguousarray(frame)
    return [frame.dtype.name, list(frame.shape), hashlib.blake2b(frame.data, digest_size=16).hexdigest()]


def _path(entry: Entry) -> str:
    """The file of an entry of a sequence of files (each has one)."""
    path = entry[0]
    assert path is not None
    return path


def file_fingerprint(path: Any, page: int, size: int | None, mtime_ns: int | None, digest: int | None) -> list:
    """The fingerprint of page ``page`` of the file at ``path``: size, modification time, XXH3."""
    return [os.fsdecode(path), page, size, mtime_ns, digest]


class Fingerprints:
    """The fingerprints of frames of two sequences as they are now: of their files (XXH3 in
    Rust, in parallel, GIL released, cached per file: the pages of a TIFF share theirs), or
    with ``arrays`` of the frames loaded as arrays."""

    def __init__(self, real: FrameSequence, sim: FrameSequence, *, arrays: bool):
        self.sides = {"real": (real, real.entries), "sim": (sim, sim.entries)}
        self.arrays = arrays
        self.cache: dict[str, list] = {}

    def _files(self, paths: list[str]) -> None:
        todo = [p for p in dict.fromkeys(paths) if p not in self.cache]
        if not todo:
            return
        digests = _core.file_digests(todo)
        for path, digest in zip(todo, digests):
            try:
                st = os.stat(path)
                self.cache[path] = [st.st_size, st.st_mtime_ns, digest]
            except OSError:
                self.cache[path] = [None, None, None]

    def _frame(self, side: str, index: int | None) -> Any:
        if index is None:
            return None
        seq, entries = self.sides[side]
        if self.arrays:
            try:
                return array_fingerprint(seq[index])
            except FidelityError:
                return None
        path = _path(entries[index])
        return file_fingerprint(path, entries[index][1], *self.cache[path])

    def of_pairs(self, pairs: list[tuple[int | None, int | None]]) -> list[dict]:
        """``{"real": ..., "sim": ...}`` for each pair (JSON-ready)."""
        if not self.arrays:
            self._files([_path(self.sides[side][1][i]) for r, s in pairs for side, i in (("real", r), ("sim", s))
                         if i is not None])
        return [{"real": self._frame("real", r), "sim": self._frame("sim", s)} for r, s in pairs]
