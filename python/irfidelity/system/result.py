"""The estimate of a pair's transfer and what it holds (:class:`Transfer`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import FidelityError
from .gain import gain as gain_of
from .readings import MIN_COHERENCE, MIN_SNR_UNKNOWN, REFERENCE_FREQUENCY, band, fit_rings, mtf_reading, noise_variances
from .rings import Geometry, RingSums, jackknife, ratio, ring_sums
from .spectra import TransferSpectra

__all__ = ["Transfer", "estimate"]


@dataclass(frozen=True)
class Transfer:
    """The simulator relative to the real camera, measured from the scene (module notes).

    Attributes
    ----------
    frequency : ndarray
        Ring centres in cycles per pixel, ``k/tile`` for k = 1..tile/2.
    mtf_ratio, mtf_ratio_err : ndarray
        Simulated MTF / real MTF, radially averaged, and its standard error (jackknife over
        groups of tiles, with the gain's error).
    horizontal, vertical : ndarray
        The ratio along the frame's rows (horizontal frequencies) and columns.
    coherence : ndarray
        Of the pair per ring, in [-1, 1] (signed: negative for inverted grey levels).
    snr : ndarray or None
        The real scene's signal-to-noise ratio per ring, when the real camera's noise is known.
    band : (float, float) or None
        The frequencies where the ratio is trusted (module notes); None when the scene
        carries no detail above its noise.
    gain, gain_err : float or None
        ``sim ≈ gain·real + offset``: the transfer at zero frequency (the SiTF ratio of the
        simulator to the real camera on this scene). None when the scene has no contrast.
    offset, offset_err : float or None
        In frame units (in a temperature unit: degrees), ``mean(sim) − gain·mean(real)``.
    bias : float
        ``mean(sim) − mean(real)`` over the scored pixels.
    reference_frequency : float
        Where the ratio is read as an MTF50 mismatch (the real camera's MTF50 when known).
    ratio_at_reference, ratio_at_reference_err : float or None
        ``exp(−a·f₀²)`` of the Gaussian fit ``ln M = −a·f²`` over the band.
    mtf50_mismatch, mtf50_mismatch_err : float or None
        :func:`mtf50_mismatch` of it: what the mtf tolerance grades.
    shape_residual : float or None
        RMS of ``ln M`` about the fit over the band (0 for Gaussian-shaped MTFs).
    noise_ratio, noise_ratio_err : float or None
        The simulator's noise over the real camera's (white-equivalent σ), when the real
        noise is known; ``real_noise`` and ``sim_noise`` are the two σ in frame units.
    noise_source : str or None
        Where the real noise came from: "real_ref", "real_noise" or "sequence".
    shift : (float, float)
        ``(dy, dx)`` with ``real ≈ scipy.ndimage.shift(sim, shift)`` (:func:`irfidelity.register`'s
        convention), from the cross-spectrum's phase: the tiles' own displacements, weighted
        by their power. Each tile's is removed before the ratio is taken, so the ratio measures
        resolution, not geometry.
    local_shift : float or None
        The RMS spread of the tiles' displacements about ``shift`` (px): lens distortion the
        simulator lacks, or objects that moved; 0 for a rigid translation.
    tile, tiles, skipped : int
        The tile side, the tiles averaged, and those left out (a pixel masked or not finite).
    changed : int
        Groups of tiles (and their pixels, from the gain) left out because they saw a different
        scene in the two frames (:func:`~irfidelity.system.rings.unchanged`).
    notes : tuple of str
        What limits this estimate (an extrapolated reading, an unknown real noise).
    unread : str or None
        Why the ratio could not be read at the reference frequency (then the MTF50 mismatch
        is None), or None.
    unread_cause : str or None
        Whose doing that is: "scene" (it carries no detail there, or no contrast) or
        "simulator" (the real camera's noise is known and the scene carries detail past half
        the reference frequency, but the simulated frame's noise hides the ratio there).

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> from scipy import ndimage
    >>> rng = np.random.default_rng(1)
    >>> real = 3000 + ndimage.gaussian_filter(rng.normal(0, 50, (192, 192)), 2)
    >>> t = irf.transfer(real, 0.9 * real + 300)          # a 10 % contrast error, sharp
    >>> t
    Transfer(gain=0.9000±0.0000, offset=300, mtf50_mismatch=0.000±0.000, band 0.016-0.5 cy/px, 25 tiles)
    >>> t.to_dict()["gain"] == t.gain
    True
    """

    frequency: np.ndarray
    mtf_ratio: np.ndarray
    mtf_ratio_err: np.ndarray
    horizontal: np.ndarray
    vertical: np.ndarray
    coherence: np.ndarray
    snr: np.ndarray | None
    band: tuple[float, float] | None
    gain: float | None
    gain_err: float | None
    offset: float | None
    offset_err: float | None
    bias: float
    reference_frequency: float
    ratio_at_reference: float | None
    ratio_at_reference_err: float | None
    mtf50_mismatch: float | None
    mtf50_mismatch_err: float | None
    shape_residual: float | None
    noise_ratio: float | None
    noise_ratio_err: float | None
    real_noise: float | None
    sim_noise: float | None
    noise_source: str | None
    shift: tuple[float, float]
    local_shift: float | None
    tile: int
    tiles: int
    skipped: int
    changed: int = 0
    notes: tuple = field(default=())
    unread: str | None = None
    unread_cause: str | None = None

    def __repr__(self) -> str:
        def pm(value: float | None, error: float | None, digits: int) -> str:
            return "None" if value is None else f"{value:.{digits}f}±{error:.{digits}f}"
        band = "no band" if self.band is None else f"band {self.band[0]:.2g}-{self.band[1]:.2g} cy/px"
        noise = "" if self.noise_ratio is None else f", noise_ratio={pm(self.noise_ratio, self.noise_ratio_err, 3)}"
        offset = "None" if self.offset is None else f"{self.offset:.4g}"
        return (f"Transfer(gain={pm(self.gain, self.gain_err, 4)}, offset={offset}, "
                f"mtf50_mismatch={pm(self.mtf50_mismatch, self.mtf50_mismatch_err, 3)}{noise}, {band}, "
                f"{self.tiles} tiles)")

    def ratio_at(self, frequency: float) -> float:
        """The measured radial ratio at ``frequency`` (cy/px), linearly interpolated."""
        return float(np.interp(frequency, self.frequency, self.mtf_ratio))

    def to_dict(self) -> dict:
        """JSON-ready: arrays as lists (NaN as None), every scalar as is."""
        def plain(v: Any) -> Any:
            if isinstance(v, np.ndarray):
                return [None if not np.isfinite(x) else float(x) for x in v]
            if isinstance(v, tuple):
                return [plain(x) for x in v]
            return v
        return {f: plain(getattr(self, f)) for f in self.__dataclass_fields__}


def estimate(spectra: TransferSpectra, *, real_variance: float | None = None, noise_source: str | None = None,
             reference_frequency: float | None = None) -> Transfer:
    """The :class:`Transfer` of a pair, or of the pooled frames of a sequence, from its sums.

    The real camera's noise comes from a second real frame in the sums (half their difference
    spectrum), else from ``real_variance`` (its white temporal variance in frame units, e.g. from
    its 3-D noise); ``noise_source`` says where it came from (None: unknown)."""
    geometry = Geometry.of(spectra.tile)
    if spectra.tiles.sum() == 0:
        raise FidelityError(f"transfer: no {spectra.tile} x {spectra.tile} tile of the frames is wholly scored and "
                            f"finite ({spectra.skipped} left out): score a larger region, or give a smaller tile",
                            option="tile")
    noise = _noise_power(spectra, real_variance)
    rows = ring_sums(spectra, geometry, noise).replicates()
    variances = noise_variances(rows, spectra.window_energy)
    white = real_variance if spectra.difference is None else (None if variances is None else float(variances[1][0]))
    g = gain_of(spectra, (0.0, 0.0), white)  # the low spectrum's displacement is already out
    changed = spectra.changed
    return _assemble(spectra, geometry, rows, variances, g, noise_source if noise is not None else None,
                     REFERENCE_FREQUENCY if reference_frequency is None else float(reference_frequency), changed)


def displacements(spectra: TransferSpectra) -> tuple[tuple[float, float], float | None]:
    """The pair's displacement (the tiles' own, weighted by their cross power; the block-mean
    spectrum's when no tile had one) and the tiles' RMS spread about it (None without tiles)."""
    if spectra.shifts is None:
        return spectra.shift, None
    w, wy, wx, wyy, wxx = spectra.shifts.sum(axis=0)
    if not w > 0:
        return spectra.shift, None
    dy, dx = wy / w, wx / w
    return (float(dy), float(dx)), float(np.sqrt(max(wyy / w - dy * dy, 0.0) + max(wxx / w - dx * dx, 0.0)))


def _noise_power(spectra: TransferSpectra, real_variance: float | None) -> np.ndarray | None:
    """The real camera's noise power per group and bin: half the difference spectrum of two real
    frames, or a white noise of ``real_variance``; None when neither is known."""
    if spectra.difference is not None:
        return spectra.difference / 2.0
    if real_variance is None:
        return None
    per_tile = float(real_variance) * spectra.window_energy
    return np.broadcast_to(spectra.tiles[:, None, None] * per_tile, spectra.real.shape)


def _assemble(spectra: TransferSpectra, geometry: Geometry, rows: RingSums,
              variances: tuple[np.ndarray, np.ndarray] | None, gain: tuple[float, float] | None,
              noise_source: str | None, reference: float, changed: int) -> Transfer:
    """The :class:`Transfer` from the ring sums (row 0 whole, then the jackknife replicates),
    the noise variances and the gain."""
    k = slice(1, geometry.rings)
    frequency = geometry.frequency[k]
    g, g_err = gain if gain is not None else (math.nan, math.nan)
    scale = abs(g) if gain is not None else 1.0
    values = ratio(rows.cross, rows.signal)[:, k] / scale
    error = np.sqrt(jackknife(values) ** 2 + (values[0] * g_err / scale) ** 2)
    coherence = ratio(rows.cross[0] * np.abs(rows.cross[0]), rows.real[0] * rows.sim[0])[k]
    snr = None if rows.noise is None else ratio(rows.signal[0], rows.noise[0])[k]
    trusted = band(frequency, _floor_snr(rows)[k] if snr is None else snr, snr is not None, coherence) \
        if gain is not None else np.zeros(frequency.shape, dtype=bool)
    fitted = fit_rings(values[0], error, trusted)
    notes = [] if noise_source is not None else [
        "the real camera's noise is unknown (give real_ref, real_noise, or a sequence): the ratio is not corrected "
        f"for it, and the band stops where the real spectrum falls below {MIN_SNR_UNKNOWN:g}× its floor and the "
        f"pair's coherence below {MIN_COHERENCE:g}"]
    reading = mtf_reading(frequency, values, error, fitted, reference)
    unread, cause = _unread(frequency, values[0], fitted, trusted if snr is not None else None, reference,
                            gain is not None)
    if unread is not None:
        reading = {key: None for key in reading}
    elif fitted.any() and frequency[fitted][-1] < reference:
        notes.append(f"the fit ends at {frequency[fitted][-1]:.3g} cy/px, below the reference frequency "
                     f"{reference:.3g} cy/px: the ratio there is extrapolated by the fit")
    if changed:
        notes.append(f"{changed} parts of the frame saw a different scene in the two frames (their lowest frequencies "
                     f"disagree with the rest: an object moved or changed) and are left out")
    mean_real, mean_sim = spectra.sum_real / spectra.pixels, spectra.sum_sim / spectra.pixels
    along = {name: ratio(*getattr(rows, name))[0][k] / scale for name in ("horizontal", "vertical")}
    shift, spread = displacements(spectra)
    return Transfer(frequency=frequency, mtf_ratio=values[0], mtf_ratio_err=error, **along,
                    coherence=np.clip(coherence, -1.0, 1.0), snr=snr,
                    band=(float(frequency[trusted][0]), float(frequency[trusted][-1])) if trusted.any() else None,
                    gain=None if gain is None else g, gain_err=None if gain is None else g_err,
                    offset=None if gain is None else mean_sim - g * mean_real,
                    offset_err=None if gain is None else abs(mean_real) * g_err, bias=mean_sim - mean_real,
                    reference_frequency=reference, **reading, **_noise_reading(variances),
                    noise_source=noise_source, shift=(-shift[0], -shift[1]), local_shift=spread, tile=geometry.tile,
                    tiles=int(rows.tiles[0]), skipped=int(spectra.skipped), changed=changed, notes=tuple(notes),
                    unread=unread, unread_cause=cause)


def _unread(frequency: np.ndarray, value: np.ndarray, fitted: np.ndarray, trusted: np.ndarray | None,
            reference: float, has_gain: bool) -> tuple[str | None, str | None]:
    """Why the ratio cannot be read at the reference frequency, and whose doing that is (the
    scene's or the simulator's), or ``(None, None)``: no gain, no ring to fit, or fitted rings
    that end below half the reference frequency while the ratio is still above 0.5 there (the
    fit would extrapolate blindly; where the ratio has fallen below 0.5 the mismatch is large
    either way, and read). ``trusted`` is the band when the real camera's noise is known: when
    it goes on past half the reference frequency, the scene carries the detail and the rings
    left out of the fit were lost in the simulated frame's noise."""
    if not has_gain:
        return "the scene has no contrast at low frequencies to measure the gain on (a flat or unrelated pair)", "scene"
    if trusted is not None and trusted.any() and 2 * float(frequency[trusted][-1]) >= reference:
        top = float(frequency[fitted][-1]) if fitted.any() else 0.0
        if reference > 2 * top and (not fitted.any() or value[fitted][-1] > 0.5):
            return (f"the simulated frame's noise hides the MTF ratio above {top:.3g} cy/px, where the scene carries "
                    f"detail up to {float(frequency[trusted][-1]):.3g} cy/px: the simulator shows none of it beyond "
                    f"doubt (scored 0)"), "simulator"
    if not fitted.any():
        return ("the scene carries no detail above its noise to measure the MTF ratio on (no band of trusted "
                "frequencies)"), "scene"
    top = float(frequency[fitted][-1])
    if reference > 2 * top and value[fitted][-1] > 0.5:
        return (f"the scene's detail is trusted only up to {top:.3g} cy/px, below half the real MTF50 "
                f"({reference:.3g} cy/px) where the ratio is read; a second real frame (real_ref) lets the band go "
                f"further, or choose a scene with more detail"), "scene"
    return None, None


def _floor_snr(rows: RingSums) -> np.ndarray:
    """The real spectrum's level over its floor, less one, per ring: the floor is the least ring
    mean from ring 2 up, an upper bound of a white noise's level."""
    mean = ratio(rows.real[0], rows.count * rows.tiles[0])
    floor = np.nanmin(mean[2:]) if np.isfinite(mean[2:]).any() else np.nan
    return ratio(mean - floor, np.full(mean.shape, floor))


def _noise_reading(variances: tuple[np.ndarray, np.ndarray] | None) -> dict:
    """The noise ratio σ_sim/σ_real with its jackknife error, and the two σ."""
    if variances is None or not variances[1][0] > 0:
        return {"noise_ratio": None, "noise_ratio_err": None, "real_noise": None, "sim_noise": None}
    sim, real = np.maximum(variances[0], 0.0), variances[1]
    with np.errstate(invalid="ignore", divide="ignore"):
        ratios = np.sqrt(sim / real)
    return {"noise_ratio": float(ratios[0]), "noise_ratio_err": float(jackknife(ratios[:, None])[0]),
            "real_noise": math.sqrt(real[0]), "sim_noise": math.sqrt(sim[0])}
