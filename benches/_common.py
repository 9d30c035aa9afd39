"""Helpers shared by the benchmark scripts (standard library only: importable before the
scripts set their thread environment)."""

from __future__ import annotations

import time
from typing import Callable


def best(fn: Callable[[], object], repeat: int, clock: Callable[[], float] = time.perf_counter) -> float:
    """Best of ``repeat`` timed calls of ``fn``, after one untimed warm-up call (``clock``: wall
    time by default; ``time.process_time`` for CPU time, which other jobs on the machine disturb less)."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return min(times)
