"""The labelled regions of a pair report (``evaluate(..., regions=...)``): one table, a row per
region with its pixels, its image components, its fidelity and grade, and why."""

from __future__ import annotations

from collections.abc import Mapping

from ..regions import OWN_COMPONENTS
from . import sections
from .html import Raw, paragraph, section, table, text

__all__ = ["regions"]


def regions(d: Mapping) -> list[Raw]:
    """The regions section, or nothing when the report has no regions."""
    entries = {name: dict(e) for name, e in sections.mapping(d, "regions").items() if isinstance(e, Mapping)}
    if not entries:
        return []
    own = [c for c in OWN_COMPONENTS if any(c in sections.mapping(e, "components") for e in entries.values())]
    rows = []
    for name, entry in entries.items():
        components, metrics = sections.mapping(entry, "components"), sections.mapping(entry, "metrics")
        reason = sections.mapping(entry, "verdict").get("reason")
        rows.append([Raw(f"<b>{text(name)}</b>"), entry.get("label"), entry.get("pixels"),
                     metrics.get("n"), *(components.get(c) for c in own), entry.get("fidelity"),
                     entry.get("grade"), reason if isinstance(reason, str) else ""])
    caption = ("Each labelled region scored on its own: its image components over its pixels (within the mask and a "
               "registration's overlap), the pair's camera components, eq. 15 and the grade. The verdict above is "
               "the union of the regions.")
    body = table(["region", "label", "pixels", "scored", *own, "fidelity", "grade", "why"], rows)
    return [section("Regions", body + paragraph(caption, cls="caption"), anchor="regions")]
