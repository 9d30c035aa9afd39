"""How sure a score is: intervals over a sequence's frames, paired tests, sensor-noise intervals.

* :func:`bootstrap_ci` — a confidence interval for the fidelity and every component of a
  sequence from a *studentized circular block bootstrap* over frames (frames of a recording
  are correlated, so frames are resampled in blocks; :func:`block_length` states the rule).
  A pooled quantity is recomputed on every resample the way the sequence pools it: pass
  per-frame sufficient numbers (Σ squared error and pixel count for PSNR, ...:
  :func:`pool_numbers`) and a ``pool`` callable, e.g. :func:`sequence_pool`.
* :func:`paired_bootstrap` — the difference of two simulators scored on the same frames
  (both resampled with the same blocks): its interval, a p-value and ``significant``.
* :func:`psnr_noise_interval` (analytic) and :func:`noise_interval` (Monte Carlo through any
  metric) — one frame pair's interval from the real camera's temporal noise σ.

docs/ranking.md says what the intervals mean and how well they cover.

The method
----------
For a quantity θ pooled from the frames, the jackknife over frames gives its linearisation
``L_i = (n − 1)(θ − θ_(−i))`` (for a frame mean, ``L_i = x_i − x̄``); its circular block means
give the standard error ``se`` of θ and, on each resample, ``se*``. Resamples join
``⌈n / b⌉`` blocks of ``b`` consecutive frames, wrapping at the end, cut to ``n`` frames. With
``t* = (θ* − θ) / se*`` the interval at ``level`` is ``[θ − t*_(1−a)·se, θ − t*_(a)·se]``,
``a = (1 − level) / 2`` (the bootstrap-t of Götze & Künsch 1996; quantiles are order
statistics, numpy's ``inverted_cdf``). Studentizing corrects much of the too-narrow intervals
the plain percentile method gives on correlated frames (docs/ranking.md has the figures).
The block length ``b`` (:func:`block_length`) follows the frames' correlation but leaves at
least :data:`MIN_BLOCKS` (5) blocks; when the frames are too few for blocks of the length their
correlation asks for, the results carry a ``note`` and a :class:`ShortRecordingWarning` is
issued (:func:`short_recording_note`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from numbers import Real
from statistics import NormalDist
from typing import Any, Callable, Mapping

import numpy as np

from .config import ScoringConfig
from .errors import FidelityError, ShortRecordingWarning
from .fuzzy import COMPONENTS, Weights, fidelity_sum
from .metrics import psnr_from_mse
from .normalize import DEFAULT_PSNR_ANCHORS, normalize_psnr
from .temperature import frame_exponent, radiometry_of_exponent

__all__ = ["block_length", "wanted_block_length", "short_recording_note", "MIN_BLOCKS", "ShortRecordingWarning",
           "bootstrap_ci", "paired_bootstrap", "Intervals", "PairedTest", "sequence_pool",
           "pool_numbers", "POOL_INPUTS", "psnr_noise_interval", "noise_interval", "DEFAULT_RESAMPLES"]

#: Resamples drawn when none is given.
DEFAULT_RESAMPLES = 2000

#: A pool: ``pool(sums, frames)`` → ``{quantity: value}`` from the per-frame numbers summed over a
#: resample's ``frames`` frames.
Pool = Callable[[Mapping[str, float], int], Mapping[str, float]]

_MAX_RHO = 0.99  # lag-1 autocorrelations are clipped here before the block-length rule

#: Fewest blocks :func:`block_length` leaves a resample (its notes say why).
MIN_BLOCKS = 5


# --------------------------------------------------------------------------- inputs
def check_level(level: float) -> float:
    """``level`` as a float in (0, 1), else FidelityError."""
    value = float(level) if isinstance(level, Real) and not isinstance(level, bool) else math.nan
    if not 0 < value < 1:
        raise FidelityError(f"level must be a number in (0, 1), e.g. 0.95; got {level!r}", option="level")
    return value


def check_non_negative(name: str, value: Any) -> float:
    """``value`` as a finite float >= 0, else FidelityError naming ``name``."""
    number = float(value) if isinstance(value, Real) and not isinstance(value, bool) else math.nan
    if not (math.isfinite(number) and number >= 0):
        raise FidelityError(f"{name} must be a finite number >= 0, got {value!r}", option=name)
    return number


#: The most resamples: Monte Carlo error far below the sampling error already at 10,000, and the
#: resamples' arrays (one value per resample and simulator) stay within tens of megabytes.
MAX_RESAMPLES = 1_000_000


def check_resamples(resamples: int) -> int:
    if isinstance(resamples, bool) or not isinstance(resamples, (int, np.integer)) \
            or not 99 <= resamples <= MAX_RESAMPLES:
        raise FidelityError(f"resamples must be an integer in 99..{MAX_RESAMPLES}, got {resamples!r}",
                            option="resamples")
    return int(resamples)


def as_generator(rng: Any) -> np.random.Generator:
    """A numpy Generator, or one seeded with the given integer."""
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        return np.random.default_rng(int(rng))
    raise FidelityError(f"rng must be a numpy Generator or an integer seed, got {rng!r}", option="rng")


@dataclass(frozen=True)
class FrameSeries:
    """Per-frame numbers of one simulator: ``values[i, j]`` is number ``names[j]`` of frame ``i``."""

    names: tuple
    values: np.ndarray

    @property
    def frames(self) -> int:
        return self.values.shape[0]


def frame_series(per_frame: Mapping[str, Any], label: str = "per_frame") -> FrameSeries:
    """Validate ``{name: 1-D array of per-frame numbers}`` (equal lengths >= 2, finite)."""
    if not isinstance(per_frame, Mapping) or not per_frame:
        raise FidelityError(f"{label} must be a non-empty mapping {{name: per-frame values}}, "
                            f"got {type(per_frame).__name__}")
    columns = []
    for name, values in per_frame.items():
        try:
            column = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError):
            raise FidelityError(f"{label}[{name!r}] must be numbers, one per frame") from None
        if column.ndim != 1:
            raise FidelityError(f"{label}[{name!r}] must be 1-D (one number per frame), got shape {column.shape}")
        bad = np.flatnonzero(~np.isfinite(column))
        if bad.size:
            raise FidelityError(f"{label}[{name!r}] frame {int(bad[0])} is {float(column[bad[0]])!r}: drop failed "
                                f"frames before bootstrapping")
        columns.append(column)
    lengths = {len(c) for c in columns}
    if len(lengths) != 1:
        raise FidelityError(f"{label}: every series needs one value per frame; got lengths "
                            f"{dict(zip(per_frame, map(len, columns)))}")
    if columns[0].size < 2:
        raise FidelityError(f"{label}: an interval over frames needs at least 2 frames, got {columns[0].size}")
    return FrameSeries(tuple(str(k) for k in per_frame), np.column_stack(columns))


# --------------------------------------------------------------------------- pooling
def _pooled(series: FrameSeries, sums: np.ndarray, frames: int, pool: Pool | None) -> dict[str, np.ndarray]:
    """Each quantity for each row of ``sums`` (rows × names: the numbers summed over ``frames``)."""
    if pool is None:
        return {name: sums[:, j] / frames for j, name in enumerate(series.names)}
    rows = [pool(dict(zip(series.names, map(float, row))), frames) for row in sums]
    if not all(isinstance(r, Mapping) for r in rows):
        raise FidelityError("pool must return a mapping {quantity: value}")
    names = tuple(rows[0])
    out = {}
    for q in names:
        try:
            out[q] = np.array([float(r[q]) for r in rows])
        except (KeyError, TypeError, ValueError):
            raise FidelityError(f"pool must return the same numeric quantities on every resample; "
                                f"{q!r} is missing or not a number on one") from None
        bad = np.flatnonzero(~np.isfinite(out[q]))
        if bad.size:
            raise FidelityError(f"pool returned {float(out[q][bad[0]])!r} for {q!r}; every pooled quantity must "
                                f"be finite (return components, not +inf dB)")
    return out


@dataclass(frozen=True)
class Linearized:
    """A simulator's pooled quantities and their jackknife linearisations over frames."""

    estimate: dict
    influence: dict


def linearize(series: FrameSeries, pool: Pool | None) -> Linearized:
    """The pooled estimate of every quantity and ``L_i = (n − 1)(θ − θ_(−i))`` over frames ``i``."""
    n = series.frames
    total = series.values.sum(axis=0)
    estimate = {q: float(v[0]) for q, v in _pooled(series, total[None, :], n, pool).items()}
    left_out = _pooled(series, total[None, :] - series.values, n - 1, pool)
    if set(left_out) != set(estimate):
        raise FidelityError("pool must return the same quantities for every set of frames")
    influence = {q: (n - 1) * (estimate[q] - left_out[q]) for q in estimate}
    return Linearized(estimate, influence)


# --------------------------------------------------------------------------- resampling
def _lag1(series: np.ndarray) -> float:
    centred = series - series.mean()
    energy = float(centred @ centred)
    return 0.0 if energy == 0 else float(centred[1:] @ centred[:-1]) / energy


def _series_arrays(series: tuple) -> list[np.ndarray]:
    """The series as 1-D float arrays of one length >= 2, else FidelityError."""
    if not series:
        raise FidelityError("block_length needs at least one series")
    arrays = [np.asarray(s, dtype=np.float64) for s in series]
    n = arrays[0].size
    if n < 2 or any(a.ndim != 1 or a.size != n for a in arrays):
        raise FidelityError("block_length needs 1-D series of equal length >= 2")
    return arrays


def wanted_block_length(*series: Any) -> int:
    """The block length (frames) the series' correlation asks for, before the cap of
    :func:`block_length`: ``⌈2·(6ρ² / (1 − ρ²)²)^(1/3)·n^(1/3)⌉``, at least 1 (its notes).

    Examples
    --------
    >>> import numpy as np
    >>> from irfidelity.bootstrap import block_length, wanted_block_length
    >>> slow = np.sin(np.arange(100) / 20.0)
    >>> wanted_block_length(slow), block_length(slow)     # 100 frames allow blocks of 20
    (183, 20)
    """
    arrays = _series_arrays(series)
    n = arrays[0].size
    rho = min(max(abs(_lag1(a)) for a in arrays), _MAX_RHO)
    length = math.ceil(2.0 * (6.0 * rho * rho / (1.0 - rho * rho) ** 2) ** (1 / 3) * n ** (1 / 3) - 1e-9)
    return int(max(length, 1))


def longest_block(frames: int) -> int:
    """The longest block :func:`block_length` gives ``frames`` frames: ``frames // MIN_BLOCKS``, at least 1."""
    return max(1, frames // MIN_BLOCKS)


def block_length(*series: Any) -> int:
    """Block length (frames) for resampling ``n`` frames: twice the AR(1) plug-in of the
    Politis–White length, capped so that a resample has at least :data:`MIN_BLOCKS` blocks.

    With ``ρ`` the largest absolute lag-1 autocorrelation of the given series (clipped at
    0.99), the length is ``⌈2·(6ρ² / (1 − ρ²)²)^(1/3)·n^(1/3)⌉`` (:func:`wanted_block_length`),
    kept within ``[1, max(1, n // 5)]``. ``(6ρ²/(1−ρ²)²)^(1/3)·n^(1/3)`` is Politis & White's
    (2004, with Patton et al. 2009) MSE-optimal circular-block length for an AR(1) series;
    doubling it trades a little interval variance for less bias of the standard error, which
    is what decides coverage (docs/ranking.md has the figures). A series without lag-1
    correlation gets 1 (the ordinary bootstrap); white noise's sampling correlation of about
    ±0.1 gives a few frames.

    The cap keeps at least five blocks per resample: the standard error that studentizes every
    interval and test is the spread of the linearisation's block means, and with three or four
    of them (12 frames in blocks of 4) it is so erratic that intervals swing from far too narrow
    to absurdly wide. When the cap binds, the blocks are shorter than the frames' correlation asks
    for and the intervals are likely too narrow: :func:`short_recording_note` says so, and the
    bootstrap functions warn (:class:`ShortRecordingWarning`).

    Examples
    --------
    >>> import numpy as np
    >>> from irfidelity.bootstrap import block_length
    >>> block_length(np.tile([0.0, 1.0], 50))           # lag-1 correlation −0.98: n // 5
    20
    >>> block_length(np.sin(np.arange(100) / 20.0))      # slowly varying: long blocks
    20
    >>> block_length(np.random.default_rng(0).normal(size=100))   # white noise: short blocks
    4
    >>> block_length(np.sin(np.arange(12) / 3.0))        # 12 frames: blocks of 2, six of them
    2
    """
    frames = _series_arrays(series)[0].size
    return min(wanted_block_length(*series), longest_block(frames))


def short_recording_note(frames: int, block: int, wanted: int) -> str | None:
    """Why ``frames`` frames resampled in blocks of ``block`` are too few for honest intervals, or None.

    They are when they make fewer than :data:`MIN_BLOCKS` blocks of the ``wanted`` length
    (:func:`wanted_block_length`): the resamples then cut the frames into blocks shorter than
    their correlation asks for (or into fewer than five), so the intervals are likely too narrow
    and the tests too ready to call a difference significant (docs/ranking.md has the figures).

    Examples
    --------
    >>> from irfidelity.bootstrap import short_recording_note
    >>> short_recording_note(100, 20, 12) is None
    True
    >>> short_recording_note(12, 2, 4)[:52]
    '12 frames are too few for honest intervals: their co'
    """
    if wanted <= frames // MIN_BLOCKS:
        return None
    return (f"{frames} frames are too few for honest intervals: their correlation asks for blocks of {wanted} "
            f"frame(s) and at least {MIN_BLOCKS} blocks ({MIN_BLOCKS * wanted} frames); resampled in blocks of "
            f"{block}, the intervals are likely too narrow and the tests and P(first) too sure. Record more "
            f"frames, or frames further apart")


@dataclass(frozen=True)
class Resampling:
    """Circular block resamples of ``frames`` frames: ``starts[r]`` are resample ``r``'s block starts;
    ``note`` says why the frames are too few for honest intervals (:func:`short_recording_note`), or None."""

    frames: int
    block: int
    starts: np.ndarray
    note: str | None = None

    @classmethod
    def draw(cls, frames: int, block: int, resamples: int, rng: np.random.Generator,
             note: str | None = None) -> Resampling:
        blocks = -(-frames // block)
        return cls(frames, block, rng.integers(0, frames, size=(resamples, blocks)), note)

    @property
    def resamples(self) -> int:
        return self.starts.shape[0]

    def sums(self, values: np.ndarray) -> np.ndarray:
        """``values`` (frames × numbers) summed over each resample's frames: resamples × numbers.

        Resample ``r`` is the blocks starting at ``starts[r]``, the last one cut so that the
        resample has exactly ``frames`` frames."""
        blocks = self.starts.shape[1]
        last = self.frames - (blocks - 1) * self.block  # frames of the last, possibly cut, block
        full = circular_block_sums(values, self.block)[self.starts[:, :-1]].sum(axis=1)
        return full + circular_block_sums(values, last)[self.starts[:, -1]]

    def standard_errors(self, influence: np.ndarray) -> tuple[float, np.ndarray]:
        """``se`` of the full-sample estimate and ``se*`` of each resample, from the block means
        of the linearisation ``influence``."""
        block_means = circular_block_sums(influence, self.block) / self.block
        blocks = self.starts.shape[1]
        se = float(block_means.std()) / math.sqrt(blocks)
        return se, block_means[self.starts].std(axis=1) / math.sqrt(blocks)


def circular_block_sums(values: np.ndarray, length: int) -> np.ndarray:
    """``out[i]``: the sum of ``values[i], …, values[i + length − 1]`` (indices mod frames), per column."""
    frames = values.shape[0]
    wrapped = np.concatenate([values, values[: length - 1]])
    cumulative = np.concatenate([np.zeros((1,) + values.shape[1:]), np.cumsum(wrapped, axis=0)])
    return cumulative[length:length + frames] - cumulative[:frames]


def resample(series: FrameSeries, resampling: Resampling, pool: Pool | None) -> dict[str, np.ndarray]:
    """Every quantity pooled on every resample: ``{quantity: array (resamples,)}``."""
    return _pooled(series, resampling.sums(series.values), series.frames, pool)


# --------------------------------------------------------------------------- intervals and tests
def _t_draws(estimate: float, draws: np.ndarray, se_star: np.ndarray) -> np.ndarray:
    """``(θ* − θ) / se*``; a resample whose blocks all agree (se* = 0) gives 0 or ±inf."""
    excess = draws - estimate
    flat = se_star <= 0
    t = np.divide(excess, se_star, out=np.zeros_like(excess), where=~flat)
    t[flat & (excess != 0)] = np.sign(excess[flat & (excess != 0)]) * np.inf
    return t


def studentized_interval(estimate: float, draws: np.ndarray, influence: np.ndarray, resampling: Resampling,
                         level: float) -> tuple[float, float]:
    """The bootstrap-t interval of the module notes; ``(θ, θ)`` when no frame moves θ."""
    se, se_star = resampling.standard_errors(influence)
    if se == 0:
        return (estimate, estimate)
    tail = (1 - level) / 2
    low_t, high_t = np.quantile(_t_draws(estimate, draws, se_star), [tail, 1 - tail], method="inverted_cdf")
    return (float(estimate - high_t * se), float(estimate - low_t * se))


def studentized_p_value(estimate: float, draws: np.ndarray, influence: np.ndarray,
                        resampling: Resampling) -> float:
    """Two-sided p-value of θ = 0, equal-tailed like the interval: ``2·(min(#{t* ≥ t}, #{t* ≤ t}) + 1)
    / (B + 1)`` with ``t = θ / se`` (below ``1 − level`` about when the interval excludes 0; the
    smallest, ``2 / (B + 1)``, also when no frame moves a non-zero θ)."""
    se, se_star = resampling.standard_errors(influence)
    rows = resampling.resamples
    if se == 0:
        return 1.0 if estimate == 0 else 2.0 / (rows + 1)
    t = _t_draws(estimate, draws, se_star)
    observed = estimate / se
    tail = min(int(np.count_nonzero(t >= observed)), int(np.count_nonzero(t <= observed)))
    return min(1.0, 2.0 * (tail + 1) / (rows + 1))


@dataclass(frozen=True)
class Intervals:
    """Confidence intervals over frames (:func:`bootstrap_ci`) or sensor noise (:func:`noise_interval`).

    Attributes
    ----------
    estimate : dict
        ``{quantity: value}`` from all frames (or the observed pair).
    ci : dict
        ``{quantity: (lo, hi)}`` at ``level``.
    level : float
    method : str
    block, resamples, frames : int
        Block length, resamples (draws) and frames behind the intervals (block 0 when no
        frames were resampled).
    note : str or None
        Why the frames are too few for honest intervals (:func:`short_recording_note`: the
        intervals are then likely too narrow), or None.
    """

    estimate: dict
    ci: dict
    level: float
    method: str
    block: int
    resamples: int
    frames: int
    note: str | None = None

    def to_dict(self) -> dict:
        return {"estimate": dict(self.estimate), "ci": {q: list(v) for q, v in self.ci.items()},
                "level": self.level, "method": self.method, "block": self.block, "resamples": self.resamples,
                "frames": self.frames, "note": self.note}


@dataclass(frozen=True)
class PairedTest:
    """The difference A − B of two simulators on the same frames (:func:`paired_bootstrap`).

    Attributes
    ----------
    difference : dict
        ``{quantity: θ_A − θ_B}`` from all frames.
    ci : dict
        ``{quantity: (lo, hi)}``: the interval of the difference at ``level``.
    p_value : dict
        ``{quantity: p}``, two-sided, of "no difference".
    significant : dict
        ``{quantity: p < 1 − level}`` (no multiple-comparison correction here; see
        :func:`irfidelity.ranking.rank`).
    level : float
    block, resamples, frames : int
    note : str or None
        As :attr:`Intervals.note`: why the frames are too few for an honest test, or None.
    """

    difference: dict
    ci: dict
    p_value: dict
    significant: dict
    level: float
    block: int
    resamples: int
    frames: int
    note: str | None = None

    def to_dict(self) -> dict:
        return {"difference": dict(self.difference), "ci": {q: list(v) for q, v in self.ci.items()},
                "p_value": dict(self.p_value), "significant": dict(self.significant), "level": self.level,
                "block": self.block, "resamples": self.resamples, "frames": self.frames, "note": self.note}


_METHOD = "studentized circular block bootstrap over frames"


def plan_resampling(influences: list[np.ndarray], frames: int, block: int | None, resamples: int,
                    rng: Any) -> Resampling:
    """Resamples for ``frames`` frames, with the given block length or :func:`block_length`'s;
    a :class:`ShortRecordingWarning` (and the resampling's ``note``) when the frames are too few
    for honest intervals (:func:`short_recording_note`)."""
    if block is not None and (isinstance(block, bool) or not isinstance(block, (int, np.integer))
                              or not 1 <= block <= frames):
        raise FidelityError(f"block must be an integer in [1, {frames}] (frames), got {block!r}", option="block")
    count, generator = check_resamples(resamples), as_generator(rng)  # bad arguments fail before any warning
    wanted = wanted_block_length(*influences)
    length = min(wanted, longest_block(frames)) if block is None else int(block)
    note = short_recording_note(frames, length, wanted)
    if note is not None:
        warnings.warn(note, ShortRecordingWarning, stacklevel=3)
    return Resampling.draw(frames, length, count, generator, note)


def bootstrap_ci(per_frame: Mapping[str, Any], *, pool: Pool | None = None, level: float = 0.95,
                 resamples: int = DEFAULT_RESAMPLES, block: int | None = None, rng: Any = 0) -> Intervals:
    """Confidence intervals over frames for every quantity of one sequence.

    Parameters
    ----------
    per_frame : {name: 1-D array}
        One number per frame (failed frames left out), in recording order. Without ``pool``,
        each name is a quantity estimated by its frame mean (e.g. per-frame ``fidelity`` and
        components). With ``pool``, the names are additive per-frame numbers (e.g. ``sse``
        and ``n``) that ``pool`` turns into the quantities.
    pool : callable(sums, frames) -> {quantity: value}, optional
        Pools the numbers summed over a resample's ``frames`` frames, the way the sequence pools
        (:func:`sequence_pool` does it for the fidelity and its components). Values must be finite.
    level : float
        Confidence level of each interval (not simultaneous over quantities).
    resamples : int
        Bootstrap resamples (>= 99).
    block : int, optional
        Frames per block; default :func:`block_length` of the quantities' linearisations.
    rng : numpy Generator or int
        Randomness (default seed 0: reproducible).

    Returns
    -------
    Intervals
        ``.estimate`` and ``.ci`` ``{quantity: (lo, hi)}`` by the studentized circular block
        bootstrap of the module notes; ``.note`` (and a :class:`ShortRecordingWarning`) when
        the frames are too few for honest intervals (:func:`short_recording_note`).

    Examples
    --------
    The mean of 100 correlated per-frame values, and a PSNR pooled from ΣSSE / ΣN:

    >>> import math, numpy as np
    >>> from irfidelity.bootstrap import bootstrap_ci
    >>> rng = np.random.default_rng(1)
    >>> fidelity = 0.9 + 0.01 * np.convolve(rng.normal(size=102), np.ones(3) / 3, "valid")
    >>> ci = bootstrap_ci({"fidelity": fidelity}, level=0.9)
    >>> lo, hi = ci.ci["fidelity"]
    >>> bool(lo < fidelity.mean() < hi), ci.block, ci.note
    (True, 17, None)
    >>> frames = {"sse": rng.uniform(90, 110, 100) * 1000, "n": np.full(100, 1000.0)}
    >>> psnr = lambda sums, k: {"psnr_db": 10 * math.log10(255.0 ** 2 * sums["n"] / sums["sse"])}
    >>> ci = bootstrap_ci(frames, pool=psnr, level=0.9)
    >>> round(ci.estimate["psnr_db"], 2), [round(v, 2) for v in ci.ci["psnr_db"]]
    (28.13, [28.09, 28.17])
    """
    level = check_level(level)
    series = frame_series(per_frame)
    lin = linearize(series, pool)
    resampling = plan_resampling(list(lin.influence.values()), series.frames, block, resamples, rng)
    draws = resample(series, resampling, pool)
    ci = {q: studentized_interval(lin.estimate[q], draws[q], lin.influence[q], resampling, level)
          for q in lin.estimate}
    return Intervals(estimate=lin.estimate, ci=ci, level=level, method=_METHOD, block=resampling.block,
                     resamples=resampling.resamples, frames=series.frames, note=resampling.note)


def compare_replicates(a: tuple[Linearized, dict], b: tuple[Linearized, dict], resampling: Resampling,
                       level: float) -> PairedTest:
    """The paired test of A − B from each side's linearisation and draws on the same resamples."""
    (lin_a, draws_a), (lin_b, draws_b) = a, b
    if set(lin_a.estimate) != set(lin_b.estimate):
        raise FidelityError(f"the two simulators have different quantities: {sorted(lin_a.estimate)} "
                            f"and {sorted(lin_b.estimate)}")
    difference, ci, p = {}, {}, {}
    for q in lin_a.estimate:
        est = lin_a.estimate[q] - lin_b.estimate[q]
        draws = draws_a[q] - draws_b[q]
        influence = lin_a.influence[q] - lin_b.influence[q]
        difference[q] = est
        ci[q] = studentized_interval(est, draws, influence, resampling, level)
        p[q] = studentized_p_value(est, draws, influence, resampling)
    return PairedTest(difference=difference, ci=ci, p_value=p, significant={q: v < 1 - level for q, v in p.items()},
                      level=level, block=resampling.block, resamples=resampling.resamples,
                      frames=resampling.frames, note=resampling.note)


def difference_influences(linearized: list[Linearized]) -> list[np.ndarray]:
    """Every linearisation and every pairwise difference of them (what the block length is chosen on)."""
    out = [v for lin in linearized for v in lin.influence.values()]
    for i, first in enumerate(linearized):
        for second in linearized[i + 1:]:
            out += [first.influence[q] - second.influence[q] for q in first.influence if q in second.influence]
    return out


def paired_bootstrap(per_frame_a: Mapping[str, Any], per_frame_b: Mapping[str, Any], *, pool: Pool | None = None,
                     level: float = 0.95, resamples: int = DEFAULT_RESAMPLES, block: int | None = None,
                     rng: Any = 0) -> PairedTest:
    """Is simulator A's score different from B's? A paired block bootstrap over the same frames.

    Both simulators must be scored against the same real frames, in the same order: every
    resample takes the same blocks of frames from both, so what the frames share (the scene)
    cancels from the difference. Arguments as in :func:`bootstrap_ci`; ``block`` defaults to
    :func:`block_length` of both sides' linearisations and of their differences.

    Returns
    -------
    PairedTest
        Per quantity: the difference A − B, its interval at ``level``, the two-sided p-value
        of "no difference" (the bootstrap-t, equal-tailed like the interval) and
        ``significant`` (``p < 1 − level``); ``.note`` as in :func:`bootstrap_ci`.

    Examples
    --------
    Two simulators whose per-frame fidelity differs by 0.01 over a shared scene signal:

    >>> import numpy as np
    >>> from irfidelity.bootstrap import paired_bootstrap
    >>> rng = np.random.default_rng(2)
    >>> scene = 0.05 * np.convolve(rng.normal(size=102), np.ones(3) / 3, "valid")
    >>> a = 0.90 + scene + rng.normal(0, 0.004, 100)
    >>> b = 0.89 + scene + rng.normal(0, 0.004, 100)
    >>> test = paired_bootstrap({"fidelity": a}, {"fidelity": b})
    >>> round(test.difference["fidelity"], 3), test.significant["fidelity"]
    (0.011, True)
    """
    level = check_level(level)
    sides = [frame_series(per_frame_a, "per_frame_a"), frame_series(per_frame_b, "per_frame_b")]
    if sides[0].frames != sides[1].frames:
        raise FidelityError(f"a paired test needs the same frames on both sides; got {sides[0].frames} and "
                            f"{sides[1].frames} frames")
    lins = [linearize(s, pool) for s in sides]
    resampling = plan_resampling(difference_influences(lins), sides[0].frames, block, resamples, rng)
    replicates = [(lin, resample(s, resampling, pool)) for lin, s in zip(lins, sides)]
    return compare_replicates(replicates[0], replicates[1], resampling, level)


# --------------------------------------------------------------------------- the sequence's pooling
#: Per-frame numbers :func:`sequence_pool` needs for each component pooled from the frames
#: (:func:`pool_numbers` makes them from a frame's entry): the pixel pairs ``n``, the squared
#: error ``sse``, and each frame's value weighted by its pixel pairs.
POOL_INPUTS = {
    "psnr": ("n", "sse"),
    "nmi": ("n", "n_nmi"),
    "ssim": ("n", "n_ssim"),
    "radiometry": ("n", "n_radiometry_exponent"),
}


def pool_numbers(frame: Mapping[str, Any], components: Any) -> dict[str, float]:
    """The per-frame numbers of :data:`POOL_INPUTS` for ``components`` from a sequence frame's
    entry (``frame["metrics"]``, ``frame["components"]``): ``n``, ``sse = mse·n``, ``n_nmi``,
    ``n_ssim`` (the frame's component times ``n``) and ``n_radiometry_exponent`` (``n`` times
    :func:`irfidelity.temperature.frame_exponent`).

    Examples
    --------
    >>> from irfidelity.bootstrap import pool_numbers
    >>> frame = {"metrics": {"n": 100, "mse": 4.0}, "components": {"ssim": 0.5, "psnr": 0.9}}
    >>> pool_numbers(frame, ("psnr", "ssim"))
    {'n': 100, 'sse': 400.0, 'n_ssim': 50.0}
    """
    metrics, comps = frame["metrics"], frame["components"]
    n = int(metrics["n"])
    out: dict[str, float] = {"n": n}
    if "psnr" in components:
        out["sse"] = float(metrics["mse"]) * n
    for component in ("nmi", "ssim"):
        if component in components:
            out[f"n_{component}"] = n * float(comps[component])
    if "radiometry" in components:
        out["n_radiometry_exponent"] = n * frame_exponent(metrics)
    return out


def sequence_pool(weights: Any = None, *, config: ScoringConfig | None = None, peak: float | None = None,
                  camera: Mapping[str, float] | None = None) -> Pool:
    """A ``pool`` for :func:`bootstrap_ci` that pools a resample as a sequence does.

    PSNR from ΣSSE / ΣN (eq. 5, normalised by eq. 6 with ``config.psnr_anchors``), SSIM and NMI
    as the pixel-weighted means of the frames' (Σ n·x / Σ n), radiometry as ``0.9`` to the
    pixel-weighted mean of the frames' exponents, the camera components ``camera`` (mtf, sitf,
    noise, mrtd: the same for every frame), and the fidelity (eq. 15) under ``weights``
    (:mod:`irfidelity.sequence.pooling` says why each lies within its frames' values).

    Parameters
    ----------
    weights : Weights or anything :meth:`Weights.coerce` accepts, optional
        Default ``config.weights``.
    config : ScoringConfig, optional
        Anchors (default ``ScoringConfig()``).
    peak : float
        The PSNR peak the sequence used (``report.metrics["psnr_peak"]``); needed when psnr
        is weighted.
    camera : {component: value}, optional
        The camera components (``report.components`` of mtf, sitf, noise, mrtd) when weighted.

    Returns
    -------
    callable(sums, frames) -> {"fidelity": f, component: f_i, ...}
        It reads the per-frame numbers :data:`POOL_INPUTS` lists for the weighted components
        (:func:`pool_numbers` makes them from a frame's entry).

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> from irfidelity.bootstrap import pool_numbers, sequence_pool
    >>> real = np.arange(64, dtype=np.uint16).reshape(1, 8, 8)
    >>> rep = irf.score_sequence(real, real + 2, weights="psnr=0.5,ssim=0.5", peak=63.0, progress=False)
    >>> sums = pool_numbers(rep.frames[0], ("psnr", "ssim"))
    >>> pool = sequence_pool("psnr=0.5,ssim=0.5", peak=63.0)
    >>> {k: round(v, 4) for k, v in pool(sums, 1).items()}
    {'fidelity': 0.9488, 'psnr': 0.8996, 'ssim': 0.9981}
    """
    cfg = ScoringConfig() if config is None else config
    w = cfg.weights if weights is None else Weights.coerce(weights)
    image = tuple(k for k in w.active() if k in POOL_INPUTS)
    curves = {k: float(v) for k, v in (camera or {}).items()}
    missing = [k for k in w.active() if k not in POOL_INPUTS and k not in curves]
    if missing:
        raise FidelityError(f"component(s) {missing} are weighted: give their values in camera=", option="camera")
    unknown = set(curves) - set(COMPONENTS)
    if unknown:
        raise FidelityError(f"camera: unknown component(s) {sorted(unknown)}", option="camera")
    if "psnr" in image and not (peak is not None and math.isfinite(peak) and peak > 0):
        raise FidelityError(f"psnr is weighted: give the PSNR peak the sequence used, got {peak!r}", option="peak")
    needed = sorted({name for k in image for name in POOL_INPUTS[k]})

    def pool(sums: Mapping[str, float], frames: int) -> dict[str, float]:
        absent = [name for name in needed if name not in sums]
        if absent:
            raise FidelityError(f"sequence_pool needs the per-frame numbers {needed}; missing {absent}")
        comps = dict(curves)
        if "psnr" in image:
            db = psnr_from_mse(sums["sse"] / sums["n"], float(peak))  # type: ignore[arg-type]
            comps["psnr"] = normalize_psnr(db, anchors=cfg.psnr_anchors)
        for component in ("nmi", "ssim"):
            if component in image:
                comps[component] = sums[f"n_{component}"] / sums["n"]
        if "radiometry" in image:
            comps["radiometry"] = radiometry_of_exponent(sums["n_radiometry_exponent"] / sums["n"])
        return {"fidelity": fidelity_sum(w, comps), **{k: comps[k] for k in COMPONENTS if k in comps}}

    return pool


# --------------------------------------------------------------------------- one pair, sensor noise
def psnr_noise_interval(mse: float, n: int, sigma: float, *, peak: float, level: float = 0.95,
                        anchors: Any = DEFAULT_PSNR_ANCHORS) -> Intervals:
    """Interval of one pair's MSE, PSNR and normalised PSNR from the real camera's temporal noise.

    Model: the real frame is ``scene + e`` with ``e`` independent Gaussian noise of known
    standard deviation ``sigma`` per pixel (e.g. the temporal noise σ_tvh of
    :func:`irfidelity.noise.noise3d`, or ``std(real_1 − real_2) / √2`` from two frames of a static
    scene). Over noise realisations, with ``m = mean((scene − sim)²)``, the MSE has mean
    ``m + σ²`` and variance ``(4σ²m + 2σ⁴) / n``; ``m`` is estimated by ``max(mse − σ², 0)``.
    The interval ``mse ± z·sd`` (normal, ``n`` is large; the lower end clipped at 0) covers the
    noise-averaged MSE with probability ``level``, and maps to PSNR (dB) and its component
    (eq. 6) because both are monotone in the MSE.

    Returns
    -------
    Intervals
        Quantities ``mse``, ``psnr_db``, ``psnr`` (a bound at MSE 0 is ``+inf`` dB, component 1).

    Examples
    --------
    >>> from irfidelity.bootstrap import psnr_noise_interval
    >>> ci = psnr_noise_interval(400.0, 640 * 512, 10.0, peak=16383.0)
    >>> [round(v, 3) for v in ci.ci["psnr_db"]]
    [58.253, 58.281]
    """
    level = check_level(level)
    for name, value in {"mse": mse, "sigma": sigma, "peak": peak}.items():
        check_non_negative(name, value)
    if not peak > 0:
        raise FidelityError(f"peak must be > 0, got {peak!r}", option="peak")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise FidelityError(f"n must be a positive integer (pixel pairs), got {n!r}", option="n")
    variance = sigma * sigma
    systematic = max(mse - variance, 0.0)
    sd = math.sqrt((4 * variance * systematic + 2 * variance * variance) / n)
    z = NormalDist().inv_cdf(0.5 + level / 2)
    low, high = max(mse - z * sd, 0.0), mse + z * sd
    db = {"estimate": psnr_from_mse(mse, peak), "low": psnr_from_mse(high, peak), "high": psnr_from_mse(low, peak)}
    estimate = {"mse": float(mse), "psnr_db": db["estimate"], "psnr": normalize_psnr(db["estimate"], anchors=anchors)}
    ci = {"mse": (low, high), "psnr_db": (db["low"], db["high"]),
          "psnr": (normalize_psnr(db["low"], anchors=anchors), normalize_psnr(db["high"], anchors=anchors))}
    return Intervals(estimate=estimate, ci=ci, level=level, method="analytic, Gaussian temporal noise",
                     block=0, resamples=0, frames=1)


def _scores(value: Any) -> dict[str, float]:
    if isinstance(value, Mapping):
        return {str(k): float(v) for k, v in value.items()}
    return {"value": float(value)}


def noise_interval(real: Any, sim: Any, sigma: float, score: Callable[[np.ndarray, np.ndarray], Any], *,
                   draws: int = 200,
                   level: float = 0.95, rng: Any = 0) -> Intervals:
    """Interval of one pair's scores from the real camera's temporal noise, through any metric.

    ``score(real_frame, sim)`` is evaluated on ``real + e_k`` for ``draws`` draws of Gaussian
    noise ``e_k`` of standard deviation ``sigma`` (both frames as float64). The spread of
    the draws around their mean, centred on the observed score, is the interval:
    ``score(real) + (q_a, q_(1−a))`` of ``score(real + e_k) − mean_k``. The perturbed frames carry
    noise √2·σ, so the spread is somewhat wider than another noise realisation would give
    when the noise is a large part of the difference (conservative); where the systematic
    difference dominates it agrees with :func:`psnr_noise_interval` (tests/test_ranking.py).

    Parameters
    ----------
    score : callable(real_frame, sim) -> float or {quantity: float}
        E.g. ``lambda r, s: irf.evaluate(r, s, peak=p).components`` (fix the PSNR peak: a
        float frame has no dtype range).

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> from irfidelity.bootstrap import noise_interval
    >>> y, x = np.mgrid[0:64, 0:64]
    >>> real = 3000 + 300 * np.sin(x / 5.0) * np.cos(y / 7.0)
    >>> sim = real + 20 * np.cos(x / 3.0)
    >>> ci = noise_interval(real, sim, 2.0, lambda r, s: irf.stats.psnr(r, s, peak=600.0), draws=100)
    >>> lo, hi = ci.ci["value"]
    >>> bool(lo < ci.estimate["value"] < hi), round(hi - lo, 2)
    (True, 0.07)
    """
    level = check_level(level)
    check_non_negative("sigma", sigma)
    if isinstance(draws, bool) or not isinstance(draws, (int, np.integer)) or draws < 20:
        raise FidelityError(f"draws must be an integer >= 20, got {draws!r}", option="draws")
    frame, other = np.asarray(real, dtype=np.float64), np.asarray(sim, dtype=np.float64)
    generator = as_generator(rng)
    observed = _scores(score(frame, other))
    runs = [_scores(score(frame + generator.normal(0.0, sigma, frame.shape), other)) for _ in range(int(draws))]
    tail = (1 - level) / 2
    ci = {}
    for q, value in observed.items():
        spread = np.array([run[q] for run in runs])
        if not np.all(np.isfinite(spread)):
            raise FidelityError(f"score returned a non-finite {q!r} on a noisy frame")
        low, high = np.quantile(spread - spread.mean(), [tail, 1 - tail], method="inverted_cdf")
        ci[q] = (float(value + low), float(value + high))
    return Intervals(estimate=observed, ci=ci, level=level, method="Monte Carlo, Gaussian temporal noise",
                     block=0, resamples=int(draws), frames=1)
