"""No crash, no loss: crafted inputs that used to abort or crash the process, hang, or take
gigabytes of memory, and the integer binning rules at their edges.

Every hostile file is written here, by the test (a few hundred bytes to a few MB). Each decode
runs in its own child process, which reports its peak resident memory (``VmHWM``): an
abort, a segfault or a hang then fails the test instead of killing pytest, and a decode that
allocates far beyond one frame fails the memory assertion.
"""

from __future__ import annotations

import json
import os
import struct
import textwrap
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from child_process import run_python

import irfidelity as irf
from irfidelity import _core
from irfidelity.sequence.plan import SequenceRequest
from irfidelity.errors import FrameError

# Peak resident memory allowed for a child that decodes one (possibly 16384 x 16384) frame.
RSS_LIMIT = 1200 << 20
TIMEOUT = 120  # seconds per child

CHILD = textwrap.dedent(
    """
    import json, sys
    job = json.loads(sys.argv[1])
    import numpy as np
    from irfidelity import _core
    from irfidelity.errors import FrameError
    from irfidelity.frames import list_channels, load_frame, page_count
    rec = {}
    limit = job.get("max_pixels", 16384 * 16384)  # the budget, not the default pixel limit, is under test
    try:
        if job["op"] == "load" and job.get("max_bytes") is not None:
            a = _core.load_frame(job["path"], job.get("channel"), 0, limit, max_bytes=job["max_bytes"])
            rec.update(kind="ok", shape=list(a.shape), dtype=str(a.dtype), nonzero=int(np.count_nonzero(a)))
        elif job["op"] == "load":
            a = load_frame(job["path"], channel=job.get("channel"), max_pixels=limit)
            rec.update(kind="ok", shape=list(a.shape), dtype=str(a.dtype), nonzero=int(np.count_nonzero(a)))
        elif job["op"] == "channels":
            rec.update(kind="ok", value=list_channels(job["path"]))
        elif job["op"] == "pages":
            rec.update(kind="ok", value=page_count(job["path"]))
        elif job["op"] == "nmi":
            import irfidelity as irf
            r, s = (np.array(a, dtype=job["dtype"]) for a in job["frames"])
            got = irf.stats.nmi(r, s, hist_range=tuple(job["range"]), bins=job["bins"])
            rec.update(kind="ok", value=[got.value, got.h_real, got.h_sim, got.h_joint])
    except FrameError as e:
        rec.update(kind="frame_error", message=str(e))
    except BaseException as e:  # anything else is a bug
        rec.update(kind="other", message=f"{type(e).__name__}: {e}")
    # peak RSS of this process's own memory: VmHWM (ru_maxrss keeps the parent's peak across exec)
    with open("/proc/self/status") as status:
        hwm = next(line for line in status if line.startswith("VmHWM:"))
    rec["maxrss"] = int(hwm.split()[1]) * 1024
    print(json.dumps(rec))
    """
)


def run_child(**job) -> dict:
    """Run one job in a fresh interpreter; its record, with `maxrss` in bytes."""
    return run_python(CHILD, [json.dumps(job)], timeout=TIMEOUT)


# ------------------------------------------------------------------------ crafting helpers


def zeros_zlib(n: int, raw: bool = False) -> bytes:
    """A zlib stream (or raw deflate) of `n` zero bytes, without compressing `n` bytes:
    a 1 MiB segment ending in a full flush (no back-references across it) is repeated."""
    seg = 1 << 20
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    segment = c.compress(b"\0" * seg) + c.flush(zlib.Z_FULL_FLUSH)
    k, rest = divmod(n, seg)
    tail = zlib.compressobj(9, zlib.DEFLATED, -15)
    body = segment * k + tail.compress(b"\0" * rest) + tail.flush(zlib.Z_FINISH)
    if raw:
        return body
    adler = ((n % 65521) << 16) | 1  # Adler-32 of n zero bytes
    return b"\x78\xda" + body + struct.pack(">I", adler)


HALF, FLOAT = 1, 2
RLE, ZIP, PIZ, PXR24 = 1, 3, 4, 5


def _exr_attr(name: str, kind: str, value: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def exr_file(
    channels: list[tuple[str, int]],
    compression: int,
    size: tuple[int, int],
    tile: tuple[int, int] | None,
    blocks: list[bytes],
) -> bytes:
    """A single-part OpenEXR file: the header, the offset table and `blocks` (the compressed
    data of tile (i, 0) or of the scan-line block starting at row i * lines)."""
    w, h = size
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", t, 0, 1, 1) for n, t in channels) + b"\0"
    window = struct.pack("<4i", 0, 0, w - 1, h - 1)
    header = (
        _exr_attr("channels", "chlist", chlist)
        + _exr_attr("compression", "compression", bytes([compression]))
        + _exr_attr("dataWindow", "box2i", window)
        + _exr_attr("displayWindow", "box2i", window)
        + _exr_attr("lineOrder", "lineOrder", b"\0")
        + _exr_attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
        + _exr_attr("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0))
        + _exr_attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
    )
    if tile is not None:
        header += _exr_attr("tiles", "tiledesc", struct.pack("<IIB", tile[0], tile[1], 0))
    head = b"\x76\x2f\x31\x01" + struct.pack("<I", 2 | (0x200 if tile else 0)) + header + b"\0"
    lines = {RLE: 1, ZIP: 16, PIZ: 32, PXR24: 16}.get(compression, 1)
    chunks = []
    for i, data in enumerate(blocks):
        if tile is not None:
            chunks.append(struct.pack("<5i", i, 0, 0, 0, len(data)) + data)
        else:
            chunks.append(struct.pack("<2i", i * lines, len(data)) + data)
    offsets, pos = [], len(head) + 8 * len(chunks)
    for c in chunks:
        offsets.append(pos)
        pos += len(c)
    return head + b"".join(struct.pack("<Q", o) for o in offsets) + b"".join(chunks)


def _png_chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))


def png_file(width: int, height: int, depth: int, colour: int, idat: bytes, extra: bytes = b"") -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", ihdr)
        + extra
        + _png_chunk(b"IDAT", idat)
        + _png_chunk(b"IEND", b"")
    )


SHORT, LONG = 3, 4


def tiff_file(entries: list[tuple[int, int, list[int]]], data: bytes) -> bytes:
    """A little-endian one-page TIFF: the IFD (values longer than 4 bytes after it), then
    `data`; a value of -1 in StripOffsets/TileOffsets (273/324) stands for data's offset."""
    n = len(entries)
    ifd_size = 2 + 12 * n + 4
    extra_pos = 8 + ifd_size
    extras = b""
    sized = []
    for tag, kind, values in entries:
        fmt = "<H" if kind == SHORT else "<I"
        sized.append((tag, kind, values, b"".join(struct.pack(fmt, max(v, 0)) for v in values)))
    data_pos = extra_pos + sum(len(b) for *_, b in sized if len(b) > 4)
    ifd = struct.pack("<H", n)
    for tag, kind, values, packed in sized:
        if tag in (273, 324):
            fmt = "<H" if kind == SHORT else "<I"
            packed = b"".join(struct.pack(fmt, data_pos if v == -1 else v) for v in values)
        if len(packed) > 4:
            ifd += struct.pack("<HHII", tag, kind, len(values), extra_pos + len(extras))
            extras += packed
        else:
            ifd += struct.pack("<HHI", tag, kind, len(values)) + packed.ljust(4, b"\0")
    ifd += struct.pack("<I", 0)
    return b"II*\0" + struct.pack("<I", 8) + ifd + extras + data


def rgba_tiff(size: int, bits: int, sample_format: int, rows_per_strip: int, strip: bytes, compression: int) -> bytes:
    strips = -(-size // rows_per_strip)
    return tiff_file(
        [
            (256, LONG, [size]),
            (257, LONG, [size]),
            (258, SHORT, [bits] * 4),
            (259, SHORT, [compression]),
            (262, SHORT, [2]),  # RGB
            (273, LONG, [-1] * strips),  # every strip is the same data
            (277, SHORT, [4]),
            (278, LONG, [rows_per_strip]),
            (279, LONG, [len(strip)] * strips),
            (284, SHORT, [1]),
            (338, SHORT, [2]),  # unassociated alpha
            (339, SHORT, [sample_format] * 4),
        ],
        strip,
    )


# --------------------------------------------------------------- decoding budgets (bytes)

BUDGET = "exceeds the decoding budget of"


def _channels(n: int, kind: int) -> list[tuple[str, int]]:
    return [(f"c{i:03d}", kind) for i in range(n)]


HOSTILE_EXR = {
    # one 16384 x 16384 tile of 300 half channels: 300 GB of ZIP scratch (SIGABRT before)
    "zip_300_half": (_channels(300, HALF), ZIP, zlib.compress(b"\0" * 64)),
    # 16 float channels in one tile: 17 GB asked of each decompressor
    "zip_16_float": (_channels(16, FLOAT), ZIP, zlib.compress(b"\0" * 64)),
    "piz_16_float": (_channels(16, FLOAT), PIZ, struct.pack("<HHI", 1, 0, 0)),
    "pxr24_16_float": (_channels(16, FLOAT), PXR24, zlib.compress(b"\0" * 64)),
    "rle_16_float": (_channels(16, FLOAT), RLE, b"\x7f\x00" * 8),
    # 4 float channels, ~400 bytes: 4 GB of scratch touched for 12 s before its error
    "zip_4_float": ([("A", FLOAT), ("B", FLOAT), ("G", FLOAT), ("R", FLOAT)], ZIP, zlib.compress(b"\0" * 64)),
}


@pytest.mark.parametrize("name", sorted(HOSTILE_EXR))
def test_exr_block_beyond_the_budget_is_refused(tmp_path: Path, name: str) -> None:
    channels, compression, data = HOSTILE_EXR[name]
    path = tmp_path / f"{name}.exr"
    path.write_bytes(exr_file(channels, compression, (16384, 16384), (16384, 16384), [data]))
    assert path.stat().st_size < 8000
    rec = run_child(op="load", path=str(path), channel=channels[0][0])
    assert rec["kind"] == "frame_error", rec
    assert str(path) in rec["message"] and BUDGET in rec["message"] and "(max_bytes)" in rec["message"], rec
    assert rec["maxrss"] < 300 << 20, rec  # refused before allocating anything large


def test_exr_chunk_claims_are_budgeted_by_the_declared_tile(tmp_path: Path) -> None:
    # fuzzing finding: 64 x 838860800 tiles on a 512 x 512 image (the decoded tiles are
    # clamped to the image, small), and a chunk claiming 2 GB: the exr crate sized its read
    # buffer from the declared tile (a 1.9 GB allocation before failing to read)
    head = exr_file([("A", HALF), ("B", HALF), ("G", HALF), ("R", HALF)], PXR24, (512, 512), (64, 838860800), [])
    chunk = struct.pack("<5i", 0, 0, 0, 0, 2**31 - 1)  # tile (0, 0), level (0, 0), size, no data
    path = tmp_path / "tall_tiles.exr"
    path.write_bytes(head + struct.pack("<Q", len(head) + 64) * 8 + chunk)
    rec = run_child(op="load", path=str(path), channel="R")
    assert rec["kind"] == "frame_error" and BUDGET in rec["message"], rec


def test_exr_scanline_blocks_are_budgeted_too(tmp_path: Path) -> None:
    # 16384 columns x 16 lines x 300 float channels = 315 MB per ZIP block: within a 1 GB
    # budget alone, but the whole decode (frame + block + scratch) is not within 100 MB
    path = tmp_path / "wide.exr"
    path.write_bytes(exr_file(_channels(300, FLOAT), ZIP, (16384, 16), None, [zlib.compress(b"\0" * 64)]))
    rec = run_child(op="load", path=str(path), channel="c000", max_bytes=100 << 20)
    assert rec["kind"] == "frame_error" and f"{BUDGET} {100 << 20} bytes (max_bytes)" in rec["message"], rec


PNG_ICCP = "iccp.png"


def _iccp_png(path: Path) -> None:
    # 4 x 4 grey pixels and a 3 GB (zero) ICC profile, deflated to ~3 MB
    profile = b"icc\0\0" + zeros_zlib(3 << 30)
    idat = zlib.compress(b"".join(b"\0" + bytes(range(4)) for _ in range(4)))
    path.write_bytes(png_file(4, 4, 8, 0, idat, extra=_png_chunk(b"iCCP", profile)))


def test_png_compressed_icc_profile_is_not_inflated(tmp_path: Path) -> None:
    path = tmp_path / PNG_ICCP
    _iccp_png(path)
    assert 2 << 20 < path.stat().st_size < 5 << 20
    rec = run_child(op="load", path=str(path))
    assert rec["kind"] == "ok" and rec["shape"] == [4, 4] and rec["dtype"] == "uint8", rec
    assert rec["maxrss"] < 300 << 20, rec


@pytest.mark.parametrize("colour,channel", [(0, None), (6, "R")])
def test_png_16k_16bit_decodes_within_the_budget(tmp_path: Path, colour: int, channel: str | None) -> None:
    # 16384 x 16384 16-bit grey (512 MiB decoded) and RGBA (2 GiB decoded, one channel kept)
    spp = {0: 1, 6: 4}[colour]
    path = tmp_path / f"big{colour}.png"
    path.write_bytes(png_file(16384, 16384, 16, colour, zeros_zlib(16384 * (1 + 16384 * 2 * spp))))
    rec = run_child(op="load", path=str(path), channel=channel)
    assert rec["kind"] == "ok" and rec["shape"] == [16384, 16384] and rec["dtype"] == "uint16", rec
    assert rec["nonzero"] == 0
    assert rec["maxrss"] < RSS_LIMIT, rec


def test_the_default_pixel_limit_refuses_a_small_file_that_expands_past_it(tmp_path: Path, capsys) -> None:
    # a 2 KB deflate PNG of 16384 x 16384 16-bit pixels (512 MiB decoded): refused unless asked
    import irfidelity as irf
    from irfidelity.cli import main

    path = tmp_path / "big.png"
    path.write_bytes(png_file(16384, 16384, 16, 0, zeros_zlib(16384 * (1 + 16384 * 2))))
    assert path.stat().st_size < 1 << 20
    rec = run_child(op="load", path=str(path), max_pixels=None)
    assert rec["kind"] == "frame_error" and "16384 x 16384 pixels exceeds the limit of 67108864 pixels" in rec["message"]
    assert "max_pixels" in rec["message"] and "--max-pixels" in rec["message"] and rec["maxrss"] < 300 << 20, rec
    assert main(["score", str(path), str(path), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--max-pixels" in err and str(path) in err, err
    with irf.budget.pixel_limit(16384 * 16384):  # what --max-pixels sets for a command
        assert irf.frames.default_max_pixels() == 16384 * 16384
        assert irf.FrameSequence([str(path)]).max_pixels == 16384 * 16384
    assert irf.budget.max_pixels(None) == irf.budget.DEFAULT_MAX_PIXELS == 8192 * 8192


def test_tiff_claiming_16k_rgba_float64_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "f64.tif"
    path.write_bytes(rgba_tiff(16384, 64, 3, 16384, b"\0" * 16, compression=1))
    assert path.stat().st_size < 400
    rec = run_child(op="load", path=str(path), channel="R")
    assert rec["kind"] == "frame_error" and BUDGET in rec["message"] and "(max_bytes)" in rec["message"], rec
    assert rec["maxrss"] < 300 << 20, rec


def test_tiff_16k_rgba16_deflate_strips_decode_one_channel(tmp_path: Path) -> None:
    # 1024 deflate strips of 16 rows (all the same 2 KB of data): 2 GiB of RGBA16 samples,
    # of which one channel (512 MiB) is kept
    path = tmp_path / "strips.tif"
    path.write_bytes(rgba_tiff(16384, 16, 1, 16, zeros_zlib(16 * 16384 * 8), compression=8))
    rec = run_child(op="load", path=str(path), channel="R")
    assert rec["kind"] == "ok" and rec["shape"] == [16384, 16384] and rec["dtype"] == "uint16", rec
    assert rec["maxrss"] < RSS_LIMIT, rec


def test_tiff_16k_rgba16_single_deflate_strip_is_refused(tmp_path: Path) -> None:
    # one 2 GiB strip of 2 MB: beyond the budget before inflating
    path = tmp_path / "one_strip.tif"
    path.write_bytes(rgba_tiff(16384, 16, 1, 16384, zeros_zlib(16384 * 16384 * 8), compression=8))
    assert path.stat().st_size < 3 << 20
    rec = run_child(op="load", path=str(path), channel="R")
    assert rec["kind"] == "frame_error" and BUDGET in rec["message"], rec
    assert rec["maxrss"] < 300 << 20, rec


def test_max_bytes_is_an_explicit_budget(tmp_path: Path) -> None:
    path = tmp_path / "grey.png"
    path.write_bytes(png_file(64, 32, 16, 0, zeros_zlib(32 * (1 + 64 * 2))))
    assert _core.default_max_bytes() == 2 << 30
    assert _core.load_frame(path).shape == (32, 64)
    assert _core.load_frame(path, max_bytes=1 << 20).shape == (32, 64)
    with pytest.raises(FrameError, match=rf"grey.png: .*{BUDGET} 1000 bytes \(max_bytes\)"):
        _core.load_frame(path, max_bytes=1000)
    exr = tmp_path / "small.exr"
    exr.write_bytes(exr_file([("Y", HALF)], ZIP, (64, 32), None, [zlib.compress(b"\0" * 64 * 16 * 2)] * 2))
    assert _core.load_frame(exr).shape == (32, 64)
    with pytest.raises(FrameError, match=rf"small.exr: .*{BUDGET} 1000 bytes \(max_bytes\)"):
        _core.load_frame(exr, max_bytes=1000)


def test_sequence_row_for_a_hostile_frame(tmp_path: Path) -> None:
    # the frame that aborted a whole sequence run is now that pair's error row
    channels = [("Y", HALF), *_channels(299, HALF)]  # "Y": the default channel
    bad = tmp_path / "bad.exr"
    bad.write_bytes(exr_file(channels, ZIP, (16384, 16384), (16384, 16384), [zlib.compress(b"\0" * 64)]))
    good = tmp_path / "good.png"
    good.write_bytes(png_file(8, 8, 8, 0, zlib.compress(b"\0" * 72)))
    rows = _core.score_pairs([str(good), str(bad)], [str(good), str(good)], workers=1,
                             request=SequenceRequest(max_bytes=64 << 20, max_pixels=16384 * 16384))
    assert rows[0][2] is None and rows[0][1] is not None
    assert rows[1][1] is None and BUDGET in rows[1][2] and "67108864 bytes" in rows[1][2]


# ------------------------------------------------------------------- non-regular files


FIFO_CASES = [(n, op) for n in ["frame.exr", "frame.png", "frame.tif"] for op in ["load", "channels", "pages"]]
FIFO_CASES += [("frame.npy", "load"), ("frame.npy", "channels")]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs POSIX FIFOs")
@pytest.mark.parametrize("name,op", FIFO_CASES)
def test_fifo_is_refused_not_waited_on(tmp_path: Path, name: str, op: str) -> None:
    path = tmp_path / name
    os.mkfifo(path)
    rec = run_child(op=op, path=str(path))  # a hang fails here (timeout)
    assert rec["kind"] == "frame_error" and "not a regular file" in rec["message"], rec
    assert str(path) in rec["message"]


# ------------------------------------------------------------- integer histogram edges


def _entropy(keys: np.ndarray) -> float:
    _, counts = np.unique(keys, axis=0, return_counts=True)
    p = counts / counts.sum()
    return float(-(p * np.log2(p)).sum())


def exact_nmi(r: np.ndarray, s: np.ndarray, lo: float, hi: float, bins: int) -> list[float]:
    """NMI and entropies with the documented integer bins, in Python integers: width =
    ceil((hi - lo + 1) / bins) levels, values outside [lo, hi] in the edge bins."""
    lo_i, hi_i = int(lo), int(hi)
    width = -(-(hi_i - lo_i + 1) // bins)
    top = (hi_i - lo_i) // width
    rb, sb = ([min(max((int(v) - lo_i) // width, 0), top) for v in a.ravel()] for a in (r, s))
    h_r, h_s = _entropy(np.array(rb)), _entropy(np.array(sb))
    h_j = _entropy(np.array([rb, sb]).T)
    mi = max(h_r + h_s - h_j, 0.0)
    return [1.0 if h_r + h_s == 0 else min(2 * mi / (h_r + h_s), 1.0), h_r, h_s, h_j]


HUGE_RANGES = [(-1e19, 1e3), (-1e19, 1e19), (0.0, 1e19), (-9.3e18, -9.2e18), (-(2.0**100), 2.0**100), (-(2.0**70), 5.0)]


@pytest.mark.parametrize("dtype", ["uint8", "uint16", "int16", "uint32"])
@pytest.mark.parametrize("rng", HUGE_RANGES)
@pytest.mark.parametrize("bins", [1, 3, 256, 70000])
def test_huge_integer_hist_range_is_binned_exactly(dtype: str, rng: tuple[float, float], bins: int) -> None:
    # spans beyond 2^63 overflowed the integer binner: an out-of-bounds write (segfault) for
    # 16-bit frames, a wrong NMI for 8-bit ones; now exact, by the documented rule
    info = np.iinfo(dtype)
    gen = np.random.default_rng(5)
    values = np.array([info.min, info.max, 0, 1, 255, -1 if info.min < 0 else 2], dtype=np.int64)
    r = np.concatenate([values, gen.integers(info.min, int(info.max) + 1, size=58)]).astype(dtype).reshape(8, 8)
    s = np.concatenate([values[::-1], gen.integers(info.min, int(info.max) + 1, size=58)]).astype(dtype).reshape(8, 8)
    rec = run_child(op="nmi", dtype=dtype, frames=[r.tolist(), s.tolist()], range=list(rng), bins=bins)
    assert rec["kind"] == "ok", rec
    assert rec["value"] == pytest.approx(exact_nmi(r, s, *rng, bins), abs=1e-12), rec


def test_integer_hist_range_beyond_2_to_100_is_a_clear_error() -> None:
    r = np.zeros((4, 4), np.uint16)
    with pytest.raises(irf.FidelityError, match="hist_range"):
        irf.stats.nmi(r, r, hist_range=(-1e300, 1e3))


NARROW = [(0.0, 0.0), (5.0, 5.0), (2.0, 5.0), (10.0, 12.0), (0.0, 200.0), (-3.0, 3.0), (250.0, 255.0), (100.0, 355.0)]


@pytest.mark.parametrize("lo,hi", NARROW)
@pytest.mark.parametrize("dtype", [np.uint8, np.int16, np.uint16, np.uint32])
def test_narrow_integer_range_uses_edge_bins_like_floats(dtype, lo: float, hi: float) -> None:
    # with (hi - lo + 1) <= bins every level in the range is its own bin and values outside
    # it are counted in the edge bins (the documented rule), exactly as float frames are
    rng = np.random.default_rng(11)
    r = rng.integers(0, 256, size=(40, 50)).astype(dtype)
    s = ((r.astype(np.int64) * 7 + 3) % 256).astype(dtype)
    got = irf.stats.nmi(r, s, hist_range=(lo, hi), bins=256)
    want = irf.stats.nmi(r.astype(np.float64), s.astype(np.float64), hist_range=(lo, hi), bins=256)
    assert got.value == pytest.approx(want.value, abs=1e-12)
    assert got.h_real == pytest.approx(want.h_real, abs=1e-12)
    # the partition itself: levels clipped to [lo, hi], one bin each
    clip = np.clip(r.astype(np.int64), lo, hi)
    _, counts = np.unique(clip, return_counts=True)
    p = counts / counts.sum()
    assert got.h_real == pytest.approx(float(-(p * np.log2(p)).sum()), abs=1e-12)


def test_zero_width_integer_range_matches_floats() -> None:
    r = np.arange(100, dtype=np.uint16).reshape(10, 10)
    got = irf.stats.nmi(r, r[::-1], hist_range=(0, 0))
    want = irf.stats.nmi(r.astype(np.float32), r[::-1].astype(np.float32), hist_range=(0, 0))
    assert got.value == want.value
    assert got.h_real == 0.0 and got.h_joint == 0.0


# ------------------------------------------------------------------ the TIFF page cache


def _stack(path: Path, base: int) -> np.ndarray:
    tifffile = pytest.importorskip("tifffile")
    pages = (np.arange(3 * 8 * 6, dtype=np.uint16).reshape(3, 8, 6) + base).astype(np.uint16)
    tifffile.imwrite(path, pages, photometric="minisblack")
    return pages


def test_replaced_tiff_is_not_served_from_the_page_cache(tmp_path: Path) -> None:
    path = tmp_path / "stack.tif"
    _stack(path, 0)
    first = irf.load_frame(path, page=1)
    st = path.stat()
    # replaced by rename (a new inode), same size and mtime
    other = tmp_path / "other.tif"
    b = _stack(other, 1000)
    assert other.stat().st_size == st.st_size
    os.utime(other, ns=(st.st_atime_ns, st.st_mtime_ns))
    os.replace(other, path)
    np.testing.assert_array_equal(irf.load_frame(path, page=1), b[1])
    # rewritten in place (same inode), mtime reset: the change time still moves
    c_path = tmp_path / "c.tif"
    c = _stack(c_path, 2000)
    time.sleep(0.05)  # change times have the kernel's clock-tick resolution
    st = path.stat()
    with open(path, "r+b") as f:
        f.write(c_path.read_bytes())
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert path.stat().st_mtime_ns == st.st_mtime_ns and path.stat().st_size == st.st_size
    np.testing.assert_array_equal(irf.load_frame(path, page=1), c[1])
    assert not np.array_equal(first, c[1])
