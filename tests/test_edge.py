"""Slanted-edge MTF (ISO 12233:2023 e-SFR): analytic edges, the real crops against sfrmat5,
the polynomial edge fit on curved edges, and images without a usable edge (issue 14 items 3, 8)."""

from __future__ import annotations

import glob
import math
import pathlib
import warnings

import numpy as np
import pytest

from edge_render import edge_truth, edge_truth_mtf50, render_edge
from irfidelity.curves import Curve, EdgeWarning, mtf50, mtf_from_edge, mtf_similarity
from irfidelity.errors import FidelityError, FidelityWarning
from irfidelity.frames import load_frame

DATA = pathlib.Path(__file__).parent / "data"
CROPS = {  # MTF50 (cycles/pixel along the edge normal, green channel, whole crop) from sfrmat5 v1
    "sfr_edge_x0552_y1976_F16.png": 0.1542,
    "sfr_edge_x2084_y0616_F2.png": 0.3007,
    "sfr_edge_x2088_y0616_F2_8.png": 0.4651,
}
#: agreement with sfrmat5. The F2 crop's MTF sits on a plateau near 0.5 (slope -0.7 per cy/px),
#: where 0.002 of MTF moves MTF50 by 1 %; measured: default +0.1/+0.9/+0.4 %, linear +0.6/+0.6/-0.8 %
SFRMAT5_TOLERANCE = 0.015


def quiet_edge(img, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error", EdgeWarning)
        return mtf_from_edge(img, **kw)


def crop(name):
    return load_frame(DATA / "curves" / name, channel="G")


# --------------------------------------------------------------------------- analytic edges
@pytest.mark.parametrize("angle", [2.0, 5.0, 8.0, 12.0, -5.0])
@pytest.mark.parametrize("sigma", [0.5, 1.0, 1.5])
def test_slanted_edge_analytic(angle, sigma):
    c = quiet_edge(render_edge(angle_deg=angle, sigma=sigma))
    assert (c.x_unit, c.y_unit) == ("cy/px", "1") and c.x[-1] >= 1.0
    assert c.meta["angle_deg"] == pytest.approx(angle, abs=0.05) and c.meta["edge_fit_order"] == 5
    assert mtf50(c) == pytest.approx(edge_truth_mtf50(sigma, angle), rel=0.03)
    sel = c.x <= 1.0
    assert np.abs(c.y[sel] - edge_truth(c.x[sel], sigma, angle)).max() < 0.04
    assert c.meta["edge_residual_px"] < 0.05


@pytest.mark.parametrize("horizontal", [False, True])
@pytest.mark.parametrize("invert", [False, True])
def test_slanted_edge_orientation_polarity(horizontal, invert):
    c = quiet_edge(render_edge(angle_deg=5.0, sigma=1.0, horizontal=horizontal, invert=invert))
    assert c.meta["orientation"] == ("horizontal" if horizontal else "vertical")
    assert c.meta["polarity"] == (-1 if invert else 1)
    assert mtf50(c) == pytest.approx(edge_truth_mtf50(1.0, 5.0), rel=0.03)


def test_slanted_edge_noisy():
    rng = np.random.default_rng(12233)
    for sigma in (0.5, 1.0, 1.5):
        for _ in range(3):
            c = mtf_from_edge(render_edge(angle_deg=5.0, sigma=sigma, noise=0.01, rng=rng))  # SNR 80
            assert mtf50(c) == pytest.approx(edge_truth_mtf50(sigma, 5.0), rel=0.05)


def test_slanted_edge_uint16_and_float32():
    img = render_edge(angle_deg=6.0, sigma=1.0)
    u16 = np.round(img * 40000 + 1000).astype(np.uint16)
    t = edge_truth_mtf50(1.0, 6.0)
    assert mtf50(quiet_edge(u16)) == pytest.approx(t, rel=0.03)
    assert mtf50(quiet_edge(img.astype(np.float32))) == pytest.approx(t, rel=0.03)


@pytest.mark.parametrize("angle,pattern", [
    (1.2, "nearly aligned"),
    (40.0, "near 45°"),
    (26.57, "critical angle 26.57"),
    (14.04, "critical angle 14.04"),
])
@pytest.mark.filterwarnings("ignore::irfidelity.curves.EdgeWarning")  # the other warnings of the same call
def test_slanted_edge_warns_at_bad_angles(angle, pattern):
    with pytest.warns(EdgeWarning, match=pattern):
        mtf_from_edge(render_edge(angle_deg=angle, sigma=1.0))
    assert issubclass(EdgeWarning, FidelityWarning)


def test_slanted_edge_warns_clipping_and_contrast():
    img = render_edge(angle_deg=5.0, sigma=1.0, lo=0.0, hi=1.2)
    u8 = np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)
    with pytest.warns(EdgeWarning, match="clipped"):
        mtf_from_edge(u8)
    rng = np.random.default_rng(3)
    with pytest.warns(EdgeWarning, match="low contrast: edge step .* is only 1[0-9].[0-9]x the pixel noise"):
        mtf_from_edge(render_edge(angle_deg=5.0, lo=0.50, hi=0.56, noise=0.004, rng=rng))


def test_slanted_edge_errors():
    with pytest.raises(FidelityError, match="2-D"):
        mtf_from_edge(np.zeros((10, 10, 3)))
    with pytest.raises(FidelityError, match="no edge"):
        mtf_from_edge(np.ones((32, 32)))
    with pytest.raises(FidelityError, match="8x8"):
        mtf_from_edge(np.ones((4, 32)))
    bad = render_edge()
    bad[3, 4] = np.nan
    with pytest.raises(FidelityError, match=r"non-finite pixels, first at \(row, col\) = \(3, 4\)"):
        mtf_from_edge(bad)
    for order in (0, 6, 2.5, "5"):
        with pytest.raises(FidelityError, match="edge_fit_order must be an integer 1..5"):
            mtf_from_edge(render_edge(), edge_fit_order=order)
    with pytest.raises(FidelityError, match="oversample"):
        mtf_from_edge(render_edge(), oversample=0)
    with pytest.raises(FidelityError, match="orientation"):
        mtf_from_edge(render_edge(), orientation="diagonal")
    with pytest.raises(FidelityError, match="max_freq"):
        mtf_from_edge(render_edge(), max_freq=0)


# --------------------------------------------------------------------------- usable edge or not
def test_angle_outside_usable_range():
    with pytest.raises(FidelityError, match=r"edge angle 0.00° is outside the usable range: the edge shifts by "
                                            r"0.00 px over 64 rows"):
        mtf_from_edge(render_edge(angle_deg=0.0))
    with pytest.raises(FidelityError, match=r"edge angle 4[0-9].[0-9]° is outside the usable range \(at most 45°"):
        mtf_from_edge(render_edge(angle_deg=50.0), orientation="vertical")  # auto would read it along the rows


def test_too_little_contrast_is_an_error():
    rng = np.random.default_rng(4)
    with pytest.raises(FidelityError, match=r"no usable edge: the edge step .* is only [0-4].[0-9]x the pixel noise"):
        mtf_from_edge(render_edge(angle_deg=5.0, lo=0.50, hi=0.52, noise=0.006, rng=rng))


def test_gradient_is_not_an_edge():
    # a transition as wide as the ROI (sigma 14 px in 48 px): no plateaus to measure an edge between
    with pytest.raises(FidelityError, match="between 10 % and 90 % of the step, a gradient"):
        mtf_from_edge(render_edge(shape=(48, 48), angle_deg=5.0, sigma=14.0, ss=4))
    mtf_from_edge(render_edge(shape=(48, 48), angle_deg=5.0, sigma=6.0, ss=4))  # soft, but an edge


THERMAL_FRAMES = sorted(glob.glob(str(DATA / "thermal" / "*.png")))


@pytest.mark.parametrize("path", THERMAL_FRAMES, ids=[pathlib.Path(p).name for p in THERMAL_FRAMES])
def test_real_thermal_scene_is_not_an_edge(path):
    """The issue: a thermal scene without an edge gave an MTF up to 4.8 with only a low-contrast
    warning. Every whole frame of the shipped thermal data is now refused, saying why."""
    frame = load_frame(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EdgeWarning)
        with pytest.raises(FidelityError, match="no edge found|edge fit does not fit|no usable edge|ROI border"):
            mtf_from_edge(frame)


@pytest.mark.parametrize("name,reason", [
    ("cptv_v2_frame000.png", r"only 111 of 160 rows cross the fitted edge"),  # sky / ground: a soft band
    ("ptw_lwir_frame001.png", r"only 0 of 59 rows cross"),  # a uniform scene, noise
    ("ptw_bb150C_frame000.png", r"edge fit does not fit: the rows' edge locations scatter by 35.88 px"),  # a disc
    ("flirpy_frame_000000_raw16.png", r"too close to the ROI border"),
])
def test_real_thermal_scene_reasons(name, reason):
    with pytest.raises(FidelityError, match=reason):
        mtf_from_edge(load_frame(DATA / "thermal" / name))


@pytest.mark.parametrize("corner,size,reason", [
    ((0, 0), 32, r"the MTF reaches 1.94 at 0.104 cy/px, above 1.2"),
    ((8, 0), 32, r"54% of the edge profile lies between 10 % and 90 %"),
    ((0, 48), 32, r"the edge step 1.276 is only 0.3x the pixel noise"),
    ((16, 16), 32, r"edge angle 1.06° is outside the usable range"),
])
@pytest.mark.filterwarnings("ignore::irfidelity.curves.EdgeWarning")
def test_real_thermal_crops_each_check(corner, size, reason):
    """ROIs cut from a real Lepton frame, each refused by a different check."""
    r, c = corner
    frame = load_frame(DATA / "thermal" / "cptv_v2_frame000.png")
    with pytest.raises(FidelityError, match=reason):
        mtf_from_edge(frame[r:r + size, c:c + size])


# --------------------------------------------------------------------------- curved edges
@pytest.mark.parametrize("rows", [100, 200])
def test_polynomial_fit_follows_a_curved_edge(rows):
    truth = edge_truth_mtf50(1.0, 5.0)
    for sag in (0.0, 0.5, 1.0):
        img = render_edge(shape=(rows, 48), angle_deg=5.0, sigma=1.0, sag=sag, ss=8)
        poly = quiet_edge(img)
        line = quiet_edge(img, edge_fit_order=1)
        assert mtf50(poly) == pytest.approx(truth, rel=0.005)
        if sag >= 1.0:  # the straight line misplaces the edge in some rows: the ESF blurs, MTF50 reads low
            assert mtf50(line) < truth * 0.985
            assert line.meta["edge_residual_px"] > 5 * poly.meta["edge_residual_px"]
    bowed = render_edge(shape=(rows, 48), angle_deg=5.0, sigma=1.0, sag=2.0, ss=8)
    with pytest.raises(FidelityError, match="a fit of order 5 follows lens curvature"):
        mtf_from_edge(bowed, edge_fit_order=1)
    assert mtf50(quiet_edge(bowed)) == pytest.approx(truth, rel=0.005)


# --------------------------------------------------------------------------- real crops
@pytest.mark.parametrize("name", CROPS)
def test_real_crops_match_sfrmat5(name):
    img = crop(name)
    default = quiet_edge(img)
    linear = quiet_edge(img, edge_fit_order=1)
    assert mtf50(default) == pytest.approx(CROPS[name], rel=SFRMAT5_TOLERANCE)
    assert mtf50(linear) == pytest.approx(CROPS[name], rel=SFRMAT5_TOLERANCE)
    assert default.meta["edge_residual_px"] < linear.meta["edge_residual_px"] < 0.25


@pytest.mark.parametrize("name", CROPS)
def test_real_edges_invariances(name):
    img = crop(name)
    c = quiet_edge(img)
    m = mtf50(c)
    assert 1.5 < abs(c.meta["angle_deg"]) < 10
    # transposing, flipping polarity or mirroring measure the same edge
    for other in (img.T, 255 - img, img[::-1, ::-1], img[:, ::-1], img[::-1]):
        assert mtf50(quiet_edge(np.ascontiguousarray(other))) == pytest.approx(m, rel=1e-9)
    # physical bound: no camera beats its pixel aperture (|sinc f|) by more than noise
    sel = c.x <= 0.8
    assert (c.y[sel] <= np.abs(np.sinc(c.x[sel])) + 0.1).all()


def test_real_f16_below_diffraction_limit():
    # f/16, 550 nm, 5 um pixels (SFR_calculation_code's example settings): diffraction cut-off
    # 1/(lambda N) = 113.6 cy/mm = 0.568 cy/px. The system MTF50 cannot exceed that of the
    # diffraction-limited optics times the pixel aperture.
    c = quiet_edge(crop("sfr_edge_x0552_y1976_F16.png"))
    fc = 0.005 / (550e-6 * 16)
    f = np.linspace(0, fc, 20001)
    v = f / fc
    diffraction = 2 / np.pi * (np.arccos(v) - v * np.sqrt(1 - v * v))
    assert mtf50(c) < mtf50(Curve(f, diffraction * np.abs(np.sinc(f))))


def test_real_aperture_pair_similarity():
    f2 = quiet_edge(crop("sfr_edge_x2084_y0616_F2.png"))
    f28 = quiet_edge(crop("sfr_edge_x2088_y0616_F2_8.png"))
    f16 = quiet_edge(crop("sfr_edge_x0552_y1976_F16.png"))
    s_self = mtf_similarity(f2, f2)
    assert s_self.value == pytest.approx(1.0) and s_self.area == 0.0 and s_self.notes == ()
    s = mtf_similarity(f28, f16)
    assert 0 < s.value < 1 and s.mu == pytest.approx(2 * s.a * s.b / (s.a ** 2 + s.b ** 2))
    assert s.a == pytest.approx(mtf50(f28)) and s.b == pytest.approx(mtf50(f16)) and s.x_unit == "cy/px"


def test_doc_example_angle():
    rows, cols = np.mgrid[0:64, 0:64]
    distance = (cols - 32) * np.cos(0.1) - (rows - 32) * np.sin(0.1)
    assert quiet_edge(np.vectorize(math.erf)(distance / math.sqrt(2))).meta["angle_deg"] == pytest.approx(
        math.degrees(0.1), abs=0.02)
