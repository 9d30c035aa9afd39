"""One scene, one fidelity: :func:`evaluate` (paper eq. 15).

Plan first, compute second: :func:`irfidelity.scoring.plan_components` decides, from the
weights and from which inputs exist, which components are computed; only then is any
work done. A component with weight 0 is not computed at all (no histogram pass unless NMI
is weighted, no moments unless SSIM is, no curve read without a curve weight), and one
pass of the Rust kernel computes every image statistic the plan needs.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from . import stats as _stats
from .camera import CameraInputs, camera_components, describe_input
from .alignment import score_registered
from .config import ScoringConfig
from .errors import FidelityError, RangeError, ShapeError
from .results import FidelityReport, recorded_warnings
from .scoring import image_components, plan_components, psnr_peak, score_components
from .temperature import TemperatureErrors, scoring_config, temperature_scores, to_temperature, tolerance_for

__all__ = ["evaluate"]


def _load(x: Any, which: str, channel: str | None) -> np.ndarray:
    """A frame from an array or a path; a multi-page TIFF is a sequence, not a frame."""
    if not isinstance(x, (str, os.PathLike)):
        return x
    from .frames import load_frame, page_count

    pages = page_count(x)
    if pages > 1:
        raise FidelityError(f"{which} {os.fsdecode(os.fspath(x))!r} is a multi-page TIFF of {pages} frames: "
                            f"score it as a sequence (irfidelity.score_sequence, or irfidelity score with both "
                            f"sides multi-page or directories), or load one page as an array", option=which)
    return load_frame(x, channel=channel)


def _registered(r: Any, s: Any, mask: Any, components: tuple, config: ScoringConfig, sources: dict
                ) -> tuple[_stats.PairStats, float | None]:
    """Register the simulated frame onto the real one, resample it and compute the statistics
    over the overlap in one Rust call (:func:`irfidelity.alignment.score_registered`,
    docs/registration.md): the statistics (with the PSNR peak of the original sample type; a
    bit depth bounds the integer frames only) and the real frame's range over the scored
    pixels."""
    r, s = np.asarray(r), np.asarray(s)
    peak, valid = _stats.peak_and_valid(r.dtype, config.bits, config.numeric_peak)
    scored = np.dtype(np.float64)
    request, bins = _stats.kernel_request(components, scored, bins=config.bins, hist_range=config.hist_range,
                                          full=_stats.full_range(scored, None, peak), nonfinite=config.nonfinite,
                                          valid=valid)
    pair = score_registered(r, s, request, model=config.register, method=config.register_method, mask=mask,
                            extent="psnr" in components)
    sources.update(sim=pair.sim, mask=pair.mask, sim_unregistered=s, registration=pair.registration)
    span = None if pair.extent is None else pair.extent[1] - pair.extent[0]
    return _stats.PairStats(pair.stats, peak=peak, bins=bins), span


def _image_stats(real: Any, sim: Any, components: tuple, config: ScoringConfig, mask: Any,
                 inputs: dict, sources: dict) -> _stats.PairStats:
    r = _load(real, "real", config.real_channel)
    s = _load(sim, "sim", config.sim_channel)
    if config.unit is not None:
        r, s = to_temperature(r, real, "real", config), to_temperature(s, sim, "sim", config)
    sources.update(real=r, sim=s, mask=mask)
    inputs.update(real=describe_input(real), sim=describe_input(sim), shape=list(np.shape(r)),
                  dtype=np.asarray(r).dtype.name)
    try:
        if config.register is not None:
            st, span = _registered(r, s, mask, components, config, sources)
        else:
            st = _stats.pair_stats(r, s, bits=config.bits, peak=config.numeric_peak, bins=config.bins,
                                   hist_range=config.hist_range, mask=mask, need=components,
                                   nonfinite=config.nonfinite)
            span = _stats.real_range(r, mask, config.nonfinite) if "psnr" in components else None
    except (ShapeError, RangeError) as exc:
        paths = [f"{which} {inputs[which]}" for which, x in (("real", real), ("sim", sim))
                 if isinstance(x, (str, os.PathLike))]
        if not paths:
            raise
        raise type(exc)(f"{' / '.join(paths)}: {exc}", option=getattr(exc, "option", None)) from None
    if "psnr" in components:
        # st.peak is the default peak (2**bits - 1, the dtype's): psnr_peak needs it only without a peak
        peak = psnr_peak(config, st.peak, span, where="real frame")
        if peak != st.peak:
            st = st.with_peak(peak)
    return st


def evaluate(real: Any = None, sim: Any = None, *, real_mtf: Any = None, sim_mtf: Any = None,
             real_sitf: Any = None, sim_sitf: Any = None, real_noise: Any = None, sim_noise: Any = None,
             real_mrtd: Any = None, sim_mrtd: Any = None, mask: Any = None, config: ScoringConfig | None = None, **options: Any) -> FidelityReport:
    """Fidelity of a simulator on one scene (paper eq. 15) with its five components.

    Parameters
    ----------
    real, sim : 2-D arrays or frame paths, optional
        The real and simulated frame (paths are loaded with :func:`irfidelity.load_frame`;
        a multi-page TIFF is a sequence: use :func:`irfidelity.score_sequence`). Needed by
        psnr, nmi, ssim.
    real_mtf, sim_mtf : Curve, (x, y), CSV path, edge image (2-D array or image path), or bar frames
        MTF curves of both cameras; an edge image goes through
        :func:`irfidelity.curves.mtf_from_edge`; bar frames (:class:`~irfidelity.BarFrames` or a
        directory with a ``bars.csv``) give their fundamental-amplitude MTF, and a CTF curve of
        :func:`irfidelity.curves.ctf_curve` is converted by Coltman's series. Component f1.
    real_sitf, sim_sitf : Curve, (x, y) or CSV path
        SiTF curves. Component f2.
    real_noise, sim_noise : Noise3D, or a recording of a uniform source (3-D array, directory,
        glob, multi-page TIFF), optional
        The opt-in ``noise`` component (weight 0 by default: give it a weight, e.g.
        ``weights="psnr=0.3,nmi=0.2,ssim=0.3,noise=0.2"``); :func:`irfidelity.noise.noise3d`.
    real_mrtd, sim_mrtd : Curve, (x, y), CSV path, or bar frames, optional
        The opt-in ``mrtd`` component (weight 0 by default): MRTD curves (e.g. the model
        :func:`irfidelity.curves.mrtd` from MTF and NETD), or bar frames
        (:class:`~irfidelity.BarFrames` or a directory with a ``bars.csv``) whose MRTD is
        measured (:func:`irfidelity.curves.measured_mrtd`); compared by
        :func:`irfidelity.curves.mrtd_similarity` (docs/bars.md).
    mask : 2-D bool array, optional
        ``False`` excludes a pixel pair from the image components.
    config : ScoringConfig, mapping or TOML/JSON path, optional
        What decides the score (weights, bits, peak, bins, ...); default: the defaults.
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
    cfg = scoring_config(ScoringConfig.resolve(config, **options))
    if (real is None) != (sim is None):
        given, absent = ("real", "sim") if sim is None else ("sim", "real")
        raise FidelityError(f"{given} was given without {absent}: give both frames or neither", option=absent)
    camera = CameraInputs(real_mtf, sim_mtf, real_sitf, sim_sitf, real_noise, sim_noise, real_mrtd, sim_mrtd)
    given = camera.given()
    weights, image_plan, skipped = plan_components(cfg.weights, cfg.missing, have_images=real is not None,
                                                   have_mtf=given["mtf"], have_sitf=given["sitf"],
                                                   have_noise=given["noise"], have_unit=cfg.unit is not None,
                                                   have_mrtd=given["mrtd"])
    in_unit = cfg.unit is not None and real is not None
    with recorded_warnings() as notes:
        components, metrics, inputs, compared = camera_components(camera, weights, cfg)
        sources: dict[str, Any] = {"curves": compared}
        if image_plan or in_unit:
            st = _image_stats(real, sim, image_plan, cfg, mask, inputs, sources)
            image, image_metrics = image_components(st, image_plan, cfg)
            components.update(image)
            metrics.update(image_metrics)
        if in_unit:
            errors = TemperatureErrors.of_frames(sources["real"], sources["sim"], mask=sources["mask"],
                                                 tolerance=tolerance_for(cfg, metrics), unit=str(cfg.unit))
            image, image_metrics = temperature_scores(errors, weights)
            components.update(image)
            metrics.update(image_metrics)
    score = score_components(components, metrics, weights, cfg)
    registration = sources.get("registration")
    return FidelityReport(fidelity=score.fidelity, grade=score.grade, components=score.components,
                          weights=weights, metrics=score.metrics,
                          component_grades=dict(score.grading.component_grades),
                          membership=dict(score.grading.membership), skipped=skipped, config=cfg,
                          matrix=score.grading.matrix, notes=notes, inputs=inputs, sources=sources,
                          registration=None if registration is None else registration.to_dict())
