"""Progress of a sequence run: a tqdm bar, a plain line when tqdm is missing, or a callback."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any

__all__ = ["Progress"]


class _Line:
    """``scoring: 120/300 frames (40 %)`` on stderr, rewritten at most once a second."""

    def __init__(self, total: int):
        self.total, self.done, self.shown = total, 0, 0.0

    def update(self, n: int) -> None:
        self.done += n
        now = time.monotonic()
        if now - self.shown >= 1.0 or self.done == self.total:
            self.shown = now
            sys.stderr.write(f"\rscoring: {self.done}/{self.total} frames ({100 * self.done // max(self.total, 1)} %)")
            sys.stderr.flush()

    def close(self) -> None:
        sys.stderr.write("\n")
        sys.stderr.flush()


def _bar(total: int) -> Any:
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return _Line(total)
    return tqdm(total=total, unit="frame", desc="scoring", dynamic_ncols=True)


class Progress:
    """``progress``: True (a bar), False (nothing), or ``callable(done, total)``."""

    def __init__(self, total: int, progress: bool | Callable[[int, int], Any]):
        self.total, self.done = total, 0
        self.callback = progress if callable(progress) else None
        self.bar = _bar(total) if progress is True else None

    def advance(self, *, resumed: bool = False) -> None:
        """One more frame done; the callback hears only of frames scored in this run (after
        the resumed ones, so its first ``done`` is the resumed count + 1)."""
        self.done += 1
        if self.bar is not None:
            self.bar.update(1)
        if self.callback is not None and not resumed:
            self.callback(self.done, self.total)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
