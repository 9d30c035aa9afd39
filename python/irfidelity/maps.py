"""Where two frames differ: the windowed SSIM map (Wang et al. 2004) and multi-scale SSIM
(Wang, Simoncelli & Bovik 2003).

The paper's component f5 is the *global* SSIM of the whole frame (:func:`irfidelity.stats.ssim`).
The literature usually quotes the mean of a windowed SSIM map instead; :func:`ssim_map` gives
that number (scikit-image's ``structural_similarity`` with the paper's settings) and the map
itself, which shows *where* the simulator departs from the camera. Both run in Rust
(``rust/maps/``), in float64, with the GIL released, and are planned against the memory
budget ``max_bytes`` before they allocate (docs/design.md §14).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _core
from .budget import resolve
from .errors import FidelityError
from .stats import _frame_pair, peak_and_valid

__all__ = ["SSIMMap", "ssim_map", "ms_ssim", "sampled_ssim_map", "MS_SSIM_WEIGHTS"]

#: The scale weights β₁..β₅ of Wang, Simoncelli & Bovik (2003), finest scale first.
MS_SSIM_WEIGHTS: tuple[float, ...] = tuple(_core.MS_SSIM_WEIGHTS)


@dataclass(frozen=True, eq=False)
class SSIMMap:
    """A windowed SSIM map and its mean.

    Attributes
    ----------
    map : numpy.ndarray
        SSIM per pixel, float64, the frames' shape; values in [-1, 1].
    mean : float
        The mean of ``map`` without its ``(win_size - 1) // 2`` border.
    peak, sigma, win_size, k1, k2 : float, float, int, float, float
        The settings that produced it (``peak`` is the data range L).

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> y, x = np.mgrid[0:120, 0:160]
    >>> real = (8000 + 2000 * np.sin(x / 7.0) * np.cos(y / 11.0)).astype(np.uint16)
    >>> m = irf.maps.ssim_map(real, real // 2 + 4000, bits=14)    # half the contrast
    >>> m
    SSIMMap(mean=0.952503, shape=(120, 160), peak=16383)
    >>> m.map.dtype, m.settings()["win_size"], bool(m.map.min() < m.mean < m.map.max())
    (dtype('float64'), 11, True)
    """

    map: np.ndarray
    mean: float
    peak: float
    sigma: float
    win_size: int
    k1: float
    k2: float

    def settings(self) -> dict:
        """The settings as a JSON-ready dict."""
        return {"peak": self.peak, "sigma": self.sigma, "win_size": self.win_size, "k1": self.k1, "k2": self.k2}

    def __repr__(self) -> str:
        return f"SSIMMap(mean={self.mean:.6g}, shape={self.map.shape}, peak={self.peak:g})"


def _frames(real, sim, bits, peak):
    """Both frames as C-contiguous 2-D arrays of one dtype, the data range and the valid range."""
    r, s = _frame_pair(real, sim)
    data_range, valid = peak_and_valid(r.dtype, bits, peak)
    if data_range is None:
        raise FidelityError(
            "float frames need `peak`, the data range L of the SSIM constants C1 = (k1·L)², C2 = (k2·L)²"
        )
    return np.ascontiguousarray(r), np.ascontiguousarray(s), data_range, valid


def _window(sigma, win_size, k1, k2):
    """The window settings as the kernel takes them (it checks their domains)."""
    if isinstance(win_size, bool) or not isinstance(win_size, (int, np.integer)) or win_size < 1:
        raise FidelityError(f"win_size must be a positive odd integer, got {win_size!r}")
    out = {"win_size": int(win_size)}
    for name, value in (("sigma", sigma), ("k1", k1), ("k2", k2)):
        try:
            out[name] = float(value)
        except (TypeError, ValueError):
            raise FidelityError(f"{name} must be a number, got {value!r}") from None
    return out


def ssim_map(
    real,
    sim,
    *,
    bits: int | None = None,
    peak: float | None = None,
    sigma: float = 1.5,
    win_size: int = 11,
    k1: float = 0.01,
    k2: float = 0.03,
    max_bytes: int | None = None,
) -> SSIMMap:
    r"""Windowed SSIM map of Wang et al. (2004), Gaussian window, float64.

    At every pixel, with window-weighted local means :math:`\mu_x, \mu_y`, variances
    :math:`\sigma_x^2, \sigma_y^2` and covariance :math:`\sigma_{xy}` (population, Gaussian
    weights of standard deviation ``sigma`` truncated to ``win_size × win_size``, normalised to
    sum 1, borders reflected with the edge pixel repeated):

    .. math::

        \mathrm{SSIM} = \frac{(2\mu_x\mu_y + C_1)(2\sigma_{xy} + C_2)}
                             {(\mu_x^2 + \mu_y^2 + C_1)(\sigma_x^2 + \sigma_y^2 + C_2)},
        \qquad C_1 = (k_1 L)^2,\; C_2 = (k_2 L)^2

    with :math:`L` the data range (``peak``). ``.mean`` is the mean of the map without its
    ``(win_size - 1) // 2`` border: scikit-image's
    ``structural_similarity(real, sim, gaussian_weights=True, sigma=1.5,
    use_sample_covariance=False, data_range=peak)`` (which builds a ``2·int(3.5·sigma + 0.5) + 1``
    window: 11 for the default sigma; give the same ``win_size`` for other sigmas). scikit-image
    filters float16/float32 frames in float32; irfidelity always in float64, with each band of
    rows centred on a sample value so a large offset does not cancel the local variances.

    Parameters
    ----------
    real, sim : 2-D arrays or paths
        Same shape and dtype (uint8, uint16, int16, uint32, float16, float32, float64), at least
        ``win_size`` pixels on each side.
    bits : int, optional
        Integer frames: ``L = 2**bits − 1``; a value above it is a :class:`RangeError` naming
        it and its position.
    peak : float, optional
        The data range L; required for float frames. Default for integer frames: the dtype's
        maximum (unsigned) or range (signed), as scikit-image.
    sigma : float
        Standard deviation of the Gaussian window, pixels (1.5 in the paper).
    win_size : int
        Odd side of the window (11 in the paper).
    k1, k2 : float
        Positive constants (0.01, 0.03 in the paper). With them the map is defined on flat
        regions: two flat windows of values a and b give ``(2ab + C1)/(a² + b² + C1)``
        (1 when a = b). Use :func:`irfidelity.stats.ssim` for the paper's constant-free global SSIM.
    max_bytes : int, optional
        The memory budget (default :data:`irfidelity.budget.DEFAULT_MAX_BYTES`): the frames,
        the map (8 bytes a pixel) and each thread's band buffers must fit.

    Returns
    -------
    SSIMMap
        ``.map`` (frame-sized float64) and ``.mean``, with the settings.

    Raises
    ------
    RangeError
        NaN or Inf in a float frame (with their count and the first position), or an
        integer value above ``2**bits − 1``.
    ShapeError
        Frames of different shapes or dtypes, not 2-D, or smaller than the window.
    FidelityError
        Float frames without ``peak``; a parameter out of its domain; frames whose map does
        not fit ``max_bytes``.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> rng = np.random.default_rng(0)
    >>> real = rng.integers(0, 16384, size=(120, 160), dtype=np.uint16)
    >>> m = irf.maps.ssim_map(real, real, bits=14)
    >>> m.map.shape, m.mean
    ((120, 160), 1.0)
    >>> noisy = np.clip(real + rng.normal(0, 800, real.shape), 0, 16383).astype(np.uint16)
    >>> 0 < irf.maps.ssim_map(real, noisy, bits=14).mean < 1
    True

    References
    ----------
    .. [1] Z. Wang, A. C. Bovik, H. R. Sheikh and E. P. Simoncelli, "Image quality assessment:
       from error visibility to structural similarity", IEEE Trans. Image Processing 13(4),
       600–612 (2004), doi:10.1109/TIP.2003.819861.
    """
    r, s, data_range, valid = _frames(real, sim, bits, peak)
    window = _window(sigma, win_size, k1, k2)
    values, mean = _core.ssim_map(r, s, peak=data_range, valid=valid, max_bytes=resolve(max_bytes), **window)
    return SSIMMap(map=values, mean=mean, peak=data_range, **window)


def sampled_ssim_map(real, sim, step: int, *, peak: float, max_bytes: int | None = None) -> SSIMMap:
    """:func:`ssim_map` with the paper's window, keeping only ``map[::step, ::step]`` (the
    same values, and the same ``mean`` of the whole map, without holding the whole map): what
    a display of the map needs.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> real = np.random.default_rng(1).integers(0, 4096, (64, 80)).astype(np.uint16)
    >>> sim = real // 2 + 100
    >>> whole, part = irf.maps.ssim_map(real, sim, bits=12), sampled_ssim_map(real, sim, 3, peak=4095.0)
    >>> bool(np.array_equal(whole.map[::3, ::3], part.map)), whole.mean == part.mean
    (True, True)
    """
    r, s, data_range, valid = _frames(real, sim, None, peak)
    window = _window(1.5, 11, 0.01, 0.03)
    values, mean = _core.ssim_map(r, s, peak=data_range, valid=valid, step=int(step), max_bytes=resolve(max_bytes),
                                  **window)
    return SSIMMap(map=values, mean=mean, peak=data_range, **window)


def ms_ssim(
    real,
    sim,
    *,
    bits: int | None = None,
    peak: float | None = None,
    scales: int | None = None,
    sigma: float = 1.5,
    win_size: int = 11,
    k1: float = 0.01,
    k2: float = 0.03,
    max_bytes: int | None = None,
) -> float:
    r"""Multi-scale SSIM of Wang, Simoncelli & Bovik (2003).

    .. math::

        \mathrm{MS\text{-}SSIM} = [\overline{\mathrm{SSIM}}_M]^{\beta_M}
                                 \prod_{j=1}^{M-1} [\overline{cs}_j]^{\beta_j},
        \qquad cs = \frac{2\sigma_{xy} + C_2}{\sigma_x^2 + \sigma_y^2 + C_2}

    Scale 1 is the frames themselves, scale j + 1 the 2×2 averages of scale j (the reference
    implementation's ``imfilter(ones(2)/4, 'symmetric')`` followed by every other pixel: an odd
    last row or column is averaged with itself); :math:`\overline{cs}_j` and
    :math:`\overline{\mathrm{SSIM}}_M` are means over each scale's map without its border
    (:func:`ssim_map`), with the same C1, C2 at every scale. Weights
    β = (0.0448, 0.2856, 0.3001, 0.2363, 0.1333).

    **Small frames.** The number of scales M is capped at the largest number (at most 5) for
    which the smallest scale is still at least ``win_size`` pixels on both sides, and the
    weights of the kept scales are divided by their sum. A 160×120 Lepton frame gives scales
    of 120, 60, 30 and 15 rows: M = 4 (the fifth, 8 rows, would be smaller than the 11-pixel
    window, where other implementations fail or pad).

    **Negative terms.** A mean term ≤ 0 (anti-correlated structure at that scale) counts as 0,
    so MS-SSIM lies in [0, 1] and is never NaN: the frames share no structure at that scale.

    Parameters
    ----------
    real, sim, bits, peak, sigma, win_size, k1, k2
        As for :func:`ssim_map`.
    scales : int, optional
        M, 1..5; default: the cap above. More scales than the cap is a :class:`FidelityError`
        naming the cap. ``scales=1`` gives ``max(ssim_map(...).mean, 0)``.
    max_bytes : int, optional
        The memory budget (default :data:`irfidelity.budget.DEFAULT_MAX_BYTES`): the frames
        and two consecutive coarser scales of both as float64 (at most 5 bytes a pixel of
        the frames) must fit.

    Returns
    -------
    float
        MS-SSIM in [0, 1].

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> y, x = np.mgrid[0:120, 0:160]
    >>> real = (8000 + 2000 * np.sin(x / 7.0) * np.cos(y / 11.0)).astype(np.uint16)
    >>> irf.maps.ms_ssim(real, real, bits=14)
    1.0
    >>> 0 < irf.maps.ms_ssim(real, real // 2 + 1000, bits=14) < 1   # 4 scales on 160×120
    True

    References
    ----------
    .. [1] Z. Wang, E. P. Simoncelli and A. C. Bovik, "Multiscale structural similarity for
       image quality assessment", Proc. 37th Asilomar Conference on Signals, Systems and
       Computers, vol. 2, 1398–1402 (2003), doi:10.1109/ACSSC.2003.1292216.
    .. [2] Z. Wang, A. C. Bovik, H. R. Sheikh and E. P. Simoncelli, IEEE Trans. Image
       Processing 13(4), 600–612 (2004), doi:10.1109/TIP.2003.819861.
    """
    r, s, data_range, valid = _frames(real, sim, bits, peak)
    window = _window(sigma, win_size, k1, k2)
    if scales is not None and (
        isinstance(scales, bool) or not isinstance(scales, (int, np.integer)) or not 1 <= scales <= 5
    ):
        raise FidelityError(f"scales must be an integer between 1 and 5, got {scales!r}")
    value, _weights, _ssim, _cs = _core.ms_ssim(
        r, s, peak=data_range, valid=valid, scales=None if scales is None else int(scales),
        max_bytes=resolve(max_bytes), **window
    )
    return value
