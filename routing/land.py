"""The land mask around a route: a window of the global 30" raster, and the one land check.

:class:`LandMask` is a window of the GLOBE-derived 30 arc-second land/ocean raster of
global-land-mask [1]_, read through :mod:`thresholds.land_raster` (a bit-packed cache file
memory-mapped row window by row window, so a route reads a few hundred kB instead of
inflating the 0.93 GB raster).

References
----------
.. [1] T. Karin, global-land-mask (GLOBE 30" land mask), https://github.com/toddkarin/global-land-mask
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from routing import _land
from thresholds import land_raster
from thresholds.geodesy import haversine_nmi, intermediate_point
from thresholds.units import EARTH_RADIUS_NMI

#: Mask pixels per degree of global-land-mask (30 arc-seconds).
PX_PER_DEG = land_raster.PX_PER_DEG
_N_COLS = land_raster.N_COLS


@dataclass(frozen=True)
class LandMask:
    """A window of the global 30 arc-second land/ocean raster (global-land-mask / GLOBE).

    Pixel (r, c) of the global raster covers lat (90 - (r+1)/120, 90 - r/120] and lon
    [-180 + c/120, -180 + (c+1)/120) (global-land-mask's own indexing); this window holds rows
    ``r0 ..`` and columns ``c0 ..`` of the raster continued periodically in longitude (``c0``
    may be negative or beyond 43 200 for a window in a longitude frame past ±180). Pixel
    coordinates of a point: ``y = (90 - lat)*120 - r0``, ``x = (lon + 180)*120 - c0`` taken
    modulo 43 200 (any longitude frame); pixel (r, c) is the square [c, c+1) x [r, r+1).
    """

    ocean: np.ndarray  # bool (rows, cols), True = ocean
    r0: int
    c0: int
    px_per_deg: int = PX_PER_DEG

    def pixel_xy(self, lat_deg, lon_deg):
        """Window pixel coordinates of points, x wrapped into [0, 43 200)."""
        x = (np.asarray(lon_deg, dtype=float) + 180.0) * self.px_per_deg - self.c0
        return np.mod(x, _N_COLS), (90.0 - np.asarray(lat_deg, dtype=float)) * self.px_per_deg - self.r0

    def is_ocean(self, lat_deg, lon_deg) -> np.ndarray:
        """Ocean at points (outside the window counts as land)."""
        x, y = self.pixel_xy(lat_deg, lon_deg)
        r = np.floor(y).astype(np.int64)
        c = np.floor(x).astype(np.int64)
        inside = (r >= 0) & (r < self.ocean.shape[0]) & (c >= 0) & (c < self.ocean.shape[1])
        out = np.zeros(np.shape(r), dtype=bool)
        out[inside] = self.ocean[r[inside], c[inside]]
        return out

    def land_fraction(self, grid, margin_px: int = 0) -> np.ndarray:
        """Fraction of land pixels overlapping each cell of a regular grid (border pixels count
        for both cells), the cell grown by ``margin_px`` pixels on every side. (ny, nx)

        ``grid`` has ``lat_deg``, ``lon_deg``, ``dlat_deg``, ``dlon_deg`` (a :class:`routing.mesh.MeshGrid`).
        """
        from routing import _kernels

        rows, cols = self.ocean.shape
        ppd = self.px_per_deg
        m = float(margin_px)
        lat = np.asarray(grid.lat_deg, dtype=float)
        lon = np.asarray(grid.lon_deg, dtype=float)
        y_top = (90.0 - (lat + 0.5 * grid.dlat_deg)) * ppd - self.r0 - m
        y_bot = (90.0 - (lat - 0.5 * grid.dlat_deg)) * ppd - self.r0 + m
        x_lo = (lon - 0.5 * grid.dlon_deg + 180.0) * ppd - self.c0 - m
        shift = _N_COLS * math.floor(x_lo[0] / _N_COLS + 1e-12)  # the grid in the window's frame
        x_lo = x_lo - shift
        x_hi = (lon + 0.5 * grid.dlon_deg + 180.0) * ppd - self.c0 + m - shift
        r0 = np.clip(np.floor(y_top + 1e-9).astype(np.int64), 0, rows - 1)
        r1 = np.clip(np.ceil(y_bot - 1e-9).astype(np.int64), 1, rows)
        c0 = np.clip(np.floor(x_lo + 1e-9).astype(np.int64), 0, cols - 1)
        c1 = np.clip(np.ceil(x_hi - 1e-9).astype(np.int64), 1, cols)
        r1 = np.maximum(r1, r0 + 1)
        c1 = np.maximum(c1, c0 + 1)
        sat = _kernels.land_summed_area(self.ocean)  # summed-area table of land pixels
        R0, C0 = np.meshgrid(r0, c0, indexing="ij")
        R1, C1 = np.meshgrid(r1, c1, indexing="ij")
        land = sat[R1, C1] - sat[R0, C1] - sat[R1, C0] + sat[R0, C0]
        return land / ((R1 - R0) * (C1 - C0))


def land_window(lat_min: float, lat_max: float, lon_min: float, lon_max: float) -> LandMask:
    """The raster pixels covering a lat/lon box (any longitude frame, ``lon_min <= lon_max``).

    Reads only the box's rows and columns from the memory-mapped cache
    (:func:`thresholds.land_raster.read_ocean`); latitudes are clipped to the raster.
    """
    ppd = PX_PER_DEG
    r0 = int(np.clip(math.floor((90.0 - float(lat_max)) * ppd), 0, land_raster.N_ROWS - 1))
    r1 = int(np.clip(math.ceil((90.0 - float(lat_min)) * ppd), r0 + 1, land_raster.N_ROWS))
    c0 = int(math.floor((float(lon_min) + 180.0) * ppd))
    c1 = max(int(math.ceil((float(lon_max) + 180.0) * ppd)), c0 + 1)
    c1 = min(c1, c0 + _N_COLS)
    return LandMask(land_raster.read_ocean(r0, r1, c0, c1), r0, c0, ppd)


# --------------------------------------------------------------------------------------------
# The one land check
# --------------------------------------------------------------------------------------------

#: Radius around a berth (a route's departure and arrival port) inside which a leg may touch
#: land pixels: port basins and quays read as land at 30" (~0.9 km), e.g. Barcelona's and
#: Palma's berths. Outside it, no leg touches a land pixel. [nmi]
BERTH_RADIUS_NMI = 1.5
_WINDOW_PAD_DEG = 0.25
_last_window: list = []


def _unwrapped(lon) -> np.ndarray:
    """Longitudes of a polyline made continuous (each within 180 deg of the one before)."""
    lon = np.asarray(lon, dtype=float)
    if lon.size < 2:
        return lon
    step = (np.diff(lon) + 180.0) % 360.0 - 180.0
    return np.concatenate([[lon[0]], lon[0] + np.cumsum(step)])


def window_for(lat, lon) -> LandMask:
    """A raster window holding every great-circle leg of a polyline (any longitude frame).

    Every point of a leg of angular length d lies within d / 2 of one of its ends, so within
    d / 2 of its latitude and asin(sin(d / 2) / cos(lat)) of its longitude: the window is the
    points' box widened by that for the longest leg, plus two pixels. The last window read is kept
    and reused while it covers the legs (a night checks thousands of legs in one region).
    """
    if len(lat) == 2:  # one leg (the deviation walk asks thousands): plain floats
        la1, la2 = float(lat[0]), float(lat[1])
        lo1 = float(lon[0])
        lo2 = lo1 + ((float(lon[1]) - lo1 + 180.0) % 360.0 - 180.0)
        s1, s2 = math.sin(math.radians(la2 - la1) / 2), math.sin(math.radians(lo2 - lo1) / 2)
        a = min(1.0, s1 * s1 + math.cos(math.radians(la1)) * math.cos(math.radians(la2)) * s2 * s2)
        half_deg = math.degrees(math.asin(math.sqrt(a)))  # half the leg's angular length
        lat_min, lat_max, lon_min, lon_max = min(la1, la2), max(la1, la2), min(lo1, lo2), max(lo1, lo2)
    else:
        lat = np.asarray(lat, dtype=float)
        lon = _unwrapped(lon)
        half_deg = 0.0
        if lat.size > 1:
            half_deg = 0.5 * float(np.max(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]))) / EARTH_RADIUS_NMI * 180.0 / math.pi
        lat_min, lat_max, lon_min, lon_max = float(lat.min()), float(lat.max()), float(lon.min()), float(lon.max())
    m = 2.0 / PX_PER_DEG + half_deg
    lat_lo, lat_hi = lat_min - m, lat_max + m
    cos_max = math.cos(math.radians(min(max(abs(lat_lo), abs(lat_hi)), 89.9)))
    m_lon = 2.0 / PX_PER_DEG + math.degrees(math.asin(min(1.0, math.sin(math.radians(half_deg)) / cos_max)))
    need = (lat_lo, lat_hi, lon_min - m_lon, lon_max + m_lon)
    if _last_window:
        w = _last_window[0]
        lat_top = 90.0 - w.r0 / w.px_per_deg
        lat_bot = 90.0 - (w.r0 + w.ocean.shape[0]) / w.px_per_deg
        west = w.c0 / w.px_per_deg - 180.0
        shift = 360.0 * math.floor((need[2] - west) / 360.0)  # the legs in the window's frame
        east = west + w.ocean.shape[1] / w.px_per_deg
        if lat_bot <= need[0] and need[1] <= lat_top and west <= need[2] - shift and need[3] - shift <= east:
            return w
    pad = _WINDOW_PAD_DEG
    w = land_window(max(need[0] - pad, -90.0), min(need[1] + pad, 90.0), need[2] - pad, need[3] + pad)
    _last_window[:] = [w]
    return w


def legs_at_sea(lat, lon, *, berths=None, berth_radius_nmi: float = BERTH_RADIUS_NMI, window: LandMask | None = None) -> np.ndarray:
    """The one land check: per leg of a polyline, True when its great circle touches no land pixel.

    Each leg (great circle between consecutive points, any longitude frame) is tested against
    every 30" pixel it touches (:func:`routing._land.gc_leg_ocean`: exact pixel traversal of
    chords that provably contain the arc, conservative by at most 0.02 pixel), except the parts
    of the leg within ``berth_radius_nmi`` of a berth.

    Parameters
    ----------
    lat, lon : array_like
        Waypoints. [deg]
    berths : sequence of (lat, lon), optional
        Where land is tolerated within the radius; default: the polyline's first and last points
        (a route's departure and arrival berths). ``()`` for none.
    berth_radius_nmi : float
    window : LandMask, optional
        The raster window to use (default: read around the legs; a window that does not hold a
        leg makes it fail, never pass).

    Returns
    -------
    ndarray of bool, shape (n - 1,)
    """
    lat = np.ascontiguousarray(lat, dtype=float)
    lon = np.ascontiguousarray(lon, dtype=float)
    if lat.size < 2:
        return np.ones(0, dtype=bool)
    if berths is None:
        berths = [(lat[0], lon[0]), (lat[-1], lon[-1])]
    b = np.asarray(list(berths), dtype=float).reshape(-1, 2)
    w = window_for(lat, lon) if window is None else window
    rho = float(berth_radius_nmi) / EARTH_RADIUS_NMI if b.shape[0] else 0.0
    return _land.legs_ocean(lat, lon, np.ascontiguousarray(b[:, 0]), np.ascontiguousarray(b[:, 1]), rho,
                            w.ocean, int(w.r0), int(w.c0), float(w.px_per_deg))  # fmt: skip


def leg_at_sea(lat1: float, lon1: float, lat2: float, lon2: float, *, berths=(), berth_radius_nmi: float = BERTH_RADIUS_NMI) -> bool:
    """:func:`legs_at_sea` of one leg (no berth unless given)."""
    return bool(legs_at_sea([lat1, lat2], [lon1, lon2], berths=berths, berth_radius_nmi=berth_radius_nmi)[0])


def land_nmi(lat, lon, *, berths=None, berth_radius_nmi: float = BERTH_RADIUS_NMI, step_nmi: float = 0.05) -> np.ndarray:
    """Length of each leg over land pixels outside the berth radius, sampled every ``step_nmi``
    along its great circle (for reports: how much of a leg lies on land). [nmi] (n - 1,)"""
    lat = np.asarray(lat, dtype=float)
    lon = np.asarray(lon, dtype=float)
    if berths is None:
        berths = [(lat[0], lon[0]), (lat[-1], lon[-1])] if lat.size else []
    b = np.asarray(list(berths), dtype=float).reshape(-1, 2)
    out = np.zeros(max(lat.size - 1, 0))
    for k in range(lat.size - 1):
        d = float(haversine_nmi(lat[k], lon[k], lat[k + 1], lon[k + 1]))
        n = max(1, int(math.ceil(d / step_nmi)))
        f = (np.arange(n) + 0.5) / n
        la, lo = intermediate_point(lat[k], lon[k], lat[k + 1], lon[k + 1], f)
        la, lo = np.atleast_1d(la), np.atleast_1d(lo)
        keep = np.ones(la.size, dtype=bool)
        for bl, bo in b:
            keep &= np.asarray(haversine_nmi(bl, bo, la, lo)) > berth_radius_nmi
        out[k] = float((~land_raster.is_ocean(la[keep], lo[keep])).sum()) * d / n
    return out
