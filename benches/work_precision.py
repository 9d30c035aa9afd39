#!/usr/bin/env python
"""Work-precision benchmark (issue 7): error against an exact reference, and run time,
for every metric of the framework on a suite of stiff and extreme frame pairs.

    python benches/work_precision.py [--out DIR] [--quick] [--threads N]

Implementations
---------------
irfidelity: the default mode (``irf.stats.mse / psnr / ssim / nmi``, which for integer frames
is the exact integer path, for float frames the float64 centred path), NMI with the
default 256 bins and with ``bins="levels"``, and the masked path (an all-true ``mask``:
chunks centred on their own means and merged with Chan's update); and the peers: scikit-image
(``mean_squared_error``, ``peak_signal_noise_ratio``, ``normalized_mutual_information``),
numpy float32 / float64 one-pass (E[x²] − E[x]²) and two-pass formulas, OpenCV
(``cv2.norm``, ``cv2.PSNR``, ``cv2.meanStdDev``), scikit-learn
(``normalized_mutual_info_score``).

References
----------
Every float value is a dyadic rational: both frames are written as Python integers times
one common power of two, so all sums are exact Python integers; the SSIM factors'
square roots and the entropies' logarithms are taken with mpmath at 60 digits. NMI is
compared against the exact NMI *of the binning the implementation uses* (the library's
documented 256-bin edges, or one bin per grey level), so every implementation is judged
on the same question: how well it computes its own definition.

Registration
------------
The registration of a simulated frame onto the real one has no exact reference; its
reference is a known transform: real frames from ``tests/data/thermal`` seen through known
subpixel shifts, rotations and scales, blurred, gain/offset-changed and noised
(``registration_cases.py``, shared with ``bench_register.py``). Error: the worst displacement
of a frame corner between the found and the true transform, in pixels; peers: scikit-image
``phase_cross_correlation``, OpenCV ``phaseCorrelate`` and ``findTransformECC``.

Output: ``DIR/work_precision.md`` (table) and ``DIR/work_precision.png`` (error vs time,
log-log, one panel per metric, and one per registration model). ``--quick`` uses 128×128 frames and fewer repeats.
``--threads 1`` limits irfidelity's Rust pool (and OpenCV) to one thread: core for core, since
the peers compute on one core while irfidelity shares a pass between the calling thread and
idle pool threads.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
import warnings
from collections import Counter, defaultdict
from pathlib import Path

import mpmath
import numpy as np

import irfidelity as irf

mpmath.mp.dps = 60
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
DATA = HERE.parent / "tests" / "data" / "thermal"

METRICS = ("mse", "psnr", "ssim_l", "ssim_c", "ssim_s", "h_real", "h_sim", "h_joint", "nmi")
TINY = 1e-18  # errors of exactly 0 are drawn here on the log axis


# =========================================================================== cases
def _png(path: Path) -> np.ndarray:
    import png

    w, h, rows, info = png.Reader(filename=str(path)).read()
    a = np.vstack([np.asarray(r, dtype=np.uint16) for r in rows])
    return a.reshape(h, w, -1)[..., 0] if a.shape[1] != w else a


def make_cases(side: int) -> list[dict]:
    rng = np.random.default_rng(20120547)
    sh = (side, side)
    cases = []

    def add(name, r, s, *, peak, note):
        cases.append(dict(name=name, r=np.ascontiguousarray(r), s=np.ascontiguousarray(s), peak=float(peak), note=note,
                          all_true=np.ones(np.shape(r), dtype=bool)))

    # real 14-bit thermal frames (consecutive frames of a Cacophony Project CPTV recording)
    r, s = _png(DATA / "cptv_v2_frame000.png"), _png(DATA / "cptv_v2_frame001.png")
    add("thermal14", r, s, peak=2**14 - 1, note="real 14-bit frames, consecutive (120x160)")
    # 16-bit at the top of the range, 1 LSB apart
    r = (65535 - rng.integers(0, 16, sh)).astype(np.uint16)
    s = r - ((rng.random(sh) < 0.3) & (r > 0)).astype(np.uint16)
    add("u16_65535_1lsb", r, s, peak=65535, note="uint16 in 65520..65535, sim 1 LSB lower on 30 %")
    # saturated halves
    r = np.zeros(sh, np.uint16)
    r[:, side // 2 :] = 65535
    add("u16_sat_halves", r, 65535 - r, peak=65535, note="0 | 65535 halves vs the inverse")
    # full-range random
    r = rng.integers(0, 65536, sh).astype(np.uint16)
    s = np.clip(r.astype(np.int64) + rng.integers(-3000, 3001, sh), 0, 65535).astype(np.uint16)
    add("u16_random", r, s, peak=65535, note="uniform uint16 + noise")
    # anti-correlated
    s = np.clip(65535 - r.astype(np.int64) + rng.integers(-50, 51, sh), 0, 65535).astype(np.uint16)
    add("u16_anticorr", r, s, peak=65535, note="sim ≈ 65535 − real (s ≈ −1)")
    # one constant frame
    r = np.full(sh, 30000, np.uint16)
    s = (30000 + np.arange(side * side).reshape(sh) % 7).astype(np.uint16)
    add("u16_const_vs_ramp", r, s, peak=65535, note="real constant: c = s = 0 and NMI = 0 by docs/design.md §4")
    # dim vs bright: very different means (luminance ≈ 2e-9)
    r = rng.integers(0, 4, sh).astype(np.uint32)
    s = (r.astype(np.uint64) * 10**9 + rng.integers(0, 1000, sh)).astype(np.uint32)
    add("u32_dim_vs_bright", r, s, peak=2**32 - 1, note="means 1.5 vs 1.5e9 (l ≈ 2e-9)")
    # float32 at a 1e6 offset, σ ≈ 1e-2 (ulp there is 0.0625)
    kr = (rng.random(sh) < 0.0263).astype(np.int64)
    ks = np.where(rng.random(sh) < 0.8, kr, (rng.random(sh) < 0.0263).astype(np.int64))
    add(
        "f32_offset_1e6",
        (np.float32(1e6) + kr * 0.0625).astype(np.float32),
        (np.float32(1e6) + ks * 0.0625).astype(np.float32),
        peak=2e6,
        note="float32 1e6 + {0, 1 ulp}, σ ≈ 1e-2",
    )
    # float32 near ±3e38: squares overflow float32
    r = rng.uniform(-3e38, 3e38, sh).astype(np.float32)
    s = np.clip(r.astype(np.float64) * 0.9 + rng.normal(0, 3e37, sh), -3.4e38, 3.4e38).astype(np.float32)
    add("f32_near_max", r, s, peak=float(np.finfo(np.float32).max), note="float32 in ±3e38")
    # subnormal float32
    t = float(np.finfo(np.float32).smallest_subnormal)
    k = rng.integers(0, 1000, sh)
    r = (k * t).astype(np.float32)
    s = (np.clip(k + rng.integers(-20, 21, sh), 0, 2000) * t).astype(np.float32)
    add("f32_subnormal", r, s, peak=2000 * t, note="float32 subnormals (k·1.4e-45)")
    # negative float64
    r = -np.abs(rng.normal(50, 20, sh))
    s = 0.9 * r - 3 + rng.normal(0, 2, sh)
    add("f64_negative", r, s, peak=200.0, note="float64, all negative")
    return cases


# =========================================================================== exact reference
def _as_scaled_ints(r: np.ndarray, s: np.ndarray):
    """Both frames as Python ints K with x = K·2**E (one common E). Exact."""
    if r.dtype.kind in "ui":
        return r.astype(object).ravel(), s.astype(object).ravel(), 0
    a = np.concatenate([r.ravel(), s.ravel()]).astype(np.float64)
    m, e = np.frexp(a)  # a = m·2**e, |m| in [0.5, 1)
    k = (m * 2.0**53).astype(np.int64)  # exact: m has at most 53 significant bits
    e = e.astype(np.int64) - 53
    nz = k != 0
    emin = int(e[nz].min()) if nz.any() else 0
    ints = np.array([int(ki) << int(ei - emin) if ki else 0 for ki, ei in zip(k.tolist(), e.tolist())], dtype=object)
    n = r.size
    return ints[:n], ints[n:], emin


def _entropy(counts) -> mpmath.mpf:
    """H = log2 N − Σ c·log2 c / N, grouping equal counts (exact to 60 digits)."""
    cc = Counter(int(c) for c in counts if c)
    n = sum(c * m for c, m in cc.items())
    return mpmath.log(n, 2) - sum(m * c * mpmath.log(c, 2) for c, m in cc.items()) / n


def bin_index(r: np.ndarray, s: np.ndarray, bins):
    """The library's documented binning (docs/design.md §3): integer frames, width = ceil(levels/bins)
    whole grey levels from the data min; float frames, (hi − lo)/bins wide from the data min."""
    if bins == "levels":
        return r.astype(np.int64), s.astype(np.int64)
    if r.dtype.kind in "ui":
        lo = int(min(r.min(), s.min()))
        hi = int(max(r.max(), s.max()))
        width = -(-(hi - lo + 1) // bins)
        f = lambda a: (a.astype(np.int64) - lo) // width  # noqa: E731
        return f(r), f(s)
    a, b = r.astype(np.float64), s.astype(np.float64)
    lo, hi = float(min(a.min(), b.min())), float(max(a.max(), b.max()))
    w = (hi - lo) / bins
    if w == 0:
        return np.zeros(a.shape, np.int64), np.zeros(b.shape, np.int64)
    f = lambda x: np.clip(np.floor((x - lo) * (1.0 / w)), 0, bins - 1).astype(np.int64)  # noqa: E731
    return f(a), f(b)


def exact_reference(r, s, peak, *, bins_list=(256, "levels")) -> dict:
    kr, ks, e = _as_scaled_ints(r, s)
    n = kr.size
    sr, ss = int(kr.sum()), int(ks.sum())
    srr, sss, srs = int((kr * kr).sum()), int((ks * ks).sum()), int((kr * ks).sum())
    d = kr - ks
    sse = int((d * d).sum())
    scale2 = mpmath.mpf(2) ** (2 * e)
    ref = {}
    mse = mpmath.mpf(sse) * scale2 / n
    ref["mse"] = mse
    ref["psnr"] = mpmath.inf if sse == 0 else 20 * mpmath.log10(peak) - 10 * mpmath.log10(mse)
    den = sr * sr + ss * ss
    ref["ssim_l"] = mpmath.mpf(1) if den == 0 else mpmath.mpf(2 * sr * ss) / den
    drr, dss, drs = n * srr - sr * sr, n * sss - ss * ss, n * srs - sr * ss
    if drr == 0 and dss == 0:
        ref["ssim_c"], ref["ssim_s"] = mpmath.mpf(1), mpmath.mpf(1)
    elif drr == 0 or dss == 0:
        ref["ssim_c"], ref["ssim_s"] = mpmath.mpf(0), mpmath.mpf(0)
    else:
        root = mpmath.sqrt(mpmath.mpf(drr) * dss)
        ref["ssim_c"] = 2 * root / (drr + dss)
        ref["ssim_s"] = drs / root
    for bins in bins_list:
        if bins == "levels" and r.dtype.kind not in "ui":
            continue
        br, bs = bin_index(r, s, bins)
        # relabel the occupied bins 0..m-1 (levels of uint32 frames span up to 2^32)
        _, inv = np.unique(np.concatenate([br.ravel(), bs.ravel()]), return_inverse=True)
        ir, is_ = inv[: br.size].astype(np.int64), inv[br.size :].astype(np.int64)
        m = int(inv.max()) + 1
        hr = _entropy(np.bincount(ir))
        hs = _entropy(np.bincount(is_))
        hj = _entropy(np.unique(ir * m + is_, return_counts=True)[1])
        tag = f"@{bins}"
        ref["h_real" + tag], ref["h_sim" + tag], ref["h_joint" + tag] = hr, hs, hj
        ref["nmi" + tag] = mpmath.mpf(1) if hr + hs == 0 else max(hr + hs - hj, 0) * 2 / (hr + hs)
    return ref


# =========================================================================== implementations
def _ent64(counts: np.ndarray) -> float:
    c = counts[counts > 0].astype(np.float64)
    n = c.sum()
    return float(math.log2(n) - np.sum(c * np.log2(c)) / n)


def _nmi_from_h(hr, hs, hj):
    return 1.0 if hr + hs == 0 else max(hr + hs - hj, 0.0) * 2 / (hr + hs)


def impl_irf_mse(c):
    return {"mse": irf.stats.mse(c["r"], c["s"])}


def impl_irf_psnr(c):
    return {"psnr": irf.stats.psnr(c["r"], c["s"], peak=c["peak"])}


def impl_irf_ssim(c):
    v = irf.stats.ssim(c["r"], c["s"])
    return {"ssim_l": v.luminance, "ssim_c": v.contrast, "ssim_s": v.structure}


def impl_irf_masked(c):
    """The masked path (an all-true mask): per-chunk means merged with Chan's update, not the
    default's common centre; what `mask=` and `nonfinite="mask"` use."""
    st = irf.pair_stats(c["r"], c["s"], peak=c["peak"], need=("psnr", "ssim"), mask=c["all_true"])
    v = st.ssim()
    return {"mse": st.mse(), "psnr": st.psnr(), "ssim_l": v.luminance, "ssim_c": v.contrast, "ssim_s": v.structure}


impl_irf_masked.metrics = ("mse", "psnr", "ssim_l", "ssim_c", "ssim_s")


def _irf_nmi(bins):
    def f(c):
        v = irf.stats.nmi(c["r"], c["s"], bins=bins)
        return {"h_real": v.h_real, "h_sim": v.h_sim, "h_joint": v.h_joint, "nmi": v.value}

    return f


def _np_mse(dt):
    def f(c):
        d = c["r"].astype(dt) - c["s"].astype(dt)
        return {"mse": float(np.mean(d * d, dtype=dt))}

    return f


def _np_psnr(dt):
    def f(c):
        d = c["r"].astype(dt) - c["s"].astype(dt)
        m = np.mean(d * d, dtype=dt)
        pk = dt(c["peak"])
        return {"psnr": float(10 * np.log10(pk * pk / m)) if m != 0 else math.inf}

    return f


def _np_ssim(dt, two_pass):
    def f(c):
        r, s = c["r"].astype(dt).ravel(), c["s"].astype(dt).ravel()
        mr, ms = np.mean(r, dtype=dt), np.mean(s, dtype=dt)
        if two_pass:
            dr, ds = r - mr, s - ms
            vr, vs, cv = np.mean(dr * dr, dtype=dt), np.mean(ds * ds, dtype=dt), np.mean(dr * ds, dtype=dt)
        else:
            vr = np.mean(r * r, dtype=dt) - mr * mr
            vs = np.mean(s * s, dtype=dt) - ms * ms
            cv = np.mean(r * s, dtype=dt) - mr * ms
        sr, ss = np.sqrt(vr), np.sqrt(vs)
        return {
            "ssim_l": float(2 * mr * ms / (mr * mr + ms * ms)),
            "ssim_c": float(2 * sr * ss / (vr + vs)),
            "ssim_s": float(cv / (sr * ss)),
        }

    return f


def _edges(r, s, bins):
    """The library's documented bin edges (integer frames: whole grey levels, width
    ceil(span/bins), starting at the data min), as float edges for numpy/scikit-image."""
    if r.dtype.kind in "ui":
        lo = int(min(r.min(), s.min()))
        hi = int(max(r.max(), s.max()))
        width = -(-(hi - lo + 1) // bins)
        nb = -(-(hi - lo + 1) // width)
        return lo - 0.5 + width * np.arange(nb + 1, dtype=np.float64)
    lo = float(min(r.min(), s.min()))
    hi = float(max(r.max(), s.max()))
    return np.linspace(lo, hi, bins + 1) if hi > lo else np.array([lo - 0.5, lo + 0.5])


def _np_hist2d_nmi(bins):
    def f(c):
        r, s = c["r"], c["s"]
        edges = _edges(r, s, bins)
        h, _, _ = np.histogram2d(r.ravel().astype(np.float64), s.ravel().astype(np.float64), bins=[edges, edges])
        hr, hs, hj = _ent64(h.sum(1)), _ent64(h.sum(0)), _ent64(h.ravel())
        return {"h_real": hr, "h_sim": hs, "h_joint": hj, "nmi": _nmi_from_h(hr, hs, hj)}

    return f


def _sk_nmi(bins):
    from skimage.metrics import normalized_mutual_information

    def f(c):
        r, s = c["r"], c["s"]
        edges = _edges(r, s, bins)
        y = normalized_mutual_information(r, s, bins=[edges, edges])  # (H(A)+H(B))/H(A,B)
        # paper (eq. 10): NMI = 2·MI/(H(A)+H(B)) = 2·(1 − H(A,B)/(H(A)+H(B))) = 2 − 2/Y
        return {"nmi": 2.0 - 2.0 / y}

    return f


def _skl_nmi(bins):
    from sklearn.metrics import normalized_mutual_info_score

    def f(c):
        br, bs = bin_index(c["r"], c["s"], bins)
        return {"nmi": float(normalized_mutual_info_score(br.ravel(), bs.ravel(), average_method="arithmetic"))}

    return f


def sk_mse(c):
    from skimage.metrics import mean_squared_error

    return {"mse": float(mean_squared_error(c["r"], c["s"]))}


def sk_psnr(c):
    from skimage.metrics import peak_signal_noise_ratio

    return {"psnr": float(peak_signal_noise_ratio(c["r"], c["s"], data_range=c["peak"]))}


def _cv_ok(c):
    return c["r"].dtype in (np.uint8, np.uint16, np.int16, np.float32, np.float64)


def cv_mse(c):
    import cv2

    return {"mse": cv2.norm(c["r"], c["s"], cv2.NORM_L2SQR) / c["r"].size}


def cv_psnr(c):
    import cv2

    return {"psnr": float(cv2.PSNR(c["r"], c["s"], c["peak"]))}


def cv_ssim(c):
    import cv2

    (mr,), (sr,) = (v.ravel() for v in cv2.meanStdDev(c["r"]))
    (ms,), (ss,) = (v.ravel() for v in cv2.meanStdDev(c["s"]))
    return {"ssim_l": 2 * mr * ms / (mr * mr + ms * ms), "ssim_c": 2 * sr * ss / (sr * sr + ss * ss)}


# name, function, reference tag for NMI/entropies, predicate(case) -> applicable, is_irfidelity_default
IMPLS = [
    ("irfidelity", impl_irf_mse, None, None, True),
    ("irfidelity", impl_irf_psnr, None, None, True),
    ("irfidelity", impl_irf_ssim, None, None, True),
    ("irfidelity", _irf_nmi(256), 256, None, True),
    ("irfidelity levels", _irf_nmi("levels"), "levels", lambda c: c["r"].dtype.kind in "ui", False),
    ("irfidelity masked", impl_irf_masked, None, None, False),
    ("skimage", sk_mse, None, None, False),
    ("skimage", sk_psnr, None, None, False),
    ("skimage", _sk_nmi(256), 256, None, False),
    ("sklearn", _skl_nmi(256), 256, None, False),
    ("sklearn levels", _skl_nmi("levels"), "levels", lambda c: c["r"].dtype.kind in "ui", False),
    ("numpy f64 hist2d", _np_hist2d_nmi(256), 256, None, False),
    ("numpy f32", _np_mse(np.float32), None, None, False),
    ("numpy f64", _np_mse(np.float64), None, None, False),
    ("numpy f32", _np_psnr(np.float32), None, None, False),
    ("numpy f64", _np_psnr(np.float64), None, None, False),
    ("numpy f32 1-pass", _np_ssim(np.float32, False), None, None, False),
    ("numpy f64 1-pass", _np_ssim(np.float64, False), None, None, False),
    ("numpy f32 2-pass", _np_ssim(np.float32, True), None, None, False),
    ("numpy f64 2-pass", _np_ssim(np.float64, True), None, None, False),
    ("opencv", cv_mse, None, _cv_ok, False),
    ("opencv", cv_psnr, None, _cv_ok, False),
    ("opencv meanStdDev", cv_ssim, None, _cv_ok, False),
]


#: Fast calls are repeated until this much time was spent (at most MAX_REPEATS calls): the
#: best of a handful of 30-µs calls is mostly timer and scheduler noise, for every side.
TIME_BUDGET = 0.05
MAX_REPEATS = 200


def timed(fn, case, repeats):
    """(result, best wall time) over at least `repeats` calls, more for fast calls (TIME_BUDGET)."""
    best = math.inf
    out = None
    spent, k = 0.0, 0
    while k < repeats or (spent < TIME_BUDGET and k < MAX_REPEATS):
        t0 = time.perf_counter()
        out = fn(case)
        dt = time.perf_counter() - t0
        best, spent, k = min(best, dt), spent + dt, k + 1
    return out, best


def error(value, ref):
    """(abs, rel) error; a NaN or an infinity where the reference is finite is an infinite error."""
    if value is None:
        return math.inf, math.inf
    v = float(value)
    if math.isinf(float(ref)):
        return (0.0, 0.0) if v == float(ref) else (math.inf, math.inf)
    if not math.isfinite(v):
        return math.inf, math.inf
    a = abs(mpmath.mpf(v) - ref)
    r = a / abs(ref) if ref != 0 else a
    return float(a), float(r)


# =========================================================================== run
def run(out: Path, quick: bool) -> list[dict]:
    side = 128 if quick else 512
    repeats = 3 if quick else 7
    cases = make_cases(side)
    rows = []
    warnings.simplefilter("ignore")
    np.seterr(all="ignore")
    for c in cases:
        t0 = time.perf_counter()
        ref = exact_reference(c["r"], c["s"], c["peak"])
        t_ref = time.perf_counter() - t0
        for name, fn, tag, pred, default in IMPLS:
            if pred is not None and not pred(c):
                continue
            try:
                got, t = timed(fn, c, repeats)
                err_msg = None
            except Exception as exc:  # a peer (or irfidelity) refusing is recorded, not fatal
                got, t, err_msg = {}, math.nan, f"{type(exc).__name__}: {str(exc)[:60]}"
            keys = got.keys() if got else _metrics_of(fn, c)
            for k in keys:
                rk = k + (f"@{tag}" if k in ("h_real", "h_sim", "h_joint", "nmi") else "")
                if rk not in ref:
                    continue
                v = got.get(k) if got else None
                a, r = error(v, ref[rk]) if err_msg is None else (math.inf, math.inf)
                rows.append(
                    dict(
                        case=c["name"],
                        metric=k,
                        impl=name + ("" if tag is None or "levels" in name else f" ({tag} bins)"),
                        value=v,
                        ref=float(ref[rk]),
                        abs=a,
                        rel=r,
                        time=t,
                        default=default,
                        peak=c["peak"],
                        note=err_msg,
                    )
                )
        print(f"  {c['name']:<20} {c['r'].dtype} {c['r'].shape}  reference {t_ref:.2f}s", file=sys.stderr)
    return rows


def _metrics_of(fn, c):
    if hasattr(fn, "metrics"):
        return fn.metrics
    for name in ("ssim", "nmi", "psnr", "mse"):
        if name in getattr(fn, "__name__", "") or name in getattr(fn, "__qualname__", ""):
            return {"ssim": ("ssim_l", "ssim_c", "ssim_s"), "nmi": ("nmi",), "psnr": ("psnr",), "mse": ("mse",)}[name]
    return ()


def _fmt(x):
    if x is None:
        return "—"
    if isinstance(x, float) and (math.isinf(x) or math.isnan(x)):
        return "inf" if x == math.inf else "NaN" if math.isnan(x) else "-inf"
    if x == 0:
        return "0"
    return f"{x:.2e}"


def verdict(rows):
    """For each case×metric: is irfidelity's default at least as accurate as every peer
    (rel error within 4.5e-16 = 2 ulp counts as a tie), and faster?"""
    by = defaultdict(list)
    for r in rows:
        by[(r["case"], r["metric"])].append(r)
    lines = []
    acc_ok = acc_all = speed_ok = speed_all = 0
    losses = []
    slower = []
    ratios = defaultdict(list)
    for (case, metric), rs in by.items():
        mine = [r for r in rs if r["default"]]
        if not mine:
            continue
        m = mine[0]
        for p in rs:
            if p["impl"].startswith("irfidelity"):
                continue
            acc_all += 1
            if metric == "psnr":  # a log quantity: judge the error in dB, tie within 2 ulp of 20·log10(peak)
                mine_e, peer_e, tie = m["abs"], p["abs"], 4.5e-16 * max(1.0, abs(20 * math.log10(m["peak"])))
            else:
                mine_e, peer_e, tie = m["rel"], p["rel"], 4.5e-16
            if mine_e <= max(peer_e, tie):
                acc_ok += 1
            else:
                what = "abs (dB)" if metric == "psnr" else "rel"
                losses.append(f"{case}/{metric}: {p['impl']} {what} {_fmt(peer_e)} vs irfidelity {_fmt(mine_e)}")
            if math.isfinite(p["time"]):
                speed_all += 1
                ratios[p["impl"]].append(m["time"] / p["time"])
                if m["time"] <= p["time"]:
                    speed_ok += 1
                else:
                    slower.append(f"{case}/{metric}: {p['impl']} {p['time'] * 1e3:.3f} ms vs irfidelity {m['time'] * 1e3:.3f} ms")
    lines.append(f"- accuracy: irfidelity default at or beyond the peer in **{acc_ok}/{acc_all}** (case, metric, peer) comparisons")
    lines.append(f"- speed: irfidelity default faster in **{speed_ok}/{speed_all}** comparisons")
    lines.append("- time of irfidelity's default / time of the peer (median over cases; < 1 = irfidelity faster):")
    for name, rs in sorted(ratios.items()):
        lines.append(f"  - {name}: {float(np.median(rs)):.2f} (faster in {sum(x <= 1 for x in rs)}/{len(rs)})")
    if losses:
        lines.append("- accuracy losses:")
        lines += [f"  - {x}" for x in losses]
    if slower:
        lines.append("- where a peer was faster:")
        lines += [f"  - {x}" for x in slower]
    return lines


#: Metric groups of the summary table.
GROUPS = (
    ("MSE", ("mse",)),
    ("PSNR (dB)", ("psnr",)),
    ("SSIM l, c, s", ("ssim_l", "ssim_c", "ssim_s")),
    ("entropies, NMI", ("h_real", "h_sim", "h_joint", "nmi")),
)


def summary_table(rows) -> list[str]:
    """One line per metric group and peer: worst errors of the peer and of irfidelity's
    default over the same (case, metric) pairs, the median time ratio and the wins."""
    mine = {(r["case"], r["metric"]): r for r in rows if r["default"]}
    out = [
        "| metric | peer | peer worst error | irfidelity worst error | peer time / irfidelity time (median) "
        "| irfidelity faster |",
        "|---|---|---|---|---|---|",
    ]
    for label, metrics in GROUPS:
        peers = sorted({r["impl"] for r in rows if r["metric"] in metrics and not r["impl"].startswith("irfidelity")})
        for peer in peers:
            pairs = [(r, mine[(r["case"], r["metric"])]) for r in rows
                     if r["impl"] == peer and r["metric"] in metrics and (r["case"], r["metric"]) in mine]
            if not pairs:
                continue
            key = "abs" if metrics == ("psnr",) else "rel"
            worst_p = max(p[key] for p, _ in pairs)
            worst_m = max(m[key] for _, m in pairs)
            timed_pairs = [(p, m) for p, m in pairs if math.isfinite(p["time"])]
            ratio = float(np.median([p["time"] / m["time"] for p, m in timed_pairs])) if timed_pairs else math.nan
            wins = sum(m["time"] <= p["time"] for p, m in timed_pairs)
            shown = "NaN/inf on some case" if not math.isfinite(worst_p) else _fmt(worst_p)
            out.append(f"| {label} | {peer} | {shown} | {_fmt(worst_m)} | {ratio:.2f} | {wins}/{len(timed_pairs)} |")
    return out


REGISTRATION_MODELS = ("translation", "rigid", "similarity")


def registration_rows(quick: bool) -> list[dict]:
    """Registration error (px) and time per frame size, model and method (``registration_cases``)."""
    from registration_cases import run as run_registration

    return run_registration(2 if quick else 6, 1 if quick else 3, time.perf_counter, verbose=False)


def registration_table(rows) -> list[str]:
    out = ["| frames | model | method | worst corner error (px) | median (px) | time / call (ms) |",
           "|---|---|---|---|---|---|"]
    for r in rows:
        worst = "failed" if not math.isfinite(r["worst"]) else f"{r['worst']:.3f}"
        out.append(f"| {r['frame']} | {r['model']} | {r['method']} | {worst} | {r['median']:.3f} | {r['time_ms']:.1f} |")
    return out


def write_md(rows, out: Path, quick: bool, cases_note: list[str], reg_rows=()):
    lines = [
        "# Work-precision: error against an exact reference, and run time",
        "",
        f"`python benches/work_precision.py{' --quick' if quick else ''}` — frames {'128×128' if quick else '512×512'}"
        f" (thermal14: 120×160); time = best of ≥ {3 if quick else 7} calls (fast calls: until"
        f" {TIME_BUDGET * 1e3:.0f} ms spent, ≤ {MAX_REPEATS}), one call computing one metric.",
        f"Machine: {os.cpu_count()} CPUs; numpy {np.__version__}; irfidelity {irf.__version__}; "
        f"irfidelity threads: {os.environ.get('RAYON_NUM_THREADS', 'all cores')}.",
        "",
        "Reference: exact (Python integers for every sum, mpmath 60 digits for √ and log). NMI and entropies are",
        "compared with the exact value *for the binning each implementation uses* (256 bins = the library's",
        "documented integer-level edges; levels = one bin per grey level). `inf` error = NaN/inf returned",
        "where the exact value is finite (or the call raised: see note).",
        "",
        "## Verdict",
        "",
        "Accuracy: relative error, ties within 2 ulp (4.5e-16); PSNR in absolute dB, ties within 2 ulp of",
        "20·log10(peak). Speed: wall time of one call computing that metric, best of the repeats.",
        "",
        *verdict(rows),
        "",
        "## By metric and peer",
        "",
        "Worst error over the cases (relative; PSNR absolute, in dB) and the median of peer time /",
        "irfidelity time (> 1 = irfidelity faster).",
        "",
        *summary_table(rows),
        "",
        "## Registration",
        "",
        "Known transforms of real thermal frames (see the module docstring); error = worst frame-corner",
        "displacement between the found and the true transform (px); time = wall time, best of the repeats,",
        "median over the cases. An `inf` median or `failed` = the call raised on some case.",
        "",
        *registration_table(reg_rows),
        "",
        "## Cases",
        "",
        *cases_note,
        "",
        "## Table",
        "",
        "| case | metric | implementation | value | abs error | rel error | time (ms) | note |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        v = r["value"]
        vs = "—" if v is None else (f"{v:.10g}" if isinstance(v, float) else str(v))
        lines.append(
            f"| {r['case']} | {r['metric']} | {'**' + r['impl'] + '**' if r['default'] else r['impl']} | {vs} | "
            f"{_fmt(r['abs'])} | {_fmt(r['rel'])} | {r['time'] * 1e3:.3f} | {r['note'] or ''} |"
        )
    (out / "work_precision.md").write_text("\n".join(lines) + "\n", encoding="utf-8")


def plot_registration(axes, reg_rows):
    """One panel per registration model: worst corner error against time, every frame size."""
    from matplotlib.lines import Line2D

    methods = sorted({r["method"] for r in reg_rows})
    cmap = plt_colours(len(methods))
    markers = {"640×512 Lepton↑": "o", "640×512 XT-R": "s", "160×120 Lepton": "^"}
    for ax, model in zip(axes, REGISTRATION_MODELS):
        for r in reg_rows:
            if r["model"] != model:
                continue
            y = r["worst"] if math.isfinite(r["worst"]) else 1e2
            ax.scatter(r["time_ms"], y, s=40, marker=markers.get(r["frame"], "o"),
                       color=cmap[methods.index(r["method"])], label=f"{r['method']}", alpha=0.85)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.axhline(1e2, color="r", lw=0.5, ls=":")
        ax.set_title(f"registration, {model} (○ 640×512 Lepton↑, □ XT-R, △ 160×120)", fontsize=9)
        ax.set_xlabel("time per call (ms)")
        ax.set_ylabel("worst corner error (px; 1e2 = failed)")
        ax.grid(True, which="major", alpha=0.3)
        shown = sorted({r["method"] for r in reg_rows if r["model"] == model})
        ax.legend([Line2D([], [], ls="", marker="o", color=cmap[methods.index(m)]) for m in shown], shown, fontsize=7)


def plt_colours(n: int):
    import matplotlib.pyplot as plt

    cmap = plt.get_cmap("tab10")
    return [cmap(i % 10) for i in range(n)]


def plot(rows, out: Path, reg_rows=()):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    impls = sorted({r["impl"] for r in rows})
    cmap = plt.get_cmap("tab20")
    colour = {name: cmap(i % 20) for i, name in enumerate(impls)}
    fig, axes = plt.subplots(4 if reg_rows else 3, 3, figsize=(15, 17 if reg_rows else 13))
    if reg_rows:
        plot_registration(axes[3], reg_rows)
    for ax, metric in zip(axes[:3].ravel(), METRICS):
        for r in rows:
            if r["metric"] != metric or not math.isfinite(r["time"]):
                continue
            e = r["rel"]
            y = 1e2 if not math.isfinite(e) else max(e, TINY)
            ax.scatter(
                r["time"] * 1e3,
                y,
                s=60 if r["default"] else 22,
                marker="*" if r["impl"].startswith("irfidelity") else "o",
                color=colour[r["impl"]],
                edgecolors="k" if r["default"] else "none",
                label=r["impl"],
                alpha=0.85,
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(TINY / 3, 1e3)
        ax.axhline(1e2, color="r", lw=0.5, ls=":")
        ax.set_title(metric)
        ax.set_xlabel("time per call (ms)")
        ax.set_ylabel("relative error (1e-18 = exact, 1e2 = NaN/inf)")
        ax.grid(True, which="major", alpha=0.3)
    handles = {}
    for ax in axes[:3].ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=5, fontsize=8)
    fig.suptitle("irfidelity vs peers: relative error against an exact reference vs run time (all cases)")
    fig.tight_layout(rect=(0, 0.07, 1, 0.97))
    fig.savefig(out / "work_precision.png", dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="bench-out", help="output directory (default: bench-out/)")
    ap.add_argument("--quick", action="store_true", help="128×128 frames, fewer repeats (< 2 min on 2 cores)")
    ap.add_argument("--threads", type=int, default=None, help="Rust threads (default: all cores; 1 = core for core)")
    args = ap.parse_args(argv)
    if args.threads:
        os.environ["RAYON_NUM_THREADS"] = str(args.threads)  # read when the pool is first used
        if args.threads == 1:
            import cv2

            cv2.setNumThreads(1)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rows = run(out, args.quick)
    reg_rows = registration_rows(args.quick)
    notes = [f"- `{c['name']}`: {c['note']} ({c['r'].dtype})" for c in make_cases(8)]
    write_md(rows, out, args.quick, notes, reg_rows)
    plot(rows, out, reg_rows)
    print(f"wrote {out / 'work_precision.md'} and {out / 'work_precision.png'} in {time.perf_counter() - t0:.1f}s")
    print("\n".join(verdict(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
