"""Hostile input: damaged, truncated, bit-flipped and lying files must raise FrameError.

Every decode runs in a child process (one child per batch, reporting JSON), with an
address-space limit and a timeout, so a crash, abort, hang or unbounded allocation fails
the test instead of killing pytest.
"""

from __future__ import annotations

import json
import struct
import textwrap
import zlib
from pathlib import Path

import numpy as np
import pytest
from child_process import run_python

DATA = Path(__file__).parent / "data"
HOSTILE_DIRS = ["exr/damaged", "png/corrupt", "tiff/corrupt"]
MEMORY_LIMIT = 3 << 30  # bytes of address space for the child
TIMEOUT = 600  # seconds for a whole batch

CHILD = textwrap.dedent(
    """
    import json, sys, resource
    limit = int(sys.argv[1])
    if limit:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    import numpy as np
    from irfidelity.errors import FrameError
    from irfidelity.frames import load_frame, list_channels, page_count
    jobs = json.load(sys.stdin)
    out = []
    for job in jobs:
        rec = {"path": job["path"], "op": job.get("op", "load")}
        try:
            if rec["op"] == "load":
                a = load_frame(job["path"], channel=job.get("channel"), max_pixels=job.get("max_pixels"))
                rec.update(kind="ok", shape=list(a.shape), dtype=str(a.dtype),
                           digest=int(np.frombuffer(a.tobytes(), np.uint8).astype(np.uint64).sum()))
            elif rec["op"] == "channels":
                rec.update(kind="ok", value=list_channels(job["path"]))
            else:
                rec.update(kind="ok", value=page_count(job["path"]))
        except FrameError as e:
            rec.update(kind="frame_error", message=str(e))
        except BaseException as e:  # anything else is a bug
            rec.update(kind="other", message=f"{type(e).__name__}: {e}")
        out.append(rec)
    print(json.dumps(out))
    """
)


def run_batch(jobs: list[dict], memory_limit: int = MEMORY_LIMIT) -> list[dict]:
    recs = run_python(CHILD, [str(memory_limit)], timeout=TIMEOUT, stdin=json.dumps(jobs))
    assert len(recs) == len(jobs)
    return recs


def hostile_files() -> list[Path]:
    return sorted(p for d in HOSTILE_DIRS for p in (DATA / d).iterdir() if p.is_file())


def test_every_damaged_file_raises_frame_error() -> None:
    files = hostile_files()
    assert len(files) >= 35
    jobs = [{"path": str(p), "channel": ch} for p in files for ch in (None, "R", "Y")]
    jobs += [{"path": str(p), "op": op} for p in files for op in ("channels", "pages")]
    recs = run_batch(jobs)
    bad = []
    for r in recs:
        name = Path(r["path"]).name
        if r["kind"] == "other" or (r["op"] == "load" and r["kind"] != "frame_error"):
            bad.append((name, r["op"], r["kind"], r.get("message"), r.get("shape")))
        elif r["kind"] == "frame_error":
            assert r["path"] in r["message"], r["message"]
            assert len(r["message"]) > len(r["path"]) + 5, r["message"]
    assert not bad, bad


VALID = [
    ("thermal/cptv_v2_frame000.png", None),
    ("thermal/cptv_v2_all100frames_uint16.tif", None),
    ("thermal/cptv_v2_frame000_counts_f32_zip.exr", None),
    ("thermal/cptv_v2_frame001_counts_f16_piz.exr", None),
    ("thermal/flirpy_example_radiometric.tiff", None),
    ("png/pngsuite_basi0g16.png", None),
    ("tiff/imagetiff_seq-1c-16b-tiled-68f373a0.tiff", None),
    ("tiff/imagetiff_predictor-3-gray-f32.tif", None),
    ("tiff/libtiffpic_caspian.tif", "0"),
    ("exr/openexr_comp_dwab_v2.exr", "G"),
    ("exr/exrimages_TestImages_WideFloatRange.exr", None),
    ("exr/exrimages_LuminanceChroma_Garden.exr", None),
    ("exr/openexr_v1.7.test.tiled.exr", "Z"),
    ("exr/exrimages_MultiResolution_ColorCodedLevels.exr", "R"),
    ("exr/tinyexr_piz-bug-issue-100.exr", None),
    ("exr/openexr_test.exr", "G"),
]


@pytest.fixture(scope="module")
def mutated(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[tuple[str, str, str | None]]]:
    """Truncations and bit flips of valid files: {'trunc': [...], 'flip': [...]} of (path, source, channel)."""
    root = tmp_path_factory.mktemp("mutated")
    rng = np.random.default_rng(20240611)
    out: dict[str, list[tuple[str, str, str | None]]] = {"trunc": [], "flip": []}
    for rel, ch in VALID:
        raw = (DATA / rel).read_bytes()
        n = len(raw)
        stem = rel.replace("/", "__")
        cuts = sorted({0, 1, 4, 7, 8, 12, 16, 33, 64, 100, n // 5, n // 3, n // 2, (3 * n) // 4, n - 100, n - 17} - {n})
        for c in (c for c in cuts if 0 <= c < n):
            p = root / f"trunc{c}_{stem}"
            p.write_bytes(raw[:c])
            out["trunc"].append((str(p), rel, ch))
        for k in range(25):
            b = bytearray(raw)
            # flips concentrated in the header (where lengths and sizes live) and anywhere
            span = min(n, 512) if k % 2 == 0 else n
            for _ in range(1 + k % 3):
                i = int(rng.integers(0, span))
                b[i] ^= 1 << int(rng.integers(0, 8))
            p = root / f"flip{k}_{stem}"
            p.write_bytes(bytes(b))
            out["flip"].append((str(p), rel, ch))
    return out


def reference_digests() -> dict[str, tuple[list[int], str, int]]:
    recs = run_batch([{"path": str(DATA / rel), "channel": ch} for rel, ch in VALID])
    out = {}
    for (rel, _), r in zip(VALID, recs):
        assert r["kind"] == "ok", r
        out[rel] = (r["shape"], r["dtype"], r["digest"])
    return out


def test_truncated_files_raise_frame_error(mutated: dict) -> None:
    ref = reference_digests()
    jobs = [{"path": p, "channel": ch} for p, _, ch in mutated["trunc"]]
    recs = run_batch(jobs)
    bad = []
    for (p, rel, _), r in zip(mutated["trunc"], recs):
        if r["kind"] == "frame_error":
            assert p in r["message"]
            continue
        # a cut inside trailing metadata may leave every pixel intact: then the frame must
        # be exactly the original one, never different pixels
        if r["kind"] == "ok" and (r["shape"], r["dtype"], r["digest"]) == ref[rel] and "trunc0_" not in p:
            continue
        bad.append((Path(p).name, r))
    assert not bad, bad


def test_bit_flipped_files_never_crash(mutated: dict) -> None:
    jobs = [{"path": p, "channel": ch} for p, _, ch in mutated["flip"]]
    recs = run_batch(jobs)
    others = [(Path(r["path"]).name, r["message"]) for r in recs if r["kind"] == "other"]
    assert not others, others
    errors = [r for r in recs if r["kind"] == "frame_error"]
    assert all(r["path"] in r["message"] for r in errors)
    assert errors, "no bit flip was detected at all"


def _png_chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))


def test_lying_headers_refused_before_allocating(tmp_path: Path) -> None:
    # PNG: a valid IHDR claiming 2^31-1 x 2^31-1 16-bit pixels, then a tiny IDAT
    ihdr = struct.pack(">IIBBBBB", 2**31 - 1, 2**31 - 1, 16, 0, 0, 0, 0)
    big_png = tmp_path / "huge.png"
    big_png.write_bytes(
        b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IDAT", zlib.compress(b"\0" * 64)) + _png_chunk(b"IEND", b"")
    )
    # PNG within the default limit of pixels but a lower explicit max_pixels
    ihdr2 = struct.pack(">IIBBBBB", 20000, 20000, 16, 0, 0, 0, 0)
    mid_png = tmp_path / "mid.png"
    mid_png.write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr2) + _png_chunk(b"IEND", b""))
    # TIFF: little-endian, one IFD claiming 1,000,000 x 1,000,000 16-bit grey, one tiny strip
    entries = [
        (256, 4, 1, 1_000_000),  # ImageWidth LONG
        (257, 4, 1, 1_000_000),  # ImageLength
        (258, 3, 1, 16),  # BitsPerSample
        (259, 3, 1, 1),  # Compression none
        (262, 3, 1, 1),  # MinIsBlack
        (273, 4, 1, 8 + 2 + 12 * 8 + 4),  # StripOffsets
        (277, 3, 1, 1),  # SamplesPerPixel
        (278, 4, 1, 1_000_000),  # RowsPerStrip
        (279, 4, 1, 16),  # StripByteCounts
    ]
    ifd = struct.pack("<H", len(entries))
    for tag, typ, count, value in entries:
        val = struct.pack("<H", value) + b"\0\0" if typ == 3 else struct.pack("<I", value)
        ifd += struct.pack("<HHI", tag, typ, count) + val
    ifd += struct.pack("<I", 0)
    big_tif = tmp_path / "huge.tif"
    big_tif.write_bytes(b"II*\0" + struct.pack("<I", 8) + ifd + b"\0" * 16)
    jobs = [
        {"path": str(big_png)},
        {"path": str(mid_png), "max_pixels": 1_000_000},
        {"path": str(big_tif)},
        {"path": str(DATA / "exr/damaged/exrimages_memory_DOS_1"), "channel": "R"},
        {"path": str(DATA / "exr/openexr_comp_zip.exr"), "channel": "R", "max_pixels": 10_000},
    ]
    # a tight address-space limit: refusing must not need the claimed memory
    recs = run_batch(jobs, memory_limit=2 << 30)
    for r in recs:
        assert r["kind"] == "frame_error", r
        assert r["path"] in r["message"]
    assert "exceeds the limit" in recs[0]["message"]
    assert "exceeds the limit of 1000000 pixels" in recs[1]["message"]
    assert "exceeds the limit" in recs[2]["message"]
    assert "exceeds the limit of 10000 pixels" in recs[4]["message"]


def test_partial_palette_entry_is_a_clean_frame_error(tmp_path: Path) -> None:
    # a fuzzing finding: the png crate panics on a PLTE chunk that is not whole RGB entries;
    # the file must give one FrameError naming it, and nothing on stderr
    rows = b"".join(b"\0\0\1\0\1" for _ in range(4))
    jobs = []
    for n in (4, 5, 8):
        path = tmp_path / f"palette_{n}.png"
        path.write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", struct.pack(">IIBBBBB", 4, 4, 8, 3, 0, 0, 0))
                         + _png_chunk(b"PLTE", bytes(range(n))) + _png_chunk(b"IDAT", zlib.compress(rows))
                         + _png_chunk(b"IEND", b""))
        jobs.append({"path": str(path), "channel": "R"})
    for job, rec in zip(jobs, run_python(CHILD, ["0"], timeout=TIMEOUT, stdin=json.dumps(jobs))):
        assert rec["kind"] == "frame_error", rec
        assert rec["message"].startswith(f"{job['path']}: corrupt PNG file: the PLTE chunk holds"), rec
