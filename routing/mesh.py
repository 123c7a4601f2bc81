"""Regular lat/lon routing mesh, sea/land cells, edge stencils and port snapping.

Nodes sit on a regular grid ``lat0 + j*dlat``, ``lon0 + i*dlon`` (node id ``j*nx + i``); each
node is the centre of a cell of ``dlat x dlon``. A spacing given in nautical miles is converted
as SIMROUTE does, ``x/60`` degrees on both axes (cells are not square in nmi). A cell is sea
when the weather has data there and the real land mask (global-land-mask, 30 arc-second GLOBE
raster) has no land pixel overlapping it (``land_frac_max`` relaxes this).

Edges follow a stencil of primitive steps ``(di, dj)``: 8 (king moves), 16 (+ knight moves),
24 (+ (1, 3) moves) or 48 (every primitive step with max(|di|, |dj|) <= 4, angular resolution
3.2-14.0 deg, Grifoll et al. 2022 section 2.2). **An edge is allowed only if every cell its
segment touches is sea** (corner contacts included), where SIMROUTE tests only the end node,
and its great circle touches no land pixel: the one land check's pixel test
(:func:`routing._land.gc_leg_ocean`, also used by smoothing and by :mod:`routing.land` for every
other route), run for edges near land (cells with a land pixel within a margin that holds the arc).

References
----------
.. [1] M. Grifoll, C. Borén and M. Castells-Sanabra, Ocean Eng. 255, 111427, 2022,
       doi:10.1016/j.oceaneng.2022.111427, section 2.2 and Fig. 3.
.. [2] T. Karin, global-land-mask (GLOBE 30" land mask), https://github.com/toddkarin/global-land-mask
.. [3] J. Amanatides and A. Woo, "A fast voxel traversal algorithm for ray tracing," in
       Eurographics '87, pp. 3-10, 1987 (cells crossed by a segment; here the closed variant).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from routing import _kernels
from routing.errors import LandPointError, MeshSizeError, OutsideMeshError
from routing.land import PX_PER_DEG as _MASK_PX_PER_DEG
from routing.land import LandMask, land_window
from thresholds.geodesy import haversine_nmi, initial_bearing_deg
from thresholds.units import EARTH_RADIUS_NMI

#: Edge land tests: every touched cell (ours) or only the end node (SIMROUTE, for comparisons).
LAND_CHECKS = ("cells", "end_node")
#: Stencil sizes offered.
STENCIL_SIZES = (8, 16, 24, 48)
#: Largest mesh built (nodes); beyond it a MeshSizeError asks for a coarser spacing.
MAX_NODES = 30_000_000


def stencil(n_edges: int) -> np.ndarray:
    """Steps ``(di, dj)`` (lon index, lat index) of a stencil, sorted by angle from east.

    8: max(|di|,|dj|) = 1. 16: plus the primitive steps with max = 2. 24: plus (±1, ±3) and
    (±3, ±1). 48: every primitive step (gcd 1) with max(|di|, |dj|) <= 4.

    Examples
    --------
    >>> [len(stencil(k)) for k in (8, 16, 24, 48)]
    [8, 16, 24, 48]
    """
    if n_edges not in STENCIL_SIZES:
        raise ValueError(f"edges must be one of {STENCIL_SIZES}, got {n_edges}")
    reach = {8: 1, 16: 2, 24: 3, 48: 4}[n_edges]
    steps = []
    for dj in range(-reach, reach + 1):
        for di in range(-reach, reach + 1):
            if (di, dj) == (0, 0) or math.gcd(abs(di), abs(dj)) != 1:
                continue
            if n_edges == 24 and max(abs(di), abs(dj)) == 3 and min(abs(di), abs(dj)) != 1:
                continue
            steps.append((di, dj))
    steps.sort(key=lambda s: math.atan2(s[1], s[0]) % (2 * math.pi))
    return np.array(steps, dtype=np.int64)


def stencil_angular_gaps_deg(n_edges: int) -> np.ndarray:
    """Angles between consecutive stencil directions on square cells. [deg]"""
    angles = np.sort(np.degrees(np.arctan2(stencil(n_edges)[:, 1], stencil(n_edges)[:, 0])) % 360.0)
    return np.diff(np.append(angles, angles[0] + 360.0))


def _cells_touched(di: int, dj: int) -> np.ndarray:
    """Offsets of the cells the segment (0, 0) -> (di, dj) touches (closed squares), shape (m, 2)."""
    cells = []
    xmin, xmax = min(0, di), max(0, di)
    for c in range(math.ceil(xmin - 0.5 - 1e-9), math.floor(xmax + 0.5 + 1e-9) + 1):
        if di == 0:
            ya, yb = 0.0, float(dj)
        else:
            xa, xb = max(xmin, c - 0.5), min(xmax, c + 0.5)
            ya, yb = dj * xa / di, dj * xb / di
        lo, hi = min(ya, yb), max(ya, yb)
        for r in range(math.ceil(lo - 0.5 - 1e-9), math.floor(hi + 0.5 + 1e-9) + 1):
            cells.append((c, r))
    return np.array(sorted(set(cells)), dtype=np.int64)


@dataclass(frozen=True)
class MeshGrid:
    """Geometry of a regular mesh: node (j, i) at ``(lat0 + j*dlat, lon0 + i*dlon)``."""

    lat0_deg: float
    lon0_deg: float
    dlat_deg: float
    dlon_deg: float
    ny: int
    nx: int

    @classmethod
    def from_bbox(cls, bbox, spacing_deg: float, anchor=None, max_nodes: int = MAX_NODES) -> "MeshGrid":
        """Mesh over ``bbox = (lon_min, lat_min, lon_max, lat_max)`` with ``spacing_deg`` on both axes.

        ``anchor = (lat, lon)`` shifts the lattice so that this point is a node (the start),
        otherwise the south-west corner is node (0, 0).
        """
        lon_min, lat_min, lon_max, lat_max = (float(x) for x in bbox)
        d = float(spacing_deg)
        if not d > 0:
            raise MeshSizeError(f"mesh spacing must be positive, got {spacing_deg!r} deg")
        if not (lon_min < lon_max and lat_min < lat_max):
            raise MeshSizeError(f"empty bbox {bbox!r}: need lon_min < lon_max and lat_min < lat_max")
        if lat_min < -89.0 or lat_max > 89.0 or lon_min < -540.0 or lon_max > 540.0 or lon_max - lon_min > 360.0:
            raise MeshSizeError(f"bbox {bbox!r} must lie within lat -89..89 and span at most 360 deg of longitude "
                                "(a continuous frame: past 180 deg to cross the antimeridian, e.g. 170..200)")
        lat0, lon0 = lat_min, lon_min
        if anchor is not None:
            a_lat, a_lon = float(anchor[0]), float(anchor[1])
            if lat_min <= a_lat <= lat_max and lon_min <= a_lon <= lon_max:
                lat0 = a_lat - math.floor((a_lat - lat_min) / d + 1e-9) * d
                lon0 = a_lon - math.floor((a_lon - lon_min) / d + 1e-9) * d
        ny = int(math.floor((lat_max - lat0) / d + 1e-9)) + 1
        nx = int(math.floor((lon_max - lon0) / d + 1e-9)) + 1
        if ny < 2 or nx < 2:
            raise MeshSizeError(f"bbox {bbox!r} holds fewer than 2 x 2 nodes at {d:g} deg")
        if ny * nx > max_nodes:
            raise MeshSizeError(
                f"mesh of {ny} x {nx} = {ny * nx:,} nodes exceeds {max_nodes:,}; use a coarser spacing or a smaller bbox"
            )
        return cls(lat0, lon0, d, d, ny, nx)

    @property
    def n_nodes(self) -> int:
        return self.ny * self.nx

    @cached_property
    def lat_deg(self) -> np.ndarray:
        return self.lat0_deg + self.dlat_deg * np.arange(self.ny)

    @cached_property
    def lon_deg(self) -> np.ndarray:
        return self.lon0_deg + self.dlon_deg * np.arange(self.nx)

    @property
    def bbox(self) -> tuple:
        return (self.lon0_deg, self.lat0_deg, float(self.lon_deg[-1]), float(self.lat_deg[-1]))

    def node_latlon(self, node):
        node = np.asarray(node)
        return self.lat_deg[node // self.nx], self.lon_deg[node % self.nx]

    @property
    def lon_mid_deg(self) -> float:
        """Middle longitude of the mesh's continuous frame."""
        return self.lon0_deg + 0.5 * (self.nx - 1) * self.dlon_deg

    def to_frame(self, lon_deg):
        """Longitudes in the mesh's continuous frame (within 180 deg of its middle): a mesh across
        the antimeridian runs e.g. from 170 to 200 deg, and -175 deg is 185 there."""
        mid = self.lon_mid_deg
        return mid + np.mod(np.asarray(lon_deg, dtype=float) - mid + 180.0, 360.0) - 180.0

    def contains(self, lat: float, lon: float) -> bool:
        lon = float(self.to_frame(lon))
        tol = 1e-9
        return (
            self.lat0_deg - 0.5 * self.dlat_deg - tol <= lat <= self.lat_deg[-1] + 0.5 * self.dlat_deg + tol
            and self.lon0_deg - 0.5 * self.dlon_deg - tol <= lon <= self.lon_deg[-1] + 0.5 * self.dlon_deg + tol
        )


def global_land_mask_window(grid: "MeshGrid") -> LandMask:
    """The global-land-mask raster around a mesh (1.5 cells of margin), as a :class:`LandMask`.

    global-land-mask ships the GLOBE-derived 30" mask (~0.93 km) [2]; the window is read from
    the memory-mapped cache of :mod:`thresholds.land_raster` (only the box's rows and columns).
    """
    return land_window(
        grid.lat_deg[0] - 1.5 * grid.dlat_deg, grid.lat_deg[-1] + 1.5 * grid.dlat_deg,
        grid.lon_deg[0] - 1.5 * grid.dlon_deg, grid.lon_deg[-1] + 1.5 * grid.dlon_deg,
    )  # fmt: skip


_NO_PX = np.ones((1, 1), dtype=bool)


@dataclass(frozen=True)
class Mesh:
    """A routing mesh: geometry, sea nodes, passable cells and the allowed edges of every node.

    Attributes
    ----------
    grid : MeshGrid
    sea : ndarray of bool, shape (ny, nx)
        Sea nodes: weather data there and, with a land mask, an ocean pixel at the node.
    cell_ok : ndarray of bool, shape (ny, nx)
        Cells an edge may cross: the weather has data there (all True without weather).
    land : LandMask or None
        The 30" raster; an edge touching a cell that holds land pixels must not touch any
        land pixel (exact pixel traversal), edges in land-free cells skip that test.
    edges : int
        Stencil size.
    land_check : {"cells", "end_node"}
        ``"cells"`` (default): the rule above. ``"end_node"``: only the end node must be sea,
        as SIMROUTE does; for comparisons only, such edges can cross land.
    steps : ndarray, shape (K, 2)
        Stencil steps ``(di, dj)``.
    allowed : ndarray of uint64, shape (N,)
        Bit k set when edge k of the node is allowed.
    """

    grid: MeshGrid
    sea: np.ndarray
    cell_ok: np.ndarray
    land: LandMask | None = None
    edges: int = 48
    land_check: str = "cells"
    cell_clean: np.ndarray = field(default=None)
    steps: np.ndarray = field(default=None)
    allowed: np.ndarray = field(default=None)

    def __post_init__(self):
        shape = (self.grid.ny, self.grid.nx)
        sea = np.asarray(self.sea, dtype=bool)
        cell_ok = np.asarray(self.cell_ok, dtype=bool)
        if sea.shape != shape or cell_ok.shape != shape:
            raise ValueError(f"sea/cell masks {sea.shape}, {cell_ok.shape} do not match the grid {shape}")
        if self.land_check not in LAND_CHECKS:
            raise ValueError(f"land_check must be one of {LAND_CHECKS}, got {self.land_check!r}")
        steps = stencil(self.edges)
        clean = np.ones(shape, dtype=bool) if self.land is None else self.land.land_fraction(self.grid, self._clean_margin_px(steps)) <= 0.0
        object.__setattr__(self, "sea", sea)
        object.__setattr__(self, "cell_ok", cell_ok)
        object.__setattr__(self, "cell_clean", clean)
        object.__setattr__(self, "steps", steps)
        cells, counts = self.stencil_cells  # cached: the safe search reuses it
        px = self._px()
        allowed = _kernels.allowed_edges(
            sea, cell_ok, clean, cells, counts, steps[:, 0].copy(), steps[:, 1].copy(),
            self.grid.lat0_deg, self.grid.lon0_deg, self.grid.dlat_deg, self.grid.dlon_deg,
            px[0], px[1], px[2], px[3], px[4], self.land_check == "end_node",
        )  # fmt: skip
        object.__setattr__(self, "allowed", allowed)

    def _clean_margin_px(self, steps) -> int:
        """Pixels by which a cell is grown before it is called land-free (``cell_clean``).

        An edge is a great circle; the cells it touches are found from the straight segment
        between its end nodes in lat/lon, from which the arc strays by at most
        ``d^2 / (2 cos^3 phi_m)`` rad (:mod:`routing._land`, d its angular length, phi_m the
        largest |latitude|). Edges whose cells are land-free skip the pixel test, which is
        exact only if no land pixel lies within that distance of those cells: the margin.
        """
        g = self.grid
        d_rad = math.radians(max(g.dlat_deg, g.dlon_deg)) * float(np.max(np.hypot(steps[:, 0], steps[:, 1])))
        phi = min(math.radians(max(abs(float(g.lat_deg[0])), abs(float(g.lat_deg[-1])))) + d_rad, math.radians(89.99))
        pad_px = d_rad * d_rad / (2.0 * math.cos(phi) ** 3) * math.degrees(1.0) * _MASK_PX_PER_DEG
        return max(1, int(math.ceil(pad_px + 1e-6)))

    def _px(self):
        """(ocean, r0, c0, px_per_deg, has_px) for the compiled land tests."""
        if self.land is None:
            return _NO_PX, 0, 0, float(_MASK_PX_PER_DEG), False
        return self.land.ocean, int(self.land.r0), int(self.land.c0), float(self.land.px_per_deg), True

    @property
    def n_nodes(self) -> int:
        return self.grid.n_nodes

    @property
    def n_sea(self) -> int:
        return int(self.sea.sum())

    @cached_property
    def edge_geometry(self):
        """Per (row j, step k): great-circle length [nmi] and cos/sin of the initial course.

        On a regular lat/lon mesh these depend on the row only, not on the column.
        """
        g = self.grid
        K = self.steps.shape[0]
        lat1 = np.repeat(g.lat_deg[:, None], K, axis=1)
        lat2 = g.lat0_deg + g.dlat_deg * (np.arange(g.ny)[:, None] + self.steps[None, :, 1])
        dlon = g.dlon_deg * self.steps[None, :, 0] * np.ones((g.ny, 1))
        lat2c = np.clip(lat2, -90.0, 90.0)
        length = np.asarray(haversine_nmi(lat1, 0.0, lat2c, dlon))
        course = np.deg2rad(np.asarray(initial_bearing_deg(lat1, 0.0, lat2c, dlon)))
        length = np.where(np.abs(lat2) <= 90.0, length, np.nan)
        return np.ascontiguousarray(length), np.ascontiguousarray(np.cos(course)), np.ascontiguousarray(np.sin(course))

    @cached_property
    def stencil_cells(self) -> tuple[np.ndarray, np.ndarray]:
        """Cells each stencil edge touches (closed squares, both end nodes included), as offsets
        from the edge's start node: ``cells`` (K, m, 2) of ``(di, dj)`` and ``counts`` (K,)."""
        offsets = [_cells_touched(int(di), int(dj)) for di, dj in self.steps]
        m = max(len(o) for o in offsets)
        cells = np.zeros((len(offsets), m, 2), dtype=np.int64)
        counts = np.zeros(len(offsets), dtype=np.int64)
        for k, o in enumerate(offsets):
            cells[k, : len(o)] = o
            counts[k] = len(o)
        return cells, counts

    @property
    def max_edge_nmi(self) -> float:
        return float(np.nanmax(self.edge_geometry[0]))

    @property
    def min_cell_nmi(self) -> float:
        """Smallest cell side, for land checks along arbitrary legs. [nmi]"""
        g = self.grid
        coslat = np.cos(np.deg2rad(np.max(np.abs(g.lat_deg))))
        return float(min(g.dlat_deg, g.dlon_deg * coslat) * EARTH_RADIUS_NMI * math.pi / 180.0)

    def node_id(self, j: int, i: int) -> int:
        return int(j) * self.grid.nx + int(i)

    def leg_is_sea(self, lat1: float, lon1: float, lat2: float, lon2: float) -> bool:
        """True when the great-circle leg crosses only passable cells and no land pixel."""
        g = self.grid
        lon1, lon2 = float(g.to_frame(lon1)), float(g.to_frame(lon2))
        px = self._px()
        return bool(
            _kernels.gc_leg_is_sea(
                float(lat1), float(lon1), float(lat2), float(lon2), g.lat0_deg, g.lon0_deg, g.dlat_deg, g.dlon_deg,
                self.cell_ok, self.cell_clean, px[0], px[1], px[2], px[3], px[4], 0.5 * self.min_cell_nmi, EARTH_RADIUS_NMI,
            )  # fmt: skip
        )

    def nearest_node(self, lat: float, lon: float) -> int:
        g = self.grid
        lon = float(g.to_frame(lon))
        if not g.contains(lat, lon):
            raise OutsideMeshError(
                f"point ({lat:.4f}, {lon:.4f}) is outside the mesh bbox lon {g.bbox[0]:.4f}..{g.bbox[2]:.4f}, "
                f"lat {g.bbox[1]:.4f}..{g.bbox[3]:.4f}"
            )
        j = int(np.clip(round((lat - g.lat0_deg) / g.dlat_deg), 0, g.ny - 1))
        i = int(np.clip(round((lon - g.lon0_deg) / g.dlon_deg), 0, g.nx - 1))
        return self.node_id(j, i)

    def snap(self, lat: float, lon: float, limit_nmi: float, *, within=None, what: str = "point") -> tuple[int, float]:
        """Nearest sea node with at least one edge, within ``limit_nmi`` great-circle distance.

        ``within`` (bool per node) restricts the candidates (e.g. to the start's sea area).
        Returns ``(node, distance_nmi)``; raises :class:`LandPointError` when none qualifies.
        """
        node = self.nearest_node(lat, lon)
        g = self.grid
        usable = self.sea.ravel() & (self.allowed != 0)
        if within is not None:
            usable = usable & within
        if usable[node]:
            d = float(haversine_nmi(lat, lon, *g.node_latlon(node)))
            if d <= limit_nmi:
                return node, d
        nm_per_deg = EARTH_RADIUS_NMI * math.pi / 180.0
        wj = int(math.ceil(limit_nmi / (nm_per_deg * g.dlat_deg))) + 1
        coslat = max(math.cos(math.radians(min(abs(lat) + wj * g.dlat_deg, 89.0))), 1e-3)
        wi = int(math.ceil(limit_nmi / (nm_per_deg * coslat * g.dlon_deg))) + 1
        j0, i0 = divmod(node, g.nx)
        js = np.arange(max(j0 - wj, 0), min(j0 + wj, g.ny - 1) + 1)
        is_ = np.arange(max(i0 - wi, 0), min(i0 + wi, g.nx - 1) + 1)
        jj, ii = np.meshgrid(js, is_, indexing="ij")
        cand = (jj * g.nx + ii).ravel()
        cand = cand[usable[cand]]
        if cand.size:
            dist = np.asarray(haversine_nmi(lat, lon, g.lat_deg[cand // g.nx], g.lon_deg[cand % g.nx]))
            best = int(np.argmin(dist))
            if dist[best] <= limit_nmi:
                return int(cand[best]), float(dist[best])
        extra = " reachable from the start" if within is not None else ""
        raise LandPointError(
            f"{what} ({lat:.4f}, {lon:.4f}) is on land or in a closed basin at this mesh resolution "
            f"({g.dlat_deg * 60:.3g} nmi): no sea node{extra} within {limit_nmi:g} nmi", what, float(limit_nmi)
        )


def build_mesh(
    grid: MeshGrid,
    *,
    edges: int = 48,
    weather_sea: np.ndarray | None = None,
    land: LandMask | None = None,
    ignore_land: bool = False,
    land_check: str = "cells",
) -> Mesh:
    """Combine the sea layers into a :class:`Mesh`.

    Parameters
    ----------
    grid : MeshGrid
    edges : {8, 16, 24, 48}
    weather_sea : ndarray of bool (ny, nx), optional
        Nodes/cells where the weather has data (False = the weather's land NaN or outside its grid).
    land : LandMask, optional
        Real coastline (:func:`global_land_mask_window`); nodes on land pixels are land and no
        edge may touch a land pixel.
    ignore_land : bool
        An all-sea mesh (for accuracy tests on the sphere).
    land_check : {"cells", "end_node"}
        See :class:`Mesh`.
    """
    shape = (grid.ny, grid.nx)
    if ignore_land:
        ones = np.ones(shape, dtype=bool)
        return Mesh(grid, ones, ones, None, edges, land_check)
    cell_ok = np.ones(shape, dtype=bool) if weather_sea is None else np.asarray(weather_sea, dtype=bool)
    sea = cell_ok.copy()
    if land is not None:
        lat2d, lon2d = np.meshgrid(grid.lat_deg, grid.lon_deg, indexing="ij")
        sea &= land.is_ocean(lat2d, lon2d)
    return Mesh(grid, sea, cell_ok, land, edges, land_check)
