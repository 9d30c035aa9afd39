"""One frame pair's outcome, as a backend reports it, and its entry in the report.

A frame entry has the keys of a single-pair result (:mod:`irfidelity.schema`): ``index``,
``real``, ``sim``, ``rows``, ``cols``, ``dtype``, ``fidelity``, ``grade``, ``components``,
``component_grades``, ``membership``, ``metrics``, ``registration`` (the one applied to the
pair, or None) and ``error`` (None, or why the pair could not be scored — then the values
are None and the dicts empty).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import FidelityError
from ..schema import registration_values
from ..scoring import image_components, psnr_peak, score_components
from ..stats import PairStats
from .plan import SequencePlan

__all__ = ["Outcome", "frame_entry", "error_entry"]


@dataclass(frozen=True)
class Outcome:
    """What a backend reports for the pair at ``index``: its statistics or an error.

    ``real_extent`` is the real frame's (min, max) over the scored pixels, when the backend
    measured it (needed for ``peak="range"``); ``registration`` the pair's own
    :class:`~irfidelity.Registration` (``register_each``); ``inputs`` the fingerprints of
    what was scored, ``{"real": ..., "sim": ...}`` (:mod:`.fingerprint`), when asked for and
    taken (a record is kept only with them).
    """

    index: int
    stats: PairStats | None
    error: str | None
    shape: tuple[int, int] | None = None
    dtype: str | None = None
    real_extent: tuple[float, float] | None = None
    registration: Any = None
    inputs: dict | None = None


def _blank(index: int, real: str | None, sim: str | None) -> dict:
    return {"index": index, "real": real, "sim": sim, "rows": None, "cols": None, "dtype": None,
            "fidelity": None, "grade": None, "components": {}, "component_grades": {}, "membership": {},
            "metrics": {}, "registration": None, "error": None}


def error_entry(index: int, real: str | None, sim: str | None, error: str) -> dict:
    """The entry of a pair that could not be scored."""
    entry = _blank(index, real, sim)
    entry["error"] = " ".join(str(error).split())  # one physical line in CSV
    return entry


def _frame_peak(plan: SequencePlan, outcome: Outcome, real_name: str) -> float | None:
    if "psnr" not in plan.image:
        return None
    if plan.config.peak != "range":
        return plan.peak
    extent = outcome.real_extent
    return psnr_peak(plan.config, plan.default_peak, None if extent is None else extent[1] - extent[0],
                     where=real_name)


def frame_entry(plan: SequencePlan, outcome: Outcome, real: str | None, sim: str | None) -> tuple[dict, PairStats | None]:
    """The report entry of one outcome, and the statistics to pool (None for a failure).

    The components come from the same functions :func:`irfidelity.evaluate` uses, so a
    frame's values equal those of evaluating the pair alone.
    """
    if outcome.error is not None:
        return error_entry(outcome.index, real, sim, outcome.error), None
    if plan.dtype is not None and outcome.dtype != plan.dtype.name:
        return error_entry(outcome.index, real, sim, f"{real}: frame type {outcome.dtype} differs from the "
                           f"sequence's {plan.dtype.name} (its first readable real frame); store every frame "
                           f"in one sample type"), None
    entry = _blank(outcome.index, real, sim)
    if outcome.shape is not None:
        entry["rows"], entry["cols"] = int(outcome.shape[0]), int(outcome.shape[1])
    entry["dtype"] = outcome.dtype
    try:
        stats = outcome.stats.with_peak(_frame_peak(plan, outcome, str(real)))
        comps, metrics = image_components(stats, plan.image, plan.config)
        extent = outcome.real_extent
        score = score_components(comps | plan.camera_components, metrics | plan.camera_metrics, plan.weights,
                                 plan.config, ceiling=plan.ceiling,
                                 scene_range=plan.scene_range if extent is None else extent[1] - extent[0])
    except FidelityError as exc:
        return error_entry(outcome.index, real, sim, str(exc)), None
    entry.update(score.to_dict())
    registration = outcome.registration if outcome.registration is not None else plan.registration
    entry["registration"] = None if registration is None else registration.to_dict()
    return entry, stats


def flat_row(entry: dict, columns: list[str]) -> list[Any]:
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
