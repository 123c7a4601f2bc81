"""Nightly stage 6, report (I/O): the HTML report, its model as JSON and the route exports.

The model holds what the page needs (issue 22): every case's rules, notes and comparison table;
the routes, weather slice, events and Hs samples of the first ``max_detail`` cases only (the ones
drawn); every lane's centroid path (the fleet map) and one row per lane-departure (the matrix);
the overview's figures (:func:`pipelines.nightly.rank.overview_of`, which the CLI prints too).
Exports go into one ``exports.zip`` with an index (``--exports proposed|all|none``).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from pipelines.nightly.night import ROLES, Night, NightResult
from pipelines.nightly.paths import _require_out_dir


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


def _methods(night: Night) -> list[str]:
    """The method notes of the provenance section."""
    return [
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
        "Vessel profiles by lane (AIS ship type of the lane's voyages): every profile used and the limit set applied to it "
        "are listed under 'Vessels and limits'; the speed-loss curve is drawn for the most common one.",
    ]


def _weather_spans(meta: dict, ds) -> list[dict]:
    """Per weather product read: its variables, time span and step (from the readers' metadata)."""
    spans: dict = {}
    for m in meta.get("inputs") or []:
        prod = str(m.get("product") or "")
        s = spans.setdefault(prod, {"product": prod, "variables": set(), "start_utc": m.get("start_utc"), "end_utc": m.get("end_utc"),
                                    "step_h": None})
        s["variables"] |= set((m.get("variables") or {}).keys())
        s["start_utc"] = min(filter(None, [s["start_utc"], m.get("start_utc")]), default=None)
        s["end_utc"] = max(filter(None, [s["end_utc"], m.get("end_utc")]), default=None)
        n = int(m.get("n_times") or 0)
        if n > 1 and m.get("start_utc") and m.get("end_utc"):
            s["step_h"] = round((pd.Timestamp(m["end_utc"]) - pd.Timestamp(m["start_utc"])).total_seconds() / 3600.0 / (n - 1), 3)
    out = [{**s, "variables": ", ".join(sorted(s["variables"]))} for s in spans.values()]
    if not out and ds is not None:
        times = pd.DatetimeIndex(ds["time_utc"].values)
        out = [{"product": str(meta.get("product") or ds.attrs.get("product", "")), "variables": ", ".join(sorted(ds.data_vars)),
                "start_utc": times[0].isoformat() + "Z", "end_utc": times[-1].isoformat() + "Z",
                "step_h": round(float((times[1] - times[0]).total_seconds()) / 3600.0, 3) if len(times) > 1 else None}]
    return out


def _vessels(night: Night) -> list[dict]:
    """Every vessel profile the night used, with the limit set applied to it and its lanes."""
    from pipelines.reporting import limits_for_report

    lanes: dict = {}
    for p in night.paths:
        lanes[p.vessel_profile] = lanes.get(p.vessel_profile, 0) + 1
    from pipelines.learn import class_not_learned

    beside = night.learned_limits or {}
    learned = {r["vessel_profile"]: r for r in beside.get("rows", [])}
    out = []
    for name, vessel in sorted(night.vessels.items()):
        limits = _limits_of(night, vessel)
        d = vessel.to_dict()
        shown = limits_for_report(limits)
        if name in learned:  # beside the configured limits: evidence, not a limit
            r = learned[name]
            shown[f"AIS voluntary slow-down ({beside['model']}, {r['ship_class']})"] = (
                f"not learned: {r['why_none']}" if class_not_learned(r)
                else "none found" if r["learned_hs_m"] is None else f"above Hs {r['learned_hs_m']:.2f} m, head-to-bow seas")
        out.append({"name": name, "lanes": lanes.get(name, 0),
                    "thresholds_profile": f"{getattr(night.limits, 'name', '')}: {getattr(limits, 'name', '')}".strip(": "),
                    "limits": shown,
                    "particulars": {k: d[k] for k in ("vessel_class", "speed_kn", "lpp_m", "beam_m", "draught_m", "dwt_t",
                                                      "installed_power_kw", "gm_m") if d.get(k) is not None}})
    return out


def _models(night: Night) -> dict:
    p = night.params
    return {
        "speed loss": f"{p.speed_loss} (at the lane's typical AIS speed, never below the profile's floor)",
        "fuel and emissions": "STEAM2 (Jalkanen et al. 2009/2012): P(v) = EL P_inst (v/v_design)^3, wave power increase, SFOC by load",
        "safety rules": "IMO MSC.1/Circ.1228 (surf-riding/broaching, synchronous and parametric roll, successive high waves) "
                        "+ the operator limits of each vessel",
        "routes": "cargo-safe deviation (Spyrou-Sioula et al. 2022, Alg. 1); time-optimal and minimum-distance A* "
                  + ("" if p.safety == "none" else f"and safe time-optimal A* ({p.safety} limits, soft when hard finds none) ")
                  + "on a lat/lon mesh (SIMROUTE)",
        "land": "global-land-mask 30\" raster, one check of every great-circle leg",
        **({"learned limits": f"{night.learned_limits['model']}: per ship class, the Hs above which the fleet's AIS shows masters "
                              "slowing down voluntarily (head-to-bow seas), listed beside each vessel's operator limits: evidence "
                              "for the operator, not a replacement (the screen uses the configured limits)"}
           if night.learned_limits else {}),
    }


def _provenance(night: Night):
    from pipelines.reporting import provenance

    vessel = _most_common_vessel(night)
    prov = provenance(
        weather_meta=night.weather_meta, weather_ds=night.weather_ds, vessel=vessel, speed_loss_model=night.params.speed_loss,
        limits=_limits_of(night, vessel), profile_name=getattr(night.limits, "name", ""),
        weather_source=str(night.weather_meta.get("source") or night.weather_source), methods=_methods(night))
    prov.vessels = _vessels(night)
    prov.weather_spans = _weather_spans(night.weather_meta, night.weather_ds)
    prov.models = _models(night)
    return prov


def _lane_lines(night: Night) -> list:
    from dashboards.model import LaneLine

    return [LaneLine(lane_id=p.path_id, origin=p.origin, destination=p.destination, vessel=p.vessel_profile,
                     lat_deg=p.centroids["lat_deg"].to_numpy(float), lon_deg=p.centroids["lon_deg"].to_numpy(float))
            for p in night.paths]


def _grid(result: NightResult) -> pd.DataFrame:
    """One row per lane-departure checked, for the matrix (and the fleet map's colours)."""
    d = result.departures
    risk = {}
    for case in result.cases:
        o = case["outcome"]
        if o is not None and "lane" in o["evaluations"]:
            risk[(case["row"]["path_id"], case["row"]["depart_utc"])] = float(o["evaluations"]["lane"].summary["adverse_h"])
    keys = list(zip(d["path_id"], d["depart_utc"]))
    return pd.DataFrame({
        "lane_id": d["path_id"].astype(str).to_numpy(), "depart_utc": pd.to_datetime(d["depart_utc"], utc=True).to_numpy(),
        "status": d["status"].to_numpy(), "rules": d["rules"].fillna("").to_numpy(),
        "risk_h": [risk.get(k, float("nan")) for k in keys],
        "risk_avoided_h": pd.to_numeric(d["risk_avoided_h"], errors="coerce").to_numpy(dtype=float),
        "proposed": [x if isinstance(x, str) else None for x in d["proposed"]],
        "case": pd.to_numeric(d["rank"], errors="coerce").to_numpy(dtype=float),
        # centroids timed after the weather's last time (not screened): the matrix marks an `ok` cell with them
        "beyond": [int(result.beyond_weather.get(k, {}).get("n_beyond", 0)) for k in keys],
    }).assign(depart_utc=lambda f: pd.to_datetime(f["depart_utc"], utc=True))


def _write_exports(night: Night, result: NightResult, out: Path) -> dict | None:
    """``exports.zip`` (proposed routes only by default; every route with ``--exports all``)."""
    from dashboards.archive import write_exports_zip

    mode = night.params.exports
    stale = out / "exports.zip"
    if mode == "none":
        stale.unlink(missing_ok=True)
        return None
    cases = []
    for case in result.cases:
        o, row = case["outcome"], case["row"]
        if o is None:
            continue
        cases.append({"rank": row["rank"], "lane_id": row["path_id"], "origin": row["origin"], "destination": row["destination"],
                      "depart_utc": row["depart_utc"], "proposed": o["proposed"], "risk_avoided_h": row["risk_avoided_h"],
                      "routes": {role: o["evaluations"][role].route for role in ROLES if role in o["evaluations"]}})
    return write_exports_zip(cases, stale, mode=mode, when=night.now_utc)


def _case_model(night: Night, case: dict, detailed: bool, archive: dict | None):
    from pipelines.reporting import lane_departure_model

    row = case["row"]
    rules = [r["text"] for r in case["reasons"]] or list(filter(None, row["rules"].split(",")))
    common = dict(lane_id=row["path_id"], origin=row["origin"], destination=row["destination"], depart_utc=row["depart_utc"],
                  rules=rules, vessel=_vessel_name(night, row["path_id"]), reasons=case["reasons"])
    if case["outcome"] is None:
        return lane_departure_model(error=row["error"], **common)
    o = case["outcome"]
    members = (archive or {}).get("members", {}).get(row["rank"], [])
    links = {f"{m.rsplit('.', 1)[1].upper()} {m.rsplit('_', 1)[-1].rsplit('.', 1)[0]}": f"exports.zip#{m}" for m in members}
    events = row["events_avoided"]
    return lane_departure_model(
        evaluations=o["evaluations"], table=o["table"], proposed=o["proposed"], weather_ds=night.weather_ds, exports=links,
        risk_avoided=row["risk_avoided_h"], events_avoided=None if events is None or pd.isna(events) else int(events),
        hs_limit_m=_hs_limit_m(night, row["path_id"]), optimality=o.get("optimality", ()), detailed=detailed,
        bands=o.get("bands"), **common)


def _curve(night: Night):
    """The speed-loss curve of the most common vessel at its service speed (a learned model's table
    for it; no curve, said in the methods, when that vessel lies outside what the model was trained on)."""
    from pipelines.reporting import speed_loss_curve
    from thresholds.errors import StormlaneError

    vessel = _most_common_vessel(night)
    choice = night.speed_model
    try:
        table = choice.table(vessel) if choice is not None else None
    except StormlaneError:
        return None
    return speed_loss_curve(vessel, night.params.speed_loss, learned=table)


def write_report(night: Night, result: NightResult, started_utc: pd.Timestamp) -> dict:
    """I/O step: the exports archive, the HTML report and its model as JSON.

    Returns ``{"report", "model", "exports_zip"}`` (paths as strings; ``exports_zip`` None with
    ``--exports none``), ``exports`` (route files in the archive) and the sizes in bytes.
    """
    from dashboards.model import NightlyReport, report_to_json
    from dashboards.report import render_nightly_report
    from pipelines.nightly.rank import overview_of

    out = Path(night.out)
    _require_out_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    archive = _write_exports(night, result, out)
    detailed = {id(c) for c in [c for c in result.cases if c["outcome"] is not None][: night.params.max_detail]}
    departures = [_case_model(night, case, id(case) in detailed, archive) for case in result.cases]
    window = night.window()
    model = NightlyReport(
        run_id=night.run_id, started_utc=started_utc, finished_utc=pd.Timestamp.now(tz="UTC"), now_utc=night.now_utc,
        window_start_utc=window["start_utc"], window_end_utc=window["end_utc"],
        departure_step_h=window["step_h"], lanes_checked=result.counts["lanes_checked"],
        departures_checked=result.counts["departures_checked"], departures=departures, provenance=_provenance(night),
        speed_loss=_curve(night), max_detail=night.params.max_detail,
        lanes=_lane_lines(night), grid=_grid(result), summary=overview_of(result),
        exports={"exports.zip": "exports.zip"} if archive else {},
    )
    report = render_nightly_report(model, out / "report.html")
    model_path = out / "report.json"
    model_path.write_text(report_to_json(model), encoding="utf-8")
    return {"report": str(report), "model": str(model_path), "exports": (archive or {}).get("files", 0),
            "exports_zip": (archive or {}).get("path"), "exports_bytes": (archive or {}).get("bytes", 0),
            "report_bytes": report.stat().st_size, "model_bytes": model_path.stat().st_size}
