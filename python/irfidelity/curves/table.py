"""Text tables of curve data: reading, choosing two columns, choosing the rows of one series.

Comma-, semicolon-, tab- or whitespace-separated; blank lines and lines starting with ``#``
are skipped; the first remaining line is a header when any of its fields is not a number.
:meth:`irfidelity.curves.Curve.from_csv` builds on this module; :func:`parse_columns` and
:func:`parse_where` turn command-line text into its ``columns`` and ``where`` arguments.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass
from typing import Mapping, Sequence

from ..errors import FidelityError

__all__ = ["Table", "read_table", "parse_columns", "parse_where"]


@dataclass(frozen=True)
class Table:
    """A text table as read: ``header`` (None without one) and ``rows`` of (line number, fields)."""

    path: str
    header: list[str] | None
    rows: list[tuple[int, list[str]]]

    @property
    def ncols(self) -> int:
        return len(self.header) if self.header is not None else len(self.rows[0][1])

    def describe_columns(self) -> str:
        if self.header is None:
            return f"{self.ncols} columns, no header"
        return f"{self.ncols} columns: {', '.join(self.header)}"

    def column(self, spec: int | str) -> int:
        """Index of a column given by header name or (0-based, negative from the end) index."""
        if isinstance(spec, str):
            if self.header is None or spec not in self.header:
                raise FidelityError(f"{self.path}: no column named {spec!r} ({self.describe_columns()})")
            return self.header.index(spec)
        try:
            i = int(spec)
        except (TypeError, ValueError):
            raise FidelityError(f"{self.path}: a column is a name or an index, got {spec!r}") from None
        if i != spec or not -self.ncols <= i < self.ncols:
            raise FidelityError(f"{self.path}: column index {spec!r} out of range ({self.describe_columns()})")
        return i % self.ncols

    def column_name(self, i: int) -> str:
        return self.header[i] if self.header is not None else f"column {i}"

    def numbers(self, i: int) -> list[float]:
        """Column ``i`` as floats; raises naming the file, line and field."""
        out = []
        for lineno, fields in self.rows:
            try:
                out.append(float(fields[i]))
            except ValueError:
                raise FidelityError(f"{self.path}:{lineno}: not a number: {fields[i]!r} "
                                    f"(column {self.column_name(i)})") from None
        return out

    def select_rows(self, where: Mapping[int | str, float]) -> Table:
        """The rows whose columns equal the given numbers (all conditions at once)."""
        rows = self.rows
        for spec, value in where.items():
            i = self.column(spec)
            try:
                target = float(value)
            except (TypeError, ValueError):
                raise FidelityError(f"{self.path}: the row filter on {self.column_name(i)} must be a "
                                    f"number, got {value!r}") from None
            kept = [(n, f) for n, f in rows if _is_number(f[i]) and float(f[i]) == target]
            if not kept:
                seen = sorted({f[i] for _, f in rows}, key=lambda t: (not _is_number(t), t))
                raise FidelityError(f"{self.path}: no row has {self.column_name(i)} = {target:g} "
                                    f"(values present: {', '.join(seen[:12])})")
            rows = kept
        return Table(self.path, self.header, rows)


def read_table(path: str | os.PathLike[str]) -> Table:
    """Read a text table; raises naming the file (and line) for unreadable or ragged files."""
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8-sig") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise FidelityError(f"{p}: cannot read curve file ({exc})") from None
    rows: list[tuple[int, list[str]]] = []
    for lineno, line in enumerate(io.StringIO(text), start=1):
        s = line.strip()
        if s and not s.startswith("#"):
            rows.append((lineno, _split_fields(s)))
    if not rows:
        raise FidelityError(f"{p}: no data rows")
    header = None
    if not all(_is_number(f) for f in rows[0][1]):
        header = [h.strip() for h in rows[0][1]]
        rows = rows[1:]
        if not rows:
            raise FidelityError(f"{p}: header line but no data rows")
    ncols = len(header) if header is not None else len(rows[0][1])
    for lineno, fields in rows:
        if len(fields) != ncols:
            raise FidelityError(f"{p}:{lineno}: expected {ncols} fields, found {len(fields)}")
    return Table(p, header, rows)


def _split_fields(s: str) -> list[str]:
    for sep in (",", ";", "\t"):
        if sep in s:
            return [f.strip() for f in next(csv.reader([s], delimiter=sep, skipinitialspace=True))]
    return s.split()


def _is_number(f: str) -> bool:
    try:
        float(f)
    except ValueError:
        return False
    return True


def parse_columns(text: str) -> tuple[int | str, int | str]:
    """``"x,y"`` (names or 0-based indices) as a ``columns`` pair.

    Examples
    --------
    >>> parse_columns("blackbody_temp_C,digital_level"), parse_columns("2, 3")
    (('blackbody_temp_C', 'digital_level'), (2, 3))
    """
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 2 or not all(parts):
        raise FidelityError(f"columns must be two names or indices separated by a comma, got {text!r}")
    return tuple(int(p) if p.lstrip("-").isdigit() else p for p in parts)  # type: ignore[return-value]


def parse_where(text: str) -> dict[int | str, float]:
    """``"name=value[,name=value]"`` as a ``where`` row filter.

    Examples
    --------
    >>> parse_where("instrument_temp_C=17.1")
    {'instrument_temp_C': 17.1}
    """
    out: dict[int | str, float] = {}
    for part in text.split(","):
        name, sep, value = part.partition("=")
        name = name.strip()
        if not sep or not name or not _is_number(value.strip()):
            raise FidelityError(f"a row filter is name=number (several separated by commas), got {text!r}")
        out[int(name) if name.lstrip("-").isdigit() else name] = float(value)
    return out


def pick_two(table: Table, columns: Sequence[int | str] | None) -> tuple[int, int]:
    """The (x, y) column indices: ``columns`` or, without it, the only two columns there are."""
    if columns is None:
        if table.ncols != 2:
            raise FidelityError(f"{table.path}: expected two columns (x, y), found {table.describe_columns()}; "
                                f"choose two by name or index")
        return 0, 1
    if isinstance(columns, (str, bytes)) or len(columns) != 2:
        raise FidelityError(f"{table.path}: columns must be a pair (x, y) of names or indices, got {columns!r}")
    return table.column(columns[0]), table.column(columns[1])


def series_hint(table: Table, ix: int, iy: int) -> str:
    """A row filter that picks the first series of a table whose x column restarts, or ''."""
    x = table.numbers(ix)
    end = next((k for k in range(1, len(x)) if x[k] <= x[k - 1]), len(x))
    for j in range(table.ncols):
        if j in (ix, iy):
            continue
        first = [f[j] for _, f in table.rows[:end]]
        rest = [f[j] for _, f in table.rows[end:]]
        if len(set(first)) == 1 and rest and first[0] not in rest[:1]:
            return f"{table.column_name(j)}={first[0]}"
    return ""
