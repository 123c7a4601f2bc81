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

from thresholds import land_raster

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
