"""One memory budget for a pair's work and a run's (docs/design.md §14): every operation on
large legal frames either refuses, before allocating, with the library's error naming it, or
takes a bounded path — in a child process under an address-space cap, which exits normally
(no signal, no MemoryError) — and the bounded paths give the same answers."""

from __future__ import annotations

import json
import re
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

import irfidelity as irf
from irfidelity import budget
from irfidelity.errors import FidelityError, FrameError, RegistrationError
from irfidelity.maps import sampled_ssim_map
from child_process import run_python

BIG = 8192
GIB = 1 << 30

# The child: cap its address space, make two BIG x BIG uint16 frames (a smooth ramp and a
# shifted copy, cheap to make), run one operation and print what happened as JSON.
CHILD = r"""
import json, resource, sys
job = json.loads(sys.argv[1])
resource.setrlimit(resource.RLIMIT_AS, (job["cap"], job["cap"]))
out = {}
try:
    import numpy as np, irfidelity as irf
    n = job["size"]
    if job.get("frames", True):
        ramp = (np.arange(n, dtype=np.uint32)[:, None] * 3 + np.arange(n, dtype=np.uint32)[None, :] * 5) % 4096
        real = ramp.astype(np.uint16)
        del ramp
        sim = np.roll(real, (2, 3), axis=(0, 1))
    op, kw = job["op"], job.get("kwargs", {})
    if op == "register":
        irf.register(real, sim, **kw)
    elif op == "evaluate":
        rep = irf.evaluate(real, sim, bits=12, **kw)
        out["fidelity"] = rep.fidelity
        if job.get("html"):
            page = rep.to_html(**job.get("html_kwargs", {}))
            out["html"] = len(page)
            out["ssim_mean"] = "Mean SSIM" in page
    elif op == "ssim_map":
        m = irf.maps.ssim_map(real, sim, bits=12, **kw)
        out["mean"], out["shape"] = m.mean, list(m.map.shape)
    elif op == "apply":
        reg = irf.registration.Registration.from_dict({"model": "translation", "method": "phase", "confidence": 1.0,
                                                       "overlap": 1.0, "matrix": [[1, 0, 2.5], [0, 1, -1.5]],
                                                       "shape": [n, n]})
        values, valid = reg.apply(sim, **kw)
        out["valid"] = int(valid.sum())
    elif op == "noise3d":
        nz = irf.noise.noise3d(job["paths"], **kw)
        out["sigma"] = nz.sigma
    elif op == "load":
        out["shape"] = list(irf.load_frame(job["path"], **kw).shape)
    elif op == "evaluate_paths":
        out["fidelity"] = irf.evaluate(job["real"], job["sim"], **kw).fidelity
    elif op == "cli":
        import contextlib, io
        from irfidelity.cli import main
        err, said = io.StringIO(), io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(said):
            out["status"] = main(job["argv"])
        out["stderr"], out["stdout"] = err.getvalue(), said.getvalue()
    elif op == "sequence":
        seq = irf.score_sequence(job["real"], job["sim"], progress=False, **kw)
        out["errors"] = [f["error"] for f in seq.frames]
        out["fidelity"] = [f["fidelity"] for f in seq.frames]
        out["run"] = seq.run
    out["kind"] = "ok"
except irf.errors.FidelityError as exc:
    out.update(kind="error", type=type(exc).__name__, message=str(exc))
except MemoryError as exc:
    out.update(kind="memory_error", message=str(exc))
# the peak resident size of this process (ru_maxrss would count the parent's at the fork too)
with open("/proc/self/status") as f:
    out["maxrss"] = next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmHWM:"))
print(json.dumps(out))
"""


def run_child(cap: int = 3 * GIB, size: int = BIG, timeout: float = 600, **job) -> dict:
    job.update(cap=cap, size=size)
    rec = run_python(CHILD, [json.dumps(job)], timeout=timeout)
    assert rec["kind"] != "memory_error", rec
    return rec


def assert_refused(rec: dict, kind: str, operation: str, size: int = BIG) -> None:
    """The library's error of ``kind``, naming the operation, the frame size, the bytes and the budget."""
    assert rec["kind"] == "error" and rec["type"] == kind, rec
    message = rec["message"]
    assert operation in message and f"{size} x {size} pixel frames" in message, message
    assert re.search(r"needs about \d+ bytes .* memory budget of \d+ bytes", message), message
    assert "max_bytes" in message and "max_memory" in message, message


def write_png(path: Path, frame: np.ndarray) -> str:
    assert cv2.imwrite(str(path), frame)
    return str(path)


def smooth_pair(rows: int, cols: int, shift: tuple[int, int] = (2, -3)) -> tuple[np.ndarray, np.ndarray]:
    """A smooth random scene and a shifted copy (registrable, 12-bit levels in uint16)."""
    rng = np.random.default_rng(7)
    coarse = rng.random((rows // 8 + 4, cols // 8 + 4))
    big = cv2.resize(coarse, ((cols // 8 + 4) * 8, (rows // 8 + 4) * 8), interpolation=cv2.INTER_CUBIC)
    big = np.clip(1000 + 2000 * big + rng.normal(0, 5, big.shape), 0, 4095).astype(np.uint16)
    real = big[16:16 + rows, 16:16 + cols]
    sim = big[16 - shift[0]:16 - shift[0] + rows, 16 - shift[1]:16 - shift[1] + cols]
    return np.ascontiguousarray(real), np.ascontiguousarray(sim)


# ------------------------------------------------------------------ large frames, capped


def test_register_8k_is_refused_before_it_allocates() -> None:
    rec = run_child(op="register")
    assert_refused(rec, "RegistrationError", "registration (translation, method phase)")
    assert rec["maxrss"] < 1 * GIB, rec  # the two frames, nothing of the search


def test_evaluate_8k_scores_unregistered_and_refuses_registration() -> None:
    rec = run_child(op="evaluate")
    assert rec["kind"] == "ok" and 0 < rec["fidelity"] <= 1, rec
    rec = run_child(op="evaluate", kwargs={"register": "rigid"})
    assert_refused(rec, "RegistrationError", "registration (rigid, method phase)")


def test_ssim_map_8k_within_the_budget_and_refused_beyond_it() -> None:
    rec = run_child(op="ssim_map")
    assert rec["kind"] == "ok" and rec["shape"] == [BIG, BIG] and 0 < rec["mean"] <= 1, rec
    rec = run_child(op="ssim_map", kwargs={"max_bytes": 512 << 20})
    assert_refused(rec, "FidelityError", "the SSIM map")


def test_apply_8k_is_refused_beyond_the_budget() -> None:
    rec = run_child(op="apply", kwargs={"max_bytes": 256 << 20})
    assert_refused(rec, "FidelityError", "resampling (Registration.apply)")


def test_to_html_8k_takes_the_bounded_path() -> None:
    # the page needs display-size copies only: well within the budget, under a 3 GiB cap
    rec = run_child(op="evaluate", html=True)
    assert rec["kind"] == "ok" and rec["html"] > 10_000 and rec["ssim_mean"], rec
    assert rec["maxrss"] < 2 * GIB, rec
    # a budget below the frames themselves is refused, naming the report
    rec = run_child(op="evaluate", html=True, html_kwargs={"max_bytes": 128 << 20})
    assert_refused(rec, "FidelityError", "the HTML report of a frame pair")


def test_noise3d_8k_files_plan_the_whole_measurement(tmp_path: Path) -> None:
    frame = np.full((BIG, BIG), 1000, dtype=np.uint16)
    paths = [write_png(tmp_path / f"n{i}.png", frame + i) for i in range(8)]
    # the default budget: the spectra are refused before the pass starts; without them the
    # sums fit, not with a worker's accumulator and two frames in flight
    rec = run_child(op="noise3d", frames=False, paths=paths)
    assert_refused(rec, "FidelityError", "the 3-D noise decomposition and spectra (spectra=False needs less)")
    assert rec["maxrss"] < 1 * GIB, rec
    rec = run_child(op="noise3d", frames=False, paths=paths, kwargs={"spectra": False})
    assert_refused(rec, "FidelityError", "the 3-D noise pass (1 worker, 1 frame read at a time each)")
    assert rec["maxrss"] < 1 * GIB, rec
    # 3 GiB: one worker decoding 4 frames at a time instead of two workers decoding 8
    rec = run_child(cap=4 * GIB + GIB // 2, op="noise3d", frames=False, paths=paths,
                    kwargs={"spectra": False, "max_bytes": 3 * GIB, "workers": 2})
    assert rec["kind"] == "ok", rec
    assert rec["sigma"]["tvh"] == 0 and rec["sigma"]["vh"] == 0 and rec["sigma"]["t"] > 2, rec
    assert rec["maxrss"] < 3 * GIB + GIB // 2, rec

def test_a_runs_peak_is_its_workers_times_the_pair_budget(tmp_path: Path) -> None:
    # four 8192² pairs on two workers: each pair gets max_memory // 2, so the run holds at
    # most max_memory besides the interpreter (the frames alone: 256 MiB a pair)
    frame = np.full((BIG, BIG), 1000, dtype=np.uint16)
    real, sim = tmp_path / "real", tmp_path / "sim"
    real.mkdir()
    sim.mkdir()
    for i in range(4):
        write_png(real / f"f{i}.png", frame + i)
        write_png(sim / f"f{i}.png", frame + 2 * i)
    max_memory = 2 * (256 << 20) + (64 << 20)
    rec = run_child(op="sequence", frames=False, real=str(real), sim=str(sim),
                    kwargs={"workers": 2, "max_memory": max_memory, "bits": 12})
    assert rec["kind"] == "ok" and rec["errors"] == [None] * 4, rec
    assert rec["run"]["max_bytes"] == max_memory // 2
    assert rec["maxrss"] < max_memory + (256 << 20), rec  # + the interpreter and libraries
    # half the budget: every pair is its own error row (the simulated frame does not fit
    # what the real one leaves), the run ends normally
    rec = run_child(op="sequence", frames=False, real=str(real), sim=str(sim),
                    kwargs={"workers": 2, "max_memory": max_memory // 2, "bits": 12})
    assert rec["kind"] == "ok" and all("max_bytes" in e for e in rec["errors"]), rec
    assert rec["maxrss"] < max_memory, rec



def test_register_each_sequence_8k_pair_is_an_error_row(tmp_path: Path) -> None:
    small_real, small_sim = smooth_pair(96, 128)
    big = np.full((BIG, BIG), 1000, dtype=np.uint16)
    real, sim = tmp_path / "real", tmp_path / "sim"
    real.mkdir()
    sim.mkdir()
    for i, (r, s) in enumerate([(small_real, small_sim), (big, big), (small_real, small_sim)]):
        write_png(real / f"f{i}.png", r)
        write_png(sim / f"f{i}.png", s)
    rec = run_child(op="sequence", frames=False, real=str(real), sim=str(sim),
                    kwargs={"register": "translation", "register_each": True, "workers": 1})
    assert rec["kind"] == "ok", rec
    errors = rec["errors"]
    assert errors[0] is None and errors[2] is None, errors
    assert "registration (translation, method phase) and scoring of a frame pair" in errors[1], errors
    assert f"{BIG} x {BIG} pixel frames" in errors[1] and "max_bytes" in errors[1], errors
    assert all(0 < f <= 1 for i, f in enumerate(rec["fidelity"]) if i != 1), rec["fidelity"]


# ------------------------------------------------------------------ plans and bounded paths


def test_over_budget_errors_name_the_step_everywhere() -> None:
    real, sim = smooth_pair(64, 80)
    tiny = 10_000
    with pytest.raises(RegistrationError, match=r"registration \(rigid, method phase\) of 64 x 80 pixel frames"):
        irf.register(real, sim, model="rigid", method="phase", max_bytes=tiny)
    with pytest.raises(FidelityError, match=r"the SSIM map of 64 x 80"):
        irf.maps.ssim_map(real, sim, bits=12, max_bytes=tiny)
    with pytest.raises(FidelityError, match=r"MS-SSIM of 64 x 80"):
        irf.maps.ms_ssim(real, sim, bits=12, max_bytes=tiny)
    with pytest.raises(FidelityError, match=r"scoring a frame pair of 64 x 80"):
        irf.evaluate(real, sim, bits=12, max_bytes=tiny)
    reg = irf.register(real, sim)
    with pytest.raises(FidelityError, match=r"resampling \(Registration.apply\)"):
        reg.apply(sim, max_bytes=tiny)
    for bad in (0, -1, True, 1.5, "1G"):
        with pytest.raises(FidelityError, match="max_bytes must be a positive number of bytes"):
            irf.register(real, sim, max_bytes=bad)


def _decoding_peak(path: str) -> int:
    """The smallest budget that decodes ``path`` (bisection on load_frame)."""
    lo, hi = 1, 1 << 24
    while lo < hi:
        mid = (lo + hi) // 2
        try:
            irf.load_frame(path, max_bytes=mid)
            hi = mid
        except FrameError:
            lo = mid + 1
    return lo


def test_decoding_within_the_pair_budget(tmp_path: Path) -> None:
    real, sim = smooth_pair(64, 80)
    pr, ps = write_png(tmp_path / "r.png", real), write_png(tmp_path / "s.png", sim)
    assert irf.evaluate(pr, ps, bits=12, max_bytes=1 << 20).fidelity == irf.evaluate(real, sim, bits=12).fidelity
    # the simulated frame is decoded within what the real one leaves
    decoding = _decoding_peak(ps)
    assert decoding >= sim.nbytes
    with pytest.raises(FrameError, match=r"s\.png: decoding .* exceeds the decoding budget .*\(max_bytes\)"):
        irf.evaluate(pr, ps, bits=12, max_bytes=decoding + real.nbytes - 1)
    assert irf.evaluate(pr, ps, bits=12, max_bytes=decoding + real.nbytes + 4 * real.size).fidelity > 0


def test_budget_does_not_change_the_answers() -> None:
    real, sim = smooth_pair(120, 160)
    reg = irf.register(real, sim, model="rigid")
    assert irf.register(real, sim, model="rigid", max_bytes=64 << 20) == reg
    a = irf.evaluate(real, sim, bits=12, register="translation")
    b = irf.evaluate(real, sim, bits=12, register="translation", max_bytes=64 << 20)
    assert a.components == b.components and a.registration == b.registration


def test_sampled_ssim_map_equals_the_displayed_part_of_the_map() -> None:
    real, sim = smooth_pair(131, 97)
    whole = irf.maps.ssim_map(real, sim, bits=12)
    for step in (1, 2, 3, 7, 40):
        part = sampled_ssim_map(real, sim, step, peak=4095.0)
        assert np.array_equal(part.map, whole.map[::step, ::step]), step
        assert part.mean == whole.mean


def test_report_statistics_are_those_of_the_whole_frames(monkeypatch: pytest.MonkeyPatch) -> None:
    from irfidelity.report import pair

    real, sim = smooth_pair(200, 300)
    mask = np.ones(real.shape, dtype=bool)
    mask[10:40, 50:90] = False
    monkeypatch.setattr(pair, "BAND_PIXELS", 1000)  # many bands of a few rows
    count, mean, rms, largest = pair._difference_stats(real, sim, mask)
    diff = (sim.astype(np.float64) - real.astype(np.float64))[mask]
    assert count == diff.size and largest == np.abs(diff).max()
    assert mean == pytest.approx(diff.mean(), rel=1e-12) and rms == pytest.approx(np.sqrt(np.mean(diff**2)), rel=1e-12)
    noisy = real.astype(np.float32)
    noisy[3, 4], noisy[150, 7] = np.nan, np.inf
    counts, edges = pair._histogram(noisy)
    want_counts, want_edges = np.histogram(noisy[np.isfinite(noisy)], bins=256)
    assert np.array_equal(counts, want_counts) and np.array_equal(edges, want_edges)


def test_noise_pass_takes_fewer_workers_and_frames_when_the_budget_asks(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    frames = rng.integers(900, 1100, (12, 64, 80), dtype=np.uint16)
    paths = [write_png(tmp_path / f"f{i:02d}.png", f) for i, f in enumerate(frames)]
    want = irf.noise.noise_sums(frames).exact_ss()
    pixels, frame = 64 * 80, 64 * 80 * 2
    lines = 2 * 8 * 12 * (64 + 80)
    # two accumulators (the total and one worker's) and two frames in flight: nothing more fits
    tight = 2 * 16 * pixels + lines + 2 * frame
    got = irf.noise.noise_sums(paths, workers=2, max_bytes=tight)
    assert got.exact_ss() == want
    with pytest.raises(FidelityError, match=r"the 3-D noise pass \(1 worker, 1 frame read at a time each\) of 64 x 80"):
        irf.noise.noise_sums(paths, max_bytes=tight - 1)
    # float frames: fewer workers, the same sums bit for bit
    floats = frames.astype(np.float32)
    assert irf.noise.noise_sums(floats, workers=2).to_bytes() == irf.noise.noise_sums(floats, workers=2,
                                                                                      max_bytes=100 * pixels).to_bytes()
    with pytest.raises(FidelityError, match=r"spectra \(spectra=False needs less\)"):
        irf.noise.noise3d(frames, max_bytes=60 * pixels)
    limited = irf.noise.noise3d(frames, spectra=False, max_bytes=60 * pixels)
    assert limited.sigma == irf.noise.noise3d(frames, spectra=False).sigma


# ------------------------------------------------------------------ a run's budget


def test_max_memory_is_shared_by_the_workers(tmp_path: Path) -> None:
    real, sim = smooth_pair(64, 80)
    seq = irf.score_sequence(np.stack([real] * 3), np.stack([sim] * 3), bits=12, workers=2, max_memory=8 << 20,
                             progress=False)
    assert seq.run["max_bytes"] == 4 << 20 and seq.run["max_memory"] == 8 << 20
    assert not seq.failed
    # files, registered on their own, each pair over its share: error rows, the run goes on
    (tmp_path / "r").mkdir()
    (tmp_path / "s").mkdir()
    for i in range(3):
        write_png(tmp_path / "r" / f"{i}.png", real)
        write_png(tmp_path / "s" / f"{i}.png", sim)
    seq = irf.score_sequence(tmp_path / "r", tmp_path / "s", bits=12, workers=2, max_memory=2 * (1 << 20),
                             max_bytes=10 << 20, register="translation", register_each=True, progress=False)
    assert seq.run["max_bytes"] == 1 << 20
    assert seq.failed == [0, 1, 2]
    assert all("registration (translation, method phase) and scoring of a frame pair" in f["error"] for f in seq.frames)
    assert budget.per_pair(None, None, 4) is None and budget.per_pair(3 << 20, None, 4) == 3 << 20
    with pytest.raises(FidelityError, match="leaves nothing"):
        budget.per_pair(None, 3, 4)


@pytest.mark.parametrize("text,want", [("2G", 2 << 30), ("512M", 512 << 20), ("1000", 1000), ("64k", 64 << 10),
                                        ("1.5GiB", 3 << 29), (" 8 GB ", 8 << 30)])
def test_sizes_parse(text: str, want: int) -> None:
    assert budget.parse_size(text) == want


@pytest.mark.parametrize("text", ["", "G", "-1G", "2X", "0", "1e9", "0.1", "8388608T", "99999999999T"])
def test_bad_sizes_are_refused(text: str) -> None:
    with pytest.raises(FidelityError, match="size"):
        budget.parse_size(text)


def test_cli_max_memory(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from irfidelity.cli import main

    real, sim = smooth_pair(64, 80)
    pr, ps = write_png(tmp_path / "r.png", real), write_png(tmp_path / "s.png", sim)
    assert main(["score", pr, ps, "--bits", "12", "--max-memory", "64M"]) == 0
    assert main(["score", pr, ps, "--bits", "12", "--max-memory", "lots"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--max-memory" in err[0] and "2G" in err[0], err
    assert main(["score", pr, ps, "--bits", "12", "--register", "translation", "--max-memory", "100k"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "memory budget of 102400 bytes" in err[0] and "--max-memory" in err[0], err


def test_the_transfer_plans_its_copies_of_cropped_frames() -> None:
    """A cropped view is copied for the kernel: planned with the frames before it is made."""
    rng = np.random.default_rng(3)
    whole = rng.normal(1000.0, 20.0, (1024, 1025))
    real, sim = whole[:, :-1], whole[:, 1:]  # views, not C-contiguous: 8 MB each
    frames = real.nbytes + sim.nbytes
    with pytest.raises(FidelityError, match="measuring the transfer of 1024 x 1024") as err:
        irf.transfer(real, sim, max_bytes=frames + real.size)  # no room for the two copies
    assert "max_bytes" in str(err.value) or "budget" in str(err.value)
    t = irf.transfer(np.ascontiguousarray(real), np.ascontiguousarray(sim), max_bytes=frames + real.size)
    assert t.tiles > 0


# ------------------------------------------------------------------ radiometric files, capped

def flir_file(path: Path, size: int, counts: np.ndarray | None) -> str:
    """A little-endian FLIR FFF frame of ``size`` x ``size`` counts (each row ``counts``, or
    zeros), as a PNG raw record (FLIR's byte order) with a camera-info record holding a
    Duo Pro R calibration; built row by row, never holding the frame."""
    row = b"\0" + (bytes(2 * size) if counts is None else counts.astype("<u2").tobytes())
    z = zlib.compressobj(1)
    rows = b"".join(z.compress(row) for _ in range(size)) + z.flush()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 16, 0, 0, 0, 0))
           + chunk(b"IDAT", rows) + chunk(b"IEND", b""))
    raw = struct.pack("<HHH", 2, size, size) + bytes(26) + png
    camera = bytearray(0x468)
    camera[0:2] = struct.pack("<H", 2)
    for at, value in {0x20: 0.95, 0x24: 1.0, 0x28: 293.15, 0x2C: 293.15, 0x30: 293.15, 0x34: 1.0, 0x3C: 0.5,
                      0x58: 17096.0, 0x5C: 1428.0, 0x60: 1.0, 0x70: 0.006569, 0x74: 0.01262, 0x78: -0.002276,
                      0x7C: -0.00667, 0x80: 1.9, 0x30C: 0.0125}.items():
        camera[at:at + 4] = struct.pack("<f", value)
    camera[0x308:0x30C] = struct.pack("<i", -370)
    records = [(1, raw), (0x20, bytes(camera))]
    head = bytearray(64)
    head[:4], head[4:8] = b"FFF\0", b"FLIR"
    head[20:32] = struct.pack("<III", 100, 64, len(records))
    at, directory = 64 + 32 * len(records), b""
    for kind, body in records:
        directory += struct.pack("<HHIIII", kind, 1, 100, 1, at, len(body)) + bytes(12)
        at += len(body)
    path.write_bytes(bytes(head) + directory + b"".join(body for _, body in records))
    return str(path)


def test_a_huge_radiometric_frame_in_temperature_is_refused_under_a_cap(tmp_path: Path) -> None:
    """A 2 MB FFF whose PNG holds 16000 x 16000 counts: refused by the default pixel limit, and
    with the limit raised its conversion to temperature is refused by the budget before it
    allocates (it aborted under a 2 GB cap)."""
    path = flir_file(tmp_path / "huge.fff", 16000, None)
    rec = run_child(cap=2 * GIB, frames=False, op="load", path=path, kwargs={"unit": "C"})
    assert rec["kind"] == "error" and "exceeds the limit of 67108864 pixels" in rec["message"], rec
    rec = run_child(cap=2 * GIB, frames=False, op="load", path=path,
                    kwargs={"unit": "C", "max_bytes": 600_000_000, "max_pixels": 16000 * 16000})
    assert rec["kind"] == "error" and "conversion to temperature of 16000 x 16000" in rec["message"], rec
    assert rec["maxrss"] < 800 << 20, rec


def test_scoring_in_temperature_at_8k_peaks_at_its_plan(tmp_path: Path) -> None:
    """Two 8192 x 8192 FFF frames scored in °C within a 1300 MiB budget, under a cap: the
    peak is the scoring plan's (both frames' temperatures and 3 bytes a pixel) within 10 %,
    and a smaller budget refuses the simulated frame's conversion, naming it."""
    levels = (np.arange(BIG) * 3) % 2000
    real = flir_file(tmp_path / "real.fff", BIG, 13000 + levels)
    sim = flir_file(tmp_path / "sim.fff", BIG, 13100 + levels)
    budget_bytes = 1300 << 20
    rec = run_child(cap=int(1.9 * GIB), frames=False, op="evaluate_paths", real=real, sim=sim,
                    kwargs={"unit": "C", "max_bytes": budget_bytes})
    assert rec["kind"] == "ok" and 0 < rec["fidelity"] <= 1, rec
    plan = 2 * 8 * BIG * BIG + 3 * BIG * BIG  # budget.SCORING_BYTES
    assert abs(rec["maxrss"] - plan) <= 0.1 * plan and rec["maxrss"] <= budget_bytes, (rec["maxrss"], plan)
    rec = run_child(cap=int(1.9 * GIB), frames=False, op="cli",
                    argv=["score", real, sim, "--unit", "C", "--max-memory", "1100M"])
    assert rec["status"] == 2 and len(rec["stderr"].strip().splitlines()) == 1, rec
    assert "conversion to temperature beside the pair's other frames" in rec["stderr"] and "--max-memory" in rec["stderr"]


def test_a_sequence_of_frames_beyond_the_pixel_limit_is_error_rows_under_a_cap(tmp_path: Path) -> None:
    """Two workers on two pairs of small files that decode to 16384 x 16384: error rows naming
    --max-pixels by default; with it raised, scored within the workers' budgets; never a signal."""
    rows = zlib.compress(bytes(16384 * (1 + 2 * 16384)), 1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 16384, 16384, 16, 0, 0, 0, 0))
           + chunk(b"IDAT", rows) + chunk(b"IEND", b""))
    for side in ("real", "sim"):
        (tmp_path / side).mkdir()
        for i in range(2):
            (tmp_path / side / f"{i}.png").write_bytes(png)
    argv = ["score", str(tmp_path / "real"), str(tmp_path / "sim"), "--workers", "2", "--no-progress", "--bits", "12"]
    rec = run_child(cap=4 * GIB, frames=False, op="cli", argv=argv)
    assert rec["status"] == 3 and "0 scored, 2 failed" in rec["stdout"], rec
    assert "exceeds the limit of 67108864 pixels; raise max_pixels (--max-pixels)" in rec["stdout"], rec
    rec = run_child(cap=4 * GIB, frames=False, op="cli", argv=[*argv, "--max-pixels", str(16384 * 16384)])
    assert rec["status"] == 0 and "2 scored, 0 failed" in rec["stdout"], rec  # within 2 workers x 2 GiB


DATA = Path(__file__).parent / "data"


@pytest.mark.parametrize("argv, needle", [
    (["targets", "{tmp}/out", "--frequency", "0.1", "--size", "30000,30000", "--format", "npy"], "--size 30000,30000"),
    (["targets", "{tmp}/out", "--frequency", "0.1", "--levels", "0,1e308", "--format", "tiff"], "--levels 0,1e308"),
    (["rank", "{lepton}", "{lepton}", "{lepton}", "--names", "a,b", "--no-progress", "--resamples", "100000000"],
     "--resamples"),
    (["weights", "fit", "{tmp}/many.csv"], "more than 100000 judgement rows"),
    (["weights", "fit", "{tmp}/huge.csv"], "not a CSV row"),
])
def test_the_cli_answers_in_one_line_under_a_cap(tmp_path: Path, argv: list[str], needle: str) -> None:
    """The CLI cases that printed tracebacks or grew without bound, each in a child under a
    1 GiB address-space cap: exit 2 and one line naming the flag or the file's fault."""
    header = "a_psnr,a_ssim,b_psnr,b_ssim,preferred\n"
    if "many.csv" in argv[-1]:
        (tmp_path / "many.csv").write_text(header + "0.9,0.7,0.8,0.9,b\n" * 1_000_000)  # 18 MB
    if "huge.csv" in argv[-1]:
        (tmp_path / "huge.csv").write_text(header + "0.9,0.7,0.8,0.9," + "b" * 200_000 + "\n")
    lepton = str(DATA / "thermal" / "cptv_v2_all100frames_uint16.tif")
    argv = [a.format(tmp=tmp_path, lepton=lepton) for a in argv]
    rec = run_child(cap=GIB, frames=False, op="cli", argv=argv)
    err = rec["stderr"].strip()
    assert rec["status"] == 2 and len(err.splitlines()) == 1 and needle in err, rec
    assert not list(tmp_path.glob("out/*.*"))  # nothing written
