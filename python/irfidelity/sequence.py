"""Whole sequences: :func:`score_sequence` and :class:`SequenceReport` (DESIGN §2–§3).

A real camera's recording and a simulator's rendering of the same run are scored frame
by frame, and pooled:

* **Files** (directories, globs, lists of paths, multi-page TIFFs): the whole loop runs
  in Rust (``_core.score_pairs``) — both frames of a pair are decoded and reduced to a
  :class:`~irfidelity.PairStats` on ``workers`` threads, in parallel over pairs, with the
  GIL released and a few frames in flight per worker whatever the sequence length.
  Finished pairs stream back to Python, which turns each into metrics, components and a
  fidelity with the same functions :func:`irfidelity.evaluate` uses
  (:func:`~irfidelity.evaluation.plan_components`,
  :func:`~irfidelity.evaluation.image_components`), writes its CSV row and folds its
  statistics into the pooled ones.
* **Arrays** (3-D arrays, lists of 2-D arrays, ``.npy`` files): a Python loop over
  :func:`irfidelity.pair_stats` (each call is itself parallel in Rust).
* **Many machines**: ``client=dask.distributed.Client(...)`` sends chunks of frame pairs
  (paths) to the cluster's workers, each running the Rust engine on its chunk; the
  PairStats come back as bytes and are merged here. Results are identical to a local run
  (the files must be readable at the same paths on every worker).

Pooling. ``report.pooled`` holds the metrics of the *merged* PairStats of all scored
frames: PSNR from ΣSSE/ΣN (not a mean of dB values), SSIM from the pooled moments, exact
for integer frames. Statistics are merged in frame-index order whatever order the frames
finish in, so float results do not depend on scheduling either. NMI pools only when every
frame was binned on the same edges: ``hist_range="full"``, an explicit ``(lo, hi)`` or
``bins="levels"`` give a pooled joint histogram (``pooled["nmi_pooling"] ==
"histogram"``). With the default ``hist_range="data"`` each frame is binned over its own
range — so per-frame values equal those of :func:`irfidelity.pair_stats` and
:func:`irfidelity.evaluate` with their defaults — and the pooled NMI is the mean of the
per-frame NMI (``"frame_mean"``).

CSV. ``csv=path`` streams one row per frame as frames finish (completion order, with an
``index`` column; each row is written with one ``write`` and flushed). Next to it,
``path + ".pairstats"`` keeps each frame's statistics so that a resumed run can still pool
them. ``resume=True`` keeps the rows of frames already scored successfully, drops error
rows and a partly written last line, and scores only the rest: an interrupted run
(Ctrl-C, kill) loses nothing and scores nothing twice.
"""

from __future__ import annotations

import hashlib
import os
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import _core
from .errors import FidelityError, FrameError
from .evaluation import _enc, _pair, curve_components, image_components, plan_components
from .framelog import FrameLog, csv_columns, csv_line, row_values
from .frames import FrameSequence, load_frame
from .fuzzy import Weights, fidelity_sum, ordered_components
from .normalize import DEFAULT_PSNR_ANCHORS
from .stats import KernelRequest, PairStats, hist_params, pair_stats, peak_and_valid, plan_need

__all__ = ["score_sequence", "SequenceReport"]

_SUMMARY_METRICS = ("mse", "psnr_db", "ssim", "nmi", "fidelity")
_PERCENTILES = (5, 50, 95)


# --------------------------------------------------------------------------- report
@dataclass
class SequenceReport:
    """Fidelity of a whole sequence, frame by frame and pooled.

    Attributes
    ----------
    frames : list of dict
        One dict per frame, in index order: ``index``, ``real``, ``sim`` (display names),
        ``rows``, ``cols``, ``dtype``, ``n``, the raw metrics the plan computed (``mse``,
        ``psnr_db``; ``ssim`` and its factors; ``nmi``, ``mi``, ``h_real``, ``h_sim``,
        ``h_joint``), ``components`` (``{"psnr"|"nmi"|"ssim": f}``), ``fidelity``
        (eq. 15) and ``error`` (None, or why the frame could not be scored).
    pooled : dict
        Metrics, components and fidelity of the merged statistics of all scored frames
        (see the module notes; ``nmi_pooling`` says how NMI was pooled), plus ``frames``
        (how many were pooled) and ``n`` (pixel pairs).
    failed : list of int
        Indices of frames with an error.
    frame_stats : dict
        For each metric, component (``f_psnr``...) and ``fidelity``: ``mean``, ``p5``,
        ``p50``, ``p95``, ``min``, ``max`` over the scored frames.
    weights : Weights
        The weights eq. (15) used (components without inputs dropped, the rest rescaled).
    skipped : dict
        ``{component: reason}`` for components not computed.
    settings : dict
        bits, peak, bins, hist_range, channel, ... as used.
    curves : dict
        The curve components (camera properties, the same for every frame) when MTF/SiTF
        inputs were given: ``components`` (``{"mtf"|"sitf": f}``), ``metrics`` (MTF50s,
        slopes, mu, rho, ...), ``inputs`` and ``notes``; empty otherwise. They enter every
        frame's and the pooled fidelity.
    """

    frames: list[dict]
    pooled: dict
    failed: list[int]
    frame_stats: dict
    weights: Weights
    skipped: dict
    settings: dict = field(default_factory=dict)
    curves: dict = field(default_factory=dict)

    @property
    def fidelity(self) -> float | None:
        """The pooled fidelity (eq. 15 on the pooled components)."""
        return self.pooled.get("fidelity")

    @property
    def columns(self) -> list[str]:
        return list(self.settings.get("columns", csv_columns(self.weights, self.settings.get("nonfinite") == "mask")))

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write one row per frame, in index order (the same columns as ``csv=``)."""
        cols = self.columns
        with open(path, "w", newline="", encoding="utf-8") as f:
            f.write(csv_line(cols))
            for fr in self.frames:
                f.write(csv_line(row_values(fr, cols)))

    def to_dict(self) -> dict:
        """JSON-ready dict (non-finite floats as ``"inf"``/``"-inf"``/``"nan"``)."""
        return _enc(
            {
                "frames": [dict(f) for f in self.frames],
                "pooled": dict(self.pooled),
                "failed": list(self.failed),
                "frame_stats": dict(self.frame_stats),
                "weights": self.weights.as_dict(),
                "skipped": dict(self.skipped),
                "settings": {k: v for k, v in self.settings.items() if k != "columns"},
                "curves": dict(self.curves),
            }
        )

    def summary_text(self) -> str:
        """A short human-readable summary."""
        n = len(self.frames)
        lines = [f"sequence of {n} frame pairs: {n - len(self.failed)} scored, {len(self.failed)} failed"]
        p = self.pooled
        if p.get("fidelity") is not None:
            lines.append(f"pooled fidelity: {p['fidelity']:.4f}")
        m = self.curves.get("metrics", {})
        for k, v in self.curves.get("components", {}).items():
            raw = (f"MTF50 real {m['mtf50_real']:.4g}, sim {m['mtf50_sim']:.4g}" if k == "mtf"
                   else f"slope real {m['sitf_slope_real']:.4g}, sim {m['sitf_slope_sim']:.4g}")
            lines.append(f"{k} component (every frame): {v:.4f} ({raw}; mu {m[k + '_mu']:.4f}, rho {m[k + '_rho']:.4f})")
        for key, label in (("psnr_db", "PSNR (dB, from ΣSSE/ΣN)"), ("ssim", "SSIM"), ("nmi", "NMI")):
            if p.get(key) is not None:
                note = " (mean of frames)" if key == "nmi" and p.get("nmi_pooling") == "frame_mean" else ""
                lines.append(f"pooled {label}: {p[key]:.6g}{note}")
        for key in ("fidelity", "psnr_db", "ssim", "nmi"):
            s = self.frame_stats.get(key)
            if s:
                lines.append(
                    f"per frame {key}: mean {s['mean']:.6g}  p5 {s['p5']:.6g}  p50 {s['p50']:.6g}  p95 {s['p95']:.6g}"
                )
        if self.failed:
            shown = ", ".join(str(i) for i in self.failed[:10])
            more = ", ..." if len(self.failed) > 10 else ""
            lines.append(f"failed frames: {shown}{more}")
            first = next(f for f in self.frames if f.get("error"))
            lines.append(f"  first error (frame {first['index']}): {first['error']}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary_text()


# --------------------------------------------------------------------------- helpers
def _percentiles(values: list[float]) -> dict:
    a = np.asarray(values, dtype=float)
    a = a[~np.isnan(a)]
    if a.size == 0:
        return {}
    method = "linear" if np.all(np.isfinite(a)) else "nearest"
    ps = np.percentile(a, _PERCENTILES, method=method)
    out = {"mean": float(np.mean(a))}
    out.update({f"p{q}": float(v) for q, v in zip(_PERCENTILES, ps)})
    out.update(min=float(a.min()), max=float(a.max()))
    return out


def _frame_stats(frames: list[dict]) -> dict:
    ok = [f for f in frames if not f.get("error")]
    out: dict[str, dict] = {}
    keys = list(_SUMMARY_METRICS)
    for k in ("psnr", "nmi", "ssim"):
        keys.append(f"f_{k}")
    for k in keys:
        if k.startswith("f_"):
            vals = [f["components"][k[2:]] for f in ok if k[2:] in (f.get("components") or {})]
        else:
            vals = [f[k] for f in ok if f.get(k) is not None]
        s = _percentiles(vals)
        if s:
            out[k] = s
    return out


def _as_sequence(x: Any, channel: str | None, which: str) -> FrameSequence:
    if isinstance(x, FrameSequence):
        return x
    if isinstance(x, np.ndarray):
        if x.ndim != 3:
            raise FidelityError(f"{which}: an array sequence must be 3-D (frames, rows, cols), got shape {x.shape}")
        return FrameSequence(x)
    if isinstance(x, (list, tuple)) and x and all(isinstance(e, np.ndarray) for e in x):
        shapes = {e.shape for e in x}
        if len(shapes) != 1 or len(next(iter(shapes))) != 2:
            raise FidelityError(f"{which}: a list of arrays must hold 2-D frames of one shape, got {sorted(shapes)}")
        return FrameSequence(np.stack(x))
    return FrameSequence(x, channel=channel)


def _file_sources(seq: FrameSequence) -> list[tuple[str, int]] | None:
    """(path, page) of every frame when the Rust engine can decode them all, else None."""
    src = seq.sources
    if any(p is None or str(p).lower().endswith(".npy") for p, _ in src):
        return None
    return [(str(p), int(g)) for p, g in src]


def _names_digest(names: list[str]) -> str:
    return hashlib.sha256("\n".join(names).encode()).hexdigest()[:16]


def _tqdm_bar(total: int, initial: int):
    try:
        from tqdm.auto import tqdm
    except Exception:  # tqdm is optional (the `progress` extra)
        return None
    return tqdm(total=total, initial=initial, unit="frame", desc="scoring", dynamic_ncols=True)


# --------------------------------------------------------------------------- the scorer
class _Scorer:
    """Turns outcomes into frame dicts, streams them, and pools statistics in index order."""

    def __init__(self, *, n, real_names, sim_names, weights, pk, bin_label, ref_dtype, keep_hist, anchors,
                 exponents, store, bar, progress_cb, columns, fixed):
        self.n = n
        self.fixed = fixed  # curve components, the same for every frame
        self.keys = [c for c in columns if not c.startswith("f_")]
        self.real_names, self.sim_names = real_names, sim_names
        self.w = weights
        self.pk = pk
        self.bin_label = bin_label
        self.ref_dtype = ref_dtype
        self.keep_hist = keep_hist
        self.anchors, self.exponents = anchors, exponents
        self.store = store
        self.bar = bar
        self.progress_cb = progress_cb
        self.frames: dict[int, dict] = {}
        # pooling in index order: index -> raw stats (or bytes) / None for failures
        self.pending: dict[int, Any] = {}
        self.next = 0
        self.pooled = None
        self.hist_merged = keep_hist
        self.done = 0

    def add_resumed(self, frames: dict[int, dict], stats: dict[int, bytes]) -> None:
        for i, fr in frames.items():
            fr["real"] = fr.get("real") or self.real_names[i]
            fr["sim"] = fr.get("sim") or self.sim_names[i]
            self.frames[i] = fr
            self.pending[i] = stats[i]
        self.done = len(frames)
        self._advance()

    def outcome(self, index: int, raw, err: str | None, shape, dtype) -> None:
        fr: dict[str, Any] = {"index": index, "real": self.real_names[index], "sim": self.sim_names[index]}
        if shape is not None:
            fr["rows"], fr["cols"] = int(shape[0]), int(shape[1])
        fr["dtype"] = dtype
        if err is None and dtype != self.ref_dtype:
            err = (f"{self.real_names[index]}: frame dtype {dtype} differs from the sequence's "
                   f"{self.ref_dtype} (first frame); convert the frames to one type")
            raw = None
        if err is None:
            st = PairStats(raw, peak=self.pk, bins=self.bin_label)
            try:
                comps, mets = image_components(st, self.w, psnr_anchors=self.anchors, ssim_exponents=self.exponents)
                comps = ordered_components(comps | self.fixed)
                fid = fidelity_sum(self.w, comps)
            except FidelityError as e:
                err, raw = str(e), None
            else:
                mets.pop("bins", None)
                mets.pop("masked", None)
                mets["nonfinite"] = int(raw.nonfinite)
                fr.update(mets)
                fr["components"] = comps
                fr["fidelity"] = float(fid)
        if err is not None:
            fr["error"] = " ".join(str(err).split())
            fr.setdefault("components", {})
            raw = None
        else:
            fr["error"] = None
        # every frame has the same keys: the CSV columns (None when not computed) + components
        fr = {k: fr.get(k) for k in self.keys} | {"components": fr.get("components", {})}
        self.frames[index] = fr
        if self.store is not None:
            self.store.write(fr, None if raw is None else raw.to_bytes())
        self.pending[index] = raw
        self._advance()
        self.done += 1
        if self.bar is not None:
            self.bar.update(1)
        if self.progress_cb is not None:
            self.progress_cb(self.done, self.n)

    def _advance(self) -> None:
        run = []
        while self.next in self.pending:
            item = self.pending.pop(self.next)
            if isinstance(item, (bytes, bytearray)):
                item = _core.PairStats.from_bytes(zlib.decompress(item))
            if item is not None:
                run.append(item)
            self.next += 1
        if run:
            if self.pooled is not None:
                run.insert(0, self.pooled)
            merged, hist_ok = _core.merge_all(run, keep_hist=self.keep_hist)
            self.pooled = merged
            self.hist_merged = self.hist_merged and hist_ok

    def report(self, settings: dict, skipped: dict, curves: dict) -> SequenceReport:
        frames = [self.frames[i] for i in range(self.n)]
        failed = [f["index"] for f in frames if f.get("error")]
        pooled: dict[str, Any] = {"frames": self.n - len(failed), "n": 0, "nmi_pooling": None}
        if self.pooled is not None and self.pooled.n > 0:
            st = PairStats(self.pooled, peak=self.pk, bins=self.bin_label if self.hist_merged else None)
            w = self.w
            pooled_nmi = w.nmi > 0 and self.hist_merged and self.pooled.has_hist
            if w.nmi > 0 and not pooled_nmi:
                rest = {k: w[k] for k in ("psnr", "ssim") if w[k] > 0}
                wp = Weights.normalized(**rest) if rest else None
            else:
                wp = w
            comps, mets = image_components(st, wp, psnr_anchors=self.anchors, ssim_exponents=self.exponents) \
                if wp is not None else ({}, {"n": int(self.pooled.n)})
            mets.pop("bins", None)
            pooled.update(mets)
            pooled["n"] = int(self.pooled.n)
            if w.nmi > 0:
                if pooled_nmi:
                    pooled["nmi_pooling"] = "histogram"
                else:
                    ok = [f for f in frames if not f.get("error")]
                    pooled["nmi_pooling"] = "frame_mean"
                    pooled["nmi"] = float(np.mean([f["nmi"] for f in ok]))
                    comps["nmi"] = float(np.mean([f["components"]["nmi"] for f in ok]))
            pooled["components"] = ordered_components(comps | self.fixed)
            pooled["fidelity"] = float(fidelity_sum(w, pooled["components"]))
        return SequenceReport(
            frames=frames,
            pooled=pooled,
            failed=failed,
            frame_stats=_frame_stats(frames),
            weights=self.w,
            skipped=dict(skipped),
            settings=settings,
            curves=curves,
        )


# --------------------------------------------------------------------------- Dask task
def _dask_score_chunk(real_paths, sim_paths, real_pages, sim_pages, kwargs):
    """Run on a Dask worker: score one chunk with the Rust engine; PairStats as bytes."""
    from irfidelity import _core as core

    out = core.score_pairs(real_paths, sim_paths, real_pages, sim_pages, **kwargs)
    return [(i, None if st is None else st.to_bytes(), err, shape, dtype) for i, st, err, shape, dtype in out]


# --------------------------------------------------------------------------- entry point
def _peek_dtype(seq: FrameSequence, files: list[tuple[str, int]] | None, limit: int = 8) -> np.dtype:
    first_err = None
    for i in range(min(len(seq), limit)):
        try:
            if files is not None:
                path, page = files[i]
                return load_frame(path, channel=seq.channel, page=page).dtype
            return np.asarray(seq[i]).dtype
        except FidelityError as e:
            first_err = first_err or e
    raise FrameError(f"none of the first {min(len(seq), limit)} real frames can be read: {first_err}")


def score_sequence(
    real: Any,
    sim: Any,
    *,
    weights: Any = None,
    bits: int | None = None,
    peak: float | None = None,
    bins: int | str = 256,
    hist_range: Any = "data",
    channel: str | None = None,
    workers: int | None = None,
    progress: bool | Callable[[int, int], Any] = True,
    client: Any = None,
    csv: str | os.PathLike | None = None,
    resume: bool = False,
    missing: str = "renormalize",
    chunk_size: int = 16,
    nonfinite: str = "raise",
    psnr_anchors=DEFAULT_PSNR_ANCHORS,
    ssim_exponents=(1.0, 1.0, 1.0),
    max_pixels: int | None = None,
    real_mtf: Any = None,
    sim_mtf: Any = None,
    real_sitf: Any = None,
    sim_sitf: Any = None,
    edge_channel: str | None = None,
    mtf_options: Any = None,
    sitf_options: Any = None,
) -> SequenceReport:
    """Score a simulated sequence against the real one, frame by frame and pooled.

    Parameters
    ----------
    real, sim : directory, glob, list of paths, multi-page TIFF, 3-D array, list of 2-D
        arrays, or :class:`~irfidelity.FrameSequence`
        Frame ``i`` of ``sim`` is compared with frame ``i`` of ``real``; both must have the
        same number of frames (else :class:`FidelityError` naming both counts, before
        any work). Directories and globs are ordered naturally (``f2`` before ``f10``).
    weights : Weights, preset name, "name=value,…" string, mapping or None (balanced)
        The image components (psnr, nmi, ssim) are scored per frame; the curve components
        (mtf, sitf) are camera properties, computed once from ``real_mtf``/``sim_mtf`` and
        ``real_sitf``/``sim_sitf`` and added to every frame's and the pooled fidelity
        (``report.curves``). Without curve inputs, the default ``missing="renormalize"``
        drops those components and rescales the others (recorded in ``report.skipped``).
        Only what the weighted components need is computed (no histogram when ``nmi`` has
        weight 0, no curve read when ``mtf`` has weight 0, ...).
    bits, peak : PSNR peak ``2**bits − 1`` or ``peak`` (float frames need ``peak``);
        ``bits`` also bounds integer values (a frame outside fails with a RangeError row).
    bins, hist_range : NMI histogram, as for :func:`irfidelity.pair_stats`. With
        ``hist_range="data"`` (default) the pooled NMI is the mean of the frames' NMI; use
        ``"full"``, ``(lo, hi)`` or ``bins="levels"`` for NMI of the pooled histogram.
    channel : EXR/PNG/TIFF channel to decode (both sequences).
    workers : threads over frame pairs (default: all cores); with ``client``, threads
        per Dask task (default 1).
    progress : True (a tqdm bar if tqdm is installed), False, or ``callable(done, total)``.
    client : dask.distributed.Client, optional
        Score chunks of ``chunk_size`` frame pairs on the cluster (file sources only;
        paths must be valid on the workers). Identical results to a local run.
    csv : path, optional
        Stream one row per frame (with an ``index`` column) as frames finish, flushed;
        ``csv + ".pairstats"`` holds their statistics for pooling after a resume.
    resume : bool
        Keep the successful rows of an existing ``csv`` (written with the same settings
        and frames) and score only the other frames, appending their rows.
    missing : "renormalize" (default) or "raise", as in :func:`irfidelity.evaluate`.
    chunk_size : frame pairs per Dask task.
    nonfinite : "raise" or "mask" (NaN/Inf in float frames).
    psnr_anchors, ssim_exponents : as in :func:`irfidelity.evaluate`.
    max_pixels : per-frame pixel limit for decoding.
    real_mtf, sim_mtf, real_sitf, sim_sitf, edge_channel, mtf_options, sitf_options :
        The camera curves, as in :func:`irfidelity.evaluate` (Curve, (x, y), CSV path; an
        edge image or its path for the MTF). Read and compared once, before any frame.

    Returns
    -------
    SequenceReport
        ``.frames``, ``.pooled``, ``.failed``, ``.frame_stats``, ``.to_csv()``,
        ``.to_dict()``, ``.summary_text()``.
    """
    rseq = _as_sequence(real, channel, "real")
    sseq = _as_sequence(sim, channel, "sim")
    n = len(rseq)
    if n != len(sseq):
        raise FidelityError(
            f"the real sequence has {n} frames and the simulated sequence {len(sseq)}; "
            "they must have the same number of frames"
        )
    if n == 0:
        raise FidelityError("empty sequences: nothing to score")
    if channel is None:
        chans = {s.channel for s in (rseq, sseq)} - {None}
        if len(chans) > 1:
            raise FidelityError(f"the two FrameSequences select different channels {sorted(chans)}; pass channel=")
        channel = chans.pop() if chans else None
    if nonfinite not in ("raise", "mask"):
        raise FidelityError(f"nonfinite must be 'raise' or 'mask', got {nonfinite!r}")
    if resume and csv is None:
        raise FidelityError("resume=True needs csv=PATH (the CSV of the interrupted run)")
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise FidelityError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1):
        raise FidelityError(f"workers must be a positive integer or None, got {workers!r}")

    # --- the plan (same as evaluate)
    have_mtf = _pair(real_mtf, sim_mtf, "real_mtf", "sim_mtf")
    have_sitf = _pair(real_sitf, sim_sitf, "real_sitf", "sim_sitf")
    w, need, skipped = plan_components(weights, have_images=True, have_mtf=have_mtf, have_sitf=have_sitf,
                                       missing=missing)
    if not need:
        raise FidelityError("a sequence needs a positive weight on psnr, nmi or ssim (the per-frame components); "
                            "for curves alone use irfidelity.evaluate")
    # the camera curves: compared once, before any frame (a bad curve fails fast)
    fixed, curve_metrics, curve_inputs, curve_notes = curve_components(
        w, real_mtf, sim_mtf, real_sitf, sim_sitf, edge_channel=edge_channel, mtf_options=mtf_options,
        sitf_options=sitf_options)
    wanted = plan_need(need)
    rfiles, sfiles = _file_sources(rseq), _file_sources(sseq)
    engine = rfiles is not None and sfiles is not None
    if client is not None and not engine:
        raise FidelityError("client= needs file sources (EXR/PNG/TIFF paths) for both sequences; "
                            "arrays and .npy files are scored locally")
    ref_dtype = _peek_dtype(rseq, rfiles if engine else None)
    pk, valid = peak_and_valid(ref_dtype, bits, peak)
    if "sse" in wanted and pk is None:
        raise FidelityError("PSNR of float frames needs an explicit `peak` (the maximum possible value)")
    nbins, levels, rng = None, False, None
    if "hist" in wanted:
        nbins, levels, rng = hist_params(bins, hist_range, ref_dtype, bits, peak, pk)
    bin_label = ("levels" if levels else nbins) if "hist" in wanted else None
    keep_hist = "hist" in wanted and (levels or rng is not None)

    settings = {
        "frames": n,
        "names": _names_digest(rseq.names + sseq.names),
        "weights": w.as_dict(),
        "bits": bits,
        "peak": pk,
        "bins": bin_label,
        "hist_range": list(rng) if rng is not None else (None if "hist" not in wanted else "data"),
        "channel": channel,
        "dtype": ref_dtype.name,
        "nonfinite": nonfinite,
        "psnr_anchors": [list(map(float, a)) for a in psnr_anchors],
        "ssim_exponents": [float(x) for x in ssim_exponents],
    }
    if fixed:  # a resumed run must have compared the same curves
        settings["curves"] = {k: float(v) for k, v in fixed.items()}
    columns = csv_columns(w, nonfinite == "mask")

    store = FrameLog(os.fspath(csv), columns, settings, resume) if csv is not None else None
    bar = None
    try:
        done_rows = store.done_rows if store is not None else {}
        todo = [i for i in range(n) if i not in done_rows]
        if progress is True:
            bar = _tqdm_bar(n, len(done_rows))
        cb = progress if callable(progress) else None
        scorer = _Scorer(n=n, real_names=rseq.names, sim_names=sseq.names, weights=w, pk=pk, bin_label=bin_label,
                         ref_dtype=ref_dtype.name, keep_hist=keep_hist, anchors=psnr_anchors,
                         exponents=ssim_exponents, store=store, bar=bar, progress_cb=cb, columns=columns,
                         fixed=fixed)
        if store is not None:
            scorer.add_resumed(store.done_rows, store.done_stats)

        kernel = dict(request=KernelRequest(
            channel=channel,
            sse="sse" in wanted,
            moments="moments" in wanted,
            bins=nbins,
            levels=levels,
            hist_range=rng,
            valid=valid,
            mask_nonfinite=nonfinite == "mask",
            max_pixels=max_pixels,
        ))
        if todo and engine and client is None:
            rp = [rfiles[i][0] for i in todo]
            sp = [sfiles[i][0] for i in todo]
            rg = [rfiles[i][1] for i in todo]
            sg = [sfiles[i][1] for i in todo]

            def on_result(batch):
                for k, st, err, shape, dtype in batch:
                    scorer.outcome(todo[k], st, err, shape, dtype)

            _core.score_pairs(rp, sp, rg, sg, workers=int(workers or 0), on_result=on_result, **kernel)
        elif todo and engine:
            _run_dask(client, todo, rfiles, sfiles, kernel, int(workers or 1), int(chunk_size), scorer)
        elif todo:
            need_names = sorted(need)
            for i in todo:
                try:
                    r, s = rseq[i], sseq[i]
                    st = pair_stats(r, s, bits=bits, peak=peak, bins=bins, hist_range=hist_range, need=need_names,
                                    nonfinite=nonfinite)
                except FidelityError as e:
                    scorer.outcome(i, None, str(e), None, None)
                    continue
                scorer.outcome(i, st._raw, None, r.shape, r.dtype.name)
    finally:
        if bar is not None:
            bar.close()
        if store is not None:
            store.close()
    settings = dict(settings, columns=columns, csv=None if csv is None else os.fspath(csv),
                    resumed=len(done_rows), workers=workers)
    settings.pop("names")
    curves = {"components": fixed, "metrics": curve_metrics, "inputs": curve_inputs, "notes": curve_notes} \
        if fixed else {}
    return scorer.report(settings, skipped, curves)


def _run_dask(client, todo, rfiles, sfiles, kernel, workers, chunk_size, scorer) -> None:
    try:
        from distributed import as_completed
    except ImportError as e:  # pragma: no cover - only without the dask extra
        raise FidelityError("client= needs dask.distributed (pip install 'irfidelity[dask]')") from e
    futures = {}
    for start in range(0, len(todo), chunk_size):
        idx = todo[start : start + chunk_size]
        fut = client.submit(
            _dask_score_chunk,
            [rfiles[i][0] for i in idx],
            [sfiles[i][0] for i in idx],
            [rfiles[i][1] for i in idx],
            [sfiles[i][1] for i in idx],
            dict(kernel, workers=workers),
            pure=False,
        )
        futures[fut] = idx
    try:
        for fut in as_completed(list(futures)):
            idx = futures.pop(fut)
            rows = fut.result()
            fut.release()
            for k, data, err, shape, dtype in rows:
                raw = None if data is None else _core.PairStats.from_bytes(data)
                scorer.outcome(idx[k], raw, err, shape, dtype)
    finally:
        if futures:
            client.cancel(list(futures))
