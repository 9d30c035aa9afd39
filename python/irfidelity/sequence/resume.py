"""What a resumed run takes from its log: each kept record read, checked and pooled one at a
time, so a resume holds one record's statistics at once whatever the run's length.

A record is taken only when

* its meta is what a run writes: a JSON object whose shape, sample type, extent and
  registration have the types and ranges of this run's frames;
* its statistics unpack within the size a frame of this run can have
  (:class:`RecordBounds`: the plan's bins or levels, the frame's pixels, the decoding
  budget), parse, have the make of this run's statistics (integer or float sums, the parts
  the components need, the histogram binning when histograms pool), and count exactly the
  frame's pixels;
* its frame's entry computes without an error;
* and its inputs' fingerprints equal those of the inputs now.

Otherwise its frame is scored again, and the run's notes count the records that could not be
used and the frames whose inputs changed. Nothing in a record can abort the run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .. import _core
from ..errors import FidelityError
from ..registration import Registration
from ..stats import PairStats
from ..temperature import TemperatureErrors
from .fingerprint import Fingerprints
from .log import FrameLog
from .outcomes import Outcome, frame_entry
from .pairing import Pairing
from .plan import SequencePlan
from .sidecar import BadRecord, Limits, max_stats_size, unpack_stats

__all__ = ["RecordBounds", "Resumer"]

_BATCH = 256  # records whose inputs are fingerprinted at once (in parallel)
_DENSE_LIMIT = max_stats_size(512, None, 0)  # the largest dense histogram (8 bytes x 512²): always allowed


class RecordBounds:
    """How large a record's statistics can be: a :meth:`PairStats.to_bytes` with the plan's
    histogram for a frame of the record's pixels; a sparse histogram (beyond 512 bins or
    levels) no larger than the decoding budget ``max_bytes``."""

    def __init__(self, plan: SequencePlan, max_pixels: int, max_bytes: int):
        nmi = "nmi" in plan.image
        self.bins = plan.bins if nmi and not plan.levels else None
        lo_hi = plan.valid if plan.valid is not None else (0, 0)
        self.levels = lo_hi[1] - lo_hi[0] + 1 if nmi and plan.levels else None
        self.max_pixels, self.cap = max_pixels, max(max_bytes, _DENSE_LIMIT)
        self.run = self.of(max_pixels)

    def of(self, pixels: int) -> Limits:
        """The limits of a record of a frame of ``pixels`` pixels."""
        return Limits(min(max_stats_size(self.bins, self.levels, pixels), self.cap))


def _make(raw: _core.PairStats, hist_pools: bool) -> tuple:
    """What statistics must share to be this run's: sums, parts, and pooled binning."""
    return (raw.is_int, raw.has_sse, raw.has_moments, raw.has_hist, raw.hist_spec() if hist_pools else None)


def _expected_make(plan: SequencePlan) -> tuple | None:
    """The make of this run's statistics: those of one pixel scored as the plan scores."""
    assert plan.dtype is not None
    dtype = np.dtype(np.float64) if plan.config.register is not None else plan.dtype
    value = plan.valid[0] if plan.valid is not None and dtype.kind in "ui" else 0
    pixel = np.full((1, 1), value, dtype=dtype)
    try:
        return _make(_core.pair_stats(pixel, pixel, plan.pair_request()), plan.keep_hist)
    except FidelityError:
        return None


def _int(value: Any) -> bool:
    return type(value) is int


def _number(value: Any) -> bool:
    return type(value) in (int, float) and math.isfinite(value)


class Resumer:
    """Takes the kept records of ``log`` into a run (:meth:`take`)."""

    def __init__(self, plan: SequencePlan, pairing: Pairing, log: FrameLog, fingerprints: Fingerprints,
                 bounds: RecordBounds):
        self.plan, self.pairing, self.log, self.fingerprints, self.bounds = plan, pairing, log, fingerprints, bounds
        self.dtype = plan.dtype_name
        self.make = _expected_make(plan) if plan.dtype is not None else None
        self.unusable = log.foreign  # records that could not be used
        self.why = "no frame of this run has its index" if log.foreign else None  # why the first could not
        self.changed = 0

    def take(self, names: Callable[[int], tuple], keep: Callable[..., None]) -> int:
        """Hand each record that can be trusted to ``keep(entry, stats, extent, reload)``
        (``reload()`` reads its statistics again) in index order; returns how many."""
        taken = 0
        indices = sorted(self.log.kept)
        for start in range(0, len(indices), _BATCH):
            batch = [i for i in indices[start:start + _BATCH] if self._pairable(i)]
            current = self.fingerprints.of_pairs([self.pairing.pairs[i] for i in batch])
            for index, inputs in zip(batch, current):
                try:
                    taken += self._take_one(index, inputs, names, keep)
                except BadRecord as exc:
                    self._unusable(str(exc))
        return taken

    def _pairable(self, index: int) -> bool:
        pairs = self.pairing.pairs
        if None not in pairs[index] and self.make is not None:
            return True
        self._unusable("its frame has no pair in this run, or no frame of the run is readable")
        return False

    def _unusable(self, why: str) -> None:
        self.unusable += 1
        self.why = self.why or why

    def _take_one(self, index: int, inputs: dict, names: Callable[[int], tuple], keep: Callable[..., None]) -> bool:
        where = self.log.kept[index]
        found, meta, payload = self.log.read(where)
        if found != index:
            raise BadRecord("record moved")
        shape, extent, registration = self._meta(meta)
        if meta.get("inputs") != inputs:
            self.changed += 1
            return False
        stats = self._stats(payload, shape)
        outcome = Outcome(index, stats, None, shape, meta["dtype"], extent, registration, inputs,
                          self._temperature(meta))
        real, sim = names(index)
        try:  # the scoring functions expect statistics a kernel made: a forged sum may upset them
            entry, pooled = frame_entry(self.plan, outcome, real, sim)
        except (ArithmeticError, ValueError) as exc:
            raise BadRecord(f"its statistics do not score ({type(exc).__name__}: {exc})") from None
        if entry["error"] is not None:
            raise BadRecord(f"its statistics do not score ({entry['error']})")
        if not (type(entry["fidelity"]) is float and math.isfinite(entry["fidelity"])):
            raise BadRecord("its statistics score no finite fidelity")
        keep(entry, pooled, extent, lambda: self._reload(where, shape))
        return True

    def _temperature(self, meta: Any) -> TemperatureErrors | None:
        """A record's temperature errors, checked (scored in a unit, every record has them)."""
        if self.plan.config.unit is None:
            return None
        try:
            return TemperatureErrors.from_dict(meta.get("temperature"))
        except ValueError as exc:
            raise BadRecord(f"its temperature errors are unusable: {exc}") from None

    def _meta(self, meta: Any) -> tuple[tuple[int, int], tuple[float, float] | None, Registration | None]:
        """The shape, extent and registration of a record's meta, checked."""
        if not isinstance(meta, dict):
            raise BadRecord("its meta is not a JSON object")
        shape = meta.get("shape")
        if not (isinstance(shape, list) and len(shape) == 2 and all(_int(v) and v > 0 for v in shape)
                and shape[0] * shape[1] <= self.bounds.max_pixels):
            raise BadRecord("its shape is not two positive integers within max_pixels")
        if meta.get("dtype") != self.dtype:
            raise BadRecord("its sample type is not the sequence's")
        extent = meta.get("extent")
        if extent is not None and not (isinstance(extent, list) and len(extent) == 2 and all(map(_number, extent))
                                       and extent[0] <= extent[1]):
            raise BadRecord("its extent is not two finite numbers in order")
        return (shape[0], shape[1]), None if extent is None else (extent[0], extent[1]), \
            self._registration(meta.get("registration"), shape)

    def _registration(self, found: Any, shape: list) -> Registration | None:
        if found is None:
            return None
        if not (self.plan.config.register_each and isinstance(found, dict)):
            raise BadRecord("it has a registration this run does not make")
        try:
            registration = Registration.from_dict(found)
        except (FidelityError, TypeError, ValueError, OverflowError):
            raise BadRecord("its registration is not a Registration") from None
        if list(registration.shape) != shape or not np.isfinite(registration.matrix).all():
            raise BadRecord("its registration is not of its frame")
        return registration

    def _stats(self, payload: bytes, shape: tuple[int, int]) -> PairStats:
        """A record's statistics, unpacked within their bound and checked to be this run's."""
        pixels = shape[0] * shape[1]
        data = unpack_stats(payload, self.bounds.of(pixels).max_stats)
        try:
            raw = _core.PairStats.from_bytes(data)
        except FidelityError:
            raise BadRecord("its statistics do not parse") from None
        if _make(raw, self.plan.keep_hist) != self.make:
            raise BadRecord("its statistics are not of the kind this run computes")
        if raw.n + raw.masked + raw.nonfinite != pixels:
            raise BadRecord("its statistics do not count its frame's pixels")
        if raw.is_int and not self._plausible(raw):
            raise BadRecord("its sums are beyond what its pixels' grey levels allow")
        return PairStats(raw, bins=self.plan.bin_label)

    def _plausible(self, raw: _core.PairStats) -> bool:
        """Whether exact integer sums lie within what ``n`` pixels of the valid grey levels
        can add up to."""
        if self.plan.valid is None:
            return True
        lo, hi = self.plan.valid
        n, top, sums = raw.n, max(abs(lo), abs(hi)) ** 2, raw.int_sums()
        assert sums is not None  # integer statistics have exact sums
        ok = not raw.has_sse or 0 <= sums["sse"] <= n * (hi - lo) ** 2
        if raw.has_moments:
            ok = ok and all(n * lo <= sums[k] <= n * hi for k in ("sum_real", "sum_sim"))
            ok = ok and all(0 <= sums[k] <= n * top for k in ("sum_real_sq", "sum_sim_sq"))
            ok = ok and abs(sums["sum_cross"]) <= n * top
        return ok

    def _reload(self, where: tuple[int, int], shape: tuple[int, int]) -> PairStats:
        """A taken record's statistics read again (for pooling, once their turn comes)."""
        try:
            return self._stats(self.log.read(where)[2], shape)
        except BadRecord as exc:
            raise FidelityError(f"{self.log.side}: a record changed while the run resumed ({exc}); "
                                f"score without resuming", option="resume") from None

    def notes(self) -> list[str]:
        """What the run's report says about the records that were not taken."""
        out = []
        if self.unusable:
            out.append(f"{self.log.side}: {self.unusable} record(s) with a valid checksum could not be used "
                       f"(the first: {self.why}); their frames are scored again")
        if self.changed:
            out.append(f"{self.changed} frame(s) whose input files changed since they were scored are scored again")
        return out
