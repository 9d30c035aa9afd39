"""Tests of the performance curves (issue 4): Curve, CSV reading, MTF from LSF/ESF, MTF50, SiTF
fit, NETD and the curve similarity of the paper (eqs. 1-4). The slanted edge is in test_edge.py,
units in test_curve_units.py.

Truth is analytic wherever possible (see edge_render.py); a logistic SiTF
A + B/(1 + exp(-(x - x0)/s)) has central slope B/(4 s).
"""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

import irfidelity
from edge_render import erf, gauss_mtf, gauss_mtf50
from irfidelity.curves import (Curve, CurveSimilarity, SiTFFit, curve_similarity, mtf50,
                               mtf_from_esf, mtf_from_lsf, mtf_similarity, netd, sitf_fit, sitf_similarity)
from irfidelity.errors import FidelityError

DATA = pathlib.Path(__file__).parent / "data" / "curves"
JADE = DATA / "pyradi_jade_lwir_calibration_sitf.csv"

pytestmark = pytest.mark.filterwarnings("ignore::irfidelity.curves.CurveUnitsWarning")


# --------------------------------------------------------------------------- Curve
class TestCurve:
    def test_basic(self):
        c = Curve([0, 1, 2], [1.0, 0.5, 0.1], name="m", x_unit="cycles/pixel")
        assert c.x.dtype == np.float64 and len(c) == 3 and c.x_unit == "cy/px"
        with pytest.raises(ValueError):
            c.x[0] = 5  # read-only

    @pytest.mark.parametrize("x,y,msg", [
        ([0, 1], [1, 0.5], "at least 3"),
        ([0, 1, 1], [1, 0.5, 0.2], "strictly increasing"),
        ([0, 2, 1], [1, 0.5, 0.2], "strictly increasing"),
        ([0, 1, 2], [1, np.nan, 0.2], "finite"),
        ([0, 1, np.inf], [1, 0.5, 0.2], "finite"),
        ([0, 1, 2], [1, 0.5], "same length"),
        ([[0, 1, 2]], [[1, 0.5, 0.2]], "1-D"),
    ])
    def test_rules(self, x, y, msg):
        with pytest.raises(FidelityError, match=msg):
            Curve(x, y)
        with pytest.raises(ValueError):
            Curve(x, y)

    def test_units_convert_and_relabel(self):
        c = Curve([0, 0.25, 0.5], [1, 0.6, 0.2], x_unit="cy/px")
        m = c.to_units(x_unit="cycles/mrad", camera=irfidelity.curves.CameraGeometry(ifov_mrad=0.05))
        assert (m.x_unit, m.y_unit) == ("cy/mrad", None)
        np.testing.assert_allclose(m.x, [0, 5, 10])
        np.testing.assert_array_equal(m.y, c.y)
        assert c.with_units(y_unit="%").y_unit == "%" and c.with_units(y_unit="%").x_unit == "cy/px"
        assert c.with_units(x_unit=None).x_unit is None
        with pytest.raises(FidelityError, match="--ifov MRAD"):
            c.to_units(x_unit="cy/mrad")
        assert c != c.with_units(y_unit="1") and c == Curve([0, 0.25, 0.5], [1, 0.6, 0.2], x_unit="cycles/pixel")

    def test_csv(self, tmp_path):
        p = tmp_path / "m.csv"
        p.write_text("# comment\nfreq, mtf\n0, 1\n0.1, 0.8\n\n0.2, 0.5\n")
        c = Curve.from_csv(p)
        np.testing.assert_allclose(c.y, [1, 0.8, 0.5])
        q = tmp_path / "w.txt"
        q.write_text("0 1\n0.1\t0.8\n0.2   0.5\n")
        np.testing.assert_allclose(Curve.from_csv(q).x, [0, 0.1, 0.2])
        bad = tmp_path / "bad.csv"
        bad.write_text("x,y\n0,1\n0.1,abc\n0.2,0.5\n")
        with pytest.raises(FidelityError, match=r"bad\.csv:3: not a number"):
            Curve.from_csv(bad)
        ragged = tmp_path / "ragged.csv"
        ragged.write_text("0,1\n0.1,0.8,3\n0.2,0.5\n")
        with pytest.raises(FidelityError, match=r"ragged\.csv:2"):
            Curve.from_csv(ragged)
        with pytest.raises(FidelityError, match="cannot read"):
            Curve.from_csv(tmp_path / "missing.csv")

    def test_csv_real_multicolumn(self):
        # four columns, two series (instrument temperatures) one after the other
        with pytest.raises(FidelityError, match=r"found 4 columns: instrument_temp_C, dl_floor, "
                                                r"blackbody_temp_C, digital_level; choose two"):
            Curve.from_csv(JADE)
        with pytest.raises(FidelityError, match=r"strictly increasing.*row filter such as instrument_temp_C=17\.1"):
            Curve.from_csv(JADE, columns=("blackbody_temp_C", "digital_level"))
        cold = Curve.from_csv(JADE, columns=("blackbody_temp_C", "digital_level"), where={"instrument_temp_C": 17.1})
        warm = Curve.from_csv(JADE, columns=(2, 3), where={0: 34.4})
        assert len(cold) == len(warm) == 9 and cold.x.tolist() == list(range(50, 451, 50))
        assert (cold.x_unit, cold.y_unit) == ("degC", "counts")  # blackbody_temp_C: absolute; digital_level
        assert (warm.x_unit, warm.y_unit) == ("degC", "counts")  # by index: the header still names the units
        assert cold.y[0] == 4571 and warm.y[-1] == 14921
        with pytest.raises(FidelityError, match=r"no row has instrument_temp_C = 20 \(values present: 17\.1, 34\.4\)"):
            Curve.from_csv(JADE, columns=("blackbody_temp_C", "digital_level"), where={"instrument_temp_C": 20})
        with pytest.raises(FidelityError, match="no column named 'T'"):
            Curve.from_csv(JADE, columns=("T", "digital_level"))
        with pytest.raises(FidelityError, match="out of range"):
            Curve.from_csv(JADE, columns=(0, 4))

    def test_csv_units_from_header(self, tmp_path):
        p = tmp_path / "m.csv"
        p.write_text("freq_cy_per_mrad,mtf\n0,1\n0.5,0.6\n1,0.2\n")
        c = Curve.from_csv(p)
        assert (c.x_unit, c.y_unit) == ("cy/mrad", "1")
        assert Curve.from_csv(p, x_unit="cycles/mrad").x_unit == "cy/mrad"
        with pytest.raises(FidelityError, match=r"column 'freq_cy_per_mrad' is in cy/mrad, but the x unit was "
                                                r"given as cy/px"):
            Curve.from_csv(p, x_unit="cy/px")
        q = tmp_path / "s.csv"
        q.write_text("K,signal\n1,10\n2,20\n3,30\n")  # K alone: a difference or an absolute temperature?
        assert Curve.from_csv(q).x_unit is None
        assert Curve.from_csv(q, x_unit="dT").x_unit == "delta_K"

    def test_cli_text_helpers(self):
        from irfidelity.curves.table import parse_columns, parse_where

        assert parse_columns("blackbody_temp_C,digital_level") == ("blackbody_temp_C", "digital_level")
        assert parse_columns(" 2 , 3 ") == (2, 3)
        assert parse_where("instrument_temp_C=17.1,dl_floor=3625") == {"instrument_temp_C": 17.1, "dl_floor": 3625.0}
        for bad in ("a", "a,b,c", ",b"):
            with pytest.raises(FidelityError, match="two names or indices"):
                parse_columns(bad)
        with pytest.raises(FidelityError, match="name=number"):
            parse_where("instrument_temp_C")


# --------------------------------------------------------------------------- MTF from LSF / ESF
@pytest.mark.parametrize("sigma", [0.8, 1.3, 2.0])
def test_gaussian_lsf(sigma):
    x = np.arange(-64, 65, dtype=float)
    c = mtf_from_lsf(np.exp(-x ** 2 / (2 * sigma ** 2)))
    assert c.x_unit == "cy/px" and c.y[0] == 1.0
    assert c.x[-1] == pytest.approx(0.5, abs=0.01)  # up to Nyquist
    # the DFT of a sampled Gaussian is the aliased sum of the continuous MTF
    aliased = sum(gauss_mtf(c.x - k, sigma) for k in range(-3, 4)) / sum(gauss_mtf(k, sigma) for k in range(-3, 4))
    assert np.abs(c.y - aliased).max() <= 1e-3
    if sigma >= 1.2:  # aliasing below 1e-3 at Nyquist: the continuous MTF itself
        assert np.abs(c.y - gauss_mtf(c.x, sigma)).max() <= 1e-3
    assert mtf50(c) == pytest.approx(gauss_mtf50(sigma), rel=5e-3)
    assert mtf50(c, smooth=True) == pytest.approx(gauss_mtf50(sigma), rel=5e-3)


def test_lsf_options():
    x = np.arange(-32, 33, dtype=float)
    lsf = np.exp(-x ** 2 / 8)
    c = mtf_from_lsf(lsf, dx=0.5, pad=256)
    assert c.x[1] == pytest.approx(1 / (256 * 0.5)) and c.x[-1] == pytest.approx(1.0)
    assert c.x_unit is None  # dx != 1: the unit is the caller's
    # sigma = 2 samples = 1 unit
    assert np.abs(c.y - gauss_mtf(c.x, 1.0)).max() <= 1e-3
    for w in ("hamming", "tukey", "hann"):
        assert np.abs(mtf_from_lsf(lsf, window=w).y - gauss_mtf(np.arange(33) / 65, 2.0)).max() < 1e-2  # window bias
    with pytest.raises(FidelityError, match="sums to zero"):
        mtf_from_lsf([1.0, -2.0, 1.0])
    with pytest.raises(FidelityError, match="pad"):
        mtf_from_lsf(lsf, pad=10)
    with pytest.raises(FidelityError, match="dx"):
        mtf_from_lsf(lsf, dx=0)


@pytest.mark.parametrize("dx", [1.0, 0.25])
@pytest.mark.parametrize("falling", [False, True])
def test_erf_esf(dx, falling):
    sigma = 1.2
    x = np.arange(-40, 40 + dx / 2, dx)
    esf = 0.5 * (1 + erf(x / (sigma * math.sqrt(2))))
    c = mtf_from_esf(esf[::-1] if falling else esf, dx=dx)
    assert np.abs(c.y - gauss_mtf(c.x, sigma)).max() <= 2e-2
    assert mtf50(c) == pytest.approx(gauss_mtf50(sigma), rel=5e-3)
    # without the derivative correction the (sampled) box of the difference shows up
    raw = mtf_from_esf(esf, dx=dx, correct=False)
    np.testing.assert_allclose(raw.y, c.y * np.abs(np.sinc(c.x * dx)), atol=1e-12)


# --------------------------------------------------------------------------- MTF50
def test_mtf50_linear_interpolation_and_errors():
    c = Curve([0, 0.1, 0.2, 0.3], [1.0, 0.7, 0.4, 0.2])
    assert mtf50(c) == pytest.approx(0.1 + 0.1 * (0.2 / 0.3))
    assert mtf50(Curve([0, 0.1, 0.2], [1.0, 0.5, 0.2])) == pytest.approx(0.1)
    with pytest.raises(ValueError, match="never falls to 0.5"):
        mtf50(Curve([0, 0.1, 0.2], [1.0, 0.9, 0.8]))
    with pytest.raises(FidelityError, match="never falls to 0.5"):
        mtf_similarity(Curve([0, 0.1, 0.2], [1.0, 0.9, 0.8]), c)
    with pytest.raises(FidelityError, match="already"):
        mtf50(Curve([0.3, 0.4, 0.5], [0.4, 0.3, 0.2]))
    with pytest.raises(FidelityError, match="7 points"):
        mtf50(c, smooth=True)


def test_mtf50_smooth_noisy():
    rng = np.random.default_rng(7)
    f = np.linspace(0, 0.5, 60)
    y = gauss_mtf(f, 1.0) + rng.normal(0, 0.01, f.size)
    y[0] = 1.0
    assert mtf50(Curve(f, y), smooth=True) == pytest.approx(gauss_mtf50(1.0), rel=0.02)


# --------------------------------------------------------------------------- SiTF
def logistic(x, A, B, x0, s):
    return A + B / (1 + np.exp(-(x - x0) / s))


@pytest.mark.parametrize("B", [800.0, -800.0])
def test_sitf_logistic_central_slope(B):
    x = np.linspace(-20, 30, 101)
    y = logistic(x, 1000.0, B, 4.0, 3.0)
    f = sitf_fit(Curve(x, y), method="logistic")
    assert f.slope == pytest.approx(B / 12.0, rel=1e-6)
    assert f.intercept + f.slope * 4.0 == pytest.approx(1000 + B / 2, rel=1e-9)
    assert f.lo == pytest.approx(4 - 3 * math.log(9), rel=1e-6)
    assert f.hi == pytest.approx(4 + 3 * math.log(9), rel=1e-6)
    assert f.r2 == pytest.approx(1.0)
    # with noise, still close
    rng = np.random.default_rng(1)
    fn = sitf_fit(Curve(x, y + rng.normal(0, 5, x.size)), method="logistic")
    assert fn.slope == pytest.approx(B / 12.0, rel=0.02)
    # the band rule is the least-squares secant of the 10-90 % band: a bit shallower
    fb = sitf_fit(Curve(x, y))
    assert 0.75 < fb.slope / (B / 12.0) < 1.0


def s_curve_exact_middle(x, slope=25.0, floor=500.0, ceil=4500.0, knee=8.0):
    """Linear middle, saturating smoothly (tanh knees) at both ends."""
    lin = floor + (ceil - floor) / 2 + slope * x
    lo_k, hi_k = floor + 0.05 * (ceil - floor), ceil - 0.05 * (ceil - floor)
    y = lin.copy()
    m = lin < lo_k
    y[m] = lo_k - knee * slope * np.tanh((lo_k - lin[m]) / (knee * slope)) * 0.05 * (ceil - floor) / (knee * slope)
    m = lin > hi_k
    y[m] = hi_k + knee * slope * np.tanh((lin[m] - hi_k) / (knee * slope)) * 0.05 * (ceil - floor) / (knee * slope)
    return y


def test_sitf_band_exact_linear_middle_under_noise():
    x = np.linspace(-150, 150, 121)
    y = s_curve_exact_middle(x)
    f = sitf_fit(Curve(x, y))
    assert f.slope == pytest.approx(25.0, rel=1e-9) and f.linearity_error < 1e-9 and f.r2 == pytest.approx(1)
    rng = np.random.default_rng(5)
    for _ in range(5):
        fn = sitf_fit(Curve(x, y + rng.normal(0, 20, x.size)))
        assert fn.slope == pytest.approx(25.0, rel=0.02)
    # inverted polarity
    fi = sitf_fit(Curve(x, -y))
    assert fi.slope == pytest.approx(-25.0, rel=1e-9)
    assert netd(10.0, fi) == pytest.approx(0.4)


def test_sitf_errors():
    x = np.linspace(0, 10, 11)
    with pytest.raises(ValueError, match="flat"):
        sitf_fit(Curve(x, np.full(11, 7.0)))
    step = np.where(x < 5, 100.0, 4000.0)  # floor straight to saturation
    with pytest.raises(ValueError, match="no linear region"):
        sitf_fit(Curve(x, step))
    with pytest.raises(ValueError, match="window"):
        sitf_fit(Curve(x, x), window=(0.5, 1.5))
    with pytest.raises(ValueError, match="lo_frac"):
        sitf_fit(Curve(x, x), lo_frac=0.9, hi_frac=0.1)
    with pytest.raises(ValueError, match="method"):
        sitf_fit(Curve(x, x), method="spline")
    with pytest.raises(ValueError, match="slope is 0"):
        netd(1.0, 0.0)


def test_sitf_real_jade_calibration():
    curves = {t: Curve.from_csv(JADE, columns=("blackbody_temp_C", "digital_level"), where={"instrument_temp_C": t})
              for t in (17.1, 34.4)}
    cold, warm = curves[17.1], curves[34.4]
    for c in (cold, warm):
        f = sitf_fit(c)
        local = np.diff(c.y) / np.diff(c.x)
        assert local.min() < f.slope < local.max()  # a secant of the convex (Planck) response
        assert f.r2 > 0.97 and 0 < f.linearity_error < 0.2
    s = sitf_similarity(cold, warm)
    fc = sitf_fit(cold)
    fw = sitf_fit(warm, window=(fc.lo, fc.hi))
    assert s.a == pytest.approx(fc.slope) and s.b == pytest.approx(fw.slope)
    assert s.rho > 0.999 and 0.95 < s.mu <= 1 and s.value == pytest.approx(s.mu * abs(s.rho))
    assert 0 < s.area < 0.2 and s.ccc < s.rho  # offset between the series shows in ccc and area, not rho
    assert (s.x_unit, s.y_unit, s.notes) == ("degC", "counts", ())
    # the same blackbody temperatures in kelvin: converted, same result
    warm_k = warm.to_units(x_unit="K")
    s_k = sitf_similarity(cold, warm_k)
    assert s_k.value == pytest.approx(s.value, rel=1e-12)
    assert s_k.notes == ("simulated x axis converted from K to degC",)


def test_sitf_similarity_windows():
    x = np.linspace(-150, 150, 121)
    real = Curve(x, s_curve_exact_middle(x, slope=25.0))
    sim = Curve(x, s_curve_exact_middle(x, slope=20.0))
    s_real = sitf_similarity(real, sim)
    s_each = sitf_similarity(real, sim, window="each")
    assert s_each.a == pytest.approx(25.0) and s_each.b == pytest.approx(20.0)
    assert s_each.mu == pytest.approx(2 * 25 * 20 / (25 ** 2 + 20 ** 2))
    assert s_real.a == pytest.approx(25.0)
    s_fix = sitf_similarity(real, sim, window=(-40, 40))
    assert s_fix.b == pytest.approx(20.0)


# --------------------------------------------------------------------------- similarity
def test_similarity_paper_arithmetic():
    c = Curve([0, 0.5, 1.0], [1.0, 0.6, 0.1])
    s = curve_similarity(c, c, a=0.2, b=0.4)
    assert s.mu == pytest.approx(0.8) and s.rho == pytest.approx(1.0) and s.value == pytest.approx(0.8)
    assert isinstance(s, CurveSimilarity) and s.points.size == 64
    s2 = curve_similarity(c, c, a=0.2, b=0.4, alpha=2, beta=3)
    assert s2.value == pytest.approx(0.64)


def test_similarity_identical_and_regridded():
    f = np.linspace(0, 1, 101)
    g = np.linspace(0, 1, 37)
    a = Curve(f, gauss_mtf(f, 1.0))
    b = Curve(g, gauss_mtf(g, 1.0))
    s = mtf_similarity(a, a)
    assert s.value == 1.0 and s.rho == 1.0 and s.ccc == pytest.approx(1.0) and s.area == 0.0
    s = mtf_similarity(a, b)
    assert s.value == pytest.approx(1.0, abs=2e-3) and s.area < 5e-3


def test_similarity_limits():
    x = np.linspace(0, 1, 11)
    up, down = Curve(x, x), Curve(x, 1 - x)
    s = curve_similarity(up, down, a=1, b=1)
    assert s.rho == pytest.approx(-1.0) and s.value == pytest.approx(1.0) and s.ccc == pytest.approx(-1.0)
    flat1, flat2 = Curve(x, np.full(11, 0.3)), Curve(x, np.full(11, 0.7))
    s = curve_similarity(flat1, flat2, a=1, b=1)
    assert s.rho == 1.0 and s.value == 1.0 and not math.isnan(s.ccc)
    s = curve_similarity(flat1, up, a=1, b=1)
    assert s.rho == 0.0 and s.value == 0.0
    s = curve_similarity(up, up, a=0, b=0)
    assert s.mu == 1.0 and s.value == 1.0
    s = curve_similarity(up, up, a=0, b=3)
    assert s.mu == 0.0 and s.value == 0.0
    s = curve_similarity(up, up, a=1e300, b=1e300)
    assert s.mu == 1.0
    for v in s.to_dict().values():
        assert not (isinstance(v, float) and math.isnan(v))


def test_similarity_overlap_and_points():
    a = Curve([0, 1, 2], [1, 0.5, 0.2])
    b = Curve([1, 2, 3], [0.9, 0.4, 0.1])
    s = curve_similarity(a, b, a=1, b=1, points=5)
    np.testing.assert_allclose(s.points, [1, 1.25, 1.5, 1.75, 2])
    s = curve_similarity(a, b, a=1, b=1, points=[1.0, 1.5, 2.0])
    assert s.points.tolist() == [1.0, 1.5, 2.0]
    with pytest.raises(ValueError, match="overlap"):
        curve_similarity(a, b, a=1, b=1, points=[0.5, 1.5])
    with pytest.raises(ValueError, match="do not overlap"):
        curve_similarity(a, Curve([3, 4, 5], [1, 0.5, 0.2]), a=1, b=1)
    with pytest.raises(ValueError, match="do not overlap"):  # touching at one point only
        curve_similarity(a, Curve([2, 4, 5], [1, 0.5, 0.2]), a=1, b=1)
    with pytest.raises(ValueError):
        curve_similarity(a, b, a=1, b=1, points=1)
    with pytest.raises(ValueError, match="alpha"):
        curve_similarity(a, b, a=1, b=1, alpha=-1)
    with pytest.raises(ValueError, match="finite"):
        curve_similarity(a, b, a=float("nan"), b=1)


def test_ccc_and_area_are_sharper_than_rho():
    f = np.linspace(0, 0.5, 64)
    real = Curve(f, gauss_mtf(f, 1.0))
    sim = Curve(f, gauss_mtf(f, 1.4))
    s = mtf_similarity(real, sim)
    assert s.rho > 0.97  # the paper's rho barely notices
    assert s.ccc < s.rho - 0.03 and s.area > 0.05


hyp = pytest.importorskip("hypothesis")
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_vals = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(_vals, _vals), min_size=3, max_size=30), _vals, _vals,
       st.floats(0, 4), st.floats(0, 4))
def test_similarity_properties(ys, a, b, alpha, beta):
    x = np.arange(len(ys), dtype=float)
    r = Curve(x, [p[0] for p in ys])
    s = Curve(x, [p[1] for p in ys])
    one = curve_similarity(r, s, a=a, b=b, alpha=alpha, beta=beta, points=17)
    two = curve_similarity(s, r, a=b, b=a, alpha=alpha, beta=beta, points=17)
    for v in (one.value, one.mu, one.rho, one.ccc, one.area):
        assert math.isfinite(v)
    assert 0.0 <= one.value <= 1.0 and 0.0 <= one.mu <= 1.0 and -1.0 <= one.rho <= 1.0
    assert -1.0 <= one.ccc <= 1.0 and 0.0 <= one.area <= 1.0
    assert one.value == pytest.approx(two.value, abs=1e-12)
    assert one.rho == pytest.approx(two.rho, abs=1e-12)
    assert one.ccc == pytest.approx(two.ccc, abs=1e-9)
    self_sim = curve_similarity(r, r, a=a, b=a, points=17)
    assert self_sim.value == pytest.approx(1.0) or np.ptp(r.y) == 0


def test_sitffit_is_dataclass():
    f = sitf_fit(Curve(np.arange(10.0), 3 * np.arange(10.0) + 1))
    assert isinstance(f, SiTFFit) and f.slope == pytest.approx(3) and f.intercept == pytest.approx(1)
    assert f.to_dict()["method"] == "band"


@pytest.mark.parametrize("module", ["curve", "table", "units", "similarity", "mtf", "edge", "sitf"])
def test_docstring_examples(module):
    """The Examples sections of the curves package run as written."""
    import doctest
    import importlib

    mod = importlib.import_module(f"irfidelity.curves.{module}")
    result = doctest.testmod(mod, extraglobs={"np": np, "Curve": Curve}, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0 and (result.attempted > 0 or module == "table")
