"""Frame-pair statistics (docs/design.md §2): :func:`pair_stats` and :class:`PairStats`, the one
value every image metric is computed from, plus the array-level metric functions
:func:`mse`, :func:`psnr`, :func:`ssim` and :func:`nmi`.

The pass itself runs in Rust (``irfidelity._core``) with the GIL released: integer
frames are summed exactly, float frames with centred, compensated sums.
"""

from __future__ import annotations

import math
import numbers
import os
import reprlib
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from . import _core
from .errors import ConfigError, FidelityError, ShapeError
from .frames import FRAME_DTYPES
from .metrics import NMI, SSIM, check_exponents, nmi_from_entropies, psnr_from_mse, ssim_terms

__all__ = ["PairStats", "pair_stats", "merge_all", "mse", "psnr", "ssim", "nmi", "plan_need", "peak_and_valid", "hist_params",
           "bins_value"]

# dtype.name is slow (it formats a string); compare the type objects instead
_SUPPORTED_TYPES = frozenset(d.type for d in FRAME_DTYPES)

# What each metric needs from the pass (docs/design.md §2, "plan only what is needed").
_NEEDS = {
    "mse": {"sse"},
    "psnr": {"sse"},
    "ssim": {"moments"},
    "nmi": {"hist"},
    "sse": {"sse"},
    "moments": {"moments"},
    "hist": {"hist"},
}


def plan_need(need: Iterable[str] | None) -> set[str]:
    """Map metric names (``mse psnr ssim nmi``) to kernel outputs (``sse moments hist``)."""
    if need is None:
        return {"sse", "moments", "hist"}
    if isinstance(need, str):
        need = (need,)
    out: set[str] = set()
    for name in need:
        if name not in _NEEDS:
            raise FidelityError(f"need: unknown item {name!r}; expected some of {sorted(_NEEDS)}")
        out |= _NEEDS[name]
    return out


@dataclass(frozen=True, slots=True)
class PairRequest:
    """What one pass of the Rust kernel computes on a frame pair.

    The one list of the kernel's request fields: :func:`pair_stats`, the registered path
    (:func:`irfidelity.alignment.score_registered`) and the sequence engine
    (:class:`irfidelity.sequence.plan.SequenceRequest`) build it, ``irfidelity._core`` reads
    it attribute by attribute.

    Attributes
    ----------
    sse, moments : bool
        Compute the squared error (MSE, PSNR) and the moments (SSIM).
    bins : int or None
        Uniform histogram bins over ``hist_range`` (NMI); ``None``: no histogram.
    levels : bool
        One histogram bin per grey level (integer frames); overrides ``bins``.
    each : bool
        Each frame's bins over its own data range (``hist_range="each"``); overrides
        ``hist_range``.
    hist_range : (float, float) or None
        Explicit histogram edges; ``None``: the data's min..max over both frames.
    valid : (int, int) or None
        Integer frames: the allowed values ``[lo, hi]`` (from ``bits``); anything else is a
        :class:`~irfidelity.errors.RangeError`.
    mask_nonfinite : bool
        Float frames: exclude NaN/Inf pairs instead of raising.
    """

    sse: bool = True
    moments: bool = True
    bins: int | None = None
    levels: bool = False
    each: bool = False
    hist_range: tuple[float, float] | None = None
    valid: tuple[int, int] | None = None
    mask_nonfinite: bool = False


class _Summary(NamedTuple):
    """What the metrics read from the kernel's statistics, fetched in one call (each None
    when the pass did not compute it)."""

    mse: float | None
    moments: tuple[float, float, float, float, float] | None
    centred: tuple[float, float, float] | None
    entropies: tuple[float, float, float] | None


class PairStats:
    """Sufficient statistics of a (real, simulated) frame pair.

    Holds the pixel count, exact (integer frames) or centred (float frames) sums and the
    joint grey-level histogram; every image metric is a function of it. Mergeable
    (``a.merge(b)`` equals the statistics of the union of both pixel sets, exactly for
    integer frames) and picklable, so tiles, frames of a sequence and Dask workers
    combine through it.

    Attributes
    ----------
    n : int
        Pixel pairs counted (after ``mask`` and ``nonfinite="mask"``).
    masked, nonfinite : int
        Pairs excluded by the mask, and as NaN/Inf.
    peak : float or None
        Peak used by :meth:`psnr` (``2**bits - 1``, the given ``peak``, or the integer
        dtype's range).
    bins : int, "levels" or None
        The histogram's binning, if one was computed.
    level_origin : int or None
        Integer frames: the grey level of the kernel's level key 0 (the dtype's minimum),
        which places a ``"levels"`` histogram's edges; None when unknown.
    """

    __slots__ = ("_raw", "peak", "bins", "level_origin", "_fetched")

    def __init__(
        self, raw: _core.PairStats, *, peak: float | None = None, bins: object = None, level_origin: int | None = None
    ):
        self._raw = raw
        self.peak = peak
        self.bins = bins
        self.level_origin = level_origin
        self._fetched: _Summary | None = None

    def _summary(self) -> _Summary:
        """MSE, moments, centred sums and entropies, from one call into the kernel's object."""
        if self._fetched is None:
            self._fetched = _Summary(*self._raw.summary())
        return self._fetched

    # -- counts -------------------------------------------------------------------
    @property
    def n(self) -> int:
        return self._raw.n

    @property
    def masked(self) -> int:
        return self._raw.masked

    @property
    def nonfinite(self) -> int:
        return self._raw.nonfinite

    def _nonempty(self) -> None:
        if self._raw.n == 0:
            raise FidelityError("no pixel pairs were counted (everything masked or non-finite)")

    def _missing(self, what: str, metric: str) -> FidelityError:
        return FidelityError(f"these statistics were computed without {what}; ask for {metric!r} in need",
                             option="need")

    # -- metrics ------------------------------------------------------------------
    def mse(self) -> float:
        """Mean squared error ``E[(S − R)²]`` (eq. 5's denominator)."""
        self._nonempty()
        value = self._summary().mse
        if value is None:
            raise self._missing("the squared error", "mse")
        return value

    def psnr(self, peak: float | None = None) -> float:
        """PSNR in dB (eq. 5), ``+inf`` when MSE == 0. ``peak`` overrides the stored peak."""
        peak = self.peak if peak is None else float(peak)
        if peak is None:
            raise FidelityError("PSNR of float frames needs a peak (the largest possible value)", option="peak")
        return psnr_from_mse(self.mse(), peak)

    def ssim(
        self,
        alpha: float = 1.0,
        beta: float = 1.0,
        gamma: float = 1.0,
        *,
        c1: float = 0.0,
        c2: float = 0.0,
        c3: float | None = None,
    ) -> SSIM:
        """Global SSIM ``l^α·c^β·s^γ`` (eqs. 11–14) with the limits of docs/design.md §4."""
        check_exponents(alpha, beta, gamma)
        return SSIM(*self.ssim_terms(alpha, beta, gamma, c1=c1, c2=c2, c3=c3))

    def ssim_terms(self, alpha: float, beta: float, gamma: float, *, c1: float = 0.0, c2: float = 0.0,
                   c3: float | None = None) -> tuple[float, float, float, float]:
        """:meth:`ssim` as ``(value, luminance, contrast, structure)``, the exponents taken as
        checked (a :class:`~irfidelity.ScoringConfig` checks them once)."""
        self._nonempty()
        summary = self._summary()
        if summary.moments is None or summary.centred is None:
            raise self._missing("moments", "ssim")
        mean_r, mean_s, var_r, var_s, cov = summary.moments
        if c1 == 0 and c2 == 0 and c3 in (None, 0):
            # Exact-integer route: c and s are ratios of the centred numerators, N cancels.
            d_r, d_s, d_rs = summary.centred
            var_r, var_s, cov = d_r, d_s, d_rs
        return ssim_terms(mean_r, mean_s, var_r, var_s, cov, alpha, beta, gamma, c1, c2, c3)

    def nmi(self) -> NMI:
        """Normalised mutual information (eqs. 7–10) from the joint histogram."""
        self._nonempty()
        ent = self._summary().entropies
        if ent is None:
            raise self._missing("a histogram", "nmi")
        return nmi_from_entropies(*ent, bins=self.bins)

    def int_sums(self) -> dict[str, int] | None:
        """The exact integer sums of integer frames, as Python ints; ``None`` for float frames.

        Keys: ``sum_real`` Σx, ``sum_sim`` Σy, ``sum_real_sq`` Σx², ``sum_sim_sq`` Σy²,
        ``sum_cross`` Σxy and ``sse`` Σ(x − y)², over the ``n`` counted pixel pairs. Every
        integer-frame metric is a function of these and ``n``, rounded once at the end, so
        they are an exact reference (they do not depend on threads, layout or merging).
        Sums the pass did not compute (see ``need``) are 0.

        Examples
        --------
        >>> import numpy as np, irfidelity as irf
        >>> r = np.array([[1, 2], [3, 4]], dtype=np.uint16)
        >>> irf.pair_stats(r, r + 1).int_sums()["sse"]
        4
        """
        return self._raw.int_sums()

    def joint_histogram(self, *, max_cells: int = 1 << 24) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The joint grey-level histogram behind NMI: ``(counts, real_edges, sim_edges)``.

        ``counts[i, j]`` (int64, ``counts.sum() == n``) counts the pixel pairs whose real value
        lies in ``[real_edges[i], real_edges[i + 1])`` and simulated value in
        ``[sim_edges[j], sim_edges[j + 1])``. The edges are those of :func:`pair_stats`'s
        binning: ``bins=B`` gives ``B × B`` counts and the edges ``lo + i·width`` (shared, or
        each frame's own with ``hist_range="each"``)
        (integer frames: a bin is ``width`` whole grey levels; float frames: the last bin also
        holds the top of the range; values outside an explicit ``hist_range`` are counted in
        the edge bins). ``bins="levels"`` gives one row per real grey level and one column per
        simulated level over the span each frame occupies, edges ``v, v + 1``.

        A table of more than ``max_cells`` counts is a :class:`FidelityError` (use fewer bins).
        The entropies of eqs. 7–8 are those of ``counts.sum(1)``, ``counts.sum(0)`` and ``counts``
        (each divided by ``n``).

        Examples
        --------
        >>> import numpy as np, irfidelity as irf
        >>> real = np.array([[0, 1], [2, 3]], dtype=np.uint8)
        >>> counts, real_edges, sim_edges = irf.pair_stats(real, 3 - real, bins="levels").joint_histogram()
        >>> counts
        array([[0, 0, 0, 1],
               [0, 0, 1, 0],
               [0, 1, 0, 0],
               [1, 0, 0, 0]])
        >>> real_edges
        array([0., 1., 2., 3., 4.])

        References
        ----------
        .. [1] Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547, eqs. 7–10.
        """
        self._nonempty()
        spec = self._raw.hist_spec()
        if spec is None:
            raise self._missing("a histogram", "nmi")
        if isinstance(max_cells, bool) or not isinstance(max_cells, (int, np.integer)) or max_cells < 1:
            raise FidelityError(f"max_cells must be a positive integer, got {max_cells!r}")
        if spec[0] == "levels" and self.level_origin is None:
            raise FidelityError("the grey level of these 'levels' statistics' first key is unknown (level_origin)")
        table = self._raw.joint_histogram(int(max_cells))
        assert table is not None  # None only without a histogram (spec None, refused above)
        counts, real_first, sim_first = table
        if spec[0] == "levels":
            assert self.level_origin is not None  # refused above
            real_edges = float(self.level_origin + real_first) + np.arange(counts.shape[0] + 1, dtype=np.float64)
            sim_edges = float(self.level_origin + sim_first) + np.arange(counts.shape[1] + 1, dtype=np.float64)
        elif spec[0] == "each":
            _, nbins, real_lo, real_width, sim_lo, sim_width = spec
            steps = np.arange(nbins + 1, dtype=np.float64)
            real_edges, sim_edges = real_lo + real_width * steps, sim_lo + sim_width * steps
        else:
            _, nbins, lo, width = spec
            real_edges = lo + width * np.arange(nbins + 1, dtype=np.float64)
            sim_edges = real_edges.copy()
        return counts, real_edges, sim_edges

    def moments(self) -> dict:
        """Population means, variances and covariance."""
        self._nonempty()
        m = self._summary().moments
        if m is None:
            raise self._missing("moments", "ssim")
        return dict(zip(("mean_real", "mean_sim", "var_real", "var_sim", "cov"), m))

    def metrics(self) -> dict:
        """Every metric these statistics support, as a flat JSON-ready dict."""
        out: dict = {"n": self.n}
        if self._raw.n == 0:
            return out
        if self._raw.has_sse:
            out["mse"] = self.mse()
            if self.peak is not None:
                out["psnr_db"] = self.psnr()
        if self._raw.has_moments:
            s = self.ssim()
            out.update(ssim=s.value, ssim_luminance=s.luminance, ssim_contrast=s.contrast, ssim_structure=s.structure)
        if self._raw.has_hist:
            v = self.nmi()
            out.update(nmi=v.value, h_real=v.h_real, h_sim=v.h_sim, h_joint=v.h_joint, mi=v.mi)
        return out

    def with_peak(self, peak: float | None) -> PairStats:
        """The same statistics with another PSNR peak (nothing is recomputed)."""
        out = PairStats(self._raw, peak=None if peak is None else float(peak), bins=self.bins,
                        level_origin=self.level_origin)
        out._fetched = self._fetched
        return out

    # -- combining ----------------------------------------------------------------
    def to_bytes(self) -> bytes:
        """The statistics as bytes (peak and binning not included); see :meth:`from_bytes`."""
        return self._raw.to_bytes()

    @classmethod
    def from_bytes(cls, data: bytes, *, peak: float | None = None, bins: object = None,
                   level_origin: int | None = None) -> PairStats:
        """Statistics from :meth:`to_bytes` (a FidelityError for damaged bytes)."""
        return cls(_core.PairStats.from_bytes(data), peak=peak, bins=bins, level_origin=level_origin)

    def merge(self, other: PairStats) -> PairStats:
        """Statistics of the union of both pixel sets (exact for integer frames)."""
        if not isinstance(other, PairStats):
            raise TypeError(f"can only merge PairStats, not {type(other).__name__}")
        if self.peak != other.peak:
            raise FidelityError(f"cannot merge statistics with different peaks ({self.peak} vs {other.peak})")
        origin = self.level_origin if self.level_origin == other.level_origin else None
        return PairStats(self._raw.merge(other._raw), peak=self.peak, bins=self.bins, level_origin=origin)

    def __reduce__(self):
        return (_restore, (self._raw.to_bytes(), self.peak, self.bins, self.level_origin))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PairStats):
            return NotImplemented
        return (self._raw.to_bytes(), self.peak, self.bins) == (other._raw.to_bytes(), other.peak, other.bins)

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        parts = [f"n={self.n}"]
        if self._raw.n:
            parts += [f"{k}={v:.6g}" for k, v in self.metrics().items() if k != "n"]
        return f"PairStats({', '.join(parts)})"


def merge_all(stats: list[PairStats], *, histograms: bool = True) -> PairStats | None:
    """Statistics of the union of every pixel set in ``stats`` (None for an empty list), merged
    in list order. Histograms are merged when ``histograms`` and every item has one on the same
    edges, and left out otherwise."""
    if not stats:
        return None
    merged, _ = _core.merge_all([item._raw for item in stats], keep_hist=histograms)
    assert merged is not None  # None only for an empty list
    first = stats[0]
    return PairStats(merged, peak=first.peak, bins=first.bins if merged.has_hist else None,
                     level_origin=first.level_origin)


def _restore(data: bytes, peak, bins, level_origin=None) -> PairStats:
    return PairStats(_core.PairStats.from_bytes(data), peak=peak, bins=bins, level_origin=level_origin)


def _as_frame(x, name: str) -> np.ndarray:
    if isinstance(x, (str, os.PathLike)):
        from .frames import load_frame  # only when a path is given

        x = load_frame(x)
    arr = np.asarray(x)
    if arr.ndim != 2:
        raise ShapeError(f"{name}: expected a 2-D frame, got shape {arr.shape}")
    if arr.dtype.type not in _SUPPORTED_TYPES:
        raise ShapeError(f"{name}: unsupported dtype {arr.dtype}; expected one of {', '.join(_core.SUPPORTED_DTYPES)}")
    if not arr.dtype.isnative:
        arr = arr.astype(arr.dtype.newbyteorder("="))
    return arr


def _frame_pair(real, sim) -> tuple[np.ndarray, np.ndarray]:
    """``real`` and ``sim`` as 2-D frames of one dtype (else a ShapeError); the Rust call they
    are given to checks that they have one shape (``_core``'s one check of a pair's shapes)."""
    r = _as_frame(real, "real")
    s = _as_frame(sim, "sim")
    if r.dtype != s.dtype:
        raise ShapeError(
            f"real and sim frames differ in dtype: {r.dtype} vs {s.dtype}; convert one explicitly "
            "(e.g. sim.astype(real.dtype)) so no silent rounding happens"
        )
    return r, s


def peak_and_valid(dtype: np.dtype, bits, peak):
    """The PSNR peak and (for integer frames) the allowed value range.

    ``bits`` bounds integer values to ``[0, 2**bits - 1]`` and makes ``2**bits - 1`` the
    default peak; a numeric ``peak`` sets the peak, with or without ``bits``.
    """
    is_int = dtype.kind in "ui"
    top = valid = None
    if bits is not None:
        if not is_int:
            raise FidelityError("a bit depth applies to integer frames; give a peak for float frames", option="bits")
        width = dtype.itemsize * 8
        if not (isinstance(bits, (int, np.integer)) and 1 <= bits <= width):
            raise FidelityError(f"bits must be an integer in 1..{width} for {dtype} frames, got {bits!r}",
                                option="bits")
        top = (1 << int(bits)) - 1
        valid = (0, top)
    if peak is not None:
        return _numeric_peak(peak), valid
    if top is not None:
        return float(top), valid
    if is_int:
        info = np.iinfo(dtype)
        # unsigned: the dtype's maximum; signed: its full range (as scikit-image does)
        return float(info.max - min(info.min, 0)), None
    return None, None


def _numeric_peak(peak: Any) -> float:
    """``peak`` as a positive finite float, or a :class:`FidelityError` naming what was given."""
    try:
        value = float(peak) if not isinstance(peak, (str, bytes, bool)) else math.nan
    except (TypeError, ValueError):
        value = math.nan
    if not (value > 0 and math.isfinite(value)):
        hint = ("; peak='range' (the real frame's range over the scored pixels) is for irfidelity.stats.psnr, "
                "evaluate and ScoringConfig: here give the number") if isinstance(peak, str) and peak == "range" else ""
        raise FidelityError(f"peak must be a positive finite number, got {peak!r}{hint}", option="peak")
    return value


def full_range(dtype: np.dtype, bits: int | None, peak: float | None) -> tuple[float, float] | None:
    """The edges of ``hist_range="full"``: ``0..2**bits - 1`` (the values' range, also when a
    peak is given), else ``0..peak``; an integer dtype's whole range (from 0 for unsigned
    dtypes) when neither is given; None for float frames without a peak. ``bits`` and
    ``peak`` are those :func:`peak_and_valid` checked."""
    if bits is not None:
        return 0.0, float((1 << int(bits)) - 1)
    if peak is not None:
        return 0.0, float(peak)
    if dtype.kind in "ui":
        info = np.iinfo(dtype)
        return float(min(info.min, 0)), float(info.max)
    return None


def bins_value(bins: Any) -> int | str:
    """``bins`` checked: an integer in ``1.._core.MAX_HIST_BINS`` or ``"levels"``, else a
    :class:`~irfidelity.errors.ConfigError` naming ``bins``. The one check of ``bins``:
    :class:`~irfidelity.ScoringConfig`, :func:`pair_stats` (and the metrics on it) and the
    command line's ``--bins`` make it."""
    if isinstance(bins, str) and bins == "levels":
        return bins
    if isinstance(bins, numbers.Integral) and not isinstance(bins, bool) and 1 <= int(bins) <= _core.MAX_HIST_BINS:
        return int(bins)
    raise ConfigError("bins", f"expected an integer in 1..{_core.MAX_HIST_BINS} or 'levels'; got {reprlib.repr(bins)}")


#: The named histogram ranges: "each" (each frame's bins over its own robust range, the
#: simulated frame's carried by the gain and offset between the frames), "data" (min..max over
#: both frames, shared edges: the paper's) and "full" (0..peak, shared); else an explicit (lo, hi).
HIST_RANGES = ("each", "data", "full")

#: The default: a gain, an offset or a few extreme pixels do not move NMI (docs/design.md).
DEFAULT_HIST_RANGE = "each"


class HistParams(NamedTuple):
    """The kernel's histogram request: ``bins`` uniform bins (None with ``levels``), one bin per
    grey level, each frame's own range, or the shared explicit ``range`` (None: the data's)."""

    bins: int | None
    levels: bool
    each: bool
    range: tuple[float, float] | None


def hist_params(bins, hist_range, dtype: np.dtype, full: tuple[float, float] | None) -> HistParams:
    """The kernel's :class:`HistParams` from ``bins``/``hist_range`` (see :func:`pair_stats`);
    ``full`` is :func:`full_range`. Shared with the sequence engine, so both bin frames alike."""
    bins = bins_value(bins)
    levels = bins == "levels"
    nbins = None if levels else int(bins)
    if levels and dtype.kind not in "ui":
        raise FidelityError("the 'levels' binning needs integer frames; give a number of bins for float frames",
                            option="bins")
    wrong = f"hist_range must be one of {', '.join(map(repr, HIST_RANGES))} or (lo, hi), got {hist_range!r}"
    rng = None
    if isinstance(hist_range, str):
        if hist_range not in HIST_RANGES:
            raise FidelityError(wrong, option="hist_range")
        if hist_range == "full":
            if full is None:
                raise FidelityError("the 'full' histogram range of float frames needs a peak", option="hist_range")
            rng = full
    else:
        try:
            lo, hi = (float(v) for v in hist_range)
        except (TypeError, ValueError) as exc:
            raise FidelityError(wrong, option="hist_range") from exc
        rng = (lo, hi)
    return HistParams(nbins, levels, hist_range == "each" and not levels, rng)


def pair_stats(
    real,
    sim,
    *,
    bits: int | None = None,
    peak: float | None = None,
    bins: int | str = 256,
    hist_range=DEFAULT_HIST_RANGE,
    mask=None,
    need: Iterable[str] | None = None,
    nonfinite: str = "raise",
) -> PairStats:
    """Sufficient statistics of a frame pair, in one pass (Rust, GIL released).

    Parameters
    ----------
    real, sim : 2-D arrays or paths
        Real and simulated frames, same shape and dtype (uint8, uint16, int16, uint32,
        float16, float32, float64), any memory layout.
    bits : int, optional
        Integer frames: values must lie in ``[0, 2**bits − 1]`` (else :class:`RangeError`
        naming the value and position) and the PSNR peak is ``2**bits − 1`` (eq. 5).
    peak : float, optional
        The PSNR peak; required for PSNR of float frames. Default for integer frames:
        the dtype's maximum (unsigned) or range (signed).
    bins : int or "levels"
        Histogram bins for NMI. An int gives uniform bins over ``hist_range``; for integer
        frames each bin is a whole number of grey levels (width ``ceil(span/bins)``), so a
        pair spanning at most ``bins`` levels is binned exactly. ``"levels"``: every grey
        level its own bin (integer frames).
    hist_range : "each" (default), "data", "full" or (lo, hi)
        ``"each"``: the real frame's bins over its own range, set by its bulk — its min..max
        cut to the 0.1 %..99.9 % quantiles of a sample of (at most 16,384) counted pixels, in
        evenly spaced runs of 16, widened by that span on each side — and the simulated
        frame's over that range carried over by the map between the two frames' bulks (a gain
        and an offset from quantiles); each bin ``(hi − lo) / bins`` wide, integer frames too.
        A gain or offset between the frames then moves the bins with the levels, and a few
        extreme pixels do not stretch them; values outside the range are counted in the edge
        bins. ``"data"`` (the paper's): min..max over both frames; ``"full"``: 0..peak; or
        explicit edges: both frames share these edges. Use "full" or explicit edges to merge
        histograms of different frames.
    mask : 2-D bool array, optional
        ``False`` excludes a pixel pair.
    need : iterable of {"mse", "psnr", "ssim", "nmi"}, optional
        Compute only what these metrics need (default: all).
    nonfinite : "raise" or "mask"
        NaN/Inf in float frames: a :class:`RangeError` with counts and the first position,
        or exclude those pairs (counted in ``PairStats.nonfinite``).

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> real = np.array([[100, 200], [300, 400]], dtype=np.uint16)
    >>> sim = np.array([[101, 199], [302, 400]], dtype=np.uint16)
    >>> st = irf.pair_stats(real, sim, bits=14)
    >>> st.n, st.mse(), round(st.psnr(), 2), st.nmi().value
    (4, 1.5, 82.53, 1.0)

    Statistics merge: those of two frames are the statistics of their union (histograms on
    shared edges, such as ``"full"``'s, merge too).

    >>> full = irf.pair_stats(real, sim, bits=14, hist_range="full")
    >>> both = full.merge(irf.pair_stats(real, real, bits=14, hist_range="full"))
    >>> both.mse(), both.n                                      # (6 + 0) / 8
    (0.75, 8)
    """
    r, s = _frame_pair(real, sim)
    if nonfinite not in ("raise", "mask"):
        raise FidelityError(f"nonfinite must be 'raise' or 'mask', got {nonfinite!r}")
    pk, valid = peak_and_valid(r.dtype, bits, peak)
    request, binning = kernel_request(need, r.dtype, bins=bins, hist_range=hist_range,
                                      full=full_range(r.dtype, bits, peak), nonfinite=nonfinite, valid=valid)
    m = None
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != r.shape:
            raise ShapeError(f"mask: shape {m.shape} differs from the frames' {r.shape}")
        if m.dtype != np.bool_:
            raise ShapeError(f"mask: expected a bool array, got dtype {m.dtype}")
    # the kernel reads the frames in place when it can (any shared contiguous layout)
    raw = _core.pair_stats(r, s, request, m)
    return PairStats(raw, peak=pk, bins=binning, level_origin=int(np.iinfo(r.dtype).min) if r.dtype.kind in "ui" else None)


def kernel_request(need: Iterable[str] | None, dtype: np.dtype, *, bins: int | str, hist_range: Any,
                   full: tuple[float, float] | None, nonfinite: str,
                   valid: tuple[int, int] | None) -> tuple[PairRequest, int | str | None]:
    """The kernel's request for the metrics ``need`` on frames of ``dtype`` scored as
    :func:`pair_stats` does (``full``: :func:`full_range`; ``valid``: the allowed integer
    levels of the frames given, from :func:`peak_and_valid`), and the histogram's binning as
    :class:`PairStats` records it."""
    wanted = plan_need(need)
    hist = HistParams(None, False, False, None)
    if "hist" in wanted:
        hist = hist_params(bins, hist_range, dtype, full)
    request = PairRequest(sse="sse" in wanted, moments="moments" in wanted, bins=hist.bins, levels=hist.levels,
                          each=hist.each, hist_range=hist.range, valid=valid, mask_nonfinite=nonfinite == "mask")
    return request, (("levels" if hist.levels else hist.bins) if "hist" in wanted else None)


# Default PSNR peak per integer dtype (see peak_and_valid), for the single-metric fast path.
_DEFAULT_PEAK: dict[object, float] = {np.dtype(t): peak_and_valid(np.dtype(t), None, None)[0]
                                      for t in (np.uint8, np.uint16, np.int16, np.uint32)}


def mse(real, sim, *, mask=None) -> float:
    """Mean squared error of two frames, exact for integer frames.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> real = np.array([[100, 200], [300, 400]], dtype=np.uint16)
    >>> sim = np.array([[101, 199], [302, 400]], dtype=np.uint16)
    >>> irf.stats.mse(real, sim)                  # (1 + 1 + 4 + 0) / 4
    1.5
    """
    if mask is None:
        # plain 2-D C-contiguous arrays of one dtype: straight to the kernel (None otherwise)
        value = _core.plain_mse(real, sim)
        if value is not None:
            return value
    return pair_stats(real, sim, need=("mse",), mask=mask).mse()


def psnr(real, sim, *, bits: int | None = None, peak: float | str | None = None, mask=None) -> float:
    """PSNR in dB (paper eq. 5), ``10·log10(peak²/MSE)``; ``+inf`` for identical frames.

    ``peak``: a number; ``"range"``, the real frame's ``max − min`` over the counted pixels
    (those of ``mask``), as :func:`irfidelity.evaluate` with ``peak="range"``; default
    ``2**bits − 1`` when ``bits`` is given (which also bounds integer values to
    ``[0, 2**bits − 1]``), else the integer dtype's maximum. Float frames need ``peak``.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> real = np.array([[100, 200], [300, 400]], dtype=np.uint16)
    >>> sim = np.array([[101, 199], [302, 400]], dtype=np.uint16)
    >>> round(irf.stats.psnr(real, sim, bits=14), 2)     # 10·log10(16383² / 1.5)
    82.53
    >>> round(irf.stats.psnr(real, sim, peak=300), 2)    # against the scene's range, 400 − 100
    47.78
    >>> irf.stats.psnr(real, real, bits=14)
    inf
    >>> real = np.array([[100, 110], [120, 130]], dtype=np.uint16)
    >>> round(irf.stats.psnr(real, real + 3, peak="range"), 4)   # 10·log10(30² / 3²)
    20.0
    >>> round(irf.stats.psnr(real, real + 3, bits=12, peak=100), 4)
    30.4576
    """
    if isinstance(peak, str):
        return _psnr_over_range(real, sim, bits, peak, mask)
    if mask is None and bits is None:
        pk = _DEFAULT_PEAK.get(getattr(real, "dtype", None)) if peak is None else peak
        if pk is not None:
            value = _core.plain_mse(real, sim)
            if value is not None:
                return psnr_from_mse(value, float(pk))
    return pair_stats(real, sim, bits=bits, peak=peak, need=("psnr",), mask=mask).psnr()


def _psnr_over_range(real, sim, bits, rule: str, mask) -> float:
    """PSNR with the peak ``"range"``: the real frame's max − min over the counted pixels."""
    if rule != "range":
        raise FidelityError(f"peak must be a positive number or 'range', got {rule!r}", option="peak")
    r, s = _frame_pair(real, sim)
    st = pair_stats(r, s, bits=bits, need=("psnr",), mask=mask)  # checks the values, the mask, NaN/Inf
    span = real_range(r, mask, "raise") or 0.0
    if not span > 0:
        raise FidelityError("the PSNR peak 'range' needs a real frame with more than one value over the counted "
                            f"pixels (its range is {span:g})", option="peak")
    return st.psnr(span)


def real_range(real: np.ndarray, mask: Any, nonfinite: str, stats: PairStats | None = None) -> float | None:
    """``max − min`` of the real frame over the pixels that are scored (finite, unmasked): the
    PSNR peak ``"range"``; None when no pixel is scored, or when a scored pixel is NaN or
    infinite and ``nonfinite`` is not ``"mask"`` (the kernel reports those with their
    position). One Rust pass (``_core.scored_range``); a frame that is not C-contiguous is
    copied. ``stats``: this frame's statistics over the same pixels, whose scan may have found
    the range already (float frames without a mask, every value finite)."""
    known = None if stats is None else stats._raw.real_range
    if known is not None:
        return known[1] - known[0]
    values = np.ascontiguousarray(real)
    where = None if mask is None else np.ascontiguousarray(mask, dtype=bool)
    extent, nonfinite_scored = _core.scored_range(values, where)
    if extent is None or (nonfinite_scored and nonfinite != "mask"):
        return None
    return extent[1] - extent[0]


def ssim(real, sim, *, alpha: float = 1.0, beta: float = 1.0, gamma: float = 1.0, mask=None, nonfinite="raise") -> SSIM:
    """Global (whole-image) SSIM, eqs. 11–14, no stabilising constants (the paper's form).

    Returns an :class:`SSIM` with ``.value .luminance .contrast .structure``.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> real = np.array([[100, 200], [300, 400]], dtype=np.uint16)
    >>> sim = np.array([[101, 199], [302, 400]], dtype=np.uint16)
    >>> s = irf.stats.ssim(real, sim)
    >>> round(s.value, 5), round(s.luminance, 5), round(s.contrast, 5), round(s.structure, 5)
    (0.99995, 1.0, 1.0, 0.99995)
    """
    if mask is None and nonfinite == "raise":
        # plain 2-D C-contiguous arrays of one dtype: straight to the kernel (None otherwise)
        raw = _core.plain_moments(real, sim)
        if raw is not None:
            return PairStats(raw).ssim(alpha, beta, gamma)
    st = pair_stats(real, sim, need=("ssim",), mask=mask, nonfinite=nonfinite)
    return st.ssim(alpha, beta, gamma)


def nmi(real, sim, *, bins: int | str = 256, hist_range=DEFAULT_HIST_RANGE, bits=None, peak=None, mask=None) -> NMI:
    """Normalised mutual information, eqs. 7–10: ``MI / ((H(R) + H(S)) / 2)``.

    Returns an :class:`NMI` with ``.value .h_real .h_sim .h_joint .mi .bins``. NMI = 1
    means a one-to-one grey-level relation, not equality. Depends on ``bins``: see the
    README's numerical notes.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> real = np.array([[100, 200], [300, 400]], dtype=np.uint16)
    >>> sim = np.array([[101, 199], [302, 400]], dtype=np.uint16)
    >>> irf.stats.nmi(real, sim).value         # each real grey level has its own simulated one
    1.0
    >>> irf.stats.nmi(real, 500 - real).value   # inverted: still one-to-one
    1.0
    >>> merged = np.array([[100, 100], [300, 400]], dtype=np.uint16)     # two levels merged
    >>> n = irf.stats.nmi(real, merged)
    >>> round(n.value, 4), n.h_real, n.h_sim, n.mi        # MI / ((H(R) + H(S)) / 2) = 1.5 / 1.75
    (0.8571, 2.0, 1.5, 1.5)
    """
    st = pair_stats(real, sim, bins=bins, hist_range=hist_range, bits=bits, peak=peak, need=("nmi",), mask=mask)
    return st.nmi()
