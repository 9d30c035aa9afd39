"""Several simulators' runs sharing one pass of the Rust engine (``_core.score_shared``).

Each simulator's run is an ordinary :func:`~irfidelity.sequence.run.execute` (its pairing,
plan, log, resume and report), on a thread of its own, whose backend is a
:class:`SharedMember`: instead of scoring, it hands its pairs to the :class:`SharedRun` and
waits for their outcomes. Once every run has handed over its pairs (or ended without any),
the calling thread scores them all in one engine call: each real frame is decoded once and
every simulated frame paired with it is scored against it on the same worker. Outcomes go
back to their run through a bounded queue, so a run that falls behind holds the engine
back instead of filling memory.
"""

from __future__ import annotations

import queue
import threading
from dataclasses import dataclass
from typing import Any, Callable

from .. import _core
from ..errors import FidelityError
from ..frames import FrameSequence
from .backends import Deliver, RustEngine, Todo
from .options import RunOptions
from .plan import SequencePlan
from .progress import Progress

__all__ = ["SharedRun", "SharedMember"]

_BATCHES = 4  # outcome batches a run's queue holds before the engine waits for it
_WAIT = 0.1  # seconds between checks that a waiting run is still alive


class _Stop:
    """What a member's queue gets when the engine stopped (None: finished normally)."""

    def __init__(self, error: BaseException | None):
        self.error = error


@dataclass
class SharedMember:
    """A run's backend: its pairs, handed to the shared engine, and its outcomes' queue."""

    shared: SharedRun
    name: str
    engine: RustEngine
    todo: Todo | None = None
    stopped: bool = False  # the engine stopped for another reason than this run

    def __post_init__(self) -> None:
        self.outcomes: queue.Queue = queue.Queue(maxsize=_BATCHES)

    def run(self, todo: Todo, deliver: Deliver) -> None:
        self.todo = todo
        self.shared.arrive(self.name, self)
        while True:
            item = self.outcomes.get()
            if isinstance(item, _Stop):
                if item.error is not None:
                    self.stopped = True
                    raise FidelityError(f"{self.name}: scoring stopped: {item.error}") from item.error
                return
            deliver(self.engine._outcomes(todo, item))


class SharedRun:
    """Runs every simulator's ``execute`` on its own thread, scoring their pairs in one engine call."""

    def __init__(self, names: list, workers: int | None, progress: bool | Callable[[int, int], Any]):
        self.names, self.workers, self.progress = list(names), workers, progress
        self.ready = threading.Condition()
        self.arrived: dict[str, SharedMember | None] = {}
        self.threads: dict[str, threading.Thread] = {}

    def backend(self, name: str) -> Callable[..., SharedMember]:
        """The ``RunOptions.backend`` of simulator ``name``."""
        def make(real: FrameSequence, sim: FrameSequence, plan: SequencePlan, options: RunOptions,
                 fingerprint: bool = False) -> SharedMember:
            return SharedMember(self, name, RustEngine(real, sim, plan, options, fingerprint))

        return make

    def arrive(self, name: str, member: SharedMember | None) -> None:
        """``name``'s run has handed over its pairs (``member``), or ended without (None)."""
        with self.ready:
            self.arrived.setdefault(name, member)
            self.ready.notify_all()

    def run(self, runs: dict[str, Callable[[], Any]]) -> dict:
        """``{name: runs[name]()}``, each on its own thread, their pairs scored together."""
        results: dict[str, Any] = {}
        errors: dict[str, BaseException] = {}

        def one(name: str) -> None:
            try:
                results[name] = runs[name]()
            except BaseException as exc:  # every exception: re-raised by the calling thread
                errors[name] = exc
            finally:
                self.arrive(name, None)

        for name in self.names:
            self.threads[name] = threading.Thread(target=one, args=(name,), name=f"irfidelity-sim-{name}", daemon=True)
            self.threads[name].start()
        stop: BaseException | None = None
        try:
            with self.ready:
                self.ready.wait_for(lambda: len(self.arrived) == len(self.names))
            members = [m for m in self.arrived.values() if m is not None]
            if members:
                self._score(members)
        except BaseException as exc:  # every exception: re-raised below, once every run has ended
            stop = exc
        for member in self.arrived.values():
            if member is not None:
                self._put(member, _Stop(stop), wait=stop is None)
        for thread in self.threads.values():
            thread.join()
        # a run's own failure first (the engine stops because of it), then the engine's
        own = [e for n, e in errors.items() if not getattr(self.arrived.get(n), "stopped", False)]
        if own or stop is not None:
            raise own[0] if own else stop  # type: ignore[misc]
        if errors:
            raise next(iter(errors.values()))
        return {name: results[name] for name in self.names}

    def _put(self, member: SharedMember, item: Any, wait: bool = True) -> None:
        """Queue ``item`` for ``member``'s run. A run whose thread has ended takes nothing:
        outcomes for it are an error (stopping the engine), a stop is dropped. Without
        ``wait``, a full queue is emptied first."""
        while True:
            try:
                member.outcomes.put(item, timeout=_WAIT)
                return
            except queue.Full:
                if not self.threads[member.name].is_alive():
                    if isinstance(item, _Stop):
                        return
                    raise FidelityError(f"{member.name}: the run stopped before its frames were scored") from None
                if not wait:
                    _drain(member.outcomes)

    def _score(self, members: list[SharedMember]) -> None:
        """Every member's pairs in one ``_core.score_shared`` call."""
        first = members[0].engine
        real_paths = [p for p, _ in first.real]
        real_pages = [g for _, g in first.real]
        task_of: list[tuple[int, int]] = []  # task -> (member, position in its todo)
        sim_paths, sim_pages, owners, kinds = [], [], [], []
        for m, member in enumerate(members):
            for position, (_, r, s) in enumerate(member.todo or []):
                path, page = member.engine.sim[s]
                sim_paths.append(path)
                sim_pages.append(page)
                owners.append(r)
                kinds.append(m)
                task_of.append((m, position))
        requests = [member.engine.plan.kernel_request(member.engine.options.max_pixels,
                                                      member.engine.options.max_bytes) for member in members]
        mask = first.plan.mask
        if any(member.engine.plan.mask is not mask for member in members):
            raise FidelityError("the simulators' runs were planned with different masks; one pass scores every "
                                "simulator over one mask (on the real frames' grid)", option="mask")
        progress = Progress(len(task_of), self.progress)

        def on_result(rows: list) -> None:
            batches: dict[int, list] = {}
            for k, *rest in rows:
                m, position = task_of[k]
                batches.setdefault(m, []).append((position, *rest))
            for m, batch in batches.items():
                self._put(members[m], batch)
            for _ in rows:
                progress.advance()

        try:
            _core.score_shared(real_paths, real_pages, sim_paths, sim_pages, owners, kinds, requests=requests,
                               workers=int(self.workers or 0), on_result=on_result,
                               fingerprints=any(member.engine.fingerprint for member in members),
                               mask=first.plan.mask_values)
        finally:
            progress.close()


def _drain(q: queue.Queue) -> None:
    while True:
        try:
            q.get_nowait()
        except queue.Empty:
            return
