"""Compiled cell and pixel traversals: which mesh cells (and land-mask pixels) a segment touches,
the per-node edge masks, and reachability over them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from routing._kernels.core import _haversine, _intermediate
from routing._land import box_ocean, gc_leg_ocean  # the one land check's pixel tests (routing/land.py)


@njit
def _segment_cells_sea(x0, y0, x1, y1, sea):
    """True when every mesh cell whose closed square the index-space segment touches is sea.

    Cell (r, c) is the square [c - 1/2, c + 1/2] x [r - 1/2, r + 1/2] around node (r, c);
    touching a corner counts (conservative). Cells outside the mesh count as land. The traversal
    is the land check's (``routing._land.box_ocean``, squares [c, c + 1]: shifted by half a cell).
    """
    return box_ocean(x0 + 0.5, y0 + 0.5, x1 + 0.5, y1 + 0.5, 1e-9, sea)


@njit
def _cells_ok(x0, y0, x1, y1, cell_ok, cell_clean):
    """(passable, clean): every touched mesh cell passable; and all of them free of land pixels."""
    ny, nx = cell_ok.shape
    xmin = min(x0, x1)
    xmax = max(x0, x1)
    eps = 1e-9
    clean = True
    c_lo = int(math.ceil(xmin - 0.5 - eps))
    c_hi = int(math.floor(xmax + 0.5 + eps))
    for c in range(c_lo, c_hi + 1):
        if c < 0 or c >= nx:
            return False, False
        if x1 == x0:
            ya, yb = y0, y1
        else:
            xa = max(xmin, c - 0.5)
            xb = min(xmax, c + 0.5)
            ya = y0 + (y1 - y0) * (xa - x0) / (x1 - x0)
            yb = y0 + (y1 - y0) * (xb - x0) / (x1 - x0)
        ylo = min(ya, yb)
        yhi = max(ya, yb)
        r_lo = int(math.ceil(ylo - 0.5 - eps))
        r_hi = int(math.floor(yhi + 0.5 + eps))
        for r in range(r_lo, r_hi + 1):
            if r < 0 or r >= ny:
                return False, False
            if not cell_ok[r, c]:
                return False, False
            if not cell_clean[r, c]:
                clean = False
    return True, clean


@njit
def _gc_leg_is_sea(lat1, lon1, lat2, lon2, lat0, lon0, dlat, dlon, cell_ok, cell_clean, ocean, px_r0, px_c0, ppd, has_px, step_nmi, radius):
    """True when the great-circle leg (deg) touches only passable cells and no land pixel.

    Cells are checked in great-circle pieces of at most ``step_nmi``; when any piece touches a
    cell holding land (within the clean-cell margin) the whole leg goes through the one land
    check's pixel test (``gc_leg_ocean``, as ``routing.land.legs_at_sea`` runs it), so smoothing
    and every later check of the same leg agree. Longitudes are taken in the mesh's continuous
    frame (within 180 deg of its middle), so a leg across the antimeridian stays on the mesh.
    """
    deg = math.pi / 180.0
    lon_mid = lon0 + 0.5 * (cell_ok.shape[1] - 1) * dlon
    lon1 = lon_mid + (lon1 - lon_mid + 180.0) % 360.0 - 180.0
    lon2 = lon_mid + (lon2 - lon_mid + 180.0) % 360.0 - 180.0
    la1 = lat1 * deg
    lo1 = lon1 * deg
    la2 = lat2 * deg
    lo2 = lon2 * deg
    L = _haversine(la1, lo1, la2, lo2, radius)
    n = int(math.ceil(L / step_nmi))
    if n < 1:
        n = 1
    alat, alon = lat1, lon1
    near_land = False
    for q in range(n):
        if q == n - 1:
            blat, blon = lat2, lon2
        else:
            pl, po = _intermediate(la1, lo1, la2, lo2, (q + 1.0) / n)
            blat, blon = pl / deg, lon_mid + (po / deg - lon_mid + 180.0) % 360.0 - 180.0
        ok, clean = _cells_ok(
            (alon - lon0) / dlon, (alat - lat0) / dlat, (blon - lon0) / dlon, (blat - lat0) / dlat, cell_ok, cell_clean
        )
        if not ok:
            return False
        near_land = near_land or not clean
        alat, alon = blat, blon
    if has_px and near_land:
        return gc_leg_ocean(lat1, lon1, lat2, lon2, ocean, px_r0, px_c0, ppd)
    return True


@njit(cache=True)
def allowed_edges(sea, cell_ok, cell_clean, cells, counts, di, dj, lat0, lon0, dlat, dlon, ocean, px_r0, px_c0, ppd, has_px, end_node_only):
    """uint64 edge mask per node (see :class:`routing.mesh.Mesh`)."""
    ny, nx = sea.shape
    K = di.size
    out = np.zeros(ny * nx, dtype=np.uint64)
    for j in range(ny):
        for i in range(nx):
            if not sea[j, i]:
                continue
            bits = np.uint64(0)
            for k in range(K):
                j2 = j + dj[k]
                i2 = i + di[k]
                if j2 < 0 or j2 >= ny or i2 < 0 or i2 >= nx or not sea[j2, i2]:
                    continue
                if not end_node_only:
                    ok = True
                    clean = True
                    for q in range(counts[k]):
                        c = i + cells[k, q, 0]
                        r = j + cells[k, q, 1]
                        if r < 0 or r >= ny or c < 0 or c >= nx or not cell_ok[r, c]:
                            ok = False
                            break
                        if not cell_clean[r, c]:
                            clean = False
                    if not ok:
                        continue
                    if has_px and not clean:
                        if not gc_leg_ocean(
                            lat0 + j * dlat, lon0 + i * dlon, lat0 + j2 * dlat, lon0 + i2 * dlon, ocean, px_r0, px_c0, ppd
                        ):
                            continue
                bits |= np.uint64(1) << np.uint64(k)
            out[j * nx + i] = bits
    return out


@njit(cache=True)
def component_from(start, allowed, di, dj, nx):
    """Nodes reachable from ``start`` over allowed edges (breadth-first). bool (N,)"""
    n = allowed.size
    seen = np.zeros(n, dtype=np.bool_)
    queue = np.empty(n, dtype=np.int64)
    head = 0
    tail = 0
    seen[start] = True
    queue[tail] = start
    tail += 1
    K = di.size
    while head < tail:
        u = queue[head]
        head += 1
        mask = allowed[u]
        for k in range(K):
            if (mask >> np.uint64(k)) & np.uint64(1) == 0:
                continue
            v = u + dj[k] * nx + di[k]
            if not seen[v]:
                seen[v] = True
                queue[tail] = v
                tail += 1
    return seen


@njit(cache=True)
def land_summed_area(ocean):
    """Summed-area table of land pixels: sat[r, c] = land pixels in rows < r, columns < c."""
    rows, cols = ocean.shape
    sat = np.zeros((rows + 1, cols + 1), dtype=np.int32)
    for r in range(rows):
        run = 0
        for c in range(cols):
            if not ocean[r, c]:
                run += 1
            sat[r + 1, c + 1] = sat[r, c + 1] + run
    return sat


@njit(cache=True)
def segment_cells_sea(x0, y0, x1, y1, sea):
    """Compiled entry point of :func:`_segment_cells_sea`."""
    return _segment_cells_sea(x0, y0, x1, y1, sea)


@njit(cache=True)
def gc_leg_is_sea(lat1, lon1, lat2, lon2, lat0, lon0, dlat, dlon, cell_ok, cell_clean, ocean, px_r0, px_c0, ppd, has_px, step_nmi, radius):
    """Compiled entry point of :func:`_gc_leg_is_sea`."""
    return _gc_leg_is_sea(
        lat1, lon1, lat2, lon2, lat0, lon0, dlat, dlon, cell_ok, cell_clean, ocean, px_r0, px_c0, ppd, has_px, step_nmi, radius
    )
