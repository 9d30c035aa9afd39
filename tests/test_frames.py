"""Frame loading: decoded arrays equal independent decoders' (OpenEXR C++, tifffile, pypng).

Lossless codecs must be bit-identical; DWAA/DWAB must equal OpenEXR's own decode.
"""

from __future__ import annotations

import shutil
import threading
from pathlib import Path

import numpy as np
import pytest

from irfidelity.errors import FrameError, FidelityError
from irfidelity.frames import FrameSequence, list_channels, load_frame, natural_key, page_count

OpenEXR = pytest.importorskip("OpenEXR")
tifffile = pytest.importorskip("tifffile")
png = pytest.importorskip("png")

DATA = Path(__file__).parent / "data"


def bits(a: np.ndarray) -> np.ndarray:
    """Bit patterns, so NaN payloads and -0.0 compare exactly."""
    if a.dtype.kind == "f":
        return a.view({2: np.uint16, 4: np.uint32, 8: np.uint64}[a.dtype.itemsize])
    return a


def assert_identical(ours: np.ndarray, ref: np.ndarray) -> None:
    assert ours.dtype == ref.dtype, (ours.dtype, ref.dtype)
    assert ours.shape == ref.shape, (ours.shape, ref.shape)
    assert np.array_equal(bits(ours), bits(ref))


def exr_reference(path: Path) -> list[tuple[str, dict[str, np.ndarray]]]:
    """(part name, {channel: pixels}) per part, decoded by OpenEXR (C++)."""
    out = []
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for p in f.parts:
            out.append((p.name(), {k: np.asarray(v.pixels) for k, v in p.channels.items()}))
    return out


# ------------------------------------------------------------------------ OpenEXR

FLAT_EXR = sorted(
    p.name
    for p in (DATA / "exr").glob("*.exr")
    if p.name not in {"openexr_11.deep.exr", "openexr_comp_b44.exr"}
)


@pytest.mark.parametrize("name", FLAT_EXR)
def test_exr_every_channel_equals_openexr(name: str) -> None:
    path = DATA / "exr" / name
    parts = exr_reference(path)
    assert len(parts) == 1
    channels = parts[0][1]
    assert sorted(list_channels(path)) == sorted(channels)
    for ch, ref in channels.items():
        assert_identical(load_frame(path, channel=ch), ref)


def test_exr_thermal_frames_equal_openexr_and_png() -> None:
    counts = load_frame(DATA / "thermal/cptv_v2_frame000.png")
    f32 = load_frame(DATA / "thermal/cptv_v2_frame000_counts_f32_zip.exr")
    assert_identical(f32, exr_reference(DATA / "thermal/cptv_v2_frame000_counts_f32_zip.exr")[0][1]["Y"])
    assert np.array_equal(f32, counts.astype(np.float32))
    f16 = load_frame(DATA / "thermal/cptv_v2_frame001_counts_f16_piz.exr")
    assert f16.dtype == np.float16  # float16 stays float16
    assert_identical(f16, exr_reference(DATA / "thermal/cptv_v2_frame001_counts_f16_piz.exr")[0][1]["Y"])
    c1 = load_frame(DATA / "thermal/cptv_v2_frame001.png")
    assert np.array_equal(f16, (c1 / 1000).astype(np.float16))


def _rgba_source() -> dict[str, np.ndarray]:
    return exr_reference(DATA / "exr/openexr_comp_zip.exr")[0][1]


COMPRESSIONS = ["NO", "RLE", "ZIPS", "ZIP", "PIZ", "PXR24", "B44", "B44A", "DWAA", "DWAB"]


@pytest.mark.parametrize("comp", COMPRESSIONS)
def test_exr_every_compression_equals_openexr(comp: str, tmp_path: Path) -> None:
    """Files written by OpenEXR itself in each compression: half RGBA, float, uint."""
    src = _rgba_source()
    rng = np.random.default_rng(7)
    chans = dict(src)
    h, w = src["R"].shape
    chans["depth"] = (src["G"].astype(np.float32) * 1000 + rng.normal(0, 1, (h, w))).astype(np.float32)
    ids = rng.integers(0, 2**32, size=(h, w), dtype=np.uint32)
    chans["id"] = ids.copy()
    path = tmp_path / f"{comp}.exr"
    OpenEXR.File({"compression": getattr(OpenEXR, f"{comp}_COMPRESSION")}, chans).write(str(path))
    ref = exr_reference(path)[0][1]
    for ch in ("R", "A", "depth", "id"):
        assert_identical(load_frame(path, channel=ch), ref[ch])
    if comp in {"NO", "RLE", "ZIPS", "ZIP", "PIZ"}:  # lossless: equal to the source too
        assert_identical(load_frame(path, channel="B"), src["B"])
        assert_identical(load_frame(path, channel="id"), ids)


@pytest.mark.parametrize("comp", ["ZIP", "PIZ", "B44A", "DWAB"])
def test_exr_tiled_written_by_openexr(comp: str, tmp_path: Path) -> None:
    src = _rgba_source()
    td = OpenEXR.TileDescription()
    td.xSize, td.ySize, td.mode = 64, 32, OpenEXR.ONE_LEVEL
    path = tmp_path / "tiled.exr"
    hdr = {"compression": getattr(OpenEXR, f"{comp}_COMPRESSION"), "type": OpenEXR.tiledimage, "tiles": td}
    OpenEXR.File(hdr, {"Y": src["G"]}).write(str(path))
    assert_identical(load_frame(path), exr_reference(path)[0][1]["Y"])


@pytest.mark.parametrize("comp", ["PIZ", "ZIP", "ZIPS"])
@pytest.mark.parametrize("tiled", [False, True])
def test_exr_piz_zip_noisy_multichannel_equal_openexr(comp: str, tiled: bool, tmp_path: Path) -> None:
    """Our own PIZ and ZIP decoders on data that stresses them: float noise (a ~65k-symbol
    Huffman alphabet with codes past 14 bits), random uint32 (16-bit wavelet), a constant
    half channel (runs), odd sizes with partial blocks; each channel alone."""
    rng = np.random.default_rng(11)
    h, w = 203, 517
    chans = {
        "A": rng.normal(0, 1, (h, w)).astype(np.float32),
        "B": rng.integers(0, 2**32, size=(h, w), dtype=np.uint32),
        "C": np.full((h, w), 0.25, dtype=np.float16),
        "Y": (np.add.outer(np.arange(h), np.arange(w)) / 100 + rng.normal(0, 0.01, (h, w))).astype(np.float16),
    }
    hdr = {"compression": getattr(OpenEXR, f"{comp}_COMPRESSION")}
    if tiled:
        td = OpenEXR.TileDescription()
        td.xSize, td.ySize, td.mode = 64, 48, OpenEXR.ONE_LEVEL
        hdr.update({"type": OpenEXR.tiledimage, "tiles": td})
    path = tmp_path / f"noisy_{comp}.exr"
    OpenEXR.File(hdr, dict(chans)).write(str(path))  # (the binding replaces dict values)
    ref = exr_reference(path)[0][1]
    for ch, src in chans.items():
        got = load_frame(path, channel=ch)
        assert_identical(got, ref[ch])
        assert_identical(got, src)


def test_exr_multipart(tmp_path: Path) -> None:
    a = np.arange(48 * 64, dtype=np.float32).reshape(48, 64)
    parts = [
        OpenEXR.Part({"compression": OpenEXR.ZIP_COMPRESSION}, {"Y": a}, name="left"),
        OpenEXR.Part({"compression": OpenEXR.PIZ_COMPRESSION}, {"Y": a * 2, "Z": a.astype(np.float16)}, name="right"),
    ]
    path = tmp_path / "mp.exr"
    OpenEXR.File(parts).write(str(path))
    assert list_channels(path) == ["left.Y", "right.Y", "right.Z"]
    assert_identical(load_frame(path, channel="left.Y"), a)
    assert_identical(load_frame(path, channel="right.Y"), a * 2)
    assert_identical(load_frame(path, channel="Z"), a.astype(np.float16))  # unique bare name
    with pytest.raises(FrameError, match="ambiguous.*left.Y, right.Y"):
        load_frame(path, channel="Y")
    with pytest.raises(FrameError, match="several channels"):
        load_frame(path)


def test_exr_data_window_and_layers() -> None:
    # data window (20, 20)-(197, 174): the array is the data window, as OpenEXR returns it
    z = load_frame(DATA / "exr/openexr_v1.7.test.1.exr", channel="Z")
    assert z.shape == (155, 178) and z.dtype == np.float32
    names = list_channels(DATA / "exr/tinyexr_flaga.exr")
    assert "Warstwa 1.R" in names and "Warstwa 2.A" in names
    assert load_frame(DATA / "exr/openexr_manifest_id.exr", channel="id").dtype == np.uint32


def test_exr_channel_rules() -> None:
    with pytest.raises(FrameError, match=r"openexr_comp_zip\.exr: several channels \(A, B, G, R\)"):
        load_frame(DATA / "exr/openexr_comp_zip.exr")
    with pytest.raises(FrameError, match=r"no channel 'Q'|no channel \"Q\""):
        load_frame(DATA / "exr/openexr_comp_zip.exr", channel="Q")
    # "Y" is the default when present among several channels
    y = load_frame(DATA / "exr/exrimages_TestImages_GrayRampsHorizontal.exr")
    assert y.shape == (800, 800)


def test_exr_unsupported_is_clear(tmp_path: Path) -> None:
    with pytest.raises(FrameError, match="openexr_11.deep.exr: unsupported: deep data"):
        load_frame(DATA / "exr/openexr_11.deep.exr", channel="R")
    with pytest.raises(FrameError, match="openexr_comp_b44.exr: .*subsampling"):
        load_frame(DATA / "exr/openexr_comp_b44.exr", channel="Y")
    # big enough to compress (a chunk stored raw is legal and decodes with any codec)
    a = np.tile(np.linspace(0, 1, 256, dtype=np.float32), (256, 1))
    for comp in ("HTJ2K32", "ZSTD"):
        if not hasattr(OpenEXR, f"{comp}_COMPRESSION"):
            continue
        path = tmp_path / f"{comp}.exr"
        OpenEXR.File({"compression": getattr(OpenEXR, f"{comp}_COMPRESSION")}, {"Y": a}).write(str(path))
        with pytest.raises(FrameError, match="unsupported compression"):
            load_frame(path)


# --------------------------------------------------------------------------- PNG

def pypng_read(path: Path) -> tuple[np.ndarray, int]:
    w, h, rows, info = png.Reader(filename=str(path)).read()
    a = np.vstack([np.asarray(r) for r in rows])
    dtype = np.uint16 if info["bitdepth"] > 8 else np.uint8
    planes = info["planes"]
    return a.reshape(h, w, planes).astype(dtype), planes


PNGS = sorted(str(p.relative_to(DATA)) for p in [*(DATA / "png").glob("*.png"), *(DATA / "thermal").glob("*.png")])


@pytest.mark.parametrize("name", PNGS)
def test_png_equals_pypng(name: str) -> None:
    path = DATA / name
    ref, planes = pypng_read(path)
    names = list_channels(path)
    if planes == 1:
        assert_identical(load_frame(path), ref[:, :, 0])
    for i, ch in enumerate(names[:planes]):
        assert_identical(load_frame(path, channel=ch), ref[:, :, i])
        assert_identical(load_frame(path, channel=str(i)), ref[:, :, i])


def test_png_colour_needs_channel() -> None:
    with pytest.raises(FrameError, match=r"pngsuite_basn2c16\.png: several channels \(R, G, B\)"):
        load_frame(DATA / "png/pngsuite_basn2c16.png")
    # grey + alpha defaults to the grey channel
    assert load_frame(DATA / "png/pngsuite_basn4a16.png").dtype == np.uint16


# -------------------------------------------------------------------------- TIFF

UNSUPPORTED_TIFF = {  # clear FrameError, not silent garbage (tiff crate limits)
    "imagetiff_12bit.cropped.tiff": "Gray\\(12\\)",
    "imagetiff_seq-1c-10b-6d739fa2.tiff": "Gray\\(10\\)",
    "imagetiff_seq-1c-12b-47c39b31.tiff": "Gray\\(12\\)",
    "imagetiff_seq-1c-14b-e883657f.tiff": "Gray\\(14\\)",
    "imagetiff_seq-1c-14b-hpredict-e883657f.tiff": "Gray\\(14\\)",
    "libtiffpic_flower-minisblack-10.tif": "Gray\\(10\\)",
    "libtiffpic_flower-minisblack-12.tif": "Gray\\(12\\)",
    "libtiffpic_flower-minisblack-14.tif": "Gray\\(14\\)",
    "imagetiff_int16_zstd.tif": "ZSTD",
}

TIFFS = sorted(
    str(p.relative_to(DATA))
    for p in [*(DATA / "tiff").glob("*.tif*"), *(DATA / "thermal").glob("*.tif*")]
    if p.name not in UNSUPPORTED_TIFF
)


def tifffile_pages(path: Path) -> list[np.ndarray]:
    with tifffile.TiffFile(str(path)) as t:
        return [p.asarray() for p in t.pages]


@pytest.mark.parametrize("name", TIFFS)
def test_tiff_equals_tifffile(name: str) -> None:
    path = DATA / name
    try:
        pages = tifffile_pages(path)
    except ValueError as e:  # e.g. LZW without imagecodecs
        pytest.skip(f"tifffile cannot decode {name}: {e}")
    assert page_count(path) == len(pages)
    n = len(pages)
    for page in sorted({*range(min(5, n)), max(n - 2, 0), n - 1}):
        ref = pages[page]
        if ref.ndim == 2:
            assert_identical(load_frame(path, page=page), ref)
        else:
            names = list_channels(path)
            planar = ref.shape[0] == len(names) and ref.shape[-1] != len(names)
            for c, ch in enumerate(names):
                want = ref[c] if planar else ref[..., c]
                assert_identical(load_frame(path, channel=ch, page=page), want)


@pytest.mark.parametrize("name,pattern", sorted(UNSUPPORTED_TIFF.items()))
def test_tiff_unsupported_is_clear(name: str, pattern: str) -> None:
    with pytest.raises(FrameError, match=f"{name}: unsupported.*{pattern}"):
        load_frame(DATA / "tiff" / name)


def test_tiff_layouts_and_byte_orders_agree() -> None:
    base = load_frame(DATA / "tiff/imagetiff_seq-1c-16b-bigendian-68f373a0.tiff")
    for v in ("deflate", "lzw", "multistrip", "tiled"):
        assert_identical(load_frame(DATA / f"tiff/imagetiff_seq-1c-16b-{v}-68f373a0.tiff"), base)


def test_thermal_png_tiff_exr_parity() -> None:
    stack = tifffile.imread(str(DATA / "thermal/cptv_v2_all100frames_uint16.tif"))
    assert page_count(DATA / "thermal/cptv_v2_all100frames_uint16.tif") == 100
    for i in (0, 1, 2, 3, 10, 11):
        p = load_frame(DATA / f"thermal/cptv_v2_frame{i:03d}.png")
        t = load_frame(DATA / "thermal/cptv_v2_all100frames_uint16.tif", page=i)
        assert_identical(p, t)
        assert_identical(t, stack[i])
    e = load_frame(DATA / "thermal/cptv_v2_frame000_counts_f32_zip.exr")
    assert np.array_equal(e, load_frame(DATA / "thermal/cptv_v2_frame000.png").astype(np.float32))
    ptw = tifffile.imread(str(DATA / "thermal/ptw_lwir_all100frames_uint16.tif"))
    assert_identical(load_frame(DATA / "thermal/ptw_lwir_all100frames_uint16.tif", page=1), ptw[1])
    assert_identical(load_frame(DATA / "thermal/ptw_lwir_frame001.png"), ptw[1])


# ------------------------------------------------------------------- errors, npy

def test_errors_name_the_path(tmp_path: Path) -> None:
    missing = tmp_path / "nope.png"
    with pytest.raises(FrameError, match="nope.png: cannot open"):
        load_frame(missing)
    with pytest.raises(FrameError, match="is a directory"):
        load_frame(tmp_path)
    junk = tmp_path / "junk.exr"
    junk.write_bytes(b"hello world, not an image")
    with pytest.raises(FrameError, match="junk.exr: unsupported file format"):
        load_frame(junk)
    empty = tmp_path / "empty.tif"
    empty.write_bytes(b"")
    with pytest.raises(FrameError, match="empty.tif: empty file"):
        load_frame(empty)
    with pytest.raises(FrameError, match="page 100 out of range"):
        load_frame(DATA / "thermal/cptv_v2_all100frames_uint16.tif", page=100)
    with pytest.raises(FrameError, match="page 1 out of range"):
        load_frame(DATA / "png/pngsuite_basn0g16.png", page=1)
    with pytest.raises(FrameError, match="page must be an integer in 0..2\\^63-1"):
        load_frame(DATA / "png/pngsuite_basn0g16.png", page=-1)
    # FrameError is a FidelityError (ValueError) and an OSError
    with pytest.raises(OSError):
        load_frame(missing)
    with pytest.raises(FidelityError):
        load_frame(missing)


def test_max_pixels_refused_before_decoding() -> None:
    for name in ("png/pngsuite_basn0g16.png", "thermal/cptv_v2_all100frames_uint16.tif"):
        with pytest.raises(FrameError, match="exceeds the limit of 100 pixels"):
            load_frame(DATA / name, max_pixels=100)
    with pytest.raises(FrameError, match="exceeds the limit of 1000 pixels"):
        load_frame(DATA / "exr/openexr_comp_zip.exr", channel="R", max_pixels=1000)
    assert load_frame(DATA / "png/pngsuite_basn0g16.png", max_pixels=1024).shape == (32, 32)


def test_npy(tmp_path: Path) -> None:
    a = np.arange(12, dtype=np.uint16).reshape(3, 4)
    np.save(tmp_path / "a.npy", a)
    assert_identical(load_frame(tmp_path / "a.npy"), a)
    stack = np.stack([a, a + 1])
    np.save(tmp_path / "s.npy", stack)
    assert_identical(load_frame(tmp_path / "s.npy", page=1), a + 1)
    assert page_count(tmp_path / "s.npy") == 2
    np.save(tmp_path / "i64.npy", a.astype(np.int64))
    with pytest.raises(FrameError, match="i64.npy: unsupported dtype int64"):
        load_frame(tmp_path / "i64.npy")
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(FrameError, match="obj.npy"):
        load_frame(tmp_path / "obj.npy")
    (tmp_path / "bad.npy").write_bytes(b"\x93NUMPY garbage")
    with pytest.raises(FrameError, match="bad.npy: corrupt"):
        load_frame(tmp_path / "bad.npy")
    raw = (tmp_path / "a.npy").read_bytes()
    (tmp_path / "cut.npy").write_bytes(raw[:-5])
    with pytest.raises(FrameError, match="cut.npy"):
        load_frame(tmp_path / "cut.npy")
    with pytest.raises(FrameError, match="exceeds the limit of 4 pixels"):
        load_frame(tmp_path / "a.npy", max_pixels=4)


def test_decoding_in_threads_gives_identical_frames() -> None:
    path = DATA / "exr/openexr_comp_piz.exr"
    want = load_frame(path, channel="G")
    results: list[np.ndarray] = []

    def work() -> None:
        for _ in range(3):
            results.append(load_frame(path, channel="G"))

    threads = [threading.Thread(target=work) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(results) == 9
    for r in results:
        assert_identical(r, want)


# ---------------------------------------------------------------- FrameSequence

def test_natural_key_orders_numbers() -> None:
    names = ["frame_10.png", "frame_2.png", "frame_1.png", "Frame_3.png"]
    assert sorted(names, key=natural_key) == ["frame_1.png", "frame_2.png", "Frame_3.png", "frame_10.png"]


@pytest.fixture()
def seq_dir(tmp_path: Path) -> Path:
    d = tmp_path / "seq"
    d.mkdir()
    for i, src in enumerate([0, 1, 2, 3, 10, 11]):
        shutil.copy(DATA / f"thermal/cptv_v2_frame{src:03d}.png", d / f"frame_{[2, 10, 1, 33, 4, 100][i]}.png")
    (d / "notes.txt").write_text("not a frame")
    return d


def test_sequence_directory_natural_order(seq_dir: Path) -> None:
    s = FrameSequence(seq_dir)
    assert s.names == ["frame_1.png", "frame_2.png", "frame_4.png", "frame_10.png", "frame_33.png", "frame_100.png"]
    assert len(s) == 6
    assert_identical(s[0], load_frame(DATA / "thermal/cptv_v2_frame002.png"))
    assert_identical(s[-1], load_frame(DATA / "thermal/cptv_v2_frame011.png"))
    frames = list(s)
    assert len(frames) == 6 and all(f.shape == (120, 160) for f in frames)
    sub = s[1:3]
    assert isinstance(sub, FrameSequence) and sub.names == ["frame_2.png", "frame_4.png"]
    assert_identical(sub[0], frames[1])
    with pytest.raises(IndexError):
        s[6]


def test_sequence_glob_and_list(seq_dir: Path) -> None:
    g = FrameSequence(str(seq_dir / "frame_1*.png"))
    assert g.names == ["frame_1.png", "frame_10.png", "frame_100.png"]
    paths = [seq_dir / "frame_33.png", seq_dir / "frame_1.png"]
    lst = FrameSequence(paths)
    assert lst.names == ["frame_33.png", "frame_1.png"]  # a list keeps its order
    assert_identical(lst[1], g[0])


def test_sequence_multipage_tiff() -> None:
    path = DATA / "thermal/cptv_v2_all100frames_uint16.tif"
    s = FrameSequence(path)
    assert len(s) == 100
    assert s.names[3] == "cptv_v2_all100frames_uint16.tif[3]"
    assert_identical(s[3], load_frame(DATA / "thermal/cptv_v2_frame003.png"))
    assert s.sources[5] == (str(path), 5)


def test_sequence_array() -> None:
    a = np.arange(2 * 3 * 4, dtype=np.float32).reshape(2, 3, 4)
    s = FrameSequence(a)
    assert len(s) == 2 and s.names == ["[0]", "[1]"]
    assert_identical(s[1], a[1])
    with pytest.raises(FrameError, match="3-D"):
        FrameSequence(a[0])


def test_sequence_channel_and_errors(tmp_path: Path) -> None:
    s = FrameSequence([DATA / "exr/openexr_comp_zip.exr", DATA / "exr/openexr_comp_piz.exr"], channel="R")
    assert_identical(s[0], s[1])
    with pytest.raises(FrameError, match="no such file or directory"):
        FrameSequence(tmp_path / "missing")
    with pytest.raises(FrameError, match="matches no files"):
        FrameSequence(str(tmp_path / "*.png"))
    with pytest.raises(FrameError, match="holds no frame files"):
        FrameSequence(tmp_path)
    bad = tmp_path / "d"
    bad.mkdir()
    (bad / "x.png").write_bytes(b"\x89PNG\r\n\x1a\n broken")
    s = FrameSequence(bad)  # lazy: listing works, decoding fails with the path
    with pytest.raises(FrameError, match="x.png"):
        s[0]
