"""The ``.pairstats`` file: a settings header, then one record per scored frame.

Layout::

    IRFSEQ3\\n  settings JSON \\n  CRC-32 of the JSON as 8 hex digits \\n
    record*

    record = b"\\0IRF", CRC-32 (of the rest), index (u64), meta length (u32),
             payload length (u32), meta (JSON), payload           -- little-endian

The payload holds a frame's :meth:`PairStats.to_bytes` with its zero 8-byte words left out:
``zlib(length (u64) + bitmap of the non-zero words + the non-zero words)``. A frame's joint
histogram is mostly empty cells, so this is small and fast to pack and unpack.

The file is read one record at a time, and nothing in it is believed before it is checked:
lengths are bounded before anything is read (:class:`Limits`), the CRC is computed over the
record in blocks, decompression stops at the largest size a real record can have, and a
record that fails any check is :class:`BadRecord` (a CRC failure is *damage*, from which the
reader resynchronises on the next record's magic; a record with a valid CRC whose contents
cannot be used is the caller's to count).
"""

from __future__ import annotations

import json
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import IO, Any

import numpy as np

__all__ = ["BadRecord", "Limits", "Scan", "encode_record", "header", "read_header", "read_record",
           "max_stats_size", "pack_stats", "unpack_stats"]

HEADER_MAGIC = b"IRFSEQ3\n"
RECORD_MAGIC = b"\x00IRF"
RECORD = struct.Struct("<4sIQII")  # magic, crc32 of the rest, index, meta length, payload length
_LENGTH = struct.Struct("<Q")
MAX_HEADER = 1 << 20  # the settings JSON: the config, columns and plan (a few kB)
MAX_META = 1 << 16  # a record's meta: fingerprints, shape, extent, registration (under 1 kB)
_BLOCK = 1 << 20  # read and checksum in blocks of this size


class BadRecord(ValueError):
    """A record (or payload) that cannot be trusted; the message says why."""


# --------------------------------------------------------------------------- sizes
_STATS_FIXED = 256  # PairStats.to_bytes without its histogram cells: magic, counts, sums, specs (168)
_DENSE_MAX_BINS = 512  # the kernel stores up to this many bins (or levels) per axis densely


def max_stats_size(bins: int | None, levels: int | None, pixels: int) -> int:
    """The largest :meth:`PairStats.to_bytes` of a frame of ``pixels`` pixels whose joint
    histogram has ``bins`` bins or one bin per grey level of ``levels`` (neither: no
    histogram). Dense tables hold 8 bytes per cell; sparse ones 16 bytes per occupied cell, at
    most one per pixel."""
    cells = bins if bins is not None else levels
    if cells is None:
        return _STATS_FIXED
    dense = 8 * min(cells, _DENSE_MAX_BINS) ** 2
    sparse = 16 * min(cells * cells, pixels) if cells > _DENSE_MAX_BINS else 0
    return _STATS_FIXED + max(dense, sparse)


def _packed_size(stats_size: int) -> int:
    words = -(-stats_size // 8)
    return _LENGTH.size + -(-words // 8) + 8 * words


def _zlib_bound(size: int) -> int:
    """zlib's compressBound: the most ``zlib.compress`` can make of ``size`` bytes."""
    return size + (size >> 12) + (size >> 14) + (size >> 25) + 13


@dataclass(frozen=True)
class Limits:
    """What a record of this run may hold: ``max_stats`` bytes of statistics at most (the
    payload follows from it)."""

    max_stats: int

    @property
    def max_payload(self) -> int:
        return _zlib_bound(_packed_size(self.max_stats))


# --------------------------------------------------------------------------- payload
def pack_stats(stats: bytes) -> bytes:
    """The payload of a record: ``stats`` with its zero words left out, compressed."""
    padded = stats + b"\0" * (-len(stats) % 8)
    words = np.frombuffer(padded, dtype="<u8")
    nonzero = words != 0
    body = b"".join((_LENGTH.pack(len(stats)), np.packbits(nonzero, bitorder="little").tobytes(),
                     words[nonzero].tobytes()))
    return zlib.compress(body, 1)


def unpack_stats(payload: bytes | bytearray, max_stats: int) -> bytes:
    """The statistics' bytes of a payload; :class:`BadRecord` when it is not a payload of at
    most ``max_stats`` bytes (decompression stops there: a zlib bomb costs nothing)."""
    inflater = zlib.decompressobj()
    limit = _packed_size(max_stats)
    try:
        body = inflater.decompress(payload, limit + 1)
    except zlib.error as exc:
        raise BadRecord(f"statistics do not decompress ({exc})") from None
    if len(body) > limit or inflater.unconsumed_tail:
        raise BadRecord(f"statistics larger than the {max_stats} bytes a frame of this run can have")
    if not inflater.eof or inflater.unused_data:
        raise BadRecord("statistics are cut short or followed by other data")
    if len(body) < _LENGTH.size:
        raise BadRecord("statistics without their length")
    (size,) = _LENGTH.unpack_from(body)
    if size > max_stats:
        raise BadRecord(f"statistics of {size} bytes, beyond the {max_stats} a frame of this run can have")
    count = -(-size // 8)
    bitmap_end = _LENGTH.size + -(-count // 8)
    if len(body) < bitmap_end:
        raise BadRecord("statistics cut short")
    bits = np.unpackbits(np.frombuffer(body, np.uint8, bitmap_end - _LENGTH.size, _LENGTH.size),
                         bitorder="little")
    nonzero = bits[:count].astype(bool)
    if bits[count:].any() or len(body) != bitmap_end + 8 * int(np.count_nonzero(nonzero)):
        raise BadRecord("statistics whose word map does not match their words")
    values = np.frombuffer(body, "<u8", offset=bitmap_end)
    if not values.all():
        raise BadRecord("statistics with a zero word stored as non-zero")
    words = np.zeros(count, dtype="<u8")
    words[nonzero] = values
    out = words.tobytes()
    if any(out[size:]):
        raise BadRecord("statistics with data past their length")
    return out[:size]


# --------------------------------------------------------------------------- header
def header(settings: dict) -> bytes:
    """The header of a log written with ``settings``."""
    text = json.dumps(settings, sort_keys=True, separators=(",", ":")).encode()
    return HEADER_MAGIC + text + b"\n" + b"%08x" % zlib.crc32(text) + b"\n"


def read_header(fh: IO[bytes]) -> tuple[Any, int]:
    """(settings, end of header) read from the start of ``fh``; (None, 0) for a missing or
    damaged header, ("other version", 0) for a log of another format."""
    fh.seek(0)
    head = fh.read(MAX_HEADER + 32)
    if not head.startswith(HEADER_MAGIC):
        return ("other version" if head.startswith(HEADER_MAGIC[:6]) else None), 0
    text_end = head.find(b"\n", len(HEADER_MAGIC))
    crc_end = head.find(b"\n", text_end + 1) if text_end >= 0 else -1
    if crc_end < 0:
        return None, 0
    text = head[len(HEADER_MAGIC):text_end]
    if head[text_end + 1:crc_end] != b"%08x" % zlib.crc32(text):
        return None, 0
    try:
        return json.loads(text), crc_end + 1
    except (ValueError, RecursionError):
        return None, 0


# --------------------------------------------------------------------------- records
def encode_record(index: int, meta: dict, stats: bytes) -> bytes:
    """One record: frame ``index``, its ``meta`` (JSON-ready) and statistics' bytes."""
    text = json.dumps(meta, separators=(",", ":")).encode()
    payload = pack_stats(stats)
    body = struct.pack("<QII", index, len(text), len(payload)) + text + payload
    return RECORD_MAGIC + struct.pack("<I", zlib.crc32(body)) + body


def _checked_size(head: bytes, limits: Limits) -> int | None:
    """The size of the record whose fixed part is ``head``, if its magic and lengths can be
    those of a record of this run."""
    magic, _, _, meta_len, payload_len = RECORD.unpack(head)
    if magic != RECORD_MAGIC or meta_len > MAX_META or payload_len > limits.max_payload:
        return None
    return RECORD.size + meta_len + payload_len


def _crc_matches(fh: IO[bytes], start: int, size: int) -> bool:
    """Whether the record of ``size`` bytes at ``start`` is whole and its CRC matches (read in
    blocks: a record is never held whole to check it)."""
    fh.seek(start)
    head = fh.read(RECORD.size)
    crc = zlib.crc32(head[8:])
    left = size - RECORD.size
    while left:
        block = fh.read(min(left, _BLOCK))
        if not block:
            return False
        crc = zlib.crc32(block, crc)
        left -= len(block)
    return crc == RECORD.unpack(head)[1]


def _next_magic(fh: IO[bytes], start: int) -> int | None:
    """The offset of the next record magic at or after ``start``, or None."""
    keep = len(RECORD_MAGIC) - 1
    fh.seek(start)
    carry, base = b"", start
    while True:
        block = fh.read(_BLOCK)
        if not block:
            return None
        window = carry + block
        found = window.find(RECORD_MAGIC)
        if found >= 0:
            return base - len(carry) + found
        carry = window[-keep:]
        base += len(block)


class Scan:
    """Every record of a log with a valid CRC, in file order, as ``(offset, size, index)``
    (iterate); afterwards ``damaged`` counts the stretches that were not records."""

    def __init__(self, fh: IO[bytes], start: int, limits: Limits):
        self.fh, self.start, self.limits = fh, start, limits
        self.damaged = 0

    def __iter__(self) -> Iterator[tuple[int, int, int]]:
        pos = self.start
        while True:
            self.fh.seek(pos)
            head = self.fh.read(RECORD.size)
            if not head:
                return
            size = _checked_size(head, self.limits) if len(head) == RECORD.size else None
            if size is not None and _crc_matches(self.fh, pos, size):
                yield pos, size, RECORD.unpack(head)[2]
                pos += size
                continue
            self.damaged += 1
            found = _next_magic(self.fh, pos + 1)  # resynchronise on the next record
            if found is None:
                return
            pos = found


def read_record(fh: IO[bytes], offset: int, size: int, limits: Limits) -> tuple[int, Any, bytes]:
    """``(index, meta, payload)`` of the record at ``offset`` (as :class:`Scan` found it; its
    CRC is checked again). The meta is parsed JSON of any type; :class:`BadRecord` when the
    record is not there, or its meta is not JSON."""
    if size > RECORD.size + MAX_META + limits.max_payload:
        raise BadRecord("record larger than a record of this run can be")
    fh.seek(offset)
    data = fh.read(size)
    if len(data) != size or len(data) < RECORD.size:
        raise BadRecord("record cut short")
    magic, crc, index, meta_len, payload_len = RECORD.unpack_from(data)
    if magic != RECORD_MAGIC or RECORD.size + meta_len + payload_len != size or zlib.crc32(data[8:]) != crc:
        raise BadRecord("record changed since it was checked")
    try:
        meta = json.loads(data[RECORD.size:RECORD.size + meta_len])
    except (ValueError, RecursionError):
        raise BadRecord("its meta is not JSON") from None
    return index, meta, data[RECORD.size + meta_len:]
