"""The least-fuel role of the nightly run and the audit (issue 20), on a finished plan.

:func:`least_fuel_role`: the least-fuel route (a speed setting per leg, :mod:`routing.planner_fuel`) on the
plan's mesh, weather and vessel model, arriving no later than the lane's or the voyage's arrival, and its
fair reference (the minimum-distance route at the one constant setting arriving when it does).
:func:`same_arrival_twin`: the audit's reference, the sailed track at the constant setting that meets the
voyage's real arrival. Both are :func:`for_table` copies, so a comparison table evaluates them as it
evaluates every other route (like for like within the table). :func:`fuel_saving` measures a saving only
between routes arriving together; :func:`proposal_words` says why the role was or was not proposed under
:func:`routing.audit.propose`'s rules (safety first, then time). The search does not avoid the vessel's
limits (:data:`LIMITS_NOTE`, said on the route).

References
----------
.. [1] G. Mannarini et al., "VISIR-2: ship weather routing in Python," Geosci. Model Dev. 17, 4355-4382, 2024,
       doi:10.5194/gmd-17-4355-2024 (savings measured against the least-distance route).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from routing.audit import improves_on, not_proposable, safety_order
from routing.emissions import Engine
from routing.errors import NoRouteError
from routing.fuel import REFERENCE_MIN_KN, FuelSpec, fuel_summary, legs_fuel, max_power_speed_kn, same_arrival_reference
from routing.planner_fuel import fuel_routes
from routing.planner_parts import make_route

#: What the least-fuel role of the nightly run and the audit does not do, said on the route itself.
LIMITS_NOTE = ("the least-fuel search does not avoid the vessel's operator or IMO limits: its hours over them are evaluated "
               "like every route's and the safety-first proposal rules decide")


def _copy(route, name: str | None = None):
    from routing.route import Route

    return Route(name or route.name, route.lat_deg, route.lon_deg, route.time_utc, route.leg_speed_kn, dict(route.weather),
                 dict(route.properties))


def for_table(route):
    """The route as a comparison table of the nightly run or the audit evaluates every route: its planned
    settings and fuel kept as ``planned_setting_kn`` and ``planned_fuel_t`` (exports carry them), so
    :func:`routing.evaluate.evaluate_route` charges its fuel the way it charges the lane's, the track's and the
    A* routes' (each leg at the engine setting whose speed made in the weather met is the leg's speed,
    :mod:`routing.leg_setting`), like for like within the table."""
    r = _copy(route)
    p = r.properties
    p["planned_setting_kn"] = p.pop("speed_setting_kn", None)
    p["planned_fuel_t"] = p.pop("fuel_t", None)
    p.pop("co2_t", None)
    return r


def default_settings(vessel) -> tuple:
    """``(engine, settings_kn, capped_vessel, v_max_kn)``: the vessel's STEAM2 engine and its default speed settings
    (:func:`routing.fuel.speed_settings`) up to its maximum-power speed; a vessel sailed faster than that (a lane's
    typical AIS speed above the profile's engine) is capped there (``capped_vessel`` is then a copy)."""
    from routing.fuel import speed_settings

    engine = Engine.from_vessel(vessel)
    v_max = max_power_speed_kn(engine)
    # floored to the settings' 6 decimals, so the cap and the range's top setting are one setting, not two
    capped = vessel if vessel.speed_kn <= v_max else dataclasses.replace(vessel, speed_kn=np.floor(v_max * 1e6) / 1e6)
    return engine, speed_settings(capped, engine), capped, v_max


def least_fuel_role(plan, vessel, arrive_utc) -> dict:
    """The least-fuel route of a finished plan (same mesh, weather and vessel model) arriving no later than
    ``arrive_utc`` (the lane's or the voyage's arrival), with the vessel's default speed settings
    (:func:`routing.fuel.speed_settings`) and its STEAM2 engine; and its fair reference, the minimum-distance
    route at the one constant setting arriving when it does (``min_distance_same_arrival``).

    Returns ``{"least_fuel": Route | None, "min_distance_same_arrival": Route | None, "stats": dict,
    "error": str | None}``; ``error`` says why there is no route (an arrival no route can meet: the earliest
    possible one is named). The route's properties carry ``arrive_by_utc`` and ``limits`` (:data:`LIMITS_NOTE`); both
    routes are :func:`for_table` copies (planned settings and fuel under ``planned_*``).
    """
    from routing.planner import _props_maker

    st = plan.stage
    engine, settings, capped, v_max = default_settings(vessel)
    arrive = pd.Timestamp(arrive_utc)
    spec = FuelSpec(settings, engine, arrive)
    routes = {n: _copy(plan.routes[n]) for n in ("optimal", "optimal_smoothed", "min_distance")}
    try:
        stats = fuel_routes(st, routes, st.paths["time"], st.paths["distance"], spec, _props_maker(st))
    except NoRouteError as e:  # no arrival by the deadline (InfeasibleArrivalError), or the label budget
        cap = "" if capped is vessel else f" (settings capped at the engine's maximum-power speed {v_max:.2f} kn, below the {vessel.speed_kn:.2f} kn sailed)"
        return {"least_fuel": None, "min_distance_same_arrival": None, "stats": {}, "error": f"{e}{cap}"}
    lf = for_table(routes["least_fuel"])
    lf.properties.update(arrive_by_utc=arrive.isoformat(), limits=LIMITS_NOTE)
    if capped is not vessel:
        lf.properties["speed_cap"] = (f"the {vessel.speed_kn:.2f} kn sailed is above the engine's maximum-power speed {v_max:.2f} kn: "
                                      f"the settings stop there (the legs off the mesh's nodes keep {vessel.speed_kn:.2f} kn)")
    ref = routes.get("min_distance_same_arrival")
    return {"least_fuel": lf, "min_distance_same_arrival": None if ref is None else for_table(ref), "stats": stats, "error": None}


def same_arrival_twin(plan, lat_deg, lon_deg, depart_utc, arrive_utc, engine, name: str, lo_kn: float = REFERENCE_MIN_KN):
    """A polyline (the sailed track) sailed by the plan's vessel model at the one constant setting that arrives at
    ``arrive_utc`` (the voyage's real arrival; :func:`routing.fuel.same_arrival_reference`), or None when no setting
    from ``lo_kn`` (the compared least-fuel route's slowest setting) to the maximum-power speed does."""
    from routing.planner import _props_maker

    st = plan.stage
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    lon = lon + 360.0 * np.round((st.start[1] - lon) / 360.0)  # the mesh's longitude frame
    depart = pd.Timestamp(depart_utc)
    t0_h = st.wx.rel_h(int(depart.value))
    ref = same_arrival_reference(st.mesh, st.wx, plan.ship, lat, lon, t0_h, st.wx.rel_h(int(pd.Timestamp(arrive_utc).value)), engine,
                                 lo_kn=lo_kn)
    if ref is None:
        return None
    s_kn, times, fuel_t = ref
    route = make_route(name, st.mesh, st.mw, lat, lon, times, depart,
                       _props_maker(st)("constant", None, times, 0.0, speed_setting_kn=[round(s_kn, 6)] * (times.size - 1)))
    route.properties.update(fuel_summary(fuel_t, engine))
    return for_table(route)


def proposal_words(evaluations: dict, role: str, proposed: str | None, reference: str) -> str:
    """Why ``role`` was or was not proposed under :func:`propose`'s rules (safety first, then time)."""
    s, r = evaluations[role].summary, evaluations[reference].summary

    def risk(x):
        return (f"{x['adverse_h']:.1f} h over the limits or in IMO situations, {x['n_safety_events']} IMO events, "
                f"max Hs {x['max_hs_m']:.2f} m")

    safer = safety_order(s, r) < 0
    if role == proposed:
        return f"proposed: {'safer than' if safer else 'as safe as and faster than'} {reference} ({risk(s)} against {risk(r)})"
    why = not_proposable({**s, **{k: v for k, v in evaluations[role].route.properties.items() if k == "not_proposed"}}, r)
    if why:
        return f"not proposed: {why}"
    if not improves_on(s, r):
        return f"not proposed: neither safer than {reference} nor as safe and faster ({risk(s)} against {risk(r)})"
    p = evaluations[proposed].summary
    return (f"not proposed: {proposed} ranks first (safety first, then time): {proposed} {risk(p)}, {p['time_h']:.2f} h; "
            f"{role} {risk(s)}, {s['time_h']:.2f} h")


#: Arrival difference within which two routes count as arriving together (the same-arrival bisection's tolerance). [h]
SAME_ARRIVAL_TOL_H = 1.0 / 60.0


#: Planned and evaluated fuel within this fraction of each other are said to agree (the planner's edge weather against
#: the evaluation's samples: on the demo's night 52 of 102 least-fuel routes agree, all within -1.7 % .. +4.2 %).
PLANNED_AGREE_FRAC = 0.005


def planned_difference(ev, engine) -> dict | None:
    """Planned against evaluated fuel of a :func:`for_table` route and the cause of their difference: per leg, the
    engine setting the evaluation solved from the leg's planned times in the weather it samples (every 15 min along
    the leg, at the time the ship is there) against the planned setting (the planner times a mesh edge, or a piece of
    a polyline, in its two ends' weather at the quarter-hour nearest the time the ship leaves them:
    :mod:`routing._kernels.edge`, :mod:`routing._kernels.walk`). None without planned settings. ``diff_t`` evaluated
    minus planned; ``legs`` the (up to 3) legs that carry most of it: index, hours, planned and evaluated setting, fuel."""
    planned = ev.route.properties.get("planned_setting_kn")
    if planned is None or len(planned) != len(ev.legs):
        return None
    dt = ev.legs["time_h"].to_numpy()
    p = np.nan_to_num(np.asarray(planned, dtype=float), nan=0.0)
    at_plan = legs_fuel(dt, p, engine)["fuel_t"].to_numpy()  # P(setting) over each leg's time: the planner's charge
    per_leg = ev.legs["fuel_t"].to_numpy() - at_plan
    top = [int(k) for k in np.argsort(-np.abs(per_leg))[:3] if abs(per_leg[k]) > 1e-3]
    s = ev.legs["setting_kn"].to_numpy()
    plan_t = float(at_plan.sum())
    diff = float(ev.summary["fuel_t"]) - plan_t
    return {"planned_fuel_t": round(plan_t, 6), "diff_t": round(diff, 6), "diff_pct": round(100.0 * diff / plan_t, 3) if plan_t > 0 else None,
            "agree": abs(diff) <= PLANNED_AGREE_FRAC * plan_t,
            "legs": [{"leg": k, "time_h": round(float(dt[k]), 3), "planned_kn": round(float(p[k]), 3), "evaluated_kn": round(float(s[k]), 3),
                      "diff_t": round(float(per_leg[k]), 4)} for k in top]}


def planned_words(diff: dict | None, planned_t) -> str:
    """`` (planned X t ...)``: agreement, or the difference and its cause in a sentence (see :func:`planned_difference`)."""
    if diff is None:
        return "" if planned_t is None else f" (planned {planned_t:.3f} t)"
    head = f" (planned {diff['planned_fuel_t']:.3f} t"
    if diff["agree"]:
        return head + f", within {100 * PLANNED_AGREE_FRAC:.1f} %)"
    legs = ", ".join(f"leg {x['leg']} of {x['time_h']:.1f} h {x['planned_kn']:.2f} -> {x['evaluated_kn']:.2f} kn ({x['diff_t']:+.3f} t)"
                     for x in diff["legs"])
    more = "a higher" if diff["diff_t"] > 0 else "a lower"
    return (head + f"; {diff['diff_t']:+.3f} t ({diff['diff_pct']:+.1f} %): to keep the planned times, the weather the evaluation samples "
            f"every 15 min along each leg needs {more} engine setting than the planner's (each mesh edge or polyline piece timed in its two "
            f"ends' weather when the ship leaves them), most on {legs})")


def fuel_saving(evaluations: dict, role: str, reference, reference_words: str, engine, why_none: str | None = None) -> dict:
    """The fuel and CO2 saving of ``role`` against ``reference`` (a RouteEvaluation arriving at the same time),
    both evaluated by the same model in the same weather: ``saving_fuel_t`` and ``saving_pct`` (reference minus route,
    positive = less fuel), or ``saving_note`` why none is shown (no reference: ``why_none`` when given, or the route arrives later: a
    difference at different arrival times is never a saving), and ``planned_vs_evaluated``
    (:func:`planned_difference` with the vessel's ``engine``: required, so that no caller drops that line)."""
    s = evaluations[role].summary
    planned = evaluations[role].route.properties.get("planned_fuel_t")
    out = {"fuel_t": round(float(s["fuel_t"]), 6), "co2_t": round(float(s["co2_t"]), 6), "arrive_utc": evaluations[role].route.time_utc[-1].isoformat(),
           "planned_fuel_t": None if planned is None else round(float(planned), 6), "reference": reference_words,
           "planned_vs_evaluated": planned_difference(evaluations[role], engine)}
    if reference is None:  # why_none: the plan's own reason (routing.planner_fuel), else the reference named
        return {**out, "saving_pct": None, "saving_note": why_none or f"no reference ({reference_words}): no saving shown"}
    late_h = (evaluations[role].route.time_utc[-1] - reference.route.time_utc[-1]).total_seconds() / 3600.0
    rf = float(reference.summary["fuel_t"])
    out.update(reference_fuel_t=round(rf, 6), reference_arrive_utc=reference.route.time_utc[-1].isoformat())
    if late_h > SAME_ARRIVAL_TOL_H:
        return {**out, "saving_pct": None, "saving_note": f"it arrives {late_h:.2f} h after the reference: no saving shown"}
    return {**out, "saving_fuel_t": round(rf - out["fuel_t"], 6), "saving_co2_t": round(float(reference.summary["co2_t"]) - out["co2_t"], 6),
            "saving_pct": round(100.0 * (rf - out["fuel_t"]) / rf, 4) if rf > 0 else None}


def least_fuel_note(saving: dict, proposal: str, limits: str, cap: str | None = None) -> str:
    """One line on the least-fuel role: its fuel, the fair saving (or why none), the proposal decision, the limits
    (and ``cap``: its speed settings capped at the engine's maximum power below the speed sailed)."""
    planned = planned_words(saving.get("planned_vs_evaluated"), saving.get("planned_fuel_t"))
    fuel = f"least fuel {saving['fuel_t']:.3f} t as the table evaluates every route{planned}"
    if saving.get("saving_pct") is not None:
        fuel += f", saving {saving['saving_pct']:.2f} % ({saving['saving_fuel_t']:.3f} t) against {saving['reference']}"
    else:
        fuel += f"; {saving['saving_note']}"
    return "; ".join(filter(None, [fuel, proposal, limits, cap]))


def audit_least_fuel(plan, track, vessel, alts: dict, notes: list):
    """The least-fuel alternative arriving by the voyage's real (AIS) arrival (into ``alts``), and the fair reference
    of its saving: the sailed track at the one constant setting that meets that arrival, same model and weather
    (:func:`routing.planner_fuel.same_arrival_twin`; None when no setting does)."""
    arrive = track.time_utc[-1]
    lf = least_fuel_role(plan, vessel, arrive)
    if lf["least_fuel"] is None:
        notes.append(f"least-fuel route not computed: {lf['error']}")
        return None
    alts["least_fuel"] = lf["least_fuel"]
    return same_arrival_twin(plan, track.lat_deg, track.lon_deg, track.time_utc[0], arrive, Engine.from_vessel(vessel),
                             "as_sailed_same_arrival", lo_kn=min(lf["stats"]["speeds_kn"]))


def audit_least_fuel_saving(out: dict, twin, sampler, vessel, limits, speed_loss_model: str, learned=None) -> dict:
    """The least-fuel role's saving against the sailed track at the constant setting meeting the real arrival
    (both evaluated like every route), why it was or was not proposed, and the limits it ignores."""
    from routing.evaluate import evaluate_route

    evs = out["evaluations"]
    words = "the sailed track at a constant setting arriving at the voyage's AIS arrival"
    ref = None
    if twin is not None:
        ref = evaluate_route(twin, sampler, vessel, limits=limits, speed_loss_model=speed_loss_model, learned=learned)
        words = f"the sailed track at a constant {twin.properties['planned_setting_kn'][0]:.2f} kn arriving at the voyage's AIS arrival"
    saving = fuel_saving(evs, "least_fuel", ref, words, Engine.from_vessel(vessel))
    saving["proposal"] = proposal_words(evs, "least_fuel", out["proposed"], out["reference"])
    saving["note"] = least_fuel_note(saving, saving["proposal"], LIMITS_NOTE, evs["least_fuel"].route.properties.get("speed_cap"))
    evs["least_fuel"].route.properties["note"] = saving["note"]
    return saving


__all__ = ["LIMITS_NOTE", "PLANNED_AGREE_FRAC", "SAME_ARRIVAL_TOL_H", "planned_difference", "planned_words", "audit_least_fuel", "audit_least_fuel_saving", "default_settings", "for_table", "fuel_saving",
           "least_fuel_note", "least_fuel_role", "proposal_words", "same_arrival_twin"]
