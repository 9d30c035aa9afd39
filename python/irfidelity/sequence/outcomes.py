"""One frame pair's outcome, as a backend reports it, and its entry in the report
(:class:`~irfidelity.sequence.entry.FrameEntry`: the keys of a single-pair result, the
frame's place, and ``error`` — None, or why the pair could not be scored, when the values
are None and the dicts empty)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..errors import FidelityError
from ..schema import registration_values
from ..fuzzy import ordered_components
from ..scoring import image_components, psnr_peak
from ..stats import PairStats
from ..temperature import TemperatureErrors, temperature_scores
from .entry import FrameEntry
from .plan import SequencePlan

__all__ = ["Outcome", "frame_entry", "error_entry"]


@dataclass(frozen=True)
class Outcome:
    """What a backend reports for the pair at ``index``: its statistics or an error.

    ``real_extent`` is the real frame's (min, max) over the scored pixels, when the backend
    measured it (needed for ``peak="range"``); ``registration`` the pair's own
    :class:`~irfidelity.registration.Registration` (``register_each``); ``inputs`` the fingerprints of
    what was scored, ``{"real": ..., "sim": ...}`` (:mod:`.fingerprint`), when asked for and
    taken (a record is kept only with them); ``temperature`` the pair's
    :class:`~irfidelity.temperature.TemperatureErrors` when scored in a unit.
    """

    index: int
    stats: PairStats | None
    error: str | None
    shape: tuple[int, int] | None = None
    dtype: str | None = None
    real_extent: tuple[float, float] | None = None
    registration: Any = None
    inputs: dict | None = None
    temperature: TemperatureErrors | None = None


def error_entry(index: int, real: str | None, sim: str | None, error: str) -> FrameEntry:
    """The entry of a pair that could not be scored."""
    return FrameEntry(index, real, sim, error=" ".join(str(error).split()))  # one physical line in CSV


def _frame_peak(plan: SequencePlan, outcome: Outcome, real_name: str) -> float | None:
    if "psnr" not in plan.image:
        return None
    if plan.config.peak != "range":
        return plan.peak
    extent = outcome.real_extent
    return psnr_peak(plan.config, plan.default_peak, None if extent is None else extent[1] - extent[0],
                     where=real_name)


def frame_entry(plan: SequencePlan, outcome: Outcome, real: str | None, sim: str | None) -> tuple[FrameEntry, PairStats | None]:
    """The report entry of one outcome, and the statistics to pool (None for a failure).

    The components come from the same functions :func:`irfidelity.evaluate` uses, and the
    grades from the same cuts (:class:`irfidelity.verdict.Grader`, without the verdict's
    words), so a frame's values equal those of evaluating the pair alone.
    """
    if outcome.error is not None:
        return error_entry(outcome.index, real, sim, outcome.error), None
    if plan.dtype_name is not None and outcome.dtype != plan.dtype_name:
        return error_entry(outcome.index, real, sim, f"{real}: frame type {outcome.dtype} differs from the "
                           f"sequence's {plan.dtype_name} (its first readable real frame); store every frame "
                           f"in one sample type"), None
    assert outcome.stats is not None  # an outcome without an error has statistics
    try:
        stats = outcome.stats.with_peak(_frame_peak(plan, outcome, str(real)))
        comps, metrics = image_components(stats, plan.image, plan.config)
        if outcome.temperature is not None:
            comps, metrics = _with_temperature(comps, metrics, outcome.temperature, plan)
        extent = outcome.real_extent
        comps, metrics = ordered_components(comps | plan.camera_components), metrics | plan.camera_metrics
        graded = plan.grader.summary(comps, metrics, plan.scene_range if extent is None else extent[1] - extent[0])
    except FidelityError as exc:
        return error_entry(outcome.index, real, sim, str(exc)), None
    shape = outcome.shape
    registration = outcome.registration if outcome.registration is not None else plan.registration
    return FrameEntry(outcome.index, real, sim, rows=None if shape is None else int(shape[0]),
                      cols=None if shape is None else int(shape[1]), dtype=outcome.dtype, components=comps,
                      metrics=metrics, **graded,
                      registration=None if registration is None else registration.to_dict()), stats


def _with_temperature(comps: dict, metrics: dict, errors: TemperatureErrors, plan: SequencePlan
                      ) -> tuple[dict, dict]:
    temperature_comps, temperature_metrics = temperature_scores(errors, plan.weights)
    return comps | temperature_comps, metrics | temperature_metrics


def flat_row(entry: Mapping[str, Any], columns: list[str]) -> list[Any]:
    """The CSV values of an entry: frame keys, the registration's ``reg_*``, then metrics,
    then ``f_X`` = components.X."""
    metrics, comps = entry.get("metrics") or {}, entry.get("components") or {}
    registration = registration_values(entry.get("registration"))
    out = []
    for c in columns:
        if c.startswith("f_"):
            out.append(comps.get(c[2:]))
        elif c.startswith("reg_"):
            out.append(registration.get(c))
        elif c in entry and not isinstance(entry[c], dict):
            out.append(entry[c])
        else:
            out.append(metrics.get(c))
    return out
