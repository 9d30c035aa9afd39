"""Where frame pairs are scored: three backends behind one interface.

A backend takes the pairs still to score, ``[(index, real_index, sim_index), ...]``, and
calls ``deliver(outcomes)`` with batches of :class:`~irfidelity.sequence.outcomes.Outcome`
as pairs finish, in any order.

* :class:`RustEngine` — files (EXR/PNG/TIFF): the whole loop in Rust (``_core.score_pairs``):
  both frames decoded and reduced to statistics on ``workers`` threads, in parallel over
  pairs, GIL released, a few frames in flight per worker whatever the sequence length.
* :class:`DaskBackend` — the same engine on a Dask cluster's workers, chunk by chunk; the
  statistics come back as bytes (identical results; the files must be readable at the same
  paths on every worker).
* :class:`ArrayLoop` — arrays and ``.npy`` files: a Python loop over
  :func:`irfidelity.pair_stats` (each call itself parallel in Rust).

With ``Decoding.fingerprint`` (a run that keeps a log), every outcome carries the
fingerprints of what was scored (:mod:`.fingerprint`), taken by the backend as it reads.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from .. import _core
from ..alignment import aligned_pair, find_registration
from ..errors import FidelityError, ShapeError
from ..frames import FrameSequence
from ..registration import RegistrationWarning, from_engine
from ..stats import KernelRequest, PairStats, pair_stats
from .fingerprint import array_fingerprint, file_fingerprint
from .outcomes import Outcome
from .plan import SequencePlan

__all__ = ["Backend", "RustEngine", "DaskBackend", "ArrayLoop", "choose_backend", "engine_reads", "Todo"]

Todo = list[tuple[int, int, int]]  # (index, real index, sim index)
Deliver = Callable[[list[Outcome]], None]


class Backend(Protocol):
    def run(self, todo: Todo, deliver: Deliver) -> None: ...


@dataclass(frozen=True)
class Decoding:
    """How frame files are decoded (limits do not change a score, only what is refused)."""

    workers: int | None = None
    max_pixels: int | None = None
    max_bytes: int | None = None
    fingerprint: bool = False  # fingerprint what is scored, for a resumable log


def _file_sources(seq: FrameSequence) -> list[tuple[str, int]] | None:
    """(path, page) of every frame when the Rust engine can decode them all, else None."""
    if not seq.is_files:
        return None
    entries = seq.entries
    if any(str(p).lower().endswith(".npy") for p, _, _ in entries):
        return None
    return [(p, page) for p, page, _ in entries]


class RustEngine:
    def __init__(self, real: FrameSequence, sim: FrameSequence, plan: SequencePlan, decoding: Decoding):
        self.real, self.sim = _file_sources(real), _file_sources(sim)
        self.plan, self.decoding = plan, decoding

    def _outcomes(self, todo: Todo, rows: list) -> list[Outcome]:
        """Outcomes from the engine's ``(k, stats, error, shape, dtype, real extent,
        registration, fingerprints)`` tuples (k indexes ``todo``)."""
        plan, out = self.plan, []
        for k, raw, err, shape, dtype, extent, found, fingerprints in rows:
            index, r, s = todo[k]
            stats = None if raw is None else PairStats(raw, bins=plan.bin_label)
            registration = None if found is None else from_engine(found, str(plan.config.register), shape)
            inputs = None if fingerprints is None else {
                "real": file_fingerprint(*self.real[r], *fingerprints[0]),
                "sim": file_fingerprint(*self.sim[s], *fingerprints[1])}
            out.append(Outcome(index, stats, err, None if shape is None else tuple(shape), dtype, extent,
                               registration, inputs))
        return out

    def run(self, todo: Todo, deliver: Deliver) -> None:
        request = self.plan.kernel_request(self.decoding.max_pixels, self.decoding.max_bytes)
        real = [self.real[r] for _, r, _ in todo]
        sim = [self.sim[s] for _, _, s in todo]
        _core.score_pairs([p for p, _ in real], [p for p, _ in sim], [g for _, g in real], [g for _, g in sim],
                          request=request, workers=int(self.decoding.workers or 0),
                          on_result=lambda rows: deliver(self._outcomes(todo, rows)),
                          fingerprints=self.decoding.fingerprint)


def score_chunk(real_paths: list, sim_paths: list, real_pages: list, sim_pages: list, request: KernelRequest,
                workers: int, fingerprints: bool = False) -> list:
    """Run on a Dask worker: score one chunk with the Rust engine; statistics as bytes (the
    files' fingerprints, taken by the worker as it decoded them, come back with them)."""
    from irfidelity import _core as core

    out = core.score_pairs(real_paths, sim_paths, real_pages, sim_pages, request=request, workers=workers,
                           fingerprints=fingerprints)
    return [(k, None if st is None else st.to_bytes(), *rest) for k, st, *rest in out]


class DaskBackend(RustEngine):
    def __init__(self, real: FrameSequence, sim: FrameSequence, plan: SequencePlan, decoding: Decoding,
                 client: Any, chunk_size: int):
        super().__init__(real, sim, plan, decoding)
        self.client, self.chunk_size = client, chunk_size

    def run(self, todo: Todo, deliver: Deliver) -> None:
        try:
            from distributed import as_completed
        except ImportError as exc:  # only without the dask extra
            raise FidelityError("a Dask client needs dask.distributed (pip install 'irfidelity[dask]')") from exc
        request = self.plan.kernel_request(self.decoding.max_pixels, self.decoding.max_bytes)
        workers = int(self.decoding.workers or 1)
        futures = {}
        for start in range(0, len(todo), self.chunk_size):
            chunk = todo[start:start + self.chunk_size]
            real = [self.real[r] for _, r, _ in chunk]
            sim = [self.sim[s] for _, _, s in chunk]
            future = self.client.submit(score_chunk, [p for p, _ in real], [p for p, _ in sim],
                                        [g for _, g in real], [g for _, g in sim], request, workers,
                                        self.decoding.fingerprint, pure=False)
            futures[future] = chunk
        try:
            for future in as_completed(list(futures)):
                chunk = futures.pop(future)
                rows = future.result()
                future.release()
                deliver(self._outcomes(chunk, [(k, None if data is None else _core.PairStats.from_bytes(data), *rest)
                                               for k, data, *rest in rows]))
        finally:
            if futures:
                self.client.cancel(list(futures))


def _extent(frame: np.ndarray) -> tuple[float, float] | None:
    values = frame[np.isfinite(frame)] if frame.dtype.kind == "f" else frame
    return (float(values.min()), float(values.max())) if values.size else None


class ArrayLoop:
    def __init__(self, real: FrameSequence, sim: FrameSequence, plan: SequencePlan, fingerprint: bool = False):
        self.real, self.sim, self.plan, self.fingerprint = real, sim, plan, fingerprint

    def _one(self, index: int, r: int, s: int) -> Outcome:
        cfg = self.plan.config
        registration = None
        try:
            real, sim = np.asarray(self.real[r]), np.asarray(self.sim[s])
            numeric_peak = cfg.peak if isinstance(cfg.peak, float) else None
            bits, mask, hist_range = cfg.bits, None, cfg.hist_range
            scored_real, scored_sim = real, sim
            if cfg.register is not None:  # the frames as the Rust engine scores them
                registration = self._registration(real, sim)
                scored_real, scored_sim, mask = aligned_pair(real, sim, registration, valid=self.plan.valid)
                bits, numeric_peak = None, numeric_peak or self.plan.default_peak
                hist_range = self.plan.hist_range if self.plan.hist_range is not None else hist_range
            st = pair_stats(scored_real, scored_sim, bits=bits, peak=numeric_peak, bins=cfg.bins, hist_range=hist_range,
                            mask=mask, need=self.plan.image, nonfinite=cfg.nonfinite)
        except FidelityError as exc:
            return Outcome(index, None, str(exc))
        extent = _extent(scored_real if mask is None else scored_real[mask]) if "psnr" in self.plan.image else None
        inputs = {"real": array_fingerprint(real), "sim": array_fingerprint(sim)} if self.fingerprint else None
        return Outcome(index, st, None, real.shape, real.dtype.name, extent,
                       registration if cfg.register_each else None, inputs)

    def _registration(self, real: np.ndarray, sim: np.ndarray) -> Any:
        """The plan's registration, or with ``register_each`` the pair's own (its confidence
        is in the pair's row; the run counts the unsure ones instead of warning per pair)."""
        if real.shape != sim.shape:
            raise ShapeError(f"real and sim frames differ in shape: {real.shape} vs {sim.shape}")
        if not self.plan.config.register_each:
            return self.plan.registration
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RegistrationWarning)
            return find_registration(real, sim, self.plan.config)

    def run(self, todo: Todo, deliver: Deliver) -> None:
        for index, r, s in todo:
            deliver([self._one(index, r, s)])


def choose_backend(real: FrameSequence, sim: FrameSequence, plan: SequencePlan, decoding: Decoding,
                   client: Any, chunk_size: int) -> Backend:
    """The Rust engine for files it decodes, Dask when a client is given, else the array loop."""
    files = engine_reads(real, sim)
    if client is not None:
        if not files:
            raise FidelityError("a Dask client needs file sources (EXR/PNG/TIFF paths) for both sequences; "
                                "arrays and .npy files are scored locally", option="client")
        return DaskBackend(real, sim, plan, decoding, client, chunk_size)
    if files:
        return RustEngine(real, sim, plan, decoding)
    return ArrayLoop(real, sim, plan, decoding.fingerprint)


def engine_reads(real: FrameSequence, sim: FrameSequence) -> bool:
    """Whether the Rust engine (locally or on Dask) reads both sequences' files; if not, their
    frames are scored as arrays."""
    return _file_sources(real) is not None and _file_sources(sim) is not None
