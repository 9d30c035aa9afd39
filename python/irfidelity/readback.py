"""Reading a report back from its JSON form: every field a report keeps is checked.

:meth:`FidelityReport.from_dict` and :meth:`SequenceReport.from_dict` accept what ``to_dict``
writes (after a JSON round trip, or as is) and refuse anything else with a
:class:`~irfidelity.FidelityError` naming the field, so that a report they return can always
be summarised, serialised and rendered. Checked: the whole value is JSON-ready (strings as
keys; no deeper than :data:`MAX_REPORT_DEPTH`; integers within 64 bits), numbers are numbers
(fractions within [0, 1]), names are strings, and the nested records (frames, registrations,
the delay, per-frame statistics, the grading matrix) have the keys and types their readers use.
Keys a report does not use are kept as they are.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping
from typing import Any

from .config import ScoringConfig
from .config_fields import REGISTRATION_MODELS
from .errors import FidelityError
from .fuzzy import COMPONENTS, Weights

__all__ = ["MAX_REPORT_DEPTH", "ReportError", "check_json", "Fields", "shared_fields"]

#: Deepest nesting of a report's JSON form (a sequence report needs 6).
MAX_REPORT_DEPTH = 32

#: Largest magnitude of an integer in a report (JSON readers keep 64-bit integers exactly).
_INT_LIMIT = 2**63

#: A fraction (fidelity, component, membership) may exceed [0, 1] by rounding only.
_ROUNDING = 1e-6

Check = Callable[[Any, str], Any]


class ReportError(FidelityError):
    """A report dict that ``from_dict`` cannot read; the message names the field."""


def _fail(where: str, expected: str, value: Any) -> ReportError:
    shown = repr(value)
    shown = shown if len(shown) <= 60 else shown[:60] + "..."
    return ReportError(f"{where}: expected {expected}, got {shown}")


def check_json(data: Any, what: str) -> None:
    """``data`` is a JSON-ready value no deeper than :data:`MAX_REPORT_DEPTH` (iteratively, so
    any depth gets this error rather than a RecursionError)."""
    stack: list[tuple[Any, str, int]] = [(data, what, 1)]
    while stack:
        value, where, depth = stack.pop()
        if depth > MAX_REPORT_DEPTH:
            raise ReportError(f"{what}: nested more than {MAX_REPORT_DEPTH} levels deep (at {where})")
        if isinstance(value, Mapping):
            for key, child in value.items():
                if not isinstance(key, str):
                    raise _fail(where, "string keys", key)
                stack.append((child, f"{where}.{key}", depth + 1))
        elif isinstance(value, (list, tuple)):
            stack.extend((child, f"{where}[{i}]", depth + 1) for i, child in enumerate(value))
        elif isinstance(value, bool) or value is None or isinstance(value, str):
            continue
        elif isinstance(value, numbers.Integral):
            if abs(int(value)) >= _INT_LIMIT:
                raise _fail(where, "an integer within 64 bits", value)
        elif not isinstance(value, numbers.Real):
            raise _fail(where, "a JSON value (number, string, bool, null, list or mapping)", value)


# --------------------------------------------------------------------------- leaves
def number(value: Any, where: str) -> float:
    """Any real number (non-finite ones too: an infinite PSNR is a result)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise _fail(where, "a number", value)
    return float(value)


def finite(value: Any, where: str) -> float:
    x = number(value, where)
    if not math.isfinite(x):
        raise _fail(where, "a finite number", value)
    return x


def fraction(value: Any, where: str) -> float:
    x = number(value, where)
    if not -_ROUNDING <= x <= 1 + _ROUNDING:
        raise _fail(where, "a number in [0, 1]", value)
    return x


def count(value: Any, where: str) -> int:
    """A non-negative integer (an index, a size)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise _fail(where, "an integer >= 0", value)
    return int(value)


def text(value: Any, where: str) -> str:
    if not isinstance(value, str):
        raise _fail(where, "a string", value)
    return value


def flag(value: Any, where: str) -> bool:
    if not isinstance(value, bool):
        raise _fail(where, "true or false", value)
    return value


def anything(value: Any, where: str) -> Any:
    return value  # already checked to be JSON-ready


def metric(value: Any, where: str) -> Any:
    """A raw metric: a number (an integer, such as a pixel count, stays one), a unit string, or null."""
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return int(value)
    return number(value, where)


# --------------------------------------------------------------------------- combinators
def optional(check: Check) -> Check:
    return lambda value, where: None if value is None else check(value, where)


def mapping_of(check: Check) -> Check:
    def read(value: Any, where: str) -> dict:
        if not isinstance(value, Mapping):
            raise _fail(where, "a mapping", value)
        return {k: check(v, f"{where}.{k}") for k, v in value.items()}

    return read


def list_of(check: Check) -> Check:
    def read(value: Any, where: str) -> list:
        if not isinstance(value, (list, tuple)):
            raise _fail(where, "a list", value)
        return [check(v, f"{where}[{i}]") for i, v in enumerate(value)]

    return read


def numbers_of(size: int) -> Check:
    def read(value: Any, where: str) -> list:
        if not isinstance(value, (list, tuple)) or len(value) != size:
            raise _fail(where, f"a list of {size} numbers", value)
        return [finite(v, f"{where}[{i}]") for i, v in enumerate(value)]

    return read


def record(required: Mapping[str, Check], optional_keys: Mapping[str, Check] | None = None) -> Check:
    """A mapping with ``required`` keys and ``optional_keys``, each checked; other keys kept."""
    def read(value: Any, where: str) -> dict:
        if not isinstance(value, Mapping):
            raise _fail(where, "a mapping", value)
        missing = [k for k in required if k not in value]
        if missing:
            raise ReportError(f"{where}: missing key(s) {', '.join(missing)}")
        out = dict(value)
        for key, check in {**required, **(optional_keys or {})}.items():
            if key in value:
                out[key] = check(value[key], f"{where}.{key}")
        return out

    return read


# --------------------------------------------------------------------------- records
#: Mean, percentiles, min and max of a quantity over frames: all or none of them.
_SPREAD_KEYS = ("mean", "p5", "p50", "p95", "min", "max")


def spread(value: Any, where: str) -> dict:
    if isinstance(value, Mapping) and not value:
        return {}
    return record(dict.fromkeys(_SPREAD_KEYS, number))(value, where)


def _model(value: Any, where: str) -> str:
    if value not in REGISTRATION_MODELS:
        raise _fail(where, f"one of {', '.join(REGISTRATION_MODELS)}", value)
    return value


#: A registration applied to a pair (:meth:`irfidelity.registration.Registration.to_dict`).
registration = record(
    {"model": _model, "method": text, "shift": numbers_of(2), "angle": finite, "scale": finite,
     "confidence": number, "overlap": fraction},
    {"matrix": list_of(numbers_of(3)), "shape": list_of(count), "inverted": flag})

#: A sequence registered frame by frame: the spread of the frames' registrations.
registration_spread = record(
    {"model": _model, "method": text, "each": flag, "frames": count},
    {"low_confidence": number, "unsure": list_of(count),
     **dict.fromkeys(("shift_dy", "shift_dx", "angle", "scale", "confidence", "overlap"), spread)})


def any_registration(value: Any, where: str) -> dict:
    """A sequence's registration: the one applied to every pair, or the spread per frame."""
    if isinstance(value, Mapping) and value.get("each"):
        return registration_spread(value, where)
    return registration(value, where)


#: Largest frame offset a report may record (the bound of ``max_delay``).
_MAX_OFFSET = 1 << 20


def offset(value: Any, where: str) -> int:
    """A frame offset: an integer within ±2^20."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or abs(int(value)) > _MAX_OFFSET:
        raise _fail(where, f"an integer within ±{_MAX_OFFSET}", value)
    return int(value)


def _correlations(value: Any, where: str) -> dict:
    """``{str(delay): |correlation|}``: the keys are offsets written as strings."""
    checked = mapping_of(number)(value, where)
    for key in checked:
        try:
            candidate = int(key)
        except ValueError:
            raise _fail(f"{where} key", "an integer delay", key) from None
        offset(candidate, f"{where} key")
    return checked


#: The frame offset found between two sequences (``report.delay``).
delay = record({"frames": offset, "confidence": number, "correlation": _correlations},
               {"window": optional(count), "max_delay": optional(count),
                "unpaired": mapping_of(list_of(anything))})

#: The grading record (:meth:`irfidelity.fuzzy.Grading.to_dict`).
grading = record({}, {"grades": list_of(text), "matrix": mapping_of(mapping_of(fraction)),
                      "membership": mapping_of(fraction), "component_grades": mapping_of(text),
                      "grade": text})


def components(value: Any, where: str) -> dict:
    checked = mapping_of(fraction)(value, where)
    unknown = [k for k in checked if k not in COMPONENTS]
    if unknown:
        raise ReportError(f"{where}: unknown component(s) {', '.join(unknown)}; the components are "
                          f"{', '.join(COMPONENTS)}")
    return checked


#: A result's fields (a single pair's report, a sequence's pooled result, a frame's entry).
RESULT = {"components": components, "component_grades": mapping_of(text), "membership": mapping_of(fraction),
          "metrics": mapping_of(metric)}

#: A labelled region's entry of a single pair's report (``report.regions[name]``).
region = record({"label": count, "pixels": count, "fidelity": fraction, "grade": text, **RESULT},
                {"verdict": mapping_of(anything), "ceiling": optional(mapping_of(number)),
                 "relative": optional(mapping_of(number))})

#: One frame pair's entry of a sequence report.
frame = record({"index": count, "error": optional(text)},
               {"fidelity": optional(fraction), "grade": optional(text), **RESULT,
                "registration": optional(registration), "real": anything, "sim": anything,
                "rows": optional(count), "cols": optional(count), "dtype": optional(text)})

#: Per-frame statistics of a sequence (``report.frame_stats``).
frame_stats = record({}, {"fidelity": spread, "components": mapping_of(spread), "metrics": mapping_of(spread)})


class Fields:
    """The checked fields of a report dict ``d`` (JSON-decoded), read one by one."""

    def __init__(self, d: Mapping[str, Any], what: str):
        self.d, self.what = d, what

    def get(self, key: str, check: Check, default: Any = None) -> Any:
        """``d[key]`` checked, or ``default`` when absent."""
        if key not in self.d:
            return default
        return check(self.d[key], f"{self.what}.{key}")

    def require(self, key: str, check: Check) -> Any:
        if key not in self.d:
            raise ReportError(f"{self.what}: missing key {key!r}")
        return check(self.d[key], f"{self.what}.{key}")


def _weights(value: Any, where: str) -> Weights:
    if not isinstance(value, (Mapping, str)):
        raise _fail(where, "a mapping of weights", value)
    try:
        return Weights.coerce(value)
    except FidelityError as exc:
        raise ReportError(f"{where}: {exc}") from None


def _config(value: Any, where: str) -> ScoringConfig:
    try:
        return ScoringConfig.from_dict(value)
    except FidelityError as exc:
        raise ReportError(f"{where}: {exc}") from None


def shared_fields(fields: Fields) -> dict[str, Any]:
    """The fields a single pair's report and a sequence's report share, checked."""
    config = fields.get("config", _config)
    return {**{key: fields.get(key, check, {}) for key, check in RESULT.items()},
            "weights": fields.require("weights", _weights),
            "skipped": fields.get("skipped", mapping_of(text), {}),
            "config": config if config is not None else ScoringConfig(),
            "version": fields.get("irfidelity", text, "unknown"),
            "notes": fields.get("notes", list_of(text), []),
            "inputs": fields.get("inputs", mapping_of(anything), {}),
            **_verdict_fields(fields)}


def _verdict_fields(fields: Fields) -> dict[str, Any]:
    """``verdict``, ``ceiling`` and ``relative`` of a report read back (absent in older ones)."""
    numbers = optional(mapping_of(number))
    return {"verdict": fields.get("verdict", mapping_of(anything), {}),
            "ceiling": fields.get("ceiling", numbers), "relative": fields.get("relative", numbers),
            "transfer": fields.get("transfer", optional(mapping_of(anything)))}
