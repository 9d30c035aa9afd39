"""The Rust binding (`irfidelity._core`) at its edges: arrays numpy may hand over in any
layout, argument values out of range, the kernel request, and the error classes."""

from __future__ import annotations

import numpy as np
import pytest

import irfidelity as irf
from irfidelity import _core
from irfidelity.errors import FidelityError, FrameError, RangeError, ShapeError
from irfidelity.frames import FRAME_DTYPES
from irfidelity.sequence.plan import SequenceRequest
from irfidelity.stats import PairRequest

# --------------------------------------------------------------------------- unaligned arrays
RNG = np.random.default_rng(13)


def _pair(dtype) -> tuple[np.ndarray, np.ndarray]:
    real = RNG.integers(0, 4000, (37, 41)).astype(dtype)
    sim = (real * 0.9 + RNG.integers(0, 50, real.shape)).astype(dtype)
    return real, sim


def _unaligned(a: np.ndarray) -> np.ndarray:
    """A C-contiguous copy of `a` starting one byte into its buffer (not aligned)."""
    buf = bytearray(a.nbytes + 1)
    out = np.frombuffer(buf, dtype=a.dtype, offset=1, count=a.size).reshape(a.shape)
    out[...] = a
    assert out.flags.c_contiguous and not out.flags.aligned
    return out


def _memmap_unaligned(a: np.ndarray, path) -> np.ndarray:
    """`a` as an `np.memmap` at an odd offset of a file."""
    path.write_bytes(b"\0" + a.tobytes())
    out = np.memmap(path, dtype=a.dtype, mode="r", offset=1, shape=a.shape)
    assert out.flags.c_contiguous and not out.flags.aligned
    return out


def _metrics(real, sim) -> dict:
    return {
        "mse": irf.stats.mse(real, sim),
        "psnr": irf.stats.psnr(real, sim, peak=4000.0),
        "ssim": irf.stats.ssim(real, sim),
        "nmi": irf.stats.nmi(real, sim),
        "pair_stats": irf.pair_stats(real, sim, peak=4000.0),
        "masked": irf.pair_stats(real, sim, peak=4000.0, mask=real > 1000),
    }


@pytest.mark.parametrize("dtype", [np.uint16, np.float32, np.float64])
def test_unaligned_frames_score_as_aligned_ones(dtype, tmp_path):
    real, sim = _pair(dtype)
    want = _metrics(real, sim)
    assert _metrics(_unaligned(real), _unaligned(sim)) == want
    assert _metrics(_memmap_unaligned(real, tmp_path / "r.bin"), _memmap_unaligned(sim, tmp_path / "s.bin")) == want
    assert _metrics(_unaligned(real), sim) == want  # one unaligned, one aligned
    # an unaligned Fortran-ordered pair (the transpose of an unaligned C array) is read in
    # Fortran order, like an aligned one (float sums depend on the order in their last bits)
    fortran = np.asfortranarray(real), np.asfortranarray(sim)
    assert _metrics(_unaligned(real.T).T, _unaligned(sim.T).T) == _metrics(*fortran)


def test_unaligned_frames_bypass_the_fast_path_only():
    real, sim = _pair(np.uint16)
    assert _core.plain_mse(_unaligned(real), _unaligned(sim)) is None  # the general path copies
    assert _core.plain_mse(real, sim) == irf.stats.mse(real, sim)


def test_frames_in_different_orders_pair_pixel_by_pixel():
    real, sim = _pair(np.float64)
    want = irf.pair_stats(real, sim, peak=4000.0)
    # no shared order: both are read in C order
    assert irf.pair_stats(np.asfortranarray(real), sim, peak=4000.0) == want
    assert irf.pair_stats(real[::2], sim[::2], peak=4000.0) == irf.pair_stats(real[::2].copy(), sim[::2].copy(), peak=4000.0)
    # integer sums are exact in any order, mask included
    real, sim = _pair(np.uint16)
    mask = real > 2000
    want = irf.pair_stats(real, sim, mask=mask)
    assert irf.pair_stats(np.asfortranarray(real), np.asfortranarray(sim), mask=mask) == want
    assert irf.pair_stats(np.asfortranarray(real), np.asfortranarray(sim), mask=np.asfortranarray(mask)) == want


# --------------------------------------------------------------------------- argument values
@pytest.mark.parametrize("value", [2**64, 2**70, -1])
def test_integers_out_of_range_are_range_errors(value, tmp_path):
    with pytest.raises(RangeError, match=rf"page must be an integer in 0\.\.=18446744073709551615, got {value}"):
        _core.load_frame(str(tmp_path / "x.png"), None, value)
    with pytest.raises(RangeError, match="max_pixels must be an integer"):
        _core.load_frame(str(tmp_path / "x.png"), None, 0, value)
    with pytest.raises(RangeError, match="real_pages must be an integer"):
        _core.score_pairs(["a"], ["b"], [value], [0], request=SequenceRequest())
    with pytest.raises(RangeError, match="workers must be an integer"):
        _core.score_pairs(["a"], ["b"], request=SequenceRequest(), workers=value)
    with pytest.raises(RangeError, match=r"request: .*SequenceRequest\.max_pixels"):
        _core.score_pairs(["a"], ["b"], request=SequenceRequest(max_pixels=value))
    with pytest.raises(RangeError, match=r"request: .*SequenceRequest\.max_bytes"):
        _core.score_pairs(["a"], ["b"], request=SequenceRequest(max_bytes=value))
    real, sim = _pair(np.uint16)
    with pytest.raises(RangeError, match=r"request: .*PairRequest\.bins"):
        _core.pair_stats(real, sim, PairRequest(bins=value))


def test_public_functions_refuse_huge_pages(tmp_path):
    path = tmp_path / "f.png"
    path.write_bytes(b"not a png")
    with pytest.raises(FidelityError):
        irf.load_frame(path, page=2**64)
    with pytest.raises(FidelityError):
        irf.load_frame(path, max_pixels=2**64)


def test_a_bad_request_is_a_fidelity_error():
    real, sim = _pair(np.uint16)
    with pytest.raises(FidelityError, match="no attribute 'sse'"):
        _core.pair_stats(real, sim, object())
    with pytest.raises(FidelityError, match=r"PairRequest\.bins: .*integer"):
        _core.pair_stats(real, sim, PairRequest(bins="many"))
    with pytest.raises(FidelityError, match=r"SequenceRequest\.pair: .*PairRequest\.hist_range"):
        _core.score_pairs(["a"], ["b"], request=SequenceRequest(PairRequest(hist_range=(0.0, 1.0, 2.0))))
    with pytest.raises(FidelityError, match="model must be one of 'translation', 'rigid', 'similarity', got \"affine\""):
        _core.score_pairs(["a"], ["b"], request=SequenceRequest(register_each=("affine", "auto", None, 3)))
    with pytest.raises(FidelityError, match="warp order must be 1 .* got 2"):
        _core.score_pairs(["a"], ["b"], request=SequenceRequest(register_each=("rigid", "auto", None, 2)))
    with pytest.raises(FidelityError, match="warp and register_each exclude each other"):
        _core.score_pairs(["a"], ["b"], request=SequenceRequest(warp=((1.0, 0.0, 0.0, 0.0, 1.0, 0.0), 3),
                                                                register_each=("rigid", "auto", None, 3)))


# --------------------------------------------------------------------------- request and errors
def test_the_request_says_what_is_computed():
    real, sim = _pair(np.uint16)
    st = _core.pair_stats(real, sim, PairRequest(sse=True, moments=False))
    assert st.has_sse and not st.has_moments and not st.has_hist
    st = _core.pair_stats(real, sim, PairRequest(sse=False, moments=False, levels=True))
    assert st.hist_spec() == ("levels",)
    st = _core.pair_stats(real, sim, PairRequest(sse=False, moments=False, bins=8, hist_range=(0.0, 7.0)))
    assert st.hist_spec() == ("bins", 8, 0.0, 1.0)
    with pytest.raises(RangeError, match="2047"):
        _core.pair_stats(real, sim, PairRequest(valid=(0, 2047)))


def test_core_errors_are_irfidelity_classes(tmp_path):
    real, sim = _pair(np.uint16)
    with pytest.raises(ShapeError, match=r"differ in dtype: uint16 vs float32"):
        _core.pair_stats(real, sim.astype(np.float32), PairRequest())
    with pytest.raises(ShapeError, match=r"differ in shape: \(37, 41\) vs \(41, 37\)"):
        _core.pair_stats(real, sim.T.copy(), PairRequest())
    with pytest.raises(ShapeError, match=r"unsupported frame dtype int64"):
        _core.pair_stats(real.astype(np.int64), sim.astype(np.int64), PairRequest())
    with pytest.raises(ShapeError, match=r"^real: expected a 2-D frame, got shape \(1517,\)"):
        _core.pair_stats(real.ravel(), sim.ravel(), PairRequest())
    with pytest.raises(ShapeError, match=r"mask: shape \(41, 37\)"):
        _core.pair_stats(real, sim, PairRequest(), np.ones((41, 37), bool))
    with pytest.raises(FrameError, match="missing.png"):
        _core.load_frame(str(tmp_path / "missing.png"))
    with pytest.raises(FidelityError, match="real: 2 paths but 1 pages"):
        _core.score_pairs(["a", "b"], ["a", "b"], [0], request=SequenceRequest())
    with pytest.raises(FidelityError, match="PairStats"):
        _core.PairStats.from_bytes(b"junk")


def test_supported_dtypes_come_from_the_binding():
    assert _core.SUPPORTED_DTYPES == ("uint8", "uint16", "int16", "uint32", "float16", "float32", "float64")
    assert FRAME_DTYPES == tuple(np.dtype(n) for n in _core.SUPPORTED_DTYPES)
    for name in _core.SUPPORTED_DTYPES:
        a = np.arange(12, dtype=name).reshape(3, 4)
        assert _core.pair_stats(a, a, PairRequest()).n == 12


# --------------------------------------------------------------------------- int_sums
def test_int_sums_are_exact_and_public():
    real, sim = _pair(np.uint16)
    sums = irf.pair_stats(real, sim).int_sums()
    r, s = real.astype(object).ravel(), sim.astype(object).ravel()
    assert sums == {
        "sum_real": sum(r),
        "sum_sim": sum(s),
        "sum_real_sq": sum(r * r),
        "sum_sim_sq": sum(s * s),
        "sum_cross": sum(r * s),
        "sse": sum((r - s) * (r - s)),
    }
    assert irf.pair_stats(real.astype(np.float32), sim.astype(np.float32), peak=1.0).int_sums() is None
