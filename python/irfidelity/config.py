"""The scoring configuration: everything that decides a score, in one frozen object.

:class:`ScoringConfig` is what :func:`irfidelity.evaluate`, :func:`irfidelity.score_sequence`
and ``irfidelity score`` take (keyword arguments still work and override its fields), what
``irfidelity score --config scoring.toml`` reads, and what every report embeds, with the
irfidelity version, so that a number can always be traced back to how it was made.

What is *not* here: how the work is run (workers, progress, CSV paths, resume, Dask
clients, decoding limits). Those change how fast a score arrives, never its value.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, cast

from .config_fields import (MISSING_MODES, NONFINITE_MODES, PAIRING_RULES, REGISTRATION_METHODS, REGISTRATION_MODELS,
                            ConfigError, bins_value, choice, curve_options, finite_numbers, grade_scale,
                            hist_range_value, optional_int, optional_name, optional_positive, pairs, peak_value)
from .config_file import read_config, toml_document
from .errors import FidelityError
from .fuzzy import GradeScale, Weights
from .normalize import DEFAULT_PSNR_ANCHORS, psnr_curve_params
from .registration import DEFAULT_METHOD
from .stats import DEFAULT_HIST_RANGE
from .temperature import unit_fields
from .tolerances import Tolerances

__all__ = ["ScoringConfig", "MISSING_MODES", "NONFINITE_MODES", "REGISTRATION_MODELS", "PAIRING_RULES"]


def _shared(kind: type) -> Any:
    """A default built once and shared by every configuration: weights, grade scales and
    tolerances are immutable, and building them (with their checks) on every call would cost
    each evaluation more than scoring a small frame."""
    default = kind()
    return lambda: default


#: Configurations resolved from plain keyword options (numbers, names, flags), remembered: a
#: loop scoring pair after pair with the same options validates them once. The objects are
#: frozen, so sharing one is safe; options that name files or take containers are not kept.
_RESOLVED: dict[tuple, ScoringConfig] = {}
_RESOLVED_MAX = 64
_MEMO_TYPES = (bool, int, float, str)


def _memo_key(overrides: Mapping[str, Any]) -> tuple | None:
    """A key for ``overrides`` (types included: ``True`` is no ``1``), or None when an option
    may not be remembered (a container, a file)."""
    if "calibration" in overrides or any(type(v) not in _MEMO_TYPES for v in overrides.values()):
        return None
    return tuple(sorted((k, type(v).__name__, v) for k, v in overrides.items()))


@dataclass(frozen=True)
class ScoringConfig:
    """What decides a fidelity score: weights, PSNR peak, binning, anchors, exponents, ...

    Every field has the default a new user gets; a report embeds the whole object
    (``report.config``), and :meth:`load` / :meth:`save` read and write it as TOML or
    JSON. Invalid values raise :class:`~irfidelity.FidelityError` naming the field.

    Attributes
    ----------
    weights : Weights
        ``K`` of eq. (15). Anything :meth:`Weights.coerce` accepts (a preset name, a
        ``"psnr=0.5,ssim=0.5"`` string, a mapping). Default: the paper's 1/5 each.
    bits : int or None
        Bit depth of integer frames: values must lie in ``[0, 2**bits - 1]`` (else a
        RangeError naming value and position), and the default PSNR peak is ``2**bits - 1``.
    peak : float, "range" or None
        The PSNR peak (eq. 5). None: ``2**bits - 1`` (the paper's choice), or the integer
        dtype's maximum; float frames need a number or ``"range"``. ``"range"``: the real
        frame's ``max - min``, for scenes that use a small part of the sensor's range (see
        docs/interpretation.md). ``bits`` and ``peak`` compose: ``bits`` still bounds the
        values when ``peak`` (a number or ``"range"``) sets the PSNR peak (``bits=16,
        peak=100``: values in ``0..65535``, PSNR peak 100; ``hist_range="full"`` is
        ``0..2**bits - 1``).
    bins : int or "levels"
        Histogram bins for NMI (uniform over ``hist_range``), or one bin per grey level.
    hist_range : "each" (default), "data", "full" or (lo, hi)
        The NMI histogram's edges. ``"each"``: the real frame's bins over its own robust range
        and the simulated frame's carried over by the gain and offset between the two frames'
        bulks (:func:`irfidelity.pair_stats` states the rule), so a gain or an offset moves the
        bins with the levels and a few extreme pixels do not stretch them
        (docs/interpretation.md). ``"data"`` (the paper's binning): edges shared by both frames
        over their joint min..max; ``"full"``: shared ``0..peak``; or shared explicit
        ``(lo, hi)``.
    psnr_anchors : ((dB, value), (dB, value))
        The two points fixing eq. (6); default 30 dB -> 0.9, 45 dB -> 0.99. Both within
        0.01..1000 dB, and giving a curve that rises there
        (:func:`irfidelity.normalize.psnr_curve_params` states the bounds).
    ssim_exponents : (alpha, beta, gamma)
        Exponents of eq. (14).
    missing : "renormalize" or "raise"
        A weighted component without inputs (no curves given, say): drop it and rescale the
        other weights (recorded in ``report.skipped``), or fail.
    nonfinite : "raise" or "mask"
        NaN/Inf in float frames: an error with counts and the first position, or exclude
        those pixel pairs (counted in the report).
    real_channel, sim_channel : str or None
        Channel of multi-channel frame files ("Y", "R", an EXR channel name, ...), per side.
    edge_channel : str or None
        Channel of multi-channel slanted-edge image files, both sides (unless their own is
        set).
    real_edge_channel, sim_edge_channel : str or None
        Channel of one side's slanted-edge image files, overriding ``edge_channel`` (a real
        RGBA edge image scored against a grey simulated one: ``real_edge_channel="G"``).
    edge_fit_order : int
        Order (1..5) of the polynomial fitted to the edge location of slanted-edge images:
        5 follows lens curvature (ISO 12233:2023), 1 is the straight line of ISO 12233:2014.
    ifov_mrad, pixel_pitch_um, focal_length_mm : float or None
        Camera geometry for converting curve frequencies between cycles/pixel, cycles/mrad
        and line pairs/mm (only needed when the two curves are in different units).
    mtf_options, sitf_options : mapping
        Options of the curve comparisons (:func:`irfidelity.curves.mtf_similarity`:
        ``smooth``, ``points``, ``alpha``, ``beta``; :func:`irfidelity.curves.sitf_similarity`:
        ``window``, ``lo_frac``, ``hi_frac``, ``method``, ``points``, ``alpha``, ``beta``),
        e.g. ``{"points": 64}``. Names and values are checked when the configuration is built;
        ``points`` is a count or a list of at most
        :data:`~irfidelity.curves.similarity.MAX_FEATURE_POINTS` (65536).
    mrtd_options : mapping
        Options of the ``mrtd`` component: the comparison
        (:func:`irfidelity.curves.mrtd_similarity`: ``tolerance`` in % of ΔT, ``points``,
        ``alpha``, ``beta``) and the MRTD measured on bar frames
        (:func:`irfidelity.curves.measured_mrtd`: ``snr_threshold``, ``eye_time``,
        ``frame_rate``), e.g. ``{"tolerance": 10}``.
    transfer_options : mapping
        The scene's transfer (:func:`irfidelity.transfer`, docs/interpretation.md "The
        pair as a system"): ``scene`` (default true: without camera curves, ``mtf``, ``sitf``
        and ``noise`` are graded from the frame pair; false leaves them to curves only),
        ``reference_frequency`` (the real camera's MTF50 in cy/px, where the MTF ratio is read
        as an MTF50 mismatch; default the real MTF curve's MTF50 when one is given in cy/px,
        else 0.25), ``tile`` (the tile side in pixels).
    grades : GradeScale
        The grade names (four: the tolerances separate excellent, good, fair and poor); its
        boundaries and widths are those of :meth:`GradeScale.evaluate` called directly.
    tolerances : Tolerances
        What each grade allows of each component, in engineering units (MTF50 and SiTF-slope
        mismatch, noise and MRTD ratio, RMS error relative to the scene's range, temperature
        error in temperature tolerances, NMI and SSIM relative to the real camera's own
        repeatability); they decide the grades
        (:func:`irfidelity.verdict.judge`, docs/interpretation.md). TOML ``[tolerances]``.
    register : "translation", "rigid", "similarity" or None
        Register the simulated frame onto the real one before the image metrics, which then
        count the overlap only (:func:`irfidelity.register`). A sequence is registered once,
        on its first readable pair (fixed camera geometry), unless ``register_each``.
    register_method : "auto", "phase" or "nmi"
        :func:`irfidelity.register`'s method; default
        :data:`irfidelity.registration.DEFAULT_METHOD`.
    register_each : bool
        Sequences: register every frame pair on its own (a moving simulated viewpoint),
        with the model of ``register``; each frame's transform is in its row.
    max_delay : int
        Sequences: find the frame offset ``d`` in ``[-max_delay, max_delay]`` between the
        two sequences (real frame ``i`` shows what simulated frame ``i + d`` shows) and pair
        frames by position offset by it (``report.delay``); 0: no search.
    pair_by : "auto", "name" or "order"
        Sequences: pair frames by file name (``"auto"`` does when both sides are named
        files) or by position. With ``max_delay``, by position (``"name"`` is refused).
    unit : "K", "C" or None
        Score temperatures in this unit (:mod:`irfidelity.temperature`): radiometric files are
        converted with their calibration, float frames taken as already in the unit; adds the
        ``temperature_*`` metrics and allows the opt-in ``radiometry`` component. The PSNR peak
        then defaults to the real frame's temperature range, and ``bits`` does not apply.
    calibration : mapping
        With ``unit``: calibration fields replacing a radiometric file's (``emissivity``,
        ``reflected_temperature`` (°C), ``object_distance`` (m), ``relative_humidity`` (%), ...:
        :data:`irfidelity.radiometry.CALIBRATION_FIELDS`), which with all five Planck constants
        also calibrate integer frames that carry none; or a linear ``gain`` and ``offset``
        (temperature in ``unit`` = gain·count + offset) for integer frames without a calibration.
    temperature_tolerance : float or None
        With ``unit``: the error in K counted as within tolerance, and the scale of the
        ``radiometry`` component. None: the real camera's NETD when the noise component
        measured it, else 1 K.

    Examples
    --------
    >>> import irfidelity as irf
    >>> cfg = irf.ScoringConfig(bits=14, peak="range", weights="psnr=0.5,ssim=0.5")
    >>> print(cfg.weights)
    mtf=0, sitf=0, psnr=0.5, nmi=0, ssim=0.5, noise=0, radiometry=0, mrtd=0
    >>> cfg.replace(bins="levels").bins, cfg.bins                 # frozen: replace makes a copy
    ('levels', 256)
    >>> cfg.save("scoring.toml")
    >>> irf.ScoringConfig.load("scoring.toml") == cfg
    True
    """

    weights: Weights = field(default_factory=_shared(Weights))
    bits: int | None = None
    peak: float | str | None = None
    bins: int | str = 256
    hist_range: str | tuple = DEFAULT_HIST_RANGE
    psnr_anchors: tuple = DEFAULT_PSNR_ANCHORS
    ssim_exponents: tuple = (1.0, 1.0, 1.0)
    missing: str = "renormalize"
    nonfinite: str = "raise"
    real_channel: str | None = None
    sim_channel: str | None = None
    edge_channel: str | None = None
    real_edge_channel: str | None = None
    sim_edge_channel: str | None = None
    edge_fit_order: int = 5
    ifov_mrad: float | None = None
    pixel_pitch_um: float | None = None
    focal_length_mm: float | None = None
    mtf_options: Mapping = field(default_factory=dict)
    sitf_options: Mapping = field(default_factory=dict)
    mrtd_options: Mapping = field(default_factory=dict)
    transfer_options: Mapping = field(default_factory=dict)
    grades: GradeScale = field(default_factory=_shared(GradeScale))
    tolerances: Tolerances = field(default_factory=_shared(Tolerances))
    register: str | None = None
    register_method: str = DEFAULT_METHOD
    register_each: bool = False
    max_delay: int = 0
    pair_by: str = "auto"
    unit: str | None = None
    calibration: Mapping = field(default_factory=dict)
    temperature_tolerance: float | None = None

    def __post_init__(self) -> None:
        for name, value in self._validated().items():
            object.__setattr__(self, name, value)

    def _validated(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        try:
            out["weights"] = Weights.coerce(self.weights)
        except FidelityError as exc:
            raise ConfigError("weights", str(exc)) from None
        out["bits"] = optional_int("bits", self.bits, 1, 32)
        out["peak"] = peak_value(self.peak)
        out["bins"] = bins_value(self.bins)
        out["hist_range"] = hist_range_value(self.hist_range)
        anchors = tuple(finite_numbers("psnr_anchors", a, 2) for a in pairs("psnr_anchors", self.psnr_anchors))
        try:
            psnr_curve_params(anchors)
        except FidelityError as exc:
            raise ConfigError("psnr_anchors", str(exc)) from None
        out["psnr_anchors"] = anchors
        exponents = finite_numbers("ssim_exponents", self.ssim_exponents, 3)
        if any(e < 0 for e in exponents):
            raise ConfigError("ssim_exponents", f"expected numbers >= 0; got {self.ssim_exponents!r}")
        out["ssim_exponents"] = exponents
        out["missing"] = choice("missing", self.missing, MISSING_MODES)
        out["nonfinite"] = choice("nonfinite", self.nonfinite, NONFINITE_MODES)
        for name in ("real_channel", "sim_channel", "edge_channel", "real_edge_channel", "sim_edge_channel"):
            out[name] = optional_name(name, getattr(self, name))
        out["edge_fit_order"] = optional_int("edge_fit_order", self.edge_fit_order, 1, 5)
        for name in ("ifov_mrad", "pixel_pitch_um", "focal_length_mm"):
            out[name] = optional_positive(name, getattr(self, name))
        for name in ("mtf_options", "sitf_options", "mrtd_options", "transfer_options"):
            out[name] = curve_options(name, getattr(self, name))
        if not isinstance(self.grades, GradeScale):
            out["grades"] = grade_scale(self.grades)
        out["tolerances"] = Tolerances.coerce(self.tolerances)  # its errors name the tolerance
        out["register"] = None if self.register is None else choice("register", self.register, REGISTRATION_MODELS)
        out["register_method"] = choice("register_method", self.register_method, REGISTRATION_METHODS)
        if not isinstance(self.register_each, bool):
            raise ConfigError("register_each", f"expected true or false; got {self.register_each!r}")
        if self.register_each and out["register"] is None:
            raise ConfigError("register_each", "registers every pair with the model of register; set register to "
                                               "translation, rigid or similarity")
        out["max_delay"] = optional_int("max_delay", self.max_delay, 0, 1 << 20)
        out["pair_by"] = choice("pair_by", self.pair_by, PAIRING_RULES)
        if out["max_delay"] and out["pair_by"] == "name":
            raise ConfigError("pair_by", "frames paired by name have no delay to search; with max_delay the frames "
                                         "are paired by position, offset by the delay found (pair_by = auto or order)")
        out.update(unit_fields(self.unit, self.calibration, self.temperature_tolerance, out["bits"]))
        return out

    @property
    def numeric_peak(self) -> float | None:
        """The PSNR peak when it is a number; None for ``"range"`` (each real frame's own) or unset."""
        return self.peak if isinstance(self.peak, float) else None

    # -- construction ---------------------------------------------------------------
    @classmethod
    def fields(cls) -> tuple[str, ...]:
        """Names of the configuration fields, in order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    def replace(self, **changes: Any) -> ScoringConfig:
        """A copy with some fields changed (``channel=`` sets both frame channels).

        Unknown names raise :class:`~irfidelity.FidelityError` listing the valid ones.
        """
        changes = self._known(changes)
        return dataclasses.replace(self, **changes) if changes else self

    def _with_range_peak(self) -> ScoringConfig:
        """A copy whose PSNR peak is each real frame's own range (``peak="range"``), the other
        fields as checked already: none is checked again."""
        out = copy.copy(self)
        object.__setattr__(out, "peak", "range")
        return out

    @classmethod
    def _known(cls, changes: Mapping[str, Any]) -> dict[str, Any]:
        """``changes`` by field (``channel`` sets both frame channels); unknown names raise."""
        changes = dict(changes)
        if "channel" in changes:
            channel = changes.pop("channel")
            changes.setdefault("real_channel", channel)
            changes.setdefault("sim_channel", channel)
        unknown = sorted(set(changes) - set(cls.fields()))
        if unknown:
            raise FidelityError(f"unknown scoring option(s) {', '.join(unknown)}; "
                                f"the options are: {', '.join(cls.fields())}, channel", option=unknown[0])
        return changes

    @classmethod
    def resolve(cls, config: ScoringConfig | Mapping | str | os.PathLike | None = None,
                **overrides: Any) -> ScoringConfig:
        """The configuration an entry point runs with: ``config`` (an object, a mapping or a
        TOML/JSON path; default: the defaults) with ``overrides`` applied. Overrides that
        are None are ignored, so keyword arguments left at their default change nothing.
        Without ``config``, the configuration made from plain options (numbers, names,
        flags) is remembered: calling again with the same ones returns the same frozen
        object without validating them again."""
        overrides = {k: v for k, v in overrides.items() if v is not None}
        if config is None:
            key = _memo_key(overrides)
            resolved = _RESOLVED.get(key) if key is not None else None
            if resolved is None:
                resolved = cls(**cls._known(overrides))  # validated once
                if key is not None and len(_RESOLVED) < _RESOLVED_MAX:
                    _RESOLVED[key] = resolved
            return resolved
        if isinstance(config, ScoringConfig):
            base = config
        elif isinstance(config, Mapping):
            base = cls.from_dict(config)
        elif isinstance(config, (str, os.PathLike)):
            base = cls.load(config)
        else:
            raise FidelityError(f"config: expected a ScoringConfig, a mapping or a TOML/JSON path; "
                                f"got {type(config).__name__}")
        return base.replace(**overrides)

    # -- serialisation --------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict; :meth:`from_dict` inverts it."""
        out: dict[str, Any] = {}
        for name in self.fields():
            value = getattr(self, name)
            if isinstance(value, Weights):
                value = value.as_dict()
            elif isinstance(value, GradeScale):
                value = {"grades": list(value.grades), "cuts": {k: list(v) for k, v in value.cuts.items()},
                         "width": dict(cast(Mapping[str, float], value.width))}  # a mapping since __post_init__
            elif isinstance(value, Tolerances):
                value = value.to_dict()
            elif isinstance(value, tuple):
                value = [list(v) if isinstance(v, tuple) else v for v in value]
            out[name] = value
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ScoringConfig:
        """A configuration from a mapping (missing fields keep their defaults)."""
        if not isinstance(data, Mapping) or not all(isinstance(k, str) for k in data):
            raise FidelityError(f"config: expected a mapping of option names to values; got {type(data).__name__}",
                                option="config")
        values = dict(data)
        values.pop("version", None)  # reports record it beside the options
        return cls().replace(**values)

    @classmethod
    def load(cls, path: str | os.PathLike) -> ScoringConfig:
        """Read a configuration from a ``.toml`` or ``.json`` file (see :meth:`save`).

        Files larger than :data:`~irfidelity.config_file.MAX_CONFIG_BYTES` (256 KiB) or nested
        deeper than :data:`~irfidelity.config_file.MAX_CONFIG_DEPTH` (16) are refused before
        parsing; every error is a :class:`~irfidelity.FidelityError` naming the file.
        """
        data = read_config(path)
        try:
            return cls.from_dict(data)
        except FidelityError as exc:
            raise FidelityError(f"{os.fsdecode(os.fspath(path))}: {exc}", option=exc.option) from None

    def save(self, path: str | os.PathLike) -> None:
        """Write the configuration as TOML (or JSON for a ``.json`` path)."""
        spath = os.fspath(path)
        text = (json.dumps(self.to_dict(), indent=2) + "\n" if os.fsdecode(spath).lower().endswith(".json")
                else self.to_toml())
        with open(spath, "w", encoding="utf-8") as fh:
            fh.write(text)

    def to_toml(self) -> str:
        """The configuration as TOML. TOML has no null: a field that is None is written as a
        commented-out example. Keys that are not bare TOML keys are quoted."""
        tables = ("weights", "mtf_options", "sitf_options", "mrtd_options", "transfer_options", "grades", "tolerances",
                  "calibration")
        return toml_document(self.to_dict(), tables, _UNSET_EXAMPLES,
                             "irfidelity scoring configuration (irfidelity score --config FILE)")


#: What a commented-out line shows for a field that is not set.
_UNSET_EXAMPLES = {
    "bits": "14            # bit depth of integer frames (default PSNR peak 2^bits - 1)",
    "peak": '"range"       # or a number: the PSNR peak',
    "real_channel": '"Y"   # channel of the real frame files',
    "sim_channel": '"Y"    # channel of the simulated frame files',
    "edge_channel": '"R"   # channel of slanted-edge images (both sides)',
    "real_edge_channel": '"G"   # channel of the real slanted-edge image, if it differs',
    "sim_edge_channel": '"Y"    # channel of the simulated slanted-edge image, if it differs',
    "ifov_mrad": "0.5     # camera geometry for curve unit conversions",
    "pixel_pitch_um": "12.0",
    "focal_length_mm": "25.0",
    "register": '"translation"   # or "rigid", "similarity": align before the image metrics',
    "unit": '"K"          # or "C": score temperatures (radiometric files, float frames)',
    "temperature_tolerance": "0.5   # K; default the real camera's NETD, else 1 K",
}


