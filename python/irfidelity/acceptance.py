"""Acceptance specifications: which components a simulator must get right, and how well.

A score says how close a simulator is; an acceptance says whether it is close enough for one
use. An :class:`Acceptance` lists the required components, the least grade each must reach and,
optionally, its own tolerance limits (in the units of ``[tolerances]``, docs/interpretation.md
"Grades"), read from a TOML file::

    # acceptance.toml
    name = "LWIR trainer, detection range study"
    grade = "good"              # the least overall grade accepted (optional)
    [require.mtf]               # a required component
    mtf50 = [0.05, 0.10, 0.20]  # its tolerance limits (optional; else the configuration's)
    grade = "good"              # the least grade of this component
    [require.sitf]
    grade = "good"
    [require.psnr]
    grade = "fair"

The rules, chosen so that an accepted simulator is one an engineer can sign off:

* **Keys.** Top level: ``name`` (text, optional), ``grade`` (optional) and ``require``, a table
  of components (``mtf``, ``sitf``, ``psnr``, ``nmi``, ``ssim``, ``noise``, ``radiometry``,
  ``mrtd``). A requirement holds ``grade`` and the component's own tolerance, by its name in
  ``[tolerances]`` (``mtf50`` for mtf, ``sitf_slope``, ``rms_error`` for psnr, ``nmi``,
  ``ssim``, ``noise_ratio``, ``radiometry``, ``mrtd_ratio``): three limits, for excellent,
  good and fair. ``require.psnr = "fair"`` is short for ``[require.psnr] grade = "fair"``.
  Any other key, an unknown component or grade name is a :class:`SpecError` naming the key and
  the file; so is a spec that requires nothing.
* **Grades.** A requirement without ``grade`` takes the spec's ``grade``; without either it is
  an error (an acceptance states its threshold). The top-level ``grade`` checks the report's
  overall grade, the worst grade of *every* weighted component, required or not.
* **Tolerances.** The spec's limits replace the configuration's *before* scoring
  (:meth:`Acceptance.overrides`, :meth:`Acceptance.apply`; the command line's ``--spec`` does
  it), so that the report's grades and its reasons are the spec's. :func:`check` refuses a
  report graded with other limits rather than re-grading it behind the report's back. Limits
  of tolerances the spec does not name stay the configuration's.
* **Not assessed is not accepted.** A required component that was not computed (weight 0, no
  input: ``report.skipped``) fails its requirement, with a reason naming the input it needs.
  So does an NMI or SSIM requirement with its own limits when no ceiling was measured: those
  limits are fractions of the ceiling, and without one the calibrated absolute boundaries
  grade instead (not the spec's limits).
* **Sequences** are judged on their pooled result; the result records the frames that failed
  (the command line then exits 3, as without a spec).

Examples
--------
>>> import numpy as np
>>> import irfidelity as irf
>>> from irfidelity.acceptance import Acceptance, check
>>> spec = Acceptance.from_dict({"name": "demo", "require": {"psnr": {"grade": "good", "rms_error": [0.01, 0.02, 0.05]},
...                                                         "ssim": "fair"}})
>>> spec.tolerances
{'rms_error': (0.01, 0.02, 0.05)}
>>> real = np.tile(np.arange(0, 1600, 10, dtype=np.uint16), (120, 1))   # a ramp spanning 1590 counts
>>> sim = real + np.uint16(20)                                          # 20 counts too warm: 1.26 % of it
>>> rep = irf.evaluate(real, sim, bits=14, peak="range", weights="psnr=0.5,ssim=0.5", **spec.overrides())
>>> result = check(rep, spec)
>>> result.passed, result.requirements[0].grade
(True, 'good')
>>> print(result.requirements[0].reason)
psnr good, required good: RMS error 1.26 % of the scene's range (20 of 1590); the tolerance for good is 2 % of
the scene's range
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .errors import FidelityError
from .fuzzy import COMPONENTS
from .schema import to_json
from .tolerances import COMPONENT_OF, TOLERANCE_GRADES, Tolerances

__all__ = ["Acceptance", "Requirement", "AcceptanceResult", "RequirementResult", "SpecError", "check",
           "MAX_SPEC_BYTES"]

#: Largest acceptance specification read (bytes): a spec is a few hundred bytes.
MAX_SPEC_BYTES = 1 << 16

#: The keys of a spec's top level and of one requirement (besides the component's tolerance).
_TOP_KEYS = ("name", "grade", "require")
_REQUIREMENT_KEYS = ("grade",)

#: The tolerance of each component (``[tolerances]`` name).
TOLERANCE_OF = {component: name for name, component in COMPONENT_OF.items()}

#: What each component is computed from, in the API's and the command line's words.
_NEEDS = {
    "mtf": "MTF curves or slanted-edge images of both cameras (real_mtf/sim_mtf, --real-mtf/--sim-mtf), or frames "
           "whose scene carries detail",
    "sitf": "SiTF curves of both cameras (real_sitf/sim_sitf, --real-sitf/--sim-sitf), or frames of a scene with "
            "contrast",
    "psnr": "the real and simulated frames", "nmi": "the real and simulated frames",
    "ssim": "the real and simulated frames",
    "noise": "recordings of a uniform source from both cameras (real_noise/sim_noise, --real-noise/--sim-noise)",
    "radiometry": "frames scored in a temperature unit (unit=, --unit K|C)",
    "mrtd": "bar frames or MRTD curves of both cameras (real_mrtd/sim_mrtd, --real-bars/--sim-bars)",
}

#: The unit of each component's measure (:attr:`RequirementResult.measure`).
_UNITS = {"mtf": "MTF50 mismatch (1 − smaller/larger)", "sitf": "SiTF-slope mismatch (1 − smaller/larger)",
          "noise": "noise ratio (larger/smaller)", "mrtd": "MRTD ratio (larger/smaller)",
          "radiometry": "temperature error in temperature tolerances"}

#: Statuses of a requirement.
PASS, FAIL, NOT_ASSESSED = "pass", "fail", "not assessed"


class SpecError(FidelityError):
    """An acceptance specification that cannot be used: unreadable, not TOML, an unknown key,
    component or grade, bad limits — or a report that was not graded by its tolerances. The
    message names the file and the key."""

    def __init__(self, message: str):
        super().__init__(message, option="spec")


# --------------------------------------------------------------------------- the spec
@dataclass(frozen=True)
class Requirement:
    """One required component.

    Attributes
    ----------
    component : str
        The component (``"mtf"``, ``"psnr"``, ...).
    grade : str
        The least grade it must reach.
    limits : (float, float, float) or None
        Its tolerance's limits for excellent, good and fair (in the unit of
        :attr:`tolerance`), or None: the configuration's.
    """

    component: str
    grade: str
    limits: tuple | None = None

    def __post_init__(self) -> None:  # made directly too, not only from a file: the same checks
        key = f"require.{self.component}"
        if self.component not in COMPONENTS:
            raise SpecError(f"{key}: unknown component; the components are {', '.join(COMPONENTS)}")
        if not (isinstance(self.grade, str) and self.grade):
            raise SpecError(f"{key}.grade: expected a grade name; got {self.grade!r}")
        if self.limits is not None:
            object.__setattr__(self, "limits", _limits(self.tolerance, self.limits, f"{key}.{self.tolerance}"))

    @property
    def tolerance(self) -> str:
        """The name of the component's tolerance (``"mtf50"`` for mtf)."""
        return TOLERANCE_OF[self.component]

    def to_dict(self) -> dict:
        out: dict[str, Any] = {"grade": self.grade}
        if self.limits is not None:
            out[self.tolerance] = list(self.limits)
        return out


@dataclass(frozen=True)
class Acceptance:
    """An acceptance specification (the module notes give the format and the rules).

    Attributes
    ----------
    requirements : tuple of Requirement
        The required components, in the order given.
    grade : str or None
        The least overall grade accepted.
    name : str or None
        What the spec is for.
    source : str or None
        The file it was read from (named in messages).
    """

    requirements: tuple = ()
    grade: str | None = None
    name: str | None = None
    source: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        requirements = tuple(self.requirements)
        if not all(isinstance(r, Requirement) for r in requirements):
            raise SpecError("requirements: expected Requirement objects")
        twice = [r.component for i, r in enumerate(requirements) if r.component in
                 [q.component for q in requirements[:i]]]
        if twice:
            raise SpecError(f"require.{twice[0]}: required twice")
        object.__setattr__(self, "requirements", requirements)

    # -- reading ---------------------------------------------------------------------
    @classmethod
    def from_toml(cls, path: str | os.PathLike) -> Acceptance:
        """Read a spec from a TOML file; a :class:`SpecError` naming the file and key otherwise."""
        spath = os.fsdecode(os.fspath(path))
        return cls.from_dict(_read_toml(spath), source=spath)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, source: str | None = None,
                  grades: tuple = TOLERANCE_GRADES) -> Acceptance:
        """A spec from a mapping of the TOML's shape; ``source`` prefixes the messages, and
        ``grades`` are the valid grade names (best first)."""
        try:
            return cls._parse(data, grades, source)
        except SpecError as exc:
            raise SpecError(f"{source}: {exc}" if source else str(exc)) from None

    @classmethod
    def _parse(cls, data: Any, grades: tuple, source: str | None) -> Acceptance:
        if not isinstance(data, Mapping):
            raise SpecError(f"expected a table of {', '.join(_TOP_KEYS)}; got {type(data).__name__}")
        _refuse_unknown(data, _TOP_KEYS, "", "the keys of an acceptance specification are")
        name = data.get("name")
        if name is not None and not (isinstance(name, str) and name.strip()):
            raise SpecError(f"name: expected a non-empty text; got {name!r}")
        grade = None if data.get("grade") is None else _grade(data["grade"], "grade", grades)
        table = data.get("require", {})
        if not isinstance(table, Mapping):
            raise SpecError(f"require: expected a table of components ([require.psnr] ...); got {table!r}")
        _refuse_unknown(table, COMPONENTS, "require.", "the components are")
        requirements = tuple(_requirement(k, v, grade, grades) for k, v in table.items())
        if not requirements and grade is None:
            raise SpecError("nothing is required: give [require.COMPONENT] tables or an overall grade")
        return cls(requirements=requirements, grade=grade, name=name, source=source)

    # -- what it asks of the scoring ---------------------------------------------------
    @property
    def tolerances(self) -> dict[str, tuple]:
        """``{tolerance name: limits}`` the spec sets (its requirements' own limits)."""
        return {r.tolerance: r.limits for r in self.requirements if r.limits is not None}

    def overrides(self, config: Any = None) -> dict[str, Tolerances]:
        """The scoring options that make a report gradeable by this spec: ``{"tolerances":
        ...}`` — ``config``'s tolerances (a ScoringConfig, a Tolerances, or None: the defaults)
        with the spec's limits in place — or ``{}`` when the spec sets no limits. Pass them to
        :func:`irfidelity.evaluate` or :func:`irfidelity.score_sequence` as keywords."""
        if not self.tolerances:
            return {}
        base = getattr(config, "tolerances", config)
        limits = Tolerances.coerce(base).to_dict()
        limits.update({name: list(v) for name, v in self.tolerances.items()})
        return {"tolerances": Tolerances.from_dict(limits)}

    def apply(self, config: Any) -> Any:
        """``config`` (a :class:`~irfidelity.ScoringConfig`) with the spec's tolerances."""
        return config.replace(**self.overrides(config))

    def check(self, report: Any) -> AcceptanceResult:
        """:func:`check` this spec against ``report``."""
        return check(report, self)

    def to_dict(self) -> dict:
        """The spec as the mapping :meth:`from_dict` reads (the TOML's shape)."""
        out: dict[str, Any] = {}
        if self.name is not None:
            out["name"] = self.name
        if self.grade is not None:
            out["grade"] = self.grade
        out["require"] = {r.component: r.to_dict() for r in self.requirements}
        return out


def _read_toml(path: str) -> Any:
    """The parsed TOML of ``path``, within :data:`MAX_SPEC_BYTES`."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_SPEC_BYTES + 1)
    except OSError as exc:
        raise SpecError(f"{path}: cannot read the acceptance specification: {exc.strerror or exc}") from None
    if len(raw) > MAX_SPEC_BYTES:
        raise SpecError(f"{path}: larger than {MAX_SPEC_BYTES} bytes, too large for an acceptance specification")
    try:
        return tomllib.loads(raw.decode("utf-8"))
    except (ValueError, RecursionError) as exc:  # UnicodeDecodeError and TOMLDecodeError are ValueErrors
        raise SpecError(f"{path}: not a valid TOML acceptance specification: {exc}") from None


def _refuse_unknown(table: Mapping, known: tuple, prefix: str, what: str) -> None:
    unknown = [str(k) for k in table if k not in known]
    if unknown:
        raise SpecError(f"{prefix}{unknown[0]}: unknown key; {what} {', '.join(known)}")


def _grade(value: Any, key: str, grades: tuple) -> str:
    if not isinstance(value, str) or value not in grades:
        raise SpecError(f"{key}: expected a grade, one of {', '.join(grades)}; got {value!r}")
    return value


def _requirement(component: str, value: Any, default: str | None, grades: tuple) -> Requirement:
    """One ``[require.COMPONENT]`` table (or its short form, a grade name)."""
    key = f"require.{component}"
    if isinstance(value, str):
        value = {"grade": value}
    if not isinstance(value, Mapping):
        raise SpecError(f"{key}: expected a table (grade = ..., {TOLERANCE_OF[component]} = [...]) or a grade name; "
                        f"got {value!r}")
    tolerance = TOLERANCE_OF[component]
    _refuse_unknown(value, _REQUIREMENT_KEYS + (tolerance,), key + ".",
                    f"a requirement of {component} holds")
    if value.get("grade") is None and default is None:
        raise SpecError(f"{key}: no grade: give grade = \"good\" (or another grade: {', '.join(grades)}), or an "
                        f"overall grade for the spec")
    given = value.get("grade")
    grade = _grade(given, f"{key}.grade", grades) if given is not None else str(default)
    limits = None if tolerance not in value else _limits(tolerance, value[tolerance], f"{key}.{tolerance}")
    return Requirement(component, grade, limits)


def _limits(name: str, value: Any, key: str) -> tuple:
    """Three limits, checked as ``[tolerances]`` checks them."""
    try:
        return Tolerances.from_dict({name: value}).limits(name)
    except FidelityError as exc:
        raise SpecError(str(exc).replace(f"tolerances.{name}", key, 1)) from None


# --------------------------------------------------------------------------- the check
@dataclass(frozen=True)
class RequirementResult:
    """One requirement checked against a report.

    Attributes
    ----------
    component : str
        The component, or ``"overall"`` for the spec's overall grade.
    required : str
        The least grade required.
    grade : str or None
        The grade measured; None when not assessed.
    status : str
        ``"pass"``, ``"fail"`` or ``"not assessed"`` (which fails the acceptance too).
    detail : str
        Why: the measure in words and the tolerance of the required grade; or why the
        component was not assessed and what it needs. :attr:`reason` is the whole sentence.
    value : float or None
        The component's value f_i in [0, 1] (the fidelity for ``"overall"``).
    measure : float or None
        The component in its tolerance's unit (:attr:`unit`), as the verdict measured it.
    unit : str or None
        The unit of :attr:`measure` and :attr:`limit`.
    limit : float or None
        The tolerance's limit for the required grade, in :attr:`unit` (None for the worst
        grade, which anything assessed reaches).
    at_most : bool or None
        True when the measure may be at most the limit (a mismatch, a ratio, an error), False
        when at least (a fraction of the ceiling, an absolute NMI or SSIM).
    basis : str or None
        What the limits rest on (:class:`irfidelity.verdict.ComponentVerdict`): "tolerance",
        "range", "peak", "ceiling" or "absolute".
    """

    component: str
    required: str
    grade: str | None
    status: str
    detail: str = ""
    value: float | None = None
    measure: float | None = None
    unit: str | None = None
    limit: float | None = None
    at_most: bool | None = None
    basis: str | None = None

    @property
    def passed(self) -> bool:
        return self.status == PASS

    @property
    def reason(self) -> str:
        """One sentence: "psnr fair, required good: RMS error ...; the tolerance for good is ...",
        or "noise is required but was not assessed: ...; it needs ..."."""
        if self.status == NOT_ASSESSED:
            what = "the overall grade" if self.component == "overall" else self.component
            return f"{what} is required but was not assessed: {self.detail}"
        return f"{self.component} {self.grade}, required {self.required}" + (f": {self.detail}" if self.detail else "")

    @property
    def outcome(self) -> str:
        """Short: "fair (required good)", "not assessed (required good)"."""
        return f"{self.grade or 'not assessed'} (required {self.required})"

    def to_dict(self) -> dict:
        """JSON-ready: ``component``, ``required``, ``grade``, ``status``, ``passed``, ``reason``
        (the whole sentence, in place of ``detail``), ``value``, ``measure``, ``unit``, ``limit``,
        ``at_most``, ``basis``."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "detail"}
        return to_json(fields | {"passed": self.passed, "reason": self.reason})

    def line(self) -> str:
        """One line of the summary: PASS/FAIL, the component, its grade against the required one,
        and the detail."""
        detail = f": {self.detail}" if self.detail else ""
        return f"  {'PASS' if self.passed else 'FAIL'}  {self.component:<10} {self.outcome}{detail}"


@dataclass(frozen=True)
class AcceptanceResult:
    """A report checked against an :class:`Acceptance`.

    Attributes
    ----------
    spec : Acceptance
    passed : bool
        Every requirement and the overall grade (when required) met.
    requirements : tuple of RequirementResult
        One per required component, in the spec's order.
    overall : RequirementResult or None
        The overall grade against the spec's ``grade``.
    reason : str
        "every requirement met (N)", or each requirement not met with its grade ("psnr fair
        (required good); noise not assessed (required good)"); each one's own reason is in
        :attr:`requirements`.
    failed_frames : tuple of int
        A sequence's frames that could not be scored (the result is that of the others).
    """

    spec: Acceptance
    passed: bool
    requirements: tuple
    overall: RequirementResult | None
    reason: str
    failed_frames: tuple = ()

    def __getitem__(self, component: str) -> RequirementResult:
        """The result of one required component (``result["psnr"]``), or ``"overall"``."""
        for r in self.requirements + ((self.overall,) if self.overall else ()):
            if r.component == component:
                return r
        raise KeyError(component)

    def to_dict(self) -> dict:
        """JSON-ready: ``accepted``, ``reason``, ``name``, ``spec`` (its file), ``tolerances``
        (the limits it set), ``grade`` (the overall requirement or None), ``requirements``
        (``{component: RequirementResult.to_dict()}``), ``failed_frames``."""
        return to_json({"accepted": self.passed, "reason": self.reason, "name": self.spec.name,
                        "spec": self.spec.source, "tolerances": self.spec.tolerances,
                        "grade": None if self.overall is None else self.overall.to_dict(),
                        "requirements": {r.component: r.to_dict() for r in self.requirements},
                        "failed_frames": list(self.failed_frames)})

    def summary_lines(self) -> list[str]:
        """The summary: a heading, one line per requirement, ACCEPTED / NOT ACCEPTED."""
        title = self.spec.name or "acceptance"
        where = f" ({self.spec.source})" if self.spec.source else ""
        lines = [f"acceptance: {title}{where}"]
        lines += [r.line() for r in self.requirements + ((self.overall,) if self.overall else ())]
        verdict = "ACCEPTED" if self.passed else "NOT ACCEPTED"
        if self.failed_frames:
            verdict += f" (on the frames scored; {len(self.failed_frames)} failed)"
        return lines + [f"{verdict}: {self.reason}"]


def check(report: Any, spec: Acceptance | Mapping | str | os.PathLike) -> AcceptanceResult:
    """Check a :class:`~irfidelity.FidelityReport` or :class:`~irfidelity.SequenceReport`
    against an acceptance specification.

    Parameters
    ----------
    report : FidelityReport or SequenceReport
        Scored with the spec's tolerances (:meth:`Acceptance.overrides`).
    spec : Acceptance, mapping or path of a TOML file

    Returns
    -------
    AcceptanceResult
        ``passed`` and each requirement's grade, measure and reason; a required component
        that was not assessed fails with the reason it was not and the input it needs.

    Raises
    ------
    SpecError
        A spec that cannot be read, or a report graded with other limits than the spec's or
        with grade names the spec does not use.
    """
    spec = _as_spec(spec)
    names = tuple(report.config.grades.grades)
    _same_grades(spec, names)
    _same_tolerances(report, spec)
    verdicts = (report.verdict or {}).get("components", {})
    results = tuple(_judge(r, report, names, verdicts.get(r.component)) for r in spec.requirements)
    overall = None if spec.grade is None else _judge_overall(spec.grade, report, names)
    judged = results + ((overall,) if overall else ())
    passed = all(r.passed for r in judged)
    reason = (f"every requirement met ({len(judged)})" if passed
              else "; ".join(f"{r.component} {r.outcome}" for r in judged if not r.passed))
    return AcceptanceResult(spec=spec, passed=passed, requirements=results, overall=overall, reason=reason,
                            failed_frames=tuple(getattr(report, "failed", None) or ()))


def _as_spec(spec: Any) -> Acceptance:
    if isinstance(spec, Acceptance):
        return spec
    if isinstance(spec, Mapping):
        return Acceptance.from_dict(spec)
    if isinstance(spec, (str, os.PathLike)):
        return Acceptance.from_toml(spec)
    raise SpecError(f"expected an Acceptance, a mapping or the path of a TOML file; got {type(spec).__name__}")


def _named(spec: Acceptance) -> str:
    return f"the acceptance specification {spec.source}" if spec.source else "the acceptance specification"


def _same_grades(spec: Acceptance, names: tuple) -> None:
    used = [r.grade for r in spec.requirements] + ([spec.grade] if spec.grade else [])
    foreign = [g for g in used if g not in names]
    if foreign:
        raise SpecError(f"{_named(spec)} requires grade {foreign[0]!r}, but the report's grades are "
                        f"{', '.join(names)}")


def _same_tolerances(report: Any, spec: Acceptance) -> None:
    """Refuse a report graded with other limits than the spec's: its grades are not the spec's."""
    used = Tolerances.coerce(report.config.tolerances)
    for name, limits in spec.tolerances.items():
        if not all(math.isclose(a, b, rel_tol=1e-12) for a, b in zip(used.limits(name), limits)):
            raise SpecError(f"the report was graded with {name} = {list(used.limits(name))}, but {_named(spec)} "
                            f"sets {list(limits)}: score with its tolerances (evaluate(..., **spec.overrides(config)) "
                            f"or config=spec.apply(config); the command line's --spec does it)")


def _not_assessed(req: Requirement, report: Any) -> RequirementResult:
    """A required component the report did not grade, with why and what it needs."""
    k = req.component
    why = _plain(report.skipped.get(k) if report.grade is not None else "no frame pair was scored") or "weight 0"
    also = _plain((report.verdict or {}).get("unassessed", {}).get(k))
    if also and also not in why:
        why += f"; {also}"
    needs = _NEEDS[k]
    if report.config.weights[k] <= 0:  # the configured weight (the report's are renormalised)
        weight = "a positive weight (weights=, --weights)"
        needs = weight if k in ("psnr", "nmi", "ssim") else f"{needs}, and {weight}"
    return RequirementResult(k, req.grade, None, NOT_ASSESSED, f"{why}; it needs {needs}")


def _plain(why: str | None) -> str:
    """A skip reason without what the acceptance does not need: its "not assessed" prefix and the
    renormalisation of the other weights."""
    return (why or "").removeprefix("not assessed: ").split("; weight ")[0]


def _verdict_of(k: str, entry: Mapping[str, Any] | None) -> Any:
    """The component's :class:`~irfidelity.verdict.ComponentVerdict` from the report's verdict."""
    from .verdict import ComponentVerdict

    if not isinstance(entry, Mapping):
        return None
    known = {f.name for f in dataclasses.fields(ComponentVerdict)}
    values: dict[str, Any] = {name: tuple(v) if isinstance(v, list) else v for name, v in entry.items()
                              if name in known}
    try:
        return ComponentVerdict(component=k, **values)
    except TypeError:  # a verdict without the fields of this version
        return None


def _unit(k: str, basis: str) -> str:
    if k == "psnr":
        return "RMS error / the scene's range" if basis == "range" else "RMS error / the PSNR peak"
    if k in ("nmi", "ssim"):
        name = k.upper()
        return f"{name} (absolute; no ceiling was measured)" if basis == "absolute" else f"{name} / the ceiling"
    return _UNITS[k]


def _judge(req: Requirement, report: Any, names: tuple, entry: Mapping[str, Any] | None) -> RequirementResult:
    """One requirement: the component's grade against the least grade required."""
    k = req.component
    grade = report.component_grades.get(k)
    if grade is None or k in report.skipped:
        return _not_assessed(req, report)
    verdict = _verdict_of(k, entry)
    level = names.index(req.grade)
    if verdict is None:
        status = PASS if names.index(grade) <= level else FAIL
        return RequirementResult(k, req.grade, grade, status, value=report.components.get(k))
    if req.limits is not None and verdict.basis == "absolute":
        return RequirementResult(k, req.grade, None, NOT_ASSESSED, _no_ceiling(req), value=verdict.value)
    status = PASS if names.index(grade) <= level else FAIL
    last = level >= len(names) - 1
    tail = "any assessed grade meets it" if last else f"the tolerance for {req.grade} is {verdict.limit_text(level)}"
    return RequirementResult(k, req.grade, grade, status, f"{verdict.text}; {tail}",
                             value=verdict.value, measure=verdict.measure, unit=_unit(k, verdict.basis),
                             limit=None if last else verdict.limits[level], at_most=verdict.at_most,
                             basis=verdict.basis)


def _no_ceiling(req: Requirement) -> str:
    return (f"the spec's {req.tolerance} limits are fractions of the ceiling, and no ceiling was measured (the "
            f"calibrated absolute boundaries graded it instead); it needs a second real frame (real_ref=, --real-ref) "
            f"or the real camera's noise (real_noise=, --real-noise), or a sequence")


def _judge_overall(required: str, report: Any, names: tuple) -> RequirementResult:
    """The report's overall grade against the spec's ``grade``."""
    if report.grade is None:
        return RequirementResult("overall", required, None, NOT_ASSESSED, "no frame pair was scored")
    status = PASS if names.index(report.grade) <= names.index(required) else FAIL
    why = (report.verdict or {}).get("reason", "") if status == FAIL else ""  # what set the grade: worth it on a fail
    return RequirementResult("overall", required, report.grade, status, why, value=report.fidelity)
