"""One path per registered pair (issue 26): register → resample → statistics in one Rust call,
shared by evaluate, the array loop of sequences and the report; binding errors through the
crate error."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.ndimage as ndi

import irfidelity as irf
from irfidelity import _core
from irfidelity.alignment import score_registered
from irfidelity.errors import FidelityError, RangeError, ShapeError
from irfidelity.stats import PairRequest

DATA = Path(__file__).parent / "data" / "thermal"


def _pair(name: str, shift=(1.3, -0.7), seed=1) -> tuple[np.ndarray, np.ndarray]:
    """A real frame from tests/data and a blurred, shifted, noised simulation of it."""
    real = irf.load_frame(DATA / name)
    rng = np.random.default_rng(seed)
    sim = ndi.shift(ndi.gaussian_filter(real.astype(float), 0.8), shift, order=3, mode="nearest")
    return real, np.clip(sim + rng.normal(0, 4, sim.shape), 0, np.iinfo(real.dtype).max).astype(real.dtype)


FRAMES = ["readthermal_zenmuse_xtr_raw16.png", "cptv_v2_frame000.png", "flirpy_frame_000000_raw16.png"]


@pytest.mark.parametrize("name", FRAMES)
def test_one_call_equals_register_apply_and_pair_stats(name):
    real, sim = _pair(name)
    mask = np.ones(real.shape, bool)
    mask[:5, :7] = False
    request = PairRequest(sse=True, moments=True, bins=256)
    pair = score_registered(real, sim, request, model="translation", method="phase", mask=mask, extent=True)
    reg = irf.register(real, sim, method="phase", mask=mask)
    aligned, valid = reg.apply(sim, mask=mask)
    keep = valid & mask
    want = irf.pair_stats(real.astype(np.float64), aligned, bins=256, hist_range="data", peak=1.0, mask=keep)
    assert pair.registration == reg
    assert pair.stats.to_bytes() == want.to_bytes()
    np.testing.assert_array_equal(pair.sim, aligned)
    np.testing.assert_array_equal(pair.mask, keep)
    scored = real[keep].astype(np.float64)
    assert pair.extent == (scored.min(), scored.max())
    # a registration found before, applied: the same statistics
    fixed = score_registered(real, sim, request, registration=reg, mask=mask)
    assert fixed.stats.to_bytes() == want.to_bytes()


@pytest.mark.parametrize("name", FRAMES[:2])
def test_registered_evaluate_equals_the_steps_it_stands_for(name):
    real, sim = _pair(name)
    kw = dict(bits=16, peak="range", register="translation", register_method="phase")
    rep = irf.evaluate(real, sim, **kw)
    reg = irf.register(real, sim, method="phase")
    aligned, valid = reg.apply(sim)
    r64 = real.astype(np.float64)
    st = irf.pair_stats(r64, aligned, mask=valid, bins=256, hist_range=rep.config.hist_range)
    span = r64[valid].max() - r64[valid].min()
    assert rep.metrics["psnr_peak"] == span
    assert rep.metrics["psnr_db"] == st.psnr(span)
    assert rep.metrics["mse"] == st.mse()
    assert rep.metrics["nmi"] == st.nmi().value
    assert rep.metrics["ssim"] == st.ssim().value
    assert rep.registration == reg.to_dict()


def _core_calls(fn) -> list[str]:
    calls: list[str] = []

    def profiler(frame, event, arg):
        if event == "c_call":
            owner = getattr(arg, "__self__", None)
            if (getattr(arg, "__module__", None) or "").startswith("irfidelity._core") or \
                    type(owner).__module__ == "irfidelity._core":
                calls.append(arg.__qualname__)

    sys.setprofile(profiler)
    try:
        fn()
    finally:
        sys.setprofile(None)
    return calls


def test_a_registered_evaluate_makes_one_scoring_call():
    # the pair's one path, the defects search on the frames as scored (the error profile with
    # the threshold's sample; the largest difference passes the threshold on this pair, so the
    # far pixels are listed; none is a defect, so the concentrated-error check reads the same
    # profile), the summary, then the scene's transfer (its memory plan, block means, tiles)
    real, sim = _pair(FRAMES[1])
    kw = dict(bits=16, peak="range", register="translation", register_method="phase")
    calls = _core_calls(lambda: irf.evaluate(real, sim, **kw))
    scene = ["check_budget", "low_spectrum", "cross_spectra"]
    defects = ["error_profile", "far_pixels"]
    assert calls == ["score_registered", *defects, "PairStats.summary", *scene], calls
    # unregistered: the memory plan is checked (no data crosses), then one pass, the real
    # frame's range (the PSNR peak "range") and the summary
    calls = _core_calls(lambda: irf.evaluate(real, sim, bits=16, peak="range"))
    pair = ["check_budget", "pair_stats", "scored_range"]
    assert calls == [*pair, *defects, "PairStats.summary", *scene], calls
    # without the scene, the pair alone
    calls = _core_calls(lambda: irf.evaluate(real, sim, bits=16, peak="range", transfer_options={"scene": False}))
    assert calls == [*pair, *defects, "PairStats.summary"], calls


def test_the_array_loop_scores_as_the_engine(tmp_path):
    cv2 = pytest.importorskip("cv2")
    frames = [_pair(FRAMES[1], shift=(0.4 * k, -0.3 * k), seed=k) for k in range(3)]
    for k, (r, s) in enumerate(frames):
        (tmp_path / "r").mkdir(exist_ok=True)
        (tmp_path / "s").mkdir(exist_ok=True)
        cv2.imwrite(str(tmp_path / "r" / f"{k}.png"), r)
        cv2.imwrite(str(tmp_path / "s" / f"{k}.png"), s)
    reals, sims = np.stack([r for r, _ in frames]), np.stack([s for _, s in frames])
    for each in (False, True):
        kw = dict(bits=16, peak="range", register="translation", register_method="phase", register_each=each,
                  progress=False)
        arrays = irf.score_sequence(reals, sims, **kw)
        files = irf.score_sequence(str(tmp_path / "r"), str(tmp_path / "s"), workers=1, **kw)
        assert [f["metrics"] for f in arrays.to_dict()["frames"]] == [f["metrics"] for f in files.to_dict()["frames"]]


def test_levels_are_checked_before_resampling():
    real, sim = _pair(FRAMES[1])
    with pytest.raises(RangeError, match="sim frame: value .* outside the valid range 0 .. 255"):
        irf.evaluate(real // 300, sim, bits=8, register="translation")


def test_registered_report_shows_the_ssim_map_joint_histogram_and_overlay():
    pytest.importorskip("matplotlib")
    real, sim = _pair(FRAMES[0], shift=(2.6, -3.4))
    rep = irf.evaluate(real, sim, bits=16, peak="range", register="translation")
    html = rep.to_html()
    for anchor in ("ssim-map", "joint-histogram", "overlay"):
        assert f'id="{anchor}"' in html
        assert f'<section id="{anchor}" class="missing">' not in html, anchor
    assert "differ in dtype" not in html
    assert "Registration overlay" in html and "before registration" in html and "after registration" in html
    # the overlay's RMS difference falls with registration
    caption = html[html.index("RMS difference simulated"):]
    before, after = (float(v) for v in
                     caption.split(":", 1)[1].split("(over")[0].replace("before", "").replace("after", "").split(","))
    assert after < before
    # an unregistered report has no overlay section
    assert 'id="overlay"' not in irf.evaluate(real, sim, bits=16, peak="range").to_html()


@pytest.mark.parametrize("call", [
    lambda a: _core.register_frames(a, a, "translation", "phase", None, None),
    lambda a: _core.warp_frame(a, (1.0, 0.0, 0.0, 0.0, 1.0, 0.0), 3, a.shape, None),
    lambda a: _core.pair_stats(a, a, PairRequest()),
    lambda a: _core.score_registered(a, a, PairRequest(), search=("translation", "phase", None)),
    lambda a: _core.noise_sums_array(np.ascontiguousarray(a[None].repeat(3, 0)), workers=1),
])
def test_an_unsupported_dtype_is_a_shape_error_everywhere(call):
    frame = np.arange(64 * 64, dtype=np.int64).reshape(64, 64)
    with pytest.raises(ShapeError, match="unsupported frame dtype int64: expected one of uint8, uint16"):
        call(frame)


def test_binding_errors_are_the_library_classes():
    frame = np.arange(64 * 64, dtype=np.uint16).reshape(64, 64)
    with pytest.raises(FidelityError, match="internal: the mask must be C-contiguous"):
        _core.register_frames(frame, frame, "translation", "phase", None, np.ones((64, 128), bool)[:, ::2])
    with pytest.raises(ShapeError, match="mask must have the frames' shape"):
        _core.warp_frame(frame, (1.0, 0.0, 0.0, 0.0, 1.0, 0.0), 3, frame.shape, np.ones((3, 3), bool))
    with pytest.raises(FidelityError, match="internal: the cube must be a C-contiguous 3-D array"):
        _core.noise_sums_array(frame, workers=1)
    with pytest.raises(FidelityError, match="2 paths but 1 pages"):
        _core.noise_sums_paths(["a", "b"], [0])
    with pytest.raises(ShapeError, match="differ in dtype: uint16 vs float32"):
        _core.score_registered(frame, frame.astype(np.float32), PairRequest(), matrix=(1.0, 0, 0, 0, 1.0, 0))
    with pytest.raises(FidelityError, match="exactly one of search and matrix"):
        _core.score_registered(frame, frame, PairRequest())


def test_a_registered_pair_with_defects_left_out_is_scored_on_float64_frames():
    """A registered integer pair whose real frame holds hot pixels: the defects pass leaves them
    out and the pair is scored again over the rest, the real frame as float64 beside the
    resampled simulation (it raised a dtype ShapeError); one-pixel defects named as a pixel."""
    real = irf.load_frame(DATA / "readthermal_zenmuse_xtr_raw16.png")
    rng = np.random.default_rng(0)
    blurred = 0.98 * ndi.gaussian_filter(real.astype(float), 1.0) + 45 + rng.normal(0, 16, real.shape)
    sim = np.clip(ndi.shift(blurred, (1.4, -2.6), order=3, mode="nearest"), 0, 65535).round().astype(np.uint16)
    rep = irf.evaluate(real, sim, register="translation", register_method="phase", bits=16, peak="range")
    defects = rep.verdict["defects"]
    assert defects is not None and defects["pixels"] >= 1
    mask = rep.sources["mask"]
    want = irf.pair_stats(real.astype(np.float64), rep.sources["sim"], peak=1.0, mask=mask)
    assert rep.metrics["n"] == want.n == int(mask.sum()) < real.size
    assert rep.metrics["mse"] == want.mse() and rep.metrics["nmi"] == want.nmi().value
    single = next(c for c in defects["clusters"] if c["pixels"] == 1)
    assert f"row {single['rows'][0]}, column {single['cols'][0]}" in defects["text"]
