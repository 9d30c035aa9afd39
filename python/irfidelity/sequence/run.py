"""One sequence run: pair, plan, resume what can be trusted, score the rest, pool, report."""

from __future__ import annotations

import hashlib
import os
from typing import Callable, Sequence

from .. import _core, budget
from ..errors import FidelityError
from ..frames import FrameSequence
from ..ceiling import relative_to
from ..schema import csv_columns
from ..stats import PairStats
from .backends import choose_backend, engine_reads
from .entry import FrameEntry
from .fingerprint import Fingerprints
from .log import FrameLog
from .options import RunOptions
from .outcomes import Outcome, error_entry, flat_row, frame_entry
from .pairing import Pairing
from .plan import SequencePlan
from .pooling import FrameColumns, Pool, frame_statistics, registration_summary
from .progress import Progress
from .report import SequenceReport
from .resume import RecordBounds, Resumer
from .sidecar import encode_record
from .sources import FramePairs

__all__ = ["RunOptions", "execute"]


def _log_settings(plan: SequencePlan, pairing: Pairing, real_names: Sequence[str], sim_names: Sequence[str],
                  columns: list[str]) -> dict:
    def name(names: Sequence[str], index: int | None) -> str | None:
        return None if index is None else names[index]

    text = "\n".join(f"{name(real_names, r)}\t{name(sim_names, s)}" for r, s in pairing.pairs)
    return {"config": plan.config.to_dict(), "plan": plan.settings(), "columns": columns,
            "frames": len(pairing.pairs), "pairs": hashlib.sha256(text.encode()).hexdigest()[:16]}


class _Scorer:
    """Turns outcomes into report entries, logs them, pools their statistics, shows progress.

    Statistics are pooled in index order. A resumed frame whose turn has not come yet is
    pooled later from its record (``deferred``), so waiting frames hold no statistics.
    """

    def __init__(self, plan: SequencePlan, pairing: Pairing, real_names: Sequence[str], sim_names: Sequence[str],
                 log: FrameLog | None, progress: Progress, columns: list[str]):
        self.plan, self.pairing, self.log, self.progress, self.columns = plan, pairing, log, progress, columns
        self.real_names, self.sim_names = real_names, sim_names
        self.entries: dict[int, FrameEntry] = {}
        self.pool = Pool(plan)
        self.deferred: dict[int, tuple[Callable[[], PairStats], tuple | None]] = {}
        self.sums: dict[int, dict] = {}  # each scored frame's exact sums, for intervals

    def names(self, index: int) -> tuple[str | None, str | None]:
        r, s = self.pairing.pairs[index]
        return (None if r is None else self.real_names[r]), (None if s is None else self.sim_names[s])

    def unmatched(self, index: int) -> None:
        real, sim = self.names(index)
        entry = error_entry(index, real, sim, f"{real or sim}: {self.pairing.why_alone(index)}")
        if self.log is not None:
            self.log.write(flat_row(entry, self.columns), None)
        self._keep(entry, None, None)

    def deliver(self, outcomes: list[Outcome]) -> None:
        for outcome in outcomes:
            real, sim = self.names(outcome.index)
            entry, stats = frame_entry(self.plan, outcome, real, sim)
            if self.log is not None:
                self.log.write(flat_row(entry, self.columns), _record(outcome, stats))
            self._keep(entry, stats, outcome.real_extent)

    def resumed(self, entry: FrameEntry, stats: PairStats, extent: tuple | None, reload: Callable[[], PairStats]) -> None:
        """A frame taken from the log (``reload()`` reads its statistics again)."""
        index = entry["index"]
        ready = index == self.pool.next
        if not ready:
            self.deferred[index] = (reload, extent)
        self._keep(entry, stats, extent, resumed=True, pool=ready)

    def _keep(self, entry: FrameEntry, stats: PairStats | None, extent: tuple | None, *, resumed: bool = False,
              pool: bool = True) -> None:
        index = entry["index"]
        self.entries[index] = entry
        sums = None if stats is None else stats.int_sums()
        if sums is not None:
            self.sums[index] = {"n": stats.n, **sums}  # type: ignore[union-attr]
        if pool:
            self.pool.add(index, stats, extent)
        while self.pool.next in self.deferred:
            reload, deferred_extent = self.deferred.pop(self.pool.next)
            self.pool.add(self.pool.next, reload(), deferred_extent)
        self.progress.advance(resumed=resumed)


def _record(outcome: Outcome, stats: PairStats | None) -> bytes | None:
    """What a resumed run needs to trust a scored frame (None for a failure, or when the
    backend could not fingerprint what it scored: the frame is scored again)."""
    if stats is None or outcome.inputs is None:
        return None
    assert outcome.shape is not None  # a scored frame has a shape
    meta = {"inputs": outcome.inputs, "shape": list(outcome.shape), "dtype": outcome.dtype,
            "extent": None if outcome.real_extent is None else list(outcome.real_extent),
            "registration": None if outcome.registration is None else outcome.registration.to_dict(),
            "temperature": None if outcome.temperature is None else outcome.temperature.to_dict()}
    return encode_record(outcome.index, meta, stats.to_bytes())


def _resume(scorer: _Scorer, log: FrameLog, real: FrameSequence, sim: FrameSequence, plan: SequencePlan,
            pairing: Pairing, options: RunOptions) -> tuple[int, list[str]]:
    """Take the trusted records of the log (:mod:`.resume`); how many, and what to note."""
    fingerprints = Fingerprints(real, sim, arrays=not engine_reads(real, sim))
    resumer = Resumer(plan, pairing, log, fingerprints, _bounds(plan, options))
    taken = resumer.take(scorer.names, scorer.resumed)
    return taken, resumer.notes()


def _bounds(plan: SequencePlan, options: RunOptions) -> RecordBounds:
    max_pixels = options.max_pixels  # resolved by RunOptions
    assert max_pixels is not None
    max_bytes = _core.default_max_bytes() if options.max_bytes is None else options.max_bytes
    return RecordBounds(plan, max_pixels, max_bytes)


def execute(real: FrameSequence, sim: FrameSequence, pairing: Pairing, plan: SequencePlan,
            options: RunOptions) -> SequenceReport:
    """Score every pair of ``pairing`` (the module notes of :mod:`irfidelity.sequence`)."""
    columns = csv_columns(plan.weights.active(), registered=plan.config.register is not None,
                          temperature=plan.config.unit is not None)
    real_names, sim_names = real.names, sim.names
    log = None
    if options.csv is not None:
        assert isinstance(options.csv, str)  # RunOptions made it one
        log = FrameLog(options.csv, columns, _log_settings(plan, pairing, real_names, sim_names, columns),
                       options.resume, _bounds(plan, options).run, len(pairing.pairs))
    total = len(pairing.pairs)
    progress = Progress(total, options.progress)
    notes = list(plan.notes) + list(pairing.notes)
    try:
        scorer = _Scorer(plan, pairing, real_names, sim_names, log, progress, columns)
        resumed = 0
        if log is not None:
            notes += log.notes
            if options.resume:
                resumed, found = _resume(scorer, log, real, sim, plan, pairing, options)
                notes += found
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
                backend = (options.backend or choose_backend)(real, sim, plan, options, fingerprint=log is not None)
                backend.run(todo, scorer.deliver)
        frames = [scorer.entries[i] for i in range(total)]
        if log is not None:
            log.finish(flat_row(f, columns) for f in frames)
    finally:
        progress.close()
        if log is not None:
            log.close()
    scored = FrameColumns(frames, {"components": plan.camera_components, "metrics": plan.camera_metrics})
    score, pooling = scorer.pool.result(scored)
    pooled = score.to_dict() if score is not None else {}
    if score is not None:
        pooled.update(verdict=score.verdict.to_dict(), ceiling=plan.ceiling,
                      relative=relative_to(plan.ceiling, score.components))
    unpaired = pairing.expected_alone
    alone = set(unpaired)
    return SequenceReport(
        frames=frames, weights=plan.weights, unpaired=unpaired,
        failed=[f.index for f in frames if f.error and f.index not in alone],
        frame_stats=frame_statistics(scored), pooling=pooling, skipped=dict(plan.skipped), config=plan.config,
        notes=notes, inputs=dict(plan.inputs),
        registration=registration_summary(plan, frames),
        delay=None if pairing.delay is None else {**pairing.delay.to_dict(), "unpaired": pairing.unpaired},
        run={"pair_by": pairing.rule, "workers": options.workers,
             "csv": None if options.csv is None else os.fsdecode(options.csv), "resumed": resumed,
             "max_bytes": budget.resolve(options.max_bytes), "max_memory": options.max_memory},
        sources={"frames": FramePairs(real, sim, pairing.pairs), "curves": plan.camera_objects, "sums": scorer.sums},
        transfer=plan.transfer, **pooled)


def _unreadable(real: FrameSequence, index: int) -> str:
    try:
        real[index]
    except FidelityError as exc:
        return str(exc)
    return f"{real.names[index]}: no real frame of the sequence could be read"
