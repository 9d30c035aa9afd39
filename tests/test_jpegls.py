"""irfidelity's JPEG-LS decoder (``rust/io/jpegls``) against CharLS, the reference codec.

Each stream is made by CharLS (imagecodecs, pillow-jpls) and decoded by irfidelity inside an
FFF frame, the only place irfidelity meets JPEG-LS: the counts must equal the image coded,
bit for bit when lossless and within NEAR when near-lossless, and equal CharLS's own
decoding in every case. The images exercise both coding modes: noise (regular mode), flat
areas (run mode, runs ending at the line's end and interrupted), gradients, and the edges of
the sizes and parameters.
"""

from __future__ import annotations

import struct

import imagecodecs
import numpy as np
import pytest

import irfidelity as irf
from flir_records import Frame, jpegls, with_restarts
from irfidelity.errors import FrameError
from test_radiometry import FFF_BE, _fff


def fff(stream: bytes, shape: tuple[int, int]) -> bytes:
    """A little-endian FFF frame whose raw-data record holds ``stream``."""
    rows, cols = shape
    return _fff(struct.pack("<HHH", 2, cols, rows) + bytes(26) + stream)


def decoded(tmp_path, stream: bytes, shape: tuple[int, int], **options) -> np.ndarray:
    path = tmp_path / "frame.fff"
    path.write_bytes(fff(stream, shape))
    return irf.load_frame(path, **options)


def images(rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Test images (uint16) named by what they exercise."""
    rows, cols = np.mgrid[0:48, 0:61]
    noise14 = rng.integers(0, 1 << 14, (48, 61))
    flat = np.full((48, 61), 7000)
    flat[10:20, 5:50] = 7100  # runs interrupted at the block's edges
    flat[30, ::7] = 0  # single samples breaking runs
    plateaus = (rng.integers(0, 4, (48, 61)) * 300 + 5000) * (rng.random((48, 61)) < 0.3) + 5000
    return {
        "noise 16-bit": rng.integers(0, 1 << 16, (48, 61)),
        "noise 14-bit": noise14,
        "smooth": 8000 + 40 * rows + 13 * cols + (rng.random((48, 61)) * 3).astype(int),
        "flat with blocks": flat,
        "plateaus": plateaus,
        "constant": np.full((48, 61), 12345),
        "zeros": np.zeros((48, 61), int),
        "full scale": np.where((rows + cols) % 2 == 0, 0, 65535),
        "thermal-like": (20000 + 800 * np.sin(rows / 6.0) * np.cos(cols / 9.0) + rng.normal(0, 12, (48, 61))).astype(int),
        "one pixel": np.array([[4242]]),
        "one row": rng.integers(0, 1 << 16, (1, 300)),
        "one column": rng.integers(0, 1 << 16, (300, 1)),
        "long runs": np.repeat(rng.integers(0, 3, (4, 1)) * 1000, 5000, axis=1),
    }


@pytest.mark.parametrize("name", list(images(np.random.default_rng(0))))
def test_lossless_counts_equal_the_image(tmp_path, name):
    image = images(np.random.default_rng(0))[name].astype(np.uint16)
    stream = imagecodecs.jpegls_encode(image)
    counts = decoded(tmp_path, stream, image.shape)
    assert counts.dtype == np.uint16
    np.testing.assert_array_equal(counts, image)


@pytest.mark.parametrize("bits", [2, 3, 5, 8, 10, 12, 15, 16])
def test_every_precision(tmp_path, bits):
    rng = np.random.default_rng(bits)
    image = rng.integers(0, 1 << bits, (37, 45)).astype(np.uint16)
    image[5:25, 3:40] = image[5, 3]  # a flat block: run mode at this precision too
    stream = jpegls(image, bits_per_sample=bits)
    np.testing.assert_array_equal(decoded(tmp_path, stream, image.shape), image)


@pytest.mark.parametrize("near", [1, 2, 3, 7, 30])
@pytest.mark.parametrize("name", ["noise 14-bit", "smooth", "plateaus", "thermal-like", "flat with blocks"])
def test_near_lossless_equals_charls_and_stays_within_near(tmp_path, name, near):
    image = images(np.random.default_rng(1))[name].astype(np.uint16)
    stream = imagecodecs.jpegls_encode(image, level=near)
    counts = decoded(tmp_path, stream, image.shape)
    np.testing.assert_array_equal(counts, imagecodecs.jpegls_decode(stream))
    assert np.abs(counts.astype(int) - image).max() <= near


@pytest.mark.parametrize("options", [
    dict(t1=5, t2=9, t3=30, reset=40),
    dict(t1=2, t2=3, t3=4, reset=3),
    dict(reset=255),
    dict(maxval=65535),
    dict(bits_per_sample=12, near_lossless=2, t1=20, t2=40, t3=80),
    dict(t1=300, t2=900, t3=4000, reset=1000),
], ids=str)
def test_preset_coding_parameters(tmp_path, options):
    rng = np.random.default_rng(2)
    image = (images(rng)["thermal-like"] % (1 << options.get("bits_per_sample", 16))).astype(np.uint16)
    image[::9] = image[::9, :1]  # some flat lines
    stream = jpegls(image, **options)
    assert b"\xff\xf8" in stream  # CharLS wrote an LSE segment
    counts = decoded(tmp_path, stream, image.shape)
    np.testing.assert_array_equal(counts, imagecodecs.jpegls_decode(stream))
    assert np.abs(counts.astype(int) - image).max() <= options.get("near_lossless", 0)


@pytest.mark.parametrize("lines", [1, 5, 7, 48])
def test_restart_markers(tmp_path, lines):
    image = images(np.random.default_rng(3))["plateaus"].astype(np.uint16)
    stream = with_restarts(image, lines)
    markers = sum(stream.count(bytes([0xFF, code])) for code in range(0xD0, 0xD8))
    assert markers == -(-image.shape[0] // lines) - 1
    np.testing.assert_array_equal(decoded(tmp_path, stream, image.shape), image)
    if lines < 48:  # the restart markers' order is checked
        rst = stream.index(b"\xff\xd0")
        swapped = stream[:rst] + b"\xff\xd3" + stream[rst + 2:]
        with pytest.raises(FrameError, match=r"restart marker 1 is 0xFFD3, expected 0xFFD0"):
            decoded(tmp_path, swapped, image.shape)


def test_large_frame_equals_charls(tmp_path):
    """A 640 x 512 14-bit frame, the size of a FLIR research camera's."""
    rng = np.random.default_rng(4)
    rows, cols = np.mgrid[0:512, 0:640]
    image = (9000 + 2000 * np.exp(-((rows - 200) ** 2 + (cols - 300) ** 2) / 5000.0)
             + rng.normal(0, 20, (512, 640))).astype(np.uint16)
    stream = imagecodecs.jpegls_encode(image)
    np.testing.assert_array_equal(decoded(tmp_path, stream, image.shape), image)


def test_spiff_and_comment_segments_are_skipped(tmp_path):
    image = images(np.random.default_rng(5))["smooth"].astype(np.uint16)
    stream = jpegls(image)
    with_comment = stream[:2] + b"\xff\xfe\x00\x07hello" + b"\xff\xe8\x00\x04ab" + stream[2:]
    np.testing.assert_array_equal(decoded(tmp_path, with_comment, image.shape), image)


# ------------------------------------------------------------------------------ refusals


def test_damaged_streams_are_refused_by_name(tmp_path):
    image = images(np.random.default_rng(6))["thermal-like"].astype(np.uint16)
    stream = imagecodecs.jpegls_encode(image)
    sos = stream.index(b"\xff\xda")
    cases = {
        "truncated JPEG-LS data": stream[: len(stream) // 2],
        "truncated JPEG-LS stream": stream[: sos + 4],
        "not JPEG-LS .SOF55.": stream.replace(b"\xff\xf7", b"\xff\xc3", 1),
        "mapping table": stream[: sos + 6] + b"\x01" + stream[sos + 7:],
        "point transform": stream[: sos + 9] + b"\x02" + stream[sos + 10:],
    }
    for expected, bad in cases.items():
        with pytest.raises(FrameError, match=expected) as info:
            decoded(tmp_path, bad, image.shape)
        assert "frame.fff" in str(info.value) and "JPEG-LS" in str(info.value)


def test_colour_and_mismatched_sizes_are_refused(tmp_path):
    rgb = imagecodecs.jpegls_encode(np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(FrameError, match="3 components: irfidelity reads greyscale"):
        decoded(tmp_path, rgb, (8, 8))
    grey = imagecodecs.jpegls_encode(np.zeros((8, 9), np.uint16))
    with pytest.raises(FrameError, match=r"its header says 9 x 10 pixels, its image holds 9 x 8"):
        decoded(tmp_path, grey, (10, 9))


def test_limits_hold_before_decoding(tmp_path):
    image = np.zeros((400, 300), np.uint16)
    stream = imagecodecs.jpegls_encode(image)
    with pytest.raises(FrameError, match="max_bytes"):
        decoded(tmp_path, stream, image.shape, max_bytes=100_000)
    with pytest.raises(FrameError, match="max_pixels"):
        decoded(tmp_path, stream, image.shape, max_pixels=1000)


def test_random_damage_never_crashes(tmp_path):
    """Flipped bytes in a valid stream: counts of the right shape or a FrameError, never a crash."""
    rng = np.random.default_rng(7)
    image = images(rng)["plateaus"].astype(np.uint16)
    stream = bytearray(imagecodecs.jpegls_encode(image))
    outcomes = {"decoded": 0, "refused": 0}
    for _ in range(300):
        bad = bytearray(stream)
        for at in rng.integers(2, len(bad), rng.integers(1, 4)):
            bad[at] = rng.integers(0, 256)
        try:
            counts = decoded(tmp_path, bytes(bad), image.shape)
        except FrameError as exc:
            assert "JPEG-LS" in str(exc) or "raw-data" in str(exc), exc
            outcomes["refused"] += 1
        else:
            assert counts.shape == image.shape and counts.dtype == np.uint16
            outcomes["decoded"] += 1
    assert outcomes["refused"] > 0 and outcomes["decoded"] > 0, outcomes


def test_a_real_frame_recoded_keeps_its_counts(tmp_path):
    """The counts of a real FLIR frame (an FFF of raw samples), JPEG-LS coded: the same counts back."""
    source = Frame.parse(FFF_BE.read_bytes())
    counts = irf.load_frame(FFF_BE)
    recoded = tmp_path / "recoded.fff"
    recoded.write_bytes(source.with_raw_image(jpegls(counts)).to_bytes())
    np.testing.assert_array_equal(irf.load_frame(recoded), counts)
