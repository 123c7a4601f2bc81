"""Shared pieces of the compiled router: parameter vector, great-circle geometry, the speed model,
weather at a node and in time, the 4-ary heap, and the weather-grid -> mesh gather.

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
