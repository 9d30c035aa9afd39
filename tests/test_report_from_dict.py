"""Reports read back from dicts: ``from_dict`` refuses a malformed dict with a FidelityError
naming the field, or returns a report that summarises, serialises and renders.

The mutation campaign starts from real reports (a registered pair with curves; a sequence with
failed frames; a sequence registered frame by frame with a delay) and mutates them with a
seeded mutator (tests/report_mutations.py): keys dropped, types changed, NaN / huge /
negative numbers and deep nesting inserted anywhere."""

from __future__ import annotations

import json
import math
from functools import lru_cache

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.errors import FidelityError
from irfidelity.readback import MAX_REPORT_DEPTH
from report_inputs import pair_inputs, sequence_report
from report_mutations import mutations

pytest.importorskip("matplotlib")

MUTATIONS = 300


@lru_cache(maxsize=1)
def registered_sequence() -> dict:
    """A sequence registered frame by frame, paired with a delay of one frame."""
    rng = np.random.default_rng(0)
    rows, cols = np.mgrid[0:64, 0:80]
    count = 24
    level = rng.normal(0, 300, count).cumsum()
    blob = np.exp(-((cols - 40) ** 2 + (rows - 30) ** 2) / 200)
    real = np.stack([3000 + 200 * np.sin(cols / 5.0 + 0.3 * k) + 100 * np.cos(rows / 4.0) + level[k] * blob
                     + rng.normal(0, 5, rows.shape) for k in range(count)]).clip(0, 16000).astype(np.uint16)
    sim = np.stack([np.roll(real[min(i + 1, count - 1)], 1, axis=0) for i in range(count)])
    report = irf.score_sequence(real, sim, bits=14, progress=False, register="translation", register_each=True,
                                max_delay=2)
    return json.loads(json.dumps(report.to_dict()))


@lru_cache(maxsize=1)
def registered_pair() -> dict:
    d = pair_inputs()
    report = irf.evaluate(d["real"], d["sim"], bits=14, register="translation", weights="image_quality",
                          missing="renormalize", real_mtf=d["curves"]["real_mtf"], sim_mtf=d["curves"]["sim_mtf"],
                          real_sitf=d["curves"]["real_sitf"], sim_sitf=d["curves"]["sim_sitf"])
    return json.loads(json.dumps(report.to_dict()))


BASES = {
    "pair": (irf.FidelityReport, registered_pair),
    "sequence with failures": (irf.SequenceReport, lambda: json.loads(json.dumps(sequence_report(12, failed_every=5)))),
    "registered sequence": (irf.SequenceReport, registered_sequence),
}


def assert_usable(report) -> None:
    assert isinstance(report.summary_text(), str)
    json.dumps(report.to_dict(), allow_nan=False)  # what the CLI writes
    page = report.to_html()
    assert page.startswith("<!DOCTYPE html>")


@pytest.mark.parametrize("name", list(BASES))
def test_the_unmutated_reports_read_back(name):
    cls, base = BASES[name]
    back = cls.from_dict(base())
    assert back.to_dict() == base()
    assert_usable(back)


@pytest.mark.parametrize("name", list(BASES))
def test_mutated_reports_are_refused_or_usable(name):
    cls, base = BASES[name]
    accepted = refused = 0
    for i, data in enumerate(mutations(base(), MUTATIONS, seed=25)):
        try:
            report = cls.from_dict(data)
        except FidelityError:
            refused += 1
            continue
        accepted += 1
        try:
            assert_usable(report)
        except Exception as exc:  # name the mutation that got through
            raise AssertionError(f"mutation {i} was accepted but is not usable: {exc!r}") from exc
    assert accepted > MUTATIONS // 10 and refused > MUTATIONS // 10, (accepted, refused)


@pytest.mark.parametrize("cls", [irf.FidelityReport, irf.SequenceReport])
def test_deep_nesting_is_refused_before_recursing(cls):
    deep: object = 1
    for _ in range(100_000):
        deep = [deep]
    base = registered_pair() if cls is irf.FidelityReport else registered_sequence()
    with pytest.raises(FidelityError, match=f"nested more than {MAX_REPORT_DEPTH} levels"):
        cls.from_dict({**base, "inputs": {"note": deep}})


@pytest.mark.parametrize("change, needle", [
    ({"fidelity": "high"}, "report.fidelity: expected a number"),
    ({"fidelity": 7.5}, "report.fidelity: expected a number in [0, 1]"),
    ({"components": {"psnr": math.nan}}, "report.components.psnr"),
    ({"components": {"colour": 0.5}}, "unknown component(s) colour"),
    ({"components": [0.5]}, "report.components: expected a mapping"),
    ({"membership": {"good": [1]}}, "report.membership.good"),
    ({"metrics": {"psnr_db": {"v": 1}}}, "report.metrics.psnr_db: expected a number"),
    ({"grade": None}, "report.grade: expected a string"),
    ({"notes": "one note"}, "report.notes: expected a list"),
    ({"weights": {"psnr": 2}}, "report.weights"),
    ({"config": {"bits": "x"}}, "report.config"),
    ({"registration": {"model": "translation"}}, "report.registration: missing key(s) method, shift"),
    ({"registration": {**registered_pair()["registration"], "model": "affine"}}, "report.registration.model"),
    ({"grading": {"matrix": {"psnr": 5}}}, "report.grading.matrix.psnr: expected a mapping"),
    ({"inputs": {"n": 10**30}}, "an integer within 64 bits"),
    ({"inputs": {"f": object()}}, "a JSON value"),
])
def test_pair_fields_are_named(change, needle):
    with pytest.raises(FidelityError) as info:
        irf.FidelityReport.from_dict({**registered_pair(), **change})
    assert needle in str(info.value)


def _frames_with(change: dict) -> list:
    frames = json.loads(json.dumps(registered_sequence()["frames"]))
    frames[3].update(change)
    return frames


@pytest.mark.parametrize("change, needle", [
    ({"frames": 3}, "report.frames: expected a list"),
    ({"frames": _frames_with({"index": -1})}, "report.frames[3].index: expected an integer >= 0"),
    ({"frames": _frames_with({"error": 5})}, "report.frames[3].error: expected a string"),
    ({"frames": _frames_with({"registration": {"shift": [0, 0]}})}, "report.frames[3].registration: missing"),
    ({"frames": [{"index": 0}]}, "report.frames[0]: missing key(s) error"),
    ({"grade": None}, "fidelity and grade are both given"),
    ({"failed": ["3"]}, "report.failed[0]: expected an integer >= 0"),
    ({"frame_stats": {"fidelity": {"mean": 1}}}, "report.frame_stats.fidelity: missing key(s) p5"),
    ({"delay": {"frames": 10**9, "confidence": 1, "correlation": {}}}, "report.delay.frames"),
    ({"delay": {"frames": 1, "confidence": 1, "correlation": {"x": 0.5}}}, "report.delay.correlation key"),
    ({"registration": {"model": "translation", "method": "auto", "each": True, "frames": 3,
                       "shift_dy": {"mean": 1}}}, "report.registration.shift_dy: missing key(s)"),
])
def test_sequence_fields_are_named(change, needle):
    with pytest.raises(FidelityError) as info:
        irf.SequenceReport.from_dict({**registered_sequence(), **change})
    assert needle in str(info.value)


def test_a_report_without_a_pooled_result_reads_back():
    data = {**json.loads(json.dumps(sequence_report(6, failed_every=1))), "fidelity": None, "grade": None,
            "components": {}, "membership": {}, "component_grades": {}, "metrics": {}, "frame_stats": {}}
    report = irf.SequenceReport.from_dict(data)
    assert report.fidelity is None and len(report.failed) == 6
    assert_usable(report)


def test_failed_frames_without_error_rows_still_summarise():
    data = json.loads(json.dumps(sequence_report(6, failed_every=100)))
    data["failed"] = [2]
    text = irf.SequenceReport.from_dict(data).summary_text()
    assert "failed frames: 2" in text and "first error" not in text


def test_pixel_counts_stay_integers_through_json():
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 1000, (3, 64, 64)).astype(np.uint16)
    rep = irf.score_sequence(frames, frames, bits=10, progress=False)
    back = irf.SequenceReport.from_dict(json.loads(json.dumps(rep.to_dict())))
    for metrics in (back.metrics, back.frames[0]["metrics"]):
        assert all(type(metrics[k]) is int for k in ("n", "masked", "nonfinite")), metrics
    assert back.to_dict() == rep.to_dict()
