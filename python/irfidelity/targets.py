"""Test targets as an engineer feeds them to a simulator or a collimator: four- and three-bar
patterns (7:1 bars) and slanted edges, rendered exactly.

Every pixel is the mean of the ideal pattern over its square footprint (area sampling), so a
rendering is exact at any sub-pixel position ("phase") and needs no oversampling:

* without an optical transfer function (``otf=None``) the pixel values are the exact areas: a
  bar target is a union of rectangles sharing one extent along the bars, whose pixel averages
  are products of one-dimensional interval overlaps; an edge's pixel average is the
  trapezoidal distribution of a half-plane over a square;
* with an ``otf`` (:func:`gaussian_otf`, :func:`diffraction_otf`, or their product) the
  pattern is seen through that optical transfer function and then integrated over each pixel:
  the pixel values are the samples of ``pattern ⊛ PSF ⊛ pixel box``, computed from the
  pattern's analytic Fourier transform ``T`` by Poisson summation,

  .. math::

      \\sum_n g[n]\\, e^{-2\\pi i f n} = \\sum_{m} T(f + m)\\,\\mathrm{OTF}(f + m)\\,
      \\mathrm{sinc}(f_x + m_x)\\,\\mathrm{sinc}(f_y + m_y),

  summed over every alias ``m`` where the OTF exceeds 1e-13 and evaluated on the DFT grid of a
  frame padded against wrap-around. The system MTF of such an image along x is therefore
  ``OTF(f, 0) · |sinc(f)|`` exactly, which is what the accuracy tests compare with.

Frequencies are in cycles per pixel, or in cycles/mrad or lp/mm with a
:class:`~irfidelity.curves.CameraGeometry`. A bar target at frequency ``f`` has bars ``W =
1/(2f)`` pixels wide, separated by gaps of the same width, ``bar_length · W`` long (7 for the
standard 7:1 bars of ASTM E1213 and STANAG 4349): a four-bar target is a ``7W × 7W`` square.

``orientation="vertical"`` draws bars running along the columns (the intensity changes along a
row: the horizontal resolution, as for ``mtf_from_edge``); ``"horizontal"`` the transpose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .curves.bars import cycles_per_pixel, positive
from .curves.units import CameraGeometry
from .errors import FidelityError

__all__ = ["four_bar", "three_bar", "bar_target", "slanted_edge", "OTF", "gaussian_otf", "diffraction_otf"]

#: an OTF below this is treated as zero when the aliases are summed
OTF_FLOOR = 1e-13
_ORIENTATIONS = ("vertical", "horizontal")


# --------------------------------------------------------------------------- optical transfer functions
@dataclass(frozen=True)
class OTF:
    """A rotationally symmetric optical transfer function of spatial frequency (cycles/pixel).

    Attributes
    ----------
    name : str
    radial : callable
        ``OTF`` as a function of the radial frequency ``ρ = √(fx² + fy²)``.
    support : float
        Radial frequency beyond which ``|OTF| < 1e-13`` (0 exactly for a band-limited OTF).
    factor : callable or None
        The one-dimensional factor when ``OTF(fx, fy) = factor(fx) · factor(fy)`` (a
        Gaussian); None otherwise. Rendering uses it to sum the aliases axis by axis.

    Examples
    --------
    >>> otf = gaussian_otf(1.0) * diffraction_otf(0.8)
    >>> otf.name, round(float(otf(0.2, 0.0)), 4), otf.support
    ('gaussian(sigma=1 px) x diffraction(cutoff=0.8 cy/px)', 0.311, 0.8)
    """

    name: str
    radial: Callable[[np.ndarray], np.ndarray]
    support: float
    factor: Callable[[np.ndarray], np.ndarray] | None = None

    def __call__(self, fx: Any, fy: Any = 0.0) -> np.ndarray:
        """The OTF at ``(fx, fy)`` cycles/pixel."""
        return self.radial(np.hypot(np.asarray(fx, dtype=np.float64), np.asarray(fy, dtype=np.float64)))

    def __mul__(self, other: OTF) -> OTF:
        """The cascade of two OTFs (their product)."""
        if not isinstance(other, OTF):
            return NotImplemented
        a, b = self, other
        factor = None
        if a.factor is not None and b.factor is not None:
            fa, fb = a.factor, b.factor
            factor = lambda f: fa(f) * fb(f)  # noqa: E731
        return OTF(name=f"{a.name} x {b.name}", radial=lambda rho: a.radial(rho) * b.radial(rho),
                   support=min(a.support, b.support), factor=factor)


def gaussian_otf(sigma: float) -> OTF:
    """The OTF of a Gaussian PSF of standard deviation ``sigma`` pixels:
    ``exp(-2π² σ² ρ²)`` (separable).

    Examples
    --------
    >>> round(float(gaussian_otf(1.0)(0.25)), 4)  # exp(-2π² / 16)
    0.2912
    """
    s = positive(sigma, "sigma")
    k = -2 * math.pi ** 2 * s * s

    def gauss(f: np.ndarray) -> np.ndarray:
        return np.exp(k * np.asarray(f, dtype=np.float64) ** 2)

    support = math.sqrt(math.log(1 / OTF_FLOOR) / (2 * math.pi ** 2)) / s
    return OTF(name=f"gaussian(sigma={s:g} px)", radial=gauss, support=support, factor=gauss)


def diffraction_otf(cutoff: float) -> OTF:
    """The diffraction-limited OTF of a circular aperture with cutoff ``cutoff`` cycles/pixel
    (``1/(λ N)`` in the pixel's units): with ``r = ρ / cutoff``,
    ``(2/π) (arccos r − r √(1 − r²))`` for ``r < 1``, else 0.

    Examples
    --------
    >>> round(float(diffraction_otf(1.0)(0.5)), 4)
    0.391
    """
    fc = positive(cutoff, "cutoff")

    def airy(rho: np.ndarray) -> np.ndarray:
        r = np.minimum(np.abs(np.asarray(rho, dtype=np.float64)) / fc, 1.0)
        return (2 / math.pi) * (np.arccos(r) - r * np.sqrt(1 - r * r))

    return OTF(name=f"diffraction(cutoff={fc:g} cy/px)", radial=airy, support=fc)


# --------------------------------------------------------------------------- the pattern as rectangles
@dataclass(frozen=True)
class _Rect:
    """A rectangle of the pattern: centre ``(x, y)`` in pixel coordinates (pixel ``j`` covers
    ``[j - 0.5, j + 0.5]``), ``width`` along its own first axis, ``height`` along its second,
    first axis at ``angle`` radians from the x axis."""

    x: float
    y: float
    width: float
    height: float
    angle: float = 0.0

    def corners(self) -> list[tuple[float, float]]:
        c, s = math.cos(self.angle), math.sin(self.angle)
        return [(self.x + a * c * self.width / 2 - b * s * self.height / 2,
                 self.y + a * s * self.width / 2 + b * c * self.height / 2) for a in (-1, 1) for b in (-1, 1)]

    def spectrum(self, fx: np.ndarray, fy: np.ndarray) -> np.ndarray:
        """Continuous Fourier transform ``∫∫ 1_rect e^{-2πi(fx x + fy y)}``."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        u, v = fx * c + fy * s, -fx * s + fy * c
        phase = np.exp(-2j * math.pi * (fx * self.x + fy * self.y))
        return self.width * self.height * np.sinc(self.width * u) * np.sinc(self.height * v) * phase


def _overlap(lo: float, hi: float, n: int) -> np.ndarray:
    """Fraction of each of ``n`` unit pixels (pixel ``j`` on ``[j - 0.5, j + 0.5]``) inside ``[lo, hi]``."""
    j = np.arange(n, dtype=np.float64)
    return np.clip(np.minimum(hi, j + 0.5) - np.maximum(lo, j - 0.5), 0.0, 1.0)


def _check_levels(levels: Any) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in levels)
    except (TypeError, ValueError):
        raise FidelityError(f"levels must be (background, target) numbers, got {levels!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise FidelityError(f"levels must be finite, got {levels!r}")
    return lo, hi


def _check_shape(shape: Any) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in shape)
    except (TypeError, ValueError):
        raise FidelityError(f"shape must be (rows, columns), got {shape!r}") from None
    if h < 1 or w < 1:
        raise FidelityError(f"shape must be positive, got {shape!r}")
    return h, w


def _check_orientation(orientation: Any) -> str:
    if orientation not in _ORIENTATIONS:
        raise FidelityError(f"orientation must be 'vertical' or 'horizontal', got {orientation!r}")
    return str(orientation)


def _centre(centre: Any, h: int, w: int) -> tuple[float, float]:
    if centre is None:
        return (h - 1) / 2, (w - 1) / 2
    try:
        row, col = (float(v) for v in centre)
    except (TypeError, ValueError):
        raise FidelityError(f"centre must be (row, column), got {centre!r}") from None
    return row, col


# --------------------------------------------------------------------------- rendering
def _render_rects(shape: tuple[int, int], rects: list[_Rect], otf: OTF) -> np.ndarray:
    """Pixel values of the union of ``rects`` (level 1 on 0) seen through ``otf`` and integrated
    over each pixel, by Poisson summation on a padded DFT grid."""
    h, w = shape
    corners = np.array([c for r in rects for c in r.corners()])
    margin = 32.0  # pixels of empty padding beyond the pattern and the frame, against wrap-around
    pad_x = int(math.ceil(max(margin, w / 2, -corners[:, 0].min() + margin, corners[:, 0].max() - w + margin)))
    pad_y = int(math.ceil(max(margin, h / 2, -corners[:, 1].min() + margin, corners[:, 1].max() - h + margin)))
    rows, cols = h + 2 * pad_y, w + 2 * pad_x
    fy, fx = np.fft.fftfreq(rows), np.fft.fftfreq(cols)
    aliases = int(math.ceil(otf.support + 0.5))
    shifted = [_Rect(r.x + pad_x, r.y + pad_y, r.width, r.height, r.angle) for r in rects]
    if otf.factor is not None and all(r.angle == 0.0 for r in shifted):
        total = _separable_sum(shifted, fx, fy, aliases, otf)
    else:
        total = _full_sum(shifted, fx, fy, aliases, otf)
    image = np.fft.ifft2(total).real
    return image[pad_y:pad_y + h, pad_x:pad_x + w]


def _alias_axis(f: np.ndarray, aliases: int, support: float) -> list[np.ndarray]:
    """The shifted frequency grids ``f + m`` that reach inside the OTF's support."""
    return [f + m for m in range(-aliases, aliases + 1) if np.abs(f + m).min() <= support]


def _separable_sum(rects: list[_Rect], fx: np.ndarray, fy: np.ndarray, aliases: int, otf: OTF) -> np.ndarray:
    """Σ over aliases for axis-aligned rectangles and a separable OTF: per rectangle an outer
    product of two one-dimensional alias sums."""
    assert otf.factor is not None
    total = np.zeros((fy.size, fx.size), dtype=np.complex128)
    grids_x, grids_y = _alias_axis(fx, aliases, otf.support), _alias_axis(fy, aliases, otf.support)
    for r in rects:
        along_x = sum(r.width * np.sinc(r.width * g) * np.exp(-2j * math.pi * g * r.x) * np.sinc(g) * otf.factor(g)
                      for g in grids_x)
        along_y = sum(r.height * np.sinc(r.height * g) * np.exp(-2j * math.pi * g * r.y) * np.sinc(g)
                      * otf.factor(g) for g in grids_y)
        total += np.outer(along_y, along_x)
    return total


def _full_sum(rects: list[_Rect], fx: np.ndarray, fy: np.ndarray, aliases: int, otf: OTF) -> np.ndarray:
    total = np.zeros((fy.size, fx.size), dtype=np.complex128)
    for gy in _alias_axis(fy, aliases, otf.support):
        for gx in _alias_axis(fx, aliases, otf.support):
            ggx, ggy = np.meshgrid(gx, gy)
            transfer = otf(ggx, ggy)
            if not transfer.any():
                continue
            pattern = sum(r.spectrum(ggx, ggy) for r in rects)
            total += pattern * transfer * np.sinc(ggx) * np.sinc(ggy)
    return total


# --------------------------------------------------------------------------- bar targets
def bar_target(frequency: float, shape: Any, *, bars: int = 4, orientation: str = "vertical", phase: float = 0.0,
               levels: Any = (0.0, 1.0), bar_length: float = 7.0, centre: Any = None, otf: OTF | None = None,
               unit: str = "cy/px", camera: CameraGeometry | None = None) -> np.ndarray:
    """A target of ``bars`` parallel bars at spatial ``frequency`` on a uniform background.

    Bar ``i`` (``i = 0 … n-1``) is centred at ``c + (i - (n-1)/2) / f`` across the bars, ``c``
    the target's centre; each bar is ``W = 1/(2f)`` wide and ``bar_length · W`` long. Pixel
    values are exact area averages (module docstring).

    Parameters
    ----------
    frequency : float
        Bar frequency (one bar plus one gap per cycle), in ``unit``.
    shape : (rows, columns)
    bars : int
        Number of bars (≥ 2): 4 for the MRTD target, 3 for the USAF-style one.
    orientation : "vertical" | "horizontal"
        Vertical bars run along the columns (intensity changes along a row).
    phase : float
        Shift of the target across the bars, pixels (sub-pixel shifts sample the bars at other
        phases).
    levels : (background, bar)
        Levels of the background and of the bars (bars below the background are cold bars).
    bar_length : float
        Bar length in bar widths (7 for 7:1 bars).
    centre : (row, column), optional
        Target centre in pixel coordinates (pixel ``j`` covers ``[j - 0.5, j + 0.5]``);
        default the frame centre.
    otf : OTF, optional
        Optical transfer function the target is seen through (:func:`gaussian_otf`,
        :func:`diffraction_otf`); the pixel aperture is always applied.
    unit : str
        Unit of ``frequency``: ``"cy/px"``, ``"cy/mrad"`` or ``"lp/mm"`` (the last two with
        ``camera``).
    camera : CameraGeometry, optional

    Returns
    -------
    numpy.ndarray
        float64, ``shape``.

    Raises
    ------
    FidelityError
        A frequency that is not > 0, a target that does not fit in the frame, or a bad option.

    Examples
    --------
    >>> t = bar_target(0.25, (16, 20), bars=3, phase=0.5)  # bars 2 px wide, half a pixel off the grid
    >>> t[8].round(2).tolist()
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 0.5, 0.0, 0.5, 1.0, 0.5, 0.0, 0.5, 1.0, 0.5, 0.0, 0.0, 0.0, 0.0]
    """
    f = cycles_per_pixel(frequency, unit=unit, camera=camera, what="frequency")
    h, w = _check_shape(shape)
    orientation = _check_orientation(orientation)
    if isinstance(bars, bool) or not isinstance(bars, (int, np.integer)) or bars < 2:
        raise FidelityError(f"bars must be an integer >= 2, got {bars!r}")
    length = positive(bar_length, "bar_length")
    lo, hi = _check_levels(levels)
    row, col = _centre(centre, h, w)
    across, along = (col, row) if orientation == "vertical" else (row, col)
    across += float(phase)
    width = 1.0 / (2.0 * f)
    offsets = (np.arange(bars) - (bars - 1) / 2) / f
    size_across, size_along = (w, h) if orientation == "vertical" else (h, w)
    extent = (2 * bars - 1) * width
    if (across - extent / 2 < -0.5 or across + extent / 2 > size_across - 0.5
            or along - length * width / 2 < -0.5 or along + length * width / 2 > size_along - 0.5):
        raise FidelityError(f"a {bars}-bar target at {f:g} cy/px ({extent:.1f} x {length * width:.1f} px) "
                            f"centred at (row, column) = ({row:g}, {col:g}) does not fit in a {h} x {w} frame")
    if otf is None:
        profile = sum(_overlap(across + o - width / 2, across + o + width / 2, size_across) for o in offsets)
        extent_along = _overlap(along - length * width / 2, along + length * width / 2, size_along)
        pattern = np.outer(extent_along, profile)
    else:
        rects = [_Rect(across + o, along, width, length * width) for o in offsets]
        pattern = _render_rects((size_along, size_across), rects, otf)
    if orientation == "horizontal":
        pattern = pattern.T
    return lo + (hi - lo) * pattern


def four_bar(frequency: float, shape: Any, **options: Any) -> np.ndarray:
    """The four-bar MRTD target (7:1 bars): :func:`bar_target` with ``bars=4``.

    Examples
    --------
    >>> t = four_bar(0.1, (40, 40), levels=(20.0, 21.0))  # bars 5 px wide, 35 px long
    >>> t.shape, float(t.min()), float(t.max()), float(t.mean().round(4))
    ((40, 40), 20.0, 21.0, 20.4375)
    """
    return bar_target(frequency, shape, bars=4, **options)


def three_bar(frequency: float, shape: Any, **options: Any) -> np.ndarray:
    """A three-bar target: :func:`bar_target` with ``bars=3``.

    Examples
    --------
    >>> three_bar(0.125, (32, 48), orientation="horizontal").shape
    (32, 48)
    """
    return bar_target(frequency, shape, bars=3, **options)


# --------------------------------------------------------------------------- slanted edge
def _trapezoid_cdf(s: np.ndarray, a: float, b: float) -> np.ndarray:
    """P(a·U + b·V ≤ s) for U, V uniform on [-1/2, 1/2], a ≥ b ≥ 0: the fraction of a unit
    square on one side of a line at signed distance ``s`` from its centre."""
    if b < 1e-12:
        return np.clip(s / a + 0.5, 0.0, 1.0)
    lo, mid = (a + b) / 2, (a - b) / 2
    rising = (s + lo) ** 2 / (2 * a * b)
    linear = (s + a / 2) / a
    falling = 1 - (lo - s) ** 2 / (2 * a * b)
    return np.where(s <= -lo, 0.0, np.where(s <= -mid, rising, np.where(s <= mid, linear,
                                                                     np.where(s < lo, falling, 1.0))))


def slanted_edge(shape: Any, *, angle: float = 5.0, levels: Any = (0.0, 1.0), centre: Any = None,
                 orientation: str = "vertical", otf: OTF | None = None) -> np.ndarray:
    """A straight edge through ``centre``, tilted ``angle`` degrees from the pixel grid, as the
    ISO 12233 slanted-edge MTF (:func:`irfidelity.curves.mtf_from_edge`) reads it.

    A vertical edge runs along the columns: ``levels[0]`` on its left, ``levels[1]`` on its
    right, turned clockwise by ``angle``. Pixel values are exact area averages, through
    ``otf`` when given (module docstring).

    Parameters
    ----------
    shape : (rows, columns)
    angle : float
        Tilt from the columns (vertical) or rows (horizontal), degrees, within ±45.
    levels : (dark side, bright side)
    centre : (row, column), optional
        A point of the edge; default the frame centre.
    orientation : "vertical" | "horizontal"
    otf : OTF, optional

    Examples
    --------
    >>> e = slanted_edge((8, 8), angle=0.0, centre=(3.5, 3.25))
    >>> e[0].tolist()
    [0.0, 0.0, 0.0, 0.25, 1.0, 1.0, 1.0, 1.0]
    """
    h, w = _check_shape(shape)
    orientation = _check_orientation(orientation)
    lo, hi = _check_levels(levels)
    theta = math.radians(float(angle))
    if not abs(theta) <= math.pi / 4:
        raise FidelityError(f"angle must be within ±45 degrees, got {angle!r}")
    row, col = _centre(centre, h, w)
    size_across, size_along = (w, h) if orientation == "vertical" else (h, w)
    across, along = (col, row) if orientation == "vertical" else (row, col)
    normal = (math.cos(theta), -math.sin(theta))  # (across, along) components
    if otf is None:
        j = np.arange(size_across, dtype=np.float64)[None, :]
        i = np.arange(size_along, dtype=np.float64)[:, None]
        distance = (j - across) * normal[0] + (i - along) * normal[1]
        pattern = 1.0 - _trapezoid_cdf(-distance, abs(normal[0]), abs(normal[1]))
    else:
        reach = math.hypot(h, w) + 32.0
        rect = _Rect(across + normal[0] * reach / 2, along + normal[1] * reach / 2, reach, 2 * reach, -theta)
        pattern = _render_rects((size_along, size_across), [rect], otf)
    if orientation == "horizontal":
        pattern = pattern.T
    return lo + (hi - lo) * pattern
