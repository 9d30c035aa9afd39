"""An options object given whole or field by field: one rule for every entry point that
takes one (``score_sequence(run=...)``, ``noise3d(options=...)``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, TypeVar

from .errors import FidelityError

__all__ = ["options_from"]

T = TypeVar("T")


def options_from(cls: type[T], given: T | None, keywords: Mapping[str, Any], argument: str) -> T:
    """``given`` (an instance of the dataclass ``cls``), or one made from ``keywords`` (its
    fields). A field given both ways is given twice: a FidelityError naming it; a keyword
    that is no field of ``cls`` is a TypeError, as for any function."""
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    unknown = [k for k in keywords if k not in names]
    if unknown:
        raise TypeError(f"unexpected keyword argument(s) {', '.join(map(repr, unknown))}; the {argument} options "
                        f"are {', '.join(names)}")
    if given is None:
        return cls(**keywords)
    if not isinstance(given, cls):
        raise FidelityError(f"{argument} must be a {cls.__name__}, got {type(given).__name__}", option=argument)
    if keywords:
        raise FidelityError(f"{', '.join(keywords)} given twice: as a keyword and in {argument}=; give each "
                            f"option in one place", option=next(iter(keywords)))
    return given
