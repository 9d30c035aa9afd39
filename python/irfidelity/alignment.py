"""A registered pair scored in one call (paper §2.4, docs/registration.md).

With ``config.register`` set, a single pair is registered and a sequence is registered once
(on its first readable pair) or pair by pair (``register_each``); every registered pair then
takes the one path of ``_core.score_registered`` — the path the sequence engine takes for
each file pair: integer levels checked against the bit depth, the pair registered (or a
registration found before applied), the simulated frame resampled onto the real one, and the
statistics computed over the overlap (and the mask), both frames as float64, in one Rust call
with the GIL released.

Memory (docs/design.md §14): the one call plans its peak before it starts (the frames as
given, registration's working memory or the real frame as float64, the resampled one with its
overlap and the scored mask, whichever is more) against ``max_bytes``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from . import _core
from .budget import resolve
from .config import ScoringConfig
from .errors import ShapeError
from .registration import DEFAULT_ORDER, Registration, from_engine, warn_if_unsure
from .stats import PairRequest, _frame_pair

__all__ = ["RegisteredPair", "score_registered", "find_registration"]


@dataclass(frozen=True)
class RegisteredPair:
    """A pair scored through a registration.

    Attributes
    ----------
    stats : _core.PairStats
        The statistics over the scored pixels (both frames as float64).
    registration : Registration
        The registration applied (the pair's own when it was searched).
    extent : (float, float) or None
        The real frame's (min, max) over the scored pixels, when asked for.
    sim : ndarray
        The simulated frame resampled onto the real one (float64, NaN where it does not cover it).
    mask : ndarray
        The scored pixels: the overlap, and the caller's mask.
    """

    stats: Any
    registration: Registration
    extent: tuple[float, float] | None
    sim: np.ndarray
    mask: np.ndarray


def score_registered(real: Any, sim: Any, request: PairRequest, *, model: str | None = None,
                     method: str | None = None, registration: Registration | None = None, mask: Any = None,
                     extent: bool = False, max_bytes: int | None = None) -> RegisteredPair:
    """Register ``sim`` onto ``real`` (``model``, ``method``) or apply ``registration``, and
    compute what ``request`` asks for over the overlap, in one Rust call planned against the
    memory budget ``max_bytes`` (default :data:`irfidelity.budget.DEFAULT_MAX_BYTES`).

    ``request.valid`` bounds the integer samples before they are resampled; a searched
    registration of low confidence warns (:class:`~irfidelity.registration.RegistrationWarning`).
    """
    r, s = (np.ascontiguousarray(f) for f in _frame_pair(real, sim))
    if mask is not None:
        mask = np.ascontiguousarray(mask, dtype=bool)
        if mask.shape != r.shape:
            raise ShapeError(f"mask has shape {mask.shape}, frames have {r.shape}")
    if registration is None:
        assert model is not None and method is not None  # given whenever no registration is
        search, matrix = (model, method, None), None
    else:
        if tuple(registration.shape) != r.shape:
            raise ShapeError(f"sim has shape {r.shape}, the registration was made for {tuple(registration.shape)}")
        search, matrix = None, tuple(float(v) for v in registration.matrix.ravel())
    raw, found, span, aligned, scored = _core.score_registered(r, s, request, search=search, matrix=matrix,
                                                               order=DEFAULT_ORDER, mask=mask, extent=extent,
                                                               max_bytes=resolve(max_bytes))
    if found is not None:
        registration = from_engine(found, str(model), r.shape)
        warn_if_unsure(registration)
    assert registration is not None
    return RegisteredPair(raw, registration, span, aligned, scored)


def find_registration(real: np.ndarray, sim: np.ndarray, config: ScoringConfig, mask: Any = None,
                      max_bytes: int | None = None) -> Any:
    """The registration of ``sim`` onto ``real`` that ``config`` asks for (model, method),
    within the memory budget ``max_bytes``."""
    from .registration import register

    assert config.register is not None  # asked only when registering
    return register(real, sim, model=config.register, method=config.register_method,
                    mask=None if mask is None else np.asarray(mask, dtype=bool), max_bytes=max_bytes)
