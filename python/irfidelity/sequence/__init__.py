"""Whole sequences: :func:`score_sequence` and :class:`SequenceReport`.

A real camera's recording and a simulator's rendering of the same run are scored frame by
frame and pooled. The package, in the order a run goes through it:

* :mod:`.sources` — inputs as :class:`~irfidelity.FrameSequence`;
* :mod:`.pairing` — which simulated frame goes with which real frame (by name, or order);
* :mod:`.delay` — with ``max_delay``, the frame offset between the two sequences;
* :mod:`.plan` — what is computed, fixed before any pair is scored;
* :mod:`.backends` — where pairs are scored: the Rust engine, Dask, or an array loop;
* :mod:`.outcomes` — a scored pair as a report entry (the same functions as ``evaluate``);
* :mod:`.log`, :mod:`.sidecar`, :mod:`.lock`, :mod:`.fingerprint`, :mod:`.resume` — the
  streamed CSV and what makes resuming safe;
* :mod:`.pooling` — the pooled result, every component within its frames' values;
* :mod:`.options` — how a run is carried out (:class:`RunOptions`);
* :mod:`.run` — one run, start to end; :mod:`.report` — its result (:mod:`.entry`: a
  frame's row).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from ..bootstrap import check_level
from ..camera import CameraInputs
from ..config import ScoringConfig
from ..errors import FidelityError
from ..frames import FrameSequence
from ..masks import MaskSpec
from ..results import recorded_warnings
from ..evaluation import Scorer
from ..temperature import temperature_sequence
from .delay import find_delay
from .intervals import sequence_intervals
from .pairing import Pairing, pair_frames, pair_with_delay
from .plan import make_plan
from .report import SequenceReport
from .options import RunOptions, split_options
from .run import execute
from .sources import as_sequence

__all__ = ["score_sequence", "SequenceReport", "RunOptions"]


def _pairing(real: FrameSequence, sim: FrameSequence, cfg: ScoringConfig) -> Pairing:
    """By name or position (``pair_by``), or with ``max_delay`` by position offset by the
    delay found (its warnings become notes of the pairing)."""
    if not cfg.max_delay:
        return pair_frames(real, sim, cfg.pair_by)
    with recorded_warnings() as notes:
        delay = find_delay(real, sim, cfg.max_delay)
    pairing = pair_with_delay(real, sim, delay)
    return dataclasses.replace(pairing, notes=pairing.notes + tuple(notes))


def score_sequence(real: Any, sim: Any, *, real_mtf: Any = None, sim_mtf: Any = None, real_sitf: Any = None,
                   sim_sitf: Any = None, real_noise: Any = None, sim_noise: Any = None,
                   real_mrtd: Any = None, sim_mrtd: Any = None, config: ScoringConfig | Scorer | None = None,
                   run: RunOptions | None = None, ci: bool | float = False, mask: Any = None, roi: Any = None,
                   **options: Any) -> SequenceReport:
    """Score a simulated sequence against the real one, frame by frame and pooled.

    What is computed comes from ``config`` (a :class:`~irfidelity.ScoringConfig`); how the
    run is carried out from ``run`` (a :class:`~irfidelity.sequence.RunOptions`). Both can
    be given field by field as keywords instead.

    Parameters
    ----------
    real, sim : directory, glob, list of paths, multi-page TIFF, 3-D array, list of 2-D
        arrays, or :class:`~irfidelity.FrameSequence`
        Frames are paired by file name when both are files (``pair_by``; a frame without a
        partner is reported as a failed frame, never dropped), else by position.
    real_mtf, sim_mtf, real_sitf, sim_sitf, real_noise, sim_noise, real_mrtd, sim_mrtd :
        The camera curves, noise recordings and MRTD inputs, as in :func:`irfidelity.evaluate`: compared
        once, before any frame; their components enter every frame's and the pooled fidelity.
        ``real_noise`` (also alone) sets the ceiling instead of consecutive real frames.
    config : ScoringConfig, Scorer, mapping or TOML/JSON path, optional
        What decides the score; ScoringConfig fields given as keywords override it.
    ci : bool or float
        Also compute ``report.ci``, the block-bootstrap intervals of the pooled fidelity and
        components over frames (True: at level 0.95; a float: that level;
        :mod:`irfidelity.sequence.intervals`); it costs a bootstrap over the frames.
    run : RunOptions, optional
        How the run is carried out: ``workers``, ``progress``, ``client``, ``csv``,
        ``resume``, ``chunk_size``, ``max_pixels``, ``max_bytes``, ``max_memory`` (each described in
        :class:`~irfidelity.sequence.RunOptions`). Without ``run``, these are keywords of
        their own; a run keyword given together with ``run`` is a FidelityError.
    **options
        ScoringConfig fields (``bits=14``, ``register="translation"``, ...) and, without
        ``run``, the run keywords above (``workers=4``, ``progress=False``,
        ``csv="run.csv"``, ...). Notably:

        * ``csv`` streams one row per frame as frames finish (flushed), with
          ``csv + ".pairstats"`` (what a resume trusts) and, while the run writes,
          ``csv + ".lock"``; see :mod:`irfidelity.sequence.log`;
        * ``resume=True`` keeps the frames of an earlier run on ``csv`` whose records are
          intact and whose files are unchanged, and scores the rest (records are read one at
          a time: memory does not grow with the run);
        * ``client`` (a ``dask.distributed.Client``) scores chunks of ``chunk_size`` pairs on
          the cluster (file sources only).
        * ``max_bytes`` is the memory budget of one pair's work and ``max_memory`` that of the
          run (``max_memory // workers`` a pair): a pair over budget is its frame's error row,
          never the end of the run (docs/design.md §14).

    Returns
    -------
    SequenceReport
        The pooled result at the top level (the keys of a single-pair report), ``.frames``,
        ``.failed``, ``.frame_stats``, ``.to_csv()``, ``.to_dict()``, ``.summary_text()``.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> from irfidelity.sequence import RunOptions
    >>> ramp = np.arange(64, dtype=np.uint16).reshape(8, 8)      # a scene spanning 63 counts
    >>> real = np.stack([ramp, ramp.T, ramp[::-1]])               # three frames
    >>> config = irf.ScoringConfig(bits=14, peak="range", weights="psnr=1")
    >>> rep = irf.score_sequence(real, real + 1, config=config, run=RunOptions(progress=False))
    >>> len(rep.frames), rep.failed, round(rep.metrics["psnr_db"], 2), rep.metrics["psnr_peak"]
    (3, [], 35.99, 63.0)

    The same run with keywords:

    >>> again = irf.score_sequence(real, real + 1, bits=14, peak="range", weights="psnr=1", progress=False)
    >>> again.frames == rep.frames
    True

    Only the top half of every frame:

    >>> top = irf.score_sequence(real, real + 1, config=config, run=RunOptions(progress=False), roi="0:4,:")
    >>> top.inputs["mask"]["pixels"], top.inputs["mask"]["roi"]
    (32, [0, 4, 0, 8])
    """
    run, config_options = split_options(run, options)
    cfg = Scorer(config, **config_options).config
    real_seq = temperature_sequence(as_sequence(real, "real", cfg.real_channel, run.max_pixels, run.max_bytes),
                                    "real", cfg)
    sim_seq = temperature_sequence(as_sequence(sim, "sim", cfg.sim_channel, run.max_pixels, run.max_bytes), "sim",
                                   cfg)
    if len(real_seq) == 0 or len(sim_seq) == 0:
        raise FidelityError("empty sequences: nothing to score")
    pairing = _pairing(real_seq, sim_seq, cfg)
    camera = CameraInputs(real_mtf, sim_mtf, real_sitf, sim_sitf, real_noise, sim_noise, real_mrtd, sim_mrtd)
    plan = make_plan(real_seq, sim_seq, pairing, camera, cfg, MaskSpec(mask, roi))
    return with_intervals(execute(real_seq, sim_seq, pairing, plan, run), ci)


def with_intervals(report: SequenceReport, ci: bool | float) -> SequenceReport:
    """``report`` with ``ci`` and ``pooling["ci"]`` when asked for (``ci``: True, or a level)
    and when at least two frames were scored (else a note says why there is none)."""
    if ci is False or ci is None:
        return report
    level = 0.95 if ci is True else check_level(ci)
    scored = len(report.frames) - len(report.failed) - len(report.unpaired)
    if scored < 2:
        report.notes.append(f"no interval: {scored} frame(s) scored, at least 2 are needed")
        return report
    intervals = sequence_intervals(report, level=level)
    report.ci = dict(intervals.ci)
    report.pooling["ci"] = {"level": intervals.level, "method": intervals.method, "block": intervals.block,
                            "resamples": intervals.resamples, "frames": intervals.frames}
    if intervals.note is not None:  # too few frames for honest intervals: the report says so
        report.pooling["ci"]["note"] = intervals.note
    return report
