"""Radiometric FLIR files: raw counts, the camera-info record, and counts <-> temperatures.

Oracles: the lossless extractions of the raw counts (``*_raw16.png``, read with OpenCV), the
ExifTool dump shipped with the FFF frame and ExifTool itself (CI installs it), an independent
numpy float64 implementation of the published FLIR model (Thermimage's ``raw2temp``, written
out term by term below), and Thermimage's README worked value.
"""

from __future__ import annotations

import datetime
import json
import pathlib
import shutil
import struct
import subprocess
import warnings

import cv2
import numpy as np
import pytest

import irfidelity as irf
from irfidelity.cli import main
from irfidelity.errors import FidelityError, FrameError, RadiometryWarning, RangeError

DATA = pathlib.Path(__file__).parent / "data"
RAD = DATA / "radiometric"
FFF_BE = RAD / "flirpy_frame_000000.fff"
FFF_LE = RAD / "flirpy_frame_000000_le.fff"
AX8 = RAD / "readthermal_flir_ax8.jpg"
EXAMPLE = RAD / "readthermal_flir_example.jpg"
ZENMUSE = RAD / "readthermal_zenmuse_xtr.jpg"
FILES = [FFF_BE, FFF_LE, AX8, EXAMPLE, ZENMUSE]

#: each radiometric file and the lossless extraction of its raw counts
EXTRACTIONS = {
    FFF_BE: DATA / "thermal" / "flirpy_frame_000000_raw16.png",
    FFF_LE: RAD / "flirpy_frame_000000_le_raw16.png",
    AX8: DATA / "thermal" / "readthermal_flir_ax8_raw16.png",
    EXAMPLE: RAD / "readthermal_flir_example_raw16.png",
    ZENMUSE: DATA / "thermal" / "readthermal_zenmuse_xtr_raw16.png",
}

ZERO_C = 273.15


# ----------------------------------------------------------------------------------- raw counts


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_raw_counts_equal_the_lossless_extraction(path):
    counts = irf.load_frame(path)
    expected = cv2.imread(str(EXTRACTIONS[path]), cv2.IMREAD_UNCHANGED)
    assert counts.dtype == np.uint16 and expected.dtype == np.uint16
    assert counts.shape == expected.shape
    np.testing.assert_array_equal(counts, expected)
    assert irf.frames.page_count(path) == 1
    assert irf.frames.list_channels(path) == ["Y"]


# ------------------------------------------------------------------------------------- metadata


def _dump(path: pathlib.Path) -> dict[str, str]:
    out = {}
    for line in path.read_text().splitlines():
        key, _, value = line.partition(":")
        out[key.strip()] = value.strip()
    return out


def test_fff_metadata_equals_the_shipped_exiftool_dump():
    dump = _dump(RAD / "flirpy_frame_000000.exiftool.txt")
    cal = irf.read_radiometry(FFF_BE)
    number = lambda key: float(dump[key].split()[0])  # noqa: E731
    # ExifTool prints rounded values: each field to the digits it prints
    checks = {
        "planck_r1": ("Planck R1", 0.5), "planck_b": ("Planck B", 0.5), "planck_f": ("Planck F", 0.5),
        "planck_o": ("Planck O", 0), "planck_r2": ("Planck R2", 0.5),
        "emissivity": ("Emissivity", 0.005), "object_distance": ("Object Distance", 0.005),
        "reflected_temperature": ("Reflected Apparent Temperature", 0.05),
        "atmospheric_temperature": ("Atmospheric Temperature", 0.05),
        "window_temperature": ("IR Window Temperature", 0.05),
        "window_transmission": ("IR Window Transmission", 0.005),
        "relative_humidity": ("Relative Humidity", 0.05),
        "alpha1": ("Atmospheric Trans Alpha 1", 5e-7), "alpha2": ("Atmospheric Trans Alpha 2", 5e-7),
        "beta1": ("Atmospheric Trans Beta 1", 5e-7), "beta2": ("Atmospheric Trans Beta 2", 5e-7),
        "x": ("Atmospheric Trans X", 5e-7),
    }
    for field, (key, half_digit) in checks.items():
        assert abs(getattr(cal, field) - number(key)) <= half_digit + 1e-12, field
    assert cal.camera_model == dump["Camera Model"] == "Duo Pro R"
    assert cal.camera_serial == dump["Camera Serial Number"]
    assert cal.lens_model is None and dump["Lens Model"] == ""
    assert cal.frame_rate == int(dump["Frame Rate"]) == 30
    stamp = datetime.datetime.strptime(dump["Date/Time Original"], "%Y:%m:%d %H:%M:%S.%f%z")
    assert cal.date == stamp and cal.date.utcoffset() == stamp.utcoffset()
    assert cal.source == str(FFF_BE)


#: ExifTool's output for each file of FILES, shipped for machines without the program
EXIFTOOL_DUMP = json.loads((RAD / "exiftool.json").read_text())["files"]


def _exiftool(path: pathlib.Path) -> dict:
    """ExifTool's FLIR tags of ``path``: the live program's when it is installed (CI installs it),
    which must then equal the shipped dump, else the dump."""
    dump = EXIFTOOL_DUMP[path.name]
    if shutil.which("exiftool") is None:
        return dump
    out = subprocess.run(["exiftool", "-j", "-n", "-FLIR:all", str(path)], capture_output=True, text=True,
                         check=True, timeout=60)
    tags = json.loads(out.stdout)[0]
    for tag in (*EXIF_NAMES.values(), "RelativeHumidity", "CameraModel", "DateTimeOriginal", "FrameRate"):
        assert tags.get(tag) == dump.get(tag), f"{path.name}: the shipped dump's {tag} is not ExifTool's"
    return tags


#: Radiometry field -> ExifTool tag (numeric values, ``-n``)
EXIF_NAMES = {
    "planck_r1": "PlanckR1", "planck_r2": "PlanckR2", "planck_b": "PlanckB", "planck_f": "PlanckF",
    "planck_o": "PlanckO", "emissivity": "Emissivity", "object_distance": "ObjectDistance",
    "reflected_temperature": "ReflectedApparentTemperature", "atmospheric_temperature": "AtmosphericTemperature",
    "window_temperature": "IRWindowTemperature", "window_transmission": "IRWindowTransmission",
    "alpha1": "AtmosphericTransAlpha1", "alpha2": "AtmosphericTransAlpha2", "beta1": "AtmosphericTransBeta1",
    "beta2": "AtmosphericTransBeta2", "x": "AtmosphericTransX",
}


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_metadata_equals_exiftool(path):
    tags = _exiftool(path)
    cal = irf.read_radiometry(path)
    for field, tag in EXIF_NAMES.items():
        assert getattr(cal, field) == pytest.approx(float(tags[tag]), rel=1e-9, abs=1e-9), field
    assert cal.relative_humidity == pytest.approx(100 * float(tags["RelativeHumidity"]), rel=1e-9)
    for field, tag in (("camera_model", "CameraModel"), ("camera_serial", "CameraSerialNumber"),
                       ("lens_model", "LensModel")):
        assert getattr(cal, field) == (str(tags.get(tag, "")).strip() or None), field
    assert cal.frame_rate == (int(tags.get("FrameRate", 0)) or None)
    stamp = datetime.datetime.strptime(tags["DateTimeOriginal"], "%Y:%m:%d %H:%M:%S.%f%z")
    assert cal.date == stamp and cal.date.utcoffset() == stamp.utcoffset()


def test_zenmuse_records_its_non_default_conditions():
    cal = irf.read_radiometry(ZENMUSE)
    assert cal.emissivity == pytest.approx(0.70) and cal.object_distance == 20
    assert cal.atmospheric_temperature == pytest.approx(32.0, abs=1e-4)
    with pytest.raises(dataclass_error()):
        cal.emissivity = 0.5  # frozen


def dataclass_error():
    import dataclasses

    return dataclasses.FrozenInstanceError


# ----------------------------------------------------------------------------------- conversion


def thermimage_raw2temp(raw, cal: irf.radiometry.Radiometry):
    """The published FLIR model, term by term in numpy float64 (°C)."""
    e, od, w = cal.emissivity, cal.object_distance, cal.window_transmission
    ta = cal.atmospheric_temperature
    h2o = cal.relative_humidity / 100 * np.exp(1.5587 + 0.06939 * ta - 0.00027816 * ta**2 + 0.00000068455 * ta**3)
    tau = cal.x * np.exp(-np.sqrt(od / 2) * (cal.alpha1 + cal.beta1 * np.sqrt(h2o))) + (1 - cal.x) * np.exp(
        -np.sqrt(od / 2) * (cal.alpha2 + cal.beta2 * np.sqrt(h2o)))

    def blackbody(celsius):
        return cal.planck_r1 / (cal.planck_r2 * (np.exp(cal.planck_b / (celsius + ZERO_C)) - cal.planck_f)) \
            - cal.planck_o

    refl = (1 - e) / e * blackbody(cal.reflected_temperature)
    atm1 = (1 - tau) / e / tau * blackbody(ta)
    wind = (1 - w) / e / tau / w * blackbody(cal.window_temperature)
    atm2 = (1 - tau) / e / tau / w / tau * blackbody(ta)
    obj = np.asarray(raw, dtype=np.float64) / e / tau / w / tau - atm1 - atm2 - wind - refl
    return cal.planck_b / np.log(cal.planck_r1 / (cal.planck_r2 * (obj + cal.planck_o)) + cal.planck_f) - ZERO_C


README_CAL = irf.radiometry.Radiometry(planck_r1=21106.77, planck_r2=0.012545258, planck_b=1501, planck_f=1,
                                       planck_o=-7340, emissivity=0.95, object_distance=1, reflected_temperature=20,
                                       atmospheric_temperature=20, window_temperature=20, window_transmission=0.96,
                                       relative_humidity=50)


def test_thermimage_worked_value():
    assert README_CAL.temperature(17994.06) == pytest.approx(23.31223, abs=5e-6)
    assert thermimage_raw2temp(17994.06, README_CAL) == pytest.approx(23.31223, abs=5e-6)
    assert README_CAL.temperature(17994.06, unit="K") == pytest.approx(23.31223 + ZERO_C, abs=5e-6)
    assert README_CAL.counts(23.31223) == pytest.approx(17994.06, abs=1e-2)


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_temperatures_equal_the_published_model_and_invert(path):
    cal = irf.read_radiometry(path)
    raw = irf.load_frame(path)
    celsius = cal.temperature(raw)
    assert celsius.dtype == np.float64 and celsius.shape == raw.shape
    np.testing.assert_allclose(celsius, thermimage_raw2temp(raw, cal), rtol=0, atol=1e-4)
    kelvin = irf.load_frame(path, unit="K")
    np.testing.assert_allclose(kelvin, celsius + ZERO_C, rtol=0, atol=1e-9)
    back = cal.counts(celsius)
    np.testing.assert_array_equal(np.rint(back), raw)
    assert np.abs(back - raw).max() < 1e-6
    np.testing.assert_array_equal(np.rint(cal.counts(kelvin, unit="K")), raw)


def test_overrides_change_the_conditions_not_the_file():
    cal = irf.read_radiometry(ZENMUSE)
    raw = irf.load_frame(ZENMUSE)
    changed = dict(emissivity=0.98, reflected_temperature=10.0, object_distance=5.0, relative_humidity=40.0,
                   atmospheric_temperature=15.0, window_transmission=0.9, window_temperature=18.0)
    got = irf.load_frame(ZENMUSE, unit="C", **changed)
    np.testing.assert_allclose(got, thermimage_raw2temp(raw, cal.replace(**changed)), rtol=0, atol=1e-4)
    np.testing.assert_array_equal(got, cal.temperature(raw, **changed))
    assert not np.allclose(got, cal.temperature(raw))
    assert irf.read_radiometry(ZENMUSE) == cal  # unchanged
    # every integer and float dtype gives the same temperatures
    for dtype in (np.uint16, np.uint32, np.int32, np.int64, np.float32, np.float64):
        np.testing.assert_array_equal(cal.temperature(raw.astype(dtype)), cal.temperature(raw), err_msg=str(dtype))
    np.testing.assert_array_equal(cal.temperature(raw[::2, ::3]), cal.temperature(raw)[::2, ::3])


def test_counts_outside_the_domain_are_nan_with_a_warning():
    cal = irf.read_radiometry(FFF_BE)
    raw = np.array([[2650, 0], [2700, 1]], dtype=np.uint16)
    with pytest.warns(RadiometryWarning, match="2 raw counts outside the calibration's domain"):
        t = cal.temperature(raw)
    assert np.isnan(t[:, 1]).all() and np.isfinite(t[:, 0]).all()
    with pytest.warns(RadiometryWarning, match="1 non-finite raw counts"):
        cal.temperature(np.array([2650.0, np.nan]))
    with pytest.raises(RangeError, match="all 2 values are NaN"):
        cal.temperature(np.array([0, 1], dtype=np.uint16))
    with pytest.warns(RadiometryWarning, match="outside"):
        assert np.isnan(cal.counts(np.array([-300.0, 20.0]))[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cal.temperature(irf.load_frame(FFF_BE))  # no warning on real counts


@pytest.mark.parametrize("override, match", [
    (dict(planck_r2=0), "planck_r2 = 0"),
    (dict(planck_b=0), "planck_b = 0"),
    (dict(planck_b=-1428), "planck_b = -1428"),
    (dict(emissivity=0), "emissivity = 0"),
    (dict(emissivity=1.01), "emissivity = 1.01"),
    (dict(object_distance=-1), "object_distance = -1"),
    (dict(relative_humidity=120), "relative_humidity = 120"),
    (dict(window_transmission=0), "window_transmission = 0"),
    (dict(reflected_temperature=-300), "reflected_temperature = -300"),
    (dict(atmospheric_temperature=float("nan")), "atmospheric_temperature = NaN"),
    (dict(object_distance=1e15), "atmospheric transmission"),
])
def test_invalid_calibration_fields_are_named(override, match):
    cal = irf.read_radiometry(FFF_BE)
    field = next(iter(override))
    with pytest.raises(FidelityError, match=match) as info:
        cal.temperature(np.array([2650], dtype=np.uint16), **override)
    assert str(FFF_BE) in str(info.value)
    assert not isinstance(info.value, FrameError)
    if field != "object_distance" or override[field] < 0:
        assert info.value.option == field
    with pytest.raises(FidelityError, match=match):
        irf.load_frame(FFF_BE, unit="K", **override)


def test_bad_override_names_and_units():
    cal = irf.read_radiometry(FFF_BE)
    with pytest.raises(FidelityError, match="unknown calibration override emisivity"):
        cal.temperature(2650, emisivity=0.9)
    with pytest.raises(FidelityError, match="unknown calibration override camera_model"):
        cal.replace(camera_model="x")
    with pytest.raises(FidelityError, match="unit must be 'C' or 'K'"):
        cal.temperature(2650, unit="F")
    with pytest.raises(FidelityError, match="unit must be"):
        irf.load_frame(FFF_BE, emissivity=0.9)
    with pytest.raises(FidelityError, match="must be a number"):
        cal.replace(emissivity="0.9")


def test_files_without_calibration():
    png = DATA / "thermal" / "cptv_v2_frame000.png"
    with pytest.raises(FrameError, match="no radiometric calibration") as info:
        irf.read_radiometry(png)
    assert str(png) in str(info.value)
    with pytest.raises(FrameError, match="cannot become temperatures"):
        irf.load_frame(png, unit="K")
    exr = DATA / "thermal" / "cptv_v2_frame000_counts_f32_zip.exr"
    np.testing.assert_array_equal(irf.load_frame(exr, unit="K"), irf.load_frame(exr))
    with pytest.raises(FidelityError, match="float frame is taken as already in K"):
        irf.load_frame(exr, unit="K", emissivity=0.9)


# ------------------------------------------------------------------------------------ sequences


def _seq(tmp_path, name, frames) -> pathlib.Path:
    path = tmp_path / name
    path.write_bytes(b"".join(f.read_bytes() for f in frames))
    return path


def test_seq_pages_read_through_frame_sequence(tmp_path):
    seq = _seq(tmp_path, "run.seq", [FFF_LE, FFF_BE, FFF_LE])
    assert irf.frames.page_count(seq) == 3
    frames = irf.FrameSequence(seq)
    assert len(frames) == 3 and frames.names == ["run.seq[0]", "run.seq[1]", "run.seq[2]"]
    np.testing.assert_array_equal(frames[1], irf.load_frame(FFF_BE))
    np.testing.assert_array_equal(frames[2], irf.load_frame(FFF_LE))
    np.testing.assert_array_equal(frames[0], irf.load_frame(seq, page=2))
    assert irf.read_radiometry(seq, page=1) == irf.read_radiometry(FFF_BE)
    np.testing.assert_array_equal(irf.load_frame(seq, page=1, unit="C"), irf.load_frame(FFF_BE, unit="C"))
    with pytest.raises(FrameError, match=r"page 3 out of range \(3 frames\)"):
        irf.load_frame(seq, page=3)
    # the directory source picks up .seq and .fff files
    assert len(irf.FrameSequence(tmp_path)) == 3


def test_seq_scores_as_a_sequence(tmp_path):
    real = _seq(tmp_path, "real.seq", [FFF_LE] * 3)
    sim = _seq(tmp_path, "sim.seq", [FFF_LE] * 3)
    report = irf.score_sequence(real, sim, bits=16, peak="range", progress=False, workers=1)
    assert len(report.frames) == 3 and not report.failed
    assert all(f["fidelity"] == pytest.approx(1.0) for f in report.frames)
    rc = main(["score", str(real), str(sim), "--bits", "16", "--peak", "range", "--pages", "0:2", "--no-progress",
               "--workers", "1", "--csv", str(tmp_path / "frames.csv")])
    assert rc == 0
    assert len((tmp_path / "frames.csv").read_text().strip().splitlines()) == 3  # header and two frames


# ------------------------------------------------------------------------------------ bad input


def _patched(tmp_path, source, edits, name=None) -> pathlib.Path:
    data = bytearray(source.read_bytes())
    for offset, payload in edits:
        data[offset:offset + len(payload)] = payload
    path = tmp_path / (name or source.name)
    path.write_bytes(bytes(data))
    return path


def _records(path) -> dict[int, tuple[int, int]]:
    """Record type -> (offset, length) of a big- or little-endian FFF file."""
    data = path.read_bytes()
    order = ">" if 100 <= struct.unpack(">I", data[20:24])[0] < 200 else "<"
    directory, entries = struct.unpack(order + "II", data[24:32])
    out = {}
    for k in range(entries):
        kind, _, _, _, offset, length = struct.unpack(order + "HHIIII", data[directory + 32 * k:][:20])
        if kind:
            out[kind] = (offset, length)
    return out


def test_truncated_files(tmp_path):
    for source, size in ((FFF_BE, 1000), (FFF_BE, 40), (FFF_LE, 156000), (ZENMUSE, 300000), (AX8, 3000)):
        cut = tmp_path / f"cut_{size}_{source.name}"
        cut.write_bytes(source.read_bytes()[:size])
        with pytest.raises(FrameError) as info:
            irf.load_frame(cut)
        assert str(cut) in str(info.value) and "truncated" in str(info.value), str(info.value)
        with pytest.raises(FrameError, match="truncated"):
            irf.read_radiometry(cut)


def test_zeroed_records(tmp_path):
    records = _records(FFF_BE)
    offset, length = records[0x20]
    zeroed = _patched(tmp_path, FFF_BE, [(offset, bytes(length))])
    with pytest.raises(FrameError, match="camera-info record: its byte-order mark is 0x0000") as info:
        irf.read_radiometry(zeroed)
    assert str(zeroed) in str(info.value)
    with pytest.raises(FrameError, match="byte-order mark"):
        irf.load_frame(zeroed, unit="C")
    np.testing.assert_array_equal(irf.load_frame(zeroed), irf.load_frame(FFF_BE))  # counts are intact
    offset, length = records[0x01]
    raw_zeroed = _patched(tmp_path, FFF_BE, [(offset, bytes(64))], name="raw.fff")
    with pytest.raises(FrameError, match="raw-data record"):
        irf.load_frame(raw_zeroed)
    whole = tmp_path / "zeros.fff"
    whole.write_bytes(b"FFF\0" + bytes(2000))
    with pytest.raises(FrameError, match="unsupported FLIR FFF version"):
        irf.load_frame(whole)


def test_absurd_planck_constants_in_the_file(tmp_path):
    offset, _ = _records(FFF_LE)[0x20]
    bad = _patched(tmp_path, FFF_LE, [(offset + 0x30c, struct.pack("<f", 0.0))])
    assert irf.read_radiometry(bad).planck_r2 == 0  # read as stored
    with pytest.raises(FidelityError, match="planck_r2 = 0 is invalid") as info:
        irf.load_frame(bad, unit="C")
    assert str(bad) in str(info.value) and "the file's value; override it with planck_r2=" in str(info.value)
    fixed = irf.load_frame(bad, unit="C", planck_r2=irf.read_radiometry(FFF_LE).planck_r2)
    np.testing.assert_array_equal(fixed, irf.load_frame(FFF_LE, unit="C"))
    negative_b = _patched(tmp_path, FFF_LE, [(offset + 0x5c, struct.pack("<f", -5.0))], name="b.fff")
    with pytest.raises(FidelityError, match="planck_b = -5"):
        irf.load_frame(negative_b, unit="K")


def _fff(raw_record: bytes) -> bytes:
    """A little-endian FFF frame holding one raw-data record."""
    header = bytearray(64)
    header[:4] = b"FFF\0"
    header[20:32] = struct.pack("<III", 100, 64, 1)
    entry = struct.pack("<HHIIII", 1, 2, 100, 1, 96, len(raw_record)) + bytes(12)
    return bytes(header) + entry + raw_record


def test_tiny_header_claiming_a_huge_image(tmp_path):
    path = tmp_path / "huge.fff"
    path.write_bytes(_fff(struct.pack("<HHH", 2, 16000, 16000) + bytes(26) + bytes(10)))
    with pytest.raises(FrameError, match="claims 16000 x 16000 pixels") as info:
        irf.load_frame(path, max_pixels=16000 * 16000)
    assert str(path) in str(info.value)
    with pytest.raises(FrameError, match=r"16000 x 16000 pixels exceeds the limit of 67108864 pixels.*--max-pixels"):
        irf.load_frame(path)  # the default limit: 8192 x 8192
    with pytest.raises(FrameError, match="max_pixels"):
        irf.load_frame(path, max_pixels=1000)
    with pytest.raises(FrameError, match="max_bytes"):
        irf.load_frame(FFF_BE, max_bytes=100_000)
    with pytest.raises(FrameError, match="max_bytes"):
        irf.load_frame(ZENMUSE, max_bytes=100_000)


def test_damaged_csq_and_plain_jpeg_are_refused_clearly(tmp_path, capsys):
    csq = tmp_path / "frame.csq"
    csq.write_bytes(_fff(struct.pack("<HHH", 2, 4, 2) + bytes(26) + b"\xff\xd8\xff\xf7" + bytes(60)))
    damaged = "the raw-data record's JPEG-LS image: corrupt JPEG-LS stream: segment 0xFFF7 claims 0 bytes"
    with pytest.raises(FrameError, match=damaged):
        irf.load_frame(csq)
    assert main(["score", str(csq), str(csq)]) == 2  # the CLI says it in one line
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and damaged in err and str(csq) in err, err
    recording = tmp_path / "recording.csq"  # a CSQ recording is frames one after another: a sequence
    recording.write_bytes(csq.read_bytes() * 2)
    assert main(["score", str(recording), str(recording), "--no-progress"]) == 3
    out = capsys.readouterr().out
    assert "0 scored, 2 failed" in out and damaged in out, out
    with pytest.raises(FidelityError, match="is a FLIR recording of 2 frames: score it as a sequence"):
        irf.evaluate(recording, recording)
    ok, encoded = cv2.imencode(".jpg", np.zeros((8, 8), np.uint8))
    plain = tmp_path / "plain.jpg"
    plain.write_bytes(encoded.tobytes())
    with pytest.raises(FrameError, match="JPEG without FLIR segments") as info:
        irf.load_frame(plain)
    assert str(plain) in str(info.value)
    with pytest.raises(FrameError, match="JPEG without FLIR segments"):
        irf.read_radiometry(plain)


def test_guide_radiometric_example_runs(capsys):
    import re

    readme = (pathlib.Path(__file__).parent.parent / "docs" / "guide.md").read_text(encoding="utf-8")
    block = next(b for b in re.findall(r"```python\n(.*?)```", readme, re.S) if "read_radiometry" in b)
    namespace: dict = {}
    exec(compile(block, "docs/guide.md", "exec"), namespace)
    assert namespace["counts"].shape == (60, 80) and namespace["counts"].dtype == np.uint16
    celsius = namespace["celsius"]
    assert celsius.dtype == np.float64 and np.isfinite(celsius).all() and 0 < celsius.mean() < 60
    assert namespace["cal"].camera_model in capsys.readouterr().out
