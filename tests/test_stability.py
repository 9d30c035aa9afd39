"""Stiff and extreme cases (issue 7): every case has a documented outcome — a value,
checked against an exact reference (Python ints / Fractions / mpmath on the actual
stored values), or a clear error. Never NaN, never a crash.

The outcomes are listed in docs/numerics.md ("Stiff and extreme cases").
"""

from __future__ import annotations

import math
from fractions import Fraction

import mpmath
import numpy as np
import pytest

import irfidelity as irf
from irfidelity.normalize import normalize_psnr
from irfidelity.errors import FidelityError, RangeError

mpmath.mp.dps = 60

U16 = np.uint16


# --------------------------------------------------------------------------- exact references
def _vals(a: np.ndarray) -> list:
    """The stored values as exact Python numbers (floats are dyadic rationals)."""
    return [Fraction(v) for v in np.asarray(a).ravel().tolist()]


def _mp(x: Fraction) -> mpmath.mpf:
    return mpmath.mpf(x.numerator) / x.denominator


def exact_moments(r: np.ndarray, s: np.ndarray) -> dict:
    """MSE and SSIM factors (docs/design.md §4 limits) in exact / 60-digit arithmetic."""
    R, S = _vals(r), _vals(s)
    n = len(R)
    mr, ms = sum(R) / n, sum(S) / n
    srr = sum((x - mr) ** 2 for x in R)
    sss = sum((y - ms) ** 2 for y in S)
    srs = sum((x - mr) * (y - ms) for x, y in zip(R, S))
    sse = sum((x - y) ** 2 for x, y in zip(R, S))
    den = mr * mr + ms * ms
    lum = Fraction(1) if den == 0 else 2 * mr * ms / den
    if srr == 0 and sss == 0:
        con, struct = mpmath.mpf(1), mpmath.mpf(1)
    elif srr == 0 or sss == 0:
        con, struct = mpmath.mpf(0), mpmath.mpf(0)
    else:
        root = mpmath.sqrt(_mp(srr * sss))
        con = 2 * root / _mp(srr + sss)
        struct = _mp(srs) / root
    return dict(n=n, mse=sse / n, l=_mp(lum), c=con, s=struct, mean_r=mr, mean_s=ms)


def exact_entropies(r: np.ndarray, s: np.ndarray) -> tuple:
    """H(R), H(S), H(R,S) in bits from grey-level counts (every distinct value its own bin)."""

    def h(counts) -> mpmath.mpf:
        n = sum(counts)
        return mpmath.log(n, 2) - sum(c * mpmath.log(c, 2) for c in counts) / n

    R, S = np.asarray(r).ravel().tolist(), np.asarray(s).ravel().tolist()
    from collections import Counter

    return (h(list(Counter(R).values())), h(list(Counter(S).values())), h(list(Counter(zip(R, S)).values())))


def exact_nmi(r, s) -> mpmath.mpf:
    hr, hs, hj = exact_entropies(r, s)
    if hr + hs == 0:
        return mpmath.mpf(1)
    return max(hr + hs - hj, 0) * 2 / (hr + hs)


def rel(a: float, b) -> float:
    b = _mp(b) if isinstance(b, Fraction) else mpmath.mpf(b)
    if b == 0:
        return abs(a)
    return float(abs((mpmath.mpf(a) - b) / b))


def assert_finite_metrics(st: irf.PairStats) -> dict:
    m = st.metrics()
    for k, v in m.items():
        assert not (isinstance(v, float) and math.isnan(v)), f"{k} is NaN"
    return m


def check_against_exact(r, s, *, peak=None, tol=1e-14, levels=None):
    """All of MSE, PSNR, SSIM factors and (for <= 256 distinct values) NMI vs the exact reference."""
    st = irf.pair_stats(r, s, peak=peak)
    assert_finite_metrics(st)
    ex = exact_moments(r, s)
    assert rel(st.mse(), ex["mse"]) <= tol
    if peak is not None or r.dtype.kind in "ui":
        pk = st.peak
        if ex["mse"] == 0:
            assert st.psnr() == math.inf
        else:
            ref = 20 * mpmath.log10(pk) - 10 * mpmath.log10(_mp(ex["mse"]))
            # PSNR = 20·log10(peak) − 10·log10(MSE): the rounding of the larger term bounds it
            scale = abs(20 * math.log10(pk)) + abs(10 * math.log10(float(ex["mse"])))
            assert float(abs(st.psnr() - ref)) <= 4 * tol * max(1.0, scale)
    sm = st.ssim()
    for got, want in ((sm.luminance, ex["l"]), (sm.contrast, ex["c"]), (sm.structure, ex["s"])):
        assert float(abs(got - want)) <= tol * 4, (got, want)
    if levels or len(set(np.asarray(r).ravel().tolist()) | set(np.asarray(s).ravel().tolist())) <= 256:
        # every distinct value is then its own bin for integer frames
        if r.dtype.kind in "ui":
            v = irf.stats.nmi(r, s, bins="levels")
            assert float(abs(v.value - exact_nmi(r, s))) <= 1e-13
    return st, ex


# --------------------------------------------------------------------------- constant frames
def test_constant_identical_frames():
    a = np.full((8, 8), 1234, U16)
    st = irf.pair_stats(a, a.copy(), bits=16)
    m = assert_finite_metrics(st)
    assert m["mse"] == 0.0 and m["psnr_db"] == math.inf
    assert (m["ssim_luminance"], m["ssim_contrast"], m["ssim_structure"], m["ssim"]) == (1.0, 1.0, 1.0, 1.0)
    assert (m["nmi"], m["h_real"], m["h_sim"], m["h_joint"]) == (1.0, 0.0, 0.0, 0.0)
    assert normalize_psnr(m["psnr_db"]) == 1.0


def test_two_different_constants():
    # l = 2·7·9/(49+81) exactly; both σ = 0 → c = s = 1; both constant → NMI = 1
    st = irf.pair_stats(np.full((5, 3), 7, U16), np.full((5, 3), 9, U16))
    m = assert_finite_metrics(st)
    assert m["mse"] == 4.0
    assert m["ssim_luminance"] == pytest.approx(126 / 130, rel=1e-15)
    assert (m["ssim_contrast"], m["ssim_structure"], m["nmi"]) == (1.0, 1.0, 1.0)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int16, np.uint32, np.float16, np.float32, np.float64])
def test_all_zeros(dtype):
    z = np.zeros((6, 7), dtype)
    st = irf.pair_stats(z, z.copy(), peak=1.0 if np.dtype(dtype).kind == "f" else None)
    m = assert_finite_metrics(st)
    assert m["mse"] == 0.0 and m["psnr_db"] == math.inf
    assert (m["ssim_luminance"], m["ssim_contrast"], m["ssim_structure"], m["ssim"], m["nmi"]) == (1, 1, 1, 1, 1)


@pytest.mark.parametrize("n", range(1, 40))
def test_constant_float_frame_mean_is_its_value_and_merges_stay_constant(n):
    # Σx/n of n copies of x can round an ulp away; a merge of two constant parts would then
    # see a spread (variance ~1e-32) and global SSIM without constants would drop from 1 to 0
    value, other = -4.9995625, -5.0
    real, sim = np.full((n + 1, 1), other), np.full((n + 1, 1), value)
    assert irf.pair_stats(sim[:n], sim[:n], peak=1e7).moments()["mean_real"] == value
    merged = irf.pair_stats(real[:1], sim[:1], peak=1e7).merge(irf.pair_stats(real[1:], sim[1:], peak=1e7))
    assert merged.moments()["var_sim"] == 0.0
    assert merged.ssim().contrast == 1.0


def test_one_frame_constant_the_other_not():
    r = np.full((4, 4), 7, U16)
    s = np.arange(16, dtype=U16).reshape(4, 4)
    st, ex = check_against_exact(r, s)
    sm = st.ssim()
    assert sm.contrast == 0.0 and sm.structure == 0.0 and sm.value == 0.0
    nm = st.nmi()
    assert nm.value == 0.0 and nm.h_real == 0.0 and nm.h_sim == 4.0
    # and the other way round
    sm2 = irf.stats.ssim(s, r)
    assert (sm2.contrast, sm2.structure) == (0.0, 0.0)
    assert irf.stats.nmi(s, r).value == 0.0


# --------------------------------------------------------------------------- tiny shapes
@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (9, 1), (1, 1000), (1000, 1)])
def test_degenerate_shapes(shape):
    rng = np.random.default_rng(sum(shape))
    r = rng.integers(0, 4096, size=shape).astype(U16)
    s = rng.integers(0, 4096, size=shape).astype(U16)
    check_against_exact(r, s, tol=4e-16, levels=True)
    # the same pair transposed gives the same statistics (1×N vs N×1)
    a, b = irf.pair_stats(r, s).metrics(), irf.pair_stats(r.T.copy(), s.T.copy()).metrics()
    assert a == pytest.approx(b, rel=1e-15, abs=1e-15)


def test_one_by_one_values():
    st = irf.pair_stats(np.array([[3]], U16), np.array([[5]], U16))
    m = assert_finite_metrics(st)
    assert m["mse"] == 4.0
    assert m["ssim_luminance"] == pytest.approx(30 / 34, rel=1e-15)
    assert (m["ssim_contrast"], m["ssim_structure"], m["nmi"]) == (1.0, 1.0, 1.0)


def test_empty_and_fully_masked_are_clear_errors():
    z = np.zeros((3, 3), U16)
    st = irf.pair_stats(z, z, mask=np.zeros((3, 3), bool))
    assert st.n == 0 and st.metrics() == {"n": 0}
    for f in (st.mse, st.ssim, st.nmi):
        with pytest.raises(FidelityError, match="no pixel pairs"):
            f()
    e = np.zeros((0, 5), U16)
    with pytest.raises(FidelityError):
        irf.stats.mse(e, e)


# --------------------------------------------------------------------------- 16-bit extremes
def test_16bit_at_65535_one_lsb():
    r = np.full((4, 4), 65535, U16)
    s = r.copy()
    s[2, 3] = 65534
    st, ex = check_against_exact(r, s, tol=4e-16)
    m = st.metrics()
    assert m["mse"] == 1 / 16
    assert m["psnr_db"] == pytest.approx(20 * math.log10(65535) + 10 * math.log10(16), rel=1e-15)
    # l = 1 − (1/16)²/(μr²+μs²) ≈ 1 − 4.5e-13: representable, must not round to 1
    assert 0 < 1 - m["ssim_luminance"] < 1e-12
    assert abs(m["ssim_contrast"]) < 1e-15  # exactly 0: see test_contrast_exactly_zero_with_one_constant_frame
    assert (m["ssim_structure"], m["nmi"]) == (0.0, 0.0)


def test_saturated_halves_zero_vs_65535():
    r = np.zeros((6, 8), U16)
    r[:, 4:] = 65535
    s = 65535 - r
    st, ex = check_against_exact(r, s, tol=0)
    m = st.metrics()
    assert m["mse"] == 65535.0**2 and m["psnr_db"] == 0.0
    assert (m["ssim_luminance"], m["ssim_contrast"], m["ssim_structure"], m["ssim"]) == (1.0, 1.0, -1.0, -1.0)
    assert m["nmi"] == 1.0  # one-to-one grey-level relation (a negative), not equality
    assert st.int_sums()["sum_cross"] == 0


def test_exact_4096_square_near_65535_one_lsb():
    """4096² frames at the top of the 16-bit range differing by 1 LSB on a pattern:
    every sum is exact (checked with Python ints), the metrics are the exact values rounded."""
    rng = np.random.default_rng(7)
    n = 4096
    r = (np.frombuffer(rng.bytes(2 * n * n), U16).reshape(n, n) | U16(0xFFF0)).copy()  # 65520..65535
    flip = np.frombuffer(rng.bytes(n * n), np.uint8).reshape(n, n) < 37
    s = r.copy()
    s[flip & (r > 65520)] -= 1
    st = irf.pair_stats(r, s, bits=16, bins="levels")
    sums = st.int_sums()
    # references: counts per value (bincount) times the value, in Python ints — no overflow possible
    cr = np.bincount(r.ravel(), minlength=65536)
    cs = np.bincount(s.ravel(), minlength=65536)
    v = np.arange(65536)
    ref_r = sum(int(c) * x for c, x in zip(cr[65520:], range(65520, 65536)))
    ref_s = sum(int(c) * x for c, x in zip(cs[65519:], range(65519, 65536)))
    assert sums["sum_real"] == ref_r and sums["sum_sim"] == ref_s
    assert sums["sum_real_sq"] == sum(int(c) * x * x for c, x in zip(cr[65520:], range(65520, 65536)))
    assert sums["sum_sim_sq"] == sum(int(c) * x * x for c, x in zip(cs[65519:], range(65519, 65536)))
    d = int(np.count_nonzero(r != s))
    assert sums["sse"] == d  # every difference is exactly 1
    # cross: Σ r·s = Σ r² − Σ_{changed} r  (s = r − 1 there)
    changed = r[r != s].astype(np.int64)
    assert sums["sum_cross"] == sums["sum_real_sq"] - int(changed.sum())
    N = n * n
    assert st.mse() == float(Fraction(d, N))  # correctly rounded
    # SSIM factors from the exact integers
    a, b = Fraction(sums["sum_real"], N), Fraction(sums["sum_sim"], N)
    srr = sums["sum_real_sq"] - Fraction(sums["sum_real"] ** 2, N)
    sss = sums["sum_sim_sq"] - Fraction(sums["sum_sim"] ** 2, N)
    srs = sums["sum_cross"] - Fraction(sums["sum_real"] * sums["sum_sim"], N)
    sm = st.ssim()
    assert rel(sm.luminance, _mp(2 * a * b / (a * a + b * b))) < 1e-15
    root = mpmath.sqrt(_mp(srr * sss))
    assert rel(sm.contrast, 2 * root / _mp(srr + sss)) < 1e-14
    assert rel(sm.structure, _mp(srs) / root) < 1e-14
    # NMI (levels) against entropies from exact counts
    joint = np.bincount(((r.astype(np.int64) - 65519) * 17 + (s.astype(np.int64) - 65519)).ravel())

    def h(c):
        c = [int(x) for x in c if x]
        return mpmath.log(N, 2) - sum(x * mpmath.log(x, 2) for x in c) / N

    hr, hs, hj = h(cr), h(cs), h(joint)
    nm = st.nmi()
    assert abs(nm.h_real - hr) < 1e-13 and abs(nm.h_sim - hs) < 1e-13 and abs(nm.h_joint - hj) < 1e-13
    assert abs(nm.value - 2 * (hr + hs - hj) / (hr + hs)) < 1e-13
    del v


def test_exact_8192_square_uint16_at_scale():
    """8192² uint16 (2^26 pixels): Σx² reaches 2^58, beyond float64's 53 bits. The kernel's
    integer sums must equal int64 references (2^26·(2^16)² = 2^58 < 2^63: no overflow)."""
    rng = np.random.default_rng(8192)
    n = 8192
    r = np.frombuffer(rng.bytes(2 * n * n), U16).reshape(n, n)
    s = np.frombuffer(rng.bytes(2 * n * n), U16).reshape(n, n) | U16(0x8000)
    st = irf.pair_stats(r, s, bits=16, need=("mse", "ssim"))
    sums = st.int_sums()
    assert sums["sum_real"] == int(r.sum(dtype=np.int64))
    assert sums["sum_sim"] == int(s.sum(dtype=np.int64))
    acc = dict(rr=0, ss=0, rs=0, sse=0)
    step = 1024  # chunks keep the int64 temporaries at 64 MB
    for i in range(0, n, step):
        a = r[i : i + step].astype(np.int64)
        b = s[i : i + step].astype(np.int64)
        acc["rr"] += int(np.einsum("ij,ij->", a, a))
        acc["ss"] += int(np.einsum("ij,ij->", b, b))
        acc["rs"] += int(np.einsum("ij,ij->", a, b))
        a -= b
        acc["sse"] += int(np.einsum("ij,ij->", a, a))
        del a, b
    assert sums["sum_real_sq"] == acc["rr"]
    assert sums["sum_sim_sq"] == acc["ss"]
    assert sums["sum_cross"] == acc["rs"]
    assert sums["sse"] == acc["sse"]
    assert st.mse() == float(Fraction(acc["sse"], n * n))
    # a float64 one-pass sum would not be exact here: show that the check has teeth
    assert acc["rr"] > 2**53


# --------------------------------------------------------------------------- float cancellation
def test_float32_at_1e6_offset_sigma_1e2():
    """float32 around 1e6 (ulp 0.0625) with σ ≈ 1e-2: a few pixels one ulp off the offset.
    E[x²] − E[x]² in float32 loses everything; contrast/structure must match the exact
    values (computed on the actual float32 values) to 1e-9."""
    rng = np.random.default_rng(1)
    shape = (256, 256)
    base = np.float32(1e6)
    ulp = float(np.spacing(base))
    assert ulp == 0.0625
    kr = (rng.random(shape) < 0.0263).astype(np.int64)  # 0 or +1 ulp above the offset
    ks = np.where(rng.random(shape) < 0.8, kr, (rng.random(shape) < 0.0263).astype(np.int64))
    r = (base + kr * ulp).astype(np.float32)
    s = (base + ks * ulp).astype(np.float32)
    assert 0.008 < float(np.std(r.astype(np.float64))) < 0.012
    # exact reference via integer ulp counts (the values are exactly 1e6 + k/16)
    assert np.array_equal((r.astype(np.float64) - 1e6) * 16, kr)
    n = r.size
    sr, ss = int(kr.sum()), int(ks.sum())
    srr = Fraction(int((kr * kr).sum()) * n - sr * sr, n)
    sss = Fraction(int((ks * ks).sum()) * n - ss * ss, n)
    srs = Fraction(int((kr * ks).sum()) * n - sr * ss, n)
    root = mpmath.sqrt(_mp(srr * sss))
    c_ref, s_ref = 2 * root / _mp(srr + sss), _mp(srs) / root
    sm = irf.stats.ssim(r, s)
    assert abs(sm.contrast - c_ref) < 1e-9
    assert abs(sm.structure - s_ref) < 1e-9
    mr, ms = Fraction(10**6) + Fraction(sr, 16 * n), Fraction(10**6) + Fraction(ss, 16 * n)
    assert rel(sm.luminance, _mp(2 * mr * ms / (mr * mr + ms * ms))) < 1e-15
    mse_ref = Fraction(int(((kr - ks) ** 2).sum()), 256 * n)
    assert rel(irf.stats.mse(r, s), _mp(mse_ref)) < 1e-15
    # the naive float32 one-pass formula is useless here (documented in docs/numerics.md)
    r32 = r.ravel()
    naive = np.mean(r32 * r32, dtype=np.float32) - np.mean(r32, dtype=np.float32) ** 2
    assert abs(float(naive) - float(_mp(srr) / n)) > 1e-3


def test_float32_near_max_squares_overflow_f32():
    """Values near ±3e38: squares overflow float32 (and sums of squares ~1e77 are fine in
    float64). The result is right (vs Fractions) — never inf/NaN."""
    f = np.float32
    r = np.array([[3e38, -3e38, 1e38], [2e38, -1.5e38, 3.4e38]], f)
    s = np.array([[-3e38, 3e38, 2e38], [1e38, -3.4e38, 0.5e38]], f)
    check_against_exact(r, s, peak=float(np.finfo(f).max), tol=1e-15)
    # exact extremes: ±max
    m = np.finfo(f).max
    st = irf.pair_stats(np.array([[m, -m]], f), np.array([[-m, m]], f), peak=float(m))
    out = assert_finite_metrics(st)
    assert out["ssim_structure"] == -1.0 and out["ssim_contrast"] == 1.0
    assert out["psnr_db"] == pytest.approx(-20 * math.log10(2), rel=1e-12)


def test_masked_path_near_max_keeps_the_mean():
    """With a mask (or nonfinite="mask") chunks are centred on their own means and the pivot is
    the first counted value: ±3e38 data whose mean is ~1e35 used to lose ten digits of the
    mean there (luminance off by 1.5e-14 relative). Several chunks, so merges happen."""
    rng = np.random.default_rng(11)
    r = rng.uniform(-3e38, 3e38, (300, 700)).astype(np.float32)
    s = np.clip(r.astype(np.float64) * 0.9 + rng.normal(0, 3e37, r.shape), -3.4e38, 3.4e38).astype(np.float32)
    mask = np.ones(r.shape, bool)
    mask[::7, ::3] = False
    st = irf.pair_stats(r, s, peak=float(np.finfo(np.float32).max), mask=mask)
    ex = exact_moments(r[mask], s[mask])
    sm = st.ssim()
    assert rel(sm.luminance, ex["l"]) < 1e-15
    assert rel(sm.contrast, ex["c"]) < 1e-15
    assert rel(sm.structure, ex["s"]) < 2e-15
    assert rel(st.mse(), ex["mse"]) < 1e-15


def test_float64_whose_sums_overflow_is_a_clear_range_error():
    r = np.array([[1e300, -1e300], [5e299, 1e299]])
    s = np.array([[-1e300, 1e300], [1e299, 5e299]])
    try:
        st = irf.pair_stats(r, s, peak=1.7e308)
    except RangeError as exc:
        assert "too large" in str(exc) and "rescale" in str(exc)
    else:  # a future core may handle it: then it must be right
        ex = exact_moments(r, s)
        assert rel(st.mse(), ex["mse"]) < 1e-14
        assert abs(st.ssim().structure - ex["s"]) < 1e-14


def test_float32_subnormals():
    f = np.float32
    tiny = float(np.finfo(f).smallest_subnormal)
    r = (np.array([[1, 2, 3], [0, 7, 5]], np.float64) * tiny).astype(f)
    s = (np.array([[2, 1, 0], [3, 5, 7]], np.float64) * tiny).astype(f)
    assert np.all(r[r != 0] < np.finfo(f).tiny)
    check_against_exact(r, s, peak=8 * tiny, tol=1e-15)
    st = irf.pair_stats(r, s, peak=8 * tiny, bins=8)
    assert st.nmi().h_real > 2  # six distinct values, not "constant"


def test_float16_against_exact():
    rng = np.random.default_rng(16)
    r = rng.normal(1000, 30, (20, 20)).astype(np.float16)
    s = (r.astype(np.float64) + rng.normal(0, 5, (20, 20))).astype(np.float16)
    check_against_exact(r, s, peak=65504.0, tol=1e-14)


def test_float64_subnormals_are_a_clear_error():
    # Every square of a subnormal underflows in float64, so MSE would read 0 and different
    # frames would look identical: documented outcome is a RangeError asking to rescale.
    tiny = 5e-324
    r = np.array([[tiny, 2 * tiny]])
    s = np.array([[2 * tiny, tiny]])
    with pytest.raises(irf.errors.RangeError, match="rescale"):
        irf.pair_stats(r, s, peak=1e-300)
    # the PSNR-only pass checks too (it looks for the largest value only when the squares
    # sum to almost nothing), also on frames long enough for the vector loop
    big_r, big_s = np.tile(r, (40, 50)), np.tile(s, (40, 50))
    for a, b in ((r, s), (big_r, big_s)):
        with pytest.raises(irf.errors.RangeError, match="rescale"):
            irf.stats.mse(a, b)
    # identical normal frames: squares sum to 0, no error
    assert irf.stats.mse(np.ldexp(big_r, 1100), np.ldexp(big_r, 1100)) == 0.0
    # rescaled by an exact power of two, the same frames are fine and exact
    st = irf.pair_stats(np.ldexp(r, 1100), np.ldexp(s, 1100), peak=1.0)
    m = st.metrics()
    assert m["psnr_db"] != math.inf
    assert m["ssim_structure"] == -1.0
    assert m["h_real"] == 1.0
    # float32 subnormals are fine: their squares are normal float64 numbers
    r32 = np.array([[1e-45, 3e-45]], np.float32)
    st32 = irf.pair_stats(r32, r32[:, ::-1].copy(), peak=1e-38)
    assert st32.mse() > 0 and st32.ssim().structure == -1.0


# --------------------------------------------------------------------------- NaN / Inf
def test_nonfinite_raise_names_count_and_position():
    r = np.ones((4, 5), np.float32)
    s = np.ones((4, 5), np.float32)
    r[1, 3] = np.nan
    r[2, 0] = np.inf
    s[3, 4] = -np.inf
    with pytest.raises(RangeError) as exc:
        irf.pair_stats(r, s, peak=1.0)
    msg = str(exc.value)
    assert "2 in the real frame" in msg and "1 in the simulated frame" in msg
    assert "row 1, col 3" in msg and "nonfinite='mask'" in msg
    for f in (irf.stats.mse, irf.stats.ssim):
        with pytest.raises(RangeError):
            f(r, s)


def test_nonfinite_mask_excludes_pairs_and_counts_them():
    rng = np.random.default_rng(3)
    r = rng.normal(size=(10, 10))
    s = r + rng.normal(scale=0.1, size=(10, 10))
    r2, s2 = r.copy(), s.copy()
    r2[0, 0], r2[5, 5], s2[5, 5], s2[9, 1] = np.nan, np.inf, np.nan, -np.inf
    st = irf.pair_stats(r2, s2, peak=10.0, nonfinite="mask")
    assert st.n == 97 and st.nonfinite == 3
    keep = np.isfinite(r2) & np.isfinite(s2)
    ref = irf.pair_stats(r, s, peak=10.0, mask=keep)
    assert st.mse() == pytest.approx(ref.mse(), rel=1e-15)
    assert st.ssim().value == pytest.approx(ref.ssim().value, rel=1e-14)
    ex = exact_moments(r[keep], s[keep])
    assert rel(st.mse(), ex["mse"]) < 1e-14
    # everything non-finite: a clear error, not NaN
    nan = np.full((2, 2), np.nan)
    st0 = irf.pair_stats(nan, nan, peak=1.0, nonfinite="mask")
    assert st0.n == 0 and st0.nonfinite == 4
    with pytest.raises(FidelityError, match="no pixel pairs"):
        st0.ssim()


def test_negative_floats():
    rng = np.random.default_rng(4)
    r = -np.abs(rng.normal(50, 20, (16, 16)))
    s = r * 0.9 - 3
    check_against_exact(r, s, peak=100.0, tol=1e-14)
    # means of opposite sign: luminance is negative (eq. 11), SSIM stays in [-1, 1]
    sm = irf.stats.ssim(r, -r)
    assert sm.luminance == -1.0 and sm.structure == -1.0 and -1 <= sm.value <= 1


# --------------------------------------------------------------------------- SSIM sign handling
@pytest.mark.parametrize("gamma", [0.5, 1 / 3, 0.75, 1.5, 2.0])
def test_anticorrelated_fractional_gamma_is_sign_preserving(gamma):
    r = np.arange(64, dtype=U16).reshape(8, 8)
    s = (63 - r).astype(U16)  # same mean, s = −1 exactly
    sm = irf.stats.ssim(r, s, gamma=gamma)
    assert (sm.luminance, sm.contrast, sm.structure) == (1.0, 1.0, -1.0)
    assert sm.value == -1.0  # sign(s)·|s|^γ = −1 for every γ, even γ = 2 (docs/design.md §4)
    # partially anti-correlated: value = −|s|^γ, real and finite
    rng = np.random.default_rng(5)
    noisy = np.clip(s.astype(np.int64) + rng.integers(-20, 21, s.shape), 0, 200).astype(U16)
    st, ex = check_against_exact(r, noisy)
    v = irf.stats.ssim(r, noisy, gamma=gamma)
    want = ex["l"] * ex["c"] * (-(abs(ex["s"]) ** gamma))
    assert ex["s"] < 0 and abs(v.value - want) < 1e-13


# l and c are formed as 2ab/(a² + b²) and 2·sqrt(var_r·var_s)/(var_r + var_s): exact at
# equality, and no cancellation when the factor is small.


def test_contrast_exactly_zero_with_one_constant_frame():
    r = np.full((4, 4), 65535, U16)
    s = r.copy()
    s[2, 3] = 65534
    sm = irf.stats.ssim(r, s)
    assert sm.contrast == 0.0 and sm.structure == 0.0


def test_small_luminance_and_contrast_keep_relative_accuracy():
    # means 1.25 vs 1.25e9: l = 2e-9 (to 1e-16 relative with the direct formula)
    r = np.array([[1, 1], [1, 2]], np.uint32)
    s = r * np.uint32(10**9)
    ex = exact_moments(r, s)
    sm = irf.stats.ssim(r, s)
    assert rel(sm.luminance, ex["l"]) < 1e-14
    r = np.array([[0, 1], [0, 1]], np.uint32)
    s = r * np.uint32(10**8)
    ex = exact_moments(r, s)
    assert rel(irf.stats.ssim(r, s).contrast, ex["c"]) < 1e-14


# --------------------------------------------------------------------------- curves
def test_curve_rho_minus_one():
    x = np.linspace(0, 1, 20)
    cs = irf.curves.curve_similarity(irf.Curve(x, x), irf.Curve(x, 1 - x), a=1.0, b=1.0)
    assert cs.rho == pytest.approx(-1.0, abs=1e-15)
    assert cs.value == pytest.approx(1.0, abs=1e-15)  # eq. 3 uses |rho|
    assert 0 <= cs.value <= 1


def test_flat_curves():
    x = np.linspace(0, 1, 10)
    both = irf.curves.curve_similarity(irf.Curve(x, np.ones(10)), irf.Curve(x, 2 * np.ones(10)), a=0.0, b=0.0)
    assert (both.rho, both.mu, both.value) == (1.0, 1.0, 1.0)
    one = irf.curves.curve_similarity(irf.Curve(x, np.ones(10)), irf.Curve(x, x), a=0.3, b=0.3)
    assert (one.rho, one.value) == (0.0, 0.0)
    with pytest.raises(FidelityError, match="flat"):
        irf.curves.sitf_fit(irf.Curve(x, np.full(10, 5.0)))


def test_mtf_that_never_reaches_half_is_an_error():
    c = irf.Curve(np.linspace(0, 0.7, 8), np.linspace(1.0, 0.65, 8))
    with pytest.raises(FidelityError, match="never falls to 0.5"):
        irf.curves.mtf50(c)
    with pytest.raises(FidelityError, match="never falls to 0.5"):
        irf.curves.mtf50(c, smooth=True)


def test_sitf_with_no_linear_region():
    x = np.arange(12.0)
    step = np.where(x < 6, 100.0, 16383.0)  # floor then saturation, no points in between
    with pytest.raises(FidelityError, match="no linear region"):
        irf.curves.sitf_fit(irf.Curve(x, step))
    with pytest.raises(FidelityError, match="flat"):  # saturated everywhere
        irf.curves.sitf_fit(irf.Curve(x, np.full(12, 16383.0)))


def test_two_point_curves_are_a_clear_error():
    with pytest.raises(FidelityError, match="at least 3 points"):
        irf.Curve([0.0, 1.0], [1.0, 0.0])
    # three points is the minimum, and works
    assert irf.curves.mtf50(irf.Curve([0.0, 1.0, 2.0], [1.0, 0.6, 0.2])) == pytest.approx(1.25)


def test_float32_means_near_the_largest_float_are_exact_to_rounding():
    """Float32 values spread over ±3e38 cancel in the mean: the unmasked pass rounds the mean
    once from its compensated sums (it was 1e-14 off when a plainly summed residual was added)."""
    rng = np.random.default_rng(0)
    real = rng.uniform(-3e38, 3e38, (128, 128)).astype(np.float32)
    sim = np.clip(real.astype(np.float64) * 0.9 + rng.normal(0, 3e37, real.shape), -3.4e38, 3.4e38).astype(np.float32)
    for mask in (None, np.ones(real.shape, dtype=bool)):
        m = irf.pair_stats(real, sim, peak=float(np.finfo(np.float32).max), mask=mask).moments()
        for got, frame in ((m["mean_real"], real), (m["mean_sim"], sim)):
            exact = sum(Fraction(float(v)) for v in frame.ravel()) / frame.size
            assert abs(Fraction(got) - exact) <= abs(exact) * Fraction(2) ** -52
