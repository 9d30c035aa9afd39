"""What the radial estimates say: the band where the MTF ratio is trusted, the ratio read as
an MTF50 mismatch, and the two cameras' noise."""

from __future__ import annotations

import math

import numpy as np

from .rings import RingSums, jackknife, ratio

__all__ = ["MIN_SNR", "MIN_SNR_UNKNOWN", "MIN_COHERENCE", "FIT_FLOOR", "fit_rings", "REFERENCE_FREQUENCY", "band", "mtf_reading",
           "mtf50_mismatch", "noise_variances"]

#: The band ends where the real scene's signal-to-noise ratio falls below this, with the real
#: camera's noise known (the ratio is corrected for it) ...
MIN_SNR = 1.0
#: ... or, with it unknown, where neither the real spectrum stands this far above its floor (its
#: least ring mean, an upper bound of the noise) nor the pair's coherence reaches
#: :data:`MIN_COHERENCE`: either bounds how low the uncorrected ratio can read (1/11, 10 %).
MIN_SNR_UNKNOWN = 10.0
MIN_COHERENCE = 0.9

#: Rings whose ratio is below this are left out of the fit (their logarithm is mostly noise).
FIT_FLOOR = 0.02

#: Where the MTF ratio is read as an MTF50 mismatch when the real camera's MTF50 is not known
#: (cy/px): a typical MTF50 of a well-sampled thermal imager.
REFERENCE_FREQUENCY = 0.25


def band(frequency: np.ndarray, snr: np.ndarray, known: bool, coherence: np.ndarray) -> np.ndarray:
    """The rings where the scene carries signal above the real camera's noise: from the first
    such ring among the three lowest up to the first that is not (SNR below :data:`MIN_SNR`; when
    the noise is not ``known``, neither the SNR against the spectrum's floor at least
    :data:`MIN_SNR_UNKNOWN` nor the coherence at least :data:`MIN_COHERENCE`), within
    0 < f ≤ 0.5 cy/px. The simulated frame's own noise does not end it where the noise is known:
    it widens the ratio's errors instead."""
    with np.errstate(invalid="ignore"):
        ok = snr >= MIN_SNR if known else (snr >= MIN_SNR_UNKNOWN) | (coherence >= MIN_COHERENCE)
    ok &= (frequency > 0) & (frequency <= 0.5)
    trusted = np.zeros(ok.shape, dtype=bool)
    first = next((k for k in range(min(3, len(ok))) if ok[k]), None)
    if first is None:
        return trusted
    last = first
    while last + 1 < len(ok) and ok[last + 1]:
        last += 1
    trusted[first:last + 1] = True
    return trusted


def fit_rings(value: np.ndarray, error: np.ndarray, trusted: np.ndarray) -> np.ndarray:
    """The rings of the band the fit uses: a ratio above :data:`FIT_FLOOR` and twice its error
    (below, it cannot be told from a lost one, and its logarithm is noise)."""
    with np.errstate(invalid="ignore"):
        return trusted & np.isfinite(value) & np.isfinite(error) & (value >= np.maximum(FIT_FLOOR, 2 * error))


def mtf50_mismatch(ratio_at_mtf50: float) -> float:
    """The MTF50 mismatch ``1 − smaller/larger`` of two Gaussian MTFs whose ratio (simulated /
    real) at the real MTF50 is ``ratio_at_mtf50``: ``MTF50_sim/MTF50_real = (1 − log2 r)^(−1/2)``.

    Examples
    --------
    >>> round(mtf50_mismatch(1.0), 6), round(mtf50_mismatch(0.7349), 3), mtf50_mismatch(0.0)
    (0.0, 0.168, 1.0)
    """
    if not ratio_at_mtf50 > 0:
        return 1.0
    log = math.log2(ratio_at_mtf50)
    if log >= 1.0:
        return 1.0
    scale = (1.0 - log) ** -0.5
    return 1.0 - min(scale, 1.0 / scale)


def _curvature(frequency: np.ndarray, values: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """``a`` of ``ln M = c − a·f²`` (weighted least squares) for each row of ``values``: with its
    own intercept ``c`` on three rings or more, so a gain read slightly off at zero frequency
    does not bend the shape; through the origin on fewer."""
    x = frequency ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        y = np.log(values)
    if len(x) < 3:
        return -np.sum(weight * x * y, axis=-1) / np.sum(weight * x * x)
    w = weight / weight.sum()
    xm, ym = float(np.sum(w * x)), np.sum(w * y, axis=-1, keepdims=True)
    return -np.sum(w * (x - xm) * (y - ym), axis=-1) / float(np.sum(w * (x - xm) ** 2))


def mtf_reading(frequency: np.ndarray, values: np.ndarray, error: np.ndarray, rings: np.ndarray,
                reference: float) -> dict:
    """The Gaussian fit of the ratio over ``rings`` (:func:`fit_rings`; weights 1/var ln M) read
    at ``reference``: the ratio there, its MTF50 mismatch and the fit's RMS residual in ``ln M``,
    with jackknife errors over the replicate rows of ``values`` (row 0 the whole estimate)."""
    if not rings.any():
        return {"ratio_at_reference": None, "ratio_at_reference_err": None, "mtf50_mismatch": None,
                "mtf50_mismatch_err": None, "shape_residual": None}
    f, rows = frequency[rings], values[:, rings]
    weight = (rows[0] / np.maximum(error[rings], 1e-12)) ** 2
    slopes = _curvature(f, rows, weight)
    at = np.exp(-slopes * reference ** 2)
    mismatch = np.array([mtf50_mismatch(v) for v in at])
    with np.errstate(invalid="ignore", divide="ignore"):
        log = np.log(rows[0]) + slopes[0] * f ** 2
    residual = log - np.sum(weight * log) / np.sum(weight)
    at_err, mismatch_err = (float(jackknife(v[:, None])[0]) for v in (at, mismatch))
    return {"ratio_at_reference": float(at[0]), "ratio_at_reference_err": at_err,
            "mtf50_mismatch": float(mismatch[0]), "mtf50_mismatch_err": mismatch_err,
            "shape_residual": float(np.sqrt(np.mean(residual ** 2)))}


def noise_variances(sums: RingSums, window_energy: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The white-equivalent noise variances of the simulated frame and of the real one, for
    each row of ``sums`` (row 0 the whole estimate, then the jackknife replicates).

    Per ring from 2 up, the simulated frame's noise is what the transfer of the real frame
    leaves, ``S_ss − G²·S_T`` with ``G = S_rs/S_T`` the ring's transfer (the cross-spectrum's
    real part, the displacement removed), corrected for the finite average. Where the scene's
    share of the real power is below 10 %, ``S_T`` is too uncertain to divide by and ``S_rr``
    stands for it: the residual then reads high by at most ``G²·S_T``, a tenth of the image of
    the real noise. Both variances are weighted alike by each ring's bins over the square of
    its mean simulated power, so the rings where the simulated frame is mostly noise decide."""
    if sums.noise is None:
        return None
    tiles = sums.tiles[:, None].astype(np.float64)
    if np.any(tiles < 2):
        return None
    count = sums.count[None, 2:] * tiles
    real, sim, cross, noise = (ratio(x[:, 2:], count) for x in (sums.real, sums.sim, sums.cross, sums.noise))
    signal = real - noise
    divisor = np.where(signal > 0.1 * real, signal, real)
    residual = (sim - ratio(cross ** 2, divisor)) * tiles / (tiles - 1)
    keep = np.isfinite(residual) & (sim > 0)
    weight = np.where(keep, sums.count[None, 2:] / np.where(keep, sim, 1.0) ** 2, 0.0)
    total = weight.sum(axis=1) * window_energy
    with np.errstate(invalid="ignore", divide="ignore"):
        return (np.where(keep, weight * residual, 0.0).sum(axis=1) / total,
                np.where(keep, weight * noise, 0.0).sum(axis=1) / total)
