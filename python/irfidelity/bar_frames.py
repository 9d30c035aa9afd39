"""Frames of bar targets taken with one camera, and what they measure: its MRTD, CTF and MTF.

A set of bar frames is a :class:`BarFrames` (arrays or files with each frame's frequency and
ΔT), or a directory holding the frames and a list of them, ``bars.csv`` (docs/bars.md,
section 5)::

    file,frequency_cy_per_px,delta_t_K
    f005_dt010.png,0.05,0.10
    f005_dt030.png,0.05,0.30
    ...

:func:`bar_curves` reads them: the MRTD measured on every frame
(:func:`~irfidelity.curves.measured_mrtd`), and, on each frequency's frame of largest ``|ΔT|``,
the CTF (bar modulation) and the MTF (fundamental-amplitude ratio) of
:func:`~irfidelity.curves.ctf_curve`.
"""

from __future__ import annotations

import csv
import os
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from .curves import Curve, CameraGeometry, ctf_curve, measured_mrtd
from .curves.units import FREQUENCY, UNITS, unit_from_header
from .errors import BarWarning, FidelityError

__all__ = ["BarFrames", "BAR_LIST", "bar_curves", "is_bar_directory"]

#: The list of a directory of bar frames.
BAR_LIST = "bars.csv"


@dataclass(frozen=True, init=False)
class BarFrames:
    """Frames of bar targets (one target at a known ΔT read per frame).

    Attributes
    ----------
    frames : tuple of 2-D arrays or paths
    frequencies : tuple of float
        Each frame's bar frequency, in ``unit``.
    delta_t : tuple of float
        Each frame's ΔT (bars − background), K; not 0.
    unit : str
        "cy/px", "cy/mrad" or "lp/mm" (the last two need the camera geometry).
    rois : tuple, optional
        Each frame's ROI ``(row_start, row_stop, col_start, col_stop)`` or None (found).
    source : str, optional
        The directory they were read from.

    Examples
    --------
    >>> from irfidelity.targets import four_bar
    >>> bars = BarFrames([four_bar(f, (64, 64), levels=(0, 1)) for f in (0.1, 0.15, 0.2)], [0.1, 0.15, 0.2], [1, 1, 1])
    >>> bars.describe()
    '3 bar frames at 3 frequencies 0.1..0.2 cy/px'
    """

    frames: tuple
    frequencies: tuple
    delta_t: tuple
    unit: str = "cy/px"
    rois: tuple | None = None
    source: str | None = None

    def __init__(self, frames: Any, frequencies: Any, delta_t: Any, *, unit: str = "cy/px", rois: Any = None,
                 source: str | None = None) -> None:
        count = len(frames)
        values = {"frequencies": frequencies, "delta_t": delta_t}
        for what, given in values.items():
            a = np.atleast_1d(np.asarray(given, dtype=np.float64))
            if a.shape != (count,) or not np.isfinite(a).all():
                raise FidelityError(f"bar frames: {what} must hold one finite number per frame ({count})",
                                    option=what)
            values[what] = tuple(a.tolist())
        if unit not in UNITS or UNITS[unit].quantity != FREQUENCY:
            raise FidelityError(f"bar frames: unit must be cy/px, cy/mrad or lp/mm, got {unit!r}", option="unit")
        if rois is not None and len(rois) != count:
            raise FidelityError(f"bar frames: {len(rois)} rois for {count} frames", option="rois")
        object.__setattr__(self, "frames", tuple(frames))
        object.__setattr__(self, "frequencies", values["frequencies"])
        object.__setattr__(self, "delta_t", values["delta_t"])
        object.__setattr__(self, "unit", unit)
        object.__setattr__(self, "rois", None if rois is None else tuple(rois))
        object.__setattr__(self, "source", source)

    @classmethod
    def read(cls, directory: str | os.PathLike) -> BarFrames:
        """The bar frames a directory lists in its ``bars.csv`` (module docstring).

        Raises
        ------
        FidelityError
            No list, a list without the columns ``file``, ``frequency…`` and a ΔT (``delta_t``,
            ``dT_K``, …), a row that is not numbers, a listed file that does not exist.
        """
        folder = os.fsdecode(os.fspath(directory))
        path = os.path.join(folder, BAR_LIST)
        if not os.path.isfile(path):
            raise FidelityError(f"{folder!r}: no {BAR_LIST} listing the bar frames (columns file, frequency, "
                                f"delta_t; docs/bars.md)")
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = [row for row in csv.reader(fh) if row and not row[0].lstrip().startswith("#")]
        if len(rows) < 2:
            raise FidelityError(f"{path}: expected a header and one row per bar frame")
        columns, unit = _columns(rows[0], path)
        files, freqs, dts, rois = [], [], [], []
        for number, row in enumerate(rows[1:], start=2):
            cells = [c.strip() for c in row] + [""] * len(rows[0])
            name = cells[columns["file"]]
            full = os.path.join(folder, name)
            if not name or not os.path.isfile(full):
                raise FidelityError(f"{path}, row {number}: bar frame {name!r}: no such file")
            files.append(full)
            freqs.append(_number(cells[columns["frequency"]], path, number, "frequency"))
            dts.append(_number(cells[columns["delta_t"]], path, number, "delta_t"))
            rois.append(_roi(cells[columns["roi"]], path, number) if "roi" in columns else None)
        return cls(files, freqs, dts, unit=unit, rois=rois, source=folder)

    def describe(self) -> str:
        """``'N bar frames at M frequencies lo..hi unit'`` (and where from)."""
        f = np.unique(self.frequencies)
        where = f" in {self.source}" if self.source else ""
        return (f"{len(self.frames)} bar frames at {f.size} frequencies {f[0]:g}..{f[-1]:g} {self.unit}"
                f"{where}")


def _columns(header: list[str], path: str) -> tuple[dict[str, int], str]:
    """Where the file, frequency, ΔT (and optional roi) columns are, and the frequency unit."""
    found: dict[str, int] = {}
    unit = "cy/px"
    for index, name in enumerate(h.strip() for h in header):
        low = name.lower()
        if low in ("file", "frame", "path") and "file" not in found:
            found["file"] = index
        elif low == "roi":
            found["roi"] = index
        elif low.startswith("freq") and "frequency" not in found:
            found["frequency"] = index
            declared = unit_from_header(name)
            if declared is not None and UNITS[declared].quantity != FREQUENCY:
                raise FidelityError(f"{path}: column {name!r} declares {declared}, not a spatial frequency")
            unit = declared or unit
        elif "delta_t" not in found and (unit_from_header(name) == "delta_K" or low.startswith("delta")):
            found["delta_t"] = index
    absent = [k for k in ("file", "frequency", "delta_t") if k not in found]
    if absent:
        raise FidelityError(f"{path}: no {', '.join(absent)} column in the header {header!r}; expected "
                            f"file,frequency,delta_t (the frequency header may name its unit: frequency_cy_per_mrad)")
    return found, unit


def _number(text: str, path: str, row: int, what: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise FidelityError(f"{path}, row {row}: {what} must be a number, got {text!r}") from None


def _roi(text: str, path: str, row: int) -> tuple[int, ...] | None:
    """``row_start:row_stop:col_start:col_stop``, or empty for a target found automatically."""
    if not text:
        return None
    try:
        bounds = tuple(int(v) for v in text.split(":"))
    except ValueError:
        bounds = ()
    if len(bounds) != 4:
        raise FidelityError(f"{path}, row {row}: roi must be row_start:row_stop:col_start:col_stop, got {text!r}")
    return bounds


def is_bar_directory(x: Any) -> bool:
    """Whether ``x`` is a path to a directory listing bar frames (it holds ``bars.csv``)."""
    return isinstance(x, (str, os.PathLike)) and os.path.isfile(os.path.join(os.fspath(x), BAR_LIST))


def as_bar_frames(x: Any) -> BarFrames | None:
    """A :class:`BarFrames` from one or a bar directory; None for anything else."""
    if isinstance(x, BarFrames):
        return x
    return BarFrames.read(x) if is_bar_directory(x) else None


def _loaded(bars: BarFrames, channel: str | None) -> list[np.ndarray]:
    from .frames import load_frame

    out = []
    for frame in bars.frames:
        if isinstance(frame, (str, os.PathLike)):
            try:
                frame = load_frame(frame, channel=channel)
            except FidelityError as exc:
                raise type(exc)(f"bar frame {os.fsdecode(os.fspath(frame))}: {exc}", option=exc.option) from None
        out.append(frame)
    return out


def bar_curves(bars: BarFrames, *, who: str = "real", channel: str | None = None,
               camera: CameraGeometry | None = None, quantities: tuple[str, ...] = ("mrtd", "ctf", "mtf"),
               **mrtd_options: Any) -> dict[str, Curve]:
    """The measured MRTD, CTF and MTF of one camera's bar frames.

    Parameters
    ----------
    bars : BarFrames
    who : str
        The camera, for names and messages ("real" or "simulated").
    channel : str, optional
        Channel of multi-channel frame files.
    camera : CameraGeometry, optional
        For frequencies in cy/mrad or lp/mm.
    quantities : tuple of "mrtd", "ctf", "mtf"
        What to measure.
    **mrtd_options
        ``snr_threshold``, ``eye_time``, ``frame_rate`` of
        :func:`~irfidelity.curves.measured_mrtd`.

    Returns
    -------
    dict
        ``{"mrtd": Curve, "ctf": Curve, "mtf": Curve}`` for the quantities asked. The CTF and
        MTF are read on each frequency's frame of largest ``|ΔT|``; a CTF or MTF that cannot
        be read is left out with a :class:`~irfidelity.errors.BarWarning` giving the reason
        (the MRTD's errors are raised).

    Examples
    --------
    >>> from irfidelity.targets import four_bar, gaussian_otf
    >>> rng = np.random.default_rng(0)
    >>> frames, freqs, dts = [], [], []
    >>> for f in (0.05, 0.1, 0.15):
    ...     for dt in (0.05, 0.1, 0.2):
    ...         frames.append(four_bar(f, (96, 96), otf=gaussian_otf(1.0), levels=(0, dt)) + rng.normal(0, 0.03, (96, 96)))
    ...         freqs.append(f); dts.append(dt)
    >>> c = bar_curves(BarFrames(frames, freqs, dts))
    >>> sorted(c), c["mrtd"].y_unit, c["mtf"].x.tolist()
    (['ctf', 'mrtd', 'mtf'], 'delta_K', [0.05, 0.1, 0.15])
    """
    frames = _loaded(bars, channel)
    freqs, dts = np.asarray(bars.frequencies), np.asarray(bars.delta_t)
    out: dict[str, Curve] = {}
    if "mrtd" in quantities:
        try:
            out["mrtd"] = measured_mrtd(frames, frequencies=freqs, delta_t=dts, rois=bars.rois, unit=bars.unit,
                                        camera=camera, name=f"{who} MRTD (measured)", **mrtd_options)
        except FidelityError as exc:
            raise type(exc)(f"{who} bar frames{_where(bars)}: {exc}", option=exc.option) from None
    strongest = [int(np.flatnonzero(freqs == f)[np.argmax(np.abs(dts[freqs == f]))]) for f in np.unique(freqs)]
    for quantity, method in (("ctf", "modulation"), ("mtf", "fundamental")):
        if quantity not in quantities:
            continue
        try:
            out[quantity] = ctf_curve([frames[i] for i in strongest], frequencies=freqs[strongest],
                                      rois=None if bars.rois is None else [bars.rois[i] for i in strongest],
                                      method=method, unit=bars.unit, camera=camera,
                                      name=f"{who} {quantity.upper()} (bars)")
        except FidelityError as exc:
            if quantity == "mtf" and "mrtd" not in quantities:
                raise type(exc)(f"{who} bar frames{_where(bars)}: {exc}", option=exc.option) from None
            warnings.warn(f"{who} bar frames{_where(bars)}: no {quantity.upper()} curve: {exc}", BarWarning,
                          stacklevel=2)
    return out


def _where(bars: BarFrames) -> str:
    return f" ({bars.source})" if bars.source else ""
