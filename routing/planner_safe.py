"""The safety-constrained part of a route plan (:func:`routing.planner.plan_routes` with
``safety="soft"`` or ``"hard"``): the vessel's limits as per-slice, per-heading flags, the safe
searches (hard, falling back to soft when no route keeps within the limits), smoothing that is
never more exposed, and every route's hours over the limits (:mod:`routing.safety`).
"""

from __future__ import annotations

import logging
import math
import time as _time

from routing.astar import evaluate_path, path_exposure, search, smooth
from routing.errors import NoRouteError
from routing.planner_parts import make_route, mesh_weather_at
from routing.safety import SafetySpec, build_flags, limits_exposure

log = logging.getLogger("routing.planner")


class _Flags:
    """The vessel's unsafe-cell flags for one plan, first for the slices the safe route is expected
    to need (twice the plain optimal route's duration + 6 h), extended to the whole weather when a
    search or an exposure reaches beyond them; build times go to ``timings``."""

    def __init__(self, spec: SafetySpec, req, mesh, mw, wx, timings: dict, *, exempt, t0_h: float, opt_end_h: float):
        self.spec, self.req, self.mesh, self.mw, self.wx, self.timings = spec, req, mesh, mw, wx, timings
        self.exempt, self.t0_h = exempt, t0_h
        t, c = _time.perf_counter(), _time.process_time()
        n_need = int(math.ceil((opt_end_h + (opt_end_h - t0_h) + 6.0) / wx.dt_h)) + 2 if mw is not None else None
        self.fl = build_flags(spec, req.ship, mw, mesh.n_sea, n_slices=n_need).with_mode(spec.mode)
        timings["safety_flags_s"] = _time.perf_counter() - t
        timings["safety_flags_cpu_s"] = _time.process_time() - c

    def complete(self) -> None:
        """Extend the flags to every weather slice (the search needed more than the first guess)."""
        t = _time.perf_counter()
        self.fl = build_flags(self.spec, self.req.ship, self.mw, self.mesh.n_sea, extend=self.fl)
        self.timings["safety_flags_s"] += _time.perf_counter() - t

    def search(self, start_node, goal_node, t_node_h: float):
        """The safe A* under the current flags, re-run on complete flags if it ran past them."""
        res = search(self.mesh, self.wx, self.req.ship, start_node, goal_node, t_start_h=t_node_h, safety=self.fl)
        if res.horizon_hit and not self.fl.complete:
            self.complete()
            res = search(self.mesh, self.wx, self.req.ship, start_node, goal_node, t_start_h=t_node_h, safety=self.fl)
        return res

    def exposure(self, lat, lon):
        """Hours in unsafe cells, cumulated per vertex, as the search judges edges."""
        args = (self.mesh, self.wx, self.req.ship, lat, lon)
        _, ex, hit = path_exposure(*args, self.fl, exempt=self.exempt, t_start_h=self.t0_h)
        if hit and not self.fl.complete:
            self.complete()
            _, ex, _ = path_exposure(*args, self.fl, exempt=self.exempt, t_start_h=self.t0_h)
        return ex


def _search_with_fallback(spec: SafetySpec, flags: _Flags, start_node, goal_node, t_node_h: float):
    """(the safe search's result, the fallback text or None): hard limits fall back to soft ones,
    said in the text, when no route keeps within them."""
    try:
        return flags.search(start_node, goal_node, t_node_h), None
    except NoRouteError as err:
        if spec.mode != "hard":
            raise
        fallback = (f"hard: {err}; fell back to soft limits ({spec.penalty_per_h:g} h of penalty per hour over the limits): "
                    "the route below still breaks them")
        log.info("%s", fallback)  # not a warning: stats["safety"]["fallback"] carries it to every front end
        flags.fl = flags.fl.with_mode("soft")
        return flags.search(start_node, goal_node, t_node_h), fallback


def fuel_routes_exposure(spec: SafetySpec, st, routes: dict, names) -> None:
    """The least-fuel route and its reference judged like every route of a safety plan: hours over the limits at their
    own ETAs (:func:`routing.safety.limits_exposure`, the same weather on the mesh). The least-fuel search does not avoid
    the limits, so a table beside the safe routes must show what it meets (before: an empty column)."""
    weather_at = mesh_weather_at(st.mesh, st.mw, st.wx)
    for name in names:
        if name in routes:
            routes[name].properties.update(limits_exposure(routes[name], weather_at, spec))


def safe_routes(spec: SafetySpec, req, mesh, mw, wx, routes: dict, timings: dict, *, start_node, goal_node, t_node_h, t0_h,
                polyline, props) -> dict:
    """Add ``safe_optimal`` and ``safe_optimal_smoothed`` to ``routes`` and the hours over the limits
    to every route's properties; returns the statistics for :attr:`RoutePlan.stats`."""
    flags = _Flags(spec, req, mesh, mw, wx, timings, exempt=(int(start_node), int(goal_node)), t0_h=t0_h,
                   opt_end_h=t0_h + routes["optimal"].time_h)
    t, c = _time.perf_counter(), _time.process_time()
    res, fallback = _search_with_fallback(spec, flags, start_node, goal_node, t_node_h)
    timings["search_safe_s"] = _time.perf_counter() - t
    timings["search_safe_cpu_s"] = _time.process_time() - c

    t, c = _time.perf_counter(), _time.process_time()
    extra = {"safety_requested": spec.mode, "safety_mode": "hard" if flags.fl.hard else "soft", "safety_fallback": fallback,
             "safety": spec.describe(), "search_cost_h": round(res.cost, 6)}
    routes.update(_safe_pair(flags, res, polyline, props, extra))

    # every route: hours over the limits at its own ETAs (threshold functions) and in unsafe cells
    weather_at = mesh_weather_at(mesh, mw, wx)
    for name in ("optimal", "optimal_smoothed", "min_distance", "safe_optimal", "safe_optimal_smoothed"):
        r = routes[name]
        r.properties.update(limits_exposure(r, weather_at, spec))
        if "unsafe_cell_h" not in r.properties:
            r.properties["unsafe_cell_h"] = round(float(flags.exposure(r.lat_deg, r.lon_deg)[-1]), 6)
    timings["safety_routes_s"] = _time.perf_counter() - t
    timings["safety_routes_cpu_s"] = _time.process_time() - c
    skipped = list(routes["safe_optimal"].properties.get("rules_not_evaluated", []))
    return {
        "expanded_safe": res.expanded,
        "scanned_safe": res.scanned,
        "safety": {**spec.describe(), "requested": spec.mode, "mode": extra["safety_mode"], "fallback": fallback,
                   "rules_not_evaluated": skipped, "flag_slices": int(flags.fl.unsafe.shape[0]), "weather_slices": int(flags.fl.n_times)},
    }


def _safe_pair(flags: _Flags, res, polyline, props, extra: dict) -> dict:
    """``safe_optimal`` (the search's path) and ``safe_optimal_smoothed`` (its smoothing, kept only
    when it is neither slower nor more exposed in unsafe cells)."""
    mesh, mw, wx, ship, t0_h = flags.mesh, flags.mw, flags.wx, flags.req.ship, flags.t0_h
    sa_lat, sa_lon = polyline(res.nodes)
    sa_t, sa_hs = evaluate_path(mesh, wx, ship, sa_lat, sa_lon, t_start_h=t0_h)
    raw_cum = flags.exposure(sa_lat, sa_lon)
    keep = smooth(mesh, wx, ship, sa_lat, sa_lon, sa_t, safety=flags.fl, exempt=flags.exempt, raw_exposure_h=raw_cum)
    ss_lat, ss_lon = sa_lat[keep], sa_lon[keep]
    ss_t, ss_hs = evaluate_path(mesh, wx, ship, ss_lat, ss_lon, t_start_h=t0_h)
    raw_ex = float(raw_cum[-1])
    sm_ex = float(flags.exposure(ss_lat, ss_lon)[-1])
    if ss_t[-1] > sa_t[-1] + 1e-9 or sm_ex > raw_ex + 1e-9:  # never slower, never more exposed
        ss_lat, ss_lon, ss_t, ss_hs, sm_ex = sa_lat, sa_lon, sa_t, sa_hs, raw_ex
    depart = flags.req.depart_utc
    return {
        "safe_optimal": make_route("safe_optimal", mesh, mw, sa_lat, sa_lon, sa_t, depart,
                                   props("time", res, sa_t, sa_hs, unsafe_cell_h=round(raw_ex, 6), **extra)),
        "safe_optimal_smoothed": make_route(
            "safe_optimal_smoothed", mesh, mw, ss_lat, ss_lon, ss_t, depart,
            props("time", None, ss_t, ss_hs, smoothed_from=int(sa_lat.size), unsafe_cell_h=round(sm_ex, 6), **extra)),
    }  # fmt: skip
