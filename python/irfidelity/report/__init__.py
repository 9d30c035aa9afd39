"""Self-contained HTML reports: what the numbers are and where the simulator departs from the
camera.

:func:`render_pair_html` (one frame pair) and :func:`render_sequence_html` (a scored sequence)
take the JSON-ready report dict (``report.to_dict()``) and, optionally, the frames and camera
curves, and return one HTML document with every figure embedded as a PNG data URI, the styles
inline, no script, and a Content-Security-Policy that forbids any network fetch: the file can be
mailed, archived or opened offline. Figures need matplotlib (``pip install 'irfidelity[report]'``).

Layout: :mod:`.html` (escaping, tables, the page), :mod:`.figures` (matplotlib, Agg canvas),
:mod:`.sections` (verdict, components, settings, curves, registration), :mod:`.pair` and
:mod:`.sequence` (the two pages).
"""

from __future__ import annotations

import os

from .pair import render_pair_html
from .sequence import render_sequence_html

__all__ = ["render_pair_html", "render_sequence_html", "write_html"]


def write_html(html: str, path: str | os.PathLike | None) -> str:
    """Write ``html`` to ``path`` (UTF-8) when given; return ``html`` either way."""
    if path is not None:
        with open(path, "w", encoding="utf-8", newline="\n") as f:
            f.write(html)
    return html
