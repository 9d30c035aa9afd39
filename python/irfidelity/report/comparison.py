"""The comparison report of several simulators (:func:`irfidelity.score_simulators`):
:func:`render_comparison_html`, and the one-row-per-simulator table of its CSV
(:func:`comparison_rows`).

The page: one row per simulator (best first) with its grade, the fidelity and every component
side by side with their intervals, and P(first); the order and what decided it (each pair's
difference, its interval and Holm-corrected p-value: significant or not at the stated level);
the order's stability under the frames' sampling and weight changes; the per-frame fidelity of
every simulator on one plot.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..fuzzy import COMPONENTS
from . import figures, sections
from .html import Raw, image, number, page, paragraph, section, table

__all__ = ["render_comparison_html", "comparison_rows", "write_rows", "intervals_section"]

_LINESTYLES = ["-", "--", "-.", ":"]
_MARKERS = ["o", "s", "^", "v", "D", "P", "X"]


def _quantities(ranking: Any) -> list[str]:
    first = ranking.estimate[ranking.order[0]]
    return ["fidelity"] + [q for q in COMPONENTS if q in first]


def _with_interval(value: float, interval: tuple[float, float] | None) -> Raw:
    if interval is None:
        return number(value)
    lo, hi = interval
    return Raw(f"{number(value)} <small>[{number(lo)}, {number(hi)}]</small>")


def comparison_rows(comparison: Any) -> list[dict]:
    """One dict per simulator, best first: ``rank``, ``simulator``, ``grade`` (the overall grade
    of its report), for the fidelity and each component its value and interval (``<q>``,
    ``<q>_lo``, ``<q>_hi``) over the ranked frames, ``p_first`` (stability), and the frames
    scored and failed."""
    ranking = comparison.ranking
    rows = []
    for position, name in enumerate(ranking.order, start=1):
        rep = comparison.reports[name]
        row: dict[str, Any] = {"rank": position, "simulator": name, "grade": rep.grade}
        for q in _quantities(ranking):
            lo, hi = ranking.ci[name][q]
            row.update({q: ranking.estimate[name][q], f"{q}_lo": lo, f"{q}_hi": hi})
        row["p_first"] = None if ranking.stability is None else ranking.stability.p_first[name]
        row["frames_ranked"] = ranking.frames
        row["frames_failed"] = len(rep.failed)
        rows.append(row)
    return rows


def write_rows(rows: list[dict], path: str | os.PathLike) -> None:
    """``rows`` as a CSV file (a header of the first row's keys; None as an empty cell)."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows({k: ("" if v is None else v) for k, v in row.items()} for row in rows)


def _ranking_table(comparison: Any) -> Raw:
    ranking = comparison.ranking
    quantities = _quantities(ranking)
    header = ["rank", "simulator", "grade", *quantities, "P(first)", "failed frames"]
    rows = []
    for position, name in enumerate(ranking.order, start=1):
        rep = comparison.reports[name]
        cells = [_with_interval(ranking.estimate[name][q], ranking.ci[name].get(q)) for q in quantities]
        p_first = None if ranking.stability is None else ranking.stability.p_first[name]
        rows.append([position, name, rep.grade, *cells, p_first, len(rep.failed)])
    caption = (f"Pooled over the {ranking.frames} real frames every simulator scored; in brackets the "
               f"{ranking.level:g} interval of each (block bootstrap over frames, blocks of {ranking.block}, "
               f"{ranking.resamples} resamples). Grade: the simulator's overall grade, as in its own report "
               f"(over every frame it scored). P(first): the share of draws, each a block resample of the "
               f"frames with a weight vector drawn around K, in which the simulator's pooled fidelity is the "
               f"highest.")
    body = table(header, rows) + paragraph(caption, cls="caption")
    if ranking.note is not None:
        body += paragraph(ranking.note, cls="note")
    return section("Ranking", body, anchor="ranking")


def _verdict(a: str, b: str, p: float, significant: bool, level: float, correction: str) -> str:
    how = "Holm-corrected " if correction == "holm" else ""
    if significant:
        return f"{a} is closer than {b}: significant at {level:g} ({how}p = {p:.3g})."
    return (f"{a} scores above {b}, but these frames cannot tell them apart at {level:g} ({how}p = {p:.3g}): "
            f"not significant.")


def _decisions(comparison: Any) -> Raw:
    ranking = comparison.ranking
    quantities = _quantities(ranking)
    adjacent = list(zip(ranking.order, ranking.order[1:]))
    lines = [paragraph(_verdict(a, b, ranking.p_adjusted[(a, b)]["fidelity"], ranking.significant[(a, b)],
                                ranking.level, ranking.correction)) for a, b in adjacent]
    rows = []
    for (a, b), test in ranking.pairs.items():
        lo, hi = test.ci["fidelity"]
        components = [q for q in quantities[1:] if ranking.significance[(a, b)][q]]
        rows.append([f"{a} − {b}", Raw(f"{number(test.difference['fidelity'])} <small>[{number(lo)}, "
                                      f"{number(hi)}]</small>"),
                     test.p_value["fidelity"], ranking.p_adjusted[(a, b)]["fidelity"],
                     "yes" if ranking.significant[(a, b)] else "no", ", ".join(components) or "none"])
    header = ["pair", "fidelity difference", "p", f"p ({ranking.correction})", "significant",
              "components that differ significantly"]
    caption = (f"Every pair on the same resampled blocks of frames (paired bootstrap); p-values adjusted over "
               f"the {len(ranking.pairs)} pairs ({ranking.correction}); significant when the adjusted p is below "
               f"{1 - ranking.level:.3g}. Not significant means these frames cannot tell the two apart, not that "
               f"they are equal.")
    body = "".join(lines) + table(header, rows) + paragraph(caption, cls="caption")
    return section("What decided the order", body, anchor="decisions")


def _stability(comparison: Any) -> Raw:
    stability = comparison.ranking.stability
    if stability is None:
        return Raw("")
    rows = [[name, stability.p_first[name], stability.mean_rank[name]] for name in stability.ranking]
    caption = (f"The order over {stability.samples} draws, each a block resample of the {stability.frames} frames "
               f"(blocks of {stability.block}) with weights drawn around K (Dirichlet, concentration "
               f"{stability.concentration:g}): how often each simulator ranks first, its mean rank. Simulators "
               f"that these frames cannot tell apart share the first place.")
    return section("Stability under the frames' sampling and weight changes",
                   table(["simulator", "P(first)", "mean rank"], rows) + paragraph(caption, cls="caption"),
                   anchor="stability")


def fidelity_curves_figure(series: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> bytes:
    """Per-frame fidelity of every simulator against the frame index, one line style each."""
    fig = figures._figure(10.0, 4.2, left=0.07, right=0.84)
    ax = fig.add_subplot()
    for i, (name, (index, values)) in enumerate(series.items()):
        ax.plot(index, values, label=name, color=figures.PALETTE[i % len(figures.PALETTE)],
                ls=_LINESTYLES[i % len(_LINESTYLES)], marker=_MARKERS[i % len(_MARKERS)],
                markevery=max(1, len(index) // 30), markersize=4, lw=1.2)
    ax.set_xlabel("frame index")
    ax.set_ylabel("fidelity")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return figures._png(fig)


def _curves(comparison: Any) -> Raw:
    series = {}
    for name in comparison.ranking.order:
        scored = [f for f in comparison.reports[name].frames if not f.get("error") and f.get("fidelity") is not None]
        series[name] = (np.array([f["index"] for f in scored]), np.array([f["fidelity"] for f in scored]))
    png = fidelity_curves_figure(series)
    return section("Fidelity frame by frame", image(png, "per-frame fidelity of every simulator",
                                                    caption="Each simulator's fidelity on every frame it scored."),
                   anchor="curves")


def intervals_section(d: Mapping) -> Raw:
    """A sequence report's ``ci`` (its intervals), or nothing when it has none."""
    ci = d.get("ci")
    if not ci:
        return Raw("")
    info = sections.mapping(d.get("pooling") or {}, "ci")
    rows = [[q, *interval] for q, interval in ci.items()]
    caption = (f"Level {info.get('level', '?')}: {info.get('method', 'block bootstrap over frames')}; blocks of "
               f"{info.get('block', '?')} frames, {info.get('resamples', '?')} resamples.")
    body = table(["quantity", "low", "high"], rows) + paragraph(caption, cls="caption")
    if info.get("note"):  # too few frames for honest intervals
        body += paragraph(info["note"], cls="note")
    return section("Intervals", body, anchor="intervals")


def render_comparison_html(comparison: Any, *, title: str | None = None, fragment: bool = False) -> str:
    """One self-contained HTML page comparing the simulators of a
    :class:`~irfidelity.simulators.SimulatorComparison`.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> from irfidelity.report.comparison import render_comparison_html
    >>> rng = np.random.default_rng(0)
    >>> real = rng.integers(1000, 3000, (40, 32, 32)).astype(np.uint16)
    >>> sims = {f"s{k}": (real + rng.integers(0, 10 * k, real.shape)).astype(np.uint16) for k in (1, 4)}
    >>> result = irf.score_simulators(real, sims, peak="range", weights="psnr=0.5,ssim=0.5", progress=False)
    >>> html = render_comparison_html(result)
    >>> "What decided the order" in html and "s1 is closer than s4" in html
    True
    """
    figures.require_matplotlib()
    ranking = comparison.ranking
    subtitle = (f"{len(comparison.reports)} simulators against one real recording, best first: "
                f"{', '.join(ranking.order)}")
    body = [sections.header(title or "Which simulator is closer", subtitle), _ranking_table(comparison),
            _decisions(comparison), _stability(comparison), _curves(comparison)]
    if comparison.notes:
        body.append(section("Notes", "".join(paragraph(n, cls="note") for n in comparison.notes), anchor="notes"))
    first = next(iter(comparison.reports.values()))
    body.append(sections.settings(first.to_dict()))
    return page(title or "irfidelity simulator comparison", "".join(str(b) for b in body), fragment=fragment)
