"""evaluate(): plan first, compute second; the report; the paper's worked example (Table 1)."""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
import warnings

import numpy as np
import pytest

import irfidelity._core as core
import irfidelity.stats as stats_mod
from irfidelity.curves import Curve, EdgeWarning, mtf_from_edge, mtf_similarity, sitf_similarity
from irfidelity.errors import FidelityError, ShapeError
from irfidelity.config import ScoringConfig
from irfidelity.evaluation import evaluate
from irfidelity.results import FidelityReport
from irfidelity.scoring import image_components, plan_components
from irfidelity.frames import load_frame
from irfidelity.fuzzy import PAPER_COMPONENTS, Weights, fidelity_sum
from irfidelity.metrics import nmi_from_entropies
from irfidelity.normalize import normalize_psnr
from irfidelity.stats import nmi, pair_stats, psnr, ssim

DATA = pathlib.Path(__file__).parent / "data"
REAL = DATA / "thermal" / "ptw_bb150C_frame000.png"
SIM = DATA / "thermal" / "ptw_bb150C_frame001.png"
EDGE = DATA / "curves" / "sfr_edge_x2084_y0616_F2.png"
JADE = DATA / "curves" / "pyradi_jade_lwir_calibration_sitf.csv"


@pytest.fixture(scope="module")
def frames():
    return load_frame(REAL), load_frame(SIM)


def _grey_edge(path):
    png = pytest.importorskip("png")
    w, h, rows, info = png.Reader(filename=str(path)).asDirect()
    a = np.vstack([np.asarray(r, dtype=np.uint8) for r in rows]).reshape(h, w, info["planes"])
    return np.ascontiguousarray(a[..., 0])


def _blur_rows_cols(img, sigma):
    r = int(math.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    a = np.pad(img.astype(np.float64), r, mode="reflect")
    a = np.apply_along_axis(lambda v: np.convolve(v, k, mode="valid"), 1, a)
    a = np.apply_along_axis(lambda v: np.convolve(v, k, mode="valid"), 0, a)
    return a


@pytest.fixture(scope="module")
def edges():
    real = _grey_edge(EDGE)
    sim = np.clip(np.rint(_blur_rows_cols(real, 0.8)), 0, 255).astype(np.uint8)
    return real, sim


@pytest.fixture(scope="module")
def sitf_curves():
    tab = np.loadtxt(JADE, delimiter=",", skiprows=2)
    cold, warm = tab[tab[:, 0] == 17.1], tab[tab[:, 0] == 34.4]
    return (Curve(cold[:, 2], cold[:, 3], name="Jade 17.1 C"), Curve(warm[:, 2], warm[:, 3], name="Jade 34.4 C"))


# --------------------------------------------------------------------------- plan
class TestPlan:
    def test_full(self):
        w, image, skipped = plan_components(Weights(), "raise", have_images=True, have_mtf=True, have_sitf=True)
        assert w == Weights() and image == ("psnr", "nmi", "ssim") and skipped == {}

    def test_weight_zero_is_planned_out(self):
        w, image, skipped = plan_components(Weights.parse("psnr=1"), "raise", have_images=True, have_mtf=True,
                                            have_sitf=True)
        assert image == ("psnr",)
        assert set(skipped) == {"mtf", "sitf", "nmi", "ssim"} and skipped["nmi"] == "weight 0"

    def test_missing_raise_names_inputs(self):
        with pytest.raises(FidelityError, match="real_mtf/sim_mtf") as ei:
            plan_components(Weights(), "raise", have_images=True, have_mtf=False, have_sitf=True)
        assert "real_sitf" not in str(ei.value) and ei.value.option == "missing"
        with pytest.raises(FidelityError, match=r"real/sim"):
            plan_components(Weights(), "raise", have_images=False, have_mtf=True, have_sitf=True)

    def test_missing_renormalize(self):
        w, image, skipped = plan_components(Weights.performance(), "renormalize", have_images=True,
                                            have_mtf=False, have_sitf=True)
        assert w.mtf == 0 and w.sitf == pytest.approx(0.35 / 0.65)
        assert "real_mtf/sim_mtf" in skipped["mtf"] and "sitf" not in skipped
        assert image == ("psnr", "nmi", "ssim")
        with pytest.raises(FidelityError, match="nothing to compute"):
            plan_components(Weights.parse("mtf=1"), "renormalize", have_images=True, have_mtf=False,
                            have_sitf=False)

    def test_bad_missing(self):
        with pytest.raises(FidelityError, match="missing: expected one of renormalize, raise") as ei:
            evaluate(np.zeros((2, 2), np.uint8), np.zeros((2, 2), np.uint8), missing="drop")
        assert ei.value.option == "missing"


# --------------------------------------------------------------------------- components == standalone functions
def test_components_equal_standalone(frames, edges, sitf_curves):
    r, s = frames
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EdgeWarning)
        rep = evaluate(r, s, real_mtf=edges[0], sim_mtf=edges[1], real_sitf=sitf_curves[0],
                       sim_sitf=sitf_curves[1], bits=14)
        m_r, m_s = mtf_from_edge(edges[0]), mtf_from_edge(edges[1])
    assert list(rep.components) == list(PAPER_COMPONENTS)
    assert rep.components["psnr"] == normalize_psnr(psnr(r, s, bits=14))
    assert rep.metrics["psnr_db"] == psnr(r, s, bits=14)
    assert rep.components["nmi"] == nmi(r, s, hist_range=rep.config.hist_range).value
    assert rep.components["ssim"] == max(ssim(r, s).value, 0)
    assert rep.components["mtf"] == mtf_similarity(m_r, m_s).value
    assert rep.components["sitf"] == sitf_similarity(*sitf_curves).value
    assert rep.metrics["mtf50_sim"] < rep.metrics["mtf50_real"]  # the blur shows
    # eq. (15), exactly
    assert rep.fidelity == math.fsum(rep.weights[k] * rep.components[k] for k in PAPER_COMPONENTS)
    assert rep.fidelity == fidelity_sum(rep.weights, rep.components)
    assert 0 < rep.fidelity < 1 and rep.skipped == {}
    assert rep.grade in rep.membership and sum(rep.membership.values()) == pytest.approx(1)


def test_paths_and_curve_files(frames, tmp_path, sitf_curves):
    r, s = frames
    # SiTF as CSV files, MTF as edge image paths (the real crops as grey PNGs via the edge arrays)
    for name, c in zip(("real.csv", "sim.csv"), sitf_curves):
        np.savetxt(tmp_path / name, np.column_stack([c.x, c.y]), delimiter=",", header="dT,signal")
    rep_p = evaluate(REAL, SIM, real_sitf=tmp_path / "real.csv", sim_sitf=str(tmp_path / "sim.csv"),
                     weights="sitf=0.5,ssim=0.5")
    rep_a = evaluate(r, s, real_sitf=sitf_curves[0], sim_sitf=(sitf_curves[1].x, sitf_curves[1].y),
                     weights="sitf=0.5,ssim=0.5")
    assert rep_p.components == pytest.approx(rep_a.components, rel=1e-12)
    assert rep_p.inputs["real"] == str(REAL)


def test_custom_exponents_and_anchors(frames):
    r, s = frames
    rep = evaluate(r, s, weights="psnr=0.5,ssim=0.5", bits=14, ssim_exponents=(1, 2, 0.5),
                   psnr_anchors=((20, 0.5), (40, 0.9)))
    assert rep.components["ssim"] == max(ssim(r, s, alpha=1, beta=2, gamma=0.5).value, 0)
    assert rep.components["psnr"] == normalize_psnr(psnr(r, s, bits=14), anchors=((20, 0.5), (40, 0.9)))


def test_negative_ssim_clipped():
    rng = np.random.default_rng(0)
    r = rng.integers(0, 255, (32, 32), dtype=np.uint8)
    s = (255 - r).astype(np.uint8)
    rep = evaluate(r, s, weights="ssim=1")
    assert rep.metrics["ssim"] < 0 and rep.components["ssim"] == 0.0 and rep.fidelity == 0.0


# --------------------------------------------------------------------------- plan only what is needed
class _Spy:
    def __init__(self, monkeypatch):
        self.calls = []
        real = core.pair_stats

        def spy(real_frame, sim_frame, request, *a):
            self.calls.append(dataclasses.asdict(request))
            return real(real_frame, sim_frame, request, *a)

        monkeypatch.setattr(core, "pair_stats", spy)


def test_weight_zero_not_computed(frames, monkeypatch):
    r, s = frames
    spy = _Spy(monkeypatch)
    rep = evaluate(r, s, weights="psnr=1", bits=14)
    assert len(spy.calls) == 1
    kw = spy.calls[0]
    assert kw["sse"] is True and kw["moments"] is False
    assert kw["bins"] is None and kw["levels"] is False  # no histogram pass
    assert set(rep.components) == {"psnr"}
    assert not {"nmi", "h_real", "h_sim", "h_joint", "mi", "ssim", "ssim_structure", "mtf50_real"} & set(rep.metrics)
    assert set(rep.skipped) == {"mtf", "sitf", "nmi", "ssim"}

    spy.calls.clear()
    rep = evaluate(r, s, weights="psnr=0.5,ssim=0.5", bits=14)
    assert spy.calls[0]["moments"] is True and spy.calls[0]["bins"] is None
    assert "nmi" not in rep.components and "h_joint" not in rep.metrics

    spy.calls.clear()
    evaluate(r, s, weights="nmi=1", bins="levels")
    assert spy.calls[0]["levels"] is True and spy.calls[0]["sse"] is False and spy.calls[0]["moments"] is False


def test_no_image_pass_without_image_weight(monkeypatch, sitf_curves):
    def boom(*a, **kw):
        raise AssertionError("pair_stats must not be called")

    monkeypatch.setattr(stats_mod, "pair_stats", boom)
    monkeypatch.setattr(core, "pair_stats", boom)
    rep = evaluate("does/not/exist.png", "nor/this.png", real_sitf=sitf_curves[0], sim_sitf=sitf_curves[1],
                   weights="sitf=1")
    assert set(rep.components) == {"sitf"} and rep.fidelity == rep.components["sitf"]


def test_no_curve_work_without_curve_weight(frames, monkeypatch):
    import irfidelity.curves as mtf_module

    def boom(*a, **kw):
        raise AssertionError("no curve work expected")

    monkeypatch.setattr(mtf_module, "mtf_similarity", boom)
    r, s = frames
    # the curve inputs do not even exist: they are never touched
    rep = evaluate(r, s, real_mtf="missing.csv", sim_mtf="missing2.csv", real_sitf="x.csv", sim_sitf="y.csv",
                   weights="psnr=0.4,nmi=0.3,ssim=0.3", bits=14)
    assert set(rep.components) == {"psnr", "nmi", "ssim"}
    assert not any(k.startswith(("mtf", "sitf")) for k in rep.metrics)


# --------------------------------------------------------------------------- missing inputs
def test_missing_inputs(frames):
    r, s = frames
    only_curves = {"transfer_options": {"scene": False}}  # mtf and sitf from camera curves only
    with pytest.raises(FidelityError, match="real_mtf/sim_mtf and real_sitf/sim_sitf"):
        evaluate(r, s, bits=14, missing="raise", **only_curves)
    rep = evaluate(r, s, bits=14, **only_curves)  # missing components are dropped by default, everywhere
    assert rep.config.missing == "renormalize" and ScoringConfig().missing == "renormalize"
    assert set(rep.components) == {"psnr", "nmi", "ssim"}
    assert rep.weights.psnr == pytest.approx(1 / 3) and rep.config.weights == Weights()
    assert "real_mtf/sim_mtf" in rep.skipped["mtf"] and "renormalised" in rep.skipped["sitf"]
    assert rep.fidelity == math.fsum(rep.weights[k] * rep.components[k] for k in rep.components)
    with pytest.raises(FidelityError, match="sim_mtf was given without real_mtf"):
        evaluate(r, s, sim_mtf="x.csv", missing="renormalize")


def test_the_scene_stands_in_for_missing_curves(frames):
    """Without curves, mtf and sitf come from the pair's transfer; a region that holds no whole
    tile cannot give them, and the report says why."""
    r, s = frames
    rep = evaluate(r, s, bits=14)
    for k in ("mtf", "sitf"):
        assert rep.metrics[f"{k}_source"] == "scene" and rep.verdict["components"][k]["source"] == "scene"
    assert rep.transfer["gain"] == rep.metrics["scene_gain"] and "not assessed: noise" in rep.verdict["reason"]
    small = evaluate(r[:40, :40], s[:40, :40], bits=14, transfer_options={"tile": 64})
    assert "mtf" not in small.components and "no whole tile" in small.skipped["mtf"]
    assert "not assessed: mtf" in small.verdict["reason"]
    with pytest.raises(FidelityError, match="from the frames: mtf: the scored region holds no whole tile"):
        evaluate(r[:40, :40], s[:40, :40], bits=14, missing="raise", transfer_options={"tile": 64})
    curves_only = evaluate(r, s, bits=14, transfer_options={"scene": False})
    assert "mtf" not in curves_only.components and "scene_gain" not in curves_only.metrics


def test_errors_name_the_problem(frames, tmp_path):
    r, s = frames
    with pytest.raises(ShapeError, match="differ in shape"):
        evaluate(r, s[:10], weights="psnr=1")
    with pytest.raises(FidelityError, match="nope.png"):
        evaluate(tmp_path / "nope.png", SIM, weights="psnr=1")
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y\n1,2\n2,oops\n3,4\n")
    with pytest.raises(FidelityError, match="bad.csv:3"):
        evaluate(real_sitf=bad, sim_sitf=bad, weights="sitf=1")
    with pytest.raises(FidelityError, match="peak"):
        evaluate(r.astype(np.float32), s.astype(np.float32), weights="psnr=1")


# --------------------------------------------------------------------------- report
def test_json_round_trip(frames, sitf_curves):
    r, s = frames
    rep = evaluate(r, s, real_sitf=sitf_curves[0], sim_sitf=sitf_curves[1], missing="renormalize", bits=14)
    text = json.dumps(rep.to_dict(), allow_nan=False)
    back = FidelityReport.from_dict(json.loads(text))
    assert back == rep
    assert back.to_dict() == rep.to_dict()
    # identical frames: PSNR = +inf survives as "inf"
    same = evaluate(r, r, weights="psnr=1")
    d = json.loads(json.dumps(same.to_dict(), allow_nan=False))
    assert d["metrics"]["psnr_db"] == "inf" and same.components["psnr"] == 1.0
    assert FidelityReport.from_dict(d).metrics["psnr_db"] == math.inf
    with pytest.raises(FidelityError, match="missing key"):
        FidelityReport.from_dict({"fidelity": 1})


def test_summary_text(frames):
    r, s = frames
    t = evaluate(r, s, bits=14, missing="renormalize", transfer_options={"scene": False}).summary_text()
    assert "fidelity" in t and "skipped" in t and "grade" in t and "PSNR" in t
    t = evaluate(r, s, bits=14).summary_text()
    assert "scene: MTF ratio" in t and "scene: gain" in t


# --------------------------------------------------------------------------- the paper's Table 1
class _Table1Stats:
    """PairStats stand-in holding the paper's Table 1 numbers (Fig. 5 / Fig. 6 are not available)."""

    n, masked, nonfinite = 1, 0, 0

    peak = 255.0

    def mse(self):
        return 255.0 ** 2 / 10 ** 2.1072

    def psnr(self):
        return 21.072

    def nmi(self):
        return nmi_from_entropies(6.8712, 6.4682, 11.8671, bins=256)

    def ssim_terms(self, a, b, g):
        l, c, s = 0.9977, 0.9998, 0.9354  # noqa: E741 (SSIM's luminance, contrast, structure)
        return l ** a * c ** b * s ** g, l, c, s


def test_paper_table1():
    comps, mets = image_components(_Table1Stats(), ("psnr", "nmi", "ssim"), ScoringConfig())
    assert mets["mi"] == pytest.approx(1.4723, abs=1e-9)  # the paper prints 1.4724 (rounded inputs)
    assert comps["nmi"] == pytest.approx(0.22074, abs=5e-6)
    assert comps["psnr"] == pytest.approx(0.7160, abs=5e-5)
    assert comps["ssim"] == pytest.approx(0.9331, abs=5e-5)
    # Eq. (15) with k_i = 1/5. The paper does not print f1, f2; its Fidelity = 0.7678 implies
    # f1 + f2 = 5·0.7678 − (f3 + f4 + f5) ≈ 1.969. Assume f1 = f2 = that / 2 (≈ 0.9846 each,
    # two very similar curves) and check the sum reproduces the paper's number.
    f12 = (5 * 0.7678 - (comps["psnr"] + comps["nmi"] + comps["ssim"])) / 2
    assert 0.98 < f12 < 0.99
    fid = fidelity_sum(Weights(), {"mtf": round(f12, 4), "sitf": round(f12, 4), **comps})
    assert fid == pytest.approx(0.7678, abs=5e-5)


def test_image_components_only_the_plan():
    comps, mets = image_components(_Table1Stats(), ("nmi",), ScoringConfig())
    assert set(comps) == {"nmi"} and "psnr_db" not in mets and "ssim" not in mets
    comps, mets = image_components(_Table1Stats(), (), ScoringConfig())
    assert comps == {} and set(mets) == {"n", "masked", "nonfinite"}


def test_sequence_style_use(frames):
    """plan_components + pair_stats + image_components is what evaluate does."""
    r, s = frames
    cfg = ScoringConfig(weights="image_quality", bits=14)
    w, image, _ = plan_components(cfg.weights, cfg.missing, have_images=True, have_mtf=False, have_sitf=False)
    comps, _ = image_components(pair_stats(r, s, bits=14, hist_range=cfg.hist_range, need=image), image, cfg)
    rep = evaluate(r, s, config=cfg)
    assert comps == {k: v for k, v in rep.components.items() if k in image}


def test_a_scorer_checks_its_configuration_once_and_scores_as_evaluate(frames, monkeypatch):
    import pickle

    from irfidelity import Scorer

    real, sim = frames
    with pytest.raises(FidelityError, match="bins"):
        Scorer(bins=0)  # refused when built, before any pair
    with pytest.raises(FidelityError, match="unknown scoring option"):
        Scorer(weight="psnr=1")
    scorer = Scorer(weights="psnr=0.4,nmi=0.3,ssim=0.3", bits=14)
    checked = []
    real_post_init = ScoringConfig.__post_init__
    monkeypatch.setattr(ScoringConfig, "__post_init__", lambda self: checked.append(1) or real_post_init(self))
    reports = [scorer.score(real, sim + k) for k in range(3)]
    assert checked == []  # three pairs, no configuration built or checked again
    for k, report in enumerate(reports):
        want = evaluate(real, sim + k, weights="psnr=0.4,nmi=0.3,ssim=0.3", bits=14)
        assert report.fidelity == want.fidelity and report.components == want.components
        assert report.grade == want.grade and report.config == want.config
    again = pickle.loads(pickle.dumps(scorer))
    assert again.config == scorer.config and again.score(real, sim).fidelity == reports[0].fidelity
    assert Scorer(unit="K").config.peak == "range"  # in a unit, each real frame's temperature range


def test_a_scorer_is_the_configuration_of_a_sequence_and_of_a_comparison(frames):
    import irfidelity as irf

    real, sim = frames
    reals, sims = np.stack([real, real]), np.stack([sim, sim + 3])
    scorer = irf.Scorer(weights="psnr=0.5,ssim=0.5", bits=14)
    by_scorer = irf.score_sequence(reals, sims, config=scorer, progress=False)
    by_options = irf.score_sequence(reals, sims, weights="psnr=0.5,ssim=0.5", bits=14, progress=False)
    assert by_scorer.config == scorer.config and by_scorer.fidelity == by_options.fidelity
    assert irf.Scorer(scorer, bits=16).config.bits == 16  # a scorer's options, overridden
    compared = irf.score_simulators(reals, {"A": sims, "B": sims + 5}, config=scorer, progress=False, resamples=99)
    assert compared.reports["A"].fidelity == by_scorer.fidelity and compared.reports["A"].config == scorer.config
