"""Compiled walk along any polyline through the weather: times, highest Hs, and (optionally) the
hours spent on pieces that touch an unsafe cell.

A leg of the polyline is cut into ceil(L / max_piece) equal great-circle pieces; each piece is
timed exactly as the search times an edge (:func:`routing._kernels.edge.arrival`: the travel
time in the weather of the quarter-hour sub-slice nearest to the departure, the weather linear
in time between slices, and with ``wait`` the FIFO arrival, min over later departures), the
ends' weather read bilinearly over the sea nodes around them (the node values exactly at nodes,
so a grid path re-timed here equals the search's cost).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from routing._kernels.core import P_MIN_SOG, P_PACE_MIN, P_TIME_STEP, P_WAIT, _bearing_cs, _haversine, _intermediate
from routing._kernels.edge import arrival, frame_lon, sample_hs, sample_weights, time_slot
from routing._kernels.flags import _sector_bit, _segment_cells_unsafe, _slice_range
from routing._kernels.speed import ship_of


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
    hs,
    cur,
    has_cur,
    dt_h,
    n_times,
    p,
    radius,
):
    """Times [h since slice 0] at each vertex of a polyline, and the highest Hs met along it.

    Pieces are timed as described in the module docstring; ``hs`` (T, n_sea) is the significant
    wave height, read at both ends of every piece when the ship reaches its start.
    """
    times, hs_max, _, _ = _walk_path(
        lat_deg, lon_deg, t_start_h, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index, wave, hs, cur, has_cur,
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
    hs,
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
    slice from the one at or before the time the ship reaches the piece's start to the one at or
    after its arrival at the end (see :func:`routing._kernels.search_safe.astar_safe`). Returns
    ``(times, hs_max, exposure_h, horizon_hit)``, the exposure cumulated at each vertex.
    Longitudes are taken in the mesh's continuous frame (:func:`frame_lon`).
    """
    ship = ship_of(p)
    min_sog = p[P_MIN_SOG]
    step = p[P_TIME_STEP] > 0.5
    wait = p[P_WAIT] > 0.5
    pace_min = p[P_PACE_MIN]
    lon_mid = lon0 + 0.5 * (nx - 1) * dlon
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
                i0, i1, wt = time_slot(t, dt_h, n_times, step)
                a_lon = frame_lon(pa_lon / deg, lon_mid)
                b_lon = frame_lon(pb_lon / deg, lon_mid)
                swa = sample_weights(pa_lat / deg, a_lon, lat0, lon0, dlat, dlon, ny, nx, sea_index)
                swb = sample_weights(pb_lat / deg, b_lon, lat0, lon0, dlat, dlon, ny, nx, sea_index)
                hs_max = max(hs_max, sample_hs(swa, i0, i1, wt, hs), sample_hs(swb, i0, i1, wt, hs))
                dtp = arrival(ship, min_sog, pace_min, plen, t, swa, swb, wave, cur, has_cur, ch, sh, dt_h, n_times, step, wait) - t
                if use_safety:
                    k_lo, k_hi = _slice_range(t, t + dtp, dt_h, n_times)
                    if k_hi >= n_safe:
                        hit = True
                        k_hi = n_safe - 1
                    if _segment_cells_unsafe(
                        (a_lon - lon0) / dlon, (pa_lat / deg - lat0) / dlat, (b_lon - lon0) / dlon,
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
    wave, hs, cur, has_cur, dt_h, n_times, p, radius,
):  # fmt: skip
    """Compiled entry point of :func:`_eval_path`."""
    return _eval_path(
        lat_deg, lon_deg, t_start_h, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index,
        wave, hs, cur, has_cur, dt_h, n_times, p, radius,
    )  # fmt: skip


@njit(cache=True)
def walk_path_safety(
    lat_deg, lon_deg, t_start_h, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index,
    wave, hs, cur, has_cur, dt_h, n_times, p, radius, unsafe, sectors, exempt_a, exempt_b,
):  # fmt: skip
    """Compiled entry point of :func:`_walk_path` with the safety flags: (times, hs_max, exposure_h, horizon_hit)."""
    return _walk_path(
        lat_deg, lon_deg, t_start_h, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, sea_index,
        wave, hs, cur, has_cur, dt_h, n_times, p, radius, True, unsafe, sectors, exempt_a, exempt_b,
    )  # fmt: skip
