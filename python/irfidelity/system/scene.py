"""The camera components from the scene: ``mtf``, ``sitf`` and ``noise`` graded from the pair's
:class:`~irfidelity.system.Transfer` when no camera curves or noise recordings are given, and
the scene's estimate beside the curves when they are (a cross-check).

Each component has the value its tolerance's cut is defined on (:mod:`irfidelity.tolerances`),
so the grade reads the estimate exactly: ``mtf = μ(1 − e)^α`` with ``e`` the MTF50 mismatch the
ratio implies at the real camera's MTF50; ``sitf = μ(gain)^α`` (the SiTF-slope ratio of the
simulator on this scene; 0 for inverted grey levels); ``noise = μ(noise ratio)``. Each is taken
at the edge of its estimate's interval (:data:`DOUBT` standard errors) nearest to a perfect
match: the grade counts what the scene shows beyond doubt, and a scene that cannot tell (a short
or changing one) does not blame the simulator for its own uncertainty.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Mapping

import numpy as np

from ..tolerances import mu_of_ratio
from .. import budget
from ..errors import FidelityError
from ..reuse import computed
from .pair import aligned, cropped, real_noise_variance
from .readings import REFERENCE_FREQUENCY
from .result import Transfer, displacements, estimate
from .spectra import transfer_spectra

__all__ = ["SCENE_KINDS", "SceneEstimate", "scene_estimate", "sequence_estimate", "scene_kinds", "scene_transfer",
           "pair_spectra", "scene_components", "scene_metrics", "reference_frequency", "unassessed"]

#: The components the scene can stand in for.
SCENE_KINDS = ("mtf", "sitf", "noise")

#: Why the scene gave no input, by component (the skip reasons and the verdict's "not assessed").
_UNKNOWN_NOISE = ("the real camera's noise is unknown (give real_ref or real_noise, or score a sequence whose scene "
                  "stands still between frames)")


def reference_frequency(config: Any, curves: Mapping[str, Any]) -> float:
    """Where the MTF ratio is read: ``transfer_options.reference_frequency``, else the MTF50 of
    a real MTF curve in cycles per pixel, else :data:`~irfidelity.system.REFERENCE_FREQUENCY`."""
    given = config.transfer_options.get("reference_frequency")
    if given is not None:
        return float(given)
    curve = curves.get("real_mtf")
    if curve is not None and getattr(curve, "x_unit", None) == "cy/px":
        from ..curves import mtf50

        try:
            value = float(mtf50(curve))
        except ValueError:
            return REFERENCE_FREQUENCY
        if 0 < value <= 0.5:
            return value
    return REFERENCE_FREQUENCY


def pair_spectra(sources: Mapping[str, Any], config: Any, *, real_ref: np.ndarray | None = None,
                 max_bytes: int | None = None) -> Any:
    """The transfer sums of the pair as scored (``sources``: ``real``, ``sim``, ``mask``, and
    with a registration ``sim_unregistered`` and ``registration``): a translation is taken as the
    whole-pixel overlap of the unregistered frames (no resampling), other registrations as
    resampled; ``real_ref`` a second real frame. Defective pixels found in an unregistered pair
    (``defects``, left out of ``mask``) are filled from their surroundings instead
    (:meth:`~irfidelity.defects.Defects.repaired`): leaving one out would lose its tiles;
    ``repair`` says in which frames ("real" alone for the real camera against itself)."""
    real, sim, mask = sources["real"], sources["sim"], sources.get("mask")
    registration = sources.get("registration")
    defects = sources.get("defects")
    if defects is not None and registration is None and mask is not None:
        budget.check("filling defective pixels for the transfer", np.shape(real), 2 * budget.nbytes(real), max_bytes)
        real, sim = defects.repaired(np.asarray(real), np.asarray(sim), sources.get("repair", ("real", "simulated")))
        mask = np.asarray(mask, dtype=bool) | defects.mask
        mask = None if mask.all() else mask
    if registration is not None and registration.model == "translation":
        real, sim, mask, _ = aligned(real, sources["sim_unregistered"], registration, mask, max_bytes)
        real_ref = None if real_ref is None else real_ref[_overlap(sources["real"].shape, registration)]
    (real, sim, real_ref), mask = cropped([real, sim, real_ref], None if mask is None else np.asarray(mask, dtype=bool))
    return transfer_spectra(real, sim, mask=mask, real_ref=real_ref, tile=config.transfer_options.get("tile"),
                            max_bytes=max_bytes)


def scene_transfer(sources: Mapping[str, Any], config: Any, *, real_ref: np.ndarray | None = None,
                   real_noise: Any = None, max_bytes: int | None = None) -> Transfer:
    """The transfer of the pair as scored (:func:`pair_spectra`); the real camera's noise from
    ``real_ref`` or its 3-D noise ``real_noise``."""
    variance, source = None, None
    if real_ref is not None:
        source = "real_ref"
    elif real_noise is not None:
        variance, source = real_noise_variance(real_noise), "real_noise"
    spectra = pair_spectra(sources, config, real_ref=real_ref, max_bytes=max_bytes)
    return estimate(spectra, real_variance=variance, noise_source=source,
                    reference_frequency=reference_frequency(config, sources.get("curves", {})))


def _overlap(shape: tuple[int, int], registration: Any) -> tuple[slice, slice]:
    """The real frame's part that :func:`~irfidelity.system.pair.aligned` keeps."""
    dy, dx = (int(round(v)) for v in registration.shift)
    return (slice(max(dy, 0), shape[0] + min(dy, 0)), slice(max(dx, 0), shape[1] + min(dx, 0)))


def scene_components(t: Transfer, kinds: tuple[str, ...], config: Any, ceiling: Transfer | None = None
                     ) -> tuple[dict, dict]:
    """``({component: value}, {component: why it could not be assessed})`` for ``kinds``;
    ``ceiling`` the transfer of the real camera against itself (:func:`camera_ceiling`)."""
    values: dict[str, float] = {}
    missing: dict[str, str] = {}
    for kind in kinds:
        value, reason = _component(kind, t, config, ceiling)
        if value is None:
            missing[kind] = reason
        else:
            values[kind] = value
    return values, missing


#: A component is graded at the edge of its estimate's interval nearest to a perfect match,
#: this many standard errors away: the grade counts what the scene shows beyond doubt.
DOUBT = 2.0


def _doubted(value: float, error: float | None, perfect: float | None = None) -> float:
    """A mismatch (≥ 0) less :data:`DOUBT` standard errors, not below 0; the error no larger
    than ``perfect``'s, when known: what a perfect simulator's estimate would show on this scene
    (the real camera against itself). The doubt the simulator's own noise adds is its fault, and
    forgiving it would grade a noisier simulator better."""
    if error is None or not math.isfinite(error):
        return value
    if perfect is not None and math.isfinite(perfect):
        error = min(error, perfect)
    return max(0.0, value - DOUBT * error)


def _gain_mismatch(gain: float) -> float:
    return 1.0 - min(gain, 1.0 / gain)


def graded_mismatch(kind: str, t: Transfer, ceiling: Transfer | None) -> float | None:
    """The mismatch a scene component is graded by: the estimate less :data:`DOUBT` standard
    errors (no more than the real camera's against itself shows), less what the real camera
    shows against itself on the same scene (a second real frame: scene motion and the camera's
    own changes are no fault of the simulator). An MTF ratio the simulated frame's noise hides
    where the scene carries detail is a whole mismatch (``Transfer.unread_cause``)."""
    if kind == "mtf":
        if t.mtf50_mismatch is None:
            return 1.0 if t.unread_cause == "simulator" else None
        own, perfect = (0.0, None) if ceiling is None or ceiling.mtf50_mismatch is None else (
            ceiling.mtf50_mismatch, ceiling.mtf50_mismatch_err)
        return max(0.0, _doubted(t.mtf50_mismatch, t.mtf50_mismatch_err, perfect) - own)
    if kind == "sitf":
        if t.gain is None or not t.gain > 0:
            return None if t.gain is None else 1.0
        if ceiling is None or ceiling.gain is None or not ceiling.gain > 0:
            own, perfect = 0.0, None
        else:
            own, perfect = _gain_mismatch(ceiling.gain), (ceiling.gain_err or 0.0) / ceiling.gain
        relative = (t.gain_err or 0.0) / t.gain
        return max(0.0, _doubted(_gain_mismatch(t.gain), relative, perfect) - own)
    if t.noise_ratio is None or not t.noise_ratio > 0:
        return None if t.noise_ratio is None else 1.0
    return _doubted(_gain_mismatch(t.noise_ratio), (t.noise_ratio_err or 0.0) / t.noise_ratio)


def _component(kind: str, t: Transfer, config: Any, ceiling: Transfer | None) -> tuple[float | None, str]:
    """The component's value from its graded mismatch ``e``: ``μ(1 − e)^α`` (or why none)."""
    mismatch = graded_mismatch(kind, t, ceiling)
    if mismatch is None:
        return None, {"mtf": t.unread or _NO_CONTRAST, "sitf": _NO_CONTRAST, "noise": _UNKNOWN_NOISE}[kind]
    alpha = float({"mtf": config.mtf_options, "sitf": config.sitf_options}.get(kind, {}).get("alpha", 1.0))
    return (mu_of_ratio(1.0 - mismatch) ** alpha if mismatch < 1 else 0.0), ""


def camera_ceiling(sources: Mapping[str, Any], config: Any, real_ref: np.ndarray | None,
                   max_bytes: int | None = None) -> Transfer | None:
    """The real camera against itself: the transfer of the real frame to a second real frame of
    the scene (None without one, or when it cannot be measured)."""
    if real_ref is None:
        return None
    frames = {"real": sources["real"], "sim": real_ref, "mask": sources.get("mask"), "defects": sources.get("defects"),
              "repair": ("real",)}
    try:
        return estimate(pair_spectra(frames, config, max_bytes=max_bytes),
                        reference_frequency=reference_frequency(config, sources.get("curves", {})))
    except FidelityError:
        return None


_NO_CONTRAST = "the scene has no contrast at low frequencies to measure the gain on (a flat or unrelated pair)"


def scene_metrics(t: Transfer) -> dict:
    """The scene's estimate as raw metrics (:data:`irfidelity.schema.METRICS`, ``scene_*``)."""
    def number(v: Any) -> float | None:
        return None if v is None or (isinstance(v, float) and not math.isfinite(v)) else float(v)

    band = t.band or (None, None)
    return {"scene_mtf50_mismatch": number(t.mtf50_mismatch), "scene_mtf50_mismatch_err": number(t.mtf50_mismatch_err),
            "scene_mtf_ratio": number(t.ratio_at_reference), "scene_mtf_ratio_err": number(t.ratio_at_reference_err),
            "scene_reference_frequency": t.reference_frequency, "scene_band_low": number(band[0]),
            "scene_band_high": number(band[1]), "scene_gain": number(t.gain), "scene_gain_err": number(t.gain_err),
            "scene_offset": number(t.offset), "scene_bias": number(t.bias),
            "scene_noise_ratio": number(t.noise_ratio), "scene_noise_ratio_err": number(t.noise_ratio_err),
            "scene_shift_y": t.shift[0], "scene_shift_x": t.shift[1]}


def scene_kinds(config: Any, given: Mapping[str, bool], *, frames: bool, real_noise_known: bool) -> tuple[str, ...]:
    """The weighted camera components the frame pair stands in for: ``mtf`` and ``sitf`` without
    their curves, ``noise`` without noise recordings when the real camera's noise is known
    (``transfer_options.scene = false``: none)."""
    if not frames or not config.transfer_options.get("scene", True):
        return ()
    weights = config.weights
    kinds = [k for k in ("mtf", "sitf") if weights[k] > 0 and not given[k]]
    if weights["noise"] > 0 and not given["noise"] and real_noise_known:
        kinds.append("noise")
    return tuple(kinds)


@dataclass(frozen=True)
class SceneEstimate:
    """The pair's :class:`~irfidelity.system.Transfer`, the components it stands in for, its
    ``scene_*`` metrics (with ``<component>_source`` = "scene"), and the components it could not
    give with why."""

    transfer: Transfer | None
    components: dict
    metrics: dict
    missing: dict


def scene_estimate(sources: Mapping[str, Any], config: Any, kinds: tuple[str, ...], *,
                   real_ref: np.ndarray | None = None, real_noise: Any = None,
                   max_bytes: int | None = None) -> SceneEstimate:
    """The transfer of the pair as scored and what it gives (:class:`SceneEstimate`)."""
    if real_noise is not None and not isinstance(real_noise, (Mapping, int, float)) and not hasattr(real_noise, "sigma"):
        from ..camera import as_noise

        real_noise = as_noise(real_noise, "real", config)
    try:
        t = scene_transfer(sources, config, real_ref=real_ref, real_noise=real_noise, max_bytes=max_bytes)
    except FidelityError as exc:
        if exc.option != "tile":
            raise
        return _no_tile(kinds, exc)
    own = camera_ceiling(sources, config, real_ref, max_bytes) if {"mtf", "sitf"} & set(kinds) else None
    return _estimate(t, kinds, config, own)


def _estimate(t: Transfer, kinds: tuple[str, ...], config: Any, own: Transfer | None) -> SceneEstimate:
    """The :class:`SceneEstimate` of a transfer and the real camera's own (or None)."""
    values, missing = scene_components(t, kinds, config, own)
    metrics = {**scene_metrics(t), **{f"{k}_source": "scene" for k in values}}
    for kind in values:
        metrics[f"scene_{kind}_graded"] = graded_mismatch(kind, t, own)
    if own is not None:
        metrics.update(scene_mtf50_mismatch_ceiling=own.mtf50_mismatch, scene_gain_ceiling=own.gain)
    return SceneEstimate(t, values, metrics, missing)


def unassessed(skipped: Mapping[str, str], metrics: Mapping[str, Any]) -> dict:
    """``{component: why}`` for what the verdict could not assess: weighted components without
    input, and — when the pair's transfer was measured — the noise when the real camera's noise
    was unknown."""
    out = {k: reason for k, reason in skipped.items() if reason != "weight 0"}
    if "scene_gain" in metrics and metrics.get("scene_noise_ratio") is None and "noise" not in out \
            and metrics.get("noise_source") is None:
        out["noise"] = _UNKNOWN_NOISE
    return out


#: Frame pairs of a sequence whose transfers are pooled for the run's camera components.
SEQUENCE_PAIRS = 8

#: The most two consecutive real frames may be displaced (pixels) for their plain difference to
#: be taken as the camera's temporal noise: a scene displaced by δ leaves 4·sin²(π f δ) of its
#: own power in the difference (2.5 % at 0.25 cy/px for 0.1 px), which the noise correction
#: would take for noise. Beyond it the difference is taken with the displacement out
#: (:func:`aligned_difference`).
STILL_SHIFT = 0.1


def sequence_estimate(real: Any, sim: Any, pairs: list, config: Any, kinds: tuple[str, ...], *, mask: Any = None,
                      registration: Any = None, real_noise: Any = None, memo: Any = None) -> SceneEstimate | None:
    """The scene estimate of a sequence: the transfers of up to :data:`SEQUENCE_PAIRS` pairs
    spread over the run (``pairs``: (real index, sim index)), pooled; the real camera's noise
    from the next real frame of each (its temporal noise, half their difference spectrum, with
    the scene's displacement taken out when it moved: :data:`STILL_SHIFT`), or its 3-D noise
    ``real_noise``; the real camera's own transfer from each real frame to the next
    (its repeatability, :func:`graded_mismatch`), kept in ``memo`` (a
    :class:`~irfidelity.reuse.RealMemo`) for other simulators. None when no pair decodes."""
    usable = [(r, s) for r, s in pairs if r is not None and s is not None]
    if not usable:
        return None
    if real_noise is None:  # pairs with a next real frame first: their noise pools
        usable = [p for p in usable if p[0] + 1 < len(real)] or usable
    picks = sorted({int(round(i)) for i in np.linspace(0, len(usable) - 1, min(SEQUENCE_PAIRS, len(usable)))})
    pooled = own_pooled = None
    for r, s in (usable[i] for i in picks):
        try:
            spectra, own = _pair_spectra(real, sim, r, s, config, mask, registration, real_noise is None, memo)
        except FidelityError:
            continue  # an unreadable frame is the scoring's error row, not the transfer's
        if pooled is not None and not pooled.poolable(spectra):
            continue  # frames of another size than the first pair's: pooled apart they would not add
        pooled = spectra if pooled is None else _merged(pooled, spectra)
        if own is not None and (own_pooled is None or own_pooled.poolable(own)):
            own_pooled = own if own_pooled is None else _merged(own_pooled, own)
    if pooled is None:
        return None
    variance = None if real_noise is None else real_noise_variance(real_noise)
    source = "real_noise" if variance is not None else ("sequence" if pooled.difference is not None else None)
    reference = reference_frequency(config, {})
    try:
        t = estimate(pooled, real_variance=variance, noise_source=source, reference_frequency=reference)
        own = None if own_pooled is None else estimate(own_pooled, reference_frequency=reference)
    except FidelityError as exc:
        if exc.option != "tile":
            raise
        return _no_tile(kinds, exc)
    return _estimate(t, kinds, config, own)


def _no_tile(kinds: tuple[str, ...], exc: Exception) -> SceneEstimate:
    """The estimate of frames that hold no whole tile: nothing, and why."""
    why = f"the scored region holds no whole tile to measure the pair's transfer on ({exc})"
    return SceneEstimate(None, {}, {}, {k: why for k in kinds})


def _pair_spectra(real: Any, sim: Any, r: int, s: int, config: Any, mask: Any, registration: Any,
                  with_next: bool, memo: Any = None) -> Any:
    """One pair's transfer sums, with the next real frame as the second real frame."""
    frames = {"real": np.asarray(real[r]), "sim": np.asarray(sim[s]), "mask": mask}
    if registration is not None and registration.model == "translation":
        frames.update(sim_unregistered=frames["sim"], registration=registration)
    nxt = np.asarray(real[r + 1]) if r + 1 < len(real) else None
    if nxt is not None and nxt.shape != frames["real"].shape:
        nxt = None
    own = None if nxt is None else computed(  # the real camera's own: the same for every simulator
        memo, ("own spectra", r), lambda: pair_spectra({"real": frames["real"], "sim": nxt, "mask": mask}, config))
    if own is None or not with_next:
        return pair_spectra(frames, config), own
    if math.hypot(*displacements(own)[0]) <= STILL_SHIFT:
        return pair_spectra(frames, config, real_ref=nxt), own
    spectra = pair_spectra(frames, config)  # the scene moved: the difference of the frames aligned
    difference = aligned_difference(own, spectra.tiles) if own.poolable(spectra) else None
    return replace(spectra, difference=difference), own


def aligned_difference(own: Any, tiles: np.ndarray) -> np.ndarray | None:
    """Σ|R − R′|² of two real frames of a moving scene with the displacement between them taken
    out, for ``tiles`` tiles per group: ``own`` are the two frames' transfer sums, whose
    cross-spectra are aligned tile by tile. The camera's noise is the same over the frame, and
    ``own`` may have left out tiles that saw the scene change, so the difference is taken per
    tile over all of ``own``'s and counted for the pair's tiles. None when ``own`` kept no tile."""
    kept = int(own.tiles.sum())
    if kept == 0:
        return None
    per_tile = np.maximum(own.real + own.sim - 2.0 * own.cross.real, 0.0).sum(axis=0) / kept
    return np.asarray(tiles, dtype=np.float64)[:, None, None] * per_tile


def _merged(a: Any, b: Any) -> Any:
    """``a`` and ``b`` pooled (a frame without a second real frame drops the noise of all)."""
    if (a.difference is None) != (b.difference is None):
        a, b = replace(a, difference=None), replace(b, difference=None)
    return a.merge(b)
