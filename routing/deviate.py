"""Cargo-safe deviation of a traffic lane around adverse weather (R-tree nearest safe cell).

Implements Algorithm 1 of Spyrou-Sioula et al. [1]_ (§3.3): walk the lane's centroids from a
departure time, timing each next centroid from the typical speed of the current one and the
haversine distance; where the weather at (ETA, cell of the next centroid) breaks the vessel's
thresholds, move to the nearest weather-grid cell that passes them, found with an R-tree
(best-first nearest search, at most 10 candidates, within the distance sailable in 3 h at the
centroid's speed), and continue from there.

Improvements on the paper (each one is tested):

* **Legs stay at sea.** Every leg between consecutive proposed points is checked with a
  land-crossing test (``leg_at_sea``, e.g. :mod:`routing.mesh`'s "edge crosses land" check); a
  candidate cell whose leg from the current position crosses land is rejected and the next
  candidate is tried. A candidate is also refused when the leg from it to the *next* lane centroid
  would cross land, so a deviation never strands the ship behind an island: the lane centroid
  stays reachable at sea as the fall-back of the next step. The paper has no such check
  (``ANCHORS.md``).
* **ETAs are recomputed along the deviated path.** The time to a proposed point is the
  great-circle distance *from the previous proposed point* at the centroid's speed, so a detour
  arrives later and is judged in the weather of its own arrival time. The paper keeps the lane's
  centroid timing.
* **Candidates are judged at their own ETA and heading.** The R-tree indexes the cells that pass
  the heading-independent limits at the ETA's weather time step; each of the ≤ 10 nearest is then
  re-checked with the full threshold set (including beam seas, which depend on the leg's heading)
  in the weather at its own recomputed ETA.
* **Deviations make progress.** The ≤ 10 candidates are the nearest passing cells that lie
  further along the lane than the current position (projection on the lane's centroid
  polyline), and lane centroids the deviation has already passed are not sailed back to (listed
  in ``properties["skipped_centroids"]``): Algorithm 1 can send the ship back and forth between
  the same cells on consecutive adverse steps, or back to a centroid it overtook; this cannot.
* **Legs are looked at, not only points.** Algorithm 1 judges only the points; a leg between two
  passing points can cross a storm core. Among the passing candidates, the first whose leg is
  clear at every grid spacing (sampled at its own times) is preferred; if none is, the passing
  one whose leg breaks the fewest rules, then meets the lowest Hs, is taken (on the demo night's
  adverse lane-departures this lowered the deviations' hours over the limits by 2-4 % for each
  vessel class against taking the nearest) and the leg is flagged (``leg_rules_fired``). Every leg of the result
  carries that flag, so reports never present an adverse leg as safe.
* **Steps with no safe cell in reach are flagged, not silently kept.** The waypoint's status is
  ``"unresolved"`` with the rules that fired at the centroid, and the route's ``properties`` count
  them. The ship then heads for the least adverse reachable cell ahead (fewest rules fired, then
  lowest Hs) when one is clearly calmer than the centroid, else for the centroid itself.
  Departure and arrival points are never moved (the ship must leave and reach the port); if they
  break a limit they are flagged too.

The module is pure: weather, thresholds and the land check are passed in as callables
(``pipelines`` wires :mod:`routing.field`, :mod:`thresholds.operator` and :mod:`routing.mesh`).

References
----------
.. [1] K. Spyrou-Sioula, I. Kontopoulos, D. Kaklis, A. Makris, K. Tserpes, P. Eirinakis and
       F. Oikonomou, "AIS-enabled weather routing for cargo loss prevention," J. Mar. Sci. Eng.,
       vol. 10, no. 11, 1755, 2022, doi:10.3390/jmse10111755 (seed
       ``ais_weather_routing_cargo_loss``), §3.2-3.3 and Algorithm 1.
.. [2] A. Guttman, "R-trees: a dynamic index structure for spatial searching," Proc. ACM SIGMOD,
       pp. 47-57, 1984, doi:10.1145/602259.602266.
.. [3] G. R. Hjaltason and H. Samet, "Distance browsing in spatial databases," ACM Trans.
       Database Syst., vol. 24, no. 2, pp. 265-318, 1999, doi:10.1145/320248.320255 (best-first
       nearest-neighbour search).
"""

from __future__ import annotations

from typing import Callable, Mapping

import numpy as np
import pandas as pd

from routing.deviate_walk import DeviationStep, Judge, Walk  # noqa: F401  (DeviationStep: public type of the steps)
from routing.route import Route
from thresholds.geodesy import haversine_nmi

#: Search horizon of [1] §3.3: the distance sailable in 3 h at the centroid's speed. [h]
SEARCH_HORIZON_H = 3.0
#: At most this many nearest cells are examined per adverse step ([1] §3.3).
MAX_CANDIDATES = 10

#: ``weather_at(time_utc, lat_deg, lon_deg) -> {"hs_m": ndarray, ...}`` for 1-D arrays of points.
WeatherAt = Callable[[pd.DatetimeIndex, np.ndarray, np.ndarray], Mapping[str, np.ndarray]]
#: ``check(weather, heading_deg, speed_kn) -> {rule: broken (bool ndarray)}``; a point passes
#: when no rule is broken (NaN weather must not count as broken).
ThresholdCheck = Callable[[Mapping[str, np.ndarray], np.ndarray, np.ndarray], Mapping[str, np.ndarray]]
#: ``leg_at_sea(lat1, lon1, lat2, lon2) -> bool``: True when the great-circle leg stays at sea.
LegAtSea = Callable[[float, float, float, float], bool]


class SafeCellIndex:
    """R-trees over the weather-grid cells that pass the heading-independent limits, per time step.

    Cells are indexed as points ``(lon · cos φ0, lat)`` (a local equirectangular projection about
    the grid's mean latitude φ0), so the R-tree's best-first nearest search [2]_ [3]_ ranks them
    nearly by great-circle distance; the few candidates returned are re-ranked by the haversine
    distance. One tree per weather time step, built on first use (numpy bulk loading) and cached.

    Parameters
    ----------
    lat_deg, lon_deg : array_like, shape (ny,), (nx,)
        Cell-centre axes of the weather grid. [deg]
    time_utc : DatetimeIndex, shape (nt,)
        Weather time steps (tz-aware UTC).
    passing_mask : callable
        ``passing_mask(time_index) -> bool ndarray (ny, nx)``: sea cells passing the limits that do
        not depend on the heading at that time step (land must be False).
    """

    def __init__(self, lat_deg, lon_deg, time_utc, passing_mask: Callable[[int], np.ndarray]):
        self.lat_deg = np.asarray(lat_deg, dtype=float)
        self.lon_deg = np.asarray(lon_deg, dtype=float)
        times = pd.DatetimeIndex(time_utc)
        if times.tz is None:
            raise ValueError("SafeCellIndex.time_utc must be timezone-aware UTC")
        self.time_utc = times.tz_convert("UTC")
        self._t_ns = self.time_utc.asi8
        self._passing_mask = passing_mask
        self._cos0 = float(np.cos(np.deg2rad(np.mean(self.lat_deg))))
        self._trees: dict[int, tuple] = {}
        steps = [np.diff(a) for a in (self.lat_deg, self.lon_deg * self._cos0) if a.size > 1]
        #: Typical cell size, the sampling step along legs. [nmi]
        self.spacing_nmi = float(60.0 * min(np.median(np.abs(s)) for s in steps)) if steps else 0.0

    def time_index(self, time_utc: pd.Timestamp) -> int:
        """Index of the nearest weather time step ([1] §3.2: nearest available timestamp)."""
        t = pd.Timestamp(time_utc).value
        i = int(np.searchsorted(self._t_ns, t))
        if i <= 0:
            return 0
        if i >= self._t_ns.size:
            return self._t_ns.size - 1
        return i if (self._t_ns[i] - t) < (t - self._t_ns[i - 1]) else i - 1

    def _tree(self, k: int):
        if k not in self._trees:
            from rtree import index

            mask = np.asarray(self._passing_mask(k), dtype=bool)
            if mask.shape != (self.lat_deg.size, self.lon_deg.size):
                raise ValueError(f"passing_mask({k}) has shape {mask.shape}, expected {(self.lat_deg.size, self.lon_deg.size)}")
            iy, ix = np.nonzero(mask)
            if iy.size == 0:
                self._trees[k] = (None, iy, ix)
            else:
                x = self.lon_deg[ix] * self._cos0
                y = self.lat_deg[iy]
                pts = np.column_stack([x, y])
                prop = index.Property()
                prop.dimension = 2
                tree = index.Index((np.arange(iy.size, dtype=np.int64), pts, pts.copy()), properties=prop)
                self._trees[k] = (tree, iy, ix)
        return self._trees[k]

    def nearest(self, time_utc: pd.Timestamp, lat_deg: float, lon_deg: float, k: int = MAX_CANDIDATES, max_dist_nmi: float = np.inf):
        """The ≤ ``k`` passing cells nearest to a point, nearest first.

        Returns
        -------
        lat, lon, dist_nmi : ndarray
            Cell centres and their great-circle distance from the point, sorted ascending, only
            those within ``max_dist_nmi``.
        """
        tree, iy, ix = self._tree(self.time_index(time_utc))
        if tree is None:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        q = (lon_deg * self._cos0, lat_deg, lon_deg * self._cos0, lat_deg)
        ids = np.fromiter(tree.nearest(q, k), dtype=np.int64)[:k]
        lat = self.lat_deg[iy[ids]]
        lon = self.lon_deg[ix[ids]]
        dist = np.asarray(haversine_nmi(lat_deg, lon_deg, lat, lon), dtype=float).reshape(-1)
        order = np.argsort(dist, kind="stable")
        keep = order[dist[order] <= max_dist_nmi]
        return lat[keep], lon[keep], dist[keep]


def deviate_lane(
    lat_deg,
    lon_deg,
    speed_kn,
    depart_utc,
    *,
    weather_at: WeatherAt,
    check: ThresholdCheck,
    cells: SafeCellIndex,
    leg_at_sea: LegAtSea | None = None,
    repair: Callable | None = None,
    default_speed_kn: float | None = None,
    horizon_h: float = SEARCH_HORIZON_H,
    max_candidates: int = MAX_CANDIDATES,
    name: str = "deviation",
    properties: dict | None = None,
) -> Route:
    """Cargo-safe deviation of one lane for one departure (Algorithm 1 of [1]_, improved).

    Parameters
    ----------
    lat_deg, lon_deg : array_like, shape (n,)
        Lane centroids in sailing order (first = departure, last = arrival). [deg]
    speed_kn : array_like, shape (n,)
        Typical speed at each centroid; the leg from centroid i is sailed at ``speed_kn[i]``.
        Missing or non-positive speeds take ``default_speed_kn``. [kn]
    depart_utc : str or Timestamp
        Departure time (UTC).
    weather_at : callable
        ``weather_at(times, lat, lon) -> {var: values}`` (e.g. :mod:`routing.field` sampling).
    check : callable
        ``check(weather, heading_deg, speed_kn) -> {rule: broken}``, the vessel's thresholds.
    cells : SafeCellIndex
        R-tree index of the weather cells passing the heading-independent limits.
    leg_at_sea : callable, optional
        Land-crossing test of a leg; ``None`` disables it (only for open-sea tests).
    repair : callable, optional
        ``repair(lat, lon) -> routing.seapath.RepairResult``: after the walk, every leg that still
        crosses land (a lane leg over a cape, the leg into the arrival berth) is replaced by the
        shortest sea path (:func:`routing.seapath.repair_route`); when one cannot be repaired the
        route says so (``properties["sea_only"]`` False, ``"not_proposed"`` the reason) and must
        not be proposed. ``None`` keeps the walk's legs (open-sea tests).
    default_speed_kn : float, optional
        Speed used where a centroid has none.
    horizon_h : float, default 3
        Search radius in hours of sailing at the centroid's speed ([1] §3.3).
    max_candidates : int, default 10
        Nearest cells examined per adverse step ([1] §3.3).

    Returns
    -------
    Route
        ``name="deviation"``; waypoints with recomputed ETAs, leg speeds and the weather met at
        each waypoint; ``properties["steps"]`` lists each waypoint's status (``endpoint``,
        ``lane``, ``deviated``, ``unresolved``), the rules that fired at the lane centroid and how
        far the point moved; ``properties`` also counts ``n_deviated`` and ``n_unresolved``.

    Raises
    ------
    ValueError
        Fewer than two centroids, mismatched lengths, or a leg without a usable speed.
    """
    lat, lon, spd, t0 = _lane_inputs(lat_deg, lon_deg, speed_kn, depart_utc, default_speed_kn)
    walk = Walk(lat, lon, spd, t0, Judge(weather_at, check, cells.spacing_nmi), cells, leg_at_sea, horizon_h, max_candidates)
    walk.run()
    steps, weathers, skipped = walk.steps, walk.weathers, walk.skipped
    out_lat = np.array([s.lat_deg for s in steps])
    out_lon = np.array([s.lon_deg for s in steps])
    times = pd.DatetimeIndex([s.time_utc for s in steps])
    keys = sorted(set().union(*[w.keys() for w in weathers]))
    weather = {k: np.array([float(w[k][0]) if k in w else np.nan for w in weathers]) for k in keys}
    leg_speed = np.array([s.speed_kn for s in steps[1:]])
    step_rows = [_step_row(s) for s in steps]
    sea_props = {}
    if repair is not None:
        out_lat, out_lon, times, leg_speed, weather, sea_props = _repaired(repair(out_lat, out_lon), leg_speed, t0, weather, step_rows)
    props = dict(properties or {})
    props.update(
        {
            "algorithm": "cargo-safe deviation (Spyrou-Sioula et al. 2022, Alg. 1, with sea legs and recomputed ETAs)",
            "depart_utc": t0.isoformat(),
            "horizon_h": horizon_h,
            "max_candidates": max_candidates,
            "n_deviated": sum(s.status == "deviated" for s in steps),
            "n_unresolved": sum(s.status == "unresolved" for s in steps),
            "n_endpoint_adverse": sum(r["status"] == "endpoint" and bool(r["rules_fired"]) for r in step_rows),
            "n_legs_adverse": sum(bool(s.leg_rules_fired) for s in steps),
            "skipped_centroids": skipped,
            "steps": step_rows,
            **sea_props,
        }
    )
    return Route(name=name, lat_deg=out_lat, lon_deg=out_lon, time_utc=times, leg_speed_kn=leg_speed, weather=weather, properties=props)


def _step_row(s) -> dict:
    """One waypoint's line in ``properties["steps"]``: its status, the rules that fired and how far it moved."""
    return {
        "seq": s.seq,
        "status": s.status,
        "rules_fired": list(s.rules_fired),
        "moved_nmi": round(s.moved_nmi, 4),
        "candidates_tried": s.candidates_tried,
        "leg_rules_fired": list(s.leg_rules_fired),
        "centroid": [s.centroid_lat_deg, s.centroid_lon_deg],
    }


def _repaired(rr, leg_speed, t0, weather, step_rows):
    """The walk's polyline after the land repair: points, ETAs (each leg at its speed, from the
    departure), leg speeds, weather (points added by a repair have none yet: NaN) and the
    properties saying what was repaired or why the route is not sea-only."""
    src = np.asarray(rr.source_leg)
    orig = np.cumsum(src < 0) - 1  # index of the last original waypoint at or before each point
    speed = np.where(src[1:] >= 0, leg_speed[np.maximum(src[1:], 0)], leg_speed[np.maximum(orig[1:] - 1, 0)])
    d = np.asarray(haversine_nmi(rr.lat_deg[:-1], rr.lon_deg[:-1], rr.lat_deg[1:], rr.lon_deg[1:]), dtype=float).reshape(-1)
    hours = np.concatenate([[0.0], np.cumsum(d / speed)])
    times = pd.DatetimeIndex(t0 + pd.to_timedelta(hours, unit="h"))
    new = {k: np.where(src < 0, v[np.maximum(orig, 0)], np.nan) for k, v in weather.items()}
    for fix in rr.repaired_legs:  # the arrival's step: its leg in is repaired, not over land
        row = step_rows[fix["leg"] + 1]
        row["rules_fired"] = [r for r in row["rules_fired"] if r != "leg_crosses_land"]
        row["land_repair"] = {"added_nmi": fix["added_nmi"], "points": fix["points"]}
    props = {"sea_only": bool(rr.sea_only), "land_repairs": list(rr.repaired_legs),
             "not_proposed": None if rr.sea_only else f"not sea-only: {rr.reason}"}
    return rr.lat_deg, rr.lon_deg, times, speed, new, props


def threshold_inputs(sampler, vessel, limits=None):
    """The ``weather_at``, ``check`` and ``cells`` of :func:`deviate_lane` for a gridded field.

    Parameters
    ----------
    sampler : routing.sampling.PointSampler
        The weather (its grid is the candidate cells, as in [1] §3.2).
    vessel : thresholds.vessel.Vessel
    limits : OperatorProfile or OperatorLimits, optional
        Operator limits (with the profile's IMO settings); ``None`` = IMO rules only.

    Returns
    -------
    weather_at, check, cells
        ``check`` reports every rule of :func:`thresholds.safety.assess` (operator + IMO);
        ``cells`` indexes, per time step, the sea cells where no heading-free rule (Hs, wind,
        period, successive high waves) fires.
    """
    from routing.evaluate import assess_with, rule_check

    assess_fn = assess_with(vessel, limits)
    check = rule_check(assess_fn)

    def passing_mask(k: int) -> np.ndarray:
        from thresholds.safety import assess

        g = sampler.grid_slice(k)
        kwargs = {n: g[n] for n in ("hs_m", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms") if n in g}
        if "hs_m" not in kwargs:
            raise ValueError("the weather has no hs_m; deviations need significant wave height")
        return np.asarray(assess(vessel, limits, missing="skip", **kwargs).safe, dtype=bool)

    times = pd.DatetimeIndex(sampler.time_ns, tz="UTC")
    return sampler, check, SafeCellIndex(sampler.lat_deg, sampler.lon_deg, times, passing_mask)


def _lane_inputs(lat_deg, lon_deg, speed_kn, depart_utc, default_speed_kn):
    """Checked arrays of a lane (speeds filled with the default) and its UTC departure."""
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    spd = np.asarray(speed_kn, dtype=float)
    if lat.size < 2 or lon.size != lat.size or spd.size != lat.size:
        raise ValueError(f"a lane needs >= 2 centroids with lat, lon and speed of equal length (got {lat.size}, {lon.size}, {spd.size})")
    bad = ~np.isfinite(spd) | (spd <= 0.0)
    if bad[:-1].any():
        if default_speed_kn is None or not default_speed_kn > 0:
            raise ValueError(f"centroids {np.flatnonzero(bad[:-1]).tolist()} have no usable speed and no default_speed_kn was given")
        spd = np.where(bad, float(default_speed_kn), spd)
    t0 = pd.Timestamp(depart_utc)
    t0 = t0.tz_localize("UTC") if t0.tzinfo is None else t0.tz_convert("UTC")
    return lat, lon, spd, t0


def lane_route(lat_deg, lon_deg, speed_kn, depart_utc, *, default_speed_kn: float | None = None, name: str = "historical",
               properties: dict | None = None) -> Route:
    """A lane's centroid path as a :class:`Route`, timed like Algorithm 1 times it.

    The leg from centroid i takes ``haversine(c_i, c_i+1) / speed_kn[i]`` hours ([1] Alg. 1,
    line 4), starting at ``depart_utc``. This is the lane-departure the deviation is compared with.
    """
    lat, lon, spd, t0 = _lane_inputs(lat_deg, lon_deg, speed_kn, depart_utc, default_speed_kn)
    d = np.asarray(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]), dtype=float)
    hours = np.concatenate([[0.0], np.cumsum(d / spd[:-1])])
    times = pd.DatetimeIndex(t0 + pd.to_timedelta(hours, unit="h"))
    return Route(name, lat, lon, times, spd[:-1], properties=dict(properties or {}))
