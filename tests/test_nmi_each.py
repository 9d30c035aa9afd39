"""NMI's default binning (``hist_range="each"``): bins of one width for both frames, each
frame's over its own robust range, the simulated frame's edges locked to the real frame's by
the offset between their medians. The kernel equals a numpy reference, a pure offset reads NMI
1 where shared edges read the offset's phase, a few extreme pixels land in the edge bins, a
gain spreads the simulated frame over more bins as shared edges do, the statistics keep both
edge sets through pickling, and sequences, evaluate and the CLI take the option.

Data: the Lepton recording and the DJI Zenmuse XT-R frame in tests/data/thermal
(tests/data/README.md).
"""

from __future__ import annotations

import pathlib
import pickle

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.errors import ConfigError, FidelityError

DATA = pathlib.Path(__file__).resolve().parent / "data" / "thermal"


@pytest.fixture(scope="module")
def lepton() -> np.ndarray:
    import tifffile

    return tifffile.imread(DATA / "cptv_v2_all100frames_uint16.tif")


def reference_counts(real: np.ndarray, sim: np.ndarray, bins: int) -> tuple[np.ndarray, float, float, float]:
    """The joint counts by the documented rule, in numpy, for integer frames without outliers
    (the robust range is the whole range) of at most 16,384 pixels (every pixel sampled): one
    width for both frames, ``ceil((span + 1) / bins)`` levels with ``span`` the wider frame's
    max − min; the real frame's bins from its minimum; the simulated frame's from that minimum
    moved by the rounded difference of the two frames' medians (the sample's rank
    ``round(0.5·(n − 1))``), then by whole bins down to its own minimum. Returns the counts,
    the width and both first edges."""
    def median(v: np.ndarray) -> float:
        ordered = np.sort(v.astype(np.float64).ravel())
        return ordered[round(0.5 * (ordered.size - 1))]

    rlo, slo = float(real.min()), float(sim.min())
    span = max(float(real.max()) - rlo, float(sim.max()) - slo)
    width = max(np.ceil((span + 1) / bins), 1.0)
    anchor = rlo + np.round(median(sim) - median(real))
    sim_lo = anchor + np.floor((slo - anchor) / width) * width

    def bin_of(v: np.ndarray, lo: float) -> np.ndarray:
        return np.clip(np.floor((v.astype(np.float64).ravel() - lo) / width).astype(np.int64), 0, bins - 1)

    counts = np.zeros((bins, bins), dtype=np.int64)
    np.add.at(counts, (bin_of(real, rlo), bin_of(sim, sim_lo)), 1)
    return counts, width, rlo, sim_lo


@pytest.mark.parametrize("bins", [7, 64, 256])
def test_integer_frames_equal_the_reference_binning(lepton, bins):
    real, sim = lepton[10][:100, :150], lepton[40][:100, :150] // 3 + 9000  # another gain and offset
    counts, real_edges, sim_edges = irf.pair_stats(real, sim, bins=bins, hist_range="each").joint_histogram()
    want, width, rlo, sim_lo = reference_counts(real, sim, bins)
    assert np.array_equal(counts, want)
    assert real_edges[0] == rlo and sim_edges[0] == sim_lo
    assert np.array_equal(np.diff(real_edges), np.full(bins, width))
    assert np.array_equal(np.diff(sim_edges), np.full(bins, width))


def test_an_offset_copy_reads_one_and_a_few_extreme_pixels_do_not_stretch_the_bins():
    """Float frames: an offset copy is binned alike (NMI 1); 9 pixels at the float32 maximum in
    a noisy copy leave NMI near the clean pair's, where shared edges put every other pixel in
    one bin (NMI 0)."""
    rng = np.random.default_rng(11)
    real = rng.normal(300.0, 4.0, (96, 128)).astype(np.float32)
    assert irf.stats.nmi(real, real - 100, hist_range="each").value == 1.0
    sim = real + rng.normal(0.0, 2.0, real.shape).astype(np.float32)
    clean = irf.stats.nmi(real, sim, hist_range="each").value
    hot = sim.copy()
    hot.flat[rng.choice(hot.size, 9, replace=False)] = np.finfo(np.float32).max
    # they land in the top bin, and widen the bins by at most their share of a bulk span
    assert irf.stats.nmi(real, hot, hist_range="each").value == pytest.approx(clean, abs=0.05)
    assert irf.stats.nmi(real, hot, hist_range="data").value < 0.01


def test_a_pure_offset_reads_one_where_shared_edges_read_its_phase(lepton):
    real = lepton[30]
    each = [irf.stats.nmi(real, real + d, hist_range="each").value for d in range(12)]
    data = [irf.stats.nmi(real, real + d, hist_range="data").value for d in range(12)]
    assert each == [1.0] * 12
    assert min(data) < 0.9  # the phase of the shared 2-level bins (the reason for "each")
    # a gain (about the median, the ranges overlapping) spreads the simulated frame over more
    # bins of the same width, as shared edges over both frames do
    median = int(np.median(real))
    tripled = (3 * (real.astype(np.int64) - median) + median).astype(np.uint16)
    spread = irf.pair_stats(real, tripled, hist_range="each")
    counts, real_edges, sim_edges = spread.joint_histogram()
    assert np.diff(real_edges)[0] == np.diff(sim_edges)[0] == np.ceil((np.ptp(tripled) + 1) / 256)
    assert spread.nmi().value == pytest.approx(irf.stats.nmi(real, tripled, hist_range="data").value, abs=0.02)


def test_masks_and_nonfinite_values_set_each_frames_range():
    real = np.arange(64, dtype=np.float64).reshape(8, 8)
    sim = real * 2 + 1000
    sim[0, 0], real[7, 7] = np.nan, 1e9  # a NaN pair and an outlier the mask leaves out
    mask = np.ones_like(real, dtype=bool)
    mask[7, 7] = False
    st = irf.pair_stats(real, sim, peak=100, bins=8, hist_range="each", mask=mask, nonfinite="mask")
    counts, real_edges, sim_edges = st.joint_histogram()
    assert counts.sum() == st.n == 62
    # the wider span (the simulated frame's, 1002..1124) over 8 bins; the real bins from 1
    width = (1124 - 1002) / 8
    assert real_edges[0] == 1.0 and np.allclose(np.diff(real_edges), width)
    assert np.allclose(np.diff(sim_edges), width) and sim_edges[0] <= 1002.0 < sim_edges[1]
    assert (counts > 0).sum(1).max() <= 3  # a real bin's 15.25 levels span 30.5 simulated units


def test_statistics_keep_both_edge_sets_through_pickling_and_merge_only_alike(lepton):
    real, sim = lepton[5], lepton[6] + 17
    st = irf.pair_stats(real, sim, bits=16, hist_range="each")
    back = pickle.loads(pickle.dumps(st))
    for a, b in zip(st.joint_histogram(), back.joint_histogram()):
        assert np.array_equal(a, b)
    assert back.nmi().value == st.nmi().value
    assert st.merge(irf.pair_stats(real, sim, bits=16, hist_range="each")).n == 2 * st.n
    with pytest.raises(FidelityError, match="different edges"):
        st.merge(irf.pair_stats(lepton[7], lepton[8], bits=16, hist_range="each"))


def test_the_scorer_takes_each_and_the_others(lepton):
    real, sim = lepton[30], lepton[31] + 5
    options = dict(bits=14, weights="nmi=1", transfer_options={"scene": False})
    assert irf.evaluate(real, sim, **options).config.hist_range == "each"  # the default
    for hist_range in ("each", "data", "full", (2000, 4000)):
        rep = irf.evaluate(real, sim, hist_range=hist_range, **options)
        want = irf.stats.nmi(real, sim, bits=14, hist_range=hist_range).value
        assert rep.components["nmi"] == pytest.approx(want, abs=1e-12), hist_range
    with pytest.raises(ConfigError, match="'each', 'data', 'full' or \\(lo, hi\\)"):
        irf.ScoringConfig(hist_range="own")


def test_a_sequence_scores_each_frame_with_its_own_edges(tmp_path, lepton):
    import tifffile

    real_path, sim_path = tmp_path / "real.tif", tmp_path / "sim.tif"
    tifffile.imwrite(real_path, lepton[:6])
    tifffile.imwrite(sim_path, lepton[:6] + 3)
    rep = irf.score_sequence(real_path, sim_path, bits=14, weights="nmi=1", progress=False, hist_range="each",
                             transfer_options={"scene": False})
    assert [f["metrics"]["nmi"] for f in rep.frames] == [1.0] * 6
    assert rep.metrics["nmi"] == 1.0 and rep.components["nmi"] == 1.0


def test_the_cli_takes_each(tmp_path, lepton, capsys):
    import json

    from irfidelity.cli import main

    np.save(tmp_path / "real.npy", lepton[30])
    np.save(tmp_path / "sim.npy", lepton[30] + 3)
    code = main(["score", str(tmp_path / "real.npy"), str(tmp_path / "sim.npy"), "--bits", "14",
                 "--hist-range", "each", "--json", "-"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["metrics"]["nmi"] == 1.0
    assert main(["score", str(tmp_path / "real.npy"), str(tmp_path / "sim.npy"), "--hist-range", "own"]) == 2
    assert "each" in capsys.readouterr().err
