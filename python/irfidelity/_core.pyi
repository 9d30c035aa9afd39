"""Type stub of the Rust extension `irfidelity._core` (hand-written; keep in sync with rust/binding/)."""

import os
from collections.abc import Callable, Sequence
from typing import Any, final

import numpy as np
import numpy.typing as npt

from irfidelity.sequence.plan import SequenceRequest
from irfidelity.stats import PairRequest

__all__ = [
    "MAX_HIST_BINS",
    "MS_SSIM_WEIGHTS",
    "NoiseSums",
    "PairStats",
    "REGISTRATION_AMBIGUOUS",
    "REGISTRATION_INTEGER_SNAP",
    "REGISTRATION_LOW_CONFIDENCE",
    "REGISTRATION_METHODS",
    "REGISTRATION_MIN_OVERLAP",
    "REGISTRATION_MODELS",
    "SUPPORTED_DTYPES",
    "applied_matrix",
    "check_budget",
    "cross_spectra",
    "default_max_bytes",
    "default_max_pixels",
    "error_profile",
    "far_pixels",
    "file_digests",
    "list_channels",
    "load_frame",
    "low_spectrum",
    "max_scales",
    "merge_all",
    "ms_ssim",
    "noise_sums_array",
    "noise_sums_paths",
    "page_chain",
    "pair_stats",
    "plain_moments",
    "plain_mse",
    "radiometric_conversion",
    "read_camera_info",
    "register_frames",
    "robust_spread",
    "score_pairs",
    "score_registered",
    "score_shared",
    "scored_range",
    "ssim_map",
    "temperature_errors",
    "tiff_ifds_read",
    "warp_frame",
]

#: numpy names of the frame dtypes the kernel accepts.
SUPPORTED_DTYPES: tuple[str, ...]
#: The most uniform histogram bins (``bins``) a pair's statistics may have.
MAX_HIST_BINS: int

@final
class PairStats:
    """Sufficient statistics of a frame pair (wrapped by `irfidelity.PairStats`)."""

    @property
    def n(self) -> int: ...
    @property
    def masked(self) -> int: ...
    @property
    def nonfinite(self) -> int: ...
    @property
    def is_int(self) -> bool: ...
    @property
    def has_sse(self) -> bool: ...
    @property
    def has_moments(self) -> bool: ...
    @property
    def has_hist(self) -> bool: ...
    @property
    def real_range(self) -> tuple[float, float] | None: ...
    def sse(self) -> float | None: ...
    def mse(self) -> float | None: ...
    def moments(self) -> tuple[float, float, float, float, float] | None: ...
    def centred(self) -> tuple[float, float, float] | None: ...
    def entropies(self) -> tuple[float, float, float] | None: ...
    def summary(
        self,
    ) -> tuple[
        float | None,
        tuple[float, float, float, float, float] | None,
        tuple[float, float, float] | None,
        tuple[float, float, float] | None,
    ]: ...
    def hist_spec(self) -> tuple[Any, ...] | None: ...
    def int_sums(self) -> dict[str, int] | None: ...
    def joint_histogram(self, max_cells: int) -> tuple[npt.NDArray[np.int64], int, int] | None: ...
    def merge(self, other: PairStats) -> PairStats: ...
    def to_bytes(self) -> bytes: ...
    @staticmethod
    def from_bytes(data: bytes) -> PairStats: ...

def scored_range(
    values: npt.NDArray[Any], mask: npt.NDArray[np.bool_] | None = None
) -> tuple[tuple[float, float] | None, bool]:
    """A frame's (min, max) over the pixels ``mask`` keeps whose values are finite (None when
    there are none), and whether a kept pixel is NaN or infinite."""

def plain_mse(real: object, sim: object) -> float | None:
    """MSE of two non-empty, aligned, 2-D C-contiguous arrays of one supported dtype and
    shape; None otherwise."""

def plain_moments(real: object, sim: object) -> PairStats | None:
    """PairStats with the moments only (SSIM) of two non-empty, aligned, 2-D C-contiguous
    arrays of one supported dtype and shape; None otherwise."""

def pair_stats(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    request: PairRequest,
    mask: npt.NDArray[np.bool_] | None = None,
) -> PairStats: ...

# ---- frame I/O (rust/binding/io.rs) ---------------------------------------------------------

def load_frame(
    path: str | os.PathLike[str],
    channel: str | None = None,
    page: int = 0,
    max_pixels: int | None = None,
    *,
    max_bytes: int | None = None,
) -> npt.NDArray[Any]: ...
def page_chain(path: str | os.PathLike[str]) -> tuple[int, str | None]: ...
def tiff_ifds_read() -> int: ...
def list_channels(path: str | os.PathLike[str]) -> list[str]: ...
def read_camera_info(
    path: str | os.PathLike[str], page: int = 0, *, max_bytes: int | None = None
) -> dict[str, Any]: ...
def radiometric_conversion(
    values: npt.NDArray[Any], calibration: Any, unit: str, inverse: bool
) -> tuple[npt.NDArray[np.float64], int, int]: ...
def temperature_errors(
    real: npt.NDArray[np.float64],
    sim: npt.NDArray[np.float64],
    mask: npt.NDArray[np.bool_] | None = None,
    *,
    tolerance: float,
) -> tuple[int, float, float, float, int]: ...
def default_max_pixels() -> int: ...
def default_max_bytes() -> int: ...

# ---- sequences (rust/binding/sequence.rs) ---------------------------------------------------

#: A 2 x 3 affine matrix as the binding returns it: 6 floats, row-major, in a list (it takes
#: any sequence of 6 floats).
_Matrix = list[float]

#: A pair's own registration (``request.register_each``): matrix (6 floats, row-major),
#: method used, confidence, overlap, inverted.
_PairRegistration = tuple[_Matrix, str, float, float, bool]
#: A file's fingerprint: size, modification time (ns), XXH3-64 of the bytes decoded.
_FileFingerprint = tuple[int, int, int]
#: ``(index, stats, error, shape, dtype, real extent, registration, fingerprints)``.
_PairOutcome = tuple[int, PairStats | None, str | None, tuple[int, int] | None, str | None,
                    tuple[float, float] | None, _PairRegistration | None,
                    tuple[_FileFingerprint, _FileFingerprint] | None]

def score_pairs(
    real_paths: Sequence[str | os.PathLike[str]],
    sim_paths: Sequence[str | os.PathLike[str]],
    real_pages: list[int] | None = None,
    sim_pages: list[int] | None = None,
    *,
    request: SequenceRequest,
    workers: int = 0,
    progress: Callable[[int], Any] | None = None,
    on_result: Callable[[list[Any]], Any] | None = None,
    fingerprints: bool = False,
    mask: npt.NDArray[np.bool_] | None = None,
) -> list[_PairOutcome] | None: ...
def score_shared(
    real_paths: Sequence[str | os.PathLike[str]],
    real_pages: list[int],
    sim_paths: Sequence[str | os.PathLike[str]],
    sim_pages: list[int],
    owners: list[int],
    kinds: list[int],
    *,
    requests: list[SequenceRequest],
    workers: int = 0,
    progress: Callable[[int], Any] | None = None,
    on_result: Callable[[list[Any]], Any] | None = None,
    fingerprints: bool = False,
    mask: npt.NDArray[np.bool_] | None = None,
) -> list[_PairOutcome] | None: ...
def merge_all(stats: list[PairStats], keep_hist: bool = True) -> tuple[PairStats | None, bool]: ...

# ---- the memory budget (rust/binding/budget.rs) ---------------------------------------------

def check_budget(
    operation: str, shape: tuple[int, int], bytes: int, max_bytes: int | None = None, kind: str = "value"
) -> None: ...

# ---- file fingerprints (rust/binding/fingerprint.rs) -------------------------------------

def file_digests(paths: Sequence[str | os.PathLike[str]]) -> list[int | None]: ...

# ---- SSIM maps (rust/binding/maps.rs) -------------------------------------------------------

MS_SSIM_WEIGHTS: list[float]

def ssim_map(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    *,
    peak: float,
    sigma: float,
    win_size: int,
    k1: float,
    k2: float,
    valid: tuple[int, int] | None = None,
    step: int = 1,
    max_bytes: int | None = None,
) -> tuple[npt.NDArray[np.float64], float]: ...
def ms_ssim(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    *,
    peak: float,
    sigma: float,
    win_size: int,
    k1: float,
    k2: float,
    valid: tuple[int, int] | None = None,
    scales: int | None = None,
    max_bytes: int | None = None,
) -> tuple[float, list[float], list[float], list[float]]: ...
def max_scales(rows: int, cols: int, win_size: int) -> int: ...
# ---- 3-D noise (rust/binding/noise.rs) ------------------------------------------------------

@final
class NoiseSums:
    """Sufficient statistics of a recording for the 3-D noise decomposition (wrapped by
    `irfidelity.noise.NoiseSums`)."""

    @property
    def frames(self) -> int: ...
    @property
    def rows(self) -> int: ...
    @property
    def cols(self) -> int: ...
    @property
    def dtype(self) -> str: ...
    def decomposition(self) -> dict[str, Any]: ...
    def exact_ss(self) -> dict[str, int] | None: ...
    def pixel_mean(self) -> npt.NDArray[np.float64]: ...
    def pixel_var(self) -> npt.NDArray[np.float64]: ...
    def row_means(self) -> npt.NDArray[np.float64]: ...
    def col_means(self) -> npt.NDArray[np.float64]: ...
    def value_range(self) -> dict[str, float | int]: ...
    def merge(self, other: NoiseSums) -> NoiseSums: ...
    def to_bytes(self) -> bytes: ...
    @staticmethod
    def from_bytes(data: bytes) -> NoiseSums: ...

def noise_sums_array(
    cube: npt.NDArray[Any],
    *,
    limits: tuple[int, int] | None = None,
    window: tuple[int, int, int, int] | None = None,
    workers: int = 0,
    max_bytes: int | None = None,
) -> NoiseSums: ...
def noise_sums_paths(
    paths: Sequence[str | os.PathLike[str]],
    pages: list[int],
    *,
    channel: str | None = None,
    max_pixels: int | None = None,
    max_bytes: int | None = None,
    limits: tuple[int, int] | None = None,
    window: tuple[int, int, int, int] | None = None,
    workers: int = 0,
) -> NoiseSums: ...

# ---- registration (rust/binding/register.rs) ------------------------------------------------

REGISTRATION_LOW_CONFIDENCE: float
REGISTRATION_AMBIGUOUS: float
REGISTRATION_MIN_OVERLAP: float
REGISTRATION_INTEGER_SNAP: float
REGISTRATION_MODELS: list[str]
REGISTRATION_METHODS: list[str]

def applied_matrix(
    matrix: Sequence[float],
) -> _Matrix: ...

def register_frames(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    model: str,
    method: str,
    max_shift: float | None = None,
    mask: npt.NDArray[np.bool_] | None = None,
    *,
    max_bytes: int | None = None,
) -> _PairRegistration: ...
def warp_frame(
    frame: npt.NDArray[Any],
    matrix: Sequence[float],
    order: int,
    shape: tuple[int, int],
    mask: npt.NDArray[np.bool_] | None = None,
    *,
    max_bytes: int | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]: ...
def score_registered(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    request: PairRequest,
    *,
    search: tuple[str, str, float | None] | None = None,
    matrix: Sequence[float] | None = None,
    order: int = 3,
    mask: npt.NDArray[np.bool_] | None = None,
    extent: bool = False,
    max_bytes: int | None = None,
) -> tuple[
    PairStats,
    _PairRegistration | None,
    tuple[float, float] | None,
    npt.NDArray[np.float64],
    npt.NDArray[np.bool_],
]: ...

# ---- where a pair's squared error sits (rust/binding/defects.rs) --------------------------------
def error_profile(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    mask: npt.NDArray[np.bool_] | None = None,
    *,
    top_share: float,
    most: float,
    border: int,
    tolerance: float | None = None,
    spread_step: int | None = None,
) -> tuple[
    float,
    int,
    float,
    tuple[float, int, list[int] | None],
    tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]] | None,
    tuple[int, float, float, float, int] | None,
    tuple[int, tuple[float, float, float, float] | None] | None,
]: ...
def far_pixels(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    mask: npt.NDArray[np.bool_] | None = None,
    *,
    median: float,
    threshold: float,
    most: int,
) -> npt.NDArray[np.int64] | None: ...

# ---- cross-spectra of a pair, for its transfer (rust/binding/transfer.rs) -----------------------
def robust_spread(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    mask: npt.NDArray[np.bool_] | None = None,
    *,
    step: int,
) -> tuple[float, float, float, float] | None:
    """(median, median absolute deviation, 99th percentile of the absolute deviations, root mean
    square deviation) of ``sim − real`` at every ``step``-th pixel of every ``step``-th row that
    is scored and finite; the first three equal to numpy's ``median`` and ``quantile``; None
    when there is no such pixel."""

def cross_spectra(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    reference: npt.NDArray[Any] | None = None,
    mask: npt.NDArray[np.bool_] | None = None,
    *,
    tile: int,
    step: int,
    groups: int,
    shift: tuple[float, float] = ...,
) -> dict[str, Any]: ...
def low_spectrum(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    mask: npt.NDArray[np.bool_] | None = None,
    *,
    factor: int,
) -> dict[str, Any]: ...
