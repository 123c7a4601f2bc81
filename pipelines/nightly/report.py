"""Nightly stage 6, report (I/O): the HTML report, its model as JSON and the route exports."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from pipelines.nightly.night import ROLES, Night, NightResult
from pipelines.nightly.paths import _require_out_dir

def _stem(path_id: str, t: pd.Timestamp) -> str:
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in str(path_id))
    return f"{safe}_{t:%Y%m%dT%H%MZ}"


def _limits_of(night: Night, vessel):
    return night.limits.limits_for(vessel.vessel_class, vessel.lpp_m) if hasattr(night.limits, "limits_for") else night.limits


def _vessel_name(night: Night, path_id: str) -> str | None:
    """The vessel profile sailing this lane (lanes of one night differ in vessel class)."""
    return next((p.vessel_profile for p in night.paths if p.path_id == path_id), None)


def _hs_limit_m(night: Night, path_id: str) -> float | None:
    """The Hs limit of the vessel sailing this lane."""
    profile = _vessel_name(night, path_id)
    if profile is None:
        return None
    return getattr(_limits_of(night, night.vessels[profile]), "hs_max_m", None)


def _most_common_vessel(night: Night):
    names = [p.vessel_profile for p in night.paths]
    name = sorted(set(names), key=lambda n: (-names.count(n), n))[0]
    return night.vessels[name]


def write_report(night: Night, result: NightResult, started_utc: pd.Timestamp) -> dict:
    """I/O step: exports per adverse lane-departure, the HTML report and its model as JSON.

    Returns ``{"report": path, "model": path, "exports": n_files}`` (paths as strings).
    """
    from dashboards.exports import export_alternatives
    from dashboards.model import NightlyReport, report_to_json
    from dashboards.report import render_nightly_report
    from pipelines.reporting import lane_departure_model, provenance, speed_loss_curve

    out = Path(night.out)
    _require_out_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    departures, n_files = [], 0
    for case in result.cases:
        row = case["row"]
        rules = [r["text"] for r in case["reasons"]] or list(filter(None, row["rules"].split(",")))
        if case["outcome"] is None:
            departures.append(lane_departure_model(lane_id=row["path_id"], origin=row["origin"], destination=row["destination"],
                                                   depart_utc=row["depart_utc"], rules=rules, error=row["error"],
                                                   vessel=_vessel_name(night, row["path_id"])))
            continue
        evs = case["outcome"]["evaluations"]
        links = export_alternatives({role: evs[role].route for role in ROLES if role in evs}, out / "exports",
                                    _stem(row["path_id"], row["depart_utc"]), relative_to=out,
                                    proposed=case["outcome"]["proposed"], only_proposed=True)
        n_files += len(links)
        departures.append(lane_departure_model(
            lane_id=row["path_id"], origin=row["origin"], destination=row["destination"], depart_utc=row["depart_utc"],
            rules=rules, evaluations=evs, table=case["outcome"]["table"], proposed=case["outcome"]["proposed"],
            weather_ds=night.weather_ds, exports=links, risk_avoided=row["risk_avoided_h"],
            hs_limit_m=_hs_limit_m(night, row["path_id"]), vessel=_vessel_name(night, row["path_id"]),
            optimality=case["outcome"].get("optimality", ())))
    vessel = _most_common_vessel(night)
    limits = _limits_of(night, vessel)
    profiles = sorted({p.vessel_profile for p in night.paths})
    prov = provenance(
        weather_meta=night.weather_meta, weather_ds=night.weather_ds, vessel=vessel, speed_loss_model=night.params.speed_loss,
        limits=limits, profile_name=getattr(night.limits, "name", ""),
        weather_source=str(night.weather_meta.get("source") or night.weather_source),
        methods=[
            f"Run id {night.run_id}: digest of the forecast time, departures, lanes, weather values, vessels, limits and model.",
            "Screen: lane centroids timed from the departure at their typical speeds; weather of the nearest grid cell at the "
            "nearest time (DuckDB ASOF join); operator limits and IMO MSC.1/Circ.1228 at every centroid with the course to the next.",
            "Like for like: every route of a case is sailed by one vessel model from the same departure in the same weather: "
            f"the lane's typical AIS speed (median of its centroids' speeds) minus the {night.params.speed_loss} speed loss, never "
            "below the profile's floor. The reference of every delta is the lane as planned (its centroid path, sailed so).",
            "Sea only: every leg of every route passes one land check (each great-circle leg against every 30\" land pixel it "
            "touches, land tolerated within 1.5 nmi of a berth); legs over land are replaced by the shortest sea path.",
            "Deviation: Spyrou-Sioula et al. 2022, Alg. 1 (R-tree nearest passing cell within 3 h), legs kept at sea, ETAs recomputed.",
            f"A*: time-optimal (smoothed) and minimum-distance routes on a mesh at the weather's spacing, {night.params.speed_loss} "
            "speed loss at the lane's typical speed"
            + ("." if night.params.safety == "none" else f"; safe time-optimal route under the vessel's limits ({night.params.safety} "
               "constraints, soft when hard finds no route)."),
            "Ranking: risk avoided (hours over a limit or in an IMO situation, lane as planned minus proposed), then IMO events "
            "avoided, then extra time and fuel.",
            f"Vessel profiles by lane (AIS ship type of the lane's voyages): {', '.join(profiles)}; the provenance lists "
            f"{vessel.name}, the most common.",
        ],
    )
    model = NightlyReport(
        run_id=night.run_id, started_utc=started_utc, finished_utc=pd.Timestamp.now(tz="UTC"), now_utc=night.now_utc,
        window_start_utc=night.departures[0], window_end_utc=night.departures[0] + pd.Timedelta(hours=night.params.window_h),
        departure_step_h=night.params.step_h, lanes_checked=result.counts["lanes_checked"],
        departures_checked=result.counts["departures_checked"], departures=departures, provenance=prov,
        speed_loss=speed_loss_curve(vessel, night.params.speed_loss), max_detail=night.params.max_detail,
    )
    report = render_nightly_report(model, out / "report.html")
    model_path = out / "report.json"
    model_path.write_text(report_to_json(model), encoding="utf-8")
    return {"report": str(report), "model": str(model_path), "exports": n_files}
