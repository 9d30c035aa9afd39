"""What the command line writes: the summary, JSON, CSV, HTML, the configuration, and its
one-line messages (naming flags, never Python syntax)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from ..errors import FidelityError
from ..schema import csv_columns
from .parser import flag_for

__all__ = ["UsageError", "write_outputs", "message", "warning_lines"]


class UsageError(Exception):
    """A command-line mistake: printed as one line, exit status 2."""


def message(exc: BaseException) -> str:
    """One line for an error, naming the flag it concerns."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    flag = flag_for(getattr(exc, "option", None))
    if flag is not None and flag not in text:
        text += f" ({flag})"
    return text


def warning_lines(caught: list) -> list[str]:
    return [f"irfidelity: warning: {w.category.__name__}: {message(w.message)}" for w in caught]


def _write_json(data: Any, dest: str) -> None:
    text = json.dumps(data, indent=2, allow_nan=False)
    if dest == "-":
        sys.stdout.write(text + "\n")
    else:
        with open(dest, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")


def _columns(report: Any) -> list[str]:
    return csv_columns(report.components, registered=report.registration is not None)


def _single_row(report: Any) -> list[Any]:
    """The CSV row of a single pair: the columns of a sequence's frame rows."""
    from ..sequence.outcomes import flat_row

    inputs = report.inputs
    shape = inputs.get("shape") or (None, None)
    entry = {"index": 0, "real": inputs.get("real"), "sim": inputs.get("sim"), "rows": shape[0], "cols": shape[1],
             "dtype": inputs.get("dtype"), "error": None, **report.to_dict()}
    return flat_row(entry, _columns(report))


def _write_csv(report: Any, dest: str) -> None:
    from ..sequence.log import csv_line

    with open(dest, "w", newline="", encoding="utf-8") as fh:
        fh.write(csv_line(_columns(report)))
        fh.write(csv_line(_single_row(report)))


def _write_html(report: Any, dest: str, max_bytes: int | None) -> None:
    to_html = getattr(report, "to_html", None)
    if to_html is None:
        raise FidelityError("HTML reports are not available in this installation", option="report")
    to_html(dest, max_bytes=max_bytes)


def _html_budget(a: argparse.Namespace, sequence: bool) -> int | None:
    """The report's memory budget: ``--max-memory`` for a single pair, a worker's share of it
    for a sequence's thumbnails."""
    from ..budget import per_pair

    max_memory = getattr(a, "max_memory", None)
    return per_pair(None, max_memory, getattr(a, "workers", None)) if sequence else max_memory


def write_outputs(report: Any, a: argparse.Namespace, *, sequence: bool) -> None:
    """Every output the arguments ask for; the summary unless JSON goes to stdout."""
    if getattr(a, "json", None) is not None:
        _write_json(report.to_dict(), a.json)
    if getattr(a, "csv", None) is not None and not sequence:
        _write_csv(report, a.csv)
    if getattr(a, "report", None) is not None:
        _write_html(report, a.report, _html_budget(a, sequence))
    if getattr(a, "save_config", None) is not None:
        report.config.save(a.save_config)
    if getattr(a, "json", None) != "-":
        if not sequence and hasattr(a, "real"):
            print(f"real: {a.real}\nsim:  {a.sim}\n")
        print(report.summary_text())
