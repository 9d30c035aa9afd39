"""One scene, one fidelity: :func:`evaluate` (paper eq. 15).

Plan first, compute second: :func:`irfidelity.scoring.plan_components` decides, from the
weights and from which inputs exist, which components are computed; only then is any
work done. A component with weight 0 is not computed at all (no histogram pass unless NMI
is weighted, no moments unless SSIM is, no curve read without a curve weight), and one
pass of the Rust kernel computes every image statistic the plan needs.

Memory is planned too (docs/design.md §14): the frames (decoded within ``max_bytes``, the
simulated one within what the real one leaves) and every step after them are checked
against the budget before they allocate.
"""

from __future__ import annotations

import os
import warnings
from typing import Any

import numpy as np

from . import budget
from . import stats as _stats
from .ceiling import relative_to
from .defects import concentrated_error, error_profile, find_defects
from .camera import CameraInputs, camera_components, camera_source, describe_input
from .alignment import score_registered
from .budget import SCORING_BYTES, WIDENED_BYTES
from .config import ScoringConfig
from .errors import FidelityError, NoiseWarning, RangeError, ShapeError
from .frames import dtype_name
from .regions import (as_regions, masked_stats, registered_union, score_regions, scored_frames, scored_mask,
                      with_psnr_peak)
from .results import FidelityReport, recorded_warnings
from .scoring import image_components, plan_with_scene, score_components
from .temperature import TemperatureErrors, scoring_config, temperature_scores, to_temperature, tolerance_for
from .system.scene import SceneEstimate, scene_estimate, scene_kinds, unassessed

__all__ = ["evaluate", "Scorer", "SCORING_BYTES"]


def _load(x: Any, which: str, channel: str | None, max_bytes: int | None) -> np.ndarray:
    """A frame from an array or a path (decoded within ``max_bytes``); a multi-page TIFF is a
    sequence, not a frame."""
    if not isinstance(x, (str, os.PathLike)):
        return x
    from .frames import load_frame, page_count

    pages = page_count(x)
    if pages > 1:
        kind = "FLIR recording" if os.fsdecode(os.fspath(x)).lower().endswith((".seq", ".csq")) else "multi-page TIFF"
        raise FidelityError(f"{which} {os.fsdecode(os.fspath(x))!r} is a {kind} of {pages} frames: "
                            f"score it as a sequence (irfidelity.score_sequence, or irfidelity score with both "
                            f"sides multi-page or directories), or load one page as an array", option=which)
    return load_frame(x, channel=channel, max_bytes=max_bytes)


def _left(max_bytes: int | None, held: np.ndarray) -> int:
    """What ``max_bytes`` leaves once ``held`` is in memory (at least 1 byte: a decode that
    needs more is refused by its own plan)."""
    return max(1, budget.resolve(max_bytes) - int(np.asarray(held).nbytes))


def _registered(r: Any, s: Any, mask: Any, components: tuple, config: ScoringConfig, sources: dict,
                max_bytes: int | None) -> tuple[_stats.PairStats, float | None]:
    """Register the simulated frame onto the real one, resample it and compute the statistics
    over the overlap in one Rust call (:func:`irfidelity.alignment.score_registered`,
    docs/registration.md), planned against ``max_bytes`` before it starts: the statistics
    (with the PSNR peak of the original sample type; a bit depth bounds the integer frames
    only) and the real frame's range over the scored pixels."""
    r, s = np.asarray(r), np.asarray(s)
    peak, valid = _stats.peak_and_valid(r.dtype, config.bits, config.numeric_peak)
    scored = np.dtype(np.float64)
    request, bins = _stats.kernel_request(components, scored, bins=config.bins, hist_range=config.hist_range,
                                          full=_stats.full_range(scored, None, peak), nonfinite=config.nonfinite,
                                          valid=valid)
    pair = score_registered(r, s, request, model=config.register, method=config.register_method, mask=mask,
                            extent="psnr" in components, max_bytes=max_bytes)
    sources.update(sim=pair.sim, mask=pair.mask, sim_unregistered=s, registration=pair.registration)
    span = None if pair.extent is None else pair.extent[1] - pair.extent[0]
    return _stats.PairStats(pair.stats, peak=peak, bins=bins), span


def _load_ref(real_ref: Any, config: ScoringConfig, sources: dict, max_bytes: int | None) -> np.ndarray:
    """The second real frame, decoded (and converted to ``config.unit``) within what ``max_bytes``
    leaves beside the scored pair."""
    held = budget.nbytes(np.asarray(sources["real"]), np.asarray(sources["sim"]))
    ref = _load(real_ref, "real_ref", config.real_channel, max(1, budget.resolve(max_bytes) - held))
    if config.unit is not None:
        ref = to_temperature(ref, real_ref, "real_ref", config, max_bytes, held=held)
    return ref


def _left_out_defects(sources: dict, tolerance: float | None) -> bool:
    """Finds clusters of defective pixels in the pair as scored (:func:`irfidelity.defects.find_defects`)
    and leaves them out of ``sources["mask"]``; whether there were any. Without any, the pass's
    error profile stays in ``sources["error_profile"]`` for the concentrated-error check and, with a
    temperature ``tolerance``, the temperature errors."""
    real, sim = np.asarray(sources["real"]), np.asarray(sources["sim"])
    if real.ndim != 2 or real.shape != sim.shape:
        return False
    profile = error_profile(real, sim, sources.get("mask"), tolerance=tolerance, spread=True)
    found = find_defects(real, sim, sources.get("mask"), profile=profile)
    sources["defects"] = found
    if found is None:
        sources["error_profile"] = profile  # of the pair and mask as they stay scored
        return False
    mask = sources.get("mask")
    sources["mask"] = ~found.mask if mask is None else np.asarray(mask, dtype=bool) & ~found.mask
    return True


def _check_scoring(r: Any, s: Any, mask: Any, max_bytes: int | None) -> None:
    """The plan of scoring an unregistered pair: its frames and mask, and what scoring adds."""
    r, s = np.asarray(r), np.asarray(s)
    per_pixel = SCORING_BYTES + (WIDENED_BYTES if r.dtype == np.float16 else 0)
    held = budget.nbytes(r, s, None if mask is None else np.asarray(mask))
    budget.check("scoring a frame pair", r.shape, held + per_pixel * r.size, max_bytes)


def _image_stats(real: Any, sim: Any, components: tuple, config: ScoringConfig, mask: Any, regions: Any,
                 inputs: dict, sources: dict, max_bytes: int | None,
                 tolerance: float | None = None) -> tuple[_stats.PairStats, float | None]:
    """The pair's statistics and the real frame's range over the scored pixels (``mask``, within
    the union of ``regions``; a registration is searched within ``mask`` alone); ``tolerance``:
    the temperature tolerance when scored in a unit (:func:`_left_out_defects`)."""
    r = _load(real, "real", config.real_channel, max_bytes)
    if config.unit is not None:  # converted before the simulated frame is decoded: one frame of counts at a time
        r = to_temperature(r, real, "real", config, max_bytes)
    if isinstance(sim, (str, os.PathLike)) and np.ndim(r) == 2:  # the least a frame of its shape holds: a byte a pixel
        budget.check("decoding the simulated frame beside the real one", np.shape(r), budget.nbytes(r) + np.size(r),
                     max_bytes)
    s = _load(sim, "sim", config.sim_channel, _left(max_bytes, r) if isinstance(sim, (str, os.PathLike)) else None)
    if config.unit is not None:
        s = to_temperature(s, sim, "sim", config, max_bytes, held=budget.nbytes(r))
    scored = scored_mask(mask, regions, np.shape(r))
    sources.update(real=r, sim=s, mask=scored)
    inputs.update(real=describe_input(real), sim=describe_input(sim), shape=list(np.shape(r)),
                  dtype=dtype_name(np.asarray(r).dtype))
    if config.register is None and np.ndim(r) == 2:
        _check_scoring(r, s, scored, max_bytes)
    try:
        if config.register is not None:
            st, span = _registered(r, s, mask, components, config, sources, max_bytes)
            if _left_out_defects(sources, tolerance) and regions is None:
                real_scored, sim_scored, _, _ = scored_frames(sources, config, max_bytes)
                st, span = masked_stats(real_scored, sim_scored, components, config, sources["mask"],
                                        bits=None, peak=_psnr_peak(st, components))
            if regions is None:
                st = with_psnr_peak(st, span, components, config, "real frame")
            else:
                st, span = registered_union(regions, sources, components, config, max_bytes)
        else:
            # checked against bits first: a defect is left out, a value out of range is an error
            st, span = masked_stats(r, s, components, config, scored, bits=config.bits, peak=config.numeric_peak)
            if _left_out_defects(sources, tolerance):
                st, span = masked_stats(r, s, components, config, sources["mask"], bits=config.bits,
                                        peak=config.numeric_peak)
    except (ShapeError, RangeError) as exc:
        paths = [f"{which} {inputs[which]}" for which, x in (("real", real), ("sim", sim))
                 if isinstance(x, (str, os.PathLike))]
        if not paths:
            raise
        raise type(exc)(f"{' / '.join(paths)}: {exc}", option=getattr(exc, "option", None)) from None
    return st, span


def _psnr_peak(stats: _stats.PairStats, components: tuple) -> float | None:
    """The statistics' PSNR peak when the psnr component is computed (they then have one)."""
    if "psnr" not in components:
        return None
    assert stats.peak is not None
    return float(stats.peak)


def _ceiling(real_ref: Any, components: tuple, config: ScoringConfig, stats: _stats.PairStats,
             sources: dict, inputs: dict, max_bytes: int | None) -> dict:
    """The real-vs-real components with ``real_ref`` (:mod:`irfidelity.ceiling`)."""
    from .ceiling import pair_ceiling

    ref = _load_ref(real_ref, config, sources, max_bytes)
    inputs["real_ref"] = describe_input(real_ref)
    sources["real_ref"] = ref  # each region's ceiling; dropped once the regions are scored
    peak = _psnr_peak(stats, components)
    return pair_ceiling(sources["real"], ref, components, config, mask=sources.get("mask"), peak=peak)


def _noise_ceiling(real_noise: Any, components: tuple, config: ScoringConfig, stats: _stats.PairStats,
                   sources: dict, inputs: dict, max_bytes: int | None) -> dict | None:
    """The ceiling from the real camera's 3-D noise (:mod:`irfidelity.noise.repeatability`);
    None for frames scored in temperature (the noise is in frame units)."""
    from collections.abc import Mapping

    from .camera import as_noise
    from .noise.repeatability import noise_ceiling

    if config.unit is not None:
        warnings.warn(f"the real camera's noise is in frame units and the frames are scored in {config.unit}: no "
                      f"ceiling is derived from it (give real_ref=, a second real frame)", NoiseWarning, stacklevel=3)
        return None
    noise = sources["curves"].get("real_noise")
    if noise is None and isinstance(real_noise, (int, float)) and not isinstance(real_noise, bool):
        noise = {"tvh": float(real_noise)}  # one σ: the frame-to-frame noise of every pixel
    elif noise is None:
        noise = real_noise if isinstance(real_noise, Mapping) else as_noise(real_noise, "real", config)
    inputs.setdefault("real_noise", describe_input(real_noise))
    peak = _psnr_peak(stats, components)
    return noise_ceiling(sources["real"], noise, components, config, mask=sources.get("mask"), peak=peak,
                         max_bytes=max_bytes)


def _scene(sources: dict, config: ScoringConfig, real_ref: Any, real_noise: Any, scene: tuple, components: dict,
           metrics: dict, max_bytes: int | None) -> SceneEstimate:
    """The pair's transfer (:mod:`irfidelity.system`): the components the scene stands in for,
    its estimate among the metrics (beside curves, a cross-check), and what it could not give."""
    ref = sources.get("real_ref")
    if ref is None and real_ref is not None:
        ref = _load_ref(real_ref, config, sources, max_bytes)
    noise = sources["curves"].get("real_noise", real_noise) if ref is None else None
    found = scene_estimate(sources, config, scene, real_ref=ref, real_noise=noise, max_bytes=max_bytes)
    components.update(found.components)
    metrics.update(found.metrics)
    return found


def evaluate(real: Any = None, sim: Any = None, *, real_mtf: Any = None, sim_mtf: Any = None,
             real_sitf: Any = None, sim_sitf: Any = None, real_noise: Any = None, sim_noise: Any = None,
             real_mrtd: Any = None, sim_mrtd: Any = None, mask: Any = None, regions: Any = None,
             real_ref: Any = None,
             ceiling: dict | None = None, config: ScoringConfig | None = None, max_bytes: int | None = None,
             **options: Any) -> FidelityReport:
    """Fidelity of a simulator on one scene (paper eq. 15) with its five components.

    Parameters
    ----------
    real, sim : 2-D arrays or frame paths, optional
        The real and simulated frame (paths are loaded with :func:`irfidelity.load_frame`;
        a multi-page TIFF is a sequence: use :func:`irfidelity.score_sequence`). Needed by
        psnr, nmi, ssim.
    real_mtf, sim_mtf : Curve, (x, y), CSV path, edge image (2-D array or image path), or bar frames
        MTF curves of both cameras; an edge image goes through
        :func:`irfidelity.curves.mtf_from_edge`; bar frames (:class:`~irfidelity.bar_frames.BarFrames` or a
        directory with a ``bars.csv``) give their fundamental-amplitude MTF, and a CTF curve of
        :func:`irfidelity.curves.ctf_curve` is converted by Coltman's series. Component f1.
    real_sitf, sim_sitf : Curve, (x, y) or CSV path
        SiTF curves. Component f2.
    real_noise, sim_noise : Noise3D, or a recording of a uniform source (3-D array, directory,
        glob, multi-page TIFF), optional
        The opt-in ``noise`` component (weight 0 by default: give it a weight, e.g.
        ``weights="psnr=0.3,nmi=0.2,ssim=0.3,noise=0.2"``); :func:`irfidelity.noise.noise3d`.
        Without ``real_ref`` and ``ceiling``, ``real_noise`` (also a mapping of the temporal σ
        ``{"t", "tv", "th", "tvh"}`` in frame units, or one σ: pixel noise only) gives the ceiling: the components a second
        real frame would reach (:mod:`irfidelity.noise.repeatability`).
    real_mrtd, sim_mrtd : Curve, (x, y), CSV path, or bar frames, optional
        The opt-in ``mrtd`` component (weight 0 by default): MRTD curves (e.g. the model
        :func:`irfidelity.curves.mrtd` from MTF and NETD), or bar frames
        (:class:`~irfidelity.bar_frames.BarFrames` or a directory with a ``bars.csv``) whose MRTD is
        measured (:func:`irfidelity.curves.measured_mrtd`); compared by
        :func:`irfidelity.curves.mrtd_similarity` (docs/bars.md).
    mask : 2-D bool array or path, optional
        ``False`` (or 0) excludes a pixel pair from the image components; a path names a mask
        file (``.npy``, or an image whose non-zero pixels are scored).
    regions : Regions, 2-D integer array or mapping, optional
        Labelled regions scored each on its own (``report.regions``,
        :class:`~irfidelity.Regions`): a label image (0 not scored, 1..255 a region, named by
        its number), ``{name: 2-D bool array}``, or a ``Regions`` with names. The whole is
        scored over the union of the regions (within ``mask``); each region's entry equals
        ``evaluate(mask=region)``: its image components, the pair's camera components, its
        fidelity and grade.
    real_ref : 2-D array or frame path, optional
        A second real frame of the same scene: the real-vs-real components are the ceiling
        (``report.ceiling``, ``report.relative``) against which NMI and SSIM are graded
        (:mod:`irfidelity.ceiling`).
    ceiling : mapping, optional
        A ceiling measured before (``{"nmi": ..., "ssim": ...}``, e.g. a sequence report's
        ``ceiling``), instead of ``real_ref``. Where the ceiling came from is
        ``report.ceiling_source``: "given", "real_ref" or "noise3d" (``ceiling`` before
        ``real_ref`` before ``real_noise``; ``ceiling`` and ``real_ref`` together are an error).
    config : ScoringConfig, Scorer, mapping or TOML/JSON path, optional
        What decides the score (weights, bits, peak, bins, ...); default: the defaults.
    max_bytes : int, optional
        The memory budget of the pair's work (default
        :data:`irfidelity.budget.DEFAULT_MAX_BYTES`): decoding, registration, resampling and
        statistics are each planned against it before they allocate; over budget is a
        :class:`FrameError` (decoding), :class:`RegistrationError` (registration) or
        :class:`FidelityError` naming the step, the frame size and the bytes (docs/design.md
        §14). Not part of the configuration: it never changes a score.
    **options
        Any :class:`~irfidelity.ScoringConfig` field (``weights=``, ``bits=``, ``peak=``,
        ``bins=``, ``missing=``, ...; ``channel=`` sets both frame channels); overrides
        ``config``.

    Returns
    -------
    FidelityReport

    Notes
    -----
    f3 = normalised PSNR (eq. 6), f4 = NMI (eq. 10), f5 = max(SSIM, 0) (eq. 14); fidelity =
    Σ k_i·f_i (eq. 15). Nothing is computed for a component with weight 0 (curves are not
    even read), and the image statistics come from one Rust pass that computes only what
    the weighted image components need. Weighted components without inputs are dropped and
    the other weights rescaled (``config.missing = "renormalize"``, recorded in
    ``report.skipped``), or fail with ``missing="raise"``.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> real = np.arange(64, dtype=np.uint16).reshape(8, 8)    # a scene spanning 63 of 16383 counts
    >>> rep = irf.evaluate(real, real + 1, bits=14, peak="range", weights="psnr=0.5,ssim=0.5")
    >>> round(rep.metrics["psnr_db"], 2), rep.metrics["psnr_peak"], rep.components["ssim"] > 0.99
    (35.99, 63.0, True)
    >>> round(rep.fidelity, 3), rep.grade
    (0.978, 'excellent')

    ``peak="range"`` measures PSNR against the real frame's own range (max − min); against the
    14-bit full scale, a scene this narrow would pin the psnr component near 1 whatever the
    simulator does (a :class:`~irfidelity.errors.PeakWarning` says so).

    References
    ----------
    Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547.
    """
    return Scorer(config, **options).score(
        real, sim, real_mtf=real_mtf, sim_mtf=sim_mtf, real_sitf=real_sitf, sim_sitf=sim_sitf, real_noise=real_noise,
        sim_noise=sim_noise, real_mrtd=real_mrtd, sim_mrtd=sim_mrtd, mask=mask, regions=regions, real_ref=real_ref,
        ceiling=ceiling, max_bytes=max_bytes)


class Scorer:
    """Scores frame pairs with one configuration, checked once (docs/design.md §15).

    :func:`evaluate` builds one per call; a loop over many pairs builds it once and calls
    :meth:`score` for each pair, so no option is checked again. :func:`irfidelity.score_sequence`
    and :func:`irfidelity.score_simulators` take one as their ``config`` (every pair of theirs
    is scored with its configuration).

    Parameters
    ----------
    config : ScoringConfig, Scorer, mapping or TOML/JSON path, optional
        What decides the score, as for :func:`evaluate` (a scorer: its configuration); default:
        the defaults.
    **options
        Any :class:`~irfidelity.ScoringConfig` field, overriding ``config``.

    Attributes
    ----------
    config : ScoringConfig
        The configuration the pairs are scored with (in a temperature unit, the PSNR peak
        defaults to the real frame's temperature range, ``peak="range"``).

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> scorer = irf.Scorer(bits=14, peak="range", weights="psnr=0.5,ssim=0.5")
    >>> real = np.arange(64, dtype=np.uint16).reshape(8, 8)
    >>> [round(scorer.score(real, real + k).fidelity, 3) for k in (1, 2)]
    [0.978, 0.949]
    """

    __slots__ = ("config",)

    def __init__(self, config: ScoringConfig | Scorer | Any = None, **options: Any) -> None:
        if isinstance(config, Scorer):
            config = config.config
        self.config: ScoringConfig = scoring_config(ScoringConfig.resolve(config, **options))

    def __repr__(self) -> str:
        return f"Scorer({self.config!r})"

    def __reduce__(self) -> tuple:
        return (Scorer, (self.config,))

    def score(self, real: Any = None, sim: Any = None, *, real_mtf: Any = None, sim_mtf: Any = None,
              real_sitf: Any = None, sim_sitf: Any = None, real_noise: Any = None, sim_noise: Any = None,
              real_mrtd: Any = None, sim_mrtd: Any = None, mask: Any = None, regions: Any = None,
              real_ref: Any = None, ceiling: dict | None = None, max_bytes: int | None = None) -> FidelityReport:
        """The fidelity of one pair: :func:`evaluate`'s inputs but the configuration, which is
        this scorer's; the same report."""
        cfg = self.config
        _check_frames_given(real, sim, real_ref, ceiling)
        camera = CameraInputs(real_mtf, sim_mtf, real_sitf, sim_sitf, real_noise, sim_noise, real_mrtd, sim_mrtd)
        given = camera.given()
        scene = scene_kinds(cfg, given, frames=real is not None, real_noise_known=real_ref is not None or real_noise is not None)
        weights, image_plan, skipped = plan_with_scene(cfg, given, scene, have_images=real is not None)
        in_unit = cfg.unit is not None and real is not None
        # the scene's transfer: for the components it stands in for, and as a cross-check beside
        # camera curves when the frames are read anyway
        transfer_wanted = bool(scene) or (bool(image_plan) or in_unit) and any(weights[k] > 0 for k in ("mtf", "sitf"))
        regions = _region_input(regions, real, bool(image_plan) or in_unit)
        span = defect = measured = None
        ceiling = None if ceiling is None else {str(k): float(v) for k, v in dict(ceiling).items()}
        ceiling_source = None if ceiling is None else "given"
        with recorded_warnings() as notes:
            components, metrics, inputs, compared = camera_components(camera, weights, cfg, scene=scene)
            metrics.update({f"{k}_source": camera_source(k, camera) for k in ("mtf", "sitf", "noise") if k in components})
            sources: dict[str, Any] = {"curves": compared}
            # the camera's NETD (from its noise) is known by now: the tolerance of the whole call
            tolerance = tolerance_for(cfg, metrics) if in_unit else None
            profile = None
            if image_plan or in_unit or transfer_wanted:
                st, span = _image_stats(real, sim, image_plan, cfg, mask, regions, inputs, sources, max_bytes,
                                        tolerance)
                image, image_metrics = image_components(st, image_plan, cfg)
                components.update(image)
                metrics.update(image_metrics)
                if ceiling is None and image_plan:
                    ceiling, ceiling_source = _measured_ceiling(real_ref, real_noise, image_plan, cfg, st, sources,
                                                                inputs, max_bytes)
                profile = sources.pop("error_profile", None)
                defect = concentrated_error(sources["real"], sources["sim"], sources.get("mask"), profile=profile)
            if transfer_wanted:
                measured = _scene(sources, cfg, real_ref, real_noise, scene, components, metrics, max_bytes)
                weights, image_plan, skipped = plan_with_scene(cfg, given, scene, have_images=real is not None,
                                                               absent=measured.missing)
            if in_unit:
                assert tolerance is not None
                errors = TemperatureErrors.of_sums(profile.errors, tolerance=tolerance, unit=str(cfg.unit)) \
                    if profile is not None and profile.errors is not None \
                    else TemperatureErrors.of_frames(sources["real"], sources["sim"], mask=sources["mask"],
                                                     tolerance=tolerance, unit=str(cfg.unit))
                image, image_metrics = temperature_scores(errors, weights)
                components.update(image)
                metrics.update(image_metrics)
            ref = sources.pop("real_ref", None)
            missing = unassessed(skipped, metrics)
            by_region = {} if regions is None else score_regions(regions, sources, image_plan, cfg, weights, components,
                                                                 metrics, ceiling=ceiling, real_ref=ref,
                                                                 ceiling_source=ceiling_source, unassessed=missing,
                                                                 max_bytes=max_bytes)
        score = score_components(components, metrics, weights, cfg, scene_range=span, ceiling=ceiling,
                                 ceiling_source=ceiling_source, unassessed=missing)
        registration = sources.get("registration")
        return FidelityReport(fidelity=score.fidelity, grade=score.grade, components=score.components,
                              weights=weights, metrics=score.metrics,
                              component_grades=dict(score.grading.component_grades),
                              membership=dict(score.grading.membership), skipped=skipped, config=cfg,
                              matrix=score.grading.matrix, notes=notes, inputs=inputs, sources=sources,
                              registration=None if registration is None else registration.to_dict(),
                              verdict=_named_defects(score.verdict.to_dict(), defect, sources.get("defects")),
                              ceiling=ceiling,
                              relative=relative_to(ceiling, score.components), regions=by_region,
                              transfer=None if measured is None or measured.transfer is None else measured.transfer.to_dict())


def _named_defects(verdict: dict, defect: dict | None, found: Any) -> dict:
    """The verdict with the concentrated-error finding and the defective pixels left out, named
    in its reason."""
    out = {**verdict, "defect": defect, "defects": None if found is None else found.finding()}
    if found is not None:
        out["reason"] = f"{verdict['reason']}; {found.text()}"
    return out


def _check_frames_given(real: Any, sim: Any, real_ref: Any, ceiling: Any) -> None:
    """Both frames or neither; a second real frame only with them, and not beside given values."""
    if (real is None) != (sim is None):
        given, absent = ("real", "sim") if sim is None else ("sim", "real")
        raise FidelityError(f"{given} was given without {absent}: give both frames or neither", option=absent)
    if real_ref is not None and ceiling is not None:
        raise FidelityError("give real_ref (a second real frame) or ceiling (values measured before), not both",
                            option="ceiling")
    if real_ref is not None and real is None:
        raise FidelityError("real_ref was given without real and sim: it is a second real frame of their scene",
                            option="real_ref")


def _measured_ceiling(real_ref: Any, real_noise: Any, components: tuple, config: ScoringConfig,
                      stats: _stats.PairStats, sources: dict, inputs: dict,
                      max_bytes: int | None) -> tuple[dict | None, str | None]:
    """The ceiling and its source when no values were given: from ``real_ref``, else from the real
    camera's noise, else none."""
    if real_ref is not None:
        return _ceiling(real_ref, components, config, stats, sources, inputs, max_bytes), "real_ref"
    if real_noise is not None:
        ceiling = _noise_ceiling(real_noise, components, config, stats, sources, inputs, max_bytes)
        return ceiling, None if ceiling is None else "noise3d"
    return None, None


def _region_input(regions: Any, real: Any, scores_images: bool) -> Any:
    """``regions=`` as :class:`~irfidelity.Regions` (None when not given), checked against what
    is scored."""
    if regions is None:
        return None
    if real is None:
        raise FidelityError("regions were given without real and sim: they label the pixels of the frames",
                            option="regions")
    if not scores_images:
        raise FidelityError("regions score the image components, and none is weighted (psnr, nmi, ssim, or "
                            "radiometry in a unit)", option="regions")
    return as_regions(regions)
