"""Performance curves: the MTF and SiTF components f1, f2 of the fidelity (paper §1, eqs. 1-4).

A :class:`Curve` is a measured or derived characteristic curve (MTF against spatial
frequency, SiTF signal against temperature difference). This module holds

* the curve type and its CSV reader,
* MTF from a line spread function (LSF) or edge spread function (ESF),
* the "middle spatial frequency" :func:`mtf50` (paper Fig. 1),
* the curve similarity of the paper, eqs. (1)-(4): :func:`curve_similarity`,
  :func:`mtf_similarity`.

The slanted-edge MTF (ISO 12233 e-SFR) lives in :mod:`irfidelity.edge`, the SiTF
linear-portion fit, :func:`netd` and :func:`sitf_similarity` in :mod:`irfidelity.sitf`;
both are re-exported here. Everything is numpy; nothing here needs the Rust core.
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
    "mtf_from_lsf",
    "mtf_from_esf",
    "mtf50",
    "curve_similarity",
    "mtf_similarity",
    "cy_per_px_to_cy_per_mrad",
    "cy_per_mrad_to_cy_per_px",
    "similarity_mu",
    "feature_points",
    # re-exported from .edge / .sitf (bottom of this file)
    "mtf_from_edge",
    "EdgeWarning",
    "SiTFFit",
    "sitf_fit",
    "netd",
    "sitf_similarity",
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
def _window(kind: Any, n: int, center: float) -> np.ndarray:
    """Window of ``n`` samples whose symmetry centre is at sample position ``center``.

    ``kind``: None/"none", "hamming", "hann", "tukey" (alpha 0.5) or an array of n weights.
    The width is the full record, so the window reaches its minimum at ``center +- n/2``.
    """
    if kind is None or (isinstance(kind, str) and kind.lower() in ("none", "rect", "boxcar")):
        return np.ones(n)
    if not isinstance(kind, str):
        w = np.asarray(kind, dtype=np.float64)
        if w.shape != (n,) or not np.isfinite(w).all():
            raise FidelityError(f"window array must be finite with shape ({n},), got {w.shape}")
        return w
    t = (np.arange(n) - center) / n  # in [-1, 1]; |t| <= 1/2 inside the window
    inside = np.abs(t) <= 0.5
    k = kind.lower()
    if k == "hamming":
        w = 0.54 + 0.46 * np.cos(2 * np.pi * t)
    elif k in ("hann", "hanning"):
        w = 0.5 + 0.5 * np.cos(2 * np.pi * t)
    elif k == "tukey":
        a = 0.5
        u = np.abs(t) * 2  # 0 at centre, 1 at the edge of the window
        w = np.where(u <= 1 - a, 1.0, 0.5 * (1 + np.cos(np.pi * (u - 1 + a) / a)))
    else:
        raise FidelityError(f"window must be None, 'hamming', 'hann', 'tukey' or an array, got {kind!r}")
    return np.where(inside, w, 0.0)


def _centroid(v: np.ndarray) -> float:
    a = np.abs(v)
    s = a.sum()
    return float((a * np.arange(v.size)).sum() / s) if s > 0 else (v.size - 1) / 2


def _check_dx(dx: float) -> float:
    d = float(dx)
    if not (math.isfinite(d) and d > 0):
        raise FidelityError(f"dx must be finite and > 0, got {dx!r}")
    return d


def mtf_from_lsf(lsf: Any, *, dx: float = 1.0, pad: int | None = None, window: Any = None,
                 name: str | None = None, x_unit: str | None = None) -> Curve:
    """MTF as the normalised modulus of the DFT of a line spread function (paper §1.1).

    ``MTF(f_k) = |DFT(w·lsf)|_k / |DFT(w·lsf)|_0`` at ``f_k = k / (N·dx)``,
    ``k = 0 .. N//2`` (up to the Nyquist frequency ``1/(2 dx)``).

    Parameters
    ----------
    lsf : array_like
        1-D LSF samples (at least 3, finite) with spacing ``dx``.
    dx : float
        Sample spacing; frequencies come out in cycles per unit of ``dx``
        (``dx = 1`` -> cycles/pixel).
    pad : int, optional
        Zero-pad to this total length ``N`` (>= len(lsf)) for a finer frequency grid.
    window : None | "hamming" | "hann" | "tukey" | array
        Apodisation centred on the LSF centroid (ISO 12233 uses Hamming).

    Returns
    -------
    Curve
        ``x`` = frequency, ``y`` = MTF with ``y[0] == 1``; unit ``"cy/px"`` when
        ``dx == 1`` unless ``x_unit`` says otherwise.

    Raises
    ------
    FidelityError
        Non-finite samples, too few samples, or an LSF whose sum is zero (no
        zero-frequency response to normalise by).
    """
    v = np.asarray(lsf, dtype=np.float64)
    if v.ndim != 1 or v.size < 3:
        raise FidelityError(f"lsf must be 1-D with at least 3 samples, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise FidelityError(f"lsf has {int((~np.isfinite(v)).sum())} non-finite samples")
    d = _check_dx(dx)
    w = v * _window(window, v.size, _centroid(v))
    n = v.size if pad is None else int(pad)
    if n < v.size:
        raise FidelityError(f"pad must be >= len(lsf) = {v.size}, got {pad!r}")
    spec = np.abs(np.fft.rfft(w, n=n))
    if not spec[0] > 0:
        raise FidelityError("lsf sums to zero: the MTF cannot be normalised at zero frequency")
    f = np.arange(spec.size) / (n * d)
    if x_unit is None and d == 1.0:
        x_unit = CY_PX
    return Curve(f, spec / spec[0], name=name or "MTF", x_unit=x_unit)


def _diff_correction(f: np.ndarray, dx: float, cap: float) -> np.ndarray:
    """1 / |H(f)| of the two-tap derivative [1, -1]/dx, H = sinc(f·dx), capped at ``cap``."""
    h = np.abs(np.sinc(f * dx))
    with np.errstate(divide="ignore"):
        c = np.where(h > 0, 1.0 / np.maximum(h, 1e-300), np.inf)
    return np.minimum(c, cap)


def mtf_from_esf(esf: Any, *, dx: float = 1.0, pad: int | None = None, window: Any = None,
                 correct: bool = True, max_correction: float = 10.0, name: str | None = None,
                 x_unit: str | None = None) -> Curve:
    """MTF from an edge spread function: derivative -> LSF -> :func:`mtf_from_lsf`.

    The LSF is the first difference ``esf[i+1] - esf[i]`` (ISO 12233's two-tap
    derivative). Its transfer function ``sinc(f·dx)`` is divided out when
    ``correct`` is true, the correction factor capped at ``max_correction`` (it is at
    most pi/2 up to Nyquist, so the cap only matters for padded grids).

    Either edge polarity is accepted (a falling ESF gives the same MTF).

    Parameters
    ----------
    esf : array_like
        1-D ESF samples (at least 4) with spacing ``dx``.
    dx, pad, window, name, x_unit
        As in :func:`mtf_from_lsf` (``pad`` refers to the LSF length).
    correct : bool
        Divide out the derivative's transfer function.
    max_correction : float
        Upper bound of the correction factor (>= 1).
    """
    v = np.asarray(esf, dtype=np.float64)
    if v.ndim != 1 or v.size < 4:
        raise FidelityError(f"esf must be 1-D with at least 4 samples, got shape {v.shape}")
    cap = float(max_correction)
    if not (cap >= 1):
        raise FidelityError(f"max_correction must be >= 1, got {max_correction!r}")
    lsf = np.diff(v)
    if lsf.sum() < 0:
        lsf = -lsf
    c = mtf_from_lsf(lsf, dx=dx, pad=pad, window=window, name=name, x_unit=x_unit)
    if not correct:
        return c
    y = c.y * _diff_correction(c.x, _check_dx(dx), cap)
    return Curve(c.x, y, name=c.name, x_unit=c.x_unit)


# --------------------------------------------------------------------------- MTF50
def _smooth_poly(curve: Curve, degree: int = 6):
    """Least-squares polynomial of ``degree`` with p(0) = 1, in a Chebyshev basis on [0, x_max].

    Returns a callable. The constraint is built in: p(x) = 1 + (x/x_max)·q(x), q of
    degree ``degree - 1``.
    """
    x, y = curve.x, curve.y
    if x[0] < 0:
        raise FidelityError("smooth=True needs frequencies >= 0")
    if x.size < degree + 1:
        raise FidelityError(f"smooth=True fits a degree-{degree} polynomial and needs at least "
                            f"{degree + 1} points, the curve has {x.size}")
    xm = x[-1]
    t = 2 * x / xm - 1  # Chebyshev domain [-1, 1] for [0, x_max]
    u = x / xm
    basis = np.polynomial.chebyshev.chebvander(t, degree - 1) * u[:, None]
    coef, *_ = np.linalg.lstsq(basis, y - 1.0, rcond=None)

    def p(xq: np.ndarray) -> np.ndarray:
        xq = np.asarray(xq, dtype=np.float64)
        return 1.0 + (xq / xm) * np.polynomial.chebyshev.chebval(2 * xq / xm - 1, coef)

    return p


def mtf50(curve: Any, *, smooth: bool = False, level: float = 0.5) -> float:
    """The paper's "middle spatial frequency": where the MTF first falls to 0.5 (§1.1, Fig. 1).

    Found by linear interpolation between the last sample above ``level`` and the
    first at or below it. With ``smooth=True`` the paper's sixth-order polynomial
    fit is applied first (least squares in a Chebyshev basis on ``[0, f_max]``,
    constrained to MTF(0) = 1) and its first crossing is located on the curve's own
    frequency range (never extrapolated).

    Parameters
    ----------
    curve : Curve or (x, y)
        MTF normalised to 1 at zero frequency.
    smooth : bool
        Use the sixth-order polynomial fit.
    level : float
        Crossing level in (0, 1); 0.5 gives MTF50.

    Returns
    -------
    float
        Frequency in the curve's x unit.

    Raises
    ------
    FidelityError (a ValueError)
        If the MTF never falls to ``level`` within the curve's range, or is already
        below it at the first frequency. No frequency is invented.
    """
    c = _as_curve(curve, "MTF curve")
    lv = float(level)
    if not 0 < lv < 1:
        raise FidelityError(f"level must be in (0, 1), got {level!r}")
    x = c.x
    if smooth:
        p = _smooth_poly(c)
        xs = np.linspace(x[0], x[-1], max(4096, 8 * x.size))
        ys = p(xs)
        i = _first_crossing(xs, ys, lv, c)
        # refine by bisection on the polynomial (monotone bracket [xs[i-1], xs[i]])
        lo, hi = xs[i - 1], xs[i]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if p(mid) > lv:
                lo = mid
            else:
                hi = mid
        return float(0.5 * (lo + hi))
    y = c.y
    i = _first_crossing(x, y, lv, c)
    if i == 0:
        return float(x[0])
    x0, x1, y0, y1 = x[i - 1], x[i], y[i - 1], y[i]
    return float(x0 + (y0 - lv) * (x1 - x0) / (y0 - y1))


def _first_crossing(x: np.ndarray, y: np.ndarray, lv: float, c: Curve) -> int:
    below = y <= lv
    if not below.any():
        raise FidelityError(
            f"MTF never falls to {lv:g} within its range {x[0]:g}..{x[-1]:g} "
            f"(minimum {y.min():.4g}); the middle spatial frequency is undefined for this curve"
            + (f" ({c.name})" if c.name else ""))
    i = int(np.argmax(below))
    if i == 0 and y[0] < lv:
        raise FidelityError(f"MTF is already {y[0]:.4g} < {lv:g} at the first frequency {x[0]:g}; "
                            f"the crossing lies outside the curve's range")
    return i


# --------------------------------------------------------------------------- similarity
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


def mtf_similarity(real: Any, sim: Any, *, smooth: bool = False, points: Any = 64,
                   alpha: float = 1.0, beta: float = 1.0) -> CurveSimilarity:
    """Component f1: :func:`curve_similarity` of two MTF curves with ``a, b`` = their MTF50.

    The paper (§1.2) replaces the means of eq. (4) by each curve's middle spatial
    frequency (:func:`mtf50`, optionally on the sixth-order polynomial smoothing).

    Raises
    ------
    FidelityError
        If either MTF never falls to 0.5 (its MTF50 is undefined), or see
        :func:`curve_similarity`.
    """
    r_c, s_c = _as_curve(real, "real MTF"), _as_curve(sim, "simulated MTF")
    try:
        a = mtf50(r_c, smooth=smooth)
    except FidelityError as exc:
        raise FidelityError(f"real MTF: {exc}") from None
    try:
        b = mtf50(s_c, smooth=smooth)
    except FidelityError as exc:
        raise FidelityError(f"simulated MTF: {exc}") from None
    return curve_similarity(r_c, s_c, a=a, b=b, points=points, alpha=alpha, beta=beta)


# re-exports, resolved lazily (PEP 562) so that .edge and .sitf can import this module
_LAZY = {"mtf_from_edge": "edge", "EdgeWarning": "edge", "SiTFFit": "sitf", "sitf_fit": "sitf",
         "netd": "sitf", "sitf_similarity": "sitf"}


def __getattr__(name: str) -> Any:
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f".{mod}", __package__), name)


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
