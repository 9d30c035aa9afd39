"""Several simulators against one real recording: :func:`score_simulators`.

Every simulator's sequence is scored as :func:`irfidelity.score_sequence` scores it (its own
pairing, plan, CSV log and resume), but in one pass of the Rust engine: each real frame is
decoded once and every simulator's frame paired with it is scored against it on the same
worker (:mod:`irfidelity.sequence.shared`). The per-simulator reports are then ranked by
:func:`irfidelity.ranking.rank` on the real frames every simulator scored: the order, which
differences are significant (paired block bootstrap, Holm-corrected) and how stable the order
is under the frames' sampling and weight changes (P(first)). docs/ranking.md says what the
figures mean.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Mapping

from .bootstrap import DEFAULT_RESAMPLES, check_level, check_resamples
from .camera import CameraInputs
from .config import ScoringConfig
from .errors import FidelityError
from .evaluation import Scorer
from .masks import MaskSpec
from .ranking import Ranking, rank
from .reuse import RealMemo
from .schema import to_json
from .sequence import SequenceReport, _pairing, with_intervals
from .sequence.backends import engine_reads
from .sequence.intervals import FrameNumbers, frame_numbers
from .sequence.options import RunOptions, split_options
from .sequence.plan import make_plan
from .sequence.run import execute
from .sequence.shared import SharedRun
from .sequence.sources import as_sequence
from .temperature import temperature_sequence

__all__ = ["score_simulators", "SimulatorComparison"]

_SAFE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")


@dataclass
class SimulatorComparison:
    """Result of :func:`score_simulators`.

    Attributes
    ----------
    reports : dict
        ``{name: SequenceReport}``, in the order the simulators were given.
    ranking : Ranking
        :func:`irfidelity.ranking.rank` of the simulators on ``frames``.
    frames : list
        The real frames every simulator scored (the frames ranked), in order.
    notes : list of str

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> rng = np.random.default_rng(1)
    >>> real = rng.integers(1000, 3000, (20, 16, 16)).astype(np.uint16)
    >>> sims = {"a": real + 2, "b": real + 9}
    >>> result = irf.score_simulators(real, sims, peak="range", weights="psnr=1", progress=False, resamples=199)
    >>> result.order, len(result.frames), result.reports["b"].fidelity < result.reports["a"].fidelity
    (['a', 'b'], 20, True)
    """

    reports: dict
    ranking: Ranking
    frames: list
    notes: list = field(default_factory=list)

    @property
    def order(self) -> list:
        """Simulator names, best first (pooled fidelity over :attr:`frames`)."""
        return list(self.ranking.order)

    @property
    def significant(self) -> dict:
        """``{(a, b): bool}`` for every pair, ``a`` ranked above ``b``: is the fidelity
        difference significant at ``ranking.level`` after the correction."""
        return dict(self.ranking.significant)

    @property
    def stability(self) -> Any:
        """The order's stability (``p_first``, ``mean_rank``) over draws that each resample the
        ranked frames in blocks and draw the weights around K (:attr:`Ranking.stability
        <irfidelity.ranking.Ranking.stability>`): simulators these frames cannot tell apart share
        the first place."""
        return self.ranking.stability

    def to_dict(self) -> dict:
        """JSON-ready: the ranking, the frames ranked and each simulator's report."""
        return to_json({"order": self.order, "ranking": self.ranking.to_dict(), "frames": list(self.frames),
                        "notes": list(self.notes),
                        "reports": {name: rep.to_dict() for name, rep in self.reports.items()}})

    def to_csv(self, path: str | os.PathLike) -> None:
        """One row per simulator, best first: rank, fidelity and each component with their
        intervals (over the ranked frames), frames scored and failed."""
        from .report.comparison import comparison_rows, write_rows

        write_rows(comparison_rows(self), path)

    def to_html(self, path: str | os.PathLike | None = None) -> str:
        """A self-contained HTML comparison (:mod:`irfidelity.report.comparison`); written to
        ``path`` when given, returned either way. Needs matplotlib."""
        from .report import write_html
        from .report.comparison import render_comparison_html

        return write_html(render_comparison_html(self), path)

    def summary_text(self) -> str:
        head = f"{len(self.reports)} simulators ranked on {len(self.frames)} real frames"
        return "\n".join([head, self.ranking.summary_text(), *[f"note: {n}" for n in self.notes]])

    def __str__(self) -> str:
        return self.summary_text()


def _simulators(sims: Any) -> dict:
    if not isinstance(sims, Mapping) or len(sims) < 2:
        raise FidelityError("simulators must be a mapping of at least two {name: simulated sequence}",
                            option="simulators")
    names = [str(name) for name in sims]
    if any(not name.strip() for name in names) or len(set(names)) != len(names):
        raise FidelityError(f"simulator names must be distinct and non-empty, got {names}", option="simulators")
    return dict(zip(names, sims.values()))


def _per_simulator(name: str, value: Any, names: list) -> Any:
    """A per-simulator option (``sim_mtf=...``): None, or a mapping with a value per name."""
    if value is None:
        return {n: None for n in names}
    if not isinstance(value, Mapping) or set(map(str, value)) - set(names):
        raise FidelityError(f"{name} must be a mapping {{simulator: value}} over the simulators {names}",
                            option=name)
    return {n: value.get(n) for n in names}


def csv_paths(csv: str | os.PathLike | None, names: list) -> dict:
    """Each simulator's CSV: ``csv`` with ``{name}`` replaced, or ``csv/<name>.csv`` for a
    directory (created)."""
    if csv is None:
        return {n: None for n in names}
    unsafe = [n for n in names if not _SAFE_NAME.match(n)]
    if unsafe:
        raise FidelityError(f"simulator names {unsafe} cannot name CSV files: use letters, digits, '.', '_', '+', "
                            f"'-'", option="csv")
    text = os.fspath(csv)
    if "{name}" in text:
        return {n: text.replace("{name}", n) for n in names}
    if os.path.exists(text) and not os.path.isdir(text):
        raise FidelityError(f"csv: {text} is a file; give a directory or a path with '{{name}}'", option="csv")
    os.makedirs(text, exist_ok=True)
    return {n: os.path.join(text, f"{n}.csv") for n in names}


def _numbers_of(name: str, report: SequenceReport) -> FrameNumbers:
    try:
        return frame_numbers(report)
    except FidelityError as exc:
        raise FidelityError(f"simulator {name!r}: {exc}") from None


def _ranked_numbers(reports: Mapping[str, SequenceReport]) -> tuple[list, dict]:
    """The real frames every simulator scored, and each simulator's numbers on them."""
    numbers = {name: _numbers_of(name, rep) for name, rep in reports.items()}
    if any(n.pool is None for n in numbers.values()):
        numbers = {name: frame_numbers(rep, exact=False) for name, rep in reports.items()}
    first = next(iter(numbers.values()))
    common = set(first.names).intersection(*(set(n.names) for n in numbers.values()))
    frames = [name for name in first.names if name in common]
    return frames, {name: n.subset(frames) for name, n in numbers.items()}


def compare_reports(reports: Mapping[str, SequenceReport], *, level: float = 0.95, correction: str = "holm",
                    resamples: int = DEFAULT_RESAMPLES, rng: Any = 0) -> SimulatorComparison:
    """Rank sequence reports of several simulators against the same real frames.

    Parameters
    ----------
    reports : {name: SequenceReport}
        From :func:`irfidelity.score_sequence` (or :func:`score_simulators`) in this process,
        with the same real sequence and configuration.
    level, correction, resamples, rng
        As in :func:`irfidelity.ranking.rank`.

    Returns
    -------
    SimulatorComparison
    """
    reports = dict(reports)
    frames, numbers = _ranked_numbers(reports)
    notes = []
    dropped = {name: len(numbers[name].names) for name in reports}
    scored = {name: len(frame_numbers(rep, exact=False).names) for name, rep in reports.items()}
    if any(scored[n] != dropped[n] for n in reports):
        notes.append(f"ranked on the {len(frames)} real frames every simulator scored (scored per simulator: "
                     + ", ".join(f"{n} {scored[n]}" for n in reports) + ")")
    if len(frames) < 2:
        raise FidelityError(f"the simulators share {len(frames)} scored real frame(s); ranking needs at least 2")
    pool = _shared_pool(numbers)
    weights = next(iter(reports.values())).weights
    ranking = rank({name: n.numbers for name, n in numbers.items()}, pool=pool, weights=weights, level=level,
                   correction=correction, resamples=resamples, rng=rng)
    return SimulatorComparison(reports=reports, ranking=ranking, frames=frames, notes=notes)


def _shared_pool(numbers: Mapping[str, FrameNumbers]) -> Callable | None:
    """The pool of the first simulator (every simulator's reads its own curve components
    from its numbers, so one serves all)."""
    return next(iter(numbers.values())).pool


@contextlib.contextmanager
def _once_each() -> Iterator[None]:
    """Warnings raised inside, each distinct one issued once on leaving."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    seen = set()
    for w in caught:
        if (w.category, str(w.message)) not in seen:
            seen.add((w.category, str(w.message)))
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _prepare(real_seq: Any, sim: Any, name: str, cfg: ScoringConfig, run: RunOptions,
             camera: CameraInputs, mask: MaskSpec, memo: RealMemo) -> tuple:
    """A simulator's sequence, pairing and plan (over ``mask``, resolved once for all; what is of
    the real recording alone computed once for all, in ``memo``)."""
    sim_seq = temperature_sequence(as_sequence(sim, f"simulators[{name!r}]", cfg.sim_channel, run.max_pixels,
                                               run.max_bytes), "sim", cfg)
    if len(real_seq) == 0 or len(sim_seq) == 0:
        raise FidelityError(f"empty sequences ({name}): nothing to score")
    pairing = _pairing(real_seq, sim_seq, cfg)
    return sim_seq, pairing, make_plan(real_seq, sim_seq, pairing, camera, cfg, mask, memo)


def score_simulators(real: Any, simulators: Mapping[str, Any], *, real_mtf: Any = None, real_sitf: Any = None,
                     real_noise: Any = None, real_mrtd: Any = None, sim_mtf: Mapping[str, Any] | None = None,
                     sim_sitf: Mapping[str, Any] | None = None, sim_noise: Mapping[str, Any] | None = None,
                     sim_mrtd: Mapping[str, Any] | None = None, config: ScoringConfig | Scorer | None = None,
                     run: RunOptions | None = None, ci: bool | float = False, level: float = 0.95,
                     correction: str = "holm", resamples: int = DEFAULT_RESAMPLES, rng: Any = 0,
                     mask: Any = None, roi: Any = None, **options: Any) -> SimulatorComparison:
    """Score several simulators against one real recording in one pass, and rank them.

    Parameters
    ----------
    real : sequence
        As in :func:`irfidelity.score_sequence` (directory, glob, list of paths, multi-page
        TIFF, 3-D array, ...).
    simulators : {name: sequence}
        At least two simulated sequences of the same run. When every sequence is files the
        Rust engine decodes (PNG, TIFF, EXR), each real frame is decoded once for all of them.
    real_mtf, real_sitf, real_noise, real_mrtd : the real camera's inputs, as in ``score_sequence``.
    sim_mtf, sim_sitf, sim_noise, sim_mrtd : {name: input}, optional
        Each simulator's inputs (a simulator left out has none).
    config : as in ``score_sequence`` (one configuration for every simulator).
    run : RunOptions, optional
        As in ``score_sequence`` (one progress for all; no Dask ``client``: the shared pass
        runs on this machine), but ``csv`` names each simulator's streamed CSV: a path with
        ``{name}`` in it, or a directory (then ``<dir>/<name>.csv``). Names must then be
        letters, digits, ``.``, ``_``, ``+``, ``-``. With ``resume``, each simulator resumes
        from its CSV.
    ci : bool or float
        Also give each report its ``report.ci`` (as ``score_sequence(ci=...)``).
    level, correction, resamples, rng
        The ranking's (:func:`irfidelity.ranking.rank`).
    mask, roi : optional
        One mask and/or ROI on the real frames' grid, for every simulator's every pair (as in
        ``score_sequence``).
    **options
        ScoringConfig fields and, without ``run``, the run keywords (``workers=2``,
        ``progress=False``, ``csv="frames"``, ``resume=True``, ...), as in ``score_sequence``.

    Returns
    -------
    SimulatorComparison
        ``.order``, ``.reports``, ``.significant``, ``.stability``, ``.ranking``, ``.frames``.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> rng = np.random.default_rng(0)
    >>> scene = rng.normal(3000, 200, (40, 24, 24))
    >>> noisy = lambda sigma: np.clip(scene + rng.normal(0, sigma, scene.shape), 0, 16383).astype(np.uint16)
    >>> real = noisy(5)
    >>> result = irf.score_simulators(real, {"good": noisy(10), "poor": noisy(80)}, peak="range",
    ...                               weights="psnr=0.5,ssim=0.5", progress=False)
    >>> result.order, result.significant[("good", "poor")]
    (['good', 'poor'], True)
    """
    run, config_options = split_options(run, options)
    if run.client is not None:
        raise FidelityError("score_simulators runs on this machine: no Dask client (score each simulator with "
                            "score_sequence(client=...) and rank them with compare_reports)", option="client")
    cfg = Scorer(config, **config_options).config
    sims = _simulators(simulators)
    names = list(sims)
    check_level(level)
    check_resamples(resamples)  # before any frame is scored
    curves = {key: _per_simulator(key, value, names)
              for key, value in (("sim_mtf", sim_mtf), ("sim_sitf", sim_sitf), ("sim_noise", sim_noise),
                                 ("sim_mrtd", sim_mrtd))}
    paths = csv_paths(run.csv, names)
    real_seq = temperature_sequence(as_sequence(real, "real", cfg.real_channel, run.max_pixels, run.max_bytes),
                                    "real", cfg)
    runs = {}
    region = MaskSpec(mask, roi)
    memo = RealMemo()  # dropped once the plans are made: it holds the first real frame
    with _once_each():  # the real side's warnings (a PSNR peak, ...) come once, not per simulator
        for name, sim in sims.items():
            camera = CameraInputs(real_mtf, curves["sim_mtf"][name], real_sitf, curves["sim_sitf"][name],
                                  real_noise, curves["sim_noise"][name], real_mrtd, curves["sim_mrtd"][name])
            runs[name] = _prepare(real_seq, sim, name, cfg, run, camera, region, memo)
    del memo
    shared = all(engine_reads(real_seq, sim_seq) for sim_seq, _, _ in runs.values())

    def options_for(name: str, backend: Any = None) -> RunOptions:
        return dataclasses.replace(run, csv=paths[name], backend=backend,
                                   progress=run.progress if backend is None else False)

    if shared:
        coordinator = SharedRun(names, run.workers, run.progress)

        def run_one(name: str) -> Callable[[], SequenceReport]:
            sim_seq, pairing, plan = runs[name]
            return lambda: execute(real_seq, sim_seq, pairing, plan, options_for(name, coordinator.backend(name)))

        reports = coordinator.run({name: run_one(name) for name in names})
    else:  # arrays: nothing to decode twice; one simulator after the other
        reports = {name: execute(real_seq, sim_seq, pairing, plan, options_for(name))
                   for name, (sim_seq, pairing, plan) in runs.items()}
    reports = {name: with_intervals(rep, ci) for name, rep in reports.items()}
    return compare_reports(reports, level=level, correction=correction, resamples=resamples, rng=rng)
