"""Core statistics: exact references, docs/design.md §4 conventions, planning, merge, pickling."""

from __future__ import annotations

import math
import pickle
import threading
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
import png
import pytest
from sklearn.metrics import normalized_mutual_info_score

import irfidelity as irf
from irfidelity.normalize import normalize_psnr
from irfidelity import _core
from irfidelity.metrics import nmi_from_entropies, signed_power

DATA = Path(__file__).parent / "data"
INT_DTYPES = [np.uint8, np.uint16, np.int16, np.uint32]
FLOAT_DTYPES = [np.float16, np.float32, np.float64]


def read_png16(path: Path) -> np.ndarray:
    w, h, rows, info = png.Reader(filename=str(path)).read()
    return np.array([np.asarray(r) for r in rows], dtype=np.uint16).reshape(h, w)


def exact_ref(r: np.ndarray, s: np.ndarray):
    """MSE, variances and covariance as Fractions from Python integers."""
    a = [int(v) for v in r.ravel()]
    b = [int(v) for v in s.ravel()]
    n = len(a)
    sr, ss = sum(a), sum(b)
    srr = sum(x * x for x in a)
    sss = sum(y * y for y in b)
    srs = sum(x * y for x, y in zip(a, b))
    sse = sum((x - y) ** 2 for x, y in zip(a, b))
    return {
        "mse": Fraction(sse, n),
        "mean_r": Fraction(sr, n),
        "mean_s": Fraction(ss, n),
        "var_r": Fraction(n * srr - sr * sr, n * n),
        "var_s": Fraction(n * sss - ss * ss, n * n),
        "cov": Fraction(n * srs - sr * ss, n * n),
        "sums": dict(sum_real=sr, sum_sim=ss, sum_real_sq=srr, sum_sim_sq=sss, sum_cross=srs, sse=sse),
    }


def rel(a: float, b) -> float:
    b = float(b)
    return abs(a - b) / abs(b) if b else abs(a)


def rand_pair(dtype, shape=(37, 53), seed=0):
    rng = np.random.default_rng(seed)
    info = np.iinfo(dtype)
    r = rng.integers(info.min, info.max, size=shape, endpoint=True, dtype=np.int64)
    s = np.clip(r + rng.integers(-50, 51, size=shape), info.min, info.max)
    return r.astype(dtype), s.astype(dtype)


# --- exact integer arithmetic ------------------------------------------------------


@pytest.mark.parametrize("dtype", INT_DTYPES)
def test_integer_sums_are_exact(dtype):
    r, s = rand_pair(dtype)
    st = irf.pair_stats(r, s)
    ref = exact_ref(r, s)
    assert st.int_sums() == ref["sums"]
    assert st.mse() == float(ref["mse"])
    m = st.moments()
    assert rel(m["var_real"], ref["var_r"]) < 1e-15
    assert rel(m["cov"], ref["cov"]) < 1e-15
    sref = float(ref["cov"]) / math.sqrt(float(ref["var_r"]) * float(ref["var_s"]))
    assert abs(st.ssim().structure - sref) < 1e-14


def test_large_frames_near_65535_one_lsb_apart():
    rng = np.random.default_rng(1)
    r = (65535 - rng.integers(0, 4, size=(2048, 2048))).astype(np.uint16)
    flip = rng.random(r.shape) < 0.37
    s = (r.astype(np.int64) - flip).astype(np.uint16)
    st = irf.pair_stats(r, s, bits=16)
    n = r.size
    k = int(flip.sum())
    assert st.mse() == float(Fraction(k, n))
    assert st.psnr() == pytest.approx(10 * math.log10(65535**2 * n / k), rel=1e-15)
    # exact sums via int64 numpy (no overflow at this size) against the kernel's i128
    sums = st.int_sums()
    r64, s64 = r.astype(np.int64), s.astype(np.int64)
    assert sums["sum_real"] == int(r64.sum())
    assert sums["sum_real_sq"] == int((r64 * r64).sum())
    assert sums["sum_cross"] == int((r64 * s64).sum())


def test_uint32_products_do_not_overflow():
    r = np.full((3, 5), 2**32 - 1, dtype=np.uint32)
    s = r.copy()
    s[0, 0] = 0
    st = irf.pair_stats(r, s)
    ref = exact_ref(r, s)
    assert st.int_sums() == ref["sums"]
    assert rel(st.moments()["var_sim"], ref["var_s"]) < 1e-15


# --- float paths ----------------------------------------------------------------------


@pytest.mark.parametrize("dtype", FLOAT_DTYPES)
def test_float_paths_match_float64_two_pass(dtype):
    rng = np.random.default_rng(2)
    r = (rng.normal(300, 20, size=(70, 90))).astype(dtype)
    s = (r.astype(np.float64) * 0.97 + rng.normal(0, 3, size=r.shape)).astype(dtype)
    st = irf.pair_stats(r, s, peak=400.0)
    a, b = r.astype(np.float64), s.astype(np.float64)
    assert st.mse() == pytest.approx(np.mean((a - b) ** 2), rel=1e-13)
    m = st.moments()
    assert m["var_real"] == pytest.approx(a.var(), rel=1e-12)
    assert m["cov"] == pytest.approx(np.mean((a - a.mean()) * (b - b.mean())), rel=1e-12)
    assert st.psnr() == pytest.approx(10 * np.log10(400.0**2 / np.mean((a - b) ** 2)), rel=1e-13)


def test_float_cancellation_at_large_offset():
    # values exactly representable: 1e6 + k/64 in float32 (ulp at 1e6 is 1/16, so use k/16)
    rng = np.random.default_rng(3)
    k = rng.integers(-8, 9, size=(300, 301))
    r = (1e6 + k / 16).astype(np.float32)
    s = (1e6 + (k + rng.integers(-1, 2, size=k.shape)) / 16).astype(np.float32)
    st = irf.pair_stats(r, s, need=("ssim",))
    ra = [Fraction(float(v)) for v in r.ravel()]
    sa = [Fraction(float(v)) for v in s.ravel()]
    n = len(ra)
    mr, ms = sum(ra) / n, sum(sa) / n
    vr = sum((x - mr) ** 2 for x in ra) / n
    vs = sum((y - ms) ** 2 for y in sa) / n
    cv = sum((x - mr) * (y - ms) for x, y in zip(ra, sa)) / n
    c_ref = 2 * math.sqrt(vr * vs) / float(vr + vs)
    s_ref = float(cv) / math.sqrt(vr * vs)
    got = st.ssim()
    assert abs(got.contrast - c_ref) < 1e-9
    assert abs(got.structure - s_ref) < 1e-9


# --- NMI --------------------------------------------------------------------------------


def test_levels_nmi_equals_sklearn():
    rng = np.random.default_rng(4)
    r = rng.integers(1000, 1400, size=(64, 80)).astype(np.uint16)
    s = (r // 3 + rng.integers(0, 5, size=r.shape)).astype(np.uint16)
    got = irf.stats.nmi(r, s, bins="levels").value
    want = normalized_mutual_info_score(r.ravel(), s.ravel())
    assert got == pytest.approx(want, abs=1e-12)


def test_levels_wide_span_sparse_path_equals_sklearn():
    rng = np.random.default_rng(5)
    r = rng.integers(0, 65536, size=(50, 60)).astype(np.uint16)  # span > 512: sparse keys
    s = (r // 7).astype(np.uint16)
    got = irf.stats.nmi(r, s, bins="levels")
    assert got.value == pytest.approx(normalized_mutual_info_score(r.ravel(), s.ravel()), abs=1e-12)


def _nmi_from_hist2d(r, s, bins, lo, width):
    edges = lo + width * np.arange(bins + 1)
    joint, _, _ = np.histogram2d(r.ravel().astype(np.float64), s.ravel().astype(np.float64), bins=[edges, edges])
    p = joint / joint.sum()

    def h(q):
        q = q[q > 0]
        return float(-(q * np.log2(q)).sum())

    hr, hs, hj = h(p.sum(1)), h(p.sum(0)), h(p.ravel())
    return 2 * (hr + hs - hj) / (hr + hs)


def test_binned_nmi_equals_histogram2d_integer_edges():
    rng = np.random.default_rng(6)
    r = rng.integers(2600, 3200, size=(90, 110)).astype(np.uint16)
    s = np.clip(r.astype(np.int64) + rng.integers(-20, 21, size=r.shape), 0, None).astype(np.uint16)
    bins = 64
    lo = int(min(r.min(), s.min()))
    span = int(max(r.max(), s.max())) - lo + 1
    width = -(-span // bins)  # ceil: a bin is a whole number of grey levels
    want = _nmi_from_hist2d(r, s, bins, lo - 0.5, width)  # half-level edges: integers fall inside
    assert irf.stats.nmi(r, s, bins=bins, hist_range="data").value == pytest.approx(want, abs=1e-12)


def test_binned_nmi_float_equals_histogram2d():
    rng = np.random.default_rng(7)
    r = rng.normal(size=(80, 80))
    s = r + rng.normal(scale=0.3, size=r.shape)
    lo, hi = min(r.min(), s.min()), max(r.max(), s.max())
    want = _nmi_from_hist2d(r, s, 32, lo, (hi - lo) / 32)
    assert irf.stats.nmi(r, s, bins=32, hist_range="data").value == pytest.approx(want, abs=1e-9)


def test_span_within_bins_equals_levels():
    rng = np.random.default_rng(8)
    r = rng.integers(100, 300, size=(40, 40)).astype(np.uint16)
    s = rng.integers(150, 340, size=(40, 40)).astype(np.uint16)
    assert irf.stats.nmi(r, s, bins=256).value == pytest.approx(irf.stats.nmi(r, s, bins="levels").value, abs=1e-14)


# --- docs/design.md §4 conventions -----------------------------------------------------------


def test_identical_frames():
    r, _ = rand_pair(np.uint16)
    st = irf.pair_stats(r, r, bits=16)
    assert st.psnr() == math.inf
    assert normalize_psnr(st.psnr()) == 1.0
    assert st.ssim().value == 1.0
    assert st.nmi().value == pytest.approx(1.0, abs=1e-12)


def test_values_above_bits_are_an_error_naming_value_and_position():
    r = np.zeros((4, 6), dtype=np.uint16)
    s = r.copy()
    s[2, 3] = 4096
    with pytest.raises(irf.errors.RangeError, match=r"sim frame: value 4096 at \(row 2, col 3\)"):
        irf.pair_stats(r, s, bits=12)
    irf.pair_stats(r, s, bits=13)  # fits


def test_negative_int16_with_bits_is_an_error():
    r = np.zeros((2, 2), dtype=np.int16)
    r[1, 0] = -1
    with pytest.raises(irf.errors.RangeError, match="-1"):
        irf.pair_stats(r, np.zeros_like(r), bits=14)


def test_ssim_limits():
    z = np.zeros((5, 5), dtype=np.uint8)
    got = irf.stats.ssim(z, z)  # both means 0, both sigma 0
    assert (got.luminance, got.contrast, got.structure, got.value) == (1.0, 1.0, 1.0, 1.0)
    a = np.full((5, 5), 7, dtype=np.uint8)
    b = np.arange(25, dtype=np.uint8).reshape(5, 5)
    one = irf.stats.ssim(a, b)  # exactly one sigma 0
    assert one.structure == 0.0 and one.contrast == 0.0 and one.value == 0.0
    two = irf.stats.ssim(a, np.full((5, 5), 9, dtype=np.uint8))  # two different constants
    assert two.contrast == 1.0 and two.structure == 1.0
    assert two.luminance == pytest.approx(2 * 7 * 9 / (49 + 81))


def test_anticorrelated_fractional_gamma_keeps_sign():
    r = np.arange(100, dtype=np.float64).reshape(10, 10)
    s = 200.0 - r
    got = irf.stats.ssim(r, s, gamma=0.5)
    assert got.structure == pytest.approx(-1.0, abs=1e-15)
    assert got.value < 0 and not math.isnan(got.value)
    assert got.value == pytest.approx(got.luminance * got.contrast * -1.0)
    assert signed_power(-0.25, 0.5) == -0.5
    assert signed_power(0.0, 0.0) == 1.0


def test_nmi_constant_frames():
    a = np.full((8, 8), 3, dtype=np.uint8)
    b = np.full((8, 8), 200, dtype=np.uint8)
    c = np.arange(64, dtype=np.uint8).reshape(8, 8)
    assert irf.stats.nmi(a, b).value == 1.0  # both constant: a one-to-one relation
    assert irf.stats.nmi(a, c).value == 0.0  # one constant
    assert irf.stats.nmi(c, 255 - c).value == pytest.approx(1.0)  # negative image: NMI 1, not equality


def test_float_frames_need_a_peak_for_psnr():
    r = np.ones((3, 3), dtype=np.float32)
    with pytest.raises(irf.FidelityError, match="peak"):
        irf.stats.psnr(r, r * 2)
    assert irf.stats.psnr(r, r * 2, peak=1.0) == pytest.approx(0.0, abs=1e-12)


def test_nonfinite_raise_and_mask():
    r = np.ones((4, 4), dtype=np.float32)
    s = r.copy()
    s[1, 2] = np.nan
    s[3, 3] = np.inf
    with pytest.raises(irf.errors.RangeError, match=r"2 in the simulated frame; first at \(row 1, col 2\)"):
        irf.pair_stats(r, s, peak=1.0)
    st = irf.pair_stats(r, s, peak=1.0, nonfinite="mask")
    assert (st.n, st.nonfinite) == (14, 2)
    assert st.psnr() == math.inf


def test_shape_and_dtype_mismatch():
    a = np.zeros((3, 4), dtype=np.uint16)
    with pytest.raises(irf.errors.ShapeError, match=r"\(3, 4\) vs \(4, 3\)"):
        irf.pair_stats(a, a.T.copy())
    with pytest.raises(irf.errors.ShapeError, match="uint16 vs uint8"):
        irf.pair_stats(a, a.astype(np.uint8))
    with pytest.raises(irf.errors.ShapeError, match="2-D"):
        irf.pair_stats(a.ravel(), a.ravel())
    with pytest.raises(irf.errors.ShapeError, match="int64"):
        irf.pair_stats(a.astype(np.int64), a.astype(np.int64))
    with pytest.raises(irf.errors.ShapeError, match="mask"):
        irf.pair_stats(a, a, mask=np.ones((2, 2), bool))


def test_bad_arguments_are_fidelity_errors():
    a = np.zeros((3, 4), dtype=np.uint16)
    for kwargs in (
        dict(bits=17),
        dict(bins=0),
        dict(bins="many"),
        dict(hist_range="wide"),
        dict(need=("psnr", "sharpness")),
        dict(nonfinite="ignore"),
    ):
        with pytest.raises(irf.FidelityError):
            irf.pair_stats(a, a, **kwargs)
    with pytest.raises(irf.FidelityError, match="levels"):
        irf.pair_stats(a.astype(np.float32), a.astype(np.float32), bins="levels")


def test_mask_excludes_pairs():
    r, s = rand_pair(np.uint16, seed=9)
    mask = np.zeros(r.shape, bool)
    mask[5:20, 10:30] = True
    st = irf.pair_stats(r, s, mask=mask)
    ref = irf.pair_stats(r[5:20, 10:30], s[5:20, 10:30])
    assert st.n == mask.sum() and st.masked == mask.size - mask.sum()
    assert st.mse() == ref.mse() and st.moments() == ref.moments()
    assert st.nmi() == ref.nmi()


# --- planning, layout, merge, pickle ------------------------------------------------------


def test_need_computes_only_what_is_asked():
    r, s = rand_pair(np.uint16)
    st = irf.pair_stats(r, s, need=("psnr",))
    assert not st._raw.has_hist and not st._raw.has_moments and st._raw.has_sse
    with pytest.raises(irf.FidelityError, match="'nmi' in need"):
        st.nmi()
    with pytest.raises(irf.FidelityError, match="'ssim' in need"):
        st.ssim()
    only_nmi = irf.pair_stats(r, s, need=("nmi",))
    assert only_nmi._raw.has_hist and not only_nmi._raw.has_sse


def test_layout_independence():
    r, s = rand_pair(np.uint16, shape=(64, 48), seed=10)
    base = irf.pair_stats(r, s)
    assert irf.pair_stats(np.asfortranarray(r), np.asfortranarray(s)) == base
    assert irf.pair_stats(np.asfortranarray(r), s) == base  # mixed layouts
    big_r = np.zeros((128, 96), np.uint16)
    big_s = np.zeros((128, 96), np.uint16)
    big_r[::2, ::2], big_s[::2, ::2] = r, s
    assert irf.pair_stats(big_r[::2, ::2], big_s[::2, ::2]) == base  # strided views
    assert irf.pair_stats(r.T, s.T) == irf.pair_stats(r.T.copy(), s.T.copy())


def test_merge_equals_concatenation_and_pickles():
    r, s = rand_pair(np.uint16, shape=(90, 40), seed=11)
    kw = dict(bits=16, hist_range="full", bins=256)
    top = irf.pair_stats(r[:33], s[:33], **kw)
    bottom = irf.pair_stats(r[33:], s[33:], **kw)
    whole = irf.pair_stats(r, s, **kw)
    assert top.merge(bottom) == whole
    assert pickle.loads(pickle.dumps(whole)) == whole
    lv = irf.pair_stats(r[:33], s[:33], bins="levels").merge(irf.pair_stats(r[33:], s[33:], bins="levels"))
    assert lv.nmi().value == pytest.approx(irf.stats.nmi(r, s, bins="levels").value, abs=1e-14)
    # "data" ranges differ between parts: histograms cannot be pooled, and the error says why
    with pytest.raises(irf.FidelityError, match="different edges"):
        irf.pair_stats(r[:33], s[:33]).merge(irf.pair_stats(r[33:] // 2, s[33:] // 2))


def test_float_merge_matches_whole():
    rng = np.random.default_rng(12)
    r = rng.normal(1e4, 1.0, size=(300, 300)).astype(np.float32)
    s = (r + rng.normal(0, 0.1, size=r.shape)).astype(np.float32)
    whole = irf.pair_stats(r, s, peak=2e4, need=("psnr", "ssim"))
    parts = irf.pair_stats(r[:101], s[:101], peak=2e4, need=("psnr", "ssim")).merge(
        irf.pair_stats(r[101:], s[101:], peak=2e4, need=("psnr", "ssim"))
    )
    assert parts.mse() == pytest.approx(whole.mse(), rel=1e-14)
    assert parts.ssim().structure == pytest.approx(whole.ssim().structure, rel=1e-12)


def test_corrupt_pickle_is_a_clear_error():
    with pytest.raises(irf.FidelityError, match="not a serialized PairStats"):
        _core.PairStats.from_bytes(b"IFS1\x00\x01")


def test_gil_is_released_during_the_pass():
    rng = np.random.default_rng(13)
    r = rng.integers(0, 65536, size=(4096, 4096), dtype=np.uint16)
    s = r ^ 1
    ticks = 0
    stop = threading.Event()

    def spin():
        nonlocal ticks
        while not stop.is_set():
            ticks += 1

    t = threading.Thread(target=spin)
    t.start()
    time.sleep(0.05)
    before = ticks
    t0 = time.perf_counter()
    irf.pair_stats(r, s, bins="levels")
    elapsed = time.perf_counter() - t0
    during = ticks - before
    stop.set()
    t.join()
    # With the GIL held for the whole call the spinner would stall for `elapsed`.
    assert elapsed > 0.05
    assert during > 1000


# --- paper and real data ----------------------------------------------------------------


def test_paper_table1_arithmetic():
    v = nmi_from_entropies(6.8712, 6.4682, 11.8671)
    assert v.mi == pytest.approx(1.4723, abs=5e-5)
    assert v.value == pytest.approx(0.22074, abs=5e-5)
    assert normalize_psnr(21.072) == pytest.approx(0.7160, abs=5e-5)
    assert normalize_psnr(30) == pytest.approx(0.9, abs=1e-12)
    assert normalize_psnr(45) == pytest.approx(0.99, abs=1e-12)
    from irfidelity.normalize import psnr_curve_params

    a, k = psnr_curve_params()
    assert k == pytest.approx(math.log(2) / math.log(1.5), rel=1e-12)
    assert a == pytest.approx(18.4178, abs=1e-4)
    with pytest.raises(irf.FidelityError):
        normalize_psnr(float("nan"))


def test_real_thermal_frames():
    r = read_png16(DATA / "thermal" / "cptv_v2_frame000.png")
    s = read_png16(DATA / "thermal" / "cptv_v2_frame001.png")
    st = irf.pair_stats(r, s, bits=14, bins="levels")
    ref = exact_ref(r, s)
    assert st.mse() == float(ref["mse"])
    assert st.psnr() == pytest.approx(10 * math.log10(16383**2 / float(ref["mse"])), rel=1e-15)
    assert st.nmi().value == pytest.approx(normalized_mutual_info_score(r.ravel(), s.ravel()), abs=1e-12)
    big = read_png16(DATA / "thermal" / "flirpy_frame_000000_raw16.png")
    noisy = (big.astype(np.int64) + np.random.default_rng(0).integers(-2, 3, big.shape)).astype(np.uint16)
    st = irf.pair_stats(big, noisy, bits=16)
    assert st.mse() == float(exact_ref(big, noisy)["mse"])
    assert 0.99 < st.ssim().value <= 1.0


def test_simd_and_baseline_loops_give_identical_statistics():
    # The AVX2 copy of the loops and the baseline (SSE2) copy do the same operations in the
    # same order: their PairStats must be byte-identical. IRFIDELITY_NO_SIMD forces baseline.
    import os
    import subprocess
    import sys

    script = r"""
import sys, numpy as np, irfidelity as irf
rng = np.random.default_rng(21)
out = []
for dt in (np.uint8, np.uint16, np.int16, np.uint32, np.float16, np.float32, np.float64):
    if np.dtype(dt).kind == "f":
        r = rng.normal(1e3, 40, (300, 333)).astype(dt)
        s = (r.astype(np.float64) + rng.normal(0, 3, r.shape)).astype(dt)
        st = irf.pair_stats(r, s, peak=2e3)
    else:
        info = np.iinfo(dt)
        r = rng.integers(max(info.min, -30000), min(info.max, 60000), (300, 333)).astype(dt)
        s = np.clip(r.astype(np.int64) + rng.integers(-9, 10, r.shape), info.min, info.max).astype(dt)
        st = irf.pair_stats(r, s, bins="levels" if dt == np.uint16 else 256)
    out.append(st._raw.to_bytes().hex())
    out.append(float(irf.stats.mse(r, s)).hex())  # the SSE-only pass (explicit AVX2 for floats)
# float binning at the clamps: a narrow explicit range, values far outside it (beyond any
# int32 bin number), a run length that leaves a remainder
for dt in (np.float32, np.float64):
    r = rng.normal(0, 1, (123, 77)).astype(dt)
    r[0, :5] = [1e30, -1e30, 3e38, -3e38, 0.5]
    s = (r.astype(np.float64) * 0.5 + rng.normal(0, 0.2, r.shape)).astype(dt)
    out.append(irf.pair_stats(r, s, peak=4.0, hist_range=(-0.25, 0.25), bins=64)._raw.to_bytes().hex())
sys.stdout.write("\n".join(out))
"""
    env = dict(os.environ)
    simd = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    env["IRFIDELITY_NO_SIMD"] = "1"
    base = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    assert simd.stdout.splitlines() == base.stdout.splitlines()
    assert len(simd.stdout.splitlines()) == 16


def test_float_statistics_do_not_depend_on_the_thread_count():
    # Chunk results are combined in chunk order, however the chunks were shared between the
    # calling thread and pool helpers: one thread and all threads give byte-identical
    # PairStats (moments plan, SSE-only plan, mask and nonfinite="mask" paths).
    import os
    import subprocess
    import sys

    script = r"""
import sys, numpy as np, irfidelity as irf
rng = np.random.default_rng(8)
out = []
for dt in (np.float16, np.float32, np.float64):
    r = rng.normal(1e4, 3e3, (700, 650)).astype(dt)
    s = (r.astype(np.float64) * 0.97 + rng.normal(0, 40, r.shape)).astype(dt)
    for _ in range(3):  # repeated: the sharing of chunks differs from call to call
        out.append(irf.pair_stats(r, s, peak=2e4)._raw.to_bytes().hex())
        out.append(float(irf.stats.mse(r, s)).hex())
    mask = rng.random(r.shape) < 0.9
    out.append(irf.pair_stats(r, s, peak=2e4, mask=mask)._raw.to_bytes().hex())
    t = r.copy()
    t[::97, ::89] = np.nan
    out.append(irf.pair_stats(t, s, peak=2e4, nonfinite="mask")._raw.to_bytes().hex())
sys.stdout.write("\n".join(out))
"""
    runs = []
    for threads in ("1", str(max(2, os.cpu_count() or 2))):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        runs.append(subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True))
    one, many = (r.stdout.splitlines() for r in runs)
    assert len(one) == 24
    assert one == many


@pytest.mark.parametrize("dtype", INT_DTYPES + FLOAT_DTYPES)
def test_single_metric_fast_path_equals_the_general_path(dtype):
    # irf.stats.mse / irf.stats.psnr take plain arrays straight to the kernel; every other input goes
    # through pair_stats. Both must give the same numbers and the same errors.
    rng = np.random.default_rng(5)
    if np.dtype(dtype).kind == "f":
        r = rng.normal(100, 10, (37, 53)).astype(dtype)
        s = (r + rng.normal(0, 1, r.shape)).astype(dtype)
        peak = 200.0
    else:
        hi = min(np.iinfo(dtype).max, 60000)
        r = rng.integers(0, hi, (37, 53)).astype(dtype)
        s = rng.integers(0, hi, (37, 53)).astype(dtype)
        peak = None
    general = irf.pair_stats(r, s, need=("mse",))
    assert _core.plain_mse(r, s) == general.mse()
    assert irf.stats.mse(r, s) == general.mse()
    assert irf.stats.psnr(r, s, peak=peak) == irf.pair_stats(r, s, peak=peak, need=("psnr",)).psnr()
    # irf.stats.ssim likewise (moments only), also with exponents
    assert _core.plain_moments(r, s).moments() == irf.pair_stats(r, s, need=("ssim",))._raw.moments()
    for abg in ((1.0, 1.0, 1.0), (0.5, 2.0, 1.5)):
        expected = irf.pair_stats(r, s, need=("ssim",)).ssim(*abg)
        assert irf.stats.ssim(r, s, alpha=abg[0], beta=abg[1], gamma=abg[2]) == expected
    assert _core.plain_moments(np.asfortranarray(r), np.asfortranarray(s)) is None
    fr, fs = np.asfortranarray(r), np.asfortranarray(s)  # float sums follow the memory order
    assert irf.stats.ssim(fr, fs) == irf.pair_stats(fr, fs, need=("ssim",)).ssim()
    # not plain: Fortran order, strided views, big-endian, lists -> general path, same value
    assert _core.plain_mse(np.asfortranarray(r), np.asfortranarray(s)) is None
    assert irf.stats.mse(np.asfortranarray(r), np.asfortranarray(s)) == general.mse()
    assert irf.stats.mse(r[::2], s[::2]) == irf.pair_stats(r[::2].copy(), s[::2].copy(), need=("mse",)).mse()
    big = r.astype(r.dtype.newbyteorder(">")), s.astype(s.dtype.newbyteorder(">"))
    if r.dtype.itemsize > 1:  # one byte has no byte order
        assert _core.plain_mse(*big) is None
    assert irf.stats.mse(*big) == general.mse()
    assert _core.plain_mse(r.tolist(), s.tolist()) is None


def test_single_metric_fast_path_errors():
    r = np.zeros((4, 5), np.uint16)
    with pytest.raises(irf.errors.ShapeError, match="differ in shape"):
        irf.stats.mse(r, np.zeros((5, 4), np.uint16))
    with pytest.raises(irf.errors.ShapeError, match="differ in dtype"):
        irf.stats.mse(r, np.zeros((4, 5), np.uint8))
    with pytest.raises(irf.errors.ShapeError, match="2-D"):
        irf.stats.mse(np.zeros(5, np.uint16), np.zeros(5, np.uint16))
    f = np.ones((4, 5), np.float32)
    g = f.copy()
    g[2, 3] = np.nan
    with pytest.raises(irf.errors.RangeError):
        irf.stats.mse(f, g)
    with pytest.raises(irf.errors.RangeError, match="NaN"):
        irf.stats.ssim(f, g)
    assert irf.stats.ssim(f, g, nonfinite="mask").value == 1.0  # the NaN pair masked: identical frames
    with pytest.raises(irf.errors.ShapeError, match="differ in shape"):
        irf.stats.ssim(r, np.zeros((5, 4), np.uint16))
    with pytest.raises(irf.FidelityError, match="peak"):
        irf.stats.psnr(f, f)
    with pytest.raises(irf.FidelityError, match="peak"):
        irf.stats.psnr(f, f + 1, peak=-1.0)
    # a peak that is no number is named, not a bare ValueError from float(); "range" is psnr's
    for peak in ("range", "abc", [1, 2], True, float("nan")):
        with pytest.raises(irf.FidelityError, match="peak must be a positive finite number") as info:
            irf.pair_stats(f, f, peak=peak)
        assert info.value.option == "peak"
    with pytest.raises(irf.FidelityError, match="is for irfidelity.stats.psnr, evaluate and ScoringConfig"):
        irf.pair_stats(f, f, peak="range")
    assert irf.pair_stats(f, f, peak=np.float32(3)).peak == 3.0


def test_entropies_from_many_threads_at_once():
    # PairStats caches its entropies, computed with the GIL released: threads asking at the
    # same time must all get the value (a cache that blocks while holding the GIL would hang
    # here, so the check runs in a subprocess with a timeout).
    import subprocess
    import sys

    script = r"""
import threading, numpy as np
from irfidelity import _core
from irfidelity.stats import PairRequest
rng = np.random.default_rng(1)
r = rng.integers(0, 16384, (256, 320)).astype(np.uint16)
s = (r // 2 + rng.integers(0, 3, r.shape)).astype(np.uint16)
want = _core.pair_stats(r, s, PairRequest(sse=False, moments=False, bins=256)).entropies()
for _ in range(40):
    st = _core.pair_stats(r, s, PairRequest(sse=False, moments=False, bins=256))
    out = []
    ts = [threading.Thread(target=lambda: out.append(st.entropies())) for _ in range(4)]
    [t.start() for t in ts]
    [t.join() for t in ts]
    assert out == [want] * 4, out
print("ok")
"""
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr


@pytest.mark.parametrize("dtype", ["uint8", "uint16", "int16", "uint32", "float16", "float32", "float64"])
def test_the_real_range_is_numpys_over_the_scored_finite_pixels(dtype):
    from irfidelity.errors import ShapeError
    from irfidelity.stats import real_range

    rng = np.random.default_rng(7)
    values = rng.integers(0, 200, (300, 257)).astype(dtype)
    mask = rng.random(values.shape) < 0.7
    assert real_range(values, None, "raise") == float(values.max()) - float(values.min())
    kept = values[mask]
    assert real_range(values, mask, "raise") == float(kept.max()) - float(kept.min())
    # a view that is not C-contiguous, and a frame whose every pixel is left out
    assert real_range(values[:, ::2], None, "raise") == float(values[:, ::2].max()) - float(values[:, ::2].min())
    assert real_range(values, np.zeros_like(mask), "raise") is None
    with pytest.raises(ShapeError, match=r"mask is \(2, 2\) and the frame \(300, 257\)"):
        real_range(values, np.ones((2, 2), bool), "raise")
    if values.dtype.kind == "f":
        bad = values.copy()
        bad[5, 7], bad[250, 3] = np.nan, -np.inf
        finite = np.isfinite(bad)
        assert real_range(bad, None, "raise") is None  # the kernel reports them
        assert real_range(bad, None, "mask") == float(bad[finite].max()) - float(bad[finite].min())
        left_out = np.ones(values.shape, bool)
        left_out[5, 7] = left_out[250, 3] = False
        assert real_range(bad, left_out, "raise") == float(bad[left_out].max()) - float(bad[left_out].min())


@pytest.mark.parametrize("dtype", [np.float16, np.float32, np.float64])
def test_the_statistics_scan_gives_the_real_range_when_it_read_every_pixel(dtype):
    # float frames with moments and a histogram, no mask, every value finite: the scan's range
    # is the PSNR peak "range" (no pass of its own); otherwise the range's own pass
    from irfidelity.stats import real_range

    rng = np.random.default_rng(9)
    real = (300 + 20 * rng.random((130, 97))).astype(dtype)
    sim = (real + rng.normal(0, 0.5, real.shape)).astype(dtype)
    want = float(real.max()) - float(real.min())
    st = irf.pair_stats(real, sim, peak=1.0)
    assert st._raw.real_range == (float(real.min()), float(real.max()))
    assert real_range(real, None, "raise", st) == want
    masked = irf.pair_stats(real, sim, peak=1.0, mask=np.ones(real.shape, bool))
    without_hist = irf.pair_stats(real, sim, peak=1.0, need=("mse", "ssim"))
    bad = real.copy()
    bad[4, 4] = np.nan
    for other in (masked, without_hist, irf.pair_stats(bad, sim, peak=1.0, nonfinite="mask"), st.merge(st),
                  pickle.loads(pickle.dumps(st))):
        assert other._raw.real_range is None
    assert irf.pair_stats(real.astype(np.uint16), sim.astype(np.uint16))._raw.real_range is None
    assert real_range(real, np.ones(real.shape, bool), "raise", masked) == want
    report = irf.evaluate(real.astype(np.float64), sim.astype(np.float64), peak="range", weights="psnr=1")
    assert report.metrics["psnr_peak"] == want
