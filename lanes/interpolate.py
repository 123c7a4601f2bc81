"""Voyages resampled to a regular time step on great circles, with speed and course from the track.

AIS senders report every 2 s to 6 min, so a dense sender would outweigh a sparse one in any
density-based clustering. Each voyage is therefore resampled at ``step_s``: the position at a
grid time is the great-circle intermediate point [1] between the two fixes around it. Grid times
that fall in a gap longer than ``max_gap_s`` get no point (a straight line across hours of
silence is invented, not observed; it may cross land), so a voyage can have several runs.

Speed and course come from the resampled positions, over a window of ``course_window_s``
centred on the point (clamped at the ends of a run): the course is the initial great-circle
bearing from the point ``h`` steps before to the point ``h`` steps after, the speed is the path
length between them divided by the time. The window smooths GPS jitter and turns the sharp
corner at a waypoint into a gradual change of course, so that the motion-aware clustering of
:mod:`lanes.extract` follows a lane around its bends instead of cutting it there.

Before resampling, :func:`drop_position_jumps` removes fixes that imply impossible speeds
(the Ushant set has 1.4 % of steps above 50 kn, and runs of fixes thousands of nmi away).

References
----------
.. [1] E. Williams, "Aviation Formulary V1.47," 2011, "Intermediate points on a great circle".
       https://edwilliams.org/avform147.htm
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from lanes._geo import time_seconds
from thresholds.geodesy import haversine_nmi, initial_bearing_deg, intermediate_point
from thresholds.units import EARTH_RADIUS_NMI

POINT_COLUMNS = [
    "voyage", "track", "origin_port_id", "dest_port_id", "time_utc", "lat_deg", "lon_deg",
    "speed_kn", "course_deg", "run", "along_nmi",
]


@dataclass(frozen=True)
class ResampleParams:
    """Resampling parameters (units in the names)."""

    step_s: float = 300.0
    max_gap_s: float = 3600.0
    course_window_s: float = 1200.0

    def __post_init__(self):
        if not self.step_s > 0:
            raise ValueError(f"ResampleParams.step_s must be positive, got {self.step_s!r}")
        if self.max_gap_s < self.step_s:
            raise ValueError("ResampleParams.max_gap_s must be at least step_s")
        if self.course_window_s < 0:
            raise ValueError("ResampleParams.course_window_s must be non-negative")


def drop_position_jumps(pts: pd.DataFrame, max_speed_kn: float = 50.0, min_jump_nmi: float = 0.25,
                        id_col: str = "mmsi") -> tuple[pd.DataFrame, int]:
    """Remove fixes that are inconsistent with the rest of their track.

    A step between consecutive fixes is a jump when it implies more than ``max_speed_kn`` and
    moves more than ``min_jump_nmi`` (so that GPS jitter between fixes seconds apart is not a
    jump). Jumps cut a track into fragments; the first fix of the fragment with the most fixes
    is trusted. Walking away from it in both directions, each fix is kept only if it can be
    reached from the last kept fix at ``max_speed_kn`` (or lies within ``min_jump_nmi`` of it).
    An isolated bad fix, a stale position repeated after a gap (seen in the Ushant data), or a
    run of fixes on the other side of the world is dropped while the track around it stays whole.
    Tracks without a jump are not touched.

    ``pts`` must be sorted by track and time. Returns the kept rows (fresh index) and the number
    of dropped fixes.
    """
    n = len(pts)
    if n < 2:
        return pts.reset_index(drop=True), 0
    codes = pd.factorize(pts[id_col], sort=False)[0]
    t = time_seconds(pts["time_utc"])
    lat = pts["lat_deg"].to_numpy(dtype=float)
    lon = pts["lon_deg"].to_numpy(dtype=float)
    d = haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:])
    dt = t[1:] - t[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(dt > 0, d / (dt / 3600.0), np.where(d > 0, np.inf, 0.0))
    jump = (codes[1:] == codes[:-1]) & (v > max_speed_kn) & (d > min_jump_nmi)
    if not jump.any():
        return pts.reset_index(drop=True), 0
    track_start = np.flatnonzero(np.r_[True, codes[1:] != codes[:-1]])
    track_end = np.r_[track_start[1:], n]
    frag_start = np.r_[True, jump | (codes[1:] != codes[:-1])]
    starts = np.flatnonzero(frag_start)
    f_len = np.diff(np.r_[starts, n])
    f_code = codes[starts]
    # Trusted anchor per track with a jump: first fix of its longest fragment.
    bad_tracks = np.unique(codes[1:][jump])
    order = np.lexsort((-f_len, f_code))  # per track, longest fragment first
    first_of_track = order[np.r_[True, f_code[order][1:] != f_code[order][:-1]]]
    anchor_of = dict(zip(f_code[first_of_track], starts[first_of_track]))
    keep = np.ones(n, dtype=bool)
    lo = track_start[bad_tracks]
    hi = track_end[bad_tracks]
    anchors = np.array([anchor_of[c] for c in bad_tracks], dtype=np.int64)
    _walk_reachable(t, np.deg2rad(lat), np.deg2rad(lon), lo, hi, anchors, float(max_speed_kn), float(min_jump_nmi), keep)
    return pts[keep].reset_index(drop=True), int(n - keep.sum())


def _walk_reachable(t, lat_rad, lon_rad, lo, hi, anchors, max_speed_kn, min_jump_nmi, keep):
    """Sequential reachability filter of :func:`drop_position_jumps` (numba-compiled on first use)."""
    global _WALK
    if _WALK is None:
        _WALK = _compile_walk()
    _WALK(t, lat_rad, lon_rad, lo, hi, anchors, max_speed_kn, min_jump_nmi, EARTH_RADIUS_NMI, keep)


_WALK = None


def _compile_walk():
    import numba

    @numba.njit(cache=True)
    def walk(t, lat, lon, lo, hi, anchors, vmax, dmin, radius, keep):
        for k in range(lo.size):
            a = anchors[k]
            last = a
            for i in range(a + 1, hi[k]):
                s1 = np.sin((lat[i] - lat[last]) / 2.0)
                s2 = np.sin((lon[i] - lon[last]) / 2.0)
                h = s1 * s1 + np.cos(lat[last]) * np.cos(lat[i]) * s2 * s2
                d = 2.0 * radius * np.arcsin(np.sqrt(min(1.0, h)))
                dt = (t[i] - t[last]) / 3600.0
                if d <= dmin or (dt > 0 and d / dt <= vmax):
                    last = i
                else:
                    keep[i] = False
            last = a
            for i in range(a - 1, lo[k] - 1, -1):
                s1 = np.sin((lat[last] - lat[i]) / 2.0)
                s2 = np.sin((lon[last] - lon[i]) / 2.0)
                h = s1 * s1 + np.cos(lat[last]) * np.cos(lat[i]) * s2 * s2
                d = 2.0 * radius * np.arcsin(np.sqrt(min(1.0, h)))
                dt = (t[last] - t[i]) / 3600.0
                if d <= dmin or (dt > 0 and d / dt <= vmax):
                    last = i
                else:
                    keep[i] = False

    return walk


def resample_voyages(pts: pd.DataFrame, voyages: pd.DataFrame, params: ResampleParams | None = None) -> pd.DataFrame:
    """Regular-time-step points of every voyage.

    Parameters
    ----------
    pts : DataFrame
        Positions sorted by track and time (the frame ``voyages.first_row/last_row`` index).
    voyages : DataFrame
        Output of :func:`lanes.voyages.segment_voyages`.
    params : ResampleParams

    Returns
    -------
    DataFrame
        Columns :data:`POINT_COLUMNS`: ``voyage`` (the voyage id), ``track``, port ids, grid
        ``time_utc`` (multiples of ``step_s`` since 1970 UTC inside the voyage), position, ``speed_kn`` and
        ``course_deg`` from the resampled track (NaN for a run of one point), ``run`` (number of
        the gap-free run within the voyage) and ``along_nmi`` (distance sailed since departure
        along the resampled points, gaps bridged on the great circle).
    """
    # Long by design: one vectorised resampling of every voyage at once (grid, great-circle
    # interpolation, gap masks, speeds and courses) over the same flat arrays.
    params = params or ResampleParams()
    if len(voyages) == 0 or len(pts) == 0:
        return pd.DataFrame({c: pd.Series(dtype=object) for c in POINT_COLUMNS})
    t_all = time_seconds(pts["time_utc"])
    lat_all = pts["lat_deg"].to_numpy(dtype=float)
    lon_all = pts["lon_deg"].to_numpy(dtype=float)
    first = voyages["first_row"].to_numpy(dtype=np.int64)
    last = voyages["last_row"].to_numpy(dtype=np.int64)
    nv = first.size

    # Fixes of each voyage, concatenated (voyages may share their boundary fix).
    n_fix = last - first + 1
    v_of_fix = np.repeat(np.arange(nv), n_fix)
    fix_rows = np.arange(n_fix.sum()) - np.repeat(np.cumsum(n_fix) - n_fix, n_fix) + np.repeat(first, n_fix)
    ft = t_all[fix_rows]
    t0 = t_all[first]
    t1 = t_all[last]

    # Grid times per voyage: the multiples of step_s (since 1970-01-01 UTC) inside the voyage.
    # A common absolute grid keeps voyages that leave the same berth at the same speed from
    # being sampled at the same along-track places (their phases follow their departure times).
    g0 = np.ceil(t0 / params.step_s - 1e-9)
    g1 = np.floor(t1 / params.step_s + 1e-9)
    n_grid = np.maximum(0, (g1 - g0).astype(np.int64) + 1)
    v_of_grid = np.repeat(np.arange(nv), n_grid)
    k = np.arange(n_grid.sum()) - np.repeat(np.cumsum(n_grid) - n_grid, n_grid)
    gt = (g0[v_of_grid] + k) * params.step_s

    # Bracketing fixes via a combined (voyage, time) key.
    tmin = ft.min()
    span = (ft.max() - tmin) + 2.0 * params.step_s + 1.0
    fkey = v_of_fix * span + (ft - tmin)
    gkey = v_of_grid * span + (gt - tmin)
    left = np.searchsorted(fkey, gkey, side="right") - 1
    fix_end = np.cumsum(n_fix) - 1
    right = np.minimum(left + 1, fix_end[v_of_grid])
    dt = ft[right] - ft[left]
    ok = (dt <= params.max_gap_s)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(dt > 0, (gt - ft[left]) / dt, 0.0)
    lat, lon = intermediate_point(lat_all[fix_rows[left]], lon_all[fix_rows[left]],
                                  lat_all[fix_rows[right]], lon_all[fix_rows[right]], frac)
    lat = np.atleast_1d(lat)[ok]
    lon = np.atleast_1d(lon)[ok]
    gv = v_of_grid[ok]
    gk = k[ok]
    gt = gt[ok]
    m = gv.size
    if m == 0:
        return pd.DataFrame({c: pd.Series(dtype=object) for c in POINT_COLUMNS})

    # Runs: consecutive grid indices of one voyage.
    new_run = np.r_[True, (gv[1:] != gv[:-1]) | (gk[1:] != gk[:-1] + 1)]
    run_global = np.cumsum(new_run) - 1
    run_first = np.flatnonzero(new_run)
    run_last = np.r_[run_first[1:] - 1, m - 1]
    voyage_start = np.r_[True, gv[1:] != gv[:-1]]
    run_in_voyage = np.cumsum(new_run) - 1 - np.maximum.accumulate(np.where(voyage_start, np.cumsum(new_run) - 1, 0))

    step_d = np.r_[0.0, haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:])]
    step_d[voyage_start] = 0.0
    # distance along each voyage, summed voyage by voyage (not one running sum over every
    # voyage minus its start): the same bits whichever other tracks were read with it (the
    # lanes chain reads tracks in buckets); a loop over voyages, not over points
    cum = np.empty(m)
    starts = np.flatnonzero(voyage_start)
    for a, b in zip(starts, np.r_[starts[1:], m]):
        cum[a:b] = np.cumsum(step_d[a:b])
    along = cum

    h = max(1, int(round(params.course_window_s / 2.0 / params.step_s)))
    idx = np.arange(m)
    lo = np.maximum(idx - h, run_first[run_global])
    hi = np.minimum(idx + h, run_last[run_global])
    with np.errstate(invalid="ignore", divide="ignore"):
        speed = np.where(hi > lo, (cum[hi] - cum[lo]) / ((gt[hi] - gt[lo]) / 3600.0), np.nan)
    course = np.where(hi > lo, initial_bearing_deg(lat[lo], lon[lo], lat[hi], lon[hi]), np.nan)
    # A ship standing still has no course.
    course = np.where(cum[hi] - cum[lo] > 0, course, np.nan)

    vid = voyages["voyage_id"].to_numpy()
    out = pd.DataFrame({
        "voyage": vid[gv],
        "track": voyages["track"].to_numpy()[gv],
        "origin_port_id": voyages["origin_port_id"].to_numpy(dtype=np.int64)[gv],
        "dest_port_id": voyages["dest_port_id"].to_numpy(dtype=np.int64)[gv],
        "time_utc": pd.to_datetime(np.round(gt * 1e3).astype(np.int64), unit="ms", utc=True),
        "lat_deg": lat,
        "lon_deg": lon,
        "speed_kn": speed,
        "course_deg": course,
        "run": run_in_voyage.astype(np.int64),
        "along_nmi": along,
    })
    return out
