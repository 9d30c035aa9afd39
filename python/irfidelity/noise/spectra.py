"""Noise power spectra: 1-D row and column spectra and the 2-D spectrum of the fixed-pattern
and the temporal noise.

* Fixed pattern: the temporal-mean frame minus its mean (parts v + h + vh; minus the plane
  when detrended), from the streamed sums: every frame contributes.
* Temporal noise: differences of disjoint consecutive frame pairs ``(x₁ − x₀)/√2``, each
  minus its own mean; the fixed pattern cancels and the frame-mean flicker (t) is removed,
  leaving tv + th + tvh. Up to ``pairs`` pairs from the start of the recording.

Normalisation: periodograms ``|DFT|² / (V·H)²``, so the 2-D spectrum sums to the mean
square of the pattern; the 1-D spectra are one-sided (frequencies ``0 .. 0.5`` cy/px,
mirrored bins folded in) and sum to it too. The row spectrum is along a row (horizontal
frequency), averaged over rows; its 0 cy/px bin holds the power of the row offsets (v for
the fixed pattern, tv for the temporal noise), and the column spectrum's that of the column
offsets (h, th).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["NoiseSpectra", "pattern_spectra"]


@dataclass(frozen=True)
class NoiseSpectra:
    """Power spectra of a recording's fixed-pattern and temporal noise (frame units²).

    Attributes
    ----------
    freq_row, freq_col : numpy.ndarray
        Frequencies (cycles/pixel, 0 .. 0.5) of the row spectra (along a row) and of the
        column spectra (along a column).
    fixed_row, fixed_col : numpy.ndarray
        One-sided 1-D spectra of the fixed pattern; each sums to its mean square.
    temporal_row, temporal_col : numpy.ndarray or None
        The same for the temporal noise; None when no frames were available (spectra of
        merged :class:`~irfidelity.noise.NoiseSums` only).
    fixed_2d, temporal_2d : numpy.ndarray or None
        2-D spectra, zero frequency at the centre (``numpy.fft.fftshift`` order), axes
        ``freq2d_row`` (vertical) and ``freq2d_col`` (horizontal).
    pairs : int
        Frame pairs averaged in the temporal spectra.
    """

    freq_row: np.ndarray
    freq_col: np.ndarray
    fixed_row: np.ndarray
    fixed_col: np.ndarray
    fixed_2d: np.ndarray
    temporal_row: np.ndarray | None
    temporal_col: np.ndarray | None
    temporal_2d: np.ndarray | None
    freq2d_row: np.ndarray
    freq2d_col: np.ndarray
    pairs: int

    def to_dict(self) -> dict[str, Any]:
        """The 1-D spectra as lists (the 2-D spectra are left out)."""
        def lst(a: np.ndarray | None) -> list[float] | None:
            return None if a is None else [float(v) for v in a]
        return {"freq_row": lst(self.freq_row), "freq_col": lst(self.freq_col),
                "fixed_row": lst(self.fixed_row), "fixed_col": lst(self.fixed_col),
                "temporal_row": lst(self.temporal_row), "temporal_col": lst(self.temporal_col),
                "pairs": self.pairs}


def _fold(n: int) -> np.ndarray:
    """Weights folding a real signal's ``rfft`` bins into a one-sided spectrum."""
    w = np.full(n // 2 + 1, 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    return w


def _half_plane(pattern: np.ndarray) -> np.ndarray:
    """``|rfft2|² / (V·H)²`` of a 2-D pattern."""
    rows, cols = pattern.shape
    z = np.fft.rfft2(pattern)
    return (z.real ** 2 + z.imag ** 2) / float(rows * cols) ** 2


def _one_sided(half: np.ndarray, rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column 1-D spectra (averaged over rows / columns) from a half-plane periodogram."""
    fold_h = _fold(cols)
    row = (half * fold_h).sum(axis=0)
    full_v = (half * fold_h).sum(axis=1)  # power per vertical frequency, all horizontal ones
    col = full_v[: rows // 2 + 1].copy()
    mirrored = np.arange(1, (rows + 1) // 2)
    col[mirrored] += full_v[rows - mirrored]
    return row, col


def _full_plane(half: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """The whole 2-D periodogram (point symmetry of a real signal's DFT), fftshifted."""
    full = np.empty((rows, cols))
    k = half.shape[1]
    full[:, :k] = half
    if cols > k:
        kh = np.arange(k, cols)
        kv = (-np.arange(rows)) % rows
        full[:, k:] = half[kv][:, cols - kh]
    return np.fft.fftshift(full)


def pattern_spectra(fixed: np.ndarray, temporal_pairs: Iterable[np.ndarray]) -> NoiseSpectra:
    """Spectra of a fixed pattern (2-D, its mean removed) and of frame-pair differences
    (each ``(x₁ − x₀)/√2``; their means are removed here; consumed one at a time)."""
    rows, cols = fixed.shape
    half = _half_plane(fixed)
    fixed_row, fixed_col = _one_sided(half, rows, cols)
    fixed_2d = _full_plane(half, rows, cols)
    t_row = t_col = t_2d = None
    acc = np.zeros_like(half)
    count = 0
    for d in temporal_pairs:
        acc += _half_plane(d - d.mean())
        count += 1
    if count:
        acc /= count
        t_row, t_col = _one_sided(acc, rows, cols)
        t_2d = _full_plane(acc, rows, cols)
    return NoiseSpectra(
        freq_row=np.fft.rfftfreq(cols), freq_col=np.fft.rfftfreq(rows),
        fixed_row=fixed_row, fixed_col=fixed_col, fixed_2d=fixed_2d,
        temporal_row=t_row, temporal_col=t_col, temporal_2d=t_2d,
        freq2d_row=np.fft.fftshift(np.fft.fftfreq(rows)), freq2d_col=np.fft.fftshift(np.fft.fftfreq(cols)),
        pairs=count)
