"""Compiled time-dependent A* / Dijkstra on the regular lat/lon mesh (no vessel limits)."""

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


@njit(cache=True)
def astar(
    nx,
    allowed,
    di,
    dj,
    elen,
    ecos,
    esin,
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
    distance_mode,
    heuristic_speed,
    radius,
):
    """Label-setting A* from ``start`` to ``goal``; returns (g, parent, expanded, scanned, computed, reached).

    ``scanned`` counts the allowed edges looked at from expanded nodes; ``computed`` those of
    them whose cost was computed (the edges to closed nodes are skipped before that).

    Edge cost: distance (``distance_mode``) or sailing time
    ``L * (pace(u) + pace(v)) / 2`` with both paces taken in the weather interpolated at the
    time the ship reaches u (the edge's start). ``heuristic_speed`` > 0 gives the admissible
    heuristic great-circle distance / speed; 0 gives Dijkstra.
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
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    hcache = np.full(n, -1.0)
    keys = np.empty(1024, dtype=np.float64)
    vals = np.empty(1024, dtype=np.int64)
    size = 0
    glat = lat_rad[goal // nx]
    glon = lon_rad[goal % nx]
    use_h = heuristic_speed > 0.0
    # haversine to the goal from per-row and per-column factors: one asin and sqrt per node
    ny = n // nx
    srow = np.empty(ny)
    crow = np.empty(ny)
    for j in range(ny):
        srow[j] = math.sin(0.5 * (lat_rad[j] - glat)) ** 2
        crow[j] = math.cos(lat_rad[j]) * math.cos(glat)
    scol = np.empty(nx)
    for i in range(nx):
        scol[i] = math.sin(0.5 * (lon_rad[i] - glon)) ** 2
    h_scale = 2.0 * radius / heuristic_speed if use_h else 0.0
    g[start] = t_start_h if not distance_mode else 0.0
    h0 = 0.0
    if use_h:
        h0 = h_scale * math.asin(math.sqrt(min(1.0, srow[start // nx] + crow[start // nx] * scol[start % nx])))
        hcache[start] = h0
    keys, vals, size = _heap_push(keys, vals, size, g[start] + h0, start)
    expanded = 0
    scanned = 0
    computed = 0
    reached = False
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
        ju = u // nx
        mask = allowed[u]
        su = sea_index[u]
        i0, i1, wt = _time_slot(gu, dt_h, n_times, step)
        hs_u, wc_u, ws_u, cu_u, cv_u = _node_weather(su, i0, i1, wt, wave, cur, has_cur)
        for k in range(K):
            if (mask >> np.uint64(k)) & np.uint64(1) == 0:
                continue
            v = u + dj[k] * nx + di[k]
            scanned += 1
            if closed[v]:
                continue
            computed += 1
            L = elen[ju, k]
            if distance_mode:
                c = L
            else:
                hs_v, wc_v, ws_v, cu_v, cv_v = _node_weather(sea_index[v], i0, i1, wt, wave, cur, has_cur)
                c = L * _pace(
                    model, v0, floor, lpp, dwt, printed, min_sog, 0.5 * (hs_u + hs_v), 0.5 * (wc_u + wc_v),
                    0.5 * (ws_u + ws_v), 0.5 * (cu_u + cu_v), 0.5 * (cv_u + cv_v), has_cur, ecos[ju, k], esin[ju, k],
                )  # fmt: skip
            ng = gu + c
            if ng < g[v]:
                g[v] = ng
                parent[v] = u
                hv = 0.0
                if use_h:
                    hv = hcache[v]
                    if hv < 0.0:
                        jv = v // nx
                        hv = h_scale * math.asin(math.sqrt(min(1.0, srow[jv] + crow[jv] * scol[v - jv * nx])))
                        hcache[v] = hv
                keys, vals, size = _heap_push(keys, vals, size, ng + hv, v)
    return g, parent, expanded, scanned, computed, reached
