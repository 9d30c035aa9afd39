"""Resuming a sequence run (issue 25): constant memory, fingerprints of what was scored,
forged records re-scored instead of trusted or fatal, and the lock file removed at the end.

Data: tiny random frames made in tmp_path (the cost of a record is its 256² joint histogram,
not its pixels), and the 100-frame Lepton recording of tests/data/thermal for the stacks.
"""

from __future__ import annotations

import json
import os
import pathlib
import struct
import subprocess
import sys
import textwrap
import zlib

import numpy as np
import pytest

from irfidelity import _core
from irfidelity.errors import FidelityError
from irfidelity.sequence import run as run_module
from irfidelity.sequence import score_sequence
from irfidelity.sequence import lock as lock_module
from irfidelity.sequence.lock import Lock
from irfidelity.sequence.sidecar import (RECORD_MAGIC, BadRecord, Limits, Scan, encode_record, max_stats_size,
                                         pack_stats, read_header, read_record, unpack_stats)
from irfidelity.stats import pair_stats

from child_process import run_python

tifffile = pytest.importorskip("tifffile")
cv2 = pytest.importorskip("cv2")

OPTIONS = dict(bits=14, hist_range="full", progress=False)  # nmi weighted: a 256² histogram per record


def _frames(count: int, seed: int = 3, shape=(32, 32)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    real = rng.integers(0, 16384, (count, *shape), dtype=np.uint16)
    sim = np.clip(real.astype(np.int64) + rng.integers(-40, 40, real.shape), 0, 16383).astype(np.uint16)
    return np.stack([real, sim])


def _pngs(root: pathlib.Path, count: int) -> tuple[pathlib.Path, pathlib.Path]:
    frames = _frames(count)
    dirs = root / "real", root / "sim"
    for d, side in zip(dirs, frames):
        d.mkdir(parents=True)
        for i, frame in enumerate(side):
            assert cv2.imwrite(str(d / f"f{i:05d}.png"), frame)
    return dirs


def _values(rep) -> list:
    return [(f["index"], f["fidelity"], f["metrics"], f["error"]) for f in rep.frames]


def _records(side: pathlib.Path) -> dict[int, tuple]:
    """``index -> (meta, payload)`` of the intact records of a log (the last of each)."""
    with open(side, "rb") as fh:
        _, start = read_header(fh)
        limits = Limits(1 << 24)
        return {i: read_record(fh, off, size, limits)[1:] for off, size, i in Scan(fh, start, limits)}


def _raw_record(index: int, meta: bytes, payload: bytes) -> bytes:
    """A record with a valid CRC around whatever meta and payload."""
    body = struct.pack("<QII", index, len(meta), len(payload)) + meta + payload
    return RECORD_MAGIC + struct.pack("<I", zlib.crc32(body)) + body


def _bomb(size: int) -> bytes:
    """A valid zlib stream of ``size`` zero bytes (a multiple of 16 MiB), about a thousandth of
    it long: one 16 MiB block repeated (its back-references reach only zeros)."""
    chunk = 16 << 20
    deflate = zlib.compressobj(9)
    first = deflate.compress(b"\0" * chunk) + deflate.flush(zlib.Z_SYNC_FLUSH)
    adler = ((size % 65521) << 16) | 1
    return first + first[2:] * (size // chunk - 1) + b"\x03\x00" + adler.to_bytes(4, "big")


# --------------------------------------------------------------------------- the record format
def test_max_stats_size_bounds_real_statistics():
    rng = np.random.default_rng(0)
    for dtype, bits, bins, levels, shape in [
        (np.uint16, 14, 256, None, (64, 80)),  # dense 256²
        (np.uint16, 14, 2000, None, (64, 80)),  # sparse, bounded by the pixels
        (np.uint16, 14, 2000, None, (8, 8)),
        (np.uint8, 8, "levels", 256, (40, 40)),  # dense levels
        (np.uint16, 14, "levels", 1 << 14, (64, 80)),  # sparse levels
        (np.float32, None, 300, None, (33, 17)),
    ]:
        hi = 255 if dtype == np.uint8 else 16383
        real = (rng.random(shape) * hi).astype(dtype)
        sim = (rng.random(shape) * hi).astype(dtype)
        st = pair_stats(real, sim, bits=bits, bins=bins, need=("psnr", "nmi", "ssim"))
        size = len(st.to_bytes())
        bound = max_stats_size(bins if levels is None else None, levels, shape[0] * shape[1])
        assert size <= bound, (dtype, bins, size, bound)
        assert unpack_stats(pack_stats(st.to_bytes()), bound) == st.to_bytes()
    assert len(pair_stats(real, sim, need=("psnr",)).to_bytes()) <= max_stats_size(None, None, 1)


def test_unpacking_is_bounded_and_refuses_what_is_not_a_payload():
    stats = bytes(range(256)) * 3 + b"\0" * 5000 + b"\x01\x02\x03"
    packed = pack_stats(stats)
    assert len(packed) < 400 and unpack_stats(packed, len(stats)) == stats
    with pytest.raises(BadRecord, match="statistics of 5771 bytes, beyond the 5770"):
        unpack_stats(packed, len(stats) - 1)
    assert len(zlib.decompress(_bomb(64 << 20))) == 64 << 20  # a real zlib stream, from 65 kB
    with pytest.raises(BadRecord, match="larger than"):
        unpack_stats(_bomb(64 << 20), 1 << 16)
    body = zlib.decompress(packed)
    for bad in (b"", b"garbage", packed[:-3], packed + b"x", zlib.compress(body[:-8]), zlib.compress(body + b"\0" * 8),
                zlib.compress(struct.pack("<Q", 1 << 60) + body[8:]), zlib.compress(b"\0" * 8 + b"\xff" + b"\0" * 8)):
        with pytest.raises(BadRecord):
            unpack_stats(bad, 1 << 20)


def test_a_scan_resynchronises_after_damage_and_reads_records_in_blocks(tmp_path):
    path = tmp_path / "log"
    noise = np.random.default_rng(5).integers(0, 256, 3000, np.uint8).tobytes()  # does not compress
    records = [encode_record(i, {"i": i}, bytes([i]) * 100 + noise) for i in range(5)]
    garbage = b"\xff" * 70 + RECORD_MAGIC + b"\x01" * 9
    path.write_bytes(b"HEAD" + records[0] + garbage + records[1] + records[2][:-1] + records[3] + records[4][:30])
    limits = Limits(1 << 16)
    with open(path, "rb") as fh:
        scan = Scan(fh, 4, limits)
        found = [(i, read_record(fh, off, size, limits)[1]) for off, size, i in scan]
        assert found == [(0, {"i": 0}), (1, {"i": 1}), (3, {"i": 3})]
        assert scan.damaged == 4  # the garbage, its false magic, the cut record 2 and the cut record 4
        # lengths beyond what this run's records can hold are not even read
        assert [i for _, _, i in Scan(fh, 4, Limits(1000))] == []


# --------------------------------------------------------------------------- constant memory
_PEAK_MB = textwrap.dedent("""
    import resource
    def peak_mb():  # this process's peak RSS (VmHWM starts afresh at exec; ru_maxrss keeps the parent's)
        try:
            with open("/proc/self/status") as fh:
                return next(int(line.split()[1]) / 1024 for line in fh if line.startswith("VmHWM:"))
        except (OSError, StopIteration):
            return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
""")

_RESUME_RSS = _PEAK_MB + textwrap.dedent("""
    import json, sys, time
    from irfidelity.sequence import score_sequence
    t = time.perf_counter()
    rep = score_sequence(sys.argv[1], sys.argv[2], csv=sys.argv[3], resume=True, bits=14, hist_range="full",
                         progress=False)
    print(json.dumps({"rss_mb": peak_mb(),
                      "seconds": time.perf_counter() - t, "resumed": rep.run["resumed"], "notes": rep.notes,
                      "fidelity": rep.fidelity, "nmi": rep.metrics["nmi"], "failed": rep.failed}))
""")


class _Stop(Exception):
    pass


def _finished_stack_run(tmp_path: pathlib.Path, count: int) -> tuple[pathlib.Path, pathlib.Path, pathlib.Path]:
    """A finished run over ``count`` pages of two stacks of one repeated 32x32 frame each: its
    header is the real run's, its records the first record with the index and page changed
    (every page is the same frame, so they are its true records; writing them is much faster
    than scoring them)."""
    frames = _frames(1)
    paths = tmp_path / f"real{count}.tif", tmp_path / f"sim{count}.tif"
    for path, side in zip(paths, frames):
        tifffile.imwrite(path, np.repeat(side, count, axis=0))
    out = tmp_path / f"run{count}.csv"

    def stop(done, total):
        raise _Stop

    with pytest.raises(_Stop):
        score_sequence(*paths, csv=out, workers=1, **{**OPTIONS, "progress": stop})
    side = pathlib.Path(str(out) + ".pairstats")
    records = _records(side)
    meta, payload = records[min(records)]
    with open(side, "ab") as fh:
        for index in range(count):
            if index in records:
                continue
            meta["inputs"]["real"][1] = meta["inputs"]["sim"][1] = index
            fh.write(_raw_record(index, json.dumps(meta).encode(), payload))
    return paths[0], paths[1], out


def test_resume_memory_does_not_grow_with_the_run(tmp_path):
    peaks = {}
    for count in (100, 5000):
        real, sim, out = _finished_stack_run(tmp_path, count)
        got = run_python(_RESUME_RSS, [str(real), str(sim), str(out)], timeout=300)
        assert got["resumed"] == count and got["failed"] == [] and got["notes"] == []
        peaks[count] = got["rss_mb"]
        if count == 100:
            small = got
        else:  # every page is the same pair: the pooled score is the single pair's
            assert got["nmi"] == pytest.approx(small["nmi"], rel=1e-12)
            assert got["fidelity"] == pytest.approx(small["fidelity"], rel=1e-12)
    assert peaks[5000] - peaks[100] < 60, peaks  # each record holds a 512 kB histogram: 2.6 GB if all were kept


# --------------------------------------------------------------------------- stale fingerprints
def _rewrite_when_delivered(monkeypatch, targets: dict[int, callable]) -> None:
    """After the engine decoded a frame and before the run records it, rewrite its file(s):
    the race a fingerprint taken after decoding loses."""
    deliver = run_module._Scorer.deliver

    def rewriting(self, outcomes):
        for outcome in outcomes:
            change = targets.pop(outcome.index, None)
            if change is not None:
                change()
        deliver(self, outcomes)

    monkeypatch.setattr(run_module._Scorer, "deliver", rewriting)


@pytest.mark.parametrize("kind", ["png", "stack", "npy"])
def test_a_file_changed_during_the_run_is_scored_again(tmp_path, monkeypatch, kind):
    count = 8
    real, sim = _frames(count)
    changed = np.clip(sim.astype(np.int64) * 3 // 4 + 100, 0, 16383).astype(np.uint16)
    if kind == "png":
        rdir, sdir = _pngs(tmp_path, count)
        sources = rdir, sdir

        def change(i):
            return lambda: cv2.imwrite(str(sdir / f"f{i:05d}.png"), changed[i])

        targets = {2: change(2), 5: change(5)}
    elif kind == "stack":  # later pages of a stack hashed before decoding; the whole stack rewritten
        sources = tmp_path / "real.tif", tmp_path / "sim.tif"
        tifffile.imwrite(sources[0], real)
        tifffile.imwrite(sources[1], sim)
        after = sim.copy()
        after[5:] = changed[5:]
        targets = {4: lambda: tifffile.imwrite(sources[1], after)}
    else:  # arrays scored by the Python loop: the arrays scored are hashed
        rdir, sdir = tmp_path / "real", tmp_path / "sim"
        rdir.mkdir()
        sdir.mkdir()
        for i in range(count):
            np.save(rdir / f"f{i}.npy", real[i])
            np.save(sdir / f"f{i}.npy", sim[i])
        sources = rdir, sdir

        def change(i):
            return lambda: np.save(sdir / f"f{i}.npy", changed[i])

        targets = {3: change(3), 6: change(6)}
    out = tmp_path / "rows.csv"
    with monkeypatch.context() as patch:
        _rewrite_when_delivered(patch, targets)
        score_sequence(*sources, csv=out, workers=1, **OPTIONS)
    assert not targets, "every change was made"
    resumed = score_sequence(*sources, csv=out, resume=True, **OPTIONS)
    fresh = score_sequence(*sources, **OPTIONS)
    assert _values(resumed) == _values(fresh)
    assert resumed.fidelity == fresh.fidelity and resumed.metrics == fresh.metrics
    assert resumed.run["resumed"] < count
    assert any("changed since they were scored" in n for n in resumed.notes)
    assert [float(r.split(",")[-3]) for r in out.read_text().splitlines()[1:]] == \
        [f["fidelity"] for f in fresh.frames]


def test_the_engine_fingerprints_what_it_decoded(tmp_path):
    real, sim = _frames(3)
    stack = tmp_path / "stack.tif"
    tifffile.imwrite(stack, np.concatenate([real, sim]))
    png = tmp_path / "one.png"
    cv2.imwrite(str(png), real[0])
    from irfidelity.sequence.plan import SequenceRequest
    from irfidelity.stats import PairRequest

    out = _core.score_pairs([str(png), str(stack), str(stack)], [str(stack)] * 3, [0, 1, 2], [3, 4, 5],
                            request=SequenceRequest(PairRequest(bins=None)), fingerprints=True)
    digests = dict(zip(map(str, (png, stack)), _core.file_digests([png, stack])))
    for k, _st, err, *_, fingerprints in out:
        assert err is None
        (rsize, rtime, rdigest), (ssize, stime, sdigest) = fingerprints
        real_path = str(png) if k == 0 else str(stack)
        assert (rsize, rtime, rdigest) == (os.stat(real_path).st_size, os.stat(real_path).st_mtime_ns,
                                           digests[real_path])
        assert (ssize, stime, sdigest) == (os.stat(stack).st_size, os.stat(stack).st_mtime_ns, digests[str(stack)])


# --------------------------------------------------------------------------- forged records
_RESUME_FORGED = _PEAK_MB + textwrap.dedent("""
    import json, sys
    from irfidelity.sequence import score_sequence
    rep = score_sequence(sys.argv[1], sys.argv[2], csv=sys.argv[3], resume=True, bits=14, hist_range="full",
                         progress=False)
    print(json.dumps({"rss_mb": peak_mb(), "notes": rep.notes,
                      "resumed": rep.run["resumed"],
                      "frames": [[f["index"], f["fidelity"], f["metrics"], f["error"]] for f in rep.frames],
                      "fidelity": rep.fidelity}))
""")


def test_forged_records_are_scored_again_never_trusted_nor_fatal(tmp_path):
    rdir, sdir = _pngs(tmp_path, 13)
    out = tmp_path / "rows.csv"
    fresh = score_sequence(rdir, sdir, csv=out, **OPTIONS)
    side = pathlib.Path(str(out) + ".pairstats")
    genuine = _records(side)
    overflowing = bytearray(unpack_stats(genuine[12][1], 1 << 20))
    overflowing[110:126] = (1 << 120).to_bytes(16, "little")  # the SSE: beyond 1024 pixels of 14 bits
    float_stats = pair_stats(np.zeros((32, 32), np.float32), np.ones((32, 32), np.float32), bins=256,
                             need=("psnr", "nmi", "ssim")).to_bytes()

    def meta(index, **changes):
        m = dict(genuine[index][0], **changes)
        return json.dumps({k: v for k, v in m.items() if v != "drop"}).encode()

    stats = zlib.decompress(genuine[0][1])
    forged = {
        0: (meta(0), _bomb(384 << 20)),  # 384 MB of zeros, within a record's length limit
        1: (meta(1), pack_stats(bytes(np.random.default_rng(1).integers(0, 256, len(stats), np.uint8)))),
        2: (meta(2, shape="drop"), genuine[2][1]),
        3: (json.dumps([genuine[3][0]]).encode(), genuine[3][1]),
        4: (meta(4, shape=["32", 32]), genuine[4][1]),
        5: (meta(5, dtype=16), genuine[5][1]),
        6: (meta(6, extent="wide"), genuine[6][1]),
        7: (meta(7, registration=[1, 2]), genuine[7][1]),
        8: (meta(8, shape=[1 << 40, 1 << 40]), genuine[8][1]),
        9: (meta(9), pack_stats(float_stats)),  # statistics of another kind (float sums)
        10: (meta(10, shape=[16, 32]), genuine[10][1]),  # counts that are not its frame's
        11: (b"[" * 30000 + b"]" * 30000, genuine[11][1]),  # nested beyond the parser
        12: (meta(12), pack_stats(bytes(overflowing))),
    }
    with open(side, "ab") as fh:  # appended: the last record of each frame is the one a resume reads
        for index, (m, payload) in forged.items():
            fh.write(_raw_record(index, m, payload))
        fh.write(_raw_record(40, meta(0), genuine[0][1]))  # a frame this run does not have
    got = run_python(_RESUME_FORGED, [str(rdir), str(sdir), str(out)], timeout=300)
    assert got["resumed"] == 0
    assert got["frames"] == [list(v) for v in _values(fresh)] and got["fidelity"] == fresh.fidelity
    assert any("14 record(s) with a valid checksum could not be used" in n for n in got["notes"]), got["notes"]
    assert got["rss_mb"] < 250, "the bomb was inflated"
    # the frames scored again are trusted by the next resume
    again = score_sequence(rdir, sdir, csv=out, resume=True, **OPTIONS)
    assert again.run["resumed"] == 13 and _values(again) == _values(fresh) and again.notes == []


def test_an_old_log_is_scored_again_with_a_note(tmp_path):
    rdir, sdir = _pngs(tmp_path, 3)
    out = tmp_path / "rows.csv"
    fresh = score_sequence(rdir, sdir, csv=out, **OPTIONS)
    side = pathlib.Path(str(out) + ".pairstats")
    side.write_bytes(b"IRFSEQ2\n" + side.read_bytes()[8:])
    rep = score_sequence(rdir, sdir, csv=out, resume=True, **OPTIONS)
    assert rep.run["resumed"] == 0 and _values(rep) == _values(fresh)
    assert any("another version" in n for n in rep.notes)


@pytest.mark.parametrize("options", [
    dict(bits=14),  # histograms over each frame's own range: not pooled
    dict(bits=14, bins="levels"),  # sparse levels
    dict(bits=14, peak="range", weights="psnr=0.5,ssim=0.5"),
    dict(bits=14, register="translation"),  # float statistics of the overlap
    dict(nonfinite="mask", peak=16383.0, float_frames=True),
], ids=["data-range", "levels", "peak-range", "registered", "float-nan-masked"])
@pytest.mark.parametrize("arrays", [False, True], ids=["files", "arrays"])
def test_a_finished_run_resumes_whole(tmp_path, options, arrays):
    options = dict(options)
    real, sim = _frames(6, shape=(48, 40))
    if options.pop("float_frames", False):
        real, sim = real.astype(np.float32), sim.astype(np.float32)
        sim[:, :3, :3] = np.nan
    if arrays:
        sources = real, sim
    else:
        sources = tmp_path / "real.tif", tmp_path / "sim.tif"
        tifffile.imwrite(sources[0], real)
        tifffile.imwrite(sources[1], sim)
    out = tmp_path / "rows.csv"
    first = score_sequence(*sources, csv=out, progress=False, **options)
    again = score_sequence(*sources, csv=out, resume=True, progress=False, **options)
    assert again.run["resumed"] == 6 and again.notes == first.notes
    assert again.frames == first.frames and again.fidelity == first.fidelity and again.metrics == first.metrics


# --------------------------------------------------------------------------- the lock
def test_the_lock_file_is_removed_when_a_run_ends(tmp_path):
    rdir, sdir = _pngs(tmp_path, 4)
    out = tmp_path / "rows.csv"
    lock = tmp_path / "rows.csv.lock"
    score_sequence(rdir, sdir, csv=out, **OPTIONS)
    assert not lock.exists()

    def interrupt(done, total):
        assert lock.read_text() == str(os.getpid())  # held while the run writes
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        score_sequence(rdir, sdir, csv=out, resume=False, **{**OPTIONS, "progress": interrupt})
    assert not lock.exists()
    with pytest.raises(FidelityError, match="cannot resume"):  # an error before scoring releases it too
        score_sequence(rdir, sdir, csv=out, resume=True, **{**OPTIONS, "bits": 15})
    assert not lock.exists()


def test_a_lock_is_never_held_twice(tmp_path):
    path = str(tmp_path / "rows.csv.lock")
    first = Lock(path)
    with pytest.raises(FidelityError, match=f"process {os.getpid()}"):
        Lock(path)
    # a second run that opened the lock file just before the first removed it locks that
    # file once the first lets go: it must see the path is not it, and lock the path's file
    late = open(path, "a+")
    first.release()
    assert not os.path.exists(path)
    import fcntl

    fcntl.flock(late.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)  # what the late run got
    assert not lock_module._same_file(late, path)  # which it sees
    second = Lock(path)  # a third run: the path's new file, not the orphan
    with pytest.raises(FidelityError):
        Lock(path)
    assert os.path.exists(path)
    late.close()
    second.release()
    second.release()
    assert not os.path.exists(path)


def test_a_run_that_locked_a_removed_file_locks_the_path_again(tmp_path, monkeypatch):
    path = str(tmp_path / "rows.csv.lock")
    looks = []
    same_file = lock_module._same_file

    def removed_once(fh, where):
        looks.append(where)
        return len(looks) > 1 and same_file(fh, where)

    monkeypatch.setattr(lock_module, "_same_file", removed_once)
    lock = Lock(path)
    assert len(looks) == 2 and open(path).read() == str(os.getpid())
    lock.release()
    assert not os.path.exists(path)


_HOLDER = textwrap.dedent("""
    import sys
    from irfidelity.sequence.lock import Lock
    lock = Lock(sys.argv[1])
    print("locked", flush=True)
    sys.stdin.readline()
    lock.release()
""")


def test_a_concurrent_run_is_refused_and_may_start_once_the_first_ends(tmp_path):
    rdir, sdir = _pngs(tmp_path, 3)
    out = tmp_path / "rows.csv"
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(out) + ".lock"], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(FidelityError, match=f"another irfidelity run \\(process {holder.pid}\\)"):
            score_sequence(rdir, sdir, csv=out, **OPTIONS)
    finally:
        holder.communicate("\n", timeout=60)
    assert not (tmp_path / "rows.csv.lock").exists()
    assert score_sequence(rdir, sdir, csv=out, **OPTIONS).failed == []
