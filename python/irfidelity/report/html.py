"""HTML building blocks of the report: escaping, number formatting, tables, sections, embedded
images and the self-contained page (inline CSS, no script, a Content-Security-Policy that
forbids every network fetch).

Every piece of text that comes from the caller (frame names, notes, error messages, keys of
the report dict) goes through :func:`text`, which also turns undecodable bytes and lone
surrogates (file names read with ``os.fsdecode``) into visible escapes, so the page is valid
UTF-8 whatever the input.
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["text", "number", "table", "key_values", "section", "missing", "image", "panels", "colour_bar", "page",
           "Raw", "Missing"]


class Raw(str):
    """HTML that is already safe (built by this module): not escaped again."""


def text(value: Any) -> Raw:
    """``value`` as escaped HTML text (quotes too, so it is safe in attributes)."""
    if isinstance(value, Raw):
        return value
    if isinstance(value, (bytes, bytearray)):
        s = bytes(value).decode("utf-8", "backslashreplace")
    else:
        s = str(value)
    # lone surrogates (undecodable bytes of os.fsdecode'd names) become visible \udcxx escapes
    s = s.encode("utf-8", "backslashreplace").decode("utf-8")
    return Raw(html.escape(s, quote=True))


def number(value: Any, digits: int = 4) -> Raw:
    """A number for a table: ``digits`` significant figures; non-finite values and the
    ``"inf"``/``"nan"`` strings of JSON-ready reports as ∞/NaN; ``None`` as a dash."""
    if value is None:
        return Raw("–")
    if isinstance(value, bool):
        return text(value)
    if isinstance(value, str):
        low = value.strip().lower()
        if low in ("inf", "+inf", "infinity"):
            return Raw("∞")
        if low in ("-inf", "-infinity"):
            return Raw("−∞")
        if low == "nan":
            return Raw("NaN")
        return text(value)
    if isinstance(value, int):
        return text(value)
    try:
        v = float(value)
    except (TypeError, ValueError):
        return text(value)
    if math.isnan(v):
        return Raw("NaN")
    if math.isinf(v):
        return Raw("∞" if v > 0 else "−∞")
    if v.is_integer() and abs(v) < 1e12:
        return text(str(int(v)))  # whole numbers (peaks, counts) in full
    return text(f"{v:.{digits}g}")


def value_cell(value: Any) -> Raw:
    """A table cell for any JSON-ready value: numbers formatted, lists and dicts compact."""
    if isinstance(value, (int, float)) and not isinstance(value, bool) or value is None:
        return number(value)
    if isinstance(value, str):
        return number(value) if value.strip().lower() in ("inf", "-inf", "nan") else text(value)
    if isinstance(value, Mapping):
        return Raw(", ".join(f"{text(k)}: {value_cell(v)}" for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return Raw("[" + ", ".join(value_cell(v) for v in value) + "]")
    return text(value)


def table(header: Iterable[Any], rows: Iterable[Iterable[Any]], *, cls: str = "") -> Raw:
    """A table; cells that are not :class:`Raw` are escaped (numbers formatted)."""
    cell = lambda v: v if isinstance(v, Raw) else value_cell(v)  # noqa: E731
    head = "".join(f"<th>{cell(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell(v)}</td>" for v in row) + "</tr>" for row in rows)
    klass = f' class="{text(cls)}"' if cls else ""
    return Raw(f"<table{klass}><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")


def flatten(d: Mapping, prefix: str = "") -> list[tuple[str, Any]]:
    """Nested mappings as ``(dotted key, value)`` pairs, in order."""
    out: list[tuple[str, Any]] = []
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping) and v:
            out.extend(flatten(v, key + "."))
        else:
            out.append((key, v))
    return out


def key_values(d: Mapping, *, header: tuple[str, str] = ("setting", "value")) -> Raw:
    """A two-column table of a (nested) mapping."""
    return table(header, flatten(d), cls="kv")


def section(title: str, body: str, *, anchor: str) -> Raw:
    return Raw(f'<section id="{text(anchor)}"><h2>{text(title)}</h2>{body}</section>')


class Missing(Raw):
    """A section left out: its note, with the section's title in ``.title``."""

    title: str = ""  # type: ignore[assignment]  # shadows str.title on purpose: the section's title


def missing(title: str, why: str, *, anchor: str) -> Missing:
    """A section left out, with the reason (so a reader sees what is not there)."""
    out = Missing(f'<section id="{text(anchor)}" class="missing"><h2>{text(title)}</h2>'
                  f'<p class="note">Not shown: {text(why)}</p></section>')
    out.title = title
    return out


def image(png: bytes, alt: str, *, caption: str | None = None) -> Raw:
    """A PNG embedded as a data URI, with an optional caption."""
    data = base64.b64encode(png).decode("ascii")
    cap = f"<figcaption>{text(caption)}</figcaption>" if caption else ""
    return Raw(f'<figure><img src="data:image/png;base64,{data}" alt="{text(alt)}">{cap}</figure>')


def panels(items: list[tuple[bytes, str, str]], *, single: bool = False) -> Raw:
    """Images side by side (``(png, alt, title)`` each), scaled by the page with square pixels."""
    figs = "".join(
        f'<figure><div class="title">{text(title)}</div>'
        f'<img src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}" alt="{text(alt)}"></figure>'
        for png, alt, title in items
    )
    return Raw(f'<div class="panels{" single" if single else ""}">{figs}</div>')


def colour_bar(stops: list[str], ticks: list[tuple[float, str]], label: str) -> Raw:
    """A horizontal colour bar: the colour map's ``stops`` (``#rrggbb``) as a CSS gradient, and
    ``ticks`` as ``(position in [0, 1], label)``."""
    gradient = ", ".join(text(c) for c in stops)
    marks = "".join(f'<span style="left:{100.0 * min(max(p, 0.0), 1.0):.2f}%">{text(t)}</span>' for p, t in ticks)
    return Raw(f'<div class="cbar"><div class="grad" style="background:linear-gradient(to right, {gradient})">'
               f'</div><div class="ticks">{marks}</div><div class="label">{text(label)}</div></div>')


def paragraph(content: Any, *, cls: str = "") -> Raw:
    klass = f' class="{text(cls)}"' if cls else ""
    return Raw(f"<p{klass}>{text(content)}</p>")


# Every rule is scoped to .irf-report, so the same markup can sit inside a notebook page.
_CSS = """
.irf-report{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",sans-serif;color:#1b1b1b;
  background:#fff;max-width:1100px;margin:0 auto;padding:16px 24px;line-height:1.4}
.irf-report h1{font-size:1.6em;margin:0 0 4px}
.irf-report h2{font-size:1.25em;border-bottom:2px solid #ddd;padding-bottom:3px;margin-top:28px}
.irf-report .sub{color:#555;margin:0 0 12px}
.irf-report table{border-collapse:collapse;margin:8px 0;font-size:0.92em}
.irf-report th,.irf-report td{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top}
.irf-report th{background:#f0f0f0}
.irf-report td{font-variant-numeric:tabular-nums;overflow-wrap:anywhere}
.irf-report td:not(:last-child){white-space:nowrap}
.irf-report table.kv td:first-child{font-family:ui-monospace,"DejaVu Sans Mono",monospace;color:#333}
.irf-report .verdict{display:flex;gap:32px;align-items:center;flex-wrap:wrap}
.irf-report .score{font-size:2.6em;font-weight:700}
.irf-report .grade{font-size:1.3em;padding:2px 12px;border-radius:4px;background:#e8eef7;border:1px solid #9db3d6}
.irf-report figure{margin:10px 0}
.irf-report img{max-width:100%;height:auto;border:1px solid #e4e4e4}
.irf-report figcaption,.irf-report p.caption{color:#444;font-size:0.9em;margin-top:4px}
.irf-report .panels{display:flex;gap:16px;flex-wrap:wrap;max-width:980px}
.irf-report .panels figure{flex:1 1 280px;margin:6px 0}
.irf-report .panels.single figure{flex:0 1 560px}
.irf-report .panels img{width:100%;image-rendering:pixelated;border:1px solid #888}
.irf-report .panels .title{font-size:0.95em;text-align:center;margin-bottom:2px}
.irf-report .cbar{max-width:560px;margin:4px 0 10px}
.irf-report .cbar .grad{height:14px;border:1px solid #888}
.irf-report .cbar .ticks{position:relative;height:1.3em;font-size:0.85em}
.irf-report .cbar .ticks span{position:absolute;transform:translateX(-50%);white-space:nowrap}
.irf-report .cbar .ticks span:first-child{transform:none}
.irf-report .cbar .ticks span:last-child{transform:translateX(-100%)}
.irf-report .cbar .label{font-size:0.85em;color:#444}
.irf-report .note{color:#6a4c00;background:#fff8e1;border-left:4px solid #e0b000;padding:4px 10px}
.irf-report section.missing h2{color:#777}
.irf-report footer{margin-top:32px;color:#666;font-size:0.85em;border-top:1px solid #ddd;padding-top:6px}
"""

# No network at all: images only from data: URIs, styles only inline, nothing else.
_CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; base-uri 'none'; form-action 'none'"


def page(title: str, body: str, *, fragment: bool = False) -> str:
    """The whole self-contained document, or (``fragment``) a ``<div>`` for notebooks."""
    if fragment:
        return f'<div class="irf-report"><style>{_CSS}</style>{body}</div>'
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en"><head><meta charset="utf-8">'
        f'<meta http-equiv="Content-Security-Policy" content="{_CSP}">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{text(title)}</title><style>{_CSS}</style></head>"
        f'<body><div class="irf-report">{body}</div></body></html>\n'
    )
