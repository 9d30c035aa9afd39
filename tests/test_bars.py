"""Bar targets, CTF and MRTD (issue 30, phase A): exact target rendering, the CTF of rendered
bar images against the analytic CTF of the same target, the fundamental-amplitude ratio against
the system MTF and the slanted edge, Coltman's series both ways, the MRTD model's scaling and
its agreement with the MRTD measured on simulated frames, and bad input."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.curves import (CameraGeometry, Curve, ctf_curve, ctf_from_bars, ctf_from_mtf, find_bars,
                               measured_mrtd, mrtd, mtf_from_ctf, mtf_from_edge)
from irfidelity.errors import (BarClippingWarning, BarPolarityWarning, BarSamplingWarning, BarWarning, ColtmanWarning,
                               FidelityError, MRTDWarning)
from irfidelity.targets import OTF, bar_target, diffraction_otf, four_bar, gaussian_otf, slanted_edge, three_bar

_erf = np.frompyfunc(math.erf, 1, 1)


def phi(t):
    return 0.5 * (1 + _erf(np.asarray(t, dtype=float) / math.sqrt(2)).astype(float))


def psi(t):
    """∫Φ: t Φ(t) + φ(t)."""
    t = np.asarray(t, dtype=float)
    return t * phi(t) + np.exp(-t * t / 2) / math.sqrt(2 * math.pi)


def box_gauss_interval(x, a, b, sigma):
    """Mean over the pixel [x - 1/2, x + 1/2] of the indicator of [a, b] blurred by a Gaussian."""
    def integral(u, edge):
        return sigma * psi((u - edge) / sigma)
    return (integral(x + 0.5, a) - integral(x - 0.5, a)) - (integral(x + 0.5, b) - integral(x - 0.5, b))


def centre_line_profile(x, f, centre, otf, bars=4):
    """The continuous profile across infinitely long bars seen through ``otf`` and the pixel
    aperture, by numerical inverse Fourier transform of its analytic spectrum."""
    support = min(otf.support, 6.0)
    nu = np.linspace(-support, support, 120001)
    width = 1 / (2 * f)
    offsets = (np.arange(bars) - (bars - 1) / 2) / f
    phase = 2 * np.pi * np.outer(nu, centre + offsets)
    pattern = width * np.sinc(width * nu) * np.exp(-1j * phase).sum(axis=1)
    spectrum = pattern * otf(nu, 0.0) * np.sinc(nu)
    kernel = np.exp(2j * np.pi * np.outer(np.atleast_1d(x), nu))
    return (kernel.real @ spectrum.real - kernel.imag @ spectrum.imag) * (nu[1] - nu[0])


def centre_lines_2d(x, f, otf, bars=4, length=7.0):
    """The continuous image of a finite target (bars ``length`` widths long, centred at 0) seen
    through ``otf`` and the pixel aperture, at offsets ``x`` across the bars, averaged along the
    central 60 % of the bars' length: two-dimensional inverse Fourier transform."""
    support = min(otf.support, 3.0)
    width = 1 / (2 * f)
    nu = np.linspace(-support, support, 1201)
    eta = np.linspace(-support, support, 1201)
    offsets = (np.arange(bars) - (bars - 1) / 2) / f
    across = width * np.sinc(width * nu) * np.cos(2 * np.pi * np.outer(nu, offsets)).sum(axis=1) * np.sinc(nu)
    read = 0.3 * length * width  # the rows read: |y| <= read; the mean of cos(2πηy) over them
    along = length * width * np.sinc(length * width * eta) * np.sinc(eta) * np.sinc(2 * read * eta)
    transfer = otf(nu[None, :], eta[:, None])
    inner = along @ transfer  # ∫ dη for every ν
    return (np.cos(2 * np.pi * np.outer(np.atleast_1d(x), nu)) @ (across * inner)) * (nu[1] - nu[0]) * (eta[1] - eta[0])


_TRUTH: dict = {}


def analytic_ctf(f, otf, bars=4):
    """(B - G)/(B + G) of the continuous image on the bars' and gaps' centre lines (along the
    central 60 % of their length), for the finite target as rendered (at any position)."""
    key = (f, otf.name, bars)
    if key not in _TRUTH:
        bar_centres = (np.arange(bars) - (bars - 1) / 2) / f
        gap_centres = bar_centres[:-1] + 1 / (2 * f)
        if otf.factor is not None:  # separable: the profile along x is the same in every row
            b = centre_line_profile(bar_centres, f, 0.0, otf, bars).mean()
            g = centre_line_profile(gap_centres, f, 0.0, otf, bars).mean()
        else:
            b = centre_lines_2d(bar_centres, f, otf, bars).mean()
            g = centre_lines_2d(gap_centres, f, otf, bars).mean()
        _TRUTH[key] = (b - g) / (b + g)
    return _TRUTH[key]


def system_mtf(otf, f):
    return float(otf(f, 0.0) * np.sinc(f))


def sampled_fundamental_ratio(f, otf, phase, bars=4):
    """What the fundamental ratio reads on the sampled image, exactly: the image's DTFT at
    (f, 0) folds in the spectrum at f + m for every integer m (only the m = 0 term is the
    system MTF), against the ideal target's fundamental. The target centre's position on the
    pixel grid (``phase``) sets the folded terms' phases."""
    width = 1 / (2 * f)
    offsets = (np.arange(bars) - (bars - 1) / 2) / f
    total = 0j
    for m in range(-8, 9):
        nu = f + m
        pattern = width * np.sinc(width * nu) * np.exp(-2j * np.pi * nu * offsets).sum()
        total += np.exp(-2j * np.pi * m * phase) * pattern * otf(nu, 0.0) * np.sinc(nu)
    ideal = width * np.sinc(0.5) * bars
    return abs(total) / ideal


def frame_for(f, otf, phase=0.0, levels=(0.0, 1.0), orientation="vertical", bars=4, margin=24):
    width = 1 / (2 * f)
    size = int(math.ceil(7 * width + 2 * max(width, 8.0))) + margin  # the target, its margins, a surround
    image = bar_target(f, (size, size), bars=bars, otf=otf, phase=phase, levels=levels, orientation=orientation)
    return image, (size - 1) / 2 + phase


def quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BarWarning)
        return fn(*args, **kw)


WELL_SAMPLED = {"gaussian 1.0 px": gaussian_otf(1.0), "diffraction cutoff 0.5": diffraction_otf(0.5)}
UNDERSAMPLED = {"gaussian 0.5 px": gaussian_otf(0.5), "gaussian 0.3 px": gaussian_otf(0.3),
                "diffraction cutoff 0.8": diffraction_otf(0.8), "diffraction cutoff 1.2": diffraction_otf(1.2)}
FREQUENCIES = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)
#: the largest error of the bar modulation measured on the undersampled cameras above, at any
#: phase (docs/bars.md): the samples do not determine the profile between them
UNDERSAMPLED_CTF_ERROR = 0.12
#: the fundamental ratio against the system MTF on those cameras: sampling folds the bars' 3rd
#: harmonic onto the fundamental at 1/4 cy/px (the 5th at 1/6, …) and the fundamental's own alias
#: 1 - f near Nyquist (docs/bars.md)
FOLDED_HARMONIC_ERROR = 0.05


# --------------------------------------------------------------------------- targets
def test_four_bar_is_the_exact_area_average():
    """Bars 4 px wide at sixteenth-pixel phases: 16 x 16 point samples per pixel are exact."""
    for phase in (0.0, 0.0625, 0.3125, 0.5):
        image = four_bar(0.125, (40, 48), phase=phase)
        ss = 16
        sub = (np.arange(ss) + 0.5) / ss - 0.5
        ys = (np.arange(40)[:, None] + sub[None, :]).ravel()
        xs = (np.arange(48)[:, None] + sub[None, :]).ravel()
        across = xs - (47 / 2 + phase)
        inside = np.zeros(xs.size, bool)
        for i in range(4):
            inside |= np.abs(across - (i - 1.5) * 8) < 2
        along = np.abs(ys - 39 / 2) < 14
        brute = (along[:, None] & inside[None, :]).reshape(40, ss, 48, ss).mean(axis=(1, 3))
        np.testing.assert_allclose(image, brute, atol=1e-12)


@pytest.mark.parametrize("phase", [0.0, 0.137, 0.5, 0.913])
def test_bar_target_conserves_the_bars_area(phase):
    f = 0.17
    w = 1 / (2 * f)
    image = four_bar(f, (60, 60), phase=phase)
    assert image.sum() == pytest.approx(4 * w * 7 * w, rel=1e-12)
    assert 0 <= image.min() and image.max() <= 1
    horizontal = four_bar(f, (60, 60), phase=phase, orientation="horizontal")
    np.testing.assert_allclose(horizontal, image.T, atol=1e-15)
    cold = four_bar(f, (60, 60), phase=phase, levels=(20.0, 19.5))
    np.testing.assert_allclose(cold, 20 - 0.5 * image)
    assert three_bar(f, (60, 60), phase=phase).sum() == pytest.approx(3 * w * 7 * w, rel=1e-12)


def test_bar_target_in_cycles_per_mrad():
    camera = CameraGeometry(pixel_pitch_um=17, focal_length_mm=34)  # IFOV 0.5 mrad
    np.testing.assert_array_equal(four_bar(0.2, (48, 48), unit="cy/mrad", camera=camera), four_bar(0.1, (48, 48)))
    with pytest.raises(FidelityError, match="IFOV"):
        four_bar(0.2, (48, 48), unit="cy/mrad")


def test_bar_target_bad_arguments():
    with pytest.raises(FidelityError, match="does not fit"):
        four_bar(0.05, (40, 40))
    for bad in (0, -0.1, math.nan, "x"):
        with pytest.raises(FidelityError, match="frequency"):
            four_bar(bad, (40, 40))
    with pytest.raises(FidelityError, match="orientation"):
        four_bar(0.2, (40, 40), orientation="diagonal")
    with pytest.raises(FidelityError, match="bars"):
        bar_target(0.2, (40, 40), bars=1)
    with pytest.raises(FidelityError, match="sigma"):
        gaussian_otf(0)


def test_rendering_through_a_gaussian_is_exact():
    """Poisson summation reproduces the closed form (bars ⊛ Gaussian ⊛ pixel) to rounding, by the
    separable path and by the general two-dimensional one."""
    sigma, f, h, w = 0.8, 0.15, 48, 56
    width, length = 1 / (2 * f), 7 / (2 * f)
    otf = gaussian_otf(sigma)
    rows, cols = np.arange(h, dtype=float), np.arange(w, dtype=float)
    across = sum(box_gauss_interval(cols, (w - 1) / 2 + o - width / 2, (w - 1) / 2 + o + width / 2, sigma)
                 for o in (np.arange(4) - 1.5) / f)
    along = box_gauss_interval(rows, (h - 1) / 2 - length / 2, (h - 1) / 2 + length / 2, sigma)
    closed = np.outer(along, across)
    np.testing.assert_allclose(four_bar(f, (h, w), otf=otf), closed, atol=1e-10)
    general = OTF(name="gaussian, not separable", radial=otf.radial, support=otf.support)
    np.testing.assert_allclose(four_bar(f, (h, w), otf=general), closed, atol=1e-10)


def test_slanted_edge_area_fraction_and_through_an_otf():
    edge = slanted_edge((32, 32), angle=7.0, centre=(15.3, 16.1))
    ss = 32
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    ys = (np.arange(32)[:, None] + sub[None, :]).ravel()
    xs = (np.arange(32)[:, None] + sub[None, :]).ravel()
    t = math.radians(7.0)
    bright = ((xs[None, :] - 16.1) * math.cos(t) - (ys[:, None] - 15.3) * math.sin(t)) > 0
    np.testing.assert_allclose(edge, bright.reshape(32, ss, 32, ss).mean(axis=(1, 3)), atol=2e-3)
    np.testing.assert_allclose(slanted_edge((32, 32), angle=7.0, orientation="horizontal"),
                               slanted_edge((32, 32), angle=7.0).T, atol=1e-15)
    otf = gaussian_otf(0.7)
    blurred = slanted_edge((96, 96), angle=5.0, otf=otf, levels=(100.0, 500.0))
    curve = mtf_from_edge(blurred)
    f = np.linspace(0.05, 0.45, 9)
    c, s = math.cos(math.radians(5)), math.sin(math.radians(5))
    truth = otf(f, 0.0) * np.abs(np.sinc(f * c) * np.sinc(f * s))
    np.testing.assert_allclose(curve(f), truth, atol=0.012)


# --------------------------------------------------------------------------- CTF against the analytic CTF
@pytest.mark.parametrize("label", WELL_SAMPLED)
def test_ctf_of_well_sampled_bars_within_2_percent(label):
    otf = WELL_SAMPLED[label]
    rng = np.random.default_rng(3)
    worst = 0.0
    for f in FREQUENCIES:
        for phase in (0.0, 0.3, 0.65):
            image, centre = frame_for(f, otf, phase, levels=(100.0, 200.0))
            noisy = image + rng.normal(0, 0.1, image.shape)  # 0.1 % of the bars' contrast
            reading = quiet(ctf_from_bars, noisy, frequency=f)
            truth = analytic_ctf(f, otf)
            assert reading.nyquist_mtf <= 0.15
            worst = max(worst, abs(reading.ctf - truth) / truth)
    assert worst <= 0.02, worst


@pytest.mark.parametrize("label", UNDERSAMPLED)
def test_ctf_of_undersampled_bars_has_the_documented_error(label):
    """Undersampled: the bar modulation depends on the phase (within the documented error, and
    warned about for bars under 4 px), the fundamental ratio does not."""
    otf = UNDERSAMPLED[label]
    errors = []
    for f in FREQUENCIES:
        for phase in np.linspace(0, 1, 5, endpoint=False):
            image, centre = frame_for(f, otf, phase)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                reading = ctf_from_bars(image, frequency=f)
            warned = any(issubclass(w.category, BarSamplingWarning) for w in caught)
            assert warned == (reading.nyquist_mtf > 0.15 and reading.bar_width < 4), (f, phase)
            errors.append(reading.ctf - analytic_ctf(f, otf))
            # 0.02: a diffraction PSF's tails reach beyond the target's margin (docs/bars.md)
            assert reading.mtf == pytest.approx(sampled_fundamental_ratio(f, otf, centre % 1), abs=0.02)
            assert reading.mtf == pytest.approx(system_mtf(otf, f), abs=FOLDED_HARMONIC_ERROR)
    assert np.abs(errors).max() <= UNDERSAMPLED_CTF_ERROR


@pytest.mark.parametrize("sigma", [0.5, 1.0])
def test_fundamental_ratio_is_exact_at_any_phase(sigma):
    """The fundamental ratio is the image's Fourier component (folded aliases included) to
    rounding: the system MTF where the bars' spectrum does not fold onto the fundamental."""
    otf = gaussian_otf(sigma)
    for f in (0.05, 0.12, 0.2, 0.25, 0.3, 0.4, 0.45):
        for phase in (0.0, 0.25, 0.5, 0.8):
            image, centre = frame_for(f, otf, phase)
            reading = quiet(ctf_from_bars, image, frequency=f, method="fundamental",
                            roi=(0, image.shape[0], 0, image.shape[1]), orientation="vertical", background=0.0)
            assert reading.value == reading.mtf
            assert reading.mtf == pytest.approx(sampled_fundamental_ratio(f, otf, centre % 1), abs=1e-3), (f, phase)
            if f not in (0.25, 0.45):
                assert reading.mtf == pytest.approx(system_mtf(otf, f), abs=3e-3), (f, phase)


def test_three_bar_horizontal_and_cold_bars_read_alike():
    otf, f = gaussian_otf(0.9), 0.12
    base, centre = frame_for(f, otf, 0.2, levels=(10.0, 30.0))
    reference = ctf_from_bars(base, frequency=f)
    assert reference.ctf == pytest.approx(analytic_ctf(f, otf), rel=0.01)
    assert reference.polarity == 1 and reference.orientation == "vertical"
    cold = ctf_from_bars(40.0 - base, frequency=f)
    assert cold.polarity == -1 and cold.ctf == pytest.approx(reference.ctf, abs=1e-9)
    turned = ctf_from_bars(base.T, frequency=f)
    assert turned.orientation == "horizontal" and turned.ctf == pytest.approx(reference.ctf, abs=1e-9)
    assert turned.centre == pytest.approx(reference.centre[::-1])
    three, centre3 = frame_for(f, otf, 0.2, bars=3)
    r3 = ctf_from_bars(three, frequency=f, bars=3)
    assert r3.ctf == pytest.approx(analytic_ctf(f, otf, bars=3), rel=0.01)
    assert r3.mtf == pytest.approx(system_mtf(otf, f), abs=0.003)


def test_ctf_in_cycles_per_mrad_and_with_a_roi():
    otf, f = gaussian_otf(0.9), 0.1
    image, _ = frame_for(f, otf, 0.0, levels=(1000.0, 1100.0))
    camera = CameraGeometry(ifov_mrad=0.25)
    a = ctf_from_bars(image, frequency=0.4, unit="cy/mrad", camera=camera)
    b = ctf_from_bars(image, frequency=0.1, roi=(0, image.shape[0], 0, image.shape[1]))
    assert a.frequency == pytest.approx(0.1) and a.ctf == pytest.approx(b.ctf, abs=2e-3)
    assert a.to_dict()["roi"] == list(a.roi)


# --------------------------------------------------------------------------- finding targets
def test_find_bars_in_a_frame_of_four_targets():
    otf, h, w = gaussian_otf(0.8), 256, 320
    spec = [(0.06, (64, 80), "vertical"), (0.1, (64, 240), "horizontal"), (0.2, (192, 80), "vertical"),
            (0.3, (192, 240), "horizontal")]
    frame = 500 + sum(four_bar(f, (h, w), centre=c, orientation=o, otf=otf, levels=(0, 80.0)) for f, c, o in spec)
    frame = frame + np.random.default_rng(4).normal(0, 0.5, frame.shape)
    groups = find_bars(frame, frequencies=[s[0] for s in spec])
    assert len(groups) == 4
    for group, (f, centre, orientation) in zip(groups, spec):
        r0, r1, c0, c1 = group.roi
        assert r0 < centre[0] < r1 and c0 < centre[1] < c1
        assert group.orientation == orientation and group.frequency == pytest.approx(f, rel=0.1)
        assert group.polarity == 1 and group.background == pytest.approx(500, abs=0.5)
    curve = quiet(ctf_curve, frame, frequencies=[0.2, 0.06, 0.3, 0.1], method="fundamental")
    assert curve.x.tolist() == [0.06, 0.1, 0.2, 0.3]
    assert [r.orientation for r in curve.meta["readings"]] == ["vertical", "horizontal", "vertical", "horizontal"]
    np.testing.assert_allclose(curve.y, [system_mtf(otf, f) for f in curve.x], atol=0.01)


def test_find_bars_keeps_a_wide_target_whole():
    """Searching for narrow bars does not split a target of wide bars into lone bars."""
    frame = four_bar(0.025, (200, 260), centre=(100, 80)) + four_bar(0.3, (200, 260), centre=(100, 220))
    groups = find_bars(frame, frequencies=[0.3])
    assert len(groups) == 2
    assert sorted(round(g.frequency, 3) for g in groups) == pytest.approx([0.025, 0.3], rel=0.1)
    assert ctf_from_bars(frame, frequency=0.025).ctf == pytest.approx(1.0, abs=1e-3)


# --------------------------------------------------------------------------- Coltman's series
def square_wave_ctf_gaussian(f, sigma):
    """CTF of an infinite 0/1 square wave (period 1/f) blurred by a Gaussian, in closed form."""
    period, width = 1 / f, 1 / (2 * f)
    m = np.arange(-400, 401)
    bar = (phi((width / 2 - m * period) / sigma) - phi((-width / 2 - m * period) / sigma)).sum()
    gap = (phi((width / 2 - period / 2 - m * period) / sigma) - phi((-width / 2 - period / 2 - m * period) / sigma)).sum()
    return bar - gap


def test_coltman_series_is_exact_for_a_gaussian_mtf():
    sigma = 1.0
    f = np.linspace(0, 3, 3001)  # MTF below 1e-70 at the end
    mtf = Curve(f, np.exp(-2 * np.pi ** 2 * sigma ** 2 * f ** 2), x_unit="cy/px")
    ctf = ctf_from_mtf(mtf)
    for i in (10, 50, 100, 137, 250, 400):
        assert ctf.y[i] == pytest.approx(square_wave_ctf_gaussian(f[i], sigma), abs=1e-12)
    assert ctf.y[0] == 1.0
    back = mtf_from_ctf(ctf)
    np.testing.assert_allclose(back.y, mtf.y, atol=1e-13)


def test_coltman_series_is_exact_for_a_diffraction_mtf():
    cutoff = 0.8
    f = np.linspace(0, 1.2, 1201)
    mtf = Curve(f, diffraction_otf(cutoff)(f), x_unit="cy/px")
    with warnings.catch_warnings():
        warnings.simplefilter("error", ColtmanWarning)  # the MTF reaches 0 within the range
        ctf = ctf_from_mtf(mtf)
        back = mtf_from_ctf(ctf)
    above = f > cutoff / 3
    np.testing.assert_allclose(ctf.y[above], 4 / np.pi * mtf.y[above], atol=1e-15)  # only the fundamental
    np.testing.assert_allclose(back.y, mtf.y, atol=1e-13)
    below = (f > 0) & (f < cutoff / 5)
    assert (ctf.y[below] > mtf.y[below]).all()


def test_coltman_coefficients_invert_each_other():
    """The Dirichlet convolution of the two coefficient sequences is 1 at n = 1 and 0 beyond."""
    from irfidelity.curves.ctf import _odd_coefficients
    a, b = _odd_coefficients(200, inverse=False), _odd_coefficients(200, inverse=True)
    k = 2 * np.arange(200) + 1
    for n in range(1, 399, 2):
        total = sum(a[(j - 1) // 2] * b[(n // j - 1) // 2] for j in k[k <= n] if n % j == 0)
        assert total == pytest.approx(1.0 if n == 1 else 0.0, abs=1e-12)
    assert (b[:8] * 4 / np.pi * k[:8]).round(12).tolist() == [1, 1, -1, 1, 0, 1, -1, -1]


def test_coltman_warns_when_the_curve_is_cut_short():
    f = np.linspace(0, 0.5, 51)
    mtf = Curve(f, np.exp(-2 * np.pi ** 2 * 0.25 * f ** 2))  # 0.29 at Nyquist
    with pytest.warns(ColtmanWarning, match="0.1667"):
        ctf_from_mtf(mtf)
    with pytest.raises(FidelityError, match="range"):
        ctf_from_mtf(mtf, frequencies=[0.6])
    with warnings.catch_warnings():
        warnings.simplefilter("error", ColtmanWarning)
        low = ctf_from_mtf(mtf, frequencies=[0.05, 0.1, 0.15])  # 3f within the range: no warning
    assert low.x.tolist() == [0.05, 0.1, 0.15]


def test_mtf_from_measured_bar_ctf_against_the_analytic_mtf():
    """A four-bar CTF curve converted by Coltman's inverse series: the finite target makes the
    error documented in docs/bars.md, largest at low frequencies."""
    otf = gaussian_otf(1.0)
    f = np.round(np.arange(0.02, 0.481, 0.02), 3)
    frames = [frame_for(x, otf, 0.0)[0] for x in f]
    curve = quiet(ctf_curve, frames, frequencies=f, rois=[(0, a.shape[0], 0, a.shape[1]) for a in frames],
                  orientation="vertical")
    with pytest.warns(ColtmanWarning):  # the CTF read at 0.48 cy/px is -0.02, not 0
        mtf = mtf_from_ctf(curve)
    truth = np.array([system_mtf(otf, x) for x in f])
    assert np.abs(mtf.y - truth).max() <= 0.03
    infinite = ctf_from_mtf(Curve(np.linspace(0, 3, 3001), [system_mtf(otf, x) for x in np.linspace(0, 3, 3001)]),
                            frequencies=f)
    assert np.abs(curve.y - infinite.y).max() <= 0.03


# --------------------------------------------------------------------------- bars against the slanted edge
@pytest.mark.parametrize("otf", [gaussian_otf(0.7), diffraction_otf(0.7), gaussian_otf(0.5) * diffraction_otf(1.0)],
                         ids=lambda o: o.name)
def test_mtf_from_bars_matches_the_slanted_edge(otf):
    rng = np.random.default_rng(5)
    edge = slanted_edge((100, 100), angle=5.0, otf=otf, levels=(100.0, 500.0)) + rng.normal(0, 1.0, (100, 100))
    edge_mtf = mtf_from_edge(edge)
    for f in (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45):
        image, _ = frame_for(f, otf, 0.3, levels=(100.0, 500.0))
        reading = quiet(ctf_from_bars, image + rng.normal(0, 1.0, image.shape), frequency=f, method="fundamental")
        assert reading.mtf == pytest.approx(float(edge_mtf(f)), abs=0.03), f


# --------------------------------------------------------------------------- MRTD model
def gauss_mtf_curve(sigma=1.0, top=0.4, points=41, scale=1.0):
    f = np.linspace(0, top, points)
    return Curve(f, scale * np.exp(-2 * np.pi ** 2 * sigma ** 2 * f ** 2) * np.sinc(f), x_unit="cy/px")


def test_mrtd_scales_with_netd_and_inversely_with_mtf():
    base = mrtd(gauss_mtf_curve(), netd=0.05, frame_rate=30, min_mtf=0.001)
    np.testing.assert_allclose(mrtd(gauss_mtf_curve(), netd=0.1, frame_rate=30, min_mtf=0.001).y, 2 * base.y, rtol=1e-14)
    np.testing.assert_allclose(mrtd(gauss_mtf_curve(scale=0.5), netd=0.05, frame_rate=30, min_mtf=0.001).y, 2 * base.y,
                               rtol=1e-14)
    f = base.x
    mtf = np.exp(-2 * np.pi ** 2 * f ** 2) * np.sinc(f)
    np.testing.assert_allclose(base.y * mtf / f, base.y[0] * mtf[0] / f[0], rtol=1e-12)  # ∝ f / MTF
    assert (base.y > 0).all() and base.y_unit == "delta_K" and base.x[0] > 0


def test_mrtd_integration_bar_length_and_threshold():
    m = gauss_mtf_curve()
    one = mrtd(m, netd=0.05)
    np.testing.assert_allclose(mrtd(m, netd=0.05, frame_rate=30, eye_time=0.2).y, one.y / math.sqrt(6), rtol=1e-14)
    np.testing.assert_allclose(mrtd(m, netd=0.05, frame_rate=2, eye_time=0.2).y, one.y, rtol=1e-14)  # one frame
    np.testing.assert_allclose(mrtd(m, netd=0.05, bar_length=28).y, one.y / 2, rtol=1e-14)
    np.testing.assert_allclose(mrtd(m, netd=0.05, snr_threshold=5).y, 2 * one.y, rtol=1e-14)


def test_mrtd_worked_example():
    """docs/bars.md: NETD 40 mK, 30 Hz, eye 0.2 s, SNR_T 2.5, 7:1 bars, MTF 0.5 at 0.2 cy/px:
    MRTD = π²/(2√14) · 2.5 · 0.040 · 0.2 / (0.5 · √6) = 21.5 mK."""
    f = np.array([0.1, 0.2, 0.3])
    c = mrtd(Curve(f, [0.8, 0.5, 0.25], x_unit="cy/px"), netd=0.040, frame_rate=30)
    assert c(0.2) == pytest.approx(0.021537, abs=1e-6)


def test_mrtd_in_cycles_per_mrad_equals_cycles_per_pixel():
    camera = CameraGeometry(ifov_mrad=0.5)
    px = gauss_mtf_curve()
    mrad = px.to_units(x_unit="cy/mrad", camera=camera)
    a, b = mrtd(px, netd=0.05), mrtd(mrad, netd=0.05, camera=camera)
    np.testing.assert_allclose(a.y, b.y, rtol=1e-12)
    assert b.x_unit == "cy/mrad" and b.x[-1] == pytest.approx(0.8)
    with pytest.raises(FidelityError, match="IFOV"):
        mrtd(mrad, netd=0.05)


def test_mrtd_with_3d_noise_components():
    rng = np.random.default_rng(6)
    t, v, h = 40, 48, 64
    cube = (1000 + rng.normal(0, 2, (1, v, h)) + rng.normal(0, 1.5, (1, 1, h)) + rng.normal(0, 1.0, (t, 1, h))
            + rng.normal(0, 3, (t, v, h)))
    noise = irf.noise.noise3d(cube, corrected=False, spectra=False)
    m = gauss_mtf_curve()
    plain = mrtd(m, netd=0.05, frame_rate=30)
    with_noise = mrtd(m, netd=0.05, noise=noise, frame_rate=30)
    s = noise.sigma
    width, frames = 1 / (2 * plain.x), 6.0
    k = np.sqrt(1 + frames * (s["vh"] / s["tvh"]) ** 2 + 7 * width * (s["th"] / s["tvh"]) ** 2
                + 7 * width * frames * (s["h"] / s["tvh"]) ** 2)
    np.testing.assert_allclose(with_noise.y, plain.y * k, rtol=1e-12)
    assert (k > 1.5).all()
    horizontal = mrtd(m, netd=0.05, noise=noise, frame_rate=30, orientation="horizontal")
    k_h = np.sqrt(1 + frames * (s["vh"] / s["tvh"]) ** 2 + 7 * width * (s["tv"] / s["tvh"]) ** 2
                  + 7 * width * frames * (s["v"] / s["tvh"]) ** 2)
    np.testing.assert_allclose(horizontal.y, plain.y * k_h, rtol=1e-12)
    with pytest.raises(FidelityError, match="NETD"):
        mrtd(m, noise=noise)  # measured without sitf=: no NETD


def test_mrtd_bad_input():
    m = gauss_mtf_curve(top=0.5, points=51)
    with pytest.warns(MRTDWarning, match="ends at"):
        cut = mrtd(m, netd=0.05)
    assert cut.x[-1] < 0.45 and cut.meta["ends_at"] is not None
    for bad in (0, -0.05, math.inf):
        with pytest.raises(FidelityError, match="netd"):
            mrtd(m, netd=bad)
    with pytest.raises(FidelityError, match="NETD"):
        mrtd(m)
    with pytest.raises(FidelityError, match="at least 3"):
        mrtd(Curve([0, 0.1, 0.2], [1, 0.9, 0.8], x_unit="cy/px"), netd=0.05)
    below = mrtd(Curve([0, 0.1, 0.2, 0.3, 0.6], [1, 0.9, 0.8, 0.6, 0.3], x_unit="cy/px"), netd=0.05)
    assert below.x.tolist() == [0.1, 0.2, 0.3]  # above Nyquist left out
    with pytest.warns(irf.curves.CurveUnitsWarning):
        mrtd(Curve([0, 0.1, 0.2, 0.3], [1, 0.9, 0.8, 0.6]), netd=0.05)
    with pytest.raises(FidelityError, match="display_mtf"):
        mrtd(m, netd=0.05, display_mtf=Curve([0, 0.1, 0.2], [1, 0.9, 0.8], x_unit="cy/px"))
    display = mrtd(m, netd=0.05, display_mtf=Curve([0, 0.25, 0.5], [1, 0.75, 0.5], x_unit="cy/px"), min_mtf=0.001)
    plain = mrtd(m, netd=0.05, min_mtf=0.001)
    np.testing.assert_allclose(display.y * (1 - display.x), plain.y, rtol=1e-12)


# --------------------------------------------------------------------------- measured MRTD
def simulated_frames(frequencies, deltas, otf, noise, repeats, seed, levels_sign=1.0):
    rng = np.random.default_rng(seed)
    frames, freqs, dts = [], [], []
    for f in frequencies:
        unit, _ = frame_for(f, otf, 0.2)
        for dt in deltas:
            for _ in range(repeats):
                frames.append(levels_sign * dt * unit + rng.normal(0, noise, unit.shape))
                freqs.append(f)
                dts.append(dt)
    return frames, freqs, dts


def test_measured_mrtd_agrees_with_the_model():
    """Frames of 7:1 bars with white noise σ = NETD (signal 1 per K): the objective MRTD
    measured on them matches the model for one frame at equal threshold."""
    otf, netd = gaussian_otf(2.0), 1.0
    freqs = (0.05, 0.07, 0.09, 0.11)
    deltas = np.round(np.arange(0.1, 3.01, 0.1), 2)
    frames, fs, dts = simulated_frames(freqs, deltas, otf, netd, 3, seed=7)
    measured = measured_mrtd(frames, frequencies=fs, delta_t=dts)
    model = mrtd(Curve(np.linspace(0, 0.2, 201), [system_mtf(otf, x) for x in np.linspace(0, 0.2, 201)],
                       x_unit="cy/px"), netd=netd)
    assert measured.x.tolist() == list(freqs) and measured.y_unit == "delta_K"
    np.testing.assert_allclose(measured.y, model(measured.x), rtol=0.1)
    assert (np.diff(measured.y) > 0).all()


def test_measured_mrtd_hot_and_cold_bars_and_polarity():
    otf = gaussian_otf(1.5)
    freqs, deltas = (0.05, 0.08, 0.11), np.array([0.2, 0.5, 1.0, 2.0, 4.0])
    hot = simulated_frames(freqs, deltas, otf, 1.0, 1, seed=8)
    cold = simulated_frames(freqs, deltas, otf, 1.0, 1, seed=9, levels_sign=-1.0)
    both = measured_mrtd(hot[0] + cold[0], frequencies=hot[1] + cold[1], delta_t=hot[2] + [-d for d in cold[2]])
    only_hot = measured_mrtd(hot[0], frequencies=hot[1], delta_t=hot[2])
    only_cold = measured_mrtd(cold[0], frequencies=cold[1], delta_t=[-d for d in cold[2]])
    np.testing.assert_allclose(both.y, (only_hot.y + only_cold.y) / 2, rtol=0.03)  # located on one frame or two
    frames, fs, dts = hot
    dts = list(dts)
    dts[2] = -dts[2]  # a hot frame labelled cold: inverted polarity
    with pytest.warns(BarPolarityWarning, match="frame 2"):
        measured_mrtd(frames, frequencies=fs, delta_t=dts)


def test_measured_mrtd_bad_input():
    otf = gaussian_otf(1.5)
    frames, fs, dts = simulated_frames((0.05, 0.08, 0.11, 0.4), (0.5, 1.0, 2.0), otf, 1.0, 1, seed=10)
    with pytest.warns(MRTDWarning, match="0.4"):
        curve = measured_mrtd(frames, frequencies=fs, delta_t=dts)
    assert curve.meta["unresolved"] == [0.4] and (curve.y > 0).all()
    zero = list(dts)
    zero[1] = 0.0
    with pytest.raises(FidelityError, match="frame 1: ΔT = 0"):
        measured_mrtd(frames, frequencies=fs, delta_t=zero)
    with pytest.raises(FidelityError, match="one number per frame"):
        measured_mrtd(frames, frequencies=fs[:-1], delta_t=dts)
    with pytest.raises(FidelityError, match="Nyquist"):
        measured_mrtd(frames, frequencies=[0.6] * len(frames), delta_t=dts)
    with pytest.raises(FidelityError, match="at least 3 resolved"):
        quiet(measured_mrtd, frames[:6], frequencies=fs[:6], delta_t=dts[:6])


# --------------------------------------------------------------------------- bad input
def test_no_bars_and_flat_targets_are_refused():
    rng = np.random.default_rng(11)
    noise = 100 + rng.normal(0, 1, (64, 64))
    with pytest.raises(FidelityError, match="no bar target"):
        ctf_from_bars(noise, frequency=0.1)
    with pytest.raises(FidelityError, match="flat target"):
        ctf_from_bars(noise, frequency=0.1, roi=(8, 56, 8, 56), background=100.0)
    flat = four_bar(0.1, (64, 64), levels=(50.0, 50.0))
    with pytest.raises(FidelityError, match="flat target"):
        ctf_from_bars(flat, frequency=0.1, roi=(0, 64, 0, 64))
    block = np.zeros((80, 80))
    block[22:58, 22:58] = 1.0
    block = block + rng.normal(0, 0.01, block.shape)
    with pytest.raises(FidelityError, match="no bars"):
        ctf_from_bars(block, frequency=0.1, roi=(0, 80, 0, 80), orientation="vertical")


def test_frequency_at_or_above_nyquist_is_refused():
    image = four_bar(0.3, (40, 40))
    for f in (0.5, 0.6, 1.3):
        with pytest.raises(FidelityError, match="Nyquist"):
            ctf_from_bars(image, frequency=f)


def test_saturated_bars_warn():
    image, _ = frame_for(0.1, gaussian_otf(1.0), 0.0, levels=(100.0, 300.0))
    clipped = np.clip(image, 0, 255).round().astype(np.uint8)
    with pytest.warns(BarClippingWarning, match="clipping level"):
        ctf_from_bars(clipped, frequency=0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BarClippingWarning)
        ctf_from_bars(image.round().astype(np.uint16), frequency=0.1)  # far from 65535


def test_inverted_polarity_warns():
    """A defocused camera (an OTF with a negative lobe) reverses the bars' contrast."""
    defocus = OTF(name="defocus", radial=lambda rho: np.sinc(6.0 * rho), support=6.0)
    image, _ = frame_for(0.2, defocus, 0.0, levels=(0.0, 100.0))  # sinc(1.2) < 0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        reading = ctf_from_bars(image, frequency=0.2, roi=(0, image.shape[0], 0, image.shape[1]),
                                orientation="vertical")
    assert any(issubclass(w.category, BarPolarityWarning) and "inverted polarity" in str(w.message) for w in caught)
    assert reading.ctf < 0 and reading.mtf == pytest.approx(system_mtf(defocus, 0.2), abs=0.01)


def test_ctf_is_never_above_one():
    rng = np.random.default_rng(12)
    for _ in range(30):
        f = rng.uniform(0.03, 0.35)
        otf = gaussian_otf(rng.uniform(0.2, 1.5))
        image, _ = frame_for(f, otf, rng.uniform(0, 1), levels=(0.0, 10.0))
        noisy = image + rng.normal(0, rng.uniform(0.01, 0.5), image.shape)
        try:
            reading = quiet(ctf_from_bars, noisy, frequency=f)
        except FidelityError:
            continue  # too noisy to find: refused, not misread
        assert reading.ctf <= 1.0 and reading.mtf <= 1.2


def test_wrong_background_is_refused():
    image, _ = frame_for(0.1, gaussian_otf(1.0), 0.0, levels=(100.0, 200.0))
    with pytest.raises(FidelityError, match="differs from the level"):
        ctf_from_bars(image, frequency=0.1, background=180.0)


def test_bad_arguments_are_refused():
    image = four_bar(0.1, (64, 64))
    with pytest.raises(FidelityError, match="method"):
        ctf_from_bars(image, frequency=0.1, method="peak")
    with pytest.raises(FidelityError, match="2-D"):
        ctf_from_bars(np.zeros((2, 64, 64)), frequency=0.1)
    nan = image.copy()
    nan[3, 4] = np.nan
    with pytest.raises(FidelityError, match="non-finite"):
        ctf_from_bars(nan, frequency=0.1)
    with pytest.raises(FidelityError, match="roi"):
        ctf_from_bars(image, frequency=0.1, roi=(0, 80, 0, 64))
    with pytest.raises(FidelityError, match="orientation"):
        ctf_from_bars(image, frequency=0.1, roi=(0, 64, 0, 64), orientation="up")
    with pytest.raises(FidelityError, match="at least 3 frequencies"):
        ctf_curve([image, image], frequencies=[0.1, 0.2])
    with pytest.raises(FidelityError, match="distinct"):
        ctf_curve([image] * 3, frequencies=[0.1, 0.1, 0.2])


@pytest.mark.parametrize("module", ["irfidelity.targets", "irfidelity.curves.bars", "irfidelity.curves.ctf",
                                    "irfidelity.curves.mrtd"])
def test_docstring_examples(module):
    import doctest
    import importlib

    mod = importlib.import_module(module)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BarWarning)
        result = doctest.testmod(mod, extraglobs={"np": np, "Curve": Curve}, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0 and result.attempted > 0
