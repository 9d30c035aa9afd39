"""NMI with each frame binned over its own range (``hist_range="each"``, the scorer's default):
the kernel equals a numpy reference and scikit-image, a pure offset reads NMI 1 where shared
edges read the offset's phase, the statistics keep both edge sets through pickling, and
sequences, evaluate and the CLI take the option.

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


def reference_counts(real: np.ndarray, sim: np.ndarray, bins: int) -> np.ndarray:
    """The joint counts by the documented rule, in numpy: integer frames, bins of
    ``ceil(span / bins)`` whole levels from each frame's own minimum."""
    def bin_of(v: np.ndarray) -> np.ndarray:
        v = v.astype(np.int64).ravel()
        width = -(-(int(v.max()) - int(v.min()) + 1) // bins)
        return (v - v.min()) // width

    counts = np.zeros((bins, bins), dtype=np.int64)
    np.add.at(counts, (bin_of(real), bin_of(sim)), 1)
    return counts


@pytest.mark.parametrize("bins", [7, 64, 256])
def test_integer_frames_equal_the_reference_binning(lepton, bins):
    real, sim = lepton[10], lepton[40] // 3 + 9000  # another range and offset than the real frame's
    counts, real_edges, sim_edges = irf.pair_stats(real, sim, bins=bins, hist_range="each").joint_histogram()
    assert np.array_equal(counts, reference_counts(real, sim, bins))
    assert real_edges[0] == real.min() and sim_edges[0] == sim.min()
    assert not np.array_equal(real_edges, sim_edges)


def test_float_frames_equal_scikit_image():
    """Each frame over its own range is scikit-image's binning: the joint counts equal
    ``numpy.histogram2d`` over each frame's range but for values on a bin's edge (rounded
    the other way by one of the two), and Studholme's NMI from ours (``2 / (2 − NMI)``) equals
    ``normalized_mutual_information``."""
    from skimage.metrics import normalized_mutual_information

    rng = np.random.default_rng(11)
    real = rng.normal(300.0, 4.0, (96, 128))
    sim = 0.7 * real + rng.normal(0.0, 2.0, real.shape) - 40.0
    for dtype in (np.float64, np.float32):
        r, s = real.astype(dtype), sim.astype(dtype)
        counts, real_edges, sim_edges = irf.pair_stats(r, s, peak=1, bins=64, hist_range="each").joint_histogram()
        want, _, _ = np.histogram2d(r.ravel(), s.ravel(), bins=64, range=[(r.min(), r.max()), (s.min(), s.max())])
        assert np.abs(counts - want).sum() <= 4, dtype  # at most two pixels on an edge
        assert real_edges[[0, -1]] == pytest.approx([r.min(), r.max()], rel=1e-12)
        ours = irf.nmi(r, s, bins=64, hist_range="each").value
        assert 2 / (2 - ours) == pytest.approx(normalized_mutual_information(r, s, bins=64), abs=1e-6)


def test_a_pure_offset_reads_one_where_shared_edges_read_its_phase(lepton):
    real = lepton[30]
    each = [irf.nmi(real, real + d, hist_range="each").value for d in range(0, 12)]
    data = [irf.nmi(real, real + d, hist_range="data").value for d in range(0, 12)]
    assert each == [1.0] * 12
    assert min(data) < 0.9  # the phase of the shared 2-level bins (the reason for "each")


def test_masks_and_nonfinite_values_set_each_frames_range():
    real = np.arange(64, dtype=np.float64).reshape(8, 8)
    sim = real * 2 + 1000
    sim[0, 0], real[7, 7] = np.nan, 1e9  # a NaN pair and an outlier the mask leaves out
    mask = np.ones_like(real, dtype=bool)
    mask[7, 7] = False
    st = irf.pair_stats(real, sim, peak=100, bins=8, hist_range="each", mask=mask, nonfinite="mask")
    counts, real_edges, sim_edges = st.joint_histogram()
    assert counts.sum() == st.n == 62
    assert (real_edges[0], real_edges[-1]) == (1.0, 62.0)
    assert (sim_edges[0], sim_edges[-1]) == (1002.0, 1124.0)
    assert np.array_equal(np.diag(counts), counts.sum(1))  # a one-to-one relation, binned alike


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


def test_the_scorer_defaults_to_each_and_takes_the_others(lepton):
    real, sim = lepton[30], lepton[31] + 5
    assert irf.ScoringConfig().hist_range == "each"
    options = dict(bits=14, weights="nmi=1", transfer_options={"scene": False})
    for hist_range in ("each", "data", "full", (2000, 4000)):
        rep = irf.evaluate(real, sim, hist_range=hist_range, **options)
        want = irf.nmi(real, sim, bits=14, hist_range=hist_range).value
        assert rep.components["nmi"] == pytest.approx(want, abs=1e-12), hist_range
    with pytest.raises(ConfigError, match="'data', 'each', 'full' or \\(lo, hi\\)"):
        irf.ScoringConfig(hist_range="own")


def test_a_sequence_scores_each_frame_with_its_own_edges(tmp_path, lepton):
    import tifffile

    real_path, sim_path = tmp_path / "real.tif", tmp_path / "sim.tif"
    tifffile.imwrite(real_path, lepton[:6])
    tifffile.imwrite(sim_path, lepton[:6] + 3)
    rep = irf.score_sequence(real_path, sim_path, bits=14, weights="nmi=1", progress=False,
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
