"""The nightly report page: an analyst's overview first, details on demand.

What a fleet safety analyst reads at 07:00, top to bottom (issue 22):

1. **Overview** (one screen at 1400 px): the night's figures (:attr:`NightlyReport.summary`, the
   dict the CLI prints), the **fleet map** (every lane checked, coloured by its worst hours at risk
   over the window, a ringed number where a reroute is proposed), the **top cases** ranked with
   the ranking key as a column, and the **lane x departure matrix** (cells coloured by hours at
   risk avoided, the proposed role in each, linked to its case).
2. **Every adverse or failed lane-departure** as one compact row (rules as chips), folded.
3. **The cases**, each a ``<details>`` anchored ``#case-<rank>``: full rule wording, notes,
   comparison table against the lane as planned; the first ``max_detail`` also map, plots,
   events, exports and waypoints. No script: navigating to an anchor opens its case (the
   browser unfolds a ``<details>`` holding the target), and printing unfolds every case (print
   style sheet in :mod:`dashboards.html`).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from dashboards import plots
from dashboards.html import Markup, el, fmt, fmt_time, img_png, join, table
from dashboards.model import LaneDeparture, NightlyReport, Provenance, metric_delta
from dashboards.sections import (DASH, chips, events_section, exports_section, figures_section, metrics_section,
                                 provenance_section, route_notes, speed_loss_section, waypoints_section)

#: Short names of the proposed roles in the matrix cells (the legend spells them out).
ROLE_SHORT = {"safe_optimal": "SO", "optimal": "TO", "deviation": "DV", "min_distance": "MD"}


def role_short(role: str) -> str:
    """A role's letters in a matrix cell; a role the table does not know (a new one a run
    proposes) gets the initials of its words (``least_fuel`` -> ``LF``)."""
    return ROLE_SHORT.get(role) or "".join(w[:1] for w in str(role).split("_")).upper() or "?"

#: Hours at risk avoided: upper bounds of the matrix's colour classes (m1 .. m4).
AVOIDED_BOUNDS_H = (1.0, 3.0, 6.0, math.inf)
#: Rows of the ranked list of top cases.
TOP_N = 10


def _card(value, label) -> Markup:
    return el("div", el("b", value), el("span", label), class_="card")


def _anchor(k: int) -> str:
    return f"case-{k}"


def _route_text(dep) -> str:
    return f"{dep.origin} \u2192 {dep.destination}"


# ----------------------------------------------------------------------------- overview figures


def overview_figures(model: NightlyReport) -> dict:
    """The overview's figures: the run's own (``model.summary``, what the CLI printed), else
    counted and summed from the cases (models written before the overview)."""
    s = dict(model.summary or {})
    if s:
        return s
    totals = model.totals()
    adverse = model.adverse
    return {"lanes_checked": model.lanes_checked, "departures_checked": model.departures_checked, "adverse": len(adverse),
            "failed": len(model.failed), "reroutes": len(model.reroutes), "lanes_at_risk": len({d.lane_id for d in adverse}),
            "risk_avoided_h": sum(d.risk_avoided or 0.0 for d in model.reroutes) if model.reroutes else None,
            "events_avoided": totals["safety_events_avoided"], "delta_time_h": totals["delta_time_h"],
            "delta_fuel_t": totals["delta_fuel_t"], "delta_co2_t": totals["delta_co2_t"]}


def _cards(model: NightlyReport) -> Markup:
    s = overview_figures(model)

    def signed(key, unit, d=1):
        v = s.get(key)
        return DASH if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{fmt(float(v), d, signed=True)} {unit}"

    return el(
        "div",
        _card(fmt(s.get("lanes_checked")), "lanes checked"),
        _card(fmt(s.get("departures_checked")), "lane-departures checked"),
        _card(fmt(s.get("adverse")), f"adverse, on {fmt(s.get('lanes_at_risk'))} lane{'' if s.get('lanes_at_risk') == 1 else 's'}"),
        _card(fmt(s.get("reroutes")), "proposed reroutes"),
        _card(fmt(s.get("failed")), "failed"),
        _card(DASH if s.get("risk_avoided_h") is None else f"{fmt(float(s['risk_avoided_h']), 1)} h", "at risk avoided (sum)"),
        _card(fmt(s.get("events_avoided"), 0), "IMO events avoided"),
        _card(signed("delta_time_h", "h"), "\u0394 sailing time (sum)"),
        _card(signed("delta_fuel_t", "t"), "\u0394 fuel (sum)"),
        _card(signed("delta_co2_t", "t"), "\u0394 CO2 (sum)"),
        class_="cards",
    )


def _lane_rows(model: NightlyReport) -> list[dict]:
    """The lanes in matrix order (by their best case's rank, then by id), numbered from 1, with
    their cells and their worst hours at risk over the window."""
    grid = model.grid
    lanes = {ln.lane_id: ln for ln in model.lanes}
    if grid is None:
        return []
    best = {}
    for lane_id, g in grid.groupby("lane_id", sort=False):
        cases = pd.to_numeric(g["case"], errors="coerce")
        best[str(lane_id)] = float(cases.min()) if cases.notna().any() else math.inf
    ids = sorted(best, key=lambda i: (best[i], i))
    rows = []
    for n, lane_id in enumerate(ids, start=1):
        g = grid[grid["lane_id"].astype(str) == lane_id].sort_values("depart_utc")
        adverse = bool((g["status"] == "adverse").any())
        worst = pd.to_numeric(g["risk_h"], errors="coerce")
        worst_h = float(worst.max()) if worst.notna().any() else None
        ln = lanes.get(lane_id)
        rows.append({"number": n, "lane_id": lane_id, "line": ln, "cells": g, "worst_h": worst_h,
                     "risk": plots.risk_class(worst_h, adverse), "failed": bool((g["status"] == "failed").any()),
                     "reroute": bool(g["proposed"].notna().any())})
    return rows


def fleet_map(model: NightlyReport, rows: list[dict]) -> Markup:
    lanes = [{"number": r["number"], "lat_deg": r["line"].lat_deg if r["line"] is not None else np.zeros(0),
              "lon_deg": r["line"].lon_deg if r["line"] is not None else np.zeros(0), "risk": r["risk"], "failed": r["failed"],
              "reroute": r["reroute"]} for r in rows]
    return img_png(plots.fleet_map_png(lanes), "fleet map: every lane checked, coloured by its worst hours at risk", class_="fig fleet")


def _avoided_class(h, proposed: bool = True) -> str:
    """Colour class of an adverse cell: no proposal (``m-na``), a proposal that avoids no hour at
    risk (``m0``: proposed for fewer IMO events, or time and fuel), else by hours avoided."""
    if not proposed:
        return "m-na"
    if h is None or not math.isfinite(h) or h <= 0:
        return "m0"
    return f"m{next(k for k, b in enumerate(AVOIDED_BOUNDS_H, start=1) if h < b)}"


def _cell(rec) -> Markup:
    status, case = rec["status"], rec["case"]
    when = fmt_time(rec["depart_utc"])
    if status == "ok":
        beyond = rec.get("beyond", 0)
        if beyond and not pd.isna(beyond):  # the screen could not check the part after the weather's last time
            return el("td", "?", class_="m-part", title=f"{when}: no rule fired on the part with weather; {int(beyond)} centroid(s) "
                                                          "after the weather's last time were not screened")
        return el("td", "", class_="m-ok", title=f"{when}: no rule fired")
    k = int(case) if case is not None and not pd.isna(case) else None
    if status == "failed":
        inner = el("a", "\u2715", href=f"#{_anchor(k)}") if k else "\u2715"
        return el("td", inner, class_="m-fail", title=f"{when}: failed")
    h = rec["risk_avoided_h"]
    role = rec["proposed"] if isinstance(rec["proposed"], str) else None
    text = role_short(role) if role else "\u2013"
    tip = f"{when}: {rec['rules']}; " + (f"{role}, {fmt(h, 1)} h at risk avoided" if role else "no safer alternative")
    inner = el("a", text, href=f"#{_anchor(k)}") if k else text
    return el("td", inner, class_=_avoided_class(h, proposed=role is not None), title=tip)


def _roles_shown(model: NightlyReport) -> list:
    """The roles the matrix's legend spells out: the known ones, then any other the night proposed."""
    proposed = {p for p in model.grid["proposed"] if isinstance(p, str)} if model.grid is not None else set()
    return list(ROLE_SHORT) + sorted(proposed - set(ROLE_SHORT))


def matrix(model: NightlyReport, rows: list[dict]) -> Markup:
    """Rows lanes, columns departures; each cell coloured by hours at risk avoided, the proposed
    role in it, linked to its case."""
    if not rows:
        return Markup("")
    deps = sorted(pd.to_datetime(model.grid["depart_utc"], utc=True).unique())
    head = el("tr", el("th", "#"), el("th", "lane"), el("th", "route"), el("th", "worst at risk [h]", class_="num"),
              *(el("th", pd.Timestamp(t).strftime("%d"), el("br"), pd.Timestamp(t).strftime("%H:%M"), class_="dep") for t in deps))
    body = []
    for r in rows:
        by_t = {pd.Timestamp(rec["depart_utc"]): rec for rec in r["cells"].to_dict("records")}
        ln = r["line"]
        cells = [_cell(by_t[pd.Timestamp(t)]) if pd.Timestamp(t) in by_t else el("td", "", class_="m-none") for t in deps]
        body.append(el("tr", el("td", str(r["number"]), class_="num"), el("td", r["lane_id"]),
                       el("td", _route_text(ln) if ln is not None else DASH, class_="route"),
                       el("td", fmt(r["worst_h"], 1), class_="num"), *cells))
    legend = el("p", "Cells: hours at risk avoided by the proposed route (",
                *(el("span", label, class_=f"key {c}") for c, label in (("m1", "< 1 h"), ("m2", "1\u20133 h"), ("m3", "3\u20136 h"),
                                                                       ("m4", "\u2265 6 h"), ("m0", "0 h (other gains)"), ("m-na", "\u2013 no safer route"),
                                                                       ("m-ok", "no rule fired"),
                                                                       ("m-part", "? no rule fired on the part with weather"),
                                                                       ("m-fail", "failed"))),
                "); letters: the proposed route, ", "; ".join(f"{role_short(k)} = {plots.label_for(k)}" for k in _roles_shown(model)),
                ". Departure times UTC (day, hour). Worst at risk: the lane as planned, worst departure.", class_="muted small")
    return join([el("table", el("thead", head), el("tbody", *body), class_="matrix"), legend])


def _when(t) -> str:
    """Departure time without the zone (the column header says UTC)."""
    return fmt_time(t).replace(" UTC", "")


def reference_text(model: NightlyReport) -> str:
    """The reference every delta of the night is measured against, named (the cases' route sets
    say which role it is; a night compares against the lane as planned)."""
    refs = sorted({d.routes.reference for d in model.departures if d.routes is not None and d.routes.reference})
    if not refs:
        return "the reference of each case"
    named = " or ".join(("the lane as planned" if r == "lane" else f"the {plots.label_for(r)} route") for r in refs)
    return f"{named}, sailed by the same vessel model from the same departure in the same weather"


def _delta(dep, column, d):
    v = metric_delta(dep.routes, column)
    return fmt(v, d, signed=True) if math.isfinite(v) else DASH


def ranked_list(model: NightlyReport, n: int = TOP_N) -> Markup:
    """The top cases in rank order, the ranking key (hours at risk avoided) as a column."""
    cases = [(k, d) for k, d in enumerate(model.departures, start=1)][:n]
    if not cases:
        return el("p", "No adverse lane-departure in the window: every lane passed every threshold.")
    rows = []
    for k, d in cases:
        link = el("a", str(k), href=f"#{_anchor(k)}")
        if d.status == "failed":
            rows.append([link, d.lane_id, _when(d.depart_utc), el("span", "failed", class_="status-failed"), DASH, DASH, DASH, DASH])
            continue
        proposed = plots.label_for(d.routes.proposed) if d.routes is not None and d.routes.proposed else "no safer route"
        rows.append([link, d.lane_id, _when(d.depart_utc), proposed, el("b", fmt(d.risk_avoided, 1)),
                     fmt(d.events_avoided, 0) if d.events_avoided is not None else DASH, _delta(d, "time_h", 1), _delta(d, "fuel_t", 1)])
    head = ["#", "lane", "departure [UTC]", "proposed", "at risk avoided [h]", "IMO events avoided", "\u0394 time [h]", "\u0394 fuel [t]"]
    more = len(model.departures) - len(cases)
    return join([table(head, rows, numeric={0, 4, 5, 6, 7}, class_="top"),
                 el("p", "Ranked by hours at risk avoided (over an operator limit or in an IMO situation), then IMO events avoided, "
                    f"then extra time and fuel; \u0394 = proposed \u2212 {reference_text(model)}."
                    + (f" {more} more below." if more > 0 else ""), class_="muted small")])


def overview(model: NightlyReport) -> Markup:
    rows = _lane_rows(model)
    prov = model.provenance
    span = f"{fmt_time(prov.weather_start_utc)} \u2192 {fmt_time(prov.weather_end_utc)}" if prov.weather_start_utc is not None else DASH
    spacing = ("planned departures" if model.departure_step_h is None
               else f"departures every {fmt(model.departure_step_h, 1)} h")
    line = el("p", f"Forecast from {fmt_time(model.now_utc)}; {spacing} from "
              f"{fmt_time(model.window_start_utc)} to {fmt_time(model.window_end_utc)}; weather: "
              f"{', '.join(map(str, prov.weather_products)) or DASH} ({span}).", class_="muted small")
    top = el("div", el("h3", "Top cases"), ranked_list(model), class_="toplist")
    figure = el("div", fleet_map(model, rows) if rows else Markup(""), class_="fleetbox") if rows else Markup("")
    sums = el("p", f"Sums over the proposed reroutes; \u0394 = proposed \u2212 {reference_text(model)} (negative time, fuel "
              "and CO2 are savings).", class_="muted small")
    parts = [el("h2", "Overview", id="overview"), line, _cards(model), sums, *beyond_weather_note(model), *speed_capped_note(model),
             el("div", figure, top, class_="overview-row")]
    if rows:
        parts += [el("h3", "Lanes \u00d7 departures"), matrix(model, rows)]
    return join(parts)


def beyond_weather_text(n: int, n_ok: int, end: str) -> str:
    """What the night says (page, terminal) when lane-departures sail on after the weather's last
    time: the screen could not check those centroids, which is never the same as safe."""
    return (f"{n} lane-departure(s) sail on after the weather's last time ({end}): their centroids after it were not "
            f"screened (no rule can fire without weather), so {n_ok} of them shown as 'no rule fired' were screened on "
            "their part with weather only; time without weather is never counted as safe.")


def speed_capped_text(caps: list) -> str | None:
    """What the night says (page, terminal) when lanes were faster than their vessel can sail."""
    if not caps:
        return None
    shown = "; ".join(f"{c['lane']} ({c['vessel']}): AIS {c['ais_kn']:.1f} kn, sailed at {c['sailed_kn']:.1f} kn" for c in caps[:5])
    more = f"; and {len(caps) - 5} more" if len(caps) > 5 else ""
    return (f"{len(caps)} rerouted lane(s) were sailed faster by their ships than the vessel profile can sail at its "
            f"installed power: every route of these lanes, the lane as planned included, is sailed at the profile's "
            f"maximum-power speed instead: {shown}{more}.")


def speed_capped_note(model: NightlyReport) -> list:
    text = speed_capped_text((model.summary or {}).get("speed_capped"))
    return [el("p", text, class_="warn small")] if text else []


def beyond_weather_note(model: NightlyReport) -> list:
    s = model.summary or {}
    n = int(s.get("beyond_weather") or 0)
    if not n:
        return []
    end = fmt_time(model.provenance.weather_end_utc) if model.provenance.weather_end_utc is not None else DASH
    return [el("p", beyond_weather_text(n, int(s.get("beyond_weather_ok") or 0), end), class_="warn small")]


def departure_windows(model: NightlyReport) -> Markup:
    """Per lane ranked (``summary["departure_windows"]``, ``stormlane nightly --rank-departures``): every
    departure of the window with its route's arrival, time, distance, fuel, CO2, max Hs and hours over the
    limits, the best marked."""
    windows = (model.summary or {}).get("departure_windows") or []
    if not windows:
        return Markup("")
    parts = [el("h2", "Departure windows per lane", id="windows")]
    head = ["", "departure [UTC]", "arrival [UTC]", "time [h]", "distance [nmi]", "fuel [t]", "CO2 [t]", "max Hs [m]", "over limits [h]"]
    for w in windows:
        parts.append(el("h3", f"Lane {w['lane']}: objective {w['objective']}"))
        if w.get("error"):
            parts.append(el("p", f"not ranked: {w['error']}", class_="muted"))
            continue
        rows = []
        for i, r in enumerate(w["rows"]):
            mark = el("b", "best") if i == w.get("best") else ""
            if r.get("arrive_utc") is None:
                rows.append([mark, _when(pd.Timestamp(r["depart_utc"])), el("span", f"error: {r.get('error')}", class_="status-failed"), DASH, DASH,
                             DASH, DASH, DASH, DASH])
                continue
            rows.append([mark, _when(pd.Timestamp(r["depart_utc"])), _when(pd.Timestamp(r["arrive_utc"])), fmt(r["time_h"], 2), fmt(r["dist_nmi"], 1),
                         fmt(r.get("fuel_t"), 2), fmt(r.get("co2_t"), 2), fmt(r.get("max_hs_m"), 2), fmt(r.get("hours_over_limits"), 1)])
        parts.append(table(head, rows, numeric={3, 4, 5, 6, 7, 8}))
        parts.append(el("p", f"Ranked on {w.get('basis', '')}; best: least {'time' if w['objective'] == 'time' else 'fuel'} "
                        "(ties: the earlier departure).", class_="muted small"))
    return join(parts)


# ----------------------------------------------------------------------------- all cases, compact


def _worst(dep: LaneDeparture) -> str:
    if dep.worst_hs_m is None or not math.isfinite(dep.worst_hs_m):
        return DASH
    return f"{dep.worst_hs_m:.1f}"


def all_cases_table(model: NightlyReport) -> Markup:
    """One compact row per adverse or failed lane-departure, rules as chips, folded."""
    if not model.departures:
        return Markup("")
    rows = []
    for k, d in enumerate(model.departures, start=1):
        rs = d.routes
        proposed = (plots.label_for(rs.proposed) if rs is not None and rs.proposed else "no safer route") if d.status == "adverse" \
            else el("span", "failed", class_="status-failed")
        rows.append([el("a", str(k), href=f"#{_anchor(k)}"), d.lane_id, _route_text(d), d.vessel or DASH,
                     _when(d.depart_utc), chips(d.reasons, d.rules), _worst(d), proposed,
                     fmt(d.risk_avoided, 1), _delta(d, "time_h", 2), _delta(d, "fuel_t", 2), _delta(d, "co2_t", 2)])
    head = ["#", "lane", "route", "vessel", "departure [UTC]", "rules (worst value/limit, when)", "worst Hs on lane [m]", "proposed",
            "at risk avoided [h]", "\u0394 time [h]", "\u0394 fuel [t]", "\u0394 CO2 [t]"]
    return el("details", el("summary", f"All {len(model.departures)} adverse or failed lane-departures (table)"),
              table(head, rows, numeric={0, 6, 8, 9, 10, 11}, class_="compact"),
              el("p", f"\u0394: proposed \u2212 {reference_text(model)}.", class_="muted small"),
              class_="allcases")


# ----------------------------------------------------------------------------- cases


def _case_summary(k: int, d: LaneDeparture) -> Markup:
    if d.status == "failed":
        tail = el("span", "failed", class_="status-failed")
    else:
        rs = d.routes
        tail = (f"\u2192 {plots.label_for(rs.proposed)}, {fmt(d.risk_avoided, 1)} h at risk avoided" if rs is not None and rs.proposed
                else "no safer alternative")
    return el("summary", el("b", f"{k}. "), f"Lane {d.lane_id}: {_route_text(d)}, departing {fmt_time(d.depart_utc)} ", tail)


def _case_notes(d: LaneDeparture) -> Markup:
    """Every note a command would print for the case's routes (deviation not safer, fallback from
    hard to soft limits, weather held past its end, land repairs, optimality gaps)."""
    notes = route_notes(d.routes) if d.routes is not None else {}
    if not notes:
        return Markup("")
    return el("ul", *(el("li", el("b", plots.label_for(r) + ": "), "; ".join(n)) for r, n in notes.items()), class_="notes")


def case_section(k: int, d: LaneDeparture, provenance: Provenance, draw: bool = True) -> Markup:
    """A folded case; the anchor sits inside, so following it opens the case. ``draw``: with its
    map, plots, events and waypoints (the first ``max_detail`` cases that hold their routes)."""
    rules = el("div", el("b", "Rules fired (worst point of each): "), el("ul", *(el("li", r) for r in d.rules)) if d.rules else DASH)
    parts = [el("h3", f"{k}. Lane {d.lane_id}: {_route_text(d)}, departing {fmt_time(d.depart_utc)}", id=_anchor(k)),
             el("p", f"Vessel profile: {d.vessel or DASH}.", class_="muted small"), rules]
    rs = d.routes
    if d.status == "failed":
        parts.append(el("p", el("span", "failed: ", class_="status-failed"), d.error))
    elif rs is not None:
        parts.append(_case_notes(d))
        draw = draw and rs.detailed
        if draw:
            worst = (d.worst_lat_deg, d.worst_lon_deg) if d.worst_lat_deg is not None else None
            parts.append(figures_section(rs, provenance, worst=worst, worst_role=rs.reference or "lane"))
        parts.append(metrics_section(rs, compact=not draw, notes=False))
        if draw:
            parts += [events_section(rs), exports_section(rs),
                      waypoints_section(rs, roles={rs.proposed} if rs.proposed else {rs.reference})]
        else:
            parts += [exports_section(rs), el("p", "Shown without maps (beyond the report's detail limit, --max-detail).",
                                                class_="muted small")]
    return el("details", _case_summary(k, d), el("div", *parts, class_="case-body"), class_="case")


def drawn_cases(model: NightlyReport) -> set:
    """Ranks of the cases drawn with maps and plots: the first ``max_detail`` adverse cases that
    hold their routes."""
    held = [k for k, d in enumerate(model.departures, start=1) if d.status == "adverse" and d.routes is not None and d.routes.detailed]
    return set(held[: model.max_detail])


def nightly_html(model: NightlyReport) -> str:
    """The nightly report as an HTML string."""
    from dashboards.errors import ReportError
    from dashboards.html import page

    if not isinstance(model, NightlyReport):
        raise ReportError(f"render_nightly_report needs a NightlyReport, got {type(model).__name__}")
    parts = [overview(model), el("h2", "Adverse lane-departures"), all_cases_table(model) if model.departures else
             el("p", "No adverse lane-departure in the window: every lane passed every threshold.")]
    parts.append(departure_windows(model))
    drawn = drawn_cases(model)
    if model.departures:
        n_held = sum(1 for d in model.departures if d.status == "adverse" and d.routes is not None and d.routes.detailed)
        beyond = (f" (the first {len(drawn)} of {n_held} in ranking order: --max-detail)" if n_held > len(drawn) else "")
        parts.append(el("p", f"Each case below opens on a click (printing opens them all); {len(drawn)} with maps and plots{beyond}, "
                        "the others with their rules, notes and comparison table.", class_="muted small"))
        parts.extend(case_section(k, d, model.provenance, draw=k in drawn) for k, d in enumerate(model.departures, start=1))
    if model.exports:
        parts.append(el("p", "Route exports of the night: ", join([el("a", label, href=path) for label, path in model.exports.items()],
                                                                   sep=" \u00b7 "), " (index.csv inside lists every file).",
                        class_="muted"))
    parts.append(speed_loss_section(model.speed_loss))
    parts.append(provenance_section(model.provenance))
    subtitle = (f"run {model.run_id} \u00b7 forecast from {fmt_time(model.now_utc)} \u00b7 departures {fmt_time(model.window_start_utc)}"
                f" \u2192 {fmt_time(model.window_end_utc)}")
    return page(model.title, subtitle, join(parts))
