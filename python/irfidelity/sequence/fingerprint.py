"""What a frame's row was computed from: size, modification time and content hash of both
input files, so a resumed run scores again a frame whose file changed."""

from __future__ import annotations

import hashlib
import os
from typing import Any

import numpy as np

from .. import _core
from ..frames import FrameSequence

__all__ = ["Fingerprints"]


class Fingerprints:
    """Fingerprints of frames of two sequences, computed in batches (XXH3 in Rust, in
    parallel, GIL released) and cached per file (the pages of a TIFF share theirs)."""

    def __init__(self, real: FrameSequence, sim: FrameSequence):
        self.sides = {"real": real, "sim": sim}
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
        seq = self.sides[side]
        path, page, _ = seq.entries[index]
        if path is None:  # an array source: the frame's bytes
            frame = np.ascontiguousarray(seq[index])
            return [frame.dtype.name, list(frame.shape), hashlib.blake2b(frame.tobytes(), digest_size=16).hexdigest()]
        return [os.fsdecode(path), page] + self.cache[path]

    def of_pairs(self, pairs: list[tuple[int | None, int | None]]) -> list[dict]:
        """``{"real": ..., "sim": ...}`` for each pair (JSON-ready)."""
        paths = [self.sides[side].entries[i][0] for r, s in pairs for side, i in (("real", r), ("sim", s))
                 if i is not None]
        self._files([p for p in paths if p is not None])
        return [{"real": self._frame("real", r), "sim": self._frame("sim", s)} for r, s in pairs]
