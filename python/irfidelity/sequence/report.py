"""The report of a whole sequence: :class:`SequenceReport`.

Its top level is the pooled result, with the keys of a single-pair
:class:`~irfidelity.FidelityReport` (``fidelity``, ``grade``, ``components``, ``metrics``,
...); ``frames`` holds one entry per frame pair with the same keys; the CSV has the columns
:func:`irfidelity.schema.csv_columns` names, the same for a single pair.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any, Mapping

from .. import readback
from ..readback import Fields
from ..results import ReportBase, registration_line
from ..schema import csv_columns
from .entry import FrameEntry
from .log import csv_line
from .outcomes import flat_row

__all__ = ["SequenceReport"]


@dataclass(kw_only=True)
class SequenceReport(ReportBase):
    """Fidelity of a whole sequence: pooled, and frame by frame.

    Attributes
    ----------
    fidelity, grade, components, component_grades, membership, metrics
        The pooled result, each component within its frames' values
        (:mod:`irfidelity.sequence.pooling`: PSNR from ΣSSE/ΣN, SSIM and NMI as the
        pixel-weighted means of the frames'), and the curve components, which are the same
        for every frame. None / empty when no frame was scored.
    frames : list of FrameEntry
        One entry per frame pair, in index order (:class:`~irfidelity.sequence.entry.FrameEntry`,
        read as a mapping: ``frames[i]["metrics"]``), with the keys of a single-pair result
        plus ``index``, ``real``, ``sim``, ``rows``, ``cols``, ``dtype`` and ``error`` (None,
        or why the pair could not be scored).
    failed : list of int
        Indices of the frames with an error (not those in ``unpaired``).
    unpaired : list of int
        Indices of the rows of frames that no frame of the other side can pair with: with
        ``config.max_delay``, the frames the delay leaves at the ends. Each is a row with one
        side, no score and the reason in ``error`` ("no simulated frame pairs with it at
        delay +2"), but not a failure. (A frame without a partner by name is in ``failed``:
        a file is missing.)
    frame_stats : dict
        Mean, p5, p50, p95, min and max over the scored frames of ``fidelity``, of each
        component (``frame_stats["components"]``) and of each metric (``["metrics"]``).
    pooling : dict
        ``frames`` (how many were pooled), ``n`` (pixel pairs), and ``"pixel_mean"`` under
        ``nmi`` and ``ssim`` when they are scored.
    weights, skipped, config, version, notes, inputs
        As in :class:`~irfidelity.FidelityReport` (:class:`~irfidelity.results.ReportBase`).
    run : dict
        How the run went: ``pair_by`` (how frames were paired), ``workers``, ``csv``,
        ``resumed`` (frames taken from an earlier run).
    registration : dict or None
        With ``config.register``: the registration found on the first readable pair and
        applied to every pair (as :attr:`FidelityReport.registration`); with ``register_each``, the spread of the frames' own registrations
        (``"each": True``, :func:`~irfidelity.sequence.pooling.registration_summary`; each
        frame's is in ``frames[i]["registration"]``).
    verdict, ceiling, relative
        As in :class:`~irfidelity.results.ReportBase`, for the pooled result; the ceiling is that of
        consecutive real frames (t, t + 1; :func:`irfidelity.ceiling.sequence_ceiling`), or with
        ``real_noise`` the real camera's repeatability (``ceiling_source`` "noise3d").
    delay : dict or None
        With ``config.max_delay``: the frame offset found — ``frames`` (real frame ``i``
        pairs with simulated frame ``i + frames``), ``confidence``, ``window`` (frames of
        each side compared), ``max_delay``, ``correlation`` (per candidate delay) and
        ``unpaired`` (``{"real": [...], "sim": [...]}``: the names of the frames at the ends
        without a partner at this delay; their rows are listed in :attr:`unpaired`).
    ci : dict or None
        With ``score_sequence(ci=...)``: ``{"fidelity": (lo, hi), component: (lo, hi)}``, the
        block-bootstrap intervals over frames (:mod:`irfidelity.sequence.intervals`);
        ``pooling["ci"]`` has their level, method, block length and resamples.

    Examples
    --------
    Three frames whose simulated copies are off by 1, 2 and 3 counts:

    >>> import csv, numpy as np, irfidelity as irf
    >>> ramp = np.arange(64, dtype=np.uint16).reshape(8, 8)     # a scene spanning 63 counts
    >>> real = np.stack([ramp, ramp.T, ramp[::-1]])
    >>> sim = real + np.array([1, 2, 3], dtype=np.uint16)[:, None, None]
    >>> rep = irf.score_sequence(real, sim, bits=14, peak="range", weights="psnr=0.5,ssim=0.5", progress=False)
    >>> len(rep.frames), rep.failed, rep.pooling["frames"], rep.grade
    (3, [], 3, 'good')
    >>> rep.verdict["reason"]
    "good: psnr set the grade — RMS error 3.43 % of the scene's range (2.16 of 63); the tolerance for excellent is 3.2 % of the scene's range"

    The pooled PSNR is that of the merged statistics, MSE = (1 + 4 + 9) / 3, not a mean of
    the frames' PSNRs:

    >>> round(rep.metrics["psnr_db"], 2), round(rep.frame_stats["metrics"]["psnr_db"]["mean"], 2)
    (29.3, 30.8)
    >>> rep.to_csv("frames.csv")                                 # one row per frame
    >>> with open("frames.csv", newline="") as fh:
    ...     [round(float(row["psnr_db"]), 2) for row in csv.DictReader(fh)]
    [35.99, 29.97, 26.44]
    """

    frames: list[FrameEntry]
    failed: list = field(default_factory=list)
    unpaired: list = field(default_factory=list)
    frame_stats: dict = field(default_factory=dict)
    pooling: dict = field(default_factory=dict)
    run: dict = field(default_factory=dict)
    delay: dict | None = None
    ci: dict | None = None

    def __post_init__(self) -> None:
        self.frames = [f if isinstance(f, FrameEntry) else FrameEntry.from_mapping(f) for f in self.frames]

    def to_html(self, path: str | os.PathLike | None = None, *, worst: int = 10,
                max_bytes: int | None = None) -> str:
        """A self-contained HTML report (figures embedded, no network): the pooled verdict, the
        components over time with failed frames marked, the spread of per-frame fidelity, the
        ``worst`` frames (with thumbnails when the frames can still be read), the failures and
        the curves. Written to ``path`` when given; returned either way. Needs matplotlib
        (``irfidelity[report]``). ``max_bytes``: the memory budget of a thumbnail pair."""
        from ..report import write_html

        return write_html(self._render(worst=worst, max_bytes=max_bytes), path)

    def _render(self, *, fragment: bool = False, **options: Any) -> str:
        from ..report import render_sequence_html

        return render_sequence_html(self, frames=self.sources.get("frames"), curves=self.sources.get("curves"),
                                    fragment=fragment, **options)

    @property
    def columns(self) -> list[str]:
        """The CSV columns (as in a single pair's CSV)."""
        return csv_columns(self.weights.active(), registered=self.config.register is not None,
                           temperature=self.config.unit is not None)

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write one row per frame, in index order (the columns of ``csv=``)."""
        cols = self.columns
        with open(path, "w", newline="", encoding="utf-8") as fh:
            fh.write(csv_line(cols))
            fh.writelines(csv_line(flat_row(f, cols)) for f in self.frames)

    def _own_dict(self) -> dict:
        return {"failed": self.failed, "unpaired": self.unpaired, "frame_stats": self.frame_stats,
                "pooling": self.pooling, "run": self.run, "delay": self.delay, "ci": self.ci,
                "frames": [dict(f) for f in self.frames]}

    @classmethod
    def _own_fields(cls, fields: Fields) -> dict[str, Any]:
        own = {"frames": fields.require("frames", readback.list_of(readback.frame)),
               "fidelity": fields.get("fidelity", readback.optional(readback.fraction)),
               "grade": fields.get("grade", readback.optional(readback.text)),
               "failed": fields.get("failed", readback.list_of(readback.count), []),
               "unpaired": fields.get("unpaired", readback.list_of(readback.count), []),
               "frame_stats": fields.get("frame_stats", readback.frame_stats, {}),
               "pooling": fields.get("pooling", readback.mapping_of(readback.anything), {}),
               "run": fields.get("run", readback.mapping_of(readback.anything), {}),
               "registration": fields.get("registration", readback.optional(readback.any_registration)),
               "delay": fields.get("delay", readback.optional(readback.delay)),
               "ci": fields.get("ci", readback.optional(readback.mapping_of(_interval)))}
        if (own["fidelity"] is None) != (own["grade"] is None):
            raise readback.ReportError("report: fidelity and grade are both given (a pooled result) or both "
                                       "null (no frame scored)")
        return own

    def summary_text(self) -> str:
        """A short human-readable summary: pooled table, per-frame spread, failures."""
        n, alone = len(self.frames), len(self.unpaired)
        lonely = f", {alone} without a partner at the delay" if alone else ""
        lines = [f"sequence of {n} frame pairs: {n - len(self.failed) - alone} scored, {len(self.failed)} failed"
                 f"{lonely} (paired by {self.run.get('pair_by', 'order')})"]
        if self.fidelity is not None:
            means = " and ".join(k.upper() for k in ("ssim", "nmi") if self.pooling.get(k) == "pixel_mean")
            lines.append("pooled over the scored frames (PSNR from ΣSSE/ΣN"
                         + (f", {means} as the pixel-weighted mean of the frames')" if means else ")"))
            lines += self._verdict_lines()
        if self.ci:
            info = self.pooling.get("ci", {})
            lines.append(f"intervals at {info.get('level', '?')} ({info.get('method', 'bootstrap')}): "
                         + ", ".join(f"{k} [{lo:.4f}, {hi:.4f}]" for k, (lo, hi) in self.ci.items()))
        spread = [("fidelity", self.frame_stats.get("fidelity"))]
        spread += [(k, self.frame_stats.get("metrics", {}).get(k)) for k in ("psnr_db", "ssim", "nmi")]
        for key, s in spread:
            if s:
                lines.append(f"per frame {key}: mean {s['mean']:.6g}  p5 {s['p5']:.6g}  p50 {s['p50']:.6g}  "
                             f"p95 {s['p95']:.6g}  min {s['min']:.6g}")
        if self.failed:
            shown = ", ".join(str(i) for i in self.failed[:10]) + (", ..." if len(self.failed) > 10 else "")
            lines.append(f"failed frames: {shown}")
            first = next((f for f in self.frames if f.get("index") == self.failed[0]), None)
            if first is not None and first.get("error"):
                lines.append(f"  first error (frame {first['index']}): {first['error']}")
        if self.delay:
            lines.append(_delay_line(self.delay))
        if self.registration:
            applied = "" if self.registration.get("each") else " (found on the first pair, applied to every pair)"
            lines.append(registration_line(self.registration) + applied)
        return "\n".join(lines + self._made_lines())


def _interval(value: Any, where: str) -> tuple[float, float]:
    """An interval ``[lo, hi]`` of ``ci``."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise readback.ReportError(f"{where}: expected an interval [lo, hi], got {value!r}")
    return readback.number(value[0], f"{where}[0]"), readback.number(value[1], f"{where}[1]")


def _delay_line(delay: Mapping[str, Any]) -> str:
    d = int(delay["frames"])
    unpaired = delay.get("unpaired") or {}
    lonely = [f"{len(unpaired[k])} {side}" for k, side in (("real", "real"), ("sim", "simulated")) if unpaired.get(k)]
    pairing = f"real frame i with simulated frame i{d:+d}" if d else "real frame i with simulated frame i"
    text = (f"delay: {d:+d} frames ({pairing}), confidence {delay['confidence']:.3f}, "
            f"searched ±{delay.get('max_delay')} over the first {delay.get('window')} frames")
    if lonely:
        text += f"; {' and '.join(lonely)} frame(s) at the ends have no partner: rows without a score"
    return text
