"""The pair as a system: the simulator's resolution, response and noise relative to the real
camera's, measured from the scene both frames show (:func:`transfer`, also
``irfidelity.transfer``; docs/interpretation.md, "The pair as a system").

A simulated frame ``S`` of the scene a real camera recorded as ``R`` is, to first order, the
real frame through a relative transfer function plus noise of its own::

    S = gain · (h ⊛ T) + offset + N_s,        R = T + N_r

with ``T`` the real camera's image of the scene (noise-free), ``h`` the simulator's point
spread relative to the real camera's (its transform ``H`` is the MTF ratio, ``H(0) = 1``) and
``N_s``, ``N_r`` the two cameras' noise. Averaged over windowed tiles (Welch's method, Rust:
``_core.cross_spectra``), the spectra of the pair give, at every frequency ``f``::

    S_rs(f) = gain · H(f) · S_T(f)        S_rr(f) = S_T(f) + P_r(f)
    S_ss(f) = gain² · |H(f)|² · S_T(f) + P_s(f)

so ``gain · H = S_rs / (S_rr − P_r)``: the simulator's own noise does not bias it, and the real
camera's noise is subtracted when it is known (a second real frame ``real_ref``: ``P_r`` is
half the spectrum of the two real frames' difference; or the real camera's 3-D noise
``real_noise``). The gain is the transfer at zero frequency, from the lowest frequencies of the
whole frame (block means, ``_core.low_spectrum``) extrapolated by ``ln G = ln gain − a·f²``;
the MTF ratio is the transfer divided by it, radially averaged (and along each axis). The
simulator's noise is what the transfer of the real frame leaves:
``P_s = S_ss − |S_rs|² / S_T``; its ratio to the real camera's is ``noise_ratio``.

A translation between the frames only turns the cross-spectrum's phase: it is measured
(``shift``, the convention of :func:`irfidelity.register`) and removed before the real part
is taken, so an unregistered pair displaced by a few pixels gives the same ratio as a
registered one, with no resampling. Every estimate has a jackknife standard error over
:data:`GROUPS` runs of neighbouring tiles; the ``band`` is where the ratio is trusted: the
scene carries signal above the noise there and the ratio's standard error is small.
"""

from .pair import real_noise_variance, transfer
from .readings import REFERENCE_FREQUENCY, mtf50_mismatch
from .result import Transfer, estimate
from .spectra import GROUPS, TransferSpectra, tile_size, transfer_spectra

__all__ = ["transfer", "Transfer", "TransferSpectra", "transfer_spectra", "estimate", "real_noise_variance",
           "mtf50_mismatch", "tile_size", "GROUPS", "REFERENCE_FREQUENCY"]
