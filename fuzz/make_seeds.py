"""Structure-aware seeds for the fuzz targets: valid files, and valid files with hostile fields.

    python fuzz/make_seeds.py [--out fuzz/seeds]

writes ``<out>/<target>/<name>`` for the targets in ``fuzz/fuzz_targets``. Decoder seeds are one
selector byte (decode options, see ``fuzz/src/lib.rs``) followed by a file:

* EXR: every compression on scan lines and tiles, half/float/uint channels; hostile: a 16384²
  tile of 300 channels, 16 float channels in one tile, lying chunk sizes, offsets past the end,
  a data window that does not start at 0, more chunks than the file holds;
* PNG: every colour type and bit depth, Adam7, tRNS, split IDAT; hostile: IHDR claiming
  2^31 − 1 pixels, a deflated iCCP profile of a gigabyte, zTXt, eXIf, oversized chunks;
* TIFF: strips and tiles, planar and chunky, both byte orders, BigTIFF, none/deflate/PackBits,
  predictors, several pages; hostile: 16384² float64 RGBA in one strip, a single deflate strip
  of gigabytes, zero rows per strip, 0-sized tiles, offsets past the end, lying byte counts;

* FLIR FFF/SEQ: raw counts in both byte orders, byte-swapped PNG, TIFF, JPEG-LS (CSQ), a
  run of frames; hostile: a raw image claiming 65535², zeroed and short records, absurd Planck
  constants, 100,000 directory entries, a bad version, trailing junk;
* radiometric JPEG: the same frames in FLIR APP1 segments, reordered, missing, none;
* JPEG-LS streams (``jpegls_stream``): flat images coded by hand in every header variant (8 and
  16 bits, NEAR, restart markers, an LSE preset, comment and SPIFF segments); hostile: 65535²,
  zero lines, a mapping table, bad thresholds, NEAR 255, three components, cut short, restart
  markers out of order; and, when imagecodecs is installed, CharLS-coded noise, gradients and
  plateaus at 8, 12 and 16 bits, lossless and NEAR 2;

plus the small real files of ``tests/data``. Block seeds (``exr_piz_block``, ``exr_zip_block``)
are the real PIZ and ZIP blocks of the EXR files in ``tests/data``, behind the 4-byte block
header ``fuzz/src/lib.rs`` reads (width, height, channel sizes, selected channel).
Standard library only (imagecodecs optional, above); deterministic.
"""

from __future__ import annotations

import argparse
import struct
import zlib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"

# ------------------------------------------------------------------------------------ EXR

HALF, FLOAT, UINT = 1, 2, 0
NONE, RLE, ZIPS, ZIP, PIZ, PXR24, B44, B44A = range(8)
LINES = {NONE: 1, RLE: 1, ZIPS: 1, ZIP: 16, PIZ: 32, PXR24: 16, B44: 32, B44A: 32}
SIZE = {HALF: 2, FLOAT: 4, UINT: 4}


def _attr(name: str, kind: str, value: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def exr(channels, compression, size, tile=None, blocks=(), origin=(0, 0), offsets=None) -> bytes:
    """A single-part EXR: header, offset table (or `offsets`), blocks (tile (i, 0) or the
    scan-line block at row i * lines)."""
    w, h = size
    x0, y0 = origin
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", t, 0, 1, 1) for n, t in channels) + b"\0"
    window = struct.pack("<4i", x0, y0, x0 + w - 1, y0 + h - 1)
    header = (
        _attr("channels", "chlist", chlist)
        + _attr("compression", "compression", bytes([compression]))
        + _attr("dataWindow", "box2i", window)
        + _attr("displayWindow", "box2i", window)
        + _attr("lineOrder", "lineOrder", b"\0")
        + _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
        + _attr("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0))
        + _attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
    )
    if tile:
        header += _attr("tiles", "tiledesc", struct.pack("<IIB", tile[0], tile[1], 0))
    head = b"\x76\x2f\x31\x01" + struct.pack("<I", 2 | (0x200 if tile else 0)) + header + b"\0"
    chunks = []
    for i, data in enumerate(blocks):
        if tile:
            chunks.append(struct.pack("<5i", i, 0, 0, 0, len(data)) + data)
        else:
            chunks.append(struct.pack("<2i", y0 + i * LINES[compression], len(data)) + data)
    table, pos = [], len(head) + 8 * len(chunks)
    for c in chunks:
        table.append(pos)
        pos += len(c)
    if offsets is not None:
        table = offsets
    return head + b"".join(struct.pack("<Q", o) for o in table) + b"".join(chunks)


def predicted(raw: bytes) -> bytes:
    """OpenEXR's ZIP/RLE predictor: even bytes then odd bytes, then deltas + 128."""
    split = raw[0::2] + raw[1::2]
    out = bytearray(split)
    for i in range(len(split) - 1, 0, -1):
        out[i] = (split[i] - split[i - 1] + 128) & 0xFF
    return bytes(out)


def rle(data: bytes) -> bytes:
    """OpenEXR RLE: runs of up to 128 equal bytes as (count − 1, byte)."""
    out, i = bytearray(), 0
    while i < len(data):
        j = i
        while j < len(data) and j - i < 127 and data[j] == data[i]:
            j += 1
        out += bytes([j - i - 1, data[i]])
        i = j
    return bytes(out)


def compress(comp: int, raw: bytes) -> bytes:
    """A block as OpenEXR stores it: compressed, or raw when that is not smaller."""
    data = raw if comp == NONE else rle(predicted(raw)) if comp == RLE else zlib.compress(predicted(raw))
    return data if len(data) < len(raw) else raw


def block_bytes(channels, w, lines, seed: int) -> bytes:
    """Uncompressed block: per line, each channel's samples (little-endian)."""
    out = bytearray()
    for y in range(lines):
        for _, t in channels:
            for x in range(w):
                v = (x * 7 + y * 13 + seed) % 251
                out += struct.pack("<e", v / 8) if t == HALF else struct.pack("<f" if t == FLOAT else "<I", v)
    return bytes(out)


def exr_seeds() -> dict[str, bytes]:
    seeds = {}
    ch_sets = {
        "y": [("Y", HALF)],
        "rgba": [("A", HALF), ("B", HALF), ("G", HALF), ("R", HALF)],
        "mixed": [("A", FLOAT), ("Y", HALF), ("id", UINT)],
    }
    for cname, chans in ch_sets.items():
        w, h = 13, 35
        for comp in (NONE, RLE, ZIPS, ZIP):
            lines = LINES[comp]
            blocks = []
            for y in range(0, h, lines):
                blocks.append(compress(comp, block_bytes(chans, w, min(lines, h - y), y)))
            seeds[f"scan_{cname}_c{comp}.exr"] = exr(chans, comp, (w, h), blocks=blocks)
            tiles = []
            tw, th = 16, 16
            for ty in range(0, h, th):
                for tx in range(0, w, tw):
                    tiles.append(compress(comp, block_bytes(chans, min(tw, w - tx), min(th, h - ty), tx + ty)))
            # tiles are numbered along x only in `exr`; keep the file single-row of tiles
            if h <= th:
                seeds[f"tile_{cname}_c{comp}.exr"] = exr(chans, comp, (w, h), tile=(tw, th), blocks=tiles)
        seeds[f"origin_{cname}.exr"] = exr(chans, NONE, (4, 2), blocks=[block_bytes(chans, 4, 1, y) for y in range(2)], origin=(-3, 7))
        one_tile = compress(ZIP, block_bytes(chans, 20, 10, 1))
        seeds[f"tile1_{cname}.exr"] = exr(chans, ZIP, (20, 10), tile=(32, 32), blocks=[one_tile])
    z64 = zlib.compress(b"\0" * 64)
    many = [(f"c{i:03d}", HALF) for i in range(300)]
    seeds["hostile_300ch_tile.exr"] = exr(many, ZIP, (16384, 16384), tile=(16384, 16384), blocks=[z64])
    f16 = [(f"c{i:02d}", FLOAT) for i in range(16)]
    for comp in (RLE, ZIP, PIZ, PXR24, B44):
        data = struct.pack("<HHI", 1, 0, 0) if comp == PIZ else b"\x7f\x00" * 8 if comp == RLE else z64
        seeds[f"hostile_16float_c{comp}.exr"] = exr(f16, comp, (16384, 16384), tile=(16384, 16384), blocks=[data])
    four = [("A", FLOAT), ("B", FLOAT), ("G", FLOAT), ("R", FLOAT)]
    seeds["hostile_4float_tile.exr"] = exr(four, ZIP, (16384, 16384), tile=(16384, 16384), blocks=[z64])
    seeds["hostile_wide_scanline.exr"] = exr(many, ZIP, (16384, 64), blocks=[z64])
    y = [("Y", HALF)]
    seeds["hostile_offsets_past_end.exr"] = exr(y, NONE, (4, 2), blocks=[b"\0" * 8] * 2, offsets=[1 << 40, 7])
    seeds["hostile_offset_into_header.exr"] = exr(y, NONE, (4, 2), blocks=[b"\0" * 8] * 2, offsets=[8, 8])
    seeds["hostile_lying_chunk_size.exr"] = exr(y, ZIP, (4, 16), blocks=[b"\xff\xff\xff\x7f" + z64])
    seeds["hostile_more_chunks_than_file.exr"] = exr(y, NONE, (1, 1 << 20), blocks=[b"\0\0"])
    seeds["hostile_huge_window.exr"] = exr(y, NONE, (1 << 30, 1 << 30), blocks=[b"\0\0"])
    seeds["hostile_piz_bitmap.exr"] = exr(y, PIZ, (8, 8), blocks=[struct.pack("<HHI", 0, 8191, 0) + b"\xff" * 8192])
    for p in sorted((DATA / "exr").glob("*.exr")) + sorted((DATA / "thermal").glob("*.exr")):
        if p.stat().st_size <= 64 << 10:
            seeds[p.name] = p.read_bytes()
    return seeds


def exr_blocks(path: Path):
    """(compression, channel sizes, blocks as (w, h, data)) of a single-part EXR file."""
    b = path.read_bytes()
    pos, attrs = 8, {}
    while b[pos] != 0:
        name_end = b.index(b"\0", pos)
        kind_end = b.index(b"\0", name_end + 1)
        (n,) = struct.unpack_from("<i", b, kind_end + 1)
        attrs[b[pos:name_end].decode()] = b[kind_end + 5 : kind_end + 5 + n]
        pos = kind_end + 5 + n
    pos += 1
    if b[4:8] != struct.pack("<I", 2) and b[4:8] != struct.pack("<I", 2 | 0x200):
        return None  # multi-part, deep, long names: not needed for seeds
    chans, cl = [], attrs["channels"]
    i = 0
    while cl[i] != 0:
        e = cl.index(b"\0", i)
        (t,) = struct.unpack_from("<i", cl, e + 1)
        chans.append(SIZE[t])
        i = e + 17
    comp = attrs["compression"][0]
    x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    tiled = "tiles" in attrs
    if tiled:
        tw, th, mode = struct.unpack("<IIB", attrs["tiles"][:9])
        if mode & 0xF:
            return None
        count = -(-w // tw) * -(-h // th)
    else:
        count = -(-h // LINES.get(comp, 1))
    offsets = struct.unpack_from(f"<{count}Q", b, pos)
    out = []
    for o in offsets:
        if tiled:
            tx, ty, _, _, size = struct.unpack_from("<5i", b, o)
            bw, bh = min(tw, w - tx * tw), min(th, h - ty * th)
            out.append((bw, bh, b[o + 20 : o + 20 + size]))
        else:
            y, size = struct.unpack_from("<2i", b, o)
            bh = min(LINES[comp], y1 - y + 1)
            out.append((w, bh, b[o + 8 : o + 8 + size]))
    return comp, chans, out


def block_header(w: int, h: int, sizes: list[int], selected: int) -> bytes | None:
    """The 4 bytes `fuzz/src/lib.rs::block` reads back as (w, h, sizes, selected)."""
    n = len(sizes)
    if not (1 <= w <= 512 and 1 <= h <= 64 and 1 <= n <= 6):
        return None
    bits = 0
    for i, s in enumerate(sizes):
        bit = 1 << (3 + i % 5)
        if i >= 5 and bool(bits & bit) != (s == 4):
            return None
        if s == 4:
            bits |= bit
    return bytes([(w - 1) & 0xFF, (w - 1) >> 8 | (h - 1) << 1, (n - 1) | bits, selected])


def block_seeds(compressions) -> dict[str, bytes]:
    seeds = {}
    for p in sorted((DATA / "exr").glob("*.exr")) + sorted((DATA / "thermal").glob("*.exr")):
        try:
            got = exr_blocks(p)
        except (KeyError, struct.error, ValueError, IndexError):
            continue
        if got is None or got[0] not in compressions:
            continue
        comp, sizes, blocks = got
        for k, (w, h, data) in enumerate(blocks[:6]):
            head = block_header(w, h, sizes, k % len(sizes))
            if head is not None and len(data) != w * h * sum(sizes) and len(data) < 64 << 10:
                seeds[f"{p.stem}_{k}"] = head + data
    return seeds


# ------------------------------------------------------------------------------------ PNG


def chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))


def png(w, h, depth, colour, rows: bytes, extra=b"", interlace=0, split=1) -> bytes:
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, interlace)
    z = zlib.compress(rows)
    step = -(-len(z) // split)
    idats = b"".join(chunk(b"IDAT", z[i : i + step]) for i in range(0, len(z), step))
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + extra + idats + chunk(b"IEND", b"")


def png_rows(w, h, depth, colour, interlace=0) -> bytes:
    spp = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[colour]
    row_bytes = -(-w * spp * depth // 8)
    if not interlace:
        return b"".join(bytes([y % 5]) + bytes((x * 31 + y) & 0xFF for x in range(row_bytes)) for y in range(h))
    out = b""
    for x0, y0, dx, dy in [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)]:
        pw, ph = max(0, -(-(w - x0) // dx)), max(0, -(-(h - y0) // dy))
        if pw and ph:
            rb = -(-pw * spp * depth // 8)
            out += b"".join(b"\0" + bytes((x + y) & 0xFF for x in range(rb)) for y in range(ph))
    return out


def png_seeds() -> dict[str, bytes]:
    seeds = {}
    plte = chunk(b"PLTE", bytes(range(48)))
    for colour, depths in {0: (1, 2, 4, 8, 16), 2: (8, 16), 3: (1, 2, 4, 8), 4: (8, 16), 6: (8, 16)}.items():
        for depth in depths:
            for interlace in (0, 1):
                extra = plte if colour == 3 else b""
                rows = png_rows(11, 7, depth, colour, interlace)
                seeds[f"c{colour}_d{depth}_i{interlace}.png"] = png(11, 7, depth, colour, rows, extra, interlace)
    grey_rows = png_rows(9, 5, 16, 0)
    seeds["trns_grey16.png"] = png(9, 5, 16, 0, grey_rows, chunk(b"tRNS", b"\0\x07"))
    seeds["trns_palette.png"] = png(9, 5, 8, 3, png_rows(9, 5, 8, 3), plte + chunk(b"tRNS", bytes(16)))
    seeds["split_idat.png"] = png(9, 5, 16, 0, grey_rows, split=4)
    iccp = chunk(b"iCCP", b"icc\0\0" + zlib.compress(b"\0" * (8 << 20)))
    seeds["iccp_8mb.png"] = png(9, 5, 16, 0, grey_rows, iccp)
    seeds["ztxt.png"] = png(9, 5, 16, 0, grey_rows, chunk(b"zTXt", b"Comment\0\0" + zlib.compress(b"x" * (1 << 20))))
    seeds["exif.png"] = png(9, 5, 16, 0, grey_rows, chunk(b"eXIf", b"MM\0*" + bytes(200)))
    seeds["unknown_ancillary.png"] = png(9, 5, 16, 0, grey_rows, chunk(b"teSt", bytes(500)))
    huge = struct.pack(">IIBBBBB", 2**31 - 1, 2**31 - 1, 16, 6, 0, 0, 0)
    seeds["hostile_huge_ihdr.png"] = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", huge) + chunk(b"IDAT", zlib.compress(b"\0" * 64))
    wide = struct.pack(">IIBBBBB", 1 << 24, 1, 16, 6, 0, 0, 0)
    seeds["hostile_wide_row.png"] = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", wide) + chunk(b"IDAT", zlib.compress(b"\0" * 64))
    seeds["hostile_short_idat.png"] = png(4096, 4096, 16, 6, b"\0" * 100)
    seeds["hostile_chunk_length.png"] = png(9, 5, 16, 0, grey_rows)[:33] + struct.pack(">I", 0x7FFFFFFF) + b"teSt" + bytes(16)
    for p in sorted((DATA / "png").glob("*.png")):
        if p.stat().st_size <= 16 << 10:
            seeds[p.name] = p.read_bytes()
    return seeds


# ----------------------------------------------------------------------------------- TIFF

BYTE, ASCII, SHORT, LONG, RATIONAL = 1, 2, 3, 4, 5
LONG8 = 16


def tiff(pages, big_endian=False, bigtiff=False) -> bytes:
    """A TIFF of `pages`, each (entries, data) with entries (tag, type, values); a value of
    -1 in StripOffsets/TileOffsets (273/324) is replaced by the page data's offset plus the
    value's index times `len(data) // count` (equal chunks, in order)."""
    e = ">" if big_endian else "<"
    fmt = {BYTE: "B", SHORT: "H", LONG: "I", LONG8: "Q"}
    word = "Q" if bigtiff else "I"
    head_len = 16 if bigtiff else 8
    out = bytearray(
        (b"MM" if big_endian else b"II")
        + (struct.pack(e + "HHHQ", 43, 8, 0, head_len) if bigtiff else struct.pack(e + "HI", 42, head_len))
    )
    for k, (entries, data) in enumerate(pages):
        ifd_pos = len(out)
        entry_len = 20 if bigtiff else 12
        inline = 8 if bigtiff else 4
        ifd_len = (8 if bigtiff else 2) + entry_len * len(entries) + (8 if bigtiff else 4)
        extra_pos = ifd_pos + ifd_len
        packed_values = []
        for _tag, kind, values in entries:
            packed_values.append(b"".join(struct.pack(e + fmt[kind], max(v, 0)) for v in values))
        data_pos = extra_pos + sum(len(p) for p in packed_values if len(p) > inline)
        ifd, extras = bytearray(), bytearray()
        ifd += struct.pack(e + ("Q" if bigtiff else "H"), len(entries))
        for (tag, kind, values), packed in zip(entries, packed_values):
            if tag in (273, 324):
                n = len(values)
                packed = b"".join(
                    struct.pack(e + fmt[kind], data_pos + i * (len(data) // n) if v == -1 else v) for i, v in enumerate(values)
                )
            if len(packed) > inline:
                ifd += struct.pack(e + "HH" + word + word, tag, kind, len(values), extra_pos + len(extras))
                extras += packed
            else:
                ifd += struct.pack(e + "HH" + word, tag, kind, len(values)) + packed.ljust(inline, b"\0")
        next_pos = 0 if k == len(pages) - 1 else data_pos + len(data)
        ifd += struct.pack(e + word, next_pos)
        out += ifd + extras + data
    return bytes(out)


def grey_page(w, h, bits=16, rows_per_strip=None, compression=1, fmt=1, predictor=1, big_endian=False, spp=1, planar=1, tile=None):
    e = ">" if big_endian else "<"
    code = {(8, 1): "B", (16, 1): "H", (32, 1): "I", (16, 2): "h", (32, 3): "f", (64, 3): "d", (16, 3): "e"}[(bits, fmt)]
    samples = [((x * 3 + y * 5 + s * 7) % 200) for y in range(h) for x in range(w) for s in range(spp)]
    if planar == 2:
        samples = [((x * 3 + y * 5 + s * 7) % 200) for s in range(spp) for y in range(h) for x in range(w)]
    raw = struct.pack(e + code * len(samples), *samples)
    entries = [(256, LONG, [w]), (257, LONG, [h]), (258, SHORT, [bits] * spp), (259, SHORT, [compression])]
    entries += [(262, SHORT, [1 if spp in (1, 2) else 2]), (277, SHORT, [spp]), (284, SHORT, [planar])]
    if predictor != 1:
        entries.append((317, SHORT, [predictor]))
    if spp in (2, 4):
        entries.append((338, SHORT, [2]))
    entries.append((339, SHORT, [fmt] * spp))
    if tile is None:
        rps = rows_per_strip or h
        row = w * bits // 8 * (1 if planar == 2 else spp)
        strips = [raw[i : i + rps * row] for i in range(0, len(raw), rps * row)]
        data = [zlib.compress(s) if compression == 8 else s for s in strips]
        if len({len(d) for d in data}) > 1:  # equal-size chunks for the offset rule
            data = [d.ljust(max(len(x) for x in data), b"\0") for d in data]
        entries += [(273, LONG, [-1] * len(data)), (278, LONG, [rps]), (279, LONG, [len(d) for d in data])]
    else:
        tw, th = tile
        tiles = []
        for ty in range(0, h, th):
            for tx in range(0, w, tw):
                t = b""
                for y in range(ty, ty + th):
                    for x in range(tx, tx + tw):
                        v = ((x * 3 + y * 5) % 200) if x < w and y < h else 0
                        t += struct.pack(e + code * spp, *([v] * spp))
                tiles.append(zlib.compress(t) if compression == 8 else t)
        size = max(len(t) for t in tiles)
        data = [t.ljust(size, b"\0") for t in tiles]
        entries += [(322, LONG, [tw]), (323, LONG, [th]), (324, LONG, [-1] * len(data)), (325, LONG, [len(d) for d in data])]
    return sorted(entries), b"".join(data)


def tiff_seeds() -> dict[str, bytes]:
    s = {}
    for be in (False, True):
        for big in (False, True):
            tag = f"{'be' if be else 'le'}_{'big' if big else 'classic'}"
            s[f"grey16_{tag}.tif"] = tiff([grey_page(7, 5, big_endian=be)], be, big)
            s[f"deflate_strips_{tag}.tif"] = tiff([grey_page(7, 9, rows_per_strip=2, compression=8, big_endian=be)], be, big)
    s["float32_pred3.tif"] = tiff([grey_page(8, 4, 32, fmt=3, predictor=3)])
    s["float16.tif"] = tiff([grey_page(8, 4, 16, fmt=3)])
    s["float64.tif"] = tiff([grey_page(5, 3, 64, fmt=3)])
    s["int16_pred2.tif"] = tiff([grey_page(8, 4, 16, fmt=2, predictor=2)])
    s["u8_rgb.tif"] = tiff([grey_page(5, 4, 8, spp=3)])
    s["u16_rgba_planar.tif"] = tiff([grey_page(5, 4, 16, spp=4, planar=2, rows_per_strip=2)])
    s["u16_tiles.tif"] = tiff([grey_page(20, 18, 16, tile=(16, 16))])
    s["u16_rgba_tiles_deflate.tif"] = tiff([grey_page(20, 9, 16, spp=4, tile=(16, 16), compression=8)])
    s["u32.tif"] = tiff([grey_page(4, 4, 32)])
    s["three_pages.tif"] = tiff([grey_page(4, 3), grey_page(4, 3, 8), grey_page(5, 2, 32, fmt=3)])
    big_claim, _ = grey_page(2, 2, 64, fmt=3, spp=4)
    big_claim = [(t, k, [16384] if t in (256, 257, 278) else v) for t, k, v in big_claim]
    s["hostile_rgba_f64_16k.tif"] = tiff([(big_claim, b"\0" * 16)])
    one_strip, _ = grey_page(2, 2, 16, spp=4, compression=8)
    one_strip = [(t, k, [16384] if t in (256, 257, 278) else v) for t, k, v in one_strip]
    s["hostile_one_deflate_strip_16k.tif"] = tiff([(one_strip, zlib.compress(b"\0" * (4 << 20)))])
    zero_rps, data = grey_page(4, 4)
    s["hostile_zero_rows_per_strip.tif"] = tiff([([(t, k, [0] if t == 278 else v) for t, k, v in zero_rps], data)])
    zero_tile, data = grey_page(20, 18, 16, tile=(16, 16))
    s["hostile_zero_tile.tif"] = tiff([([(t, k, [0] if t == 322 else v) for t, k, v in zero_tile], data)])
    past, data = grey_page(4, 4)
    s["hostile_offset_past_end.tif"] = tiff([([(t, k, [1 << 30] if t == 273 else v) for t, k, v in past], data)])
    lying, data = grey_page(4, 4, compression=8)
    s["hostile_lying_byte_count.tif"] = tiff([([(t, k, [0x7FFFFFFF] if t == 279 else v) for t, k, v in lying], data)])
    many, data = grey_page(3, 3)
    s["hostile_many_strips.tif"] = tiff([([(t, k, [1] if t == 278 else v) for t, k, v in many], data)])
    bits12, data = grey_page(4, 4)
    s["bits12.tif"] = tiff([([(t, k, [12] if t == 258 else v) for t, k, v in bits12], data[:24])])
    for d in ("tiff", "thermal"):
        for p in sorted((DATA / d).glob("*.tif*")):
            if p.stat().st_size <= 16 << 10:
                s[p.name] = p.read_bytes()
    return s


# ----------------------------------------------------------------------------------- main


# ------------------------------------------------------------------------------ FLIR FFF / R-JPEG


def fff(records, big_endian=False, version=100, entries=None) -> bytes:
    """An FFF frame: 64-byte header, directory, then `records` ((type, body), in order); each
    record's own first word (its byte order) is part of its body."""
    e = ">" if big_endian else "<"
    n = len(records) if entries is None else entries
    head = bytearray(64)
    head[:4] = b"FFF\0"
    head[4:8] = b"FLIR"
    head[20:32] = struct.pack(e + "III", version, 64, n)
    pos = 64 + 32 * len(records)
    directory = b""
    for kind, body in records:
        directory += struct.pack(e + "HHIIII", kind, 1, 100, 1, pos, len(body)) + bytes(12)
        pos += len(body)
    return bytes(head) + directory + b"".join(body for _, body in records)


def raw_record(w, h, image: bytes, order="<") -> bytes:
    return struct.pack(order + "HHH", 2, w, h) + bytes(26) + image


def camera_record(order="<", r2=0.0125, b=1428.0, emissivity=0.95, length=0x468) -> bytes:
    rec = bytearray(length)
    fields = {0x20: emissivity, 0x24: 1.0, 0x28: 293.15, 0x2C: 293.15, 0x30: 293.15, 0x34: 1.0, 0x3C: 0.5,
              0x58: 17096.0, 0x5C: b, 0x60: 1.0, 0x70: 0.006569, 0x74: 0.01262, 0x78: -0.002276, 0x7C: -0.00667,
              0x80: 1.9, 0x30C: r2}
    rec[0:2] = struct.pack(order + "H", 2)
    for at, value in fields.items():
        if at + 4 <= length:
            rec[at:at + 4] = struct.pack(order + "f", value)
    if 0x30C <= length:
        rec[0x308:0x30C] = struct.pack(order + "i", -370)
    if 0x38E <= length:
        rec[0x384:0x38E] = struct.pack(order + "IIh", 1541416483, 84, -60)
    rec[0xD4:0xDD] = b"Duo Pro R"
    return bytes(rec[:length])


def flir_small_frames() -> dict[str, bytes]:
    w, h = 8, 6
    counts = [(x * 37 + y * 11 + 2600) & 0xFFFF for y in range(h) for x in range(w)]
    le = b"".join(struct.pack("<H", c) for c in counts)
    be_rows = b"".join(b"\0" + b"".join(struct.pack(">H", c) for c in counts[y * w:(y + 1) * w]) for y in range(h))
    swapped_rows = b"".join(b"\0" + b"".join(struct.pack("<H", c) for c in counts[y * w:(y + 1) * w]) for y in range(h))
    tiff_image = tiff([grey_page(w, h)])
    cam = camera_record()
    frames = {
        "raw_le": fff([(1, raw_record(w, h, le)), (0x20, cam)]),
        "raw_be_dir": fff([(0x20, camera_record(">")), (1, raw_record(w, h, le))], big_endian=True),
        "raw_be_record": fff([(1, raw_record(w, h, b"".join(struct.pack(">H", c) for c in counts), ">"))]),
        "png_swapped": fff([(1, raw_record(w, h, png(w, h, 16, 0, swapped_rows))), (0x20, cam)]),
        "png_be": fff([(1, raw_record(w, h, png(w, h, 16, 0, be_rows), ">"))]),
        "png_rgb": fff([(1, raw_record(w, h, png(w, h, 8, 2, png_rows(w, h, 8, 2))))]),
        "tiff": fff([(1, raw_record(w, h, tiff_image))]),
        "csq_jpegls": fff([(1, raw_record(w, h, b"\xff\xd8\xff\xf7" + bytes(40)))]),
        "csq_flat": fff([(1, raw_record(w, h, jls_flat(w, h))), (0x20, cam)]),
        "csq_flat_restarts": fff([(1, raw_record(w, h, jls_flat(w, h, restart=2)))]),
        # hostile
        "huge_claim": fff([(1, raw_record(65535, 65535, le))]),
        "zeroed_raw": fff([(1, bytes(32) + le)]),
        "zeroed_camera": fff([(1, raw_record(w, h, le)), (0x20, bytes(0x468))]),
        "short_camera": fff([(1, raw_record(w, h, le)), (0x20, camera_record(length=0x100))]),
        "bad_planck": fff([(1, raw_record(w, h, le)), (0x20, camera_record(r2=0.0, b=-1.0, emissivity=7.0))]),
        "many_entries": fff([(1, raw_record(w, h, le))], entries=100000),
        "bad_version": fff([(1, raw_record(w, h, le))], version=7),
        "short_record": fff([(1, raw_record(w, h, le))])[:-5],
        "dims_mismatch": fff([(1, raw_record(w + 1, h, png(w, h, 16, 0, be_rows), ">"))]),
    }
    frames["seq"] = frames["raw_le"] + frames["raw_be_dir"] + frames["png_swapped"]
    frames["csq"] = frames["csq_flat"] * 3
    frames["csq_cut"] = (frames["csq_flat"] * 3)[:-20]
    frames["seq_junk"] = frames["raw_le"] + b"FFF\0" + bytes(70)
    return frames


def fff_seeds() -> dict[str, bytes]:
    seeds = flir_small_frames()
    for name in ("flirpy_frame_000000.fff", "flirpy_frame_000000_le.fff"):
        real = (DATA / "radiometric" / name).read_bytes()
        seeds[f"real_{name}_head"] = real[:4096]  # header, directory, first counts: truncated
    return seeds


def jpeg_with(fff_frame: bytes, segment=4000, order=None) -> bytes:
    """A JPEG carrying `fff_frame` in FLIR APP1 segments (in `order` of indices), no image."""
    parts = [fff_frame[i:i + segment] for i in range(0, len(fff_frame), segment)] or [b""]
    last = len(parts) - 1
    segs = [b"\xff\xe1" + struct.pack(">H", len(p) + 10) + b"FLIR\0\x01" + bytes([i, last]) + p
            for i, p in enumerate(parts)]
    order = range(len(segs)) if order is None else order
    app0 = b"\xff\xe0" + struct.pack(">H", 16) + b"JFIF\0\x01\x01" + bytes(7)
    return b"\xff\xd8" + app0 + b"".join(segs[i] for i in order) + b"\xff\xda\x00\x02\xff\xd9"


def rjpeg_seeds() -> dict[str, bytes]:
    frames = flir_small_frames()
    seeds = {f"jpeg_{k}": jpeg_with(v, segment=64) for k, v in frames.items() if not k.startswith("seq")}
    seeds["jpeg_reordered"] = jpeg_with(frames["png_swapped"], segment=100, order=[2, 0, 1, 3, 4, 5])
    seeds["jpeg_missing"] = jpeg_with(frames["raw_le"], segment=100, order=[0, 2])
    seeds["jpeg_plain"] = b"\xff\xd8\xff\xe0\x00\x10JFIF\x00\x01\x01" + bytes(7) + b"\xff\xd9"
    for name in ("readthermal_flir_ax8.jpg", "readthermal_flir_example.jpg"):
        real = (DATA / "radiometric" / name).read_bytes()
        seeds[f"real_{name}_head"] = real[:8192]
    return seeds


# -------------------------------------------------------------------------------- JPEG-LS


def jls_bits(bits: list[int]) -> bytes:
    """Bits packed most significant first, a 0 bit stuffed after every 0xFF (T.87 §9.1)."""
    out, byte, count = bytearray(), 0, 0
    for bit in bits:
        byte, count = byte << 1 | bit, count + 1
        if count == (7 if out and out[-1] == 0xFF else 8):
            out.append(byte)
            byte, count = 0, 0
    if count or out.endswith(b"\xff"):  # pad with zeros; an 0xFF is always followed by a stuffed 0 bit
        out.append(byte << ((7 if out and out[-1] == 0xFF else 8) - count))
    return bytes(out)


def jls_flat(w: int, h: int, precision: int = 16, near: int = 0, preset: bytes = b"", restart: int = 0,
             extra: bytes = b"") -> bytes:
    """A JPEG-LS stream of a w x h image of zeros: every line one run to its end (the run mode's
    codes for ``w`` samples, RUNindex carried from line to line), hand-coded."""
    j = [0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 9, 10, 11, 12, 13, 14, 15]
    scans, index = [], 0
    for first in range(0, h, restart or h):
        bits, index = [], 0  # a restart interval starts afresh
        for _ in range(first, min(h, first + (restart or h))):
            left = w
            while left >= 1 << j[index]:
                bits.append(1)
                left -= 1 << j[index]
                index = min(index + 1, 31)
            if left:
                bits.append(1)
        scans.append(jls_bits(bits))
    body = b"".join(scan + (bytes([0xFF, 0xD0 + k % 8]) if k + 1 < len(scans) else b"") for k, scan in enumerate(scans))
    sof = b"\xff\xf7" + struct.pack(">HBHHB", 11, precision, h, w, 1) + b"\x01\x11\x00"
    sos = b"\xff\xda" + struct.pack(">HBBBBBB", 8, 1, 1, 0, near, 0, 0)
    dri = b"\xff\xdd\x00\x04" + struct.pack(">H", restart) if restart else b""
    lse = b"\xff\xf8" + struct.pack(">H", 2 + len(preset)) + preset if preset else b""
    return b"\xff\xd8" + extra + sof + lse + dri + sos + body + b"\xff\xd9"


def jpegls_seeds() -> dict[str, bytes]:
    """Hand-coded flat images with every header variant; hostile headers; and, when imagecodecs
    (CharLS) is installed, coded images of noise and gradients at several precisions and NEARs."""
    seeds = {
        "flat_16bit": jls_flat(40, 9),
        "flat_8bit": jls_flat(17, 5, precision=8),
        "flat_2bit": jls_flat(3, 3, precision=2),
        "flat_long_line": jls_flat(5000, 2),
        "flat_near3": jls_flat(33, 4, near=3),
        "flat_restarts": jls_flat(30, 20, restart=3),
        "flat_preset": jls_flat(20, 4, preset=struct.pack(">BHHHHH", 1, 40000, 5, 9, 30, 40)),
        "flat_comment_spiff": jls_flat(20, 4, extra=b"\xff\xfe\x00\x05abc" + b"\xff\xe8\x00\x04sp"),
        # hostile
        "huge_claim": jls_flat(8, 1)[:7] + struct.pack(">HH", 65535, 65535) + jls_flat(8, 1)[11:],
        "zero_lines": jls_flat(8, 1)[:7] + struct.pack(">H", 0) + jls_flat(8, 1)[9:],
        "mapping_table": jls_flat(8, 2, preset=struct.pack(">BBH", 2, 1, 2) + bytes(8)),
        "bad_thresholds": jls_flat(8, 2, preset=struct.pack(">BHHHHH", 1, 0, 900, 3, 2, 1)),
        "huge_near": jls_flat(8, 2, near=255),
        "three_components": jls_flat(8, 2)[:11] + b"\x03" + jls_flat(8, 2)[12:],
        "truncated": jls_flat(400, 30)[:20],
        "restart_out_of_order": jls_flat(30, 20, restart=3).replace(b"\xff\xd1", b"\xff\xd5", 1),
    }
    try:
        import imagecodecs
    except ImportError:
        return seeds
    for name, image in coded_images().items():
        for near in (0, 2):
            seeds[f"charls_{name}_near{near}"] = bytes(imagecodecs.jpegls_encode(image, level=near or None))
    return seeds


def coded_images():
    """Small images for CharLS to code (numpy comes with imagecodecs)."""
    import numpy as np

    rng = np.random.default_rng(39)
    y, x = np.mgrid[0:24, 0:37]
    return {
        "noise16": rng.integers(0, 1 << 16, (24, 37)).astype(np.uint16),
        "noise12": rng.integers(0, 1 << 12, (24, 37)).astype(np.uint16),
        "noise8": rng.integers(0, 256, (24, 37)).astype(np.uint8),
        "gradient": (9000 + 30 * y + 7 * x).astype(np.uint16),
        "plateaus": np.where(rng.random((24, 37)) < 0.2, 6000 + rng.integers(0, 3, (24, 37)) * 250, 6000).astype(np.uint16),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "seeds")
    args = ap.parse_args()
    targets = {
        "decode_exr": exr_seeds(),
        "decode_png": png_seeds(),
        "decode_tiff": tiff_seeds(),
        "exr_piz_block": block_seeds({PIZ}),
        "exr_zip_block": block_seeds({ZIP, ZIPS}),
        "decode_fff": fff_seeds(),
        "decode_rjpeg": rjpeg_seeds(),
        "temperatures_fff": {**fff_seeds(), **rjpeg_seeds()},
        "jpegls_stream": jpegls_seeds(),
    }
    for target, seeds in targets.items():
        d = args.out / target
        d.mkdir(parents=True, exist_ok=True)
        for name, data in seeds.items():
            if target == "temperatures_fff":
                for sel in (0, 9):  # page 0 in Celsius, page 0 in kelvin
                    (d / f"{name}.s{sel}").write_bytes(bytes([sel]) + data)
            elif target.startswith("decode_"):
                # selector 0 (defaults) and 2 ("R"), and one under the tight budget
                for sel in (0, 2, 130):
                    (d / f"{name}.s{sel}").write_bytes(bytes([sel]) + data)
            else:
                (d / name).write_bytes(data)
        print(f"{target}: {len(seeds)} seeds, {sum(len(v) for v in seeds.values())} bytes")


if __name__ == "__main__":
    main()
