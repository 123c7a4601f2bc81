"""Repairing legs that cross land: the shortest sea path on a routing mesh, and sea-only routes.

A route made of points chosen one at a time (a lane's centroids, a cargo-safe deviation's safe
cells, a thinned AIS track) can have a great-circle leg that cuts across a cape or an island.
:func:`sea_path` replaces such a leg by the shortest path over sea on a routing mesh built from
the land mask alone around the leg (48-edge stencil, :mod:`routing.mesh`; the edges and the
smoothed legs pass the one land check, :mod:`routing.land`), made any-angle by greedy smoothing
(:func:`routing.astar.smooth` in calm water: a direct great-circle leg replaces grid steps when
it stays at sea and is no longer). :func:`repair_route` does that for every land leg of a
polyline and says what it did; when a leg cannot be repaired (no sea connection within the
mesh) the result says why, and the route must not be proposed.

References
----------
.. [1] M. Grifoll, C. Borén and M. Castells-Sanabra, "A comprehensive ship weather routing system
       using CMEMS products and A* algorithm," Ocean Eng. 255, 111427, 2022,
       doi:10.1016/j.oceaneng.2022.111427 (A* on a 48-edge lat/lon mesh, section 2.2-2.3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from routing import land
from thresholds.geodesy import haversine_nmi

#: Spacing of the repair mesh: 0.5 arc-minute of latitude (~0.5 nmi, 3 land pixels), fine enough
#: to thread the channels of the Mediterranean ports and straits. [deg]
REPAIR_SPACING_DEG = 0.5 / 60.0
#: The repair mesh spans the leg's box widened by this fraction of the leg's length (at least
#: ``REPAIR_MIN_PAD_DEG``): room to go round an island as long as the leg. [-]
REPAIR_PAD_FRAC = 0.6
#: When that box holds no sea connection (the way round runs outside it: a leg from Palma bay to
#: Mallorca's north-west coast must round the island's west end, beyond 0.6 leg lengths), the search is
#: repeated once in a box widened by this fraction. [-]
REPAIR_WIDE_PAD_FRAC = 2.5
REPAIR_MIN_PAD_DEG = 0.1
#: Nearest sea nodes tried for each end of the leg (the first whose leg to the end is at sea). [-]
SNAP_TRIES = 40
#: Largest repair mesh built. [nodes]
REPAIR_MAX_NODES = 1_500_000


@dataclass
class RepairResult:
    """A polyline after :func:`repair_route`."""

    lat_deg: np.ndarray
    lon_deg: np.ndarray
    sea_only: bool
    #: Index of each output point's source leg in the input, or -1 for an input point.
    source_leg: np.ndarray
    repaired_legs: list = field(default_factory=list)  # [{"leg", "added_nmi", "points"}]
    failed_legs: list = field(default_factory=list)  # [{"leg", "reason"}]

    @property
    def reason(self) -> str | None:
        """Why the polyline is not sea-only (None when it is)."""
        if not self.failed_legs:
            return None
        return "; ".join(f"leg {f['leg']}: {f['reason']}" for f in self.failed_legs)


def _repair_mesh(lat1, lon1, lat2, lon2, spacing_deg, pad_frac: float = REPAIR_PAD_FRAC):
    from routing.mesh import MeshGrid, build_mesh, global_land_mask_window

    d_deg = float(haversine_nmi(lat1, lon1, lat2, lon2)) / 60.0
    pad = max(REPAIR_MIN_PAD_DEG, pad_frac * d_deg)
    lon2u = lon1 + ((lon2 - lon1 + 180.0) % 360.0 - 180.0)  # the leg in one longitude frame
    coslat = max(math.cos(math.radians(max(abs(lat1), abs(lat2)))), 0.05)
    bbox = (min(lon1, lon2u) - pad / coslat, max(min(lat1, lat2) - pad, -89.0), max(lon1, lon2u) + pad / coslat,
            min(max(lat1, lat2) + pad, 89.0))  # fmt: skip
    area = (bbox[2] - bbox[0]) * (bbox[3] - bbox[1])
    spacing_deg = max(spacing_deg, math.sqrt(area / REPAIR_MAX_NODES) * 1.01)  # long legs: a coarser mesh
    grid = MeshGrid.from_bbox(bbox, spacing_deg, max_nodes=REPAIR_MAX_NODES)
    return build_mesh(grid, land=global_land_mask_window(grid)), lon2u


def _snap(mesh, lat, lon, berths, within=None):
    """Nearest usable sea node whose leg to (lat, lon) passes the land check, or None."""
    g = mesh.grid
    usable = mesh.sea.ravel() & (mesh.allowed != 0)
    if within is not None:
        usable &= within
    j0 = int(round((lat - g.lat0_deg) / g.dlat_deg))
    i0 = int(round((lon - g.lon0_deg) / g.dlon_deg))
    for r in (4, 12, 40):
        js = np.arange(max(j0 - r, 0), min(j0 + r, g.ny - 1) + 1)
        is_ = np.arange(max(i0 - r, 0), min(i0 + r, g.nx - 1) + 1)
        jj, ii = np.meshgrid(js, is_, indexing="ij")
        cand = (jj * g.nx + ii).ravel()
        cand = cand[usable[cand]]
        if cand.size == 0:
            continue
        dist = np.asarray(haversine_nmi(lat, lon, g.lat_deg[cand // g.nx], g.lon_deg[cand % g.nx]), dtype=float).reshape(-1)
        for q in np.argsort(dist, kind="stable")[:SNAP_TRIES]:
            n = int(cand[q])
            la, lo = float(g.lat_deg[n // g.nx]), float(g.lon_deg[n % g.nx])
            if dist[q] < 1e-9 or land.legs_at_sea([lat, la], [lon, lo], berths=berths)[0]:
                return n
    return None


def sea_path(lat1: float, lon1: float, lat2: float, lon2: float, *, berths=(), spacing_deg: float = REPAIR_SPACING_DEG):
    """The shortest sea path between two points as a polyline of great-circle legs, or None.

    Parameters
    ----------
    lat1, lon1, lat2, lon2 : float
        The leg's ends. [deg]
    berths : sequence of (lat, lon)
        Points inside whose berth radius land is tolerated (:data:`routing.land.BERTH_RADIUS_NMI`).
    spacing_deg : float
        Mesh spacing. [deg]

    Returns
    -------
    (lat, lon) : tuple of ndarray, or None
        From point 1 to point 2 (longitudes in point 1's frame); every leg passes
        :func:`routing.land.legs_at_sea` with the berths. None when the mesh holds no sea
        connection between the two ends.
    """
    for pad_frac in (REPAIR_PAD_FRAC, REPAIR_WIDE_PAD_FRAC):
        path = _sea_path_in_box(lat1, lon1, lat2, lon2, berths, spacing_deg, pad_frac)
        if path is not None:
            return path
    return None


def _sea_path_in_box(lat1, lon1, lat2, lon2, berths, spacing_deg, pad_frac):
    """:func:`sea_path` on the repair mesh of the leg's box widened by ``pad_frac`` leg lengths."""
    from routing.astar import ShipModel, WeatherArrays, evaluate_path, reachable, search, smooth
    from routing.errors import NoRouteError

    mesh, lon2u = _repair_mesh(lat1, lon1, lat2, lon2, spacing_deg, pad_frac)
    a = _snap(mesh, lat1, lon1, berths)
    if a is None:
        return None
    area = reachable(mesh, a)
    b = _snap(mesh, lat2, lon2u, berths, within=area)
    if b is None:
        return None
    wx = WeatherArrays.build(mesh, None)
    ship = ShipModel(10.0, "none")
    try:
        res = search(mesh, wx, ship, a, b, cost="distance")
    except NoRouteError:
        return None
    g = mesh.grid
    la, lo = (np.asarray(x, dtype=float) for x in g.node_latlon(res.nodes))
    la, lo = np.r_[lat1, la, lat2], np.r_[lon1, lo, lon2u]
    keep_ends = np.r_[True, np.abs(np.diff(la)) + np.abs(np.diff(lo)) > 1e-12]  # a snapped node on an end point
    la, lo = la[keep_ends], lo[keep_ends]
    times, _ = evaluate_path(mesh, wx, ship, la, lo)
    keep = smooth(mesh, wx, ship, la, lo, times)
    la, lo = la[keep], lo[keep]
    ok = land.legs_at_sea(la, lo, berths=berths)
    if not ok.all():  # the end legs outside the mesh's cells: checked by the land test itself
        return None
    return la, lo


def repair_route(lat_deg, lon_deg, *, berths=None, spacing_deg: float = REPAIR_SPACING_DEG) -> RepairResult:
    """Replace every leg of a polyline that fails the land check by the shortest sea path.

    ``berths`` default to the polyline's first and last points (:func:`routing.land.legs_at_sea`).
    """
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    if berths is None:
        berths = [(lat[0], lon[0]), (lat[-1], lon[-1])] if lat.size else []
    ok = land.legs_at_sea(lat, lon, berths=berths) if lat.size >= 2 else np.ones(0, dtype=bool)
    if ok.all():
        return RepairResult(lat, lon, True, np.full(lat.size, -1))
    out_lat, out_lon, src = [lat[:1]], [lon[:1]], [np.array([-1])]
    repaired, failed = [], []
    for k in range(lat.size - 1):
        if ok[k]:
            out_lat.append(lat[k + 1 : k + 2])
            out_lon.append(lon[k + 1 : k + 2])
            src.append(np.array([-1]))
            continue
        path = sea_path(lat[k], lon[k], lat[k + 1], lon[k + 1], berths=berths, spacing_deg=spacing_deg)
        if path is None:
            failed.append({"leg": k, "reason": _no_path_reason(lat[k], lon[k], lat[k + 1], lon[k + 1], berths, spacing_deg)})
            out_lat.append(lat[k + 1 : k + 2])
            out_lon.append(lon[k + 1 : k + 2])
            src.append(np.array([-1]))
            continue
        pla, plo = path
        plo = plo.copy()
        plo[-1] = lon[k + 1]  # the end in its own longitude frame (the path is in point k's)
        added = float(np.sum(haversine_nmi(pla[:-1], plo[:-1], pla[1:], plo[1:])) - haversine_nmi(lat[k], lon[k], lat[k + 1], lon[k + 1]))
        repaired.append({"leg": k, "added_nmi": round(added, 4), "points": int(pla.size - 2)})
        out_lat.append(pla[1:])
        out_lon.append(plo[1:])
        src.append(np.r_[np.full(pla.size - 2, k), -1])
    return RepairResult(np.concatenate(out_lat), np.concatenate(out_lon), not failed, np.concatenate(src), repaired, failed)


def _no_path_reason(lat1, lon1, lat2, lon2, berths, spacing_deg) -> str:
    """Why :func:`sea_path` found nothing: an end that is not at sea by the one land check (its
    pixel is land, or it lies within the check's 0.02-pixel margin of one: no leg can leave it),
    else no connection within the mesh."""
    off = [f"({la:.5f}, {lo:.5f})" for la, lo in ((lat1, lon1), (lat2, lon2))
           if not land.legs_at_sea([la, la], [lo, lo], berths=berths)[0]]
    if off:
        return (f"no sea path: {' and '.join(off)} not at sea by the land check (on a land pixel of the 30\" "
                f"mask, or within 0.02 pixel, about 18 m, of one: no leg can leave it)")
    return (f"no sea path from ({lat1:.4f}, {lon1:.4f}) to ({lat2:.4f}, {lon2:.4f}) on a {spacing_deg * 60:.2g}-nmi "
            f"mesh around the leg")
