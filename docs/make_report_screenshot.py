"""Render the demo scene's HTML report and take the screenshot shown in docs/report.md.

The scene is ``irfidelity demo``'s: a real FLIR Lepton frame, a real slanted-edge crop and a
measured SiTF curve (bundled, see ``irfidelity/data/LICENSES.md``) against the demo's simulated
camera. Needs matplotlib and Debian's ``chromium``.

Usage: ``python docs/make_report_screenshot.py [--html docs/report_example.html]``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
from pathlib import Path

from PIL import Image

import irfidelity as irf
from irfidelity.demo import DEMO_MODEL, load_demo_data, model_sitf, simulate_camera
from irfidelity.report import render_pair_html, write_html

DOCS = Path(__file__).resolve().parent


def demo_report_html() -> str:
    d = load_demo_data()
    sim = simulate_camera(d["frame"], **DEMO_MODEL["frame"])
    sim_edge = simulate_camera(d["edge"], **DEMO_MODEL["edge"])
    sim_sitf = model_sitf(d["sitf"], band_um=DEMO_MODEL["sitf_band_um"])
    bits = DEMO_MODEL["frame"]["bits"]
    rep = irf.evaluate(d["frame"], sim, real_mtf=d["edge"], sim_mtf=sim_edge, real_sitf=d["sitf"], sim_sitf=sim_sitf,
                       bits=bits)
    rep.inputs.update(real="cptv_v2_frame000.png (FLIR Lepton, 14-bit)", sim="demo simulated camera")
    report = rep.to_dict()
    report["settings"] = {"bits": bits, "bins": 256, "hist_range": "data"}
    curves = {"real_mtf": irf.mtf_from_edge(d["edge"]), "sim_mtf": irf.mtf_from_edge(sim_edge),
              "real_sitf": d["sitf"], "sim_sitf": sim_sitf,
              "real_sitf_fit": irf.sitf_fit(d["sitf"]), "sim_sitf_fit": irf.sitf_fit(sim_sitf)}
    return render_pair_html(report, real=d["frame"], sim=sim, curves=curves, title="irfidelity demo: fidelity report")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--html", type=Path, help="also keep the rendered HTML here")
    ap.add_argument("--out", type=Path, default=DOCS / "report.png")
    args = ap.parse_args()
    html = demo_report_html()
    if args.html:
        write_html(html, args.html)
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    with tempfile.TemporaryDirectory() as td:
        page, shot = Path(td) / "report.html", Path(td) / "shot.png"
        write_html(html, page)
        subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        "--window-size=1100,2150", f"--screenshot={shot}", f"--user-data-dir={Path(td) / 'profile'}",
                        page.as_uri()], capture_output=True, check=True, timeout=90)
        # a 256-colour palette keeps the file small; the figures use few colours each
        Image.open(shot).convert("RGB").quantize(256, dither=Image.Dither.NONE).save(args.out, optimize=True)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
