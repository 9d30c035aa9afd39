"""Radiometric calibration: FLIR files' camera-info record, and counts to temperatures and back.

A FLIR camera (and DJI's XT2/XT-R, which write the same format) stores raw counts with the
factory calibration that turns them into temperatures: Planck constants fitted to a
blackbody, and the viewing conditions the camera was told (emissivity, distance, reflected and
air temperature, humidity, an external window). :func:`read_radiometry` reads them from FFF,
SEQ and radiometric JPEG files; :meth:`Radiometry.temperature` applies the FLIR model (as
Thermimage's ``raw2temp`` publishes it) and :meth:`Radiometry.counts` is its inverse. Both run
in the Rust core with the GIL released. The model and its sources: ``docs/radiometry.md``.
"""

from __future__ import annotations

import dataclasses
import datetime
import os
import warnings
from dataclasses import dataclass
from typing import Any, Union

import numpy as np

from . import _core
from .decoding import FRAME_DTYPES, check_limit, check_page
from .errors import FidelityError, RadiometryWarning, RangeError

__all__ = ["Radiometry", "read_radiometry", "RadiometryWarning", "CALIBRATION_FIELDS", "UNITS"]

PathLike = Union[str, "os.PathLike[str]"]

#: Temperature units of the conversions.
UNITS = ("C", "K")


@dataclass(frozen=True)
class Radiometry:
    """A radiometric calibration and the viewing conditions it assumes (frozen).

    Read one from a file with :func:`read_radiometry`, or give the Planck constants of a camera
    by hand (the viewing conditions then default to a blackbody seen up close: emissivity 1, no
    atmosphere, no window). The file's values are the camera operator's settings at capture
    time; override what you know better with :meth:`replace` or as keyword arguments of the
    conversions (``docs/radiometry.md`` says what each one means).

    Attributes
    ----------
    planck_r1, planck_r2, planck_b, planck_f, planck_o : float
        The factory calibration: a blackbody at ``t`` kelvin gives
        ``R1 / (R2 * (exp(B / t) - F)) - O`` counts.
    emissivity : float
        The object's emissivity, in (0, 1].
    object_distance : float
        Distance to the object in metres (>= 0): the atmosphere's path.
    reflected_temperature : float
        Apparent temperature of what the object reflects, °C.
    atmospheric_temperature : float
        Air temperature, °C.
    window_temperature : float
        Temperature of an external window (or protective lens), °C.
    window_transmission : float
        Transmission of that window, in (0, 1]; 1 means no window.
    relative_humidity : float
        Relative humidity in percent, [0, 100] (files store a fraction).
    alpha1, alpha2, beta1, beta2, x : float
        The camera's constants of atmospheric transmission.
    camera_model, camera_serial, lens_model : str or None
        From the file, when it records them.
    date : datetime.datetime or None
        When the frame was taken (with its time zone), when recorded.
    frame_rate : int or None
        Frames per second, when recorded.
    source : str or None
        The file the values were read from (named in error messages).

    Examples
    --------
    Thermimage's worked example (raw 17994.06 seen through a window at 96 % transmission):

    >>> import irfidelity as irf
    >>> cal = irf.radiometry.Radiometry(planck_r1=21106.77, planck_r2=0.012545258, planck_b=1501,
    ...                                 planck_f=1, planck_o=-7340, emissivity=0.95, object_distance=1,
    ...                                 window_transmission=0.96)
    >>> round(float(cal.temperature(17994.06)), 5)
    23.31223
    """

    planck_r1: float
    planck_r2: float
    planck_b: float
    planck_f: float
    planck_o: float
    emissivity: float = 1.0
    object_distance: float = 0.0
    reflected_temperature: float = 20.0
    atmospheric_temperature: float = 20.0
    window_temperature: float = 20.0
    window_transmission: float = 1.0
    relative_humidity: float = 50.0
    alpha1: float = 0.006569
    alpha2: float = 0.01262
    beta1: float = -0.002276
    beta2: float = -0.00667
    x: float = 1.9
    camera_model: str | None = None
    camera_serial: str | None = None
    lens_model: str | None = None
    date: datetime.datetime | None = None
    frame_rate: int | None = None
    source: str | None = dataclasses.field(default=None, compare=False)

    def __post_init__(self) -> None:
        for name in CALIBRATION_FIELDS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise FidelityError(f"{self._where()}{name} must be a number, got {value!r}", option=name)
            object.__setattr__(self, name, float(value))

    def _where(self) -> str:
        return f"{self.source}: " if self.source else ""

    def replace(self, **overrides: float) -> Radiometry:
        """A copy with some calibration fields replaced (names as the attributes).

        Raises
        ------
        FidelityError
            An unknown name, or a value that is not a number.

        Examples
        --------
        >>> import irfidelity as irf
        >>> cal = irf.radiometry.Radiometry(planck_r1=21106.77, planck_r2=0.012545258, planck_b=1501,
        ...                                 planck_f=1, planck_o=-7340)
        >>> cal.replace(emissivity=0.98).emissivity
        0.98
        """
        unknown = sorted(set(overrides) - set(CALIBRATION_FIELDS))
        if unknown:
            raise FidelityError(
                f"{self._where()}unknown calibration override {', '.join(unknown)}; the overrides are: "
                + ", ".join(CALIBRATION_FIELDS),
                option=unknown[0],
            )
        changes: dict[str, Any] = dict(overrides)  # calibration fields only (checked above)
        return dataclasses.replace(self, **changes)

    def _convert(self, values: Any, unit: str, overrides: dict[str, float], to_temperature: bool) -> Any:
        if unit not in UNITS:
            raise FidelityError(f"unit must be 'C' or 'K', got {unit!r}", option="unit")
        calibration = self.replace(**overrides) if overrides else self
        array = np.asarray(values)
        scalar = array.ndim == 0
        if array.dtype.kind == "b" or array.dtype.kind not in "iuf":
            raise FidelityError(f"expected an integer or float array, got dtype {array.dtype}")
        if array.dtype not in FRAME_DTYPES:  # what the core converts without a copy
            array = array.astype(np.float64)
        array = np.require(array, requirements=["C", "A"])
        try:
            out, outside, nonfinite = _core.radiometric_conversion(array, calibration, unit, not to_temperature)
        except FidelityError as exc:
            raise type(exc)(f"{self._where()}{exc}{self._origin(exc, overrides)}",
                            option=_field_named(str(exc))) from None
        what = "raw counts" if to_temperature else "temperatures"
        _report_nan(out, outside, nonfinite, what, self._where())
        return out[()] if scalar else out

    def _origin(self, exc: FidelityError, overrides: dict[str, float]) -> str:
        field = _field_named(str(exc))
        if field is None or field in overrides or not self.source:
            return ""
        return f" (the file's value; override it with {field}=...)"

    def temperature(self, counts: Any, unit: str = "C", **overrides: float) -> Any:
        """Temperatures of raw counts, by the FLIR model (``docs/radiometry.md``).

        Parameters
        ----------
        counts : array_like
            Raw counts, any shape, integer or float.
        unit : {"C", "K"}
            Unit of the result.
        **overrides : float
            Calibration fields to use instead of this object's (``emissivity=0.98``, ...);
            temperatures among them are in °C whatever ``unit`` is.

        Returns
        -------
        numpy.ndarray or float
            float64 temperatures of ``counts``' shape (a float for a scalar). Counts outside
            the calibration's domain (no finite temperature above 0 K) are NaN, with a
            :class:`RadiometryWarning` counting them.

        Raises
        ------
        FidelityError
            A calibration field out of its range (``emissivity`` outside (0, 1], ``planck_r2``
            = 0, ...), named in the message.
        RangeError
            No count at all within the calibration's domain.

        Examples
        --------
        >>> import numpy as np, irfidelity as irf
        >>> cal = irf.radiometry.Radiometry(planck_r1=21106.77, planck_r2=0.012545258, planck_b=1501,
        ...                                 planck_f=1, planck_o=-7340)
        >>> cal.temperature(np.array([17000, 19000], dtype=np.uint16), unit="K").round(2)
        array([290.57, 301.48])
        """
        return self._convert(counts, unit, overrides, to_temperature=True)

    def counts(self, temperature: Any, unit: str = "C", **overrides: float) -> Any:
        """Raw counts (float64, unrounded) of temperatures: the exact inverse of :meth:`temperature`.

        Parameters
        ----------
        temperature : array_like
            Temperatures in ``unit``, any shape.
        unit : {"C", "K"}
            Unit of ``temperature``.
        **overrides : float
            As for :meth:`temperature`.

        Returns
        -------
        numpy.ndarray or float
            ``np.rint(cal.counts(cal.temperature(raw)))`` gives back integer ``raw``.
            Temperatures not above 0 K (or non-finite) give NaN, with a warning.

        Examples
        --------
        >>> import irfidelity as irf
        >>> cal = irf.radiometry.Radiometry(planck_r1=21106.77, planck_r2=0.012545258, planck_b=1501,
        ...                                 planck_f=1, planck_o=-7340)
        >>> round(float(cal.counts(cal.temperature(18000))), 6)
        18000.0
        """
        return self._convert(temperature, unit, overrides, to_temperature=False)


#: The fields a conversion uses (and that overrides may replace), in the order of the file record.
CALIBRATION_FIELDS = tuple(f.name for f in dataclasses.fields(Radiometry))[:17]

def _field_named(message: str) -> str | None:
    """The calibration field a core message starts with (``"emissivity = 1.5 ..."``)."""
    head = message.split(" = ", 1)[0]
    return head if head in CALIBRATION_FIELDS else None


def _report_nan(out: np.ndarray, outside: int, nonfinite: int, what: str, where: str) -> None:
    """Warn about NaN results; raise when no value is left."""
    if outside == 0 and nonfinite == 0:
        return
    parts = []
    if outside:
        parts.append(f"{outside} {what} outside the calibration's domain (no finite temperature above 0 K)")
    if nonfinite:
        parts.append(f"{nonfinite} non-finite {what}")
    text = " and ".join(parts)
    if outside + nonfinite == out.size:
        raise RangeError(f"{where}all {out.size} values are NaN: {text}")
    warnings.warn(f"{where}{text} became NaN (of {out.size})", RadiometryWarning, stacklevel=4)


def _date(value: tuple[int, int, int] | None) -> datetime.datetime | None:
    if value is None:
        return None
    seconds, millis, east = value
    zone = datetime.timezone(datetime.timedelta(minutes=east)) if abs(east) < 24 * 60 else datetime.UTC
    return datetime.datetime.fromtimestamp(seconds, zone) + datetime.timedelta(milliseconds=millis)


def read_radiometry(path: PathLike, *, page: int = 0, max_bytes: int | None = None) -> Radiometry:
    """The radiometric calibration of a FLIR file: FFF, SEQ or CSQ (frame ``page``), or radiometric JPEG.

    Parameters
    ----------
    path : str or os.PathLike
        A FLIR FFF or SEQ file, or a radiometric JPEG (FLIR, or DJI Zenmuse XT2/XT-R).
    page : int, default 0
        The frame of a SEQ file whose record is read.
    max_bytes : int, optional
        The decoding budget (as for :func:`irfidelity.load_frame`).

    Returns
    -------
    Radiometry
        The camera-info record: temperatures in °C, humidity in percent, distance in metres,
        as the file stores them (unchecked until a conversion uses them).

    Raises
    ------
    FrameError
        The file has no calibration (not a radiometric file), or its records are truncated,
        zeroed or corrupt; the message names the file and the record.

    Examples
    --------
    The FLIR AX8 radiometric JPEG shipped with the package:

    >>> from importlib import resources
    >>> import irfidelity as irf
    >>> with resources.as_file(resources.files("irfidelity") / "data" / "readthermal_flir_ax8.jpg") as path:
    ...     cal = irf.read_radiometry(path)
    >>> cal.camera_model, round(cal.emissivity, 2), cal.object_distance
    ('FLIR AX8', 0.95, 1.0)
    """
    spath = os.fspath(path)
    page = check_page(spath, page)
    budget = check_limit(spath, "max_bytes", max_bytes)
    record = dict(_core.read_camera_info(spath, page, max_bytes=budget))
    record["date"] = _date(record["date"])
    return Radiometry(**record, source=spath)

