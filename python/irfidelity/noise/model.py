"""3-D noise of a recording of a uniform source: :func:`noise3d` and its result :class:`Noise3D`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Iterator
from typing import Any

import numpy as np

from .. import budget
from ..errors import FidelityError, ShapeError
from ..curves.sitf import netd as netd_of
from .anova import PARTS, anova
from .checks import check_clipped, plane_fit, uniformity, warn_if_not_uniform
from .spectra import NoiseSpectra, pattern_spectra
from ..keywords import options_from
from .options import NoiseOptions
from .sums import NoiseSums, Planner, Region, as_sequence, noise_sums, sums_bytes

__all__ = ["Noise3D", "noise3d"]


#: Bytes a pixel that the decomposition and its checks hold after the pass, besides the
#: sums: the temporal-mean frame (from the core) and a centred copy.
_MAPS_BYTES = 16
#: The same with the spectra: the fixed pattern, its periodograms and 2-D spectra, and a
#: frame pair (decoded, as float64, and its difference). Measured 72 bytes a pixel of numpy
#: arrays on 1024 × 1280 frames (tracemalloc), plus the core's temporal-mean frame and a
#: decoded pair of at most 8-byte samples.
_SPECTRA_BYTES = 96


def _planner(spectra: bool, max_bytes: int | None) -> Planner:
    """The check, before the pass, that what follows it fits ``max_bytes`` (the pass plans
    itself in the core)."""
    def plan(region: tuple[int, int], dtype: np.dtype) -> None:
        pixels = region[0] * region[1]
        per_pixel = _SPECTRA_BYTES if spectra else _MAPS_BYTES
        what = "the 3-D noise decomposition" + (" and spectra (spectra=False needs less)" if spectra else "")
        budget.check(what, region, sums_bytes(pixels, dtype) + per_pixel * pixels, max_bytes)

    return plan


@dataclass(frozen=True)
class Noise3D:
    """The 3-D noise of a recording (frame units unless noted).

    Attributes
    ----------
    sigma : dict
        Standard deviation of each part ``"t", "v", "h", "tv", "th", "vh", "tvh"``: the
        corrected estimates (negative variance estimates shown as 0) or, with
        ``corrected=False``, the classical ones.
    variance : dict
        The variance estimates behind ``sigma``; corrected ones may be negative (a component
        indistinguishable from 0), never hidden.
    classical : dict
        Classical σ of every part (population standard deviations of the parts), always.
    ci : dict or None
        ``(low, high)`` confidence interval of each corrected σ at ``confidence``; None for
        classical results.
    df : dict
        ANOVA degrees of freedom of each part.
    total : float
        Total noise σ: ``√(Σ variance)`` (classical: the cube's population σ).
    mean : float
        Mean of the recording (the signal level).
    frames, rows, cols : int
        T, V, H of the analysed region.
    netd, netd_ci : float, (float, float) or None
        ``σ_tvh / |SiTF slope|`` and its interval, when ``sitf=`` was given (SiTF x units).
    sitf_slope : float or None
        The SiTF slope used (signal units per x unit).
    uniformity : dict
        ``plane`` and ``low_frequency`` shares of the noise variance (see
        :mod:`irfidelity.noise.checks`) and the box width used.
    clipped : dict or None
        Integer frames: the valid range ``lo``, ``hi`` and the sample counts ``at_lo``,
        ``at_hi`` at its ends.
    spectra : NoiseSpectra or None
        Fixed-pattern and temporal noise spectra (``spectra=True``).

    Examples
    --------
    A uniform source seen through a row pattern of σ = 3 and temporal noise of σ = 2:

    >>> import numpy as np, irfidelity as irf
    >>> rng = np.random.default_rng(0)
    >>> rows = rng.normal(0, 3, (1, 64, 1))
    >>> cube = np.round(1000 + rows + rng.normal(0, 2, (50, 64, 64))).astype(np.uint16)
    >>> n = irf.noise.noise3d(cube)
    >>> (n.frames, n.rows, n.cols), round(n.mean), round(n.sigma["tvh"], 2), round(n.total, 2)
    ((50, 64, 64), 1000, 2.02, 3.42)
    >>> low, high = n.ci["v"]                                  # 95 % interval of σ_v
    >>> round(low, 1), round(high, 1), n.fixed_pattern.shape
    (2.3, 3.3, (64, 64))
    """

    sigma: dict[str, float]
    variance: dict[str, float]
    classical: dict[str, float]
    ci: dict[str, tuple[float, float]] | None
    df: dict[str, int]
    total: float
    mean: float
    frames: int
    rows: int
    cols: int
    dtype: str
    corrected: bool
    confidence: float
    detrend: str | None
    roi: tuple[int, int, int, int] | None
    netd: float | None
    netd_ci: tuple[float, float] | None
    sitf_slope: float | None
    uniformity: dict[str, float]
    clipped: dict[str, int] | None
    spectra: NoiseSpectra | None = field(repr=False)
    sums: NoiseSums = field(repr=False, compare=False)

    @property
    def fixed_pattern(self) -> np.ndarray:
        """The temporal-mean frame minus its mean (minus the plane when detrended), (rows, cols)."""
        return _fixed_pattern(self.sums, self.detrend)

    @property
    def temporal_noise_map(self) -> np.ndarray:
        """Temporal standard deviation of every pixel (population), (rows, cols)."""
        return np.sqrt(self.sums.pixel_var())

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the 1-D spectra as lists; maps and 2-D spectra left out)."""
        out = {k: getattr(self, k) for k in ("sigma", "variance", "classical", "df", "total", "mean", "frames",
                                             "rows", "cols", "dtype", "corrected", "confidence", "detrend",
                                             "netd", "sitf_slope", "uniformity", "clipped")}
        out["ci"] = None if self.ci is None else {k: list(v) for k, v in self.ci.items()}
        out["roi"] = None if self.roi is None else list(self.roi)
        out["netd_ci"] = None if self.netd_ci is None else list(self.netd_ci)
        out["spectra"] = None if self.spectra is None else self.spectra.to_dict()
        return out


def _fixed_pattern(sums: NoiseSums, detrend: str | None) -> np.ndarray:
    mean_map = sums.pixel_mean()
    fixed = mean_map - mean_map.mean()
    return fixed - plane_fit(fixed) if detrend == "plane" else fixed


def _detrended_ss(sums: NoiseSums, ss: dict[str, float]) -> dict[str, float]:
    """v and h sums of squares with a plane removed from the temporal-mean frame.

    A plane ``b·row + c·col`` has no row-column interaction: it moves only the row-mean and
    column-mean profiles (parts v and h), so those two are recomputed from the profiles
    less their fitted lines; every other part is unchanged.
    """
    t, v, h = sums.frames, sums.rows, sums.cols
    mean_map = sums.pixel_mean()
    out = dict(ss)
    for part, profile, others in (("v", mean_map.mean(axis=1), t * h), ("h", mean_map.mean(axis=0), t * v)):
        x = np.arange(profile.size) - (profile.size - 1) / 2
        centred = profile - profile.mean()
        resid = centred - x * (float(x @ centred) / float(x @ x))
        out[part] = others * float(resid @ resid)
    return out


def _temporal_pairs(frames: Any, pairs: int, roi: Region | None, channel: str | None) -> Iterator[np.ndarray]:
    """``(x₁ − x₀)/√2`` of disjoint consecutive frame pairs from the start of the recording,
    one pair in memory at a time."""
    seq = frames if isinstance(frames, np.ndarray) else as_sequence(frames, channel)
    r0, r1, c0, c1 = roi if roi is not None else (0, None, 0, None)
    for k in range(min(pairs, len(seq) // 2)):
        a = np.asarray(seq[2 * k], dtype=np.float64)[r0:r1, c0:c1]
        b = np.asarray(seq[2 * k + 1], dtype=np.float64)[r0:r1, c0:c1]
        yield (b - a) / math.sqrt(2)


def noise3d(frames: Any, options: NoiseOptions | None = None, **keywords: Any) -> Noise3D:
    """3-D noise of frames of a uniform source: the seven components of D'Agostino & Webb.

    The recording is a cube of T frames × V rows × H columns. With ``U = frames − mean`` and
    directional means ``mean_a`` over the axes ``a``, the classical parts are ::

        N_t = mean_vh U,  N_v = mean_th U,  N_h = mean_tv U,
        N_tv = mean_h U − N_t − N_v,  N_th = mean_v U − N_t − N_h,  N_vh = mean_t U − N_v − N_h,
        N_tvh = U − (all of the above)

    and ``σ_x`` is the population standard deviation of ``N_x`` (``corrected=False``).
    These are biased for finite T, V, H; ``corrected=True`` (default) gives the unbiased
    random-effects estimates (Haefner et al. 2015), e.g. ``σ_tv² = (MS_tv − MS_tvh)/H``
    with ANOVA mean squares ``MS_x = Σ N_x² / df_x``, with confidence intervals. See
    ``docs/noise.md`` for every formula.

    The pass is streamed (Rust, GIL released, ``workers`` threads): memory O(V·H + T·(V+H)),
    never the cube; integer frames are summed exactly (the seven sums of squares add up to
    the total exactly). Everything is planned against ``max_bytes`` before the pass starts
    (docs/design.md §14).

    Parameters
    ----------
    frames : numpy.ndarray, path, sequence of paths, FrameSequence or NoiseSums
        A 3-D array ``(frames, rows, cols)``; a directory, glob, list of paths or
        multi-page TIFF; or merged :class:`~irfidelity.noise.NoiseSums` (then no temporal
        spectra).
    options : NoiseOptions, optional
        The settings below as one object (:class:`~irfidelity.noise.NoiseOptions`), checked
        when made. Without it, each is a keyword (``noise3d(cube, bits=14)``); a keyword given
        together with ``options`` is a FidelityError.
    bits : int, optional
        Bit depth of integer frames (values above ``2**bits - 1`` are an error; values at
        ``0`` or ``2**bits - 1`` count as clipped).
    corrected : bool, default True
        Finite-sampling-corrected estimates with confidence intervals, or the classical
        decomposition.
    confidence : float, default 0.95
        Level of the intervals.
    detrend : None or "plane"
        ``"plane"`` removes a least-squares plane from the temporal-mean frame (a gradient
        across a uniform source); it changes only the v and h parts (each loses one degree
        of freedom).
    roi : (row_start, row_stop, col_start, col_stop), optional
        Analyse this region of every frame.
    sitf : SiTFFit or float, optional
        The camera's SiTF (or its slope, signal units per kelvin): reports
        ``netd = σ_tvh / |slope|`` (:func:`irfidelity.curves.netd`) and lets
        :func:`~irfidelity.noise.noise_similarity` compare levels in temperature units.
    spectra : bool, default True
        Compute the noise spectra (:class:`~irfidelity.noise.NoiseSpectra`).
    spectra_pairs : int, default 16
        Disjoint frame pairs (from the start) whose differences give the temporal spectra.
    saturated : "warn", "raise" or "ignore"
        What to do about samples at the ends of the valid range (integer frames).
    channel : str, optional
        Channel of multi-channel files.
    workers : int, optional
        Threads (default: all cores); results do not depend on it.
    max_bytes : int, optional
        The memory budget (default :data:`irfidelity.budget.DEFAULT_MAX_BYTES`): the pass
        (:func:`irfidelity.noise.noise_sums`), then the sums with the decomposition's maps and
        (``spectra=True``) the spectra; a cube given in memory is the caller's and not counted.

    Returns
    -------
    Noise3D

    Raises
    ------
    ShapeError
        Fewer than 2 frames, rows or columns (3 with ``detrend="plane"``), or frames of
        different shapes or dtypes (the message names the frame).
    RangeError
        NaN/Inf (count and first position), integers outside ``bits``, or clipped samples
        with ``saturated="raise"``.
    FrameError
        An unreadable frame file.
    FidelityError
        A bad option, or a recording whose pass or spectra do not fit ``max_bytes`` (the
        message names the step, the frame size, the bytes needed and the budget).

    Warns
    -----
    NoiseWarning
        The scene is not uniform (a gradient: use ``detrend="plane"``; an object: use
        ``roi=``), or samples are clipped (with counts).

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> rng = np.random.default_rng(0)
    >>> rows = rng.normal(0, 3, (1, 64, 1))                # fixed row pattern (v)
    >>> cube = np.round(1000 + rows + rng.normal(0, 2, (50, 64, 64))).astype(np.uint16)
    >>> n = irf.noise.noise3d(cube)
    >>> round(n.sigma["v"]), round(n.sigma["tvh"])
    (3, 2)

    The settings as one object (the same as ``irf.noise.noise3d(cube, bits=11, spectra=False)``):

    >>> from irfidelity.noise import NoiseOptions
    >>> settings = NoiseOptions(bits=11, spectra=False)
    >>> irf.noise.noise3d(cube, settings).sigma == irf.noise.noise3d(cube, bits=11, spectra=False).sigma
    True

    References
    ----------
    J. A. D'Agostino and C. M. Webb, "Three-dimensional analysis framework and measurement
    methodology for imaging system noise", Proc. SPIE 1488, 110–121 (1991).
    D. Haefner et al., "Finite sampling corrected 3D noise with confidence
    intervals", Applied Optics 54(15), 4907 (2015).
    T. Ting, R. K. Burdick, F. A. Graybill, S. Jeyaratnam and T.-F. C. Lu, "Confidence
    intervals on linear combinations of variance components that are unrestricted in
    sign", J. Stat. Comput. Simul. 35, 135–143 (1990).
    """
    opts = options_from(NoiseOptions, options, keywords, "options")
    corrected, level, detrend, roi = opts.corrected, opts.confidence, opts.detrend, opts.roi
    slope = opts.sitf_slope
    planner = _planner(opts.spectra, opts.max_bytes)
    if isinstance(frames, NoiseSums):
        if roi is not None:
            raise FidelityError("roi applies when the sums are computed; NoiseSums already hold their region")
        sums = frames
        planner((sums.rows, sums.cols), np.dtype(sums.dtype))
    else:
        sums = noise_sums(frames, bits=opts.bits, roi=roi, channel=opts.channel, workers=opts.workers,
                          max_bytes=opts.max_bytes, _planner=planner)
    t, v, h = sums.frames, sums.rows, sums.cols
    least = 3 if detrend == "plane" else 2
    if t < 2:
        raise ShapeError(f"3-D noise needs at least 2 frames, got {t}")
    if v < least or h < least:
        raise ShapeError(f"3-D noise needs frames of at least {least} x {least} pixels"
                         f"{' to fit a plane' if detrend else ''}, got {v} x {h}")
    dec = sums.decomposition()
    ss = _detrended_ss(sums, dec["ss"]) if detrend == "plane" else dict(dec["ss"])
    comps = anova(ss, t, v, h, plane=detrend == "plane")
    clipped = check_clipped(sums.value_range(), t * v * h, opts.saturated)
    total_variance = dec["ss_total"] / (t * v * h)
    share = uniformity(sums.pixel_mean(), total_variance)
    warn_if_not_uniform(share, detrended=detrend == "plane")

    classical = {k: math.sqrt(comps.classical[k]) for k in PARTS}
    ci: dict[str, tuple[float, float]] | None
    if corrected:
        variance = dict(comps.corrected)
        sigma = {k: math.sqrt(max(variance[k], 0.0)) for k in PARTS}
        ci = {}
        for k in PARTS:
            lo, hi = comps.interval(k, level)
            ci[k] = (math.sqrt(lo), math.sqrt(hi))
        total = math.sqrt(max(sum(variance.values()), 0.0))
    else:
        variance = dict(comps.classical)
        sigma, ci = classical, None
        total = math.sqrt(sum(variance.values()))
    netd = netd_ci = None
    if slope is not None:
        netd = netd_of(sigma["tvh"], slope)
        if ci is not None:
            netd_ci = (ci["tvh"][0] / abs(slope), ci["tvh"][1] / abs(slope))
    spec = None
    if opts.spectra:
        pairs = iter(()) if isinstance(frames, NoiseSums) else _temporal_pairs(frames, opts.spectra_pairs, roi,
                                                                               opts.channel)
        spec = pattern_spectra(_fixed_pattern(sums, detrend), pairs)
    region = None if roi is None else (int(roi[0]), int(roi[1]), int(roi[2]), int(roi[3]))  # 4 bounds (noise_sums)
    return Noise3D(sigma=sigma, variance=variance, classical=classical, ci=ci, df=comps.df, total=total,
                   mean=float(dec["mean"]), frames=t, rows=v, cols=h, dtype=sums.dtype, corrected=corrected,
                   confidence=level, detrend=detrend, roi=region,
                   netd=netd, netd_ci=netd_ci, sitf_slope=slope, uniformity=share, clipped=clipped,
                   spectra=spec, sums=sums)
