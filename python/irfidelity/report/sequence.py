"""The sequence report: :func:`render_sequence_html`. One figure for the whole sequence (no
per-frame figures), so a 1000-frame report costs about what a single pair does; the
thumbnails keep display-size copies of the frames they load, one pair at a time."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .. import budget
from ..errors import FidelityError
from . import alignment, figures, sections
from .comparison import intervals_section
from .bars import bars as bars_section
from .noise import noise as noise_section
from .html import Missing, Raw, image, key_values, missing, number, page, paragraph, section, table, text

__all__ = ["render_sequence_html"]

#: Failed frames listed in full; the rest are counted.
MAX_FAILED_ROWS = 100


def render_sequence_html(
    report: Any,
    *,
    worst: int = 10,
    frames: Callable[[int], tuple[Any, Any]] | None = None,
    thumbnails: int = 3,
    curves: Mapping[str, Any] | None = None,
    title: str | None = None,
    fragment: bool = False,
    max_bytes: int | None = None,
) -> str:
    """One self-contained HTML page (or a ``<div>`` for notebooks) for a scored sequence.

    Parameters
    ----------
    report : dict or object with ``to_dict()``
        The JSON-ready report (``SequenceReport.to_dict()``): ``frames`` (one dict per frame
        with ``index``, ``real``, ``sim``, ``fidelity``, ``components`` or ``f_<name>`` values,
        raw metrics and ``error``), ``pooled``, ``failed``, ``frame_stats``, ``weights``,
        ``skipped``, ``settings``, ``curves``. Every key is optional: a section whose data is
        missing is replaced by a note.
    worst : int
        Rows of the worst-frames table (lowest fidelity first).
    frames : callable, optional
        ``frames(index) -> (real, sim)``: loads a frame pair, to show thumbnails of the
        ``thumbnails`` worst frames. Without it the table alone is shown.
    curves : mapping, optional
        The camera curves, as for :func:`render_pair_html`.
    title : str, optional
    fragment : bool
        Return a ``<div>`` (styles scoped to it) instead of a whole document.
    max_bytes : int, optional
        The memory budget of a thumbnail pair (default
        :data:`irfidelity.budget.DEFAULT_MAX_BYTES`): each pair loaded must fit it (else the
        thumbnails are left out with the reason); only display-size copies are kept.

    Returns
    -------
    str
        Self-contained HTML (embedded PNGs, inline styles, no script, a Content-Security-Policy
        that forbids any network fetch).

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> from irfidelity.report import render_sequence_html
    >>> rng = np.random.default_rng(0)
    >>> real = rng.integers(1000, 3000, size=(30, 64, 80), dtype=np.uint16)
    >>> sim = (real + rng.integers(0, 40, size=real.shape)).astype(np.uint16)
    >>> seq = irf.score_sequence(real, sim, bits=14, progress=False)
    >>> page = render_sequence_html(seq.to_dict(), worst=3, frames=lambda i: (real[i], sim[i]))
    >>> "Worst frames" in page and "Not shown: every frame was scored" in page
    True

    References
    ----------
    .. [1] Acta Photonica Sinica 41(5):547 (2012), doi:10.3788/gzxb20124105.0547 (components and
       eq. 15, per frame).
    """
    d = sections.as_dict(report)
    figures.require_matplotlib()
    rows = [dict(f) for f in d.get("frames") or () if isinstance(f, Mapping)]
    # the pooled result is the report's top level (the keys of a single pair's report)
    pooled = {k: d[k] for k in _POOLED if d.get(k) is not None}
    verdict_source = {**pooled, "weights": d.get("weights"), "skipped": d.get("skipped"),
                      "metrics": sections.mapping(d, "metrics")}
    curves = dict(curves or {})
    curve_metrics = sections.mapping(d, "metrics")
    body = [
        sections.header(title or "Sequence fidelity report", _subtitle(d, rows)),
        sections.verdict(pooled, label="Pooled fidelity") if pooled else
        missing("Verdict", "the report has no pooled result", anchor="verdict"),
        sections.components(verdict_source) if pooled else
        missing("Components", "the report has no pooled result", anchor="components"),
        intervals_section(d),
        _timeline(d, rows),
        _distribution(rows),
        _worst(rows, worst, frames, thumbnails, max_bytes),
        _failed(d, rows),
        _frame_stats(d),
        alignment.delay(d),
        alignment.registration(d, rows),
        sections.mtf(curves, curve_metrics),
        sections.sitf(curves, curve_metrics),
        noise_section(curves, curve_metrics),
        bars_section(curves, curve_metrics),
        sections.settings(d),
    ]
    body.append(sections.footer([b.title for b in body if isinstance(b, Missing)]))
    return page(title or "irfidelity sequence report", "".join(body), fragment=fragment)


#: Keys of the pooled result at a sequence report's top level.
_POOLED = ("fidelity", "grade", "components", "component_grades", "membership", "verdict", "ceiling", "relative")


def _subtitle(d: Mapping, rows: list[dict]) -> str:
    failed = _failed_indices(d, rows)
    return f"{len(rows)} frame pairs: {len(rows) - len(failed)} scored, {len(failed)} failed"


def _index(row: Mapping, position: int) -> int:
    v = row.get("index")
    return int(v) if isinstance(v, (int, np.integer)) and not isinstance(v, bool) else position


def _unpaired(d: Mapping) -> set[int]:
    """Rows of frames without a partner at the delay: not failures."""
    listed = d.get("unpaired")
    if not isinstance(listed, (list, tuple)):
        return set()
    return {int(i) for i in listed if isinstance(i, (int, np.integer)) and not isinstance(i, bool)}


def _failed_indices(d: Mapping, rows: list[dict]) -> list[int]:
    alone = _unpaired(d)
    from_rows = [_index(r, i) for i, r in enumerate(rows) if r.get("error") and _index(r, i) not in alone]
    listed = d.get("failed")
    if isinstance(listed, (list, tuple)):
        from_rows = sorted(set(from_rows) | {int(i) for i in listed if isinstance(i, (int, np.integer))})
    return from_rows


def frame_components(row: Mapping) -> dict[str, float]:
    """A frame's components: its ``components`` mapping and any ``f_<name>`` values."""
    out: dict[str, Any] = {}
    comps = row.get("components")
    if isinstance(comps, Mapping):
        out.update(comps)
    for k, v in row.items():
        if isinstance(k, str) and k.startswith("f_") and k[2:] not in out:
            out[k[2:]] = v
    return {k: f for k, v in out.items() if (f := sections.as_float(v)) is not None}


def _series(rows: list[dict]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    index = np.array([_index(r, i) for i, r in enumerate(rows)], dtype=np.int64)
    comps = [frame_components(r) if not r.get("error") else {} for r in rows]
    names = sections.component_names(*comps)
    series = {n: np.array([c.get(n, np.nan) for c in comps], dtype=np.float64) for n in names}
    fid = [sections.as_float(r.get("fidelity")) if not r.get("error") else None for r in rows]
    series["fidelity"] = np.array([np.nan if v is None else v for v in fid], dtype=np.float64)
    return index, series


def _timeline(d: Mapping, rows: list[dict]) -> Raw:
    title = "Components over the sequence"
    if not rows:
        return missing(title, "the report lists no frames", anchor="timeline")
    index, series = _series(rows)
    if not any(np.isfinite(v).any() for v in series.values()):
        return missing(title, "no frame was scored", anchor="timeline")
    order = np.argsort(index, kind="stable")
    failed = np.array(_failed_indices(d, rows), dtype=np.int64)
    png = figures.timeline_figure(index[order], {k: v[order] for k, v in series.items()}, np.sort(failed))
    caption = ("Per-frame components f and fidelity (black) against the frame index; "
               f"{len(failed)} failed frames marked × (and a thin line) at the bottom.")
    return section(title, image(png, "per-frame components and fidelity over the sequence", caption=caption),
                   anchor="timeline")


def _distribution(rows: list[dict]) -> Raw:
    title = "Distribution of per-frame fidelity"
    _, series = _series(rows) if rows else (None, {"fidelity": np.array([])})
    values = series["fidelity"][np.isfinite(series["fidelity"])]
    if values.size == 0:
        return missing(title, "no per-frame fidelity", anchor="distribution")
    png = figures.distribution_figure(values)
    caption = (f"{values.size} scored frames: mean {values.mean():.4g}, min {values.min():.4g}, "
               f"max {values.max():.4g}.")
    return section(title, image(png, "histogram of per-frame fidelity", caption=caption), anchor="distribution")


def _worst(rows: list[dict], worst: int, load: Callable | None, thumbnails: int, max_bytes: int | None) -> Raw:
    title = "Worst frames"
    fidelities = [(sections.as_float(r.get("fidelity")), i) for i, r in enumerate(rows) if not r.get("error")]
    scored = [(f, i) for f, i in fidelities if f is not None and np.isfinite(f)]
    if not scored or worst < 1:
        return missing(title, "no per-frame fidelity", anchor="worst")
    scored.sort(key=lambda p: p[0])
    picked = [rows[i] for _, i in scored[:worst]]
    names = sections.component_names(*(frame_components(r) for r in picked))
    extra = [k for k in ("psnr_db", "ssim", "nmi") if any(k in sections.mapping(r, "metrics") for r in picked)]
    header = ["index", "real", "sim", "fidelity", *(f"f {n}" for n in names), *extra]
    body_rows = []
    for pos, r in enumerate(picked):
        comps = frame_components(r)
        body_rows.append([_index(r, pos), r.get("real"), r.get("sim"), r.get("fidelity"),
                          *(comps.get(n) for n in names), *(sections.mapping(r, "metrics").get(k) for k in extra)])
    body: str = table(header, body_rows)
    if load is not None and thumbnails > 0:
        body += _thumbnails(picked[:thumbnails], load, max_bytes)
    return section(title, body, anchor="worst")


def _thumbnails(picked: list[dict], load: Callable, max_bytes: int | None) -> Raw:
    shown = []
    for pos, r in enumerate(picked):
        i = _index(r, pos)
        try:
            real, sim = (np.asarray(f) for f in load(i))
            if real.ndim != 2 or real.shape != sim.shape:
                raise FidelityError(f"frames of shapes {real.shape} and {sim.shape}")
            budget.check("a thumbnail pair", real.shape, budget.nbytes(real, sim), max_bytes)
            real, sim = (figures.display(f)[0].astype(np.float64) for f in (real, sim))
        except (FidelityError, OSError, ValueError, TypeError, IndexError, KeyError) as exc:
            return paragraph(f"Thumbnails not shown: frame {i} could not be loaded ({exc}).", cls="note")
        shown.append((f"frame {i}", real, sim))
    return image(figures.thumbnails_figure(shown), "worst frames: real, simulated and difference",
                 caption="Each row: real and simulated frame on one colour scale, and their signed difference.")


def _failed(d: Mapping, rows: list[dict]) -> Raw:
    title = "Failed frames"
    alone = _unpaired(d)
    errs = [(_index(r, i), r) for i, r in enumerate(rows) if r.get("error") and _index(r, i) not in alone]
    indices = _failed_indices(d, rows)
    if not indices:
        return missing(title, "every frame was scored" if rows else "the report lists no frames", anchor="failed")
    body_rows = [[i, r.get("real"), r.get("sim"), r.get("error")] for i, r in errs[:MAX_FAILED_ROWS]]
    body: str = paragraph(f"{len(indices)} frames could not be scored; every other frame was.")
    body += table(["index", "real", "sim", "error"], body_rows)
    if len(errs) > MAX_FAILED_ROWS:
        body += paragraph(f"… and {len(errs) - MAX_FAILED_ROWS} more (see the CSV's error column).")
    elif not errs:
        body += paragraph("Indices: " + ", ".join(str(i) for i in indices))
    return section(title, Raw(body), anchor="failed")


def _frame_stats(d: Mapping) -> Raw:
    title = "Per-frame statistics"
    nested = sections.mapping(d, "frame_stats")
    stats: dict[str, Any] = {"fidelity": nested.get("fidelity")} if isinstance(nested.get("fidelity"), Mapping) else {}
    stats.update({f"f {k}": v for k, v in sections.mapping(nested, "components").items()})
    stats.update(sections.mapping(nested, "metrics"))
    if not stats:
        return missing(title, "the report has no frame_stats", anchor="frame-stats")
    if all(isinstance(v, Mapping) for v in stats.values()):
        columns = list(dict.fromkeys(k for v in stats.values() for k in v))
        rows = [[Raw(f"<b>{text(name)}</b>"), *(number(dict(v).get(c), 5) for c in columns)]
                for name, v in stats.items()]
        body = table(["quantity", *columns], rows)
    else:
        body = key_values(stats, header=("quantity", "value"))
    return section(title, body, anchor="frame-stats")
