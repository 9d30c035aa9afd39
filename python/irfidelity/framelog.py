"""The per-frame log of a sequence run: one CSV row per frame, streamed and flushed as frames
finish, plus a ``.pairstats`` sidecar with each frame's serialised statistics so that a resumed
run still pools every frame. ``resume`` keeps complete rows that have statistics, drops a partly
written last line and error rows, and refuses a log written with other settings or frames.
"""

from __future__ import annotations

import csv as _csv
import io
import json
import os
import struct
import zlib
from collections.abc import Iterable
from typing import Any

from .errors import FidelityError
from .fuzzy import COMPONENTS, Weights

__all__ = ["FrameLog", "csv_columns", "csv_line", "row_values", "frame_from_row"]

#: Raw metric columns per kernel output (in CSV order).
_METRIC_COLUMNS = {
    "psnr": ("mse", "psnr_db"),
    "ssim": ("ssim", "ssim_luminance", "ssim_contrast", "ssim_structure"),
    "nmi": ("nmi", "mi", "h_real", "h_sim", "h_joint"),
}
_SIDECAR_MAGIC = b"IRFSEQ1\n"
_REC = struct.Struct("<QI")  # index, payload length


def csv_columns(weights: Weights, with_nonfinite: bool) -> list[str]:
    cols = ["index", "real", "sim", "rows", "cols", "dtype", "n"]
    if with_nonfinite:
        cols.append("nonfinite")
    active = [k for k in ("psnr", "ssim", "nmi") if weights[k] > 0]
    for k in active:
        cols.extend(_METRIC_COLUMNS[k])
    # curve components (the same for every frame) too, so each row's fidelity adds up (eq. 15)
    cols.extend(f"f_{k}" for k in COMPONENTS if weights[k] > 0)
    cols += ["fidelity", "error"]
    return cols


def csv_line(values: Iterable[Any]) -> str:
    buf = io.StringIO()
    _csv.writer(buf, lineterminator="\n").writerow(values)
    return buf.getvalue()


def _fmt(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)  # round-trips exactly; inf / nan as "inf" / "nan"
    return str(v)


def row_values(frame: dict, cols: list[str]) -> list[str]:
    comps = frame.get("components") or {}
    out = []
    for c in cols:
        if c.startswith("f_"):
            v = comps.get(c[2:])
        elif c == "error":
            v = frame.get("error")
            v = None if v is None else " ".join(str(v).split())  # one physical line per row
        else:
            v = frame.get(c)
        out.append(_fmt(v))
    return out


_INT_COLS = {"index", "rows", "cols", "n", "nonfinite"}
_STR_COLS = {"real", "sim", "dtype", "error"}


def frame_from_row(row: dict[str, str]) -> dict:
    fr: dict[str, Any] = {}
    comps: dict[str, float] = {}
    for k, v in row.items():
        if k.startswith("f_"):
            if v != "":
                comps[k[2:]] = float(v)
        elif k in _INT_COLS:
            fr[k] = int(v) if v != "" else None
        elif k in _STR_COLS:
            fr[k] = v if v != "" else None
        else:
            fr[k] = float(v) if v != "" else None
    fr["components"] = comps
    fr.setdefault("error", None)
    return fr


class FrameLog:
    """The streamed CSV and its ``.pairstats`` sidecar (statistics for resumed pooling)."""

    def __init__(self, path: str, columns: list[str], settings: dict, resume: bool):
        self.path = path
        self.side = path + ".pairstats"
        self.columns = columns
        self.done_rows: dict[int, dict] = {}
        self.done_stats: dict[int, bytes] = {}
        header = _SIDECAR_MAGIC + json.dumps(settings, sort_keys=True).encode() + b"\n"
        if resume and os.path.exists(path):
            self._load_existing(header)
        else:
            self._start_fresh(header)

    def _start_fresh(self, header: bytes) -> None:
        with open(self.side, "wb") as f:
            f.write(header)
        with open(self.path, "w", newline="", encoding="utf-8") as f:
            f.write(csv_line(self.columns))
        self._open()

    def _open(self) -> None:
        self.csv = open(self.path, "a", newline="", encoding="utf-8")
        self.sidef = open(self.side, "ab")

    def _load_existing(self, header: bytes) -> None:
        # --- the sidecar: settings must match; keep complete records only
        stats: dict[int, bytes] = {}
        try:
            with open(self.side, "rb") as f:
                data = f.read()
        except FileNotFoundError:
            data = b""
        if data:
            if not data.startswith(header):
                raise FidelityError(
                    f"{self.path}: cannot resume: it was written by a run with different settings or frames "
                    f"(see {self.side}); remove both files or use resume=False"
                )
            pos = len(header)
            while pos + _REC.size <= len(data):
                idx, ln = _REC.unpack_from(data, pos)
                end = pos + _REC.size + ln
                if end > len(data):
                    break
                stats[idx] = data[pos + _REC.size : end]
                pos = end
        # --- the CSV: same columns; drop a partly written last line, error rows, rows without stats
        with open(self.path, encoding="utf-8", newline="") as f:
            text = f.read()
        lines = text.split("\n")
        if lines and lines[-1] != "":
            lines = lines[:-1]  # no newline at the end: interrupted mid-write
        lines = [ln for ln in lines if ln != ""]
        if lines:
            head = next(_csv.reader([lines[0]]))
            if head != self.columns:
                raise FidelityError(
                    f"{self.path}: cannot resume: its columns differ from this run's "
                    f"({', '.join(head)} vs {', '.join(self.columns)})"
                )
            for row in _csv.DictReader(lines):
                try:
                    fr = frame_from_row(row)
                except (TypeError, ValueError):
                    continue  # a damaged row: score that frame again
                i = fr.get("index")
                if i is None or fr.get("error") or i not in stats or i in self.done_rows:
                    continue
                self.done_rows[i] = fr
        self.done_stats = {i: stats[i] for i in self.done_rows}
        # rewrite both files atomically with what is kept, then append
        tmp = self.path + ".tmp"
        with open(tmp, "w", newline="", encoding="utf-8") as f:
            f.write(csv_line(self.columns))
            for i in sorted(self.done_rows):
                f.write(csv_line(row_values(self.done_rows[i], self.columns)))
            f.flush()
            os.fsync(f.fileno())
        tmp_side = self.side + ".tmp"
        with open(tmp_side, "wb") as f:
            f.write(header)
            for i in sorted(self.done_stats):
                payload = self.done_stats[i]
                f.write(_REC.pack(i, len(payload)) + payload)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp_side, self.side)
        os.replace(tmp, self.path)
        self._open()

    def write(self, frame: dict, raw_bytes: bytes | None) -> None:
        # statistics first: a CSV row always has its statistics
        if raw_bytes is not None:
            payload = zlib.compress(raw_bytes, 1)
            self.sidef.write(_REC.pack(frame["index"], len(payload)) + payload)
            self.sidef.flush()
        self.csv.write(csv_line(row_values(frame, self.columns)))
        self.csv.flush()

    def close(self) -> None:
        for f in (getattr(self, "csv", None), getattr(self, "sidef", None)):
            if f is not None:
                f.close()
