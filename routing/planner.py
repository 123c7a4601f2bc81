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

Stages of :func:`plan_routes` (one function each): :func:`prepare_mesh` (box, spacing, land mask,
weather on the mesh), :func:`place_ends` (start and goal on connected sea nodes), the two
searches, :func:`plain_routes` (re-timing, smoothing, the calm twin), and
:func:`routing.planner_safe.safe_routes`. Routes across the antimeridian are planned in one
continuous longitude frame (:func:`routing.planner_parts.default_bbox`) and come out with
longitudes in [-180, 180). ``RoutePlan.notes`` says what the numbers rest on (the speed-loss
model and its range, variables assumed, waits, weather held).
"""

from __future__ import annotations

import logging
import math
import time as _time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from routing.astar import ShipModel, WeatherArrays, evaluate_path, reachable, search, smooth
from routing.errors import DisconnectedSeaError, LandPointError, NoRouteError, WeatherCoverageError
from routing.field import NS_PER_HOUR, MeshWeather, WeatherField
from routing.mesh import Mesh, MeshGrid, build_mesh, global_land_mask_window
from routing.planner_parts import (  # noqa: F401 (re-exported: the planner's public helpers)
    DEFAULT_MAX_AUTO_NODES,
    DEFAULT_SPACING_DEG,
    auto_spacing,
    default_bbox,
    great_circle_frame,
    make_route,
    sample_weather,
)
from routing.planner_safe import safe_routes
from routing.planner_fuel import FUEL_ROUTE_NAMES  # re-exported: the routes a fuel objective adds
from routing.safety import DEFAULT_PENALTY_PER_H, DEFAULT_SECTORS, SafetySpec
from thresholds.geodesy import haversine_nmi

log = logging.getLogger(__name__)


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
        Default: the great circle's box with a margin (clipped to the weather's grid). Across
        the antimeridian give it in one frame (170, 30, 200, 50) or with lon_max < lon_min
        (170, 30, -160, 50): both mean 170 E eastwards to 160 W.
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
    #: What the times rest on (the speed-loss model and its range, assumptions), said in every output.
    notes: list = field(default_factory=list)
    #: The planner's stage (mesh, end points, node paths), for a later least-fuel search on the same
    #: mesh (:func:`routing.planner_fuel.least_fuel_role`).
    stage: object = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict:
        """The CLI's JSON object (with safety: the safe routes, each route's hours over the limits,
        and a ``safety`` summary)."""
        out = {"great_circle_nmi": round(self.great_circle_nmi, 6)}
        for name in ROUTE_NAMES + SAFE_ROUTE_NAMES + FUEL_ROUTE_NAMES:
            if name not in self.routes:
                continue
            r = self.routes[name]
            out[name] = r.to_dict()
            for key in SAFETY_KEYS:
                if key in r.properties:
                    out[name][key] = r.properties[key]
        if "safety" in self.stats:
            out["safety"] = self.stats["safety"]
        if "fuel" in self.stats:
            out["fuel"] = self.stats["fuel"]
        out["speed_loss"] = self.stats.get("speed_loss")
        return out


#: Routes every plan has, and those a safety-constrained plan adds.
ROUTE_NAMES = ("optimal", "optimal_smoothed", "min_distance", "min_distance_calm")
SAFE_ROUTE_NAMES = ("safe_optimal", "safe_optimal_smoothed")
#: Route properties copied into the JSON object when present.
SAFETY_KEYS = ("fuel_t", "co2_t", "speed_setting_kn", "hours_over_limits", "operator_h", "imo_h", "hours_by_rule", "unsafe_cell_h",
               "safety_requested", "safety_mode", "safety_fallback")


@dataclass
class _Stage:
    """What the stages of :func:`plan_routes` hand on (mesh, weather, end points, timings)."""

    req: RouteRequest
    timings: dict
    start: tuple = ()  # (lat, lon) in the mesh's frame
    goal: tuple = ()
    grid: MeshGrid | None = None
    mesh: Mesh | None = None
    mw: MeshWeather | None = None
    wx: WeatherArrays | None = None
    calm_wx: WeatherArrays | None = None
    start_node: int = -1
    goal_node: int = -1
    start_snap: float = 0.0
    goal_snap: float = 0.0
    lead: bool = False
    tail: bool = False
    t0_h: float = 0.0
    t_node_h: float = 0.0
    notes: list = field(default_factory=list)
    paths: dict = field(default_factory=dict)  # cost -> node path of the plan's searches

    def polyline(self, nodes):
        """Node path -> (lat, lon) in the mesh's frame, with the off-node start and goal legs."""
        la, lo = self.grid.node_latlon(nodes)
        la, lo = np.asarray(la, dtype=float), np.asarray(lo, dtype=float)
        if self.lead:
            la, lo = np.r_[self.start[0], la], np.r_[self.start[1], lo]
        if self.tail:
            la, lo = np.r_[la, self.goal[0]], np.r_[lo, self.goal[1]]
        return la, lo


class _Clock:
    """Wall and CPU time of a stage into ``timings[name + '_s']`` and ``[name + '_cpu_s']``."""

    def __init__(self, timings: dict, name: str):
        self.timings, self.name = timings, name

    def __enter__(self):
        self.t, self.c = _time.perf_counter(), _time.process_time()

    def __exit__(self, *exc):
        self.timings[f"{self.name}_s"] = _time.perf_counter() - self.t
        self.timings[f"{self.name}_cpu_s"] = _time.process_time() - self.c


def mesh_box(req: RouteRequest, weather: WeatherField | None, start, goal, margin_scale: float = 1.0) -> tuple:
    """The mesh's box in the start's longitude frame: the request's (lon_max < lon_min crosses the
    antimeridian) or the great circle's (its margin times ``margin_scale``), clipped to the
    weather's grid; checks that the weather holds start and goal."""
    if req.bbox is not None:
        lo, la0, hi, la1 = (float(x) for x in req.bbox)
        if hi < lo:
            hi += 360.0
        shift = 360.0 * round(((lo + hi) / 2.0 - start[1]) / 360.0)  # the frame of the start
        bbox = (lo - shift, la0, hi - shift, la1)
    else:
        bbox = default_bbox(start, goal, margin_scale=margin_scale)
    if weather is None or req.ignore_land:
        return bbox
    for what, (lat, lon) in (("start", req.start), ("goal", req.goal)):
        if not weather.covers(lat, lon):
            lo_w, hi_w, _ = weather.lon_cover()
            raise WeatherCoverageError(
                f"{what} ({lat:.4f}, {lon:.4f}) is outside the weather grid lat {weather.lat_deg[0]:.4f}..{weather.lat_deg[-1]:.4f}, "
                f"lon {lo_w:.4f}..{hi_w:.4f}"
            )
    if req.bbox is None:
        lo_w, hi_w, is_global = weather.lon_cover()
        bbox = (bbox[0], max(bbox[1], weather.lat_deg[0]), bbox[2], min(bbox[3], weather.lat_deg[-1]))
        if not is_global:
            shift = 360.0 * math.floor((start[1] - lo_w) / 360.0)  # the grid's interval holding the start
            bbox = (max(bbox[0], lo_w + shift), bbox[1], min(bbox[2], hi_w + shift), bbox[3])
    return bbox


def mesh_spacing(req: RouteRequest, weather: WeatherField | None, bbox) -> float:
    """The mesh step over ``bbox``: the request's, else the automatic one (the weather's grid
    step, 1.5 nmi without weather, coarsened to keep the node bound). [deg]"""
    if req.spacing_deg is not None:
        return req.spacing_deg
    base = DEFAULT_SPACING_DEG
    if weather is not None:
        base = float(min(np.min(np.diff(weather.lat_deg)), np.min(np.diff(weather.lon_deg))))
    return auto_spacing(bbox, base)


def prepare_mesh(req: RouteRequest, weather: WeatherField | None, land_mask_fn, st: _Stage, spacing_deg: float | None = None,
                 margin_scale: float = 1.0) -> None:
    """Box, spacing, land mask, weather on the mesh, the mesh and its weather arrays (into ``st``).
    ``spacing_deg`` overrides the request's (a refined automatic mesh), ``margin_scale`` widens the
    automatic box (:func:`mesh_and_ends`)."""
    start = (float(req.start[0]), float(req.start[1]))
    st.start, st.goal = start, _goal_in_start_frame(req)
    bbox = mesh_box(req, weather, start, st.goal, margin_scale)
    spacing = mesh_spacing(req, weather, bbox) if spacing_deg is None else spacing_deg
    grid = MeshGrid.from_bbox(bbox, spacing, anchor=start)
    st.grid = grid
    if grid.lon_deg[0] < -180.0 or grid.lon_deg[-1] >= 180.0:
        st.notes.append(f"the mesh crosses the antimeridian: planned in one longitude frame {grid.lon_deg[0]:.2f}..{grid.lon_deg[-1]:.2f}, "
                        "reported in -180..180")
    with _Clock(st.timings, "land_mask"):
        use_mask = req.use_land_mask and not req.ignore_land and land_mask_fn is not None
        land = land_mask_fn(grid) if use_mask else None
    if land is None:
        node_sea = np.ones((grid.ny, grid.nx), dtype=bool)
    else:
        lat2d, lon2d = np.meshgrid(grid.lat_deg, grid.lon_deg, indexing="ij")
        node_sea = land.is_ocean(lat2d, lon2d)
    with _Clock(st.timings, "weather_to_mesh"):
        if weather is not None:
            st.mw = weather.on_mesh(grid.lat_deg, grid.lon_deg, int(req.depart_utc.value), node_sea=node_sea, fill_missing=req.ignore_land)
    with _Clock(st.timings, "mesh"):
        st.mesh = build_mesh(grid, edges=req.edges, weather_sea=None if st.mw is None else st.mw.weather_sea, land=land,
                             ignore_land=req.ignore_land, land_check=req.land_check)  # fmt: skip
        st.wx = WeatherArrays.build(st.mesh, st.mw, step_time=req.weather_time == "simroute", ship=req.ship)
        st.calm_wx = WeatherArrays.build(st.mesh, None) if st.mw is not None else st.wx


def place_ends(st: _Stage) -> None:
    """Start and goal on sea nodes of one connected sea area, the off-node legs, the start times."""
    req, mesh, grid, start, goal = st.req, st.mesh, st.grid, st.start, st.goal
    st.start_node, st.start_snap = mesh.snap(start[0], start[1], req.snap_limit_nmi, what="start")
    area = reachable(mesh, st.start_node)
    st.goal_node, st.goal_snap = mesh.snap(goal[0], goal[1], req.snap_limit_nmi, what="goal")
    if not area[st.goal_node]:
        try:
            st.goal_node, st.goal_snap = mesh.snap(goal[0], goal[1], req.snap_limit_nmi, within=area, what="goal")
        except LandPointError:
            raise DisconnectedSeaError(
                f"no sea route: start ({req.start[0]:.4f}, {req.start[1]:.4f}) and goal ({req.goal[0]:.4f}, {req.goal[1]:.4f}) lie in "
                f"sea areas that do not connect within the mesh (bbox {tuple(round(x, 4) for x in grid.bbox)}, "
                f"{grid.dlat_deg * 60:.3g} nmi, {mesh.edges} edges); widen the bbox or refine the mesh"
            ) from None
    s_lat, s_lon = (float(x) for x in grid.node_latlon(st.start_node))
    g_lat, g_lon = (float(x) for x in grid.node_latlon(st.goal_node))
    sea = mesh.sea.ravel()
    st.lead = bool(st.start_snap > 1e-6 and sea[mesh.nearest_node(*start)] and mesh.leg_is_sea(start[0], start[1], s_lat, s_lon))
    st.tail = bool(st.goal_snap > 1e-6 and sea[mesh.nearest_node(*goal)] and mesh.leg_is_sea(g_lat, g_lon, goal[0], goal[1]))
    wx = st.wx
    st.t0_h = wx.rel_h(int(req.depart_utc.value))
    if req.weather_time == "simroute" and wx.time0_ns is not None:
        st.t0_h += wx.dt_h  # one slice ahead, read without interpolation
    st.t_node_h = st.t0_h
    if st.lead:
        st.t_node_h = float(evaluate_path(mesh, wx, req.ship, [start[0], s_lat], [start[1], s_lon], t_start_h=st.t0_h)[0][-1])


#: Halvings of an automatic mesh step tried when start and goal lie in sea areas the mesh does
#: not connect: a fjord, skerries or a harbour behind a passage narrower than the step (Bergen to
#: Alesund does not connect on the default 1.5 nmi mesh, does on 0.75 nmi), or when a port has
#: no sea node within the snapping limit (the mesh takes the weather's step: Lisbon has none
#: within 10 nmi on GFS's 0.5 deg, 30 nmi). Each halving quadruples the nodes, so it is taken
#: only while the mesh stays within the automatic mesh's bound
#: (:data:`routing.planner_parts.DEFAULT_MAX_AUTO_NODES`).
MAX_MESH_REFINEMENTS = 3


#: Doublings of the automatic box's margin tried when start and goal still do not connect on the
#: refined mesh: the sea way leaves the great circle's box (Venice to Naples rounds Italy's heel,
#: 4-5 deg beyond the box's 1 deg margin). Each wider box keeps the first mesh's step and lattice
#: (the same nodes around start and goal), so only the box changes, while it stays within the
#: automatic mesh's node bound (:data:`routing.planner_parts.DEFAULT_MAX_AUTO_NODES`).
MAX_BOX_WIDENINGS = 5


def mesh_and_ends(req: RouteRequest, weather: WeatherField | None, land_mask_fn) -> _Stage:
    """:func:`refined_mesh_and_ends` on the great circle's box; where start and goal do not
    connect in it, the box (when automatic) widened by doubling its margin, at the first mesh's
    step, at most :data:`MAX_BOX_WIDENINGS` times, within the node bound and the weather's grid;
    the first box that connects them is planned, and a note says so. A box the user chose is
    kept (the error stands)."""
    try:
        return refined_mesh_and_ends(req, weather, land_mask_fn)
    except DisconnectedSeaError as err:
        if req.bbox is not None or req.ignore_land:
            raise
        first = err
    goal = _goal_in_start_frame(req)

    def box_of(factor: float) -> tuple:  # the automatic box with its margin times factor, clipped to the weather
        return mesh_box(req, weather, req.start, goal, factor)

    def rounded(box: tuple) -> tuple:
        return tuple(round(x, 4) for x in box)

    box = box_of(1.0)
    step_deg = mesh_spacing(req, weather, box)  # the first mesh's step, before any refinement
    seen, scale = rounded(box), 1.0
    for k in range(1, MAX_BOX_WIDENINGS + 1):
        box = box_of(2.0**k)
        if rounded(box) == seen or auto_spacing(box, step_deg) != step_deg:
            break  # the weather's grid holds the box, or a wider box needs a coarser step (the node bound)
        st = _Stage(req, {})
        prepare_mesh(req, weather, land_mask_fn, st, spacing_deg=step_deg, margin_scale=2.0**k)
        seen, scale = rounded(box), 2.0**k
        try:
            place_ends(st)
        except DisconnectedSeaError:
            continue
        st.notes.append(f"start and goal do not connect through the sea within the great circle's box: planned in a box "
                        f"widened to lon {box[0]:.2f}..{box[2]:.2f}, lat {box[1]:.2f}..{box[3]:.2f}")
        return st
    if scale > 1.0:
        first.args = (f"{first}; the great circle's box widened up to {scale:g} times its margin on a {step_deg * 60:.3g} nmi mesh "
                      "did not connect them either",)
    raise first


def _goal_in_start_frame(req: RouteRequest) -> tuple:
    """The goal's longitude in the start's frame (unchanged unless the route crosses 180)."""
    lon = float(req.goal[1]) + 360.0 * round((float(req.start[1]) - float(req.goal[1])) / 360.0)
    return (float(req.goal[0]), lon)


def refined_mesh_and_ends(req: RouteRequest, weather: WeatherField | None, land_mask_fn) -> _Stage:
    """:func:`prepare_mesh` and :func:`place_ends`. With an automatic step (no spacing in the
    request), a mesh on which start and goal do not connect, or on which one of them has no sea
    node within the snapping limit while the step is longer than that limit, is refined by
    halving its step (at most
    :data:`MAX_MESH_REFINEMENTS` times, within the node bound), and a note says so: the route is
    planned on the finer mesh. A spacing the user chose is kept (the error stands)."""
    tried: list[float] = []
    reason = ""
    while True:
        st = _Stage(req, {})
        prepare_mesh(req, weather, land_mask_fn, st, spacing_deg=tried[-1] / 2 if tried else None)
        try:
            place_ends(st)
            break
        except (DisconnectedSeaError, LandPointError) as err:
            # a point with no sea node within the limit gains from a finer mesh only while the
            # step is longer than the limit (else the sea is that far: an inland point stays refused at once)
            helps = not isinstance(err, LandPointError) or st.grid.dlat_deg * 60.0 > err.limit_nmi
            can = (req.spacing_deg is None and helps and len(tried) < MAX_MESH_REFINEMENTS
                   and st.grid.ny * st.grid.nx * 4 <= DEFAULT_MAX_AUTO_NODES)
            tried.append(st.grid.dlat_deg)
            if not can:
                if len(tried) > 1:
                    err.args = (f"{err} (the automatic mesh refined from {tried[0] * 60:.3g} nmi)",)
                raise
            reason = reason or _refine_reason(err)
    if tried:
        st.notes.append(f"{reason} on the automatic {tried[0] * 60:.3g} nmi mesh: planned on a "
                        f"{st.grid.dlat_deg * 60:.3g} nmi mesh")
    return st


def _refine_reason(err: Exception) -> str:
    """Why an automatic mesh was refined, for the plan's note."""
    if isinstance(err, LandPointError):
        return f"the {err.what} has no sea node within {err.limit_nmi:g} nmi"
    return "start and goal do not connect through the sea"


def plain_routes(st: _Stage, results: dict) -> dict:
    """The four routes of every plan: optimal (raw and smoothed), minimum distance, and calm."""
    req, mesh, wx, mw = st.req, st.mesh, st.wx, st.mw
    t0_h = st.t0_h
    with _Clock(st.timings, "retime_smooth"):
        opt_lat, opt_lon = st.polyline(results["time"].nodes)
        opt_t, opt_hs = evaluate_path(mesh, wx, req.ship, opt_lat, opt_lon, t_start_h=t0_h)
        md_lat, md_lon = st.polyline(results["distance"].nodes)
        md_t, md_hs = evaluate_path(mesh, wx, req.ship, md_lat, md_lon, t_start_h=t0_h)
        mdc_t, _ = evaluate_path(mesh, st.calm_wx, req.ship.calm(), md_lat, md_lon, t_start_h=0.0)
        keep = smooth(mesh, wx, req.ship, opt_lat, opt_lon, opt_t)
        sm_lat, sm_lon = opt_lat[keep], opt_lon[keep]
        sm_t, sm_hs = evaluate_path(mesh, wx, req.ship, sm_lat, sm_lon, t_start_h=t0_h)
        if sm_t[-1] > opt_t[-1] + 1e-9:  # cannot happen with FIFO edges; keep the promise anyway
            log.warning("smoothing would arrive %.3f h later; keeping the raw route", sm_t[-1] - opt_t[-1])
            sm_lat, sm_lon, sm_t, sm_hs = opt_lat, opt_lon, opt_t, opt_hs
    props = _props_maker(st)
    depart = req.depart_utc
    calm_props = dict(_base_props(st), cost="distance", speed_loss_model="none", calm_water=True, max_hs_m_along=0.0)
    return {
        "optimal": make_route("optimal", mesh, mw, opt_lat, opt_lon, opt_t, depart, props("time", results["time"], opt_t, opt_hs)),
        "optimal_smoothed": make_route("optimal_smoothed", mesh, mw, sm_lat, sm_lon, sm_t, depart,
                                       props("time", None, sm_t, sm_hs, smoothed_from=int(opt_lat.size))),
        "min_distance": make_route("min_distance", mesh, mw, md_lat, md_lon, md_t, depart,
                                   props("distance", results["distance"], md_t, md_hs)),
        "min_distance_calm": make_route("min_distance_calm", mesh, None, md_lat, md_lon, mdc_t, depart, calm_props),
    }  # fmt: skip


def _base_props(st: _Stage) -> dict:
    req, grid, mesh = st.req, st.grid, st.mesh
    return {
        "vessel": req.vessel_name,
        "speed_kn": req.ship.speed_kn,
        "speed_loss_model": req.ship.model,
        "speed_loss": req.ship.describe(),
        "floor_kn": req.ship.floor_kn,
        "mesh_spacing_deg": grid.dlat_deg,
        "mesh_edges": mesh.edges,
        "mesh_bbox": [round(x, 6) for x in grid.bbox],
        "mesh_nodes": grid.n_nodes,
        "mesh_sea_nodes": mesh.n_sea,
        "ignore_land": req.ignore_land,
        "start_snap_nmi": round(st.start_snap, 4),
        "goal_snap_nmi": round(st.goal_snap, 4),
    }


def _props_maker(st: _Stage):
    """``props(kind, search_result, times, hs_along, **extra)`` for the routes of this plan."""
    base = _base_props(st)
    wx, mw = st.wx, st.mw
    end_h = None if wx.time0_ns is None else (mw.end_ns - wx.time0_ns) / NS_PER_HOUR

    def props(kind, res, times, hs_along, **extra):
        p = dict(base, cost=kind, **extra)
        if res is not None:
            p.update(search_expanded=res.expanded, search_scanned=res.scanned, search_s=round(res.seconds, 6))
        p["max_hs_m_along"] = round(hs_along, 4) if mw is None or mw.has_waves else float("nan")  # no waves in the data: unknown
        if end_h is not None and times[-1] > end_h + 1e-9:
            p["weather_held_after_h"] = round(float(times[-1] - end_h), 4)
            # INFO, not WARNING: the property carries it to the route CLI and the nightly report.
            log.info("route %s ends %.2f h after the last weather time: the last field was held", kind, times[-1] - end_h)
        return p

    return props


def model_notes(req: RouteRequest, mw: MeshWeather | None) -> list:
    """What the times rest on: the speed-loss model (its range, convention), and the variables
    it reads that the weather lacks a part of (direction assumed head seas)."""
    ship = req.ship
    notes = [f"speed loss: {ship.describe()}" + ("" if ship.wait else "; the ship never waits (not optimal where costs jump)")]
    if mw is None:  # the speed-loss model then never acts: said, so a calm-sea time is not read as a weather route's
        notes.append("no weather given: every route is sailed in a calm sea (no waves, wind or current)")
        return notes
    if ship.model == "none":
        return notes
    if ship.wind_driven:
        notes.append("Kwon's loss reads the 10 m wind (Beaufort number and direction), not the waves")
    elif not mw.has_direction:
        notes.append("the weather has no wave direction: every edge is sailed as in head seas (the largest loss)")
    if ship.model == "learned" and ship.learned.beyond_training(mw.hs_max_m):
        notes.append(f"the weather holds Hs up to {mw.hs_max_m:.1f} m, above the {ship.learned.hs_max_trained_m:.1f} m the "
                     f"learned model was trained on: its speed at {ship.learned.hs_max_trained_m:.1f} m is held beyond")
    return notes


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
    fuel=None,
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
    fuel : routing.fuel.FuelSpec, optional
        Also the least-fuel route with a speed setting per leg and its same-arrival reference
        (:mod:`routing.planner_fuel`); every route then reports ``fuel_t`` and ``co2_t``.

    Raises
    ------
    WeatherCoverageError, WeatherVariableError, OutsideMeshError, LandPointError, NoRouteError, MeshSizeError
        With messages naming the point, the mesh, the variable and what to change;
        :class:`routing.fuel.InfeasibleArrivalError` (a NoRouteError) when no route meets ``fuel.arrive_by``.
    """
    spec = safety if isinstance(safety, SafetySpec) else SafetySpec(str(safety), vessel, limits, penalty_per_h, sectors)
    t_all, c_all = _time.perf_counter(), _time.process_time()
    st = mesh_and_ends(req, weather, land_mask_fn)
    results = {}
    with _Clock(st.timings, "search_time"):
        results["time"] = search(st.mesh, st.wx, req.ship, st.start_node, st.goal_node, t_start_h=st.t_node_h, cost="time")
    with _Clock(st.timings, "search_distance"):
        results["distance"] = search(st.mesh, st.wx, req.ship, st.start_node, st.goal_node, cost="distance")
    routes = plain_routes(st, results)
    st.paths = {k: r.nodes for k, r in results.items()}
    safety_stats = {}
    if spec.mode != "none":
        safety_stats = safe_routes(
            spec, req, st.mesh, st.mw, st.wx, routes, st.timings, start_node=st.start_node, goal_node=st.goal_node,
            t_node_h=st.t_node_h, t0_h=st.t0_h, polyline=st.polyline, props=_props_maker(st),
        )  # fmt: skip
    if fuel is not None:
        from routing.planner_fuel import fuel_routes

        with _Clock(st.timings, "search_fuel"):
            safety_stats["fuel"] = fuel_routes(st, routes, results["time"].nodes, results["distance"].nodes, fuel, _props_maker(st))
        if spec.mode != "none":
            from routing.planner_fuel import FUEL_ROUTE_NAMES
            from routing.planner_safe import fuel_routes_exposure

            fuel_routes_exposure(spec, st, routes, FUEL_ROUTE_NAMES)
    st.timings["total_s"] = _time.perf_counter() - t_all
    st.timings["total_cpu_s"] = _time.process_time() - c_all
    stats = {
        "timings": st.timings,
        "expanded_time": results["time"].expanded,
        "scanned_time": results["time"].scanned,
        "expanded_distance": results["distance"].expanded,
        "scanned_distance": results["distance"].scanned,
        "start_node": int(st.start_node),
        "goal_node": int(st.goal_node),
        "speed_loss": req.ship.describe(),
        **safety_stats,
    }
    gc_nmi = float(haversine_nmi(req.start[0], req.start[1], req.goal[0], req.goal[1]))
    return RoutePlan(gc_nmi, routes, st.mesh, stats, st.wx, req.ship, model_notes(req, st.mw) + st.notes, stage=st)
