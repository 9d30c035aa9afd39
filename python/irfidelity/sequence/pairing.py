"""Which simulated frame goes with which real frame.

Pairing by position silently pairs different frames as soon as one frame is missing on each
side. So when both sequences are named files, frames are paired **by name**: first by
identical file names without extension (``frame_0007.png`` with ``frame_0007.exr``), else
by the frame number in the name (``real_0007.png`` with ``sim_7.tif``), else, for pages of
one multi-page TIFF per side, by page. A frame with no partner on the other side is not
dropped: it becomes an error row (a failed frame: a file is missing). ``pair_by="order"``
keeps pairing by position. With ``max_delay``, frames are paired by position offset by the
delay found, and the frames the offset leaves at the ends are rows too, with the reason, but
not failures: no frame of the other side can pair with them (``SequenceReport.unpaired``).
"""

from __future__ import annotations

import os
import re
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from ..errors import FidelityError
from ..frames import FrameSequence

__all__ = ["Pairing", "pair_frames"]

_NUMBER = re.compile(r"(\d+)(?!.*\d)")  # the last run of digits


@dataclass(frozen=True)
class Pairing:
    """Pairs of (real index, sim index) into the two sequences, in scoring order.

    One side is None for a frame without a partner (a row with the reason, not scored).
    ``rule`` says how the pairs were made: "order", "name", "number", "page" or "delay"
    (by position, offset by ``delay``: the :class:`~irfidelity.sequence.delay.Delay` found,
    and ``unpaired`` the names of the frames at the ends that the offset leaves without a
    partner).
    """

    pairs: tuple[tuple[int | None, int | None], ...]
    rule: str
    notes: tuple[str, ...] = field(default=())
    delay: Any = None
    unpaired: dict = field(default_factory=dict)

    @property
    def unmatched(self) -> int:
        return sum(1 for r, s in self.pairs if r is None or s is None)

    @property
    def expected_alone(self) -> list[int]:
        """Positions of the pairs without a partner that are no failure: with a delay, the
        frames at the ends (no frame of the other side can pair with them). A frame without a
        partner by name is a failure instead (a file is missing)."""
        if self.delay is None:
            return []
        return [i for i, (r, s) in enumerate(self.pairs) if r is None or s is None]

    def why_alone(self, index: int) -> str:
        """Why the frame of pair ``index`` (which has one side only) has no partner."""
        missing = "simulated" if self.pairs[index][1] is None else "real"
        if self.delay is not None:
            return f"no {missing} frame pairs with it at delay {self.delay.frames:+d}"
        return f"no {missing} frame pairs with it (paired by {self.rule})"


def _stem(entry: tuple[str | None, int, str]) -> str:
    path, _, name = entry
    return os.path.splitext(os.path.basename(path))[0] if path is not None else name


def _number(entry: tuple[str | None, int, str]) -> int | None:
    m = _NUMBER.search(_stem(entry))
    return int(m.group(1)) if m else None


def _keyed(keys_real: list, keys_sim: list) -> list[tuple[int | None, int | None]] | None:
    """Pairs by equal keys, real order first, then unmatched sim frames; None when the keys
    cannot pair (missing or repeated on one side, or no key shared at all)."""
    if None in keys_real or None in keys_sim:
        return None
    if len(set(keys_real)) != len(keys_real) or len(set(keys_sim)) != len(keys_sim):
        return None
    where = {k: j for j, k in enumerate(keys_sim)}
    if not set(keys_real) & set(where):
        return None
    pairs: list[tuple[int | None, int | None]] = [(i, where.get(k)) for i, k in enumerate(keys_real)]
    taken = {s for _, s in pairs if s is not None}
    pairs += [(None, j) for j in range(len(keys_sim)) if j not in taken]
    return pairs


def _by_name(real: FrameSequence, sim: FrameSequence) -> tuple[list, str] | None:
    re_entries, sim_entries = real.entries, sim.entries
    one_stack = len({e[0] for e in re_entries}) == 1 and len({e[0] for e in sim_entries}) == 1
    if one_stack and any(e[1] for e in re_entries):  # one multi-page TIFF per side: its pages
        pairs = _keyed([e[1] for e in re_entries], [e[1] for e in sim_entries])
        return (pairs, "page") if pairs is not None else None
    for rule, key in (("name", _stem), ("number", _number)):
        pairs = _keyed([key(e) for e in re_entries], [key(e) for e in sim_entries])
        if pairs is not None:
            return pairs, rule
    return None


def pair_frames(real: FrameSequence, sim: FrameSequence, rule: str) -> Pairing:
    """Pair the frames of two sequences by ``rule`` ("auto", "name" or "order")."""
    named = real.is_files and sim.is_files
    if rule == "name" and not named:
        raise FidelityError("frames can be paired by name only when both sequences are files "
                            "(directories, globs, lists of paths, multi-page TIFFs)", option="pair_by")
    if rule in ("name", "auto") and named:
        found = _by_name(real, sim)
        if found is not None:
            pairs, how = found
            notes = []
            lonely = Counter("real" if s is None else "sim" for r, s in pairs if r is None or s is None)
            if lonely:
                notes.append(f"paired by {how}: {lonely['real']} real and {lonely['sim']} simulated frame(s) "
                             f"have no partner and are reported as failed frames")
            return Pairing(tuple(pairs), how, tuple(notes))
        if rule == "name":
            raise FidelityError("no frame names match between the two sequences (by file name, frame number "
                                "or page); pair them by position instead (pair_by = order)", option="pair_by")
    if len(real) != len(sim):
        raise FidelityError(f"the real sequence has {len(real)} frames and the simulated sequence {len(sim)}, "
                            f"and they cannot be paired by name; give sequences of equal length", option="pair_by")
    by_position: tuple[str, ...] = \
        ("paired by position: the frame names do not match (by file name, frame number or page)",) \
        if named and rule == "auto" else ()
    return Pairing(tuple((i, i) for i in range(len(real))), "order", by_position)


def _names_text(names: list[str]) -> str:
    return ", ".join(names[:5]) + (", ..." if len(names) > 5 else "")


def pair_with_delay(real: FrameSequence, sim: FrameSequence, delay: Any) -> Pairing:
    """Real frame ``i`` with simulated frame ``i + delay.frames``, over the frames both sides
    have; the frames the offset leaves at the ends are pairs with one side (rows with the
    reason, not scored): every real frame in order, then the simulated frames left over."""
    d = delay.frames
    pairs: list[tuple[int | None, int | None]] = [(i, i + d if 0 <= i + d < len(sim) else None)
                                                  for i in range(len(real))]
    pairs += [(None, j) for j in range(len(sim)) if not 0 <= j - d < len(real)]
    unpaired = {"real": [real.names[r] for r, s in pairs if r is not None and s is None],
                "sim": [sim.names[s] for r, s in pairs if r is None and s is not None]}
    note = (f"paired by position with a delay of {d:+d} frames (real frame i with simulated frame "
            f"i{f'{d:+d}' if d else ''}; confidence {delay.confidence:.3f})")
    lonely = [f"{len(v)} {side} frame(s) ({_names_text(v)})" for side, v in
              (("real", unpaired["real"]), ("simulated", unpaired["sim"])) if v]
    if lonely:
        note += (f"; {' and '.join(lonely)} at the ends have no partner at this delay: rows without a score "
                 f"(report.unpaired), not failures")
    return Pairing(tuple(pairs), "delay", (note,), delay, unpaired)
