"""Curve units (issue 14 item 2): the spelling table, units from CSV headers, camera constants,
conversions, and comparisons that refuse different or half-known units."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from edge_render import gauss_mtf
from irfidelity.curves import (CameraGeometry, Curve, CurveUnitsWarning, curve_similarity, mtf50, mtf_similarity,
                               sitf_similarity)
from irfidelity.curves.units import UNITS, canonical_unit, convert, unit_from_header
from irfidelity.errors import FidelityError, FidelityWarning


# --------------------------------------------------------------------------- spellings
@pytest.mark.parametrize("header,unit", [
    ("freq_cy_per_mrad", "cy/mrad"), ("cy/px", "cy/px"), ("cycles_per_pixel", "cy/px"), ("lp/mm", "lp/mm"),
    ("lpmm", "lp/mm"), ("lp_mm", "lp/mm"), ("cy/mrad", "cy/mrad"), ("MTF (cy/px)", "cy/px"),
    ("frequency [cycles/mm]", "lp/mm"), ("f_cpp", "cy/px"),
    ("dT_K", "delta_K"), ("delta_T_degC", "delta_K"), ("ΔT (K)", "delta_K"), ("dT", "delta_K"),
    ("temperature_C", "degC"), ("T_K", "K"), ("T (°C)", "degC"), ("blackbody_temp_C", "degC"),
    ("Temperature [K]", "K"), ("K", None), ("degC", None), ("°C", None), ("T", None),
    ("counts", "counts"), ("DN", "counts"), ("signal_ADU", "counts"), ("digital_level", "counts"),
    ("signal_V", "V"), ("output_mV", "mV"),
    ("mtf", "1"), ("SFR", "1"), ("mtf_%", "%"), ("MTF (percent)", "%"),
    ("freq", None), ("x", None), ("signal", None), ("f", None),
    ("T_K_counts", None),  # two units in one name: ambiguous
])
def test_unit_from_header(header, unit):
    assert unit_from_header(header) == unit


@pytest.mark.parametrize("header", ["T_F", "dT_mK", "temperature_degF", "Fahrenheit"])
def test_unsupported_temperature_units_are_refused(header):
    with pytest.raises(FidelityError, match="not supported"):
        unit_from_header(header)


def test_explicit_spellings_and_labels():
    assert canonical_unit("cycles/pixel") == "cy/px" and canonical_unit("°C") == "degC"
    assert canonical_unit("dT") == "delta_K" and canonical_unit("DN") == "counts"
    assert canonical_unit("W/sr") == "W/sr" and canonical_unit(None) is None and canonical_unit("  ") is None
    for unit in UNITS.values():  # every canonical symbol and spelling maps back to its symbol
        assert canonical_unit(unit.symbol) == unit.symbol
        assert {canonical_unit(sp) for sp in unit.spellings} == {unit.symbol}
    with pytest.raises(FidelityError, match="x_unit must be a string"):
        Curve([0, 1, 2], [1, 0.5, 0.2], x_unit=3)
    with pytest.raises(FidelityError, match="Fahrenheit"):
        Curve([0, 1, 2], [1, 0.5, 0.2], x_unit="degF")


# --------------------------------------------------------------------------- camera and conversions
def test_camera_geometry_relations():
    cam = CameraGeometry(pixel_pitch_um=17, focal_length_mm=25)  # IFOV = 17 µm / 25 mm = 0.68 mrad
    assert cam.ifov() == pytest.approx(0.68) and cam.pixel_pitch() == 17 and cam.focal_length() == 25
    f = np.array([0.0, 0.1, 0.5])
    np.testing.assert_allclose(convert(f, "cy/px", "cy/mrad", camera=cam), f / 0.68)
    np.testing.assert_allclose(convert(f, "cy/px", "lp/mm", camera=cam), f * 1000 / 17)
    np.testing.assert_allclose(convert(f, "cy/mrad", "lp/mm", camera=cam), f * 1000 / 25)
    # round trips and consistency of the three routes
    for a in ("cy/px", "cy/mrad", "lp/mm"):
        for b in ("cy/px", "cy/mrad", "lp/mm"):
            np.testing.assert_allclose(convert(convert(f, a, b, camera=cam), b, a, camera=cam), f)
    via = convert(convert(f, "cy/px", "cy/mrad", camera=cam), "cy/mrad", "lp/mm", camera=cam)
    np.testing.assert_allclose(via, convert(f, "cy/px", "lp/mm", camera=cam))
    # any two constants give the third
    assert CameraGeometry(ifov_mrad=0.68, focal_length_mm=25).pixel_pitch() == pytest.approx(17)
    assert CameraGeometry(ifov_mrad=0.68, pixel_pitch_um=17).focal_length() == pytest.approx(25)
    assert CameraGeometry.from_dict(cam.to_dict()) == cam


def test_camera_geometry_errors():
    with pytest.raises(FidelityError, match="ifov_mrad must be finite and > 0"):
        CameraGeometry(ifov_mrad=0)
    with pytest.raises(FidelityError, match="pixel_pitch_um must be a number"):
        CameraGeometry(pixel_pitch_um="big")
    with pytest.raises(FidelityError, match="disagree"):
        CameraGeometry(ifov_mrad=1.0, pixel_pitch_um=17, focal_length_mm=25)
    with pytest.raises(FidelityError, match="unknown camera constant"):
        CameraGeometry.from_dict({"ifov": 1})
    # the missing constant is named, with its CLI flag and the alternative pair
    with pytest.raises(FidelityError, match=r"needs the pixel pitch \(--pixel-pitch UM; pixel_pitch_um in Python\) "
                                            r"or both the IFOV and the focal length \(--ifov MRAD and "
                                            r"--focal-length MM\)"):
        CameraGeometry(ifov_mrad=0.5).scale("cy/px", "lp/mm")


def test_fixed_conversions():
    assert convert([0.0, 26.85], "degC", "K").tolist() == pytest.approx([273.15, 300.0])
    assert convert([300.0], "K", "degC").tolist() == pytest.approx([26.85])
    assert convert([1.5], "V", "mV").tolist() == [1500.0]
    assert convert([50.0], "%", "1").tolist() == [0.5]
    with pytest.raises(FidelityError, match="temperature difference cannot be converted to an absolute"):
        convert([1.0], "delta_K", "K")
    with pytest.raises(FidelityError, match="gain"):
        convert([1.0], "counts", "V")
    with pytest.raises(FidelityError, match="unknown unit"):
        convert([1.0], None, "K")


# --------------------------------------------------------------------------- comparisons
def _mtf(unit, scale=1.0, sigma=1.0):
    f = np.linspace(0, 0.5, 51)
    return Curve(f * scale, gauss_mtf(f, sigma), x_unit=unit)


def test_mtf_in_cy_per_mrad_against_cy_per_px_is_refused_then_converted():
    """The issue's trap: freq_cy_per_mrad against a slanted-edge MTF in cy/px gave f1 = 0.06, no note."""
    real = _mtf("cy/px")
    sim = _mtf("cy/mrad", scale=1 / 0.25)  # the same camera, IFOV 0.25 mrad
    with pytest.raises(FidelityError, match=r"real x axis is in cy/px \(cycles per pixel\), the simulated one in "
                                            r"cy/mrad .*--ifov MRAD") as e:
        mtf_similarity(real, sim)
    assert "ifov_mrad in Python" in str(e.value)  # the API's argument too, without Python syntax
    assert not re.search(r"\w+=", str(e.value))
    s = mtf_similarity(real, sim, camera=CameraGeometry(ifov_mrad=0.25))
    assert s.value == pytest.approx(1.0, abs=1e-9) and s.x_unit == "cy/px"
    assert s.a == pytest.approx(s.b) == pytest.approx(mtf50(real))
    assert s.notes == ("simulated x axis converted from cy/mrad to cy/px with IFOV 0.25 mrad",)
    # lp/mm through the pitch, and through IFOV and focal length
    sim_mm = _mtf("lp/mm", scale=1000 / 17)
    for cam in (CameraGeometry(pixel_pitch_um=17), CameraGeometry(ifov_mrad=0.68, focal_length_mm=25)):
        assert mtf_similarity(real, sim_mm, camera=cam).value == pytest.approx(1.0, abs=1e-9)
    with pytest.raises(FidelityError, match=r"give the pixel pitch \(--pixel-pitch UM"):
        mtf_similarity(real, sim_mm, camera=CameraGeometry(ifov_mrad=0.68))


def test_half_known_units_are_refused():
    real = _mtf("cy/px")
    unknown = _mtf(None)
    with pytest.raises(FidelityError, match=r"real x axis is in cy/px \(cycles per pixel\), the simulated one in "
                                            r"an unknown unit.*CSV header"):
        mtf_similarity(real, unknown)
    with pytest.raises(FidelityError, match=r"simulated x axis is in cy/px.*the real one in an unknown unit"):
        mtf_similarity(unknown, real)
    with pytest.raises(FidelityError, match="unknown unit"):
        curve_similarity(real, unknown, a=1, b=1)


def test_both_unknown_is_allowed_with_a_warning_and_a_note():
    a, b = _mtf(None), _mtf(None, sigma=1.2)
    with pytest.warns(CurveUnitsWarning, match="units unknown: the x axes of both MTF curves"):
        s = mtf_similarity(a, b)
    assert s.x_unit is None and s.notes == ("units unknown: the x axes of both MTF curves carry no unit, "
                                            "assumed to agree",)
    assert s.to_dict()["notes"] == list(s.notes)
    assert issubclass(CurveUnitsWarning, FidelityWarning)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mtf_similarity(_mtf("cy/px"), _mtf("cycles/pixel"))  # known and equal: silent


def test_mtf_in_percent_is_a_ratio():
    f = np.linspace(0, 0.5, 51)
    pct = Curve(f, 100 * gauss_mtf(f, 1.0), x_unit="cy/px", y_unit="%")
    s = mtf_similarity(_mtf("cy/px"), pct)
    assert s.value == pytest.approx(1.0) and s.y_unit == "1"


def test_curve_similarity_does_not_convert():
    # a and b are the caller's: a silent conversion of one curve would leave b in the old unit
    with pytest.raises(FidelityError, match=r"real x axis is in cy/px.*simulated one in cy/mrad"):
        curve_similarity(_mtf("cy/px"), _mtf("cy/mrad"), a=1, b=1)


def _sitf(x_unit, y_unit, offset=0.0, scale=1.0):
    t = np.linspace(0, 40, 41)
    return Curve(t + offset, scale * (1000 + 30 * t), x_unit=x_unit, y_unit=y_unit)


def test_sitf_units():
    # ΔT: the same in K and °C (both spell delta_K)
    real = _sitf(canonical_unit("delta_K"), "counts")
    assert sitf_similarity(real, _sitf("dT", "DN")).value == pytest.approx(1.0)
    # absolute temperatures convert
    s = sitf_similarity(_sitf("degC", "counts", offset=20), _sitf("K", "counts", offset=293.15))
    assert s.value == pytest.approx(1.0) and s.a == pytest.approx(30) and s.x_unit == "degC"
    # volts and millivolts convert; the slope is in the real curve's units
    s = sitf_similarity(_sitf("delta_K", "V", scale=1e-3), _sitf("delta_K", "mV"))
    assert s.a == pytest.approx(0.03) and s.b == pytest.approx(0.03) and s.y_unit == "V"
    # a ΔT axis against an absolute one, counts against volts: refused, both named
    with pytest.raises(FidelityError, match=r"delta_K \(temperature difference.*degC \(absolute temperature.*"
                                            r"subtract the background temperature"):
        sitf_similarity(_sitf("delta_K", "counts"), _sitf("degC", "counts"))
    with pytest.raises(FidelityError, match=r"counts \(digital counts\).*V \(volts\).*gain"):
        sitf_similarity(_sitf("delta_K", "counts"), _sitf("delta_K", "V"))
    with pytest.raises(FidelityError, match="unknown unit"):
        sitf_similarity(_sitf("delta_K", "counts"), _sitf("delta_K", None))


def test_unit_checks_from_csv(tmp_path):
    """End to end: units read from headers decide the comparison."""
    f = np.linspace(0, 0.5, 26)
    real = tmp_path / "real.csv"
    real.write_text("freq_cy_per_px,mtf\n" + "".join(f"{a},{b}\n" for a, b in zip(f, gauss_mtf(f, 1.0))))
    sim = tmp_path / "sim.csv"
    sim.write_text("freq_cy_per_mrad,mtf\n" + "".join(f"{a / 0.1},{b}\n" for a, b in zip(f, gauss_mtf(f, 1.1))))
    r, s = Curve.from_csv(real), Curve.from_csv(sim)
    with pytest.raises(FidelityError, match="--ifov MRAD"):
        mtf_similarity(r, s)
    out = mtf_similarity(r, s, camera=CameraGeometry(ifov_mrad=0.1))
    assert out.b == pytest.approx(mtf50(Curve(f, gauss_mtf(f, 1.1))), rel=1e-6)


def test_docstring_table_is_the_table():
    """The module docstring's table lists exactly the spellings UNITS recognises."""
    from irfidelity.curves import units

    rows = {}
    for line in units.__doc__.splitlines():
        parts = line.split(None, 1)
        if parts and parts[0] in UNITS:
            rows[parts[0]] = units._normalise(line)
    assert set(rows) == set(UNITS)
    for symbol, unit in UNITS.items():
        for spelling in unit.spellings:
            assert units._normalise(spelling) in rows[symbol], (symbol, spelling)


def test_evaluate_reads_units_and_takes_the_camera(tmp_path):
    """Through evaluate: a CSV MTF in cy/mrad against a slanted-edge MTF (cy/px) is refused until
    the camera constants come in (ifov_mrad in the configuration, --ifov on the command line)."""
    import pathlib

    import irfidelity as irf
    from irfidelity.curves import mtf_from_edge
    from irfidelity.frames import load_frame

    edge = pathlib.Path(__file__).parent / "data" / "curves" / "sfr_edge_x2084_y0616_F2.png"
    measured = mtf_from_edge(load_frame(edge, channel="G"))
    csv = tmp_path / "sim_mtf.csv"
    csv.write_text("freq_cy_per_mrad,mtf\n" + "".join(f"{f / 0.5},{m}\n" for f, m in zip(measured.x, measured.y)))
    kw = dict(real_mtf=measured, sim_mtf=str(csv), weights="mtf=1")
    with pytest.raises(FidelityError, match=r"cy/px .* cy/mrad .*--ifov MRAD"):
        irf.evaluate(**kw)
    rep = irf.evaluate(**kw, ifov_mrad=0.5)
    assert rep.components["mtf"] == pytest.approx(1.0, abs=1e-9)
    assert rep.metrics["mtf50_unit"] == "cy/px" and rep.config.ifov_mrad == 0.5
