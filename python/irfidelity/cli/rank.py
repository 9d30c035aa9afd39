"""``irfidelity rank REAL SIM_A SIM_B ...`` (several simulators against one real recording, in
one pass, ranked with significance) and ``irfidelity weights fit JUDGEMENTS.csv`` (component
weights learned from experts' preferences)."""

from __future__ import annotations

import argparse
import os
from typing import Any

from ..config import PAIRING_RULES, ScoringConfig
from ..errors import FidelityError
from ..fuzzy import Weights
from ..judgements import DEFAULT_PRIOR_STRENGTH
from .output import UsageError, write_json
from .score import scoring_config

__all__ = ["add_rank", "add_weights", "rank_command", "weights_command"]

#: Flags of ``rank`` that set a ScoringConfig field of the same name.
_CONFIG_FLAGS = ("bits", "peak", "bins", "pair_by")


def _level(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1), e.g. 0.95; got {text!r}")
    return value


def add_rank(sub: argparse._SubParsersAction, types: dict) -> None:
    """The ``rank`` subcommand (``types``: the argument types of ``score``'s flags)."""
    r = sub.add_parser(
        "rank", help="rank several simulators against one real recording, with significance",
        description="Score every SIM sequence against REAL in one pass (each real frame decoded once), then "
                    "rank the simulators by pooled fidelity: intervals of every component, which differences "
                    "are significant (paired block bootstrap over frames, Holm-corrected) and how sure the "
                    "order is (P(first): frames and weights resampled together). REAL and each SIM are "
                    "directories, glob patterns or multi-page TIFFs.",
        epilog="Exit status: 0 ranked, 2 bad usage or input, 3 ranked but some frames failed.")
    r.add_argument("real", metavar="REAL", help="the real recording: a directory, glob or multi-page TIFF")
    r.add_argument("sims", metavar="SIM", nargs="+", help="two or more simulated recordings of the same run")
    r.add_argument("--names", metavar="A,B,...", help="the simulators' names (default: the SIM paths' base names)")
    r.add_argument("--config", metavar="FILE", help="scoring configuration (TOML or JSON; see 'irfidelity config')")
    r.add_argument("--weights", metavar="SPEC", help="the weights K, as for 'irfidelity score'")
    r.add_argument("--bits", type=types["bits"], metavar="N", help="bit depth of integer frames")
    r.add_argument("--peak", type=types["peak"], metavar="X|range", help="PSNR peak: a number, or 'range'")
    r.add_argument("--bins", type=types["bins"], metavar="N|levels", help="histogram bins for NMI")
    r.add_argument("--pair-by", choices=PAIRING_RULES, help="pair frames by file name or by order")
    r.add_argument("--mask", metavar="PATH", help="score only the pixels where this PNG/NPY/TIFF is non-zero "
                                                  "(on the real frames' grid; every simulator, every frame)")
    r.add_argument("--roi", metavar="Y0:Y1,X0:X1", help="score only this region (rows Y0..Y1-1, columns X0..X1-1)")
    r.add_argument("--level", type=_level, default=0.95, metavar="P",
                   help="confidence level of the intervals and tests (default 0.95)")
    r.add_argument("--resamples", type=types["positive_int"], default=2000, metavar="N",
                   help="bootstrap resamples (default 2000, at least 99)")
    r.add_argument("--no-correction", action="store_true",
                   help="do not correct the p-values for the number of pairs (Holm's method by default)")
    r.add_argument("--json", metavar="PATH|-", help="write the comparison (ranking and every report) as JSON")
    r.add_argument("--csv", metavar="PATH", help="write one row per simulator (values and intervals) as CSV")
    r.add_argument("--report", metavar="PATH", help="write a self-contained HTML comparison report")
    r.add_argument("--frames-csv", metavar="DIR", help="stream each simulator's per-frame rows to DIR/NAME.csv")
    r.add_argument("--resume", action="store_true", help="keep the frames already scored in --frames-csv")
    r.add_argument("--ci", action="store_true", help="also give each simulator's report its own intervals")
    r.add_argument("--workers", type=types["positive_int"], metavar="N", help="parallel workers")
    r.add_argument("--max-memory", type=types["size"], metavar="SIZE",
                   help="memory budget of the run, shared by the workers (as for score). Default: 2 GiB per pair")
    r.add_argument("--max-pixels", type=types["positive_int"], metavar="N",
                   help="decode frames of up to N pixels (default 67108864, one 8192 x 8192 frame)")
    r.add_argument("--no-progress", action="store_true", help="no progress display")


def add_weights(sub: argparse._SubParsersAction) -> None:
    """The ``weights fit`` subcommand."""
    w = sub.add_parser("weights", help="learn the component weights from experts' judgements",
                       description="Component weights K from experts' judgements.")
    actions = w.add_subparsers(dest="action", metavar="ACTION", required=True)
    f = actions.add_parser(
        "fit", help="fit weights to pairwise preferences (a judgement CSV)",
        description="Fit the weights K to experts' pairwise preferences (Bradley-Terry on component "
                    "differences), report the agreement and flag inconsistent experts. JUDGEMENTS is a CSV "
                    "with columns a_<component>, b_<component>, preferred (a or b) and optionally expert "
                    "(docs/ranking.md).")
    f.add_argument("judgements", metavar="JUDGEMENTS", help="the judgement CSV")
    f.add_argument("--prior", metavar="SPEC", help="weights to pull the fit toward (e.g. AHP weights), as --weights")
    f.add_argument("--prior-strength", type=float, default=DEFAULT_PRIOR_STRENGTH, metavar="L",
                   help=f"strength of the pull toward --prior (default {DEFAULT_PRIOR_STRENGTH:g}: a standard "
                        f"deviation of 0.32 per weight; the pull fades as judgements accumulate)")
    f.add_argument("--exclude", metavar="EXPERT,...",
                   help="leave these experts' judgements out of the fit (e.g. one flagged as judging by the "
                        "opposite criterion)")
    f.add_argument("--json", metavar="PATH|-", help="write the fit as JSON to PATH, or to stdout with '-'")
    f.add_argument("--save-config", metavar="PATH", help="write a scoring configuration with the fitted weights")


def _names(a: argparse.Namespace) -> list[str]:
    if a.names is None:
        names = [os.path.basename(os.path.normpath(p)) or p for p in a.sims]
        if len(set(names)) != len(names):
            raise UsageError(f"the SIM paths share base names {names}: give --names A,B,...")
        return names
    names = [n.strip() for n in a.names.split(",")]
    if len(names) != len(a.sims) or not all(names) or len(set(names)) != len(names):
        raise UsageError(f"--names: expected {len(a.sims)} distinct non-empty names separated by commas "
                         f"(one per SIM), got {a.names!r}")
    return names


def rank_command(a: argparse.Namespace) -> Any:
    """Score and rank as the arguments say; returns the comparison."""
    from ..simulators import score_simulators

    if len(a.sims) < 2:
        raise UsageError("rank needs the real recording and at least two simulated ones: REAL SIM_A SIM_B ...")
    if a.resume and a.frames_csv is None:
        raise UsageError("--resume keeps the frames of --frames-csv: give --frames-csv DIR")
    names = _names(a)
    for path in [a.real, *a.sims]:
        if not os.path.exists(path) and not any(ch in path for ch in "*?["):
            raise UsageError(f"{path}: no such file or directory")
    result = score_simulators(a.real, dict(zip(names, a.sims)), config=scoring_config(a, _CONFIG_FLAGS),
                              workers=a.workers, max_memory=a.max_memory, progress=not a.no_progress,
                              csv=a.frames_csv, resume=a.resume,
                              ci=a.ci and a.level, level=a.level, resamples=a.resamples,
                              correction="none" if a.no_correction else "holm", mask=a.mask, roi=a.roi)
    if a.json is not None:
        write_json(result.to_dict(), a.json)
    if a.csv is not None:
        result.to_csv(a.csv)
    if a.report is not None:
        result.to_html(a.report)
    if a.json != "-":
        print(result.summary_text())
        if result.ranking.note is not None:  # the summary printed it: no second copy on stderr
            a.shown_notes = {f"ShortRecordingWarning: {result.ranking.note}"}
    return result


def weights_command(a: argparse.Namespace) -> Any:
    """``weights fit``: fit, print (or write) the result."""
    from ..fuzzy import fit_weights
    from ..judgements import read_judgements

    prior = None
    if a.prior is not None:
        try:
            prior = Weights.parse(a.prior)
        except FidelityError as exc:
            raise UsageError(f"--prior: {exc}") from None
    exclude = None if a.exclude is None else [name.strip() for name in a.exclude.split(",") if name.strip()]
    fit = fit_weights(read_judgements(a.judgements), prior=prior, prior_strength=a.prior_strength, exclude=exclude)
    if a.json is not None:
        write_json(fit.to_dict(), a.json)
    if a.save_config is not None:
        ScoringConfig(weights=fit.weights).save(a.save_config)
    if a.json != "-":
        print(_fit_text(fit))
    return fit


def _fit_text(fit: Any) -> str:
    agreement = fit.agreement
    lines = ["fitted weights: " + ", ".join(f"{k}={fit.weights[k]:.3f}" for k in fit.components),
             f"decisiveness s = {fit.scale:.3g}; Kendall tau {agreement['tau']:.3f}, accuracy "
             f"{agreement['accuracy']:.3f} over {agreement['judgements']} judgements"]
    held_out = agreement.get("held_out_accuracy")
    if held_out is not None:
        lines.append(f"leave-one-expert-out accuracy {held_out:.3f} ({agreement['experts']} experts)")
    if fit.excluded:
        lines.append(f"left out (--exclude): {', '.join(fit.excluded)}")
    for expert, reasons in fit.flagged.items():
        lines.append(f"flagged expert {expert}: {'; '.join(reasons)}")
    if fit.opposed:  # their judgements pull the weights the other way: say so, and how to leave them out
        lines.append(f"OPPOSITE CRITERION: the fitted weights average in the judgements of {', '.join(fit.opposed)}, "
                     f"whom the negated weights predict better; review them, or refit with --exclude "
                     f"{','.join(fit.opposed)}")
    return "\n".join(lines)
