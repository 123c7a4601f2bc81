"""Shared pieces of the compiled router: the parameter vector's layout, great-circle geometry,
the 4-ary heap, and the weather-grid -> mesh gather.

Units: lengths in nmi, times in hours relative to the weather's slice 0, speeds in kn.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


# Per-run parameter vector (float64, built by routing.astar.ShipModel.params), unpacked into
# scalars at the top of each kernel; the published coefficients are module globals of
# routing._kernels.speed, which numba freezes into the compiled code.
P_MODEL, P_V0, P_FLOOR, P_LPP, P_DWT, P_PRINTED, P_MIN_SOG, P_TIME_STEP = 0, 1, 2, 3, 4, 5, 6, 7
#: 1: the ship may postpone the start of an edge (wait, or sail it slower) -- the FIFO arrival of
#: routing._kernels.edge; 0: it leaves at once (SIMROUTE emulation).
P_WAIT = 8
#: Aertssen Hs -> Beaufort convention: 0 ours (WMO probable maximum heights as upper edges), 1 SIMROUTE's code.
P_AERTSSEN_BANDS = 9
#: Kwon's speed-reduction coefficient C_U (for the ship's Cb, loading and Froude number) and the two
#: terms of its ship-form coefficient C_Form = a BN + b BN^6.5 (b = 1 / (k V^(2/3))).
P_KWON_CU, P_KWON_FORM_A, P_KWON_FORM_B = 10, 11, 12
#: Least pace over ground any edge can have (1 / the heuristic's speed) [h/nmi]: prunes the
#: departures worth trying (0: none pruned). Set by routing.astar for each weather.
P_PACE_MIN = 13
N_PARAMS = 14
#: A learned model's table (:meth:`routing.learned.LearnedSpeedTable.pack`) follows the parameters.
P_TABLE = N_PARAMS

#: Longest step between the times at which the edge model computes travel times (sub-slices of
#: the weather step; the weather itself is interpolated linearly in time there). [h]
SUBSTEP_MAX_H = 0.25


@njit
def _haversine(lat1, lon1, lat2, lon2, radius):
    """Great-circle distance (inputs in radians). [same unit as radius]"""
    s1 = math.sin(0.5 * (lat2 - lat1))
    s2 = math.sin(0.5 * (lon2 - lon1))
    a = s1 * s1 + math.cos(lat1) * math.cos(lat2) * s2 * s2
    if a > 1.0:
        a = 1.0
    return 2.0 * radius * math.asin(math.sqrt(a))


@njit
def _bearing_cs(lat1, lon1, lat2, lon2):
    """cos and sin of the initial great-circle course (inputs in radians)."""
    dlon = lon2 - lon1
    y = math.sin(dlon) * math.cos(lat2)
    x = math.cos(lat1) * math.sin(lat2) - math.sin(lat1) * math.cos(lat2) * math.cos(dlon)
    n = math.sqrt(x * x + y * y)
    if n == 0.0:
        return 1.0, 0.0
    return x / n, y / n


@njit
def _intermediate(lat1, lon1, lat2, lon2, f):
    """Point at fraction f of the great circle (radians in, radians out)."""
    s1 = math.sin(0.5 * (lat2 - lat1))
    s2 = math.sin(0.5 * (lon2 - lon1))
    a = s1 * s1 + math.cos(lat1) * math.cos(lat2) * s2 * s2
    if a > 1.0:
        a = 1.0
    d = 2.0 * math.asin(math.sqrt(a))
    sd = math.sin(d)
    if sd < 1e-15:
        return lat1 + f * (lat2 - lat1), lon1 + f * (lon2 - lon1)
    A = math.sin((1.0 - f) * d) / sd
    B = math.sin(f * d) / sd
    x = A * math.cos(lat1) * math.cos(lon1) + B * math.cos(lat2) * math.cos(lon2)
    y = A * math.cos(lat1) * math.sin(lon1) + B * math.cos(lat2) * math.sin(lon2)
    z = A * math.sin(lat1) + B * math.sin(lat2)
    return math.atan2(z, math.sqrt(x * x + y * y)), math.atan2(y, x)


@njit
def _heap_push(keys, vals, size, key, val):
    """Push onto a 4-ary min-heap (shallower than a binary heap: fewer cache misses per push)."""
    if size == keys.size:
        nk = np.empty(keys.size * 2, dtype=keys.dtype)
        nv = np.empty(vals.size * 2, dtype=vals.dtype)
        nk[:size] = keys[:size]
        nv[:size] = vals[:size]
        keys, vals = nk, nv
    i = size
    while i > 0:
        parent = (i - 1) >> 2
        if keys[parent] <= key:
            break
        keys[i] = keys[parent]
        vals[i] = vals[parent]
        i = parent
    keys[i] = key
    vals[i] = val
    return keys, vals, size + 1


@njit
def _heap_pop(keys, vals, size):
    """Pop the smallest key of a 4-ary min-heap."""
    top_k = keys[0]
    top_v = vals[0]
    size -= 1
    if size > 0:
        key = keys[size]
        val = vals[size]
        i = 0
        while True:
            c = 4 * i + 1
            if c >= size:
                break
            best = c
            bk = keys[c]
            end = c + 4 if c + 4 < size else size
            for q in range(c + 1, end):
                if keys[q] < bk:
                    bk = keys[q]
                    best = q
            if bk >= key:
                break
            keys[i] = bk
            vals[i] = vals[best]
            i = best
        keys[i] = key
        vals[i] = val
    return top_k, top_v, size


@njit(cache=True)
def gather_bilinear_time(flat, idx, w, t_idx0, t_w, out):
    """out[k, s, c] = sum_q w[s, q] ((1 - t_w[k]) flat[t_idx0[k], idx[s, q], c] + t_w[k] flat[t_idx0[k] + 1, idx[s, q], c]).

    ``flat`` is (T0, G, C) with the channels interleaved and no NaN (the caller zeroes gaps).
    Nodes go in blocks: a block's indices and weights stay in cache while every output time
    is filled, and its nodes read neighbouring grid points.
    """
    n = idx.shape[0]
    nt = t_idx0.size
    nt_src = flat.shape[0]
    nc = flat.shape[2]
    block = 2048
    for s0 in range(0, n, block):
        s1 = min(s0 + block, n)
        for k in range(nt):
            a = t_idx0[k]
            b = a + 1 if a + 1 < nt_src else a
            wt = t_w[k]
            for s in range(s0, s1):
                g0, g1, g2, g3 = idx[s, 0], idx[s, 1], idx[s, 2], idx[s, 3]
                w0, w1, w2, w3 = w[s, 0], w[s, 1], w[s, 2], w[s, 3]
                for c in range(nc):
                    acc = w0 * flat[a, g0, c] + w1 * flat[a, g1, c] + w2 * flat[a, g2, c] + w3 * flat[a, g3, c]
                    if wt != 0.0:
                        acc2 = w0 * flat[b, g0, c] + w1 * flat[b, g1, c] + w2 * flat[b, g2, c] + w3 * flat[b, g3, c]
                        acc = (1.0 - wt) * acc + wt * acc2
                    out[k, s, c] = acc


@njit
def goal_tables(lat_rad, lon_rad, goal, nx):
    """Per-row and per-column factors of the haversine to the goal: one asin and sqrt per node
    (:func:`heuristic_at`)."""
    ny = lat_rad.size
    glat = lat_rad[goal // nx]
    glon = lon_rad[goal % nx]
    srow = np.empty(ny)
    crow = np.empty(ny)
    for j in range(ny):
        srow[j] = math.sin(0.5 * (lat_rad[j] - glat)) ** 2
        crow[j] = math.cos(lat_rad[j]) * math.cos(glat)
    scol = np.empty(nx)
    for i in range(nx):
        scol[i] = math.sin(0.5 * (lon_rad[i] - glon)) ** 2
    return srow, crow, scol


@njit(inline="always")
def heuristic_at(node, nx, srow, crow, scol, h_scale, hcache):
    """Great-circle distance to the goal times ``h_scale`` (= 2 R / speed), cached per node."""
    hv = hcache[node]
    if hv < 0.0:
        j = node // nx
        hv = h_scale * math.asin(math.sqrt(min(1.0, srow[j] + crow[j] * scol[node - j * nx])))
        hcache[node] = hv
    return hv
