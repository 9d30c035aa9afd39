"""The report's figures, returned as PNG bytes: plots drawn with matplotlib's object-oriented
API on the Agg canvas (no pyplot, no global backend change: safe inside notebooks), and frame-
sized maps written directly through a colour map (one pixel per displayed value, no axes; the
page draws their colour bars), which costs a fraction of a figure.

Colour-blind-safe choices throughout: viridis for frames and counts, cividis for the SSIM
map, ColorBrewer's diverging RdBu for signed differences, and the Okabe–Ito palette with
distinct line styles and markers for curves, so that no information is carried by hue alone.
Large frames are subsampled for display (every k-th pixel, k chosen so the longer side is at
most ``MAX_SIDE`` pixels); statistics are always computed on the full frames.
"""

from __future__ import annotations

import io
import math
from typing import Any

import numpy as np

from ..errors import FidelityError

__all__ = ["require_matplotlib", "raster", "colour_stops", "frame_range", "histograms_figure", "difference_limit",
           "ssim_range", "joint_histogram_figure", "curves_figure", "timeline_figure", "distribution_figure",
           "thumbnails_figure", "panels_figure", "MAX_SIDE"]

#: Longest side, in pixels, of a frame as displayed.
MAX_SIDE = 480
DPI = 80
# Okabe–Ito: blue, vermillion, bluish green, orange, reddish purple, sky blue, black
PALETTE = ["#0072B2", "#D55E00", "#009E73", "#E69F00", "#CC79A7", "#56B4E9", "#000000"]
REAL_STYLE = {"color": PALETTE[0], "linestyle": "-", "marker": "o"}
SIM_STYLE = {"color": PALETTE[1], "linestyle": "--", "marker": "s"}


def require_matplotlib():
    """matplotlib's ``Figure`` class and Agg canvas, or a clear error naming the extra."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise FidelityError(
            "the HTML report draws its figures with matplotlib, which is not installed: "
            "pip install 'irfidelity[report]'"
        ) from exc
    return Figure, FigureCanvasAgg


def _figure(width: float, height: float, **margins: float):
    """A figure on its own Agg canvas, with fixed margins (a layout engine costs a second draw)."""
    Figure, Canvas = require_matplotlib()
    fig = Figure(figsize=(width, height), dpi=DPI)
    Canvas(fig)
    fig.subplots_adjust(**{"left": 0.09, "right": 0.97, "bottom": 0.13, "top": 0.95, **margins})
    return fig


def _png(fig) -> bytes:
    buf = io.BytesIO()
    # light zlib compression: noisy frames barely compress, and level 1 encodes them faster
    fig.savefig(buf, format="png", dpi=DPI, pil_kwargs={"compress_level": 1})
    return buf.getvalue()


def display(frame: np.ndarray) -> tuple[np.ndarray, int]:
    """``frame`` subsampled so its longer side is at most :data:`MAX_SIDE`, and the step."""
    step = max(1, math.ceil(max(frame.shape) / MAX_SIDE))
    return frame[::step, ::step], step


def _colour_range(*frames: np.ndarray) -> tuple[float, float]:
    """One colour scale for all frames: the 0.5–99.5th percentiles of their pixels together
    (a few hot or dead pixels do not wash out the scene), widened when flat."""
    values = np.concatenate([np.asarray(f, dtype=np.float64).ravel() for f in frames])
    values = values[np.isfinite(values)]
    if values.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(values, [0.5, 99.5])
    if hi <= lo:
        lo, hi = lo - 0.5, hi + 0.5
    return float(lo), float(hi)


def colour_stops(cmap: str, n: int = 9) -> list[str]:
    """``n`` evenly spaced colours of a colour map, as ``#rrggbb`` (for an HTML colour bar)."""
    from matplotlib import colormaps

    rgba = colormaps[cmap](np.linspace(0.0, 1.0, n), bytes=True)
    return [f"#{r:02x}{g:02x}{b:02x}" for r, g, b, _ in rgba]


def raster(values: np.ndarray, cmap: str, lo: float, hi: float, *, outline: int | None = None) -> bytes:
    """``values`` (subsampled for display) through a colour map as a PNG, one pixel per
    displayed value: no axes, so the page can scale it (pixelated) and draw the colour bar.
    NaN is grey; values beyond ``lo``/``hi`` take the end colours. ``outline``: a dotted white
    rectangle ``outline`` frame pixels inside the border (the region an SSIM mean covers)."""
    require_matplotlib()
    from matplotlib import colormaps
    from PIL import Image

    shown, step = display(np.asarray(values, dtype=np.float64))
    scaled = (shown - lo) / (hi - lo if hi > lo else 1.0)
    rgb = colormaps[cmap].with_extremes(bad="#bbbbbb")(np.ma.masked_invalid(scaled), bytes=True)[..., :3]
    if outline is not None:
        rgb = np.ascontiguousarray(rgb)
        top, left = (outline + step - 1) // step, (outline + step - 1) // step
        bottom, right = (values.shape[0] - outline - 1) // step, (values.shape[1] - outline - 1) // step
        if bottom > top and right > left:
            for r in (top, bottom):
                rgb[r, left : right + 1 : 2] = 255
            for c in (left, right):
                rgb[top : bottom + 1 : 2, c] = 255
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb)).save(buf, format="PNG", compress_level=1)
    return buf.getvalue()


def frame_range(*frames: np.ndarray) -> tuple[float, float]:
    """One colour scale for all frames: the 0.5–99.5th percentiles of their displayed pixels
    together (a few hot or dead pixels do not wash out the scene), widened when flat."""
    return _colour_range(*(display(np.asarray(f))[0] for f in frames))


def histograms_figure(histograms: tuple[np.ndarray, ...], shaded: tuple[float, float]) -> bytes:
    """Each frame's normalised histogram, side by side on one grey-level axis, with the span of
    the frames' colour scale shaded. ``histograms``: ``(real_counts, real_edges, sim_counts,
    sim_edges)``."""
    real_counts, real_edges, sim_counts, sim_edges = histograms
    span = (min(real_edges[0], sim_edges[0]), max(real_edges[-1], sim_edges[-1]))
    fig = _figure(9.0, 2.4, left=0.08, right=0.98, bottom=0.2, top=0.88)
    for col, (name, counts, edges, style) in enumerate(
        [("real", real_counts, real_edges, REAL_STYLE), ("simulated", sim_counts, sim_edges, SIM_STYLE)]
    ):
        ax = fig.add_subplot(1, 2, col + 1)
        total = max(int(np.sum(counts)), 1)
        ax.stairs(np.asarray(counts) / total, edges, color=style["color"], fill=True, alpha=0.8)
        ax.set_title(f"{name} frame", fontsize="medium")
        ax.set_xlabel("grey level")
        ax.set_ylabel("fraction of pixels")
        ax.axvspan(*shaded, color="#999999", alpha=0.15, lw=0)
        if span[1] > span[0]:
            ax.set_xlim(*span)
    return _png(fig)


def difference_limit(diff: np.ndarray) -> float:
    """The symmetric scale of a signed difference: the 99.5th percentile of |difference|."""
    shown, _ = display(diff)
    finite = np.abs(shown[np.isfinite(shown)])
    limit = float(np.percentile(finite, 99.5)) if finite.size else 1.0
    return limit if limit > 0 else 1.0


def ssim_range(ssim: np.ndarray) -> float:
    """The low end of the SSIM map's scale: its lowest displayed value (the top is 1)."""
    shown, _ = display(ssim)
    lo = float(np.nanmin(shown)) if np.isfinite(shown).any() else 0.0
    return max(lo, -1.0) if lo < 1.0 else 0.0


def coarsen(counts: np.ndarray, real_edges: np.ndarray, sim_edges: np.ndarray, max_bins: int = 256):
    """A joint histogram summed into at most ``max_bins`` bins per axis (for display)."""
    out, edges = counts, [np.asarray(real_edges), np.asarray(sim_edges)]
    for axis in (0, 1):
        n = out.shape[axis]
        factor = math.ceil(n / max_bins)
        if factor > 1:
            pad = (-n) % factor
            widths = [(0, 0), (0, 0)]
            widths[axis] = (0, pad)
            padded = np.pad(out, widths)
            shape = list(padded.shape)
            shape[axis : axis + 1] = [shape[axis] // factor, factor]
            out = padded.reshape(shape).sum(axis=axis + 1)
            e = edges[axis]
            edges[axis] = np.append(e[:-1:factor], e[-1])
    return out, edges[0], edges[1]


def joint_histogram_figure(counts: np.ndarray, real_edges: np.ndarray, sim_edges: np.ndarray) -> bytes:
    """Joint histogram, log colour scale (empty bins white), with the identity line. Bins are
    drawn as an image over the edges' extent (edges of one binning are uniform)."""
    from matplotlib.colors import LogNorm

    counts, real_edges, sim_edges = coarsen(counts, real_edges, sim_edges)
    fig = _figure(6.4, 5.0, left=0.14, right=0.98, bottom=0.11)
    ax = fig.add_subplot()
    shown = np.ma.masked_equal(counts.T.astype(np.float64), 0.0)  # x = real, y = simulated
    top = float(max(counts.max(), 2))
    extent = (float(real_edges[0]), float(real_edges[-1]), float(sim_edges[0]), float(sim_edges[-1]))
    if extent[1] <= extent[0] or extent[3] <= extent[2]:  # one-value range: unit cells
        extent = (extent[0] - 0.5, extent[0] + 0.5, extent[2] - 0.5, extent[2] + 0.5)
    mesh = ax.imshow(shown, origin="lower", extent=extent, aspect="auto", interpolation="nearest", cmap="viridis",
                     norm=LogNorm(vmin=1.0, vmax=top))
    lo, hi = max(extent[0], extent[2]), min(extent[1], extent[3])
    if hi > lo:
        ax.plot([lo, hi], [lo, hi], color="#000000", ls="--", lw=0.8, label="simulated = real")
        ax.legend(loc="upper left", fontsize="small")
    ax.set_xlabel("real grey level")
    ax.set_ylabel("simulated grey level")
    fig.colorbar(mesh, ax=ax, label="pixel pairs (log scale)")
    return _png(fig)


def curves_figure(kind: str, curves: list[dict[str, Any]], *, x_label: str, y_label: str) -> bytes:
    """Curves overlaid. Each entry: ``name``, ``x``, ``y``, ``style`` and optionally
    ``mark`` (MTF50: ``(x, 0.5)``) or ``fit`` (SiTF: ``(slope, intercept, lo, hi)``)."""
    fig = _figure(7.0, 4.2, left=0.12)
    ax = fig.add_subplot()
    for c in curves:
        style = dict(c["style"])
        ax.plot(c["x"], c["y"], label=c["name"], markersize=3, lw=1.4, **style)
        if c.get("mark") is not None:
            mx, my = c["mark"]
            ax.axvline(mx, color=style["color"], ls=":", lw=1)
            ax.plot([mx], [my], marker="D", color=style["color"], markersize=8, mec="black", ls="none",
                    label=f"MTF50 {c['name']}: {mx:.4g}")
        if c.get("fit") is not None:
            slope, intercept, lo, hi = c["fit"]
            xs = np.array([lo, hi])
            ax.plot(xs, slope * xs + intercept, color=style["color"], lw=6, alpha=0.35, solid_capstyle="butt",
                    label=f"linear fit {c['name']}: slope {slope:.4g}")
    if kind == "mtf":
        ax.axhline(0.5, color="#777777", lw=0.8, ls="-.")
    if kind == "noise":  # power spectra span decades; zero-power bins are left out
        ax.set_yscale("log", nonpositive="mask")
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return _png(fig)


def timeline_figure(index: np.ndarray, series: dict[str, np.ndarray], failed: np.ndarray) -> bytes:
    """Per-frame components and fidelity against the frame index; failed frames as marks
    along the bottom (and thin vertical lines)."""
    fig = _figure(10.0, 4.2, left=0.07, right=0.84)
    ax = fig.add_subplot()
    markers = ["o", "s", "^", "v", "D", "P", "X"]
    styles = ["-", "--", "-.", ":", "-", "--", "-."]
    every = max(1, len(index) // 40)
    for i, (name, values) in enumerate(series.items()):
        is_fid = name == "fidelity"
        ax.plot(index, values, label=name, color="#000000" if is_fid else PALETTE[i % 6],
                ls="-" if is_fid else styles[i % len(styles)], lw=2.0 if is_fid else 1.1,
                marker=None if is_fid else markers[i % len(markers)], markevery=every, markersize=4)
    if len(failed):
        ax.vlines(failed, 0.0, 1.0, transform=ax.get_xaxis_transform(), color=PALETTE[4], lw=0.6, alpha=0.5)
        ax.plot(failed, np.full(len(failed), 0.0), ls="none", marker="x", color=PALETTE[4], markersize=7,
                transform=ax.get_xaxis_transform(), clip_on=False, label=f"failed ({len(failed)})")
    ax.set_xlabel("frame index")
    ax.set_ylabel("component / fidelity")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return _png(fig)


def delay_figure(delays: np.ndarray, correlation: np.ndarray, best: int) -> bytes:
    """|correlation| of the two sequences' changes at each candidate delay; the delay found
    marked."""
    fig = _figure(7.0, 3.4)
    ax = fig.add_subplot()
    ax.bar(delays, correlation, color=[PALETTE[1] if d == best else PALETTE[0] for d in delays], width=0.7)
    ax.set_xticks(delays)
    ax.set_xlabel("delay d (real frame i with simulated frame i + d)")
    ax.set_ylabel("|correlation| of the changes")
    ax.grid(True, axis="y", alpha=0.3)
    return _png(fig)


def registration_figure(index: np.ndarray, series: dict[str, np.ndarray]) -> bytes:
    """Each frame's registration parameters (one panel each) against the frame index."""
    fig = _figure(10.0, 1.6 + 1.3 * len(series), left=0.09)
    axes = fig.subplots(len(series), 1, sharex=True, squeeze=False)[:, 0]
    for i, (ax, (name, values)) in enumerate(zip(axes, series.items())):
        ax.plot(index, values, color=PALETTE[i % 6], marker="o", markersize=3, lw=1.0)
        ax.set_ylabel(name, fontsize="small")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("frame index")
    return _png(fig)


def distribution_figure(values: np.ndarray) -> bytes:
    """Histogram of per-frame fidelity with its 5th, 50th and 95th percentiles."""
    fig = _figure(7.0, 3.6)
    ax = fig.add_subplot()
    bins = min(50, max(5, int(np.sqrt(len(values))) * 2))
    ax.hist(values, bins=bins, color=PALETTE[0], alpha=0.85, edgecolor="white")
    for q, ls in zip((5, 50, 95), (":", "-", ":")):
        v = float(np.percentile(values, q))
        ax.axvline(v, color="#000000", ls=ls, lw=1.2, label=f"p{q} = {v:.4g}")
    ax.set_xlabel("per-frame fidelity")
    ax.set_ylabel("frames")
    ax.legend(fontsize="small")
    return _png(fig)


def thumbnails_figure(rows: list[tuple[str, np.ndarray, np.ndarray]]) -> bytes:
    """Real, simulated and difference thumbnails of a few frames, one row each."""
    fig = _figure(9.0, 2.4 * len(rows), left=0.01, right=0.99, bottom=0.02, top=0.92)
    from matplotlib import colormaps

    cmap = colormaps["RdBu_r"]
    for i, (label, real, sim) in enumerate(rows):
        r, _ = display(np.asarray(real, dtype=np.float64))
        s, _ = display(np.asarray(sim, dtype=np.float64))
        lo, hi = _colour_range(r, s)
        d = s - r
        lim = float(np.nanmax(np.abs(d))) or 1.0
        for j, (img, title, kwargs) in enumerate([
            (r, "real", {"cmap": "viridis", "vmin": lo, "vmax": hi}),
            (s, "simulated", {"cmap": "viridis", "vmin": lo, "vmax": hi}),
            (d, "simulated − real", {"cmap": cmap, "vmin": -lim, "vmax": lim}),
        ]):
            ax = fig.add_subplot(len(rows), 3, 3 * i + j + 1)
            ax.imshow(img, interpolation="nearest", **kwargs)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{label}: {title}" if j == 0 else title, fontsize="small")
    return _png(fig)


def panels_figure(panels: list[dict[str, Any]], *, x_label: str) -> bytes:
    """Curves overlaid in side-by-side panels. Each panel: ``title``, ``y_label``, ``log`` (a
    logarithmic y axis) and ``curves``, entries as in :func:`curves_figure` (``name``, ``x``,
    ``y``, ``style``)."""
    fig = _figure(4.2 * len(panels), 4.0, left=0.06, right=0.99, bottom=0.14, top=0.92, wspace=0.3)
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    for ax, panel in zip(axes, panels):
        for c in panel["curves"]:
            ax.plot(c["x"], c["y"], label=c["name"], markersize=3, lw=1.4, **c["style"])
        if panel.get("log"):
            ax.set_yscale("log", nonpositive="mask")
        ax.set_title(panel["title"], fontsize="medium")
        ax.set_xlabel(x_label)
        ax.set_ylabel(panel["y_label"])
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    return _png(fig)
