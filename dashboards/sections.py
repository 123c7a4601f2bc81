"""Sections both reports share: number formats, the comparison table, events and exposure,
figures, exports, waypoints, the speed-loss curve, provenance, and the rule chips."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from dashboards import plots
from dashboards.html import Markup, el, escape, fmt, fmt_time, img_png, join, table
from dashboards.model import METRIC_COLUMNS, SEED_COLUMNS, Provenance, RouteSet, SpeedLossCurve


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


#: The wording of the notes a command prints for a route (``stormlane route``/``deviate``/``nightly``),
#: shared by :func:`pipelines.reporting.route_notes_of` and :func:`route_notes`, so that a case
#: says what a command would print for it.
SOFT_FALLBACK_NOTE = ("no route keeps within the vessel's limits for this departure; this one minimises time plus a penalty "
                      "per hour over them (soft limits), so it still breaks them")


def held_weather_note(hours: float) -> str:
    return f"arrives {hours:.1f} h after the last weather time; the last field was held for those hours"


def route_notes(rs: RouteSet) -> dict:
    """Per role (display order), the notes of a route set: the ones the run wrote
    (``rs.notes``), plus what the routes' own properties say and the run did not (a safe route
    that fell back from hard to soft limits, a route that outlasts the weather)."""
    out: dict = {}
    for role in rs.ordered_roles:
        given = rs.notes.get(role) or ""
        notes = [given] if given else []
        route = rs.routes.get(role)
        props = (route.properties or {}) if route is not None else {}
        extra = []
        if props.get("safety_requested") == "hard" and props.get("safety_mode") == "soft":
            extra.append(SOFT_FALLBACK_NOTE)
        held = props.get("weather_held_after_h")
        if held:
            extra.append(held_weather_note(float(held)))
        notes += [n for n in extra if n not in given]
        if notes:
            out[role] = notes
    for role, text in rs.notes.items():  # a note on a role the set does not hold stays visible
        if role not in out and text:
            out[role] = [text]
    return out


#: The rows of a compact comparison table (a case shown without maps).
COMPACT_COLUMNS = ("time_h", "dist_nmi", "max_hs_m", "fuel_t", "co2_t", "n_safety_events", "adverse_h")


def metrics_section(routes: RouteSet, compact: bool = False, notes: bool = True) -> Markup:
    """Comparison table: one row per metric, one column per route; values with the delta to the
    route set's reference (and the relative delta when handed over), the reference named in its
    column header and under the table; then the seed's comparison metrics and the routes' notes
    (``compact``: the main metrics only, no seed metrics)."""
    metrics = routes.metrics_table()
    deltas = routes.deltas()
    ref = routes.reference
    roles = list(metrics.index)
    head = ["metric"] + [_route_label(r) + (" \u2605 proposed" if r == routes.proposed else "")
                         + (" (reference)" if r == ref and len(roles) > 1 else "") for r in roles]
    rows = []
    columns = routes.value_columns()
    if compact:
        columns = [c for c in COMPACT_COLUMNS if c in columns]
    # plain dicts: one lookup per cell, not a pandas .loc (a night renders thousands of cells)
    values = {c: dict(zip(roles, metrics[c].tolist())) for c in columns}
    given = {c: dict(zip(deltas.index, deltas[c].tolist())) for c in columns if c in deltas.columns}
    pct = {c: dict(zip(roles, pd.to_numeric(metrics[f"d_{c}_pct"], errors="coerce").tolist()))
           for c in columns if f"d_{c}_pct" in metrics.columns}
    for col in columns:
        cells = [METRIC_COLUMNS.get(col) or _header(col)]
        for role in roles:
            value = values[col][role]
            if isinstance(value, (float, np.floating, int, np.integer)) and not isinstance(value, (bool, np.bool_)):
                d = _decimals(col)
                shown = value if not col.startswith("n_") or not math.isfinite(float(value)) else int(round(float(value)))
                cell = Markup(escape(fmt(shown, d)))
                if role != ref and role in given.get(col, {}):
                    cell = cell + _delta_span(col, float(given[col][role]), pct.get(col, {}).get(role, float("nan")))
                cells.append(cell)
            else:
                cells.append(fmt(value))
        rows.append(cells)
    parts = [table(head, rows, numeric=set(range(1, len(roles) + 1)))]
    if ref is not None and ref in metrics.index:
        parts.append(el("p", f"In brackets: difference to the {_route_label(ref)} route, the reference of every delta "
                        "(green: lower, red: higher).", class_="muted"))
    seed = [c for c in SEED_COLUMNS if c in metrics.columns] if not compact else []
    others = [r for r in roles if r != ref]
    if seed and others and ref in metrics.index:
        seed_rows = [[SEED_COLUMNS[c]] + [fmt(_num(metrics.loc[r, c]), 1) for r in others] for c in seed]
        parts.append(el("details", el("summary", f"Comparison metrics of the cargo-loss seed paper (each route against the {_route_label(ref)} route)"), table(["metric"] + [_route_label(r) for r in others], seed_rows, numeric=set(range(1, len(others) + 1)))))
    if routes.notes and notes:
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
    """Export links; a member of the night's archive (``exports.zip#name``) is named, linked to the archive."""
    if not routes.exports:
        return Markup("")
    inside = {label: path.split("#", 1)[1] for label, path in routes.exports.items() if ".zip#" in path}
    plain = {label: path for label, path in routes.exports.items() if label not in inside}
    parts = []
    if plain:
        parts.append(el("p", "Exports: ", join([el("a", label, href=path) for label, path in plain.items()], sep=" \u00b7 ")))
    if inside:
        archive = next(iter(routes.exports[label] for label in inside)).split("#", 1)[0]
        parts.append(el("p", "Exports in ", el("a", archive, href=archive), ": ",
                        join([el("code", name) for name in inside.values()], sep=" \u00b7 ")))
    return join(parts)


#: Longest waypoint table written in full; longer routes (AIS tracks) show every k-th row.
MAX_WAYPOINT_ROWS = 200


def waypoints_section(routes: RouteSet, max_rows: int = MAX_WAYPOINT_ROWS, roles=None) -> Markup:
    """Collapsed waypoint tables (position, ETA, leg speed, weather met), one per route (``roles``:
    only these)."""
    parts = []
    for role in routes.ordered_roles:
        if roles is not None and role not in roles:
            continue
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
        ["weather span" + (" used" if prov.weather_spans else ""), span],
        ["weather files", ", ".join(map(str, prov.weather_files)) or "\u2013"],
        ["AIS sources", ", ".join(map(str, prov.ais_sources)) or "\u2013"],
        ["speed-loss model", prov.speed_loss_model or "\u2013"],
    ]
    if not prov.vessels:  # else every vessel's limit set is in its own table below
        rows += [["thresholds profile", prov.thresholds_profile or "\u2013"],
                 ["limits", ", ".join(f"{k} = {v:g}" if isinstance(v, (int, float)) else f"{k} = {v}"
                                      for k, v in prov.limits.items()) or "\u2013"]]
    parts = [el("h2", "Methods and provenance"), table(["item", "value"], rows)]
    if prov.weather_spans:
        parts.append(el("h4", "Weather products"))
        parts.append(table(["product", "variables", "its files from", "to", "step [h]"],
                           [[w.get("product") or DASH, w.get("variables") or DASH, fmt_time(_ts(w.get("start_utc"))),
                             fmt_time(_ts(w.get("end_utc"))), fmt(w.get("step_h"), 2)] for w in prov.weather_spans], numeric={4}))
    if prov.vessels:
        parts.append(el("h4", "Vessels and limits"))
        parts.append(table(["vessel profile", "lanes", "limit set", "limits", "particulars"],
                           [[v.get("name"), fmt(v.get("lanes")), v.get("thresholds_profile") or DASH, _pairs(v.get("limits")),
                             _pairs(v.get("particulars"))] for v in prov.vessels], numeric={1}))
    if prov.models:
        parts.append(el("h4", "Models"))
        parts.append(table(None, [[k, v] for k, v in prov.models.items()]))
    if prov.vessel and not prov.vessels:
        parts.append(el("h4", "Vessel"))
        parts.append(table(["particular", "value"], [[k, fmt(v, 2)] for k, v in prov.vessel.items() if k != "extra" and v not in (None, "")]))
    if prov.methods:
        parts.append(el("h4", "Methods"))
        parts.append(el("ul", *(el("li", m) for m in prov.methods)))
    parts.append(el("h4", "Software"))
    parts.append(table(["package", "version"], [[k, v] for k, v in prov.software.items()]))
    return join(parts)


def _ts(text):
    return None if not text else pd.Timestamp(text)


def _pairs(d) -> str:
    return ", ".join(f"{k} = {v:g}" if isinstance(v, (int, float)) and not isinstance(v, bool) else f"{k} = {v}"
                     for k, v in (d or {}).items()) or DASH


#: Short labels and units of the rules for the chips (``thresholds.safety`` names).
RULE_CHIPS = {"hs": ("Hs", "m"), "wind": ("wind", "m/s"), "period": ("period", "s"), "beam_seas": ("beam seas", "\u00b0"),
              "surf_riding": ("surf-riding", "kn"), "high_waves": ("high waves", "m"), "synchronous_roll": ("sync. roll", "s"),
              "parametric_roll": ("param. roll", "s")}


def chip(reason: dict) -> Markup:
    """One rule as a short chip: rule, worst value / limit with the unit, and when (day and time,
    UTC); the full wording is in the case section (and the chip's title)."""
    what, unit = RULE_CHIPS.get(reason.get("rule"), (str(reason.get("rule", "?")).replace("_", " "), ""))
    value, limit = reason.get("value"), reason.get("limit")
    num = fmt(value, 1) if value is not None else DASH
    lim = f"/{fmt(limit, 1)}" if limit is not None and math.isfinite(float(limit)) else ""
    when = pd.Timestamp(reason["time_utc"]).strftime("%d %H:%M") if reason.get("time_utc") else ""
    return el("span", el("b", what), f" {num}{lim} {unit}".rstrip(), el("i", f" {when}") if when else "", class_="chip",
              title=reason.get("text"))


def chips(reasons, rules=()) -> Markup:
    """The chips of a case; from the rules' names when no structured reasons are held (older models)."""
    if reasons:
        return join([chip(r) for r in reasons], sep=" ")
    if rules:
        return join([el("span", str(r).split(":", 1)[0], class_="chip", title=r) for r in rules], sep=" ")
    return Markup(DASH)


def event_chips(rs: RouteSet, role: str) -> Markup:
    """The events of one route as chips, one per criterion: how many, hours in all, and the
    first start (day and time, UTC); the event table holds every one."""
    ev = rs.events
    if ev is None or not len(ev) or "route" not in ev.columns or "criterion" not in ev.columns:
        return Markup("")
    mine = ev[ev["route"] == role]
    out = []
    for criterion, g in mine.groupby("criterion", sort=True):
        hours = pd.to_numeric(g["duration_h"], errors="coerce").sum() if "duration_h" in g.columns else float("nan")
        first = pd.to_datetime(g["start_utc"], utc=True).min() if "start_utc" in g.columns else None
        when = f" from {first:%d %H:%M}" if first is not None and not pd.isna(first) else ""
        out.append(el("span", el("b", str(criterion)), f" {len(g)}\u00d7, {fmt(hours, 1)} h", el("i", when) if when else "",
                      class_="chip"))
    return join(out, sep=" ")
