"""Analytic slanted edges for the curve tests (imported by test_curves.py and test_edge.py).

* a Gaussian LSF of width sigma has MTF exp(-2 pi^2 sigma^2 f^2), MTF50 = sqrt(ln2/2)/(pi sigma);
* a slanted edge rendered by supersampling (Gaussian PSF, then each pixel averaged over its
  square footprint) has MTF exp(-2 pi^2 sigma^2 f^2) |sinc(f cos a) sinc(f sin a)| along the
  edge normal.
"""

from __future__ import annotations

import math

import numpy as np

from irfidelity.curves import Curve, mtf50

_erf = np.frompyfunc(math.erf, 1, 1)


def erf(x):
    return _erf(np.asarray(x, dtype=float)).astype(float)


def gauss_mtf(f, sigma):
    return np.exp(-2 * np.pi ** 2 * sigma ** 2 * np.asarray(f) ** 2)


def gauss_mtf50(sigma):
    return math.sqrt(math.log(2) / 2) / (math.pi * sigma)


def render_edge(shape=(64, 64), angle_deg=5.0, sigma=1.0, lo=0.1, hi=0.9, ss=16, horizontal=False,
                invert=False, noise=0.0, rng=None, sag=0.0):
    """Edge through the ROI centre, tilted angle_deg from vertical, bowed by ``sag`` px (a parabola
    in the row, zero mean), blurred by a Gaussian PSF and integrated over each pixel by ss x ss
    supersampling (the pixel-aperture box)."""
    h, w = shape
    th = math.radians(angle_deg)
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    yy = (np.arange(h)[:, None] + sub[None, :]).ravel()
    xx = (np.arange(w)[:, None] + sub[None, :]).ravel()
    yc = (yy - (h - 1) / 2) / ((h - 1) / 2)
    centre = (w - 1) / 2 + 0.3 + math.tan(th) * (yy - (h - 1) / 2) + sag * (yc ** 2 - 1 / 3)
    n = (xx[None, :] - centre[:, None]) * math.cos(th)
    img = (0.5 * (1 + erf(n / (sigma * math.sqrt(2))))).reshape(h, ss, w, ss).mean(axis=(1, 3))
    if invert:
        img = 1 - img
    img = lo + (hi - lo) * img
    if horizontal:
        img = img.T
    if noise:
        img = img + rng.normal(0.0, noise, img.shape)
    return img


def edge_truth(f, sigma, angle_deg):
    th = math.radians(angle_deg)
    return gauss_mtf(f, sigma) * np.abs(np.sinc(f * math.cos(th)) * np.sinc(f * math.sin(th)))


def edge_truth_mtf50(sigma, angle_deg):
    f = np.linspace(0, 1, 200001)
    return mtf50(Curve(f, edge_truth(f, sigma, angle_deg)))
