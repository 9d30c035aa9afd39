"""``irfidelity score REAL SIM``: one pair or two sequences, with the same options as the API."""

from __future__ import annotations

import argparse
import glob
import os
import re
from typing import Any

from ..config import ScoringConfig
from ..errors import FidelityError
from ..frames import MULTIPAGE_EXTENSIONS, FrameSequence, page_chain
from ..fuzzy import Weights
from ..tolerances import parse_tolerance
from .output import UsageError, write_outputs
from .flags import CALIBRATION_FLAGS
from .regions import pair_flags, region_flags, tolerance_flags

__all__ = ["score_command"]

#: Flags that set a ScoringConfig field of the same name.
_CONFIG_FLAGS = ("bits", "peak", "bins", "hist_range", "missing", "nonfinite", "channel", "real_channel",
                 "sim_channel", "edge_channel", "real_edge_channel", "sim_edge_channel", "edge_fit_order", "ifov_mrad",
                 "pixel_pitch_um", "focal_length_mm", "register", "register_method", "register_each", "max_delay",
                 "pair_by", "unit", "temperature_tolerance")


def scoring_config(a: argparse.Namespace, flags: tuple = _CONFIG_FLAGS) -> ScoringConfig:
    """The configuration of ``--config``, ``--weights`` and the ``flags`` that set a field."""
    options: dict[str, Any] = {k: getattr(a, k) for k in flags}
    if a.weights is not None:
        try:
            options["weights"] = Weights.parse(a.weights)
        except FidelityError as exc:
            raise UsageError(f"--weights: {exc}") from None
    config = ScoringConfig.resolve(a.config, **options)
    calibration = dict(getattr(a, "calibration", None) or {})  # (``rank`` has no calibration flags)
    calibration.update({field: getattr(a, dest) for dest, (field, _, _) in CALIBRATION_FLAGS.items()
                        if getattr(a, dest, None) is not None})
    if calibration:
        config = config.replace(calibration={**config.calibration, **calibration})
    tolerance = getattr(a, "tolerance", None)
    return config.replace(tolerances=tolerance_flags(tolerance, config.tolerances)) if tolerance else config


def acceptance_spec(a: argparse.Namespace, config: ScoringConfig) -> tuple[Any, ScoringConfig]:
    """The ``--spec`` acceptance specification (None without one) and ``config`` with its
    tolerances. Read before anything is scored, so that a bad spec costs nothing; a
    ``--tolerance`` that sets other limits than the spec for the same tolerance is refused (the
    spec is the contract: one place says what is accepted)."""
    if getattr(a, "spec", None) is None:
        return None, config
    from ..acceptance import Acceptance

    spec = Acceptance.from_toml(a.spec)
    for text in getattr(a, "tolerance", None) or ():
        name, limits = parse_tolerance(text)  # already checked by scoring_config
        if name in spec.tolerances and limits != spec.tolerances[name]:
            raise UsageError(f"--tolerance {text}: the acceptance specification {a.spec} sets {name} = "
                             f"{list(spec.tolerances[name])}; give the limits in one place")
    return spec, spec.apply(config)


def _is_sequence(path: str) -> bool:
    """A directory, a glob pattern, or a multi-page TIFF or FLIR SEQ (a TIFF whose chain of
    pages breaks too: its readable pages are scored, the break is a failed frame)."""
    if os.path.isdir(path):
        return True
    if not os.path.exists(path):
        return glob.has_magic(path)
    if not path.lower().endswith(MULTIPAGE_EXTENSIONS):
        return False
    pages, broken = page_chain(path)
    return pages > 1 or broken is not None


def _curve(a: argparse.Namespace, side: str, kind: str) -> Any:
    from ..curves import Curve

    given = getattr(a, f"{side}_{kind}")
    if kind == "mtf" and a.__dict__.get(f"{side}_edge") is not None:
        if given is not None:
            raise UsageError(f"give the {side} MTF either as --{side}-mtf or as --{side}-edge, not both")
        given = getattr(a, f"{side}_edge")
    columns, where = getattr(a, f"{side}_{kind}_columns"), getattr(a, f"{side}_{kind}_where")
    if columns is None and where is None:
        return given
    if given is None or not given.lower().endswith((".csv", ".txt", ".tsv", ".dat")):
        flag = f"--{side}-{kind}-columns" if columns is not None else f"--{side}-{kind}-where"
        raise UsageError(f"{flag} selects from a curve CSV given with --{side}-{kind}")
    return Curve.from_csv(given, columns=columns, where=where, name=os.path.basename(given))


def _pages(seq: FrameSequence, spec: str) -> FrameSequence:
    try:
        if ":" in spec:
            bounds = [int(p) if p.strip() else None for p in spec.split(":")]
            if len(bounds) > 3:
                raise ValueError
            return seq[slice(*bounds)]
        return seq.take([int(p) for p in spec.split(",")])
    except ValueError:
        raise UsageError(f"--pages: expected START:STOP[:STEP] or i,j,k (0-based frame positions), "
                         f"got {spec!r}") from None
    except IndexError as exc:
        raise UsageError(f"--pages: {exc}") from None


def _sequence(a: argparse.Namespace, config: ScoringConfig, curves: dict) -> Any:
    from ..sequence import score_sequence

    real: Any = a.real
    sim: Any = a.sim
    if a.pages is not None:
        real = _pages(FrameSequence(a.real, channel=config.real_channel), a.pages)
        sim = _pages(FrameSequence(a.sim, channel=config.sim_channel), a.pages)
    return score_sequence(real, sim, config=config, workers=a.workers, progress=not a.no_progress, csv=a.csv,
                          resume=a.resume, max_memory=a.max_memory, ci=a.ci, mask=a.mask, roi=a.roi, **curves)


def _bars(path: str | None, side: str) -> str | None:
    """A directory of bar frames (checked here: a wrong path is a usage error)."""
    from ..bar_frames import BAR_LIST

    if path is not None and not os.path.isfile(os.path.join(path, BAR_LIST)):
        what = "no such directory" if not os.path.isdir(path) else f"no {BAR_LIST} listing the bar frames in it"
        raise UsageError(f"--{side}-bars {path!r}: {what} (docs/bars.md)")
    return path


def _noise_roi(text: str) -> tuple[int, int, int, int]:
    """``--noise-roi Y0:Y1,X0:X1`` as ``(r0, r1, c0, c1)`` (the recording checks the bounds)."""
    match = re.fullmatch(r"\s*(\d+):(\d+)\s*,\s*(\d+):(\d+)\s*", text)
    if match is None:
        raise UsageError(f"--noise-roi: expected Y0:Y1,X0:X1 (rows, then columns; 0-based, end excluded), "
                         f"got {text!r}")
    r0, r1, c0, c1 = (int(g) for g in match.groups())
    return r0, r1, c0, c1


def _noise(a: argparse.Namespace, config: ScoringConfig, path: str | None, side: str) -> Any:
    """A noise recording as given, or its 3-D noise measured as ``--noise-detrend`` and
    ``--noise-roi`` say."""
    if path is None or (a.noise_detrend is None and a.noise_roi is None):
        return path
    from ..noise import noise3d

    roi = None if a.noise_roi is None else _noise_roi(a.noise_roi)
    channel = config.real_channel if side == "real" else config.sim_channel
    try:
        return noise3d(path, bits=config.bits, channel=channel, detrend=a.noise_detrend, roi=roi)
    except FidelityError as exc:
        raise FidelityError(f"{side} noise recording {path}: {exc}", option=f"{side}_noise") from None


def _curves(a: argparse.Namespace, config: ScoringConfig) -> dict:
    curves = {f"{side}_{kind}": _curve(a, side, kind) for side in ("real", "sim") for kind in ("mtf", "sitf")}
    curves.update(real_noise=_noise(a, config, a.real_noise, "real"),
                  sim_noise=_noise(a, config, a.sim_noise, "sim"))
    curves.update(real_mrtd=_bars(a.real_bars, "real"), sim_mrtd=_bars(a.sim_bars, "sim"))
    for kind in ("mtf", "sitf", "noise", "mrtd"):
        real, sim = curves[f"real_{kind}"], curves[f"sim_{kind}"]
        if (real is None) != (sim is None) and not (kind == "noise" and sim is None):  # alone: the ceiling
            given, absent = ("real", "sim") if sim is None else ("sim", "real")
            alternative = f" (or --{absent}-edge)" if kind == "mtf" else ""
            flag = "bars" if kind == "mrtd" else kind
            raise UsageError(f"the {given} {kind.upper()} needs the {absent} one too: give --{absent}-{flag}"
                             f"{alternative}")
    return curves


def score_command(a: argparse.Namespace) -> tuple[Any, bool, Any]:
    """Score as the arguments say; returns the report, whether it is a sequence's, and its
    :class:`~irfidelity.acceptance.AcceptanceResult` against ``--spec`` (None without one)."""
    spec, config = acceptance_spec(a, scoring_config(a))
    curves = _curves(a, config)
    seq_real, seq_sim = _is_sequence(a.real), _is_sequence(a.sim)
    if seq_real != seq_sim:
        one, other = ("REAL", "SIM") if seq_real else ("SIM", "REAL")
        raise UsageError(f"{one} is a sequence (a directory, glob or multi-page TIFF) but {other} is a single frame "
                         f"({a.real!r} vs {a.sim!r})")
    if seq_real:
        if a.real_ref is not None:
            raise UsageError("--real-ref applies to single pairs; REAL and SIM are sequences (their ceiling is "
                             "measured on consecutive real frames, or from --real-noise)")
        if a.regions is not None:
            raise UsageError("--regions applies to single pairs; REAL and SIM are sequences")
        report = _sequence(a, config, curves)
    else:
        for flag in ("resume", "pages", "ci"):
            if getattr(a, flag):
                raise UsageError(f"--{flag} applies to sequences; REAL and SIM are single frames")
        pair_options = {**pair_flags(a, config.real_channel), **region_flags(a)}
        for name, path in (("REAL", a.real), ("SIM", a.sim)):
            if not os.path.isfile(path):
                raise UsageError(f"{name} {path!r}: no such file")
        from ..evaluation import evaluate

        report = evaluate(a.real, a.sim, config=config, max_bytes=a.max_memory, **curves, **pair_options)
    acceptance = None
    if spec is not None:
        from ..acceptance import check

        acceptance = check(report, spec)
    write_outputs(report, a, sequence=seq_real, acceptance=acceptance)
    return report, seq_real, acceptance
