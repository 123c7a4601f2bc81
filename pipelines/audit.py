"""Retrospective voyage audit: the Prefect flow and the plain functions it wires.

``stormlane audit (--voyage ID | --mmsi N --start ISO --end ISO) [--weather FILE...]`` takes the
sailed AIS track from the workspace, evaluates it in the hindcast weather, computes the
time-optimal and minimum-distance routes for the same departure and vessel, the time-optimal route
under the vessel's limits (``safe_optimal``, :mod:`routing.safety`: hard constraints, soft
penalties when no route keeps within them) and the cargo-safe deviation of the voyage's lane when
the workspace has one, and compares them (:func:`routing.audit.audit_routes`).

Flow: ``load_audit_inputs`` (:mod:`pipelines.audit_inputs`; I/O task: workspace + weather files) -> :func:`audit_voyage` (plain)
-> ``store_audit`` (I/O task: results tables, optional HTML report).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd

from pipelines.audit_inputs import AuditInputs, _check_coverage, _utc, load_audit_inputs
from pipelines.runners import retry_transient
from thresholds.errors import StormlaneError

log = logging.getLogger(__name__)

#: A track longer than this many times the distance between its ends gets a finding: the A*
#: alternatives (straight between the ends) are not comparable with it.
DETOUR_FACTOR_NOTE = 3.0


def audit_voyage(inputs: AuditInputs, *, speed_loss_model="bowditch", alternatives: bool = True, safety: str = "hard",
                 check_with=None) -> dict:
    """The audit itself (plain function): track, its modelled twin, alternatives, evaluations, comparison.

    Like for like: the vessel sails at the voyage's calm-water speed (its AIS speeds in low sea
    states, else the profile's, :func:`routing.audit.calm_water_speed`) minus the model's speed
    loss, for the A* routes, the deviation and the sailed track re-timed (``as_sailed_modelled``);
    the AIS track at its AIS times (``as_sailed``) is the truth, and the difference of the two is
    the model's bias on this voyage. ``safety`` (``"hard"``, ``"soft"`` or ``"none"``) is the mode
    of the ``safe_optimal`` A* alternative (none: no such alternative). ``speed_loss_model``: a
    formula's name or a resolved :class:`pipelines.learn.SpeedLossChoice` (``learned:NAME``: the
    model is tabulated once for this vessel at the voyage's calm-water speed, and every route is
    sailed and evaluated by that table). ``check_with`` (a learned choice, when the audit sails a
    formula): its model is also compared with the AIS time of the voyage (``model_check``).

    Returns
    -------
    dict
        ``track`` (Route), ``evaluations``, ``table``, ``reference``, ``bias``, ``proposed``,
        ``findings`` (see :func:`routing.audit.audit_routes`), ``calm_water`` (the speed and where it
        comes from), ``plan_stats`` (routing statistics), ``deviation`` (Route or None), ``optimality``
        (:func:`routing.compare.optimality_gaps`) and ``notes`` (what was not computed and why).
    """
    import dataclasses

    from pipelines.routing_weather import field_from_dataset
    from routing.audit import audit_routes, calm_water_speed, detour_factor, track_to_route, trim_stationary_ends
    from routing.least_fuel_role import audit_least_fuel, audit_least_fuel_saving
    from routing.sampling import PointSampler

    track = track_to_route(inputs.positions)
    notes: list[str] = []
    if inputs.voyage is None:
        # A window may begin or end in port: the audited passage is the part under way.
        whole = track
        track = trim_stationary_ends(track)
        if track is not whole:
            notes.append(f"the window's first {(track.time_utc[0] - whole.time_utc[0]).total_seconds() / 3600:.1f} h and last "
                         f"{(whole.time_utc[-1] - track.time_utc[-1]).total_seconds() / 3600:.1f} h have the ship stationary: the "
                         f"audit covers {track.time_utc[0].isoformat()} .. {track.time_utc[-1].isoformat()}, under way")
    field_ = field_from_dataset(inputs.weather_ds)
    sampler = PointSampler.from_field(field_)
    _check_coverage(sampler, track.time_utc[0], track.time_utc[-1], "voyage")
    calm = calm_water_speed(track, sampler, inputs.vessel.speed_kn)
    vessel = dataclasses.replace(inputs.vessel, speed_kn=calm["speed_kn"]) if calm["speed_kn"] > inputs.vessel.min_speed_kn else inputs.vessel
    from pipelines.learn import resolve_speed_loss

    choice = resolve_speed_loss(speed_loss_model)
    table = choice.table(vessel, vessel.speed_kn)  # None for a formula
    alts: dict = {}
    plan = None
    plan_stats: dict = {}
    deviation = modelled = None
    optimality: list = []
    twin = None
    if alternatives:
        plan, modelled, alts, optimality = _alternatives(inputs, track, vessel, field_, sampler, choice.ship(vessel, table=table), safety,
                                                         notes)
        plan_stats = dict(plan.stats) if plan is not None else {}
        deviation = alts.get("deviation")
        if plan is not None and table is None:
            twin = audit_least_fuel(plan, track, vessel, alts, notes)
        elif plan is not None:
            notes.append("least-fuel route not computed with a learned speed-loss model (its table is for the voyage's one speed)")
    detour = detour_factor(track)
    if detour > DETOUR_FACTOR_NOTE:
        notes.append(f"the sailed track ({track.dist_nmi:.0f} nmi) is {detour:.1f} times the distance between its ends: "
                     "port calls or a loop inside the window? The A* alternatives sail straight between the ends, so their time, "
                     "fuel and exposure are not comparable with the track's")
    out = audit_routes(track, sampler, vessel, limits=inputs.limits, alternatives=alts, modelled=modelled, speed_loss_model=choice.label,
                       learned=table)
    from routing.bands import audit_uncertainty

    unc = audit_uncertainty(out["evaluations"], out["proposed"], out["reference"], track, plan if alternatives else None, sampler,
                            vessel, label=choice.label, limits=inputs.limits, check_learned=_check_table(check_with, vessel, notes))
    out["findings"] = out["findings"] + unc["findings"] + notes
    if "least_fuel" in out["evaluations"]:
        out["least_fuel"] = audit_least_fuel_saving(out, twin, sampler, vessel, inputs.limits, choice.label, table)
        out["findings"].append(f"least-fuel: {out['least_fuel']['note']}")
    out.update({"model_check": unc["model_check"], "bands": unc["bands"]})
    out.update({"track": track, "plan_stats": plan_stats, "deviation": deviation, "notes": notes, "sampler": sampler,
                "calm_water": calm, "optimality": optimality, "speed_loss_model": choice.label, "learned_table": table})
    return out


def _check_table(check_with, vessel, notes: list):
    """The table of the stored model compared with the formulas on the voyage (None when there is
    none, or the vessel lies outside what it was trained on: said in the notes)."""
    if check_with is None:
        return None
    try:
        return check_with.table(vessel, vessel.speed_kn)
    except StormlaneError as err:
        notes.append(f"{check_with.label} not compared with the AIS time: {err}")
        return None


def _alternatives(inputs: AuditInputs, track, vessel, field_, sampler, ship, safety: str, notes: list):
    """The A* plan, the modelled track, the alternatives (all sailed by one model, ``ship``) and the invariant's gaps."""
    from routing.compare import lane_departure, optimality_gaps, plan_bbox, retime
    from routing.deviate import threshold_inputs
    from routing.planner import RouteRequest, plan_routes

    start, goal = (float(track.lat_deg[0]), float(track.lon_deg[0])), (float(track.lat_deg[-1]), float(track.lon_deg[-1]))
    if inputs.lane is not None and len(inputs.lane) >= 2:
        base, props, what = inputs.lane.sort_values("seq"), {"lane_id": inputs.lane_id}, f"lane {inputs.lane_id}"
    else:
        from routing.audit import track_waypoints

        base, props, what = track_waypoints(track), {"base": "sailed track"}, "the sailed track"
        notes.append(("no lane for this voyage in the workspace" if inputs.voyage is not None else
                      "an --mmsi/--start/--end window is not a lane's voyage")
                     + ": the cargo-safe deviation walks the sailed track itself (a point every 5 nmi)")
    lat_all = np.r_[track.lat_deg, base["lat_deg"].to_numpy(dtype=float)]
    lon_all = np.r_[track.lon_deg, base["lon_deg"].to_numpy(dtype=float)]
    req = RouteRequest(start=start, goal=goal, depart_utc=track.time_utc[0], ship=ship, vessel_name=inputs.vessel_profile,
                       bbox=plan_bbox(start, goal, lat_all, lon_all, field_))
    try:
        plan = plan_routes(req, field_, safety=safety, vessel=vessel, limits=inputs.limits)
    except StormlaneError as err:
        notes.append(f"time-optimal and minimum-distance routes not computed, and the track not re-timed by the model: {err}; "
                     "the alternatives' deltas are then against the AIS times and hold the model's bias")
        return None, None, {}, []
    alts = {"optimal": _renamed(plan.routes["optimal_smoothed"], "optimal")}
    if "safe_optimal_smoothed" in plan.routes:
        alts["safe_optimal"] = _renamed(plan.routes["safe_optimal_smoothed"], "safe_optimal")
        sf = plan.stats["safety"]
        if sf["fallback"]:
            notes.append("no A* route keeps within the vessel's limits for this departure; the safe-optimal route "
                         f"minimises time plus {sf['penalty_per_h']:g} h per hour over them (soft limits)")
    alts["min_distance"] = _renamed(plan.routes["min_distance"], "min_distance")
    modelled = retime(track.lat_deg, track.lon_deg, track.time_utc[0], plan, name="as_sailed_modelled",
                      properties={k: v for k, v in track.properties.items() if k in ("mmsi", "n_fixes", "n_kept")})
    weather_at, check, cells = threshold_inputs(sampler, vessel, inputs.limits)
    try:
        pair = lane_departure(base["lat_deg"].to_numpy(dtype=float), base["lon_deg"].to_numpy(dtype=float),
                              base["speed_kn"].to_numpy(dtype=float), track.time_utc[0], plan, weather_at=weather_at, check=check,
                              cells=cells, properties=props)
        alts["deviation"] = pair["deviation"]
    except (StormlaneError, ValueError) as err:
        notes.append(f"deviation of {what} not computed: {err}")
    gaps = optimality_gaps({"as_sailed_modelled": modelled, **alts}, plan)
    return plan, modelled, alts, gaps


def _renamed(route, name):
    from routing.route import Route

    return Route(name, route.lat_deg, route.lon_deg, route.time_utc, route.leg_speed_kn, dict(route.weather), dict(route.properties))


def audit_id_of(inputs: AuditInputs) -> str:
    """Stable id of an audit: the voyage id, else ``<mmsi>@<start>``."""
    if inputs.voyage is not None:
        return f"voyage:{inputs.voyage['voyage_id']}"
    return f"{inputs.mmsi}@{inputs.start_utc.strftime('%Y-%m-%dT%H:%MZ')}"


#: The keys of the audit's JSON object (``stormlane audit --json``; printed by ``--help``).
JSON_KEYS = {
    "audit_id": "the voyage id, else <mmsi>@<start>",
    "voyage": "voyage_id, mmsi, ship_name, start_utc, end_utc, lane_id, origin, destination",
    "vessel_profile, operator_profile": "the vessel profile and the operator limits used",
    "speed_loss_model": "the speed-loss model every route is sailed by (a formula's name or learned:NAME)",
    "weather": "the weather files and product",
    "calm_water_speed": "speed_kn the model sails at, source (ais_low_sea: the voyage's AIS speeds in Hs <= low_hs_m over "
                        "low_sea_h hours; profile: the vessel profile's), low_sea_h, low_hs_m",
    "as_sailed": "the AIS track at its AIS times (the truth): time_h, dist_nmi, max_hs_m, mean_hs_m, fuel_t, co2_t, "
                 "exposure_h, adverse_h, n_safety_events, no_weather_h, sea_only, land_legs, land_nmi, events, waypoints ...",
    "as_sailed_modelled": "the same track re-timed by the vessel model from the same departure (same keys)",
    "bias": "the model's bias on this voyage, modelled minus AIS: time_h, time_pct, fuel_t, fuel_pct, co2_t, co2_pct",
    "reference": "the role every delta is measured against (as_sailed_modelled; as_sailed when the model could not run)",
    "optimal, safe_optimal, least_fuel, min_distance, deviation": "the alternatives, sailed by the same model (same keys); "
                                                                  "least_fuel arrives by the voyage's AIS arrival",
    "least_fuel_saving": "fuel_t, co2_t, arrive_utc, reference (the sailed track at the constant setting meeting the AIS "
                         "arrival), reference_fuel_t, saving_fuel_t, saving_co2_t, saving_pct (null with saving_note when no "
                         "fair reference), proposal (why least_fuel was or was not proposed), note",
    "proposed": "the recommended alternative or null (never one that is not sea-only or has more no_weather_h)",
    "comparison": "per role: the values and d_<metric> deltas (route minus reference), d_<metric>_pct",
    "optimality": "per route: gap_h (time-optimal minus it), tolerance_h (the mesh's discretisation), holds, constraint",
    "model_check": "the sailed track re-timed by each wave formula and the learned model (when used) at the same calm-water "
                   "speed against its AIS time: model, time_h, ais_time_h, bias_h, bias_pct (learned: time_h_p10, time_h_p90, "
                   "inside_band); error for a formula outside its range",
    "bands": "with learned:NAME, per role (the reference and the proposed route): time_h_p10/p50/p90 and fuel_t_p10/p50/p90 "
             "by the model's quantile tables, assumption",
    "findings": "plain-language findings, the bias against the claimed savings in words",
}


def audit_summary(inputs: AuditInputs, result: dict) -> dict:
    """The CLI's JSON object (:data:`JSON_KEYS`): one key per route (``as_sailed``,
    ``as_sailed_modelled``, ``deviation``, ``optimal``, ``safe_optimal``, ``min_distance``), the
    model's bias, the reference of the deltas, the voyage, the proposed alternative, the comparison
    table and the findings."""
    out = {
        "audit_id": audit_id_of(inputs),
        "voyage": {
            "voyage_id": None if inputs.voyage is None else str(inputs.voyage["voyage_id"]),
            "mmsi": inputs.mmsi,
            "ship_name": inputs.static.get("name"),
            "start_utc": inputs.start_utc.isoformat(),
            "end_utc": inputs.end_utc.isoformat(),
            "lane_id": inputs.lane_id,
            **inputs.port_names,
        },
        "vessel_profile": inputs.vessel_profile,
        "operator_profile": inputs.profile_name,
        "speed_loss_model": result.get("speed_loss_model", "bowditch"),
        "weather": {"files": inputs.weather_files, **{k: v for k, v in inputs.weather_meta.items() if isinstance(v, (str, int, float))}},
    }
    out["calm_water_speed"] = result.get("calm_water")
    for role, ev in result["evaluations"].items():
        out[role] = ev.to_dict(waypoints=True)
    out["bias"] = result.get("bias") or {}
    out["reference"] = result.get("reference")
    out["proposed"] = result["proposed"]
    table = result["table"].replace({np.nan: None})
    out["comparison"] = {role: row for role, row in table.to_dict(orient="index").items()}
    out["optimality"] = result.get("optimality") or []
    out["model_check"] = result.get("model_check") or []
    out["bands"] = result.get("bands") or {}
    out["least_fuel_saving"] = result.get("least_fuel")
    out["findings"] = result["findings"]
    return out


def audit_model(inputs: AuditInputs, result: dict, speed_loss_model: str | None = None):
    """The report model (:class:`dashboards.model.VoyageAudit`) of an audit, through
    :func:`pipelines.reporting.voyage_audit_model`."""
    from pipelines.reporting import voyage_audit_model

    lim = inputs.limits
    if hasattr(lim, "limits_for"):
        lim = lim.limits_for(inputs.vessel.vessel_class, inputs.vessel.lpp_m)
    voyage = dict(inputs.voyage or {})
    voyage.update({k: v for k, v in (inputs.port_names or {}).items() if v})
    return voyage_audit_model(
        result, mmsi=inputs.mmsi, static=inputs.static, voyage=voyage, vessel=inputs.vessel, limits=lim,
        weather_ds=inputs.weather_ds, weather_meta=inputs.weather_meta,
        speed_loss_model=str(speed_loss_model or result.get("speed_loss_model") or "bowditch"),
        profile_name=inputs.profile_name,
        methods=[
            "Track: AIS fixes thinned to one per 5 min; speeds made good between kept fixes.",
            "Weather met: bilinear over sea points, linear in time, sampled every <= 15 min of sailing.",
            "Fuel and emissions: STEAM2 with the wave power increase (routing/emissions.py).",
            "Like for like: the sailed track re-timed by the vessel model (as sailed, modelled) and every alternative are sailed "
            "by one model from the same departure in the same weather: the voyage's calm-water speed (its AIS speeds in low "
            "sea states, else the profile's) minus the speed loss, never below the floor. Deltas are against the modelled "
            "track; its difference from the AIS times is the model's bias on this voyage.",
            "Sea only: every leg of every route passes one land check (each great-circle leg against every 30\" land pixel it "
            "touches, land tolerated within 1.5 nmi of a berth); legs over land are replaced by the shortest sea path, and a "
            "route that cannot be repaired is not proposed.",
            "Alternatives: time-optimal (smoothed) and minimum-distance A* routes for the same departure and vessel; "
            "the time-optimal A* route under the vessel's operator and IMO limits (safe-optimal: cells over the limits "
            "forbidden, or penalised when no route avoids them); "
            "cargo-safe deviation of the voyage's lane, or of the sailed track when there is no lane "
            "(Spyrou-Sioula et al. 2022, Alg. 1, with sea legs and recomputed ETAs); "
            "the least-fuel route (a speed setting per leg, STEAM2 fuel) arriving by the voyage's AIS arrival, its saving "
            "measured against the sailed track at the one constant setting meeting that arrival (never against a route "
            "arriving at another time); it does not avoid the vessel's limits, the proposal rules (safety first) decide.",
        ] + [f"Note: {n}" for n in result.get("notes", [])],
    )


def store_audit(db, inputs: AuditInputs, result: dict, report: str | Path | None = None,
                speed_loss_model: str | None = None) -> dict:
    """Write the audit to the workspace's results tables and, optionally, the HTML report."""
    from pipelines.storage import open_workspace
    from pipelines.storage.results import write_audit

    summary = audit_summary(inputs, result)
    with open_workspace(db) as ws:
        write_audit(
            ws, summary["audit_id"], mmsi=inputs.mmsi, voyage_id=summary["voyage"]["voyage_id"], depart_utc=inputs.start_utc,
            arrive_utc=inputs.end_utc, vessel=inputs.vessel_profile, weather=inputs.weather_files,
            summary={k: summary[k] for k in ("voyage", "vessel_profile", "operator_profile", "proposed", "findings")},
            evaluations=result["evaluations"],
        )
    if report is not None:
        from dashboards.model import report_to_json
        from dashboards.report import render_audit_report

        model = audit_model(inputs, result, None if speed_loss_model is None else str(speed_loss_model))
        path = render_audit_report(model, Path(report))
        # the model beside the page (as the nightly run's report.json): `stormlane report` re-renders it
        model_path = path.with_suffix(".json") if path.suffix.lower() != ".json" else path.with_name(f"{path.stem}.model.json")
        model_path.write_text(report_to_json(model), encoding="utf-8")
        summary["report"], summary["model"] = str(path), str(model_path)
    return summary


def run_audit(db, *, voyage_id: str | None = None, mmsi: int | None = None, start=None, end=None, weather=(),
              vessel: str | None = None, profile: str | None = None, report=None, speed_loss_model="bowditch") -> dict:
    """Plain entry point (CLI, demo, tests): read, audit, store; returns :func:`audit_summary`.
    ``speed_loss_model``: a formula's name, ``learned:NAME`` (a model stored in ``db``) or a resolved
    :class:`pipelines.learn.SpeedLossChoice`."""
    from pipelines.learn import newest_learned, resolve_speed_loss

    choice = resolve_speed_loss(speed_loss_model, db)
    inputs = load_audit_inputs(db, voyage_id=voyage_id, mmsi=mmsi, start=start, end=end, weather_paths=weather or (),
                               vessel=vessel, profile=profile)
    result = audit_voyage(inputs, speed_loss_model=choice, check_with=None if choice.learned_name else newest_learned(db))
    return store_audit(db, inputs, result, report=report)


def audit_flow(db: str, voyage_id: str | None = None, mmsi: int | None = None, start: str | None = None, end: str | None = None,
               weather: list[str] | None = None, vessel: str | None = None, profile: str | None = None,
               report: str | None = None, speed_loss_model: str = "bowditch") -> dict:
    """The audit as a Prefect flow: read (I/O task, retried) -> audit (plain) -> store (I/O task, retried)."""
    from prefect import flow, task
    from prefect.cache_policies import NO_CACHE

    # inputs are DataFrames and Datasets: no input hashing / caching (the audit is cheap to redo)
    load = task(load_audit_inputs, name="load-audit-inputs", retries=3, retry_delay_seconds=[2, 5, 15], retry_condition_fn=retry_transient,
                cache_policy=NO_CACHE)
    compute = task(audit_voyage, name="audit-voyage", cache_policy=NO_CACHE)
    store = task(store_audit, name="store-audit", retries=3, retry_delay_seconds=[2, 5, 15], retry_condition_fn=retry_transient,
                 cache_policy=NO_CACHE)

    from pipelines.learn import resolve_speed_loss

    @flow(name="voyage-audit")
    def voyage_audit(db: str, voyage_id: str | None = None, mmsi: int | None = None, start: str | None = None, end: str | None = None,
                     weather: list[str] | None = None, vessel: str | None = None, profile: str | None = None,
                     report: str | None = None, speed_loss_model: str = "bowditch") -> dict:
        inputs = load(db, voyage_id=voyage_id, mmsi=mmsi, start=start, end=end, weather_paths=weather or (), vessel=vessel, profile=profile)
        result = compute(inputs, speed_loss_model=resolve_speed_loss(speed_loss_model, db))
        return store(db, inputs, result, report=report)

    return voyage_audit(db=str(db), voyage_id=voyage_id, mmsi=mmsi, start=start, end=end, weather=weather, vessel=vessel,
                        profile=profile, report=None if report is None else str(report), speed_loss_model=speed_loss_model)


if __name__ == "__main__":
    import sys

    print(audit_flow(db=sys.argv[1], voyage_id=sys.argv[2])["findings"])


def storm_voyage(db, storm: dict, kind: str = "port_to_port") -> dict | None:
    """The voyage of the workspace that sailed closest to a storm's centre at its peak.

    ``storm`` is an entry of the demo scenario's ``weather.storms`` (``peak_utc``, ``track_utc``,
    ``track_lat``, ``track_lon``). Only voyages at sea at the peak count; distance is measured
    from the ship's fix nearest to the peak time. Returns ``{"voyage_id", "mmsi", "dist_nmi"}``.
    """
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import read_positions
    from pipelines.storage.lanes import read_voyages
    from thresholds.geodesy import haversine_nmi

    peak = _utc(storm["peak_utc"])
    tt = pd.DatetimeIndex(pd.to_datetime(storm["track_utc"], utc=True)).asi8
    c_lat = float(np.interp(peak.value, tt, storm["track_lat"]))
    c_lon = float(np.interp(peak.value, tt, storm["track_lon"]))
    best = None
    with open_workspace(db) as ws:
        voyages = read_voyages(ws, kind=kind)
        at_sea = voyages[(voyages["depart_utc"] <= peak) & (voyages["arrive_utc"] >= peak)]
        for row in at_sea.itertuples(index=False):
            pos = read_positions(ws, mmsi=int(row.mmsi), start=peak - pd.Timedelta(hours=1), end=peak + pd.Timedelta(hours=1))
            if pos.empty:
                continue
            i = int(np.argmin(np.abs((pd.DatetimeIndex(pos["time_utc"]) - peak).total_seconds())))
            d = float(haversine_nmi(c_lat, c_lon, pos["lat_deg"].iloc[i], pos["lon_deg"].iloc[i]))
            if best is None or d < best["dist_nmi"]:
                best = {"voyage_id": str(row.voyage_id), "mmsi": int(row.mmsi), "dist_nmi": d}
    return best


def demo_step(ctx) -> dict:
    """Demo step: audit the voyage that sailed closest to the scenario's historical storm (A),
    in the scenario's hindcast files (else the workspace's weather), and write ``DIR/audit.html``."""
    import json

    truth = json.loads(ctx.scenario_json.read_text(encoding="utf-8"))
    weather = truth.get("weather", {})
    storms = [s for s in weather.get("storms", []) if "historical" in s.get("purpose", "")] or weather.get("storms", [])[:1]
    files = [str(ctx.workdir / f) for f in weather.get("files", [])]  # none: the workspace's weather tables
    if not storms:
        ctx.echo("  no storm in the scenario: no audit")
        return {"skipped": "no storm"}
    if files:
        try:
            import weather.io.local  # noqa: F401
        except ImportError:
            ctx.echo("  the weather readers are not installed: no audit")
            return {"skipped": "no weather readers"}
    pick = storm_voyage(ctx.db, storms[0])
    if pick is None:
        ctx.echo(f"  no voyage at sea at storm {storms[0].get('name')}'s peak ({storms[0]['peak_utc']}): no audit")
        return {"skipped": "no voyage in the storm"}
    report = ctx.workdir / "audit.html"
    out = run_audit(ctx.db, voyage_id=pick["voyage_id"], weather=files, report=report)
    v = out["voyage"]
    ctx.echo(f"  voyage {v['voyage_id']} (MMSI {v['mmsi']}, {v.get('origin', '?')} -> {v.get('destination', '?')}) passed "
             f"{pick['dist_nmi']:.0f} nmi from storm {storms[0].get('name', '')}'s centre at its peak")
    for role, row in out["comparison"].items():
        ctx.echo(f"  {role:<18} {row['time_h']:5.1f} h {row['dist_nmi']:6.1f} nmi  max Hs {row['max_hs_m']:4.1f} m  "
                 f"{row['exposure_h']:4.1f} h over limits  {int(row['n_safety_events'])} IMO event(s)  fuel {row['fuel_t']:6.2f} t")
    b = out.get("bias") or {}
    if b:
        ctx.echo(f"  model bias (modelled - AIS): time {b.get('time_h', 0):+.2f} h ({b.get('time_pct') or 0:+.1f} %), "
                 f"fuel {b.get('fuel_t', 0):+.2f} t ({b.get('fuel_pct') or 0:+.1f} %); deltas are against {out.get('reference')}")
    tail = [f for f in out["findings"][3:] if f.startswith(("Proposed alternative", "No alternative", "no A* route"))
            or "within the model's error" in f or "; not proposed: " in f]
    for line in out["findings"][1:3] + (tail or out["findings"][-1:]):
        ctx.echo(f"  {line}")
    ctx.echo(f"  audit report: {report}")
    return {"voyage_id": v["voyage_id"], "proposed": out["proposed"], "report": str(report),
            "as_sailed": {k: out["as_sailed"][k] for k in ("max_hs_m", "exposure_h", "n_safety_events", "time_h", "fuel_t")},
            "bias": out.get("bias"), "n_imo_events": out["as_sailed"]["n_imo_events"]}
