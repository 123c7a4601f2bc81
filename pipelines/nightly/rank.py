"""Nightly stage 5, rank: the screen merged with the lanes' outcomes, ranked, as the rows to store."""

from __future__ import annotations

import json
import math

import pandas as pd

from pipelines.nightly.night import REFERENCE, Night, NightResult
from pipelines.nightly.reroute import _clean_route

def _risk(outcome: dict) -> dict:
    """Risk avoided and cost of the proposed alternative against the lane as planned (same model)."""
    evs = outcome.get("evaluations") or {}
    hist = evs.get(REFERENCE)
    prop = outcome.get("proposed")
    if hist is None or prop is None:
        return {"risk_avoided_h": 0.0, "events_avoided": 0, "delta_time_h": None, "delta_fuel_t": None, "delta_co2_t": None}
    h, a = hist.summary, evs[prop].summary
    return {"risk_avoided_h": float(h["adverse_h"] - a["adverse_h"]), "events_avoided": int(h["n_safety_events"] - a["n_safety_events"]),
            "delta_time_h": float(a["time_h"] - h["time_h"]), "delta_fuel_t": float(a["fuel_t"] - h["fuel_t"]),
            "delta_co2_t": float(a["co2_t"] - h["co2_t"])}


def assemble(night: Night, screen: pd.DataFrame, outcomes: list[dict]) -> NightResult:
    """Merge the screen with the per-lane outcomes, rank, and build the rows to store (pure).

    Ranking: adverse lane-departures by risk avoided (hours over an operator limit or in an IMO
    situation, lane as planned minus proposed; 0 without a proposal), then IMO events avoided, then
    the cost (extra hours, then extra fuel), then lane and time; failed ones after them.
    """
    by_key = {(o["path_id"], pd.Timestamp(o["depart_utc"])): o for o in outcomes}
    paths = {p.path_id: p for p in night.paths}
    cases = []
    dep_rows, route_rows, event_rows = [], [], []
    beyond = {}
    for r in screen.to_dict("records"):
        key = (r["path_id"], pd.Timestamp(r["depart_utc"]))
        p = paths[r["path_id"]]
        o = by_key.get(key)
        status = "ok"
        if r["error"] is not None and not (isinstance(r["error"], float) and math.isnan(r["error"])):
            status, error = "failed", r["error"]
        elif r["adverse"]:
            if o is None:
                status, error = "failed", "the lane's task did not return this departure"
            else:
                status, error = o["status"], o.get("error")
        else:
            error = None
        row = {"path_id": r["path_id"], "lane_id": p.lane_id, "origin": p.origin, "destination": p.destination,
               "depart_utc": key[1], "vessel_profile": p.vessel_profile, "status": status, "rules": ",".join(r["rules"]),
               "reasons_json": json.dumps(r["reasons"]), "n_points": int(r["n_points"]),
               "n_points_no_weather": int(r["n_points_no_weather"]), "max_hs_m": r["max_hs_m"],
               "worst_time_utc": r["worst_time_utc"], "worst_lat_deg": r["worst_lat_deg"], "worst_lon_deg": r["worst_lon_deg"],
               "proposed": None, "rank": None, "risk_avoided_h": None, "events_avoided": None, "delta_time_h": None,
               "delta_fuel_t": None, "delta_co2_t": None, "error": error}
        if status == "adverse":
            row["proposed"] = o["proposed"]
            row.update(_risk(o))
        dep_rows.append(row)
        n_beyond = int(r.get("n_points_beyond_weather") or 0)
        if n_beyond and status != "failed":
            beyond[key] = {"n_beyond": n_beyond, "status": status}
        if status in ("adverse", "failed"):
            cases.append({"row": row, "reasons": r["reasons"], "outcome": o if status == "adverse" else None})

    def rank_key(case):
        row = case["row"]
        if row["status"] == "failed":
            return (1, 0.0, 0, 0.0, 0.0, row["path_id"], row["depart_utc"])
        return (0, -round(row["risk_avoided_h"], 9), -row["events_avoided"], round(row["delta_time_h"] or 0.0, 9),
                round(row["delta_fuel_t"] or 0.0, 9), row["path_id"], row["depart_utc"])

    cases.sort(key=rank_key)
    for k, case in enumerate(cases, start=1):
        case["row"]["rank"] = k
        o = case["outcome"]
        if o is None:
            continue
        for role, ev in o["evaluations"].items():
            s = ev.summary
            route_rows.append({"path_id": case["row"]["path_id"], "depart_utc": case["row"]["depart_utc"], "role": role,
                               **{c: s.get(c) for c in ("time_h", "dist_nmi", "max_hs_m", "mean_hs_m", "fuel_t", "co2_t",
                                                         "exposure_h", "adverse_h", "n_safety_events", "no_weather_h")},
                               "route_json": _clean_route(ev.route).to_json()})
            for e in ev.events:
                event_rows.append({"path_id": case["row"]["path_id"], "depart_utc": case["row"]["depart_utc"], "role": role,
                                   "criterion": e["criterion"], "kind": e["kind"], "start_utc": pd.Timestamp(e["start_utc"]),
                                   "end_utc": pd.Timestamp(e["end_utc"]), "duration_h": float(e["duration_h"]),
                                   "lat_deg": e.get("start_lat_deg"), "lon_deg": e.get("start_lon_deg"), "max_margin": e.get("max_margin")})
    from pipelines.storage.nightly import DEPARTURE_COLUMNS, EVENT_COLUMNS, ROUTE_COLUMNS

    deps = pd.DataFrame(dep_rows, columns=list(DEPARTURE_COLUMNS))
    counts = {
        "lanes_checked": len(night.paths),
        "departures_checked": len(deps),
        "adverse": int((deps["status"] == "adverse").sum()),
        "failed": int((deps["status"] == "failed").sum()),
        "reroutes": int(((deps["status"] == "adverse") & deps["proposed"].notna()).sum()),
    }
    windows = sorted((o["lane_window"] for o in outcomes if o.get("lane_window")), key=lambda w: w["lane"])
    from pipelines.nightly.reroute import speed_caps

    caps = speed_caps(night, deps.loc[deps["status"] == "adverse", "path_id"])  # the lanes the vessel model sailed
    return NightResult(deps, pd.DataFrame(route_rows, columns=list(ROUTE_COLUMNS)),
                       pd.DataFrame(event_rows, columns=list(EVENT_COLUMNS)), cases, counts, windows, beyond, caps)


def overview_of(result: NightResult, top: int = 10) -> dict:
    """The night's overview as one dict (pure): the counts, the sums over the proposed reroutes
    (proposed minus the lane as planned, sailed by the same model), and the ``top`` cases in rank
    order with the ranking key. The report's overview shows these figures, ``stormlane nightly``
    prints them and ``--json`` returns them: one computation, so the three agree."""
    d = result.departures
    adverse = d[d["status"] == "adverse"]
    re = adverse[adverse["proposed"].notna()]

    def total(col):
        v = pd.to_numeric(re[col], errors="coerce")
        return round(float(v.sum()), 6) + 0.0 if v.notna().any() else None

    ranked = d[d["rank"].notna()].sort_values("rank").head(top)
    beyond = result.beyond_weather or {}
    return {
        **result.counts,
        # sailing on after the weather's last time: those centroids were not screened (no rule
        # can fire without weather), so an `ok` among these was screened on its part with weather only
        "beyond_weather": len(beyond),
        "beyond_weather_ok": sum(1 for b in beyond.values() if b["status"] == "ok"),
        # lanes faster than their vessel can sail: the model sailed them at its maximum-power speed
        "speed_capped": list(result.speed_capped or []),
        "lanes_at_risk": int(adverse["path_id"].nunique()),
        "lanes_with_reroute": int(re["path_id"].nunique()),
        "risk_avoided_h": total("risk_avoided_h"),
        "events_avoided": int(pd.to_numeric(re["events_avoided"], errors="coerce").fillna(0).sum()),
        "delta_time_h": total("delta_time_h"),
        "delta_fuel_t": total("delta_fuel_t"),
        "delta_co2_t": total("delta_co2_t"),
        "ranking_key": "risk_avoided_h: hours over an operator limit or in an IMO situation, lane as planned minus proposed "
                       "(then IMO events avoided, then extra time and fuel)",
        "top": [{"rank": int(r["rank"]), "case": f"case-{int(r['rank'])}", "lane": r["path_id"], "origin": r["origin"],
                 "destination": r["destination"], "depart_utc": r["depart_utc"].isoformat(), "status": r["status"],
                 "rules": r["rules"], "proposed": r["proposed"], "risk_avoided_h": _num(r["risk_avoided_h"]),
                 "events_avoided": None if r["events_avoided"] is None or pd.isna(r["events_avoided"]) else int(r["events_avoided"]),
                 "delta_time_h": _num(r["delta_time_h"]), "delta_fuel_t": _num(r["delta_fuel_t"]), "error": r["error"]}
                for r in ranked.to_dict("records")],
        **({"departure_windows": result.windows} if result.windows else {}),
    }


def _num(x) -> float | None:
    return None if x is None or pd.isna(x) else round(float(x), 6) + 0.0  # + 0.0: no -0.0 in the JSON
