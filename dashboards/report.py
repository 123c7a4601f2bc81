"""Self-contained HTML reports: the nightly reroute report and the voyage audit report.

``render_nightly_report(model, path)`` and ``render_audit_report(model, path)`` write one HTML
file that opens from disk with no network request and no script (a Content-Security-Policy
meta tag forbids both): maps and plots are PNGs inlined as ``data:`` URIs, the style sheet is
inline. All text goes through :func:`dashboards.html.escape`. The nightly page is built in
:mod:`dashboards.nightly_page`, the sections both reports share in :mod:`dashboards.sections`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dashboards.errors import ReportError
from dashboards.html import Markup, el, fmt, fmt_time, join, page, table
from dashboards.model import NightlyReport, RouteSet, VoyageAudit
from dashboards.nightly_page import nightly_html
from dashboards.sections import (DASH, _card, _hours, _route_label, chips, events_section, exports_section, figures_section,  # noqa: F401
                                 event_chips, metrics_section, provenance_section, route_notes, speed_loss_section,
                                 waypoints_section)


def _audit_method(model: VoyageAudit) -> str:
    """How the audit compares: the two sailed rows, the calm-water speed and the reference of the deltas."""
    cw = model.calm_water or {}
    if cw.get("source") == "ais_low_sea":
        speed = (f"{fmt(cw.get('speed_kn'), 2)} kn, the voyage's calm-water speed from its AIS speeds in low sea states "
                 f"(Hs \u2264 {fmt(cw.get('low_hs_m'), 1)} m, {fmt(cw.get('low_sea_h'), 1)} h of sailing)")
    else:
        speed = f"{fmt(cw.get('speed_kn'), 2)} kn, the vessel profile's (too little sailing in low sea states to estimate it from AIS)"
    return ("Two rows for the sailed voyage: as sailed (its AIS times, the truth) and as sailed, modelled (the same track "
            f"re-timed by the vessel model from the same departure at {speed}). Their difference is the model's bias on this "
            "voyage. The alternatives are sailed by the same model, and every delta is against the modelled row.")


# ----------------------------------------------------------------------------- audit


def _folded(anchor: str, title: str, body) -> Markup:
    """A folded section; the anchor sits inside, so a link to it opens the section."""
    return el("details", el("summary", el("b", title)), el("div", body, id=anchor), class_="section")


def audit_html(model: VoyageAudit) -> str:
    """The voyage audit report as an HTML string."""
    if not isinstance(model, VoyageAudit):
        raise ReportError(f"render_audit_report needs a VoyageAudit, got {type(model).__name__}")
    rs = model.routes
    ship = model.ship_name or f"MMSI {model.mmsi}"
    ident = [
        ["ship name (AIS)", model.ship_name or "\u2013"],
        ["MMSI", model.mmsi],
        ["IMO", model.imo if model.imo is not None else "\u2013"],
        ["call sign (AIS)", model.callsign or "\u2013"],
        ["AIS ship type", model.ship_type if model.ship_type is not None else "\u2013"],
        ["destination reported (AIS)", model.ais_destination or "\u2013"],
        ["voyage", model.voyage_id or "\u2013"],
        ["from \u2192 to", f"{model.origin or DASH} \u2192 {model.destination or DASH}"],
        ["departure \u2192 arrival", f"{fmt_time(model.depart_utc)} \u2192 {fmt_time(model.arrive_utc)}"],
        ["vessel profile for the alternatives", model.vessel_profile or "\u2013"],
        ["audit computed", fmt_time(model.generated_utc)],
    ]
    metrics = rs.metrics_table()
    cards = []
    sailed = "as_sailed" if "as_sailed" in metrics.index else "historical"
    if sailed in metrics.index:
        hist = metrics.loc[sailed]
        cards.append(_card(f"{fmt(hist.get('time_h'), 2)} h", "sailed time"))
        cards.append(_card(f"{fmt(hist.get('dist_nmi'), 1)} nmi", "sailed distance"))
        cards.append(_card(f"{fmt(hist.get('max_hs_m'), 2)} m", "highest Hs met"))
        if "n_safety_events" in metrics.columns:
            cards.append(_card(fmt(hist.get("n_safety_events"), 0), "IMO events on the sailed track"))
    if rs.proposed is not None:
        deltas = rs.deltas()
        if rs.proposed in deltas.index:
            d = deltas.loc[rs.proposed]
            cards.append(_card(_hours(d.get("time_h", float("nan"))), f"\u0394 time, {_route_label(rs.proposed)}"))
            if "fuel_t" in d:
                cards.append(_card(fmt(d["fuel_t"], 2, signed=True) + " t", f"\u0394 fuel, {_route_label(rs.proposed)}"))
            if "max_hs_m" in d:
                cards.append(_card(fmt(d["max_hs_m"], 2, signed=True) + " m", f"\u0394 highest Hs, {_route_label(rs.proposed)}"))
    if model.bias:
        b = model.bias
        cards.append(_card(f"{fmt(b.get('time_h'), 2, signed=True)} h ({fmt(b.get('time_pct'), 1, signed=True)} %)",
                           "model bias, time (modelled \u2212 AIS)"))
        cards.append(_card(f"{fmt(b.get('fuel_t'), 2, signed=True)} t ({fmt(b.get('fuel_pct'), 1, signed=True)} %)",
                           "model bias, fuel (modelled \u2212 AIS)"))
    worst = None
    hist_route = rs.routes.get(sailed)
    if hist_route is not None and "hs_m" in hist_route.weather and np.isfinite(hist_route.weather["hs_m"]).any():
        i = int(np.nanargmax(hist_route.weather["hs_m"]))
        worst = (hist_route.lat_deg[i], hist_route.lon_deg[i])
    sections = [("overview", "Overview"), ("routes", "Track and alternatives"), ("events", "Events"), ("waypoints", "Waypoints"),
                ("provenance", "Methods and provenance")]
    parts = [
        el("h2", "Overview", id="overview"),
        el("p", "On this page: ", join([el("a", label, href=f"#{key}") for key, label in sections[1:]], sep=" \u00b7 "),
           " (folded sections open on a click; printing opens them all).", class_="muted small"),
        el("div", *cards, class_="cards"),
        table(None, ident),
    ]
    if rs.proposed is not None and rs.reference is not None:
        parts.insert(3, el("p", f"\u0394 = {_route_label(rs.proposed)} \u2212 {_route_label(rs.reference)} (the reference of every "
                                "delta on this page).", class_="muted small"))
    on_track = event_chips(rs, sailed)
    if on_track:
        parts.append(el("p", el("b", "On the sailed track: "), on_track))
    if model.bias or model.calm_water:
        parts.append(el("p", _audit_method(model), class_="muted"))
    if model.findings:
        parts += [el("h3", "Findings"), el("ul", *(el("li", f) for f in model.findings))]
    parts += [
        el("h2", "Sailed track and alternatives", id="routes"),
        figures_section(rs, model.provenance, worst=worst, worst_role=sailed),
        metrics_section(rs),
        exports_section(rs),
        _folded("events", f"IMO MSC.1/Circ.1228 and operator events ({0 if rs.events is None else len(rs.events)})",
                events_section(rs)),
        _folded("waypoints", "Waypoints of every route", waypoints_section(rs)),
        _folded("provenance", "Methods and provenance: weather, vessel, limits, models, software",
                join([speed_loss_section(model.speed_loss), provenance_section(model.provenance)])),
    ]
    subtitle = f"{ship} \u00b7 MMSI {model.mmsi} \u00b7 {fmt_time(model.depart_utc)} \u2192 {fmt_time(model.arrive_utc)}"
    return page(f"{model.title}: {ship}", subtitle, join(parts))


# ----------------------------------------------------------------------------- entry points


def _target(path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise ReportError(f"{path}: a report is an .html file")
    return path


def _write(text: str, path: Path) -> Path:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    except OSError as err:
        where = f": {err.filename}" if err.filename and str(err.filename) != str(path) else ""
        raise ReportError(f"{path}: cannot write the report ({err.strerror or err}{where})") from None
    return path


def render_nightly_report(model: NightlyReport, path) -> Path:
    """Write the nightly reroute report to ``path`` (one self-contained HTML file); returns the path."""
    target = _target(path)
    return _write(nightly_html(model), target)


def render_audit_report(model: VoyageAudit, path) -> Path:
    """Write the voyage audit report to ``path`` (one self-contained HTML file); returns the path."""
    target = _target(path)
    return _write(audit_html(model), target)


def render_report(model, path) -> Path:
    """Render whichever report the model describes."""
    if isinstance(model, NightlyReport):
        return render_nightly_report(model, path)
    if isinstance(model, VoyageAudit):
        return render_audit_report(model, path)
    raise ReportError(f"no report for a {type(model).__name__}")


__all__ = ["render_nightly_report", "render_audit_report", "render_report", "nightly_html", "audit_html"]
