"""One sequence run: pair, plan, resume what can be trusted, score the rest, pool, report."""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from typing import Any, Callable

from .. import budget
from ..errors import FidelityError
from ..frames import FrameSequence
from ..registration import Registration
from ..schema import csv_columns
from ..stats import PairStats
from .backends import Decoding, choose_backend
from .fingerprint import Fingerprints
from .log import FrameLog, Record
from .outcomes import Outcome, error_entry, flat_row, frame_entry
from .pairing import Pairing
from .plan import SequencePlan
from .pooling import Pool, frame_statistics, registration_summary
from .progress import Progress
from .report import SequenceReport

__all__ = ["RunOptions", "execute"]


@dataclass(frozen=True)
class RunOptions:
    """How a run is carried out (never what it computes)."""

    workers: int | None = None
    progress: bool | Callable[[int, int], Any] = True
    client: Any = None
    csv: str | None = None
    resume: bool = False
    chunk_size: int = 16
    max_pixels: int | None = None
    #: The per-pair memory budget (already ``max_memory // workers`` when a run budget was given).
    max_bytes: int | None = None
    max_memory: int | None = None


def _names(seq: FrameSequence, index: int | None) -> str | None:
    return None if index is None else seq.names[index]


def _log_settings(plan: SequencePlan, pairing: Pairing, real: FrameSequence, sim: FrameSequence,
                  columns: list[str]) -> dict:
    names = "\n".join(f"{_names(real, r)}\t{_names(sim, s)}" for r, s in pairing.pairs)
    return {"config": plan.config.to_dict(), "plan": plan.settings(), "columns": columns,
            "frames": len(pairing.pairs), "pairs": hashlib.sha256(names.encode()).hexdigest()[:16]}


class _Scorer:
    """Turns outcomes into report entries, logs them, pools their statistics, shows progress."""

    def __init__(self, plan: SequencePlan, pairing: Pairing, real: FrameSequence, sim: FrameSequence,
                 log: FrameLog | None, progress: Progress, columns: list[str]):
        self.plan, self.pairing, self.log, self.progress, self.columns = plan, pairing, log, progress, columns
        self.real, self.sim = real, sim
        self.entries: dict[int, dict] = {}
        self.pool = Pool(plan)
        self.fingerprints = Fingerprints(real, sim) if log is not None else None

    def names(self, index: int) -> tuple[str | None, str | None]:
        r, s = self.pairing.pairs[index]
        return _names(self.real, r), _names(self.sim, s)

    def resume(self, records: dict[int, Record]) -> int:
        """Take the trusted records whose input files are unchanged; returns how many."""
        indices = [i for i in sorted(records) if i < len(self.pairing.pairs)]
        current = self.fingerprints.of_pairs([self.pairing.pairs[i] for i in indices]) if indices else []
        taken = 0
        for index, fingerprint in zip(indices, current):
            meta = records[index].meta
            if meta.get("inputs") != fingerprint:
                self.log.distrust(index)
                continue
            stats = PairStats.from_bytes(records[index].stats, bins=self.plan.bin_label)
            registration = meta.get("registration")
            outcome = Outcome(index, stats, None, tuple(meta["shape"]), meta["dtype"],
                              None if meta.get("extent") is None else tuple(meta["extent"]),
                              None if registration is None else Registration.from_dict(registration))
            self._add(outcome, resumed=True)
            taken += 1
        return taken

    def unmatched(self, index: int) -> None:
        real, sim = self.names(index)
        missing = "simulated" if sim is None else "real"
        entry = error_entry(index, real, sim, f"{real or sim}: no {missing} frame pairs with it "
                                              f"(paired by {self.pairing.rule})")
        if self.log is not None:
            self.log.write(flat_row(entry, self.columns), None)
        self._keep(entry, None, None)

    def deliver(self, outcomes: list[Outcome]) -> None:
        fingerprints = (self.fingerprints.of_pairs([self.pairing.pairs[o.index] for o in outcomes])
                        if self.log is not None else [None] * len(outcomes))
        for outcome, fingerprint in zip(outcomes, fingerprints):
            self._add(outcome, fingerprint)

    def _add(self, outcome: Outcome, fingerprint: Any = None, *, resumed: bool = False) -> None:
        real, sim = self.names(outcome.index)
        entry, stats = frame_entry(self.plan, outcome, real, sim)
        if self.log is not None and not resumed:
            self.log.write(flat_row(entry, self.columns), _record(outcome, stats, fingerprint))
        self._keep(entry, stats, outcome.real_extent, resumed=resumed)

    def _keep(self, entry: dict, stats: PairStats | None, extent: tuple | None, *, resumed: bool = False) -> None:
        self.entries[entry["index"]] = entry
        self.pool.add(entry["index"], stats, extent)
        self.progress.advance(resumed=resumed)


def _record(outcome: Outcome, stats: PairStats | None, fingerprint: Any) -> Record | None:
    """What a resumed run needs to trust a scored frame (None for a failure: it is retried)."""
    if stats is None:
        return None
    meta = {"inputs": fingerprint, "shape": list(outcome.shape), "dtype": outcome.dtype,
            "extent": None if outcome.real_extent is None else list(outcome.real_extent),
            "registration": None if outcome.registration is None else outcome.registration.to_dict()}
    return Record(outcome.index, meta, stats.to_bytes())


def execute(real: FrameSequence, sim: FrameSequence, pairing: Pairing, plan: SequencePlan,
            options: RunOptions) -> SequenceReport:
    """Score every pair of ``pairing`` (the module notes of :mod:`irfidelity.sequence`)."""
    columns = csv_columns(plan.weights.active(), registered=plan.config.register is not None)
    log = None
    if options.csv is not None:
        log = FrameLog(options.csv, columns, _log_settings(plan, pairing, real, sim, columns), options.resume)
    total = len(pairing.pairs)
    progress = Progress(total, options.progress)
    notes = list(plan.notes) + list(pairing.notes)
    try:
        scorer = _Scorer(plan, pairing, real, sim, log, progress, columns)
        resumed = scorer.resume(dict(log.trusted)) if log is not None and options.resume else 0
        if log is not None:
            notes += log.notes
        todo = []
        for index, (r, s) in enumerate(pairing.pairs):
            if index in scorer.entries:
                continue
            if r is None or s is None:
                scorer.unmatched(index)
            else:
                todo.append((index, r, s))
        if todo:
            if plan.dtype is None:
                scorer.deliver([Outcome(i, None, _unreadable(real, r)) for i, r, _ in todo])
            else:
                decoding = Decoding(options.workers, options.max_pixels, options.max_bytes)
                backend = choose_backend(real, sim, plan, decoding, options.client, options.chunk_size)
                backend.run(todo, scorer.deliver)
        frames = [scorer.entries[i] for i in range(total)]
        if log is not None:
            log.finish([flat_row(f, columns) for f in frames])
    finally:
        progress.close()
        if log is not None:
            log.close()
    score, pooling = scorer.pool.result(frames)
    pooled = score.to_dict() if score is not None else {}
    return SequenceReport(
        frames=frames, weights=plan.weights, failed=[f["index"] for f in frames if f["error"]],
        frame_stats=frame_statistics(frames), pooling=pooling, skipped=dict(plan.skipped), config=plan.config,
        notes=notes, inputs=dict(plan.inputs),
        registration=registration_summary(plan, frames),
        delay=None if pairing.delay is None else {**pairing.delay.to_dict(), "unpaired": pairing.unpaired},
        run={"pair_by": pairing.rule, "workers": options.workers,
             "csv": None if options.csv is None else os.fsdecode(options.csv), "resumed": resumed,
             "max_bytes": budget.resolve(options.max_bytes), "max_memory": options.max_memory},
        sources={"frames": _loader(real, sim, pairing), "curves": plan.camera_objects}, **pooled)


def _loader(real: FrameSequence, sim: FrameSequence, pairing: Pairing) -> Callable[[int], tuple[Any, Any]]:
    """``index -> (real frame, simulated frame)`` of a paired sequence (for report thumbnails)."""
    def load(index: int) -> tuple[Any, Any]:
        r, s = pairing.pairs[index]
        if r is None or s is None:
            raise FidelityError(f"frame {index} has no partner")
        return real[r], sim[s]

    return load


def _unreadable(real: FrameSequence, index: int) -> str:
    try:
        real[index]
    except FidelityError as exc:
        return str(exc)
    return f"{real.names[index]}: no real frame of the sequence could be read"
