"""One frame pair's row of a sequence report: :class:`FrameEntry`.

A typed, frozen record that reads as a mapping (``entry["metrics"]``, ``entry.get("error")``,
``dict(entry)``), with the keys of a single-pair result (:mod:`irfidelity.schema`) plus the
frame's place in the sequence. Its dict form is the frame's JSON form.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

__all__ = ["FrameEntry"]


@dataclass(frozen=True, eq=False)
class FrameEntry(Mapping):
    """The row of the pair at ``index``: its files, its result, or why it has none.

    Attributes
    ----------
    index : int
        Position of the pair in the sequence.
    real, sim : str or None
        Display names of the two frames (None for the side a frame without a partner lacks).
    rows, cols, dtype
        The frames' shape and sample type (None when not read).
    fidelity, grade, components, component_grades, membership, metrics
        The pair's result, as in :class:`~irfidelity.FidelityReport`; None and empty dicts
        when the pair has an ``error``.
    registration : dict or None
        The registration applied to the pair (:meth:`irfidelity.registration.Registration.to_dict`).
    error : str or None
        Why the pair could not be scored, or None.
    extra : dict
        Keys of a read-back frame that a frame does not use, kept as they were.

    Equality is that of the mapping, so an entry equals the dict of its keys.
    """

    index: int
    real: Any = None
    sim: Any = None
    rows: int | None = None
    cols: int | None = None
    dtype: str | None = None
    fidelity: float | None = None
    grade: str | None = None
    components: dict = field(default_factory=dict)
    component_grades: dict = field(default_factory=dict)
    membership: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    registration: dict | None = None
    error: str | None = None
    extra: dict = field(default_factory=dict)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> FrameEntry:
        """An entry from its dict form (keys it does not use go to ``extra``)."""
        known = {k: data[k] for k in KEYS if k in data}
        return cls(**known, extra={k: v for k, v in data.items() if k not in known})

    def __getitem__(self, key: str) -> Any:
        if key in _KEY_SET:
            return getattr(self, key)
        return self.extra[key]

    def __iter__(self) -> Iterator[str]:
        yield from KEYS
        yield from self.extra

    def __len__(self) -> int:
        return len(KEYS) + len(self.extra)

    def to_dict(self) -> dict:
        """The entry as a plain dict (its JSON form, before :func:`irfidelity.schema.to_json`)."""
        return dict(self)


#: The keys of a frame entry, in the order of its JSON form.
KEYS = tuple(f.name for f in fields(FrameEntry) if f.name != "extra")
_KEY_SET = frozenset(KEYS)
