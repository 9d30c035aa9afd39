"""Pooled sequence values lie within their frames' values (docs/design.md §11, "Pooled values
inside their frames"; irfidelity.sequence.pooling).

Every pooled component — psnr (fixed peak and ``peak="range"``), the RMS error it is graded by,
nmi (``hist_range`` "data" and "full"), ssim and radiometry — lies within ``[min, max]`` of the
scored frames' values, on the real 100-frame Lepton recording, on a pan with a moving object
built from one of its frames (where the SSIM of the pooled moments does not), and on random
sequences. ``report.ci`` brackets the pooled values, a resumed run pools to the same values, and
the pooled fidelity stays within the bound docs/interpretation.md states.

Data: tests/data/thermal/cptv_v2_all100frames_uint16.tif (FLIR Lepton 3, 160 × 120, 14-bit).
"""

from __future__ import annotations

import math
import pathlib
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import irfidelity as irf
from irfidelity.errors import PeakWarning
from irfidelity.temperature import radiometry_component

tifffile = pytest.importorskip("tifffile")

STACK = pathlib.Path(__file__).parent / "data" / "thermal" / "cptv_v2_all100frames_uint16.tif"
IMAGE = "psnr=0.4,nmi=0.3,ssim=0.3"
RADIOMETRY = "psnr=0.3,ssim=0.3,radiometry=0.4"
CALIBRATION = {"gain": 0.01, "offset": 0.0}  # counts → kelvin, cheap temperatures of the recording
REL = 1e-12


@pytest.fixture(scope="module")
def recording():
    real = tifffile.imread(STACK)
    assert real.shape == (100, 120, 160) and real.dtype == np.uint16
    rng = np.random.default_rng(1)
    sim = np.clip(np.rint(real.astype(np.int64) * 1.01 - 20 + rng.normal(0, 6, real.shape)), 0, 16383)
    return real, sim.astype(np.uint16)


@pytest.fixture(scope="module")
def pan(recording):
    """A 100 × 120 window panning 2 px a frame across the recording's first frame, with a hot
    square moving the other way; the simulation drifts in gain from frame to frame and places
    the square one pixel off."""
    base = recording[0][0].astype(np.int64)
    rng = np.random.default_rng(2)
    real, sim = [], []
    for i, k in enumerate(range(0, 40, 2)):
        window = base[10:110, k:k + 120].copy()
        moved = window.copy()
        window[40:52, 100 - 4 * i:112 - 4 * i] += 300
        moved[41:53, 100 - 4 * i:112 - 4 * i] += 300
        sim.append((moved - 3000) * (1 + 0.02 * (i % 3)) + 3000 + rng.normal(0, 8, moved.shape))
        real.append(window)
    return (np.stack(real).astype(np.uint16),
            np.clip(np.rint(np.stack(sim)), 0, 16383).astype(np.uint16))


def _score(real, sim, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PeakWarning)
        return irf.score_sequence(real, sim, progress=False, **options)


def _scored(rep):
    return [f for f in rep.frames if f["error"] is None]


def _within(value, values, name):
    lo, hi = min(values), max(values)
    slack = REL * max(abs(lo), abs(hi), 1e-300)
    assert lo - slack <= value <= hi + slack, f"{name}: pooled {value!r} outside the frames' [{lo!r}, {hi!r}]"


def _rms_fractions(rep, real):
    """Each frame's RMS error as a fraction of its real frame's range."""
    return [math.sqrt(f["metrics"]["mse"]) / (int(real[f["index"]].max()) - int(real[f["index"]].min()))
            for f in _scored(rep)]


def assert_pooled_within(rep, real=None):
    """Every pooled component, the PSNR in dB, the raw NMI/SSIM metrics and (given the real
    frames) the RMS error relative to the range lie within the frames' values."""
    frames = _scored(rep)
    assert frames and set(rep.components) == set(frames[0]["components"])
    for component, value in rep.components.items():
        _within(value, [f["components"][component] for f in frames], component)
    for key in ("psnr_db", "nmi", "mi", "h_joint", "ssim", "ssim_structure"):
        if key in rep.metrics:
            _within(rep.metrics[key], [f["metrics"][key] for f in frames], key)
    if real is not None and "psnr" in rep.components:
        _within(rep.verdict["components"]["psnr"]["measure"], _rms_fractions(rep, real), "rms_error")


def assert_fidelity_bound(rep):
    """The pooled fidelity differs from the pixel-weighted mean of the frames' fidelities only by
    the non-linear components (normalised PSNR, radiometry): exactly their weighted departure from
    their own frame means, so outside the frames' fidelities by at most their weighted spread."""
    frames = _scored(rep)
    counts = np.array([f["metrics"]["n"] for f in frames], dtype=float)
    share = counts / counts.sum()
    departure = 0.0
    spread = 0.0
    for component in ("psnr", "radiometry"):
        if component in rep.components:
            values = np.array([f["components"][component] for f in frames])
            departure += rep.weights[component] * (rep.components[component] - float(share @ values))
            spread += rep.weights[component] * float(values.max() - values.min())
    fidelities = np.array([f["fidelity"] for f in frames])
    assert rep.fidelity - float(share @ fidelities) == pytest.approx(departure, abs=1e-12)
    outside = max(fidelities.min() - rep.fidelity, rep.fidelity - fidelities.max(), 0.0)
    assert outside <= spread + 1e-12
    return outside


# --------------------------------------------------------------------------- the real recording
@pytest.mark.parametrize("options", [
    dict(bits=14),
    dict(bits=14, peak="range"),
    dict(bits=14, hist_range="full"),
    dict(bits=14, peak="range", hist_range="full"),
], ids=["default", "peak-range", "hist-full", "range-and-full"])
def test_the_recording_pools_within_its_frames(recording, options):
    real, sim = recording
    rep = _score(real, sim, weights=IMAGE, **options)
    assert rep.pooling["frames"] == 100 and rep.pooling["nmi"] == rep.pooling["ssim"] == "pixel_mean"
    assert_pooled_within(rep, real)
    assert assert_fidelity_bound(rep) == 0.0  # on the recording the fidelity is inside too


def test_the_range_peak_pools_within_its_frames_psnr(recording):
    """The issue's case: with ``peak="range"`` the pooled PSNR pools each frame's error relative
    to its own range, not the whole sequence's range."""
    real, sim = recording
    rep = _score(real[:30], sim[:30], weights="psnr=1", bits=14, peak="range")
    db = [f["metrics"]["psnr_db"] for f in rep.frames]
    _within(rep.metrics["psnr_db"], db, "psnr_db")
    whole = int(real[:30].max()) - int(real[:30].min())
    assert max(f["metrics"]["psnr_peak"] for f in rep.frames) < whole  # the sequence's range would be wider
    relative = [f["metrics"]["mse"] / f["metrics"]["psnr_peak"] ** 2 for f in rep.frames]
    assert rep.metrics["psnr_db"] == pytest.approx(-10 * math.log10(math.fsum(relative) / len(relative)), rel=1e-14)


# --------------------------------------------------------------------------- a pan with a moving object
def _moment_pooled_ssim(real, sim):
    """The SSIM of all frames as one image: what the pooled moments give."""
    return irf.pair_stats(real.reshape(-1, real.shape[-1]), sim.reshape(-1, sim.shape[-1]), bits=14,
                          need=("moments",)).ssim().value


@pytest.mark.parametrize("hist_range", ["data", "full"])
def test_a_pan_pools_within_its_frames(pan, hist_range):
    real, sim = pan
    rep = _score(real, sim, weights=IMAGE, bits=14, peak="range", hist_range=hist_range)
    assert_pooled_within(rep, real)
    assert_fidelity_bound(rep)
    frames = [f["components"]["ssim"] for f in rep.frames]
    assert not min(frames) <= _moment_pooled_ssim(real, sim) <= max(frames)  # why SSIM is not moment-pooled


def test_opposite_temperature_offsets_do_not_cancel(recording):
    """Radiometry: frames alternately 0.4 K too warm and too cold. The component of all pixel
    pairs together would be better than every frame's; the pooled one lies within them."""
    real, _ = recording
    offsets = np.where(np.arange(20) % 2 == 0, 40, -40)[:, None, None]
    noise = np.rint(np.random.default_rng(3).normal(0, 5, real[:20].shape)).astype(np.int64)
    sim = np.clip(real[:20].astype(np.int64) + offsets + noise, 0, 16383).astype(np.uint16)
    rep = _score(real[:20], sim, unit="K", calibration=CALIBRATION, weights=RADIOMETRY)
    assert_pooled_within(rep)
    assert_fidelity_bound(rep)
    frames = [f["components"]["radiometry"] for f in rep.frames]
    m = rep.metrics
    together = radiometry_component(m["temperature_bias"], m["temperature_rmse"], m["temperature_tolerance"])
    assert together > max(frames) and abs(m["temperature_bias"]) < 0.01


# --------------------------------------------------------------------------- intervals and resume
def _assert_ci_holds(rep):
    assert "pooled as the sequence pools" in rep.pooling["ci"]["method"]
    for quantity, (lo, hi) in rep.ci.items():
        value = rep.fidelity if quantity == "fidelity" else rep.components[quantity]
        slack = REL * abs(value)
        assert lo - slack <= value <= hi + slack, quantity


def test_intervals_hold_the_pooled_values(recording, pan):
    real, sim = recording
    _assert_ci_holds(_score(real, sim, weights=IMAGE, bits=14, peak="range", hist_range="full", ci=True))
    _assert_ci_holds(_score(*pan, weights=IMAGE, bits=14, ci=True))
    offsets = np.where(np.arange(12) % 2 == 0, 30, -30)[:, None, None]
    warm = np.clip(real[:12].astype(np.int64) + offsets, 0, 16383).astype(np.uint16)
    _assert_ci_holds(_score(real[:12], warm, unit="K", calibration=CALIBRATION, weights=RADIOMETRY, ci=True))


@pytest.mark.parametrize("case", ["pan", "radiometry"])
def test_a_resumed_run_pools_equal(tmp_path, pan, recording, case):
    if case == "pan":
        real, sim = pan
        options = dict(weights=IMAGE, bits=14, peak="range", hist_range="full")
    else:
        real = recording[0][:8]
        sim = np.clip(real.astype(np.int64) + np.arange(-40, 40, 10)[:, None, None], 0, 16383).astype(np.uint16)
        options = dict(unit="K", calibration=CALIBRATION, weights=RADIOMETRY)
    out = tmp_path / "frames.csv"
    first = _score(real, sim, csv=out, **options)
    again = _score(real, sim, csv=out, resume=True, **options)
    assert again.run["resumed"] == len(real)
    assert again.components == first.components and again.fidelity == first.fidelity
    assert again.metrics == first.metrics
    assert_pooled_within(again)


# --------------------------------------------------------------------------- random sequences
@st.composite
def sequences(draw):
    frames = draw(st.integers(2, 5))
    rows, cols = draw(st.integers(6, 12)), draw(st.integers(6, 12))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    ramp = np.add.outer(np.arange(rows), np.arange(cols)) * draw(st.integers(1, 50))
    scale = rng.uniform(0.2, 3.0, (frames, 1, 1))  # frames of very different contrast
    real = 1000 + ramp[None] * scale + rng.normal(0, draw(st.floats(0, 40)), (frames, rows, cols))
    shift = rng.integers(-50, 50, (frames, 1, 1))  # offsets that differ between frames
    sim = real * rng.uniform(0.8, 1.2, (frames, 1, 1)) + shift + rng.normal(0, draw(st.floats(0, 60)), real.shape)
    as_counts = lambda x: np.clip(np.rint(x), 0, 16383).astype(np.uint16)  # noqa: E731
    return as_counts(real), as_counts(sim), draw(st.sampled_from([None, "range"])), \
        draw(st.sampled_from(["data", "full"]))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sequences())
def test_random_sequences_pool_within_their_frames(case):
    real, sim, peak, hist_range = case
    rep = _score(real, sim, weights=IMAGE, bits=14, peak=peak, hist_range=hist_range)
    assert_pooled_within(rep, real)
    assert_fidelity_bound(rep)


def test_the_pool_does_not_depend_on_the_order_frames_finish_in():
    import itertools
    import types

    from irfidelity.sequence.pooling import Pool

    rng = np.random.default_rng(5)
    frames = [(rng.integers(0, 4000, (16, 16)).astype(np.uint16), rng.integers(0, 4000, (16, 16)).astype(np.uint16))
              for _ in range(4)]
    plan = types.SimpleNamespace(image=("psnr",))
    ranges = []
    for order in itertools.permutations(range(4)):
        pool = Pool(plan)
        for i in order:
            real, sim = frames[i]
            pool.add(i, irf.pair_stats(real, sim, need=("psnr",)), (float(real.min()), float(real.max()) * (1 + i)))
        ranges.append(pool.scene_range())
    assert len(set(ranges)) == 1
