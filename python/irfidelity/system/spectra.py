"""The sums a transfer estimate starts from, computed in Rust: Welch sums over windowed tiles
(``_core.cross_spectra``) and the whole-frame spectrum of block means (``_core.low_spectrum``).
Mergeable, so the frames of a sequence pool into one estimate."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _core, budget
from ..errors import ShapeError
from ..frames import FRAME_DTYPES
from .rings import displacement, unchanged

__all__ = ["GROUPS", "TransferSpectra", "tile_size", "tiling", "transfer_spectra"]

#: Runs of neighbouring tiles kept apart for the jackknife standard errors.
GROUPS = 8

#: Tiles overlap by half unless the frame holds at least this many without overlap: the
#: overlap doubles the statistical information of the Hann-windowed tiles and quadruples their
#: cost, which only small frames need.
DISJOINT_TILES = 64


def tile_size(shape: tuple[int, int]) -> int:
    """The default tile side for frames of ``shape``: 64 px on frames of at least 120 px a side
    (a fine frequency resolution matters more than many tiles: a steep ratio is smeared over
    ±2/tile cy/px), 32 px down to 64 px, else 16 px."""
    side = min(shape)
    return 64 if side >= 120 else 32 if side >= 64 else 16


def tiling(shape: tuple[int, int], tile: int) -> int:
    """The step between tiles: the tile itself when at least :data:`DISJOINT_TILES` disjoint
    tiles fit the frame, else half of it."""
    disjoint = (shape[0] // tile) * (shape[1] // tile)
    return tile if disjoint >= DISJOINT_TILES else tile // 2


@dataclass
class TransferSpectra:
    """The sums a :class:`~irfidelity.system.Transfer` is estimated from, mergeable over the
    frames of a sequence.

    ``tiles`` per group; ``real``, ``sim``, ``cross`` (complex), ``difference`` (None without a
    second real frame) of shape ``(groups, tile, tile//2 + 1)``: Σ|R|², Σ|S|², Σ conj(R)·S and
    Σ|R − R′|² over each group's tiles; ``window_energy`` (Σ w² over a tile); the whole-frame
    spectrum of the ``low_shape`` block-mean frames (blocks of ``factor`` px): ``low_real``,
    ``low_cross`` (complex, the pair's displacement taken out of its phase); the frames' sums
    ``sum_real``, ``sum_sim`` over ``pixels`` scored pixels; ``skipped`` tiles (a pixel not scored or not finite); ``shift``, the pair's
    displacement from the block-mean spectrum (``sim(x) ≈ real(x − d)``; the cross-spectra are
    aligned around it, each tile on its own), and ``shifts`` per group, ``[Σw, Σw·dy, Σw·dx,
    Σw·dy², Σw·dx²]`` over the tiles' own displacements (``w`` their cross power); ``changed``,
    the groups of tiles left out because they saw a different scene (:func:`transfer_spectra`).
    """

    tile: int
    step: int
    tiles: np.ndarray
    real: np.ndarray
    sim: np.ndarray
    cross: np.ndarray
    difference: np.ndarray | None
    window_energy: float
    low_real: np.ndarray
    low_cross: np.ndarray
    low_shape: tuple[int, int]
    factor: int
    sum_real: float
    sum_sim: float
    pixels: int
    skipped: int = 0
    shift: tuple[float, float] = (0.0, 0.0)
    shifts: np.ndarray | None = None
    changed: int = 0

    def poolable(self, other: TransferSpectra) -> bool:
        """Whether :meth:`merge` can add ``other``: the same tiling and frame size."""
        return (self.tile, self.step, self.factor, self.low_shape) == (other.tile, other.step, other.factor,
                                                                        other.low_shape)

    def merge(self, other: TransferSpectra) -> TransferSpectra:
        """The sums of both (frames of one sequence: the same tiling and frame size)."""
        if not self.poolable(other):
            raise ShapeError("transfer spectra of different tilings or frame sizes cannot be merged")
        difference = (None if self.difference is None or other.difference is None
                      else self.difference + other.difference)
        return TransferSpectra(self.tile, self.step, self.tiles + other.tiles, self.real + other.real,
                               self.sim + other.sim, self.cross + other.cross, difference, self.window_energy,
                               self.low_real + other.low_real, self.low_cross + other.low_cross, self.low_shape,
                               self.factor, self.sum_real + other.sum_real, self.sum_sim + other.sum_sim,
                               self.pixels + other.pixels, self.skipped + other.skipped, self.shift,
                               None if self.shifts is None or other.shifts is None else self.shifts + other.shifts,
                               self.changed + other.changed)


def _kernel_frames(real: np.ndarray, sim: np.ndarray, ref: np.ndarray | None) -> tuple:
    """The frames as the Rust passes take them: C-contiguous, ``sim`` of ``real``'s dtype or
    float64, ``ref`` of ``real``'s dtype; other combinations as float64."""
    real, sim = np.ascontiguousarray(real), np.ascontiguousarray(sim)
    same = real.dtype in FRAME_DTYPES and sim.dtype in (real.dtype, np.float64)
    if ref is not None:
        ref = np.ascontiguousarray(ref)
        same = same and ref.dtype == real.dtype
    if not same:
        real, sim = real.astype(np.float64), sim.astype(np.float64)
        ref = None if ref is None else ref.astype(np.float64)
    return real, sim, ref


def _copy_bytes(real: np.ndarray, sim: np.ndarray, ref: np.ndarray | None) -> int:
    """The bytes :func:`_kernel_frames` allocates: every frame as float64 when the dtypes do not
    go together, else a copy of each frame that is not C-contiguous (a cropped or registered
    view)."""
    frames = [f for f in (real, sim, ref) if f is not None]
    same = real.dtype in FRAME_DTYPES and sim.dtype in (real.dtype, np.float64) and (ref is None or ref.dtype == real.dtype)
    copies = sum(f.nbytes for f in frames if not f.flags.c_contiguous)
    return copies + (0 if same else sum(8 * f.size for f in frames))


def transfer_spectra(real: np.ndarray, sim: np.ndarray, *, mask: np.ndarray | None = None,
                     real_ref: np.ndarray | None = None, tile: int | None = None,
                     max_bytes: int | None = None) -> TransferSpectra:
    """The Welch and low-frequency sums of one frame pair (2-D frames of one shape, as scored;
    ``mask`` the scored pixels; ``real_ref`` a second real frame of the scene). The frames, the
    copies the kernel needs and the mask are planned against ``max_bytes`` first."""
    real, sim = np.asarray(real), np.asarray(sim)
    ref = None if real_ref is None else np.asarray(real_ref)
    held = budget.nbytes(real, sim, ref, None if mask is None else np.asarray(mask))
    budget.check("measuring the transfer", real.shape, held + _copy_bytes(real, sim, ref) + real.size, max_bytes)
    real, sim, ref = _kernel_frames(real, sim, ref)
    tile = tile_size(real.shape) if tile is None else int(tile)
    step = tiling(real.shape, tile)
    mask = None if mask is None else np.ascontiguousarray(mask, dtype=bool)
    factor = max(1, min(real.shape) // 64)
    low = _core.low_spectrum(real, sim, mask, factor=factor)
    low_shape = (int(low["rows"]), int(low["cols"]))
    shift = displacement(low["cross_re"] + 1j * low["cross_im"], low_shape, int(low["factor"]))
    welch = _core.cross_spectra(real, sim, ref, mask, tile=tile, step=step, groups=GROUPS, shift=shift)
    welch["cross"] = welch["cross_re"] + 1j * welch["cross_im"]
    changed = ~unchanged(_group_sums(welch, tile)) & (np.asarray(welch["tiles"]) > 0)
    if changed.any():
        welch, low = _without(welch, changed), _core.low_spectrum(real, sim, _masked(mask, real.shape, welch, changed),
                                                                   factor=factor)
    low_cross = _turned(low["cross_re"] + 1j * low["cross_im"], low_shape, int(low["factor"]), shift)
    return TransferSpectra(tile=tile, step=step, tiles=np.asarray(welch["tiles"], dtype=np.int64),
                           real=welch["real"], sim=welch["sim"], cross=welch["cross"],
                           difference=welch.get("difference"), window_energy=float(welch["window_energy"]),
                           low_real=low["real"], low_cross=low_cross,
                           low_shape=(int(low["rows"]), int(low["cols"])), factor=int(low["factor"]),
                           sum_real=float(low["sum_real"]), sum_sim=float(low["sum_sim"]), pixels=int(low["pixels"]),
                           skipped=int(welch["skipped"]), shift=shift,
                           shifts=_absolute(welch["shifts"], welch["offset"]), changed=int(changed.sum()))


def _absolute(shifts: Any, offset: tuple[int, int]) -> np.ndarray:
    """The groups' displacement sums ``[Σw, Σw·dy, Σw·dx, Σw·dy², Σw·dx²]`` measured from the
    whole-pixel ``offset``, made absolute."""
    s = np.asarray(shifts, dtype=np.float64)
    w, oy, ox = s[:, 0], float(offset[0]), float(offset[1])
    return np.stack([w, s[:, 1] + w * oy, s[:, 2] + w * ox, s[:, 3] + 2 * oy * s[:, 1] + w * oy * oy,
                     s[:, 4] + 2 * ox * s[:, 2] + w * ox * ox], axis=1)


def _turned(cross: np.ndarray, shape: tuple[int, int], block: int, d: tuple[float, float]) -> np.ndarray:
    """A block-mean cross-spectrum with the displacement ``d`` (pixels) taken out of its phase."""
    fy, fx = np.fft.fftfreq(shape[0])[:, None] / block, np.fft.rfftfreq(shape[1])[None, :] / block
    return cross * np.exp(2j * np.pi * (fy * d[0] + fx * d[1]))


def _group_sums(welch: dict, tile: int):
    """The per-group ring sums of fresh Welch sums (no noise known yet)."""
    from .rings import Geometry, RingSums

    geometry = Geometry.of(tile)
    groups = len(welch["tiles"])
    real, cross = (geometry.sum_rings(v).reshape(groups, -1) for v in (welch["real"], welch["cross"].real))
    return RingSums(real, real, cross, None, (cross, real), (cross, real), geometry.count,
                    np.asarray(welch["tiles"]))


def _without(welch: dict, changed: np.ndarray) -> dict:
    """The Welch sums with the ``changed`` groups emptied."""
    out = dict(welch)
    for key in ("real", "sim", "cross", "difference"):
        if out.get(key) is not None:
            out[key] = np.where(changed[:, None, None], 0, out[key])
    out["tiles"] = np.where(changed, 0, np.asarray(welch["tiles"]))
    out["shifts"] = np.where(changed[:, None], 0.0, np.asarray(welch["shifts"], dtype=np.float64))
    return out


def _masked(mask: np.ndarray | None, shape: tuple[int, int], welch: dict, changed: np.ndarray) -> np.ndarray:
    """``mask`` without the boxes the ``changed`` groups cover."""
    out = np.ones(shape, dtype=bool) if mask is None else mask.copy()
    for (r0, r1, c0, c1), gone in zip(welch["boxes"], changed):
        if gone:
            out[r0:r1, c0:c1] = False
    return out
