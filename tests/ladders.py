"""Ladders of controlled degradations of real frames, curves and noise recordings: each rung a
simulator that is worse than the one before in one respect. Shared by tests/test_verdicts.py
(grades never improve down a ladder) and benches/sensitivity.py (the figure in docs).

A rung is ``(step, report)``: the degradation's size and :func:`irfidelity.evaluate`'s report.
Image ladders degrade the real frame at ``t + 1`` and score it against the frame at ``t``, with
the pair (t, t + 1) as the ceiling, so rung 0 is real-vs-real; a frame without a successor is
degraded itself and scored without a ceiling.
"""

from __future__ import annotations

import math
import pathlib
from typing import Callable, Iterator

import numpy as np
from scipy import ndimage

import irfidelity as irf

DATA = pathlib.Path(__file__).resolve().parent / "data" / "thermal"

#: Real scenes: (name, real frame at t, the frame at t + 1 or None, bits).
def scenes() -> list[tuple[str, np.ndarray, np.ndarray | None, int]]:
    import tifffile

    lepton = tifffile.imread(DATA / "cptv_v2_all100frames_uint16.tif")
    mwir = tifffile.imread(DATA / "ptw_mwir_all100frames_uint16.tif")
    return [("Lepton 160×120 (frames 30, 31)", lepton[30], lepton[31], 14),
            ("PTW MWIR (frames 30, 31)", mwir[30], mwir[31], 16),
            ("DJI Zenmuse XT 640×512", irf.load_frame(DATA / "readthermal_zenmuse_xtr_raw16.png"), None, 16)]


def _span(frame: np.ndarray) -> float:
    return float(frame.max()) - float(frame.min())


def _noise(shape: tuple[int, ...], seed: int = 27) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal(shape)


def _dead(frame: np.ndarray, fraction: float) -> np.ndarray:
    out = frame.copy()
    order = np.random.default_rng(5).permutation(frame.size)  # nested sets: each rung adds pixels
    out.flat[order[:int(round(fraction * frame.size))]] = 0
    return out


#: Image degradations: name -> (steps, unit, function(frame as float, step) -> degraded float frame).
IMAGE: dict[str, tuple[tuple[float, ...], str, Callable[[np.ndarray, float], np.ndarray]]] = {
    "blur σ": ((0, 0.5, 1, 2, 3, 4), "px", lambda f, s: ndimage.gaussian_filter(f, s) if s else f),
    "noise σ": ((0, 0.01, 0.02, 0.04, 0.08, 0.16), "× range", lambda f, s: f + s * _span(f) * _noise(f.shape)),
    "gain": ((1, 1.02, 1.05, 1.1, 1.2, 1.5), "×", lambda f, s: f.mean() + s * (f - f.mean())),
    "offset": ((0, 0.01, 0.02, 0.05, 0.1, 0.2), "× range", lambda f, s: f + s * _span(f)),
    "shift": ((0, 0.25, 0.5, 1, 2, 4), "px", lambda f, s: ndimage.shift(f, (s, s), order=3, mode="nearest")),
    "dead pixels": ((0, 1e-4, 1e-3, 5e-3, 0.02), "fraction", _dead),
}

#: Camera ladders: name -> (steps, unit).
CAMERA: dict[str, tuple[tuple[float, ...], str]] = {
    "MTF50 scale": ((1, 0.97, 0.95, 0.9, 0.8, 0.69, 0.5), "×"),
    "SiTF slope": ((1, 0.97, 0.95, 0.9, 0.8, 0.6), "×"),
    "NETD factor": ((1, 1.05, 1.1, 1.25, 2, 3), "×"),
}


def _as_frame(values: np.ndarray, bits: int) -> np.ndarray:
    return np.clip(np.rint(values), 0, 2 ** bits - 1).astype(np.uint16)


def image_ladder(name: str, real: np.ndarray, successor: np.ndarray | None, bits: int) -> Iterator[tuple]:
    steps, _, degrade = IMAGE[name]
    base = (real if successor is None else successor).astype(np.float64)
    for step in steps:
        sim = _as_frame(degrade(base, step), bits)
        yield step, irf.evaluate(real, sim, bits=bits, peak="range", real_ref=successor)


def _mtf(mtf50: float) -> tuple[np.ndarray, np.ndarray]:
    x = np.linspace(0, 0.5, 101)
    return x, np.exp(-math.log(2) * (x / mtf50) ** 2)


def camera_ladder(name: str) -> Iterator[tuple]:
    steps, _ = CAMERA[name]
    t = np.linspace(-10, 10, 41)
    real_noise = 1000 + 2 * _noise((16, 48, 48), 1)
    for step in steps:
        if name == "MTF50 scale":
            yield step, irf.evaluate(real_mtf=_mtf(0.25), sim_mtf=_mtf(0.25 * step), weights="mtf=1")
        elif name == "SiTF slope":
            yield step, irf.evaluate(real_sitf=(t, 1000 + 50 * t), sim_sitf=(t, 1000 + 50 * step * t),
                                     weights="sitf=1")
        else:
            sim_noise = 1000 + 2 * step * _noise((16, 48, 48), 2)
            yield step, irf.evaluate(real_noise=real_noise, sim_noise=sim_noise, weights="noise=1")
