"""The :class:`Curve` type: a sampled characteristic curve y(x) with the units of both axes."""

from __future__ import annotations

import os
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import FidelityError
from .table import pick_two, read_table, series_hint
from .units import CameraGeometry, canonical_unit, convert, unit_from_header

__all__ = ["Curve", "as_curve"]


class Curve:
    """A sampled characteristic curve ``y(x)``: an MTF against spatial frequency, a SiTF signal
    against temperature (difference), with the units of both axes.

    Parameters
    ----------
    x, y : array_like
        1-D, same length, at least 3 points, all finite; ``x`` strictly increasing.
        Stored as read-only float64 copies.
    name : str, optional
        Label used in messages and reports.
    x_unit, y_unit : str, optional
        Units of the axes: a spelling from the table in :mod:`irfidelity.curves.units`
        (``"cycles/pixel"`` → ``"cy/px"``, ``"°C"`` → ``"degC"``, ``"dT"`` → ``"delta_K"``,
        ``"DN"`` → ``"counts"`` ...), any other string (kept as a label: equal labels compare,
        different ones do not convert), or None = unknown.
    meta : mapping, optional
        Free-form provenance (e.g. the edge angle found by ``mtf_from_edge``).

    Raises
    ------
    FidelityError (a ValueError)
        Naming the rule broken: length, shape, finiteness or monotonicity.

    Examples
    --------
    >>> c = Curve([0, 0.25, 0.5], [1, 0.6, 0.2], x_unit="cycles/pixel")
    >>> c
    Curve(3 points, x 0..0.5 cy/px, y 0.2..1)
    >>> float(c(0.125))
    0.8
    """

    __slots__ = ("x", "y", "name", "x_unit", "y_unit", "meta")

    def __init__(self, x: Any, y: Any, *, name: str | None = None, x_unit: str | None = None,
                 y_unit: str | None = None, meta: Mapping[str, Any] | None = None) -> None:
        label = f"curve {name!r}" if name else "curve"
        try:
            xa = np.array(x, dtype=np.float64)
            ya = np.array(y, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise FidelityError(f"{label}: x and y must be numeric arrays ({exc})") from None
        if xa.ndim != 1 or ya.ndim != 1:
            raise FidelityError(f"{label}: x and y must be 1-D, got shapes {xa.shape} and {ya.shape}")
        if xa.shape != ya.shape:
            raise FidelityError(f"{label}: x and y must have the same length, got {xa.size} and {ya.size}")
        if xa.size < 3:
            raise FidelityError(f"{label}: needs at least 3 points, got {xa.size}")
        for arr, axis in ((xa, "x"), (ya, "y")):
            bad = ~np.isfinite(arr)
            if bad.any():
                i = int(np.argmax(bad))
                raise FidelityError(f"{label}: all values must be finite; {axis}[{i}] = {float(arr[i])} "
                                    f"({int(bad.sum())} non-finite)")
        steps = np.diff(xa)
        if not (steps > 0).all():
            i = int(np.argmax(steps <= 0))
            raise FidelityError(f"{label}: x must be strictly increasing; x[{i}] = {float(xa[i]):g} "
                                f">= x[{i + 1}] = {float(xa[i + 1]):g}")
        xa.flags.writeable = False
        ya.flags.writeable = False
        self.x = xa
        self.y = ya
        self.name = name
        self.x_unit = canonical_unit(x_unit, what="x_unit")
        self.y_unit = canonical_unit(y_unit, what="y_unit")
        self.meta = dict(meta) if meta else {}

    def __len__(self) -> int:
        return int(self.x.size)

    def __repr__(self) -> str:
        xu = f" {self.x_unit}" if self.x_unit else ""
        yu = f" {self.y_unit}" if self.y_unit else ""
        n = f", name={self.name!r}" if self.name else ""
        return (f"Curve({self.x.size} points, x {self.x[0]:g}..{self.x[-1]:g}{xu}, "
                f"y {self.y.min():g}..{self.y.max():g}{yu}{n})")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Curve):
            return NotImplemented
        return (np.array_equal(self.x, other.x) and np.array_equal(self.y, other.y)
                and self.x_unit == other.x_unit and self.y_unit == other.y_unit)

    __hash__ = None  # type: ignore[assignment]

    def __call__(self, xq: Any) -> np.ndarray:
        """Linear interpolation at ``xq``; raises if any point lies outside ``[x[0], x[-1]]``."""
        q = np.asarray(xq, dtype=np.float64)
        if not np.isfinite(q).all() or (q < self.x[0]).any() or (q > self.x[-1]).any():
            raise FidelityError(f"points must lie within the curve's x range "
                                f"[{self.x[0]:g}, {self.x[-1]:g}] (no extrapolation)")
        return np.interp(q, self.x, self.y)

    def replace(self, **changes: Any) -> Curve:
        """A new curve with some of ``x``, ``y``, ``name``, ``x_unit``, ``y_unit``, ``meta`` changed
        (checked like any new curve)."""
        fields: dict[str, Any] = {"x": self.x, "y": self.y, "name": self.name, "x_unit": self.x_unit,
                                  "y_unit": self.y_unit, "meta": self.meta}
        fields.update(changes)
        x, y = fields.pop("x"), fields.pop("y")
        return Curve(x, y, **fields)

    def with_units(self, *, x_unit: Any = ..., y_unit: Any = ...) -> Curve:
        """The same samples labelled with other units (no conversion); an omitted axis keeps its unit."""
        changes = {k: v for k, v in (("x_unit", x_unit), ("y_unit", y_unit)) if v is not ...}
        return self.replace(**changes)

    def to_units(self, *, x_unit: str | None = None, y_unit: str | None = None,
                 camera: CameraGeometry | None = None) -> Curve:
        """The curve with its axes converted to ``x_unit`` / ``y_unit`` (None: leave the axis).

        See :func:`irfidelity.curves.units.convert` for what converts; spatial frequencies need
        the ``camera`` constants.

        Examples
        --------
        >>> c = Curve([0, 0.25, 0.5], [1, 0.6, 0.2], x_unit="cy/px")
        >>> c.to_units(x_unit="cy/mrad", camera=CameraGeometry(ifov_mrad=0.05)).x.tolist()
        [0.0, 5.0, 10.0]
        """
        x, y, changes = self.x, self.y, {}
        if x_unit is not None:
            target = canonical_unit(x_unit, what="x_unit")
            x = convert(self.x, self.x_unit, target, camera=camera)
            changes["x_unit"] = target
        if y_unit is not None:
            target = canonical_unit(y_unit, what="y_unit")
            y = convert(self.y, self.y_unit, target, camera=camera)
            changes["y_unit"] = target
        return self.replace(x=x, y=y, **changes)

    @classmethod
    def from_csv(cls, path: str | os.PathLike[str], *, columns: Sequence[int | str] | None = None,
                 where: Mapping[int | str, float] | None = None, name: str | None = None,
                 x_unit: str | None = None, y_unit: str | None = None) -> Curve:
        """Read a curve from a text table (CSV, TSV or whitespace-separated).

        Blank lines and ``#`` comments are skipped; the first line is a header when any field
        is not a number. The units come from the header names (see the table in
        :mod:`irfidelity.curves.units`: ``freq_cy_per_mrad``, ``dT_K``, ``temperature_C``,
        ``digital_level`` ...) unless given.

        Parameters
        ----------
        path : path-like
        columns : (x, y), optional
            Two columns by header name or 0-based index. Required when the table has more
            than two columns; by default it must have exactly two.
        where : mapping, optional
            Keep only the rows whose columns (name or index) equal these numbers: the rows
            of one series in a table that holds several, e.g. ``{"instrument_temp_C": 17.1}``.
        name : str, optional
            Label; defaults to the file name.
        x_unit, y_unit : str, optional
            The units of the axes, when the header does not say them; a header that names a
            different unit is an error.

        Raises
        ------
        FidelityError
            Naming the file and line: unreadable file, ragged row, non-numeric value, missing
            column, no row left by ``where``, a header unit that contradicts ``x_unit`` or
            ``y_unit``, or a curve rule (a restarting x column gets a hint naming a row filter).

        Examples
        --------
        >>> import pathlib, tempfile
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "mtf.csv"
        >>> _ = p.write_text("freq_cy_per_mrad,mtf\\n0,1\\n0.5,0.6\\n1,0.2\\n")
        >>> c = Curve.from_csv(p)
        >>> c.x_unit, c.y_unit
        ('cy/mrad', '1')
        """
        table = read_table(path)
        ix, iy = pick_two(table, columns)
        if where:
            table = table.select_rows(where)
        units = [_header_or_given(table, i, given, axis)
                 for i, given, axis in ((ix, x_unit, "x_unit"), (iy, y_unit, "y_unit"))]
        xs, ys = table.numbers(ix), table.numbers(iy)
        try:
            return cls(xs, ys, name=name if name is not None else os.path.basename(table.path),
                       x_unit=units[0], y_unit=units[1])
        except FidelityError as exc:
            hint = series_hint(table, ix, iy) if "increasing" in str(exc) else ""
            more = (f"; the file seems to hold several series: select one with a row filter "
                    f"such as {hint}") if hint else ""
            raise FidelityError(f"{table.path}: {exc}{more}") from None


def _header_or_given(table: Any, i: int, given: str | None, axis: str) -> str | None:
    from_header = unit_from_header(table.header[i]) if table.header is not None else None
    stated = canonical_unit(given, what=axis)
    if stated is not None and from_header is not None and stated != from_header:
        raise FidelityError(f"{table.path}: column {table.header[i]!r} is in {from_header}, "
                            f"but the {axis.replace('_', ' ')} was given as {stated}")
    return stated if stated is not None else from_header


def as_curve(c: Any, what: str) -> Curve:
    """A Curve from a Curve or an (x, y) pair (units unknown)."""
    if isinstance(c, Curve):
        return c
    try:
        x, y = c
    except (TypeError, ValueError):
        raise FidelityError(f"{what} must be a Curve or an (x, y) pair, got {type(c).__name__}") from None
    return Curve(x, y, name=what)
