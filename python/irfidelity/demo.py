"""``irfidelity demo``: score a toy simulator against real infrared camera data.

Bundled real data (``irfidelity/data/``, licences in ``data/LICENSES.md``):

* a real thermal frame: frame 0 of a FLIR Lepton recording (160×120, 14-bit counts;
  The Cacophony Project's python-cptv test data, Apache-2.0);
* a real slanted-edge crop (74×74, 8-bit; carlasplund/SFR_calculation_code, CC0-1.0);
* a measured radiometric calibration of a Jade LWIR camera: digital level against
  blackbody temperature (NelisW/pyradi, MIT) — the real SiTF curve.

The "simulator" is :func:`simulate_camera`, a deliberately simple camera model in numpy:
Gaussian optical blur, a gain/offset (non-uniformity calibration) error and additive
Gaussian temporal noise with a fixed seed, rounded and clipped to the bit depth. Its
SiTF is :func:`model_sitf`: in-band (8–12 µm) Planck radiance mapped linearly onto
digital levels through the first and last calibration points.

In temperatures (:func:`run_radiometric_demo`): a FLIR AX8 radiometric JPEG (80×60;
Nervengift/read_thermal.py, CC0-1.0) converted with its own calibration, against a simulator
that renders temperatures in float (blurred, 3 % too much contrast and 0.8 K too warm).
"""

from __future__ import annotations

import contextlib
import math
from importlib import resources
from typing import Any, Callable, Iterator

import numpy as np

from .curves import Curve
from .evaluation import FidelityReport, evaluate
from .fuzzy import Weights

__all__ = ["gaussian_blur", "simulate_camera", "model_sitf", "load_demo_data", "run_demo", "run_radiometric_demo",
           "DEMO_MODEL"]

#: Parameters of the demo's camera model (frame: Lepton counts; edge: 8-bit grey levels).
DEMO_MODEL: dict[str, Any] = {
    "frame": {"sigma": 1.0, "gain": 0.98, "offset": 45.0, "noise": 6.0, "bits": 14, "seed": 0},
    "edge": {"sigma": 0.8, "gain": 1.0, "offset": 0.0, "noise": 1.0, "bits": 8, "seed": 1},
    "sitf_band_um": (8.0, 12.0),
}

FRAME_FILE = "cptv_v2_frame000.png"
EDGE_FILE = "sfr_edge_x2084_y0616_F2_grey.png"
SITF_FILE = "pyradi_jade_lwir_calibration_sitf.csv"
RADIOMETRIC_FILE = "readthermal_flir_ax8.jpg"

#: The radiometric demo's simulator: blur (px), contrast gain about the mean, offset (K).
RADIOMETRIC_MODEL = {"sigma": 0.8, "gain": 1.03, "offset": 0.8}


def gaussian_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur (kernel radius ceil(3σ), reflected borders), float64 result."""
    a = np.asarray(img, dtype=np.float64)
    if sigma <= 0:
        return a.copy()
    r = max(1, int(math.ceil(3 * sigma)))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    p = np.pad(a, r, mode="reflect")
    # rows then columns, as sums of shifted copies (no scipy)
    tmp = sum(k[i] * p[:, i:i + a.shape[1]] for i in range(2 * r + 1))
    return sum(k[i] * tmp[i:i + a.shape[0], :] for i in range(2 * r + 1))


def simulate_camera(frame: np.ndarray, *, sigma: float = 1.0, gain: float = 1.0, offset: float = 0.0,
                    noise: float = 0.0, bits: int | None = None, seed: int = 0) -> np.ndarray:
    """The demo's simulated camera: ``round(gain · blur_σ(frame) + offset + N(0, noise²))``.

    Clipped to ``[0, 2**bits − 1]`` (default: the dtype's range) and returned in the
    input's dtype. ``seed`` fixes the noise (numpy's default generator).
    """
    f = np.asarray(frame)
    y = gain * gaussian_blur(f, sigma) + offset
    if noise > 0:
        y = y + np.random.default_rng(seed).normal(0.0, noise, size=f.shape)
    if f.dtype.kind in "ui":
        top = (1 << bits) - 1 if bits is not None else np.iinfo(f.dtype).max
        return np.clip(np.rint(y), 0, top).astype(f.dtype)
    return y.astype(f.dtype)


def _band_radiance(t_celsius: np.ndarray, lo_um: float, hi_um: float) -> np.ndarray:
    """In-band blackbody radiance (W m⁻² sr⁻¹), Planck's law integrated over [lo, hi] µm."""
    c1, c2 = 1.191042972e-16, 1.4387769e-2  # 2hc² (W m² sr⁻¹), hc/k (m K)
    lam = np.linspace(lo_um, hi_um, 401) * 1e-6
    t = np.asarray(t_celsius, dtype=np.float64)[:, None] + 273.15
    spec = c1 / lam ** 5 / np.expm1(c2 / (lam * t))
    return np.sum((spec[:, 1:] + spec[:, :-1]) * np.diff(lam), axis=1) / 2


def model_sitf(real: Curve, *, band_um=(8.0, 12.0)) -> Curve:
    """The simulator's SiTF: ``DL = a + b·L_band(T)``, a straight line in in-band radiance
    through the real curve's first and last points (a two-point calibration)."""
    L = _band_radiance(real.x, *band_um)
    b = (real.y[-1] - real.y[0]) / (L[-1] - L[0])
    a = real.y[0] - b * L[0]
    return Curve(real.x, a + b * L, name="model SiTF", x_unit=real.x_unit, y_unit=real.y_unit)


@contextlib.contextmanager
def _resource(name: str) -> Iterator:
    with resources.as_file(resources.files("irfidelity") / "data" / name) as p:
        yield p


def load_demo_data() -> dict:
    """The bundled real data: ``frame`` (uint16), ``edge`` (uint8), ``sitf`` (Curve)."""
    from .frames import load_frame

    with _resource(FRAME_FILE) as p:
        frame = load_frame(p)
    with _resource(EDGE_FILE) as p:
        edge = load_frame(p)
    with _resource(SITF_FILE) as p:  # one instrument temperature of two: 17.1 °C
        sitf = Curve.from_csv(p, columns=("blackbody_temp_C", "digital_level"), where={"instrument_temp_C": 17.1},
                              name="Jade LWIR calibration (instrument 17.1 °C)")
    return {"frame": frame, "edge": edge, "sitf": sitf}


def run_demo(*, weights: Weights | None = None, out: Callable[[str], None] | None = print) -> FidelityReport:
    """Score the toy simulator on the bundled data and (if ``out``) print the report."""
    d = load_demo_data()
    fm, em = DEMO_MODEL["frame"], DEMO_MODEL["edge"]
    sim_frame = simulate_camera(d["frame"], **fm)
    sim_edge = simulate_camera(d["edge"], **em)
    sim_sitf = model_sitf(d["sitf"], band_um=DEMO_MODEL["sitf_band_um"])
    # the scene spans ~300 of 16383 counts: PSNR against the real frame's own range (the
    # recommended peak for thermal scenes) rather than a full scale that would pin it near 1
    rep = evaluate(d["frame"], sim_frame, real_mtf=d["edge"], sim_mtf=sim_edge, real_sitf=d["sitf"],
                   sim_sitf=sim_sitf, weights=weights, bits=fm["bits"], peak="range")
    rep.inputs.update(real=f"{FRAME_FILE} (FLIR Lepton, 160x120, 14-bit)", sim="simulate_camera(real frame)",
                      real_mtf=f"slanted edge {EDGE_FILE}", sim_mtf="simulate_camera(real edge)",
                      real_sitf=f"{SITF_FILE} (Jade LWIR, instrument 17.1 C)", sim_sitf="model_sitf (8-12 um Planck)")
    if out is not None:
        out("irfidelity demo: a toy camera simulator scored against real infrared data (bundled, see data/LICENSES.md)")
        out(f"  frame : {rep.inputs['real']}")
        out(f"          simulated = round({fm['gain']}·blur_sigma={fm['sigma']}px(real) + {fm['offset']} "
            f"+ N(0, {fm['noise']}²)), seed {fm['seed']}, clipped to {fm['bits']} bits")
        out(f"  MTF   : real slanted-edge crop vs the same crop blurred (sigma={em['sigma']} px) + N(0, {em['noise']}²)")
        out("  SiTF  : measured Jade LWIR calibration vs in-band (8-12 um) Planck model, two-point calibrated")
        out("  PSNR  : peak 'range', the real frame's max - min (the scene spans a small part of 14 bits)")
        out("")
        out(rep.summary_text())
    return rep


def run_radiometric_demo(*, out: Callable[[str], None] | None = print) -> FidelityReport:
    """Score a toy temperature-rendering simulator against the bundled FLIR AX8 radiometric JPEG
    in °C (``unit="C"``), with the opt-in ``radiometry`` component weighted; print the report."""
    from .frames import load_frame

    m = RADIOMETRIC_MODEL
    with _resource(RADIOMETRIC_FILE) as p:
        path = str(p)
        celsius = load_frame(path, unit="C")
        mean = float(celsius.mean())
        sim = m["gain"] * (gaussian_blur(celsius, m["sigma"]) - mean) + mean + m["offset"]
        rep = evaluate(path, sim, unit="C", weights="psnr=0.25,nmi=0.15,ssim=0.3,radiometry=0.3")
    rep.inputs.update(real=f"{RADIOMETRIC_FILE} (FLIR AX8 radiometric JPEG, 80x60, its own calibration)",
                      sim="float temperatures from a toy simulator")
    if out is not None:
        out("irfidelity demo, in temperatures: a simulator rendering °C against a FLIR AX8 radiometric JPEG")
        out(f"  real      : {rep.inputs['real']}")
        out(f"  simulated : {m['gain']}·(blur_sigma={m['sigma']}px(real °C) − mean) + mean + {m['offset']} K")
        out("")
        out(rep.summary_text())
    return rep
