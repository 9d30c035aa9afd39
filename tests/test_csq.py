"""FLIR CSQ recordings: FFF frames one after another whose raw counts are JPEG-LS coded.

No CSQ file is shipped (none with a licence to redistribute was found), so the recordings are
built here from a real FLIR frame: its records, its calibration, and its counts (moved a
little from frame to frame) coded by CharLS. Oracles: CharLS's own decoding for the counts
(imagecodecs), the term-by-term numpy FLIR model of test_radiometry.py for the temperatures.
"""

from __future__ import annotations

import csv
import io
import struct

import imagecodecs
import numpy as np
import pytest

import irfidelity as irf
from flir_records import CAMERA_INFO, Frame, jpegls
from irfidelity.cli import main
from irfidelity.errors import FrameError, ShortRecordingWarning
from test_radiometry import FFF_LE, thermimage_raw2temp

WEIGHTS = "psnr=0.3,nmi=0.2,ssim=0.3,radiometry=0.2"
EMISSIVITY_AT = 0x20  # in the camera-info record


def frame_counts(k: int) -> np.ndarray:
    """Frame ``k``'s counts: the real frame's, moved ``k`` columns."""
    return np.roll(irf.load_frame(FFF_LE), k, axis=1)


def with_emissivity(source: Frame, emissivity: float) -> Frame:
    record = bytearray(source.record(CAMERA_INFO))
    order = "<" if record[:2] == b"\x02\x00" else ">"
    struct.pack_into(order + "f", record, EMISSIVITY_AT, emissivity)
    return source.with_record(CAMERA_INFO, bytes(record))


def recording(tmp_path, n=5, *, emissivity_of_frame_2=None, damaged=()) -> tuple:
    """A CSQ file of ``n`` frames and each frame's JPEG-LS stream."""
    source = Frame.parse(FFF_LE.read_bytes())
    frames, streams = [], []
    for k in range(n):
        stream = jpegls(frame_counts(k))
        if k in damaged:  # the scan cut short, the record still well formed
            stream = stream[: len(stream) // 2] + b"\xff\xd9"
        frame = source.with_raw_image(stream)
        if k == 2 and emissivity_of_frame_2 is not None:
            frame = with_emissivity(frame, emissivity_of_frame_2)
        frames.append(frame.to_bytes())
        streams.append(stream)
    path = tmp_path / "recording.csq"
    path.write_bytes(b"".join(frames))
    return path, streams


def test_a_csq_reads_as_a_sequence_of_charls_decoded_counts(tmp_path):
    path, streams = recording(tmp_path)
    assert irf.frames.page_count(path) == 5
    frames = irf.FrameSequence(path)
    assert len(frames) == 5 and frames.names[3] == "recording.csq[3]"
    for k in (4, 0, 3):  # out of order: the frame index is kept
        counts = irf.load_frame(path, page=k)
        assert counts.dtype == np.uint16
        np.testing.assert_array_equal(counts, imagecodecs.jpegls_decode(streams[k]))
        np.testing.assert_array_equal(counts, frame_counts(k))
        np.testing.assert_array_equal(frames[k], counts)


def test_each_frame_converts_with_its_own_calibration(tmp_path):
    path, _ = recording(tmp_path, emissivity_of_frame_2=0.8)
    assert irf.read_radiometry(path, page=1) == irf.read_radiometry(FFF_LE)
    calibration = irf.read_radiometry(path, page=2)
    assert calibration.emissivity == pytest.approx(0.8)
    for k, cal in ((1, irf.read_radiometry(FFF_LE)), (2, calibration)):
        celsius = irf.load_frame(path, page=k, unit="C")
        np.testing.assert_allclose(celsius, thermimage_raw2temp(frame_counts(k), cal), rtol=0, atol=1e-9)
    kelvin = irf.load_frame(path, page=1, unit="K")
    np.testing.assert_array_equal(kelvin, np.roll(irf.load_frame(FFF_LE, unit="K"), 1, axis=1))


def test_a_csq_scores_against_simulated_kelvin_frames(tmp_path):
    path, _ = recording(tmp_path, 4)
    kelvin = np.stack([irf.load_frame(path, page=k, unit="K") for k in range(4)])
    sims = kelvin + 0.1 * np.arange(4)[:, None, None]
    report = irf.score_sequence(path, sims, unit="K", weights=WEIGHTS, progress=False, workers=2)
    assert not report.failed and len(report.frames) == 4
    assert [f["metrics"]["temperature_bias"] for f in report.frames] == pytest.approx([0, 0.1, 0.2, 0.3], abs=1e-9)
    sim_dir = tmp_path / "sim"
    sim_dir.mkdir()
    for k in range(4):
        np.save(sim_dir / f"f{k}.npy", sims[k])
    out = tmp_path / "frames.csv"
    assert main(["score", str(path), str(sim_dir), "--unit", "K", "--weights", WEIGHTS, "--csv", str(out),
                 "--no-progress", "--pair-by", "order"]) == 0
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert [float(r["temperature_bias"]) for r in rows] == pytest.approx([0, 0.1, 0.2, 0.3], abs=1e-9)


def test_simulators_rank_against_a_csq(tmp_path):
    path, _ = recording(tmp_path, 4)
    kelvin = np.stack([irf.load_frame(path, page=k, unit="K") for k in range(4)])
    rng = np.random.default_rng(39)
    sims = {"close": kelvin + rng.normal(0, 0.05, kelvin.shape), "far": kelvin + 1.5 + rng.normal(0, 0.5, kelvin.shape)}
    with pytest.warns(ShortRecordingWarning):  # four frames: the ranking says its intervals are too sure
        result = irf.score_simulators(path, sims, unit="K", weights=WEIGHTS, progress=False, workers=2)
    assert result.order == ["close", "far"]
    assert result.reports["far"].metrics["temperature_bias"] == pytest.approx(1.5, abs=0.05)


def test_a_damaged_frame_is_an_error_row_and_the_others_stay_paired(tmp_path, capsys):
    path, _ = recording(tmp_path, 5, damaged={3})
    with pytest.raises(FrameError, match=r"recording.csq.*frame 3: .*JPEG-LS.*truncated"):
        irf.load_frame(path, page=3)
    kelvin = {k: irf.load_frame(path, page=k, unit="K") for k in (0, 1, 2, 4)}
    sims = np.stack([kelvin.get(k, kelvin[0]) + 0.1 * k for k in range(5)])
    report = irf.score_sequence(path, sims, unit="K", weights=WEIGHTS, progress=False, workers=2)
    assert report.failed == [3] and len(report.frames) == 5
    assert "truncated JPEG-LS data" in report.frames[3]["error"]
    biases = [f["metrics"]["temperature_bias"] for k, f in enumerate(report.frames) if k != 3]
    assert biases == pytest.approx([0, 0.1, 0.2, 0.4], abs=1e-9)
    rc = main(["score", str(path), str(path), "--no-progress", "--workers", "1"])
    out, err = capsys.readouterr()
    assert "4 scored, 1 failed" in out + err, out + err
    assert rc != 0 or "failed" in out


def test_other_jpeg_processes_in_a_raw_record_are_named(tmp_path, capsys):
    baseline = imagecodecs.jpeg8_encode(np.zeros((8, 8), np.uint8))
    path = tmp_path / "baseline.csq"
    path.write_bytes(Frame.parse(FFF_LE.read_bytes()).with_raw_image(baseline).to_bytes())
    with pytest.raises(FrameError, match=r"baseline.csq: .*JPEG coded with process SOF0 .*not JPEG-LS"):
        irf.load_frame(path)
    assert main(["score", str(path), str(path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "not JPEG-LS" in err, err


def test_a_recording_cut_short_keeps_its_whole_frames(tmp_path):
    path, _ = recording(tmp_path, 5)
    whole = path.read_bytes()
    path.write_bytes(whole[: len(whole) - 1000])  # the last frame cut short, as a stopped recording
    chain = irf.frames.page_chain(path)
    assert chain.pages == 4 and "frame 4 (at byte" in chain.broken and "truncated FLIR file" in chain.broken
    with pytest.raises(FrameError, match="frame 4 .at byte"):
        irf.frames.page_count(path)
    np.testing.assert_array_equal(irf.load_frame(path, page=3), frame_counts(3))
    kelvin = np.stack([irf.load_frame(path, page=k, unit="K") for k in range(4)])
    sims = np.concatenate([kelvin, kelvin[:1]]) + 0.1 * np.arange(5)[:, None, None]
    report = irf.score_sequence(path, sims, unit="K", weights=WEIGHTS, progress=False, workers=2)
    assert report.failed == [4] and "truncated FLIR file" in report.frames[4]["error"]
    assert [f["metrics"]["temperature_bias"] for f in report.frames[:4]] == pytest.approx([0, 0.1, 0.2, 0.3], abs=1e-9)
