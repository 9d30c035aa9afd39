"""The single-pair report: :func:`render_pair_html`.

Memory (docs/design.md §14): whatever the frame size, the page needs display-size copies
only. The difference's statistics and the fallback histograms are summed over bands of rows
(:data:`BAND_PIXELS` at a time), the SSIM map is computed keeping only its displayed pixels
(:func:`irfidelity.maps.sampled_ssim_map`, the same values and mean), so besides the frames
the report holds a few bands, the coarser MS-SSIM scales (planned by :func:`~irfidelity.maps.ms_ssim`)
and, for float16 frames, the joint histogram's float32 copies.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from .. import budget
from ..errors import FidelityError
from ..maps import SSIMMap, ms_ssim, sampled_ssim_map
from ..stats import _as_frame, pair_stats
from . import figures, sections
from .bars import bars as bars_section
from .noise import noise as noise_section
from .regions import regions as regions_section
from .temperature import temperatures
from .html import Missing, Raw, colour_bar, image, missing, page, panels, paragraph, section

__all__ = ["render_pair_html", "BAND_PIXELS"]

#: Pixels of a band of rows when statistics are summed over the whole frames.
BAND_PIXELS = 1 << 20
#: Bytes a band's pixel takes at most: both frames as float64, their difference, its finite
#: values and their squares, masks.
_BAND_BYTES_PER_PIXEL = 40
#: float16 frames: the kernel's float32 copies for the joint histogram, bytes a pixel.
_WIDENED_BYTES = 8


def render_pair_html(
    report: Any,
    *,
    real: Any = None,
    sim: Any = None,
    mask: Any = None,
    ssim: Any = None,
    joint_histogram: tuple[Any, Any, Any] | None = None,
    curves: Mapping[str, Any] | None = None,
    registration: Any = None,
    sim_unregistered: Any = None,
    peak: float | None = None,
    title: str | None = None,
    fragment: bool = False,
    max_bytes: int | None = None,
) -> str:
    """One self-contained HTML page (or a ``<div>`` for notebooks) for a single frame pair.

    Parameters
    ----------
    report : dict or object with ``to_dict()``
        The JSON-ready report (``FidelityReport.to_dict()``). Every key is optional: a section
        whose data is missing is replaced by a note saying so.
    real, sim : 2-D arrays or paths, optional
        The frames as scored (``sim`` resampled onto ``real``, float64, when a registration
        was applied: the SSIM map and the joint histogram then compare it with ``real`` as
        float64, over the overlap ``mask``). Without them the frame, difference, SSIM-map and
        joint-histogram sections are left out.
    mask : 2-D bool array, optional
        Valid pixels (``False`` = excluded from the metrics, e.g. outside a registration's
        overlap): shown grey in the difference and left out of the histograms.
    ssim : SSIMMap or 2-D array, optional
        A precomputed SSIM map; default: :func:`irfidelity.maps.ssim_map` of the frames.
    joint_histogram : (counts, real_edges, sim_edges), optional
        Default: :meth:`irfidelity.PairStats.joint_histogram` with the report's ``bins`` and
        ``hist_range`` settings (256 bins over the data range when it records none).
    curves : mapping, optional
        ``real_mtf``, ``sim_mtf``, ``real_sitf``, ``sim_sitf`` (Curve, ``(x, y)`` or
        ``{"x", "y"}``) and ``real_sitf_fit``, ``sim_sitf_fit`` (SiTFFit or a mapping with
        ``slope, intercept, lo, hi``).
    registration : Registration or mapping, optional
        Default: ``report["registration"]``.
    sim_unregistered : 2-D array, optional
        The simulated frame before registration: adds a before/after overlay (checkerboards
        of the real frame with the simulated one as given and as resampled).
    peak : float, optional
        Data range L of the SSIM map. Default: the report's ``peak`` or ``bits`` setting, else
        the frames' joint data range (max − min); the page says which.
    title : str, optional
    fragment : bool
        Return a ``<div>`` (styles scoped to it) instead of a whole document.
    max_bytes : int, optional
        The memory budget (default :data:`irfidelity.budget.DEFAULT_MAX_BYTES`): the frames and
        what the page computes from them (display-size copies, bands of rows, the coarser
        MS-SSIM scales) must fit, else a :class:`FidelityError` before anything is computed
        (an MS-SSIM over budget is left out of the caption, which says why).

    Returns
    -------
    str
        HTML: figures are embedded PNGs, styles inline, no script, and a
        Content-Security-Policy that forbids any network fetch.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> from irfidelity.report import render_pair_html
    >>> y, x = np.mgrid[0:120, 0:160]
    >>> real = (3000 + 200 * np.sin(x / 9.0) + 50 * np.cos(y / 5.0)).astype(np.uint16)
    >>> sim = (real // 2 + 1600).astype(np.uint16)
    >>> rep = irf.evaluate(real, sim, bits=14, peak="range", missing="renormalize")
    >>> page = render_pair_html(rep.to_dict(), real=real, sim=sim)
    >>> page.startswith("<!DOCTYPE html>"), "Not shown: no MTF curves were given" in page
    (True, True)

    References
    ----------
    .. [1] Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547 (components,
       eq. 15, fuzzy grades, and Figs. 5–6: each frame with its normalised histogram).
    .. [2] Z. Wang et al., IEEE Trans. Image Processing 13(4), 600–612 (2004) (the SSIM map).
    """
    d = sections.as_dict(report)
    figures.require_matplotlib()
    curves = dict(curves or {})
    metrics = sections.mapping(d, "metrics")
    frames = _frames(real, sim, mask, registered=bool(d.get("registration")) or registration is not None)
    if isinstance(frames, tuple):
        _check_budget(*frames, max_bytes)
    body = [
        sections.header(title or "Fidelity report", _subtitle(d)),
        sections.verdict(d),
        sections.components(d),
        *regions_section(d),
        *(_frame_sections(d, frames, ssim, joint_histogram, peak, max_bytes) if isinstance(frames, tuple) else
          [missing(t, frames, anchor=a) for t, a in _FRAME_SECTIONS]),
        *([_overlay_section(frames, sim_unregistered)] if isinstance(frames, tuple) and sim_unregistered is not None
          else []),
        sections.mtf(curves, metrics),
        sections.sitf(curves, metrics),
        noise_section(curves, metrics),
        bars_section(curves, metrics),
        sections.registration(d, registration),
        sections.settings(d),
    ]
    body.append(sections.footer([b.title for b in body if isinstance(b, Missing)]))
    return page(title or "irfidelity fidelity report", "".join(body), fragment=fragment)


_FRAME_SECTIONS = [("Frames", "frames"), ("Difference", "difference"), ("SSIM map", "ssim-map"),
                   ("Joint histogram", "joint-histogram")]


def _subtitle(d: Mapping) -> str | None:
    inputs = sections.mapping(d, "inputs")
    if "real" in inputs or "sim" in inputs:
        return f"real: {inputs.get('real', '?')} — simulated: {inputs.get('sim', '?')}"
    return None


def _frames(real: Any, sim: Any, mask: Any, registered: bool
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | str:
    """The frames (and mask) checked, or why they cannot be shown. A registered pair is
    compared as float64 (the resampled simulated frame is float64 whatever the real one is)."""
    if real is None or sim is None:
        return "no frames were given (real=..., sim=...)"
    try:
        r, s = _as_frame(real, "real"), _as_frame(sim, "sim")
    except FidelityError as exc:
        return f"the frames could not be read: {exc}"
    if r.shape != s.shape:
        return f"the frames differ in shape: {r.shape} vs {s.shape}"
    if registered and r.dtype != s.dtype:
        r, s = r.astype(np.float64), s.astype(np.float64)
    m = None
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != r.shape or m.dtype != np.bool_:
            return f"mask must be a bool array of the frames' shape {r.shape}"
    return r, s, m


def _check_budget(real: np.ndarray, sim: np.ndarray, mask: np.ndarray | None, max_bytes: int | None) -> None:
    """The page's plan: the frames and mask, a band of rows, and float16 frames' copies."""
    widened = _WIDENED_BYTES * real.size if real.dtype == np.float16 else 0
    band = _BAND_BYTES_PER_PIXEL * min(real.size, BAND_PIXELS)
    budget.check("the HTML report of a frame pair", real.shape, budget.nbytes(real, sim, mask) + band + widened,
                 max_bytes)


def _bands(rows: int, cols: int) -> Iterator[slice]:
    """Row slices of at most :data:`BAND_PIXELS` pixels (at least one row each)."""
    step = max(1, BAND_PIXELS // max(cols, 1))
    for start in range(0, rows, step):
        yield slice(start, min(start + step, rows))


def _finite_extent(*frames: np.ndarray) -> tuple[float, float] | None:
    """(min, max) of the finite values of the frames, band by band; None when there are none."""
    lo, hi = np.inf, -np.inf
    for frame in frames:
        for band in _bands(*frame.shape):
            values = frame[band]
            if values.dtype.kind == "f":
                values = values[np.isfinite(values)]
            if values.size:
                lo, hi = min(lo, float(values.min())), max(hi, float(values.max()))
    return (lo, hi) if lo <= hi else None


def _histogram(frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.histogram(frame[np.isfinite(frame)], bins=256)``, counted band by band (the same
    edges from the finite range, the same counts)."""
    extent = _finite_extent(frame)
    edges = np.histogram_bin_edges(np.asarray(extent if extent is not None else [], dtype=np.float64), bins=256)
    counts = np.zeros(256, dtype=np.int64)
    for band in _bands(*frame.shape):
        values = frame[band]
        counts += np.histogram(values[np.isfinite(values)] if values.dtype.kind == "f" else values, bins=edges)[0]
    return counts, edges


def _settings(d: Mapping) -> dict:
    out = {}
    for key in ("settings", "config"):
        out.update(sections.mapping(d, key))
    return out


def _data_range(d: Mapping, real: np.ndarray, sim: np.ndarray, peak: float | None) -> tuple[float, str]:
    """The SSIM map's data range L and where it came from: the ``peak`` argument, the report's
    ``peak`` or ``bits`` setting, else the frames' joint data range (max − min)."""
    st = _settings(d)
    metrics = sections.mapping(d, "metrics")
    for source, value in (("the peak argument", peak), ("the report's PSNR peak", metrics.get("psnr_peak")),
                          ("the report's peak", st.get("peak"))):
        v = sections.as_float(value)
        if v is not None and v > 0:
            return v, source
    bits = st.get("bits")
    if isinstance(bits, int) and not isinstance(bits, bool) and bits > 0:
        return float(2**bits - 1), f"the report's bits = {bits}"
    extent = _finite_extent(real, sim)
    span = extent[1] - extent[0] if extent is not None else 0.0
    return (span if span > 0 else 1.0), "the frames' joint data range (the report records no peak or bits)"


def _frame_sections(d, frames, ssim, joint, peak, max_bytes) -> list[Raw]:
    real, sim, mask = frames
    hist = _joint_histogram(d, real, sim, mask, joint)
    in_unit = [temperatures(d, real, sim, mask)] if sections.mapping(d, "config").get("unit") else []
    return [_frames_section(real, sim, hist), *in_unit, _difference_section(real, sim, mask),
            _ssim_section(d, real, sim, mask, ssim, peak, max_bytes), _joint_section(hist)]


def _joint_histogram(d, real, sim, mask, given):
    """``(counts, real_edges, sim_edges)`` or the reason there is none."""
    if given is not None:
        try:
            counts, re, se = (np.asarray(a) for a in given)
        except (TypeError, ValueError):
            return "joint_histogram must be (counts, real_edges, sim_edges)"
        if counts.ndim != 2 or counts.shape != (len(re) - 1, len(se) - 1):
            return "joint_histogram: counts must be (len(real_edges) - 1) × (len(sim_edges) - 1)"
        return counts, re, se
    st = _settings(d)
    bins = st.get("bins", sections.mapping(d, "metrics").get("bins", 256))
    if not (bins == "levels" and real.dtype.kind in "ui") and not (isinstance(bins, int) and bins > 0):
        bins = 256
    hist_range = st.get("hist_range", "data")
    if not (isinstance(hist_range, (list, tuple)) and len(hist_range) == 2) and hist_range != "each":
        hist_range = "data"  # "full" needs the peak, which the pixels of a report need not know
    try:
        stats = pair_stats(real, sim, bins=bins, hist_range=hist_range, mask=mask, need=("nmi",), nonfinite="mask")
        return stats.joint_histogram()
    except FidelityError as exc:
        return f"no joint histogram: {exc}"


def _ticks(lo: float, hi: float, mid: float | None = None) -> list[tuple[float, str]]:
    mid = (lo + hi) / 2 if mid is None else mid
    span = hi - lo if hi > lo else 1.0
    return [(0.0, f"{lo:.4g}"), ((mid - lo) / span, f"{mid:.4g}"), (1.0, f"{hi:.4g}")]


def _display_note(real: np.ndarray) -> str:
    step = figures.display(real)[1]
    return f" Displayed at every {step}th pixel." if step > 1 else ""


def _frames_section(real, sim, hist) -> Raw:
    title = "Frames"
    if isinstance(hist, str):
        counts_r, edges_r = _histogram(real)
        counts_s, edges_s = _histogram(sim)
    else:
        counts, edges_r, edges_s = hist
        counts_r, counts_s = counts.sum(axis=1), counts.sum(axis=0)
    lo, hi = figures.frame_range(real, sim)
    images = panels([(figures.raster(real, "viridis", lo, hi), "real frame", "real frame"),
                     (figures.raster(sim, "viridis", lo, hi), "simulated frame", "simulated frame")])
    bar = colour_bar(figures.colour_stops("viridis"), _ticks(lo, hi), "grey level (one scale for both frames)")
    hist_png = figures.histograms_figure((counts_r, edges_r, counts_s, edges_s), (lo, hi))
    caption = (f"{real.shape[1]}×{real.shape[0]} pixels, {real.dtype}. Colour scale: the 0.5–99.5th percentiles of "
               "both frames' pixels together (shaded on the histograms); histograms normalised to the pixel count, "
               "on the edges NMI was computed with." + _display_note(real))
    body = images + bar + image(hist_png, "normalised histograms of the real and simulated frames", caption=caption)
    return section(title, body, anchor="frames")


def _difference(real: np.ndarray, sim: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """``sim − real`` as float64, NaN where ``mask`` is False."""
    diff = sim.astype(np.float64) - real.astype(np.float64)
    if mask is not None:
        diff[~mask] = np.nan
    return diff


def _difference_stats(real, sim, mask) -> tuple[int, float, float, float]:
    """Count, mean, RMS and largest magnitude of the finite differences, band by band."""
    count, total, squares, largest = 0, 0.0, 0.0, 0.0
    for band in _bands(*real.shape):
        diff = _difference(real[band], sim[band], None if mask is None else mask[band])
        valid = diff[np.isfinite(diff)]
        if valid.size:
            count += valid.size
            total += float(valid.sum())
            squares += float(np.square(valid).sum())
            largest = max(largest, float(np.abs(valid).max()))
    return count, total / max(count, 1), float(np.sqrt(squares / max(count, 1))), largest


def _difference_section(real, sim, mask) -> Raw:
    count, mean, rms, largest = _difference_stats(real, sim, mask)
    if count == 0:
        return missing("Difference", "no valid pixel pair", anchor="difference")
    shown_mask = None if mask is None else figures.display(mask)[0]
    shown = _difference(figures.display(real)[0], figures.display(sim)[0], shown_mask)
    limit = figures.difference_limit(shown)
    body: str = panels([(figures.raster(shown, "RdBu_r", -limit, limit, shown_from=real.shape),
                    "signed difference simulated minus real", "simulated − real")], single=True)
    body += colour_bar(figures.colour_stops("RdBu_r"), _ticks(-limit, limit, 0.0), "simulated − real (grey levels)")
    caption = (f"Red: simulator brighter, blue: darker; scale ±{limit:.4g} (99.5th percentile of |difference|, "
               f"beyond it the end colours). Mean (bias) {mean:.4g}, RMS {rms:.4g}, "
               f"largest |difference| {largest:.4g}." + _display_note(real))
    if count < real.size:
        caption += f" Grey: {real.size - count} pixels excluded (mask or non-finite)."
    return section("Difference", body + paragraph(caption, cls="caption"), anchor="difference")


def _overlap_crop(real, sim, mask):
    """The frames over the scored pixels ``mask`` (a registration's overlap): cropped to its
    bounding box, with the simulated values of the few pixels inside the box but outside the
    mask (a rotation's corners) taken from the real frame so the windows stay finite, those
    pixels (to blank on the map, None when there are none), and a note for the caption."""
    if mask is None or mask.all() or not mask.any():
        return real, sim, None, ""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    real, sim, inside = real[box], sim[box], mask[box]
    outside = None if inside.all() else ~inside
    if outside is not None:
        sim = np.where(inside, sim, real)
    note = (f" Computed over the scored pixels (the registration's overlap): rows {rows[0]}–{rows[-1]}, "
            f"columns {cols[0]}–{cols[-1]}{'; grey: outside it' if outside is not None else ''}. ")
    return real, sim, outside, note


def _rms_difference(real: np.ndarray, sim: np.ndarray) -> float:
    """RMS of ``sim − real`` over the pixels where both are finite, band by band."""
    total, count = 0.0, 0
    for band in _bands(*real.shape):
        d = sim[band].astype(np.float64) - real[band]
        d = d[np.isfinite(d)]
        total, count = total + float(np.square(d).sum()), count + d.size
    return math.sqrt(total / count) if count else math.nan


def _overlay_section(frames, sim_unregistered) -> Raw:
    """Checkerboards of the real frame with the simulated one before and after registration,
    drawn on the display copies (the page holds no full-size image of its own)."""
    title = "Registration overlay"
    real, after, _ = frames
    try:
        before = _as_frame(sim_unregistered, "sim")
    except FidelityError as exc:
        return missing(title, f"the simulated frame before registration cannot be shown: {exc}", anchor="overlay")
    if before.shape != real.shape:
        return missing(title, f"the simulated frame before registration has shape {before.shape}, the real one "
                              f"{real.shape}", anchor="overlay")
    tile = max(4, min(real.shape) // 8)
    step = figures.display_step(real.shape)
    shown = [np.asarray(f)[::step, ::step].astype(np.float64) for f in (real, before, after)]
    rows, cols = np.indices(shown[0].shape) * step
    board = ((rows // tile + cols // tile) % 2).astype(bool)
    lo, hi = figures.frame_range(real, before)
    images = panels([(figures.raster(np.where(board, shown[1], shown[0]), "viridis", lo, hi, shown_from=real.shape),
                      "checkerboard before", "before registration"),
                     (figures.raster(np.where(board, shown[2], shown[0]), "viridis", lo, hi, shown_from=real.shape),
                      "checkerboard after", "after registration")])
    bar = colour_bar(figures.colour_stops("viridis"), _ticks(lo, hi), "grey level (one scale for both panels)")
    rms = [_rms_difference(real, sim) for sim in (before, after)]
    caption = (f"Tiles of {tile} px alternate between the real frame and the simulated one, as given (left) and "
               f"resampled through the registration (right; grey: outside the overlap). Edges that run on across "
               f"tile borders mean aligned frames. RMS difference simulated − real: {rms[0]:.4g} before, "
               f"{rms[1]:.4g} after (over the overlap)." + _display_note(real))
    return section(title, images + bar + paragraph(caption, cls="caption"), anchor="overlay")


def _ssim_section(d, real, sim, mask, given, peak, max_bytes) -> Raw:
    title = "SSIM map"
    border, extra, shown_from = 5, "", None
    if given is not None:
        values = given.map if isinstance(given, SSIMMap) else np.asarray(given, dtype=np.float64)
        if values.shape != real.shape:
            return missing(title, f"ssim has shape {values.shape}, the frames {real.shape}", anchor="ssim-map")
        if isinstance(given, SSIMMap):
            border = (given.win_size - 1) // 2
            extra = f"Mean (Wang et al. 2004, without the {border}-pixel border) {given.mean:.6g}. "
    else:
        data_range, source = _data_range(d, real, sim, peak)
        real, sim, outside, where = _overlap_crop(real, sim, mask)
        step = figures.display_step(real.shape)
        try:
            m = sampled_ssim_map(real, sim, step, peak=data_range, max_bytes=max_bytes)
        except FidelityError as exc:
            return missing(title, f"the SSIM map cannot be computed: {exc}", anchor="ssim-map")
        values, shown_from = m.map, real.shape
        if outside is not None:
            values = np.where(outside[::step, ::step], np.nan, values)
        extra = (f"Mean SSIM (Wang et al. 2004: 11×11 Gaussian window, σ = 1.5, K = 0.01, 0.03, data range "
                 f"L = {m.peak:g} from {source}; mean without the 5-pixel border) {m.mean:.6g}")
        try:
            extra += f"; MS-SSIM {ms_ssim(real, sim, peak=m.peak, max_bytes=max_bytes):.6g}. "
        except FidelityError as exc:
            extra += f"; MS-SSIM not computed: {exc}. " if "max_bytes" in str(exc) else ". "
        extra += where
    lo = figures.ssim_range(values)
    body: str = panels([(figures.raster(values, "cividis", lo, 1.0, outline=border, shown_from=shown_from),
                    "windowed SSIM map", "local SSIM")], single=True)
    body += colour_bar(figures.colour_stops("cividis"), _ticks(lo, 1.0), "local SSIM (1 = locally identical)")
    caption = (extra + "The paper's component f5 is the global SSIM of the whole frame; this windowed map shows "
               "where the frames differ (dotted: the region the mean covers)." + _display_note(real))
    return section(title, body + paragraph(caption, cls="caption"), anchor="ssim-map")


def _joint_section(hist) -> Raw:
    title = "Joint histogram"
    if isinstance(hist, str):
        return missing(title, hist, anchor="joint-histogram")
    counts, re, se = hist
    png = figures.joint_histogram_figure(counts, re, se)
    caption = (f"{counts.shape[0]}×{counts.shape[1]} bins, {int(counts.sum())} pixel pairs, log colour scale (white: "
               "empty). The NMI component (eqs. 7–10) is computed from these counts; a thin curve means a "
               "one-to-one grey-level relation (NMI near 1), the dashed line is equality.")
    if max(counts.shape) > 256:
        caption += " Displayed summed into at most 256 bins per axis."
    return section(title, image(png, "joint histogram of real and simulated grey levels", caption=caption),
                   anchor="joint-histogram")
