"""Thermal formats irfidelity recognises but does not read: each is refused with a FrameError
that names the format and the file and says what to convert it to, and the CLI says so in one
line with exit code 2.

The files are minimal synthetic ones built from the signatures documented in
``rust/io/unread.rs`` (no real camera data).
"""

from __future__ import annotations

import struct

import cv2
import numpy as np
import pytest

import irfidelity as irf
from irfidelity.cli import main
from irfidelity.errors import FrameError


def _plain_jpeg() -> bytes:
    ok, encoded = cv2.imencode(".jpg", np.zeros((8, 8), np.uint8))
    assert ok
    return encoded.tobytes()


def _segment(marker: int, body: bytes) -> bytes:
    return bytes([0xFF, marker]) + struct.pack(">H", len(body) + 2) + body


def _with_segments(*segments: bytes) -> bytes:
    """A decodable JPEG with ``segments`` right after its start-of-image marker."""
    jpeg = _plain_jpeg()
    return jpeg[:2] + b"".join(segments) + jpeg[2:]


def _exif_make(make: str) -> bytes:
    """An APP1 Exif body (little-endian) whose first IFD holds only the Make: in the entry
    when it fits in 4 bytes ("DJI\0" does), else after the IFD."""
    value = make.encode() + b"\0"
    inline = len(value) <= 4
    field = value.ljust(4, b"\0") if inline else struct.pack("<I", 8 + 2 + 12 + 4)
    entry = struct.pack("<HHI", 0x010F, 2, len(value)) + field
    tail = b"" if inline else value
    return b"Exif\0\0" + b"II*\0" + struct.pack("<IH", 8, 1) + entry + struct.pack("<I", 0) + tail


def _dji_rjpeg() -> bytes:
    params = b"\xaa\x55\x12\x06" + bytes(124)  # DJI ThermalParams (H20T) in APP4
    return _with_segments(_segment(0xE1, _exif_make("DJI")), _segment(0xE3, bytes(600)), _segment(0xE4, params))


def _infiray_jpeg() -> bytes:
    version = b"\x01\x00\x00\x00IJPEG\0" + bytes(70)  # the IJPEG version header in APP2
    return _with_segments(_segment(0xE2, version))


def _hikmicro_jpeg() -> bytes:
    hdri = b"HDRI" + struct.pack("<HHIIII", 0x1028, 0, 0, 4, 2, 16) + bytes(20) + bytes(16)
    return _plain_jpeg() + _plain_jpeg() + hdri  # the HDRI block follows the embedded JPEG's end


def _irg() -> bytes:
    header = bytearray(128)
    header[:4] = b"\xca\xac\x80\x00"
    header[126:] = b"\xac\xca"
    return bytes(header) + bytes(4 * 2 * 3)


def _research_studio_jpeg() -> bytes:
    ats = b"\0\0\0\x10FLIR ATS-US File\0\0FOV\0Workspace" + bytes(32)
    return _with_segments(_segment(0xE1, b"FLIR\0\x01\x00\x00" + ats))


#: name of the file, its bytes, and the words its refusal must hold
CASES = {
    "dji": ("DJI_0001_T.JPG", _dji_rjpeg, "a DJI R-JPEG of the H20T/H20N/M30T/M3T/M2EA kind (DJI Thermal SDK format): "
            "irfidelity does not read it; convert it with the DJI Thermal SDK's dji_irp"),
    "infiray": ("IR_0001.jpg", _infiray_jpeg, "an InfiRay radiometric JPEG (IJPEG): irfidelity does not read it"),
    "hikmicro": ("HM_0001.jpeg", _hikmicro_jpeg, "a HIKMICRO radiometric JPEG (HDRI block): irfidelity does not "
                 "read it; export its temperature matrix (CSV) with HIKMICRO Analyzer"),
    "irg": ("frame.bin", _irg, "an InfiRay IRG file: irfidelity does not read it; read it with the infiray-irg "
            "Python package"),
    "research_studio": ("Snap-0012.jpg", _research_studio_jpeg, "a FLIR Research Studio radiometric JPEG"),
    "ats_by_extension": ("Rec-0018.ats", lambda: b"\x01\x02\x03\x04" + bytes(64),
                         "by its extension .ats, a FLIR ATS recording (FLIR Research Studio/ResearchIR), which "
                         "irfidelity does not read"),
    "irg_by_extension": ("P200.irg", lambda: b"\x04\xa0\x80\x00" + bytes(64),
                         "by its extension .irg, an InfiRay IRG file"),
}


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_unread_format_is_refused_naming_it(tmp_path, capsys, case):
    name, build, words = CASES[case]
    path = tmp_path / name
    path.write_bytes(build())
    with pytest.raises(FrameError) as info:
        irf.load_frame(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and words in message, message
    assert "\n" not in message
    with pytest.raises(FrameError, match="irfidelity does not read"):
        irf.read_radiometry(path)
    assert main(["score", str(path), str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(path) in err and words in err, err


def test_jpegs_without_a_signature_keep_the_plain_refusal(tmp_path):
    dji_without_thermal = tmp_path / "DJI_0002.JPG"  # a DJI visible photo: Make "DJI", no thermal parameters
    dji_without_thermal.write_bytes(_with_segments(_segment(0xE1, _exif_make("DJI")), _segment(0xE3, bytes(600))))
    other_make = tmp_path / "other.jpg"  # thermal parameters, but not from a DJI camera (ExifTool's rule)
    other_make.write_bytes(_with_segments(_segment(0xE1, _exif_make("Acme")),
                                          _segment(0xE4, b"\xaa\x55\x12\x06" + bytes(124))))
    for path in (dji_without_thermal, other_make):
        with pytest.raises(FrameError, match="JPEG without FLIR segments: not a radiometric JPEG"):
            irf.load_frame(path)
