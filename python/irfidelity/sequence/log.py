"""The per-frame log of a sequence run: the CSV a user reads, and what makes resuming safe.

Three files live side by side:

* ``PATH`` — the CSV, one row per frame, appended and flushed as frames finish. When a run
  ends it is rewritten (atomically) with one row per frame in index order. A resume never
  shortens it: rows are only appended until the run ends.
* ``PATH.pairstats`` — the trusted record of each scored frame (:mod:`.sidecar`): its
  statistics (from which its row is recomputed exactly), and a fingerprint of both input
  files, of the bytes that were scored. Every record, and the settings header, carry a
  CRC-32. On resume the file is read one record at a time: a record that is damaged, cannot
  be used, or whose files changed, is scored again; nothing that cannot be trusted is kept,
  nothing is dropped without being scored again. The CSV text is never trusted (an editor may
  have cut a value), only these records.
* ``PATH.lock`` — held while a run writes the log, removed when it ends (:mod:`.lock`); a
  second run on the same CSV is refused with a message, instead of interleaving duplicate
  rows.
"""

from __future__ import annotations

import csv as _csv
import io
import os
from collections.abc import Iterable
from typing import IO, Any

from ..errors import FidelityError
from .lock import Lock
from .sidecar import Limits, Scan, header, read_header, read_record

__all__ = ["FrameLog", "csv_line", "last_records"]


def csv_line(values: Iterable[Any]) -> str:
    """One CSV line; floats written with repr (they round-trip exactly, inf/nan as such)."""
    buf = io.StringIO()
    _csv.writer(buf, lineterminator="\n").writerow(
        "" if v is None else (repr(v) if isinstance(v, float) else str(v)) for v in values)
    return buf.getvalue()


def _differences(old: Any, new: dict) -> str:
    if not isinstance(old, dict):
        return "all"
    keys = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    return ", ".join(keys) or "none"


def _copy(src: IO[bytes], dst: IO[bytes], offset: int, size: int) -> None:
    src.seek(offset)
    while size:
        block = src.read(min(size, 1 << 20))
        if not block:
            raise FidelityError(f"{getattr(src, 'name', 'the log')}: shortened while it was being read")
        dst.write(block)
        size -= len(block)


def last_records(scan: Scan, frames: int) -> tuple[dict[int, tuple[int, int]], int]:
    """``index -> (offset, size)`` of the last intact record of each of ``frames`` frames, and
    how many intact records are of other indices."""
    last = {index: (offset, size) for offset, size, index in scan}
    ours = {index: where for index, where in last.items() if index < frames}
    return ours, len(last) - len(ours)


class FrameLog:
    """The streamed CSV, its ``.pairstats`` records, and the lock (module notes).

    After a resume, ``kept`` maps a frame index (below ``frames``) to where its last intact
    record lies in the rewritten ``.pairstats`` (``(offset, size)``; read it with
    :meth:`read`); nothing of a record is held in memory. ``foreign`` counts intact records of
    frames the run does not have (dropped); ``notes`` says what else the resume found.
    """

    def __init__(self, path: str, columns: list[str], settings: dict, resume: bool, limits: Limits,
                 frames: int):
        self.path, self.side, self.columns, self.limits = path, path + ".pairstats", columns, limits
        self.frames = frames
        self.kept: dict[int, tuple[int, int]] = {}
        self.foreign = 0
        self.notes: list[str] = []
        self.lock = Lock(path + ".lock")
        try:
            self._start(header(settings), settings, resume and os.path.exists(self.side))
            if not (resume and os.path.exists(path)):
                with open(path, "w", newline="", encoding="utf-8") as fh:
                    fh.write(csv_line(columns))
            # held open for the run, closed by close()
            self.csv = open(path, "a", newline="", encoding="utf-8")  # noqa: SIM115
            self.records = open(self.side, "ab")  # noqa: SIM115
            self.reader = open(self.side, "rb")  # noqa: SIM115
        except BaseException:
            self.close()
            raise

    def _start(self, head: bytes, settings: dict, resume: bool) -> None:
        """Write the new ``.pairstats``: the header, then (resuming) every intact record of the
        old one, the last of each frame, copied record by record."""
        tmp = self.side + ".tmp"
        with open(tmp, "wb") as out:
            out.write(head)
            if resume:
                with open(self.side, "rb") as old:
                    self._carry_over(old, out, settings, len(head))
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, self.side)

    def _carry_over(self, old: IO[bytes], out: IO[bytes], settings: dict, start: int) -> None:
        found, end = read_header(old)
        if found is None or found == "other version":
            why = "its header is damaged" if found is None else "it was written by another version of irfidelity"
            self.notes.append(f"{self.side}: {why}; every frame is scored again")
            return
        if found != settings:
            raise FidelityError(f"{self.path}: cannot resume: it was written with other settings or frames "
                                f"({_differences(found, settings)} differ); score without resuming, or give the "
                                f"same settings", option="resume")
        scan = Scan(old, end, self.limits)
        last, self.foreign = last_records(scan, self.frames)
        for index, (offset, size) in sorted(last.items(), key=lambda item: item[1]):
            self.kept[index] = (start, size)
            _copy(old, out, offset, size)
            start += size
        if scan.damaged:
            self.notes.append(f"{self.side}: {scan.damaged} damaged record(s); their frames are scored again")

    def read(self, where: tuple[int, int]) -> tuple[int, Any, bytes]:
        """``(index, meta, payload)`` of a kept record (:func:`.sidecar.read_record`)."""
        return read_record(self.reader, where[0], where[1], self.limits)

    def write(self, row: list[Any], record: bytes | None) -> None:
        """Append a frame: its record first (a row always has its record), then its row."""
        if record is not None:
            self.records.write(record)
            self.records.flush()
        self.csv.write(csv_line(row))
        self.csv.flush()

    def finish(self, rows: Iterable[list[Any]]) -> None:
        """The run ended: rewrite the CSV with exactly these rows (one per frame, in order)."""
        self.csv.close()
        tmp = self.path + ".tmp"
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            fh.write(csv_line(self.columns))
            fh.writelines(csv_line(r) for r in rows)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, self.path)

    def close(self) -> None:
        for name in ("csv", "records", "reader"):
            fh = getattr(self, name, None)
            if fh is not None and not fh.closed:
                fh.close()
        self.lock.release()

