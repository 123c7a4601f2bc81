"""The one path from values to HTML: every string is escaped unless it is trusted ``Markup``.

``Markup`` marks HTML the renderer built itself (from escaped parts); anything else - ship
names, call signs, destinations, port names, rule texts, error messages, numbers - goes through
:func:`escape` (``html.escape`` with quotes) on its way into an element or an attribute.
Builders (:func:`el`, :func:`table`) only accept content through that path, so there is no
second way to write text into the page.
"""

from __future__ import annotations

import html
import math
from collections.abc import Iterable

import numpy as np
import pandas as pd


class Markup(str):
    """HTML the renderer produced itself; passes through :func:`escape` unchanged."""

    __slots__ = ()

    def __add__(self, other):
        return Markup(str.__add__(self, escape(other)))


def escape(value) -> Markup:
    """HTML-escape a value (``& < > " '``); ``Markup`` is returned as is; ``None`` becomes empty."""
    if isinstance(value, Markup):
        return value
    if value is None:
        return Markup("")
    return Markup(html.escape(str(value), quote=True))


def join(parts: Iterable, sep: str = "") -> Markup:
    """Concatenate parts, escaping the ones that are not ``Markup``."""
    return Markup(escape(sep).join(escape(p) for p in parts))


_VOID = {"img", "br", "meta", "hr", "col"}


def el(tag: str, *content, **attrs) -> Markup:
    """An element ``<tag attrs>content</tag>``; attribute values and text content are escaped.

    Attribute names are Python keywords with ``_`` for ``-`` and a trailing ``_`` dropped
    (``class_="x"``, ``data_role="y"``); ``None``/``False`` attributes are left out, ``True`` ones
    written bare.
    """
    parts = [tag]
    for key, value in attrs.items():
        if value is None or value is False:
            continue
        name = key.rstrip("_").replace("_", "-")
        parts.append(name if value is True else f'{name}="{escape(value)}"')
    open_tag = "<" + " ".join(parts) + ">"
    if tag in _VOID:
        return Markup(open_tag)
    return Markup(open_tag + join(content) + f"</{tag}>")


def fmt(value, decimals: int = 2, signed: bool = False) -> str:
    """Format a number for a table: fixed decimals, ``-`` for missing; strings pass through."""
    if value is None:
        return "\u2013"
    if isinstance(value, pd.Timestamp):
        return "\u2013" if value is pd.NaT else fmt_time(value)
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return f"{int(value):+d}" if signed else f"{int(value):d}"
    if isinstance(value, (float, np.floating)):
        x = float(value)
        if not math.isfinite(x):
            return "\u2013"
        if round(x, decimals) == 0:
            x = 0.0  # no "-0.00"
        return f"{x:+.{decimals}f}" if signed else f"{x:.{decimals}f}"
    return str(value)


def fmt_time(t) -> str:
    """``YYYY-MM-DD HH:MM UTC`` for a tz-aware timestamp; ``-`` for missing."""
    if t is None or t is pd.NaT:
        return "\u2013"
    t = pd.Timestamp(t)
    if t.tz is not None:
        t = t.tz_convert("UTC")
    return t.strftime("%Y-%m-%d %H:%M UTC")


def table(columns: list | None, rows: Iterable[Iterable], class_: str | None = None, numeric: set | None = None) -> Markup:
    """A ``<table>``; every header and cell is escaped unless it is ``Markup``.

    ``columns=None`` gives a key-value table without a header row (first column as ``<th>``);
    ``numeric`` lists column positions to right-align.
    """
    numeric = numeric or set()
    if columns is None:
        body = [el("tr", el("th", row[0]), *(el("td", c) for c in row[1:])) for row in (list(r) for r in rows)]
        return el("table", el("tbody", *body), class_=class_)
    head = el("thead", el("tr", *(el("th", c, class_="num" if i in numeric else None) for i, c in enumerate(columns))))
    body_rows = []
    for row in rows:
        cells = [el("td", c, class_="num" if i in numeric else None) for i, c in enumerate(row)]
        body_rows.append(el("tr", *cells))
    return el("table", head, el("tbody", *body_rows), class_=class_)


def img_png(png: bytes, alt: str, class_: str = "fig") -> Markup:
    """An inline PNG (``data:`` URI: bytes inside the page, no request leaves the file)."""
    import base64

    return el("img", src="data:image/png;base64," + base64.b64encode(png).decode("ascii"), alt=alt, class_=class_)


CSS = """
:root { --ink:#1d2733; --muted:#5b6775; --line:#d8dee6; --bg:#f6f8fa; --bad:#b3261e; --good:#1e6b3a; }
* { box-sizing: border-box; }
body { margin:0; font:14px/1.45 -apple-system, "Segoe UI", "DejaVu Sans", Arial, sans-serif; color:var(--ink); background:#fff; }
header { background:#0b3a5b; color:#fff; padding:18px 28px; }
header h1 { margin:0 0 4px 0; font-size:22px; }
header p { margin:0; opacity:.85; }
main { padding:8px 28px 40px; }
h2 { border-bottom:2px solid var(--line); padding-bottom:4px; margin-top:28px; }
h3 { margin:22px 0 6px; }
table { border-collapse:collapse; margin:8px 0 14px; font-size:13px; }
th, td { border:1px solid var(--line); padding:4px 8px; text-align:left; vertical-align:top; }
th { background:var(--bg); }
th.num { text-align:right; }
td.num { text-align:right; font-variant-numeric: tabular-nums; white-space:nowrap; }
.cards { display:flex; flex-wrap:wrap; gap:10px; margin:12px 0; }
.card { border:1px solid var(--line); border-radius:6px; padding:8px 14px; min-width:150px; background:var(--bg); }
.card b { display:block; font-size:20px; }
.card span { color:var(--muted); font-size:12px; }
.bad { color:var(--bad); } .good { color:var(--good); }
.status-failed { color:var(--bad); font-weight:bold; }
img.fig { max-width:100%; height:auto; border:1px solid var(--line); margin:6px 0; }
.figrow { display:flex; flex-wrap:wrap; gap:12px; align-items:flex-start; }
.case { border-top:1px solid var(--line); padding-top:6px; }
.muted { color:var(--muted); }
details { margin:6px 0 12px; } summary { cursor:pointer; color:#0b3a5b; }
code { background:var(--bg); padding:0 3px; }
footer { color:var(--muted); font-size:12px; padding:12px 28px; border-top:1px solid var(--line); }
main { max-width:1400px; }
.small { font-size:12px; }
.cards .card { min-width:120px; padding:6px 12px; } .cards .card b { font-size:18px; }
.overview-row { display:flex; flex-wrap:wrap; gap:18px; align-items:flex-start; }
.fleetbox img.fig.fleet { width:580px; max-width:100%; margin:0; }
.toplist { flex:1 1 560px; } .toplist h3 { margin-top:0; }
table.top td, table.compact td { padding:2px 6px; }
table.matrix { border-collapse:collapse; font-size:12px; }
table.matrix th, table.matrix td { padding:1px 4px; text-align:center; white-space:nowrap; }
table.matrix th.dep { font-weight:normal; font-size:11px; line-height:1.1; }
table.matrix td.route { text-align:left; max-width:260px; overflow:hidden; text-overflow:ellipsis; }
table.matrix td a, .key { color:inherit; text-decoration:none; font-weight:bold; }
.m-ok { background:#eef4f8; } .m-part { background:#fff; color:#555; outline:1px dashed #8a9bb0; outline-offset:-2px; }
p.warn { border-left:4px solid #d08c00; background:#fff8e6; padding:4px 8px; }
.m-none { background:#fff; } .m0 { background:#d9d9d9; } .m-na { background:#f4f4f4; color:#777; }
.m1 { background:#fee090; } .m2 { background:#fdae61; } .m3 { background:#f46d43; color:#fff; } .m4 { background:#a50026; color:#fff; }
.m-fail { background:#000; color:#fff; }
.key { display:inline-block; padding:0 5px; margin:0 2px; border:1px solid var(--line); font-weight:normal; }
.chip { display:inline-block; border:1px solid #c9d3de; border-radius:9px; padding:0 6px; margin:1px 0; font-size:11px;
        background:#f3f6f9; white-space:nowrap; }
.chip i { color:var(--muted); font-style:normal; }
details.case { border-top:1px solid var(--line); margin:0; padding:4px 0; }
details.case > summary { padding:3px 0; }
details.section { border-top:1px solid var(--line); margin:4px 0; padding:4px 0; }
.case-body { padding:2px 0 8px 14px; }
.case-body h3 { margin:8px 0 2px; font-size:15px; }
.notes li { margin:2px 0; }
@media print {
  /* printing unfolds every case: the content of a closed <details> is made visible */
  details::details-content { content-visibility:visible; display:block; }
  details > summary { list-style:none; }
  header { background:none; color:#000; }
  main { max-width:none; padding:0; }
  img.fig { break-inside:avoid; }
  details.case { break-before:auto; }
}
"""

#: No script may run and nothing may load except inline images and the inline style sheet.
CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; base-uri 'none'; form-action 'none'"


def page(title: str, subtitle, body: Markup) -> str:
    """A complete, self-contained HTML document (no external resource, no script)."""
    head = Markup(
        '<meta charset="utf-8">'
        + el("meta", http_equiv="Content-Security-Policy", content=CSP)
        + el("meta", name="viewport", content="width=device-width, initial-scale=1")
        + el("title", title)
        + Markup("<style>" + CSS + "</style>")
    )
    header = el("header", el("h1", title), el("p", subtitle))
    footer = el("footer", "Generated by stormlane. Self-contained page: no scripts, no network requests; maps and plots are inline images.")
    return "<!DOCTYPE html>\n" + el("html", el("head", head), el("body", header, el("main", body), footer), lang="en") + "\n"
