"""The per-frame log of a sequence run: the CSV a user reads, and what makes resuming safe.

Three files live side by side:

* ``PATH`` — the CSV, one row per frame, appended and flushed as frames finish. When a run
  ends it is rewritten (atomically) with one row per frame in index order. A resume never
  shortens it: rows are only appended until the run ends.
* ``PATH.pairstats`` — the trusted record of each scored frame: its statistics (from which
  its row is recomputed exactly), and a fingerprint of both input files (size, modification
  time, XXH3 of the contents). Every record, and the settings header, carry a CRC-32. On
  resume, a record that is damaged, or whose files changed, is scored again; nothing that
  cannot be trusted is kept, nothing is dropped without being scored again. The CSV text is
  never trusted (an editor may have cut a value), only these records.
* ``PATH.lock`` — held (``flock``) while a run writes the log; a second run on the same CSV
  is refused with a message, instead of interleaving duplicate rows.
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

from ..errors import FidelityError

__all__ = ["FrameLog", "Record", "csv_line"]

_HEADER_MAGIC = b"IRFSEQ2\n"
_RECORD_MAGIC = b"\x00IRF"
_RECORD = struct.Struct("<4sIQII")  # magic, crc32 of the rest, index, meta length, stats length


def csv_line(values: Iterable[Any]) -> str:
    """One CSV line; floats written with repr (they round-trip exactly, inf/nan as such)."""
    buf = io.StringIO()
    _csv.writer(buf, lineterminator="\n").writerow(
        "" if v is None else (repr(v) if isinstance(v, float) else str(v)) for v in values)
    return buf.getvalue()


class Record:
    """A scored frame: its index, what it was computed from (``meta``: input fingerprints,
    shape, sample type) and its statistics' bytes."""

    __slots__ = ("index", "meta", "stats")

    def __init__(self, index: int, meta: dict, stats: bytes):
        self.index, self.meta, self.stats = index, meta, stats

    def encode(self) -> bytes:
        meta = json.dumps(self.meta, separators=(",", ":")).encode()
        payload = zlib.compress(self.stats, 1)
        body = struct.pack("<QII", self.index, len(meta), len(payload)) + meta + payload
        return _RECORD_MAGIC + struct.pack("<I", zlib.crc32(body)) + body


def _decode_records(data: bytes, start: int) -> tuple[dict[int, Record], int]:
    """Records with a valid CRC (the last for an index wins), and how many were damaged."""
    out: dict[int, Record] = {}
    damaged = 0
    pos = start
    while pos + _RECORD.size <= len(data):
        magic, crc, index, meta_len, stats_len = _RECORD.unpack_from(data, pos)
        end = pos + _RECORD.size + meta_len + stats_len
        body = data[pos + 8:end]
        if magic == _RECORD_MAGIC and end <= len(data) and zlib.crc32(body) == crc:
            try:
                meta = json.loads(data[pos + _RECORD.size:pos + _RECORD.size + meta_len])
                out[index] = Record(index, meta, zlib.decompress(data[end - stats_len:end]))
                pos = end
                continue
            except (ValueError, zlib.error):
                pass
        damaged += 1
        nxt = data.find(_RECORD_MAGIC, pos + 1)  # resynchronise on the next record
        pos = nxt if nxt >= 0 else len(data)
    return out, damaged


def _header(settings: dict) -> bytes:
    text = json.dumps(settings, sort_keys=True, separators=(",", ":")).encode()
    return _HEADER_MAGIC + text + b"\n" + b"%08x" % zlib.crc32(text) + b"\n"


def _read_header(data: bytes) -> tuple[dict | None, int]:
    """(settings, end of header), or (None, 0) for a missing or damaged header."""
    if not data.startswith(_HEADER_MAGIC):
        return None, 0
    text_end = data.find(b"\n", len(_HEADER_MAGIC))
    crc_end = data.find(b"\n", text_end + 1)
    if text_end < 0 or crc_end < 0:
        return None, 0
    text = data[len(_HEADER_MAGIC):text_end]
    if data[text_end + 1:crc_end] != b"%08x" % zlib.crc32(text):
        return None, 0
    try:
        return json.loads(text), crc_end + 1
    except ValueError:
        return None, 0


def _differences(old: dict, new: dict) -> str:
    keys = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    return ", ".join(keys) or "none"


class _Lock:
    """An exclusive, non-blocking advisory lock on ``PATH.lock`` (released if the process dies)."""

    def __init__(self, path: str):
        self.path = path
        self.fh = open(path, "a+")
        try:
            import fcntl

            fcntl.flock(self.fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:  # no flock (Windows): no locking
            pass
        except OSError:
            self.fh.seek(0)
            holder = self.fh.read().strip() or "unknown"
            self.fh.close()
            raise FidelityError(f"{path[:-5]}: another irfidelity run (process {holder}) is writing this CSV; "
                                f"wait for it to finish, or write to another CSV", option="csv") from None
        self.fh.seek(0)
        self.fh.truncate()
        self.fh.write(str(os.getpid()))
        self.fh.flush()

    def release(self) -> None:
        self.fh.close()


class FrameLog:
    """The streamed CSV, its trusted ``.pairstats`` records, and the lock (module notes).

    ``trusted`` maps frame index to its :class:`Record` after a resume (before the caller
    checks fingerprints); ``notes`` says what a resume found.
    """

    def __init__(self, path: str, columns: list[str], settings: dict, resume: bool):
        self.path, self.side, self.columns = path, path + ".pairstats", columns
        self.trusted: dict[int, Record] = {}
        self.notes: list[str] = []
        self.lock = _Lock(path + ".lock")
        try:
            header = _header(settings)
            if resume and os.path.exists(self.side):
                self._load(settings)
            self._start(header, fresh_csv=not (resume and os.path.exists(path)))
        except BaseException:
            self.lock.release()
            raise

    def _load(self, settings: dict) -> None:
        with open(self.side, "rb") as fh:
            data = fh.read()
        old, start = _read_header(data)
        if old is None:
            self.notes.append(f"{self.side}: its header is damaged; every frame is scored again")
            return
        if old != settings:
            raise FidelityError(f"{self.path}: cannot resume: it was written with other settings or frames "
                                f"({_differences(old, settings)} differ); score without resuming, or give the "
                                f"same settings", option="resume")
        self.trusted, damaged = _decode_records(data, start)
        if damaged:
            self.notes.append(f"{self.side}: {damaged} damaged record(s); their frames are scored again")

    def _start(self, header: bytes, fresh_csv: bool) -> None:
        tmp = self.side + ".tmp"
        with open(tmp, "wb") as fh:  # the trusted records, rewritten without damaged ones
            fh.write(header)
            fh.writelines(r.encode() for r in self.trusted.values())
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, self.side)
        if fresh_csv:
            with open(self.path, "w", newline="", encoding="utf-8") as fh:
                fh.write(csv_line(self.columns))
        self.csv = open(self.path, "a", newline="", encoding="utf-8")
        self.records = open(self.side, "ab")

    def distrust(self, index: int) -> None:
        """Drop a record whose input files changed (its frame is scored again)."""
        self.trusted.pop(index, None)

    def write(self, row: list[Any], record: Record | None) -> None:
        """Append a frame: its record first (a row always has its record), then its row."""
        if record is not None:
            self.records.write(record.encode())
            self.records.flush()
        self.csv.write(csv_line(row))
        self.csv.flush()

    def finish(self, rows: list[list[Any]]) -> None:
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
        for fh in (getattr(self, "csv", None), getattr(self, "records", None)):
            if fh is not None and not fh.closed:
                fh.close()
        self.lock.release()
