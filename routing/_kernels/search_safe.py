"""Compiled time-dependent A* under the vessel's limits (hard or penalised unsafe edges)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from routing._kernels.core import (
    P_DWT,
    P_FLOOR,
    P_LPP,
    P_MIN_SOG,
    P_MODEL,
    P_PRINTED,
    P_TIME_STEP,
    P_V0,
    _heap_pop,
    _heap_push,
    _node_weather,
    _pace,
    _time_slot,
)
from routing._kernels.flags import _slice_range, _stencil_cells_unsafe


@njit(cache=True)
def astar_safe(
    nx,
    allowed,
    di,
    dj,
    elen,
    ecos,
    esin,
    ebit,
    cells,
    counts,
    lat_rad,
    lon_rad,
    sea_index,
    wave,
    cur,
    has_cur,
    dt_h,
    n_times,
    p,
    start,
    goal,
    t_start_h,
    heuristic_speed,
    radius,
    unsafe,
    hard,
    penalty,
):
    """Time-dependent A* that respects the vessel's limits; returns
    ``(g, t, exposure, parent, expanded, scanned, reached, horizon_hit)``.

    Edge time as in :func:`astar`. An edge is *unsafe* when a cell it touches (``cells[k]``,
    ``counts[k]``: the stencil's closed-square cells, both end nodes included; the start and goal
    nodes are exempt, the ship must leave and reach them) is flagged in ``unsafe`` for the edge's
    heading sector (``ebit[row, k]``) in a weather slice bracketing the edge's time interval.
    ``hard``: unsafe edges are not taken. Otherwise (soft) an unsafe edge costs its time times
    ``1 + penalty``. The label of a node is its cost ``g`` (hours plus penalties); the weather is
    read at the node's arrival time ``t``, kept apart. Penalties only add cost, so the heuristic
    (great-circle distance / highest speed) stays admissible and consistent; with ``penalty`` 0
    the search is exactly :func:`astar`. ``horizon_hit``: an edge needed a slice beyond
    ``unsafe.shape[0]`` (the caller extends the flags and searches again).
    """
    model = int(p[P_MODEL])
    v0 = p[P_V0]
    floor = p[P_FLOOR]
    lpp = p[P_LPP]
    dwt = p[P_DWT]
    printed = p[P_PRINTED] > 0.5
    min_sog = p[P_MIN_SOG]
    step = p[P_TIME_STEP] > 0.5
    n = allowed.size
    K = di.size
    ny = n // nx
    n_safe = unsafe.shape[0]
    g = np.full(n, np.inf)
    tarr = np.full(n, np.inf)
    expo = np.zeros(n)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    hcache = np.full(n, -1.0)
    keys = np.empty(1024, dtype=np.float64)
    vals = np.empty(1024, dtype=np.int64)
    size = 0
    glat = lat_rad[goal // nx]
    glon = lon_rad[goal % nx]
    use_h = heuristic_speed > 0.0
    srow = np.empty(ny)
    crow = np.empty(ny)
    for j in range(ny):
        srow[j] = math.sin(0.5 * (lat_rad[j] - glat)) ** 2
        crow[j] = math.cos(lat_rad[j]) * math.cos(glat)
    scol = np.empty(nx)
    for i in range(nx):
        scol[i] = math.sin(0.5 * (lon_rad[i] - glon)) ** 2
    h_scale = 2.0 * radius / heuristic_speed if use_h else 0.0
    g[start] = t_start_h
    tarr[start] = t_start_h
    h0 = 0.0
    if use_h:
        h0 = h_scale * math.asin(math.sqrt(min(1.0, srow[start // nx] + crow[start // nx] * scol[start % nx])))
        hcache[start] = h0
    keys, vals, size = _heap_push(keys, vals, size, g[start] + h0, start)
    expanded = 0
    scanned = 0
    reached = False
    hit = False
    while size > 0:
        f, u, size = _heap_pop(keys, vals, size)
        if closed[u]:
            continue
        closed[u] = True
        expanded += 1
        if u == goal:
            reached = True
            break
        gu = g[u]
        tu = tarr[u]
        ju = u // nx
        iu = u - ju * nx
        mask = allowed[u]
        su = sea_index[u]
        i0, i1, wt = _time_slot(tu, dt_h, n_times, step)
        hs_u, wc_u, ws_u, cu_u, cv_u = _node_weather(su, i0, i1, wt, wave, cur, has_cur)
        for k in range(K):
            if (mask >> np.uint64(k)) & np.uint64(1) == 0:
                continue
            v = u + dj[k] * nx + di[k]
            scanned += 1
            if closed[v]:
                continue
            hs_v, wc_v, ws_v, cu_v, cv_v = _node_weather(sea_index[v], i0, i1, wt, wave, cur, has_cur)
            c = elen[ju, k] * _pace(
                model, v0, floor, lpp, dwt, printed, min_sog, 0.5 * (hs_u + hs_v), 0.5 * (wc_u + wc_v),
                0.5 * (ws_u + ws_v), 0.5 * (cu_u + cu_v), 0.5 * (cv_u + cv_v), has_cur, ecos[ju, k], esin[ju, k],
            )  # fmt: skip
            tv = tu + c
            k_lo, k_hi = _slice_range(tu, tv, dt_h, n_times)
            if k_hi >= n_safe:
                hit = True
                k_hi = n_safe - 1
            ex = 0.0
            if _stencil_cells_unsafe(iu, ju, k, cells, counts, ny, nx, sea_index, unsafe, k_lo, k_hi, ebit[ju, k], start, goal):
                if hard:
                    continue
                ex = c
            ng = gu + c + penalty * ex
            if ng < g[v]:
                g[v] = ng
                tarr[v] = tv
                expo[v] = expo[u] + ex
                parent[v] = u
                hv = 0.0
                if use_h:
                    hv = hcache[v]
                    if hv < 0.0:
                        jv = v // nx
                        hv = h_scale * math.asin(math.sqrt(min(1.0, srow[jv] + crow[jv] * scol[v - jv * nx])))
                        hcache[v] = hv
                keys, vals, size = _heap_push(keys, vals, size, ng + hv, v)
    return g, tarr, expo, parent, expanded, scanned, reached, hit
