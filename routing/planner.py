"""From a request (start, goal, departure, ship, mesh options) and weather to the four routes.

:func:`plan_routes` builds the mesh over the bbox, maps the weather onto it, snaps start and
goal to sea nodes, runs the time-optimal and the minimum-distance searches, smooths the
optimal route, re-times the minimum-distance route through the weather and in calm water,
and returns :class:`routing.route.Route` objects:

``optimal``            the raw grid route of least sailing time;
``optimal_smoothed``   the same after any-angle smoothing (never slower, never on land);
``min_distance``       the shortest sea route on the mesh, sailed through the weather;
``min_distance_calm``  the same path in calm water (v0 throughout).

With ``safety="soft"`` or ``"hard"`` (and the vessel and its operator limits) two more routes
respect the vessel's limits (:mod:`routing.safety`), and every route reports the hours it spends
over them (``hours_over_limits``, ``hours_by_rule``, judged by the threshold functions at its
own ETAs, and ``unsafe_cell_h``, as the search judges cells):

``safe_optimal``           the raw grid route of least time (``hard``) or least time plus
                           penalties (``soft``) under the limits; when ``hard`` finds no route it
                           falls back to ``soft`` and says so (``safety_fallback``);
``safe_optimal_smoothed``  the same after smoothing whose direct legs keep clear of unsafe cells
                           (never slower, never more exposed than the raw route).
"""

from __future__ import annotations

import logging
import math
import time as _time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from routing.astar import ShipModel, WeatherArrays, evaluate_path, path_exposure, reachable, search, smooth
from routing.errors import LandPointError, NoRouteError, OutsideMeshError, WeatherCoverageError
from routing.field import NS_PER_HOUR, MeshWeather, WeatherField
from routing.mesh import Mesh, MeshGrid, build_mesh, global_land_mask_window
from routing.route import Route
from routing.safety import DEFAULT_PENALTY_PER_H, DEFAULT_SECTORS, SafetySpec, build_flags, limits_exposure
from thresholds.geodesy import haversine_nmi, intermediate_point
from thresholds.units import wrap_deg

log = logging.getLogger(__name__)

#: Default mesh spacing without weather (SIMROUTE R6's 1.5 nmi), and the node budget that
#: coarsens it for long routes. [deg]
DEFAULT_SPACING_DEG = 1.5 / 60.0
DEFAULT_MAX_AUTO_NODES = 2_000_000


@dataclass(frozen=True)
class RouteRequest:
    """What to route.

    Attributes
    ----------
    start, goal : (lat_deg, lon_deg)
    depart_utc : pandas.Timestamp
        Timezone-aware departure.
    ship : ShipModel
    spacing_deg : float, optional
        Mesh step on both axes [deg]; default: the weather grid's step, or 1.5 nmi without
        weather, coarsened to stay under :data:`DEFAULT_MAX_AUTO_NODES`.
    bbox : (lon_min, lat_min, lon_max, lat_max), optional
        Default: the great circle's box with a margin (clipped to the weather's grid).
    edges : {8, 16, 24, 48}
    ignore_land : bool
        Route on an all-sea sphere (accuracy tests); weather gaps count as calm.
    snap_limit_nmi : float
        How far a start/goal on land may move to the nearest sea node.
    vessel_name : str
    land_check, use_land_mask, weather_time
        Comparison knobs, to reproduce SIMROUTE's conventions: ``land_check="end_node"`` tests
        only the end node of an edge, ``use_land_mask=False`` takes sea/land from the weather
        alone, ``weather_time="simroute"`` reads for an edge started ``e`` hours after an
        on-the-hour departure the hourly field of hour ``floor(e) + 1`` (one hour ahead, no
        interpolation) instead of interpolating at the true time (``"linear"``).
    """

    start: tuple
    goal: tuple
    depart_utc: pd.Timestamp
    ship: ShipModel
    spacing_deg: float | None = None
    bbox: tuple | None = None
    edges: int = 48
    ignore_land: bool = False
    snap_limit_nmi: float = 10.0
    vessel_name: str = ""
    land_check: str = "cells"
    use_land_mask: bool = True
    weather_time: str = "linear"

    def __post_init__(self):
        for what, (lat, lon) in (("start", self.start), ("goal", self.goal)):
            if not (-90.0 <= float(lat) <= 90.0 and -180.0 <= float(lon) <= 180.0):
                raise ValueError(f"{what} ({lat}, {lon}) is not a valid (lat, lon) in degrees")
        if self.weather_time not in ("linear", "simroute"):
            raise ValueError(f"weather_time must be 'linear' or 'simroute', got {self.weather_time!r}")
        depart = pd.Timestamp(self.depart_utc)
        if depart.tz is None:
            raise ValueError("depart_utc must be timezone-aware (UTC)")
        object.__setattr__(self, "depart_utc", depart.tz_convert("UTC"))


@dataclass
class RoutePlan:
    """The routes and how they were obtained."""

    great_circle_nmi: float
    routes: dict
    mesh: Mesh
    stats: dict = field(default_factory=dict)
    #: The weather on the mesh as the search read it (for re-timing other routes with the same
    #: model, :mod:`routing.compare`), and the vessel model it was searched with.
    weather_arrays: WeatherArrays | None = None
    ship: ShipModel | None = None

    def to_dict(self) -> dict:
        """The CLI's JSON object (with safety: the safe routes, each route's hours over the limits,
        and a ``safety`` summary)."""
        out = {"great_circle_nmi": round(self.great_circle_nmi, 6)}
        for name in ROUTE_NAMES + SAFE_ROUTE_NAMES:
            if name not in self.routes:
                continue
            r = self.routes[name]
            out[name] = r.to_dict()
            for key in SAFETY_KEYS:
                if key in r.properties:
                    out[name][key] = r.properties[key]
        if "safety" in self.stats:
            out["safety"] = self.stats["safety"]
        return out


#: Routes every plan has, and those a safety-constrained plan adds.
ROUTE_NAMES = ("optimal", "optimal_smoothed", "min_distance", "min_distance_calm")
SAFE_ROUTE_NAMES = ("safe_optimal", "safe_optimal_smoothed")
#: Route properties copied into the JSON object when present.
SAFETY_KEYS = ("hours_over_limits", "operator_h", "imo_h", "hours_by_rule", "unsafe_cell_h", "safety_requested", "safety_mode",
               "safety_fallback")


def default_bbox(start, goal, margin_deg: float | None = None) -> tuple:
    """Box around the great circle start -> goal plus a margin (max(1 deg, 15 % of its span))."""
    f = np.linspace(0.0, 1.0, 257)
    lat, lon = intermediate_point(start[0], start[1], goal[0], goal[1], f)
    lat = np.asarray(lat)
    lon = np.asarray(lon)
    if lon.max() - lon.min() > 180.0:
        raise OutsideMeshError(f"the great circle {tuple(start)} -> {tuple(goal)} crosses the antimeridian: routes across "
                               "it are not supported (the mesh spans lon -180..180)")
    span = max(lat.max() - lat.min(), lon.max() - lon.min())
    m = max(1.0, 0.15 * span) if margin_deg is None else margin_deg
    return (
        max(lon.min() - m, -180.0),
        max(lat.min() - m, -85.0),
        min(lon.max() + m, 179.999),
        min(lat.max() + m, 85.0),
    )


def _auto_spacing(bbox, base_deg: float) -> float:
    area_nodes = (bbox[2] - bbox[0]) * (bbox[3] - bbox[1]) / (base_deg * base_deg)
    if area_nodes <= DEFAULT_MAX_AUTO_NODES:
        return base_deg
    return base_deg * math.sqrt(area_nodes / DEFAULT_MAX_AUTO_NODES)


def sample_weather(mesh: Mesh, mw: MeshWeather | None, lat_deg, lon_deg, t_h) -> dict:
    """Weather at points and times (hours after the weather's slice 0), bilinear over sea nodes.

    Returns ``hs_m``, ``wave_from_deg`` (from the interpolated components), ``tp_s``,
    ``current_u_ms``/``current_v_ms`` and ``wind_u_ms``/``wind_v_ms`` as available.
    """
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    if mw is None:
        return {"hs_m": np.zeros(lat.size)}
    g = mesh.grid
    y = np.clip((lat - g.lat0_deg) / g.dlat_deg, 0.0, g.ny - 1)
    x = np.clip((lon - g.lon0_deg) / g.dlon_deg, 0.0, g.nx - 1)
    j0 = np.clip(np.floor(y).astype(int), 0, g.ny - 2)
    i0 = np.clip(np.floor(x).astype(int), 0, g.nx - 2)
    fy = y - j0
    fx = x - i0
    tx = np.asarray(t_h, dtype=float) / mw.dt_h
    k0 = np.clip(np.floor(tx).astype(int), 0, mw.n_times - 1)
    k1 = np.minimum(k0 + 1, mw.n_times - 1)
    wt = np.where(k1 > k0, np.clip(tx - k0, 0.0, 1.0), 0.0)
    channels = {"hs_m": mw.wave[:, :, 0], "wave_cos": mw.wave[:, :, 1], "wave_sin": mw.wave[:, :, 2]}
    if mw.current is not None:
        channels["current_u_kn"] = mw.current[:, :, 0]
        channels["current_v_kn"] = mw.current[:, :, 1]
    channels.update(mw.extra)
    acc = {name: np.zeros(lat.size) for name in channels}
    wsum = np.zeros(lat.size)
    for dj, di in ((0, 0), (0, 1), (1, 0), (1, 1)):
        w = (fy if dj else 1.0 - fy) * (fx if di else 1.0 - fx)
        s = mw.sea_index[(j0 + dj) * g.nx + (i0 + di)]
        ok = (s >= 0) & (w > 0)
        w = np.where(ok, w, 0.0)
        sc = np.where(ok, s, 0)
        wsum += w
        for name, arr in channels.items():  # arr: (T, n_sea)
            acc[name] += w * ((1.0 - wt) * arr[k0, sc] + wt * arr[k1, sc])
    wsum = np.where(wsum > 0, wsum, np.nan)
    vals = {name: a / wsum for name, a in acc.items()}
    out = {}
    if mw.has_waves:
        out["hs_m"] = vals["hs_m"]
    if mw.has_direction:
        out["wave_from_deg"] = np.asarray(wrap_deg(np.rad2deg(np.arctan2(vals["wave_sin"], vals["wave_cos"]))))
    for name in ("tp_s", "tm_s", "wind_u_ms", "wind_v_ms"):
        if name in vals:
            out[name] = vals[name]
    if "current_u_kn" in vals:
        from thresholds.units import MS_PER_KN

        out["current_u_ms"] = vals["current_u_kn"] * MS_PER_KN
        out["current_v_ms"] = vals["current_v_kn"] * MS_PER_KN
    return out


def _make_route(name, mesh, mw, wx_ref_ns, lat, lon, times_h, depart_utc, props) -> Route:
    times_h = np.asarray(times_h, dtype=float)
    rel = times_h - times_h[0]
    eta = depart_utc + pd.to_timedelta(np.round(rel * NS_PER_HOUR).astype(np.int64), unit="ns")
    legs = np.asarray(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:])) if lat.size > 1 else np.zeros(0)
    dt = np.diff(rel)
    speed = np.divide(legs, dt, out=np.zeros_like(legs), where=dt > 0)
    weather = sample_weather(mesh, mw, lat, lon, times_h)
    return Route(name, lat, lon, pd.DatetimeIndex(eta), speed, weather=weather, properties=props)


def plan_routes(
    req: RouteRequest,
    weather: WeatherField | None = None,
    *,
    land_mask_fn=global_land_mask_window,
    safety: str | SafetySpec = "none",
    vessel=None,
    limits=None,
    penalty_per_h: float = DEFAULT_PENALTY_PER_H,
    sectors: int = DEFAULT_SECTORS,
) -> RoutePlan:
    """Compute the optimal, smoothed, minimum-distance and calm routes for ``req``.

    Parameters
    ----------
    safety : {"none", "soft", "hard"} or SafetySpec
        Also compute the safe time-optimal routes (``safe_optimal``, ``safe_optimal_smoothed``)
        and every route's hours over the limits; ``"none"`` (default) leaves the plan exactly as
        without it.
    vessel : thresholds.vessel.Vessel
        Needed with safety (operator-limit variant, IMO rules).
    limits : OperatorProfile or OperatorLimits, optional
        The operator limits (``None``: IMO rules only).
    penalty_per_h, sectors
        See :class:`routing.safety.SafetySpec`.

    Raises
    ------
    WeatherCoverageError, OutsideMeshError, LandPointError, NoRouteError, MeshSizeError
        With messages naming the point, the mesh and what to change.
    """
    spec = safety if isinstance(safety, SafetySpec) else SafetySpec(str(safety), vessel, limits, penalty_per_h, sectors)
    timings = {}
    t_all = _time.perf_counter()
    c_all = _time.process_time()
    depart_ns = int(req.depart_utc.value)
    start, goal = (float(req.start[0]), float(req.start[1])), (float(req.goal[0]), float(req.goal[1]))
    gc_nmi = float(haversine_nmi(start[0], start[1], goal[0], goal[1]))

    bbox = req.bbox
    if bbox is None:
        bbox = default_bbox(start, goal)
        if weather is not None and not req.ignore_land:
            wl, wr = weather.lon_deg[0], weather.lon_deg[-1]
            wb, wt_ = weather.lat_deg[0], weather.lat_deg[-1]
            bbox = (max(bbox[0], wl), max(bbox[1], wb), min(bbox[2], wr), min(bbox[3], wt_))
    if weather is not None and not req.ignore_land:
        for what, (lat, lon) in (("start", start), ("goal", goal)):
            if not (weather.lat_deg[0] - 1e-9 <= lat <= weather.lat_deg[-1] + 1e-9 and weather.lon_deg[0] - 1e-9 <= lon <= weather.lon_deg[-1] + 1e-9):
                raise WeatherCoverageError(
                    f"{what} ({lat:.4f}, {lon:.4f}) is outside the weather grid lat {weather.lat_deg[0]:.4f}..{weather.lat_deg[-1]:.4f}, "
                    f"lon {weather.lon_deg[0]:.4f}..{weather.lon_deg[-1]:.4f}"
                )
    spacing = req.spacing_deg
    if spacing is None:
        base = DEFAULT_SPACING_DEG
        if weather is not None:
            base = float(min(np.min(np.diff(weather.lat_deg)), np.min(np.diff(weather.lon_deg))))
        spacing = _auto_spacing(bbox, base)
    grid = MeshGrid.from_bbox(bbox, spacing, anchor=start)

    t = _time.perf_counter()
    c = _time.process_time()
    use_mask = req.use_land_mask and not req.ignore_land and land_mask_fn is not None
    land = land_mask_fn(grid) if use_mask else None
    timings["land_mask_s"] = _time.perf_counter() - t
    timings["land_mask_cpu_s"] = _time.process_time() - c
    if land is None:
        node_sea = np.ones((grid.ny, grid.nx), dtype=bool)
    else:
        lat2d, lon2d = np.meshgrid(grid.lat_deg, grid.lon_deg, indexing="ij")
        node_sea = land.is_ocean(lat2d, lon2d)

    t = _time.perf_counter()
    c = _time.process_time()
    mw = None
    if weather is not None:
        mw = weather.on_mesh(grid.lat_deg, grid.lon_deg, depart_ns, node_sea=node_sea, fill_missing=req.ignore_land)
    timings["weather_to_mesh_s"] = _time.perf_counter() - t
    timings["weather_to_mesh_cpu_s"] = _time.process_time() - c

    t = _time.perf_counter()
    c = _time.process_time()
    mesh = build_mesh(
        grid,
        edges=req.edges,
        weather_sea=None if mw is None else mw.weather_sea,
        land=land,
        ignore_land=req.ignore_land,
        land_check=req.land_check,
    )
    wx = WeatherArrays.build(mesh, mw, step_time=req.weather_time == "simroute", ship=req.ship)
    calm_wx = WeatherArrays.build(mesh, None) if mw is not None else wx
    timings["mesh_s"] = _time.perf_counter() - t
    timings["mesh_cpu_s"] = _time.process_time() - c

    # --- start and goal on sea nodes of one connected sea area
    start_node, start_snap = mesh.snap(start[0], start[1], req.snap_limit_nmi, what="start")
    area = reachable(mesh, start_node)
    try:
        goal_node, goal_snap = mesh.snap(goal[0], goal[1], req.snap_limit_nmi, what="goal")
    except LandPointError:
        raise
    if not area[goal_node]:
        try:
            goal_node, goal_snap = mesh.snap(goal[0], goal[1], req.snap_limit_nmi, within=area, what="goal")
        except LandPointError:
            raise NoRouteError(
                f"no sea route: start ({start[0]:.4f}, {start[1]:.4f}) and goal ({goal[0]:.4f}, {goal[1]:.4f}) lie in "
                f"sea areas that do not connect within the mesh (bbox {tuple(round(x, 4) for x in grid.bbox)}, "
                f"{grid.dlat_deg * 60:.3g} nmi, {mesh.edges} edges); widen the bbox or refine the mesh"
            ) from None

    s_lat, s_lon = (float(x) for x in grid.node_latlon(start_node))
    g_lat, g_lon = (float(x) for x in grid.node_latlon(goal_node))
    lead = start_snap > 1e-6 and mesh.sea.ravel()[mesh.nearest_node(*start)] and mesh.leg_is_sea(start[0], start[1], s_lat, s_lon)
    tail = goal_snap > 1e-6 and mesh.sea.ravel()[mesh.nearest_node(*goal)] and mesh.leg_is_sea(g_lat, g_lon, goal[0], goal[1])

    t0_h = wx.rel_h(depart_ns)
    if req.weather_time == "simroute" and wx.time0_ns is not None:
        t0_h += wx.dt_h  # one slice ahead, read without interpolation
    if lead:
        t_node_h = float(evaluate_path(mesh, wx, req.ship, [start[0], s_lat], [start[1], s_lon], t_start_h=t0_h)[0][-1])
    else:
        t_node_h = t0_h

    results = {}
    t = _time.perf_counter()
    c = _time.process_time()
    results["time"] = search(mesh, wx, req.ship, start_node, goal_node, t_start_h=t_node_h, cost="time")
    timings["search_time_s"] = _time.perf_counter() - t
    timings["search_time_cpu_s"] = _time.process_time() - c
    t = _time.perf_counter()
    c = _time.process_time()
    results["distance"] = search(mesh, wx, req.ship, start_node, goal_node, cost="distance")
    timings["search_distance_s"] = _time.perf_counter() - t
    timings["search_distance_cpu_s"] = _time.process_time() - c

    def polyline(nodes):
        la, lo = grid.node_latlon(nodes)
        la, lo = np.asarray(la, dtype=float), np.asarray(lo, dtype=float)
        if lead:
            la, lo = np.r_[start[0], la], np.r_[start[1], lo]
        if tail:
            la, lo = np.r_[la, goal[0]], np.r_[lo, goal[1]]
        return la, lo

    base_props = {
        "vessel": req.vessel_name,
        "speed_kn": req.ship.speed_kn,
        "speed_loss_model": req.ship.model,
        "floor_kn": req.ship.floor_kn,
        "mesh_spacing_deg": grid.dlat_deg,
        "mesh_edges": mesh.edges,
        "mesh_bbox": [round(x, 6) for x in grid.bbox],
        "mesh_nodes": grid.n_nodes,
        "mesh_sea_nodes": mesh.n_sea,
        "ignore_land": req.ignore_land,
        "start_snap_nmi": round(start_snap, 4),
        "goal_snap_nmi": round(goal_snap, 4),
    }

    t = _time.perf_counter()
    c = _time.process_time()
    routes = {}
    opt_lat, opt_lon = polyline(results["time"].nodes)
    opt_t, opt_hs = evaluate_path(mesh, wx, req.ship, opt_lat, opt_lon, t_start_h=t0_h)
    md_lat, md_lon = polyline(results["distance"].nodes)
    md_t, md_hs = evaluate_path(mesh, wx, req.ship, md_lat, md_lon, t_start_h=t0_h)
    calm_ship = req.ship.calm()
    mdc_t, _ = evaluate_path(mesh, calm_wx, calm_ship, md_lat, md_lon, t_start_h=0.0)
    keep = smooth(mesh, wx, req.ship, opt_lat, opt_lon, opt_t)
    sm_lat, sm_lon = opt_lat[keep], opt_lon[keep]
    sm_t, sm_hs = evaluate_path(mesh, wx, req.ship, sm_lat, sm_lon, t_start_h=t0_h)
    if sm_t[-1] > opt_t[-1] + 1e-9:  # cannot happen under FIFO weather; keep the promise anyway
        log.warning("smoothing would arrive %.3f h later; keeping the raw route", sm_t[-1] - opt_t[-1])
        sm_lat, sm_lon, sm_t, sm_hs = opt_lat, opt_lon, opt_t, opt_hs
    timings["retime_smooth_s"] = _time.perf_counter() - t
    timings["retime_smooth_cpu_s"] = _time.process_time() - c

    end_h = None if wx.time0_ns is None else (mw.end_ns - wx.time0_ns) / NS_PER_HOUR

    def props(kind, res, times, hs_along, **extra):
        p = dict(base_props, cost=kind, **extra)
        if res is not None:
            p.update(search_expanded=res.expanded, search_scanned=res.scanned, search_s=round(res.seconds, 6))
        p["max_hs_m_along"] = round(hs_along, 4)
        if end_h is not None and times[-1] > end_h + 1e-9:
            p["weather_held_after_h"] = round(float(times[-1] - end_h), 4)
            # INFO, not WARNING: the property carries it to the route CLI and the nightly report.
            log.info("route %s ends %.2f h after the last weather time: the last field was held", kind, times[-1] - end_h)
        return p

    depart = req.depart_utc
    routes["optimal"] = _make_route("optimal", mesh, mw, None, opt_lat, opt_lon, opt_t, depart, props("time", results["time"], opt_t, opt_hs))
    routes["optimal_smoothed"] = _make_route(
        "optimal_smoothed", mesh, mw, None, sm_lat, sm_lon, sm_t, depart, props("time", None, sm_t, sm_hs, smoothed_from=int(opt_lat.size))
    )
    routes["min_distance"] = _make_route(
        "min_distance", mesh, mw, None, md_lat, md_lon, md_t, depart, props("distance", results["distance"], md_t, md_hs)
    )
    calm_props = dict(base_props, cost="distance", speed_loss_model="none", calm_water=True, max_hs_m_along=0.0)
    routes["min_distance_calm"] = _make_route("min_distance_calm", mesh, None, None, md_lat, md_lon, mdc_t, depart, calm_props)
    safety_stats = {}
    if spec.mode != "none":
        safety_stats = _safe_routes(
            spec, req, mesh, mw, wx, routes, timings, start_node=start_node, goal_node=goal_node, t_node_h=t_node_h, t0_h=t0_h,
            polyline=polyline, props=props,
        )  # fmt: skip
    timings["total_s"] = _time.perf_counter() - t_all
    timings["total_cpu_s"] = _time.process_time() - c_all
    stats = {
        "timings": timings,
        "expanded_time": results["time"].expanded,
        "scanned_time": results["time"].scanned,
        "expanded_distance": results["distance"].expanded,
        "scanned_distance": results["distance"].scanned,
        "start_node": int(start_node),
        "goal_node": int(goal_node),
        **safety_stats,
    }
    return RoutePlan(gc_nmi, routes, mesh, stats, wx, req.ship)


def _safe_routes(spec: SafetySpec, req, mesh, mw, wx, routes: dict, timings: dict, *, start_node, goal_node, t_node_h, t0_h,
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
    routes["safe_optimal"] = _make_route("safe_optimal", mesh, mw, None, sa_lat, sa_lon, sa_t, depart,
                                         props("time", res, sa_t, sa_hs, unsafe_cell_h=round(raw_ex, 6), **extra))
    routes["safe_optimal_smoothed"] = _make_route(
        "safe_optimal_smoothed", mesh, mw, None, ss_lat, ss_lon, ss_t, depart,
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
