"""Command line: ``irfidelity score REAL SIM ...`` and ``irfidelity demo`` (DESIGN §3).

Exit status: 0 everything scored; 2 bad usage or input (one line on stderr naming the
file or argument, no traceback); 3 a sequence finished but some frames failed.
"""

from __future__ import annotations

import argparse
import csv as _csv
import glob
import json
import os
import sys
import warnings
from typing import Any, Sequence

from .errors import FidelityError, RangeError, ShapeError

__all__ = ["main"]

EXIT_OK, EXIT_USAGE, EXIT_FAILED_FRAMES = 0, 2, 3


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, no usage dump
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


class _UsageError(Exception):
    pass


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return n


def _bins(text: str) -> int | str:
    if text == "levels":
        return text
    try:
        return _positive_int(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected a positive integer or 'levels', got {text!r}") from None


def _build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="irfidelity",
                description="Fidelity of an infrared camera simulator against the real camera "
                            "(fuzzy-logic framework, Acta Photonica Sinica 41(5):547, 2012).")
    from . import __version__

    p.add_argument("--version", action="version", version=f"irfidelity {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    s = sub.add_parser(
        "score", help="score a simulated frame (or sequence) against the real one",
        description="Score SIM against REAL: components (MTF, SiTF, PSNR, NMI, SSIM), weights, "
                    "fidelity (eq. 15) and fuzzy grade. REAL and SIM are two frame files (PNG, TIFF, "
                    "EXR, .npy), or two directories / glob patterns (a sequence, scored pairwise).",
        epilog="Exit status: 0 scored, 2 bad usage or input, 3 some frames of a sequence failed.")
    s.add_argument("real", metavar="REAL", help="real camera frame (file), or a directory / glob of frames")
    s.add_argument("sim", metavar="SIM", help="simulated frame (file), or a directory / glob of frames")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--bits", type=_positive_int, metavar="N",
                   help="bit depth of integer frames: values must be <= 2^N-1, PSNR peak = 2^N-1")
    g.add_argument("--peak", type=float, metavar="X", help="PSNR peak value (required for float frames)")
    s.add_argument("--channel", metavar="C", help="channel to read from multi-channel files (e.g. EXR 'Y')")
    s.add_argument("--bins", type=_bins, default=256, metavar="N|levels",
                   help="histogram bins for NMI (default 256), or 'levels' (one bin per grey level)")
    s.add_argument("--weights", default="balanced", metavar="SPEC",
                   help="balanced (default, 1/5 each) | performance | image_quality | "
                        "'mtf=..,sitf=..,psnr=..,nmi=..,ssim=..' (unnamed components 0; sum 1)")
    s.add_argument("--real-mtf", metavar="CSV", help="real camera MTF curve (two columns: frequency, MTF); "
                        "with sequences, the curves count for every frame")
    s.add_argument("--sim-mtf", metavar="CSV", help="simulated camera MTF curve")
    s.add_argument("--real-edge", metavar="IMG", help="real slanted-edge image (MTF by ISO 12233 e-SFR)")
    s.add_argument("--sim-edge", metavar="IMG", help="simulated slanted-edge image")
    s.add_argument("--edge-channel", metavar="C", help="channel to read from multi-channel edge images (e.g. R)")
    s.add_argument("--real-sitf", metavar="CSV", help="real camera SiTF curve (two columns: dT, signal)")
    s.add_argument("--sim-sitf", metavar="CSV", help="simulated camera SiTF curve")
    s.add_argument("--missing", choices=("raise", "renormalize"), default="renormalize",
                   help="a weighted component without inputs: drop it and renormalise the other weights "
                        "(default here; shown as skipped) or fail (raise)")
    s.add_argument("--json", metavar="PATH|-", help="write the report as JSON to PATH, or to stdout with '-'")
    s.add_argument("--csv", metavar="PATH", help="write the scores as CSV (sequences: one row per frame)")
    s.add_argument("--resume", action="store_true", help="sequences: skip frames already in the --csv file")
    s.add_argument("--workers", type=_positive_int, metavar="N", help="sequences: parallel workers")
    s.add_argument("--no-progress", action="store_true", help="sequences: no progress bar")

    d = sub.add_parser(
        "demo", help="score a toy simulator on bundled real infrared data",
        description="Scores a simulated frame made by a simple camera model (Gaussian blur, gain/offset, "
                    "seeded noise) against a real FLIR Lepton frame, a blurred slanted-edge crop against "
                    "the real crop (MTF), and a Planck in-band model against a measured Jade LWIR "
                    "calibration (SiTF). No arguments needed.")
    d.add_argument("--json", metavar="PATH|-", help="also write the report as JSON to PATH, or only JSON to stdout with '-'")
    return p


def _is_sequence(path: str) -> bool:
    if os.path.isdir(path):
        return True
    return glob.has_magic(path) and not os.path.exists(path)


def _write_json(data: Any, dest: str) -> None:
    text = json.dumps(data, indent=2, allow_nan=False)
    if dest == "-":
        sys.stdout.write(text + "\n")
    else:
        with open(dest, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")


def _write_csv(report: Any, real: str, sim: str, dest: str) -> None:
    from .fuzzy import COMPONENTS

    d = report.to_dict()
    row: dict[str, Any] = {"real": real, "sim": sim, "fidelity": d["fidelity"], "grade": d["grade"]}
    for k in COMPONENTS:
        row[f"f_{k}"] = d["components"].get(k, "")
    for k in COMPONENTS:
        row[f"k_{k}"] = d["weights"][k]
    for k, v in d["metrics"].items():
        row[k] = v
    with open(dest, "w", newline="", encoding="utf-8") as fh:
        w = _csv.DictWriter(fh, fieldnames=list(row))
        w.writeheader()
        w.writerow(row)


def _warn_lines(caught: list) -> None:
    for wm in caught:
        msg = " ".join(str(wm.message).split())
        print(f"irfidelity: warning: {wm.category.__name__}: {msg}", file=sys.stderr)


def _score(a: argparse.Namespace) -> int:
    from .evaluation import evaluate, plan_components
    from .fuzzy import Weights

    try:
        weights = Weights.parse(a.weights)
    except FidelityError as exc:
        raise _UsageError(f"--weights: {exc}") from None
    for r_opt, s_opt in (("real_mtf", "sim_mtf"), ("real_edge", "sim_edge"), ("real_sitf", "sim_sitf")):
        if (getattr(a, r_opt) is None) != (getattr(a, s_opt) is None):
            given, absent = (r_opt, s_opt) if getattr(a, s_opt) is None else (s_opt, r_opt)
            raise _UsageError(f"--{given.replace('_', '-')} needs --{absent.replace('_', '-')}")
    if a.real_mtf is not None and a.real_edge is not None:
        raise _UsageError("give the MTF either as curves (--real-mtf/--sim-mtf) or as edges "
                          "(--real-edge/--sim-edge), not both")
    seq_r, seq_s = _is_sequence(a.real), _is_sequence(a.sim)
    if seq_r != seq_s:
        one, other = ("REAL", "SIM") if seq_r else ("SIM", "REAL")
        raise _UsageError(f"{one} is a directory/glob but {other} is a single file "
                          f"({a.real if seq_r else a.sim!r} vs {a.sim if seq_r else a.real!r})")

    real_mtf = a.real_mtf if a.real_mtf is not None else a.real_edge
    sim_mtf = a.sim_mtf if a.sim_mtf is not None else a.sim_edge
    if seq_r:
        w_eff, _, skipped = plan_components(weights, have_images=True, have_mtf=real_mtf is not None,
                                            have_sitf=a.real_sitf is not None, missing=a.missing)
        dropped = [k for k, why in skipped.items() if why != "weight 0"]
        if dropped and a.json != "-":
            print(f"irfidelity: note: {', '.join(dropped)} not scored (no curves given); "
                  f"weights renormalised to {w_eff}", file=sys.stderr)
        try:
            from .sequence import score_sequence
        except ImportError as exc:
            raise _UsageError(f"sequence scoring is not available in this installation ({exc})") from None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            rep = score_sequence(a.real, a.sim, weights=w_eff, bits=a.bits, peak=a.peak, bins=a.bins,
                                 channel=a.channel, workers=a.workers, progress=not a.no_progress,
                                 csv=a.csv, resume=a.resume, real_mtf=real_mtf, sim_mtf=sim_mtf,
                                 real_sitf=a.real_sitf, sim_sitf=a.sim_sitf, edge_channel=a.edge_channel)
        _warn_lines(caught)
        if a.json is not None:
            _write_json(rep.to_dict(), a.json)
        if a.json != "-":
            print(rep.summary_text())
        return EXIT_FAILED_FRAMES if rep.failed else EXIT_OK

    for opt, path in (("REAL", a.real), ("SIM", a.sim)):
        if not os.path.isfile(path):
            what = "is a directory" if os.path.isdir(path) else "no such file"
            raise _UsageError(f"{opt} {path!r}: {what}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            rep = _evaluate_pair(evaluate, a, weights, real_mtf, sim_mtf)
        except (ShapeError, RangeError) as exc:  # name the files, not just "real"/"sim"
            raise _UsageError(f"REAL {a.real!r} / SIM {a.sim!r}: {' '.join(str(exc).split())}") from None
    _warn_lines(caught)
    if a.json is not None:
        _write_json(rep.to_dict(), a.json)
    if a.csv is not None:
        _write_csv(rep, a.real, a.sim, a.csv)
    if a.json != "-":
        print(f"real: {a.real}\nsim:  {a.sim}\n")
        print(rep.summary_text())
    return EXIT_OK


def _evaluate_pair(evaluate: Any, a: argparse.Namespace, weights: Any, real_mtf: Any, sim_mtf: Any) -> Any:
    return evaluate(a.real, a.sim, real_mtf=real_mtf, sim_mtf=sim_mtf, real_sitf=a.real_sitf,
                    sim_sitf=a.sim_sitf, weights=weights, bits=a.bits, peak=a.peak, bins=a.bins,
                    missing=a.missing, channel=a.channel, edge_channel=a.edge_channel)


def _demo(a: argparse.Namespace) -> int:
    from .demo import run_demo

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rep = run_demo(out=None if a.json == "-" else print)
    _warn_lines(caught)
    if a.json is not None:
        _write_json(rep.to_dict(), a.json)
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0, 2 or 3)."""
    parser = _build_parser()
    try:
        a = parser.parse_args(argv)
    except SystemExit as exc:  # --help / --version (0) or usage errors (2)
        return int(exc.code or 0) if not isinstance(exc.code, str) else EXIT_USAGE
    if a.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    try:
        return _score(a) if a.command == "score" else _demo(a)
    except _UsageError as exc:
        print(f"irfidelity {a.command}: error: {exc}", file=sys.stderr)
    except (FidelityError, OSError, ValueError) as exc:
        msg = " ".join(str(exc).split()) or type(exc).__name__
        print(f"irfidelity {a.command}: error: {msg}", file=sys.stderr)
    except KeyboardInterrupt:
        print("irfidelity: interrupted", file=sys.stderr)
        return 130
    return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
