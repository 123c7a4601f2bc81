"""The safety-constrained part of a route plan (:func:`routing.planner.plan_routes` with
``safety="soft"`` or ``"hard"``): the vessel's limits as per-slice, per-heading flags, the safe
searches (hard, falling back to soft when no route keeps within the limits), smoothing that is
never more exposed, and every route's hours over the limits (:mod:`routing.safety`).
"""

from __future__ import annotations

import logging
import math
import time as _time

import pandas as pd

from routing.astar import evaluate_path, path_exposure, search, smooth
from routing.errors import NoRouteError
from routing.field import NS_PER_HOUR
from routing.planner_parts import make_route, sample_weather
from routing.safety import SafetySpec, build_flags, limits_exposure

log = logging.getLogger("routing.planner")


def safe_routes(spec: SafetySpec, req, mesh, mw, wx, routes: dict, timings: dict, *, start_node, goal_node, t_node_h, t0_h,
                 polyline, props) -> dict:
    """Add ``safe_optimal`` and ``safe_optimal_smoothed`` to ``routes`` and the hours over the limits
    to every route's properties; returns the statistics for :attr:`RoutePlan.stats`."""
    grid = mesh.grid
    exempt = (int(start_node), int(goal_node))
    t = _time.perf_counter()
    c = _time.process_time()
    # flags up to twice the plain optimal route's duration (+6 h); extended to the whole weather if needed
    opt_end_h = t0_h + routes["optimal"].time_h
    n_need = None
    if mw is not None:
        n_need = int(math.ceil((opt_end_h + (opt_end_h - t0_h) + 6.0) / wx.dt_h)) + 2
    flags = build_flags(spec, req.ship, mw, mesh.n_sea, n_slices=n_need)
    timings["safety_flags_s"] = _time.perf_counter() - t
    timings["safety_flags_cpu_s"] = _time.process_time() - c

    def complete(fl):
        """The flags extended to every weather slice (the search needed more than the first guess)."""
        t1 = _time.perf_counter()
        fl = build_flags(spec, req.ship, mw, mesh.n_sea, extend=fl)
        timings["safety_flags_s"] += _time.perf_counter() - t1
        return fl

    t = _time.perf_counter()
    c = _time.process_time()
    fallback = None
    fl = flags.with_mode(spec.mode)
    try:
        res = search(mesh, wx, req.ship, start_node, goal_node, t_start_h=t_node_h, safety=fl)
        if res.horizon_hit and not fl.complete:
            fl = complete(fl)
            res = search(mesh, wx, req.ship, start_node, goal_node, t_start_h=t_node_h, safety=fl)
    except NoRouteError as err:
        if spec.mode != "hard":
            raise
        fallback = (f"hard: {err}; fell back to soft limits ({spec.penalty_per_h:g} h of penalty per hour over the limits): "
                    "the route below still breaks them")
        log.info("%s", fallback)  # not a warning: stats["safety"]["fallback"] carries it to every front end
        fl = fl.with_mode("soft")
        res = search(mesh, wx, req.ship, start_node, goal_node, t_start_h=t_node_h, safety=fl)
        if res.horizon_hit and not fl.complete:
            fl = complete(fl)
            res = search(mesh, wx, req.ship, start_node, goal_node, t_start_h=t_node_h, safety=fl)
    timings["search_safe_s"] = _time.perf_counter() - t
    timings["search_safe_cpu_s"] = _time.process_time() - c

    t = _time.perf_counter()
    c = _time.process_time()
    sa_lat, sa_lon = polyline(res.nodes)
    sa_t, sa_hs = evaluate_path(mesh, wx, req.ship, sa_lat, sa_lon, t_start_h=t0_h)

    def cell_exposure(lat, lon):
        """Hours in unsafe cells, cumulated per vertex, as the search judges edges."""
        nonlocal fl
        _, ex, hit = path_exposure(mesh, wx, req.ship, lat, lon, fl, exempt=exempt, t_start_h=t0_h)
        if hit and not fl.complete:
            fl = complete(fl)
            _, ex, _ = path_exposure(mesh, wx, req.ship, lat, lon, fl, exempt=exempt, t_start_h=t0_h)
        return ex

    raw_cum = cell_exposure(sa_lat, sa_lon)
    keep = smooth(mesh, wx, req.ship, sa_lat, sa_lon, sa_t, safety=fl, exempt=exempt, raw_exposure_h=raw_cum)
    ss_lat, ss_lon = sa_lat[keep], sa_lon[keep]
    ss_t, ss_hs = evaluate_path(mesh, wx, req.ship, ss_lat, ss_lon, t_start_h=t0_h)
    raw_ex = float(raw_cum[-1])
    sm_ex = float(cell_exposure(ss_lat, ss_lon)[-1])
    if ss_t[-1] > sa_t[-1] + 1e-9 or sm_ex > raw_ex + 1e-9:  # never slower, never more exposed
        ss_lat, ss_lon, ss_t, ss_hs, sm_ex = sa_lat, sa_lon, sa_t, sa_hs, raw_ex
    mode = "hard" if fl.hard else "soft"
    extra = {
        "safety_requested": spec.mode,
        "safety_mode": mode,
        "safety_fallback": fallback,
        "safety": spec.describe(),
        "search_cost_h": round(res.cost, 6),
    }
    depart = req.depart_utc
    routes["safe_optimal"] = make_route("safe_optimal", mesh, mw, sa_lat, sa_lon, sa_t, depart,
                                        props("time", res, sa_t, sa_hs, unsafe_cell_h=round(raw_ex, 6), **extra))
    routes["safe_optimal_smoothed"] = make_route(
        "safe_optimal_smoothed", mesh, mw, ss_lat, ss_lon, ss_t, depart,
        props("time", None, ss_t, ss_hs, smoothed_from=int(sa_lat.size), unsafe_cell_h=round(sm_ex, 6), **extra),
    )  # fmt: skip

    # every route: hours over the limits at its own ETAs (threshold functions) and in unsafe cells
    def weather_at(times, lat, lon):
        t_h = (pd.DatetimeIndex(times).asi8 - (wx.time0_ns or 0)) / NS_PER_HOUR
        return sample_weather(mesh, mw, lat, lon, t_h)

    for name in ("optimal", "optimal_smoothed", "min_distance", "safe_optimal", "safe_optimal_smoothed"):
        r = routes[name]
        r.properties.update(limits_exposure(r, weather_at, spec))
        if "unsafe_cell_h" not in r.properties:
            r.properties["unsafe_cell_h"] = round(float(cell_exposure(r.lat_deg, r.lon_deg)[-1]), 6)
    timings["safety_routes_s"] = _time.perf_counter() - t
    timings["safety_routes_cpu_s"] = _time.process_time() - c
    skipped = list(routes["safe_optimal"].properties.get("rules_not_evaluated", []))
    return {
        "expanded_safe": res.expanded,
        "scanned_safe": res.scanned,
        "safety": {**spec.describe(), "requested": spec.mode, "mode": mode, "fallback": fallback, "rules_not_evaluated": skipped,
                   "flag_slices": int(fl.unsafe.shape[0]), "weather_slices": int(fl.n_times)},
    }
