"""Time of the HTML report: a single pair (640×512 and 160×120 frames, with MTF and SiTF curves)
and a 1000-frame sequence, against the targets of 2 s and 5 s.

The sequence is real: 1000 pairs of 160×120 frames (a 100-frame FLIR Lepton recording, cycled)
written as 16-bit PNGs with the demo's simulated camera, every 97th simulated file truncated
(a failed frame), scored by ``irf.score_sequence``; the bench times the rendering only.

"cold": a fresh Python process importing irfidelity and rendering once (matplotlib's import
included, what a CLI ``--report`` pays); "warm": best of ``--repeat`` renders in one process.
Ranges over ``--rounds`` rounds.

Usage: ``python benches/bench_report.py [--rounds R] [--repeat K] [--keep DIR]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import irfidelity as irf
from irfidelity.demo import DEMO_MODEL, load_demo_data, model_sitf, simulate_camera

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data" / "thermal"
TARGETS = {"pair": 2.0, "sequence": 5.0}


def parse():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--keep", type=Path, help="write the rendered reports to this directory")
    return ap.parse_args()


def curves():
    d = load_demo_data()
    sim_edge = simulate_camera(d["edge"], **DEMO_MODEL["edge"])
    sim_sitf = model_sitf(d["sitf"])
    return {"real_mtf": irf.mtf_from_edge(d["edge"]), "sim_mtf": irf.mtf_from_edge(sim_edge),
            "real_sitf": d["sitf"], "sim_sitf": sim_sitf}


def pair_case(name: str, real: np.ndarray, bits: int) -> dict:
    sim = simulate_camera(real, sigma=1.0, gain=0.98, offset=20.0, noise=4.0, bits=bits, seed=1)
    report = irf.evaluate(real, sim, bits=bits, missing="renormalize").to_dict()
    report["settings"] = {"bits": bits}
    return {"name": name, "report": report, "real": real, "sim": sim}


def sequence_case(tmp: Path) -> dict:
    import cv2

    pages = irf.FrameSequence(DATA / "cptv_v2_all100frames_uint16.tif")
    frames = [pages[i] for i in range(len(pages))]
    (tmp / "real").mkdir()
    (tmp / "sim").mkdir()
    for k in range(1000):
        real = frames[k % len(frames)]
        sim = simulate_camera(real, **{**DEMO_MODEL["frame"], "seed": k})
        cv2.imwrite(str(tmp / "real" / f"f{k:04d}.png"), real)
        path = tmp / "sim" / f"f{k:04d}.png"
        cv2.imwrite(str(path), sim)
        if k % 97 == 96:
            path.write_bytes(path.read_bytes()[:200])
    rep = irf.score_sequence(str(tmp / "real"), str(tmp / "sim"), bits=14, progress=False)
    return {"name": "sequence 1000 × 160×120", "report": rep.to_dict(), "failed": len(rep.failed)}


def render(case: dict, curve_set: dict) -> str:
    from irfidelity.report import render_pair_html, render_sequence_html

    if "real" in case:
        return render_pair_html(case["report"], real=case["real"], sim=case["sim"], curves=curve_set)
    return render_sequence_html(case["report"], curves=curve_set)


COLD = """
import pickle, sys, time
t0 = time.perf_counter()
sys.path.insert(0, {bench!r})
import bench_report as b
case, curve_set = pickle.load(open({path!r}, "rb"))
html = b.render(case, curve_set)
print(time.perf_counter() - t0)
"""


def cold(case: dict, curve_set: dict, tmp: Path) -> float:
    import pickle

    path = tmp / "case.pkl"
    path.write_bytes(pickle.dumps((case, curve_set)))
    code = COLD.format(bench=str(Path(__file__).parent), path=str(path))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main():
    args = parse()
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        curve_set = curves()
        big = irf.load_frame(DATA / "flirpy_frame_000000_raw16.png")
        lepton = irf.load_frame(DATA / "cptv_v2_frame000.png")
        cases = [pair_case("pair 640×512", big, 16), pair_case("pair 160×120", lepton, 14), sequence_case(tmp)]
        print(f"irfidelity {irf.__version__}; sequence: {cases[2]['failed']} failed frames of 1000")
        times: dict[str, dict[str, list[float]]] = {}
        for rnd in range(args.rounds):
            for case in cases:
                t_cold = cold(case, curve_set, tmp)
                warm = []
                for _ in range(args.repeat):
                    t0 = time.perf_counter()
                    html = render(case, curve_set)
                    warm.append(time.perf_counter() - t0)
                entry = times.setdefault(case["name"], {"cold": [], "warm": []})
                entry["cold"].append(t_cold)
                entry["warm"].append(min(warm))
                print(f"round {rnd + 1}: {case['name']:<26} cold {t_cold:6.2f} s   warm {min(warm):6.2f} s   "
                      f"{len(html) / 1024:7.0f} KB")
                if args.keep:
                    args.keep.mkdir(parents=True, exist_ok=True)
                    (args.keep / (case["name"].replace(" ", "_").replace("×", "x") + ".html")).write_text(
                        html, encoding="utf-8")
    print("\n| report | cold (fresh process) | warm | target |\n|---|---|---|---|")
    for name, t in times.items():
        target = TARGETS["sequence" if name.startswith("sequence") else "pair"]
        print(f"| {name} | {min(t['cold']):.2f}–{max(t['cold']):.2f} s | {min(t['warm']):.2f}–{max(t['warm']):.2f} s "
              f"| ≤ {target:g} s |")
    print(json.dumps({k: {kk: [round(x, 3) for x in vv] for kk, vv in v.items()} for k, v in times.items()}))


if __name__ == "__main__":
    main()
