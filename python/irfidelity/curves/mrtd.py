"""Minimum resolvable temperature difference (MRTD): the classical objective model from the MTF
and the noise (:func:`mrtd`), and the objective MRTD measured on frames of bar targets at known
temperature differences (:func:`measured_mrtd`).

The model is the classical MRTD of the NVL static performance model (Ratches 1975/1976, Lloyd
1975), in the staring-array form of Holst, with the 3-D noise terms of FLIR92 (Scott &
D'Agostino 1992). Its assumptions, each a parameter:

* the observer compares the mean signal over one bar with that over the adjacent gap,
  integrating each over the bar's area ``A = bar_length · W²`` pixels (``W = 1/(2f)``,
  ``bar_length = 7`` for 7:1 bars) and over ``N = max(1, eye_time · frame_rate)`` frames
  (``eye_time = 0.2`` s; one frame when the frame rate is not given: an objective,
  single-frame MRTD);
* the bars are resolved when that difference reaches ``snr_threshold`` (``SNR_T``, 2.5) times
  its noise;
* the bar pattern reaches the eye as its fundamental: a square wave of amplitude ΔT has the
  fundamental ``(4/π)(ΔT/2) MTF(f)``, whose mean over a bar exceeds that over a gap by
  ``(8/π²) MTF(f) ΔT`` (exact above a third of the MTF's cutoff; below, the real bars are
  squarer and the model is up to ``π²/8 = 1.23`` times pessimistic);
* white temporal noise ``σ_tvh = NETD`` per pixel and frame, so the bar–gap difference has the
  noise ``NETD √(2/(A N)) k(f)``; the 3-D noise components (given a
  :class:`~irfidelity.noise.Noise3D`) that do not average away add to it (``k``, below);
  components common to a bar and its gap (``σ_t``, and for vertical bars ``σ_v``,
  ``σ_tv``) cancel in the difference; a display blur much smaller than a bar leaves the
  bar-mean noise unchanged and enters through ``display_mtf`` on the signal only.

Setting the signal difference to ``SNR_T`` times its noise gives, with ``f`` in cycles/pixel,

.. math::

    \\mathrm{MRTD}(f) = \\frac{\\pi^2}{8}\\, \\mathrm{SNR}_T\\, \\mathrm{NETD}\\,
        \\sqrt{\\frac{2}{A N}}\\, \\frac{k(f)}{\\mathrm{MTF}(f)}
      = \\frac{\\pi^2}{2\\sqrt{2\\,\\mathrm{bar\\_length}}}\\,
        \\frac{\\mathrm{SNR}_T\\, \\mathrm{NETD}\\, f\\, k(f)}{\\mathrm{MTF}(f)\\, \\sqrt{N}}

(``π²/(2√14) = 1.319`` for 7:1 bars): MRTD ∝ NETD and ∝ 1/MTF. For vertical bars (the
horizontal MRTD, frequency along the rows) the FLIR92-style noise factor is

.. math::

    k(f)^2 = 1 + N \\frac{\\sigma_{vh}^2}{\\sigma_{tvh}^2}
               + \\mathrm{bar\\_length}\\, W \\frac{\\sigma_{th}^2}{\\sigma_{tvh}^2}
               + \\mathrm{bar\\_length}\\, W N \\frac{\\sigma_h^2}{\\sigma_{tvh}^2}

(fixed-pattern noise ``σ_vh`` does not average over frames, column noise ``σ_th``, ``σ_h`` not
along the bar); horizontal bars swap ``σ_th, σ_h`` for ``σ_tv, σ_v``. Texts write the constant
differently as they define the threshold SNR (per bar, per bar–gap difference, per
half-cycle): the threshold here is that of the bar–gap difference, and
:func:`measured_mrtd` thresholds the same quantity on images, so model and measurement
compare at equal assumptions. docs/bars.md has the derivation and a worked example.

References: J. A. Ratches, "Static performance model for thermal imaging systems", Opt. Eng.
15(6):525-530 (1976), doi:10.1117/12.7972037; J. M. Lloyd, *Thermal Imaging Systems*, Plenum
(1975), ch. 5; G. C. Holst, *Electro-Optical Imaging System Performance*, JCD Publishing /
SPIE Press, the MRT chapter; L. Scott and J. D'Agostino, "NVEOD FLIR92 thermal imaging systems
performance model", Proc. SPIE 1689 (1992); ASTM E1213 and STANAG 4349 (the MRTD test).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from ..errors import BarPolarityWarning, FidelityError, MRTDWarning
from .bars import BarGeometry, cycles_per_pixel, frame_pixels, positive
from .curve import Curve, as_curve
from .ctf import RESOLVED_SIGMAS, below_nyquist, check_options, read_bars, target_region
from .units import CameraGeometry, canonical_unit, convert, warn_unknown

__all__ = ["mrtd", "measured_mrtd", "MRTD_CONSTANT"]

#: π²/8: the bar-minus-gap mean of a square wave's fundamental, per unit of ΔT·MTF, inverted
MRTD_CONSTANT = math.pi ** 2 / 8
#: frames whose statistic is below this many times the threshold fit its slope (above it, saturation
#: or a nonlinear response would bend the line)
FIT_LIMIT = 4.0
#: the 3-D noise components that do not cancel between a bar and its gap, for each bar orientation:
#: (temporal component constant along the bar, fixed component constant along the bar)
_ALONG_BAR = {"vertical": ("th", "h"), "horizontal": ("tv", "v")}


def integrated_frames(eye_time: float, frame_rate: float | None) -> float:
    """Frames the eye integrates: ``max(1, eye_time · frame_rate)``; 1 without a frame rate."""
    t = positive(eye_time, "eye_time")
    if frame_rate is None:
        return 1.0
    return max(1.0, t * positive(frame_rate, "frame_rate"))


def noise_factor(noise: Any, f: np.ndarray, frames: float, bar_length: float, orientation: str) -> np.ndarray:
    """``k(f)`` of the module docstring from a :class:`~irfidelity.noise.Noise3D` (1 without one)."""
    if noise is None:
        return np.ones_like(f)
    sigma = getattr(noise, "sigma", None)
    if not isinstance(sigma, dict) or "tvh" not in sigma:
        raise FidelityError(f"noise must be a Noise3D (irfidelity.noise.noise3d), got {type(noise).__name__}",
                            option="noise")
    base = float(sigma["tvh"])
    if not base > 0:
        raise FidelityError("noise: the temporal random noise sigma_tvh is 0; the MRTD model needs it", option="noise")
    temporal, fixed = _ALONG_BAR[orientation]
    width = 1.0 / (2.0 * f)
    ratio = {key: (float(sigma[key]) / base) ** 2 for key in ("vh", temporal, fixed)}
    return np.sqrt(1 + frames * ratio["vh"] + bar_length * width * ratio[temporal]
                   + bar_length * width * frames * ratio[fixed])


def _pixel_frequencies(c: Curve, camera: CameraGeometry | None, what: str) -> np.ndarray:
    """The curve's frequencies in cycles/pixel (an unknown unit is taken as cy/px, with a warning)."""
    if c.x_unit is None:
        warn_unknown(f"the {what}'s frequency unit is unknown: taken as cycles/pixel")
        return c.x
    return convert(c.x, c.x_unit, "cy/px", camera=camera)


def _ratio(c: Curve) -> np.ndarray:
    return convert(c.y, "%", "1") if c.y_unit == "%" else c.y


def mrtd(mtf: Any, *, netd: float | None = None, noise: Any = None, snr_threshold: float = 2.5,
         eye_time: float = 0.2, frame_rate: float | None = None, bar_length: float = 7.0,
         orientation: str = "vertical", display_mtf: Any = None, min_mtf: float = 0.02,
         max_frequency: Any = "nyquist", camera: CameraGeometry | None = None, name: str | None = None) -> Curve:
    """The objective MRTD curve of a camera from its MTF and noise (module docstring).

    Parameters
    ----------
    mtf : Curve or (x, y)
        System MTF across the bars (``y`` a ratio; % is converted). Frequencies in cy/px, or
        cy/mrad / lp/mm with ``camera``; an unknown unit is taken as cy/px (with a
        :class:`~irfidelity.curves.CurveUnitsWarning`).
    netd : float, optional
        Noise-equivalent temperature difference, K (``σ_tvh`` in kelvin). Default ``noise.netd``.
    noise : Noise3D, optional
        The 3-D noise of the camera: its components relative to ``σ_tvh`` give ``k(f)``.
    snr_threshold : float
        Threshold SNR of the bar–gap difference (``SNR_T``).
    eye_time : float
        Eye integration time, seconds.
    frame_rate : float, optional
        Frames per second; the eye integrates ``max(1, eye_time · frame_rate)`` frames. None:
        one frame (an objective, single-frame MRTD).
    bar_length : float
        Bar length in bar widths (7 for 7:1 bars).
    orientation : "vertical" | "horizontal"
        Orientation of the bars: vertical bars (the horizontal MRTD) vary along the rows.
    display_mtf : Curve or (x, y), optional
        MTF of the display (and any other stage after the noise), multiplied into ``mtf``; same
        frequency unit, covering its range.
    min_mtf : float
        The curve ends before the first frequency where the system MTF is at most this (the
        MRTD grows without bound there).
    max_frequency : "nyquist" | float | None
        Highest frequency: the Nyquist frequency 0.5 cy/px (default), a value in the MTF's
        unit, or None for no limit.
    camera : CameraGeometry, optional
    name : str, optional

    Returns
    -------
    Curve
        ``x`` the MTF's frequencies above 0 (in its unit), ``y`` the MRTD in kelvin
        (``y_unit="delta_K"``); ``meta`` the model's parameters, ``noise_factor`` (``k`` at
        each frequency) and ``ends_at`` (the frequency where ``min_mtf`` cut it, or None).

    Raises
    ------
    FidelityError
        A NETD that is not > 0 (or missing), a bad parameter, or fewer than 3 frequencies
        left.

    Warns
    -----
    MRTDWarning
        The curve ends before the MTF's range does (system MTF ≤ ``min_mtf``).

    Examples
    --------
    >>> f = np.linspace(0, 0.4, 9)
    >>> m = Curve(f, np.exp(-2 * np.pi**2 * f**2), x_unit="cy/px")  # Gaussian blur, sigma 1 px
    >>> c = mrtd(m, netd=0.05, frame_rate=30.0)
    >>> c.y_unit, round(float(c(0.25)), 4)  # 1.319 * 2.5 * 0.05 K * 0.25 / (0.2912 * sqrt(6))
    ('delta_K', 0.0578)
    """
    curve = as_curve(mtf, "MTF curve")
    if netd is None:
        netd = getattr(noise, "netd", None)
        if netd is None:
            raise FidelityError("the MRTD needs the NETD: give netd= (K) or a Noise3D measured with sitf=",
                                option="netd")
    scale = positive(netd, "netd")
    threshold = positive(snr_threshold, "snr_threshold")
    length = positive(bar_length, "bar_length")
    frames = integrated_frames(eye_time, frame_rate)
    if orientation not in _ALONG_BAR:
        raise FidelityError(f"orientation must be 'vertical' or 'horizontal', got {orientation!r}")
    floor = float(min_mtf)
    if not 0 <= floor < 1:
        raise FidelityError(f"min_mtf must be in [0, 1), got {min_mtf!r}")
    f_px = _pixel_frequencies(curve, camera, "MTF")
    system = _ratio(curve) * _display(display_mtf, curve, camera)
    keep = (f_px > 0) & (f_px <= _limit(max_frequency, curve, camera))
    ends_at = None
    low = keep & (system <= floor)
    if low.any():
        first = int(np.argmax(low))
        ends_at = float(curve.x[first])
        keep &= np.arange(curve.x.size) < first
        warnings.warn(f"the MRTD curve ends at {ends_at:g} {curve.x_unit or ''}: the system MTF falls to "
                      f"{system[first]:.3g} <= min_mtf {floor:g} there", MRTDWarning, stacklevel=2)
    if keep.sum() < 3:
        raise FidelityError(f"the MRTD curve needs at least 3 frequencies above 0 where the MTF exceeds {floor:g}, "
                            f"got {int(keep.sum())}")
    f = f_px[keep]
    k = noise_factor(noise, f, frames, length, orientation)
    values = MRTD_CONSTANT * threshold * scale * np.sqrt(2 * 4 * f ** 2 / (length * frames)) * k / system[keep]
    meta = {"model": "classical MRTD (NVL/Holst), 3-D noise terms of FLIR92", "netd": scale,
            "snr_threshold": threshold, "eye_time": float(eye_time), "frame_rate": frame_rate, "frames": frames,
            "bar_length": length, "orientation": orientation, "noise_factor": k, "ends_at": ends_at}
    return Curve(curve.x[keep], values, name=name or "MRTD (model)", x_unit=curve.x_unit, y_unit="delta_K",
                 meta=meta)


def _display(display_mtf: Any, curve: Curve, camera: CameraGeometry | None) -> np.ndarray:
    if display_mtf is None:
        return np.ones(curve.x.size)
    d = as_curve(display_mtf, "display MTF")
    x = d.x if d.x_unit == curve.x_unit or d.x_unit is None or curve.x_unit is None else \
        convert(d.x, d.x_unit, curve.x_unit, camera=camera)
    if x[0] > curve.x[0] or x[-1] < curve.x[-1]:
        raise FidelityError(f"display_mtf covers {x[0]:g}..{x[-1]:g}, not the MTF's range "
                            f"{curve.x[0]:g}..{curve.x[-1]:g}", option="display_mtf")
    return np.interp(curve.x, x, _ratio(d))


def _limit(max_frequency: Any, curve: Curve, camera: CameraGeometry | None) -> float:
    """The highest frequency kept, in cycles/pixel."""
    if max_frequency is None:
        return math.inf
    if isinstance(max_frequency, str):
        if max_frequency != "nyquist":
            raise FidelityError(f"max_frequency must be 'nyquist', a number or None, got {max_frequency!r}")
        return 0.5
    limit = positive(max_frequency, "max_frequency")
    if curve.x_unit is None:
        return limit
    return float(convert([limit], curve.x_unit, "cy/px", camera=camera)[0])


# --------------------------------------------------------------------------- measured MRTD
def _frame(item: Any, index: int) -> Any:
    if isinstance(item, (str, os.PathLike)):
        from ..frames import load_frame
        return load_frame(item)
    return item


def _per_frame(values: Any, count: int, what: str) -> np.ndarray:
    a = np.atleast_1d(np.asarray(values, dtype=np.float64))
    if a.shape != (count,):
        raise FidelityError(f"{what} must hold one number per frame ({count}), got shape {a.shape}", option=what)
    if not np.isfinite(a).all():
        raise FidelityError(f"{what} must be finite, got {a.tolist()}", option=what)
    return a


def _rois(rois: Any, count: int) -> list[Any]:
    if rois is None:
        return [None] * count
    if len(rois) == 4 and all(isinstance(v, (int, np.integer)) for v in rois):
        return [tuple(rois)] * count
    out = list(rois)
    if len(out) != count:
        raise FidelityError(f"rois: {len(out)} for {count} frames; give one roi, or one per frame", option="rois")
    return out


def _crossing(delta: np.ndarray, stat: np.ndarray, threshold: float) -> float | None:
    """The ΔT at which the statistic reaches ``threshold``: it grows in proportion to ΔT, so
    its slope is fitted through the origin (least squares) to the frames below
    ``FIT_LIMIT`` times the threshold (the frames of the smallest ΔT when none is), and the
    MRTD is ``threshold / slope``; None when no frame reaches the threshold (no extrapolation)."""
    if not (stat >= threshold).any():
        return None
    low = stat < FIT_LIMIT * threshold
    if not low.any():
        low = delta == delta.min()
    slope = float((delta[low] * stat[low]).sum() / (delta[low] ** 2).sum())
    return threshold / slope if slope > 0 else None


def measured_mrtd(frames: Sequence[Any], *, frequencies: Any, delta_t: Any, rois: Any = None,
                  orientation: str | None = None, bars: int = 4, bar_length: float = 7.0,
                  snr_threshold: float = 2.5, eye_time: float = 0.2, frame_rate: float | None = None,
                  background: float | None = None, noise: float | None = None, unit: str = "cy/px",
                  camera: CameraGeometry | None = None, name: str | None = None) -> Curve:
    """The objective MRTD measured on frames of bar targets at known temperature differences.

    For each frequency the target is located in its frame of largest ``|ΔT|`` (found
    automatically, or in its ROI) and read at that place in every frame of the frequency
    (:func:`~irfidelity.curves.ctf_from_bars`'s bar SNR: the difference of the mean profile
    over the bars and over the gaps against the noise of one bar–gap difference, each frame's
    own background and noise). The statistic ``SNR · √N`` (``N`` frames integrated, as in
    :func:`mrtd`) grows in proportion to ``ΔT``; the MRTD is the smallest ``|ΔT|`` at which it
    reaches ``snr_threshold``, interpolated on the line through the origin fitted (least
    squares) to the frames whose statistic is below 4 times the threshold — a fit rather than
    the first frame above the threshold, which the noise of the small-ΔT frames would pull
    low; at least one frame must reach the threshold (no extrapolation). Hot (ΔT > 0) and cold
    (ΔT < 0) bars give one MRTD each; with both, the MRTD is their mean (which cancels an offset
    of the ΔT scale, as the MRTD test does).

    Parameters
    ----------
    frames : sequence of 2-D arrays or paths
        One target per frame (a frame may hold others; the one at its frequency is read).
    frequencies : sequence of float
        Each frame's bar frequency, in ``unit``.
    delta_t : sequence of float
        Each frame's temperature difference bars − background, K (not 0).
    rois : (row_start, row_stop, col_start, col_stop) or sequence of them, optional
        One ROI for every frame, or one per frame (None entries found automatically).
    orientation : "vertical" | "horizontal", optional
    bars, bar_length : int, float
        Bars per target and their length in bar widths.
    snr_threshold, eye_time, frame_rate
        As in :func:`mrtd`.
    background, noise : float, optional
        As in :func:`~irfidelity.curves.ctf_from_bars` (default: each frame's own).
    unit, camera
        Unit of ``frequencies`` and the camera constants.
    name : str, optional

    Returns
    -------
    Curve
        ``x`` the resolved frequencies (in ``unit``, increasing), ``y`` the MRTD in K;
        ``meta["frames"]`` per frequency the ``(ΔT, SNR)`` of its frames, ``meta["unresolved"]``
        the frequencies no frame resolved.

    Raises
    ------
    FidelityError
        Mismatched lengths, a ΔT of 0 (a flat target: its SNR is 0 by definition, leave it
        out), a frequency at or above Nyquist, a bad ROI, or fewer than 3 resolved
        frequencies.

    Warns
    -----
    MRTDWarning
        Frequencies that no frame resolves at the threshold, or whose target cannot be found
        or shows no bars in the frame of largest ΔT (left out of the curve, with the reason).
    BarPolarityWarning
        Inverted polarity: a frame whose bars stand out of the background with the sign
        opposite to its ΔT's (relative to the frame of largest ΔT).

    Examples
    --------
    >>> from irfidelity.targets import four_bar, gaussian_otf
    >>> rng = np.random.default_rng(1)
    >>> frames, freqs, dts = [], [], []
    >>> for f in (0.05, 0.1, 0.15):
    ...     for dt in (0.02, 0.05, 0.1, 0.2):
    ...         frames.append(four_bar(f, (96, 96), otf=gaussian_otf(1.0), levels=(0, dt)) + rng.normal(0, 0.05, (96, 96)))
    ...         freqs.append(f); dts.append(dt)
    >>> c = measured_mrtd(frames, frequencies=freqs, delta_t=dts)
    >>> c.y_unit, bool(np.all(np.diff(c.y) > 0))
    ('delta_K', True)
    """
    frame_list = list(frames)
    count = len(frame_list)
    f_in = _per_frame(frequencies, count, "frequencies")
    dts = _per_frame(delta_t, count, "delta_t")
    zero = np.flatnonzero(dts == 0)
    if zero.size:
        raise FidelityError(f"frame {int(zero[0])}: ΔT = 0 is a flat target (its bar SNR is 0 by definition); "
                            f"leave it out", option="delta_t")
    bars, length = check_options("modulation", bars, bar_length)
    threshold = positive(snr_threshold, "snr_threshold")
    frames_integrated = integrated_frames(eye_time, frame_rate)
    roi_list = _rois(rois, count)
    f_px = np.array([cycles_per_pixel(f, unit=unit, camera=camera) for f in f_in])
    for f in f_px:
        below_nyquist(float(f))
    resolved, unresolved, details, reasons = [], [], [], []
    for freq in np.unique(f_in):
        members = np.flatnonzero(f_in == freq)
        stats, reason = _frequency_stats(frame_list, members, float(f_px[members[0]]), dts, roi_list, orientation,
                                         bars, length, background, noise)
        values = []
        if stats is not None:
            stat = stats * math.sqrt(frames_integrated)
            found = [_crossing(np.abs(dts[members][sign]), stat[sign], threshold)
                     for sign in (dts[members] > 0, dts[members] < 0) if sign.any()]
            values = [v for v in found if v is not None]
            details.append({"frequency": float(freq), "delta_t": dts[members].tolist(), "snr": stats.tolist()})
            reason = reason or f"no frame reaches the threshold SNR {threshold:g}"
        if values:
            resolved.append((float(freq), float(np.mean(values))))
        else:
            unresolved.append(float(freq))
            reasons.append(f"{freq:g} {unit} ({reason})")
    if unresolved:
        warnings.warn(f"bars unresolved at {'; '.join(reasons)}: left out of the measured MRTD (take frames at larger "
                      f"ΔT)", MRTDWarning, stacklevel=2)
    if len(resolved) < 3:
        raise FidelityError(f"a measured MRTD curve needs at least 3 resolved frequencies, got {len(resolved)}"
                            + (f" ({len(unresolved)} unresolved)" if unresolved else ""))
    x, y = zip(*resolved)
    meta = {"snr_threshold": threshold, "eye_time": float(eye_time), "frame_rate": frame_rate,
            "frames": frames_integrated, "bar_length": length, "details": details, "unresolved": unresolved}
    return Curve(x, y, name=name or "MRTD (measured)", x_unit=canonical_unit(unit, what="unit"), y_unit="delta_K",
                 meta=meta)


def _frequency_stats(frames: list[Any], members: np.ndarray, f: float, dts: np.ndarray, rois: list[Any],
                     orientation: str | None, bars: int, length: float, background: float | None,
                     noise: float | None) -> tuple[np.ndarray | None, str | None]:
    """The bar SNR of each frame of one frequency, the target located in the frame of largest
    |ΔT| and read at that place in every frame; None and the reason when that frame shows no
    target, or bars within the noise."""
    reference = int(members[np.argmax(np.abs(dts[members]))])
    pixels, clip = frame_pixels(_frame(frames[reference], reference), what=f"frame {reference}")
    if rois[reference] is None:
        try:
            region, side, fallback = target_region(pixels, None, f, orientation, bars)
        except FidelityError as exc:
            return None, f"frame {reference}, of the largest ΔT: {exc}"
    else:
        region, side, fallback = target_region(pixels, rois[reference], f, orientation, bars)
    try:
        geometry, _, first = read_bars(pixels, frequency=f, roi=region, orientation=side, bars=bars,
                                       bar_length=length, background=background, noise=noise, clip=clip,
                                       fallback_background=fallback)
    except FidelityError as exc:
        raise FidelityError(f"frame {reference} ({f:g} cy/px, ΔT {dts[reference]:g} K): {exc}") from None
    if not abs(first.fundamental) > RESOLVED_SIGMAS * first.fundamental_error:
        return None, f"frame {reference}, of the largest ΔT, shows no bars beyond the noise"
    out = np.empty(members.size)
    for row, index in enumerate(members):
        same_sign = np.sign(dts[index]) == np.sign(dts[reference])
        expected: BarGeometry = geometry if same_sign else replace(geometry, polarity=-geometry.polarity)
        frame, _ = frame_pixels(_frame(frames[index], int(index)), what=f"frame {int(index)}")
        if frame.shape != pixels.shape:
            raise FidelityError(f"frame {int(index)} is {frame.shape}, frame {reference} of the same frequency "
                                f"{pixels.shape}")
        _, _, signal = read_bars(frame, frequency=f, roi=region, orientation=side, bars=bars, bar_length=length,
                                 background=background, noise=noise, clip=None, fallback_background=fallback,
                                 geometry=expected)
        standing = signal.amplitude / signal.amplitude_error if signal.amplitude_error > 0 else 0.0
        if standing < -5:
            warnings.warn(f"inverted polarity in frame {int(index)}: its bars stand out of the background with the "
                          f"sign opposite to its ΔT {dts[index]:g} K (relative to frame {reference})",
                          BarPolarityWarning, stacklevel=3)
        out[row] = signal.snr
    return out, None
