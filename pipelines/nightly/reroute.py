"""Nightly stage 4, reroute: one job per lane with adverse departures (what a worker receives),
and its work: the lane as planned, the deviation and the A* routes, evaluated like for like."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pandas as pd

from pipelines.nightly.night import REFERENCE, VOLATILE_PROPERTIES, LaneJob, Night

log = logging.getLogger(__name__)

def lane_jobs(night: Night, screen: pd.DataFrame) -> list[LaneJob]:
    """One job per lane with at least one adverse departure (pure)."""
    from pipelines.routing_weather import field_from_dataset

    field_ = field_from_dataset(night.weather_ds)
    adverse = screen[screen["adverse"] & screen["error"].isna()]
    jobs = []
    by_id = {p.path_id: p for p in night.paths}
    for pid, g in adverse.groupby("path_id", sort=True):
        p = by_id[pid]
        jobs.append(LaneJob(path_id=pid, lane_id=p.lane_id, centroids=p.centroids, vessel=night.vessels[p.vessel_profile],
                            limits=night.limits, speed_loss=night.params.speed_loss,
                            departures=sorted(pd.Timestamp(t) for t in g["depart_utc"]), weather=field_,
                            safety=night.params.safety, learned=_lane_table(night, p), least_fuel=night.params.least_fuel,
                            rank_departures=night.params.rank_departures, window=night.path_departures(p)))
    return jobs


def _lane_table(night: Night, p):
    """A learned model's table for the lane's vessel at the lane's typical speed, tabulated here once
    (workers get the table, not the fitted model); the error when the vessel lies outside what the
    model was trained on (the lane then fails with it); None for a formula."""
    from thresholds.errors import StormlaneError

    if night.speed_model is None or night.speed_model.learned_name is None:
        return None
    vessel = lane_speed_vessel(night.vessels[p.vessel_profile], p.centroids.sort_values("seq"))
    try:
        return night.speed_model.table(vessel, vessel.speed_kn)
    except StormlaneError as err:
        return err


def lane_speed_vessel(vessel, centroids: pd.DataFrame):
    """The vessel sailing at the lane's typical speed (:func:`lane_speed`), so the A* routes and the
    evaluations compare like with like; the profile's speed when the lane has none."""
    sailed, _ = lane_speed(vessel, centroids)
    return vessel if sailed is None else dataclasses.replace(vessel, speed_kn=sailed)


def lane_speed(vessel, centroids: pd.DataFrame) -> tuple[float | None, float | None]:
    """``(sailed, typical)``: the lane's typical AIS speed (median of the centroids' speeds) and the
    calm-water speed the vessel model sails it at: the same, capped at the vessel's maximum-power
    speed (:func:`routing.fuel.max_power_speed_kn`, STEAM2's cubic law at the installed power)
    when the lane's ships sailed faster than this vessel can (an aframax profile on a ro-pax lane:
    20.4 kn against 16.5). ``(None, None)`` when the lane has no speed above the vessel's minimum
    (the profile's own speed is sailed). [kn]"""
    from routing.emissions import Engine
    from routing.fuel import max_power_speed_kn

    v = centroids["speed_kn"].to_numpy(dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    if v.size == 0 or not float(np.median(v)) > vessel.min_speed_kn:
        return None, None
    typical = float(np.median(v))
    try:
        top = max_power_speed_kn(Engine.from_vessel(vessel))
    except (TypeError, ValueError):  # a profile without engine data: no cap to apply
        return typical, typical
    return min(typical, top), typical


def speed_caps(night: Night, path_ids) -> list[dict]:
    """The lanes of ``path_ids`` whose typical AIS speed their vessel cannot make (:func:`lane_speed`):
    ``lane``, ``vessel``, ``ais_kn`` and ``sailed_kn`` (the maximum-power speed), said by the night."""
    out = []
    paths = {p.path_id: p for p in night.paths}
    for pid in sorted(set(path_ids)):
        p = paths[pid]
        vessel = night.vessels.get(p.vessel_profile)
        sailed, typical = (None, None) if vessel is None else lane_speed(vessel, p.centroids.sort_values("seq"))
        if sailed is not None and sailed < typical:
            out.append({"lane": pid, "vessel": vessel.name, "ais_kn": round(typical, 2), "sailed_kn": round(sailed, 2)})
    return out


def _clean_route(route, name: str | None = None):
    """A route without run-dependent properties (timings), optionally renamed."""
    from routing.route import Route

    props = {k: v for k, v in route.properties.items() if k not in VOLATILE_PROPERTIES}
    return Route(name or route.name, route.lat_deg, route.lon_deg, route.time_utc, route.leg_speed_kn, dict(route.weather), props)


def reroute_lane(job: LaneJob) -> list[dict]:
    """The work of one lane (pure): deviation, A* routes and evaluations per adverse departure.

    Returns
    -------
    list of dict
        Per departure: ``path_id``, ``depart_utc``, ``status`` (``adverse`` or ``failed``),
        ``evaluations`` (role -> RouteEvaluation), ``table`` (comparison), ``proposed`` and
        ``error``. A departure that raises is ``failed`` with ``"<Error>: message"``; the
        others still run.
    """
    from routing.astar import ShipModel
    from routing.audit import propose
    from routing.compare import lane_departure, optimality_gaps, plan_bbox, sea_checks
    from routing.deviate import threshold_inputs
    from routing.evaluate import comparison_table, evaluate_route
    from routing.planner import RouteRequest, plan_routes
    from routing.sampling import PointSampler

    out = []
    try:
        c = job.centroids.sort_values("seq")
        lat, lon, spd = c["lat_deg"].to_numpy(float), c["lon_deg"].to_numpy(float), c["speed_kn"].to_numpy(float)
        vessel = lane_speed_vessel(job.vessel, c)
        sampler = PointSampler.from_field(job.weather)
        weather_at, check, cells = threshold_inputs(sampler, vessel, job.limits)
        if isinstance(job.learned, Exception):
            raise job.learned
        ship = (ShipModel.from_vessel(vessel, "learned", learned=job.learned) if job.learned is not None
                else ShipModel.from_vessel(vessel, job.speed_loss))
        start, goal = (float(lat[0]), float(lon[0])), (float(lat[-1]), float(lon[-1]))
        bbox = plan_bbox(start, goal, lat, lon, job.weather)
        fixed = sea_checks(lat, lon)[1](lat, lon)  # the lane's legs over land, repaired once for every departure
    except Exception as err:  # noqa: BLE001 - the whole lane fails, the night goes on
        log.warning("lane %s: setup failed: %s", job.path_id, err)
        return [{"path_id": job.path_id, "depart_utc": t, "status": "failed", "error": f"{type(err).__name__}: {err}"}
                for t in job.departures]
    props = {"lane_id": job.lane_id, "path_id": job.path_id, "vessel": vessel.name}
    for t in job.departures:
        try:
            req = RouteRequest(start, goal, t, ship, vessel_name=vessel.name, bbox=bbox)
            if job.safety == "none":
                plan = plan_routes(req, job.weather)
            else:
                plan = plan_routes(req, job.weather, safety=job.safety, vessel=vessel, limits=job.limits)
            routes = lane_departure(lat, lon, spd, t, plan, weather_at=weather_at, check=check, cells=cells, properties=props,
                                    fixed=fixed)
            if "safe_optimal_smoothed" in plan.routes:
                routes["safe_optimal"] = _clean_route(plan.routes["safe_optimal_smoothed"], "safe_optimal")
            routes["optimal"] = _clean_route(plan.routes["optimal_smoothed"], "optimal")
            routes["min_distance"] = _clean_route(plan.routes["min_distance"])
            lf = least_fuel_routes(plan, vessel, routes[REFERENCE].time_utc[-1], job)
            if lf is not None and lf["least_fuel"] is not None:
                routes["least_fuel"] = _clean_route(lf["least_fuel"])
            evs = {role: evaluate_route(r, sampler, vessel, limits=job.limits, speed_loss_model=job.speed_loss, learned=job.learned)
                   for role, r in routes.items()}
            proposed = propose(evs, reference=REFERENCE)
            fuel = None if lf is None else least_fuel_outcome(lf, evs, proposed, sampler, vessel, job)
            out.append({"path_id": job.path_id, "depart_utc": t, "status": "adverse", "evaluations": evs,
                        "table": comparison_table(evs, reference=REFERENCE), "proposed": proposed,
                        "optimality": optimality_gaps(routes, plan), "least_fuel": fuel, "error": None,
                        "bands": _bands(evs, proposed, plan, sampler, vessel, job)})
        except Exception as err:  # noqa: BLE001 - one departure fails, the others run
            log.warning("lane %s departing %s failed: %s", job.path_id, t, err)
            out.append({"path_id": job.path_id, "depart_utc": t, "status": "failed", "error": f"{type(err).__name__}: {err}"})
    if job.rank_departures != "none" and out:
        out[0]["lane_window"] = lane_window(job, vessel, ship, start, goal, bbox)
    return out


def lane_window(job: LaneJob, vessel, ship, start, goal, bbox) -> dict:
    """Every departure of the lane's window routed with one objective on one mesh and ranked
    (:func:`routing.planner_window.plan_window`: arrival, time, distance, fuel, CO2, max Hs, hours over the
    vessel's limits; the best marked). With ``fuel`` each departure's least-fuel route arrives by its own
    time-optimal arrival, so the fuel figures of different departures compare different arrivals: a ranking,
    never a saving. A lane whose window cannot be routed gets its error."""
    from routing.fuel import FuelSpec
    from routing.least_fuel_role import default_settings
    from routing.planner import RouteRequest
    from routing.planner_window import plan_window

    head = {"lane": job.path_id, "objective": job.rank_departures}
    try:
        fuel = None
        if job.rank_departures == "fuel":
            engine, settings, _, _ = default_settings(vessel)
            fuel = FuelSpec(settings, engine)
        req = RouteRequest(start, goal, min(job.window), ship, vessel_name=vessel.name, bbox=bbox)
        res = plan_window(req, job.weather, sorted(job.window), objective=job.rank_departures, fuel=fuel, vessel=vessel, limits=job.limits)
    except Exception as err:  # noqa: BLE001 - the ranking is extra: the lane's cases stand without it
        log.warning("lane %s: departure window not ranked: %s", job.path_id, err)
        return {**head, "rows": [], "best": None, "error": f"{type(err).__name__}: {err}"}
    rows = [{k: v for k, v in r.items() if k != "route"} for r in res["rows"]]
    return {**head, "rows": rows, "best": res["best"], "error": None,
            "basis": "the least-time route of each departure" if job.rank_departures == "time" else
                     "the least-fuel route of each departure arriving by its own time-optimal arrival (different arrivals: "
                     "the fuel figures rank departures, they are not savings)"}


def least_fuel_routes(plan, vessel, arrive_utc, job: LaneJob) -> dict | None:
    """The least-fuel route of the departure's plan arriving by the lane's arrival, and its reference
    (:func:`routing.planner_fuel.least_fuel_role`); None without ``least_fuel``. Not with a learned speed
    model (its table holds the vessel's one speed, the settings need the loss at every speed): said."""
    from routing.least_fuel_role import least_fuel_role

    if not job.least_fuel:
        return None
    if job.learned is not None:
        return {"least_fuel": None, "min_distance_same_arrival": None, "stats": {},
                "error": "not computed with a learned speed-loss model (its table is for the lane's one speed)"}
    return least_fuel_role(plan, vessel, arrive_utc)


def least_fuel_outcome(lf: dict, evs: dict, proposed, sampler, vessel, job: LaneJob) -> dict:
    """The least-fuel role's line: its fuel, the saving against the minimum-distance route at the constant
    setting arriving when it does (evaluated like every route), why it was or was not proposed, the limits."""
    from routing.evaluate import evaluate_route
    from routing.emissions import Engine
    from routing.least_fuel_role import LIMITS_NOTE, fuel_saving, least_fuel_note, proposal_words

    if lf["least_fuel"] is None:
        return {"note": f"no least-fuel route arriving by the lane's arrival: {lf['error']}", "saving_pct": None}
    ref = lf["min_distance_same_arrival"]
    words = "the minimum-distance route at a constant setting arriving at the same time"
    if ref is not None:
        ref = evaluate_route(_clean_route(ref), sampler, vessel, limits=job.limits, speed_loss_model=job.speed_loss, learned=job.learned)
        words = f"the minimum-distance route at a constant {ref.route.properties['planned_setting_kn'][0]:.2f} kn arriving at the same time"
    out = fuel_saving(evs, "least_fuel", ref, words, Engine.from_vessel(vessel), why_none=lf["stats"].get("saving_note"))
    out["arrive_by_utc"] = evs["least_fuel"].route.properties.get("arrive_by_utc")
    out["proposal"] = proposal_words(evs, "least_fuel", proposed, REFERENCE)
    out["note"] = least_fuel_note(out, out["proposal"], LIMITS_NOTE, evs["least_fuel"].route.properties.get("speed_cap"))
    evs["least_fuel"].route.properties["note"] = out["note"]
    return out


def _bands(evs: dict, proposed: str | None, plan, sampler, vessel, job: LaneJob) -> dict:
    """With a learned model: P10/P50/P90 time and fuel of the lane as planned and of the proposed
    route (:func:`routing.bands.quantile_bands`); empty for a formula."""
    from routing.bands import quantile_bands

    if job.learned is None:
        return {}
    out = {}
    for role in dict.fromkeys([REFERENCE, proposed]):
        if role in evs:
            band = quantile_bands(evs[role].route, plan, sampler, vessel, label=job.speed_loss, limits=job.limits)
            if band is not None:
                out[role] = band
    return out


def _collect(jobs: list[LaneJob], results: list) -> list[dict]:
    """Outcomes of the lane jobs; a job that raised marks every departure of its lane failed."""
    outcomes = []
    for job, res in zip(jobs, results):
        if isinstance(res, BaseException):
            outcomes += [{"path_id": job.path_id, "depart_utc": t, "status": "failed", "error": f"{type(res).__name__}: {res}"}
                         for t in job.departures]
        else:
            outcomes += list(res)
    return outcomes
