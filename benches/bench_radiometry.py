"""Counts -> temperature speed of irfidelity vs a numpy float64 implementation, in one run.

    python benches/bench_radiometry.py [--repeat N]

On the DJI Zenmuse XT-R frame of tests/data (640x512 uint16 counts, emissivity 0.70, 20 m of
atmosphere), times ``Radiometry.temperature`` and ``Radiometry.counts`` against numpy doing
the same FLIR model in float64, with every per-frame constant hoisted out of the pixel loop
(what a careful numpy user writes: one multiply-add, a division and a logarithm per pixel, in
whole-array passes). Inputs: the uint16 counts (irfidelity converts each distinct count once;
numpy is given them already as float64, its conversion not timed) and the same counts as
float64 (every pixel converted). Prints the times and the ratio
numpy / irfidelity (> 1: irfidelity is faster). A benchmark, not a test: numbers depend on
the machine (cores, CPU).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import irfidelity as irf
from _common import best

DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "radiometric"
ZERO_C = 273.15


def numpy_model(cal: irf.radiometry.Radiometry):
    """The FLIR model reduced to per-frame constants, then applied with numpy (°C and inverse)."""
    ta = cal.atmospheric_temperature
    h2o = cal.relative_humidity / 100 * np.exp(1.5587 + 0.06939 * ta - 0.00027816 * ta**2 + 0.00000068455 * ta**3)
    root = np.sqrt(cal.object_distance / 2)
    tau = cal.x * np.exp(-root * (cal.alpha1 + cal.beta1 * np.sqrt(h2o))) \
        + (1 - cal.x) * np.exp(-root * (cal.alpha2 + cal.beta2 * np.sqrt(h2o)))
    r, b, f, o = cal.planck_r1 / cal.planck_r2, cal.planck_b, cal.planck_f, cal.planck_o

    def signal(celsius):
        return r / (np.exp(b / (celsius + ZERO_C)) - f) - o

    e, w = cal.emissivity, cal.window_transmission
    gain = e * tau * w * tau
    background = ((1 - e) * tau * w * tau * signal(cal.reflected_temperature)
                  + (1 - tau) * w * tau * signal(ta) + (1 - w) * tau * signal(cal.window_temperature)
                  + (1 - tau) * signal(ta))

    def temperature(raw):
        return b / np.log(r / ((raw - background) / gain + o) + f) - ZERO_C

    def counts(celsius):
        return gain * signal(celsius) + background

    return temperature, counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=60)
    args = parser.parse_args()
    path = DATA / "readthermal_zenmuse_xtr.jpg"
    cal = irf.read_radiometry(path)
    raw = irf.load_frame(path)
    temperature, counts = numpy_model(cal)
    celsius = cal.temperature(raw)
    assert np.allclose(temperature(raw.astype(np.float64)), celsius, rtol=0, atol=1e-9)
    assert np.allclose(counts(celsius), cal.counts(celsius), rtol=0, atol=1e-6)

    raw_float = raw.astype(np.float64)
    rows = [
        ("temperature, uint16 counts", lambda: temperature(raw_float), lambda: cal.temperature(raw)),
        ("temperature, float64 counts", lambda: temperature(raw_float), lambda: cal.temperature(raw_float)),
        ("counts, float64 temperatures", lambda: counts(celsius), lambda: cal.counts(celsius)),
    ]
    print(f"{raw.shape[1]}x{raw.shape[0]} frame ({path.name}), best of {args.repeat}")
    print(f"{'conversion':32s} {'numpy ms':>9s} {'irfidelity ms':>14s} {'ratio':>7s}")
    for name, peer, ours in rows:
        t_numpy, t_ours = best(peer, args.repeat), best(ours, args.repeat)
        print(f"{name:32s} {t_numpy * 1e3:9.2f} {t_ours * 1e3:14.2f} {t_numpy / t_ours:6.1f}x")


if __name__ == "__main__":
    main()
