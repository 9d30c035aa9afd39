"""The sequence report's alignment sections: the frame delay found (``max_delay``) with the
correlation at every candidate, and the registration — the one applied to every pair, or,
with ``register_each``, each frame's transform and confidence over the sequence."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from . import figures, sections
from .html import Raw, image, key_values, missing, paragraph, section

__all__ = ["delay", "registration"]


def delay(d: Mapping) -> Raw:
    """The frame offset between the sequences and how distinct it was."""
    title = "Frame delay"
    found = d.get("delay")
    if not isinstance(found, Mapping) or "correlation" not in found:
        return missing(title, "no delay search was asked for (max_delay)", anchor="delay")
    candidates = sorted((int(k), float(v)) for k, v in found["correlation"].items())
    png = figures.delay_figure(np.array([k for k, _ in candidates]), np.array([v for _, v in candidates]),
                               int(found["frames"]))
    shift = int(found["frames"])
    unpaired = found.get("unpaired") or {}
    caption = (f"Real frame i pairs with simulated frame i{shift:+d}" if shift else "No delay: real frame i pairs "
               "with simulated frame i") + (
        f" (confidence {found['confidence']:.3f}, over the first {found.get('window')} frames of each side). "
        f"Not scored, for want of a partner at this delay: {len(unpaired.get('real') or ())} real and "
        f"{len(unpaired.get('sim') or ())} simulated frame(s) at the ends.")
    body = image(png, "correlation of the two sequences' changes at each candidate delay", caption=caption)
    return section(title, body, anchor="delay")


def registration(d: Mapping, rows: list[dict]) -> Raw:
    """The registration: as for a single pair when one was applied to every pair; per frame
    (a plot over the sequence and the spread) with ``register_each``."""
    found = d.get("registration")
    if not (isinstance(found, Mapping) and found.get("each")):
        return sections.registration(d)
    title = "Registration per frame"
    index, series = _registration_series(rows, str(found.get("model")))
    if not index.size:
        return missing(title, "no frame was registered", anchor="registration")
    png = figures.registration_figure(index, series)
    unsure = found.get("unsure") or []
    caption = (f"{len(index)} frames registered ({found.get('model')}, {found.get('method')}); "
               f"{len(unsure)} with a confidence below {found.get('low_confidence')}.")
    spread = {k: found[k] for k in ("shift_dy", "shift_dx", "angle", "scale", "confidence", "overlap")
              if isinstance(found.get(k), Mapping)}
    body: str = image(png, "each frame's registration over the sequence", caption=caption)
    body += paragraph("Spread over the frames:") + key_values(spread, header=("quantity", "value"))
    return section(title, body, anchor="registration")


def _registration_series(rows: list[dict], model: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Frame index and, per registered frame, shift dy/dx (px), angle (°, not for
    translation) and confidence."""
    regs = [(int(r["index"]), r["registration"]) for r in rows
            if not r.get("error") and isinstance(r.get("registration"), Mapping)]
    index = np.array([i for i, _ in regs], dtype=float)
    series = {"shift dy (px)": np.array([g["shift"][0] for _, g in regs], dtype=float),
              "shift dx (px)": np.array([g["shift"][1] for _, g in regs], dtype=float)}
    if model != "translation":
        series["angle (°)"] = np.array([g["angle"] for _, g in regs], dtype=float)
    series["confidence"] = np.array([g["confidence"] for _, g in regs], dtype=float)
    return index, series
