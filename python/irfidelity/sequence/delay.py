"""The frame offset between two sequences (``max_delay``): which simulated frame shows what a
real frame shows.

A simulation started a few frames early or late pairs every real frame with the wrong
simulated one, and PSNR, NMI and SSIM then measure the scene's motion, not the simulator. The
delay ``d`` in ``[-max_delay, max_delay]`` (real frame ``i`` shows what simulated frame
``i + d`` shows) is the one at which the two sequences *change* alike:

1. the first frames of each side (:func:`window_length`) are reduced to thumbnails — means
   of square blocks, at most :data:`THUMBNAIL` pixels on the long side, so that a
   displacement of a few pixels (a registration's worth) hardly matters; a frame thinner
   than a block (a line-scan frame of 1 × N) is averaged across its whole thickness — each
   standardised (zero mean, unit variance: gain and offset do not matter either). Frames
   whose thumbnails have fewer than :data:`MIN_PIXELS` pixels are refused: standardising
   leaves them too little to compare;
2. each side's changes: the differences of consecutive thumbnails. The static scene, which
   would match at every delay, goes, and so does a slow drift (a camera's gain control),
   which would match at neighbouring delays; what moves stays;
3. for each candidate ``d``, the correlation of the real changes with the simulated ones
   ``i + d`` over the frames both have; its magnitude (inverted grey levels correlate
   negatively) peaks at the delay.

The confidence is ``1 − (best rival)/(best)``, the rival being the best delay more than one
frame from the best (a scene moving steadily changes alike at neighbouring delays). A
sequence too still to show a delay, or an ambiguous match, is an error naming why; an unsure
one a warning. Still means the best correlation stands less than :data:`NOISE_FLOOR` times
above the others: above their RMS (delays more than a frame from the best; what unrelated
changes give), and above 1/√values (what white noise gives). A still scene has no delay to
find, and pairing it at any delay scores the same.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import FidelityError, FidelityWarning
from ..frames import FrameSequence

__all__ = ["Delay", "find_delay", "window_length", "THUMBNAIL", "WINDOW", "MIN_PAIRS", "MIN_PIXELS"]

#: Longest side of the thumbnails compared, in pixels.
THUMBNAIL = 64
#: Frames beyond the largest delay that every candidate delay is compared over.
WINDOW = 32
#: Fewest frame pairs a candidate delay must be compared over.
MIN_PAIRS = 4
#: Fewest pixels of a thumbnail (standardising takes two degrees of freedom: offset and gain).
MIN_PIXELS = 4
#: The best correlation must stand this many times above what unrelated changes give.
NOISE_FLOOR = 3.0
#: Below this confidence the delay is refused as ambiguous; below UNSURE it warns.
AMBIGUOUS = 0.1
UNSURE = 0.3


@dataclass(frozen=True)
class Delay:
    """The frame offset found: real frame ``i`` pairs with simulated frame ``i + frames``."""

    frames: int
    confidence: float
    correlation: dict[int, float]  # |correlation of the changes| per candidate delay compared
    window: int  # frames of each side compared
    max_delay: int  # the search range asked for

    def to_dict(self) -> dict:
        return {"frames": self.frames, "confidence": self.confidence, "window": self.window,
                "max_delay": self.max_delay,
                "correlation": {str(d): c for d, c in sorted(self.correlation.items())}}


def window_length(max_delay: int, n_real: int, n_sim: int) -> int:
    """Frames of each side compared: every candidate delay then spans ``WINDOW`` frames, or
    all the frames of the shorter sequence."""
    return min(n_real, n_sim, 2 * max_delay + WINDOW)


def _thumbnail(frame: np.ndarray, which: str) -> np.ndarray:
    """Block means (at most THUMBNAIL px on the long side; a block spans the whole of a
    thinner side), standardised; non-finite pixels take the frame's finite mean. A
    FidelityError when the thumbnail has fewer than MIN_PIXELS pixels."""
    f = np.asarray(frame, dtype=np.float64)
    size = max(1, math.ceil(max(f.shape) / THUMBNAIL)) if f.size else 1
    block = (min(size, f.shape[0]), min(size, f.shape[1]))
    if f.size == 0 or (f.shape[0] // block[0]) * (f.shape[1] // block[1]) < MIN_PIXELS:
        raise FidelityError(f"cannot search the delay: the {which} frames of {f.shape[0]} x {f.shape[1]} pixels are "
                            f"too small to compare (the search needs thumbnails of at least {MIN_PIXELS} pixels: "
                            f"their offset and gain are taken out); pair the frames without max_delay",
                            option="max_delay")
    finite = np.isfinite(f)
    if not finite.all():
        f = np.where(finite, f, f[finite].mean() if finite.any() else 0.0)
    rows, cols = (f.shape[0] // block[0]) * block[0], (f.shape[1] // block[1]) * block[1]
    t = f[:rows, :cols].reshape(rows // block[0], block[0], cols // block[1], block[1]).mean(axis=(1, 3))
    std = t.std()
    return (t - t.mean()) / std if std > 0 else np.zeros_like(t)


def _changes(seq: FrameSequence, count: int, which: str) -> list[np.ndarray | None]:
    """The changes of the first ``count`` frames: differences of consecutive standardised
    thumbnails (None where either frame does not decode)."""
    thumbs: list[np.ndarray | None] = []
    for i in range(count):
        try:
            frame = seq[i]
        except FidelityError:
            thumbs.append(None)
            continue
        thumbs.append(_thumbnail(frame, which))
    shapes = {t.shape for t in thumbs if t is not None}
    if len(shapes) > 1:
        raise FidelityError(f"cannot search the delay: the {which} frames differ in shape", option="max_delay")
    if not any(t is not None for t in thumbs):
        raise FidelityError(f"cannot search the delay: none of the first {count} {which} frames can be read",
                            option="max_delay")
    return [None if a is None or b is None else b - a for a, b in zip(thumbs, thumbs[1:])]


def _correlation(real: list, sim: list, d: int) -> tuple[float, int]:
    """|correlation| of real[i] with sim[i + d] over the pairs both sides have (NaN for fewer
    than MIN_PAIRS), and how many values it compared."""
    pairs = [(r, sim[i + d]) for i, r in enumerate(real)
             if r is not None and 0 <= i + d < len(sim) and sim[i + d] is not None]
    if len(pairs) < MIN_PAIRS:
        return math.nan, 0
    dot = sum(float(np.vdot(r, s)) for r, s in pairs)
    norm = math.sqrt(sum(float(np.vdot(r, r)) for r, _ in pairs) * sum(float(np.vdot(s, s)) for _, s in pairs))
    return (abs(dot) / norm if norm > 0 else 0.0), sum(r.size for r, _ in pairs)


def find_delay(real: FrameSequence, sim: FrameSequence, max_delay: int) -> Delay:
    """The delay in ``[-max_delay, max_delay]`` at which the sequences change alike (module notes)."""
    count = window_length(max_delay, len(real), len(sim))
    if count - 1 - max_delay < MIN_PAIRS:
        raise FidelityError(f"max_delay {max_delay} is too large for sequences of {len(real)} and {len(sim)} "
                            f"frames: every delay must leave at least {MIN_PAIRS} frame pairs to compare (at most "
                            f"{max(count - 1 - MIN_PAIRS, 0)} here)", option="max_delay")
    real_changes, sim_changes = _changes(real, count, "real"), _changes(sim, count, "simulated")
    shapes = {c.shape for c in real_changes + sim_changes if c is not None}
    if len(shapes) > 1:
        raise FidelityError("cannot search the delay: the real and simulated frames differ in shape",
                            option="max_delay")
    found = {d: _correlation(real_changes, sim_changes, d) for d in range(-max_delay, max_delay + 1)}
    scored = {d: c for d, (c, _) in found.items() if not math.isnan(c)}
    if not scored:
        raise FidelityError(f"cannot search the delay: fewer than {MIN_PAIRS} readable frame pairs at every delay",
                            option="max_delay")
    best = max(scored, key=lambda d: scored[d])
    rival = max((c for d, c in scored.items() if abs(d - best) > 1), default=0.0)
    peak = scored[best]
    confidence = min(1.0, max(0.0, 1.0 - rival / peak)) if peak > 0 else 0.0
    delay = Delay(best, confidence, scored, count, max_delay)
    others = [c for d, c in scored.items() if abs(d - best) > 1]
    unrelated = max(math.sqrt(np.mean(np.square(others))) if others else 0.0, 1.0 / math.sqrt(found[best][1]))
    _check(delay, count, NOISE_FLOOR * unrelated)
    return delay


def _check(delay: Delay, count: int, noise: float) -> None:
    best = delay.correlation[delay.frames]
    still = best < noise
    if still or delay.confidence < AMBIGUOUS:
        why = ("match almost as well at another delay" if delay.confidence < AMBIGUOUS
               else "change too little: their changes correlate at no delay clearly more than at the others")
        raise FidelityError(
            f"cannot find the delay: over their first {count} frames the sequences {why} (best |correlation| of the "
            f"changes {best:.3f} at delay {delay.frames:+d}, confidence {delay.confidence:.3f}); a still scene or a "
            f"periodic motion shows no delay — pair the frames without max_delay", option="max_delay")
    if delay.confidence < UNSURE:
        warnings.warn(FidelityWarning(
            f"unsure delay: {delay.frames:+d} frames with confidence {delay.confidence:.3f} < {UNSURE} (another "
            f"delay matches nearly as well); check report.delay['correlation']"), stacklevel=3)
