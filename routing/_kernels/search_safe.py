"""Compiled time-dependent A* under the vessel's limits (hard or penalised unsafe edges)."""

from __future__ import annotations

import numpy as np
from numba import njit

from routing._kernels.core import P_MIN_SOG, P_PACE_MIN, P_TIME_STEP, P_WAIT, _heap_pop, _heap_push, goal_tables, heuristic_at
from routing._kernels.edge import _lerp, mean_pace, node_at, node_slice, node_wait, sub_index, sub_slices, substeps
from routing._kernels.flags import _slice_range, _stencil_cells_unsafe
from routing._kernels.speed import ship_of


@njit(cache=True)
def astar_safe(nx, allowed, di, dj, elen, ecos, esin, ebit, cells, counts, lat_rad, lon_rad, sea_index, wave, cur, has_cur,
        dt_h, n_times, p, start, goal, t_start_h, heuristic_speed, radius, unsafe, hard, penalty):
    """Time-dependent A* that respects the vessel's limits; returns
    ``(g, t, exposure, parent, expanded, scanned, reached, horizon_hit)``.

    Long by design: one compiled loop whose heap and per-node label arrays are locals; a numba
    helper per phase would need them all passed in and out on every edge.

    Edge time as in :func:`routing._kernels.search.astar`: an edge entered at t (the arrival at
    u) is left by A(t), its FIFO arrival. An edge is *unsafe* when a cell it touches
    (``cells[k]``, ``counts[k]``: the stencil's closed-square cells, both end nodes included; the
    start and goal nodes are exempt, the ship must leave and reach them) is flagged in
    ``unsafe`` for the edge's heading sector (``ebit[row, k]``) in a weather slice bracketing
    [t, A(t)] (a wait at u counts: the ship is in u's cell meanwhile). ``hard``: unsafe edges
    are not taken. Otherwise (soft) an unsafe edge costs its time ``A(t) - t`` times
    ``1 + penalty``. The label of a node is its cost ``g`` (hours plus penalties); its arrival
    time ``t`` is kept apart. A node keeps one label (the least cost) and edges are taken at
    their earliest arrival: the search does not wait for unsafe weather to pass, so under
    limits it returns the least-cost path among those whose every prefix is least-cost (not a
    proven optimum of the constrained problem). Penalties only add cost, so the heuristic
    (great-circle distance / highest speed) stays admissible and consistent; with ``penalty`` 0
    the search is exactly :func:`routing._kernels.search.astar`. ``horizon_hit``: an edge needed
    a slice beyond ``unsafe.shape[0]`` (the caller extends the flags and searches again).
    """
    ship = ship_of(p)
    min_sog = p[P_MIN_SOG]
    step = p[P_TIME_STEP] > 0.5
    wait = p[P_WAIT] > 0.5
    pace_min = p[P_PACE_MIN]
    m_sub, tau, n_sub, phase = substeps(dt_h, n_times, step)
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
    use_h = heuristic_speed > 0.0
    srow, crow, scol = goal_tables(lat_rad, lon_rad, goal, nx)
    h_scale = 2.0 * radius / heuristic_speed if use_h else 0.0
    g[start] = t_start_h
    tarr[start] = t_start_h
    h0 = heuristic_at(start, nx, srow, crow, scol, h_scale, hcache) if use_h else 0.0
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
        j_u = sub_index(tu, tau, n_sub, phase)
        k0, k1, f = sub_slices(j_u, m_sub, n_times)
        u_j = node_at(su, j_u, m_sub, n_times, wave, cur, has_cur)
        for k in range(K):
            if (mask >> np.uint64(k)) & np.uint64(1) == 0:
                continue
            v = u + dj[k] * nx + di[k]
            scanned += 1
            if closed[v]:
                continue
            # the edge model of routing._kernels.edge, written out as in routing._kernels.search.astar
            L = elen[ju, k]
            sv = sea_index[v]
            v_j = node_slice(sv, k0, wave, cur, has_cur)
            if f != 0.0:
                v_j = _lerp(v_j, node_slice(sv, k1, wave, cur, has_cur), f)
            tv = tu + L * mean_pace(ship, min_sog, u_j, v_j, has_cur, ecos[ju, k], esin[ju, k])
            if wait and j_u + 1 < n_sub:
                lower = L * pace_min
                if (j_u + 1 - phase) * tau + lower < tv:
                    tv = node_wait(ship, min_sog, lower, L, tv, j_u, su, sv, wave, cur, has_cur, ecos[ju, k], esin[ju, k], m_sub, tau, n_sub,
                                   phase, n_times)  # fmt: skip  # fmt: skip
            c = tv - tu
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
                hv = heuristic_at(v, nx, srow, crow, scol, h_scale, hcache) if use_h else 0.0
                keys, vals, size = _heap_push(keys, vals, size, ng + hv, v)
    return g, tarr, expo, parent, expanded, scanned, reached, hit
