"""Scoring in a physical unit: frames as temperatures, and the errors a thermal engineer reads.

With ``config.unit`` (``"K"`` or ``"C"``) both frames are scored as temperatures
(``docs/radiometry.md``, "Scoring in a unit"):

* a radiometric file (FLIR FFF, SEQ, CSQ, radiometric JPEG) is converted with its own calibration,
  the overrides of ``config.calibration`` (``emissivity``, ``reflected_temperature``, ...)
  replacing the file's values;
* a float frame (a simulator's EXR) is taken as already in the unit;
* integer counts without a calibration take the user's (``config.calibration``: the five
  Planck constants, or a linear ``gain`` and ``offset``, temperature = gain·count + offset),
  else are a clear error.

Then, besides the image components on the temperature frames, the errors of the simulated
temperatures — bias, RMSE, MAE and the fraction of pixels within a tolerance — and the opt-in
``radiometry`` component, ``0.9 ** ((bias² + rmse²) / (2·tolerance²))``: 1 for equal
temperatures, 0.9 for a pure offset of one tolerance (bias = RMSE = tolerance), 0.9⁴ for two,
0.9⁹ for three. Gain and offset errors, to which NMI and SSIM are blind, move it. A sequence's
component pools the frames' own errors (:func:`pooled_radiometry`), so it lies within the
frames' components; its ``temperature_*`` metrics are those of all pixel pairs together.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np

from . import _core, budget
from .config_fields import ConfigError
from .errors import FidelityError, FrameError, RangeError
from .frames import FrameSequence
from .radiometry import CALIBRATION_FIELDS, UNITS, Radiometry, read_radiometry

__all__ = ["UNITS", "LINEAR_FIELDS", "PLANCK_FIELDS", "DEFAULT_TOLERANCE", "TemperatureErrors", "frame_temperature",
           "to_temperature", "temperature_sequence", "temperature_scores", "scoring_config", "radiometry_component",
           "tolerance_for", "pooled_metrics", "pooled_radiometry", "pooled_temperature_scores",
           "radiometry_exponent", "radiometry_of_exponent", "frame_exponent", "unit_fields"]

#: A linear calibration of integer counts: temperature (in the unit) = gain·count + offset.
LINEAR_FIELDS = ("gain", "offset")

#: The fields of a Planck calibration (all five make a calibration of their own).
PLANCK_FIELDS = CALIBRATION_FIELDS[:5]

#: The tolerance when neither the configuration nor the real camera's NETD gives one, in K.
DEFAULT_TOLERANCE = 1.0

#: The radiometry component of a pure offset of one tolerance (the paper's "indistinguishable" f3).
_ONE_TOLERANCE = 0.9


# --------------------------------------------------------------------------- configuration
def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError("calibration", f"{name} must be a number; got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise ConfigError("calibration", f"{name} must be finite; got {value!r}")
    return number


def calibration_value(value: Any) -> dict[str, float]:
    """``config.calibration`` checked: calibration fields (:data:`~irfidelity.radiometry.CALIBRATION_FIELDS`)
    or a linear ``gain``/``offset``, each a finite number."""
    if not isinstance(value, Mapping):
        raise ConfigError("calibration", f"expected a mapping of calibration fields to numbers; got "
                                         f"{type(value).__name__}")
    known = CALIBRATION_FIELDS + LINEAR_FIELDS
    unknown = sorted(str(k) for k in value if k not in known)
    if unknown:
        raise ConfigError("calibration", f"unknown field(s) {', '.join(unknown)}; expected some of {', '.join(known)}")
    out = {str(k): _number(str(k), v) for k, v in value.items()}
    if any(k in out for k in LINEAR_FIELDS):
        if "gain" not in out:
            raise ConfigError("calibration", "a linear calibration needs a gain (temperature = gain·count + offset)")
        planck = [k for k in PLANCK_FIELDS if k in out]
        if planck:
            raise ConfigError("calibration", f"give a linear calibration (gain, offset) or Planck constants "
                                             f"({', '.join(planck)}), not both")
        if out["gain"] == 0:
            raise ConfigError("calibration", "gain must not be 0")
    return out


def unit_fields(unit: Any, calibration: Any, tolerance: Any, bits: Any) -> dict[str, Any]:
    """The validated ``unit``, ``calibration`` and ``temperature_tolerance`` of a ScoringConfig."""
    if unit is not None and unit not in UNITS:
        raise ConfigError("unit", f"expected 'K', 'C' or none; got {unit!r}")
    out: dict[str, Any] = {"unit": unit, "calibration": calibration_value(calibration)}
    if tolerance is not None:
        tol = _number("temperature_tolerance", tolerance) if not isinstance(tolerance, str) else math.nan
        if not tol > 0:
            raise ConfigError("temperature_tolerance", f"expected a positive number of kelvin; got {tolerance!r}")
        out["temperature_tolerance"] = tol
    else:
        out["temperature_tolerance"] = None
    if unit is None:
        for name in ("calibration", "temperature_tolerance"):
            if out[name]:
                raise ConfigError(name, "applies to temperatures: set unit to 'K' or 'C'")
    elif bits is not None:
        raise ConfigError("bits", "bounds integer counts, and with a unit the frames are scored as temperatures; "
                                  "leave bits unset")
    return out


# --------------------------------------------------------------------------- frames
def _user_calibration(frame: np.ndarray, name: str, config: Any) -> np.ndarray | None:
    """``frame`` converted with ``config.calibration`` (None when it is no full calibration)."""
    cal = dict(config.calibration)
    if "gain" in cal:
        return cal["gain"] * frame.astype(np.float64) + cal.get("offset", 0.0)
    if all(k in cal for k in PLANCK_FIELDS):
        calibration = Radiometry(**cal, source=name)
        return np.asarray(calibration.temperature(frame, config.unit), dtype=np.float64)
    return None


def frame_temperature(frame: Any, name: str, config: Any, path: str | None = None, page: int = 0,
                      max_bytes: int | None = None, held: int = 0) -> np.ndarray:
    """One frame in ``config.unit`` (float64); the module notes say how.

    Parameters
    ----------
    frame : 2-D array
        As loaded (counts or float values).
    name : str
        The frame's name in messages (``"real frame.fff"``).
    config : ScoringConfig
        Its ``unit`` and ``calibration``.
    path, page : str and int, optional
        The file the frame came from: its own calibration, when it has one, comes first.
    max_bytes, held : int, optional
        The budget of the conversion's peak (None: the default): ``held`` bytes already in
        memory beside it (the other frames of the pair), the counts and their float64
        temperatures.

    Raises
    ------
    FrameError
        Integer counts without a calibration (the file's or ``config.calibration``), or counts
        of which none lies within the calibration's domain.
    FidelityError
        A calibration field out of its range, named; a conversion beyond ``max_bytes``.
    """
    values = np.asarray(frame)
    if values.dtype.kind == "f":
        if values.dtype != np.float64:
            budget.check_float64_copy(f"{name}: conversion to float64 temperatures", values, max_bytes, held)
        return values.astype(np.float64, copy=False)
    if values.dtype.kind not in "ui":
        raise FidelityError(f"{name}: expected integer counts or float temperatures, got dtype {values.dtype}")
    budget.check_float64_copy(f"{name}: conversion to temperature", values, max_bytes, held)
    overrides = {k: v for k, v in config.calibration.items() if k in CALIBRATION_FIELDS}
    why = "an array carries none" if path is None else "a .npy file carries none"
    try:
        if path is not None and not path.lower().endswith(".npy"):
            try:
                calibration = read_radiometry(path, page=page)
            except FrameError as exc:
                why = str(exc)
            else:
                return np.asarray(calibration.temperature(values, config.unit, **overrides), dtype=np.float64)
        converted = _user_calibration(values, name, config)
    except RangeError as exc:
        raise FrameError(f"{name}: {exc}") from None
    if converted is None:
        raise FrameError(f"{name}: integer counts ({values.dtype}) without a radiometric calibration ({why}) cannot be "
                         f"scored in {config.unit}: give a radiometric file (FLIR FFF, SEQ, CSQ, radiometric JPEG), float "
                         f"temperatures, or a calibration (the Planck constants {', '.join(PLANCK_FIELDS)}, or a "
                         f"linear gain and offset)", option="calibration")
    return converted


def to_temperature(frame: np.ndarray, source: Any, which: str, config: Any, max_bytes: int | None = None,
                   held: int = 0) -> np.ndarray:
    """A loaded frame of :func:`irfidelity.evaluate` in ``config.unit``; ``source`` is what the
    caller gave (a path, whose calibration is read, or the array itself); the conversion and
    the ``held`` bytes beside it within ``max_bytes``."""
    if isinstance(source, (str, os.PathLike)):
        path = os.fsdecode(os.fspath(source))
        return frame_temperature(frame, f"{which} {path}", config, path, max_bytes=max_bytes, held=held)
    return frame_temperature(frame, f"{which} frame", config, max_bytes=max_bytes, held=held)


class TemperatureSequence(FrameSequence):
    """A :class:`~irfidelity.FrameSequence` whose frames are temperatures in ``config.unit``
    (scored as arrays: the Rust engine reads counts only)."""

    _which: str
    _config: Any

    def _load(self, entry: Any) -> np.ndarray:
        frame = super()._load(entry)
        path, page, name = entry
        return frame_temperature(frame, f"{self._which} {name}", self._config, path, page, self.max_bytes)

    @property
    def is_files(self) -> bool:
        return False


def temperature_sequence(seq: FrameSequence, which: str, config: Any) -> FrameSequence:
    """``seq`` with its frames converted to ``config.unit`` (``seq`` itself without a unit)."""
    if config.unit is None:
        return seq
    converted = TemperatureSequence._subset(seq, list(seq.entries))
    converted._which, converted._config = which, config
    return converted


# --------------------------------------------------------------------------- errors
@dataclass(frozen=True)
class TemperatureErrors:
    """The errors of simulated temperatures against real ones over the scored pixel pairs.

    Attributes
    ----------
    n : int
        Pixel pairs compared.
    bias, rmse, mae : float
        mean(S − R), √mean((S − R)²), mean |S − R|, in K (a difference: K and °C alike).
    within : int
        Pixel pairs with |S − R| ≤ ``tolerance``.
    tolerance : float
        The tolerance, K.
    unit : str
        The unit the frames were in.

    Examples
    --------
    >>> import numpy as np
    >>> from irfidelity.temperature import TemperatureErrors
    >>> real = np.array([[300.0, 301.0], [302.0, 303.0]])
    >>> e = TemperatureErrors.of_frames(real, real + [[0.5, 0.5], [0.5, 2.5]], tolerance=1.0, unit="K")
    >>> e.bias, e.mae, e.within
    (1.0, 1.0, 3)
    """

    n: int
    bias: float
    rmse: float
    mae: float
    within: int
    tolerance: float
    unit: str

    @classmethod
    def of_frames(cls, real: Any, sim: Any, *, tolerance: float, unit: str, mask: Any = None) -> TemperatureErrors:
        """The errors over the pixel pairs where ``mask`` is true and both values are finite:
        one Rust pass (``_core.temperature_errors``) a block of rows at a time, so frames that
        are not C-contiguous float64 are copied a block at a time, not whole."""
        real, sim = np.broadcast_arrays(np.atleast_1d(real), np.atleast_1d(sim))
        keep_all = None if mask is None else np.broadcast_to(np.asarray(mask, dtype=bool), real.shape)
        n, within, sums = 0, 0, []
        for block in budget.row_blocks(real.shape):
            r, s = (np.ascontiguousarray(x[block], dtype=np.float64) for x in (real, sim))
            kept = None if keep_all is None else np.ascontiguousarray(keep_all[block])
            count, total, squares, magnitudes, close = _core.temperature_errors(r, s, kept, tolerance=float(tolerance))
            n, within = n + count, within + close
            sums.append((total, squares, magnitudes))
        total, squares, magnitudes = (math.fsum(column) for column in zip(*sums))
        return cls.of_sums((n, total, squares, magnitudes, within), tolerance=tolerance, unit=unit)

    @classmethod
    def of_sums(cls, sums: tuple[int, float, float, float, int], *, tolerance: float, unit: str) -> TemperatureErrors:
        """The errors from their sums ``(n, Σd, Σd², Σ|d|, within)`` (``_core.temperature_errors``'
        or an :func:`irfidelity.defects.error_profile` taken with ``tolerance``)."""
        n, total, squares, magnitudes, within = sums
        if n == 0:
            raise FidelityError("no pixel pair with finite temperatures on both sides to compare", option="mask")
        return cls(n=n, bias=total / n, rmse=math.sqrt(squares / n), mae=magnitudes / n, within=within,
                   tolerance=float(tolerance), unit=unit)

    def to_dict(self) -> dict[str, Any]:
        """The fields, JSON-ready (a resumable run's record keeps them); :meth:`from_dict` inverts it."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: Any) -> TemperatureErrors:
        """Errors from :meth:`to_dict`'s output, checked (``ValueError`` naming what is wrong)."""
        if not isinstance(data, Mapping) or set(data) != {f.name for f in dataclasses.fields(cls)}:
            raise ValueError("not a record of temperature errors")
        n, within = data["n"], data["within"]
        if type(n) is not int or type(within) is not int or not 0 <= within <= n or n <= 0:
            raise ValueError(f"counts out of range (n {n!r}, within {within!r})")
        values = [data[k] for k in ("bias", "rmse", "mae", "tolerance")]
        if not all(type(v) is float and math.isfinite(v) for v in values) or min(values[1:]) < 0 \
                or data["tolerance"] <= 0 or data["unit"] not in UNITS:
            raise ValueError("values out of range")
        return cls(**data)

    def metrics(self) -> dict[str, Any]:
        """The ``temperature_*`` metrics (:data:`irfidelity.schema.METRICS` ``["radiometry"]``)."""
        return {"temperature_unit": self.unit, "temperature_bias": self.bias, "temperature_rmse": self.rmse,
                "temperature_mae": self.mae, "temperature_within": self.within / self.n,
                "temperature_tolerance": self.tolerance}

    @property
    def component(self) -> float:
        """The ``radiometry`` component: :func:`radiometry_component` of bias and RMSE."""
        return radiometry_component(self.bias, self.rmse, self.tolerance)


def radiometry_component(bias: float, rmse: float, tolerance: float) -> float:
    """``0.9 ** ((bias² + rmse²) / (2·tolerance²))``, in [0, 1].

    1 when the temperatures agree, 0.9 for a pure offset of one tolerance (bias = RMSE =
    tolerance), 0.9⁴ for two. A bias counts twice (in the bias and in the RMSE) and a random
    error once: an offset, which a user cannot average away, weighs more than noise of the same
    RMS.

    Examples
    --------
    >>> from irfidelity.temperature import radiometry_component
    >>> radiometry_component(0.0, 0.0, 1.0), round(radiometry_component(2.0, 2.0, 1.0), 4)
    (1.0, 0.6561)
    """
    return radiometry_of_exponent(radiometry_exponent(bias, rmse, tolerance))


def radiometry_exponent(bias: float, rmse: float, tolerance: float) -> float:
    """``(bias² + rmse²) / (2·tolerance²)``: the radiometry component is ``0.9`` to this power."""
    if not tolerance > 0:
        raise FidelityError(f"the temperature tolerance must be positive, got {tolerance!r}",
                            option="temperature_tolerance")
    return (bias * bias + rmse * rmse) / (2.0 * tolerance * tolerance)


def radiometry_of_exponent(exponent: float) -> float:
    """``0.9 ** exponent`` (0 for an infinite exponent): decreasing in the exponent."""
    return _ONE_TOLERANCE ** exponent if math.isfinite(exponent) else 0.0


def tolerance_for(config: Any, camera_metrics: Mapping[str, Any]) -> float:
    """The tolerance of ``temperature_within`` and of the radiometry component:
    ``config.temperature_tolerance``, else the real camera's NETD (``noise_netd_real``, when the
    noise component measured it against a SiTF in kelvin), else :data:`DEFAULT_TOLERANCE`."""
    if config.temperature_tolerance is not None:
        return float(config.temperature_tolerance)
    netd = camera_metrics.get("noise_netd_real")
    if isinstance(netd, (int, float)) and math.isfinite(netd) and netd > 0:
        return float(netd)
    return DEFAULT_TOLERANCE


def temperature_scores(errors: TemperatureErrors, weights: Any) -> tuple[dict[str, float], dict[str, Any]]:
    """(components, metrics) of a pair's temperature errors: the radiometry component when weighted."""
    components = {"radiometry": errors.component} if weights["radiometry"] > 0 else {}
    return components, errors.metrics()


def pooled_metrics(frames: Iterable[Mapping[str, Any]]) -> TemperatureErrors | None:
    """The temperature errors of a sequence's scored frames together (each frame's entry
    ``metrics``, with ``n``): from their sums, exactly as if every pixel pair were one frame's.
    None when no frame has them."""
    parts = [m for m in frames if "temperature_bias" in m]
    if not parts:
        return None
    n = sum(int(m["n"]) for m in parts)
    within = sum(round(m["temperature_within"] * m["n"]) for m in parts)
    return TemperatureErrors(
        n=n, bias=math.fsum(m["temperature_bias"] * m["n"] for m in parts) / n,
        rmse=math.sqrt(math.fsum(m["temperature_rmse"] ** 2 * m["n"] for m in parts) / n),
        mae=math.fsum(m["temperature_mae"] * m["n"] for m in parts) / n, within=int(within),
        tolerance=float(parts[0]["temperature_tolerance"]), unit=str(parts[0]["temperature_unit"]))


def frame_exponent(metrics: Mapping[str, Any]) -> float:
    """A frame's :func:`radiometry_exponent` from its entry's ``temperature_*`` metrics."""
    return radiometry_exponent(metrics["temperature_bias"], metrics["temperature_rmse"],
                               metrics["temperature_tolerance"])


def pooled_radiometry(frames: Iterable[Mapping[str, Any]]) -> float:
    """The radiometry component of a sequence's scored frames (each frame's entry ``metrics``,
    with ``n``): ``0.9`` to the pixel-weighted mean of the frames' exponents
    ``(bias_i² + rmse_i²) / (2·tolerance²)``.

    Each frame's error counts with its own bias, so opposite offsets of two frames do not
    cancel (as they would in the bias of all pixel pairs together), and the component, a
    decreasing function of a weighted mean of the frames' exponents, lies within the frames'
    components. The mean is an exact sum (:func:`math.fsum`) rounded once and kept within the
    frames' exponents.
    """
    parts = [m for m in frames if "temperature_bias" in m]
    if not parts:
        raise FidelityError("no frame has temperature errors to pool")
    exponents = [frame_exponent(m) for m in parts]
    n = sum(int(m["n"]) for m in parts)
    mean = math.fsum(int(m["n"]) * e for m, e in zip(parts, exponents)) / n
    return radiometry_of_exponent(min(max(mean, min(exponents)), max(exponents)))


def pooled_temperature_scores(frames: Iterable[Mapping[str, Any]], weights: Any
                              ) -> tuple[dict[str, float], dict[str, Any]] | None:
    """(components, metrics) of a sequence in a unit: the ``temperature_*`` metrics of all
    pixel pairs together (:func:`pooled_metrics`) and, when weighted, the radiometry component
    of :func:`pooled_radiometry`. None when no frame has temperature errors."""
    parts = [m for m in frames if "temperature_bias" in m]
    errors = pooled_metrics(parts)
    if errors is None:
        return None
    components = {"radiometry": pooled_radiometry(parts)} if weights["radiometry"] > 0 else {}
    return components, errors.metrics()


def scoring_config(config: Any) -> Any:
    """The configuration a run in a unit scores with: the PSNR peak defaults to the real
    frame's temperature range (``peak="range"``); unchanged without a unit."""
    if config.unit is not None and config.peak is None:
        return config._with_range_peak()
    return config
