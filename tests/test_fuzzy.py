"""Weights, eq. (15), AHP, fuzzy grades and the simulator comparison (irfidelity.fuzzy)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from irfidelity.errors import FidelityError
from irfidelity.fuzzy import (
    COMPONENTS,
    PAPER_COMPONENTS,
    AHPConsistencyWarning,
    GradeScale,
    Weights,
    ahp,
    compare,
    fidelity_sum,
)


# --------------------------------------------------------------------------- Weights
class TestWeights:
    def test_default_is_paper(self):
        w = Weights()
        assert w == Weights.balanced()
        assert w.as_dict() == {**{k: 0.2 for k in PAPER_COMPONENTS}, "noise": 0.0, "radiometry": 0.0, "mrtd": 0.0}
        assert w.active() == PAPER_COMPONENTS

    def test_presets_valid_and_emphasised(self):
        p, q = Weights.performance(), Weights.image_quality()
        assert math.isclose(sum(p.as_dict().values()), 1) and math.isclose(sum(q.as_dict().values()), 1)
        assert min(p.mtf, p.sitf) > max(p.psnr, p.nmi, p.ssim)
        assert min(q.psnr, q.nmi, q.ssim) > max(q.mtf, q.sitf)

    @pytest.mark.parametrize("kw,msg", [
        (dict(mtf=float("nan"), sitf=0.2, psnr=0.2, nmi=0.2, ssim=0.4), "finite"),
        (dict(mtf=float("inf")), "finite"),
        (dict(mtf=-0.2, sitf=0.4), ">= 0"),
        (dict(mtf=0.3), "sum to 1"),
        (dict(mtf="a"), "number"),
        (dict(mtf=True), "number"),
    ])
    def test_rules(self, kw, msg):
        with pytest.raises(ValueError, match=msg) as ei:
            Weights(**kw)
        assert isinstance(ei.value, FidelityError)

    def test_sum_tolerance(self):
        Weights(mtf=0.2 + 5e-10)
        with pytest.raises(FidelityError, match="sum to 1"):
            Weights(mtf=0.2 + 5e-9)

    def test_frozen(self):
        w = Weights()
        with pytest.raises(AttributeError):
            w.mtf = 0.5  # type: ignore[misc]

    def test_normalized(self):
        w = Weights.normalized(mtf=3, psnr=1)
        assert w.as_dict() == {"mtf": 0.75, "sitf": 0.0, "psnr": 0.25, "nmi": 0.0, "ssim": 0.0, "noise": 0.0,
                               "radiometry": 0.0, "mrtd": 0.0}
        with pytest.raises(FidelityError, match="all be 0"):
            Weights.normalized(mtf=0)
        with pytest.raises(FidelityError, match="unknown"):
            Weights.normalized(mft=1)

    @pytest.mark.parametrize("text,expect", [
        ("balanced", Weights()),
        ("performance", Weights.performance()),
        ("image-quality", Weights.image_quality()),
        ("IMAGE_QUALITY", Weights.image_quality()),
        ("psnr=1", Weights(mtf=0, sitf=0, psnr=1, nmi=0, ssim=0)),
        ("mtf=0.3, sitf=0.3,psnr=0.2,nmi=0.1,ssim=0.1", Weights(mtf=.3, sitf=.3, psnr=.2, nmi=.1, ssim=.1)),
        ("mtf=3,psnr=1,normalize", Weights.normalized(mtf=3, psnr=1)),
    ])
    def test_parse(self, text, expect):
        assert Weights.parse(text) == expect

    @pytest.mark.parametrize("text,msg", [
        ("fancy", "preset"),
        ("mtf=0.5", "sum to 1"),
        ("mtf=x", "not a number"),
        ("foo=1", "bad item"),
        ("psnr=0.5,psnr=0.5", "twice"),
        ("psnr=-1,ssim=2", ">= 0"),
    ])
    def test_parse_errors(self, text, msg):
        with pytest.raises(FidelityError, match=msg):
            Weights.parse(text)

    def test_coerce(self):
        assert Weights.coerce(None) == Weights()
        assert Weights.coerce({"psnr": 1}) == Weights.parse("psnr=1")
        with pytest.raises(FidelityError):
            Weights.coerce(3)


def test_fidelity_sum_is_eq15():
    f = {"mtf": 0.9, "sitf": 0.8, "psnr": 0.7, "nmi": 0.3, "ssim": 0.95}
    w = Weights(mtf=0.1, sitf=0.2, psnr=0.3, nmi=0.25, ssim=0.15)
    assert fidelity_sum(w, f) == math.fsum(w[k] * f[k] for k in PAPER_COMPONENTS)
    # the opt-in components add like the others
    w8 = Weights(mtf=0.1, sitf=0.1, psnr=0.3, nmi=0.2, ssim=0.1, noise=0.1, radiometry=0.05, mrtd=0.05)
    f8 = {**f, "noise": 0.5, "radiometry": 0.7, "mrtd": 0.8}
    assert set(f8) == set(COMPONENTS)
    assert fidelity_sum(w8, f8) == math.fsum(w8[k] * f8[k] for k in COMPONENTS)
    with pytest.raises(FidelityError, match="no value"):
        fidelity_sum(w, {"mtf": 1.0})


# --------------------------------------------------------------------------- AHP
class TestAHP:
    def test_consistent_matrix_gives_exact_weights(self):
        # a consistent matrix is m[i][j] = w_i / w_j; AHP must recover w and CR = 0
        w = np.array([0.4, 0.3, 0.15, 0.1, 0.05])
        m = w[:, None] / w[None, :]
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            res = ahp(m)
        assert np.allclose([res.weights[k] for k in PAPER_COMPONENTS], w, rtol=0, atol=1e-12)
        assert res.weights.noise == 0.0  # the default names are the paper's five
        assert res.lambda_max == pytest.approx(5, abs=1e-9)
        assert res.cr == pytest.approx(0, abs=1e-9) and res.consistent
        assert Weights.from_ahp(m) == res.weights

    def test_subset_of_components(self):
        m = [[1, 2, 4], [1 / 2, 1, 2], [1 / 4, 1 / 2, 1]]
        w = Weights.from_ahp(m, names=("psnr", "nmi", "ssim"))
        assert w.mtf == 0 and w.sitf == 0
        assert (w.psnr, w.nmi, w.ssim) == pytest.approx((4 / 7, 2 / 7, 1 / 7), abs=1e-12)

    def test_saaty_textbook_example(self):
        # Saaty-style 3x3 with rounded reciprocals (1/3 typed as 0.33): accepted, CR ~ 0.03
        m = [[1, 3, 5], [0.33, 1, 2], [0.2, 0.5, 1]]
        res = ahp(m, names=("mtf", "sitf", "psnr"))
        assert res.consistent and 0 < res.cr < 0.1
        pr = [res.priorities[k] for k in ("mtf", "sitf", "psnr")]
        assert pr == pytest.approx([0.648, 0.230, 0.122], abs=0.005)

    def test_inconsistent_warns_or_raises(self):
        # a > b, b > c, c > a: intransitive judgements
        m = [[1, 5, 1 / 5], [1 / 5, 1, 5], [5, 1 / 5, 1]]
        names = ("mtf", "psnr", "ssim")
        with pytest.warns(AHPConsistencyWarning, match="consistency ratio"):
            w = Weights.from_ahp(m, names=names)
        assert w.as_dict()["mtf"] == pytest.approx(1 / 3)
        with pytest.raises(FidelityError, match="consistency ratio"):
            Weights.from_ahp(m, names=names, on_inconsistent="raise")
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            res = ahp(m, names=names, on_inconsistent="ignore")
        assert res.cr > 1 and not res.consistent

    @pytest.mark.parametrize("m,msg", [
        ([[1, 2], [2, 1]], "reciprocal"),
        ([[2, 1], [1, 1]], "diagonal"),
        ([[1, -1], [-1, 1]], "positive"),
        ([[1, 2, 3], [0.5, 1, 1]], "must be 2x2"),
    ])
    def test_bad_matrices(self, m, msg):
        with pytest.raises(FidelityError, match=msg):
            ahp(m, names=("mtf", "sitf"))


# --------------------------------------------------------------------------- grades
class TestGrades:
    def test_partition_of_unity_and_shape(self):
        gs = GradeScale()
        for comp in COMPONENTS:
            for f in np.linspace(0, 1, 201):
                row = gs.memberships(comp, f)
                assert list(row) == ["excellent", "good", "fair", "poor"]
                assert math.fsum(row.values()) == pytest.approx(1, abs=1e-12)
                assert all(0 <= v <= 1 for v in row.values())
        # well inside a class: crisp
        assert gs.memberships("ssim", 0.99)["excellent"] == 1
        assert gs.memberships("ssim", 0.1)["poor"] == 1
        assert gs.memberships("ssim", 0.65)["good"] == 1
        assert gs.memberships("nmi", 0.06)["fair"] == pytest.approx(1, abs=1e-12)
        # on a boundary: half and half
        row = gs.memberships("ssim", 0.82)
        assert row["excellent"] == pytest.approx(0.5) and row["good"] == pytest.approx(0.5)

    def test_b_is_k_times_r(self):
        gs = GradeScale()
        w = Weights(mtf=0.1, sitf=0.2, psnr=0.3, nmi=0.25, ssim=0.15)
        f = {"mtf": 0.96, "sitf": 0.86, "psnr": 0.716, "nmi": 0.22074, "ssim": 0.933}
        g = gs.evaluate(w, f)
        R = np.array([[gs.memberships(k, f[k])[gr] for gr in gs.grades] for k in PAPER_COMPONENTS])
        K = np.array([w[k] for k in PAPER_COMPONENTS])
        assert np.allclose([g.membership[gr] for gr in gs.grades], K @ R, atol=1e-15)
        assert sum(g.membership.values()) == pytest.approx(1)
        # the overall grade: the weighted average of B, capped one above the worst component
        score = sum(g.membership[gr] * (3 - i) for i, gr in enumerate(gs.grades))
        worst = max(gs.grades.index(v) for v in g.component_grades.values())
        assert g.grade == gs.grades[max(3 - math.floor(score + 0.5), worst - 1, 0)]

    def test_custom_and_errors(self):
        cuts = {k: (0.5,) for k in COMPONENTS}
        gs = GradeScale(grades=("pass", "fail"), cuts=cuts, width=0)
        assert gs.evaluate(Weights(), {k: 0.6 for k in COMPONENTS}).grade == "pass"
        # ties go to the lower grade
        half = {"mtf": 1.0, "sitf": 1.0, "psnr": 0.0, "nmi": 0.0, "ssim": 1.0}
        w = Weights.normalized(mtf=1, psnr=1)
        assert gs.evaluate(w, half).grade == "fail"
        with pytest.raises(FidelityError, match="boundaries"):
            GradeScale(grades=("a", "b", "c"), cuts=cuts)
        with pytest.raises(FidelityError, match="distinct"):
            GradeScale(grades=("a", "a"), cuts=cuts)
        with pytest.raises(FidelityError, match="apart"):
            GradeScale(cuts={k: (0.5, 0.52, 0.9) for k in COMPONENTS})


# --------------------------------------------------------------------------- compare
class _R:
    def __init__(self, comps, weights=None):
        self.components = comps
        self.weights = weights or Weights()


def test_compare_ranks_and_stability():
    a = _R({"mtf": 0.95, "sitf": 0.95, "psnr": 0.9, "nmi": 0.4, "ssim": 0.95})
    b = _R({"mtf": 0.5, "sitf": 0.6, "psnr": 0.7, "nmi": 0.2, "ssim": 0.8})
    c = _R({"mtf": 0.96, "sitf": 0.94, "psnr": 0.92, "nmi": 0.39, "ssim": 0.95})
    res = compare({"A": a, "B": b, "C": c}, samples=4000, seed=1)
    assert res.ranking == ["C", "A", "B"]
    assert res.p_first["B"] == 0  # dominated everywhere
    assert res.p_first["A"] + res.p_first["C"] == pytest.approx(1)
    assert 0.05 < res.p_first["A"] < 0.95  # A and C swap under weight noise
    assert res.fidelity["A"] == fidelity_sum(Weights(), a.components)
    assert res.mean_rank["B"] == 3
    again = compare({"A": a, "B": b, "C": c}, samples=4000, seed=1)
    assert again.p_first == res.p_first  # reproducible with a seed
    tight = compare({"A": a, "C": c}, samples=4000, seed=1, concentration=1e6)
    assert tight.p_first[tight.ranking[0]] > 0.99  # no weight noise: ranking at K wins
    d = res.to_dict()
    assert d["ranking"] == res.ranking and "summary" not in d
    assert "P(first)" in res.summary_text()


def test_compare_errors():
    a = _R({"mtf": 1.0, "sitf": 1.0, "psnr": 1.0, "nmi": 1.0, "ssim": 1.0})
    b = _R({"psnr": 1.0}, Weights.parse("psnr=1"))
    with pytest.raises(FidelityError, match="different weights"):
        compare({"a": a, "b": b})
    with pytest.raises(FidelityError, match="'b' has no value"):
        compare({"a": a, "b": b}, weights=Weights())
    # comparing on PSNR only works for both
    assert compare({"a": a, "b": b}, weights="psnr=1").p_first == {"a": 0.5, "b": 0.5}
    with pytest.raises(FidelityError, match="non-empty"):
        compare({})
