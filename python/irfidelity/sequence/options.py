"""How a sequence run is carried out: :class:`RunOptions`, checked once when made.

Its fields are the one list of run keywords: :func:`~irfidelity.score_sequence` takes them
as ``run=RunOptions(...)`` or as keywords (:func:`split_options`), every other keyword is a
:class:`~irfidelity.ScoringConfig` field. A run option never changes a score, only how it
is computed and what is refused.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, fields
from typing import Any, Callable, Mapping

from .. import budget
from ..errors import FidelityError
from ..keywords import options_from

__all__ = ["RunOptions", "RUN_KEYWORDS", "split_options"]

_MOST = 1 << 16  # workers or pairs per Dask task: far beyond any machine


def _positive(name: str, value: Any, allow_none: bool = False) -> Any:
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= _MOST:
        raise FidelityError(f"{name} must be an integer in 1..{_MOST}{' or None' if allow_none else ''}, "
                            f"got {value!r}", option=name)
    return int(value)


@dataclass(frozen=True)
class RunOptions:
    """How a sequence run is carried out (never what it computes).

    Parameters
    ----------
    workers : int, optional
        Threads over frame pairs (default: all cores); with ``client``, threads per Dask task
        (default 1).
    progress : bool or callable, default True
        A tqdm bar (or a plain line without tqdm), nothing, or ``callable(done, total)``.
    client : dask.distributed.Client, optional
        Score chunks of ``chunk_size`` pairs on the cluster (file sources only).
    csv : path, optional
        Stream one row per frame as frames finish (:mod:`irfidelity.sequence.log`).
    resume : bool, default False
        Keep the trusted frames of an earlier run on ``csv``; score the rest.
    chunk_size : int, default 16
        Pairs per Dask task.
    max_pixels : int, optional
        The decoding limit per frame in pixels (:func:`irfidelity.load_frame`); a frame beyond
        it is that frame's error row.
    max_bytes : int, optional
        The memory budget of one frame pair's work, bytes (default
        :data:`irfidelity.budget.DEFAULT_MAX_BYTES`): both frames decoded, their float64
        copies, registration, resampling and statistics are planned against it before they
        allocate; a pair over budget is that frame's error row, never the end of the run.
    max_memory : int, optional
        The memory budget of the run, bytes: each pair gets ``max_memory // workers`` (the
        smaller of that and ``max_bytes`` when both are given; ``max_bytes`` becomes that
        per-pair budget), so the run holds at most ``workers`` × that budget plus a small fixed
        overhead (docs/design.md §14). With ``client``, per Dask task (one thread by default).
    backend : callable, optional
        ``backend(real, sim, plan, options, fingerprint=...)``, called as
        :func:`~irfidelity.sequence.backends.choose_backend` is: where the pairs are scored
        instead of that function's choice (:func:`irfidelity.score_simulators` hands each
        simulator's pairs to one shared engine pass this way).

    Examples
    --------
    >>> from irfidelity.sequence import RunOptions
    >>> RunOptions(workers=2, progress=False).workers
    2
    >>> RunOptions(workers=0)
    Traceback (most recent call last):
    ...
    irfidelity.errors.FidelityError: workers must be an integer in 1..65536 or None, got 0
    """

    workers: int | None = None
    progress: bool | Callable[[int, int], Any] = True
    client: Any = None
    csv: str | os.PathLike | None = None
    resume: bool = False
    chunk_size: int = 16
    max_pixels: int | None = None
    max_bytes: int | None = None
    max_memory: int | None = None
    backend: Callable[..., Any] | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen: the checked values replace the given ones
        set_(self, "workers", _positive("workers", self.workers, allow_none=True))
        threads = self.workers if self.workers is not None or self.client is None else 1
        set_(self, "max_bytes", budget.per_pair(self.max_bytes, self.max_memory, threads))
        set_(self, "max_pixels", budget.max_pixels(self.max_pixels))  # explicit for workers elsewhere
        set_(self, "chunk_size", _positive("chunk_size", self.chunk_size))
        set_(self, "csv", None if self.csv is None else os.fspath(self.csv))
        set_(self, "resume", bool(self.resume))
        if self.resume and self.csv is None:
            raise FidelityError("resuming needs the CSV of the interrupted run", option="csv")


#: The keywords of :func:`~irfidelity.score_sequence` that fill :class:`RunOptions`.
RUN_KEYWORDS = tuple(f.name for f in fields(RunOptions))


def split_options(run: RunOptions | None, options: Mapping[str, Any]) -> tuple[RunOptions, dict[str, Any]]:
    """The run options (``run``, or made from the run keywords among ``options``) and the
    remaining keywords (:class:`~irfidelity.ScoringConfig` fields). A run keyword given with
    ``run`` is given twice: a FidelityError."""
    given = {k: v for k, v in options.items() if k in RUN_KEYWORDS}
    rest = {k: v for k, v in options.items() if k not in RUN_KEYWORDS}
    return options_from(RunOptions, run, given, "run"), rest
