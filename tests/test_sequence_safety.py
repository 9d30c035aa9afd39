"""Sequences lose nothing and corrupt nothing (issue 13, items 4–9 and 11): every per-frame
failure is that frame's error row, resume trusts only what it can check, frames pair by name,
one CSV has one writer, and odd arguments are FidelityErrors.

Data: 12 consecutive real Lepton frames (tests/data/thermal, see tests/data/README.md); the
"simulated" frames are the real ones with a gain, an offset and seeded noise.
"""

from __future__ import annotations

import csv
import os
import pathlib
import struct
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.errors import FidelityError, FrameError
from irfidelity.sequence import score_sequence

tifffile = pytest.importorskip("tifffile")
cv2 = pytest.importorskip("cv2")

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
PNGS = [DATA / f"cptv_v2_frame{i:03d}.png" for i in range(12)]


def _real_frames() -> np.ndarray:
    return np.stack([cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in PNGS])


def _simulate(frames: np.ndarray, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = frames.astype(np.int64) * 1.01 - 20 + rng.normal(0, 6, frames.shape)
    return np.clip(np.rint(x), 0, 16383).astype(np.uint16)


def _write_dirs(tmp_path: pathlib.Path, ext: str = ".png", count: int = 12) -> tuple[pathlib.Path, pathlib.Path]:
    real = _real_frames()[:count]
    sim = _simulate(real)
    rdir, sdir = tmp_path / "real", tmp_path / "sim"
    rdir.mkdir(parents=True)
    sdir.mkdir()
    for i in range(count):
        for d, frames in ((rdir, real), (sdir, sim)):
            if ext == ".png":
                assert cv2.imwrite(str(d / f"frame_{i:02d}{ext}"), frames[i])
            else:
                tifffile.imwrite(d / f"frame_{i:02d}{ext}", frames[i])
    return rdir, sdir


def _rows(path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _values(rep) -> dict:
    return {f["index"]: (f["fidelity"], f["metrics"]) for f in rep.frames}


# --------------------------------------------------------------------------- per-frame failures
def test_broken_tiffs_in_a_directory_are_error_rows(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".tif", 8)
    good = (sdir / "frame_02.tif").read_bytes()
    (sdir / "frame_02.tif").write_bytes(good[: len(good) // 2])  # truncated
    (sdir / "frame_04.tif").write_bytes(b"")  # empty
    (sdir / "frame_06.tif").write_bytes(b"II*\x00" + struct.pack("<I", 10_000_000) + b"\x00" * 64)  # IFD past the end
    rep = score_sequence(rdir, sdir, bits=14, progress=False)
    assert rep.failed == [2, 4, 6]
    for i in (2, 4, 6):
        assert f"frame_0{i}.tif" in rep.frames[i]["error"]
    assert rep.pooling["frames"] == 5 and rep.fidelity is not None
    # the command line finishes the run too: exit 3 (some frames failed), not 2
    p = subprocess.run([sys.executable, "-m", "irfidelity.cli", "score", str(rdir), str(sdir), "--bits", "14",
                        "--no-progress"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 3, p.stderr
    assert "Traceback" not in p.stderr and "3 failed" in p.stdout


def test_non_utf8_file_names(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".png", 3)
    for d in (rdir, sdir):
        os.rename(d / "frame_01.png", os.path.join(os.fsencode(d), b"frame_01\xff.png"))
    out = tmp_path / "rows.csv"
    rep = score_sequence(rdir, sdir, bits=14, progress=False, csv=out)
    assert rep.failed == [] and len(rep.frames) == 3
    assert rep.frames[1]["real"] == "frame_01\\xff.png" == rep.frames[1]["sim"]
    assert any(r["real"] == "frame_01\\xff.png" for r in _rows(out))
    import json

    json.dumps(rep.to_dict())  # no UnicodeEncodeError anywhere


def test_unreadable_first_frames_do_not_refuse_the_run(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".png", 12)
    for i in range(10):
        (rdir / f"frame_{i:02d}.png").write_bytes(b"\x89PNG\r\n\x1a\n broken")
    rep = score_sequence(rdir, sdir, bits=14, progress=False)
    assert rep.failed == list(range(10))
    assert rep.pooling["frames"] == 2
    # none readable at all: every frame an error row, no exception
    for i in (10, 11):
        (rdir / f"frame_{i:02d}.png").write_bytes(b"")
    rep = score_sequence(rdir, sdir, bits=14, progress=False)
    assert rep.failed == list(range(12)) and rep.fidelity is None
    assert all("frame_" in f["error"] for f in rep.frames)


# --------------------------------------------------------------------------- pairing
def _own(metrics: dict) -> dict:
    """A frame's own metrics: without the run's scene transfer (pooled over the pairs it samples)."""
    return {k: v for k, v in metrics.items() if not k.startswith("scene_")}


def test_frames_pair_by_name_when_one_is_missing_on_each_side(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".png", 12)
    os.remove(rdir / "frame_03.png")
    os.remove(sdir / "frame_08.png")
    full = score_sequence(*_write_dirs(tmp_path / "full", ".png", 12), bits=14, progress=False)
    rep = score_sequence(rdir, sdir, bits=14, progress=False)
    assert rep.run["pair_by"] == "name" and len(rep.frames) == 12
    by_name = {f["real"]: f for f in rep.frames if f["error"] is None}
    assert len(by_name) == 10
    for f in full.frames:
        if f["real"] in by_name:  # every matched pair scores exactly what it scores in the full run
            assert _own(by_name[f["real"]]["metrics"]) == _own(f["metrics"])
    lonely = [f for f in rep.frames if f["error"]]
    assert {(f["real"], f["sim"]) for f in lonely} == {(None, "frame_03.png"), ("frame_08.png", None)}
    assert any("no partner" in n for n in rep.notes)
    # the old rule on request: by position (11 frames each)
    os.remove(rdir / "frame_08.png")
    os.remove(sdir / "frame_03.png")
    by_order = score_sequence(rdir, sdir, bits=14, progress=False, pair_by="order")
    assert by_order.run["pair_by"] == "order" and by_order.failed == []


def test_frames_pair_by_number_across_naming_schemes(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".png", 4)
    for i in range(4):
        os.rename(sdir / f"frame_{i:02d}.png", sdir / f"sim_{i}.png")
    rep = score_sequence(rdir, sdir, bits=14, progress=False)
    assert rep.run["pair_by"] == "number"
    assert [(f["real"], f["sim"]) for f in rep.frames] == [(f"frame_{i:02d}.png", f"sim_{i}.png") for i in range(4)]


# --------------------------------------------------------------------------- resume
def test_damaged_statistics_are_scored_again_and_the_csv_keeps_every_row(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".png", 12)
    out = tmp_path / "rows.csv"
    full = score_sequence(rdir, sdir, bits=14, progress=False, csv=out)
    side = pathlib.Path(str(out) + ".pairstats")
    data = bytearray(side.read_bytes())
    for pos in (len(data) // 3, 2 * len(data) // 3):  # two bytes flipped inside records
        data[pos] ^= 0xFF
    side.write_bytes(bytes(data))
    scored = []
    rep = score_sequence(rdir, sdir, bits=14, progress=lambda d, t: scored.append(d), csv=out, resume=True)
    assert 1 <= len(scored) <= 4  # only the damaged records' frames were scored again
    assert _values(rep) == _values(full)
    assert any("damaged" in n for n in rep.notes)
    assert sorted(int(r["index"]) for r in _rows(out)) == list(range(12))
    # a damaged header: nothing is trusted, everything is scored again, nothing lost
    data = bytearray(side.read_bytes())
    data[12] ^= 0x01
    side.write_bytes(bytes(data))
    rep = score_sequence(rdir, sdir, bits=14, progress=False, csv=out, resume=True)
    assert rep.run["resumed"] == 0 and _values(rep) == _values(full)
    assert len(_rows(out)) == 12


def test_a_changed_frame_is_scored_again(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".png", 6)
    out = tmp_path / "rows.csv"
    score_sequence(rdir, sdir, bits=14, progress=False, csv=out)
    target = sdir / "frame_04.png"
    st = os.stat(target)
    img = cv2.imread(str(target), cv2.IMREAD_UNCHANGED)
    img[:10] = img[:10] // 2 + 1  # same size on disk is not needed: size, mtime and content are all checked
    assert cv2.imwrite(str(target), img)
    os.utime(target, ns=(st.st_atime_ns, st.st_mtime_ns))  # the modification time kept
    resumed = score_sequence(rdir, sdir, bits=14, progress=False, csv=out, resume=True)
    fresh = score_sequence(rdir, sdir, bits=14, progress=False)
    assert resumed.run["resumed"] == 5
    assert _values(resumed) == _values(fresh)
    assert float(_rows(out)[4]["psnr_db"]) == fresh.frames[4]["metrics"]["psnr_db"]


def test_a_csv_value_cut_by_an_editor_is_not_trusted(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".png", 6)
    out = tmp_path / "rows.csv"
    full = score_sequence(rdir, sdir, bits=14, progress=False, csv=out)
    lines = out.read_text(encoding="utf-8").splitlines()
    lines[3] = lines[3][: len(lines[3]) // 2]  # cut inside a value, then newline-terminated
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    rep = score_sequence(rdir, sdir, bits=14, progress=False, csv=out, resume=True)
    assert _values(rep) == _values(full)
    rows = _rows(out)
    assert [float(r["fidelity"]) for r in rows] == [f["fidelity"] for f in full.frames]


_WRITER = textwrap.dedent("""
    import sys, time
    from irfidelity.sequence import score_sequence
    def slow(done, total):
        time.sleep(0.2)
    score_sequence(sys.argv[1], sys.argv[2], bits=14, csv=sys.argv[3], progress=slow, workers=1)
""")


def test_a_second_writer_of_one_csv_is_refused(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".png", 12)
    out = tmp_path / "rows.csv"
    first = subprocess.Popen([sys.executable, "-c", _WRITER, str(rdir), str(sdir), str(out)])
    try:
        lock = pathlib.Path(str(out) + ".lock")
        for _ in range(300):
            if lock.exists() and lock.read_text().strip() == str(first.pid):
                break
            subprocess.run(["sleep", "0.05"])
        with pytest.raises(FidelityError, match=f"another irfidelity run \\(process {first.pid}\\)"):
            score_sequence(rdir, sdir, bits=14, progress=False, csv=out, resume=True)
    finally:
        first.wait(timeout=120)
    rows = _rows(out)
    assert sorted(int(r["index"]) for r in rows) == list(range(12))  # one writer, no duplicates
    rep = score_sequence(rdir, sdir, bits=14, progress=False, csv=out, resume=True)  # free again
    assert rep.run["resumed"] == 12


# --------------------------------------------------------------------------- odd arguments
@pytest.mark.parametrize("call", [
    lambda: irf.Weights(bogus=1),
    lambda: irf.Weights(mtf=1e308, sitf=1e308, psnr=0, nmi=0, ssim=0),
    lambda: irf.Weights.parse("mtf=1e309"),
    lambda: irf.FidelityReport.from_dict({"fidelity": "x", "grade": 1, "components": {}, "weights": {}}),
    lambda: irf.FidelityReport.from_dict([1, 2]),
    lambda: irf.SequenceReport.from_dict({"frames": 3}),
    lambda: irf.load_frame(PNGS[0], page=2**64),
    lambda: irf.load_frame(PNGS[0], max_pixels=2**64),
    lambda: irf.ScoringConfig(bits=2**70),
    lambda: irf.ScoringConfig(peak=1e400),
])
def test_odd_arguments_are_fidelity_errors(call):
    with pytest.raises(FidelityError) as info:
        call()
    assert str(info.value)


def test_odd_arguments_on_the_command_line(tmp_path):
    rdir, sdir = _write_dirs(tmp_path, ".png", 2)
    for args in (["--weights", "mtf=1e308,psnr=1e308"], ["--bits", str(2**70)], ["--workers", str(2**70)],
                 ["--max-delay", str(2**70)]):
        p = subprocess.run([sys.executable, "-m", "irfidelity.cli", "score", str(rdir), str(sdir), *args],
                           capture_output=True, text=True, timeout=120)
        assert p.returncode == 2, (args, p.stderr)
        assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1


def test_page_beyond_the_stack_is_a_frame_error():
    with pytest.raises(FrameError, match="page 5 out of range"):
        irf.load_frame(PNGS[0], page=5)
