"""Where the bars are: bar targets found in a frame, and one target located in a region of
interest, for :mod:`irfidelity.curves.ctf` to read.

Finding the targets of a frame (:func:`find_bars`), in steps:

1. the frame averaged over 4 × 4 blocks (2 × 2 for frames under 256 px, none under 64), its
   background the median
   level (then the median outside the targets found), its noise from the median absolute
   difference of neighbouring blocks;
2. after a 3 × 3 box mean of the blocks, the blocks deviating from the background by more than
   a quarter of the largest deviation (and by more than 5 times their noise) mark the targets;
3. recursive XY cuts: the marked area is split along every empty band of rows or columns wider
   than the separation between targets (by default 1.5 times the widest bar of the frequencies
   sought, 16 px when none is given), until no band splits it; each piece is one target —
   unless it is shaped like a lone bar (3 times longer than wide): then the separation grows to
   1.5 times its width and the cuts are redone;
4. per piece and for both orientations, the frequency (from the extent across the bars,
   ``(2n - 1)/(2 · extent)``, refined to the peak of the mean profile's Fourier amplitude
   within -20 %/+25 %) and that amplitude against the profile's sum (``(2/π) MTF`` across
   bars, about 0.09 along them: the fundamental of a plateau 7 bar widths long); the
   orientation with the larger ratio is the piece's.

Targets must therefore stand apart by more than the separation, on a background that covers
most of the frame. Locating one target in a region (:func:`locate`): its polarity (the sign of
its summed deviation from the background), its extent along the bars (where the mean profile
along them exceeds half its peak; the central 60 % of it is read), and its centre across the
bars: the phase of the profile's Fourier component at the bar frequency gives the centre modulo
one period, the profile's centroid picks the period (a centre half a period from the centroid
means the fundamental is inverted: contrast reversal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..errors import FidelityError
from .units import FREQUENCY, UNITS, CameraGeometry, _positive, canonical_unit

__all__ = ["BarGroup", "BarGeometry", "find_bars", "find_in", "locate", "detect_orientation", "bar_score", "positive",
           "target_margin", "surround", "cycles_per_pixel", "frame_pixels", "orient",
           "pixel_noise"]

#: fraction of the length of the bars read (centred): the ends are blurred by the bar ends
READ_FRACTION = 0.6
#: a pixel deviating from the background by more than this fraction of the largest deviation marks a target
MARK_FRACTION = 0.25
#: targets are separated by this many times the widest bar sought (default separation)
SEPARATION_BARS = 1.5
#: a marked piece longer than this many times its width is a lone bar, not a target (a 7:1 bar is 7)
LONE_BAR_ASPECT = 3.0
#: a target's longer side in bar widths (7:1 bars), for its margin before its frequency is known
LENGTH_BARS = 7.0
ORIENTATIONS = ("vertical", "horizontal")
Region = tuple[int, int, int, int]


@dataclass(frozen=True)
class BarGroup:
    """A bar target found in a frame by :func:`find_bars`.

    Attributes
    ----------
    roi : (row_start, row_stop, col_start, col_stop)
        The target with a margin of background (:func:`target_margin`, stopping short of other
        targets).
    orientation : "vertical" | "horizontal"
        Vertical bars run along the columns.
    frequency : float
        Estimated bar frequency, cycles/pixel.
    polarity : int
        +1 bars above the background, -1 below.
    background : float
        The frame's background level: the median outside the targets.
    """

    roi: Region
    orientation: str
    frequency: float
    polarity: int
    background: float


@dataclass(frozen=True)
class BarGeometry:
    """Where a target lies in an oriented region (bars varying along the columns).

    Attributes
    ----------
    centre : float
        Column of the target's centre (sub-pixel).
    rows : (start, stop)
        The rows read: the central ``READ_FRACTION`` of the bars' length.
    extent : (start, stop)
        Rows the bars span (half of the peak level).
    polarity : int
        +1 bars above the background, -1 below.
    reversed : bool
        The profile's fundamental is inverted relative to the bars (contrast reversal).
    """

    centre: float
    rows: tuple[int, int]
    extent: tuple[int, int]
    polarity: int
    reversed: bool


# --------------------------------------------------------------------------- inputs
def frame_pixels(image: Any, what: str = "image") -> tuple[np.ndarray, tuple[float, float] | None]:
    """A 2-D frame as float64 and the clipping range of its integer dtype (None for floats)."""
    raw = np.asarray(image)
    if raw.ndim != 2:
        raise FidelityError(f"{what} must be a 2-D array (one channel), got shape {raw.shape}")
    if raw.dtype.kind not in "uif" or raw.size == 0:
        raise FidelityError(f"{what} must hold integer or float pixels, got dtype {raw.dtype} with {raw.size} pixels")
    pixels = raw.astype(np.float64)
    if raw.dtype.kind == "f" and not np.isfinite(pixels).all():
        bad = np.argwhere(~np.isfinite(pixels))
        raise FidelityError(f"{what} has {len(bad)} non-finite pixels, first at (row, col) = "
                            f"({int(bad[0][0])}, {int(bad[0][1])})")
    clip = None
    if raw.dtype.kind in "ui":
        info = np.iinfo(raw.dtype)
        clip = (float(info.min), float(info.max))
    return pixels, clip


def cycles_per_pixel(frequency: Any, *, unit: str | None = "cy/px", camera: CameraGeometry | None = None,
                     what: str = "frequency") -> float:
    """A spatial frequency in cycles/pixel: ``frequency`` in ``unit`` (cy/px, cy/mrad, lp/mm),
    converted with the ``camera`` constants.

    Examples
    --------
    >>> cycles_per_pixel(2.0, unit="cy/mrad", camera=CameraGeometry(ifov_mrad=0.05))
    0.1
    """
    f = positive(frequency, what)
    symbol = canonical_unit(unit, what="unit") or "cy/px"
    if symbol not in UNITS or UNITS[symbol].quantity != FREQUENCY:
        raise FidelityError(f"unit must be a spatial frequency unit (cy/px, cy/mrad, lp/mm), got {unit!r}")
    return f * (camera or CameraGeometry()).scale(symbol, "cy/px")


def positive(value: Any, what: str) -> float:
    """``value`` as a finite number > 0, else a :class:`FidelityError` naming ``what`` (its
    ``option``)."""
    if value is None:
        raise FidelityError(f"{what} must be a number, got None", option=what)
    try:
        return float(_positive(value, what))  # type: ignore[arg-type]
    except FidelityError as exc:
        raise FidelityError(str(exc), option=what) from None


def orient(pixels: np.ndarray, orientation: str) -> np.ndarray:
    """The region with the bars varying along the columns (a view; horizontal bars transposed)."""
    if orientation not in ORIENTATIONS:
        raise FidelityError(f"orientation must be 'vertical', 'horizontal' or None, got {orientation!r}")
    return pixels if orientation == "vertical" else pixels.T


def pixel_noise(values: np.ndarray, axis: int = 0) -> float:
    """Robust pixel noise from differences of neighbours along ``axis``: 1.4826 × the median
    absolute difference / √2 (the standard deviation of differences without signal); the RMS
    difference / √2 when more than half the differences are zero (quantised, nearly noiseless)."""
    d = np.abs(np.diff(values, axis=axis)).ravel()
    if d.size == 0:
        return 0.0
    median = float(np.median(d))
    if median > 0:
        return 1.4826 * median / math.sqrt(2)
    return float(np.sqrt(np.mean(d * d) / 2))


# --------------------------------------------------------------------------- one target in a region
def _fundamental(profile: np.ndarray, frequencies: np.ndarray) -> np.ndarray:
    """``|Σ p(x) e^{-2πifx}|`` at each frequency (real products: fast in every BLAS)."""
    phase = 2 * math.pi * np.outer(frequencies, np.arange(profile.size, dtype=np.float64))
    return np.hypot(np.cos(phase) @ profile, np.sin(phase) @ profile)


def bar_score(oriented: np.ndarray, frequency: float, background: float) -> float:
    """How strongly the profile across the columns varies at ``frequency``: its Fourier amplitude
    there against its sum (``(2/π) MTF`` for bars across the columns, about 0.09 along them)."""
    profile = (oriented - background).mean(axis=0)
    total = abs(float(profile.sum()))
    return float(_fundamental(profile, np.array([frequency]))[0]) / total if total > 0 else 0.0


def detect_orientation(region: np.ndarray, frequency: float, background: float) -> str:
    """The orientation whose profile across the bars carries the stronger fundamental."""
    vertical = bar_score(region, frequency, background)
    horizontal = bar_score(region.T, frequency, background)
    return "vertical" if vertical >= horizontal else "horizontal"


def locate(oriented: np.ndarray, frequency: float, bars: int, background: float) -> BarGeometry:
    """Locate a target in an oriented region (module docstring).

    Raises
    ------
    FidelityError
        A flat region: nothing deviates from the background.
    """
    deviation = oriented - background
    total = float(deviation.sum())
    polarity = 1 if total >= 0 else -1
    along = polarity * deviation.mean(axis=1)
    peak = float(along.max())
    if not peak > 0:
        raise FidelityError("flat target: no pixel of the region differs from the background level "
                            f"{background:.6g} (a temperature difference of 0?)")
    spanned = np.flatnonzero(along > 0.5 * peak)
    start, stop = int(spanned[0]), int(spanned[-1]) + 1
    trim = int(round((1 - READ_FRACTION) / 2 * (stop - start)))
    rows = (start + trim, max(stop - trim, start + trim + 1))
    profile = polarity * deviation[rows[0]:rows[1]].mean(axis=0)
    x = np.arange(profile.size, dtype=np.float64)
    weights = np.clip(profile, 0.0, None)
    centroid = float((weights * x).sum() / weights.sum()) if weights.sum() > 0 else (profile.size - 1) / 2
    # a target of n bars centred at c has a fundamental (-1)^(n-1) |R| e^{-2πifc}
    fundamental = complex((profile * np.exp(-2j * math.pi * frequency * x)).sum()) * (-1) ** (bars - 1)
    period = 1.0 / frequency
    base = -math.atan2(fundamental.imag, fundamental.real) / (2 * math.pi * frequency)
    centre = base + round((centroid - base) / period) * period
    inverted = abs(centre - centroid) > period / 4
    if inverted:
        shifted = base + period / 2
        centre = shifted + round((centroid - shifted) / period) * period
    return BarGeometry(centre=centre, rows=rows, extent=(start, stop), polarity=polarity, reversed=inverted)


def target_margin(frequency: float) -> float:
    """Pixels of background around a target that hold its blurred edges: a bar width, at least
    8 px (a long-tailed PSF, such as diffraction's, spreads the bars' low frequencies that far;
    the target's integral needs them)."""
    return max(1.0 / (2.0 * frequency), 8.0)


def surround(oriented: np.ndarray, geometry: BarGeometry, frequency: float, bars: int) -> np.ndarray:
    """The pixels of the region beyond :func:`target_margin` of the target on every side:
    where its background is read."""
    width = 1.0 / (2.0 * frequency)
    margin = target_margin(frequency)
    half = (2 * bars - 1) * width / 2
    keep = np.ones(oriented.shape, dtype=bool)
    r0 = max(int(math.floor(geometry.extent[0] - margin)), 0)
    r1 = int(math.ceil(geometry.extent[1] + margin))
    c0 = max(int(math.floor(geometry.centre - half - margin)), 0)
    c1 = int(math.ceil(geometry.centre + half + margin)) + 1
    keep[r0:r1, c0:c1] = False
    return oriented[keep]


# --------------------------------------------------------------------------- finding targets in a frame
def _block_mean(pixels: np.ndarray, factor: int) -> np.ndarray:
    """Means of ``factor`` × ``factor`` blocks (the last partial row and column of blocks dropped)."""
    h, w = (s // factor * factor for s in pixels.shape)
    total = np.zeros((h // factor, w // factor))
    for i in range(factor):
        for j in range(factor):
            total += pixels[i:h:factor, j:w:factor]
    return total / (factor * factor)


def _box3(image: np.ndarray) -> np.ndarray:
    """3 × 3 box mean (edges replicated): the marking threshold sees the targets' level, not
    the noise of single blocks."""
    padded = np.pad(image, 1, mode="edge")
    h, w = image.shape
    total = np.zeros((h, w))
    for i in range(3):
        for j in range(3):
            total += padded[i:i + h, j:j + w]
    return total / 9


def _bands(occupied: np.ndarray, min_gap: int) -> list[tuple[int, int]]:
    """Runs of occupied indices separated by more than ``min_gap`` empty ones, as (start, stop)."""
    breaks = np.flatnonzero(np.diff(occupied) > min_gap + 1)
    starts = np.concatenate(([occupied[0]], occupied[breaks + 1]))
    stops = np.concatenate((occupied[breaks], [occupied[-1]])) + 1
    return list(zip(starts.tolist(), stops.tolist()))


def _xy_cut(mask: np.ndarray, min_gap: int) -> list[Region]:
    """Bounding boxes of the pieces of ``mask`` that no empty band wider than ``min_gap`` splits."""
    pieces: list[Region] = []
    pending: list[Region] = [(0, mask.shape[0], 0, mask.shape[1])]
    while pending:
        r0, r1, c0, c1 = pending.pop()
        block = mask[r0:r1, c0:c1]
        rows = np.flatnonzero(block.any(axis=1))
        if rows.size == 0:
            continue
        cols = np.flatnonzero(block.any(axis=0))
        row_bands, col_bands = _bands(rows, min_gap), _bands(cols, min_gap)
        if len(row_bands) > 1:
            pending.extend((r0 + a, r0 + b, c0, c1) for a, b in row_bands)
        elif len(col_bands) > 1:
            pending.extend((r0, r1, c0 + a, c0 + b) for a, b in col_bands)
        else:
            pieces.append((r0 + int(rows[0]), r0 + int(rows[-1]) + 1, c0 + int(cols[0]), c0 + int(cols[-1]) + 1))
    return pieces


def _targets(mask: np.ndarray, min_gap: int) -> list[Region]:
    """XY cuts of ``mask`` into targets: while a piece is shaped like a lone bar (one side more
    than ``LONE_BAR_ASPECT`` times the other) the separation grows past its width and the cut is
    redone, so the bars of a target wider than the separation sought stay together."""
    while True:
        pieces = [p for p in _xy_cut(mask, min_gap) if (p[1] - p[0]) * (p[3] - p[2]) >= 4]
        bar_widths = [min(r1 - r0, c1 - c0) for r0, r1, c0, c1 in pieces
                      if max(r1 - r0, c1 - c0) > LONE_BAR_ASPECT * min(r1 - r0, c1 - c0)]
        wider = max((int(math.ceil(SEPARATION_BARS * w)) for w in bar_widths), default=0)
        if wider <= min_gap:
            return pieces
        min_gap = wider


def _grown(piece: Region, pad: int, shape: tuple[int, ...]) -> Region:
    r0, r1, c0, c1 = piece
    return max(r0 - pad, 0), min(r1 + pad, shape[0]), max(c0 - pad, 0), min(c1 + pad, shape[1])


def _clear_of(roi: Region, piece: Region, others: list[Region]) -> Region:
    """``roi`` (``piece`` grown) shrunk on each side so that it stops short of the other pieces."""
    r0, r1, c0, c1 = roi
    for o0, o1, p0, p1 in others:
        if o1 <= r0 or o0 >= r1 or p1 <= c0 or p0 >= c1:
            continue  # no overlap
        rows_apart = o1 <= piece[0] or o0 >= piece[1]
        if rows_apart:
            r0, r1 = (max(r0, (o1 + piece[0]) // 2), r1) if o1 <= piece[0] else (r0, min(r1, (o0 + piece[1] + 1) // 2))
        elif p1 <= piece[2]:
            c0 = max(c0, (p1 + piece[2]) // 2)
        else:
            c1 = min(c1, (p0 + piece[3] + 1) // 2)
    return r0, r1, c0, c1


def _background_outside(coarse: np.ndarray, grown: list[Region], factor: int) -> float:
    """The median of the frame outside the targets grown by their margins (pixel regions); of
    the frame's border when they leave fewer than 64 blocks."""
    outside = np.ones(coarse.shape, dtype=bool)
    for r0, r1, c0, c1 in grown:
        outside[r0 // factor:-(-r1 // factor), c0 // factor:-(-c1 // factor)] = False
    step = 2 if outside.size >= 4096 else 1  # every other block: enough for a median, and faster
    sample = coarse[::step, ::step][outside[::step, ::step]]
    if sample.size >= 64:
        return float(np.median(sample))
    return float(np.median(np.concatenate((coarse[0], coarse[-1], coarse[:, 0], coarse[:, -1]))))


def _estimate_frequency(oriented: np.ndarray, bars: int, background: float) -> tuple[float, int, float]:
    """Bar frequency (cy/px), polarity and :func:`bar_score` of a target across the columns of
    an oriented region."""
    deviation = oriented - background
    polarity = 1 if deviation.sum() >= 0 else -1
    profile = polarity * deviation.mean(axis=0)
    marked = np.flatnonzero(profile > MARK_FRACTION * profile.max())
    extent = float(marked[-1] - marked[0] + 1) if marked.size else float(profile.size)
    guess = (2 * bars - 1) / (2 * extent)
    trial = np.linspace(0.8, 1.25, 46) * guess
    amplitude = _fundamental(profile, trial)
    best = int(np.argmax(amplitude))
    refined = float(trial[best]) if 0 < best < trial.size - 1 else guess
    total = abs(float(profile.sum()))
    return min(refined, 0.5), polarity, float(amplitude[best]) / total if total > 0 else 0.0


def find_bars(image: Any, *, frequencies: Sequence[float] | float | None = None, bars: int = 4,
              separation: float | None = None, unit: str = "cy/px",
              camera: CameraGeometry | None = None) -> list[BarGroup]:
    """The bar targets of a frame (module docstring), ordered by row, then column.

    Parameters
    ----------
    image : 2-D array_like
    frequencies : float or sequence of float, optional
        The frequencies of the targets sought (in ``unit``): they set the default separation.
    bars : int
        Bars per target.
    separation : float, optional
        Narrowest band of background between two targets, pixels; default 1.5 times the widest
        bar of ``frequencies`` (16 px without them).
    unit, camera
        Unit of ``frequencies`` and the camera constants converting it to cycles/pixel.

    Returns
    -------
    list of BarGroup
        Empty when nothing stands out of the background.

    Examples
    --------
    >>> from irfidelity.targets import four_bar
    >>> frame = four_bar(0.1, (100, 160), centre=(50, 40)) + four_bar(0.2, (100, 160), centre=(50, 120))
    >>> [(g.orientation, round(g.frequency, 2)) for g in find_bars(frame, frequencies=[0.1, 0.2])]
    [('vertical', 0.1), ('vertical', 0.2)]
    """
    pixels, _ = frame_pixels(image)
    return find_in(pixels, frequencies=frequencies, bars=bars, separation=separation, unit=unit, camera=camera)


def find_in(pixels: np.ndarray, *, frequencies: Sequence[float] | float | None = None, bars: int = 4,
            separation: float | None = None, unit: str = "cy/px",
            camera: CameraGeometry | None = None) -> list[BarGroup]:
    """:func:`find_bars` on float64 pixels already checked by :func:`frame_pixels`."""
    if separation is None:
        sought = [] if frequencies is None else np.atleast_1d(np.asarray(frequencies, dtype=np.float64)).tolist()
        widest = max((1.0 / (2.0 * cycles_per_pixel(f, unit=unit, camera=camera)) for f in sought), default=None)
        gap = SEPARATION_BARS * widest if widest is not None else 16.0
    else:
        gap = float(separation)
        if not (math.isfinite(gap) and gap > 0):
            raise FidelityError(f"separation must be finite and > 0 pixels, got {separation!r}")
    factor = 4 if min(pixels.shape) >= 256 else 2 if min(pixels.shape) >= 64 else 1
    coarse = _block_mean(pixels, factor)
    background = float(np.median(coarse[::2, ::2]))
    noise = pixel_noise(coarse[::2], axis=1) / 3  # every other row of blocks: enough for a median; /3: smoothed
    deviation = np.abs(_box3(coarse) - background)
    peak = float(deviation.max())
    if not peak > 5 * noise:
        return []
    mask = deviation > max(MARK_FRACTION * peak, 5 * noise)
    pieces = [(r0 * factor, r1 * factor, c0 * factor, c1 * factor)
              for r0, r1, c0, c1 in _targets(mask, int(math.ceil(gap / factor)))]
    # margins from the piece's size: its longer side is the bars' length, 7 bar widths
    pads = [int(math.ceil(target_margin(LENGTH_BARS / (2.0 * max(r1 - r0, c1 - c0))))) for r0, r1, c0, c1 in pieces]
    background = _background_outside(coarse, [_grown(p, pad, pixels.shape) for p, pad in zip(pieces, pads)], factor)
    groups = []
    for index, (piece, pad) in enumerate(zip(pieces, pads)):
        roi = _clear_of(_grown(piece, pad, pixels.shape), piece, [p for i, p in enumerate(pieces) if i != index])
        region = pixels[roi[0]:roi[1], roi[2]:roi[3]]
        readings = {side: _estimate_frequency(orient(region, side), bars, background) for side in ORIENTATIONS}
        orientation = max(ORIENTATIONS, key=lambda side: readings[side][2])
        frequency, polarity, _ = readings[orientation]
        groups.append(BarGroup(roi=roi, orientation=orientation, frequency=frequency, polarity=polarity,
                               background=background))
    return sorted(groups, key=lambda g: (g.roi[0], g.roi[2]))
