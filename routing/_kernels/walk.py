"""Compiled walk along any polyline through the weather: times, highest Hs, and (optionally) the
hours spent on pieces that touch an unsafe cell.
"""

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
    _bearing_cs,
    _haversine,
    _intermediate,
    _node_weather,
    _pace,
    _time_slot,
)
from routing._kernels.flags import _sector_bit, _segment_cells_unsafe, _slice_range


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
