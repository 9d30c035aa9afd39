"""Inputs for the report tests: a real pair with the demo's simulated camera (frames, curves,
report dict), a sequence report dict with failed frames, and hostile strings."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

import irfidelity as irf
from irfidelity.curves import mtf_from_edge, sitf_fit
from irfidelity.demo import DEMO_MODEL, load_demo_data, model_sitf, simulate_camera
from irfidelity.sequence.outcomes import error_entry

DATA = Path(__file__).parent / "data"

HOSTILE = {
    "script": "<script>alert('x')</script>",
    "quotes": "frame \"quoted\" 'single' onload=\"alert(1)\"",
    "bytes": b"raw\xff\xfe<b>bold</b>.png",
    "surrogate": "name\udcff\udcfe.png",  # an undecodable file name as os.fsdecode returns it
    "markup": "</td></table><img src=x onerror=alert(1)>",
}


@lru_cache(maxsize=1)
def pair_inputs() -> dict:
    """The bundled demo scene: real Lepton frame, edge and SiTF curve; the demo's simulator."""
    d = load_demo_data()
    sim = simulate_camera(d["frame"], **DEMO_MODEL["frame"])
    sim_edge = simulate_camera(d["edge"], **DEMO_MODEL["edge"])
    sim_sitf = model_sitf(d["sitf"])
    rep = irf.evaluate(d["frame"], sim, real_mtf=d["edge"], sim_mtf=sim_edge, real_sitf=d["sitf"], sim_sitf=sim_sitf,
                       bits=DEMO_MODEL["frame"]["bits"])
    curves = {"real_mtf": mtf_from_edge(d["edge"]), "sim_mtf": mtf_from_edge(sim_edge),
              "real_sitf": d["sitf"], "sim_sitf": sim_sitf,
              "real_sitf_fit": sitf_fit(d["sitf"]), "sim_sitf_fit": sitf_fit(sim_sitf)}
    return {"report": rep.to_dict(), "real": d["frame"], "sim": sim, "curves": curves, "object": rep}


def sequence_report(n_frames: int = 1000, *, failed_every: int = 97) -> dict:
    """A sequence report dict of ``n_frames`` frames (scored rows of a real 20-frame Lepton
    sequence, repeated with a slow drift), every ``failed_every``-th frame failed."""
    real, sim = sequence_frames()
    d = irf.score_sequence(real, sim, bits=14, progress=False).to_dict()
    rows = []
    for k in range(n_frames):
        row = dict(d["frames"][k % len(real)])
        drift = 0.02 * np.sin(k / 60.0)
        row.update(index=k, real=f"real_{k:05d}.png", sim=f"sim_{k:05d}.png",
                   fidelity=row["fidelity"] + drift,
                   components={c: min(1.0, v + drift) for c, v in row["components"].items()})
        if k % failed_every == failed_every - 1:
            row = error_entry(k, row["real"], row["sim"], f"FrameError: sim_{k:05d}.png: truncated PNG stream").to_dict()
        rows.append(row)
    d["frames"] = rows
    d["failed"] = [r["index"] for r in rows if r.get("error")]
    return d


@lru_cache(maxsize=1)
def sequence_frames() -> tuple[np.ndarray, np.ndarray]:
    pages = irf.FrameSequence(DATA / "thermal" / "cptv_v2_all100frames_uint16.tif")
    real = np.stack([pages[i] for i in range(20)])
    sim = np.stack([simulate_camera(f, **{**DEMO_MODEL["frame"], "seed": i}) for i, f in enumerate(real)])
    return real, sim
