"""Sensor noise: the 3-D noise model (D'Agostino & Webb 1991), its finite-sampling-corrected
estimates with confidence intervals (Haefner et al. 2015), NETD, noise power spectra, and
the ``noise`` component comparing a simulator's noise with the real camera's.

* :func:`noise3d` -> :class:`Noise3D`: the seven components of a recording of a uniform
  source, streamed (never the whole cube in memory), with :class:`NoiseOptions`;
* :func:`noise_sums` -> :class:`NoiseSums`: the streamed pass alone; mergeable over frame
  ranges (Dask), serialisable;
* :func:`noise_similarity` -> :class:`NoiseSimilarity`: the ``noise`` component.

Formulas and references: ``docs/noise.md``.
"""

from .checks import NoiseWarning
from .model import Noise3D, noise3d
from .options import NoiseOptions
from .similarity import NoiseSimilarity, noise_similarity
from .spectra import NoiseSpectra
from .sums import NoiseSums, noise_sums

__all__ = ["noise3d", "NoiseOptions", "Noise3D", "noise_sums", "NoiseSums", "noise_similarity", "NoiseSimilarity",
           "NoiseSpectra", "NoiseWarning"]
