"""The report layer: one base for both reports, typed frame entries read as mappings, each
fact stored once, reports that pickle (and render after unpickling), and the sequence's run
options as one object or as keywords."""

from __future__ import annotations

import dataclasses
import json
import pickle

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.errors import FidelityError
from irfidelity.results import ReportBase
from irfidelity.sequence import RunOptions
from irfidelity.sequence.entry import KEYS, FrameEntry
from report_inputs import DATA, pair_inputs


def _sequence(**options):
    rng = np.random.default_rng(3)
    ramp = np.add.outer(np.arange(24), np.arange(32)).astype(np.uint16) * 40
    real = np.stack([ramp + rng.integers(0, 9, ramp.shape, dtype=np.uint16) for _ in range(5)])
    sim = real + rng.integers(0, 30, real.shape, dtype=np.uint16)
    if "run" not in options:
        options["progress"] = False
    return irf.score_sequence(real, sim, bits=14, peak="range", **options)


# --------------------------------------------------------------------------- one base
def test_both_reports_share_one_base_and_its_json_keys():
    pair, seq = pair_inputs()["object"], _sequence()
    assert isinstance(pair, ReportBase) and isinstance(seq, ReportBase)
    shared = {f.name for f in dataclasses.fields(ReportBase)}
    assert shared <= {f.name for f in dataclasses.fields(irf.FidelityReport)}
    assert shared <= {f.name for f in dataclasses.fields(irf.SequenceReport)}
    base_keys = {"irfidelity", "fidelity", "grade", "components", "component_grades", "membership", "metrics",
                 "weights", "skipped", "config", "notes", "inputs", "registration", "verdict", "ceiling", "relative"}
    assert base_keys <= set(pair.to_dict()) and base_keys <= set(seq.to_dict())
    assert pair.to_dict()["transfer"] == pair.transfer  # the scene's, when it was measured
    assert set(pair.to_dict()) - base_keys - {"transfer"} == {"grading"}
    assert set(seq.to_dict()) - base_keys - {"transfer"} == {"failed", "unpaired", "frame_stats", "pooling", "run", "delay", "ci",
                                               "frames"}


def test_the_grading_is_derived_from_the_one_grade_and_memberships():
    rep = pair_inputs()["object"]
    assert "grading" not in {f.name for f in dataclasses.fields(rep)}  # a property, not a second copy
    grading = rep.grading
    assert grading["grade"] == rep.grade and grading["membership"] == rep.membership
    assert grading["component_grades"] == rep.component_grades and grading["grades"] == list(rep.grades)
    assert set(grading["matrix"]) == set(rep.components)
    for row in grading["matrix"].values():
        assert list(row) == grading["grades"] and sum(row.values()) == pytest.approx(1.0)
    # a report read back without its grading: the grade and memberships are still one source
    data = json.loads(json.dumps(rep.to_dict()))
    del data["grading"]
    back = irf.FidelityReport.from_dict(data)
    assert back.grading == {**grading, "matrix": {}} and back.grade == rep.grade
    # a stale grading in the dict cannot contradict the report's grade
    data = json.loads(json.dumps(rep.to_dict()))
    data["grading"]["grade"] = "not a grade"
    assert irf.FidelityReport.from_dict(data).grading["grade"] == rep.grade


def test_a_sequence_summary_shows_the_pooled_verdict_like_a_pair():
    for rep in (_sequence(), pair_inputs()["object"]):
        lines = rep.summary_text().splitlines()
        grade_line = next(line for line in lines if line.startswith("grade"))
        assert grade_line.split()[1] == rep.grade and grade_line.endswith(rep.verdict["reason"])
        assert lines[lines.index(grade_line) - 1].startswith("fidelity")


# --------------------------------------------------------------------------- frame entries
def test_frame_entries_are_typed_and_read_as_mappings():
    seq = _sequence()
    f = seq.frames[2]
    assert isinstance(f, FrameEntry) and f.index == 2 == f["index"]
    assert f["metrics"] is f.metrics and f["metrics"]["psnr_db"] == f.metrics["psnr_db"]
    assert list(f) == list(KEYS) and len(f) == len(KEYS) and "error" in f and "colour" not in f
    assert f.get("colour", 7) == 7 and f.get("error") is None
    with pytest.raises(KeyError):
        f["colour"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.fidelity = 1.0
    # equal to the dict of its keys, both ways; the JSON form is that dict
    assert f == dict(f) and dict(f) == f and f != {**dict(f), "fidelity": None}
    assert seq.to_dict()["frames"][2] == json.loads(json.dumps(irf.schema.to_json(dict(f))))


def test_frame_entries_read_back_keep_unknown_keys():
    seq = _sequence()
    data = json.loads(json.dumps(seq.to_dict()))
    data["frames"][1]["camera_temperature"] = 31.5
    back = irf.SequenceReport.from_dict(data)
    assert all(isinstance(f, FrameEntry) for f in back.frames)
    assert back.frames[1]["camera_temperature"] == 31.5 and back.frames[1].extra == {"camera_temperature": 31.5}
    assert back.to_dict() == data
    made = irf.SequenceReport(weights=seq.weights, frames=[dict(f) for f in seq.frames])  # rows given as dicts
    assert all(isinstance(f, FrameEntry) for f in made.frames) and made.frames == seq.frames


# --------------------------------------------------------------------------- pickling
def test_a_pair_report_pickles_and_renders_after_unpickling():
    rep = pair_inputs()["object"]
    again = pickle.loads(pickle.dumps(rep))
    assert again == rep and again.to_dict() == rep.to_dict()
    page = again.to_html()
    for section in ("Frames", "Difference", "SSIM map", "Joint histogram", "MTF", "SiTF"):
        assert section in page, section
    assert "Not shown: no frames" not in page


@pytest.mark.parametrize("source", ["arrays", "files"])
def test_a_sequence_report_pickles_and_renders_its_thumbnails_after_unpickling(source, tmp_path):
    if source == "arrays":
        seq = _sequence()
    else:
        stack = DATA / "thermal" / "cptv_v2_all100frames_uint16.tif"
        seq = irf.score_sequence(irf.FrameSequence(stack)[:4], irf.FrameSequence(stack)[1:5], bits=14,
                                 peak="range", progress=False)
    again = pickle.loads(pickle.dumps(seq))
    assert again == seq and again.to_dict() == seq.to_dict() and again.summary_text() == seq.summary_text()
    real, sim = again.sources["frames"](1)
    expected = seq.sources["frames"](1)
    assert np.array_equal(real, expected[0]) and np.array_equal(sim, expected[1])
    page = again.to_html(worst=3)
    assert "Worst frames" in page and "worst frames: real, simulated and difference" in page


def test_a_report_read_back_from_json_pickles():
    seq = irf.SequenceReport.from_dict(json.loads(json.dumps(_sequence().to_dict())))
    assert pickle.loads(pickle.dumps(seq)) == seq


# --------------------------------------------------------------------------- run options
def test_run_options_or_keywords_give_the_same_run(tmp_path):
    by_keywords = _sequence(workers=1, csv=tmp_path / "a.csv")
    by_object = _sequence(run=RunOptions(workers=1, progress=False, csv=tmp_path / "b.csv"))
    assert by_object.frames == by_keywords.frames and by_object.metrics == by_keywords.metrics
    assert by_object.run["csv"] == str(tmp_path / "b.csv") and by_object.run["workers"] == 1
    assert (tmp_path / "a.csv").read_text().replace("a.csv", "") == (tmp_path / "b.csv").read_text().replace("b.csv", "")


def test_a_run_option_given_twice_is_an_error():
    real = np.zeros((2, 8, 8), dtype=np.uint16)
    with pytest.raises(FidelityError, match="workers given twice"):
        irf.score_sequence(real, real, run=RunOptions(workers=2), workers=3)
    with pytest.raises(FidelityError, match="run must be a RunOptions"):
        irf.score_sequence(real, real, run={"workers": 2})


@pytest.mark.parametrize("options, needle", [
    ({"workers": 0}, "workers must be an integer in 1..65536 or None"),
    ({"workers": True}, "workers must be an integer"),
    ({"chunk_size": 0}, "chunk_size must be an integer in 1..65536"),
    ({"resume": True}, "resuming needs the CSV"),
])
def test_run_options_are_checked_when_made(options, needle):
    with pytest.raises(FidelityError, match=needle) as info:
        RunOptions(**options)
    assert info.value.option == next(iter(options)) or "csv" in needle.lower()
    with pytest.raises(FidelityError, match=needle):  # the keywords go through the same check
        irf.score_sequence(np.zeros((2, 8, 8), dtype=np.uint16), np.zeros((2, 8, 8), dtype=np.uint16), **options)


# --------------------------------------------------------------------------- noise options
def test_noise_options_or_keywords_give_the_same_measurement():
    from irfidelity.noise import NoiseOptions

    rng = np.random.default_rng(2)
    cube = np.round(1000 + rng.normal(0, 3, (1, 24, 1)) + rng.normal(0, 2, (12, 24, 20))).astype(np.uint16)
    by_keywords = irf.noise.noise3d(cube, bits=12, detrend="plane", spectra_pairs=4)
    by_object = irf.noise.noise3d(cube, NoiseOptions(bits=12, detrend="plane", spectra_pairs=4))
    assert by_object.sigma == by_keywords.sigma and by_object.ci == by_keywords.ci
    with pytest.raises(FidelityError, match="bits given twice"):
        irf.noise.noise3d(cube, NoiseOptions(bits=12), bits=12)
    with pytest.raises(FidelityError, match="options must be a NoiseOptions"):
        irf.noise.noise3d(cube, {"bits": 12})
    with pytest.raises(TypeError, match="'colour'"):
        irf.noise.noise3d(cube, colour=1)
    with pytest.raises(FidelityError, match="confidence must lie in"):
        NoiseOptions(confidence=1.5)
