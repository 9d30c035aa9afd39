"""The checks of each scoring-configuration field: one function per kind of value, each
raising :class:`ConfigError` (a :class:`~irfidelity.FidelityError`) that names the field and
what was expected. :class:`~irfidelity.ScoringConfig` runs them when it is built."""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from typing import Any

from . import _core
from .curves.similarity import MAX_FEATURE_POINTS
from .errors import ConfigError, FidelityError
from .fuzzy import GradeScale
from .stats import HIST_RANGES
from .stats import bins_value

__all__ = ["MISSING_MODES", "NONFINITE_MODES", "REGISTRATION_MODELS", "REGISTRATION_METHODS", "PAIRING_RULES",
           "PEAK_RULES", "CURVE_OPTIONS", "ConfigError", "choice", "optional_int", "optional_positive", "finite_numbers",
           "optional_name", "pairs", "peak_value", "bins_value", "hist_range_value", "curve_options", "grade_scale"]

MISSING_MODES = ("renormalize", "raise")
NONFINITE_MODES = ("raise", "mask")
#: Registration models and methods: the Rust core's lists (``crate::register::Model::ALL``, ``Method::ALL``).
REGISTRATION_MODELS: tuple[str, ...] = tuple(_core.REGISTRATION_MODELS)
REGISTRATION_METHODS: tuple[str, ...] = tuple(_core.REGISTRATION_METHODS)
PAIRING_RULES = ("auto", "name", "order")
PEAK_RULES = ("range",)


def choice(name: str, value: Any, choices: tuple) -> str:
    if isinstance(value, str):
        key = value.lower().replace("normalise", "normalize")
        if key in choices:
            return key
    raise ConfigError(name, f"expected one of {', '.join(choices)}; got {_short(value)}")


def optional_int(name: str, value: Any, lo: int, hi: int | None = None) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < lo or (hi is not None and value > hi):
        bound = f"{lo}..{hi}" if hi is not None else f">= {lo}"
        raise ConfigError(name, f"expected an integer {bound}; got {_short(value)}")
    return int(value)


def optional_positive(name: str, value: Any) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool):
        raise ConfigError(name, f"expected a positive number; got {_short(value)}")
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ConfigError(name, f"expected a positive number; got {_short(value)}") from None
    if not (number > 0 and math.isfinite(number)):
        raise ConfigError(name, f"expected a positive finite number; got {_short(value)}")
    return number


def _real(value: Any) -> float | None:
    """``value`` as a finite float when it is a real number (not a bool), else None."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


def finite_numbers(name: str, value: Any, count: int) -> tuple[float, ...]:
    """``count`` finite numbers from a list, tuple or 1-D array."""
    listed = value.tolist() if hasattr(value, "tolist") else value
    items = tuple(listed) if isinstance(listed, (list, tuple)) else ()
    out = tuple(_real(v) for v in items)
    if len(out) != count or any(v is None for v in out):
        raise ConfigError(name, f"expected {count} finite numbers; got {_short(value)}")
    return out  # type: ignore[return-value]


def optional_name(name: str, value: Any) -> str | None:
    if value is None or (isinstance(value, str) and value):
        return value
    raise ConfigError(name, f"expected a non-empty name; got {_short(value)}")


def pairs(name: str, value: Any) -> tuple:
    try:
        items = tuple(value)
    except TypeError:
        raise ConfigError(name, f"expected two (dB, value) pairs; got {_short(value)}") from None
    if len(items) != 2:
        raise ConfigError(name, f"expected two (dB, value) pairs; got {_short(value)}")
    return items


def peak_value(value: Any) -> float | str | None:
    if value is None:
        return None
    if isinstance(value, str):
        return choice("peak", value, PEAK_RULES)
    return optional_positive("peak", value)


def hist_range_value(value: Any) -> str | tuple:
    if isinstance(value, str):
        if value in HIST_RANGES:
            return value
        raise ConfigError("hist_range", f"expected {', '.join(map(repr, HIST_RANGES))} or (lo, hi); got {_short(value)}")
    lo, hi = finite_numbers("hist_range", value, 2)
    if not lo <= hi:
        raise ConfigError("hist_range", f"expected lo <= hi; got {_short(value)}")
    return (lo, hi)


def _flag(name: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(name, f"expected true or false; got {_short(value)}")
    return value


def _exponent(name: str, value: Any) -> float:
    number = _real(value)
    if number is None or number < 0:
        raise ConfigError(name, f"expected a finite number >= 0; got {_short(value)}")
    return number


def _positive(name: str, value: Any) -> float:
    number = _real(value)
    if number is None or not number > 0:
        raise ConfigError(name, f"expected a finite number > 0; got {_short(value)}")
    return number


def _fraction(name: str, value: Any) -> float:
    number = _real(value)
    if number is None or not 0 <= number <= 1:
        raise ConfigError(name, f"expected a number in [0, 1]; got {_short(value)}")
    return number


def _points(name: str, value: Any) -> int | list:
    """A count of feature points, or the points themselves (at most MAX_FEATURE_POINTS)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        count = value if isinstance(value, int) else int(value) if value.is_integer() else 0
        if not 2 <= count <= MAX_FEATURE_POINTS:
            raise ConfigError(name, f"expected an integer in 2..{MAX_FEATURE_POINTS}; got {_short(value)}")
        return count
    if isinstance(value, (list, tuple)) and 2 <= len(value) <= MAX_FEATURE_POINTS:
        return list(finite_numbers(name, value, len(value)))
    raise ConfigError(name, f"expected a count in 2..{MAX_FEATURE_POINTS} or a list of 2..{MAX_FEATURE_POINTS} "
                            f"numbers; got {_short(value)}")


def _sitf_window(name: str, value: Any) -> str | list:
    if isinstance(value, str) and value in ("real", "each"):
        return value
    if isinstance(value, (list, tuple)):
        lo, hi = finite_numbers(name, value, 2)
        if lo < hi:
            return [lo, hi]
    raise ConfigError(name, f"expected 'real', 'each' or [lo, hi] with lo < hi; got {_short(value)}")


def _short(value: Any, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "..."


#: The keyword options of each curve comparison a configuration may set, with their checks
#: (``camera`` is not one: the configuration's geometry fields give it).
CURVE_OPTIONS: dict[str, dict[str, Any]] = {
    "mtf_options": {"smooth": _flag, "points": _points, "alpha": _exponent, "beta": _exponent},
    "sitf_options": {"window": _sitf_window, "lo_frac": _fraction, "hi_frac": _fraction,
                     "method": lambda name, value: choice(name, value, ("band", "logistic")),
                     "points": _points, "alpha": _exponent, "beta": _exponent},
    "mrtd_options": {"tolerance": _exponent, "points": _points, "alpha": _exponent, "beta": _exponent,
                     "snr_threshold": _positive, "eye_time": _positive, "frame_rate": _positive},
    "transfer_options": {"scene": _flag, "reference_frequency": lambda name, value: _frequency(name, value),
                         "tile": lambda name, value: _tile(name, value)},
}


def _frequency(name: str, value: Any) -> float:
    number = _real(value)
    if number is None or not 0 < number <= 0.5:
        raise ConfigError(name, f"expected a frequency in cycles per pixel in (0, 0.5]; got {_short(value)}")
    return number


def _tile(name: str, value: Any) -> int:
    tile = optional_int(name, value, 8, 256)
    if tile is None or tile % 2:
        raise ConfigError(name, f"expected an even number of pixels in 8..256; got {_short(value)}")
    return tile


def curve_options(name: str, value: Any) -> dict:
    """The options of a curve comparison, each name and value checked."""
    if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
        raise ConfigError(name, f"expected a mapping of option names to values; got {_short(value)}")
    checks = CURVE_OPTIONS[name]
    unknown = sorted(set(value) - set(checks))
    if unknown:
        camera = " (the camera comes from ifov_mrad, pixel_pitch_um, focal_length_mm)" if "camera" in unknown else ""
        raise ConfigError(name, f"unknown option(s) {', '.join(map(repr, unknown))}; the options are "
                                f"{', '.join(checks)}{camera}")
    out = {key: checks[key](f"{name}.{key}", v) for key, v in value.items()}
    if out.get("lo_frac", 0.1) >= out.get("hi_frac", 0.9):
        raise ConfigError(name, f"expected lo_frac < hi_frac; got {out.get('lo_frac', 0.1)!r} and "
                                f"{out.get('hi_frac', 0.9)!r} (defaults 0.1 and 0.9)")
    return out


def grade_scale(value: Any) -> GradeScale:
    if not isinstance(value, Mapping):
        raise ConfigError("grades", f"expected a GradeScale or a mapping; got {type(value).__name__}")
    names = [f.name for f in dataclasses.fields(GradeScale)]
    unknown = sorted(str(k) for k in value if k not in names)
    if unknown:
        raise ConfigError("grades", f"unknown key(s) {', '.join(unknown)}; the keys are {', '.join(names)}")
    try:
        return GradeScale(**value)
    except FidelityError as exc:
        raise ConfigError("grades", str(exc)) from None
