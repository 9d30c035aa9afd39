"""Performance curves: the MTF and SiTF components f1, f2 of the fidelity (paper §1, eqs. 1-4).

A :class:`Curve` is a measured or derived characteristic curve (MTF against spatial
frequency, SiTF signal against temperature difference). This module holds

* the curve type, its CSV reader and unit conversions,
* the curve similarity of the paper, eqs. (1)-(4): :func:`curve_similarity`.

MTF from LSF/ESF, :func:`~irfidelity.mtf.mtf50` and :func:`~irfidelity.mtf.mtf_similarity`
live in :mod:`irfidelity.mtf`, the slanted-edge MTF (ISO 12233 e-SFR) in
:mod:`irfidelity.edge`, the SiTF linear-portion fit and :func:`~irfidelity.sitf.sitf_similarity`
in :mod:`irfidelity.sitf`; all build on this module. Everything is numpy.
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from .errors import FidelityError

__all__ = [
    "Curve",
    "CurveSimilarity",
    "curve_similarity",
    "cy_per_px_to_cy_per_mrad",
    "cy_per_mrad_to_cy_per_px",
    "similarity_mu",
    "feature_points",
]

#: canonical spellings of the spatial-frequency units
CY_PX = "cy/px"
CY_MRAD = "cy/mrad"
_UNIT_ALIASES = {
    "cy/px": CY_PX, "cycles/pixel": CY_PX, "cycles/px": CY_PX, "cy/pixel": CY_PX, "cpp": CY_PX,
    "cy/mrad": CY_MRAD, "cycles/mrad": CY_MRAD, "cycles/milliradian": CY_MRAD,
}


def _unit(u: str | None) -> str | None:
    if u is None:
        return None
    if not isinstance(u, str):
        raise FidelityError(f"x_unit must be a string or None, got {type(u).__name__}")
    return _UNIT_ALIASES.get(u.strip().lower(), u.strip())


# --------------------------------------------------------------------------- Curve
class Curve:
    """A sampled characteristic curve ``y(x)``.

    Parameters
    ----------
    x, y : array_like
        1-D, same length, at least 3 points, all finite; ``x`` strictly increasing.
        Stored as read-only float64 copies.
    name : str, optional
        Label used in messages and reports.
    x_unit : str, optional
        Unit of ``x``. ``"cy/px"`` (aliases ``"cycles/pixel"``) and ``"cy/mrad"``
        (``"cycles/mrad"``) are recognised and canonicalised; any other string (e.g.
        ``"K"`` for a SiTF abscissa) is kept as given.
    meta : mapping, optional
        Free-form provenance (e.g. the edge angle found by :func:`mtf_from_edge`).

    Raises
    ------
    FidelityError (a ValueError)
        Naming the rule broken: length, shape, finiteness or monotonicity.
    """

    __slots__ = ("x", "y", "name", "x_unit", "meta")

    def __init__(self, x: Any, y: Any, *, name: str | None = None, x_unit: str | None = None,
                 meta: Mapping[str, Any] | None = None) -> None:
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
        for arr, nm in ((xa, "x"), (ya, "y")):
            bad = ~np.isfinite(arr)
            if bad.any():
                i = int(np.argmax(bad))
                raise FidelityError(f"{label}: all values must be finite; {nm}[{i}] = {arr[i]} "
                                    f"({int(bad.sum())} non-finite)")
        dx = np.diff(xa)
        if not (dx > 0).all():
            i = int(np.argmax(dx <= 0))
            raise FidelityError(f"{label}: x must be strictly increasing; x[{i}] = {xa[i]!r} "
                                f">= x[{i + 1}] = {xa[i + 1]!r}")
        xa.flags.writeable = False
        ya.flags.writeable = False
        self.x = xa
        self.y = ya
        self.name = name
        self.x_unit = _unit(x_unit)
        self.meta = dict(meta) if meta else {}

    def __len__(self) -> int:
        return int(self.x.size)

    def __repr__(self) -> str:
        u = f", x_unit={self.x_unit!r}" if self.x_unit else ""
        n = f", name={self.name!r}" if self.name else ""
        return (f"Curve({self.x.size} points, x {self.x[0]:g}..{self.x[-1]:g}, "
                f"y {self.y.min():g}..{self.y.max():g}{n}{u})")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Curve):
            return NotImplemented
        return (np.array_equal(self.x, other.x) and np.array_equal(self.y, other.y)
                and self.x_unit == other.x_unit)

    __hash__ = None  # type: ignore[assignment]

    def __call__(self, xq: Any) -> np.ndarray:
        """Linear interpolation at ``xq``; raises if any point lies outside ``[x[0], x[-1]]``."""
        q = np.asarray(xq, dtype=np.float64)
        if not np.isfinite(q).all() or (q < self.x[0]).any() or (q > self.x[-1]).any():
            raise FidelityError(f"points must lie within the curve's x range "
                                f"[{self.x[0]:g}, {self.x[-1]:g}] (no extrapolation)")
        return np.interp(q, self.x, self.y)

    def with_unit(self, x_unit: str | None) -> "Curve":
        """The same samples labelled with another unit (no conversion)."""
        return Curve(self.x, self.y, name=self.name, x_unit=x_unit, meta=self.meta)

    def to_cy_per_mrad(self, ifov_mrad: float) -> "Curve":
        """Convert a frequency axis in cycles/pixel to cycles/mrad: ``f / IFOV[mrad]``.

        The curve must be in ``"cy/px"`` (or unlabelled, which is then taken as cy/px).
        """
        if self.x_unit not in (None, CY_PX):
            raise FidelityError(f"to_cy_per_mrad needs a curve in {CY_PX!r}, this one is in {self.x_unit!r}")
        return Curve(cy_per_px_to_cy_per_mrad(self.x, ifov_mrad), self.y, name=self.name,
                     x_unit=CY_MRAD, meta=self.meta)

    def to_cy_per_px(self, ifov_mrad: float) -> "Curve":
        """Convert a frequency axis in cycles/mrad to cycles/pixel: ``f * IFOV[mrad]``."""
        if self.x_unit not in (None, CY_MRAD):
            raise FidelityError(f"to_cy_per_px needs a curve in {CY_MRAD!r}, this one is in {self.x_unit!r}")
        return Curve(cy_per_mrad_to_cy_per_px(self.x, ifov_mrad), self.y, name=self.name,
                     x_unit=CY_PX, meta=self.meta)

    @classmethod
    def from_csv(cls, path: str | os.PathLike[str], *, columns: Sequence[int | str] | None = None,
                 name: str | None = None, x_unit: str | None = None) -> "Curve":
        """Read a curve from a text table.

        Comma-, semicolon-, tab- or whitespace-separated; blank lines and lines starting
        with ``#`` are skipped; the first remaining line may be a header (any
        non-numeric field makes it one).

        Parameters
        ----------
        path : path-like
        columns : (x, y), optional
            Column indices (0-based) or header names. Required when the table has more
            than two columns; by default the table must have exactly two.
        name, x_unit : str, optional
            Passed to :class:`Curve`; ``name`` defaults to the file name.

        Raises
        ------
        FidelityError
            Naming the file and line: unreadable file, ragged row, non-numeric value,
            missing column, or a curve rule (see :class:`Curve`).
        """
        p = os.fspath(path)
        try:
            with open(p, encoding="utf-8-sig") as fh:
                text = fh.read()
        except (OSError, UnicodeDecodeError) as exc:
            raise FidelityError(f"{p}: cannot read curve file ({exc})") from None
        rows: list[tuple[int, list[str]]] = []
        for lineno, line in enumerate(io.StringIO(text), start=1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            rows.append((lineno, _split_fields(s)))
        if not rows:
            raise FidelityError(f"{p}: no data rows")
        header: list[str] | None = None
        if not all(_is_number(f) for f in rows[0][1]):
            header = [h.strip() for h in rows[0][1]]
            rows = rows[1:]
            if not rows:
                raise FidelityError(f"{p}: header line but no data rows")
        ncol = len(header) if header is not None else len(rows[0][1])
        if columns is None:
            if ncol != 2:
                raise FidelityError(f"{p}: expected two columns (x, y), found {ncol}; "
                                    f"pass columns=(x, y) to choose")
            ix, iy = 0, 1
        else:
            if len(columns) != 2:
                raise FidelityError(f"{p}: columns must be a pair (x, y), got {columns!r}")
            ix, iy = (_col_index(c, header, ncol, p) for c in columns)
        xs, ys = [], []
        for lineno, fields in rows:
            if len(fields) != ncol:
                raise FidelityError(f"{p}:{lineno}: expected {ncol} fields, found {len(fields)}")
            try:
                xs.append(float(fields[ix]))
                ys.append(float(fields[iy]))
            except ValueError:
                bad = fields[ix] if not _is_number(fields[ix]) else fields[iy]
                raise FidelityError(f"{p}:{lineno}: not a number: {bad!r}") from None
        try:
            return cls(xs, ys, name=name if name is not None else os.path.basename(p), x_unit=x_unit)
        except FidelityError as exc:
            raise FidelityError(f"{p}: {exc}") from None


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


def _col_index(c: int | str, header: list[str] | None, ncol: int, p: str) -> int:
    if isinstance(c, str):
        if header is None or c not in header:
            raise FidelityError(f"{p}: no column named {c!r} (header: {header})")
        return header.index(c)
    i = int(c)
    if not -ncol <= i < ncol:
        raise FidelityError(f"{p}: column index {i} out of range for {ncol} columns")
    return i % ncol


def _ifov(ifov_mrad: float) -> float:
    v = float(ifov_mrad)
    if not (math.isfinite(v) and v > 0):
        raise FidelityError(f"ifov_mrad must be finite and > 0, got {ifov_mrad!r}")
    return v


def cy_per_px_to_cy_per_mrad(f: Any, ifov_mrad: float) -> np.ndarray:
    """cycles/pixel -> cycles/mrad: ``f / IFOV`` with the IFOV (one pixel's angle) in mrad."""
    return np.asarray(f, dtype=np.float64) / _ifov(ifov_mrad)


def cy_per_mrad_to_cy_per_px(f: Any, ifov_mrad: float) -> np.ndarray:
    """cycles/mrad -> cycles/pixel: ``f * IFOV`` with the IFOV in mrad."""
    return np.asarray(f, dtype=np.float64) * _ifov(ifov_mrad)


def _as_curve(c: Any, what: str) -> Curve:
    if isinstance(c, Curve):
        return c
    try:
        x, y = c
    except (TypeError, ValueError):
        raise FidelityError(f"{what} must be a Curve or an (x, y) pair, got {type(c).__name__}") from None
    return Curve(x, y, name=what)


# --------------------------------------------------------------------------- MTF
@dataclass(frozen=True)
class CurveSimilarity:
    """Result of :func:`curve_similarity` (paper eqs. 1-4).

    Attributes
    ----------
    value : float
        ``mu**alpha * |rho|**beta`` (eq. 3), in [0, 1].
    mu : float
        ``2|a||b| / (a² + b²)`` (eq. 4); 1 when ``|a| == |b|`` (also a = b = 0).
    rho : float
        Pearson correlation of the two curves at the feature points (eq. 2); 1 for
        two constant curves, 0 when exactly one is constant.
    ccc : float
        Lin's concordance correlation ``2 cov / (var_r + var_s + (mean_r - mean_s)²)``
        in [-1, 1]: unlike ``rho`` it penalises offset and scale, so it separates
        falling MTFs that ``rho`` rates as near-identical. 1 for two equal constants.
    area : float
        Normalised area between the curves, ``∫|r - s| / ∫(|r| + |s|)`` over the
        feature points (trapezoids), in [0, 1]; 0 = identical.
    a, b : float
        The characteristic values used in ``mu`` (real, simulated).
    points : numpy.ndarray
        The feature abscissae.
    """

    value: float
    mu: float
    rho: float
    ccc: float
    area: float
    a: float
    b: float
    points: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "mu": self.mu, "rho": self.rho, "ccc": self.ccc,
                "area": self.area, "a": self.a, "b": self.b, "points": self.points.tolist()}


def _finite(v: Any, what: str, *, nonneg: bool = False) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise FidelityError(f"{what} must be a number, got {v!r}") from None
    if not math.isfinite(f) or (nonneg and f < 0):
        raise FidelityError(f"{what} must be finite{' and >= 0' if nonneg else ''}, got {v!r}")
    return f


def similarity_mu(a: float, b: float) -> float:
    """Eq. (4): ``2|a||b| / (a² + b²)``, overflow-safe; a = b = 0 gives 1."""
    fa, fb = abs(_finite(a, "a")), abs(_finite(b, "b"))
    m = max(fa, fb)
    if m == 0:
        return 1.0
    fa, fb = fa / m, fb / m
    return float(min(1.0, 2 * fa * fb / (fa * fa + fb * fb)))


def _trapz(y: np.ndarray, x: np.ndarray) -> float:
    return float(np.sum((y[1:] + y[:-1]) * np.diff(x)) / 2)


def feature_points(real: Any, sim: Any, points: Any = 64) -> np.ndarray:
    """Feature abscissae over the overlap of both curves' x ranges (paper §1.2).

    ``points`` is a count (>= 2; uniform over the overlap, end points included) or an
    explicit array that must lie inside the overlap.
    """
    r, s = _as_curve(real, "real curve"), _as_curve(sim, "simulated curve")
    lo, hi = max(r.x[0], s.x[0]), min(r.x[-1], s.x[-1])
    if not lo < hi:
        raise FidelityError(f"the curves' x ranges do not overlap: real {r.x[0]:g}..{r.x[-1]:g}, "
                            f"simulated {s.x[0]:g}..{s.x[-1]:g}")
    if np.ndim(points) == 0:
        try:
            n = int(points)
        except (TypeError, ValueError):
            raise FidelityError(f"points must be an int or an array, got {points!r}") from None
        if n != points or n < 2:
            raise FidelityError(f"points must be an integer >= 2, got {points!r}")
        return np.linspace(lo, hi, n)
    p = np.asarray(points, dtype=np.float64).ravel()
    if p.size < 2 or not np.isfinite(p).all():
        raise FidelityError("explicit feature points must be at least 2 finite values")
    if p.min() < lo or p.max() > hi:
        raise FidelityError(f"feature points must lie within the overlap {lo:g}..{hi:g} of both curves "
                            f"(got {p.min():g}..{p.max():g}); curves are never extrapolated")
    return p


def curve_similarity(real: Any, sim: Any, *, a: float, b: float, points: Any = 64,
                     alpha: float = 1.0, beta: float = 1.0) -> CurveSimilarity:
    """Similarity of a measured and a simulated characteristic curve (paper eqs. 1-4).

    Both curves are sampled by linear interpolation at common feature points;
    ``rho`` is their Pearson correlation (eq. 2), ``mu = 2|a||b|/(a²+b²)`` (eq. 4) with
    the characteristic values ``a`` (real) and ``b`` (simulated), and the similarity
    is ``mu**alpha * |rho|**beta`` (eq. 3).

    Parameters
    ----------
    real, sim : Curve or (x, y)
        If both carry an ``x_unit`` the units must agree.
    a, b : float
        Characteristic values (MTF50 for MTF curves, linear slope for SiTF curves).
    points : int or array_like
        Number of feature points, uniform over the overlap of both x ranges, or the
        points themselves (inside the overlap).
    alpha, beta : float
        Exponents of eq. (3), >= 0 (the paper uses 1).

    Returns
    -------
    CurveSimilarity
        Never NaN: DESIGN §4 limits (two constant curves -> rho = 1, one -> 0;
        a = b = 0 -> mu = 1).

    Raises
    ------
    FidelityError (a ValueError)
        Disjoint x ranges, points outside the overlap, mismatched units, non-finite
        or negative parameters.
    """
    r_c, s_c = _as_curve(real, "real curve"), _as_curve(sim, "simulated curve")
    if r_c.x_unit and s_c.x_unit and r_c.x_unit != s_c.x_unit:
        raise FidelityError(f"curves have different x units: real {r_c.x_unit!r}, simulated "
                            f"{s_c.x_unit!r}; convert one (e.g. Curve.to_cy_per_mrad)")
    al = _finite(alpha, "alpha", nonneg=True)
    be = _finite(beta, "beta", nonneg=True)
    mu = similarity_mu(a, b)
    p = feature_points(r_c, s_c, points)
    r = np.interp(p, r_c.x, r_c.y)
    s = np.interp(p, s_c.x, s_c.y)
    rho, ccc = _correlations(r, s)
    denom = _trapz(np.abs(r) + np.abs(s), p)
    area = _trapz(np.abs(r - s), p) / denom if denom > 0 else 0.0
    value = (mu ** al) * (abs(rho) ** be)
    return CurveSimilarity(value=float(min(1.0, value)), mu=mu, rho=rho, ccc=ccc,
                           area=float(min(1.0, max(0.0, area))), a=float(a), b=float(b),
                           points=p)


def _correlations(r: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """Pearson rho (eq. 2) and Lin's CCC with the DESIGN §4 limits for constant curves."""
    r_const = bool(np.ptp(r) == 0)
    s_const = bool(np.ptp(s) == 0)
    if r_const and s_const:
        return 1.0, (1.0 if r[0] == s[0] else 0.0)
    if r_const or s_const:
        return 0.0, 0.0
    # scale to O(1) before forming moments (huge or tiny units stay finite)
    sc = max(np.abs(r).max(), np.abs(s).max())
    r, s = r / sc, s / sc
    dr, ds = r - r.mean(), s - s.mean()
    srr, sss, srs = float(dr @ dr), float(ds @ ds), float(dr @ ds)
    if srr == 0 or sss == 0:  # spread lost to rounding: treat as constant
        return 0.0, 0.0
    rho = max(-1.0, min(1.0, srs / math.sqrt(srr * sss)))
    n = r.size
    md = float(r.mean() - s.mean())
    ccc = 2 * srs / n / (srr / n + sss / n + md * md)
    return float(rho), float(max(-1.0, min(1.0, ccc)))
