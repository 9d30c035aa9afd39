"""FLIR FFF frames taken apart and put back together, for building CSQ-like recordings.

A CSQ recording is FFF frames one after another whose raw-data record holds the counts as
JPEG-LS. No CSQ file is shipped, so the tests make them: the records of a real FFF frame
(its camera-info record, so its calibration) with the raw image replaced by a JPEG-LS stream
from CharLS.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

HEADER_LEN = 64
ENTRY_LEN = 32
RAW_DATA = 1
CAMERA_INFO = 0x20
RAW_HEADER_LEN = 32


@dataclass
class Frame:
    """An FFF frame: its header's byte order, its 64-byte header, and its records."""

    big: bool
    header: bytes
    records: list[tuple[bytes, bytes]]  # (the 32-byte directory entry, the record)

    @classmethod
    def parse(cls, data: bytes) -> Frame:
        big = 100 <= struct.unpack_from(">I", data, 0x14)[0] < 200
        order = ">" if big else "<"
        directory, count = struct.unpack_from(order + "II", data, 0x18)
        records = []
        for k in range(count):
            entry = data[directory + k * ENTRY_LEN: directory + (k + 1) * ENTRY_LEN]
            kind, = struct.unpack_from(order + "H", entry, 0)
            if kind == 0:
                continue
            offset, length = struct.unpack_from(order + "II", entry, 0x0C)
            records.append((entry, data[offset: offset + length]))
        return cls(big, data[:HEADER_LEN], records)

    def kind(self, entry: bytes) -> int:
        return struct.unpack_from(">H" if self.big else "<H", entry, 0)[0]

    def with_raw_image(self, image: bytes) -> Frame:
        """This frame with the raw-data record's image (after its 32-byte header) replaced."""
        records = [(e, r[:RAW_HEADER_LEN] + image if self.kind(e) == RAW_DATA else r) for e, r in self.records]
        return Frame(self.big, self.header, records)

    def with_record(self, kind: int, record: bytes) -> Frame:
        """This frame with its record of type ``kind`` replaced by ``record``."""
        return Frame(self.big, self.header, [(e, record if self.kind(e) == kind else r) for e, r in self.records])

    def record(self, kind: int) -> bytes:
        return next(r for e, r in self.records if self.kind(e) == kind)

    def to_bytes(self) -> bytes:
        order = ">" if self.big else "<"
        header = bytearray(self.header)
        struct.pack_into(order + "II", header, 0x18, HEADER_LEN, len(self.records))
        offset = HEADER_LEN + ENTRY_LEN * len(self.records)
        entries = bytearray()
        for entry, record in self.records:
            entry = bytearray(entry)
            struct.pack_into(order + "II", entry, 0x0C, offset, len(record))
            entries += entry
            offset += len(record)
        return bytes(header) + bytes(entries) + b"".join(r for _, r in self.records)


def jpegls(counts: np.ndarray, **options) -> bytes:
    """``counts`` (2-D uint16) as a JPEG-LS stream from CharLS (``options``: near_lossless,
    t1, t2, t3, reset, maxval, bits_per_sample)."""
    from pillow_jpls import _pycharls as charls

    info = charls.FrameInfo()
    info.height, info.width = counts.shape
    info.component_count = 1
    info.bits_per_sample = options.pop("bits_per_sample", 16)
    dtype = "u1" if info.bits_per_sample <= 8 else "<u2"  # CharLS's sample size
    return bytes(charls.encode(np.ascontiguousarray(counts, dtype=dtype).tobytes(), info, **options))


def with_restarts(counts: np.ndarray, lines: int, **options) -> bytes:
    """A JPEG-LS stream of ``counts`` with a restart marker every ``lines`` lines.

    At a restart the decoder starts afresh (contexts reset, the line above all zero), so each
    interval codes exactly as an image of its own: CharLS codes the intervals, and their
    scans are joined with RST markers under one header and a DRI segment.
    """
    scans = []
    for k, first in enumerate(range(0, counts.shape[0], lines)):
        stream = jpegls(counts[first: first + lines], **dict(options))
        sos = stream.index(b"\xff\xda")
        start = sos + 2 + struct.unpack_from(">H", stream, sos + 2)[0]
        scans.append(stream[start: stream.rindex(b"\xff\xd9")])
        if k == 0:
            head = bytearray(stream[:start])
    sof = head.index(b"\xff\xf7")
    struct.pack_into(">H", head, sof + 5, counts.shape[0])  # the whole image's lines
    dri = b"\xff\xdd\x00\x04" + struct.pack(">H", lines)
    body = b"".join(scan + (bytes([0xFF, 0xD0 + k % 8]) if k + 1 < len(scans) else b"") for k, scan in enumerate(scans))
    return bytes(head[:sof]) + dri + bytes(head[sof:]) + body + b"\xff\xd9"
