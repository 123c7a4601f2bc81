"""Compiled least-fuel search with a speed setting per edge and an arrival deadline.

The model (what "optimal" means here)
-------------------------------------
* A route is a mesh path; on every edge the ship runs one calm-water speed setting ``s`` out of a
  given set (engine settings), and it may wait at any node (engines stopped: no propulsion fuel).
* An edge of length L left at time t at setting s takes ``c_j(s) = L * pace_s(weather at the
  sub-slice j nearest to t)`` hours -- the edge model of :mod:`routing._kernels.edge` with the
  speed-loss model evaluated at the setting's speed (no waiting inside the edge: waits are explicit).
* Its fuel is ``rate(s) * c_j(s)`` with ``rate(s) = P(s) SFOC(P(s)) `` the STEAM2 fuel rate of the
  setting (:func:`routing.emissions.steam2_legs` of one hour at s, computed in Python and passed
  in): the engine setting's power over the slowed time, the weather charged once through the
  time (:func:`routing.emissions.leg_power_kw`).
* Minimise total fuel subject to arrival at the goal no later than the deadline D.

Why departures at piece starts suffice: within a sub-slice's piece ``[(j - 1/2) tau, (j + 1/2) tau)``
an edge's travel time and fuel do not depend on the departure time, so leaving earlier in the piece
is never worse; a ship at a node at time t therefore only needs to consider leaving at t or at the
start of a later piece ([1]: waiting at nodes makes every earlier label at least as good as a later
one with no more fuel).

Algorithm: bicriteria label setting over node x time bucket
-----------------------------------------------------------
Labels (time, fuel) are settled in the order (time bucket, fuel), buckets ``Delta = tau / k`` wide
and aligned with the pieces. A label at node v is *dominated* when a settled label at v arrived
no later with no more fuel ([2], Martins' multicriteria label setting; with waiting allowed the
dominating label can do whatever the dominated one does). Every settled label spawns a *waiting*
label at the start of the next piece (same fuel), unless a settled label with less fuel at no
later time exists (its own waiting chain then covers). Two variants share the code:

* ``relax=False`` (the route): labels keep their exact times. Within one bucket of one node only the
  first label settled (the least fuel of the bucket) is kept, and a costlier one only when it arrives
  before every label settled at the node (so the earliest label of every node is kept: the
  time-optimal schedule stays reachable); a label within ``eps_f`` of the fuel of a label settled
  earlier at the node is dropped. Every label is a real schedule, so the result is feasible and its
  fuel an upper bound UB of the optimum.
* ``relax=True`` (the bound): a settled label's time is rounded down to its bucket's start and its
  fuel down to a multiple of ``eps_f``, so all labels of a bucket are equal in time and the
  least-fuel one dominates the others exactly. By
  induction along any real schedule (each of its labels is dominated by a relaxed label: the relaxed
  one leaves no later, in the same piece or at the start of the real one's piece through its waiting
  chain), the relaxed optimum is a lower bound LB of the real optimum.

``UB - LB`` is the reported gap (with LB the better of the relaxation's and the start's
:func:`fuel_bound`, see :func:`routing.fuel.least_fuel`); with ``Delta`` below every difference of
arrival times both equal the exact optimum (the brute-force tests check LB <= brute force <= UB, and
equality for a fine Delta). Pruning (admissible, so neither variant loses what it would otherwise
find): a label later than ``D - d / v_top`` (d the node's great-circle distance to the goal,
``v_top`` the highest speed over ground any setting reaches in this weather), or whose fuel plus :func:`fuel_bound` (the
least fuel that covers d in the time left) reaches the incumbent (the best goal label, or a known
route's fuel ``f_upper``), or that a label already created at its node dominates.

Cost: an edge's sailing times at every setting depend on the piece it is left in only, so they are
computed once per node and piece (:func:`_node_costs`); a label dropped when it leaves the queue
gives its slot to the next label created, so the label arrays hold the settled labels and the queue
(node and parent as int32, the setting as int8), not every label ever created.

References
----------
.. [1] A. Orda and R. Rom, "Shortest-path and minimum-delay algorithms in networks with
       time-dependent edge-length," J. ACM, vol. 37, no. 3, pp. 607-625, 1990, doi:10.1145/79147.214078.
.. [2] E. Q. V. Martins, "On a multicriteria shortest path problem," Eur. J. Oper. Res., vol. 16,
       no. 2, pp. 236-245, 1984, doi:10.1016/0377-2217(84)90077-8.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from routing._kernels.core import P_MIN_SOG, _heap_pop, _heap_push, goal_tables
from routing._kernels.edge import _lerp, mean_pace, node_at, node_slice, sub_index, sub_slices, substeps
from routing._kernels.speed import ship_of


@njit(inline="always")
def _less(b1, f1, b2, f2):
    return b1 < b2 or (b1 == b2 and f1 < f2)


@njit
def _hpush(hb, hf, hv, size, b, f, v):
    """Push (bucket, fuel) -> label onto a binary min-heap ordered by bucket, then fuel."""
    if size == hb.size:
        nb = np.empty(hb.size * 2, dtype=hb.dtype)
        nf = np.empty(hf.size * 2, dtype=hf.dtype)
        nv = np.empty(hv.size * 2, dtype=hv.dtype)
        nb[:size], nf[:size], nv[:size] = hb[:size], hf[:size], hv[:size]
        hb, hf, hv = nb, nf, nv
    i = size
    while i > 0:
        par = (i - 1) >> 1
        if not _less(b, f, hb[par], hf[par]):
            break
        hb[i], hf[i], hv[i] = hb[par], hf[par], hv[par]
        i = par
    hb[i], hf[i], hv[i] = b, f, v
    return hb, hf, hv, size + 1


@njit
def _hpop(hb, hf, hv, size):
    tb, tf, tv = hb[0], hf[0], hv[0]
    size -= 1
    if size > 0:
        b, f, v = hb[size], hf[size], hv[size]
        i = 0
        while True:
            c = 2 * i + 1
            if c >= size:
                break
            if c + 1 < size and _less(hb[c + 1], hf[c + 1], hb[c], hf[c]):
                c += 1
            if not _less(hb[c], hf[c], b, f):
                break
            hb[i], hf[i], hv[i] = hb[c], hf[c], hv[c]
            i = c
        hb[i], hf[i], hv[i] = b, f, v
    return tb, tf, tv, size


@njit(inline="always")
def fuel_bound(d_nmi, t_rem_h, hull_x, hull_y):
    """Least fuel to cover ``d_nmi`` within ``t_rem_h``: ``t_rem * phi(d / t_rem)`` with phi the lower convex
    envelope of (0, 0) (waiting) and every setting's (highest speed over ground, fuel rate) (Jensen's
    inequality over the time-weighted speeds; inf when even the fastest setting is too slow)."""
    if d_nmi <= 0.0:
        return 0.0
    if t_rem_h <= 0.0:
        return np.inf
    x = d_nmi / t_rem_h
    if x > hull_x[-1] * (1.0 + 1e-12):
        return np.inf
    for i in range(1, hull_x.size):
        if x <= hull_x[i]:
            w = (x - hull_x[i - 1]) / (hull_x[i] - hull_x[i - 1])
            return t_rem_h * (hull_y[i - 1] + w * (hull_y[i] - hull_y[i - 1]))
    return t_rem_h * hull_y[-1]


@njit(cache=True, nogil=True)
def goal_distances(nx, allowed, di, dj, elen, goal):
    """Length [nmi] of the shortest path from every node to ``goal`` over the edges ``allowed`` (inf
    where none): Dijkstra backwards from the goal over the edge lengths the search sails (``elen``,
    great circles, so never below the great-circle distance). Any route from a node covers at least
    this distance: the distance of the envelope bound (:meth:`routing.fuel.FuelProblem.envelope_bound`). (The
    search itself prunes with the great-circle distance: a tighter pruning distance changes which labels its
    heuristic bucket rules keep, and so its route, by a hair either way.)"""
    n = allowed.size
    K = di.size
    dist = np.full(n, np.inf)
    done = np.zeros(n, dtype=np.bool_)
    keys = np.empty(1024, dtype=np.float64)
    vals = np.empty(1024, dtype=np.int64)
    dist[goal] = 0.0
    keys, vals, size = _heap_push(keys, vals, 0, 0.0, goal)
    while size > 0:
        d, v, size = _heap_pop(keys, vals, size)
        if done[v]:
            continue
        done[v] = True
        for k in range(K):
            u = v - dj[k] * nx - di[k]  # the node whose step k ends at v (the search's own arithmetic, reversed)
            if u < 0 or u >= n or done[u] or (allowed[u] >> np.uint64(k)) & np.uint64(1) == 0:
                continue
            nd = d + elen[u // nx, k]
            if nd < dist[u]:
                dist[u] = nd
                keys, vals, size = _heap_push(keys, vals, size, nd, u)
    return dist


@njit(cache=True)
def goal_gc_distances(nx, n, lat_rad, lon_rad, goal, radius):
    """Great-circle distance [nmi] of every node to ``goal`` (the haversine of :func:`routing._kernels.core.goal_tables`)."""
    srow, crow, scol = goal_tables(lat_rad, lon_rad, goal, nx)
    out = np.empty(n)
    for u in range(n):
        j = u // nx
        out[u] = 2.0 * radius * math.asin(math.sqrt(min(1.0, srow[j] + crow[j] * scol[u - j * nx])))
    return out


@njit
def _front_dominated(ft, ff, fn, v, t, f, tol):
    """Is (t, f) dominated by a label already created at node v (no later, no more fuel than f + tol)? If not, remember it
    (a full memory forgets its latest entry: less pruning, never a wrong one)."""
    cnt = fn[v]
    pos = 0
    while pos < cnt and ft[v, pos] <= t:
        pos += 1
    if pos > 0 and ff[v, pos - 1] <= f + tol:
        return True
    # drop the entries the new label dominates (later with no less fuel: contiguous from pos)
    end = pos
    while end < cnt and ff[v, end] >= f:
        end += 1
    shift = end - pos
    if shift > 0:
        for q in range(end, cnt):
            ft[v, q - shift] = ft[v, q]
            ff[v, q - shift] = ff[v, q]
        cnt -= shift
    cap = ft.shape[1]
    if cnt == cap:
        if pos == cap:
            fn[v] = cnt
            return False
        cnt -= 1
    for q in range(cnt, pos, -1):
        ft[v, q] = ft[v, q - 1]
        ff[v, q] = ff[v, q - 1]
    ft[v, pos] = t
    ff[v, pos] = f
    fn[v] = cnt + 1
    return False


@njit
def _grow(a, n):
    if n < a.size:
        return a
    out = np.empty(a.size * 2, dtype=a.dtype)
    out[: a.size] = a
    return out


@njit
def _grow_rows(a, n):
    if n < a.shape[0]:
        return a
    out = np.empty((a.shape[0] * 2, a.shape[1]), dtype=a.dtype)
    out[: a.shape[0]] = a
    return out


@njit
def _node_costs(out, o, u, j_u, nx, allowed, di, dj, elen, ecos, esin, sea_index, wave, cur, has_cur, m_sub, n_times, P, min_sog):
    """The sailing time [h] of every allowed edge out of node u at every setting, left in piece ``j_u``, into
    ``out[o + e * S + s]`` (e counts the allowed edges in step order): the edge model of
    :mod:`routing._kernels.edge`, which depends on the piece only, so labels of one piece share it."""
    S = P.shape[0]
    ju = u // nx
    mask = allowed[u]
    su = sea_index[u]
    k0, k1, fr = sub_slices(j_u, m_sub, n_times)
    u_j = node_at(su, j_u, m_sub, n_times, wave, cur, has_cur)
    e = 0
    for k in range(di.size):
        if (mask >> np.uint64(k)) & np.uint64(1) == 0:
            continue
        sv = sea_index[u + dj[k] * nx + di[k]]
        v_j = node_slice(sv, k0, wave, cur, has_cur)
        if fr != 0.0:
            v_j = _lerp(v_j, node_slice(sv, k1, wave, cur, has_cur), fr)
        L = elen[ju, k]
        for s in range(S):
            out[o + e * S + s] = L * mean_pace(ship_of(P[s]), min_sog, u_j, v_j, has_cur, ecos[ju, k], esin[ju, k])
        e += 1


@njit
def _new_slot(free, n_free, nl, lt, lf, lnode, lpar, lspd):
    """A label slot: the last freed one (a label dropped when it left the queue), else a new one at the end."""
    if n_free > 0:
        return free[n_free - 1], n_free - 1, nl, lt, lf, lnode, lpar, lspd
    return nl, n_free, nl + 1, _grow(lt, nl), _grow(lf, nl), _grow(lnode, nl), _grow(lpar, nl), _grow(lspd, nl)


@njit(cache=True, nogil=True)  # releases the GIL: a window's departures run in two threads
def fuel_search(nx, allowed, di, dj, elen, ecos, esin, dist, sea_index, wave, cur, has_cur, dt_h, n_times, P, rate,
                start, goal, t_start_h, f_start, deadline_h, k_bucket, relax, hull_x, hull_y, f_upper, max_labels, front_cap,
                eps_f, stop_below):
    """Least fuel from ``start`` (reached at ``t_start_h`` with ``f_start`` fuel) to ``goal`` by
    ``deadline_h``, settings ``P[s]`` (parameter vectors) at ``rate[s]`` [fuel per hour], below
    ``f_upper`` (a known route's fuel, or inf). ``dist``: every node's great-circle distance to the goal
    (:func:`goal_gc_distances`); ``hull_x, hull_y``: the fuel bound's envelope
    (:func:`fuel_bound`); ``front_cap``: labels remembered per node for pruning at push time;
    ``eps_f``: the fuel resolution (the route: a label within ``eps_f`` of an earlier one's fuel is
    dropped; the bound: fuels are rounded down to multiples of it); ``stop_below``: stop as soon as a
    goal label with no more fuel is settled (the bound: a known lower bound it cannot beat then).

    Returns ``(lt, lf, lnode, lpar, lspd, n_labels, goal_labels, n_goal, settled, status)``: the
    label arrays (time, fuel, node, parent label, setting index or -1 for a wait; a dropped label's
    slot is reused, so only settled labels are kept), the number of labels created, the settled
    labels at the goal in time order (each with less fuel than the one before: the time-fuel
    front; the last one is the least fuel), the number settled, and ``status`` 0 (done), 1 (the
    label budget ``max_labels`` was exhausted) or 2 (stopped at a goal label within ``stop_below``).

    Long by design: one compiled label loop whose queue, label arrays and per-node pruning
    arrays are locals (numba helpers would need about twenty of them passed on every push).
    """
    step = False
    m_sub, tau, n_sub, phase = substeps(dt_h, n_times, step)
    delta = tau / k_bucket
    origin = -phase * tau  # bucket boundaries fall on the pieces' starts
    n = allowed.size
    K = di.size
    S = rate.size
    min_sog = P[0, P_MIN_SOG]
    best_f = np.full(n, np.inf)  # least fuel settled at the node
    prev_f = np.full(n, np.inf)  # least fuel settled in the node's earlier buckets
    last_b = np.full(n, -(2**62), dtype=np.int64)
    earliest = np.full(n, np.inf)  # earliest time settled at the node
    first_t = np.full(n, np.inf)  # earliest time of any label created at the node
    tent_b = np.full(n, -(2**62), dtype=np.int64)  # the latest bucket a label was created in at the node
    tent_f = np.full(n, np.inf)  # and the least fuel created there
    cap = 1 << 16
    lt = np.empty(cap)
    lf = np.empty(cap)
    lnode = np.empty(cap, dtype=np.int32)
    lpar = np.empty(cap, dtype=np.int32)
    lspd = np.empty(cap, dtype=np.int8)
    free = np.empty(1 << 14, dtype=np.int32)  # slots of dropped labels, for reuse
    n_free = 0
    hb = np.empty(1 << 14, dtype=np.int64)
    hf = np.empty(1 << 14)
    hv = np.empty(1 << 14, dtype=np.int32)
    size = 0
    lt[0], lf[0], lnode[0], lpar[0], lspd[0] = t_start_h, f_start, start, -1, -2
    nl = 1
    created = 1
    b0 = int(math.floor((t_start_h - origin) / delta))
    hb, hf, hv, size = _hpush(hb, hf, hv, size, b0, f_start, 0)
    goal_labels = np.empty(64, dtype=np.int64)
    n_goal = 0
    incumbent = f_upper
    v_top_kn = hull_x[-1]
    fslot = np.full(n, -1, dtype=np.int32)  # per node its row of the front memory (allocated on first use)
    ft = np.empty((1 << 10, front_cap))  # per row: labels created so far (time ascending, fuel descending)
    ff = np.empty((1 << 10, front_cap))
    fn = np.zeros(1 << 10, dtype=np.int64)
    n_rows = 0
    cost_at = np.full(n, -1, dtype=np.int64)  # per node: offset of its edges' times in `costs` (allocated on first use)
    cost_piece = np.full(n, -1, dtype=np.int64)  # and the piece they were computed for
    costs = np.empty(1 << 14)
    n_costs = 0
    settled = 0
    status = 0
    tol = 0.0 if relax else eps_f
    while size > 0:
        b, f, lab, size = _hpop(hb, hf, hv, size)
        if origin + b * delta > deadline_h + 1e-9:
            break
        u = lnode[lab]
        t = lt[lab]
        if relax:  # the relaxation: time down to the bucket's start, fuel down to the resolution
            t = origin + b * delta
            if eps_f > 0.0:
                f = math.floor(f / eps_f) * eps_f
            lt[lab], lf[lab] = t, f
        keep = True
        if f >= incumbent or (u != goal and f + fuel_bound(dist[u], deadline_h - t, hull_x, hull_y) >= incumbent):
            keep = False
        elif lspd[lab] == -1:  # a waiting label: valid unless a label with less fuel settled at no later time
            ref = prev_f[u] if last_b[u] == b else best_f[u]
            if f > ref:
                keep = False
        elif last_b[u] == b:
            if t >= earliest[u] or f >= prev_f[u] - tol:
                keep = False  # a costlier label of a bucket already settled, unless the earliest of the node
            else:
                earliest[u] = t
                if f < best_f[u]:
                    best_f[u] = f
        elif f >= best_f[u] - tol:
            keep = False
        else:
            prev_f[u] = best_f[u]
            best_f[u] = f
            last_b[u] = b
            if t < earliest[u]:
                earliest[u] = t
        if not keep:  # its slot is free again (nothing points at an unsettled label)
            free = _grow(free, n_free)
            free[n_free] = lab
            n_free += 1
            continue
        settled += 1
        if u == goal:
            if t <= deadline_h + 1e-9 and f < incumbent:
                incumbent = f
                goal_labels = _grow(goal_labels, n_goal)
                goal_labels[n_goal] = lab
                n_goal += 1
                if f <= stop_below:
                    status = 2
                    break
            continue
        if created + K * S + 1 >= max_labels:
            status = 1
            break
        # the waiting label: leave at the start of the next piece (the weather is held after the last)
        j_u = sub_index(t, tau, n_sub, phase)
        du = dist[u]
        if j_u + 1 < n_sub and f <= best_f[u]:  # only the least fuel so far waits (it covers the others)
            tw = (j_u + 1 - phase) * tau
            if tw + du / v_top_kn <= deadline_h + 1e-9:
                q, n_free, nl, lt, lf, lnode, lpar, lspd = _new_slot(free, n_free, nl, lt, lf, lnode, lpar, lspd)
                lt[q], lf[q], lnode[q], lpar[q], lspd[q] = tw, f, u, lab, -1
                bw = int(math.floor((tw - origin) / delta + 1e-9))
                hb, hf, hv, size = _hpush(hb, hf, hv, size, bw, f, q)
                created += 1
        mask = allowed[u]
        o = cost_at[u]
        if o < 0:
            deg = 0
            for k in range(K):
                deg += (mask >> np.uint64(k)) & np.uint64(1)
            o = n_costs
            n_costs += deg * S
            while costs.size < n_costs:
                costs = _grow(costs, costs.size)
            cost_at[u] = o
        if cost_piece[u] != j_u:
            _node_costs(costs, o, u, j_u, nx, allowed, di, dj, elen, ecos, esin, sea_index, wave, cur, has_cur, m_sub, n_times, P, min_sog)
            cost_piece[u] = j_u
        e = -1
        for k in range(K):
            if (mask >> np.uint64(k)) & np.uint64(1) == 0:
                continue
            e += 1
            v = u + dj[k] * nx + di[k]
            dv = dist[v]
            t_lb = dv / v_top_kn
            if t + t_lb > deadline_h + 1e-9:
                continue
            for s in range(S):
                c = costs[o + e * S + s]
                arr = t + c
                if arr + t_lb > deadline_h + 1e-9:
                    continue
                nf = f + rate[s] * c
                if nf + fuel_bound(dv, deadline_h - arr, hull_x, hull_y) >= incumbent:
                    continue
                bnew = int(math.floor((arr - origin) / delta))
                tq, fq = arr, nf
                if relax:
                    tq = origin + bnew * delta
                    if eps_f > 0.0:
                        fq = math.floor(nf / eps_f) * eps_f
                if bnew == last_b[v]:  # the pop rules above, applied early
                    if tq >= earliest[v] or fq >= prev_f[v] - tol:
                        continue
                elif fq >= best_f[v] - tol:
                    continue
                if tq < first_t[v]:
                    first_t[v] = tq
                elif bnew == tent_b[v] and fq >= tent_f[v] - tol:
                    continue  # a cheaper label of this bucket exists already: the pop rule would drop this one
                row = fslot[v]
                if row < 0:
                    row = n_rows
                    fslot[v] = row
                    n_rows += 1
                    ft, ff, fn = _grow_rows(ft, row), _grow_rows(ff, row), _grow(fn, row)
                    fn[row] = 0
                if _front_dominated(ft, ff, fn, row, tq, fq, tol):
                    continue
                if bnew != tent_b[v] or fq < tent_f[v]:
                    tent_b[v], tent_f[v] = bnew, fq
                q, n_free, nl, lt, lf, lnode, lpar, lspd = _new_slot(free, n_free, nl, lt, lf, lnode, lpar, lspd)
                lt[q], lf[q], lnode[q], lpar[q], lspd[q] = arr, nf, v, lab, s
                hb, hf, hv, size = _hpush(hb, hf, hv, size, bnew, nf, q)
                created += 1
    return lt, lf, lnode, lpar, lspd, created, goal_labels, n_goal, settled, status
