"""Multi-page TIFFs: every page accounted for, in one pass over the chain of pages.

A truncated file or an IFD chain that loops back gives the pages before the break and one
failed frame naming the break, the same through the API and the CLI; a file's pages cost
one walk over its chain whatever their number (counted through ``_core.tiff_ifds_read``).
"""

from __future__ import annotations

import csv
import json
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
import tifffile

import irfidelity as irf
from irfidelity import _core
from irfidelity.errors import FrameError
from irfidelity.frames import FrameSequence, page_chain, page_count

PAGES = 200


def write_stack(path, frames) -> None:
    """One page per frame, each with its own IFD (as a camera's recorder writes them)."""
    with tifffile.TiffWriter(path) as w:
        for f in frames:
            w.write(f, contiguous=False, photometric="minisblack")


def frames(count: int, seed: int = 0, shape=(8, 8)) -> np.ndarray:
    return np.random.default_rng(seed).integers(1000, 3000, (count, *shape), dtype=np.uint16)


def ifds(path) -> list[tuple[int, int]]:
    """(IFD offset, offset of its next-IFD field) of every page of a little-endian classic TIFF."""
    data = path.read_bytes()
    assert data[:4] == b"II*\x00"
    out, at = [], struct.unpack_from("<I", data, 4)[0]
    while at:
        count = struct.unpack_from("<H", data, at)[0]
        out.append((at, at + 2 + 12 * count))
        at = struct.unpack_from("<I", data, out[-1][1])[0]
    return out


@pytest.fixture
def truncated(tmp_path):
    """A 200-page TIFF cut at 60 % of its bytes, and the intact file."""
    whole = tmp_path / "whole.tif"
    write_stack(whole, frames(PAGES))
    cut = tmp_path / "cut.tif"
    data = whole.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.6)])
    found = sum(1 for at, field in ifds(whole) if field + 4 <= len(data) * 0.6)
    return cut, whole, found


def run_cli(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "irfidelity.cli", "score", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


def test_a_truncated_stack_gives_its_pages_and_one_failed_frame_at_the_break(truncated):
    cut, whole, found = truncated
    assert 100 < found < PAGES
    pages, broken = page_chain(cut)
    assert pages == found
    assert broken.startswith(f"{cut}: truncated at page {found}: its IFD at byte ")
    assert "lies beyond the end of the file" in broken or "runs past the end of the file" in broken
    with pytest.raises(FrameError, match=f"truncated at page {found}"):
        page_count(cut)  # the number of pages is not known: never a silent 1
    seq = FrameSequence(cut)
    assert len(seq) == found + 1 and seq.names[-1] == f"cut.tif[{found}]"
    assert np.array_equal(irf.load_frame(cut), irf.load_frame(whole))  # page 0 still loads
    assert np.array_equal(seq[found - 2], irf.load_frame(whole, page=found - 2))
    with pytest.raises(FrameError, match=f"truncated at page {found}"):
        seq[found]

    rep = irf.score_sequence(cut, cut, bits=12, progress=False)
    assert len(rep.frames) == found + 1
    assert rep.frames[found]["error"] == broken
    assert found in rep.failed and not rep.unpaired
    # every page before the break is scored (but the last one, whose pixels may be cut too)
    assert set(rep.failed) <= {found - 1, found}
    assert all(f["fidelity"] is not None for f in rep.frames[: found - 1])


def test_the_api_and_the_cli_give_the_same_rows_for_a_truncated_stack(truncated, tmp_path):
    cut, whole, found = truncated
    sim = tmp_path / "sim.tif"
    write_stack(sim, frames(PAGES, seed=1))
    rep = irf.score_sequence(cut, sim, bits=12, progress=False)
    # by page: the readable pages, the break, then the simulated pages with no real partner
    assert len(rep.frames) == PAGES
    assert rep.frames[found]["error"].startswith(f"{cut}: truncated at page {found}")
    assert all(rep.frames[i]["error"] == f"sim.tif[{i}]: no real frame pairs with it (paired by page)"
               for i in range(found + 1, PAGES))
    out = tmp_path / "r.csv"
    p = run_cli(cut, sim, "--bits", "12", "--csv", out, "--no-progress")
    assert p.returncode == 3, p.stderr  # a sequence finished but some frames failed
    rows = list(csv.DictReader(open(out, encoding="utf-8")))
    assert len(rows) == PAGES
    for row, frame in zip(rows, rep.frames):
        names = tuple(row[k] or None for k in ("real", "sim", "error"))
        assert names == (frame["real"], frame["sim"], frame["error"])
        assert (float(row["fidelity"]) if row["fidelity"] else None) == frame["fidelity"]
        assert (float(row["psnr_db"]) if row["psnr_db"] else None) == frame["metrics"].get("psnr_db")


def test_a_looping_ifd_chain_is_read_up_to_the_loop(tmp_path):
    path = tmp_path / "loop.tif"
    count = 300
    write_stack(path, frames(count, seed=2))
    chain = ifds(path)
    data = bytearray(path.read_bytes())
    struct.pack_into("<I", data, chain[-1][1], chain[100][0])  # the last page points back to page 100
    path.write_bytes(bytes(data))
    t0 = time.perf_counter()
    pages, broken = page_chain(path)
    assert pages == count and time.perf_counter() - t0 < 10
    assert broken == (f"{path}: the IFD chain loops back at page {count}: page {count - 1}'s next-IFD offset points "
                      f"back to page 100's IFD (byte {chain[100][0]}); the {count} page(s) before it are found")
    want = frames(count, seed=2)
    assert np.array_equal(irf.load_frame(path, page=count - 1), want[-1])  # the page with the bad link too
    rep = irf.score_sequence(path, path, bits=12, progress=False)
    assert len(rep.frames) == count + 1 and rep.failed == [count]
    assert rep.frames[count]["error"] == broken
    out = tmp_path / "r.json"
    p = run_cli(path, path, "--bits", "12", "--json", out, "--no-progress", timeout=120)
    assert p.returncode == 3, p.stderr
    d = json.loads(out.read_text())
    assert len(d["frames"]) == count + 1 and d["failed"] == [count] and d["frames"][count]["error"] == broken


def test_noise3d_of_a_truncated_stack_names_the_file_and_the_break(truncated, tmp_path):
    cut, _, found = truncated  # cut inside page found - 1's pixels: that page fails first
    with pytest.raises(FrameError, match=rf"^{cut}: page {found - 1}: truncated or corrupt TIFF file"):
        irf.noise.noise3d(cut)
    whole = tmp_path / "whole50.tif"
    write_stack(whole, frames(50))
    at = ifds(whole)[30][0]
    short = tmp_path / "short.tif"
    short.write_bytes(whole.read_bytes()[: at + 6])  # every page before page 30 is whole
    with pytest.raises(FrameError, match=rf"^{short}: truncated at page 30: its IFD at byte {at} \(.* the 30 page"):
        irf.noise.noise3d(short)


def test_a_stack_costs_one_walk_over_its_chain(tmp_path):
    """Page access is linear: scoring an n-page stack against itself reads each IFD once
    (counted by the walk), however many times its pages are decoded."""
    for count in (300, 3000):
        path = tmp_path / f"s{count}.tif"
        write_stack(path, frames(count, seed=3, shape=(4, 4)))
        before = _core.tiff_ifds_read()
        rep = irf.score_sequence(path, path, bits=12, progress=False, workers=2)
        assert len(rep.frames) == count and not rep.failed
        assert _core.tiff_ifds_read() - before == count


class _CountingList(list):
    """Counts the passes over a sequence's entries."""

    passes = 0

    def __iter__(self):
        _CountingList.passes += 1
        return super().__iter__()


def test_a_run_passes_over_the_frame_list_a_fixed_number_of_times(tmp_path):
    """Looking up a frame's name, path or page during a run costs O(1), not a copy of the list."""
    counts = {}
    for count in (50, 500):
        path = tmp_path / f"s{count}.tif"
        write_stack(path, frames(count, seed=4, shape=(4, 4)))
        real, sim = FrameSequence(path), FrameSequence(path)
        real._entries, sim._entries = _CountingList(real._entries), _CountingList(sim._entries)
        _CountingList.passes = 0
        irf.score_sequence(real, sim, bits=12, progress=False, csv=tmp_path / f"s{count}.csv")
        counts[count] = _CountingList.passes
    assert counts[500] == counts[50] < 50, counts
