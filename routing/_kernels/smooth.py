"""Compiled any-angle smoothing of a grid route that keeps the time-dependent cost (and exposure)."""

from __future__ import annotations

import numpy as np
from numba import njit

from routing._kernels.cells import _gc_leg_is_sea
from routing._kernels.walk import _walk_path


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
                wave, hs, cur, has_cur, dt_h, n_times, p, radius, use_safety, unsafe, sectors, exempt_a, exempt_b,
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
                wave, hs, cur, has_cur, dt_h, n_times, p, radius, use_safety, unsafe, sectors, exempt_a, exempt_b,
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
    ppd, has_px, sea_step_nmi, sea_index, wave, hs, cur, has_cur, dt_h, n_times, p, radius,
):  # fmt: skip
    """Indices of the waypoints kept by greedy any-angle smoothing (see :func:`_smooth`)."""
    return _smooth(
        lat_deg, lon_deg, raw_times, np.zeros(lat_deg.size), max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, cell_ok, cell_clean,
        ocean, px_r0, px_c0, ppd, has_px, sea_step_nmi, sea_index, wave, hs, cur, has_cur, dt_h, n_times, p, radius,
        False, np.zeros((1, 1), dtype=np.uint16), 1, -1, -1,
    )  # fmt: skip


@njit(cache=True)
def smooth_path_safe(
    lat_deg, lon_deg, raw_times, raw_exposure, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, cell_ok, cell_clean, ocean, px_r0,
    px_c0, ppd, has_px, sea_step_nmi, sea_index, wave, hs, cur, has_cur, dt_h, n_times, p, radius, unsafe, sectors, exempt_a, exempt_b,
):  # fmt: skip
    """:func:`smooth_path` whose direct legs are no more exposed to unsafe cells than the raw route (see :func:`_smooth`)."""
    return _smooth(
        lat_deg, lon_deg, raw_times, raw_exposure, max_piece_nmi, lat0, lon0, dlat, dlon, ny, nx, cell_ok, cell_clean, ocean,
        px_r0, px_c0, ppd, has_px, sea_step_nmi, sea_index, wave, hs, cur, has_cur, dt_h, n_times, p, radius,
        True, unsafe, sectors, exempt_a, exempt_b,
    )  # fmt: skip
