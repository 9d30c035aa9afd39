"""One mask or ROI for every frame pair of a sequence (issue 27): ``score_sequence(mask=,
roi=)``, ``score_simulators``, ``irfidelity score/rank --mask/--roi``, in every backend (the
Rust engine on files, the array loop, Dask), with registration, the ceiling and resume.

Data: the real 100-frame Lepton recording (multi-page uint16 TIFF, tests/data/thermal); the
"simulated" frames are the real ones with a gain, an offset and seeded noise, plus a dead
cluster and a hot border that a mask leaves out.
"""

from __future__ import annotations

import json
import pathlib
import warnings

import numpy as np
import pytest

import irfidelity as irf
from irfidelity import _core
from irfidelity.ceiling import pair_ceiling
from irfidelity.cli import main
from irfidelity.errors import FidelityError, ShapeError
from irfidelity.masks import parse_roi, scoring_mask
from irfidelity.sequence import RunOptions, score_sequence
from irfidelity.sequence.plan import SequenceRequest
from irfidelity.stats import PairRequest
from scene_off import NO_SCENE

tifffile = pytest.importorskip("tifffile")
cv2 = pytest.importorskip("cv2")

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
STACK = DATA / "cptv_v2_all100frames_uint16.tif"
FRAMES = 10
CONFIG = irf.ScoringConfig(bits=14, peak="range", hist_range="full")
QUIET = RunOptions(progress=False)


def _simulate(frames: np.ndarray, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = frames.astype(np.int64) * 1.01 - 20 + rng.normal(0, 6, frames.shape)
    sim = np.clip(np.rint(x), 0, 16383).astype(np.uint16)
    sim[:, 50:56, 80:86] = 0  # a dead cluster
    sim[:, :2, :] = 16000  # a hot border
    return sim


@pytest.fixture(scope="module")
def lepton(tmp_path_factory):
    """(real TIFF, simulated TIFF, real frames, simulated frames, mask) of the recording's
    first frames; the mask leaves out the dead cluster and the hot border."""
    real = tifffile.imread(STACK)[:FRAMES]
    sim = _simulate(real, 1)
    folder = tmp_path_factory.mktemp("masked")
    real_path, sim_path = folder / "real.tif", folder / "sim.tif"
    tifffile.imwrite(real_path, real, compression="zlib")
    tifffile.imwrite(sim_path, sim, compression="zlib")
    mask = np.ones(real.shape[1:], dtype=bool)
    mask[48:58, 78:88] = False
    mask[:3, :] = False
    return real_path, sim_path, real, sim, mask


def _quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", irf.FidelityWarning)
        return fn(*args, **kwargs)


def _close(a: dict, b: dict) -> bool:
    """Dicts of the same keys whose numbers agree to 1e-13 and whose other values are equal."""
    assert set(a) == set(b)
    for k in a:
        number = isinstance(a[k], float) and isinstance(b[k], float)
        assert a[k] == (pytest.approx(b[k], rel=1e-13) if number else b[k]), k
    return True


def _same_numbers(a, b):
    """Two sequence reports with the same values per frame and pooled (whatever the frames' names)."""
    numbers = ("metrics", "components", "fidelity", "grade", "error", "registration")
    assert [[f[k] for k in numbers] for f in a.frames] == [[f[k] for k in numbers] for f in b.frames]
    # pooled: Pool sums each frame's error relative to its range in completion order (float)
    assert _close(a.metrics, b.metrics) and a.components == pytest.approx(b.components, rel=1e-13)
    assert a.fidelity == pytest.approx(b.fidelity, rel=1e-13) and a.grade == b.grade


# ---- the numbers --------------------------------------------------------------------------

def test_every_frame_is_scored_as_evaluate_scores_it_with_the_mask(lepton):
    real_path, sim_path, real, sim, mask = lepton
    config = CONFIG.replace(**NO_SCENE)
    for source in ((real_path, sim_path), (real, sim)):
        rep = score_sequence(*source, config=config, run=QUIET, mask=mask)
        assert not rep.failed
        for i in (0, 4, FRAMES - 1):
            alone = irf.evaluate(real[i], sim[i], config=config, mask=mask)
            assert rep.frames[i]["metrics"] == alone.metrics
            assert rep.frames[i]["components"] == alone.components
            assert rep.frames[i]["metrics"]["n"] == mask.sum()
    unmasked = score_sequence(real, sim, config=CONFIG, run=QUIET)
    assert rep.components["ssim"] > unmasked.components["ssim"]  # the defects are left out


def test_the_pooled_error_is_that_of_the_masked_pixels(lepton):
    _, _, real, sim, mask = lepton
    rep = score_sequence(real, sim, config=CONFIG, run=QUIET, mask=mask)
    diff = real[:, mask].astype(np.int64) - sim[:, mask].astype(np.int64)
    assert rep.metrics["n"] == diff.size
    # peak="range": each frame's squared error relative to its own (masked) range, pixel-weighted
    ranges = real[:, mask].max(axis=1).astype(float) - real[:, mask].min(axis=1)
    relative = ((diff.astype(float) ** 2).mean(axis=1) / ranges ** 2).mean()
    assert rep.metrics["psnr_db"] == pytest.approx(-10 * np.log10(relative), rel=1e-12)
    # with a fixed peak, the pooled MSE is exactly that of every masked pixel
    fixed = _quiet(score_sequence, real, sim, config=CONFIG.replace(peak=16383.0), run=QUIET, mask=mask)
    assert fixed.metrics["mse"] == pytest.approx((diff.astype(float) ** 2).mean(), rel=1e-15)


def test_an_roi_equals_its_mask_and_the_cropped_frames(lepton):
    _, _, real, sim, _ = lepton
    box = np.zeros(real.shape[1:], dtype=bool)
    box[10:90, 20:140] = True
    by_roi = score_sequence(real, sim, config=CONFIG, run=QUIET, roi="10:90,20:140")
    by_tuple = score_sequence(real, sim, config=CONFIG, run=QUIET, roi=(10, 90, 20, 140))
    by_mask = score_sequence(real, sim, config=CONFIG, run=QUIET, mask=box)
    cropped = score_sequence(real[:, 10:90, 20:140], sim[:, 10:90, 20:140], config=CONFIG, run=QUIET)
    _same_numbers(by_roi, by_mask)
    _same_numbers(by_roi, by_tuple)
    assert by_roi.metrics["masked"] == FRAMES * (120 * 160 - 80 * 120) and cropped.metrics["masked"] == 0
    assert {**by_roi.metrics, "masked": 0} == cropped.metrics and by_roi.fidelity == cropped.fidelity
    assert by_roi.inputs["mask"] == {"pixels": 80 * 120, "of": 120 * 160, "shape": [120, 160],
                                     "roi": [10, 90, 20, 140], "mask": None}
    assert by_mask.inputs["mask"]["mask"] == "array" and by_mask.inputs["mask"]["roi"] is None
    assert any("ROI rows 10:90, columns 20:140" in n and "9600 of 19200 pixels" in n for n in by_roi.notes)
    assert by_roi.to_dict()["inputs"]["mask"]["pixels"] == 9600
    both = score_sequence(real, sim, config=CONFIG, run=QUIET, mask=box, roi=(0, 50, 0, 160))
    assert both.metrics["n"] == FRAMES * 40 * 120


def test_every_backend_gives_the_same_numbers(lepton, tmp_path):
    real_path, sim_path, real, sim, mask = lepton
    options = dict(config=CONFIG, mask=mask)
    engine = score_sequence(real_path, sim_path, run=QUIET, **options)
    arrays = score_sequence(real, sim, run=QUIET, **options)
    for side, frames in (("real", real), ("sim", sim)):
        (tmp_path / side).mkdir()
        for i, frame in enumerate(frames):
            cv2.imwrite(str(tmp_path / side / f"f{i:03d}.png"), frame)
    pngs = score_sequence(tmp_path / "real", tmp_path / "sim", run=QUIET, **options)
    np.save(tmp_path / "mask.npy", mask.astype(np.uint8))
    from_file = score_sequence(real_path, sim_path, run=QUIET, config=CONFIG, mask=tmp_path / "mask.npy")
    for other in (arrays, pngs, from_file):
        _same_numbers(engine, other)
    assert from_file.inputs["mask"]["mask"] == str(tmp_path / "mask.npy")
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None,
                                  silence_logs=40) as cluster, distributed.Client(cluster) as client:
        remote = score_sequence(real_path, sim_path, client=client, chunk_size=3, progress=False, **options)
    _same_numbers(engine, remote)


@pytest.mark.parametrize("each", [False, True], ids=["registered-once", "registered-each"])
def test_registration_is_searched_and_scored_within_the_mask(lepton, each):
    real_path, _, real, _, _ = lepton
    shifted = np.roll(_simulate(real, 2), (2, -3), axis=(1, 2))
    mask = np.ones(real.shape[1:], dtype=bool)
    mask[:5] = False
    mask[46:60, 74:90] = False  # the defects, where they are in both frames
    config = CONFIG.replace(register="translation", register_each=each, bins=64, **NO_SCENE)
    with pytest.raises(irf.errors.RegistrationError):  # the defects mislead the registration
        _quiet(irf.evaluate, real[0], shifted[0], config=config)
    rep = _quiet(score_sequence, real, shifted, config=config, run=QUIET, mask=mask)
    assert not rep.failed
    for i in (0, FRAMES - 1):
        reg = irf.registration.Registration.from_dict(rep.frames[i]["registration"] if each else rep.registration)
        assert reg.shift == pytest.approx((-2, 3), abs=0.05)
        # scored: the real pixels within the mask covered by unmasked simulated pixels
        assert rep.frames[i]["metrics"]["n"] == np.count_nonzero(reg.apply(shifted[i], mask=mask)[1] & mask)
        if each:
            assert rep.frames[i]["metrics"] == _quiet(irf.evaluate, real[i], shifted[i], config=config,
                                                      mask=mask).metrics
    if not each:  # the registration applied to every pair is the first pair's, found over the mask
        assert rep.registration == _quiet(irf.evaluate, real[0], shifted[0], config=config, mask=mask).registration
    path = pathlib.Path(real_path).with_name(f"shifted{int(each)}.tif")
    tifffile.imwrite(path, shifted)
    _same_numbers(rep, _quiet(score_sequence, real_path, path, config=config, run=QUIET, mask=mask))


def test_the_ceiling_is_measured_over_the_mask(lepton):
    _, _, real, sim, mask = lepton
    rep = _quiet(score_sequence, real, sim, config=CONFIG.replace(peak=16383.0), run=QUIET, mask=mask)
    bare = _quiet(score_sequence, real, sim, config=CONFIG.replace(peak=16383.0), run=QUIET)
    assert rep.ceiling is not None and rep.ceiling != bare.ceiling
    starts = sorted({int(round(i)) for i in np.linspace(0, FRAMES - 2, min(8, FRAMES - 1))})
    for key in ("nmi", "ssim"):
        values = [pair_ceiling(real[t], real[t + 1], ("nmi", "ssim"), CONFIG.replace(peak=16383.0), mask=mask)[key]
                  for t in starts]
        assert rep.ceiling[key] == pytest.approx(float(np.median(values)), rel=1e-12)


# ---- resume ---------------------------------------------------------------------------------

def test_resume_needs_the_same_mask(lepton, tmp_path):
    real_path, sim_path, _, _, mask = lepton
    log = tmp_path / "run.csv"
    first = score_sequence(real_path, sim_path, config=CONFIG, progress=False, csv=log, mask=mask)
    again = score_sequence(real_path, sim_path, config=CONFIG, progress=False, csv=log, resume=True, mask=mask)
    assert again.run["resumed"] == FRAMES
    _same_numbers(first, again)
    other = mask.copy()
    other[100:, :] = False
    for changed in (dict(mask=other), dict(), dict(roi="0:100,:")):
        with pytest.raises(FidelityError, match="cannot resume") as err:
            score_sequence(real_path, sim_path, config=CONFIG, progress=False, csv=log, resume=True, **changed)
        assert err.value.option == "resume"
    # without resume the run starts again with the new mask
    fresh = score_sequence(real_path, sim_path, config=CONFIG, progress=False, csv=log, mask=other)
    assert fresh.run["resumed"] == 0 and fresh.metrics["n"] == FRAMES * other.sum()


# ---- errors -----------------------------------------------------------------------------------

def test_a_wrong_mask_or_roi_is_a_clear_error(lepton, tmp_path):
    _, _, real, sim, mask = lepton
    cases = [
        (dict(mask=mask[:-1]), ShapeError, "mask has shape (119, 160), the frames (120, 160)", "mask"),
        (dict(mask=np.zeros_like(mask)), FidelityError, "mask leave no pixel to score", "mask"),
        (dict(mask=mask, roi="0:2,:"), FidelityError, "mask and roi leave no pixel to score", "mask"),
        (dict(roi="0:200,:"), FidelityError, "rows 0:200 are not a non-empty range within the frame's 120 rows",
         "roi"),
        (dict(roi=(0, 10, 150, 170)), FidelityError, "columns 150:170", "roi"),
        (dict(roi="rows 1-5"), FidelityError, "Y0:Y1,X0:X1", "roi"),
        (dict(mask=tmp_path / "missing.png"), FidelityError, "missing.png", "mask"),
        (dict(mask=np.array(["a"] * mask.size).reshape(mask.shape)), FidelityError, "bool or numeric", "mask"),
    ]
    for kwargs, kind, needle, option in cases:
        with pytest.raises(kind) as err:
            score_sequence(real, sim, config=CONFIG, run=QUIET, **kwargs)
        assert needle in str(err.value) and err.value.option == option, (kwargs, str(err.value))


def test_a_frame_of_another_shape_than_the_mask_is_its_own_error_row(lepton, tmp_path):
    _, _, real, sim, mask = lepton
    for side, frames in (("real", real), ("sim", sim)):
        (tmp_path / side).mkdir()
        for i in range(3):
            cv2.imwrite(str(tmp_path / side / f"f{i}.png"), frames[i, :100] if i == 1 else frames[i])
    rep = score_sequence(tmp_path / "real", tmp_path / "sim", config=CONFIG, run=QUIET, mask=mask)
    assert rep.failed == [1] and "the mask has shape (120, 160), the frames (100, 160)" in rep.frames[1]["error"]


def test_the_engine_takes_one_mask_for_the_run_and_checks_it(lepton):
    real_path, sim_path, real, sim, mask = lepton
    request = SequenceRequest(PairRequest(sse=True, moments=True))
    rows = _core.score_pairs([str(real_path)] * 2, [str(sim_path)] * 2, [0, 1], [0, 1], request=request, mask=mask)
    for _, stats, err, *_ in rows:
        assert err is None and stats.n == mask.sum()
    for bad, needle in ((mask.reshape(-1), "2-D"), (np.zeros_like(mask), "no pixel"),
                        (np.ones((3, 4), dtype=bool), None)):
        if needle is None:  # a mask of another shape: each pair's error
            rows = _core.score_pairs([str(real_path)], [str(sim_path)], request=request, mask=bad)
            assert "the mask has shape (3, 4), the frames (120, 160)" in rows[0][2]
            continue
        with pytest.raises(FidelityError, match=needle):
            _core.score_pairs([str(real_path)], [str(sim_path)], request=request, mask=bad)


def test_parse_roi_and_scoring_mask():
    assert parse_roi(":,5:", (4, 8)) == (slice(0, 4), slice(5, 8))
    m = scoring_mask(np.eye(4), None, (4, 4))
    assert m.pixels == 4 and m.roi is None and m.values.dtype == bool and m.values.flags.c_contiguous
    assert scoring_mask(None, None, (4, 4)) is None
    assert m.digest() != scoring_mask(np.eye(4)[::-1], None, (4, 4)).digest()
    with pytest.raises(FidelityError, match="roi"):
        parse_roi((0, 2, 0), (4, 4))


# ---- several simulators -------------------------------------------------------------------

def test_score_simulators_scores_every_simulator_over_the_mask(lepton, tmp_path):
    real_path, sim_path, real, sim, mask = lepton
    other = _simulate(real, 5) // 2 * 2
    other_path = tmp_path / "other.tif"
    tifffile.imwrite(other_path, other)
    for source, sims in ((real_path, {"a": sim_path, "b": other_path}), (real, {"a": sim, "b": other})):
        result = irf.score_simulators(source, sims, config=CONFIG, progress=False, resamples=199, mask=mask)
        for name, frames in (("a", sim), ("b", other)):
            alone = score_sequence(real, frames, config=CONFIG, run=QUIET, mask=mask)
            _same_numbers(result.reports[name], alone)
            assert result.reports[name].inputs["mask"]["pixels"] == mask.sum()


# ---- command line ---------------------------------------------------------------------------

def test_cli_masks_and_rois_sequences(lepton, tmp_path, capsys):
    real_path, sim_path, real, sim, mask = lepton
    np.save(tmp_path / "mask.npy", mask.astype(np.uint8))
    cv2.imwrite(str(tmp_path / "mask.png"), mask.astype(np.uint8) * 255)
    base = ["score", str(real_path), str(sim_path), "--bits", "14", "--peak", "range", "--hist-range", "full",
            "--no-progress"]
    want = score_sequence(real, sim, config=CONFIG, run=QUIET, mask=mask, roi="0:100,:")
    for name in ("mask.npy", "mask.png"):
        out = tmp_path / f"{name}.json"
        assert main([*base, "--mask", str(tmp_path / name), "--roi", "0:100,:", "--json", str(out)]) == 0
        got = json.loads(out.read_text())
        # (the pooled PSNR peak sums the frames' relative errors in completion order: last bits)
        assert _close(got["metrics"], json.loads(json.dumps(want.metrics)))
        assert got["inputs"]["mask"]["roi"] == [0, 100, 0, 160]
        assert got["inputs"]["mask"]["pixels"] == int((mask[:100]).sum())
    capsys.readouterr()
    ranked = tmp_path / "rank.json"
    assert main(["rank", str(real_path), str(sim_path), str(real_path), "--names", "sim,same", "--bits", "14",
                 "--peak", "range", "--no-progress", "--resamples", "199", "--roi", "10:90,20:140",
                 "--json", str(ranked)]) == 0
    capsys.readouterr()
    reports = json.loads(ranked.read_text())["reports"]
    assert all(r["inputs"]["mask"]["pixels"] == 80 * 120 for r in reports.values())
    np.save(tmp_path / "small.npy", np.ones((10, 10), dtype=np.uint8))
    np.save(tmp_path / "empty.npy", np.zeros(mask.shape, dtype=np.uint8))
    for flags, needle in [(["--roi", "0:500,:"], "rows 0:500"), (["--roi", "a:b"], "Y0:Y1,X0:X1"),
                          (["--mask", str(tmp_path / "nope.npy")], "--mask"),
                          (["--mask", str(tmp_path / "small.npy")], "shape (10, 10)"),
                          (["--mask", str(tmp_path / "empty.npy")], "no pixel to score")]:
        for command in (base, ["rank", str(real_path), str(sim_path), str(real_path), "--names", "x,y",
                               "--no-progress"]):
            assert main([*command, *flags]) == 2
            err = capsys.readouterr().err.strip()
            assert len(err.splitlines()) == 1 and needle in err, err
            assert "--mask" in err or "--roi" in err


def test_a_ceilings_range_peak_is_the_masked_range():
    from irfidelity.ceiling import pair_ceiling
    from irfidelity.config import ScoringConfig

    rng = np.random.default_rng(3)
    a = rng.integers(100, 200, (32, 32)).astype(np.uint16)
    a[0, 0] = 4000  # outside the mask: must not set the peak
    b = (a.astype(np.int64) + rng.integers(-3, 4, a.shape)).clip(0).astype(np.uint16)
    mask = np.ones(a.shape, bool)
    mask[0, 0] = False
    got = pair_ceiling(a, b, ("psnr",), ScoringConfig(peak="range", weights="psnr=1"), mask=mask)
    peak = float(a[mask].max()) - float(a[mask].min())
    want = irf.evaluate(a, b, mask=mask, peak=peak, weights="psnr=1").components["psnr"]
    assert got["psnr"] == pytest.approx(want, rel=1e-12)
