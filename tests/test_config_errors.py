"""Configuration errors are the library's: every field checked, curve options against the
comparisons' real keywords, bounded sizes (feature points, anchors, file size and nesting),
and TOML that reads back whatever its keys."""

from __future__ import annotations

import inspect
import json
import math
import pathlib
import time
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import irfidelity as irf
from irfidelity.cli import main
from irfidelity.config import ScoringConfig
from irfidelity.config_fields import CURVE_OPTIONS
from irfidelity.config_file import MAX_CONFIG_BYTES, MAX_CONFIG_DEPTH, toml_document
from irfidelity.curves import mtf_similarity, sitf_similarity
from irfidelity.curves.similarity import MAX_FEATURE_POINTS
from irfidelity.errors import FidelityError
from irfidelity.normalize import EXPONENT_RANGE, PSNR_RANGE_DB, normalize_psnr, psnr_curve_params

DATA = pathlib.Path(__file__).parent / "data"
REAL = str(DATA / "thermal" / "ptw_bb150C_frame000.png")
SIM = str(DATA / "thermal" / "ptw_bb150C_frame001.png")


def cli_error(capsys, *argv: str) -> str:
    """The one stderr line of a CLI run that must fail as a user error (exit 2)."""
    assert main(list(argv)) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert "Traceback" not in lines[0]
    return lines[0]


def write(tmp_path: pathlib.Path, name: str, text: str) -> str:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


# --------------------------------------------------------------------------- grades
@pytest.mark.parametrize("grades, needle", [
    ({"cuts": [1, 2]}, "grade cuts must be a mapping"),
    ({"cuts": {"mtf": "abc"}}, "must be a list of numbers"),
    ({"cuts": {"mtf": [0.1, None, 0.9]}}, "must be a number"),
    ({"cuts": {"psnr": {"a": 1}}}, "must be a list of numbers"),
    ({"cuts": {"colour": [0.1, 0.2, 0.3]}}, "unknown component"),
    ({"width": [0.01]}, "must be a number"),
    ({"width": True}, "must be a number"),
    ({"width": {"zz": 0.01}}, "unknown component"),
    ({"width": -1}, "finite and >= 0"),
    ({"grades": "abc"}, "at least 2 distinct"),
    ({"grades": ["a", 2]}, "at least 2 distinct"),
    ({"grades": ["a", "b"]}, "need 1 boundaries"),
    ({"scale": 1}, "unknown key(s) scale; the keys are grades, cuts, width"),
])
def test_every_grade_scale_field_is_checked(grades, needle):
    with pytest.raises(FidelityError, match="grades") as info:
        ScoringConfig(grades=grades)
    assert needle in str(info.value)
    assert info.value.option == "grades"


def test_grade_cuts_list_in_a_toml_file(tmp_path, capsys):
    path = write(tmp_path, "g.toml", "[grades]\ncuts = [1, 2]\n")
    with pytest.raises(FidelityError, match="grade cuts must be a mapping"):
        ScoringConfig.load(path)
    line = cli_error(capsys, "score", REAL, SIM, "--config", path)
    assert "g.toml" in line and "grades" in line


def test_custom_grade_scale_round_trips(tmp_path):
    cuts = {k: [0.5] for k in irf.fuzzy.COMPONENTS}
    cfg = ScoringConfig(grades={"grades": ["pass", "fail"], "cuts": cuts, "width": 0.01})
    assert cfg.grades.grades == ("pass", "fail")
    path = tmp_path / "g.toml"
    cfg.save(path)
    assert ScoringConfig.load(path) == cfg


# --------------------------------------------------------------------------- curve options
def _keywords(function) -> set[str]:
    return {p.name for p in inspect.signature(function).parameters.values() if p.kind is p.KEYWORD_ONLY}


def test_curve_options_are_the_comparisons_keywords():
    """One check per keyword of the function the options are passed to (``camera`` comes
    from the configuration's geometry fields)."""
    assert set(CURVE_OPTIONS["mtf_options"]) == _keywords(mtf_similarity) - {"camera"}
    assert set(CURVE_OPTIONS["sitf_options"]) == _keywords(sitf_similarity)


@pytest.mark.parametrize("field, options, needle", [
    ("mtf_options", {"pointz": 32}, "unknown option(s) 'pointz'; the options are smooth, points, alpha, beta"),
    ("mtf_options", {"camera": {}}, "the camera comes from ifov_mrad"),
    ("sitf_options", {"frac": 1}, "the options are window, lo_frac, hi_frac, method, points, alpha, beta"),
    ("mtf_options", {"smooth": "yes"}, "mtf_options.smooth: expected true or false"),
    ("mtf_options", {"alpha": -1}, "mtf_options.alpha: expected a finite number >= 0"),
    ("mtf_options", {"beta": "1"}, "mtf_options.beta: expected a finite number >= 0"),
    ("mtf_options", {"points": 1}, "expected an integer in 2..65536"),
    ("mtf_options", {"points": 5e7}, "expected an integer in 2..65536"),
    ("mtf_options", {"points": 10**12}, "expected an integer in 2..65536"),
    ("mtf_options", {"points": 32.5}, "expected an integer in 2..65536"),
    ("mtf_options", {"points": "64"}, "expected a count in 2..65536"),
    ("mtf_options", {"points": [0.1, "a"]}, "finite numbers"),
    ("sitf_options", {"window": [3, 1]}, "expected 'real', 'each' or [lo, hi] with lo < hi"),
    ("sitf_options", {"window": "all"}, "expected 'real', 'each'"),
    ("sitf_options", {"lo_frac": 0.95}, "expected lo_frac < hi_frac"),
    ("sitf_options", {"hi_frac": 2}, "expected a number in [0, 1]"),
    ("sitf_options", {"method": "spline"}, "expected one of band, logistic"),
    ("sitf_options", [("points", 3)], "expected a mapping of option names"),
])
def test_curve_options_are_checked_when_the_config_is_built(field, options, needle):
    with pytest.raises(FidelityError) as info:
        ScoringConfig(**{field: options})
    assert needle in str(info.value)
    assert info.value.option == field


def test_unknown_curve_option_in_a_config_file(tmp_path, capsys):
    path = write(tmp_path, "o.toml", "[mtf_options]\npointz = 32\n")
    line = cli_error(capsys, "score", REAL, SIM, "--config", path)
    assert "unknown option(s) 'pointz'" in line and "smooth, points, alpha, beta" in line


def test_valid_curve_options_reach_the_comparisons():
    x = np.linspace(0, 10, 41)
    real = irf.Curve(x, 100 + 40 * x, x_unit="K", y_unit="counts")
    sim = irf.Curve(x, 90 + 36 * x, x_unit="K", y_unit="counts")
    cfg = ScoringConfig(sitf_options={"window": [2, 8], "points": 9.0, "method": "logistic"},
                        weights="sitf=1")
    assert cfg.sitf_options == {"window": [2.0, 8.0], "points": 9, "method": "logistic"}
    rep = irf.evaluate(np.zeros((8, 8), np.uint8), np.zeros((8, 8), np.uint8), real_sitf=real, sim_sitf=sim,
                       config=cfg)
    assert rep.metrics["sitf_slope_real"] == pytest.approx(40.0)
    assert rep.metrics["sitf_slope_sim"] == pytest.approx(36.0)


def test_feature_points_are_bounded_in_the_api():
    curve = irf.Curve([0.0, 0.25, 0.5], [1.0, 0.5, 0.1], x_unit="cy/px", y_unit="1")
    start = time.perf_counter()
    for points in (10**12, MAX_FEATURE_POINTS + 1, float("inf"), np.zeros(MAX_FEATURE_POINTS + 1)):
        with pytest.raises(FidelityError, match="points must be"):
            mtf_similarity(curve, curve, points=points)
    assert time.perf_counter() - start < 5
    assert mtf_similarity(curve, curve, points=MAX_FEATURE_POINTS).points.size == MAX_FEATURE_POINTS
    with pytest.raises(FidelityError, match="array of numbers"):
        mtf_similarity(curve, curve, points=["a", "b"])


# --------------------------------------------------------------------------- PSNR anchors
@pytest.mark.parametrize("anchors, needle", [
    (((30, 0.9), (30.0000001, 0.99)), "nearly a step"),
    (((30, 1e-300), (45, 0.99)), "nearly a step"),
    (((30, 0.5), (45, 0.5 + 1e-16)), "nearly flat"),
    (((999.9999999999999, 0.5), (1000, 0.6)), "nearly a step"),
    (((10, 1e-9), (1000, 1e-8)), "stay near 0"),
    (((1e-320, 0.5), (1, 0.6)), "0.01 <= x1 < x2 <= 1000"),
    (((30, 0.9), (1e308, 0.99)), "0.01 <= x1 < x2 <= 1000"),
    (((30, 0.9), (45, 1.0)), "0 < y1 < y2 < 1"),
])
def test_extreme_psnr_anchors_are_refused(anchors, needle):
    with pytest.raises(FidelityError, match="psnr_anchors") as info:
        ScoringConfig(psnr_anchors=anchors)
    assert needle in str(info.value)
    assert info.value.option == "psnr_anchors"


finite = st.floats(allow_nan=False, allow_infinity=False)
anchor = st.tuples(st.one_of(finite, st.floats(0.001, 2000)), st.one_of(finite, st.floats(0, 1)))


@settings(max_examples=400, deadline=None)
@given(anchor, anchor, st.lists(st.one_of(finite, st.floats(0, 2000)), min_size=1, max_size=8))
def test_accepted_anchors_give_a_usable_curve(first, second, psnrs):
    """Anchors are refused with a FidelityError, or give finite positive a and k in their
    documented ranges and a monotone curve into [0, 1] for every PSNR."""
    try:
        a, k = psnr_curve_params((first, second))
    except FidelityError:
        return
    assert PSNR_RANGE_DB[0] <= a <= PSNR_RANGE_DB[1] and EXPONENT_RANGE[0] <= k <= EXPONENT_RANGE[1]
    ys = [normalize_psnr(x, anchors=(first, second)) for x in sorted(psnrs) + [math.inf]]
    assert all(0.0 <= y <= 1.0 for y in ys)
    assert all(y0 <= y1 for y0, y1 in zip(ys, ys[1:]))
    for x, y in (first, second):
        assert normalize_psnr(x, anchors=(first, second)) == pytest.approx(y, rel=1e-6, abs=1e-12)


# --------------------------------------------------------------------------- files
@pytest.mark.parametrize("name, text", [
    ("deep.toml", "a = " + "[" * 100_000 + "]" * 100_000),
    ("deep_inline.toml", "a = " + "{b = " * 5000 + "1" + "}" * 5000),
    ("dotted.toml", "x" + ".x" * 100_000 + " = 1"),
    ("header.toml", "[" + ".".join(["t"] * 100_000) + "]"),
    ("quoted.toml", ".".join(['"q"'] * 50_000) + " = 1"),
    ("deep.json", "[" * 100_000 + "]" * 100_000),
    ("deep_objects.json", '{"a":' * 40_000 + "1" + "}" * 40_000),
])
def test_deeply_nested_files_are_refused_before_parsing(tmp_path, capsys, name, text):
    path = write(tmp_path, name, text)
    start = time.perf_counter()
    with pytest.raises(FidelityError, match=f"nested more than {MAX_CONFIG_DEPTH} levels") as info:
        ScoringConfig.load(path)
    assert time.perf_counter() - start < 5
    assert name in str(info.value)
    assert "nested more than" in cli_error(capsys, "score", REAL, SIM, "--config", path)


def test_nesting_within_the_bound_is_an_ordinary_error(tmp_path):
    path = write(tmp_path, "shallow.toml", "a = " + "[" * (MAX_CONFIG_DEPTH - 2) + "]" * (MAX_CONFIG_DEPTH - 2))
    with pytest.raises(FidelityError, match="unknown scoring option"):
        ScoringConfig.load(path)


def test_brackets_and_dots_in_strings_and_comments_do_not_count(tmp_path):
    deep = "[" * 100 + "a.b" * 100
    text = (f'# {deep}\nreal_channel = {json.dumps(deep)}\nsim_channel = \'{deep}\'\n'
            f'[weights] # {deep}\npsnr = 1.0\nmtf = 0.0\nsitf = 0.0\nnmi = 0.0\nssim = 0.0\n')
    cfg = ScoringConfig.load(write(tmp_path, "strings.toml", text))
    assert cfg.real_channel == deep and cfg.sim_channel == deep
    cfg = ScoringConfig.load(write(tmp_path, "strings.json", json.dumps({"real_channel": deep})))
    assert cfg.real_channel == deep


def test_large_files_are_refused(tmp_path):
    path = write(tmp_path, "big.toml", "# padding\n" * (MAX_CONFIG_BYTES // 10 + 1))
    with pytest.raises(FidelityError, match=f"larger than {MAX_CONFIG_BYTES} bytes"):
        ScoringConfig.load(path)


@pytest.mark.parametrize("name, raw", [
    ("bad.toml", b"\xff\xfe"), ("bad.json", b"\xff\xfe"), ("int.toml", b"bits = " + b"9" * 5000),
    ("nul.json", b'{"bits": 1e999}'), ("list.json", b"[1, 2]"), ("scoring.toml", b"scoring = 3"),
])
def test_malformed_files_are_fidelity_errors(tmp_path, name, raw):
    path = tmp_path / name
    path.write_bytes(raw)
    with pytest.raises(FidelityError, match=name):
        ScoringConfig.load(path)


def test_default_configuration_is_within_the_bounds(tmp_path):
    cfg = ScoringConfig(mtf_options={"points": [0.1, 0.2, 0.3]}, sitf_options={"window": [1, 2]})
    for name in ("c.toml", "c.json"):
        cfg.save(tmp_path / name)
        assert ScoringConfig.load(tmp_path / name) == cfg


# --------------------------------------------------------------------------- TOML keys
ODD_KEYS = ["a b", "x.y", 'say "hi"', "tab\tkey", "", "ü", "[t]", "#c", "back\\slash", "plain_key-1"]


def test_toml_keys_are_quoted_when_not_bare():
    data = {"top": 1, "table": {k: i for i, k in enumerate(ODD_KEYS)},
            "nested": {"a b": {k: [1.5, "v"] for k in ODD_KEYS}}}
    text = toml_document(data, ("table", "nested"), {}, "odd keys")
    assert tomllib.loads(text) == data
    assert "plain_key-1 = 9" in text  # bare keys stay bare


@settings(max_examples=200, deadline=None)
@given(st.dictionaries(st.text(max_size=12), st.one_of(st.integers(-10**6, 10**6), st.text(max_size=8),
                                                        st.booleans(), finite), max_size=6))
def test_any_keys_round_trip_through_toml(table):
    data = {"value": 1, "table": table}
    assert tomllib.loads(toml_document(data, ("table",), {}, "keys")) == data


def test_odd_grade_names_round_trip(tmp_path):
    names = ["très bien", 'with "quotes"', "x.y"]
    cfg = ScoringConfig(grades={"grades": names, "cuts": {k: [0.4, 0.7] for k in irf.fuzzy.COMPONENTS}})
    cfg.save(tmp_path / "odd.toml")
    assert ScoringConfig.load(tmp_path / "odd.toml") == cfg


def test_strings_with_control_characters_round_trip(tmp_path):
    channel = 'a\x00b\x7fc\x1b"\\\n\tü𐀀'
    cfg = ScoringConfig(real_channel=channel)
    cfg.save(tmp_path / "c.toml")
    assert ScoringConfig.load(tmp_path / "c.toml").real_channel == channel


def test_a_lone_surrogate_is_a_clear_error_in_toml_and_saved_in_json(tmp_path):
    cfg = ScoringConfig(real_channel="name\udcff")
    with pytest.raises(FidelityError, match="lone surrogate"):
        cfg.save(tmp_path / "c.toml")
    cfg.save(tmp_path / "c.json")
    assert ScoringConfig.load(tmp_path / "c.json") == cfg


@pytest.mark.parametrize("text, needle", [
    ("psnr_anchors = [[30.0, 0.9], [30.0000001, 0.99]]\n", "psnr_anchors"),
    ("[mtf_options]\npoints = 5e7\n", "mtf_options.points"),
    ("[sitf_options]\n'a b' = 1\n", "unknown option(s) 'a b'"),
    ("bits = 99\n", "bits"),
    ("[grades]\nwidth = {mtf = [1]}\n", "grade width of mtf"),
    ("weights = 3\n", "weights"),
    ("x = 1\n", "unknown scoring option(s) x"),
])
def test_cli_reports_config_file_errors_in_one_line(tmp_path, capsys, text, needle):
    line = cli_error(capsys, "score", REAL, SIM, "--config", write(tmp_path, "c.toml", text))
    assert needle in line and "c.toml" in line


def test_curve_parameters_are_remembered_only_for_what_they_are():
    """The parameters of hashable anchors are remembered; lists give the same numbers, and a
    refused pair is refused every time (errors are not remembered)."""
    assert psnr_curve_params([[30, 0.9], [45, 0.99]]) == psnr_curve_params(((30.0, 0.9), (45.0, 0.99)))
    for _ in range(2):
        with pytest.raises(FidelityError, match="anchor values"):
            psnr_curve_params(((30.0, 0.9), (45.0, 1.5)))
