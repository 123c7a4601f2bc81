"""The compiled kernels of :mod:`lanes.dbscan_grid` (numba; compiled on first use, cached on disk).

Module-level functions, so that numba's cache keys them on this file: a kernel calling a
closure's jitted function was recompiled in every process (3.5 CPU s per run).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def rdist(x, i, j):
    # scikit-learn's reduced Euclidean distance: squared differences summed in coordinate order
    s = 0.0
    for k in range(x.shape[1]):
        t = x[i, k] - x[j, k]
        s += t * t
    return s


@numba.njit(cache=True)
def find(parent, a):
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@numba.njit(cache=True)
def keep_candidates(cells, rows, nbrs, bound):
    # the candidate pairs whose boxes lie within eps: sum over dims of (|dk| - 1)+^2 <= bound
    keep = np.zeros(rows.size, dtype=np.bool_)
    for m in range(rows.size):
        s = 0
        for k in range(cells.shape[1]):
            g = abs(cells[rows[m], k] - cells[nbrs[m], k]) - 1
            if g > 0:
                s += g * g
        keep[m] = s <= bound
    return keep


@numba.njit(cache=True)
def core_points(x, w, r2, order, start, cand_ptr, cand, lo, hi):
    # core[p]; amb[p] when p's count is within the tie margin (recomputed by the caller)
    n = x.shape[0]
    nc = start.size - 1
    cell_w = np.zeros(nc)
    for c in range(nc):
        t = 0.0
        for k in range(start[c], start[c + 1]):
            t += w[order[k]]
        cell_w[c] = t
    core = np.zeros(n, dtype=np.bool_)
    amb = np.zeros(n, dtype=np.bool_)
    for c in range(nc):
        if cell_w[c] >= hi:  # a dense cell: every point is core
            for k in range(start[c], start[c + 1]):
                core[order[k]] = True
            continue
        for k in range(start[c], start[c + 1]):
            p = order[k]
            t = cell_w[c]
            for m in range(cand_ptr[c], cand_ptr[c + 1]):
                b = cand[m]
                if b == c:
                    continue
                for kk in range(start[b], start[b + 1]):
                    q = order[kk]
                    if rdist(x, p, q) <= r2:
                        t += w[q]
            if t >= hi:
                core[p] = True
            elif t >= lo:
                amb[p] = True
    return core, amb


@numba.njit(cache=True)
def link_cells(x, core, r2, order, start, cand_ptr, cand):
    # union-find over the cells holding core points; returns each cell's root (-1: no core)
    nc = start.size - 1
    parent = np.arange(nc)
    has_core = np.zeros(nc, dtype=np.bool_)
    for c in range(nc):
        for k in range(start[c], start[c + 1]):
            if core[order[k]]:
                has_core[c] = True
                break
    for a in range(nc):
        if not has_core[a]:
            continue
        for m in range(cand_ptr[a], cand_ptr[a + 1]):
            b = cand[m]
            if b <= a or not has_core[b]:
                continue
            ra = find(parent, a)
            rb = find(parent, b)
            if ra == rb:
                continue
            linked = False
            for k in range(start[a], start[a + 1]):
                p = order[k]
                if core[p]:
                    for kk in range(start[b], start[b + 1]):
                        q = order[kk]
                        if core[q] and rdist(x, p, q) <= r2:
                            linked = True
                            break
                if linked:
                    break
            if linked:
                parent[max(ra, rb)] = min(ra, rb)
    root = np.full(nc, -1, dtype=np.int64)
    for c in range(nc):
        if has_core[c]:
            root[c] = find(parent, c)
    return root


@numba.njit(cache=True)
def border_labels(x, core, labels, r2, cell_of, start, order, cand_ptr, cand):
    # each non-core point: the smallest label among its core neighbours (else stays -1)
    n = x.shape[0]
    for p in range(n):
        if core[p]:
            continue
        c = cell_of[p]
        best = -1
        for m in range(cand_ptr[c], cand_ptr[c + 1]):
            b = cand[m]
            for kk in range(start[b], start[b + 1]):
                q = order[kk]
                if core[q] and (best < 0 or labels[q] < best) and rdist(x, p, q) <= r2:
                    best = labels[q]
        labels[p] = best
    return labels


@numba.njit(cache=True)
def uniform_labels(core, labels, order, start, cand_ptr, cand):
    # per cell holding a core point: the label of every core point of its candidate cells when
    # they all have one label, else -1
    nc = start.size - 1
    lo = np.full(nc, np.iinfo(np.int64).max, dtype=np.int64)
    hi = np.full(nc, -1, dtype=np.int64)
    for c in range(nc):
        for k in range(start[c], start[c + 1]):
            p = order[k]
            if core[p]:
                lo[c] = min(lo[c], labels[p])
                hi[c] = max(hi[c], labels[p])
    out = np.full(nc, -1, dtype=np.int64)
    for c in range(nc):
        if hi[c] < 0:
            continue
        a = lo[c]
        b = hi[c]
        for m in range(cand_ptr[c], cand_ptr[c + 1]):
            if hi[cand[m]] >= 0:
                a = min(a, lo[cand[m]])
                b = max(b, hi[cand[m]])
        if a == b:
            out[c] = a
    return out
