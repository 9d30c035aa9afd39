"""PairStats.joint_histogram: counts and edges for dense, sparse ("levels") and float
histograms, checked against numpy.histogram2d with the returned edges and against NMI."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

import irfidelity as irf
from irfidelity import FidelityError
from irfidelity.metrics import nmi_from_entropies

DATA = Path(__file__).parent / "data"


def lepton_pair():
    return (irf.load_frame(DATA / "thermal" / f"cptv_v2_frame00{i}.png") for i in range(2))


def entropy(counts):
    p = counts[counts > 0] / counts.sum()
    return float(-(p * np.log2(p)).sum())


def check_against_numpy(st, real, sim):
    counts, re, se = st.joint_histogram()
    assert counts.dtype == np.int64 and counts.sum() == st.n
    assert counts.shape == (len(re) - 1, len(se) - 1)
    want, _, _ = np.histogram2d(real.ravel().astype(np.float64), sim.ravel().astype(np.float64), bins=[re, se])
    assert np.array_equal(counts, want.astype(np.int64))
    # the table is the histogram NMI was computed from
    nmi = nmi_from_entropies(entropy(counts.sum(1)), entropy(counts.sum(0)), entropy(counts), bins=st.bins)
    assert abs(nmi.value - st.nmi().value) < 1e-12
    return counts, re, se


def test_dense_integer_bins_are_whole_grey_levels():
    real, sim = lepton_pair()  # 14-bit counts spanning ~330 levels
    st = irf.pair_stats(real, sim, bits=14, bins=64)
    counts, re, se = check_against_numpy(st, real, sim)
    lo = min(real.min(), sim.min())
    width = -(-(int(max(real.max(), sim.max())) - int(lo) + 1) // 64)  # ceil(span / bins)
    assert counts.shape == (64, 64) and np.array_equal(re, se)
    assert np.array_equal(re, lo + width * np.arange(65))


def test_levels_sparse_over_the_occupied_span():
    real = irf.load_frame(DATA / "thermal" / "flirpy_frame_000000_raw16.png")  # 640×512, ~117 levels
    sim = np.clip(real.astype(np.int64) * 5 - 4 * int(real.min()) + np.arange(real.size).reshape(real.shape) % 7,
                  0, 65535).astype(np.uint16)  # spans > 512 levels: the sparse representation
    st = irf.pair_stats(real, sim, bins="levels")
    counts, re, se = check_against_numpy(st, real, sim)
    assert re[0] == real.min() and re[-1] == real.max() + 1
    assert se[0] == sim.min() and se[-1] == sim.max() + 1 and len(se) - 1 > 512


def test_levels_of_signed_frames_start_at_their_minimum():
    rng = np.random.default_rng(0)
    real = rng.integers(-300, 200, size=(40, 50)).astype(np.int16)
    sim = (real // 2 + rng.integers(-3, 4, size=real.shape)).astype(np.int16)
    st = irf.pair_stats(real, sim, bins="levels")
    counts, re, se = check_against_numpy(st, real, sim)
    assert re[0] == real.min() and se[0] == sim.min()
    # survives pickling and merging
    again = pickle.loads(pickle.dumps(st))
    assert all(np.array_equal(a, b) for a, b in zip(again.joint_histogram(), (counts, re, se)))


def test_dense_levels_for_8_bit_frames():
    rng = np.random.default_rng(1)
    real = rng.integers(10, 200, size=(30, 30)).astype(np.uint8)
    sim = np.clip(real.astype(int) + rng.integers(-5, 6, size=real.shape), 0, 255).astype(np.uint8)
    st = irf.pair_stats(real, sim, bins="levels")
    check_against_numpy(st, real, sim)
    # a pair spanning at most `bins` levels is binned exactly: the same table as "levels"
    span = int(max(real.max(), sim.max())) - int(min(real.min(), sim.min())) + 1
    exact = irf.pair_stats(real, sim, bins=span, hist_range="data").joint_histogram()[0]
    lv, re, se = st.joint_histogram()
    lo = int(min(real.min(), sim.min()))
    r0, s0 = int(re[0]) - lo, int(se[0]) - lo
    assert np.array_equal(exact[r0 : r0 + lv.shape[0], s0 : s0 + lv.shape[1]], lv)


def test_float_bins_and_explicit_range():
    rng = np.random.default_rng(2)
    real = rng.normal(20.0, 3.0, size=(60, 70)).astype(np.float32)
    sim = (real * 0.8 + rng.normal(0, 1, real.shape)).astype(np.float32)
    st = irf.pair_stats(real, sim, peak=50.0, bins=100, hist_range="data")
    counts, re, se = check_against_numpy(st, real, sim)
    assert counts.shape == (100, 100)
    assert re[0] == min(real.min(), sim.min()) and abs(re[-1] - max(real.max(), sim.max())) < 1e-9
    # explicit range: out-of-range values go to the edge bins, counts still sum to n
    clipped = irf.pair_stats(real, sim, peak=50.0, bins=10, hist_range=(15.0, 25.0))
    counts, re, _ = clipped.joint_histogram()
    assert counts.sum() == clipped.n and re[0] == 15.0 and re[-1] == 25.0


def test_mask_merge_and_errors():
    real, sim = lepton_pair()
    mask = np.zeros(real.shape, bool)
    mask[10:60, 20:90] = True
    st = irf.pair_stats(real, sim, bits=14, mask=mask, hist_range="full", bins=128)
    assert st.joint_histogram()[0].sum() == mask.sum() == st.n
    rest = irf.pair_stats(real, sim, bits=14, mask=~mask, hist_range="full", bins=128)
    merged = st.merge(rest)
    assert np.array_equal(merged.joint_histogram()[0], st.joint_histogram()[0] + rest.joint_histogram()[0])
    assert merged.joint_histogram()[0].sum() == real.size
    with pytest.raises(FidelityError, match="histogram"):
        irf.pair_stats(real, sim, need=("psnr",)).joint_histogram()
    with pytest.raises(FidelityError, match="max_cells"):
        irf.pair_stats(real, sim, bins="levels").joint_histogram(max_cells=100)
    with pytest.raises(FidelityError, match="max_cells"):
        st.joint_histogram(max_cells=0)


def test_docstring_example():
    import doctest

    runner = doctest.DocTestRunner()
    for test in doctest.DocTestFinder().find(irf.PairStats.joint_histogram, "joint_histogram", globs={}):
        runner.run(test)
    assert runner.tries >= 3 and runner.failures == 0
