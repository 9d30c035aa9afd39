"""Fuzz target (atheris): the ``.pairstats`` reader of a resumed sequence run.

What it feeds: a whole ``.pairstats`` file (header + records) to the code a resume runs on
it — :func:`irfidelity.sequence.sidecar.read_header`, :class:`~irfidelity.sequence.sidecar.Scan`
(CRC checks, resynchronisation), :func:`~irfidelity.sequence.log.last_records`, and
:class:`irfidelity.sequence.resume.Resumer` taking every record (meta checks, bounded
unpacking, ``PairStats.from_bytes``, the statistics' make and pixel count, the frame's entry,
the inputs' fingerprints, the reload for pooling) — for one of three runs' plans.

Input: one byte of flags, then the file. Flags: bits 0–1 choose the plan (uint16 with a
pooled 64-bin histogram; uint16 grey levels, sparse; float32 registered pair by pair); bit 2
makes every record's CRC (and the header's) valid, as a forger would; bit 3 takes each
record's payload as the uncompressed packed body and compresses it, so the fuzzer explores the
packed format rather than deflate. The runs' frames are fixed arrays, so records copied from a
real run of them (the seeds) carry the fingerprints a resume finds.

A finding is any exception other than :class:`~irfidelity.sequence.sidecar.BadRecord` (the
reader's "cannot be trusted"), a crash, or an allocation beyond ``-rss_limit_mb``.

Run (from the repository root, with the worktree's irfidelity importable)::

    python fuzz/python/fuzz_pairstats_log.py --make-seeds fuzz/python/seeds
    python fuzz/python/fuzz_pairstats_log.py fuzz/python/corpus fuzz/python/seeds \\
        -runs=1000000 -max_len=65536 -rss_limit_mb=1024 -timeout=10
"""

from __future__ import annotations

import io
import pathlib
import struct
import sys
import tempfile
import warnings
import zlib

import atheris
import numpy as np

with atheris.instrument_imports(include=["irfidelity"]):  # coverage of irfidelity's code only
    from irfidelity import _core
    from irfidelity.camera import CameraInputs
    from irfidelity.config import ScoringConfig
    from irfidelity.sequence import score_sequence
    from irfidelity.sequence.fingerprint import Fingerprints
    from irfidelity.sequence.log import last_records
    from irfidelity.sequence.pairing import pair_frames
    from irfidelity.sequence.plan import make_plan
    from irfidelity.sequence.resume import RecordBounds, Resumer
    from irfidelity.sequence.sidecar import (HEADER_MAGIC, RECORD, RECORD_MAGIC, BadRecord, Scan, read_header,
                                             read_record)
    from irfidelity.sequence.sources import as_sequence

FRAMES = 3


def _frames(dtype: type) -> tuple[np.ndarray, np.ndarray]:
    """Three 24x32 pairs: a smooth scene with a blob (it registers), the simulated one moved."""
    y, x = np.mgrid[0:24, 0:32]
    scenes = [1000 + 40 * x + 25 * y + 3000 * np.exp(-((x - 12 - k) ** 2 + (y - 10) ** 2) / 18) for k in range(FRAMES)]
    real = np.stack(scenes)
    sim = np.roll(real, 1, axis=2) * 1.01 + 5
    return real.astype(dtype), sim.astype(dtype)


_OPTIONS = [  # few bins: small records, more runs per second through the same code
    (np.uint16, dict(bits=14, bins=64, hist_range="full")),
    (np.uint16, dict(bits=14, bins="levels")),
    (np.float32, dict(peak=16383.0, bins=32, register="translation", register_each=True)),
]


class _Run:
    """One run's plan, pairing and fingerprints (as a resume of it has them)."""

    def __init__(self, dtype: type, options: dict):
        self.arrays = _frames(dtype)
        self.options = options
        real, sim = (as_sequence(a, side) for a, side in zip(self.arrays, ("real", "sim")))
        self.pairing = pair_frames(real, sim, "auto")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.plan = make_plan(real, sim, self.pairing, CameraInputs(), ScoringConfig(**options))
        self.fingerprints = Fingerprints(real, sim, arrays=True)
        self.bounds = RecordBounds(self.plan, _core.default_max_pixels(), _core.default_max_bytes())


class _MemoryLog:
    """A :class:`~irfidelity.sequence.log.FrameLog` after its carry-over, over bytes."""

    side = "fuzz.pairstats"

    def __init__(self, data: bytes, limits):
        self.fh, self.limits = io.BytesIO(data), limits
        _, start = read_header(self.fh)
        self.kept, self.foreign = last_records(Scan(self.fh, start, limits), FRAMES)

    def read(self, where: tuple[int, int]):
        return read_record(self.fh, where[0], where[1], self.limits)


def _fix_records(data: bytes, compress: bool) -> bytes:
    """Every stretch that starts with a record magic as a record with a valid CRC (and with
    ``compress``, its payload compressed); the header's CRC made valid too."""
    out, pos = [], 0
    if data.startswith(HEADER_MAGIC):
        text_end = data.find(b"\n", len(HEADER_MAGIC))
        if text_end >= 0:
            text = data[len(HEADER_MAGIC):text_end]
            out.append(HEADER_MAGIC + text + b"\n" + b"%08x" % zlib.crc32(text) + b"\n")
            pos = text_end + 1 + 9
    while pos < len(data):
        start = data.find(RECORD_MAGIC, pos)
        if start < 0 or start + RECORD.size > len(data):
            out.append(data[pos:])
            break
        out.append(data[pos:start])
        _, _, index, meta_len, payload_len = RECORD.unpack_from(data, start)
        meta = data[start + RECORD.size:start + RECORD.size + meta_len]
        payload = data[start + RECORD.size + len(meta):start + RECORD.size + len(meta) + payload_len]
        pos = start + RECORD.size + len(meta) + len(payload)
        if compress:
            payload = zlib.compress(payload, 1)
        body = struct.pack("<QII", index, len(meta), len(payload)) + meta + payload
        out.append(RECORD_MAGIC + struct.pack("<I", zlib.crc32(body)) + body)
    return b"".join(out)


RUNS: list[_Run] = []


def test_one_input(data: bytes) -> None:
    if not data:
        return
    flags, data = data[0], data[1:]
    run = RUNS[(flags & 3) % len(RUNS)]
    if flags & 4:
        data = _fix_records(data, compress=bool(flags & 8))
    log = _MemoryLog(data, run.bounds.run)
    resumer = Resumer(run.plan, run.pairing, log, run.fingerprints, run.bounds)

    def keep(entry, stats, extent, reload):
        assert entry["error"] is None and entry["fidelity"] is not None
        assert reload().n == stats.n

    try:
        resumer.take(lambda i: (f"r{i}", f"s{i}"), keep)
    except BadRecord:
        raise AssertionError("BadRecord escaped the resume") from None
    resumer.notes()


def make_seeds(folder: pathlib.Path) -> None:
    """Seeds: each run's real ``.pairstats`` (as is, and with its payloads uncompressed for
    flag bit 3), and a few damaged ones."""
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for k, run in enumerate(RUNS):
            csv = pathlib.Path(tmp) / f"run{k}.csv"
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                score_sequence(*run.arrays, csv=csv, progress=False, **run.options)
            side = pathlib.Path(str(csv) + ".pairstats").read_bytes()
            raw = _uncompressed(side)
            for name, flags, data in [("real", k, side), ("fixed", k | 4, side), ("raw", k | 12, raw),
                                      ("cut", k, side[: len(side) * 2 // 3]), ("bare", k | 4, side[side.find(RECORD_MAGIC):])]:
                (folder / f"run{k}_{name}").write_bytes(bytes([flags]) + data)


def _uncompressed(side: bytes) -> bytes:
    """A ``.pairstats`` with every payload replaced by its packed body (for flag bit 3)."""
    fh = io.BytesIO(side)
    _, start = read_header(fh)
    out = [side[:start]]
    for offset, size, _ in Scan(fh, start, RUNS[0].bounds.run):
        head = side[offset:offset + RECORD.size]
        meta_len = RECORD.unpack(head)[3]
        meta = side[offset + RECORD.size:offset + RECORD.size + meta_len]
        body = zlib.decompress(side[offset + RECORD.size + meta_len:offset + size])
        out.append(head[:16] + struct.pack("<II", meta_len, len(body)) + meta + body)
    return b"".join(out)


def main() -> None:
    RUNS.extend(_Run(dtype, options) for dtype, options in _OPTIONS)
    if sys.argv[1:2] == ["--make-seeds"]:
        make_seeds(pathlib.Path(sys.argv[2]))
        return
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
