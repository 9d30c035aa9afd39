"""Property tests (hypothesis): symmetry, identity → 1, bounds, merge = concatenation,
layout independence, and agreement with scikit-learn / numpy.histogram2d NMI."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import irfidelity as irf

sklearn_metrics = pytest.importorskip("sklearn.metrics")

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])

INT_DTYPES = (np.uint8, np.uint16, np.int16, np.uint32)
FLOAT_DTYPES = (np.float16, np.float32, np.float64)


@st.composite
def int_pair(draw, dtype=None, min_side=1, max_side=24):
    dtype = np.dtype(draw(st.sampled_from(INT_DTYPES)) if dtype is None else dtype)
    info = np.iinfo(dtype)
    h = draw(st.integers(min_side, max_side))
    w = draw(st.integers(min_side, max_side))
    lo = draw(st.integers(int(info.min), int(info.max)))
    span = draw(st.sampled_from([0, 1, 3, 15, 255, 4095, 65535, int(info.max) - int(info.min)]))
    hi = min(int(info.max), lo + span)
    elems = st.integers(lo, hi)
    r = draw(hnp.arrays(dtype, (h, w), elements=elems))
    s = draw(hnp.arrays(dtype, (h, w), elements=elems))
    return r, s


@st.composite
def float_pair(draw, min_side=1, max_side=24):
    dtype = np.dtype(draw(st.sampled_from(FLOAT_DTYPES)))
    h = draw(st.integers(min_side, max_side))
    w = draw(st.integers(min_side, max_side))
    scale = draw(st.sampled_from([1e-3, 1.0, 1e3] + ([1e6] if dtype.itemsize > 2 else [])))
    offset = draw(st.sampled_from([0.0, -5.0, 1e3]))
    elems = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False, width=32)
    r = (draw(hnp.arrays(np.float64, (h, w), elements=elems)) * scale + offset).astype(dtype)
    s = (draw(hnp.arrays(np.float64, (h, w), elements=elems)) * scale + offset).astype(dtype)
    assume(np.isfinite(r).all() and np.isfinite(s).all())
    return r, s


def _peak(a):
    return 1e7 if a.dtype.kind == "f" else None


def _no_nan(m: dict):
    for k, v in m.items():
        assert not (isinstance(v, float) and math.isnan(v)), k


# --------------------------------------------------------------------------- symmetry
@SETTINGS
@given(st.one_of(int_pair(), float_pair()))
def test_symmetry(pair):
    r, s = pair
    # shared edges: the default binning takes the real frame as the reference, not symmetric
    a = irf.pair_stats(r, s, peak=_peak(r), hist_range="data")
    b = irf.pair_stats(s, r, peak=_peak(r), hist_range="data")
    assert a.mse() == b.mse()
    sa, sb = a.ssim(), b.ssim()
    if r.dtype.kind in "ui":  # exact sums: bit-identical
        assert sa == sb
    else:
        assert sa.value == pytest.approx(sb.value, rel=1e-13, abs=1e-14)
    na, nb = a.nmi(), b.nmi()
    assert (na.h_real, na.h_sim) == (nb.h_sim, nb.h_real)
    assert na.value == pytest.approx(nb.value, rel=1e-12, abs=1e-13)


# --------------------------------------------------------------------------- identity
@SETTINGS
@given(st.one_of(int_pair(), float_pair()))
def test_identity_is_one(pair):
    r, _ = pair
    stt = irf.pair_stats(r, r.copy(), peak=_peak(r))
    m = stt.metrics()
    _no_nan(m)
    assert m["mse"] == 0.0 and m["psnr_db"] == math.inf
    assert (m["ssim_luminance"], m["ssim_contrast"], m["ssim_structure"], m["ssim"]) == (1.0, 1.0, 1.0, 1.0)
    assert m["nmi"] == 1.0
    if r.dtype.kind in "ui":
        assert irf.stats.nmi(r, r.copy(), bins="levels").value == 1.0


# --------------------------------------------------------------------------- bounds
@SETTINGS
@given(st.one_of(int_pair(), float_pair()), st.sampled_from([1, 2, 16, 256, 1000]))
def test_bounds(pair, bins):
    r, s = pair
    stt = irf.pair_stats(r, s, peak=_peak(r), bins=bins)
    m = stt.metrics()
    _no_nan(m)
    assert m["mse"] >= 0
    assert -1 <= m["ssim_luminance"] <= 1 and -1 <= m["ssim_structure"] <= 1
    assert 0 <= m["ssim_contrast"] <= 1
    assert -1 <= m["ssim"] <= 1
    assert 0 <= m["nmi"] <= 1 and m["mi"] >= 0
    eps = 1e-12
    assert m["h_real"] >= 0 and m["h_sim"] >= 0
    assert m["h_joint"] >= max(m["h_real"], m["h_sim"]) - eps
    assert m["h_joint"] <= m["h_real"] + m["h_sim"] + eps
    assert m["h_joint"] <= math.log2(stt.n) + eps


# --------------------------------------------------------------------------- merge
@SETTINGS
@given(int_pair(dtype=np.uint16, max_side=16), st.integers(1, 15), st.sampled_from([256, 64, "levels"]))
def test_merge_equals_concatenation_integer(pair, cut, bins):
    r, s = pair
    assume(r.shape[0] >= 2)
    cut = min(cut, r.shape[0] - 1)
    rng = "full" if bins != "levels" else "data"
    whole = irf.pair_stats(r, s, bits=16, bins=bins, hist_range=rng)
    top = irf.pair_stats(r[:cut], s[:cut], bits=16, bins=bins, hist_range=rng)
    bot = irf.pair_stats(r[cut:], s[cut:], bits=16, bins=bins, hist_range=rng)
    merged = top.merge(bot)
    assert merged.n == whole.n
    assert merged.int_sums() == whole.int_sums()
    assert merged.metrics() == whole.metrics()  # exact: same integers, same counts


@SETTINGS
@given(float_pair(max_side=16), st.integers(1, 15))
def test_merge_equals_concatenation_float(pair, cut):
    r, s = pair
    assume(r.shape[0] >= 2)
    cut = min(cut, r.shape[0] - 1)
    edges = (-2e6, 2e6)
    whole = irf.pair_stats(r, s, peak=1e7, hist_range=edges)
    merged = irf.pair_stats(r[:cut], s[:cut], peak=1e7, hist_range=edges).merge(
        irf.pair_stats(r[cut:], s[cut:], peak=1e7, hist_range=edges)
    )
    a, b = whole.metrics(), merged.metrics()
    assert a["n"] == b["n"]
    # the Chan merge forms the difference of the parts' means: its rounding is relative to the
    # offset, so the tolerance scales with |mean|/σ (docs/numerics.md, "float frames")
    r64, s64 = r.astype(np.float64), s.astype(np.float64)
    sd = min(r64.std(), s64.std())
    big = max(np.abs(r64).max(), np.abs(s64).max(), 1e-300)
    cond = 1.0 if sd == 0 else max(1.0, big / sd)
    for k in a:
        tol = 1e-13 * cond if k.startswith("ssim") else 1e-12
        assert b[k] == pytest.approx(a[k], rel=tol, abs=tol), k


# --------------------------------------------------------------------------- layout
@SETTINGS
@given(st.one_of(int_pair(min_side=2), float_pair(min_side=2)))
def test_layout_independence(pair):
    r, s = pair
    pk = _peak(r)
    ref = irf.pair_stats(r, s, peak=pk).metrics()
    # Fortran order
    f = irf.pair_stats(np.asfortranarray(r), np.asfortranarray(s), peak=pk).metrics()
    # strided views into bigger arrays, and a C frame paired with a Fortran one
    big_r = np.zeros((2 * r.shape[0], 3 * r.shape[1]), r.dtype)
    big_s = np.zeros_like(big_r)
    big_r[::2, ::3], big_s[::2, ::3] = r, s
    v = irf.pair_stats(big_r[::2, ::3], big_s[::2, ::3], peak=pk).metrics()
    mixed = irf.pair_stats(r, np.asfortranarray(s), peak=pk).metrics()
    # transposed view of a transposed copy (negative/odd strides)
    tt = irf.pair_stats(r.T.copy().T, s[::-1].copy()[::-1], peak=pk).metrics()
    for other in (f, v, mixed, tt):
        if r.dtype.kind in "ui":
            assert other == ref
        else:  # float sums may add in another order: agree to rounding
            assert other.keys() == ref.keys()
            for k in ref:
                assert other[k] == pytest.approx(ref[k], rel=1e-12, abs=1e-13), k


# --------------------------------------------------------------------------- peers
@SETTINGS
@given(int_pair(max_side=32))
def test_levels_nmi_equals_sklearn(pair):
    r, s = pair
    got = irf.stats.nmi(r, s, bins="levels")
    ref = sklearn_metrics.normalized_mutual_info_score(r.ravel(), s.ravel(), average_method="arithmetic")
    # sklearn returns 1.0 when both labelings are constant, and so does irfidelity (docs/design.md §4);
    # when exactly one is constant sklearn's MI is 0 → 0, as ours.
    assert got.value == pytest.approx(ref, abs=1e-12)


def _hist2d_nmi(r, s, edges):
    h, _, _ = np.histogram2d(r.ravel().astype(np.float64), s.ravel().astype(np.float64), bins=[edges, edges])
    n = h.sum()

    def ent(c):
        c = c[c > 0]
        return math.log2(n) - float(np.sum(c * np.log2(c))) / n

    hr, hs, hj = ent(h.sum(1)), ent(h.sum(0)), ent(h.ravel())
    if hr + hs < 1e-12:  # both constant (log2 n − n·log2 n / n rounds to ±eps, not 0)
        return 1.0
    return max(hr + hs - hj, 0) * 2 / (hr + hs)


@SETTINGS
@given(int_pair(max_side=32), st.sampled_from([1, 2, 3, 7, 16, 64, 256, 1000]))
def test_binned_nmi_equals_histogram2d_with_integer_level_edges(pair, bins):
    r, s = pair
    lo = int(min(r.min(), s.min()))
    hi = int(max(r.max(), s.max()))
    levels = hi - lo + 1
    width = -(-levels // bins)  # ceil(span / bins) whole grey levels, starting at the data min
    nb = -(-levels // width)
    edges = lo - 0.5 + width * np.arange(nb + 1, dtype=np.float64)
    got = irf.stats.nmi(r, s, bins=bins, hist_range="data")
    assert got.value == pytest.approx(_hist2d_nmi(r, s, edges), abs=1e-12)
    if levels <= bins:  # a pair spanning at most `bins` levels is binned exactly
        assert got.value == pytest.approx(irf.stats.nmi(r, s, bins="levels").value, abs=1e-15)


@SETTINGS
@given(int_pair(max_side=32), st.integers(-3000, 3000), st.sampled_from([3, 16, 256]))
def test_an_offset_reads_nmi_one_on_the_default_binning(pair, offset, bins):
    """The default bins lock the simulated frame's edges to the real frame's by the offset."""
    r, _ = pair
    info = np.iinfo(r.dtype)
    s = r.astype(np.int64) + offset
    assume(s.min() >= info.min and s.max() <= info.max)
    assert irf.stats.nmi(r, s.astype(r.dtype), bins=bins).value == 1.0


@SETTINGS
@given(float_pair(max_side=24), st.sampled_from([2, 16, 256]))
def test_float_binned_nmi_equals_histogram2d(pair, bins):
    r, s = pair
    r64, s64 = r.astype(np.float64), s.astype(np.float64)
    lo, hi = float(min(r64.min(), s64.min())), float(max(r64.max(), s64.max()))
    assume(hi > lo)
    edges = np.linspace(lo, hi, bins + 1)
    # values sitting exactly on an interior edge may fall either side by one rounding: skip those
    width = (hi - lo) / bins
    pos = np.concatenate([(r64.ravel() - lo) / width, (s64.ravel() - lo) / width])
    frac = np.abs(pos - np.round(pos))
    assume(not np.any((frac < 1e-9) & (np.round(pos) > 0) & (np.round(pos) < bins)))
    got = irf.stats.nmi(r, s, bins=bins, hist_range="data")
    assert got.value == pytest.approx(_hist2d_nmi(r64, s64, edges), abs=1e-12)
