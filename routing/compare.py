"""Like-for-like comparisons: every route sailed by the same vessel model in the same weather.

An A* plan (:func:`routing.planner.plan_routes`) times its routes with one edge model: the speed
through the water is the vessel's calm-water speed minus the speed loss of the chosen model in
the weather met (mean of the two ends of each piece of at most one stencil edge, read when the
ship reaches the piece), never below the floor, plus the current (:mod:`routing.astar`).
:func:`retime` sails any other polyline (a lane's centroids, a deviation, an AIS track) through
exactly that model, from the same departure, so a comparison of routes is a comparison of
routes, not of speed models.

The invariant (:func:`optimality_gaps`): with the same model, the smoothed time-optimal route is
not slower than any other route of the comparison by more than the mesh's discretisation
(:func:`discretisation_tolerance_h`), except a route whose search had a safety constraint
active (``safe_optimal``: the vessel's limits), which says so.

References
----------
.. [1] M. Grifoll, C. Borén and M. Castells-Sanabra, Ocean Eng. 255, 111427, 2022,
       doi:10.1016/j.oceaneng.2022.111427, section 2.2 (48-edge stencil, 3.2-14.0 deg).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from routing.route import Route
from thresholds.geodesy import haversine_nmi
from thresholds.units import EARTH_RADIUS_NMI

#: Routes whose search has a safety constraint (they may be slower than the time-optimal route).
CONSTRAINED = {"safe_optimal": "the vessel's operator and IMO limits (safe time-optimal A*)"}


def retime(lat_deg, lon_deg, depart_utc, plan, *, name: str, properties: dict | None = None) -> Route:
    """A polyline sailed by the plan's vessel model in the plan's weather from ``depart_utc``.

    Parameters
    ----------
    lat_deg, lon_deg : array_like
        Waypoints (great-circle legs). [deg]
    depart_utc : Timestamp
        Departure (tz-aware).
    plan : routing.planner.RoutePlan
        Its mesh, weather arrays and ship model (``properties`` of its routes) are used.

    Returns
    -------
    Route
        ETAs from the model, leg speeds = distance / time (speed over ground), ``properties``
        plus ``timed_by="model"``, the model's speed, loss model and floor, ``max_hs_m_along``.
    """
    from routing.astar import evaluate_path

    ship = plan_ship(plan)
    wx = plan.weather_arrays
    t0 = pd.Timestamp(depart_utc)
    t0 = t0.tz_localize("UTC") if t0.tzinfo is None else t0.tz_convert("UTC")
    t0_h = wx.rel_h(t0.value)
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    times_h, hs_max = evaluate_path(plan.mesh, wx, ship, lat, lon, t_start_h=t0_h)
    hours = np.asarray(times_h, dtype=float) - t0_h
    times = pd.DatetimeIndex(t0 + pd.to_timedelta(hours, unit="h"))
    d = np.asarray(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]), dtype=float).reshape(-1)
    dt = np.diff(hours)
    speed = np.divide(d, dt, out=np.zeros_like(d), where=dt > 0)
    props = dict(properties or {})
    props.update({"timed_by": "model", "speed_kn": ship.speed_kn, "speed_loss_model": ship.model, "floor_kn": ship.floor_kn,
                  "max_hs_m_along": round(float(hs_max), 4)})
    return Route(name, lat, lon, times, speed, properties=props)


def plan_ship(plan):
    """The :class:`routing.astar.ShipModel` a plan was searched with (from its routes' properties)."""
    return plan.ship


def _max_gap_deg(steps: np.ndarray, lat_deg: float, dlat: float, dlon: float) -> float:
    """Largest angle between consecutive stencil directions on the ground at a latitude. [deg]"""
    x = steps[:, 0] * dlon * math.cos(math.radians(lat_deg))
    y = steps[:, 1] * dlat
    ang = np.sort(np.degrees(np.arctan2(y, x)) % 360.0)
    return float(np.max(np.diff(np.append(ang, ang[0] + 360.0))))


def discretisation_tolerance_h(plan, time_h: float, dist_nmi: float) -> float:
    """How much slower than another route the time-optimal route may be on this mesh. [h]

    Two parts. (1) Directions: a mesh path follows stencil directions only; a straight leg
    between two directions is replaced by steps along the two neighbouring ones, at most
    ``1 / cos(gap / 2)`` times longer, ``gap`` the largest angle between consecutive stencil
    directions on the ground at the mesh's latitudes (14.0 deg on square cells with 48 edges,
    [1]; more where cells are not square) - a fraction of the route's time. (2) Ends: the search
    starts and ends at mesh nodes, up to half a cell diagonal from where another route starts and
    ends: one cell diagonal sailed at the route's mean speed.
    """
    mesh = plan.mesh
    g = mesh.grid
    gap = max(_max_gap_deg(mesh.steps, float(lat), g.dlat_deg, g.dlon_deg) for lat in (g.lat_deg[0], g.lat_deg[-1]))
    frac = 1.0 / math.cos(math.radians(gap / 2.0)) - 1.0
    coslat = math.cos(math.radians(max(abs(g.lat_deg[0]), abs(g.lat_deg[-1]))))
    diag_nmi = math.hypot(g.dlat_deg, g.dlon_deg * coslat) * EARTH_RADIUS_NMI * math.pi / 180.0
    speed = dist_nmi / time_h if time_h > 0 else plan_ship(plan).speed_kn
    return frac * time_h + diag_nmi / max(speed, 1e-3)


def optimality_gaps(routes: dict, plan, optimal: str = "optimal") -> list[dict]:
    """The like-for-like invariant: is the time-optimal route slower than another route?

    Returns one entry per other route: ``route``, ``gap_h`` (optimal minus that route's time,
    positive = the optimal route is slower), ``tolerance_h`` (:func:`discretisation_tolerance_h`),
    ``holds`` (gap within the tolerance, or the other route is not sailed by the model), and
    ``constraint`` for a route whose search had a safety constraint active (then the optimal
    route being faster is expected, and being slower is not a breach of this invariant either:
    the two searches differ only by the constraint).
    """
    opt = routes[optimal]
    tol = discretisation_tolerance_h(plan, opt.time_h, opt.dist_nmi)
    out = []
    for role, r in routes.items():
        if role == optimal:
            continue
        gap = opt.time_h - r.time_h
        modelled = r.properties.get("timed_by", "model") == "model"
        out.append({"route": role, "gap_h": round(gap, 4), "tolerance_h": round(tol, 4), "modelled": modelled,
                    "constraint": CONSTRAINED.get(role), "holds": (not modelled) or gap <= tol + 1e-9})
    return out


def plan_bbox(start, goal, lat_deg, lon_deg, weather=None, pad_deg: float = 0.25) -> tuple:
    """The A* plan's box: the great circle's default box (:func:`routing.planner.default_bbox`)
    widened to hold another route of the comparison (a lane, a track) with ``pad_deg`` to spare,
    so that route is re-timed in the plan's weather everywhere (outside the mesh the model would
    read the nearest edge's weather); clipped to the weather's grid."""
    from routing.planner import default_bbox

    b = default_bbox(start, goal)
    lat, lon = np.asarray(lat_deg, dtype=float), np.asarray(lon_deg, dtype=float)
    b = (min(b[0], lon.min() - pad_deg), min(b[1], lat.min() - pad_deg), max(b[2], lon.max() + pad_deg), max(b[3], lat.max() + pad_deg))
    if weather is not None:
        b = (max(b[0], weather.lon_deg[0]), max(b[1], weather.lat_deg[0]), min(b[2], weather.lon_deg[-1]), min(b[3], weather.lat_deg[-1]))
    return b


def sea_checks(lat_deg, lon_deg):
    """The land test and the land repair of a lane-like polyline, its ends as the berths:
    ``(leg_at_sea(lat1, lon1, lat2, lon2) -> bool, repair(lat, lon) -> RepairResult)``."""
    from routing import land
    from routing.seapath import repair_route

    ends = [(float(lat_deg[0]), float(lon_deg[0])), (float(lat_deg[-1]), float(lon_deg[-1]))]

    def leg_at_sea(lat1, lon1, lat2, lon2) -> bool:
        return land.leg_at_sea(lat1, lon1, lat2, lon2, berths=ends)

    def repair(lat, lon):
        return repair_route(lat, lon, berths=ends)

    return leg_at_sea, repair


def lane_departure(lat_deg, lon_deg, speed_kn, depart_utc, plan, *, weather_at, check, cells, properties=None,
                   lane_role: str = "lane", fixed=None) -> dict:
    """The lane as planned and its cargo-safe deviation for one departure, sailed like the A* routes.

    * ``lane``: the centroid path, legs over land replaced by the shortest sea path
      (:func:`routing.seapath.repair_route`), sailed by the plan's vessel model (the lane's
      intended calm-water speed minus the speed loss, same floor) from ``depart_utc``;
    * ``deviation``: Algorithm 1 (:func:`routing.deviate.deviate_lane`) walking the centroids at
      the speeds the model makes on the lane's legs, its land legs repaired, then sailed by the
      same model.

    ``fixed`` is the lane's own repair (:func:`routing.seapath.repair_route` of the centroids), the
    same for every departure: pass it to compute it once per lane.

    Returns ``{lane_role: Route, "deviation": Route}``; each says ``sea_only`` and what was repaired.
    """
    from routing.deviate import deviate_lane

    lat, lon = np.asarray(lat_deg, dtype=float), np.asarray(lon_deg, dtype=float)
    props = dict(properties or {})
    leg_at_sea, repair = sea_checks(lat, lon)
    fixed = repair(lat, lon) if fixed is None else fixed
    lane = retime(fixed.lat_deg, fixed.lon_deg, depart_utc, plan, name=lane_role,
                  properties={**props, "sea_only": fixed.sea_only, "land_repairs": fixed.repaired_legs,
                              "not_proposed": None if fixed.sea_only else f"not sea-only: {fixed.reason}"})
    walk = retime(lat, lon, depart_utc, plan, name="walk").leg_speed_kn  # the model's speed on each lane leg
    walk = np.where(walk > 0, walk, plan_ship(plan).floor_kn)
    dev = deviate_lane(lat, lon, np.r_[walk, walk[-1]], depart_utc, weather_at=weather_at, check=check, cells=cells,
                       leg_at_sea=leg_at_sea, repair=repair, properties=props)
    deviation = retime(dev.lat_deg, dev.lon_deg, depart_utc, plan, name="deviation",
                       properties={**dev.properties, "walk_speeds": "the vessel model's speeds on the lane's legs"})
    return {lane_role: lane, "deviation": deviation}
