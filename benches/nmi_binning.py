"""NMI on the default binning (``hist_range="each"``: each frame's bins over its own robust
range, one width, the edges locked by the offset) against shared edges (``hist_range="data"``,
the paper's): the figures docs/design.md quotes for the choice.

- A pure offset of a real frame (0..20 counts): NMI per offset on both binnings, per camera.
- Nine pixels at 65535 in a noisy copy of the FLIR Duo Pro R frame: NMI against the clean copy's.
- Two independent 14-bit Gaussian frames (120×160, σ 40 counts): the finite-sample floor of NMI.

Frames from ``tests/data`` (tests/data/README.md). Usage: ``python benches/nmi_binning.py``.
"""

from __future__ import annotations

import pathlib

import numpy as np

import irfidelity as irf

DATA = pathlib.Path(__file__).resolve().parent.parent / "tests" / "data"
FRAMES = {"DJI XT-R": DATA / "thermal" / "readthermal_zenmuse_xtr_raw16.png",
          "FLIR Duo Pro R": DATA / "thermal" / "flirpy_frame_000000_raw16.png",
          "FLIR Lepton": DATA / "thermal" / "cptv_v2_frame000.png"}
BINNINGS = ("data", "each")


def offsets() -> None:
    print("NMI of a real frame against itself + an offset (counts 0, 1, 2, 3, 5, 10, 20):")
    for name, path in FRAMES.items():
        real = irf.load_frame(path)
        for binning in BINNINGS:
            values = [irf.stats.nmi(real, real + d, hist_range=binning).value for d in (0, 1, 2, 3, 5, 10, 20)]
            print(f"  {name:<15} {binning:<5} " + " ".join(f"{v:.4f}" for v in values))


def hot_pixels() -> None:
    real = irf.load_frame(FRAMES["FLIR Duo Pro R"])
    rng = np.random.default_rng(1)
    sim = np.clip(np.rint(real + 0.02 * np.ptp(real) * rng.standard_normal(real.shape)), 0, 65535).astype(np.uint16)
    hot = sim.copy()
    hot.flat[rng.choice(hot.size, 9, replace=False)] = 65535
    print("NMI of the Duo Pro R frame against a noisy copy, clean and with 9 pixels at 65535:")
    for binning in BINNINGS:
        clean, spoilt = (irf.stats.nmi(real, s, hist_range=binning).value for s in (sim, hot))
        print(f"  {binning:<5} clean {clean:.4f}, 9 hot pixels {spoilt:.4f}")


def independent() -> None:
    rng = np.random.default_rng(1)
    a, b = (np.rint(2700 + 40 * rng.standard_normal((120, 160))).astype(np.uint16) for _ in range(2))
    print("NMI of two independent 14-bit frames (the finite-sample floor):")
    for binning in BINNINGS:
        print(f"  {binning:<5} {irf.stats.nmi(a, b, hist_range=binning).value:.4f}")


if __name__ == "__main__":
    offsets()
    hot_pixels()
    independent()
