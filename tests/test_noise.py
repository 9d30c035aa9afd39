"""3-D noise (issue 18): the streamed decomposition against exact Fraction references on
synthetic cubes with known parts, merge = one pass, files = arrays, the corrected estimator
and its intervals on known-variance random cubes, pyradi's formulas, spectra, the noise
similarity, bad input, and the real PTW recordings (LWIR near-uniform, MWIR with strong row
structure, a 150 °C blackbody scene).

pyradi (the peer named in the issue) is not on the package index this project installs
from, so its ``ry3dnoise`` formulas are re-implemented with numpy below (from its documented
operators: DT/DV/DH averages, SDT/SDV/SDH subtractions, ``np.std(ddof=1)``).

Data: tests/data/thermal/ptw_* (see tests/data/README.md).
"""

from __future__ import annotations

import json
import math
import pathlib
import pickle
import warnings
from fractions import Fraction

import numpy as np
import pytest
import scipy.stats as scipy_stats
import tifffile

import irfidelity as irf
from irfidelity.errors import FidelityError, FrameError, RangeError, ShapeError
from irfidelity.noise import NoiseSums, NoiseWarning, noise_sums
from irfidelity.noise.anova import PARTS, anova, variance_interval
from irfidelity.noise.quantiles import chi2_ppf, f_ppf
from irfidelity.noise.similarity import NOISE_METRICS

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
LWIR = DATA / "ptw_lwir_all100frames_uint16.tif"
MWIR = DATA / "ptw_mwir_all100frames_uint16.tif"
BB150 = [DATA / "ptw_bb150C_frame000.png", DATA / "ptw_bb150C_frame001.png"]


# --------------------------------------------------------------------------- references
def exact_parts(cube: np.ndarray) -> tuple[dict[str, Fraction], Fraction, Fraction]:
    """``(SS_x as Fractions, SS_total, mean)`` straight from the definitions of the parts (every
    value taken exactly, integer or float)."""
    t, v, h = cube.shape
    x = [[[Fraction(cube[a, b, c].item()) for c in range(h)] for b in range(v)] for a in range(t)]
    n = t * v * h
    m = Fraction(sum(x[a][b][c] for a in range(t) for b in range(v) for c in range(h)), n)
    u = [[[x[a][b][c] - m for c in range(h)] for b in range(v)] for a in range(t)]
    mt = [sum(u[a][b][c] for b in range(v) for c in range(h)) / (v * h) for a in range(t)]
    mv = [sum(u[a][b][c] for a in range(t) for c in range(h)) / (t * h) for b in range(v)]
    mh = [sum(u[a][b][c] for a in range(t) for b in range(v)) / (t * v) for c in range(h)]
    mtv = [[sum(u[a][b][c] for c in range(h)) / h - mt[a] - mv[b] for b in range(v)] for a in range(t)]
    mth = [[sum(u[a][b][c] for b in range(v)) / v - mt[a] - mh[c] for c in range(h)] for a in range(t)]
    mvh = [[sum(u[a][b][c] for a in range(t)) / t - mv[b] - mh[c] for c in range(h)] for b in range(v)]
    ss = {k: Fraction(0) for k in PARTS}
    total = Fraction(0)
    for a in range(t):
        for b in range(v):
            for c in range(h):
                parts = {"t": mt[a], "v": mv[b], "h": mh[c], "tv": mtv[a][b], "th": mth[a][c], "vh": mvh[b][c]}
                parts["tvh"] = u[a][b][c] - sum(parts.values())
                for k, p in parts.items():
                    ss[k] += p * p
                total += u[a][b][c] ** 2
    return ss, total, m


def known_cube(shape: tuple[int, int, int], amplitudes: dict[str, int], seed: int, dtype=np.uint16,
               offset: int = 1000) -> np.ndarray:
    """Integer cube: ``offset`` plus integer random effects of the given amplitudes."""
    rng = np.random.default_rng(seed)
    t, v, h = shape
    dims = {"t": (t, 1, 1), "v": (1, v, 1), "h": (1, 1, h), "tv": (t, v, 1), "th": (t, 1, h),
            "vh": (1, v, h), "tvh": (t, v, h)}
    cube = np.full(shape, offset, dtype=np.int64)
    for part, amp in amplitudes.items():
        cube = cube + rng.integers(-amp, amp + 1, dims[part])
    return cube.astype(dtype)


def random_effects(rng: np.random.Generator, sigma: dict[str, float], shape: tuple[int, int, int]) -> np.ndarray:
    t, v, h = shape
    dims = {"t": (t, 1, 1), "v": (1, v, 1), "h": (1, 1, h), "tv": (t, v, 1), "th": (t, 1, h),
            "vh": (1, v, h), "tvh": (t, v, h)}
    cube = np.zeros(shape)
    for part, s in sigma.items():
        cube = cube + rng.normal(0.0, s, dims[part])
    return cube


def numpy_parts(cube: np.ndarray) -> dict[str, np.ndarray]:
    """The classical parts N_x of the documented decomposition, in float64 numpy."""
    u = cube.astype(np.float64) - cube.mean(dtype=np.float64)
    nt = u.mean(axis=(1, 2))
    nv = u.mean(axis=(0, 2))
    nh = u.mean(axis=(0, 1))
    ntv = u.mean(axis=2) - nt[:, None] - nv[None, :]
    nth = u.mean(axis=1) - nt[:, None] - nh[None, :]
    nvh = u.mean(axis=0) - nv[:, None] - nh[None, :]
    ntvh = (u - nt[:, None, None] - nv[None, :, None] - nh[None, None, :] - ntv[:, :, None]
            - nth[:, None, :] - nvh[None, :, :])
    return {"t": nt, "v": nv, "h": nh, "tv": ntv, "th": nth, "vh": nvh, "tvh": ntvh}


def pyradi_formulas(cube: np.ndarray) -> dict[str, float]:
    """pyradi.ry3dnoise's getNT ... getNTVH: ``np.std(ddof=1)`` of operator compositions."""
    x = cube.astype(np.float64)
    dt = lambda a: a.mean(axis=0, keepdims=True)  # noqa: E731  (operators as in ry3dnoise)
    dv = lambda a: a.mean(axis=1, keepdims=True)  # noqa: E731
    dh = lambda a: a.mean(axis=2, keepdims=True)  # noqa: E731
    sdt, sdv, sdh = (lambda a: a - dt(a)), (lambda a: a - dv(a)), (lambda a: a - dh(a))
    ims = {"t": dv(dh(sdt(x))), "v": dt(dh(sdv(x))), "h": dt(dv(sdh(x))), "tv": dh(sdt(sdv(x))),
           "th": dv(sdt(sdh(x))), "vh": dt(sdv(sdh(x))), "tvh": sdt(sdv(sdh(x)))}
    return {k: float(np.std(im, ddof=1)) for k, im in ims.items()}


def quiet_noise3d(*args, **kwargs) -> irf.noise.Noise3D:
    with warnings.catch_warnings():
        warnings.simplefilter("error", NoiseWarning)
        return irf.noise.noise3d(*args, **kwargs)


# --------------------------------------------------------------------------- exact decomposition
def pure_part(part: str, shape: tuple[int, int, int], seed: int) -> np.ndarray:
    """An integer cube holding one part only: random integers centred over every axis the
    part varies along (scaled by the axis lengths so that the centring stays integer)."""
    rng = np.random.default_rng(seed)
    axes = {"t": 0, "v": 1, "h": 2}
    dims = [n if name in part else 1 for name, n in zip("tvh", shape)]
    effect = rng.integers(-3, 4, dims).astype(np.int64)
    for name in part:
        ax = axes[name]
        effect = shape[ax] * effect - effect.sum(axis=ax, keepdims=True)
    return 30000 + np.broadcast_to(effect, shape)


@pytest.mark.filterwarnings("ignore::irfidelity.noise.NoiseWarning")
@pytest.mark.parametrize("part", PARTS)
def test_each_part_alone_is_found_exactly_and_the_others_are_exactly_zero(part):
    cube = pure_part(part, (5, 4, 6), seed=PARTS.index(part)).astype(np.uint16)
    sums = noise_sums(cube)
    ss, total, _ = exact_parts(cube)
    n = cube.size
    exact = sums.exact_ss()
    for k in PARTS:
        assert exact[k] == ss[k] * n * n, k
        assert (exact[k] == 0) == (k != part), k
    assert exact["total"] == total * n * n
    n3d = irf.noise.noise3d(cube, corrected=False, spectra=False)
    assert n3d.sigma[part] == pytest.approx(math.sqrt(ss[part] / n), rel=1e-15)
    assert n3d.total == pytest.approx(math.sqrt(total / n), rel=1e-15)


@pytest.mark.parametrize("dtype,offset,amp", [(np.uint16, 1000, 40), (np.int16, 0, 30000 // 8),
                                              (np.uint8, 128, 18), (np.uint32, 2**31, 2**28)])
def test_all_parts_together_equal_the_fraction_reference_and_add_up_exactly(dtype, offset, amp):
    cube = known_cube((6, 5, 7), {k: amp for k in PARTS}, seed=3, dtype=dtype, offset=offset)
    ss, total, mean = exact_parts(cube)
    n = cube.size
    sums = noise_sums(cube)
    exact = sums.exact_ss()
    assert {k: exact[k] for k in PARTS} == {k: ss[k] * n * n for k in PARTS}
    assert sum(exact[k] for k in PARTS) == exact["total"] == total * n * n
    dec = sums.decomposition()
    for k in PARTS:
        assert dec["ss"][k] == pytest.approx(float(ss[k]), rel=1e-15, abs=0)
    assert dec["mean"] == float(mean)


def test_float_frames_match_the_exact_reference_closely():
    cube = known_cube((7, 6, 5), {k: 50 for k in PARTS}, seed=8)
    ss, total, mean = exact_parts(cube)
    for dtype in (np.float16, np.float32, np.float64):
        dec = noise_sums(cube.astype(dtype)).decomposition()
        for k in PARTS:
            assert dec["ss"][k] == pytest.approx(float(ss[k]), rel=1e-12), (dtype, k)
        assert dec["ss_total"] == pytest.approx(float(total), rel=1e-13)
        assert dec["mean"] == pytest.approx(float(mean), rel=1e-15)


def test_float_values_far_from_zero_keep_their_digits():
    rng = np.random.default_rng(5)
    cube = 1e6 + random_effects(rng, {"vh": 1e-3, "tvh": 1e-4}, (20, 16, 16))
    ours = noise_sums(cube).decomposition()["ss"]
    # reference: the same cube without its offset (the parts do not depend on it)
    ref = {k: float((p ** 2).sum()) * (cube.size // p.size) for k, p in numpy_parts(cube - 1e6).items()}
    for k in ("vh", "tvh"):
        assert ours[k] == pytest.approx(ref[k], rel=1e-8), k


@pytest.mark.filterwarnings("ignore::irfidelity.noise.NoiseWarning")
@pytest.mark.parametrize("offset", [0.0, 1e6, 1e9, 1e12])
def test_float64_frames_on_a_large_offset_give_every_sigma_to_1e_6(offset):
    """Every σ, classical and corrected, against the exact decomposition of the very values
    given (float64 cube of 8 × 16 × 16: every part present, amplitudes 0.5–3, on an offset)."""
    rng = np.random.default_rng(25)
    shape = (8, 16, 16)
    cube = offset + random_effects(rng, {"t": 1.0, "v": 2.0, "h": 1.5, "tv": 0.7, "th": 0.5, "vh": 3.0, "tvh": 1.0},
                                   shape)
    ss, total, mean = exact_parts(cube)
    reference = anova({k: float(ss[k]) for k in PARTS}, *shape)
    n = irf.noise.noise3d(cube, spectra=False)
    classical = irf.noise.noise3d(cube, corrected=False, spectra=False)
    for k in PARTS:
        assert reference.corrected[k] > 0.05, k  # every corrected part well away from 0
        assert n.sigma[k] == pytest.approx(math.sqrt(reference.corrected[k]), rel=1e-6), (offset, k)
        assert classical.sigma[k] == pytest.approx(math.sqrt(reference.classical[k]), rel=1e-6), (offset, k)
    assert n.mean == pytest.approx(float(mean), rel=1e-15)
    assert n.sums.decomposition()["ss_total"] == pytest.approx(float(total), rel=1e-9)


# --------------------------------------------------------------------------- merging, files, workers
def test_merge_over_frame_ranges_equals_one_pass_and_pickles():
    cube = known_cube((23, 9, 11), {k: 20 for k in PARTS}, seed=11)
    whole = noise_sums(cube)
    parts = [noise_sums(cube[a:b]) for a, b in ((0, 5), (5, 6), (6, 23))]
    merged = pickle.loads(pickle.dumps(parts[0])).merge(parts[1]).merge(pickle.loads(pickle.dumps(parts[2])))
    assert merged.exact_ss() == whole.exact_ss()
    np.testing.assert_array_equal(merged.row_means(), whole.row_means())
    np.testing.assert_array_equal(merged.pixel_var(), whole.pixel_var())
    assert merged.to_bytes() == whole.to_bytes()
    a = irf.noise.noise3d(merged)
    b = irf.noise.noise3d(cube, spectra=False)
    assert a.sigma == b.sigma and a.ci == b.ci
    floats = cube.astype(np.float32) / 7
    fw = noise_sums(floats).decomposition()
    fm = noise_sums(floats[:10]).merge(noise_sums(floats[10:])).decomposition()
    for k in PARTS:
        assert fm["ss"][k] == pytest.approx(fw["ss"][k], rel=1e-12)
    with pytest.raises(ShapeError):
        whole.merge(noise_sums(cube[:, :8]))
    with pytest.raises(ShapeError):
        whole.merge(noise_sums(floats))
    with pytest.raises(FidelityError):
        NoiseSums.from_bytes(whole.to_bytes()[:-3])


def test_dask_spreads_frame_ranges_over_processes(tmp_path):
    import dask  # in the test extra; imported here, the only test that needs it
    cube = known_cube((40, 16, 12), {k: 30 for k in PARTS}, seed=13)
    tifffile.imwrite(tmp_path / "stack.tif", cube)
    seq = irf.FrameSequence(tmp_path / "stack.tif")
    parts = [dask.delayed(noise_sums)(seq[a:b]) for a, b in ((0, 15), (15, 31), (31, 40))]
    computed = dask.compute(*parts, scheduler="processes", num_workers=2)
    total = computed[0].merge(computed[1]).merge(computed[2])
    assert total.to_bytes() == noise_sums(cube).to_bytes()


@pytest.mark.filterwarnings("ignore::irfidelity.noise.NoiseWarning")
def test_streamed_from_files_equals_from_the_array(tmp_path):
    cube = known_cube((20, 12, 10), {k: 25 for k in PARTS}, seed=2)
    tifffile.imwrite(tmp_path / "stack.tif", cube)
    frames = tmp_path / "frames"
    frames.mkdir()
    for i, f in enumerate(cube):
        tifffile.imwrite(frames / f"f_{i}.tif", f)
    np.save(tmp_path / "cube.npy", cube)
    for i, f in enumerate(cube):
        np.save(frames / f"n_{i:02d}.npy", f)
    ref = noise_sums(cube)
    for source in (tmp_path / "stack.tif", str(frames / "f_*.tif"), [frames / f"f_{i}.tif" for i in range(20)],
                   str(frames / "n_*.npy"), irf.FrameSequence(tmp_path / "stack.tif")):
        got = noise_sums(source, workers=2)
        assert got.to_bytes() == ref.to_bytes(), source
    floats = cube.astype(np.float32) * 0.37
    tifffile.imwrite(tmp_path / "floats.tif", floats)
    assert noise_sums(tmp_path / "floats.tif").to_bytes() == noise_sums(floats).to_bytes()
    a = irf.noise.noise3d(tmp_path / "stack.tif")
    b = irf.noise.noise3d(cube)
    assert a.sigma == b.sigma
    np.testing.assert_array_equal(a.spectra.temporal_row, b.spectra.temporal_row)


def test_results_do_not_depend_on_the_worker_count():
    cube = known_cube((70, 8, 9), {k: 9 for k in PARTS}, seed=4).astype(np.float64) * 1.1
    one = noise_sums(cube, workers=1).to_bytes()
    assert noise_sums(cube, workers=3).to_bytes() == one
    assert noise_sums(cube).to_bytes() == one


def test_roi_equals_the_cropped_cube(tmp_path):
    cube = known_cube((6, 10, 12), {k: 7 for k in PARTS}, seed=6)
    tifffile.imwrite(tmp_path / "s.tif", cube)
    crop = noise_sums(cube[:, 2:7, 3:11])
    assert noise_sums(cube, roi=(2, 7, 3, 11)).to_bytes() == crop.to_bytes()
    assert noise_sums(tmp_path / "s.tif", roi=(2, 7, 3, 11)).to_bytes() == crop.to_bytes()
    for bad in ((2, 2, 0, 5), (0, 11, 0, 5), (0, 5, -1, 5), (1, 2, 3)):
        with pytest.raises((ShapeError, FidelityError)):
            noise_sums(cube, roi=bad)


# --------------------------------------------------------------------------- classical vs corrected
def test_classical_equals_numpy_and_pyradi_formulas():
    rng = np.random.default_rng(21)
    cube = 500 + random_effects(rng, {k: 1.0 + i for i, k in enumerate(PARTS)}, (9, 13, 11))
    n3d = irf.noise.noise3d(cube, corrected=False, spectra=False)
    parts = numpy_parts(cube)
    pyradi = pyradi_formulas(cube)
    for k, p in parts.items():
        assert n3d.sigma[k] == pytest.approx(float(p.std()), rel=1e-12), k
        # pyradi divides by (elements of the part − 1)
        assert n3d.sigma[k] * math.sqrt(p.size / (p.size - 1)) == pytest.approx(pyradi[k], rel=1e-12), k
    assert n3d.total == pytest.approx(float(cube.std()), rel=1e-12)


def expected_mean_squares(sigma: dict[str, float], t: int, v: int, h: int) -> dict[str, float]:
    """E[MS_x] under the random-effects model (balanced three-way ANOVA, one observation per cell)."""
    s = {k: sigma.get(k, 0.0) ** 2 for k in PARTS}
    e = {"tvh": s["tvh"], "tv": s["tvh"] + h * s["tv"], "th": s["tvh"] + v * s["th"], "vh": s["tvh"] + t * s["vh"]}
    e["t"] = s["tvh"] + h * s["tv"] + v * s["th"] + v * h * s["t"]
    e["v"] = s["tvh"] + h * s["tv"] + t * s["vh"] + t * h * s["v"]
    e["h"] = s["tvh"] + v * s["th"] + t * s["vh"] + t * v * s["h"]
    return e


def test_corrected_estimates_are_unbiased_and_classical_ones_are_not():
    t, v, h = 4, 5, 6
    sigma = {"t": 0.3, "v": 0.5, "h": 0.4, "tv": 0.6, "th": 0.3, "vh": 0.8, "tvh": 3.0}
    rng = np.random.default_rng(1234)
    corr = {k: [] for k in PARTS}
    clas = {k: [] for k in PARTS}
    covered = total = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoiseWarning)  # random row offsets may line up
        for _ in range(150):
            n3d = irf.noise.noise3d(random_effects(rng, sigma, (t, v, h)), spectra=False)
            for k in PARTS:
                corr[k].append(n3d.variance[k])
                clas[k].append(n3d.classical[k] ** 2)
                lo, hi = n3d.ci[k]
                covered += lo <= sigma[k] <= hi
                total += 1
    ems = expected_mean_squares(sigma, t, v, h)
    df = {"t": 3, "v": 4, "h": 5, "tv": 12, "th": 15, "vh": 20, "tvh": 60}
    biased = 0
    for k in PARTS:
        se_c = np.std(corr[k]) / math.sqrt(150)
        assert abs(np.mean(corr[k]) - sigma[k] ** 2) < 3.5 * se_c, k
        # the classical estimate has mean df·E[MS]/N, not σ²
        expected = df[k] * ems[k] / (t * v * h)
        se = np.std(clas[k]) / math.sqrt(150)
        assert abs(np.mean(clas[k]) - expected) < 3.5 * se, k
        biased += abs(np.mean(clas[k]) - sigma[k] ** 2) > 5 * se
    assert biased >= 5
    assert 0.92 <= covered / total <= 0.99, covered / total


def test_intervals_cover_components_that_are_zero():
    rng = np.random.default_rng(77)
    covered = {k: 0 for k in PARTS if k != "tvh"}
    for _ in range(100):
        n3d = irf.noise.noise3d(random_effects(rng, {"tvh": 1.0}, (8, 8, 8)), spectra=False)
        for k in covered:
            covered[k] += n3d.ci[k][0] == 0.0
    assert min(covered.values()) >= 90, covered


def test_interval_of_one_mean_square_is_the_exact_chi_square_interval():
    lo, hi = variance_interval({"x": 1.0}, {"x": 2.5}, {"x": 17}, 0.9)
    chi2 = scipy_stats.chi2
    assert lo == pytest.approx(17 * 2.5 / chi2.ppf(0.95, 17), rel=1e-11)
    assert hi == pytest.approx(17 * 2.5 / chi2.ppf(0.05, 17), rel=1e-11)


def test_quantiles_match_scipy():
    for df in (0.05, 0.7, 1, 3.5, 40, 999.5, 1.5e5):
        for p in (1e-6, 0.025, 0.5, 0.975, 1 - 1e-6):
            assert chi2_ppf(p, df) == pytest.approx(scipy_stats.chi2.ppf(p, df), rel=1e-9), (p, df)
    for df in (3e5, 3.2e7):
        for p in (1e-4, 0.025, 0.975, 1 - 1e-4):
            assert chi2_ppf(p, df) == pytest.approx(scipy_stats.chi2.ppf(p, df), rel=1e-8), (p, df)
    for n1, n2 in ((0.5, 2), (3, 7), (99, 50589), (511, 1000), (5e4, 3.1)):
        for p in (1e-5, 0.025, 0.5, 0.975):
            assert f_ppf(p, n1, n2) == pytest.approx(scipy_stats.f.ppf(p, n1, n2), rel=1e-8), (p, n1, n2)
    assert f_ppf(0.975, 99, 3e7) == pytest.approx(scipy_stats.f.ppf(0.975, 99, 3e7), rel=(99 + 10) / 3e7)


def test_anova_identity_matches_the_documented_estimators():
    ss = {"t": 10.0, "v": 20.0, "h": 30.0, "tv": 40.0, "th": 50.0, "vh": 60.0, "tvh": 70.0}
    a = anova(ss, 3, 4, 5)
    ms = {"t": 5.0, "v": 20 / 3, "h": 7.5, "tv": 40 / 6, "th": 50 / 8, "vh": 60 / 12, "tvh": 70 / 24}
    assert a.mean_squares == pytest.approx(ms)
    assert a.corrected["tvh"] == pytest.approx(ms["tvh"])
    assert a.corrected["tv"] == pytest.approx((ms["tv"] - ms["tvh"]) / 5)
    assert a.corrected["th"] == pytest.approx((ms["th"] - ms["tvh"]) / 4)
    assert a.corrected["vh"] == pytest.approx((ms["vh"] - ms["tvh"]) / 3)
    assert a.corrected["t"] == pytest.approx((ms["t"] - ms["tv"] - ms["th"] + ms["tvh"]) / 20)
    assert a.corrected["v"] == pytest.approx((ms["v"] - ms["tv"] - ms["vh"] + ms["tvh"]) / 15)
    assert a.corrected["h"] == pytest.approx((ms["h"] - ms["th"] - ms["vh"] + ms["tvh"]) / 12)
    assert a.classical == pytest.approx({k: v / 60 for k, v in ss.items()})


# --------------------------------------------------------------------------- NETD, spectra, similarity
def test_netd_is_the_temporal_random_part_over_the_sitf_slope():
    rng = np.random.default_rng(3)
    cube = 2000 + random_effects(rng, {"tvh": 4.0, "vh": 2.0}, (10, 20, 20))
    n3d = irf.noise.noise3d(cube, sitf=-8.0, spectra=False)
    assert n3d.netd == pytest.approx(n3d.sigma["tvh"] / 8.0)
    assert n3d.netd_ci[0] < n3d.netd < n3d.netd_ci[1]
    fit = irf.curves.sitf_fit(irf.Curve(np.arange(10.0), 3.0 * np.arange(10.0) + 5))
    assert irf.noise.noise3d(cube, sitf=fit, spectra=False).netd == pytest.approx(n3d.sigma["tvh"] / 3.0)
    assert irf.noise.noise3d(cube, spectra=False).netd is None
    for bad in (0.0, math.nan, "steep"):
        with pytest.raises(FidelityError):
            irf.noise.noise3d(cube, sitf=bad, spectra=False)


def test_spectra_hold_the_patterns_power_where_it_is():
    rng = np.random.default_rng(8)
    t, v, h = 12, 32, 40
    cols = np.arange(h)
    stripes = 3.0 * np.cos(2 * np.pi * 0.25 * cols)            # fixed column pattern at 0.25 cy/px
    cube = 100 + stripes[None, None, :] + rng.normal(0, 1.0, (t, v, h))
    n3d = irf.noise.noise3d(cube)
    sp = n3d.spectra
    fixed = n3d.fixed_pattern
    assert sp.fixed_row.sum() == pytest.approx(float((fixed ** 2).mean()), rel=1e-12)
    assert sp.fixed_col.sum() == pytest.approx(float((fixed ** 2).mean()), rel=1e-12)
    assert sp.fixed_2d.sum() == pytest.approx(float((fixed ** 2).mean()), rel=1e-12)
    assert sp.freq_row[np.argmax(sp.fixed_row)] == pytest.approx(0.25)
    assert sp.fixed_row[np.argmax(sp.fixed_row)] == pytest.approx(4.5, rel=0.05)  # 3²/2
    diffs = [(cube[2 * k + 1] - cube[2 * k]) / math.sqrt(2) for k in range(6)]
    power = np.mean([((d - d.mean()) ** 2).mean() for d in diffs])
    assert sp.pairs == 6
    assert sp.temporal_row.sum() == pytest.approx(power, rel=1e-12)
    assert sp.temporal_col.sum() == pytest.approx(power, rel=1e-12)
    # white temporal noise: flat within its estimation error
    inner = sp.temporal_row[1:-1]
    assert inner.std() / inner.mean() < 0.2
    assert sp.temporal_2d.shape == (v, h) and sp.fixed_2d.shape == (v, h)
    assert irf.noise.noise3d(noise_sums(cube)).spectra.temporal_row is None


def _blurred(rng, shape):
    """Temporal noise correlated along rows and columns (a 3-tap average), σ about 1."""
    x = rng.normal(0, 1.0, (shape[0], shape[1] + 2, shape[2] + 2))
    x = (x[:, :, :-2] + x[:, :, 1:-1] + x[:, :, 2:]) / 3
    x = (x[:, :-2, :] + x[:, 1:-1, :] + x[:, 2:, :]) / 3
    return x * 3


def test_noise_similarity_levels_and_shapes():
    rng = np.random.default_rng(10)
    shape = (16, 48, 48)
    base = {"v": 1.0, "vh": 1.5, "tvh": 2.0}
    real = irf.noise.noise3d(300 + random_effects(rng, base, shape))
    twin = irf.noise.noise3d(300 + random_effects(rng, base, shape))
    same = irf.noise.noise_similarity(real, twin)
    assert same.value > 0.95 and same.mu > 0.97 and same.rho > 0.97
    assert irf.noise.noise_similarity(real, real).value == pytest.approx(1.0)
    # every level doubled: mu = 2·2/(1 + 4) exactly, shapes unchanged
    single = irf.noise.noise3d(300 + random_effects(np.random.default_rng(10), base, shape))
    double = irf.noise.noise3d(600 + 2 * random_effects(np.random.default_rng(10), base, shape))
    sim = irf.noise.noise_similarity(single, double)
    assert sim.mu == pytest.approx(0.8, rel=1e-9)
    assert sim.rho == pytest.approx(1.0, abs=1e-12)
    # white vs correlated temporal noise of about the same level: the shape term drops
    corr = irf.noise.noise3d(300 + random_effects(rng, {"v": 1.0, "vh": 1.5}, shape) + 2.0 * _blurred(rng, shape))
    diff = irf.noise.noise_similarity(real, corr)
    assert diff.overlap["temporal_row"] < 0.9 and diff.rho < same.rho - 0.05
    # temperature units: a simulator with twice the gain and twice the SiTF slope matches
    real_k = irf.noise.noise3d(300 + random_effects(np.random.default_rng(10), base, shape), sitf=1.0)
    sim_k = irf.noise.noise3d(600 + 2 * random_effects(np.random.default_rng(10), base, shape), sitf=2.0)
    assert irf.noise.noise_similarity(real_k, sim_k).mu == pytest.approx(1.0)
    assert irf.noise.noise_similarity(real_k, sim_k).units == "temperature"
    with pytest.raises(FidelityError, match="SiTF"):
        irf.noise.noise_similarity(real_k, twin)
    with pytest.raises(FidelityError, match="spectra"):
        irf.noise.noise_similarity(real, irf.noise.noise3d(noise_sums(np.stack([np.ones((4, 4)), np.zeros((4, 4))]))))
    with pytest.raises(FidelityError, match="corrected"):
        irf.noise.noise_similarity(real, irf.noise.noise3d(300 + random_effects(rng, base, shape), corrected=False))
    assert json.dumps(same.to_dict())
    metrics = same.metrics()
    assert list(metrics) == [key for key, _, _ in NOISE_METRICS]
    assert metrics["noise_sigma_tvh_real"] == real.sigma["tvh"] and metrics["noise_sigma_vh_sim"] == twin.sigma["vh"]
    assert metrics["noise_mu"] == same.mu and metrics["noise_netd_real"] is None
    assert json.dumps(metrics)


def test_noise_similarity_of_frames_of_different_sizes():
    rng = np.random.default_rng(4)
    a = irf.noise.noise3d(random_effects(rng, {"tvh": 1.0, "vh": 0.5}, (10, 40, 60)))
    b = irf.noise.noise3d(random_effects(rng, {"tvh": 1.0, "vh": 0.5}, (10, 33, 51)))
    assert irf.noise.noise_similarity(a, b).value > 0.93


# --------------------------------------------------------------------------- bad input
def test_fewer_than_two_frames_rows_or_columns():
    with pytest.raises(ShapeError, match="at least 2 frames"):
        irf.noise.noise3d(np.ones((1, 5, 5), np.uint16))
    with pytest.raises(ShapeError, match="at least 2 x 2"):
        irf.noise.noise3d(np.ones((5, 1, 5), np.uint16))
    with pytest.raises(ShapeError, match="3 x 3"):
        irf.noise.noise3d(np.ones((5, 2, 5), np.uint16), detrend="plane")
    with pytest.raises(ShapeError):
        irf.noise.noise3d(np.ones((5, 5), np.uint16))
    with pytest.raises(ShapeError):
        irf.noise.noise3d(np.ones((3, 4, 4), np.int64))


def test_frames_of_different_shapes_or_dtypes_name_the_file(tmp_path):
    tifffile.imwrite(tmp_path / "a.tif", np.ones((4, 4), np.uint16))
    tifffile.imwrite(tmp_path / "c.tif", np.ones((5, 4), np.uint16))
    with pytest.raises(ShapeError, match=r"c\.tif: frame of 5 x 4"):
        irf.noise.noise3d([tmp_path / "a.tif", tmp_path / "a.tif", tmp_path / "c.tif"])
    tifffile.imwrite(tmp_path / "b.tif", np.ones((4, 4), np.uint8))
    with pytest.raises(ShapeError, match="b.tif"):
        noise_sums([tmp_path / "a.tif", tmp_path / "b.tif"])
    with pytest.raises(FrameError):
        noise_sums(tmp_path / "nothing_here")
    (tmp_path / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n broken")
    with pytest.raises(FrameError, match="broken.png"):
        noise_sums([tmp_path / "a.tif", tmp_path / "broken.png"])


def test_nan_inf_and_values_above_bits_are_errors_with_positions():
    cube = np.ones((4, 5, 6), np.float32)
    cube[2, 3, 1] = np.nan
    cube[2, 4, 4] = np.inf
    with pytest.raises(RangeError, match=r"frame 2: 2 non-finite.*row 3, column 1"):
        irf.noise.noise3d(cube)
    ints = np.full((3, 4, 4), 100, np.uint16)
    ints[1, 2, 3] = 4096
    with pytest.raises(RangeError, match="frame 1.*row 2, column 3"):
        irf.noise.noise3d(ints, bits=12)
    with pytest.raises(FidelityError, match="bits"):
        irf.noise.noise3d(np.zeros_like(cube), bits=12)
    with pytest.raises(RangeError, match="too large"):
        irf.noise.noise3d(np.full((3, 3, 3), 1e200))


def test_clipped_samples_warn_or_raise_with_counts():
    rng = np.random.default_rng(2)
    cube = np.clip(np.round(4090 + rng.normal(0, 3, (6, 10, 10))), 0, 4095).astype(np.uint16)
    at_hi = int((cube == 4095).sum())
    assert at_hi > 0
    with pytest.warns(NoiseWarning, match=f"{at_hi} samples at the saturation level 4095"):
        n3d = irf.noise.noise3d(cube, bits=12, spectra=False)
    assert n3d.clipped == {"lo": 0, "hi": 4095, "at_lo": 0, "at_hi": at_hi}
    with pytest.raises(RangeError, match="saturation"):
        irf.noise.noise3d(cube, bits=12, saturated="raise")
    quiet_noise3d(cube, bits=12, saturated="ignore", spectra=False)
    assert quiet_noise3d(cube, spectra=False).clipped["at_hi"] == 0  # 65535 is never reached


def test_a_gradient_warns_and_plane_detrending_removes_it():
    rng = np.random.default_rng(9)
    t, v, h = 12, 30, 40
    ramp = 0.5 * np.arange(v)[:, None] + 0.3 * np.arange(h)[None, :]
    base = random_effects(rng, {"v": 1.0, "h": 0.8, "vh": 1.2, "tvh": 2.0}, (t, v, h))
    with pytest.warns(NoiseWarning, match="detrend='plane'"):
        tilted = irf.noise.noise3d(1000 + ramp + base, spectra=False)
    plain = quiet_noise3d(1000 + base, spectra=False)
    detrended = quiet_noise3d(1000 + ramp + base, detrend="plane", spectra=False)
    assert tilted.sigma["v"] > 3 * plain.sigma["v"]
    for k in PARTS:
        assert detrended.sigma[k] == pytest.approx(plain.sigma[k], rel=0.1, abs=0.05), k
    assert detrended.df["v"] == plain.df["v"] - 1 and detrended.df["h"] == plain.df["h"] - 1
    assert abs(detrended.fixed_pattern.mean()) < 1e-9


def test_an_object_warns_and_a_region_avoids_it():
    rng = np.random.default_rng(12)
    t, v, h = 8, 48, 48
    yy, xx = np.mgrid[:v, :h]
    disc = 40.0 * ((yy - 20) ** 2 + (xx - 30) ** 2 < 10 ** 2)
    cube = 500 + disc + random_effects(rng, {"vh": 1.0, "tvh": 2.0}, (t, v, h))
    with pytest.warns(NoiseWarning, match="roi="):
        irf.noise.noise3d(cube, spectra=False)
    quiet_noise3d(cube, roi=(32, 48, 0, 48), spectra=False)


def test_bad_options_are_errors():
    cube = np.ones((3, 4, 4), np.uint16)
    for kwargs in ({"detrend": "quadratic"}, {"confidence": 1.0}, {"confidence": "high"}, {"corrected": 1},
                   {"saturated": "clip"}, {"spectra_pairs": 0}, {"workers": 0}, {"bits": 2.5}):
        with pytest.raises(FidelityError):
            irf.noise.noise3d(cube, **kwargs)
    with pytest.raises(FidelityError, match="roi"):
        irf.noise.noise3d(noise_sums(cube), roi=(0, 2, 0, 2))


# --------------------------------------------------------------------------- real recordings
def _parts_from_reference(path: pathlib.Path) -> dict[str, float]:
    cube = tifffile.imread(path).astype(np.int64)
    parts = numpy_parts(cube)
    return {k: float((p ** 2).sum()) * (cube.size // p.size) for k, p in parts.items()}


def test_lwir_recording_is_near_uniform_and_dominated_by_random_temporal_noise():
    n3d = quiet_noise3d(LWIR)
    assert (n3d.frames, n3d.rows, n3d.cols) == (100, 68, 75)
    ref = _parts_from_reference(LWIR)
    dec = n3d.sums.decomposition()
    for k in PARTS:
        assert dec["ss"][k] == pytest.approx(ref[k], rel=1e-9), k
    exact = n3d.sums.exact_ss()
    assert sum(exact[k] for k in PARTS) == exact["total"]
    assert max(n3d.sigma, key=n3d.sigma.get) == "tvh"
    assert n3d.sigma["tvh"] > 2 * max(v for k, v in n3d.sigma.items() if k != "tvh")
    for k in PARTS:
        assert n3d.ci[k][0] <= n3d.sigma[k] <= n3d.ci[k][1]
    assert n3d.uniformity["plane"] < 0.10 and n3d.uniformity["low_frequency"] < 0.10
    assert json.dumps(n3d.to_dict())


def test_mwir_recording_has_dominant_row_structure():
    with pytest.warns(NoiseWarning, match="gradient"):
        n3d = irf.noise.noise3d(MWIR)
    ranked = sorted(n3d.sigma, key=n3d.sigma.get, reverse=True)
    assert ranked[:2] == ["v", "vh"]
    detrended = quiet_noise3d(MWIR, detrend="plane")
    assert detrended.sigma["v"] < n3d.sigma["v"]
    assert sorted(detrended.sigma, key=detrended.sigma.get, reverse=True)[:2] == ["v", "vh"]
    # the row pattern shows in the fixed-pattern column spectrum: alternate rows differ
    sp = detrended.spectra
    assert sp.fixed_col[-1] > 10 * np.median(sp.fixed_col)
    lwir = quiet_noise3d(LWIR)
    assert irf.noise.noise_similarity(lwir, detrended).value < 0.2


def test_blackbody_frames_warn_about_the_object_and_its_aperture_is_uniform():
    with pytest.warns(NoiseWarning, match="large-scale structure"):
        irf.noise.noise3d(BB150)
    # the central 30 x 30 pixels of the source: its emitter still has a gradient across it
    aperture = quiet_noise3d(BB150, roi=(85, 115, 132, 162), detrend="plane")
    assert aperture.frames == 2 and aperture.rows == aperture.cols == 30
    # with two frames, the random temporal part is the double-centred frame difference
    a, b = (irf.load_frame(p)[85:115, 132:162].astype(np.float64) for p in BB150)
    d = b - a
    dc = d - d.mean(axis=0, keepdims=True) - d.mean(axis=1, keepdims=True) + d.mean()
    assert aperture.variance["tvh"] == pytest.approx(float((dc ** 2).sum()) / (2 * 29 * 29), rel=1e-12)
    # the emitter's fixed pattern dominates; with two frames the temporal parts are uncertain
    assert aperture.sigma["vh"] > 3 * aperture.sigma["tvh"]
    assert aperture.df["t"] == 1 and aperture.df["tvh"] == 29 * 29
    lo, hi = aperture.ci["tvh"]
    assert (hi - lo) / aperture.sigma["tvh"] < 0.15


# --------------------------------------------------------------------------- the noise component in scores
def test_noise_component_in_evaluate_sequences_and_cli(tmp_path):
    import json
    import subprocess
    import sys

    stack = DATA / "ptw_lwir_all100frames_uint16.tif"
    frames = irf.FrameSequence(stack)
    real_noise, sim_noise = np.stack([frames[i] for i in range(40)]), np.stack([frames[i] for i in range(40, 80)])
    lepton = DATA / "cptv_v2_frame000.png", DATA / "cptv_v2_frame001.png"
    weights = "psnr=0.3,nmi=0.2,ssim=0.3,noise=0.2"
    rep = irf.evaluate(*lepton, real_noise=real_noise, sim_noise=sim_noise, weights=weights, bits=14)
    expected = irf.noise.noise_similarity(irf.noise.noise3d(real_noise, bits=14), irf.noise.noise3d(sim_noise, bits=14))
    assert rep.components["noise"] == expected.value and 0 < expected.value <= 1
    assert rep.metrics["noise_sigma_tvh_real"] == expected.metrics()["noise_sigma_tvh_real"]
    assert rep.fidelity == pytest.approx(sum(rep.weights[k] * v for k, v in rep.components.items()), rel=1e-15)
    assert "noise" in rep.summary_text()
    # weight 0 (the default): the simulator's recording is not read at all, and the paper's five are
    # scored; the real camera's noise still sets the ceiling (tests/test_noise_ceiling.py)
    plain = irf.evaluate(*lepton, real_noise=real_noise, sim_noise="nor/this", bits=14)
    assert "noise" not in plain.components and "noise" not in plain.skipped and plain.ceiling_source == "noise3d"
    # a weighted noise component without recordings is dropped like any other
    dropped = irf.evaluate(*lepton, weights=weights, bits=14)
    assert "real_noise/sim_noise" in dropped.skipped["noise"]
    # sequences: computed once, in every frame and the pooled fidelity
    seq = irf.score_sequence(DATA / "cptv_v2_all100frames_uint16.tif",
                             DATA / "cptv_v2_all100frames_uint16.tif", bits=14, weights=weights,
                             real_noise=real_noise, sim_noise=sim_noise, progress=False, pair_by="order")
    assert {f["components"]["noise"] for f in seq.frames} == {expected.value} == {seq.components["noise"]}
    # the command line: directories of frames
    for name, arr in (("real", real_noise), ("sim", sim_noise)):
        d = tmp_path / name
        d.mkdir()
        for i, frame in enumerate(arr):
            np.save(d / f"f{i:03d}.npy", frame)
    p = subprocess.run([sys.executable, "-m", "irfidelity.cli", "score", *map(str, lepton), "--bits", "14",
                        "--weights", weights, "--real-noise", str(tmp_path / "real"), "--sim-noise",
                        str(tmp_path / "sim"), "--json", "-"], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["components"]["noise"] == pytest.approx(expected.value, rel=1e-12)
