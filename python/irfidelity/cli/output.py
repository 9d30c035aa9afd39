"""What the command line writes: the summary, JSON, CSV, HTML, the configuration, and its
one-line messages (naming flags, never Python syntax)."""

from __future__ import annotations

import argparse
import glob
import json
import os
import re
import sys
from typing import Any

from ..errors import FidelityError
from ..regions import region_columns, region_values
from ..schema import csv_columns
from .flags import flag_for

__all__ = ["UsageError", "write_outputs", "write_json", "message", "warning_lines"]


class UsageError(Exception):
    """A command-line mistake: printed as one line, exit status 2."""


def message(exc: BaseException, a: argparse.Namespace | None = None) -> str:
    """One line for an error, naming the flag it concerns, in the command line's words (the
    library's messages name keyword arguments and numpy calls)."""
    text = cli_wording(" ".join(str(exc).split()) or type(exc).__name__, a)
    flag = flag_for(getattr(exc, "option", None))
    if flag is not None and flag not in text:
        text += f" ({flag})"
    return text


def warning_lines(caught: list, a: argparse.Namespace | None = None) -> list[str]:
    """The warnings for stderr, less those the summary on stdout already printed as notes."""
    shown: set[str] = getattr(a, "shown_notes", set())
    return [f"irfidelity: warning: {w.category.__name__}: {message(w.message, a)}" for w in caught
            if f"{w.category.__name__}: {w.message}" not in shown]


#: Which channel flags decode each input's files: (arguments holding paths, flags).
_CHANNEL_FLAGS = (
    (("real_mtf", "real_edge"), "--real-edge-channel (or --edge-channel for both edge images)"),
    (("sim_mtf", "sim_edge"), "--sim-edge-channel (or --edge-channel for both edge images)"),
    (("real", "real_noise", "real_bars"), "--real-channel (or --channel for both sides)"),
    (("sim", "sim_noise", "sim_bars"), "--sim-channel (or --channel for both sides)"),
)
_ANY_CHANNEL = "--channel (or --real-channel / --sim-channel; --edge-channel for edge images)"

#: The library's advice for dtypes, as the command line gives it (the files are what to change).
_DTYPE_ADVICE = {
    "(e.g. sim.astype(real.dtype))": "(write the simulated frames in the real frames' sample type)",
    "convert one so no silent rounding happens": "write the simulated frames in the real frames' sample type so no "
                                                 "silent rounding happens",
}


#: The noise analysis's and the statistics' advice, as the command line gives it.
_NOISE_ADVICE = {
    "pass nonfinite='mask'": "pass --nonfinite mask",
    "pass detrend='plane'": "pass --noise-detrend plane",
    "with roi=(r0, r1, c0, c1)": "with --noise-roi Y0:Y1,X0:X1",
}


def _literal_part(path: str) -> str:
    """What the name of a file an input holds starts with: the path, or a glob's directory."""
    if not glob.has_magic(path):
        return path
    return os.path.dirname(re.split(r"[*?\[]", path, maxsplit=1)[0])


def _channel_flags(text: str, a: argparse.Namespace | None) -> str:
    """The channel flags of the input whose file the message names (the longest match)."""
    best, flags = 0, _ANY_CHANNEL
    for names, side_flags in _CHANNEL_FLAGS:
        for name in names:
            path = getattr(a, name, None)
            where = _literal_part(path) if isinstance(path, str) else ""
            if where and where in text and len(where) > best:
                best, flags = len(where), side_flags
    return flags


def cli_wording(text: str, a: argparse.Namespace | None = None) -> str:
    """``text`` with the library's keyword-argument advice replaced by the flags to use."""
    if "channel=..." in text:
        text = text.replace("channel=...", _channel_flags(text, a))
    for api, cli in (_DTYPE_ADVICE | _NOISE_ADVICE).items():
        text = text.replace(api, cli)
    return text


def write_json(data: Any, dest: str) -> None:
    """``data`` as indented JSON to ``dest``, or to stdout with ``"-"``."""
    text = json.dumps(data, indent=2, allow_nan=False)
    if dest == "-":
        sys.stdout.write(text + "\n")
    else:
        with open(dest, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")


def _columns(report: Any) -> list[str]:
    return csv_columns(report.components, registered=report.registration is not None,
                       temperature=report.config.unit is not None)


def _single_row(report: Any) -> list[Any]:
    """The CSV row of a single pair: the columns of a sequence's frame rows."""
    from ..sequence.outcomes import flat_row

    inputs = report.inputs
    shape = inputs.get("shape") or (None, None)
    entry = {"index": 0, "real": inputs.get("real"), "sim": inputs.get("sim"), "rows": shape[0], "cols": shape[1],
             "dtype": inputs.get("dtype"), "error": None, **report.to_dict()}
    return flat_row(entry, _columns(report)) + region_values(getattr(report, "regions", None) or {})


def _write_csv(report: Any, dest: str) -> None:
    from ..sequence.log import csv_line

    with open(dest, "w", newline="", encoding="utf-8") as fh:
        fh.write(csv_line(_columns(report) + region_columns(getattr(report, "regions", None) or {})))
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


def write_outputs(report: Any, a: argparse.Namespace, *, sequence: bool, acceptance: Any = None) -> None:
    """Every output the arguments ask for; the summary unless JSON goes to stdout. With an
    ``acceptance`` result (``--spec``), the JSON gains an ``"acceptance"`` block and the summary
    ends with one line per requirement and ACCEPTED / NOT ACCEPTED."""
    if getattr(a, "json", None) is not None:
        data = report.to_dict()
        if acceptance is not None:
            data["acceptance"] = acceptance.to_dict()
        write_json(data, a.json)
    if getattr(a, "csv", None) is not None and not sequence:
        _write_csv(report, a.csv)
    if getattr(a, "report", None) is not None:
        _write_html(report, a.report, _html_budget(a, sequence))
    if getattr(a, "save_config", None) is not None:
        report.config.save(a.save_config)
    if getattr(a, "json", None) != "-":
        if not sequence and hasattr(a, "real"):
            print(f"real: {a.real}\nsim:  {a.sim}\n")
        print(cli_wording(report.summary_text(), a))
        if acceptance is not None:
            print("\n" + cli_wording("\n".join(acceptance.summary_lines()), a))
        a.shown_notes = set(getattr(report, "notes", ()))
