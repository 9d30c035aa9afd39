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

Each takes the run's :class:`~irfidelity.sequence.options.RunOptions` (threads, decoding
limits, the Dask client and chunk size) and scores every pair over the plan's mask when it has
one (``plan.mask``: one array for the whole run; Dask sends it to each worker once). With ``fingerprint`` (a run that keeps a log), every
outcome carries the fingerprints of what was scored (:mod:`.fingerprint`), taken by the
backend as it reads.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Protocol

import numpy as np

from .. import _core
from ..alignment import RegisteredPair, score_registered
from ..errors import FidelityError, ShapeError
from ..frames import FrameSequence
from ..registration import RegistrationWarning, from_engine
from ..stats import PairStats, pair_stats
from ..temperature import TemperatureErrors, tolerance_for
from .fingerprint import array_fingerprint, file_fingerprint
from .options import RunOptions
from .outcomes import Outcome
from .plan import SequencePlan, SequenceRequest

__all__ = ["Backend", "RustEngine", "DaskBackend", "ArrayLoop", "choose_backend", "engine_reads", "Todo"]

Todo = list[tuple[int, int, int]]  # (index, real index, sim index)
Deliver = Callable[[list[Outcome]], None]


class Backend(Protocol):
    def run(self, todo: Todo, deliver: Deliver) -> None: ...


def _file_sources(seq: FrameSequence) -> list[tuple[str, int]] | None:
    """(path, page) of every frame when the Rust engine can decode them all, else None."""
    if not seq.is_files:
        return None
    # (a sequence of files has a path for each frame; a multi-page file's pages share one)
    sources = [(p, page) for p, page in seq.sources if p is not None]
    if len(sources) < len(seq) or any(str(p).lower().endswith(".npy") for p in {p for p, _ in sources}):
        return None
    return sources


class RustEngine:
    def __init__(self, real: FrameSequence, sim: FrameSequence, plan: SequencePlan, options: RunOptions,
                 fingerprint: bool = False):
        real_files, sim_files = _file_sources(real), _file_sources(sim)
        assert real_files is not None and sim_files is not None  # chosen only when engine_reads(real, sim)
        self.real, self.sim = real_files, sim_files
        self.plan, self.options, self.fingerprint = plan, options, fingerprint

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
        request = self.plan.kernel_request(self.options.max_pixels, self.options.max_bytes)
        real = [self.real[r] for _, r, _ in todo]
        sim = [self.sim[s] for _, _, s in todo]
        _core.score_pairs([p for p, _ in real], [p for p, _ in sim], [g for _, g in real], [g for _, g in sim],
                          request=request, workers=int(self.options.workers or 0),
                          on_result=lambda rows: deliver(self._outcomes(todo, rows)),
                          fingerprints=self.fingerprint, mask=self.plan.mask_values)


def score_chunk(real_paths: list, sim_paths: list, real_pages: list, sim_pages: list, request: SequenceRequest,
                workers: int, fingerprints: bool = False, mask: np.ndarray | None = None) -> list:
    """Run on a Dask worker: score one chunk with the Rust engine (over ``mask``); statistics
    as bytes (the files' fingerprints, taken by the worker as it decoded them, come back with
    them)."""
    from irfidelity import _core as core

    out = core.score_pairs(real_paths, sim_paths, real_pages, sim_pages, request=request, workers=workers,
                           fingerprints=fingerprints, mask=mask)
    assert out is not None  # returned when no on_result takes them
    return [(k, None if st is None else st.to_bytes(), *rest) for k, st, *rest in out]


class DaskBackend(RustEngine):
    """The Rust engine on the workers of ``options.client``, ``options.chunk_size`` pairs a task."""

    def run(self, todo: Todo, deliver: Deliver) -> None:
        try:
            from distributed import as_completed
        except ImportError as exc:  # only without the dask extra
            raise FidelityError("a Dask client needs dask.distributed (pip install 'irfidelity[dask]')") from exc
        request = self.plan.kernel_request(self.options.max_pixels, self.options.max_bytes)
        workers, chunk_size = int(self.options.workers or 1), self.options.chunk_size
        client = self.options.client
        # the mask goes to every worker once, not with each chunk
        mask = None if self.plan.mask is None else client.scatter(self.plan.mask_values, broadcast=True)
        futures = {}
        for start in range(0, len(todo), chunk_size):
            chunk = todo[start:start + chunk_size]
            real = [self.real[r] for _, r, _ in chunk]
            sim = [self.sim[s] for _, _, s in chunk]
            future = client.submit(score_chunk, [p for p, _ in real], [p for p, _ in sim], [g for _, g in real],
                                   [g for _, g in sim], request, workers, self.fingerprint, mask, pure=False)
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
                client.cancel(list(futures))


def _extent(frame: np.ndarray, mask: np.ndarray | None) -> tuple[float, float] | None:
    """The frame's (min, max) over its finite values within ``mask``; None when there are none."""
    if mask is not None:
        frame = frame[mask]
    values = frame[np.isfinite(frame)] if frame.dtype.kind == "f" else frame
    return (float(values.min()), float(values.max())) if values.size else None


class ArrayLoop:
    def __init__(self, real: FrameSequence, sim: FrameSequence, plan: SequencePlan, fingerprint: bool = False,
                 max_bytes: int | None = None):
        self.real, self.sim, self.plan = real, sim, plan
        self.max_bytes, self.fingerprint = max_bytes, fingerprint

    def _one(self, index: int, r: int, s: int) -> Outcome:
        cfg = self.plan.config
        registration = extent = None
        try:
            real, sim = np.asarray(self.real[r]), np.asarray(self.sim[s])
            scored_sim, mask = sim, self._mask(real)
            if cfg.register is not None:  # the frames as the Rust engine scores them, on the same path
                st, pair = self._registered(real, sim, mask)
                registration, extent, scored_sim, mask = pair.registration, pair.extent, pair.sim, pair.mask
            else:
                st = pair_stats(real, sim, bits=cfg.bits, peak=cfg.numeric_peak, bins=cfg.bins,
                                hist_range=cfg.hist_range, need=self.plan.image, nonfinite=cfg.nonfinite, mask=mask)
                extent = _extent(real, mask) if self.plan.real_extent else None
            temperature = None if cfg.unit is None else TemperatureErrors.of_frames(
                real, scored_sim, mask=mask, unit=cfg.unit, tolerance=tolerance_for(cfg, self.plan.camera_metrics))
        except FidelityError as exc:
            return Outcome(index, None, str(exc))
        inputs = {"real": array_fingerprint(real), "sim": array_fingerprint(sim)} if self.fingerprint else None
        return Outcome(index, st, None, real.shape, real.dtype.name, extent,
                       registration if cfg.register_each else None, inputs, temperature)

    def _mask(self, real: np.ndarray) -> np.ndarray | None:
        """The plan's mask for this pair (a frame of another shape: the pair's error, as the
        engine gives it)."""
        mask = self.plan.mask
        if mask is not None and real.shape != mask.shape:
            raise ShapeError(f"the mask has shape {mask.shape}, the frames {real.shape}", option="mask")
        return None if mask is None else mask.values

    def _registered(self, real: np.ndarray, sim: np.ndarray,
                    mask: np.ndarray | None) -> tuple[PairStats, RegisteredPair]:
        """The pair scored through the plan's registration or, with ``register_each``, its
        own (whose confidence is in the pair's row: the run counts the unsure ones instead
        of warning per pair), over ``mask``, as the engine scores a file pair."""
        plan, cfg = self.plan, self.plan.config
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RegistrationWarning)
            pair = score_registered(real, sim, plan.pair_request(), model=cfg.register, method=cfg.register_method,
                                    registration=None if cfg.register_each else plan.registration, mask=mask,
                                    extent=plan.real_extent, max_bytes=self.max_bytes)
        st = PairStats(pair.stats, peak=cfg.numeric_peak or plan.default_peak, bins=plan.bin_label)
        return st, pair

    def run(self, todo: Todo, deliver: Deliver) -> None:
        for index, r, s in todo:
            deliver([self._one(index, r, s)])


def choose_backend(real: FrameSequence, sim: FrameSequence, plan: SequencePlan, options: RunOptions,
                   fingerprint: bool = False) -> Backend:
    """The Rust engine for files it decodes, Dask when a client is given, else the array loop."""
    files = engine_reads(real, sim)
    if options.client is not None:
        if not files:
            local = ("frames scored in a unit (config.unit) are converted and scored locally" if plan.config.unit
                     else "arrays and .npy files are scored locally")
            raise FidelityError(f"a Dask client needs file sources (EXR/PNG/TIFF paths) for both sequences; {local}",
                                option="client")
        return DaskBackend(real, sim, plan, options, fingerprint)
    if files:
        return RustEngine(real, sim, plan, options, fingerprint)
    return ArrayLoop(real, sim, plan, fingerprint, options.max_bytes)


def engine_reads(real: FrameSequence, sim: FrameSequence) -> bool:
    """Whether the Rust engine (locally or on Dask) reads both sequences' files; if not, their
    frames are scored as arrays."""
    return _file_sources(real) is not None and _file_sources(sim) is not None
