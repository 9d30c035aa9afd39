"""Tolerances in engineering units: what each grade allows of each component.

A grade boundary is a statement an engineer can sign — "excellent: the simulated MTF50 within
5 % of the real camera's" — not a number on a component's [0, 1] scale. :class:`Tolerances`
holds three limits per component (for excellent, good and fair; beyond the last is poor) in
the quantity that is specified for a camera, and :func:`component_cuts` converts each limit
exactly to the component's scale, where the grade is decided (docs/interpretation.md,
"Tolerances", lists each default and where it comes from):

* ``mtf50``, ``sitf_slope``: the mismatch ``1 − smaller/larger`` of the two MTF50s (slopes);
  on the scale of f1 (f2), ``μ(1 − e)^α`` with ``μ(r) = 2r/(1 + r²)`` (eq. 4 at the ratio
  ``r``), the value a simulator gets whose curve has the real shape (ρ = 1) and whose MTF50 is
  off by exactly ``e``; a shape difference (ρ < 1) lowers f1 further and counts too;
* ``noise_ratio``: the ratio ``larger/smaller`` of the temporal noise (σ_tvh, the NETD in
  counts); on the noise component's scale ``μ(1/q)``, exact for noise scaled by ``q``;
* ``mrtd_ratio``: the ratio ``larger/smaller`` of the MRTD levels (their geometric means over
  the common frequencies); on the mrtd component's scale ``μ(1/q)^α``, exact for an MRTD of the
  real shape scaled by ``q`` (``mrtd_options.tolerance`` forgives a level difference before
  that: the grade counts what is left of it);
* ``radiometry``: the temperature error ``sqrt((bias² + RMSE²)/2)`` in units of the
  temperature tolerance (``config.temperature_tolerance``, else the real camera's NETD, else
  1 K); on the radiometry component's scale ``0.9^(e²)``, exact
  (:func:`irfidelity.temperature.radiometry_component`);
* ``rms_error``: the RMS difference of the frames as a fraction of the real scene's range
  (max − min); on f3's scale the normalised PSNR at ``20·log10(peak / (e·range))`` dB;
* ``nmi``, ``ssim``: the least fraction of the camera's own repeatability — the value two real
  frames of the scene reach (the *ceiling*, docs/interpretation.md) — the simulator must reach;
  on the component's scale ``limit × ceiling``. Without a second real frame there is no
  ceiling, and the calibrated absolute boundaries of :data:`irfidelity.fuzzy.DEFAULT_CUTS`
  apply (scene-dependent; the report says so).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .errors import FidelityError
from .fuzzy import DEFAULT_CUTS
from .normalize import DEFAULT_PSNR_ANCHORS, normalize_psnr

__all__ = ["Tolerances", "TOLERANCE_GRADES", "KINDS", "mu_of_ratio", "component_cuts", "parse_tolerance"]

#: The grades the tolerances separate, best first (three limits: excellent, good, fair).
TOLERANCE_GRADES = ("excellent", "good", "fair", "poor")

#: How each tolerance is read: "most" (the quantity may be at most the limit) or "least".
KINDS = {"mtf50": "most", "sitf_slope": "most", "noise_ratio": "most", "mrtd_ratio": "most", "rms_error": "most",
         "radiometry": "most", "nmi": "least", "ssim": "least"}

#: The component each tolerance grades.
COMPONENT_OF = {"mtf50": "mtf", "sitf_slope": "sitf", "noise_ratio": "noise", "mrtd_ratio": "mrtd",
                "rms_error": "psnr", "radiometry": "radiometry", "nmi": "nmi", "ssim": "ssim"}

#: Valid range of each tolerance's limits: (lowest, highest, what).
_BOUNDS = {"mtf50": (0.0, 1.0, "fractions in (0, 1)"), "sitf_slope": (0.0, 1.0, "fractions in (0, 1)"),
           "noise_ratio": (1.0, math.inf, "ratios > 1"), "mrtd_ratio": (1.0, math.inf, "ratios > 1"),
           "rms_error": (0.0, math.inf, "fractions > 0"),
           "radiometry": (0.0, math.inf, "multiples of the temperature tolerance > 0"),
           "nmi": (0.0, 1.0, "fractions of the ceiling in (0, 1]"),
           "ssim": (0.0, 1.0, "fractions of the ceiling in (0, 1]")}


def mu_of_ratio(ratio: float) -> float:
    """Eq. (4) at the ratio ``r = b/a`` of two positive values: ``μ = 2r/(1 + r²)``.

    Examples
    --------
    >>> round(mu_of_ratio(0.9), 5), mu_of_ratio(1.0)
    (0.99448, 1.0)
    """
    r = float(ratio)
    return 2.0 * r / (1.0 + r * r)


def _limits(name: str, value: Any) -> tuple[float, float, float]:
    """Three limits for excellent, good, fair: each within the tolerance's bounds, from the
    strictest to the loosest."""
    lo, hi, what = _BOUNDS[name]
    items = value.tolist() if hasattr(value, "tolist") else value
    try:
        limits = tuple(float(v) for v in items if not isinstance(v, bool))
    except (TypeError, ValueError):
        limits = ()
    ok = len(limits) == 3 and len(items) == 3 and all(math.isfinite(v) and lo < v <= hi for v in limits)
    if ok and name not in ("nmi", "ssim"):
        ok = all(v < hi for v in limits)
    if not ok:
        raise FidelityError(f"tolerances.{name}: expected three {what}, for excellent, good and fair; "
                            f"got {value!r}", option="tolerances")
    stricter = (lambda a, b: a <= b) if KINDS[name] == "most" else (lambda a, b: a >= b)
    if not (stricter(limits[0], limits[1]) and stricter(limits[1], limits[2])):
        order = "ascending" if KINDS[name] == "most" else "descending"
        raise FidelityError(f"tolerances.{name}: the limits for excellent, good and fair must be {order} "
                            f"(excellent the strictest); got {list(limits)}", option="tolerances")
    return limits  # type: ignore[return-value]


@dataclass(frozen=True)
class Tolerances:
    """The limits of each grade, per component, in engineering units.

    Each field holds three limits, for excellent, good and fair; a component beyond the fair
    limit is poor. The defaults and their sources are in docs/interpretation.md.

    Attributes
    ----------
    mtf50 : (float, float, float)
        Mismatch of the MTF50s, ``1 − smaller/larger``: default 5 %, 10 %, 20 %.
    sitf_slope : (float, float, float)
        Mismatch of the SiTF slopes (responsivity), ``1 − smaller/larger``: 5 %, 10 %, 20 %.
    noise_ratio : (float, float, float)
        Ratio of the temporal noise (NETD), ``larger/smaller``: 1.1, 1.25, 2.
    mrtd_ratio : (float, float, float)
        Ratio of the MRTD levels, ``larger/smaller``: 1.1, 1.25, 2 (the MRTD scales with the
        NETD, so as the noise ratio).
    rms_error : (float, float, float)
        RMS error as a fraction of the real scene's range (max − min): 0.032, 0.068, 0.14
        (PSNR 29.9, 23.4, 17.1 dB relative to the range).
    radiometry : (float, float, float)
        Temperature error ``sqrt((bias² + RMSE²)/2)`` in temperature tolerances: 1, 2, 3 (a
        pure offset of 1, 2, 3 tolerances; the radiometry component 0.9, 0.9⁴, 0.9⁹).
    nmi, ssim : (float, float, float)
        The least fraction of the ceiling (the value two real frames of the scene reach):
        NMI 0.7, 0.5, 0.3; SSIM 0.85, 0.7, 0.4 (benches/calibrate_tolerances.py).

    Examples
    --------
    >>> from irfidelity.tolerances import Tolerances
    >>> tol = Tolerances(mtf50=(0.03, 0.08, 0.15))
    >>> tol.mtf50, tol.limits("nmi")
    ((0.03, 0.08, 0.15), (0.7, 0.5, 0.3))
    >>> Tolerances.from_dict({"rms_error": [0.02, 0.05, 0.1]}).rms_error
    (0.02, 0.05, 0.1)
    """

    mtf50: tuple = (0.05, 0.10, 0.20)
    sitf_slope: tuple = (0.05, 0.10, 0.20)
    noise_ratio: tuple = (1.10, 1.25, 2.0)
    mrtd_ratio: tuple = (1.10, 1.25, 2.0)
    rms_error: tuple = (0.032, 0.068, 0.14)
    radiometry: tuple = (1.0, 2.0, 3.0)
    nmi: tuple = (0.70, 0.50, 0.30)
    ssim: tuple = (0.85, 0.70, 0.40)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _limits(f.name, getattr(self, f.name)))

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))

    def limits(self, name: str) -> tuple[float, float, float]:
        """The three limits of one tolerance (by its name, e.g. ``"mtf50"``)."""
        return getattr(self, name)

    def to_dict(self) -> dict[str, list[float]]:
        return {name: list(self.limits(name)) for name in self.names()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Tolerances:
        """Tolerances from a mapping (missing names keep their defaults)."""
        if not isinstance(data, Mapping):
            raise FidelityError(f"tolerances: expected a mapping of tolerance names to three limits; got "
                                f"{type(data).__name__}", option="tolerances")
        unknown = sorted(str(k) for k in data if k not in cls.names())
        if unknown:
            raise FidelityError(f"tolerances: unknown name(s) {', '.join(unknown)}; the tolerances are "
                                f"{', '.join(cls.names())}", option="tolerances")
        return cls(**dict(data))

    @classmethod
    def coerce(cls, value: Any) -> Tolerances:
        """A Tolerances from one, a mapping, or None (the defaults)."""
        if value is None:
            return cls()
        if isinstance(value, Tolerances):
            return value
        return cls.from_dict(value)


def parse_tolerance(text: str) -> tuple[str, tuple[float, ...]]:
    """``"NAME=E,G,F"`` (the command line's ``--tolerance``) as ``(name, limits)``.

    Examples
    --------
    >>> parse_tolerance("mtf50=0.03,0.08,0.15")
    ('mtf50', (0.03, 0.08, 0.15))
    """
    name, sep, values = str(text).partition("=")
    name = name.strip().replace("-", "_")
    if not sep or name not in Tolerances.names():
        raise FidelityError(f"tolerance {text!r}: expected NAME=EXCELLENT,GOOD,FAIR with NAME one of "
                            f"{', '.join(Tolerances.names())}", option="tolerances")
    try:
        limits = tuple(float(v) for v in values.split(","))
    except ValueError:
        raise FidelityError(f"tolerance {text!r}: the limits must be numbers", option="tolerances") from None
    return name, _limits(name, limits)


def component_cuts(component: str, tolerances: Tolerances, *, alpha: float = 1.0, peak: float | None = None,
                   scene_range: float | None = None, anchors: Any = DEFAULT_PSNR_ANCHORS,
                   ceiling: float | None = None) -> tuple[tuple[float, float, float], str]:
    """The limits of ``component``'s grades on its own [0, 1] scale, strictest first
    (excellent, good, fair: a value at or above a cut meets that grade), and the basis.

    ``alpha`` is the exponent of μ (eq. 3; mtf, sitf, mrtd); ``peak``, ``scene_range`` and
    ``anchors`` fix the PSNR scale (psnr; without a range the tolerance is relative to the
    peak); ``ceiling`` is the real-vs-real value (nmi, ssim). The basis says which applied:
    "tolerance", "range", "peak", "ceiling" or "absolute" (no ceiling: calibrated cuts).

    Examples
    --------
    >>> cuts, basis = component_cuts("mtf", Tolerances())
    >>> [round(c, 5) for c in cuts], basis
    ([0.99869, 0.99448, 0.97561], 'tolerance')
    >>> cuts, basis = component_cuts("ssim", Tolerances(), ceiling=0.9)
    >>> [round(c, 3) for c in cuts], basis
    ([0.765, 0.63, 0.36], 'ceiling')
    """
    name = next(n for n, c in COMPONENT_OF.items() if c == component)
    limits = tolerances.limits(name)
    if component in ("mtf", "sitf"):
        return tuple(mu_of_ratio(1.0 - e) ** alpha for e in limits), "tolerance"
    if component in ("noise", "mrtd"):
        exponent = alpha if component == "mrtd" else 1.0
        return tuple(mu_of_ratio(1.0 / q) ** exponent for q in limits), "tolerance"
    if component == "radiometry":
        from .temperature import radiometry_component

        return tuple(radiometry_component(e, e, 1.0) for e in limits), "tolerance"  # type: ignore[return-value]
    if component == "psnr":
        if peak is None:
            raise FidelityError("the psnr grade needs the PSNR peak")
        span, basis = (scene_range, "range") if scene_range is not None and scene_range > 0 else (peak, "peak")
        cuts = tuple(normalize_psnr(20.0 * math.log10(peak / (e * span)), anchors=anchors) for e in limits)
        return cuts, basis  # type: ignore[return-value]
    if ceiling is None or not ceiling > 0:
        return tuple(reversed(DEFAULT_CUTS[component])), "absolute"  # type: ignore[return-value]
    return tuple(e * ceiling for e in limits), "ceiling"  # type: ignore[return-value]
