"""Pieces of the route planner: the default mesh box and spacing, the weather along a route, and
Route objects from polylines (:mod:`routing.planner`).

Longitudes: the mesh lives in one continuous frame (past 180 deg when a route crosses the
antimeridian, e.g. 130..250 for Japan -> Canada); routes leave the planner with longitudes
wrapped to [-180, 180) (DESIGN.md), and every function here accepts either.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from routing.field import NS_PER_HOUR, MeshWeather
from routing.mesh import Mesh
from routing.route import Route
from thresholds.geodesy import haversine_nmi, intermediate_point
from thresholds.units import wrap_deg

#: Default mesh spacing without weather (SIMROUTE R6's 1.5 nmi), and the node budget that
#: coarsens it for long routes. [deg]
DEFAULT_SPACING_DEG = 1.5 / 60.0
DEFAULT_MAX_AUTO_NODES = 2_000_000


def great_circle_frame(start, goal, n: int = 257) -> tuple[np.ndarray, np.ndarray]:
    """Points of the great circle start -> goal, longitudes unwrapped into one continuous frame
    starting at the start's longitude (past 180 deg where the circle crosses the antimeridian). [deg]"""
    f = np.linspace(0.0, 1.0, n)
    lat, lon = intermediate_point(start[0], start[1], goal[0], goal[1], f)
    lon = np.degrees(np.unwrap(np.radians(np.asarray(lon, dtype=float))))
    lon = lon + (float(start[1]) - lon[0])
    return np.asarray(lat, dtype=float), lon


def default_bbox(start, goal, margin_deg: float | None = None, margin_scale: float = 1.0) -> tuple:
    """Box around the great circle start -> goal plus a margin (max(1 deg, 15 % of its span),
    times ``margin_scale``: a widened box, :func:`routing.planner.mesh_and_ends`), in the
    continuous longitude frame of :func:`great_circle_frame` (e.g. 130..250 for Japan -> Canada
    across the antimeridian)."""
    lat, lon = great_circle_frame(start, goal)
    span = max(lat.max() - lat.min(), lon.max() - lon.min())
    m = (max(1.0, 0.15 * span) if margin_deg is None else margin_deg) * margin_scale
    lo, hi = lon.min() - m, lon.max() + m
    if hi - lo >= 359.0:  # a circle round the world: the whole band
        lo, hi = float(lon[0]) - 179.5, float(lon[0]) + 179.5
    return (lo, max(lat.min() - m, -85.0), hi, min(lat.max() + m, 85.0))


def auto_spacing(bbox, base_deg: float) -> float:
    """The base spacing, coarsened to keep the mesh under :data:`DEFAULT_MAX_AUTO_NODES` nodes. [deg]"""
    area_nodes = (bbox[2] - bbox[0]) * (bbox[3] - bbox[1]) / (base_deg * base_deg)
    if area_nodes <= DEFAULT_MAX_AUTO_NODES:
        return base_deg
    return base_deg * math.sqrt(area_nodes / DEFAULT_MAX_AUTO_NODES)


def mesh_weather_at(mesh: Mesh, mw: MeshWeather | None, wx):
    """``weather_at(times, lat, lon)`` (as :func:`routing.safety.limits_exposure` reads weather): the
    plan's weather on the mesh (:func:`sample_weather`) at UTC times; ``wx`` gives the weather's slice 0."""

    def weather_at(times, lat, lon):
        t_h = (pd.DatetimeIndex(times).asi8 - (wx.time0_ns or 0)) / NS_PER_HOUR
        return sample_weather(mesh, mw, lat, lon, t_h)

    return weather_at


def sample_weather(mesh: Mesh, mw: MeshWeather | None, lat_deg, lon_deg, t_h) -> dict:
    """Weather at points and times (hours after the weather's slice 0), bilinear over sea nodes.

    Returns ``hs_m``, ``wave_from_deg`` (from the interpolated components), ``tp_s``,
    ``current_u_ms``/``current_v_ms`` and ``wind_u_ms``/``wind_v_ms`` as available.
    """
    lat = np.asarray(lat_deg, dtype=float)
    if mw is None:
        return {"hs_m": np.zeros(lat.size)}
    g = mesh.grid
    lon = g.to_frame(lon_deg)  # any longitude frame
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


def make_route(name, mesh, mw, lat, lon, times_h, depart_utc, props) -> Route:
    """A :class:`routing.route.Route` from a polyline in the mesh's frame and its times [h after
    the weather's slice 0]: longitudes wrapped to [-180, 180), leg speeds, the weather sampled
    at the waypoints."""
    times_h = np.asarray(times_h, dtype=float)
    rel = times_h - times_h[0]
    eta = depart_utc + pd.to_timedelta(np.round(rel * NS_PER_HOUR).astype(np.int64), unit="ns")
    legs = np.asarray(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:])) if lat.size > 1 else np.zeros(0)
    dt = np.diff(rel)
    speed = np.divide(legs, dt, out=np.zeros_like(legs), where=dt > 0)
    weather = sample_weather(mesh, mw, lat, lon, times_h)
    lon = np.asarray(lon, dtype=float)
    off = (lon < -180.0) | (lon >= 180.0)
    lon = np.where(off, np.mod(lon + 180.0, 360.0) - 180.0, lon)  # DESIGN: positions in [-180, 180); others untouched
    return Route(name, lat, lon, pd.DatetimeIndex(eta), speed, weather=weather, properties=props)
