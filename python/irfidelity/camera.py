"""The camera-property components from whatever the user gives: f1 (MTF), f2 (SiTF) and the
opt-in ``noise`` and ``mrtd`` components.

A curve input is a :class:`~irfidelity.Curve`, an ``(x, y)`` pair, a CSV path, or — for the
MTF — a slanted-edge image (array or path) measured with
:func:`irfidelity.curves.mtf_from_edge`, bar frames (a :class:`~irfidelity.bar_frames.BarFrames` or a
directory with a ``bars.csv``: the fundamental-amplitude MTF), or a CTF curve of
:func:`irfidelity.curves.ctf_curve` (converted by Coltman's series). An MRTD input is a curve
(e.g. :func:`irfidelity.curves.mrtd`, the model from MTF and NETD) or bar frames (the MRTD
measured on them, :func:`irfidelity.curves.measured_mrtd`). A noise input is a :class:`~irfidelity.noise.Noise3D`
or a recording of a uniform source (3-D array, directory, glob, multi-page TIFF) measured with
:func:`irfidelity.noise.noise3d`. These are camera properties: a sequence compares them once,
before any frame, and every frame's fidelity includes them.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from .config import ScoringConfig
from .curves import Curve
from .errors import FidelityError
from .frames import dtype_name
from .fuzzy import Weights

__all__ = ["CameraInputs", "camera_components", "camera_source", "describe_input"]

_CURVE_EXTENSIONS = (".csv", ".txt", ".tsv", ".dat")

#: The camera-property components, in report order.
KINDS = ("mtf", "sitf", "noise", "mrtd")


@dataclass(frozen=True)
class CameraInputs:
    """The camera-property inputs of a scene (any of them None; given in pairs, except the real
    camera's noise, which alone sets the ceiling: :mod:`irfidelity.noise.repeatability`)."""

    real_mtf: Any = None
    sim_mtf: Any = None
    real_sitf: Any = None
    sim_sitf: Any = None
    real_noise: Any = None
    sim_noise: Any = None
    real_mrtd: Any = None
    sim_mrtd: Any = None

    def __post_init__(self) -> None:
        for kind in KINDS:
            real, sim = getattr(self, f"real_{kind}"), getattr(self, f"sim_{kind}")
            if (real is None) != (sim is None) and not (kind == "noise" and sim is None):
                given, absent = (f"real_{kind}", f"sim_{kind}") if sim is None else (f"sim_{kind}", f"real_{kind}")
                raise FidelityError(f"{given} was given without {absent}: give both or neither", option=absent)

    def given(self) -> dict[str, bool]:
        """``{kind: whether both inputs were given}`` for mtf, sitf, noise and mrtd."""
        return {kind: getattr(self, f"real_{kind}") is not None and getattr(self, f"sim_{kind}") is not None
                for kind in KINDS}


def describe_input(x: Any) -> Any:
    """A short, JSON-ready description of an input (path, curve, array)."""
    if isinstance(x, (str, os.PathLike)):
        return os.fsdecode(os.fspath(x))
    if isinstance(x, Curve):
        return f"Curve({len(x)} points{', ' + repr(x.name) if x.name else ''})"
    if isinstance(x, np.ndarray):
        return f"array {x.shape} {dtype_name(x.dtype)}"
    return type(x).__name__


def _edge_curve(image: Any, what: str, channel: str | None, config: ScoringConfig) -> Curve:
    """The MTF of a slanted-edge image (an array, or a file read with ``channel``)."""
    from .curves import mtf_from_edge

    is_file = isinstance(image, (str, os.PathLike))
    try:
        return mtf_from_edge(image, name=what, edge_fit_order=config.edge_fit_order,
                             channel=channel if is_file else None)
    except FidelityError as exc:
        raise type(exc)(f"{what}: {exc}", option=exc.option) from None


def edge_channel(config: ScoringConfig, side: str) -> str | None:
    """The channel of one side's slanted-edge image files (``side``: "real" or "sim"): its own
    (``real_edge_channel``, ``sim_edge_channel``), else ``edge_channel``."""
    own = config.real_edge_channel if side == "real" else config.sim_edge_channel
    return own if own is not None else config.edge_channel


def _camera(config: ScoringConfig) -> Any:
    from .curves import CameraGeometry

    return CameraGeometry(ifov_mrad=config.ifov_mrad, pixel_pitch_um=config.pixel_pitch_um,
                          focal_length_mm=config.focal_length_mm)


def _bar_mtf(x: Any, what: str, config: ScoringConfig, edge_side: str) -> Curve | None:
    """The MTF of bar frames (fundamental-amplitude ratio), or of a CTF curve of
    :func:`~irfidelity.curves.ctf_curve` (Coltman's series); None for other inputs."""
    from .bar_frames import as_bar_frames, bar_curves
    from .curves import mtf_from_ctf

    if isinstance(x, Curve):
        return mtf_from_ctf(x, name=what) if x.meta.get("quantity") == "ctf" else None
    bars = as_bar_frames(x)
    if bars is None:
        return None
    channel = config.real_channel if edge_side == "real" else config.sim_channel
    who = "real" if edge_side == "real" else "simulated"
    return bar_curves(bars, who=who, channel=channel, camera=_camera(config), quantities=("mtf",))["mtf"]


def as_curve(x: Any, what: str, config: ScoringConfig, *, edge_side: str | None) -> Curve:
    """A Curve from a Curve, an (x, y) pair, a CSV path, or (MTF only: ``edge_side`` "real" or
    "sim") a slanted-edge image, an array or a path read with that side's edge channel, bar
    frames or a CTF curve."""
    if edge_side is not None:
        from_bars = _bar_mtf(x, what, config, edge_side)
        if from_bars is not None:
            return from_bars
    if isinstance(x, Curve):
        return x
    if isinstance(x, (str, os.PathLike)):
        path = os.fspath(x)
        if os.fsdecode(path).lower().endswith(_CURVE_EXTENSIONS):
            return Curve.from_csv(path, name=what)
        if edge_side is None:
            raise FidelityError(f"{what}: {path!r} is not a curve file ({', '.join(_CURVE_EXTENSIONS)})")
        return _edge_curve(path, what, edge_channel(config, edge_side), config)
    if isinstance(x, np.ndarray) and x.ndim == 2 and edge_side is not None and min(x.shape) > 2:
        return _edge_curve(x, what, None, config)
    try:
        cx, cy = x
    except (TypeError, ValueError):
        kinds = "a Curve, an (x, y) pair, a CSV path" + (" or an edge image (array or path)" if edge_side else "")
        raise FidelityError(f"{what} must be {kinds}, got {type(x).__name__}") from None
    return Curve(cx, cy, name=what)


def as_noise(x: Any, side: str, config: ScoringConfig) -> Any:
    """A :class:`~irfidelity.noise.Noise3D` from one, or from a recording of a uniform source
    (``side``: "real" or "sim")."""
    from .noise import Noise3D, noise3d

    if isinstance(x, Noise3D):
        return x
    channel = config.real_channel if side == "real" else config.sim_channel
    try:
        return noise3d(x, bits=config.bits, channel=channel)
    except FidelityError as exc:
        raise FidelityError(f"{side} noise recording: {exc}", option=f"{side}_noise") from None


def _compare_noise(inputs: CameraInputs, config: ScoringConfig) -> tuple[float, dict, dict, dict]:
    from .noise import noise_similarity

    real = as_noise(inputs.real_noise, "real", config)
    sim = as_noise(inputs.sim_noise, "sim", config)
    s = noise_similarity(real, sim)
    described = {"real_noise": describe_input(inputs.real_noise), "sim_noise": describe_input(inputs.sim_noise)}
    return float(s.value), s.metrics(), described, {"real_noise": real, "sim_noise": sim}


def as_mrtd(x: Any, side: str, config: ScoringConfig) -> dict[str, Curve]:
    """``{"mrtd": Curve}`` from an MRTD curve (Curve, (x, y), CSV path), or the measured MRTD,
    CTF and MTF of bar frames (a BarFrames or a bar directory); ``side``: "real" or "sim"."""
    from .bar_frames import as_bar_frames, bar_curves

    who = "real" if side == "real" else "simulated"
    bars = as_bar_frames(x)
    if bars is None:
        return {"mrtd": as_curve(x, f"{who} MRTD", config, edge_side=None)}
    measure = {k: v for k, v in config.mrtd_options.items() if k in ("snr_threshold", "eye_time", "frame_rate")}
    channel = config.real_channel if side == "real" else config.sim_channel
    return bar_curves(bars, who=who, channel=channel, camera=_camera(config), **measure)


def _compare_mrtd(inputs: CameraInputs, config: ScoringConfig) -> tuple[float, dict, dict, dict]:
    from .curves.mrtd_similarity import mrtd_similarity

    measured = {side: as_mrtd(getattr(inputs, f"{side}_mrtd"), side, config) for side in ("real", "sim")}
    compare = {k: v for k, v in config.mrtd_options.items() if k in ("tolerance", "points", "alpha", "beta")}
    s = mrtd_similarity(measured["real"]["mrtd"], measured["sim"]["mrtd"], camera=_camera(config), **compare)
    metrics = {"mrtd_real": s.a, "mrtd_sim": s.b, "mrtd_ratio": s.ratio, "mrtd_mu": s.mu, "mrtd_rho": s.rho,
               "mrtd_max_deviation": s.max_deviation, "mrtd_tolerance": s.tolerance,
               "mrtd_f_min": float(s.points[0]), "mrtd_f_max": float(s.points[-1]), "mrtd_f_unit": s.x_unit}
    described = {f"{side}_mrtd": describe_input(getattr(inputs, f"{side}_mrtd")) for side in ("real", "sim")}
    compared = {f"{side}_{'bar_mtf' if k == 'mtf' else k}": c for side in ("real", "sim")
                for k, c in measured[side].items()}
    return float(s.value), metrics, described, compared


def _compare(kind: str, inputs: CameraInputs, config: ScoringConfig) -> tuple[float, dict, dict, dict]:
    """One camera component: its value, raw metrics, input descriptions and what was compared."""
    from .curves import mtf_similarity, sitf_similarity

    if kind == "noise":
        return _compare_noise(inputs, config)
    if kind == "mrtd":
        return _compare_mrtd(inputs, config)
    real_in, sim_in = getattr(inputs, f"real_{kind}"), getattr(inputs, f"sim_{kind}")
    real = as_curve(real_in, f"real {kind.upper()}", config, edge_side="real" if kind == "mtf" else None)
    sim = as_curve(sim_in, f"simulated {kind.upper()}", config, edge_side="sim" if kind == "mtf" else None)
    if kind == "mtf":
        s = mtf_similarity(real, sim, camera=_camera(config), **config.mtf_options)
        metrics = {"mtf50_real": s.a, "mtf50_sim": s.b, "mtf50_unit": s.x_unit}
    else:
        s = sitf_similarity(real, sim, **config.sitf_options)
        unit = None if s.x_unit is None and s.y_unit is None else f"{s.y_unit or '?'}/{s.x_unit or '?'}"
        metrics = {"sitf_slope_real": s.a, "sitf_slope_sim": s.b, "sitf_slope_unit": unit}
    metrics.update({f"{kind}_mu": s.mu, f"{kind}_rho": s.rho, f"{kind}_ccc": s.ccc, f"{kind}_area": s.area})
    described = {f"real_{kind}": describe_input(real_in), f"sim_{kind}": describe_input(sim_in)}
    return float(s.value), metrics, described, {f"real_{kind}": real, f"sim_{kind}": sim}


def camera_components(inputs: CameraInputs, weights: Weights, config: ScoringConfig, *, scene: tuple = ()
                     ) -> tuple[dict, dict, dict, dict]:
    """Components f1 (MTF, eqs. 1–4), f2 (SiTF), ``noise`` and ``mrtd`` whose weight is positive,
    but those the frame pair's scene stands in for (``scene``, :mod:`irfidelity.system.scene`).

    Inputs with weight 0 are not read at all. Curves in different units are converted with
    the configuration's camera geometry, or refused (:mod:`irfidelity.curves.units`).

    Returns
    -------
    (components, metrics, inputs, curves)
        ``{"mtf"|"sitf": f}``; the raw metrics (:data:`irfidelity.schema.METRICS`); short input
        descriptions; and the :class:`~irfidelity.Curve` and noise objects compared
        (``real_mtf``, ..., ``real_noise``, ``sim_noise``, ``real_mrtd``, ``sim_mrtd``; from bar
        frames also ``real_ctf``, ``real_bar_mtf``, ``sim_ctf``, ``sim_bar_mtf``).
    """
    components: dict[str, float] = {}
    metrics: dict[str, Any] = {}
    described: dict[str, Any] = {}
    curves: dict[str, Any] = {}
    for kind in KINDS:
        if weights[kind] > 0 and kind not in scene:
            components[kind], kind_metrics, kind_inputs, kind_curves = _compare(kind, inputs, config)
            metrics.update(kind_metrics)
            described.update(kind_inputs)
            curves.update(kind_curves)
    return components, metrics, described, curves


def camera_source(kind: str, inputs: CameraInputs) -> str:
    """Where a camera component's input came from: "curves", "edge images", "bar frames",
    "CTF curves" (MTF), "noise recordings" (noise) — the scene's is "scene"
    (:mod:`irfidelity.system.scene`)."""
    from .bar_frames import as_bar_frames

    x = getattr(inputs, f"real_{kind}")
    if kind == "noise":
        return "noise recordings"
    if isinstance(x, Curve):
        return "CTF curves" if x.meta.get("quantity") == "ctf" else "curves"
    if kind == "mtf" and as_bar_frames(x) is not None:
        return "bar frames"
    if isinstance(x, (str, os.PathLike)):
        return "curves" if os.fsdecode(os.fspath(x)).lower().endswith(_CURVE_EXTENSIONS) else "edge images"
    if isinstance(x, np.ndarray) and x.ndim == 2 and min(x.shape) > 2:
        return "edge images" if kind == "mtf" else "curves"
    return "curves"
