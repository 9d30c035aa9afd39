"""What resampling does to the metrics: a noisy simulated frame warped by a subpixel shift
with bilinear or bicubic interpolation, or snapped to the nearest whole pixel.

A registered simulated frame must be resampled onto the real frame's pixels before PSNR,
NMI and SSIM compare them. Interpolation averages neighbouring pixels, so it also averages
the simulator's noise: the warped frame looks less noisy than the simulator made it, and the
metrics score the interpolator as much as the simulator. Snapping to whole pixels keeps the
noise but leaves a misalignment of up to half a pixel. This bench measures both effects:

- the noise of the simulated frame alone (white Gaussian noise warped by the shift): its
  standard deviation after the warp relative to before (1 = untouched);
- PSNR, SSIM and NMI between the real frame and the warped simulated frame, minus the same
  metrics for the ideal simulated frame — rendered directly on the real frame's pixels with
  the same noise, which no resampling touched. That difference is the bias resampling adds.

Scene: the real 640×512 XT-R frame in ``tests/data/thermal`` (σ = 0.7 px smoothing, so that
the subpixel views of it are exact up to a 5th-order spline's error). The real frame and
the simulated one each carry their own noise of ``--noise`` × the scene's standard deviation.

Usage: ``python benches/bench_interpolation.py [--noise 0.03 0.1 0.3] [--out bench-out]``; prints a
Markdown table (also written to ``OUT/interpolation.md``).
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np
import scipy.ndimage as ndi

import irfidelity as irf
from irfidelity import _core

ROOT = pathlib.Path(__file__).resolve().parent.parent
FRAME = ROOT / "tests" / "data" / "thermal" / "readthermal_zenmuse_xtr_raw16.png"
FRACTIONS = (0.02, 0.05, 0.1, 0.25, 0.5)
WHOLE = (3.0, -2.0)  # the whole-pixel part of every shift (dy, dx)
MARGIN = 8


def translation(dy: float, dx: float) -> irf.registration.Registration:
    """A registration holding a known translation (simulated → real: ``real(p + d) = sim(p)``)."""
    return irf.registration.Registration.from_dict({"model": "translation", "method": "phase", "confidence": 1.0,
                                                    "overlap": 1.0, "matrix": [[1, 0, dx], [0, 1, dy]],
                                                    "shape": list(SHAPE)})


def view(scene: np.ndarray, dy: float, dx: float) -> np.ndarray:
    """``out(p) = scene(p + d)``: the scene as a camera displaced by ``d`` sees it."""
    return ndi.shift(scene, (-dy, -dx), order=5, mode="reflect")


def warped(reg: irf.registration.Registration, sim: np.ndarray, how: str) -> tuple[np.ndarray, np.ndarray]:
    """The simulated frame on the real frame's pixels: ``how`` = "bilinear", "bicubic" (never
    snapped, unlike ``Registration.apply``) or "whole pixel" (the shift rounded)."""
    m = reg.matrix
    if how == "whole pixel":
        m[:, 2] = np.round(m[:, 2])
    order = 3 if how == "bicubic" else 1
    return _core.warp_frame(np.ascontiguousarray(sim), tuple(m.ravel()), order, sim.shape)


def metrics(real: np.ndarray, sim: np.ndarray, valid: np.ndarray, peak: float) -> np.ndarray:
    return np.array([irf.stats.psnr(real, sim, peak=peak, mask=valid), irf.stats.ssim(real, sim, mask=valid).value,
                     irf.stats.nmi(real, sim, mask=valid).value])


def measure(noise: float, seed: int = 7) -> list[dict]:
    scene = ndi.gaussian_filter(irf.load_frame(FRAME).astype(np.float64), 0.7)
    global SHAPE
    SHAPE = scene.shape
    rng = np.random.default_rng(seed)
    sigma = noise * scene.std()
    peak = float(np.ptp(scene))
    real = scene + rng.normal(0, sigma, scene.shape)
    # compared away from the border, where the displaced views hold reflected content
    inner = np.zeros(scene.shape, bool)
    inner[MARGIN:-MARGIN, MARGIN:-MARGIN] = True
    rows = []
    for f in FRACTIONS:
        d = (WHOLE[0] + f, WHOLE[1] - f)
        reg = translation(*d)
        # what the simulator renders: the scene from its displaced viewpoint, plus its noise
        own_noise = rng.normal(0, sigma, scene.shape)
        sim = view(scene, *d) + own_noise  # sim(p) = scene(p + d): real(p + d) ≈ sim(p)
        # the same noise, rendered directly on the real frame's pixels: what the metrics should see
        ideal = scene + np.roll(own_noise, (int(WHOLE[0]), int(WHOLE[1])), axis=(0, 1))
        for how in ("bilinear", "bicubic", "whole pixel"):
            out, valid = warped(reg, sim, how)
            noise_out, noise_valid = warped(reg, own_noise, how)
            ratio = float(np.std(noise_out[noise_valid]) / sigma)
            assert valid[inner].all()
            bias = metrics(real, out, inner, peak) - metrics(real, ideal, inner, peak)
            rows.append(dict(noise=noise, fraction=f, how=how, noise_ratio=ratio, d_psnr=bias[0], d_ssim=bias[1], d_nmi=bias[2]))
    return rows


def table(rows: list[dict]) -> str:
    out = ["Shift = whole pixels + (f, −f); noise on each frame in units of the scene's standard deviation; "
           "bias = metric after resampling − metric of the ideal (unresampled) frame.", "",
           "| noise | subpixel part f (px) | resampling | noise std after / before | PSNR bias (dB) | SSIM bias "
           "| NMI bias |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['noise']:g} | {r['fraction']:g} | {r['how']} | {r['noise_ratio']:.3f} | {r['d_psnr']:+.3f} | "
                   f"{r['d_ssim']:+.4f} | {r['d_nmi']:+.4f} |")
    return "\n".join(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.03, 0.1, 0.3],
                    help="noise std / scene std on each frame (default 0.03 0.1 0.3)")
    ap.add_argument("--out", default="bench-out", help="output directory (default bench-out/)")
    args = ap.parse_args()
    md = table([r for noise in args.noise for r in measure(noise)])
    print(md)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "interpolation.md").write_text(md + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
