"""The least-fuel part of a plan (:func:`routing.planner.plan_routes` with ``fuel=FuelSpec``).

Adds to the plan, beside the time-optimal and minimum-distance routes:

``least_fuel``                  the least-fuel (= least-CO2) mesh route arriving no later than the
                                deadline (``FuelSpec.arrive_by``; default the time-optimal route's
                                arrival), a speed setting per leg (``speed_setting_kn``; 0 on a wait);
``min_distance_same_arrival``   the fair reference: the minimum-distance route at the one constant
                                setting that arrives when ``least_fuel`` does.

Every route of the plan gets ``fuel_t`` and ``co2_t``: the plain routes at the service-speed
setting over their own ETAs (the same :func:`routing.emissions.steam2_legs`). The search's gap
(:mod:`routing._kernels.fuel`) and the saving against the reference are in ``stats["fuel"]``.
The start and goal legs off the mesh nodes are sailed at the service speed.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd

from routing.astar import ShipModel, WeatherArrays, evaluate_path, search, smooth
from routing.fuel import (ARRIVAL_TOL_H, FuelProblem, FuelSpec, InfeasibleArrivalError, corridor_edges, earliest_arrival_h, fuel_summary, least_fuel,
                          fuel_rates_t_per_h, max_power_speed_kn, retime_constant, same_arrival_reference, saving_pct)
from routing.planner_parts import make_route
from routing.field import NS_PER_HOUR

FUEL_ROUTE_NAMES = ("least_fuel", "min_distance_same_arrival")
#: Threads of the per-setting time-optimal searches that draw the corridor (:func:`_setting_paths`).
SETTING_THREADS = 2


def _h(st, when) -> float:
    """A time as the plan's hours (after the weather's slice 0; after departure in a calm sea)."""
    return st.t0_h + (pd.Timestamp(when).value - st.req.depart_utc.value) / NS_PER_HOUR


def _utc(st, t_h: float) -> pd.Timestamp:
    """The plan's hours as a time, to the second."""
    return (st.req.depart_utc + pd.Timedelta(hours=float(t_h) - st.t0_h)).round("s")


def route_fuel(times_h, setting_kn, engine) -> float:
    """Fuel [t] of a schedule: each leg at its setting over its time, the sum of :func:`routing.fuel.legs_fuel`'s legs
    (STEAM2 in calm water is linear in the leg's time, so each leg is its setting's hourly rate
    (:func:`routing.fuel.fuel_rates_t_per_h`) times its hours; waits, NaN or 0, burn nothing), without a table per call."""
    s = np.nan_to_num(np.asarray(setting_kn, dtype=float), nan=0.0)
    if s.size == 0:
        return 0.0
    u, inv = np.unique(s, return_inverse=True)
    return float(np.sum(fuel_rates_t_per_h(u, engine)[inv] * np.diff(np.asarray(times_h, dtype=float))))


def _tail_h(st, t_h: float) -> float:
    """Hours of the leg from the goal node to the goal point at the service speed, left at ``t_h``."""
    if not st.tail:
        return 0.0
    g_lat, g_lon = (float(x) for x in st.grid.node_latlon(st.goal_node))
    times, _ = evaluate_path(st.mesh, st.wx, st.req.ship, [g_lat, st.goal[0]], [g_lon, st.goal[1]], t_start_h=t_h)
    return float(times[-1] - times[0])


def _full_schedule(st, sched):
    """Polyline, times and settings of a schedule with the off-node start and goal legs (service speed)."""
    lat, lon = st.polyline(sched.nodes)
    times = np.asarray(sched.times_h, dtype=float)
    setting = np.nan_to_num(np.asarray(sched.setting_kn, dtype=float), nan=0.0)
    v0 = st.req.ship.speed_kn
    if st.lead:
        times, setting = np.r_[st.t0_h, times], np.r_[v0, setting]
    if st.tail:
        times, setting = np.r_[times, times[-1] + _tail_h(st, times[-1])], np.r_[setting, v0]
    return lat, lon, times, setting


def _deadline_h(st, spec: FuelSpec, routes: dict) -> tuple[float, str]:
    if spec.arrive_by is not None:
        return _h(st, spec.arrive_by), "arrive_by"
    return _h(st, routes["optimal"].time_utc[-1]), "the time-optimal route's arrival"


def _candidates(st, routes: dict, opt_nodes, md_nodes, spec: FuelSpec, deadline_h: float) -> list:
    """Known routes of the model arriving by the deadline, as (source, lat, lon, times, setting, fuel): the
    time-optimal route at the service speed when that is one of the settings, and its smoothed twin at each setting
    (constant, never waiting) that arrives in time. The search must beat it (its
    incumbent); when it cannot, it is the answer (so least fuel never exceeds the time-optimal route's). And
    :func:`_deadline_candidates`."""
    v0 = st.req.ship.speed_kn
    out = []
    sm_polyline = (None, None)
    opt = routes["optimal"]
    t = np.asarray(opt.time_utc.asi8 - opt.time_utc.asi8[0], dtype=float) / 3.6e12 + st.t0_h
    if any(abs(s - v0) < 1e-9 for s in spec.speeds_kn) and t[-1] <= deadline_h + 1e-9:
        lat, lon = st.polyline(opt_nodes)
        setting = np.full(t.size - 1, v0)
        out.append(("the time-optimal route at the service speed", lat, lon, t, setting, route_fuel(t, setting, spec.engine)))
    sm = routes.get("optimal_smoothed")
    if sm is not None:  # off the mesh's edges, so the search cannot find it: each setting, constant, that arrives in time
        lat, lon = np.asarray(sm.lat_deg, dtype=float), np.asarray(sm.lon_deg, dtype=float)
        lon = lon + 360.0 * np.round((st.start[1] - lon) / 360.0)  # back in the mesh's longitude frame
        sm_polyline = (lat, lon)
        own = np.asarray(sm.time_utc.asi8 - sm.time_utc.asi8[0], dtype=float) / 3.6e12 + st.t0_h  # at v0, as planned
        for s in spec.speeds_kn:
            t = own if abs(s - v0) < 1e-9 else retime_constant(st.mesh, st.wx, st.req.ship, lat, lon, st.t0_h, s)
            if t[-1] <= deadline_h + 1e-9:
                setting = np.full(t.size - 1, float(s))
                out.append((f"the smoothed time-optimal route at a constant {s:g} kn", lat, lon, t, setting,
                            route_fuel(t, setting, spec.engine)))
    return out + _deadline_candidates(st, spec, deadline_h, [("the smoothed time-optimal route", sm_polyline),
                                                             ("the minimum-distance route", min_distance_polyline(st, md_nodes))])


def _deadline_candidates(st, spec: FuelSpec, deadline_h: float, polylines) -> list:
    """Each polyline at the one constant setting that arrives exactly at the deadline, when the settings sample a
    continuous range (``FuelSpec.between_settings``) and that setting lies within it. Why: the same-arrival reference
    sails at such a continuous constant setting, and with a few settings (or a coarse mesh's time buckets) the search
    may not reach it; the fuel rate is convex in the speed, so one constant speed can beat any mix of the
    neighbouring settings (Jensen). With these candidates least fuel never uses more than its reference arriving
    together (measured before: -0.63 % on a tight deadline in the Baltic test weather, container-feeder, 9 settings)."""
    if not spec.between_settings:
        return []
    lo, hi = min(spec.speeds_kn), max(spec.speeds_kn)
    out = []
    for name, (lat, lon) in polylines:
        if lat is None:
            continue
        ref = same_arrival_reference(st.mesh, st.wx, st.req.ship, lat, lon, st.t0_h, deadline_h, spec.engine)
        if ref is None or not lo - 1e-9 <= ref[0] <= hi + 1e-9 or ref[1][-1] > deadline_h + 1e-6:
            continue
        setting = np.full(ref[1].size - 1, float(ref[0]))
        out.append((f"{name} at a constant {ref[0]:.4g} kn arriving at the deadline (between the offered settings)", lat, lon, ref[1],
                    setting, route_fuel(ref[1], setting, spec.engine)))
    return out


def fuel_routes(st, routes: dict, opt_nodes, md_nodes, spec: FuelSpec, props, *, bound: bool = True) -> dict:
    """Add ``least_fuel`` and ``min_distance_same_arrival`` to ``routes`` (and ``fuel_t``/``co2_t`` to every
    route); returns the ``fuel`` stats. ``bound=False`` skips the relaxation's lower bound (no gap reported: a
    departure window's ranking, which shows none). Raises :class:`routing.fuel.InfeasibleArrivalError`."""
    req, mesh, wx, engine = st.req, st.mesh, st.wx, spec.engine
    prob = FuelProblem.build(mesh, wx, req.ship, spec)
    v0 = req.ship.speed_kn
    deadline_h, source = _deadline_h(st, spec, routes)
    f_lead = route_fuel([st.t0_h, st.t_node_h], [v0], engine) if st.lead else 0.0
    tail_h = _tail_h(st, deadline_h - _tail_h(st, deadline_h))
    node_deadline = deadline_h - tail_h
    f_tail = route_fuel([0.0, tail_h], [v0], engine) if st.tail else 0.0

    def earliest():
        e = earliest_arrival_h(mesh, wx, prob, st.start_node, st.goal_node, st.t_node_h)
        return f"{_utc(st, e + _tail_h(st, e)).isoformat()} (sailing at {max(spec.speeds_kn):g} kn on every leg)"

    if not node_deadline > st.t_node_h:
        raise InfeasibleArrivalError(f"no route arrives by {_utc(st, deadline_h).isoformat()}: the earliest possible arrival is {earliest()}")
    cands = _candidates(st, routes, opt_nodes, md_nodes, spec, deadline_h)
    if spec.corridor is not None:
        prob.allowed = corridor_edges(mesh, [opt_nodes, md_nodes] + _setting_paths(st, prob), spec.corridor)
    f_upper = min((c[5] for c in cands), default=np.inf) - f_tail
    try:
        res = least_fuel(prob, st.start_node, st.goal_node, st.t_node_h, f_lead, node_deadline, spec, earliest=earliest, f_upper=f_upper,
                         bound=bound)
    except InfeasibleArrivalError as e:
        raise InfeasibleArrivalError(f"no route arrives by {_utc(st, deadline_h).isoformat()}: {str(e).split(': ', 1)[-1]}") from None
    if res.schedule is not None:
        lat, lon, times, setting = _full_schedule(st, res.schedule)
        cands.append(("search", lat, lon, times, setting, route_fuel(times, setting, engine)))
    found = [c for c in cands if c[3][-1] <= deadline_h + 1e-6]
    won, lat, lon, times, setting, fuel_t = min(found, key=lambda c: c[5])
    extra = {"speed_setting_kn": [round(float(s), 6) for s in setting], "objective": spec.objective}
    routes["least_fuel"] = make_route("least_fuel", mesh, st.mw, lat, lon, times, req.depart_utc, props("fuel", None, times, 0.0, **extra))
    arrive_h = float(times[-1])
    lb = res.lower_bound_t + f_tail if res.lower_bound_t == res.lower_bound_t else None
    # the bound covers mesh routes at the offered settings: a candidate off the mesh's edges (smoothed) or between the
    # settings may fall below it, and then no gap is claimed
    below = lb is not None and fuel_t < lb * (1.0 - 1e-9)
    stats = {
        "objective": spec.objective,
        "speeds_kn": list(spec.speeds_kn),
        "deadline_utc": _utc(st, deadline_h).isoformat(),
        "deadline_source": source,
        "least_fuel_from": won,
        "lower_bound_fuel_t": None if lb is None else round(min(lb, fuel_t), 6),
        "gap_pct": None if lb is None or below or fuel_t <= 0 else round(max(0.0, 100.0 * (fuel_t - lb) / fuel_t), 4),
        "bound_note": ("least fuel sails off the mesh's edges or between the offered settings, below the search's lower bound "
                       f"({lb:.3f} t), which covers mesh routes at the offered settings only") if below else None,
        "search_fuel_t": None if res.schedule is None else round(res.schedule.fuel_t + f_tail, 9),  # the kernel's sum of rate x time
        "labels": res.labels,
        "search_s": round(res.seconds, 4),
        "buckets_per_subslice": spec.buckets_per_subslice,
        "graph": "the whole mesh" if spec.corridor is None else (
            f"the corridor of the time-optimal paths at every setting and the minimum-distance path (width {spec.corridor} nodes)"),
        **fuel_summary(fuel_t, engine),
    }
    stats.update(_reference(st, routes, md_nodes, arrive_h, fuel_t, engine, props, min(spec.speeds_kn)))
    for name, r in routes.items():
        if "fuel_t" in r.properties:
            continue
        t = np.asarray((r.time_utc.asi8 - r.time_utc.asi8[0]) / 3.6e12, dtype=float)
        setting = r.properties.get("speed_setting_kn") or [v0] * (t.size - 1)
        r.properties.update(fuel_summary(route_fuel(t, setting, engine), engine))
    if spec.pareto:
        chosen = {**_front_row(st, lat, lon, times, fuel_t, engine), "least_fuel": True}
        stats["pareto"] = non_dominated(pareto_front(st, prob, spec, deadline_h, f_lead) + [chosen])
    return stats


def _setting_paths(st, prob) -> list:
    """The time-optimal node paths at every setting but the service speed (its path is the plan's), in setting order.
    The searches are independent and the compiled A* releases the GIL, so they run in two threads (the machines
    have two cores; the CPU time is the same)."""
    ships = [sh for sh in prob.ships if sh != st.req.ship]

    def path(sh):
        return search(st.mesh, st.wx, sh, st.start_node, st.goal_node, t_start_h=st.t_node_h).nodes

    if len(ships) < 2 or threading.current_thread() is not threading.main_thread():  # a window's departures run in threads already
        return [path(sh) for sh in ships]
    with ThreadPoolExecutor(max_workers=SETTING_THREADS) as pool:
        return list(pool.map(path, ships))


def min_distance_polyline(st, md_nodes):
    """The minimum-distance mesh path made any-angle, as the reference of a saving is sailed: greedy smoothing in calm
    water (:func:`routing.astar.smooth`: a direct great-circle leg over sea cells replaces grid steps when it is no
    longer), as :func:`routing.seapath.sea_path` does. The least-fuel route may be a smoothed polyline, so a reference
    left on the mesh's zig-zag credited it with the mesh's detour: in a calm sea (Fiji -> Samoa, 0.1 deg mesh) least
    fuel 'saved' 1.52 % against a path 0.57 % longer. Remembered per stage (the plan's stage)."""
    memo = st.__dict__.setdefault("_md_smoothed", {})
    key = tuple(int(n) for n in md_nodes)
    if key not in memo:
        lat, lon = st.polyline(md_nodes)
        wx = WeatherArrays.build(st.mesh, None)
        calm = ShipModel(10.0, "none")
        times, _ = evaluate_path(st.mesh, wx, calm, lat, lon)
        keep = smooth(st.mesh, wx, calm, lat, lon, times)
        memo[key] = (np.asarray(lat)[keep], np.asarray(lon)[keep])
    return memo[key]


def _reference(st, routes, md_nodes, arrive_h, fuel_t, engine, props, lo_kn: float) -> dict:
    """The same-arrival reference route (into ``routes``) and the saving against it: the minimum-distance route at the
    one constant setting from the slowest offered one (``lo_kn``) to the maximum-power speed that arrives together."""
    md_lat, md_lon = min_distance_polyline(st, md_nodes)
    ref = same_arrival_reference(st.mesh, st.wx, st.req.ship, md_lat, md_lon, st.t0_h, arrive_h, engine, lo_kn=lo_kn)
    if ref is None:
        early_h = arrive_h - retime_constant(st.mesh, st.wx, st.req.ship, md_lat, md_lon, st.t0_h, lo_kn)[-1]
        late_h = retime_constant(st.mesh, st.wx, st.req.ship, md_lat, md_lon, st.t0_h, max_power_speed_kn(engine))[-1] - arrive_h
        why = (f"even at the slowest setting offered, {lo_kn:g} kn, it arrives {early_h:.2f} h earlier" if early_h > ARRIVAL_TOL_H else
               f"even at the maximum-power speed it arrives {late_h:.2f} h later" if late_h > ARRIVAL_TOL_H else
               # e.g. Marseille -> Alger in storm B: 13.740 kn arrives 36.047 h out, 13.745 kn 35.958 h, the target 35.996 h between
               "its arrival jumps across that time as the constant setting varies: the legs' sailing times change in steps with the "
               "weather's quarter-hour pieces")
        return {"reference": None, "saving_pct": None,
                "saving_note": f"no constant setting sails the minimum-distance route to the same arrival ({why}): no saving shown"}
    s_ref, ref_times, ref_fuel = ref
    setting = [round(s_ref, 6)] * (ref_times.size - 1)
    routes["min_distance_same_arrival"] = make_route("min_distance_same_arrival", st.mesh, st.mw, md_lat, md_lon, ref_times, st.req.depart_utc,
                                                     props("distance", None, ref_times, 0.0, speed_setting_kn=setting))  # fmt: skip
    routes["min_distance_same_arrival"].properties.update(fuel_summary(ref_fuel, engine))
    return {"reference": {"route": "min_distance_same_arrival", "setting_kn": round(s_ref, 4), "arrive_utc": _utc(st, ref_times[-1]).isoformat(),
                          **fuel_summary(ref_fuel, engine)},
            "saving_pct": round(saving_pct(ref_fuel, fuel_t), 4), "saving_fuel_t": round(ref_fuel - fuel_t, 6)}  # fmt: skip


def pareto_front(st, prob, spec: FuelSpec, deadline_h: float, f_lead: float) -> list:
    """Up to ``spec.pareto`` non-dominated (arrival, fuel) routes, from the earliest arrival to the least fuel
    by the latest of the deadline and the slowest setting's time-optimal arrival (each: arrival, time, fuel, CO2)."""
    slow = min(prob.ships, key=lambda s: s.speed_kn)
    t_slow = st.t_node_h + search(st.mesh, st.wx, slow, st.start_node, st.goal_node, t_start_h=st.t_node_h).time_h
    horizon = max(deadline_h, t_slow)
    res = least_fuel(prob, st.start_node, st.goal_node, st.t_node_h, f_lead, horizon, spec, bound=False)
    front = res.front
    if len(front) > spec.pareto:
        pick = np.unique(np.round(np.linspace(0, len(front) - 1, spec.pareto)).astype(int))
        front = [front[i] for i in pick]
    rows = []
    for sched in front:
        lat, lon, times, setting = _full_schedule(st, sched)
        rows.append(_front_row(st, lat, lon, times, route_fuel(times, setting, spec.engine), spec.engine))
    return rows


def _front_row(st, lat, lon, times, fuel_t: float, engine) -> dict:
    """One route of the time-fuel front: arrival, time, distance, fuel and CO2."""
    return {"arrive_utc": _utc(st, times[-1]).isoformat(), "time_h": round(float(times[-1] - st.t0_h), 4),
            "dist_nmi": round(float(np.sum(_legs_nmi(lat, lon))), 4), **fuel_summary(fuel_t, engine)}


def non_dominated(rows: list) -> list:
    """The rows no other row beats on both arrival and fuel (earlier or equal and less fuel, or earlier and no
    more), by arrival. The search's front and the least-fuel route (which may sail off the mesh's edges or between
    the settings) together: a front point the chosen route dominates is not shown."""
    rows = sorted(rows, key=lambda r: (pd.Timestamp(r["arrive_utc"]), r["fuel_t"]))
    out, best = [], np.inf
    for r in rows:  # by arrival: a row is kept only when it uses less fuel than every earlier one
        if r["fuel_t"] < best - 1e-12:
            out.append(r)
            best = r["fuel_t"]
    return out


def _legs_nmi(lat, lon):
    from thresholds.geodesy import haversine_nmi

    return np.asarray(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]))


__all__ = ["FUEL_ROUTE_NAMES", "fuel_routes", "route_fuel"]
