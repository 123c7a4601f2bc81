"""Compiled (numba) cores of the router: flat arrays in, flat arrays out, no Python objects.

* :func:`astar` — time-dependent A* / Dijkstra on a regular lat/lon mesh with a binary heap.
* :func:`eval_path` — times along any polyline through the same weather (re-timing).
* :func:`smooth_path` — any-angle smoothing that keeps the time-dependent cost.
* :func:`astar_safe`, :func:`smooth_path_safe`, :func:`walk_path_safety` — the same under the
  vessel's limits (per-cell, per-slice, per-heading-sector flags precomputed by
  :mod:`routing.safety`).
* :func:`segment_is_sea` — every mesh cell a segment crosses is sea.
* :func:`gather_bilinear_time` — weather grid -> mesh nodes.

The speed model here is the scalar twin of :mod:`routing.speed_loss` (same module constants,
cross-checked by tests). Encounter sectors are tested through cosines of the encounter angle
(``cos a = cos(wave_from) cos(heading) + sin(wave_from) sin(heading)``), which avoids an
``atan2`` per edge.

Units: lengths in nmi, times in hours relative to the weather's slice 0, speeds in kn.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from routing import speed_loss as sl
from thresholds.units import METRES_PER_FOOT

MODEL_CODES = {"none": 0, "bowditch": 1, "aertssen": 2, "khokhlov": 3}

_COS30 = math.cos(math.radians(30.0))
_COS45 = math.cos(math.radians(45.0))
_COS60 = math.cos(math.radians(60.0))
_COS150 = math.cos(math.radians(150.0))

# Per-run parameter vector (float64), unpacked into scalars at the top of each kernel; the
# published coefficients are module globals, which numba freezes into the compiled code.
P_MODEL, P_V0, P_FLOOR, P_LPP, P_DWT, P_PRINTED, P_MIN_SOG, P_TIME_STEP = 0, 1, 2, 3, 4, 5, 6, 7
N_PARAMS = 8

_FT = METRES_PER_FOOT
_BF_FOL = sl.BOWDITCH_F_FOLLOWING_KN_FT2
_BF_BEAM = sl.BOWDITCH_F_BEAM_KN_FT2
_BF_HEAD = sl.BOWDITCH_F_HEAD_KN_FT2
_KA, _KB, _KC = sl.KHOKHLOV_A, sl.KHOKHLOV_B, sl.KHOKHLOV_C
_HS_UP = np.array(sl.AERTSSEN_HS_UPPER_M, dtype=np.float64)
_AM = np.ascontiguousarray(sl.AERTSSEN_M, dtype=np.float64)
_AN = np.ascontiguousarray(sl.AERTSSEN_N, dtype=np.float64)


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


@njit(inline="always")
def speed_through_water(model, v0, floor, lpp, dwt, printed, hs, cosa, sina):
    """Attained speed [kn] for wave height hs [m] and encounter (cos a, sin a), 0 = head seas."""
    loss = 0.0
    if hs > 0.0:
        if model == 1:  # Bowditch: [1] Eq. A1.1, Table A1.1 of routing.speed_loss
            if printed:
                alpha = math.degrees(math.atan2(sina, cosa)) % 360.0
                theta = (alpha + 180.0) % 360.0
                if theta <= 45.0 or theta >= 270.0:
                    f = _BF_FOL
                elif theta >= 135.0 and theta <= 225.0:
                    f = _BF_HEAD
                else:
                    f = _BF_BEAM
            else:
                if cosa >= _COS45:
                    f = _BF_HEAD
                elif cosa <= -_COS45:
                    f = _BF_FOL
                else:
                    f = _BF_BEAM
            h_ft = hs / _FT
            loss = f * h_ft * h_ft
        elif model == 2:  # Aertssen: Eq. A1.2, Table A1.2
            if hs > _HS_UP[0]:
                if hs <= _HS_UP[1]:
                    col = 0
                elif hs <= _HS_UP[2]:
                    col = 1
                elif hs <= _HS_UP[3]:
                    col = 2
                else:
                    col = 3
                if cosa > _COS30:
                    sec = 0
                elif cosa > _COS60:
                    sec = 1
                elif cosa > _COS150:
                    sec = 2
                else:
                    sec = 3
                loss = (_AM[sec, col] / lpp + _AN[sec, col]) * v0 / 100.0
        elif model == 3:  # Khokhlov: Eq. A1.3
            c = cosa
            if c > 1.0:
                c = 1.0
            elif c < -1.0:
                c = -1.0
            theta = math.acos(c)
            loss = (_KA * hs - _KB * theta * hs) * (1.0 - _KC * dwt * v0)
    v = v0 - loss
    if floor > v0:
        floor = v0
    if v < floor:
        v = floor
    return v


@njit(inline="always")
def _pace(model, v0, floor, lpp, dwt, printed, min_sog, hs, wc, ws, cu, cv, has_cur, ch, sh):
    """Hours per nmi over ground for heading (cos, sin) in the given interpolated weather."""
    # Direction unknown (absent, or components cancelling out): head seas, the conservative case.
    n = math.sqrt(wc * wc + ws * ws)
    cosa = 1.0
    sina = 0.0
    if n > 1e-6:
        cosa = (wc * ch + ws * sh) / n
        sina = (ws * ch - wc * sh) / n
    v = speed_through_water(model, v0, floor, lpp, dwt, printed, hs, cosa, sina)
    if has_cur:
        along = cu * sh + cv * ch
        cross = cu * ch - cv * sh
        v2 = v * v - cross * cross
        sog = (math.sqrt(v2) if v2 > 0.0 else 0.0) + along
        if sog < min_sog:
            sog = min_sog
        return 1.0 / sog
    return 1.0 / v


@njit(inline="always")
def _time_slot(t_h, dt_h, n_times, step):
    """Slice index i0, next index i1 and weight for time t_h (hours since slice 0); held at the ends.

    ``step`` (SIMROUTE emulation only) uses the slice at or before t_h without interpolating.
    """
    x = t_h / dt_h
    if x <= 0.0 or n_times == 1:
        return 0, 0, 0.0
    i0 = int(math.floor(x))
    if i0 >= n_times - 1:
        return n_times - 1, n_times - 1, 0.0
    if step:
        return i0, i0, 0.0
    return i0, i0 + 1, x - i0


@njit(inline="always")
def _node_weather(s, i0, i1, wt, wave, cur, has_cur):
    """Hs, wave-direction components and current at sea node row s, interpolated in time.

    ``wave`` is (T, n_sea, 3) = (Hs, cos, sin of the direction waves come from), ``cur`` is
    (T, n_sea, 2) or a (1, 1, 2) array of zeros read at [0, 0] when there is no current (an
    unconditional load compiles to much faster code than a load under a runtime flag).
    """
    fc = 1 if has_cur else 0
    hs = wave[i0, s, 0] * (1.0 - wt) + wave[i1, s, 0] * wt
    wc = wave[i0, s, 1] * (1.0 - wt) + wave[i1, s, 1] * wt
    ws = wave[i0, s, 2] * (1.0 - wt) + wave[i1, s, 2] * wt
    cu = cur[i0 * fc, s * fc, 0] * (1.0 - wt) + cur[i1 * fc, s * fc, 0] * wt
    cv = cur[i0 * fc, s * fc, 1] * (1.0 - wt) + cur[i1 * fc, s * fc, 1] * wt
    return hs, wc, ws, cu, cv


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


# --------------------------------------------------------------------------- safety-constrained search
#
# ``unsafe`` is a (n_slices, n_sea) uint16 array: bit s of unsafe[k, row] is set when the vessel's
# limits are broken at that sea node in weather slice k for a course in heading sector s (sector s
# is centred on s * 360 / sectors degrees; see routing.safety). A cell is judged over every slice
# from the one at or before the time the ship enters the edge (piece) to the one at or after the
# time it leaves it, so a linear-in-time value between two passing slices passes too (Hs, wind).


@njit(inline="always")
def _sector_bit(ch, sh, sectors):
    """Bit of the heading sector of the course with cosine ``ch`` and sine ``sh``."""
    w = 360.0 / sectors
    theta = math.degrees(math.atan2(sh, ch))
    s = int(math.floor(((theta + 0.5 * w) % 360.0) / w))
    if s >= sectors:
        s = sectors - 1
    elif s < 0:
        s = 0
    return np.uint16(1 << s)


@njit(inline="always")
def _slice_range(ta, tb, dt_h, n_times):
    """Weather slices bracketing the time interval [ta, tb] (hours since slice 0), clamped."""
    if n_times == 1:
        return 0, 0
    lo = int(math.floor(ta / dt_h))
    hi = int(math.ceil(tb / dt_h))
    if lo < 0:
        lo = 0
    if lo > n_times - 1:
        lo = n_times - 1
    if hi > n_times - 1:
        hi = n_times - 1
    if hi < lo:
        hi = lo
    return lo, hi


@njit(inline="always")
def _row_unsafe(s, unsafe, k_lo, k_hi, bit):
    for kk in range(k_lo, k_hi + 1):
        if unsafe[kk, s] & bit:
            return True
    return False


@njit(inline="always")
def _stencil_cells_unsafe(iu, ju, k, cells, counts, ny, nx, sea_index, unsafe, k_lo, k_hi, bit, exempt_a, exempt_b):
    """True when a cell touched by stencil edge k from node (ju, iu) is unsafe (exempt nodes and
    cells without a weather row are skipped)."""
    for q in range(counts[k]):
        c = iu + cells[k, q, 0]
        r = ju + cells[k, q, 1]
        if r < 0 or r >= ny or c < 0 or c >= nx:
            continue
        node = r * nx + c
        if node == exempt_a or node == exempt_b:
            continue
        s = sea_index[node]
        if s < 0:
            continue
        if _row_unsafe(s, unsafe, k_lo, k_hi, bit):
            return True
    return False


@njit
def _segment_cells_unsafe(x0, y0, x1, y1, ny, nx, sea_index, unsafe, k_lo, k_hi, bit, exempt_a, exempt_b):
    """:func:`_stencil_cells_unsafe` for any index-space segment (closed squares, as :func:`_cells_ok`)."""
    xmin = min(x0, x1)
    xmax = max(x0, x1)
    eps = 1e-9
    c_lo = int(math.ceil(xmin - 0.5 - eps))
    c_hi = int(math.floor(xmax + 0.5 + eps))
    for c in range(c_lo, c_hi + 1):
        if c < 0 or c >= nx:
            continue
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
                continue
            node = r * nx + c
            if node == exempt_a or node == exempt_b:
                continue
            s = sea_index[node]
            if s < 0:
                continue
            if _row_unsafe(s, unsafe, k_lo, k_hi, bit):
                return True
    return False


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


@njit(inline="always")
def _sample(lat, lon, lat0, lon0, dlat, dlon, ny, nx, sea_index, i0, i1, wt, wave, cur, has_cur):
    """Bilinear weather at (lat, lon) [deg] over the sea nodes around it, at slot (i0, i1, wt)."""
    y = (lat - lat0) / dlat
    x = (lon - lon0) / dlon
    ry = round(y)
    rx = round(x)
    if abs(y - ry) < 1e-7:
        y = ry
    if abs(x - rx) < 1e-7:
        x = rx
    j0 = int(math.floor(y))
    i0x = int(math.floor(x))
    if j0 < 0:
        j0 = 0
    if j0 > ny - 2:
        j0 = ny - 2
    if i0x < 0:
        i0x = 0
    if i0x > nx - 2:
        i0x = nx - 2
    fy = y - j0
    fx = x - i0x
    if fy < 0.0:
        fy = 0.0
    if fy > 1.0:
        fy = 1.0
    if fx < 0.0:
        fx = 0.0
    if fx > 1.0:
        fx = 1.0
    wsum = 0.0
    hs = 0.0
    wc = 0.0
    ws = 0.0
    cu = 0.0
    cv = 0.0
    for q in range(4):
        jj = j0 + (q >> 1)
        ii = i0x + (q & 1)
        w = (fy if (q >> 1) else 1.0 - fy) * (fx if (q & 1) else 1.0 - fx)
        if w <= 0.0:
            continue
        s = sea_index[jj * nx + ii]
        if s < 0:
            continue
        wsum += w
        h1, c1, s1, u1, v1 = _node_weather(s, i0, i1, wt, wave, cur, has_cur)
        hs += w * h1
        wc += w * c1
        ws += w * s1
        cu += w * u1
        cv += w * v1
    if wsum > 0.0:
        hs /= wsum
        wc /= wsum
        ws /= wsum
        cu /= wsum
        cv /= wsum
    return hs, wc, ws, cu, cv


@njit
def _eval_path(
    lat_deg,
    lon_deg,
    t_start_h,
    max_piece_nmi,
    lat0,
    lon0,
    dlat,
    dlon,
    ny,
    nx,
    sea_index,
    wave,
    cur,
    has_cur,
    dt_h,
    n_times,
    p,
    radius,
):
    """Times [h since slice 0] at each vertex of a polyline, and the highest Hs met along it.

    Each leg is split into ceil(L / max_piece_nmi) equal great-circle pieces; each piece takes
    ``len * (pace(start) + pace(end)) / 2`` in the weather at the time the ship reaches the
    piece's start, bilinear in space over sea nodes (exactly the node values at nodes, so a
    grid path re-timed here equals the A* cost).
    """
    times, hs_max, _, _ = _walk_path(
        lat_deg, lon_deg, t_start_h, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index, wave, cur, has_cur,
        dt_h, n_times, p, radius, False, np.zeros((1, 1), dtype=np.uint16), 1, -1, -1,
    )  # fmt: skip
    return times, hs_max


@njit
def _walk_path(
    lat_deg,
    lon_deg,
    t_start_h,
    max_piece_nmi,
    lat0,
    lon0,
    dlat,
    dlon,
    ny,
    nx,
    sea_index,
    wave,
    cur,
    has_cur,
    dt_h,
    n_times,
    p,
    radius,
    use_safety,
    unsafe,
    sectors,
    exempt_a,
    exempt_b,
):
    """:func:`_eval_path`, plus (``use_safety``) the hours spent on pieces that touch an unsafe cell.

    A piece is unsafe when a mesh cell its index-space segment touches (closed squares, as the
    search's stencil cells) is flagged in ``unsafe`` for the piece's heading sector in any weather
    slice from the one at or before the piece's start time to the one at or after its end time
    (see :func:`astar_safe`). Returns ``(times, hs_max, exposure_h, horizon_hit)``, the exposure
    cumulated at each vertex.
    """
    model = int(p[P_MODEL])
    v0 = p[P_V0]
    floor = p[P_FLOOR]
    lpp = p[P_LPP]
    dwt = p[P_DWT]
    printed = p[P_PRINTED] > 0.5
    min_sog = p[P_MIN_SOG]
    step = p[P_TIME_STEP] > 0.5
    n = lat_deg.size
    times = np.empty(n)
    times[0] = t_start_h
    t = t_start_h
    hs_max = 0.0
    exposure = 0.0
    cum = np.zeros(n)
    hit = False
    n_safe = unsafe.shape[0]
    deg = math.pi / 180.0
    for leg in range(n - 1):
        la1 = lat_deg[leg] * deg
        lo1 = lon_deg[leg] * deg
        la2 = lat_deg[leg + 1] * deg
        lo2 = lon_deg[leg + 1] * deg
        L = _haversine(la1, lo1, la2, lo2, radius)
        if L > 0.0:
            npieces = int(math.ceil(L / max_piece_nmi - 1e-9))
            if npieces < 1:
                npieces = 1
            plen = L / npieces
            pa_lat, pa_lon = la1, lo1
            for q in range(npieces):
                if q == npieces - 1:
                    pb_lat, pb_lon = la2, lo2
                else:
                    pb_lat, pb_lon = _intermediate(la1, lo1, la2, lo2, (q + 1.0) / npieces)
                ch, sh = _bearing_cs(pa_lat, pa_lon, pb_lat, pb_lon)
                i0, i1, wt = _time_slot(t, dt_h, n_times, step)
                hs1, wc1, ws1, cu1, cv1 = _sample(
                    pa_lat / deg, pa_lon / deg, lat0, lon0, dlat, dlon, ny, nx, sea_index, i0, i1, wt,
                    wave, cur, has_cur,
                )  # fmt: skip
                hs2, wc2, ws2, cu2, cv2 = _sample(
                    pb_lat / deg, pb_lon / deg, lat0, lon0, dlat, dlon, ny, nx, sea_index, i0, i1, wt,
                    wave, cur, has_cur,
                )  # fmt: skip
                hs_max = max(hs_max, hs1, hs2)
                dtp = plen * _pace(
                    model, v0, floor, lpp, dwt, printed, min_sog, 0.5 * (hs1 + hs2), 0.5 * (wc1 + wc2),
                    0.5 * (ws1 + ws2), 0.5 * (cu1 + cu2), 0.5 * (cv1 + cv2), has_cur, ch, sh,
                )  # fmt: skip
                if use_safety:
                    k_lo, k_hi = _slice_range(t, t + dtp, dt_h, n_times)
                    if k_hi >= n_safe:
                        hit = True
                        k_hi = n_safe - 1
                    if _segment_cells_unsafe(
                        (pa_lon / deg - lon0) / dlon, (pa_lat / deg - lat0) / dlat, (pb_lon / deg - lon0) / dlon,
                        (pb_lat / deg - lat0) / dlat, ny, nx, sea_index, unsafe, k_lo, k_hi, _sector_bit(ch, sh, sectors),
                        exempt_a, exempt_b,
                    ):  # fmt: skip
                        exposure += dtp
                t += dtp
                pa_lat, pa_lon = pb_lat, pb_lon
        times[leg + 1] = t
        cum[leg + 1] = exposure
    return times, hs_max, cum, hit


@njit
def _segment_cells_sea(x0, y0, x1, y1, sea):
    """True when every mesh cell whose closed square the index-space segment touches is sea.

    Cell (r, c) is the square [c - 1/2, c + 1/2] x [r - 1/2, r + 1/2] around node (r, c);
    touching a corner counts (conservative). Cells outside the mesh count as land.
    """
    ny, nx = sea.shape
    xmin = min(x0, x1)
    xmax = max(x0, x1)
    eps = 1e-9
    c_lo = int(math.ceil(xmin - 0.5 - eps))
    c_hi = int(math.floor(xmax + 0.5 + eps))
    for c in range(c_lo, c_hi + 1):
        if c < 0 or c >= nx:
            return False
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
                return False
            if not sea[r, c]:
                return False
    return True


@njit
def _pixels_ocean(lat1, lon1, lat2, lon2, ocean, px_r0, px_c0, ppd):
    """True when the straight pixel-space segment between two points touches only ocean pixels."""
    x0 = (lon1 + 180.0) * ppd - px_c0 - 0.5
    y0 = (90.0 - lat1) * ppd - px_r0 - 0.5
    x1 = (lon2 + 180.0) * ppd - px_c0 - 0.5
    y1 = (90.0 - lat2) * ppd - px_r0 - 0.5
    return _segment_cells_sea(x0, y0, x1, y1, ocean)


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

    Checked in great-circle pieces of at most ``step_nmi``; pieces in land-free cells skip the
    pixel traversal.
    """
    deg = math.pi / 180.0
    la1 = lat1 * deg
    lo1 = lon1 * deg
    la2 = lat2 * deg
    lo2 = lon2 * deg
    L = _haversine(la1, lo1, la2, lo2, radius)
    n = int(math.ceil(L / step_nmi))
    if n < 1:
        n = 1
    alat, alon = lat1, lon1
    for q in range(n):
        if q == n - 1:
            blat, blon = lat2, lon2
        else:
            pl, po = _intermediate(la1, lo1, la2, lo2, (q + 1.0) / n)
            blat, blon = pl / deg, po / deg
        ok, clean = _cells_ok(
            (alon - lon0) / dlon, (alat - lat0) / dlat, (blon - lon0) / dlon, (blat - lat0) / dlat, cell_ok, cell_clean
        )
        if not ok:
            return False
        if has_px and not clean:
            if not _pixels_ocean(alat, alon, blat, blon, ocean, px_r0, px_c0, ppd):
                return False
        alat, alon = blat, blon
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
                        if not _pixels_ocean(
                            lat0 + j * dlat, lon0 + i * dlon, lat0 + j2 * dlat, lon0 + i2 * dlon, ocean, px_r0, px_c0, ppd
                        ):
                            continue
                bits |= np.uint64(1) << np.uint64(k)
            out[j * nx + i] = bits
    return out


@njit
def _smooth(
    lat_deg,
    lon_deg,
    raw_times,
    raw_exposure,
    max_piece_nmi,
    lat0,
    lon0,
    dlat,
    dlon,
    ny,
    nx,
    cell_ok,
    cell_clean,
    ocean,
    px_r0,
    px_c0,
    ppd,
    has_px,
    sea_step_nmi,
    sea_index,
    wave,
    cur,
    has_cur,
    dt_h,
    n_times,
    p,
    radius,
    use_safety,
    unsafe,
    sectors,
    exempt_a,
    exempt_b,
):
    """Indices of the waypoints kept by greedy any-angle smoothing.

    From each kept waypoint i (reached at time t_i <= raw_times[i]) the direct great-circle leg
    to a later waypoint j replaces the path between them when it crosses only sea cells and
    arrives no later than the raw route did (t_i + leg <= raw_times[j]); j is pushed forward
    until the first failure. Arrival at every kept waypoint, the goal included, is therefore
    never later than on the raw route. With ``use_safety`` a direct leg must also keep the hours
    spent in unsafe cells (:func:`_walk_path`, at its own times) at or below the raw route's up to
    j (``raw_exposure``, cumulated per waypoint; all zeros for a route that keeps within the
    limits, whose direct legs must then touch no unsafe cell). A raw leg kept is re-timed but not
    re-judged (the caller compares the smoothed and the raw route's exposure).
    """
    n = lat_deg.size
    keep = np.empty(n, dtype=np.int64)
    nk = 0
    keep[nk] = 0
    nk += 1
    i = 0
    t_i = raw_times[0]
    e_i = 0.0
    two_lat = np.empty(2)
    two_lon = np.empty(2)
    while i < n - 1:
        best = i + 1
        best_t = -1.0
        best_e = 0.0
        j = i + 2
        while j < n:
            if not _gc_leg_is_sea(
                lat_deg[i], lon_deg[i], lat_deg[j], lon_deg[j], lat0, lon0, dlat, dlon,
                cell_ok, cell_clean, ocean, px_r0, px_c0, ppd, has_px, sea_step_nmi, radius,
            ):  # fmt: skip
                break
            two_lat[0] = lat_deg[i]
            two_lat[1] = lat_deg[j]
            two_lon[0] = lon_deg[i]
            two_lon[1] = lon_deg[j]
            tt, _, ex, _ = _walk_path(
                two_lat, two_lon, t_i, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index,
                wave, cur, has_cur, dt_h, n_times, p, radius, use_safety, unsafe, sectors, exempt_a, exempt_b,
            )  # fmt: skip
            if tt[1] <= raw_times[j] + 1e-9 and e_i + ex[1] <= raw_exposure[j] + 1e-9:
                best = j
                best_t = tt[1]
                best_e = e_i + ex[1]
                j += 1
            else:
                break
        if best_t < 0.0:
            two_lat[0] = lat_deg[i]
            two_lat[1] = lat_deg[best]
            two_lon[0] = lon_deg[i]
            two_lon[1] = lon_deg[best]
            tt, _, ex, _ = _walk_path(
                two_lat, two_lon, t_i, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index,
                wave, cur, has_cur, dt_h, n_times, p, radius, use_safety, unsafe, sectors, exempt_a, exempt_b,
            )  # fmt: skip
            best_t = tt[1]
            best_e = e_i + ex[1]
        keep[nk] = best
        nk += 1
        i = best
        t_i = best_t
        e_i = best_e
    return keep[:nk]


@njit(cache=True)
def smooth_path(
    lat_deg, lon_deg, raw_times, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, cell_ok, cell_clean, ocean, px_r0, px_c0,
    ppd, has_px, sea_step_nmi, sea_index, wave, cur, has_cur, dt_h, n_times, p, radius,
):  # fmt: skip
    """Indices of the waypoints kept by greedy any-angle smoothing (see :func:`_smooth`)."""
    return _smooth(
        lat_deg, lon_deg, raw_times, np.zeros(lat_deg.size), max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, cell_ok, cell_clean,
        ocean, px_r0, px_c0, ppd, has_px, sea_step_nmi, sea_index, wave, cur, has_cur, dt_h, n_times, p, radius,
        False, np.zeros((1, 1), dtype=np.uint16), 1, -1, -1,
    )  # fmt: skip


@njit(cache=True)
def smooth_path_safe(
    lat_deg, lon_deg, raw_times, raw_exposure, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, cell_ok, cell_clean, ocean, px_r0,
    px_c0, ppd, has_px, sea_step_nmi, sea_index, wave, cur, has_cur, dt_h, n_times, p, radius, unsafe, sectors, exempt_a, exempt_b,
):  # fmt: skip
    """:func:`smooth_path` whose direct legs are no more exposed to unsafe cells than the raw route (see :func:`_smooth`)."""
    return _smooth(
        lat_deg, lon_deg, raw_times, raw_exposure, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, cell_ok, cell_clean, ocean,
        px_r0, px_c0, ppd, has_px, sea_step_nmi, sea_index, wave, cur, has_cur, dt_h, n_times, p, radius,
        True, unsafe, sectors, exempt_a, exempt_b,
    )  # fmt: skip


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


@njit(cache=True)
def eval_path(
    lat_deg, lon_deg, t_start_h, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index,
    wave, cur, has_cur, dt_h, n_times, p, radius,
):  # fmt: skip
    """Compiled entry point of :func:`_eval_path`."""
    return _eval_path(
        lat_deg, lon_deg, t_start_h, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index,
        wave, cur, has_cur, dt_h, n_times, p, radius,
    )  # fmt: skip


@njit(cache=True)
def walk_path_safety(
    lat_deg, lon_deg, t_start_h, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index,
    wave, cur, has_cur, dt_h, n_times, p, radius, unsafe, sectors, exempt_a, exempt_b,
):  # fmt: skip
    """Compiled entry point of :func:`_walk_path` with the safety flags: (times, hs_max, exposure_h, horizon_hit)."""
    return _walk_path(
        lat_deg, lon_deg, t_start_h, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index,
        wave, cur, has_cur, dt_h, n_times, p, radius, True, unsafe, sectors, exempt_a, exempt_b,
    )  # fmt: skip


@njit(cache=True)
def heading_flags(hs, wf_deg, period_s, headings_deg, members, p, beam_lo, beam_hi, beam_gate, use_beam, imo_gate, use_imo,
                  surf_num, use_surf, tr_s, roll_tol, use_roll):  # fmt: skip
    """Heading-sector bits of the heading-dependent rules, the compiled twin of
    :func:`thresholds.safety.assess` restricted to them (cross-checked by tests).

    For every element e and sample heading h_j: encounter α = (wf − h_j) mod 360 (0 = head seas);
    beam seas: α in a closed range [beam_lo, beam_hi] (operator limits, where Hs ≥ beam_gate when
    that is > 0); IMO MSC.1/Circ.1228 (where Hs ≥ imo_gate when > 0): surf-riding
    135° < α < 225° and V > surf_num / cos(180° − α) (surf_num = 1.8·√L), synchronous and
    parametric roll |k·T_E − T_R| ≤ ε·T_R for k = 1, 2 with T_E = 3T² / |3T + V cos α|; V is the
    speed through the water on that heading (:func:`speed_through_water`, parameters ``p``).
    Bit s of the result is set when a rule fires at one of the headings ``members[s]``; the
    samples of a sector are judged until one fires.
    """
    model = int(p[P_MODEL])
    v0 = p[P_V0]
    floor = p[P_FLOOR]
    lpp = p[P_LPP]
    dwt = p[P_DWT]
    printed = p[P_PRINTED] > 0.5
    m = hs.size
    H = headings_deg.size
    S = members.shape[0]
    Q = members.shape[1]
    nr = beam_lo.size
    out = np.zeros(m, dtype=np.uint16)
    state = np.zeros(H, dtype=np.int8)  # 0 not judged yet, 1 fires, 2 passes
    ch = np.empty(H)
    sh = np.empty(H)
    for j in range(H):
        ch[j] = math.cos(math.radians(headings_deg[j]))
        sh[j] = math.sin(math.radians(headings_deg[j]))
    band = roll_tol * tr_s
    for e in range(m):
        h = hs[e]
        beam_ok = use_beam and (beam_gate <= 0.0 or h >= beam_gate)
        imo_ok = use_imo and (imo_gate <= 0.0 or h >= imo_gate)
        if not (beam_ok or imo_ok):
            continue
        wf = wf_deg[e]
        cw = math.cos(math.radians(wf))
        sw = math.sin(math.radians(wf))
        t = period_s[e]
        t3 = 3.0 * t
        tt3 = 3.0 * t * t
        state[:] = 0
        bits = 0
        for s in range(S):
            for q in range(Q):
                j = members[s, q]
                if state[j] == 0:
                    a = wf - headings_deg[j]
                    if a < 0.0:
                        a += 360.0
                    f = False
                    if beam_ok:
                        for r in range(nr):
                            if a >= beam_lo[r] and a <= beam_hi[r]:
                                f = True
                                break
                    if not f and imo_ok:
                        ca = cw * ch[j] + sw * sh[j]  # cos and sin of the encounter angle wf - h
                        sa = sw * ch[j] - cw * sh[j]
                        v = speed_through_water(model, v0, floor, lpp, dwt, printed, h, ca, sa)
                        if use_surf and a > 135.0 and a < 225.0 and v * -ca > surf_num:  # cos(180 - a) = -cos a > 0
                            f = True
                        if not f and use_roll:
                            d = abs(t3 + v * ca)  # T_E = 3T^2 / d; |k T_E - T_R| <= eps T_R, times d
                            if d > 0.0 and (abs(tt3 - tr_s * d) <= band * d or abs(2.0 * tt3 - tr_s * d) <= band * d):
                                f = True
                    state[j] = 1 if f else 2
                if state[j] == 1:
                    bits |= 1 << s
                    break
        out[e] = bits
    return out
