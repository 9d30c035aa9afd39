"""Command line: ``irfidelity score REAL SIM ...``, ``irfidelity rank REAL SIM...``, ``irfidelity
weights fit FILE``, ``irfidelity demo``, ``irfidelity config``, ``irfidelity targets OUT``.

Exit status: 0 everything scored (and accepted, with ``score --spec``); 2 bad usage or input
(one line on stderr naming the file or flag, no traceback; a bad acceptance specification
too); 3 a sequence finished but some frames failed (before 4: the acceptance then covers only
the frames scored); 4 scored, but not accepted by the ``--spec`` acceptance specification.
"""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections.abc import Sequence

from ..errors import FidelityError
from .output import UsageError, message, warning_lines, write_outputs
from .parser import EXIT_FAILED_FRAMES, EXIT_NOT_ACCEPTED, EXIT_OK, EXIT_USAGE, build_parser

__all__ = ["main"]


def _demo(a) -> int:
    from ..demo import run_demo

    report = run_demo(out=None if a.json == "-" else print)
    if a.json != "-":
        from ..demo import run_radiometric_demo

        print()
        run_radiometric_demo()
    a.save_config = None
    write_outputs(report, a, sequence=False) if (a.json or a.report) else None
    return EXIT_OK


def _config(a) -> int:
    from ..config import ScoringConfig

    if a.path is None:
        sys.stdout.write(ScoringConfig().to_toml())
    else:
        ScoringConfig().save(a.path)
    return EXIT_OK


def _pixel_limit(a) -> contextlib.AbstractContextManager:
    """``--max-pixels`` for every decode of the command."""
    from .. import budget

    limit = getattr(a, "max_pixels", None)
    return contextlib.nullcontext() if limit is None else budget.pixel_limit(limit)


def _run(a) -> int:
    if a.command == "score":
        from .score import score_command

        report, sequence, acceptance = score_command(a)
        if sequence and report.failed:
            return EXIT_FAILED_FRAMES
        return EXIT_NOT_ACCEPTED if acceptance is not None and not acceptance.passed else EXIT_OK
    if a.command in ("rank", "weights"):
        from .rank import rank_command, weights_command

        if a.command == "weights":
            weights_command(a)
            return EXIT_OK
        result = rank_command(a)
        return EXIT_FAILED_FRAMES if any(rep.failed for rep in result.reports.values()) else EXIT_OK
    if a.command == "targets":
        from .targets import targets_command

        targets_command(a)
        return EXIT_OK
    return _demo(a) if a.command == "demo" else _config(a)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0, 2, 3 or 4: the module notes)."""
    parser = build_parser()
    try:
        a = parser.parse_args(argv)
    except SystemExit as exc:  # --help / --version (0) or usage errors (2)
        return int(exc.code or 0) if not isinstance(exc.code, str) else EXIT_USAGE
    if a.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with _pixel_limit(a):
                return _run(a)
        except (UsageError, FidelityError, OSError, ValueError, OverflowError) as exc:
            print(f"irfidelity {a.command}: error: {message(exc, a)}", file=sys.stderr)
            return EXIT_USAGE
        except KeyboardInterrupt:
            print("irfidelity: interrupted", file=sys.stderr)
            return 130
        finally:
            for line in warning_lines(caught, a):
                print(line, file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
