"""Every departure of a window routed with one objective, on one mesh (``--depart-window``).

:func:`plan_window` builds the mesh and the weather on it once (from the window's first departure,
so every later one reads the same slices), finds the minimum-distance path once (it does not
depend on the departure), and for each departure runs the time-optimal search and, with a fuel
objective, the least-fuel search of :mod:`routing.planner_fuel` (with ``FuelSpec.arrive_by`` a
fixed arrival for every departure; without it each departure's own time-optimal arrival; without the
relaxation's lower bound, as the rows report no gap: `stormlane route` for one departure gives it). Each row
gives the route's arrival, time, distance, fuel, CO2, max Hs and (with ``vessel``) the hours over
the vessel's limits at its own ETAs (:func:`routing.safety.limits_exposure`, operator profile +
IMO rules), and with a fuel objective the saving against that departure's own same-arrival reference
(``saving_pct``, ``reference_fuel_t``: :mod:`routing.planner_fuel`); the best departure (least time for
``time``, least fuel otherwise; ties: the earlier) is marked. A departure no route serves (an arrival
it cannot meet, or a departure after the weather's last time, which `route --depart` refuses too) is a row
with its error, never dropped; a route arriving after the last weather time has ``weather_held_after_h``
(the hours sailed in the held last field), as a single plan's routes.
"""

from __future__ import annotations

import dataclasses
import time as _time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd

from routing.astar import evaluate_path, search
from routing.errors import NoRouteError
from routing.fuel import FuelSpec
from routing.planner import RouteRequest, _props_maker, mesh_and_ends, model_notes, plain_routes
from routing.planner_fuel import fuel_routes
from routing.planner_parts import mesh_weather_at
from routing.mesh import global_land_mask_window


#: Threads routing the departures of a window (:func:`plan_window`).
WINDOW_THREADS = 2


def departures(start: pd.Timestamp, end: pd.Timestamp, step_h: float) -> list:
    """START, START + step, ... up to END (inclusive)."""
    if not step_h > 0:
        raise ValueError(f"the departure step must be positive hours, got {step_h!r}")
    if end < start:
        raise ValueError(f"the window ends ({end.isoformat()}) before it starts ({start.isoformat()})")
    n = int(np.floor((end - start) / pd.Timedelta(hours=step_h) + 1e-9)) + 1
    return [start + pd.Timedelta(hours=step_h * i) for i in range(n)]


def plan_window(req: RouteRequest, weather, times: list, *, objective: str = "time", fuel: FuelSpec | None = None, vessel=None,
                limits=None, land_mask_fn=global_land_mask_window) -> dict:
    """Route every departure of ``times`` (see the module docstring); returns ``{"rows": [...], "best": i, "seconds": s}``."""
    t_all = _time.perf_counter()
    first = dataclasses.replace(req, depart_utc=min(times))
    base = mesh_and_ends(first, weather, land_mask_fn)
    md = search(base.mesh, base.wx, req.ship, base.start_node, base.goal_node, cost="distance")
    exposure = _exposure(vessel, limits, base) if vessel is not None else None
    end_ns = None if base.mw is None or base.wx.time0_ns is None else int(base.mw.end_ns)

    def one(when) -> dict:
        st = dataclasses.replace(base, req=dataclasses.replace(req, depart_utc=pd.Timestamp(when)), timings={}, notes=list(base.notes))
        st.t0_h = st.wx.rel_h(int(st.req.depart_utc.value))
        st.t_node_h = st.t0_h
        if st.lead:
            s_lat, s_lon = (float(x) for x in st.grid.node_latlon(st.start_node))
            st.t_node_h = float(evaluate_path(st.mesh, st.wx, req.ship, [st.start[0], s_lat], [st.start[1], s_lon], t_start_h=st.t0_h)[0][-1])
        row = {"depart_utc": st.req.depart_utc.isoformat()}
        if end_ns is not None and st.req.depart_utc.value > end_ns:  # as `route --depart` refuses it: never routed in a held field
            end = pd.Timestamp(end_ns, tz="UTC").isoformat()
            return {**row, "route": None, "error": f"departure after the weather's last time {end}: not routed"}
        try:
            opt = search(st.mesh, st.wx, req.ship, st.start_node, st.goal_node, t_start_h=st.t_node_h, cost="time")
            routes = plain_routes(st, {"time": opt, "distance": md})
            name, saving = "optimal_smoothed", {}
            if objective != "time":
                stats = fuel_routes(st, routes, opt.nodes, md.nodes, fuel, _props_maker(st), bound=False)  # no gap in the rows
                name = "least_fuel"
                # against this departure's own same-arrival reference (never against another departure)
                saving = {"saving_pct": stats.get("saving_pct"), "reference_fuel_t": (stats.get("reference") or {}).get("fuel_t")}
            r = routes[name]
            row.update(_row(r, exposure), **saving)
        except NoRouteError as e:
            row.update({"route": None, "error": str(e)})
        return row

    # the departures share only read-only arrays (mesh, weather, the minimum-distance path) and the compiled searches
    # release the GIL, so two threads route them (the machines have two cores); rows keep the departures' order
    if len(times) > 1:
        with ThreadPoolExecutor(max_workers=WINDOW_THREADS) as pool:
            rows = list(pool.map(one, times))
    else:
        rows = [one(when) for when in times]
    key = "time_h" if objective == "time" else "fuel_t"
    ok = [i for i, r in enumerate(rows) if r.get(key) is not None]
    best = min(ok, key=lambda i: (rows[i][key], i)) if ok else None
    for i, r in enumerate(rows):
        r["best"] = i == best
    # what every row rests on, as a plan's notes: the model, and the mesh's refinement, wider box or antimeridian frame
    notes = model_notes(first, base.mw) + base.notes
    return {"objective": objective, "rows": rows, "best": best, "notes": notes, "seconds": round(_time.perf_counter() - t_all, 4)}


def _row(r, exposure) -> dict:
    out = {"route": r.name, "arrive_utc": r.time_utc[-1].round("s").isoformat(), "time_h": round(r.time_h, 4),
           "dist_nmi": round(r.dist_nmi, 4), "fuel_t": r.properties.get("fuel_t"), "co2_t": r.properties.get("co2_t"),
           "max_hs_m": None if np.isnan(r.max_hs_m) else round(r.max_hs_m, 4)}  # fmt: skip
    if exposure is not None:
        out["hours_over_limits"] = round(exposure(r)["hours_over_limits"], 4)
    if r.properties.get("weather_held_after_h"):  # arrives after the last weather time: the last field was held
        out["weather_held_after_h"] = r.properties["weather_held_after_h"]
    return out


def _exposure(vessel, limits, st):
    """Hours over the vessel's limits of a route at its own ETAs, in the plan's weather on the mesh."""
    from routing.safety import SafetySpec, limits_exposure

    spec = SafetySpec("soft", vessel, limits)
    weather_at = mesh_weather_at(st.mesh, st.mw, st.wx)
    return lambda route: limits_exposure(route, weather_at, spec)
