"""Self-contained HTML reports: the nightly reroute report and the voyage audit report.

``render_nightly_report(model, path)`` and ``render_audit_report(model, path)`` write one HTML
file that opens from disk with no network request and no script (a Content-Security-Policy
meta tag forbids both): maps and plots are PNGs inlined as ``data:`` URIs, the style sheet is
inline. All text goes through :func:`dashboards.html.escape`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from dashboards import plots
from dashboards.errors import ReportError
from dashboards.html import Markup, el, escape, fmt, fmt_time, img_png, join, page, table
from dashboards.model import METRIC_COLUMNS, SEED_COLUMNS, metric_delta, LaneDeparture, NightlyReport, Provenance, RouteSet, SpeedLossCurve, VoyageAudit

DASH = "\u2013"

#: Metrics where a lower value is better (deltas coloured accordingly).
LOWER_IS_BETTER = {
    "time_h", "dist_nmi", "max_hs_m", "mean_hs_m", "fuel_t", "co2_t", "so2_t", "nox_t", "pm_t",
    "n_safety_events", "n_operator_events", "exposure_h", "adverse_h", "imo_adverse_h",
}


def _decimals(column: str) -> int:
    if column.startswith("n_"):
        return 0
    if column in ("lat_deg", "lon_deg"):
        return 3
    for suffix, d in (("_nmi", 1), ("_h", 2), ("_kn", 2), ("_m", 2), ("_t", 2), ("_pct", 1), ("_deg", 0), ("_s", 1), ("_ms", 1)):
        if column.endswith(suffix):
            return d
    return 3


COLUMN_LABELS = {
    "start_utc": "start [UTC]",
    "end_utc": "end [UTC]",
    "duration_h": "duration [h]",
    "lat_deg": "lat [deg]",
    "lon_deg": "lon [deg]",
    "exposure_h": "exposure [h]",
    "max_margin": "max margin",
}


def _num(value) -> float:
    """A table value as float (NaN when missing or not numeric)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def _header(column: str) -> str:
    return COLUMN_LABELS.get(column) or METRIC_COLUMNS.get(column, column)


def _hours(h: float) -> str:
    if h is None or not math.isfinite(h):
        return "\u2013"
    return f"{h:+.2f} h"


def _card(value, label) -> Markup:
    return el("div", el("b", value), el("span", label), class_="card")


def _delta_span(column: str, delta: float, pct: float = float("nan")) -> Markup:
    if delta is None or not math.isfinite(delta):
        return Markup("")
    cls = None
    d = _decimals(column)
    if column in LOWER_IS_BETTER and round(delta, d) != 0:
        cls = "good" if delta < 0 else "bad"
    shown = int(round(delta)) if column.startswith("n_") else delta
    text = fmt(shown, d, signed=True) + (f", {fmt(pct, 1, signed=True)} %" if math.isfinite(pct) else "")
    return el("span", f" ({text})", class_=cls)


# ----------------------------------------------------------------------------- shared sections


def _route_label(role: str) -> str:
    return plots.label_for(role)


def metrics_section(routes: RouteSet) -> Markup:
    """Comparison table: one row per metric, one column per route; values with the delta to the
    route set's reference (and the relative delta when handed over), the reference named under
    the table; then the seed's comparison metrics and the routes' notes."""
    metrics = routes.metrics_table()
    deltas = routes.deltas()
    ref = routes.reference
    roles = list(metrics.index)
    head = ["metric"] + [_route_label(r) + (" \u2605 proposed" if r == routes.proposed else "") for r in roles]
    rows = []
    for col in routes.value_columns():
        cells = [METRIC_COLUMNS.get(col) or _header(col)]
        for role in roles:
            value = metrics.loc[role, col]
            if isinstance(value, (float, np.floating, int, np.integer)) and not isinstance(value, (bool, np.bool_)):
                d = _decimals(col)
                shown = value if not col.startswith("n_") or not math.isfinite(float(value)) else int(round(float(value)))
                cell = Markup(escape(fmt(shown, d)))
                if role != ref and role in deltas.index and col in deltas.columns:
                    cell = cell + _delta_span(col, float(deltas.loc[role, col]), routes.delta_pct(col, role))
                cells.append(cell)
            else:
                cells.append(fmt(value))
        rows.append(cells)
    parts = [table(head, rows, numeric=set(range(1, len(roles) + 1)))]
    if ref is not None and ref in metrics.index:
        parts.append(el("p", f"In brackets: difference to the {_route_label(ref)} route, the reference of every delta "
                        "(green: lower, red: higher).", class_="muted"))
    seed = [c for c in SEED_COLUMNS if c in metrics.columns]
    others = [r for r in roles if r != ref]
    if seed and others and ref in metrics.index:
        seed_rows = [[SEED_COLUMNS[c]] + [fmt(_num(metrics.loc[r, c]), 1) for r in others] for c in seed]
        parts.append(el("details", el("summary", f"Comparison metrics of the cargo-loss seed paper (each route against the {_route_label(ref)} route)"), table(["metric"] + [_route_label(r) for r in others], seed_rows, numeric=set(range(1, len(others) + 1)))))
    if routes.notes:
        parts.append(el("ul", *(el("li", f"{_route_label(r)}: {n}") for r, n in routes.notes.items()), class_="muted"))
    return join(parts)


def events_section(routes: RouteSet) -> Markup:
    parts = []
    if routes.events is not None:
        ev = routes.events
        if len(ev):
            cols = [c for c in ("route", "criterion", "start_utc", "end_utc", "duration_h", "lat_deg", "lon_deg") if c in ev.columns]
            cols += [c for c in ev.columns if c not in cols]
            rows = [[_route_label(v) if c == "route" else fmt(v, _decimals(c)) for c, v in zip(cols, rec)] for rec in ev[cols].itertuples(index=False)]
            parts.append(el("h4", "IMO MSC.1/Circ.1228 and operator events"))
            parts.append(table([_header(c) for c in cols], rows))
        else:
            parts.append(el("p", "No IMO MSC.1/Circ.1228 event on any route.", class_="muted"))
    if routes.exposure is not None and len(routes.exposure):
        ex = routes.exposure
        if "exposure_h" in ex.columns:
            ex = ex[pd.to_numeric(ex["exposure_h"], errors="coerce") > 0]
        cols = list(ex.columns)
        rows = [[_route_label(v) if c == "route" else fmt(v, _decimals(c)) for c, v in zip(cols, rec)] for rec in ex.itertuples(index=False)]
        parts.append(el("h4", "Exposure over operator limits"))
        if rows:
            parts.append(table([_header(c) for c in cols], rows, numeric={i for i, c in enumerate(cols) if c.endswith("_h")}))
        else:
            parts.append(el("p", "No route spent time over an operator limit.", class_="muted"))
    return join(parts)


def figures_section(routes: RouteSet, provenance: Provenance, worst=None, worst_role: str = "reference") -> Markup:
    hs_limit = routes.hs_limit_m
    if hs_limit is None and provenance.limits:
        hs_limit = provenance.limits.get("hs_m")
    ordered = {role: routes.routes[role] for role in routes.ordered_roles}
    if not ordered:
        return Markup("")
    map_png = plots.route_map_png(ordered, routes.weather, hs_limit_m=hs_limit, worst=worst, worst_role=worst_role)
    series = plots.series_png(ordered, hs_limit_m=hs_limit, profiles=routes.profiles)
    return el(
        "div",
        img_png(map_png, "map: land, Hs field, wave direction and the routes"),
        img_png(series, "Hs and speed along each route against time"),
        class_="figrow",
    )


def exports_section(routes: RouteSet) -> Markup:
    if not routes.exports:
        return Markup("")
    links = join([el("a", label, href=path) for label, path in routes.exports.items()], sep=" \u00b7 ")
    return el("p", "Exports: ", links)


#: Longest waypoint table written in full; longer routes (AIS tracks) show every k-th row.
MAX_WAYPOINT_ROWS = 200


def waypoints_section(routes: RouteSet, max_rows: int = MAX_WAYPOINT_ROWS) -> Markup:
    """Collapsed waypoint tables (position, ETA, leg speed, weather met), one per route."""
    parts = []
    for role in routes.ordered_roles:
        route = routes.routes[role]
        frame = route.to_frame()
        note = ""
        if len(frame) > max_rows:
            k = int(math.ceil(len(frame) / max_rows))
            keep = sorted(set(range(0, len(frame), k)) | {len(frame) - 1})
            frame = frame.iloc[keep]
            note = f"; every {k}th shown, all of them in the exports"
        cols = list(frame.columns)
        rows = [[fmt_time(v) if c == "time_utc" else fmt(v, 5 if c in ("lat_deg", "lon_deg") else _decimals(c)) for c, v in zip(cols, rec)] for rec in frame.itertuples(index=False)]
        summary = el("summary", f"Waypoints of the {_route_label(role)} route ({route.n_waypoints}{note})")
        parts.append(el("details", summary, table(cols, rows, numeric=set(range(len(cols))) - {cols.index("time_utc")})))
    return join(parts)


def speed_loss_section(curve: SpeedLossCurve | None) -> Markup:
    if curve is None:
        return Markup("")
    text = f"Vessel profile {curve.vessel}, calm-water speed {curve.speed_kn:g} kn, model {curve.model}; encounter angle 0\u00b0 = head seas, 180\u00b0 = following seas."
    return join([el("h2", "Speed-loss curve"), el("p", text), img_png(plots.speed_loss_png(curve), "attainable speed against wave height")])


def provenance_section(prov: Provenance) -> Markup:
    span = f"{fmt_time(prov.weather_start_utc)} \u2192 {fmt_time(prov.weather_end_utc)}" if prov.weather_start_utc is not None else "\u2013"
    rows = [
        ["weather source", prov.weather_source or "\u2013"],
        ["weather products", ", ".join(map(str, prov.weather_products)) or "\u2013"],
        ["weather span", span],
        ["weather files", ", ".join(map(str, prov.weather_files)) or "\u2013"],
        ["AIS sources", ", ".join(map(str, prov.ais_sources)) or "\u2013"],
        ["speed-loss model", prov.speed_loss_model or "\u2013"],
        ["thresholds profile", prov.thresholds_profile or "\u2013"],
        ["limits", ", ".join(f"{k} = {v:g}" if isinstance(v, (int, float)) else f"{k} = {v}" for k, v in prov.limits.items()) or "\u2013"],
    ]
    parts = [el("h2", "Methods and provenance"), table(["item", "value"], rows)]
    if prov.vessel:
        parts.append(el("h4", "Vessel"))
        parts.append(table(["particular", "value"], [[k, fmt(v, 2)] for k, v in prov.vessel.items() if k != "extra" and v not in (None, "")]))
    if prov.methods:
        parts.append(el("h4", "Methods"))
        parts.append(el("ul", *(el("li", m) for m in prov.methods)))
    parts.append(el("h4", "Software"))
    parts.append(table(["package", "version"], [[k, v] for k, v in prov.software.items()]))
    return join(parts)


# ----------------------------------------------------------------------------- nightly


def _rules(dep: LaneDeparture) -> Markup:
    return join([el("div", r) for r in dep.rules]) if dep.rules else Markup("\u2013")


def _departure_title(dep: LaneDeparture) -> str:
    return f"Lane {dep.lane_id}: {dep.origin} \u2192 {dep.destination}, departing {fmt_time(dep.depart_utc)}"


def lanes_at_risk_table(model: NightlyReport) -> Markup:
    """One row per adverse or failed lane-departure, in the run's order, with the rule that fired."""
    if not model.departures:
        return el("p", "No adverse lane-departure in the window: every lane passed every threshold.")
    rows = []
    for k, dep in enumerate(model.departures, start=1):
        worst = "\u2013"
        if dep.worst_hs_m is not None and math.isfinite(dep.worst_hs_m):
            where = f" at {dep.worst_lat_deg:.2f}N {dep.worst_lon_deg:.2f}E" if dep.worst_lat_deg is not None else ""
            worst = f"{dep.worst_hs_m:.2f} m{where}, {fmt_time(dep.worst_time_utc)}"
        rs = dep.routes
        proposed = _route_label(rs.proposed) if rs is not None and rs.proposed else "\u2013"
        d_time = metric_delta(rs, "time_h")
        d_fuel = metric_delta(rs, "fuel_t")
        d_co2 = metric_delta(rs, "co2_t")
        d_events = metric_delta(rs, "n_safety_events")
        status = el("span", "failed: ", dep.error, class_="status-failed") if dep.status == "failed" else dep.status
        link = el("a", str(k), href=f"#case-{k}") if dep.status == "adverse" and dep.routes is not None and k <= model.max_detail else str(k)
        rows.append(
            [
                link,
                dep.lane_id,
                f"{dep.origin} \u2192 {dep.destination}",
                dep.vessel or "\u2013",
                fmt_time(dep.depart_utc),
                _rules(dep),
                worst,
                proposed,
                fmt(d_time, 2, signed=True),
                fmt(d_fuel, 3, signed=True),
                fmt(d_co2, 3, signed=True),
                fmt(-d_events if math.isfinite(d_events) else d_events, 0),
                status,
            ]
        )
    cols = ["#", "lane", "route", "vessel", "departure", "rule(s) fired", "worst Hs on lane", "proposed", "\u0394 time [h]", "\u0394 fuel [t]", "\u0394 CO2 [t]", "events avoided", "status"]
    return table(cols, rows, numeric={8, 9, 10, 11})


def _vessels_line(model: NightlyReport, prov) -> str:
    """The provenance's vessel, or, when the night's lanes are sailed by several profiles, each
    with its number of lanes at risk (the per-lane profile is in the lanes-at-risk table)."""
    lanes: dict[str, set] = {}
    for dep in model.departures:
        if dep.vessel:
            lanes.setdefault(dep.vessel, set()).add(dep.lane_id)
    if len(lanes) > 1:
        return ", ".join(f"{name} ({len(ids)} lane{'s' if len(ids) != 1 else ''} at risk)" for name, ids in sorted(lanes.items()))
    if lanes:
        return next(iter(lanes))
    return prov.vessel.get("name", DASH) if prov.vessel else DASH


def _nightly_summary(model: NightlyReport) -> Markup:
    totals = model.totals()
    prov = model.provenance
    duration_s = (model.finished_utc - model.started_utc).total_seconds() if model.started_utc is not None and model.finished_utc is not None else float("nan")
    cards = el(
        "div",
        _card(fmt(model.lanes_checked), "lanes checked"),
        _card(fmt(model.departures_checked), "lane-departures checked"),
        _card(fmt(len(model.adverse)), "adverse lane-departures"),
        _card(fmt(len(model.reroutes)), "proposed reroutes"),
        _card(fmt(len(model.failed)), "failed lanes"),
        _card(_hours(totals["delta_time_h"]), "\u0394 sailing time (sum)"),
        _card(fmt(totals["delta_fuel_t"], 2, signed=True) + " t", "\u0394 fuel (sum)"),
        _card(fmt(totals["delta_co2_t"], 2, signed=True) + " t", "\u0394 CO2 (sum)"),
        _card(fmt(totals["safety_events_avoided"], 0), "safety events avoided"),
        class_="cards",
    )
    span = f"{fmt_time(prov.weather_start_utc)} \u2192 {fmt_time(prov.weather_end_utc)}" if prov.weather_start_utc is not None else "\u2013"
    rows = [
        ["run", model.run_id],
        ["run time", f"{fmt_time(model.started_utc)} \u2192 {fmt_time(model.finished_utc)} ({fmt(duration_s, 1)} s)"],
        ["forecast reference (now)", fmt_time(model.now_utc)],
        ["departure window", f"{fmt_time(model.window_start_utc)} \u2192 {fmt_time(model.window_end_utc)}, every {fmt(model.departure_step_h, 1)} h"],
        ["weather", f"{prov.weather_source or 'unknown source'}: {', '.join(map(str, prov.weather_products)) or DASH}; {span}"],
        ["vessel / model / limits", f"{_vessels_line(model, prov)} / {prov.speed_loss_model or DASH} / {prov.thresholds_profile or DASH}"],
    ]
    note = el("p", "Deltas are proposed minus the reference of each case, summed over the proposed reroutes; negative time, fuel "
              "and CO2 are savings. The reference is the lane as planned, sailed by the same vessel model (the lane's typical "
              "AIS speed minus the speed loss) from the same departure in the same weather as the alternatives.", class_="muted")
    return join([el("h2", "Summary"), cards, table(None, rows), note])


def route_notes(rs: RouteSet) -> list[str]:
    """What a reader must know about the routes of a case, from their properties: a safe-optimal
    route that could not keep within the limits (the search fell back to soft penalties), and
    routes that outlast the weather (the last field held)."""
    notes = []
    for role, route in rs.routes.items():
        props = route.properties or {}
        if props.get("safety_requested") == "hard" and props.get("safety_mode") == "soft":
            notes.append(f"{_route_label(role)}: no route keeps within the vessel's limits for this departure; this one "
                         "minimises time plus a penalty per hour over them (soft limits), so it still breaks them.")
        held = props.get("weather_held_after_h")
        if held:
            notes.append(f"{_route_label(role)}: arrives {fmt(held, 1)} h after the last weather time; the last field was "
                         "held for those hours.")
    return notes


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


def _case_section(k: int, dep: LaneDeparture, provenance: Provenance) -> Markup:
    rs = dep.routes
    worst = (dep.worst_lat_deg, dep.worst_lon_deg) if dep.worst_lat_deg is not None else None
    rules = el("p", el("b", "Rule(s) fired: "), join(dep.rules, sep="; ") if dep.rules else "\u2013")
    notes = route_notes(rs)
    return el(
        "section",
        el("h3", f"{k}. {_departure_title(dep)}", id=f"case-{k}"),
        rules,
        el("ul", *(el("li", n) for n in notes), class_="notes") if notes else "",
        figures_section(rs, provenance, worst=worst, worst_role=rs.reference or "lane"),
        metrics_section(rs),
        events_section(rs),
        exports_section(rs),
        waypoints_section(rs),
        class_="case",
    )


def nightly_html(model: NightlyReport) -> str:
    """The nightly report as an HTML string."""
    if not isinstance(model, NightlyReport):
        raise ReportError(f"render_nightly_report needs a NightlyReport, got {type(model).__name__}")
    detailed = [(k, d) for k, d in enumerate(model.departures, start=1) if d.status == "adverse" and d.routes is not None][: model.max_detail]
    parts = [
        _nightly_summary(model),
        el("h2", "Lanes at risk"),
        lanes_at_risk_table(model),
    ]
    if detailed:
        parts.append(el("h2", "Adverse lane-departures"))
        n_adverse = sum(1 for d in model.departures if d.status == "adverse" and d.routes is not None)
        if n_adverse > len(detailed):
            parts.append(el("p", f"Maps and plots for the first {len(detailed)} of {n_adverse} in ranking order; the others are in the table above.", class_="muted"))
        parts.extend(_case_section(k, d, model.provenance) for k, d in detailed)
    parts.append(speed_loss_section(model.speed_loss))
    parts.append(provenance_section(model.provenance))
    subtitle = f"run {model.run_id} \u00b7 forecast from {fmt_time(model.now_utc)} \u00b7 departures {fmt_time(model.window_start_utc)} \u2192 {fmt_time(model.window_end_utc)}"
    return page(model.title, subtitle, join(parts))


# ----------------------------------------------------------------------------- audit


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
    parts = [
        el("h2", "Ship and voyage"),
        table(None, ident),
        el("div", *cards, class_="cards"),
    ]
    if model.bias or model.calm_water:
        parts.append(el("p", _audit_method(model), class_="muted"))
    if model.findings:
        parts += [el("h2", "Findings"), el("ul", *(el("li", f) for f in model.findings))]
    parts += [
        el("h2", "Sailed track and alternatives"),
        figures_section(rs, model.provenance, worst=worst, worst_role=sailed),
        metrics_section(rs),
        events_section(rs),
        exports_section(rs),
        waypoints_section(rs),
        speed_loss_section(model.speed_loss),
        provenance_section(model.provenance),
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
