"""SSIM maps and MS-SSIM: agreement with scikit-image and an independent MS-SSIM reference,
the scale cap for small frames, degenerate frames and bad input."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter
from skimage.metrics import structural_similarity

import irfidelity as irf
from irfidelity.errors import FidelityError, RangeError, ShapeError

DATA = Path(__file__).parent / "data"
REAL_FRAMES = [DATA / "thermal" / f"cptv_v2_frame00{i}.png" for i in range(2)]


def skimage_ssim(real, sim, peak, sigma=1.5, win_size=None):
    return structural_similarity(
        real, sim, gaussian_weights=True, sigma=sigma, use_sample_covariance=False, data_range=peak,
        win_size=win_size, full=True,
    )


def lepton_pair():
    real = irf.load_frame(REAL_FRAMES[0])
    sim = irf.load_frame(REAL_FRAMES[1])  # the next frame of the recording: a realistic near-miss
    return real, sim


def pair(dtype, shape=(67, 93), seed=0):
    """A textured frame and a blurred, noisy, offset version of it, in `dtype`'s range."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0 : shape[0], 0 : shape[1]]
    base = np.sin(x / 5.0) * np.cos(y / 7.0) + 0.3 * rng.standard_normal(shape)
    other = gaussian_filter(base, 1.0) * 0.9 + 0.1 + 0.2 * rng.standard_normal(shape)
    dt = np.dtype(dtype)
    if dt.kind == "f":
        return base.astype(dt), other.astype(dt), 4.0
    info = np.iinfo(dt)
    lo, hi = (info.min, info.max) if dt.itemsize < 4 else (0, 2**20)
    scale = (hi - lo) / 6.0
    mid = (hi + lo) / 2.0
    conv = lambda a: np.clip(np.rint(mid + scale * a), lo, hi).astype(dt)  # noqa: E731
    peak = float(info.max - min(info.min, 0))
    return conv(base), conv(other), peak


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int16, np.uint32, np.float16, np.float32, np.float64])
def test_mean_and_map_equal_scikit_image(dtype):
    real, sim, peak = pair(dtype)
    m = irf.maps.ssim_map(real, sim, peak=peak)
    # scikit-image filters float16/float32 frames in float32; irfidelity always in float64:
    # the reference is scikit-image on the frames converted to float64 (the same values)
    want, want_map = skimage_ssim(real.astype(np.float64), sim.astype(np.float64), peak)
    assert m.map.dtype == np.float64 and m.map.shape == real.shape
    assert abs(m.mean - want) < 1e-9
    assert np.abs(m.map - want_map).max() < 1e-9
    if np.dtype(dtype).kind in "ui":
        # integer frames: the default data range is scikit-image's dtype range
        default = irf.maps.ssim_map(real, sim)
        assert default.peak == peak and default.mean == m.mean


def test_real_thermal_frames_with_bits():
    real, sim = lepton_pair()
    m = irf.maps.ssim_map(real, sim, bits=14)
    want, want_map = skimage_ssim(real, sim, 2**14 - 1)
    assert abs(m.mean - want) < 1e-9 and np.abs(m.map - want_map).max() < 1e-9
    assert m.peak == 16383 and m.settings()["win_size"] == 11


@pytest.mark.parametrize(("sigma", "win_size"), [(1.0, 9), (2.0, 15), (0.5, 5)])
def test_other_windows_equal_scikit_image(sigma, win_size):
    # scikit-image's Gaussian window is 2·int(3.5·sigma + 0.5) + 1 wide
    assert win_size == 2 * int(3.5 * sigma + 0.5) + 1
    real, sim, peak = pair(np.uint16, shape=(40, 51))
    m = irf.maps.ssim_map(real, sim, peak=peak, sigma=sigma, win_size=win_size)
    want, want_map = skimage_ssim(real, sim, peak, sigma=sigma, win_size=win_size)
    assert abs(m.mean - want) < 1e-9 and np.abs(m.map - want_map).max() < 1e-9


def test_layouts_and_paths_give_the_same_map():
    real, sim = lepton_pair()
    m = irf.maps.ssim_map(real, sim, bits=14)
    t = irf.maps.ssim_map(np.asfortranarray(real), sim[:, :], bits=14)
    assert np.array_equal(m.map, t.map)
    strided = irf.maps.ssim_map(real[::2, ::2], sim[::2, ::2], bits=14)
    assert abs(strided.mean - skimage_ssim(real[::2, ::2], sim[::2, ::2], 16383)[0]) < 1e-9
    assert irf.maps.ssim_map(str(REAL_FRAMES[0]), str(REAL_FRAMES[1]), bits=14).mean == m.mean


def test_flat_frames_have_documented_values():
    same = irf.maps.ssim_map(np.full((20, 20), 700, np.uint16), np.full((20, 20), 700, np.uint16), bits=12)
    assert same.mean == 1.0 and np.all(same.map == 1.0)
    a, b, peak = 3000.0, 1000.0, 4095.0
    c1 = (0.01 * peak) ** 2
    diff = irf.maps.ssim_map(np.full((20, 20), 3000, np.uint16), np.full((20, 20), 1000, np.uint16), bits=12)
    assert np.allclose(diff.map, (2 * a * b + c1) / (a * a + b * b + c1), rtol=0, atol=1e-15)
    zeros = irf.maps.ssim_map(np.zeros((11, 11)), np.zeros((11, 11)), peak=1.0)
    assert zeros.mean == 1.0
    flat_vs_texture = irf.maps.ssim_map(np.full((30, 30), 0.5), np.random.default_rng(1).random((30, 30)), peak=1.0)
    assert np.isfinite(flat_vs_texture.map).all()


def test_large_offset_float_frames_keep_their_local_variance():
    # float64 frames at 1e6 with texture of size ~1 and data range 4: scikit-image's
    # E[x²] − E[x]² loses ~1e-4 of each local variance; the centred computation does not
    real, sim, peak = pair(np.float64)
    base = irf.maps.ssim_map(real, sim, peak=peak)
    shifted = irf.maps.ssim_map(real + 2.0**20, sim + 2.0**20, peak=peak)
    # the luminance term changes (it compares means), contrast-structure must not:
    # at offset 2^20 both means are ~2^20 and luminance ≈ 1 everywhere
    lum = lambda r, s: (2 * r * s + (0.01 * peak) ** 2) / (r * r + s * s + (0.01 * peak) ** 2)  # noqa: E731
    mu = lambda a: gaussian_filter(a.astype(np.float64), 1.5, truncate=3.5, mode="reflect")  # noqa: E731
    cs_base = base.map / lum(mu(real), mu(sim))
    cs_shift = shifted.map / lum(mu(real + 2.0**20), mu(sim + 2.0**20))
    assert np.abs(cs_base - cs_shift).max() < 1e-9


def test_bad_input_is_a_clear_error():
    real, sim = lepton_pair()
    with pytest.raises(RangeError, match=r"value \d+ at \(row \d+, col \d+\)"):
        irf.maps.ssim_map(real, sim, bits=8)
    f = real.astype(np.float32)
    f[7, 9] = np.nan
    f[50, 3] = np.inf
    with pytest.raises(RangeError, match=r"2 non-finite.*real frame at \(row 7, col 9\)"):
        irf.maps.ssim_map(f, sim.astype(np.float32), peak=16383)
    with pytest.raises(FidelityError, match="peak"):
        irf.maps.ssim_map(f, f)
    with pytest.raises(ShapeError, match="smaller than the 11 × 11"):
        irf.maps.ssim_map(real[:10], sim[:10], bits=14)
    with pytest.raises(ShapeError):
        irf.maps.ssim_map(real, sim[:, :-1], bits=14)
    with pytest.raises(ShapeError):
        irf.maps.ssim_map(real, sim.astype(np.int16), bits=14)
    with pytest.raises(FidelityError, match="k1"):
        irf.maps.ssim_map(real, sim, bits=14, k1=0)
    with pytest.raises(FidelityError, match="win_size"):
        irf.maps.ssim_map(real, sim, bits=14, win_size=10)
    with pytest.raises(FidelityError, match="sigma"):
        irf.maps.ssim_map(real, sim, bits=14, sigma=-1)
    assert irf.maps.ssim_map(real[:11, :11], sim[:11, :11], bits=14).map.shape == (11, 11)


def test_gil_is_released():
    real, sim, peak = pair(np.float64, shape=(600, 800))
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(1)

    t = threading.Thread(target=count)
    t.start()
    try:
        for _ in range(5):
            irf.maps.ssim_map(real, sim, peak=peak)
    finally:
        done.set()
        t.join()
    assert len(ticks) > 100  # the counting thread ran while the maps were computed


# --------------------------------------------------------------------------- MS-SSIM
MS_WEIGHTS = np.array([0.0448, 0.2856, 0.3001, 0.2363, 0.1333])


def reference_ms_ssim(real, sim, peak, scales):
    """MS-SSIM from scratch with scipy: Gaussian moments, the 2×2 'symmetric' averaging of
    Wang's msssim.m, the paper's weights renormalised, terms clipped at 0."""
    c1, c2 = (0.01 * peak) ** 2, (0.03 * peak) ** 2
    x, y = real.astype(np.float64), sim.astype(np.float64)
    terms = []
    for j in range(scales):
        f = lambda a: gaussian_filter(a, 1.5, truncate=3.5, mode="reflect")  # noqa: E731
        mx, my = f(x), f(y)
        vx, vy, vxy = f(x * x) - mx**2, f(y * y) - my**2, f(x * y) - mx * my
        cs = (2 * vxy + c2) / (vx + vy + c2)
        ssim = (2 * mx * my + c1) / (mx**2 + my**2 + c1) * cs
        crop = (slice(5, -5), slice(5, -5))
        terms.append((ssim if j == scales - 1 else cs)[crop].mean())
        x, y = (np.pad(a, ((0, a.shape[0] % 2), (0, a.shape[1] % 2)), mode="edge") for a in (x, y))
        x, y = ((a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]) / 4 for a in (x, y))
    w = MS_WEIGHTS[:scales] / MS_WEIGHTS[:scales].sum()
    return float(np.prod(np.maximum(terms, 0.0) ** w))


def test_ms_ssim_equals_reference_on_640x512():
    real = irf.load_frame(DATA / "thermal" / "flirpy_frame_000000_raw16.png")
    rng = np.random.default_rng(3)
    sim = np.clip(gaussian_filter(real.astype(float), 1.2) + rng.normal(0, 4, real.shape), 0, 65535)
    sim = sim.astype(np.uint16)
    got = irf.maps.ms_ssim(real, sim, bits=16)
    assert abs(got - reference_ms_ssim(real, sim, 65535, 5)) < 1e-9
    assert 0 < got < 1


def test_ms_ssim_caps_scales_for_lepton_frames():
    real, sim = lepton_pair()  # 160×120: 120, 60, 30, 15 rows; an 8-row fifth scale is refused
    got = irf.maps.ms_ssim(real, sim, bits=14)
    assert abs(got - reference_ms_ssim(real, sim, 16383, 4)) < 1e-9
    assert got == irf.maps.ms_ssim(real, sim, bits=14, scales=4)
    with pytest.raises(FidelityError, match="at most 4 scales"):
        irf.maps.ms_ssim(real, sim, bits=14, scales=5)
    # odd sizes: 75 columns -> 38 -> 19 (the last column averaged with itself)
    odd_r, odd_s = real[:75, :75], sim[:75, :75]
    assert abs(irf.maps.ms_ssim(odd_r, odd_s, bits=14) - reference_ms_ssim(odd_r, odd_s, 16383, 3)) < 1e-9


def test_ms_ssim_limits():
    real, sim = lepton_pair()
    assert irf.maps.ms_ssim(real, real, bits=14) == 1.0
    one = irf.maps.ms_ssim(real, sim, bits=14, scales=1)
    assert one == max(irf.maps.ssim_map(real, sim, bits=14).mean, 0.0)
    y, x = np.mgrid[0:64, 0:64]
    texture = np.sin(x * 0.7) + np.cos(y * 0.3)
    anti = irf.maps.ms_ssim(texture, -texture, peak=4.0)
    assert anti == 0.0  # negative contrast-structure: no shared structure, not NaN
    for bad in (0, 6, 2.5, True):
        with pytest.raises(FidelityError, match="scales"):
            irf.maps.ms_ssim(real, sim, bits=14, scales=bad)
    with pytest.raises(ShapeError):
        irf.maps.ms_ssim(real[:10], sim[:10], bits=14)
    assert irf.maps.MS_SSIM_WEIGHTS == tuple(MS_WEIGHTS)


def test_docstring_examples():
    import doctest

    import irfidelity.maps

    result = doctest.testmod(irfidelity.maps)
    assert result.attempted >= 8 and result.failed == 0
