"""From a tile's half spectra to radial estimates: the frequency geometry, the pair's
displacement from the cross-spectrum's phase, and the ring sums of every group of tiles, from
which the whole estimate and its leave-one-group-out replicates (the jackknife) follow by
subtraction."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, overload

import numpy as np

if TYPE_CHECKING:
    from .spectra import TransferSpectra

__all__ = ["Geometry", "RingSums", "displacement", "ring_sums", "unchanged", "ratio", "jackknife"]


@dataclass(frozen=True, eq=False)
class Geometry:
    """The frequencies of a tile's half spectrum: ``fy``, ``fx`` (cy/px), the ring
    ``k = round(f·tile)`` of each bin, the weight of each stored bin (2 for columns whose
    mirror is not stored), and the bins of the two axes (``horizontal``: frequencies along the
    rows, ``ky = 0``; ``vertical``: ``kx = 0``)."""

    tile: int
    fy: np.ndarray
    fx: np.ndarray
    ring: np.ndarray
    weight: np.ndarray
    horizontal: np.ndarray
    vertical: np.ndarray

    @classmethod
    @functools.lru_cache(maxsize=8)
    def of(cls, tile: int) -> Geometry:
        fy = np.fft.fftfreq(tile)[:, None]
        fx = np.fft.rfftfreq(tile)[None, :]
        weight = np.full((tile, tile // 2 + 1), 2.0)
        weight[:, 0] = weight[:, -1] = 1.0
        ring = np.rint(np.hypot(fy, fx) * tile).astype(np.int64)
        ky = np.broadcast_to(np.rint(fy * tile), ring.shape)
        kx = np.broadcast_to(np.rint(fx * tile), ring.shape)
        return cls(tile, fy, fx, ring, weight, (ky == 0) & (kx > 0), (kx == 0) & (ky > 0))

    @property
    def rings(self) -> int:
        """Rings up to the Nyquist frequency, 0..tile/2."""
        return self.tile // 2 + 1

    @functools.cached_property
    def _order(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The bins within the rings sorted by ring, where each ring starts, their weights."""
        ring = self.ring.ravel()
        inside = np.flatnonzero(ring < self.rings)
        order = inside[np.argsort(ring[inside], kind="stable")]
        starts = np.searchsorted(ring[order], np.arange(self.rings))
        return order, starts, self.weight.ravel()[order]

    def sum_rings(self, values: np.ndarray) -> np.ndarray:
        """Σ weight·values over each ring, rings 0..tile/2, for each row of ``values`` (a stack
        of flattened half spectra; a sparse sum: small matrix products go through a BLAS
        thread pool that costs more than they do)."""
        order, starts, weight = self._order
        flat = np.reshape(values, (-1, self.ring.size))
        return np.add.reduceat(flat[:, order] * weight, starts, axis=1)

    @functools.cached_property
    def count(self) -> np.ndarray:
        """The weighted number of bins of each ring."""
        return self.sum_rings(np.ones(self.ring.size))[0]

    @property
    def frequency(self) -> np.ndarray:
        """The centre of each ring, cy/px."""
        return np.arange(self.rings) / self.tile


def displacement(cross: np.ndarray, shape: tuple[int, int], block: int = 1) -> tuple[float, float]:
    """The displacement ``d`` in pixels of the simulated frame (``sim(x) ≈ real(x − d)``) from
    the phase of a half cross-spectrum of ``shape`` frames of ``block``-pixel blocks (a tile's,
    or the block-mean frames'): the whole-block peak of the phase correlation, then a weighted
    least-squares fit of the remaining phase ramp over the lower half of the frequencies."""
    rows, cols = shape
    size = np.abs(cross)
    surface = np.fft.irfft2(np.where(size > 0, cross / np.where(size > 0, size, 1.0), 0), s=(rows, cols))
    iy, ix = np.unravel_index(int(np.argmax(surface)), surface.shape)
    whole = (block * (iy if iy < rows // 2 else iy - rows), block * (ix if ix < cols // 2 else ix - cols))
    fy, fx = np.fft.fftfreq(rows)[:, None] / block, np.fft.rfftfreq(cols)[None, :] / block
    rest = cross * np.exp(2j * np.pi * (fy * whole[0] + fx * whole[1]))
    f = np.hypot(fy, fx)
    use = (f > 0) & (f < 0.25 / block) & (np.abs(rest) > 0)
    if use.sum() < 3:
        return float(whole[0]), float(whole[1])
    weight = np.abs(rest)[use]
    design = -2 * np.pi * np.stack([np.broadcast_to(fy, f.shape)[use], np.broadcast_to(fx, f.shape)[use]], axis=1)
    normal = design.T @ (weight[:, None] * design)
    if not np.linalg.det(normal) > 0:
        return float(whole[0]), float(whole[1])
    solution = np.linalg.solve(normal, design.T @ (weight * np.angle(rest[use])))
    return float(whole[0] + solution[0]), float(whole[1] + solution[1])


@dataclass(frozen=True)
class RingSums:
    """Σ weight·value over each ring, one row per group of tiles (``groups × rings``): the
    two power spectra, the cross-spectrum's real part (the displacement removed), the real
    camera's noise power (None when unknown), and the axis sums of the cross-spectrum and of
    the real signal (``S_rr`` less the noise); ``count`` is the bins of each ring."""

    real: np.ndarray
    sim: np.ndarray
    cross: np.ndarray
    noise: np.ndarray | None
    horizontal: tuple[np.ndarray, np.ndarray]
    vertical: tuple[np.ndarray, np.ndarray]
    count: np.ndarray
    tiles: np.ndarray

    @property
    def signal(self) -> np.ndarray:
        return self.real if self.noise is None else self.real - self.noise

    def only(self, keep: np.ndarray) -> RingSums:
        """The sums of the groups ``keep`` marks."""
        @overload
        def pick(x: np.ndarray) -> np.ndarray: ...
        @overload
        def pick(x: None) -> None: ...
        def pick(x: np.ndarray | None) -> np.ndarray | None:
            return None if x is None else x[keep]

        return RingSums(pick(self.real), pick(self.sim), pick(self.cross), pick(self.noise),
                        (pick(self.horizontal[0]), pick(self.horizontal[1])),
                        (pick(self.vertical[0]), pick(self.vertical[1])), self.count, self.tiles[keep])

    def replicates(self) -> RingSums:
        """Row 0 the sums of every group; then, for each group with tiles, the sums without it."""
        used = np.flatnonzero(self.tiles > 0)

        @overload
        def rows(x: np.ndarray) -> np.ndarray: ...
        @overload
        def rows(x: None) -> None: ...
        def rows(x: np.ndarray | None) -> np.ndarray | None:
            if x is None:
                return None
            total = x.sum(axis=0, keepdims=True)
            return np.concatenate([total, total - x[used]]) if len(used) > 1 else total

        return RingSums(rows(self.real), rows(self.sim), rows(self.cross), rows(self.noise),
                        (rows(self.horizontal[0]), rows(self.horizontal[1])),
                        (rows(self.vertical[0]), rows(self.vertical[1])), self.count,
                        rows(self.tiles[:, None])[:, 0])


def ring_sums(spectra: TransferSpectra, geometry: Geometry, noise: np.ndarray | None) -> RingSums:
    """The per-group ring sums of the spectra (their cross-spectrum aligned tile by tile in
    Rust; ``noise`` the real camera's noise power per group and bin, or None)."""
    groups = len(spectra.tiles)
    signal = spectra.real if noise is None else spectra.real - noise
    cross = spectra.cross.real
    stack = [spectra.real, spectra.sim, cross, signal, cross * geometry.horizontal, signal * geometry.horizontal,
             cross * geometry.vertical, signal * geometry.vertical] + ([] if noise is None else [noise])
    # each array on its own: a stacked copy of all of them would be megabytes of fresh pages a call
    sums = [geometry.sum_rings(values).reshape(groups, -1) for values in stack]
    return RingSums(sums[0], sums[1], sums[2], None if noise is None else sums[8], (sums[4], sums[5]),
                    (sums[6], sums[7]), geometry.count, np.asarray(spectra.tiles))


#: A group whose transfer over rings 1..3 departs from the groups' median by more than this
#: share (and four robust deviations) saw a different scene: an object that moved or changed.
CHANGED = 0.1


def unchanged(sums: RingSums) -> np.ndarray:
    """The groups that saw the same scene in both frames: their transfer at the lowest rings
    (1..3, where a blur barely acts) agrees with the other groups'. At most a third are left out
    (a change everywhere is the pair's, not a part's)."""
    used = sums.tiles > 0
    low = ratio(sums.cross[:, 1:4].sum(axis=1), sums.signal[:, 1:4].sum(axis=1))
    good = used & np.isfinite(low)
    if good.sum() < 3:
        return used
    median = float(np.median(low[good]))
    spread = 4 * 1.4826 * float(np.median(np.abs(low[good] - median)))
    same = good & (np.abs(low - median) <= max(CHANGED * abs(median), spread))
    return same if (used & ~same).sum() <= used.sum() / 3 else used


def ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """``num/den`` where ``den > 0``, NaN elsewhere."""
    good = den > 0
    return np.where(good, num / np.where(good, den, 1.0), np.nan)


def jackknife(values: np.ndarray) -> np.ndarray:
    """The jackknife standard error of row 0 from the replicate rows 1.. that are finite (NaN
    where fewer than two are)."""
    rest = np.asarray(values, dtype=np.float64)[1:]
    finite = np.isfinite(rest)
    m = finite.sum(axis=0)
    kept = np.where(finite, rest, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = kept.sum(axis=0) / m
        spread = np.where(finite, kept - mean, 0.0)
        return np.where(m >= 2, np.sqrt((m - 1) / m * (spread ** 2).sum(axis=0)), np.nan)
