"""The ceiling from the real camera's 3-D noise (irfidelity.noise.repeatability, issue 27).

A real frame and the camera's temporal noise give the components a second real frame of the
scene would reach. Checked against two synthetic real frames of a real scene with that noise,
against its own Monte-Carlo realisations, against noise3d's definitions of the parts, and on
the real PTW recordings. Data: tests/data/thermal (see tests/data/README.md).
"""

from __future__ import annotations

import json
import math
import pathlib
import warnings

import numpy as np
import pytest

import irfidelity as irf
from irfidelity.ceiling import pair_ceiling
from irfidelity.cli import main
from irfidelity.errors import FidelityError, NoiseWarning
from irfidelity.noise.repeatability import noise_ceiling, second_frame, temporal_sigma

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
LEPTON = DATA / "cptv_v2_frame000.png"  # a real 160 × 120 Lepton frame: the scene
LWIR_UNIFORM = DATA / "ptw_lwir_all100frames_uint16.tif"  # 100 frames of a near-uniform source (PTW LWIR)
BB150 = [DATA / "ptw_bb150C_frame000.png", DATA / "ptw_bb150C_frame001.png"]  # two real frames, one scene

COMPONENTS = ("psnr", "nmi", "ssim")
CONFIG = irf.ScoringConfig(bits=14, peak="range")
SEEDS = 6
QUIET = {"t": 1.0, "tv": 0.7, "th": 1.2, "tvh": 4.0}  # noise well below the scene's σ of 16.8 counts
LOUD = {"t": 3.0, "tv": 3.0, "th": 5.0, "tvh": 40.0}  # noise that dominates the scene


def real_frame(scene: np.ndarray, sigma: dict, rng: np.random.Generator) -> np.ndarray:
    """A real frame of ``scene``: its temporal noise part by part (noise3d's model), as counts."""
    rows, cols = scene.shape
    noise = (rng.normal(0, sigma["t"]) + rng.normal(0, sigma["tv"], (rows, 1)) + rng.normal(0, sigma["th"], (1, cols))
             + rng.normal(0, sigma["tvh"], scene.shape))
    return np.round(scene + noise).astype(np.uint16)


@pytest.fixture(scope="module")
def scene() -> np.ndarray:
    return irf.load_frame(LEPTON).astype(np.float64)


def spread(values: list[float]) -> tuple[float, float]:
    """Mean and standard error of the mean."""
    return float(np.mean(values)), float(np.std(values, ddof=1) / math.sqrt(len(values)))


@pytest.mark.parametrize("sigma", [QUIET, LOUD], ids=["quiet", "loud"])
def test_noise_ceiling_is_that_of_two_real_frames(scene, sigma):
    # Two real frames with a known noise (real_ref's ceiling) against the noise ceiling of one of
    # them: both are random, so they must agree within 3 standard errors of the difference of
    # their means over the seeds (plus 0.002 for the 14-bit rounding of the frames). The loud case
    # is where adding the noise to the real frame without compensation fails (SSIM 0.71 for 0.59).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoiseWarning)
        pairs = [(real_frame(scene, sigma, rng), real_frame(scene, sigma, rng))
                 for rng in map(np.random.default_rng, range(SEEDS))]
        measured = [pair_ceiling(a, b, COMPONENTS, CONFIG) for a, b in pairs]
        derived = [noise_ceiling(a, sigma, COMPONENTS, CONFIG) for a, _ in pairs]
    for k in COMPONENTS:
        (m, m_se), (d, d_se) = spread([c[k] for c in measured]), spread([c[k] for c in derived])
        assert abs(m - d) <= 3 * math.hypot(m_se, d_se) + 0.002, (k, m, d)


def test_uncompensated_noise_would_not_be(scene):
    # The reason for the compensation: a + independent difference noise is not a second frame.
    rng = np.random.default_rng(0)
    a, b = real_frame(scene, LOUD, rng), real_frame(scene, LOUD, rng)
    naive = a + rng.normal(0, math.sqrt(2) * LOUD["tvh"], a.shape)
    measured = pair_ceiling(a, b, ("ssim",), CONFIG)["ssim"]
    assert pair_ceiling(a.astype(float), naive, ("ssim",), irf.ScoringConfig(peak=16383.0))["ssim"] > measured + 0.05
    assert noise_ceiling(a, LOUD, ("ssim",), CONFIG)["ssim"] == pytest.approx(measured, abs=0.02)


@pytest.mark.parametrize("sigma", [QUIET, LOUD], ids=["quiet", "loud"])
def test_closed_form_equals_monte_carlo(scene, sigma):
    # SSIM and PSNR in closed form against the same components of seeded second frames: the mean
    # over 24 realisations within 3 standard errors (+ 0.001 for the rounding to counts).
    a = real_frame(scene, sigma, np.random.default_rng(1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoiseWarning)
        closed = noise_ceiling(a, sigma, COMPONENTS, CONFIG)
        drawn = [pair_ceiling(a, second_frame(a, sigma, CONFIG, seed=s), ("psnr", "ssim"), CONFIG) for s in range(24)]
    for k in ("psnr", "ssim"):
        mean, se = spread([c[k] for c in drawn])
        assert abs(closed[k] - mean) <= 3 * se + 0.001, (k, closed[k], mean, se)
    # and the mean squared difference is 2 Σ σ² exactly in expectation
    mse = [float(np.mean((second_frame(a, sigma, CONFIG, seed=s).astype(float) - a) ** 2)) for s in range(24)]
    mean, se = spread(mse)
    assert abs(mean - 2 * sum(v * v for v in sigma.values())) <= 3 * se


def test_second_frame_differs_by_noise3d_parts_times_root_two(scene):
    # noise3d of a stack of second frames recovers each temporal part of the difference noise:
    # √(1 + κ)·σ (κ = 1 − σ_s²/var ≈ 0.94 here; √2·σ as κ → 1) and √2·σ_t, within its 99 % intervals.
    a = real_frame(scene, QUIET, np.random.default_rng(2))
    kappa = 1 - (QUIET["tv"] ** 2 + QUIET["th"] ** 2 + QUIET["tvh"] ** 2) / float(np.var(a.astype(float)))
    cube = np.stack([second_frame(a, QUIET, CONFIG, seed=s) for s in range(40)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoiseWarning)  # the scene is the fixed pattern here
        measured = irf.noise.noise3d(cube, confidence=0.99)
    expected = {"t": math.sqrt(2) * QUIET["t"], **{p: math.sqrt(1 + kappa) * QUIET[p] for p in ("tv", "th", "tvh")}}
    for part, value in expected.items():
        low, high = measured.ci[part]
        assert low <= value <= high, (part, value, measured.ci[part])
    assert 0.9 < kappa < 1


def test_deterministic_and_seeded(scene):
    a = real_frame(scene, QUIET, np.random.default_rng(3))
    first = noise_ceiling(a, QUIET, COMPONENTS, CONFIG)
    assert noise_ceiling(a, QUIET, COMPONENTS, CONFIG) == first
    assert irf.evaluate(a, a, real_noise=QUIET, config=CONFIG).ceiling == first
    other = noise_ceiling(a, QUIET, COMPONENTS, CONFIG, seed=5)
    assert other["nmi"] != first["nmi"] and other["ssim"] == first["ssim"]  # only NMI is drawn


def test_real_recording_on_a_real_pair():
    # The PTW LWIR camera's noise (a near-uniform recording: σ_tvh 2.0 counts) on the PTW blackbody
    # pair, whose own frame difference has σ 3.2/√2 = 2.3 counts: the derived NMI within 0.02 of
    # the pair's (NMI falls by ~0.01 for 10 % more noise here), SSIM and PSNR both 1 to 4 places.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoiseWarning)
        noise = irf.noise.noise3d(LWIR_UNIFORM)
    real, other = (irf.load_frame(p) for p in BB150)
    measured = pair_ceiling(real, other, COMPONENTS, irf.ScoringConfig())
    derived = noise_ceiling(real, noise, COMPONENTS, irf.ScoringConfig())
    assert derived["nmi"] == pytest.approx(measured["nmi"], abs=0.02)
    assert derived["ssim"] == pytest.approx(measured["ssim"], abs=1e-4)
    assert derived["psnr"] == pytest.approx(measured["psnr"], abs=1e-4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoiseWarning)
        rep = irf.evaluate(real, other, real_noise=LWIR_UNIFORM)
    assert rep.grade == "excellent" and rep.ceiling_source == "noise3d"  # real vs real of a still scene
    assert rep.inputs["real_noise"] == str(LWIR_UNIFORM)


@pytest.mark.parametrize("sigma", [QUIET, LOUD], ids=["quiet", "loud"])
def test_real_vs_real_grades_excellent(scene, sigma):
    rng = np.random.default_rng(4)
    a, b = real_frame(scene, sigma, rng), real_frame(scene, sigma, rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoiseWarning)
        rep = irf.evaluate(a, b, real_noise=sigma, config=CONFIG, weights="nmi=0.5,ssim=0.5")
    assert rep.grade == "excellent", rep.verdict["reason"]
    assert "from the real camera's 3-D noise" in rep.verdict["reason"]


def test_a_simulator_is_graded_against_it(scene):
    rng = np.random.default_rng(5)
    a = real_frame(scene, QUIET, rng)
    blurred = np.round(0.5 * scene + 0.25 * (np.roll(scene, 1, 0) + np.roll(scene, 1, 1))).astype(np.uint16)
    sim = real_frame(blurred.astype(float), {p: 4 * v for p, v in QUIET.items()}, rng)
    rep = irf.evaluate(a, sim, real_noise=QUIET, config=CONFIG, weights="nmi=0.5,ssim=0.5")
    assert rep.relative["nmi"] < 0.8 and rep.grade != "excellent"
    assert rep.verdict["components"]["nmi"]["basis"] == "ceiling"


def test_precedence_and_sources(scene):
    rng = np.random.default_rng(6)
    a, b, sim = (real_frame(scene, QUIET, rng) for _ in range(3))
    noise_only = irf.evaluate(a, sim, real_noise=QUIET, config=CONFIG)
    assert noise_only.ceiling_source == "noise3d" and noise_only.verdict["ceiling_source"] == "noise3d"
    with_ref = irf.evaluate(a, sim, real_ref=b, real_noise=QUIET, config=CONFIG)
    assert with_ref.ceiling_source == "real_ref"
    assert with_ref.ceiling == irf.evaluate(a, sim, real_ref=b, config=CONFIG).ceiling
    given = {"nmi": 0.5, "ssim": 0.9}
    explicit = irf.evaluate(a, sim, ceiling=given, real_noise=QUIET, config=CONFIG)
    assert explicit.ceiling == given and explicit.ceiling_source == "given"
    none = irf.evaluate(a, sim, config=CONFIG)
    assert none.ceiling is None and none.ceiling_source is None
    with pytest.raises(FidelityError, match="not both"):
        irf.evaluate(a, sim, real_ref=b, ceiling=given, config=CONFIG)


def test_readback_and_text(scene):
    rng = np.random.default_rng(7)
    a, sim = real_frame(scene, QUIET, rng), real_frame(scene, QUIET, rng)
    rep = irf.evaluate(a, sim, real_noise=QUIET, config=CONFIG)
    back = irf.FidelityReport.from_dict(json.loads(json.dumps(rep.to_dict())))
    assert back == rep and back.ceiling_source == "noise3d" and back.ceiling == rep.ceiling
    assert "ceiling (real vs real), from the real camera's 3-D noise:" in rep.summary_text()
    assert "The camera against itself (from the real camera&#x27;s 3-D noise)" in rep.to_html()


def test_sequence_takes_the_noise(scene):
    rng = np.random.default_rng(8)
    real = [real_frame(scene, QUIET, rng) for _ in range(4)]
    sim = [real_frame(scene, QUIET, rng) for _ in range(4)]
    consecutive = irf.score_sequence(real, sim, config=CONFIG, progress=False)
    assert consecutive.ceiling_source == "sequence"
    with_noise = irf.score_sequence(real, sim, config=CONFIG, progress=False, real_noise=QUIET)
    assert with_noise.ceiling_source == "noise3d" and with_noise.inputs["real_noise"] == "dict"
    for k in ("nmi", "ssim"):  # a still scene: both ceilings estimate the same repeatability
        assert with_noise.ceiling[k] == pytest.approx(consecutive.ceiling[k], abs=0.01)
    one = irf.score_sequence(real[:1], sim[:1], config=CONFIG, progress=False, real_noise=QUIET)
    assert one.ceiling_source == "noise3d" and one.ceiling is not None  # one real frame: no consecutive pair
    assert irf.score_sequence(real[:1], sim[:1], config=CONFIG, progress=False).ceiling is None
    back = type(with_noise).from_dict(json.loads(json.dumps(with_noise.to_dict())))
    assert back.ceiling_source == "noise3d"


def test_cli_real_noise_sets_the_ceiling(tmp_path, capsys):
    out = tmp_path / "pair.json"
    assert main(["score", str(BB150[0]), str(BB150[1]), "--real-noise", str(LWIR_UNIFORM), "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["verdict"]["ceiling_source"] == "noise3d" and set(data["ceiling"]) == set(COMPONENTS)
    assert "from the real camera's 3-D noise" in capsys.readouterr().out
    # the simulator's noise alone is still a usage error (it has nothing to compare with)
    assert main(["score", str(BB150[0]), str(BB150[1]), "--sim-noise", str(LWIR_UNIFORM)]) == 2
    assert "needs the real one too" in capsys.readouterr().err


def test_cli_noise_detrend_and_roi_measure_as_noise3d_does(tmp_path, capsys):
    from irfidelity.noise import noise3d

    out = tmp_path / "pair.json"
    args = ["score", str(BB150[0]), str(BB150[1]), "--real-noise", str(LWIR_UNIFORM)]
    assert main([*args, "--noise-detrend", "plane", "--noise-roi", "8:60,10:70", "--json", str(out)]) == 0
    noise = noise3d(str(LWIR_UNIFORM), detrend="plane", roi=(8, 60, 10, 70))
    want = irf.evaluate(str(BB150[0]), str(BB150[1]), real_noise=noise)
    assert json.loads(out.read_text())["ceiling"] == want.ceiling
    capsys.readouterr()
    assert main([*args, "--noise-roi", "8:72"]) == 2
    assert "--noise-roi: expected Y0:Y1,X0:X1" in capsys.readouterr().err
    assert main([*args, "--noise-roi", "8:72,16:9000"]) == 2
    err = capsys.readouterr().err
    assert "outside" in err and "--real-noise" in err and err.count("\n") == 1


def test_cli_words_the_noise_advice_as_flags():
    from irfidelity.cli.output import cli_wording

    text = "... pass detrend='plane' to remove it ... a uniform region with roi=(r0, r1, c0, c1)"
    assert cli_wording(text) == "... pass --noise-detrend plane to remove it ... a uniform region with --noise-roi " \
                                "Y0:Y1,X0:X1"


def test_bad_noise_and_degenerate_frames(scene):
    a = real_frame(scene, QUIET, np.random.default_rng(9))
    with pytest.raises(FidelityError, match="σ_tvh .* must be a finite number >= 0") as err:
        noise_ceiling(a, {"tvh": -1.0}, COMPONENTS, CONFIG)
    assert err.value.option == "real_noise"
    with pytest.raises(FidelityError, match="Noise3D .* or a mapping"):
        irf.evaluate(a, a, real_noise={"v": 3.0}, config=CONFIG)
    with pytest.raises(FidelityError, match="2-D real frame"):
        noise_ceiling(np.zeros((2, 3, 4)), QUIET, COMPONENTS, CONFIG)
    assert temporal_sigma({"tvh": 2}) == {"t": 0.0, "tv": 0.0, "th": 0.0, "tvh": 2.0}
    # noiseless camera: a second frame is the frame itself
    assert noise_ceiling(a, {"tvh": 0.0}, COMPONENTS, CONFIG) == {"psnr": 1.0, "nmi": 1.0, "ssim": 1.0}
    # noise beyond the frame's own variance: said, and the ceiling is that of uncorrelated frames
    with pytest.warns(NoiseWarning, match="at least the real frame's variance"):
        loud = noise_ceiling(a, {"tvh": 100.0}, COMPONENTS, CONFIG)
    assert loud["ssim"] == 0.0 and loud["nmi"] < 0.05


def test_temperature_frames_get_no_noise_ceiling(scene):
    # the noise is in counts; frames scored in kelvin would be compared with it in other units
    real = 290.0 + scene / 100.0
    with pytest.warns(NoiseWarning, match="frame units and the frames are scored in K"):
        rep = irf.evaluate(real, real + 0.05, unit="K", real_noise=QUIET, weights="nmi=0.5,ssim=0.5")
    assert rep.ceiling is None and rep.ceiling_source is None
