"""Values of the real recording computed once and reused by every simulator of a run.

:func:`irfidelity.score_simulators` plans one run per simulator against the same real
recording. What a plan needs of the real recording alone — its first readable frame and
scored mask, the scene's range, the ceiling of consecutive real frames, the real camera's own
frame-to-frame transfer — is the same for every simulator; a :class:`RealMemo` computes each
for the first plan that asks and gives it to the others, with the warnings it raised (each
plan records its own notes; the caller shows them once).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Hashable
from typing import Any

__all__ = ["RealMemo", "computed"]


class RealMemo:
    """Values keyed by what they depend on besides the real recording (module notes)."""

    def __init__(self) -> None:
        self._values: dict[Hashable, tuple[Any, list[warnings.WarningMessage]]] = {}

    def get(self, key: Hashable, compute: Callable[[], Any]) -> Any:
        """``compute()``, once per ``key``; its warnings raised again on every call."""
        if key not in self._values:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                value = compute()
            self._values[key] = (value, list(caught))
        value, caught = self._values[key]
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        return value


def computed(memo: RealMemo | None, key: Hashable, compute: Callable[[], Any]) -> Any:
    """``compute()`` through ``memo``, or directly without one."""
    return compute() if memo is None else memo.get(key, compute)
