"""Type stub of the Rust extension `irfidelity._core` (hand-written; keep in sync with rust/binding/)."""

import os
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

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
    def sse(self) -> float | None: ...
    def mse(self) -> float | None: ...
    def moments(self) -> tuple[float, float, float, float, float] | None: ...
    def centred(self) -> tuple[float, float, float] | None: ...
    def entropies(self) -> tuple[float, float, float] | None: ...
    def hist_spec(self) -> tuple[Any, ...] | None: ...
    def int_sums(self) -> dict[str, int] | None: ...
    def merge(self, other: PairStats) -> PairStats: ...
    def to_bytes(self) -> bytes: ...
    @staticmethod
    def from_bytes(data: bytes) -> PairStats: ...

def plain_mse(real: object, sim: object, /) -> float | None:
    """MSE of two non-empty 2-D C-contiguous arrays of one supported dtype and shape; None otherwise."""

def plain_moments(real: object, sim: object, /) -> PairStats | None:
    """PairStats with the moments only (SSIM) of two non-empty 2-D C-contiguous arrays of one
    supported dtype and shape; None otherwise."""

def pair_stats(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    *,
    sse: bool = True,
    moments: bool = True,
    bins: int | None = None,
    levels: bool = False,
    hist_range: tuple[float, float] | None = None,
    mask: npt.NDArray[np.bool_] | None = None,
    valid: tuple[int, int] | None = None,
    mask_nonfinite: bool = False,
    shape: tuple[int, int] = (0, 0),
    fortran: bool = False,
) -> PairStats: ...

# ---- frame I/O (rust/binding/io.rs) ---------------------------------------------------------

def load_frame(
    path: str | os.PathLike[str],
    channel: str | None = None,
    page: int = 0,
    max_pixels: int | None = None,
) -> npt.NDArray[Any]: ...
def page_count(path: str | os.PathLike[str]) -> int: ...
def list_channels(path: str | os.PathLike[str]) -> list[str]: ...
def default_max_pixels() -> int: ...

# ---- sequences (rust/binding/sequence.rs) ---------------------------------------------------

def score_pairs(
    real_paths: list[str | os.PathLike[str]],
    sim_paths: list[str | os.PathLike[str]],
    real_pages: list[int] | None = None,
    sim_pages: list[int] | None = None,
    *,
    channel: str | None = None,
    sse: bool = True,
    moments: bool = True,
    bins: int | None = None,
    levels: bool = False,
    hist_range: tuple[float, float] | None = None,
    valid: tuple[int, int] | None = None,
    mask_nonfinite: bool = False,
    max_pixels: int | None = None,
    workers: int = 0,
    progress: Callable[[int], Any] | None = None,
    on_result: Callable[[list[Any]], Any] | None = None,
) -> list[tuple[int, PairStats | None, str | None, tuple[int, int] | None, str | None]] | None: ...
def merge_all(stats: list[PairStats], keep_hist: bool = True) -> tuple[PairStats | None, bool]: ...

# ---- registration (rust/binding/register.rs) ------------------------------------------------

REGISTRATION_LOW_CONFIDENCE: float
REGISTRATION_AMBIGUOUS: float
REGISTRATION_MIN_OVERLAP: float

def register_frames(
    real: npt.NDArray[Any],
    sim: npt.NDArray[Any],
    model: str,
    method: str,
    max_shift: float | None = None,
    mask: npt.NDArray[np.bool_] | None = None,
) -> tuple[tuple[float, float, float, float, float, float], str, float, float, bool]: ...
def warp_frame(
    frame: npt.NDArray[Any],
    matrix: tuple[float, float, float, float, float, float],
    order: int,
    shape: tuple[int, int],
    mask: npt.NDArray[np.bool_] | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]: ...
