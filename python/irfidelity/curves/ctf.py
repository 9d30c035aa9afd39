"""Contrast transfer function (CTF) from images of bar targets, and Coltman's series between
CTF and MTF.

Reading one target (:func:`ctf_from_bars`): the target is located (:mod:`.bars`), its
background subtracted, and the profile across the bars averaged over the central 60 % of their
length. With ``n`` bars of width ``W = 1/(2f)`` centred at ``c_i`` and gaps centred half a
period beyond them:

* **bar modulation** (the CTF): ``B`` and ``G`` are the profile's values on the bars' and
  gaps' centre lines averaged over the bars (``B``) and the gaps between them (``G``), in the
  target's polarity, after the background is subtracted:

  .. math:: \\mathrm{CTF}(f) = \\frac{B - G}{B + G}.

  A centre line rarely falls on a sample. When the image is sampled well — the system MTF
  near Nyquist, estimated from the target's own spectrum between 0.35 and 0.5 cy/px against
  the ideal target's, is at most 0.15 — the values come from the profile's band-limited
  (trigonometric) interpolation, exact for such images; otherwise from a least-squares
  parabola through the samples within ``max(W/4, 1 px)`` of the line (the 3 nearest when
  fewer), which reads the flat tops of sharp bars exactly. In between, the samples do not
  determine the profile between them and the bar modulation depends on the sampling phase
  (the errors measured are in docs/bars.md);

* **fundamental-amplitude ratio** (Boreman & Yang 1995): the image's Fourier component at
  the bar frequency against the ideal target's. With ``s(x)`` the image minus the background
  summed along the bars over the whole target and a margin of a bar width (at least 8 px) on
  every side — blur conserves that integral ``Σs``, and the ideal target of that integral has
  the fundamental ``(2/π) Σs`` —

  .. math:: \\mathrm{MTF}(f) = \\frac{(-1)^{n-1}\\,\\mathrm{Re}\\sum_x s(x)\\,
            e^{-2\\pi i f (x - c)}}{(2/\\pi) \\sum_x s(x)},

  the two-dimensional Fourier transform at ``(f, 0)`` of image and ideal target. It is an
  MTF sample — the system MTF including the pixel aperture, as the slanted edge measures —
  needs no series conversion, and does not depend on where the samples fall on the bars, so it
  stays valid when the bars are only 1-2 pixels wide (undersampled sensors); it is signed
  (negative on contrast reversal).

Both are in every :class:`BarReading`, with the bar signal-to-noise ratio that
:func:`~irfidelity.curves.measured_mrtd` thresholds.

Coltman's series (J. W. Coltman, JOSA 44(6):468, 1954) relate the CTF of an infinite square
wave to the MTF, with ``χ(k) = (-1)^((k-1)/2)`` and the Möbius function ``μ`` over odd ``k``:

.. math::

    \\mathrm{CTF}(f) = \\frac{4}{\\pi} \\sum_{k\\ \\mathrm{odd}} \\chi(k)\\, \\frac{\\mathrm{MTF}(kf)}{k},
    \\qquad
    \\mathrm{MTF}(f) = \\frac{\\pi}{4} \\sum_{k\\ \\mathrm{odd}} \\mu(k)\\, \\chi(k)\\, \\frac{\\mathrm{CTF}(kf)}{k}

(``MTF(f) = π/4 [CTF(f) + CTF(3f)/3 − CTF(5f)/5 + CTF(7f)/7 + CTF(11f)/11 − …]``). Where the
truncation matters is in docs/bars.md: a curve taken as 0 beyond its last frequency ``f_max``
misses terms for ``f > f_max/3``; and a finite (three- or four-bar) target is not the infinite
square wave the series assumes.

References: J. W. Coltman, "The specification of imaging properties by response to a sine
wave input", JOSA 44(6):468-471 (1954), doi:10.1364/JOSA.44.000468; G. D. Boreman and S. Yang,
"Modulation transfer function measurement using three- and four-bar targets", Appl. Opt.
34(34):8050-8052 (1995), doi:10.1364/AO.34.008050.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass
from typing import Any, Sequence

import numpy as np

from ..errors import BarClippingWarning, BarPolarityWarning, BarSamplingWarning, BarWarning, ColtmanWarning, \
    FidelityError
from .bars import (BarGeometry, BarGroup, cycles_per_pixel, detect_orientation, find_in, frame_pixels, locate, orient,
                   pixel_noise, surround, target_margin)
from .curve import Curve, as_curve
from .edge import MTF_LIMIT
from .units import CameraGeometry, canonical_unit

__all__ = ["BarReading", "ctf_from_bars", "ctf_curve", "ctf_from_mtf", "mtf_from_ctf", "read_bars", "target_region",
           "check_options", "below_nyquist"]

METHODS = ("modulation", "fundamental")
#: bars narrower than this (pixels) make the bar modulation depend on the sampling phase
MIN_BAR_WIDTH = 2.0
#: a target whose summed deviation from the background is below this many standard errors is flat
FLAT_SIGMAS = 5.0
#: bars whose fundamental is below this many standard errors are not resolved
RESOLVED_SIGMAS = 3.0
#: bars read a modulation of at least about 0.85 of their fundamental ratio (Coltman's series with
#: MTF(3f) <= MTF(f)); a modulation under this fraction of it is not bars (a uniform block, an edge)
NOT_BARS_RATIO = 0.4
#: a CTF above 1 by less than this many standard errors plus CTF_TOLERANCE reads 1 without a warning
#: (noise, and the centre-line estimate's error on resolved bars); above 1 + CTF_GROSS_EXCESS it is refused
CTF_EXCESS_SIGMAS = 3.0
CTF_TOLERANCE = 0.02
CTF_GROSS_EXCESS = 0.5
#: the profile counts as sampled well (band-limited interpolation of the centre lines) when the
#: system MTF estimated near Nyquist is at most this (docs/bars.md has the errors either side)
WELL_SAMPLED_MTF = 0.15
#: bars narrower than this (pixels) in an image that is not sampled well warn too
MIN_UNDERSAMPLED_BAR_WIDTH = 4.0
#: fraction of the target's pixels at the clipping level that warns
CLIPPED_FRACTION = 0.001


@dataclass(frozen=True)
class BarReading:
    """What one bar target reads (:func:`ctf_from_bars`).

    Attributes
    ----------
    value : float
        ``ctf`` or ``mtf``, as ``method`` asked.
    method : "modulation" | "fundamental"
    ctf : float
        Bar modulation ``(B - G)/(B + G)`` (negative on contrast reversal, at most 1).
    mtf : float
        Fundamental-amplitude ratio: the MTF at ``frequency``.
    frequency : float
        Bar frequency, cycles/pixel.
    orientation : "vertical" | "horizontal"
    bars : int
    polarity : int
        +1 bars above the background (hot bars for a white-hot camera), -1 below.
    centre : (float, float)
        Target centre (row, column) in the image.
    roi : (row_start, row_stop, col_start, col_stop)
        Region read.
    background : float
        Background level subtracted.
    bar_level, gap_level : float
        ``B`` and ``G``: the profile on the bars' and gaps' centre lines above the background,
        in the target's polarity.
    amplitude : float
        The bars' large-area level above the background in the target's polarity: the
        target's integral over the bars' area (blur conserves the integral).
    noise : float
        Pixel noise (standard deviation) used.
    snr : float
        Bar signal-to-noise ratio: the difference of the mean profile over the bars and over the
        gaps, against the noise of the difference between one bar and one gap of the target's
        area ``bar_length · W²`` pixels: ``(B̄ − Ḡ) / (σ √(2 / (bar_length W²)))``
        (:func:`~irfidelity.curves.mrtd` models the same quantity).
    bar_width : float
        ``W = 1/(2f)`` pixels.
    ctf_error : float
        Standard error of ``ctf`` from the pixel noise.
    nyquist_mtf : float
        The system MTF near Nyquist (0.35-0.5 cy/px) estimated from the target's spectrum:
        at most 0.15 the image counts as sampled well.
    """

    value: float
    method: str
    ctf: float
    mtf: float
    frequency: float
    orientation: str
    bars: int
    polarity: int
    centre: tuple[float, float]
    roi: tuple[int, int, int, int]
    background: float
    bar_level: float
    gap_level: float
    amplitude: float
    noise: float
    snr: float
    bar_width: float
    ctf_error: float
    nyquist_mtf: float

    def to_dict(self) -> dict[str, Any]:
        """The reading as plain JSON-ready values."""
        d = asdict(self)
        d["centre"], d["roi"] = list(self.centre), list(self.roi)
        return d


@dataclass(frozen=True)
class _Signal:
    """The measurement of a located target, before checks."""

    bar_level: float
    gap_level: float
    ctf: float
    ctf_error: float
    mtf: float
    fundamental: float
    fundamental_error: float
    amplitude: float
    amplitude_error: float
    noise: float
    snr: float
    nyquist_mtf: float
    clipped: int
    read_pixels: int


# --------------------------------------------------------------------------- options
def check_options(method: Any, bars: Any, bar_length: Any) -> tuple[int, float]:
    if method not in METHODS:
        raise FidelityError(f"method must be 'modulation' or 'fundamental', got {method!r}")
    if isinstance(bars, bool) or not isinstance(bars, (int, np.integer)) or bars < 2:
        raise FidelityError(f"bars must be an integer >= 2, got {bars!r}")
    try:
        length = float(bar_length)
    except (TypeError, ValueError):
        length = math.nan
    if not (math.isfinite(length) and length > 0):
        raise FidelityError(f"bar_length must be finite and > 0, got {bar_length!r}")
    return int(bars), length


def below_nyquist(f: float) -> None:
    if f >= 0.5:
        alias = 1.0 - f % 1.0 if f % 1.0 > 0.5 else f % 1.0
        raise FidelityError(f"bar frequency {f:.4g} cy/px is at or above the Nyquist frequency 0.5 cy/px: the "
                            f"sampled image cannot resolve the bars (the pattern aliases to {alias:.4g} cy/px)")


def _region(roi: Any, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    try:
        r0, r1, c0, c1 = (int(v) for v in roi)
    except (TypeError, ValueError):
        raise FidelityError(f"roi must be (row_start, row_stop, col_start, col_stop), got {roi!r}") from None
    if not (0 <= r0 < r1 <= shape[0] and 0 <= c0 < c1 <= shape[1]):
        raise FidelityError(f"roi {roi!r} is empty or outside the {shape[0]} x {shape[1]} image")
    if min(r1 - r0, c1 - c0) < 4:
        raise FidelityError(f"roi {roi!r} is smaller than 4 x 4 pixels")
    return r0, r1, c0, c1


def _border_median(region: np.ndarray) -> float:
    ring = np.concatenate((region[0], region[-1], region[1:-1, 0], region[1:-1, -1]))
    return float(np.median(ring))


# --------------------------------------------------------------------------- measuring a located target
def _parabola_value(profile: np.ndarray, centre: float, width: float) -> tuple[float, float]:
    """The profile on a centre line: constant term of a least-squares parabola through the
    samples within ``max(W/4, 1)`` px of it (the 3 nearest when fewer); and the factor by which
    it scales the profile's noise."""
    half = max(width / 4, 1.0)
    offsets = np.arange(profile.size, dtype=np.float64) - centre
    near = np.flatnonzero(np.abs(offsets) <= half)
    if near.size < 3:
        near = np.argsort(np.abs(offsets), kind="stable")[:3]
    basis = np.vander(offsets[near], min(3, near.size), increasing=True)
    coef = np.linalg.solve(basis.T @ basis, basis.T @ profile[near])  # normal equations: 3 × 3 at most
    return float(coef[0]), 1.0 / math.sqrt(near.size)


def _band_limited_values(window: np.ndarray, start: int, points: np.ndarray) -> np.ndarray:
    """The window's periodic band-limited (trigonometric) interpolation at ``points``
    (profile coordinates): exact for a profile sampled above its Nyquist rate."""
    n = window.size
    spectrum = np.fft.fft(window)
    phase = 2 * math.pi * np.outer(points - start, np.fft.fftfreq(n))
    return (np.cos(phase) @ spectrum.real - np.sin(phase) @ spectrum.imag) / n  # real products: fast in every BLAS


def _nyquist_mtf(window: np.ndarray, noise: float, f: float, bars: int, amplitude: float) -> float:
    """The system MTF near the Nyquist frequency (0.35-0.5 cy/px) estimated from the target
    itself: the profile's spectral power there against the ideal target's, noise power removed."""
    size = 4 * window.size
    power = np.abs(np.fft.rfft(window, size)) ** 2
    nu = np.arange(power.size) / size
    band = nu >= 0.35
    width = 1.0 / (2.0 * f)
    offsets = (np.arange(bars) - (bars - 1) / 2) / f
    phase = 2 * math.pi * np.outer(nu[band], offsets)
    ideal = (amplitude * width * np.sinc(width * nu[band]) * np.hypot(np.cos(phase).sum(axis=1),
                                                                      np.sin(phase).sum(axis=1))) ** 2
    signal = max(float(power[band].sum()) - noise ** 2 * window.size * int(band.sum()), 0.0)
    return math.sqrt(signal / float(ideal.sum())) if ideal.sum() > 0 else math.inf


def _measure(oriented: np.ndarray, geometry: BarGeometry, f: float, bars: int, bar_length: float,
             background: float, noise: float | None, clip: tuple[float, float] | None,
             background_pixels: int = 0) -> _Signal:
    """Levels, fundamental, amplitude and SNR of a located target (module docstring)."""
    width = 1.0 / (2.0 * f)
    r0, r1 = geometry.rows
    read = oriented[r0:r1]
    profile = geometry.polarity * (read.mean(axis=0) - background)
    x = np.arange(profile.size, dtype=np.float64)
    bar_centres = geometry.centre + (np.arange(bars) - (bars - 1) / 2) / f
    gap_centres = bar_centres[:-1] + width
    margin = target_margin(f)
    half = (2 * bars - 1) * width / 2 + margin
    lo = max(int(math.floor(geometry.centre - half)), 0)
    hi = min(int(math.ceil(geometry.centre + half)) + 1, profile.size)
    window, xs = profile[lo:hi], x[lo:hi]
    sigma = pixel_noise(read[:, lo:hi], axis=0) if noise is None else float(noise)
    profile_sigma = sigma / math.sqrt(r1 - r0)
    # the whole target with a margin along the bars too: a 2-D PSF spreads the bars' low
    # frequencies beyond their ends, and only the 2-D sums conserve them
    e0 = max(int(math.floor(geometry.extent[0] - margin)), 0)
    e1 = min(int(math.ceil(geometry.extent[1] + margin)), oriented.shape[0])
    column_sums = geometry.polarity * (oriented[e0:e1, lo:hi].sum(axis=0) - (e1 - e0) * background)
    dc = float(column_sums.sum())
    length = float(geometry.extent[1] - geometry.extent[0])
    amplitude = dc / (bars * width * length)
    fundamental = float((column_sums * np.cos(2 * math.pi * f * (xs - geometry.centre))).sum()) * (-1) ** (bars - 1)
    sum_sigma = sigma * math.sqrt(e1 - e0)
    # a background read as the median of n pixels is off by about 1.2533 σ/√n over the whole window
    background_sigma = 1.2533 * sigma / math.sqrt(background_pixels) if background_pixels else 0.0
    dc_sigma = math.hypot(sum_sigma * math.sqrt(window.size), background_sigma * (e1 - e0) * window.size)
    nyquist = _nyquist_mtf(window, profile_sigma, f, bars, float(window.sum()) / (bars * width))
    if nyquist <= WELL_SAMPLED_MTF:
        values = _band_limited_values(window, lo, np.concatenate((bar_centres, gap_centres)))
        scales = np.ones(values.size)
    else:
        fits = [_parabola_value(profile, c, width) for c in np.concatenate((bar_centres, gap_centres))]
        values, scales = np.array([v for v, _ in fits]), np.array([s for _, s in fits])
    bar_level, gap_level = float(values[:bars].mean()), float(values[bars:].mean())
    sigma_b = profile_sigma * math.sqrt(float((scales[:bars] ** 2).sum())) / bars
    sigma_g = profile_sigma * math.sqrt(float((scales[bars:] ** 2).sum())) / max(bars - 1, 1)
    total = bar_level + gap_level
    in_bars = np.abs(x[:, None] - bar_centres[None, :]).min(axis=1) < width / 2
    in_gaps = np.abs(x[:, None] - gap_centres[None, :]).min(axis=1) < width / 2
    bar_mean = float(profile[in_bars].mean()) if in_bars.any() else bar_level
    gap_mean = float(profile[in_gaps].mean()) if in_gaps.any() else gap_level
    snr = ((bar_mean - gap_mean) / sigma * math.sqrt(bar_length * width ** 2 / 2) if sigma > 0
           else math.copysign(math.inf, bar_mean - gap_mean))
    clipped = 0
    if clip is not None:
        target = oriented[geometry.extent[0]:geometry.extent[1], lo:hi]
        clipped = int(((target <= clip[0]) | (target >= clip[1])).sum())
    return _Signal(bar_level=bar_level, gap_level=gap_level,
                   ctf=(bar_level - gap_level) / total if total > 0 else math.nan,
                   ctf_error=2 * math.hypot(gap_level * sigma_b, bar_level * sigma_g) / total ** 2 if total > 0
                   else math.inf,
                   mtf=fundamental / ((2 / math.pi) * dc) if dc > 0 else math.nan, fundamental=fundamental,
                   fundamental_error=sum_sigma * math.sqrt(window.size / 2), amplitude=amplitude,
                   amplitude_error=dc_sigma / (bars * width * length), noise=sigma, snr=snr,
                   nyquist_mtf=nyquist, clipped=clipped, read_pixels=int((r1 - r0) * window.size))


# --------------------------------------------------------------------------- checks
def _warn(message: str, category: type[BarWarning]) -> None:
    warnings.warn(message, category, stacklevel=4)


def _check_signal(signal: _Signal, f: float, method: str, where: str, background: float) -> float:
    """Refuse a reading without a target or without bars, warn about a doubtful one; returns
    the CTF to report (a value above 1 within the noise reads 1)."""
    if not abs(signal.amplitude) > FLAT_SIGMAS * signal.amplitude_error:
        raise FidelityError(f"flat target{where}: the bars do not stand out of the background (level "
                            f"{signal.amplitude:.4g} against a standard error of {signal.amplitude_error:.3g}; "
                            f"a temperature difference of 0?)")
    if not abs(signal.fundamental) > RESOLVED_SIGMAS * signal.fundamental_error:
        raise FidelityError(f"no bars{where}: nothing varies at {f:.4g} cy/px beyond the noise (fundamental ratio "
                            f"{signal.mtf:.3g}); the region holds no bar target at this frequency, or the camera "
                            f"does not resolve it")
    if 1.0 / (2.0 * f) >= MIN_BAR_WIDTH and abs(signal.ctf) < NOT_BARS_RATIO * abs(signal.mtf) - \
            RESOLVED_SIGMAS * signal.ctf_error:
        raise FidelityError(f"no bars{where}: the region varies at {f:.4g} cy/px, but not as bars (bar modulation "
                            f"{signal.ctf:.3g} against a fundamental ratio {signal.mtf:.3g}); the region holds no bar "
                            f"target at this frequency")
    if not signal.bar_level + signal.gap_level > 0:
        raise FidelityError(f"bar modulation undefined{where}: bars and gaps read {signal.bar_level:.4g} and "
                            f"{signal.gap_level:.4g} above the background (wrong background level?)")
    if signal.mtf > MTF_LIMIT:
        raise FidelityError(f"fundamental ratio {signal.mtf:.3g} above {MTF_LIMIT}{where}: not a bar target at "
                            f"{f:.4g} cy/px")
    if signal.clipped >= CLIPPED_FRACTION * signal.read_pixels:
        _warn(f"{signal.clipped} pixels of the bar target{where} sit at the clipping level: saturated bars or gaps "
              f"bias the bar modulation", BarClippingWarning)
    width = 1.0 / (2.0 * f)
    undersampled = signal.nyquist_mtf > WELL_SAMPLED_MTF
    if method == "modulation" and (width < MIN_BAR_WIDTH or (undersampled and width < MIN_UNDERSAMPLED_BAR_WIDTH)):
        state = (f"an MTF near Nyquist of about {signal.nyquist_mtf:.2f}" if undersampled else "a well-sampled image")
        _warn(f"bars {width:.2f} px wide in {state}{where}: the bar modulation depends on where the samples fall on "
              f"the bars; method='fundamental' does not", BarSamplingWarning)
    if signal.ctf < 0 or signal.mtf < 0:
        _warn(f"inverted polarity{where}: the bar centres read darker than the gaps (CTF {signal.ctf:.3g}, "
              f"fundamental ratio {signal.mtf:.3g}): contrast reversal beyond the MTF's first zero, or aliasing",
              BarPolarityWarning)
    excess = signal.ctf - 1
    if excess > CTF_GROSS_EXCESS:
        raise FidelityError(f"bar modulation {signal.ctf:.4g} above 1{where}: the gaps read {-signal.gap_level:.4g} "
                            f"below the background {background:.6g} (background level wrong?)")
    if excess > CTF_EXCESS_SIGMAS * signal.ctf_error + CTF_TOLERANCE:
        _warn(f"bar modulation {signal.ctf:.4g} above 1{where}: the gaps read below the background (sharpening, "
              f"ringing, or a background level slightly off); reported as 1", BarWarning)
    return min(signal.ctf, 1.0)


# --------------------------------------------------------------------------- reading one target
def read_bars(pixels: np.ndarray, *, frequency: float, roi: tuple[int, int, int, int], orientation: str, bars: int,
              bar_length: float, background: float | None, noise: float | None, clip: tuple[float, float] | None,
              fallback_background: float | None = None,
              geometry: BarGeometry | None = None) -> tuple[BarGeometry, float, _Signal]:
    """Locate (unless ``geometry`` is given) and measure the target in ``roi``.

    The background is ``background`` when given, else the median of the region a bar width
    beyond the target, else ``fallback_background``. Returns the geometry, the background used
    and the unchecked measurement.
    """
    r0, r1, c0, c1 = roi
    oriented = orient(pixels[r0:r1, c0:c1], orientation)
    located = geometry is None
    if background is not None:
        level = float(background)
        if not math.isfinite(level):
            raise FidelityError(f"background must be finite, got {background!r}", option="background")
    else:
        level = fallback_background if fallback_background is not None else _border_median(oriented)
    if geometry is None:
        geometry = locate(oriented, frequency, bars, level)
    outside = surround(oriented, geometry, frequency, bars)
    if background is not None and outside.size >= 32:
        _check_background(level, float(np.median(outside)), oriented, geometry, roi)
    counted = 0
    if background is None:
        if outside.size >= 32:
            level = float(np.median(outside))
            counted = int(outside.size)
            if located and fallback_background is None:  # located on the ROI border's level: again on the surround's
                geometry = locate(oriented, frequency, bars, level)
        elif fallback_background is None:
            raise FidelityError(f"no background around the bars in roi {roi}: fewer than 32 pixels lie "
                                f"{target_margin(frequency):.0f} px beyond the target; enlarge the roi or give "
                                f"background=")
    return geometry, level, _measure(oriented, geometry, frequency, bars, bar_length, level, noise, clip, counted)


def target_region(pixels: np.ndarray, roi: Any, f: float, orientation: str | None, bars: int,
                  groups: list[BarGroup] | None = None) -> tuple[tuple[int, int, int, int], str, float | None]:
    """The region, orientation and fallback background of the target at ``f``: the target
    found in the frame (among ``groups`` when the frame's targets were found already) when
    ``roi`` is None, else the ROI (orientation detected unless given)."""
    if roi is None:
        found = find_in(pixels, frequencies=[f], bars=bars) if groups is None else groups
        group = _pick_group(found, f, orientation)
        return group.roi, group.orientation, group.background
    region = _region(roi, pixels.shape)
    if orientation is None:
        sub = pixels[region[0]:region[1], region[2]:region[3]]
        orientation = detect_orientation(sub, f, _border_median(sub))
    orient(pixels[:1, :1], orientation)  # validates the orientation
    return region, orientation, None


def _check_background(given: float, around: float, oriented: np.ndarray, geometry: BarGeometry,
                      roi: tuple[int, int, int, int]) -> None:
    """Refuse a given background level that the region around the target contradicts by more
    than a quarter of the target's contrast."""
    r0, r1 = geometry.rows
    contrast = float(np.abs(oriented[r0:r1].mean(axis=0) - around).max())
    if abs(given - around) > 0.25 * contrast:
        raise FidelityError(f"background {given:.6g} differs from the level {around:.6g} around the target in roi "
                            f"{roi} by more than a quarter of the target's contrast {contrast:.4g}",
                            option="background")


def _pick_group(groups: list[BarGroup], f: float, orientation: str | None) -> BarGroup:
    """The found target whose frequency is nearest ``f`` (within -20 %/+25 %)."""
    candidates = [g for g in groups if orientation is None or g.orientation == orientation]
    if not candidates:
        raise FidelityError("no bar target found in the image" + ("" if orientation is None else
                                                                  f" with {orientation} bars")
                            + (f" (targets found: {_describe(groups)})" if groups else "")
                            + "; give roi= to read a region")
    ratio = [abs(math.log(g.frequency / f)) for g in candidates]
    best = int(np.argmin(ratio))
    if ratio[best] > math.log(1.25):
        raise FidelityError(f"no bar target at {f:.4g} cy/px found in the image (targets found: "
                            f"{_describe(candidates)}); give roi= to read a region")
    rivals = [g for g, r in zip(candidates, ratio) if r <= math.log(1.25) and g is not candidates[best]]
    if rivals and orientation is None and any(g.orientation != candidates[best].orientation for g in rivals):
        raise FidelityError(f"{len(rivals) + 1} bar targets match {f:.4g} cy/px ({_describe([candidates[best]] + rivals)}); "
                            f"give orientation= or roi=")
    return candidates[best]


def _describe(groups: list[BarGroup]) -> str:
    return ", ".join(f"{g.orientation} {g.frequency:.3g} cy/px at rows {g.roi[0]}:{g.roi[1]} columns "
                     f"{g.roi[2]}:{g.roi[3]}" for g in groups)


def _reading(signal: _Signal, ctf: float, method: str, f: float, orientation: str, bars: int, geometry: BarGeometry,
             roi: tuple[int, int, int, int], background: float) -> BarReading:
    r0, r1 = geometry.rows
    along, across = (r0 + r1 - 1) / 2, geometry.centre
    centre = (roi[0] + along, roi[2] + across) if orientation == "vertical" else (roi[0] + across, roi[2] + along)
    return BarReading(value=ctf if method == "modulation" else signal.mtf, method=method, ctf=ctf, mtf=signal.mtf,
                      frequency=f, orientation=orientation, bars=bars, polarity=geometry.polarity, centre=centre,
                      roi=roi, background=background, bar_level=signal.bar_level, gap_level=signal.gap_level,
                      amplitude=signal.amplitude, noise=signal.noise, snr=signal.snr, bar_width=1.0 / (2.0 * f),
                      ctf_error=signal.ctf_error, nyquist_mtf=signal.nyquist_mtf)


def ctf_from_bars(image: Any, *, frequency: float, roi: Any = None, orientation: str | None = None,
                  method: str = "modulation", bars: int = 4, bar_length: float = 7.0, background: float | None = None,
                  noise: float | None = None, clip: tuple[float, float] | None = None, unit: str = "cy/px",
                  camera: CameraGeometry | None = None) -> BarReading:
    """The CTF of one bar target in an image: bar modulation and fundamental-amplitude ratio
    (module docstring).

    Parameters
    ----------
    image : 2-D array_like
        Integer or float pixels; one channel.
    frequency : float
        The target's bar frequency (one bar and one gap per cycle), in ``unit``.
    roi : (row_start, row_stop, col_start, col_stop), optional
        The region holding the target, best with a margin of background around it. Default:
        the target at ``frequency`` found in the image (:func:`~irfidelity.curves.bars.find_bars`).
    orientation : "vertical" | "horizontal", optional
        Vertical bars run along the columns. Default: detected (the direction whose mean
        profile carries the stronger component at ``frequency``).
    method : "modulation" | "fundamental"
        Which of ``ctf`` (bar modulation) and ``mtf`` (fundamental ratio) is the ``value``.
    bars : int
        Bars of the target (4; 3 for a three-bar target).
    bar_length : float
        Bar length in bar widths (7:1 bars), for the SNR.
    background : float, optional
        Background level; default the median of the ROI beyond a bar width (at least 8 px) of
        the target, or the frame's background outside its targets when the ROI leaves
        fewer than 32 such pixels (a target found automatically).
    noise : float, optional
        Pixel noise (standard deviation, image units); default from the differences of
        neighbouring pixels along the bars.
    clip : (lo, hi), optional
        Levels at which a pixel counts as clipped; default the integer dtype's range.
    unit, camera
        Unit of ``frequency`` (cy/px, cy/mrad, lp/mm) and the camera constants converting it.

    Returns
    -------
    BarReading

    Raises
    ------
    FidelityError
        A frequency at or above Nyquist (0.5 cy/px), no target at ``frequency`` in the image,
        a flat target (no contrast with the background: ΔT = 0), no bars (nothing varies at the
        frequency beyond the noise), no background around the bars in the ROI, a bar modulation
        above 1 beyond the noise (wrong background) or a fundamental ratio above 1.2.

    Warns
    -----
    BarClippingWarning
        Pixels at the clipping level (saturated bars).
    BarSamplingWarning
        ``method="modulation"`` with bars under 2 px wide.
    BarPolarityWarning
        Inverted polarity: the bar centres darker than the gaps (contrast reversal).

    References
    ----------
    .. [1] G. D. Boreman and S. Yang, Appl. Opt. 34(34):8050 (1995), doi:10.1364/AO.34.008050.
    .. [2] ASTM E1213, Standard test method for minimum resolvable temperature difference for
       thermal imaging systems (the 7:1 four-bar target).

    Examples
    --------
    >>> from irfidelity.targets import four_bar, gaussian_otf
    >>> frame = four_bar(0.1, (64, 64), otf=gaussian_otf(1.0), levels=(100.0, 150.0))
    >>> r = ctf_from_bars(frame, frequency=0.1)
    >>> r.orientation, round(r.ctf, 3), round(r.mtf, 3)  # MTF exp(-2π²σ²f²) sinc(f) = 0.807
    ('vertical', 0.966, 0.807)
    """
    pixels, dtype_clip = frame_pixels(image)
    f = cycles_per_pixel(frequency, unit=unit, camera=camera)
    bars, bar_length = check_options(method, bars, bar_length)
    return _read_target(pixels, f, roi=roi, orientation=orientation, method=method, bars=bars, bar_length=bar_length,
                        background=background, noise=noise, clip=clip if clip is not None else dtype_clip)


def _read_target(pixels: np.ndarray, f: float, *, roi: Any, orientation: str | None, method: str, bars: int,
                 bar_length: float, background: float | None, noise: float | None,
                 clip: tuple[float, float] | None, groups: list[BarGroup] | None = None) -> BarReading:
    below_nyquist(f)
    region, orientation, fallback = target_region(pixels, roi, f, orientation, bars, groups)
    geometry, level, signal = read_bars(pixels, frequency=f, roi=region, orientation=orientation, bars=bars,
                                        bar_length=bar_length, background=background, noise=noise, clip=clip,
                                        fallback_background=fallback)
    ctf = _check_signal(signal, f, method, f" in roi {region}", level)
    return _reading(signal, ctf, method, f, orientation, bars, geometry, region, level)


def ctf_curve(frames: Any, *, frequencies: Sequence[float] | np.ndarray, rois: Any = None,
              orientation: str | None = None, method: str = "modulation", bars: int = 4, unit: str = "cy/px",
              camera: CameraGeometry | None = None, name: str | None = None, **options: Any) -> Curve:
    """A CTF curve (or, with ``method="fundamental"``, an MTF curve) from bar targets at several
    frequencies.

    Parameters
    ----------
    frames : 2-D array or sequence of 2-D arrays
        One frame holding all the targets, or one frame per frequency.
    frequencies : sequence of float
        The targets' frequencies in ``unit``, at least 3 and distinct (in any order).
    rois : sequence, optional
        One ROI per frequency (None entries are found automatically).
    orientation, method, bars, unit, camera
        As in :func:`ctf_from_bars`; ``options`` are passed on to it (``background``,
        ``noise``, ``clip``, ``bar_length``).
    name : str, optional

    Returns
    -------
    Curve
        ``x`` the frequencies in ``unit`` (increasing), ``y`` the CTF (``y_unit="1"``);
        ``meta["readings"]`` the :class:`BarReading` of each, ``meta["quantity"]`` "ctf" or
        "mtf".

    Raises
    ------
    FidelityError
        Fewer than 3 or repeated frequencies, a count of frames or ROIs that does not match, or
        any target's error from :func:`ctf_from_bars` (naming its frequency).

    Examples
    --------
    >>> from irfidelity.targets import four_bar, gaussian_otf
    >>> freqs = [0.05, 0.1, 0.2]
    >>> frames = [four_bar(f, (90, 90), otf=gaussian_otf(1.0)) for f in freqs]
    >>> c = ctf_curve(frames, frequencies=freqs, method="fundamental")
    >>> c.y.round(3).tolist(), c.meta["quantity"]
    ([0.948, 0.807, 0.425], 'mtf')
    """
    f_list = np.atleast_1d(np.asarray(frequencies, dtype=np.float64))
    if f_list.ndim != 1 or f_list.size < 3:
        raise FidelityError(f"a CTF curve needs at least 3 frequencies, got {f_list.size}")
    if np.unique(f_list).size != f_list.size:
        raise FidelityError(f"frequencies must be distinct, got {f_list.tolist()}")
    single = isinstance(frames, np.ndarray) and frames.ndim == 2
    frame_list = [frames] * f_list.size if single else list(frames)
    if len(frame_list) != f_list.size:
        raise FidelityError(f"{len(frame_list)} frames for {f_list.size} frequencies: give one frame per frequency "
                            f"or one frame holding all the targets")
    roi_list = [None] * f_list.size if rois is None else list(rois)
    if len(roi_list) != f_list.size:
        raise FidelityError(f"{len(roi_list)} rois for {f_list.size} frequencies")
    unknown = set(options) - {"background", "noise", "clip", "bar_length"}
    if unknown:
        raise FidelityError(f"ctf_curve got unexpected options {sorted(unknown)}")
    bars, bar_length = check_options(method, bars, options.get("bar_length", 7.0))
    f_px = [cycles_per_pixel(freq, unit=unit, camera=camera) for freq in f_list]
    shared = None
    if single:
        pixels, dtype_clip = frame_pixels(frames)
        if any(r is None for r in roi_list):
            shared = find_in(pixels, frequencies=f_px, bars=bars)
    readings = []
    for index, (frame, freq, roi) in enumerate(zip(frame_list, f_px, roi_list)):
        if not single:
            pixels, dtype_clip = frame_pixels(frame, what=f"frame {index}")
        clip = options.get("clip")
        try:
            readings.append(_read_target(pixels, freq, roi=roi, orientation=orientation, method=method, bars=bars,
                                         bar_length=bar_length, background=options.get("background"),
                                         noise=options.get("noise"), clip=clip if clip is not None else dtype_clip,
                                         groups=shared))
        except FidelityError as exc:
            raise FidelityError(f"bar target at {f_list[index]:g} {unit}: {exc}") from None
    order = np.argsort(f_list)
    quantity = "ctf" if method == "modulation" else "mtf"
    return Curve(f_list[order], [readings[i].value for i in order],
                 name=name or ("CTF" if quantity == "ctf" else "MTF (bar fundamentals)"),
                 x_unit=canonical_unit(unit, what="unit"), y_unit="1",
                 meta={"quantity": quantity, "method": method, "readings": [readings[i] for i in order]})


# --------------------------------------------------------------------------- Coltman's series
def _odd_coefficients(count: int, inverse: bool) -> np.ndarray:
    """Coltman's coefficients for k = 1, 3, 5, …: ``(4/π) χ(k)/k`` or ``(π/4) μ(k) χ(k)/k``."""
    k = 2 * np.arange(count) + 1
    chi = np.where((k // 2) % 2 == 0, 1.0, -1.0)
    if not inverse:
        return (4 / math.pi) * chi / k
    mobius = np.ones(count)
    top = int(k[-1])
    for p in range(3, top + 1, 2):
        if all(p % q for q in range(3, int(math.isqrt(p)) + 1, 2)):  # p is an odd prime
            mobius[(k % p) == 0] *= -1
            mobius[(k % (p * p)) == 0] = 0
    return (math.pi / 4) * mobius * chi / k


def _coltman(curve: Curve, frequencies: Any, inverse: bool, name: str) -> Curve:
    """Coltman's series (``inverse``: MTF from CTF) of ``curve`` at ``frequencies``."""
    what = "CTF" if inverse else "MTF"
    x, y = curve.x, curve.y
    f = x if frequencies is None else np.asarray(frequencies, dtype=np.float64)
    if f.ndim != 1 or not np.isfinite(f).all() or (f < x[0]).any() or (f > x[-1]).any() or (f < 0).any():
        raise FidelityError(f"frequencies must be finite, >= 0 and within the {what}'s range "
                            f"[{x[0]:g}, {x[-1]:g}]")
    top = x[-1] * (1 + 1e-12)
    positive = f > 0
    count = int(math.floor(top / f[positive].min() + 1) // 2 + 1) if positive.any() else 1
    coefficients = _odd_coefficients(count, inverse)
    k = 2 * np.arange(count) + 1
    out = np.interp(f, x, y)  # f = 0: the series' limit is the value itself
    fp = f[positive]
    harmonics = fp[:, None] * k[None, :]
    inside = harmonics <= top
    values = np.where(inside, np.interp(np.minimum(harmonics, x[-1]), x, y), 0.0)
    out[positive] = values @ coefficients
    if abs(y[-1]) > 0.01 * max(float(np.abs(y).max()), 1e-300) and (fp > x[-1] / 3).any():
        warnings.warn(f"the {what} is {y[-1]:.3g} at its last frequency {x[-1]:g}, not 0: Coltman's series takes it "
                      f"as 0 beyond, so values above {x[-1] / 3:.4g} miss terms", ColtmanWarning, stacklevel=3)
    return Curve(f, out, name=name, x_unit=curve.x_unit, y_unit=curve.y_unit or "1")


def ctf_from_mtf(mtf: Any, *, frequencies: Any = None, name: str | None = None) -> Curve:
    """The square-wave CTF of an MTF curve by Coltman's series (module docstring):
    ``CTF(f) = (4/π) [MTF(f) − MTF(3f)/3 + MTF(5f)/5 − …]``.

    ``MTF(kf)`` is interpolated linearly on the curve and taken as 0 beyond its last
    frequency; on a uniform grid starting at 0 every ``kf`` is a grid point, so the series is
    exact to rounding and :func:`mtf_from_ctf` inverts it exactly. ``CTF(0) = MTF(0)``.

    Parameters
    ----------
    mtf : Curve or (x, y)
    frequencies : array_like, optional
        Where to evaluate (within the curve's range); default the curve's own frequencies.
    name : str, optional

    Warns
    -----
    ColtmanWarning
        The MTF has not fallen to (1 % of its peak) by its last frequency: values above a
        third of it miss terms.

    References
    ----------
    .. [1] J. W. Coltman, JOSA 44(6):468 (1954), doi:10.1364/JOSA.44.000468.

    Examples
    --------
    >>> f = np.linspace(0, 1, 11)
    >>> mtf = Curve(f, np.clip(1 - f / 0.8, 0, None), x_unit="cy/px")  # a triangle, zero at 0.8
    >>> ctf_from_mtf(mtf).y[:4].round(4).tolist()
    [1.0, 0.9216, 0.8488, 0.7958]
    """
    return _coltman(as_curve(mtf, "MTF curve"), frequencies, inverse=False, name=name or "CTF (Coltman)")


def mtf_from_ctf(ctf: Any, *, frequencies: Any = None, name: str | None = None) -> Curve:
    """The MTF of a square-wave CTF curve by Coltman's inverse series (module docstring):
    ``MTF(f) = (π/4) [CTF(f) + CTF(3f)/3 − CTF(5f)/5 + CTF(7f)/7 + CTF(11f)/11 − …]``.

    ``CTF(kf)`` is interpolated linearly and taken as 0 beyond the last frequency (see
    :func:`ctf_from_mtf`). A CTF measured on three- or four-bar targets is not the infinite
    square wave's: docs/bars.md has the error this makes.

    Parameters
    ----------
    ctf : Curve or (x, y)
    frequencies : array_like, optional
    name : str, optional

    Warns
    -----
    ColtmanWarning
        As :func:`ctf_from_mtf` (whose reference is Coltman's paper).

    Examples
    --------
    >>> g = Curve(np.linspace(0, 2, 201), np.exp(-2 * np.pi**2 * np.linspace(0, 2, 201)**2))
    >>> bool(np.abs(mtf_from_ctf(ctf_from_mtf(g)).y - g.y).max() < 1e-14)  # the inverse, exactly
    True
    """
    return _coltman(as_curve(ctf, "CTF curve"), frequencies, inverse=True, name=name or "MTF (Coltman)")
