"""Compiled time-dependent A* / Dijkstra on the regular lat/lon mesh (no vessel limits)."""

from __future__ import annotations

import numpy as np
from numba import njit

from routing._kernels.core import P_MIN_SOG, P_PACE_MIN, P_TIME_STEP, P_WAIT, _heap_pop, _heap_push, goal_tables, heuristic_at
from routing._kernels.edge import _lerp, mean_pace, node_at, node_slice, node_wait, sub_index, sub_slices, substeps
from routing._kernels.speed import ship_of


@njit(cache=True, nogil=True)  # releases the GIL: a window's departures and the least-fuel corridor's searches run in two threads
def astar(nx, allowed, di, dj, elen, ecos, esin, lat_rad, lon_rad, sea_index, wave, cur, has_cur, dt_h, n_times, p, start,
        goal, t_start_h, distance_mode, heuristic_speed, radius):
    """Label-setting A* from ``start`` to ``goal``; returns (g, parent, expanded, scanned, computed, reached).

    ``scanned`` counts the allowed edges looked at from expanded nodes; ``computed`` those of
    them whose cost was computed (the edges to closed nodes are skipped before that).

    Edge cost: its length (``distance_mode``), or the time from reaching u to reaching v,
    ``A(t) - t``, by the model of :func:`routing._kernels.edge.arrival` (the travel time in the
    weather of the quarter-hour sub-slice nearest to t, the weather linear in time between
    slices; with ``p[P_WAIT]`` the FIFO arrival, min over later departures). The labels are
    arrival times; under FIFO edges the first time the goal leaves the heap its label is the
    earliest arrival. ``heuristic_speed`` > 0 gives the admissible
    heuristic great-circle distance / speed (the speed is at least any speed over ground an
    edge can reach, so no edge is faster, waiting included); 0 gives Dijkstra.
    """
    ship = ship_of(p)
    min_sog = p[P_MIN_SOG]
    step = p[P_TIME_STEP] > 0.5
    wait = p[P_WAIT] > 0.5
    pace_min = p[P_PACE_MIN]
    m_sub, tau, n_sub, phase = substeps(dt_h, n_times, step)
    n = allowed.size
    K = di.size
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    hcache = np.full(n, -1.0)
    keys = np.empty(1024, dtype=np.float64)
    vals = np.empty(1024, dtype=np.int64)
    size = 0
    use_h = heuristic_speed > 0.0
    srow, crow, scol = goal_tables(lat_rad, lon_rad, goal, nx)
    h_scale = 2.0 * radius / heuristic_speed if use_h else 0.0
    g[start] = t_start_h if not distance_mode else 0.0
    h0 = heuristic_at(start, nx, srow, crow, scol, h_scale, hcache) if use_h else 0.0
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
        j_u = sub_index(gu, tau, n_sub, phase)
        k0, k1, f = sub_slices(j_u, m_sub, n_times)
        u_j = node_at(su, j_u, m_sub, n_times, wave, cur, has_cur)
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
                ng = gu + L
            else:
                # the edge model of routing._kernels.edge, written out here: an inlined helper doubled the loop's time
                sv = sea_index[v]
                v_j = node_slice(sv, k0, wave, cur, has_cur)
                if f != 0.0:
                    v_j = _lerp(v_j, node_slice(sv, k1, wave, cur, has_cur), f)
                ng = gu + L * mean_pace(ship, min_sog, u_j, v_j, has_cur, ecos[ju, k], esin[ju, k])
                if wait and j_u + 1 < n_sub:
                    lower = L * pace_min  # no departure arrives sooner than this after it
                    if (j_u + 1 - phase) * tau + lower < ng:
                        ng = node_wait(ship, min_sog, lower, L, ng, j_u, su, sv, wave, cur, has_cur, ecos[ju, k], esin[ju, k], m_sub, tau,
                                       n_sub, phase, n_times)  # fmt: skip  # fmt: skip
            if ng < g[v]:
                g[v] = ng
                parent[v] = u
                hv = heuristic_at(v, nx, srow, crow, scol, h_scale, hcache) if use_h else 0.0
                keys, vals, size = _heap_push(keys, vals, size, ng + hv, v)
    return g, parent, expanded, scanned, computed, reached
