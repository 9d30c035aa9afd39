"""Units of curve axes: the one table of recognised spellings, header parsing, conversions.

A :class:`~irfidelity.curves.Curve` carries ``x_unit`` and ``y_unit``: a canonical symbol
from :data:`UNITS`, any other string (kept as an opaque label), or ``None`` (unknown).

========== ========================= ==========================================================
symbol     quantity                  spellings recognised (case-insensitive; in CSV headers as
                                     a token, e.g. ``freq_cy_per_mrad``, ``MTF (cy/px)``)
========== ========================= ==========================================================
cy/px      spatial frequency         cy/px, cy/pixel, cycles/pixel, cycles/px, c/px, cpp
cy/mrad    spatial frequency         cy/mrad, cycles/mrad, c/mrad, cycles/milliradian
lp/mm      spatial frequency         lp/mm, lpmm, cy/mm, cycles/mm, c/mm
K          temperature (absolute)    K, kelvin — in a header only next to a temperature name
degC       temperature (absolute)    degC, °C, C, celsius — idem
delta_K    temperature difference    delta_K, ΔK, dK, delta_degC, Δ°C, ΔT, dT, delta_T
counts     signal                    counts, count, DN, ADU, LSB, DL, digital_level, digital_number
V          signal                    V, volt, volts
mV         signal                    mV, millivolt, millivolts
1          modulation (MTF)          1, ratio, fraction; in a header also mtf, sfr, modulation
%          modulation (MTF)          %, percent, pct
========== ========================= ==========================================================

In ``x_unit=``/``y_unit=`` arguments a spelling stands alone (``"°C"``, ``"cycles/pixel"``).
In a CSV header the reader splits the column name into words (``_``, spaces, brackets; ``per``
becomes ``/``) and decides:

* a frequency unit anywhere in the name gives that unit (``freq_cy_per_mrad`` → cy/mrad);
* a temperature unit gives an absolute temperature only next to a temperature name (``T``,
  ``temp``, ``temperature``, ``blackbody``, ``bb``, ``scene``, ``target``) and ``delta_K`` next
  to a difference name (``dT``, ``delta``, ``ΔT``, ``diff``, ``difference``); ``dT`` alone is
  ``delta_K`` (a difference is the same in K and °C); ``K`` or ``C`` alone is unknown, because
  the reader cannot tell a ΔT axis from an absolute one;
* ``mtf``/``sfr``/``modulation`` without ``%`` gives ``1``;
* a name that matches two different units, or none, is unknown. Fahrenheit and millikelvin are
  refused with a message (convert the file).

Conversions (:func:`convert`): absolute K ↔ °C (``K = °C + 273.15``), V ↔ mV, % ↔ 1, and the
spatial frequencies, which need the camera (:class:`CameraGeometry`): one pixel subtends the
IFOV (mrad) and covers the pixel pitch (µm) of the focal plane, and IFOV [mrad] = pitch [µm] /
focal length [mm], so ``f[cy/mrad] = f[cy/px] / IFOV``, ``f[lp/mm] = 1000 f[cy/px] / pitch`` and
``f[lp/mm] = 1000 f[cy/mrad] / focal length``. A temperature difference never converts to an
absolute temperature, nor counts to volts (that needs the camera's gain).
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..errors import CurveUnitsWarning, FidelityError

__all__ = ["UNITS", "Unit", "CameraGeometry", "CurveUnitsWarning", "canonical_unit", "unit_from_header",
           "convert"]

FREQUENCY = "spatial frequency"
TEMPERATURE = "temperature"
TEMPERATURE_DIFFERENCE = "temperature difference"
SIGNAL = "signal"
MODULATION = "modulation"


@dataclass(frozen=True)
class Unit:
    """One row of the unit table: canonical ``symbol``, the ``quantity`` it measures, a
    one-line ``meaning`` for messages and the ``spellings`` recognised for it."""

    symbol: str
    quantity: str
    meaning: str
    spellings: tuple[str, ...]


#: The recognised units, by canonical symbol (the table in the module docstring).
UNITS: dict[str, Unit] = {u.symbol: u for u in (
    Unit("cy/px", FREQUENCY, "cycles per pixel",
         ("cy/px", "cy/pixel", "cycles/pixel", "cycles/px", "c/px", "cpp")),
    Unit("cy/mrad", FREQUENCY, "cycles per milliradian of field angle",
         ("cy/mrad", "cycles/mrad", "c/mrad", "cycles/milliradian")),
    Unit("lp/mm", FREQUENCY, "line pairs per millimetre in the focal plane",
         ("lp/mm", "lpmm", "cy/mm", "cycles/mm", "c/mm")),
    Unit("K", TEMPERATURE, "absolute temperature in kelvin", ("k", "kelvin")),
    Unit("degC", TEMPERATURE, "absolute temperature in degrees Celsius", ("degc", "°c", "c", "celsius")),
    Unit("delta_K", TEMPERATURE_DIFFERENCE, "temperature difference ΔT (1 K = 1 °C)",
         ("delta_k", "Δk", "dk", "delta_degc", "Δ°c", "Δt", "dt", "delta_t")),
    Unit("counts", SIGNAL, "digital counts",
         ("counts", "count", "dn", "adu", "lsb", "dl", "digital_level", "digital_number")),
    Unit("V", SIGNAL, "volts", ("v", "volt", "volts")),
    Unit("mV", SIGNAL, "millivolts", ("mv", "millivolt", "millivolts")),
    Unit("1", MODULATION, "modulation ratio (1 at zero frequency)", ("1", "ratio", "fraction")),
    Unit("%", MODULATION, "modulation in per cent", ("%", "percent", "pct")),
)}

#: spellings refused (a silent misreading would be off by a factor or an offset); in a header the
#: short ones ("F", "mK") only next to a temperature name, as "f" alone usually names a frequency
_REFUSED = {"degf": "Fahrenheit", "°f": "Fahrenheit", "fahrenheit": "Fahrenheit", "millikelvin": "millikelvin",
            "f": "Fahrenheit", "mk": "millikelvin"}
_REFUSED_IN_CONTEXT = {"f", "mk"}
#: header words naming the quantity rather than the unit
_ABSOLUTE_WORDS = {"t", "temp", "temperature", "blackbody", "bb", "scene", "target", "tbb", "t_bb"}
_DIFFERENCE_WORDS = {"dt", "delta", "delta_t", "Δt", "diff", "difference", "deltat"}
_MODULATION_WORDS = {"mtf", "sfr", "modulation"}

#: linear conversions that need no camera constant: (from, to) -> (scale, offset), to = scale·from + offset
_FIXED_CONVERSIONS = {("degC", "K"): (1.0, 273.15), ("K", "degC"): (1.0, -273.15),
                      ("V", "mV"): (1000.0, 0.0), ("mV", "V"): (0.001, 0.0),
                      ("%", "1"): (0.01, 0.0), ("1", "%"): (100.0, 0.0)}


def _normalise(text: str) -> str:
    s = text.strip().lower().replace("δ", "Δ")
    s = re.sub(r"\s*/\s*", "/", s)
    return re.sub(r"(?:^|[\s_])per[\s_]", "/", s)


_SPELLING_TO_SYMBOL = {_normalise(sp): u.symbol for u in UNITS.values() for sp in u.spellings}
_SPELLING_TO_SYMBOL.update({_normalise(u.symbol): u.symbol for u in UNITS.values()})


def canonical_unit(unit: str | None, *, what: str = "unit") -> str | None:
    """The canonical symbol of a unit spelling; an unrecognised string is kept as a label.

    Examples
    --------
    >>> canonical_unit("cycles/pixel"), canonical_unit("°C"), canonical_unit("W/sr"), canonical_unit(None)
    ('cy/px', 'degC', 'W/sr', None)
    """
    if unit is None:
        return None
    if not isinstance(unit, str):
        raise FidelityError(f"{what} must be a string or None, got {type(unit).__name__}")
    key = _normalise(unit)
    if key in _REFUSED:
        raise FidelityError(f"{what} {unit!r}: {_REFUSED[key]} is not supported; convert the values "
                            f"to K or °C first")
    if not key:
        return None
    return _SPELLING_TO_SYMBOL.get(key, unit.strip())


def unit_from_header(name: str) -> str | None:
    """The unit a CSV column name declares, or None when it declares none (or is ambiguous).

    Examples
    --------
    >>> [unit_from_header(h) for h in ("freq_cy_per_mrad", "MTF (cy/px)", "lp_mm", "dT_K",
    ...                                "delta_T_degC", "temperature_C", "T_K", "K", "digital_level")]
    ['cy/mrad', 'cy/px', 'lp/mm', 'delta_K', 'delta_K', 'degC', 'K', None, 'counts']
    """
    words = [w for w in re.split(r"[\s_,;:()\[\]{}]+", _normalise(name)) if w]
    candidates = words + [f"{a}{sep}{b}" for a, b in zip(words, words[1:]) for sep in ("_", "/")]
    is_difference = bool(_DIFFERENCE_WORDS & set(candidates))
    is_absolute = bool(_ABSOLUTE_WORDS & set(candidates))
    for c in candidates:
        if c in _REFUSED and (c not in _REFUSED_IN_CONTEXT or is_difference or is_absolute):
            raise FidelityError(f"column {name!r}: {_REFUSED[c]} is not supported; convert the values "
                                f"to K or °C first")
    found = {_SPELLING_TO_SYMBOL[c] for c in candidates if c in _SPELLING_TO_SYMBOL}
    is_difference = is_difference or "delta_K" in found
    temperatures = found & {"K", "degC", "delta_K"}
    if temperatures:
        found -= temperatures
        if is_difference:
            found.add("delta_K")
        elif is_absolute and len(temperatures) == 1:
            found |= temperatures
        else:
            return None  # K or °C without saying whether it is a difference or an absolute temperature
    if not found and _MODULATION_WORDS & set(candidates):
        found.add("1")
    return found.pop() if len(found) == 1 else None


def _positive(value: Any, what: str) -> float | None:
    if value is None:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise FidelityError(f"{what} must be a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise FidelityError(f"{what} must be finite and > 0, got {value!r}")
    return v


#: how each camera constant is given: (keyword, CLI flag)
_CONSTANTS = {"ifov_mrad": "--ifov MRAD", "pixel_pitch_um": "--pixel-pitch UM", "focal_length_mm": "--focal-length MM"}
_NAMES = {"ifov_mrad": "IFOV", "pixel_pitch_um": "pixel pitch", "focal_length_mm": "focal length"}
#: which constant converts between two frequency units (the third pair of constants derives it)
_LINKS = {frozenset(("cy/px", "cy/mrad")): "ifov_mrad", frozenset(("cy/px", "lp/mm")): "pixel_pitch_um",
          frozenset(("cy/mrad", "lp/mm")): "focal_length_mm"}


@dataclass(frozen=True)
class CameraGeometry:
    """The camera constants that convert spatial frequencies between cy/px, cy/mrad and lp/mm.

    Give any of them; two determine the third through ``IFOV [mrad] = pitch [µm] / focal length
    [mm]``. The CLI flags ``--ifov MRAD``, ``--pixel-pitch UM`` and ``--focal-length MM`` build one.

    Parameters
    ----------
    ifov_mrad : float, optional
        Instantaneous field of view of one pixel, milliradians.
    pixel_pitch_um : float, optional
        Detector pixel pitch, micrometres.
    focal_length_mm : float, optional
        Effective focal length, millimetres.

    Raises
    ------
    FidelityError
        A constant that is not finite and > 0, or three constants that disagree by more than
        0.1 %.

    Examples
    --------
    >>> cam = CameraGeometry(pixel_pitch_um=17, focal_length_mm=25)
    >>> round(cam.ifov(), 3)
    0.68
    >>> round(cam.scale("cy/px", "cy/mrad"), 4)  # f[cy/mrad] = f[cy/px] / IFOV
    1.4706
    """

    ifov_mrad: float | None = None
    pixel_pitch_um: float | None = None
    focal_length_mm: float | None = None

    def __post_init__(self) -> None:
        for key in _CONSTANTS:
            object.__setattr__(self, key, _positive(getattr(self, key), key))
        i, p, f = self.ifov_mrad, self.pixel_pitch_um, self.focal_length_mm
        if i is not None and p is not None and f is not None and abs(p / f - i) > 1e-3 * i:
            raise FidelityError(f"camera constants disagree: pixel pitch {p:g} µm / focal length {f:g} mm = "
                                f"{p / f:.6g} mrad, but the IFOV is {i:g} mrad; give two of the three")

    def ifov(self) -> float | None:
        """IFOV in mrad, given or derived from pitch and focal length; None if unknown."""
        if self.ifov_mrad is not None:
            return self.ifov_mrad
        if self.pixel_pitch_um is not None and self.focal_length_mm is not None:
            return self.pixel_pitch_um / self.focal_length_mm
        return None

    def pixel_pitch(self) -> float | None:
        """Pixel pitch in µm, given or derived (IFOV × focal length); None if unknown."""
        if self.pixel_pitch_um is not None:
            return self.pixel_pitch_um
        if self.ifov_mrad is not None and self.focal_length_mm is not None:
            return self.ifov_mrad * self.focal_length_mm
        return None

    def focal_length(self) -> float | None:
        """Focal length in mm, given or derived (pitch / IFOV); None if unknown."""
        if self.focal_length_mm is not None:
            return self.focal_length_mm
        if self.ifov_mrad is not None and self.pixel_pitch_um is not None:
            return self.pixel_pitch_um / self.ifov_mrad
        return None

    def scale(self, from_unit: str, to_unit: str) -> float:
        """Factor ``s`` with ``f[to_unit] = s · f[from_unit]`` between two frequency units.

        Raises
        ------
        FidelityError
            Naming the constant that is missing and how to give it.
        """
        if from_unit == to_unit:
            return 1.0
        link = _LINKS.get(frozenset((from_unit, to_unit)))
        if link is None:
            raise FidelityError(f"no frequency conversion from {from_unit!r} to {to_unit!r}")
        value = {"ifov_mrad": self.ifov, "pixel_pitch_um": self.pixel_pitch,
                 "focal_length_mm": self.focal_length}[link]()
        if value is None:
            raise FidelityError(f"converting {from_unit} to {to_unit} needs {_how_to_give(link)}")
        # length of one unit of each kind, in pixels: 1 mrad = 1/IFOV px, 1 mm = 1000/pitch px
        per_px = {"ifov_mrad": {"cy/px": 1.0, "cy/mrad": value},
                  "pixel_pitch_um": {"cy/px": 1.0, "lp/mm": value / 1000.0},
                  "focal_length_mm": {"cy/mrad": 1.0, "lp/mm": value / 1000.0}}[link]
        return per_px[from_unit] / per_px[to_unit]

    def describe(self, link_units: tuple[str, str]) -> str:
        """The constant used between two frequency units, for notes (``"IFOV 0.68 mrad"``)."""
        link = _LINKS[frozenset(link_units)]
        value = {"ifov_mrad": self.ifov, "pixel_pitch_um": self.pixel_pitch,
                 "focal_length_mm": self.focal_length}[link]()
        unit = {"ifov_mrad": "mrad", "pixel_pitch_um": "µm", "focal_length_mm": "mm"}[link]
        return f"{_NAMES[link]} {value:g} {unit}"

    def to_dict(self) -> dict[str, float | None]:
        """The constants as given (JSON-ready)."""
        return {key: getattr(self, key) for key in _CONSTANTS}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> CameraGeometry:
        """Inverse of :meth:`to_dict`; unknown keys are refused."""
        d = dict(d or {})
        unknown = set(d) - set(_CONSTANTS)
        if unknown:
            raise FidelityError(f"unknown camera constant(s) {sorted(unknown)}; expected {sorted(_CONSTANTS)}")
        return cls(**d)


def _how_to_give(link: str) -> str:
    others = [k for k in _CONSTANTS if k != link]
    return (f"the {_NAMES[link]} ({_CONSTANTS[link]}; {link} in Python) or both the {_NAMES[others[0]]} "
            f"and the {_NAMES[others[1]]} ({_CONSTANTS[others[0]]} and {_CONSTANTS[others[1]]})")


def conversion_hint(from_unit: str, to_unit: str) -> str:
    """How to make two units comparable, for error messages."""
    a, b = UNITS.get(from_unit), UNITS.get(to_unit)
    if a is None or b is None:
        return "relabel or convert one of the curves"
    if a.quantity == b.quantity == FREQUENCY:
        return "give " + _how_to_give(_LINKS[frozenset((from_unit, to_unit))])
    if (from_unit, to_unit) in _FIXED_CONVERSIONS:
        return "they convert without further input"
    if {a.quantity, b.quantity} == {TEMPERATURE, TEMPERATURE_DIFFERENCE}:
        return ("a temperature difference cannot be converted to an absolute temperature: give both "
                "curves against ΔT (subtract the background temperature) or both against T")
    if a.quantity == b.quantity == SIGNAL:
        return "counts and volts differ by the camera's gain: give both curves in the same signal unit"
    return f"a {a.quantity} axis cannot be compared with a {b.quantity} axis"


def convert(values: Any, from_unit: str | None, to_unit: str | None, *,
            camera: CameraGeometry | None = None) -> np.ndarray:
    """Values in ``from_unit`` expressed in ``to_unit`` (both canonical symbols).

    Raises
    ------
    FidelityError
        An unknown unit, units of different quantities, or a frequency conversion whose camera
        constant is missing — naming both units and how to convert.

    Examples
    --------
    >>> convert([0.0, 20.0], "degC", "K").tolist()
    [273.15, 293.15]
    >>> convert([0.25], "cy/px", "lp/mm", camera=CameraGeometry(pixel_pitch_um=12)).round(4).tolist()
    [20.8333]
    """
    v = np.asarray(values, dtype=np.float64)
    if from_unit == to_unit:
        return v.copy()
    if from_unit is None or to_unit is None:
        raise FidelityError(f"cannot convert between {from_unit or 'an unknown unit'} and "
                            f"{to_unit or 'an unknown unit'}")
    if (from_unit, to_unit) in _FIXED_CONVERSIONS:
        scale, offset = _FIXED_CONVERSIONS[(from_unit, to_unit)]
        return v * scale + offset
    a, b = UNITS.get(from_unit), UNITS.get(to_unit)
    if a is not None and b is not None and a.quantity == b.quantity == FREQUENCY:
        return v * (camera or CameraGeometry()).scale(from_unit, to_unit)
    raise FidelityError(f"cannot convert {from_unit} to {to_unit}: {conversion_hint(from_unit, to_unit)}")


def warn_unknown(message: str) -> None:
    """Issue a :class:`CurveUnitsWarning` attributed to the caller of the public function."""
    warnings.warn(message, CurveUnitsWarning, stacklevel=4)
