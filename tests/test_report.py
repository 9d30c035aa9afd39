"""The HTML report without a browser: content, self-containment (a parser-level scan of every
element and attribute), escaping of hostile text, sections left out with a note when their
data is missing, and the message when matplotlib is absent."""

from __future__ import annotations

import re
import sys
from html.parser import HTMLParser

import numpy as np
import pytest
from report_inputs import HOSTILE, pair_inputs, sequence_report

import irfidelity as irf
from irfidelity import FidelityError
from irfidelity.report import render_pair_html, render_sequence_html, write_html

ALLOWED_TAGS = {"html", "head", "meta", "title", "style", "body", "div", "header", "footer", "h1", "h2", "h3", "p",
                "section", "table", "thead", "tbody", "tr", "th", "td", "b", "span", "figure", "img", "figcaption"}


class Scan(HTMLParser):
    """Every element and attribute of a page, to check it loads nothing and runs nothing."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.tags: list[str] = []
        self.attrs: list[tuple[str, str, str]] = []
        self.style = ""
        self._in_style = False
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        self.attrs.extend((tag, k, v or "") for k, v in attrs)
        self._in_style = tag == "style"

    def handle_endtag(self, tag):
        self._in_style = False

    def handle_data(self, data):
        if self._in_style:
            self.style += data
        else:
            self.text.append(data)


def scan(page: str) -> Scan:
    s = Scan()
    s.feed(page)
    s.close()
    return s


def assert_self_contained(page: str) -> Scan:
    """No element that fetches or runs anything; every image a PNG data URI; no URL in CSS;
    the Content-Security-Policy that forbids network fetches."""
    s = scan(page)
    assert set(s.tags) <= ALLOWED_TAGS, set(s.tags) - ALLOWED_TAGS
    for tag, name, value in s.attrs:
        assert not name.startswith("on"), (tag, name)
        if name in ("src", "href", "srcset", "poster", "data", "action", "formaction", "background", "xlink:href"):
            assert tag == "img" and name == "src" and value.startswith("data:image/png;base64,"), (tag, name, value[:60])
    assert "url(" not in s.style and "@import" not in s.style
    assert not any(k == "style" and ("url(" in v or "@import" in v) for _, k, v in s.attrs)
    csp = [v for t, k, v in s.attrs if t == "meta" and k == "content" and "default-src" in v]
    assert csp and "default-src 'none'" in csp[0] and "img-src data:" in csp[0]
    page.encode("utf-8")  # valid UTF-8, no lone surrogates
    return s


def section_ids(page: str) -> dict[str, bool]:
    """Section id -> shown (True) or left out with a note (False)."""
    return {m.group(1): m.group(2) is None for m in re.finditer(r'<section id="([^"]+)"( class="missing")?', page)}


def test_pair_report_has_every_section_and_is_self_contained(tmp_path):
    p = pair_inputs()
    page = render_pair_html(p["report"], real=p["real"], sim=p["sim"], curves=p["curves"])
    s = assert_self_contained(page)
    shown = section_ids(page)
    for sid in ("verdict", "components", "frames", "difference", "ssim-map", "joint-histogram", "mtf", "sitf",
                "settings"):
        assert shown.get(sid) is True, sid
    assert shown.get("registration") is False  # no registration in this report: a note
    assert sum(1 for t, k, v in s.attrs if t == "img" and k == "src") == 8  # 2 frames, 6 figures
    text = " ".join(s.text)
    assert f"{p['report']['fidelity']:.4g}" in text and p["report"]["grade"] in text
    for metric in ("psnr_db", "mtf50_real", "sitf_slope_sim", "h_joint", "ssim_structure"):
        assert metric in text
    # the windowed SSIM mean of the frames, with the report's bits
    assert f"{irf.maps.ssim_map(p['real'], p['sim'], bits=14).mean:.6g}" in text
    assert write_html(page, tmp_path / "r.html") == page
    assert (tmp_path / "r.html").read_text(encoding="utf-8") == page


def test_sequence_report_content():
    d = sequence_report(200, failed_every=23)
    page = render_sequence_html(d, worst=5)
    assert_self_contained(page)
    shown = section_ids(page)
    for sid in ("verdict", "components", "timeline", "distribution", "worst", "failed", "frame-stats", "settings"):
        assert shown.get(sid) is True, sid
    assert shown.get("mtf") is False and shown.get("sitf") is False
    failed = [r for r in d["frames"] if r.get("error")]
    assert len(failed) == 200 // 23
    assert f"{len(failed)} frames could not be scored" in page
    assert all(r["error"].split(":")[0] in page for r in failed)
    # worst frames: the five lowest fidelities, lowest first
    scored = sorted((r["fidelity"], r["index"]) for r in d["frames"] if not r.get("error"))
    table = page[page.index('id="worst"'):page.index('id="failed"')]
    firsts = [int(m) for m in re.findall(r"<tr><td>(\d+)</td>", table)]
    assert firsts == [i for _, i in scored[:5]]


def test_fragment_for_notebooks():
    p = pair_inputs()
    frag = render_pair_html(p["report"], fragment=True)
    assert frag.startswith('<div class="irf-report">') and not re.search(r"<(html|head|body)[\s>]", frag)
    # every style rule is scoped to the report's div
    css = scan(frag).style
    rules = [r.split("{")[0].strip() for r in css.split("}") if "{" in r]
    assert rules and all(sel.startswith(".irf-report") for rule in rules for sel in rule.split(","))


def test_hostile_text_is_escaped():
    p = pair_inputs()
    report = dict(p["report"])
    report["inputs"] = {"real": HOSTILE["script"], "sim": HOSTILE["quotes"], HOSTILE["markup"]: HOSTILE["bytes"]}
    report["notes"] = [HOSTILE["surrogate"], HOSTILE["markup"]]
    report["grade"] = HOSTILE["script"]
    report["membership"] = {HOSTILE["markup"]: 0.5, "good": 0.5}
    report["skipped"] = {HOSTILE["script"]: HOSTILE["quotes"]}
    report["settings"] = {"label": HOSTILE["bytes"], "nested": {HOSTILE["quotes"]: [HOSTILE["script"], 1.5]}}
    page = render_pair_html(report, real=p["real"], sim=p["sim"], title=HOSTILE["script"])
    s = assert_self_contained(page)
    assert "<script" not in page.lower()
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt;" in page
    assert "&quot;quoted&quot;" in page and "onload=&quot;alert(1)&quot;" in page
    text = " ".join(s.text)
    assert "raw\\xff\\xfe<b>bold</b>.png" in text  # the bytes shown as escapes, the markup as text
    assert "name\\udcff\\udcfe.png" in text
    assert HOSTILE["markup"] in text  # parsed back as text, not as elements
    # sequence: hostile frame names and errors
    d = sequence_report(30, failed_every=7)
    d["frames"][0]["real"] = HOSTILE["script"]
    d["frames"][6]["error"] = HOSTILE["markup"]
    d["frames"][13]["sim"] = HOSTILE["bytes"]
    d["settings"] = {HOSTILE["script"]: HOSTILE["surrogate"]}
    seq = render_sequence_html(d, worst=30)
    st = assert_self_contained(seq)
    assert "<script" not in seq.lower()
    seq_text = " ".join(st.text)
    assert HOSTILE["script"] in seq_text and HOSTILE["markup"] in seq_text and "raw\\xff\\xfe" in seq_text


def test_missing_data_leaves_sections_out_with_a_note():
    page = render_pair_html({})
    assert_self_contained(page)
    shown = section_ids(page)
    assert shown and not any(shown.values())  # every section left out, none crashed
    assert page.count("Not shown:") == len(shown)
    assert "no frames were given" in page and "no MTF curves were given" in page
    # only a fidelity: the verdict is shown, the rest is noted
    page = render_pair_html({"fidelity": 0.5, "components": "not a mapping", "metrics": None})
    shown = section_ids(page)
    assert shown["verdict"] and not shown["frames"] and not shown["components"]
    # frames but no report values; odd curve inputs; a bad joint histogram
    p = pair_inputs()
    page = render_pair_html({"weights": {"psnr": 1.0}}, real=p["real"], sim=p["sim"],
                            curves={"real_mtf": "junk", "sim_mtf": None, "real_sitf": p["curves"]["real_sitf"]},
                            joint_histogram=(np.ones((3, 3)), [0, 1], [0, 1]))
    shown = section_ids(page)
    assert shown["frames"] and shown["ssim-map"] and not shown["joint-histogram"]
    assert not shown["mtf"] and not shown["sitf"]
    # frames that cannot be shown: a note, not an exception
    page = render_pair_html({"fidelity": 1.0}, real=p["real"], sim=p["sim"][:, :-1])
    assert "differ in shape" in page
    f = p["real"].astype(np.float32)
    f[3, 4] = np.nan
    page = render_pair_html({"fidelity": 1.0}, real=f, sim=p["sim"].astype(np.float32))
    assert section_ids(page)["frames"] and "the SSIM map cannot be computed" in page and "non-finite" in page
    # sequences: nothing, frames without values, all failed
    assert not any(section_ids(render_sequence_html({})).values())
    page = render_sequence_html({"frames": [{"index": 0}, {"real": "a"}, "not a frame"]})
    assert "no frame was scored" in page
    page = render_sequence_html({"frames": [{"index": i, "error": "unreadable"} for i in range(4)], "failed": [0, 1, 2, 3]})
    assert section_ids(page)["failed"] and "4 frames could not be scored" in page


def test_registration_and_given_maps():
    p = pair_inputs()
    report = dict(p["report"])
    report["registration"] = {"model": "translation", "method": "phase", "matrix": [[1, 0, 2.5], [0, 1, -1.25]],
                              "shift": [1.25, -2.5], "confidence": 0.93, "overlap": 0.97}
    m = irf.maps.ssim_map(p["real"], p["sim"], bits=14)
    page = render_pair_html(report, real=p["real"], sim=p["sim"], ssim=m,
                            joint_histogram=irf.pair_stats(p["real"], p["sim"], bins="levels").joint_histogram())
    shown = section_ids(page)
    assert shown["registration"] and shown["ssim-map"] and shown["joint-histogram"]
    assert "phase" in page and "0.93" in page and "-1.25" in page
    assert f"{m.mean:.6g}" in page


def test_report_objects_are_accepted():
    p = pair_inputs()

    class Obj:
        def to_dict(self):
            return p["report"]

    assert "0.7" in render_pair_html(Obj())
    with pytest.raises(FidelityError, match="to_dict"):
        render_pair_html(42)


def test_missing_matplotlib_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    monkeypatch.setitem(sys.modules, "matplotlib.backends.backend_agg", None)
    with pytest.raises(FidelityError, match=re.escape("pip install 'irfidelity[report]'")):
        render_pair_html({"fidelity": 0.5})
    with pytest.raises(FidelityError, match=re.escape("pip install 'irfidelity[report]'")):
        render_sequence_html({})


def test_docstring_examples():
    import doctest

    import irfidelity.report.pair
    import irfidelity.report.sequence

    for module in (irfidelity.report.pair, irfidelity.report.sequence):
        result = doctest.testmod(module)
        assert result.attempted >= 5 and result.failed == 0, module.__name__


# --------------------------------------------------------------------------- the reports' own methods
def test_reports_render_themselves_and_the_cli_writes_them(tmp_path):
    import json
    import subprocess
    import sys

    from report_inputs import DATA, pair_inputs, sequence_frames

    rep = pair_inputs()["object"]
    page = rep.to_html(tmp_path / "pair.html")
    assert (tmp_path / "pair.html").read_text(encoding="utf-8") == page
    for section in ("Frames", "Difference", "SSIM map", "Joint histogram", "MTF", "SiTF"):
        assert section in page, section
    assert "<div" in rep._repr_html_()[:200] and "<html" not in rep._repr_html_()
    # read back from JSON: the numbers only; the frame sections say they are missing
    back = irf.FidelityReport.from_dict(json.loads(json.dumps(rep.to_dict())))
    assert "no frames" in back.to_html().lower() or "not shown" in back.to_html().lower()
    real, sim = sequence_frames()
    seq = irf.score_sequence(real[:6], sim[:6], bits=14, progress=False)
    seq_page = seq.to_html(tmp_path / "seq.html", worst=3)
    assert "Worst frames" in seq_page and "data:image/png;base64," in seq_page
    stack = DATA / "thermal" / "cptv_v2_all100frames_uint16.tif"
    for args, name in (([str(stack), str(stack), "--pages", "0:5"], "cli_seq.html"),
                       ([str(DATA / "thermal" / "cptv_v2_frame000.png"), str(DATA / "thermal" / "cptv_v2_frame001.png")],
                        "cli_pair.html")):
        p = subprocess.run([sys.executable, "-m", "irfidelity.cli", "score", *args, "--bits", "14", "--no-progress",
                            "--report", str(tmp_path / name)], capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, p.stderr
        assert "Verdict" in (tmp_path / name).read_text(encoding="utf-8")


def test_noise_section_shows_both_cameras_parts_and_spectra():
    rng = np.random.default_rng(5)
    base = rng.integers(1000, 1100, size=(1, 40, 48)) + rng.integers(0, 30, size=(1, 40, 1))  # fixed v pattern
    real = (base + rng.normal(0, 2.0, size=(24, 40, 48))).round().astype(np.uint16)
    sim = (base + rng.normal(0, 5.0, size=(24, 40, 48))).round().astype(np.uint16)
    weights = irf.Weights(mtf=0, sitf=0, psnr=0.3, nmi=0.2, ssim=0.3, noise=0.2)
    real_noise = irf.noise.noise3d(real, bits=16, spectra=True)
    sim_noise = irf.noise.noise3d(sim, bits=16, spectra=True)
    report = irf.evaluate(real[0], sim[0], bits=16, weights=weights, real_noise=real_noise, sim_noise=sim_noise)
    page = report.to_html()
    assert section_ids(page).get("noise") is True
    s = assert_self_contained(page)
    section = page[page.index('<section id="noise"'):]
    section = section[:section.index("</section>")]
    ratio = report.metrics["noise_sigma_tvh_sim"] / report.metrics["noise_sigma_tvh_real"]
    assert 2.0 < ratio < 3.0  # σ 5 against σ 2
    assert f"{ratio:.4g}" in section and "σ_tvh" in section and "noise_rho" in section
    assert section.count("<img") == 1  # the spectra figure (Noise3D objects at hand)
    # read back from JSON: the numbers, no spectra
    again = render_pair_html(report.to_dict())
    assert section_ids(again).get("noise") is True and "Noise spectra" not in again
    # a report without noise inputs: the section is a note naming the CLI flags
    plain = render_pair_html(irf.evaluate(real[0], sim[0], bits=16).to_dict())
    assert section_ids(plain).get("noise") is False and "--real-noise" in plain
    assert s is not None
