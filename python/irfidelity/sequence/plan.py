"""What a sequence run computes, decided before any frame pair is scored.

The plan fixes, from the configuration and the first readable real frame: the weights and
image components (the same :func:`~irfidelity.scoring.plan_components` as a single pair),
the camera-curve components (compared once, so a bad curve fails before any work), the
sample type every frame must have, the PSNR peak, the histogram binning, and the pixels
scored in every pair (a mask and/or ROI, :mod:`irfidelity.masks`, checked against that
frame's shape).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ..alignment import find_registration
from ..camera import CameraInputs, as_noise, camera_components, describe_input
from ..system.scene import scene_kinds, sequence_estimate
from ..ceiling import sequence_ceiling
from ..config import ScoringConfig
from ..errors import FidelityError
from ..frames import FrameSequence
from ..fuzzy import Weights
from ..masks import MaskSpec, ScoringMask
from ..registration import DEFAULT_ORDER
from ..results import recorded_warnings
from ..reuse import RealMemo, computed
from ..scoring import plan_with_scene, psnr_peak
from ..verdict import Grader
from ..stats import PairRequest, full_range, hist_params, peak_and_valid, real_range
from .pairing import Pairing

__all__ = ["SequencePlan", "SequenceRequest", "make_plan"]


@dataclass(frozen=True, slots=True)
class SequenceRequest:
    """What the Rust engine computes for every pair of a sequence and how it reads them:
    the pairs' :class:`~irfidelity.stats.PairRequest` and what a sequence adds.

    Attributes
    ----------
    pair : PairRequest
        What each pair's kernel pass computes.
    real_channel, sim_channel : str or None
        The channel to decode from each side's files (``None``: the only one, or luminance).
    real_extent : bool
        Report each real frame's (min, max) over its finite scored values.
    max_pixels, max_bytes : int or None
        The decode limits per frame (``None``: the defaults).
    warp : ((6 floats), int) or None
        A registration applied to every pair — its matrix (simulated → real, row-major) and
        interpolation order; the overlap is scored, both frames as float64.
    register_each : (model, method, max_shift, order) or None
        Register every pair on its own (:func:`irfidelity.register`'s model, method and
        max_shift), then score it as with ``warp``; excludes ``warp``.
    """

    pair: PairRequest = PairRequest()
    real_channel: str | None = None
    sim_channel: str | None = None
    real_extent: bool = False
    max_pixels: int | None = None
    max_bytes: int | None = None
    warp: tuple[tuple[float, ...], int] | None = None
    register_each: tuple[str, str, float | None, int] | None = None


@dataclass(frozen=True)
class SequencePlan:
    """Everything the per-frame scoring needs, fixed for the whole run."""

    config: ScoringConfig
    weights: Weights
    image: tuple[str, ...]
    skipped: dict
    camera_components: dict
    camera_metrics: dict
    inputs: dict
    camera_objects: dict  # the curves and noise measurements compared (for reports)
    notes: tuple[str, ...]
    dtype: np.dtype | None  # of the first readable real frame; None when no frame is readable
    peak: float | None  # None with peak="range" (per frame) or when no frame is readable
    default_peak: float | None
    valid: tuple[int, int] | None
    bins: int | None
    levels: bool
    each: bool
    hist_range: tuple[float, float] | None
    registration: Any = None  # found once on the first readable pair (config.register, not register_each)
    ceiling: dict | None = None  # real frame t vs t + 1, or from the real camera's noise (irfidelity.ceiling)
    transfer: dict | None = None  # the run's scene transfer (irfidelity.system), pooled over frame pairs
    ceiling_source: str | None = None  # "sequence" or "noise3d" (irfidelity.ceiling.CEILING_SOURCES)
    scene_range: float | None = None  # of the first readable real frame: for frames without their own extent
    mask: ScoringMask | None = None  # the pixels scored in every pair (None: all)

    @property
    def mask_values(self) -> np.ndarray | None:
        """The mask every pair is scored over, as the engine takes it (bool, C-contiguous)."""
        return None if self.mask is None else self.mask.values

    @cached_property
    def dtype_name(self) -> str | None:
        """The name of the sample type every frame must have (None when no frame is readable)."""
        return None if self.dtype is None else self.dtype.name

    @cached_property
    def grader(self) -> Grader:
        """Grades every frame of the run (each component's cuts found once)."""
        return Grader(self.weights, self.config, self.ceiling)

    @cached_property
    def bin_label(self) -> Any:
        """The histogram's binning as reports name it (int, "levels" or None)."""
        if "nmi" not in self.image:
            return None
        return "levels" if self.levels else self.bins

    @property
    def keep_hist(self) -> bool:
        """Whether frames share histogram edges, so their histograms pool."""
        return "nmi" in self.image and (self.levels or self.hist_range is not None)

    def pair_request(self) -> PairRequest:
        """What every pair's kernel pass computes (only what the image components need)."""
        return PairRequest(sse="psnr" in self.image, moments="ssim" in self.image, bins=self.bins,
                           levels=self.levels, each=self.each, hist_range=self.hist_range, valid=self.valid,
                           mask_nonfinite=self.config.nonfinite == "mask")

    @property
    def real_extent(self) -> bool:
        """Whether each pair reports its real frame's extent: with psnr, for the PSNR peak
        "range" and for the RMS tolerance, which is relative to the scene's range."""
        return "psnr" in self.image

    def kernel_request(self, max_pixels: int | None = None, max_bytes: int | None = None) -> SequenceRequest:
        """What the Rust engine computes per pair and how it decodes frames."""
        cfg = self.config
        return SequenceRequest(self.pair_request(), real_channel=cfg.real_channel, sim_channel=cfg.sim_channel,
                               real_extent=self.real_extent, max_pixels=max_pixels, max_bytes=max_bytes,
                               warp=self.warp, register_each=self.register_each)

    @property
    def warp(self) -> tuple[tuple[float, ...], int] | None:
        """The registration as the engine applies it: matrix (6 floats) and interpolation order."""
        if self.registration is None:
            return None
        return tuple(float(v) for v in self.registration.applied_matrix().ravel()), DEFAULT_ORDER

    @property
    def register_each(self) -> tuple[str, str, None, int] | None:
        """With ``config.register_each``: what the engine registers every pair with (model,
        method, max_shift, interpolation order)."""
        cfg = self.config
        if not cfg.register_each:
            return None
        return str(cfg.register), cfg.register_method, None, DEFAULT_ORDER

    def settings(self) -> dict:
        """What a resumed run must share with the one it continues (beyond the config)."""
        return {"dtype": None if self.dtype is None else self.dtype.name, "peak": self.peak,
                "bins": self.bin_label, "hist_range": None if self.hist_range is None else list(self.hist_range),
                # the scene's components are measured again from the frames at every run
                "curves": {k: float(v) for k, v in self.camera_components.items()
                           if self.camera_metrics.get(f"{k}_source") != "scene"},
                "registration": None if self.registration is None else self.registration.to_dict(),
                **({} if self.mask is None else {"mask": self.mask.digest()})}


def _first_readable(real: FrameSequence, pairing: Pairing) -> np.ndarray | None:
    """The first real frame (in pairing order) that decodes; None when none does."""
    for r, _ in pairing.pairs:
        if r is None:
            continue
        try:
            return np.asarray(real[r])
        except FidelityError:
            continue
    return None


def _first_pair(pairing: Pairing) -> int | None:
    """The real index of the first pair with a real frame (what the first readable frame is sought from)."""
    return next((r for r, _ in pairing.pairs if r is not None), None)


def _registration(real: FrameSequence, sim: FrameSequence, pairing: Pairing, config: ScoringConfig,
                  mask: ScoringMask | None) -> Any:
    """With ``config.register``: the registration of the first pair whose frames both decode
    (the camera geometry is fixed, so one registration serves every pair), searched over
    ``mask``. None with ``register_each`` (every pair is registered as it is scored)."""
    if config.register is None:
        return None
    if config.bins == "levels":
        raise FidelityError("bins='levels' counts integer levels, and registered frames are resampled to floats: "
                            "give a number of bins", option="bins")
    if config.register_each:
        return None
    for r, s in pairing.pairs:
        if r is None or s is None:
            continue
        try:
            real_frame, sim_frame = np.asarray(real[r]), np.asarray(sim[s])
        except FidelityError:
            continue
        try:
            return find_registration(real_frame, sim_frame, config, max_bytes=real.max_bytes,
                                     mask=None if mask is None else mask.values)
        except FidelityError as exc:
            raise type(exc)(f"registering the first readable pair ({real.names[r]} and {sim.names[s]}): {exc}",
                            option="register") from None
    return None


def _scene_range(frame: np.ndarray, mask: ScoringMask | None = None) -> float | None:
    """max − min of the frame's finite values (within ``mask``); None when there are none. The
    values are not copied (:func:`irfidelity.stats.real_range`)."""
    within = mask.values if mask is not None and frame.shape == mask.shape else None
    return real_range(frame, within, "mask")


def _ceiling(real: Any, camera: CameraInputs, compared: dict, image: tuple[str, ...], config: ScoringConfig,
             peak: float | None, mask: np.ndarray | None) -> tuple[dict | None, str | None]:
    """The run's ceiling over ``mask`` and where it came from: the real camera's 3-D noise when it
    is given (the camera's repeatability, whatever the scene does), else consecutive real frames."""
    from ..noise.repeatability import sequence_noise_ceiling

    if camera.real_noise is None or config.unit is not None:  # the noise is in frame units
        ceiling = sequence_ceiling(real, image, config, peak=peak, mask=mask)
        return ceiling, None if ceiling is None else "sequence"
    noise = compared.get("real_noise")
    if noise is None:
        noise = camera.real_noise if isinstance(camera.real_noise, Mapping) else \
            as_noise(camera.real_noise, "real", config)
    ceiling = sequence_noise_ceiling(real, noise, image, config, peak=peak, mask=mask)
    return ceiling, None if ceiling is None else "noise3d"


def make_plan(real: FrameSequence, sim: FrameSequence, pairing: Pairing, camera: CameraInputs,
              config: ScoringConfig, mask: MaskSpec | None = None, memo: RealMemo | None = None) -> SequencePlan:
    """Plan a sequence run (raises before any pair is scored when the plan cannot work).

    ``mask`` (a mask and/or ROI) is resolved against the first readable real frame's shape;
    every pair, the registration found for all and the ceiling are computed over it. ``memo``
    keeps what is of the real recording alone for the plans of other simulators against it
    (:mod:`irfidelity.reuse`)."""
    given = camera.given()
    scene = scene_kinds(config, given, frames=True, real_noise_known=camera.real_noise is not None or len(real) > 1)
    weights, image, skipped = plan_with_scene(config, given, scene, have_images=True)
    if not image:
        raise FidelityError("a sequence needs a positive weight on psnr, nmi or ssim (the per-frame components); "
                            "to compare curves alone, score a single pair without frames", option="weights")
    with recorded_warnings() as notes:
        fixed, fixed_metrics, inputs, compared = camera_components(camera, weights, config, scene=scene)
        first = computed(memo, ("first", _first_pair(pairing)), lambda: _first_readable(real, pairing))
        scored = None if first is None or mask is None else \
            computed(memo, ("mask", first.shape), lambda: mask.resolve(first.shape))
        if scored is not None:
            inputs = {**inputs, "mask": scored.describe()}
            notes.append(scored.note())
        registration = _registration(real, sim, pairing, config, scored)
        transfer = None
        if scene or any(weights[k] > 0 for k in ("mtf", "sitf")):
            found = sequence_estimate(real, sim, list(pairing.pairs), config, scene,
                                      mask=None if scored is None else scored.values, registration=registration,
                                      real_noise=compared.get("real_noise", camera.real_noise), memo=memo)
            missing = {k: "no frame pair decodes" for k in scene} if found is None else found.missing
            if found is not None and found.transfer is not None:
                fixed, fixed_metrics, transfer = {**fixed, **found.components}, {**fixed_metrics, **found.metrics}, \
                    found.transfer
            if missing:
                weights, image, skipped = plan_with_scene(config, given, scene, have_images=True, absent=missing)
        dtype = None if first is None else first.dtype
        default_peak = valid = None
        peak = bins = hist_range = None
        levels = each = False
        ceiling = ceiling_source = None
        scene_range = None if first is None else computed(memo, ("scene_range", _first_pair(pairing)),
                                                          lambda: _scene_range(first, scored))
        if dtype is not None:
            default_peak, valid = peak_and_valid(dtype, config.bits, None)
            if "psnr" in image and config.peak != "range":  # "range": each frame's own
                peak = psnr_peak(config, default_peak, scene_range, where="the first real frame")
            if "nmi" in image:
                bins, levels, each, hist_range = hist_params(config.bins, config.hist_range, dtype,
                                                             full_range(dtype, config.bits, config.numeric_peak))
            ceiling, ceiling_source = computed(
                memo, ("ceiling", image, peak),
                lambda: _ceiling(real, camera, compared, image, config, peak, None if scored is None else scored.values))
            if ceiling_source == "noise3d":
                inputs.setdefault("real_noise", describe_input(camera.real_noise))
    return SequencePlan(config=config, weights=weights, image=image, skipped=skipped, camera_components=fixed,
                        camera_metrics=fixed_metrics, inputs=inputs, camera_objects=compared, notes=tuple(notes), dtype=dtype,
                        peak=peak, default_peak=default_peak, valid=valid if dtype is not None and dtype.kind in "ui"
                        else None, bins=bins, levels=levels, each=each, hist_range=hist_range, registration=registration,
                        ceiling=ceiling, ceiling_source=ceiling_source,
                        transfer=None if transfer is None else transfer.to_dict(),
                        scene_range=scene_range, mask=scored)
