"""A seeded mutator of report dicts (for the from_dict tests): drops keys, changes types,
inserts NaN / huge / negative numbers and deep nesting anywhere in a real report's dict."""

from __future__ import annotations

import copy
import math
import random
from typing import Any

#: Values a mutation puts in place of another (deep nesting is built on demand).
REPLACEMENTS: tuple[Any, ...] = (None, "x", "", "nan", "inf", -1, 0, 1, 2, -1e308, 1e308, math.nan, math.inf,
                                 -math.inf, 10**30, -(10**30), True, False, [], {}, [1, 2], {"k": 1}, [[0.5]],
                                 "1", 0.5, -0.5, 3.5, 2**63, "\udcff<b>", 1e-320)


def _nested(depth: int) -> Any:
    value: Any = 1
    for i in range(depth):
        value = [value] if i % 2 else {"k": value}
    return value


def _paths(data: Any, max_depth: int = 12) -> list[tuple]:
    """The paths to the values in a nested dict/list, down to ``max_depth`` (root excluded)."""
    out: list[tuple] = []
    stack: list[tuple[tuple, Any]] = [((), data)]
    while stack:
        prefix, value = stack.pop()
        items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
        for key, child in items:
            out.append(prefix + (key,))
            if len(prefix) < max_depth:
                stack.append((prefix + (key,), child))
    return out


def _mutate_once(data: dict, rng: random.Random) -> None:
    by_depth: dict[int, list[tuple]] = {}
    for path in _paths(data):
        by_depth.setdefault(len(path), []).append(path)
    path = rng.choice(by_depth[rng.choice(sorted(by_depth))])  # every depth as likely: top-level keys too
    parent = data
    for key in path[:-1]:
        parent = parent[key]
    key = path[-1]
    roll = rng.random()
    if roll < 0.25 and isinstance(parent, dict):
        del parent[key]
    elif roll < 0.35:
        parent[key] = _nested(rng.choice((3, 40, 2000)))
    elif roll < 0.45:
        parent[key] = [parent[key]] if rng.random() < 0.5 else {"v": parent[key]}
    elif roll < 0.5 and isinstance(parent, dict):
        parent[rng.choice(("extra", "", "index", "frames", "error", 7))] = rng.choice(REPLACEMENTS)
    else:
        parent[key] = copy.deepcopy(rng.choice(REPLACEMENTS))


def mutations(report: dict, count: int, seed: int) -> list[dict]:
    """``count`` mutated copies of ``report`` (1 to 3 mutations each), reproducible by ``seed``."""
    rng = random.Random(seed)
    out = []
    for _ in range(count):
        d = copy.deepcopy(report)
        for _ in range(rng.choice((1, 1, 2, 3))):
            _mutate_once(d, rng)
        out.append(d)
    return out
