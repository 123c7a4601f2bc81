"""Stop points: where and when a vessel stood still, from its AIS positions.

A stop episode is a run of "stopped" fixes of one track. The navigational status is ignored on
purpose: berthed ferries keep reporting 0 = "under way using engine" while SOG is 0 (measured on
the New York harbour day: about 48 k of 82 k fixes say "under way", 63 % have SOG = 0), and
transponders at berth sometimes repeat a stale SOG. A fix is stopped when

* its SOG is below ``max_speed_kn`` **or** the speed implied by its positions over a window of
  ``window_s`` seconds is below ``max_speed_kn`` (a stale or noisy SOG at a berth), **and**
* the vessel did not move faster than ``moving_speed_kn`` both into and out of the fix
  (a SOG frozen at 0 while sailing; steps under ``radius_nmi`` are jitter, not motion).

Consecutive stopped fixes form one episode while they are at most ``max_gap_s`` apart, or while
the vessel has not moved more than ``radius_nmi`` across a longer silence (a berthed ship that
stops transmitting is still berthed). Episodes of one track that are close in time
(``merge_gap_s``) and place (``radius_nmi``) are merged, which absorbs single speed spikes from
GPS noise at a berth. Episodes shorter than ``min_duration_s`` or with fewer than ``min_fixes``
fixes are dropped.

References
----------
.. [1] G. Pallotta, M. Vespe and K. Bryan, "Vessel pattern knowledge discovery from AIS data: a
       framework for anomaly detection and route prediction," Entropy, vol. 15, no. 6,
       pp. 2218-2245, 2013, doi:10.3390/e15062218 (stationary points as SOG below a threshold
       for a minimum time; their clustering gives ports and waypoints).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from lanes._geo import run_starts, time_seconds
from thresholds.geodesy import haversine_nmi

STOP_COLUMNS = [
    "stop_id", "track", "start_utc", "end_utc", "duration_s", "lat_deg", "lon_deg",
    "n_fixes", "extent_nmi", "first_row", "last_row",
]


@dataclass(frozen=True)
class StopParams:
    """Thresholds of stop detection (units in the names)."""

    max_speed_kn: float = 0.5
    moving_speed_kn: float = 2.0
    window_s: float = 600.0
    max_gap_s: float = 1800.0
    radius_nmi: float = 0.1
    merge_gap_s: float = 900.0
    min_duration_s: float = 180.0
    min_fixes: int = 3

    def __post_init__(self):
        for name in ("max_speed_kn", "moving_speed_kn", "window_s", "radius_nmi"):
            if not getattr(self, name) > 0:
                raise ValueError(f"StopParams.{name} must be positive, got {getattr(self, name)!r}")
        if self.moving_speed_kn < self.max_speed_kn:
            raise ValueError("StopParams.moving_speed_kn must not be below max_speed_kn")
        if self.min_fixes < 1:
            raise ValueError("StopParams.min_fixes must be at least 1")


def sort_track_points(positions: pd.DataFrame, id_col: str = "mmsi") -> pd.DataFrame:
    """Positions sorted by track id and time, with a fresh 0..n-1 index; checks the columns."""
    missing = [c for c in (id_col, "time_utc", "lat_deg", "lon_deg") if c not in positions.columns]
    if missing:
        raise ValueError(f"positions lack the column(s) {missing}; expected the canonical AIS columns")
    if len(positions) == 0:
        return positions.reset_index(drop=True)
    ids = positions[id_col].to_numpy()
    t = time_seconds(positions["time_utc"])
    if positions[id_col].isna().any():
        raise ValueError(f"positions have missing values in the track id column {id_col!r}")
    ordered = bool(np.all((ids[1:] > ids[:-1]) | ((ids[1:] == ids[:-1]) & (t[1:] >= t[:-1])))) if len(ids) > 1 else True
    if ordered:
        return positions.reset_index(drop=True)
    return positions.sort_values([id_col, "time_utc"], kind="stable").reset_index(drop=True)


def window_speed_kn(track_codes: np.ndarray, t_s: np.ndarray, lat_deg: np.ndarray, lon_deg: np.ndarray,
                    window_s: float) -> np.ndarray:
    """Speed implied by the positions over a centred time window. [kn]

    For each fix, the displacement between the first fix at or after ``t - window/2`` and the
    last fix at or before ``t + window/2`` of the same track, divided by their time difference.
    NaN where the window holds less than half its length of data (track ends, gaps).
    Inputs must be sorted by track code, then time.
    """
    n = t_s.shape[0]
    if n == 0:
        return np.empty(0)
    t0 = t_s.min()
    span = (t_s.max() - t0) + 2.0 * window_s + 1.0
    key = track_codes.astype(float) * span + (t_s - t0)
    half = window_s / 2.0
    left = np.searchsorted(key, key - half, side="left")
    right = np.searchsorted(key, key + half, side="right") - 1
    dt = t_s[right] - t_s[left]
    same = (track_codes[left] == track_codes) & (track_codes[right] == track_codes)
    ok = same & (dt >= half)
    speed = np.full(n, np.nan)
    if ok.any():
        d = haversine_nmi(lat_deg[left[ok]], lon_deg[left[ok]], lat_deg[right[ok]], lon_deg[right[ok]])
        speed[ok] = d / (dt[ok] / 3600.0)
    return speed


def neighbour_speed_kn(track_codes: np.ndarray, t_s: np.ndarray, lat_deg: np.ndarray, lon_deg: np.ndarray,
                       min_move_nmi: float) -> np.ndarray:
    """Slower of the two implied speeds into and out of each fix. [kn]

    A fix is "moving" by its positions only when the vessel moved both to reach it and to leave
    it (steps shorter than ``min_move_nmi`` count as 0 kn: GPS jitter at a berth). The first and
    last fix of a track use their one neighbour; a lone fix gets NaN.
    """
    n = t_s.shape[0]
    out = np.full(n, np.nan)
    if n < 2:
        return out
    d = haversine_nmi(lat_deg[:-1], lon_deg[:-1], lat_deg[1:], lon_deg[1:])
    dt = t_s[1:] - t_s[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(d <= min_move_nmi, 0.0, np.where(dt > 0, d / (dt / 3600.0), np.inf))
    same = track_codes[1:] == track_codes[:-1]
    v = np.where(same, v, np.nan)
    v_in = np.r_[np.nan, v]
    v_out = np.r_[v, np.nan]
    return np.fmin(v_in, v_out)


def stopped_mask(sog_kn: np.ndarray, pos_speed_kn: np.ndarray, step_speed_kn: np.ndarray, params: StopParams) -> np.ndarray:
    """Which fixes are stopped (see the module docstring for the rule)."""
    sog_slow = np.isfinite(sog_kn) & (sog_kn < params.max_speed_kn)
    pos_slow = np.isfinite(pos_speed_kn) & (pos_speed_kn < params.max_speed_kn)
    pos_fast = np.isfinite(step_speed_kn) & (step_speed_kn > params.moving_speed_kn)
    return (sog_slow | pos_slow) & ~pos_fast


def detect_stops(positions: pd.DataFrame, params: StopParams | None = None, id_col: str = "mmsi") -> pd.DataFrame:
    """Stop episodes of every track.

    Parameters
    ----------
    positions : DataFrame
        Canonical AIS positions (``id_col``, ``time_utc``, ``lat_deg``, ``lon_deg``, ``sog_kn``);
        ``sog_kn`` may be missing or NaN, then the positions decide alone.
    params : StopParams
        Thresholds; defaults as in :class:`StopParams`.
    id_col : str
        Column identifying a track (an MMSI, or an anonymous trajectory id).

    Returns
    -------
    DataFrame
        One row per episode: ``stop_id`` (0..n-1), ``track`` (the id), ``start_utc``,
        ``end_utc``, ``duration_s``, ``lat_deg``/``lon_deg`` (median of the fixes), ``n_fixes``,
        ``extent_nmi`` (largest distance of a fix from the median), ``first_row``/``last_row``
        (row positions in ``sort_track_points(positions)``).

    Examples
    --------
    >>> import pandas as pd
    >>> t = pd.date_range("2025-01-01", periods=6, freq="2min", tz="UTC")
    >>> df = pd.DataFrame({"mmsi": 1, "time_utc": t, "lat_deg": 41.35, "lon_deg": 2.17, "sog_kn": 0.0})
    >>> detect_stops(df)[["track", "duration_s", "n_fixes"]].values.tolist()
    [[1, 600.0, 6]]
    """
    params = params or StopParams()
    pts = sort_track_points(positions, id_col)
    empty = pd.DataFrame({c: pd.Series(dtype=float) for c in STOP_COLUMNS})
    if len(pts) == 0:
        return empty
    codes = pd.factorize(pts[id_col], sort=False)[0].astype(np.int64)
    t = time_seconds(pts["time_utc"])
    lat = pts["lat_deg"].to_numpy(dtype=float)
    lon = pts["lon_deg"].to_numpy(dtype=float)
    sog = pts["sog_kn"].to_numpy(dtype=float) if "sog_kn" in pts.columns else np.full(len(pts), np.nan)

    pos_speed = window_speed_kn(codes, t, lat, lon, params.window_s)
    step_speed = neighbour_speed_kn(codes, t, lat, lon, params.radius_nmi)
    stopped = stopped_mask(sog, pos_speed, step_speed, params)
    rows = np.flatnonzero(stopped)
    if rows.size == 0:
        return empty

    # Link consecutive stopped fixes of one track into episodes.
    r_codes, r_t, r_lat, r_lon = codes[rows], t[rows], lat[rows], lon[rows]
    link = np.zeros(rows.size, dtype=bool)
    if rows.size > 1:
        same = r_codes[1:] == r_codes[:-1]
        adjacent = rows[1:] == rows[:-1] + 1  # no moving fix in between
        gap = r_t[1:] - r_t[:-1]
        moved = haversine_nmi(r_lat[:-1], r_lon[:-1], r_lat[1:], r_lon[1:])
        link[1:] = same & adjacent & ((gap <= params.max_gap_s) | (moved <= params.radius_nmi))
    episode = np.cumsum(~link) - 1

    ep = _aggregate(episode, rows, r_codes, r_t, r_lat, r_lon)

    # Merge episodes of one track separated by a short blip or silence without moving.
    if len(ep) > 1:
        same = ep["code"].to_numpy()[1:] == ep["code"].to_numpy()[:-1]
        gap = ep["start_s"].to_numpy()[1:] - ep["end_s"].to_numpy()[:-1]
        d = haversine_nmi(ep["lat"].to_numpy()[:-1], ep["lon"].to_numpy()[:-1], ep["lat"].to_numpy()[1:], ep["lon"].to_numpy()[1:])
        merge = np.concatenate([[False], same & (gap <= params.merge_gap_s) & (d <= params.radius_nmi)])
        if merge.any():
            group = np.cumsum(~merge) - 1
            episode = group[episode]
            ep = _aggregate(episode, rows, r_codes, r_t, r_lat, r_lon)

    keep = (ep["end_s"] - ep["start_s"] >= params.min_duration_s) & (ep["n_fixes"] >= params.min_fixes)
    ep = ep[keep].reset_index(drop=True)
    ids = pts[id_col].to_numpy()
    out = pd.DataFrame({
        "stop_id": np.arange(len(ep), dtype=np.int64),
        "track": ids[ep["first_row"].to_numpy()] if len(ep) else ids[:0],
        "start_utc": pts["time_utc"].iloc[ep["first_row"].to_numpy()].reset_index(drop=True),
        "end_utc": pts["time_utc"].iloc[ep["last_row"].to_numpy()].reset_index(drop=True),
        "duration_s": ep["end_s"].to_numpy() - ep["start_s"].to_numpy(),
        "lat_deg": ep["lat"].to_numpy(),
        "lon_deg": ep["lon"].to_numpy(),
        "n_fixes": ep["n_fixes"].to_numpy(dtype=np.int64),
        "extent_nmi": ep["extent"].to_numpy(),
        "first_row": ep["first_row"].to_numpy(dtype=np.int64),
        "last_row": ep["last_row"].to_numpy(dtype=np.int64),
    })
    for col in ("start_utc", "end_utc"):
        out[col] = pd.to_datetime(out[col], utc=True)
    return out


def _aggregate(episode, rows, r_codes, r_t, r_lat, r_lon) -> pd.DataFrame:
    """Per-episode summary of the stopped fixes (median position and its extent)."""
    frame = pd.DataFrame({"ep": episode, "row": rows, "code": r_codes, "t": r_t, "lat": r_lat, "lon": r_lon})
    g = frame.groupby("ep", sort=True)
    ep = pd.DataFrame({
        "code": g["code"].first(),
        "start_s": g["t"].min(),
        "end_s": g["t"].max(),
        "lat": g["lat"].median(),
        "lon": g["lon"].median(),
        "n_fixes": g["row"].size(),
        "first_row": g["row"].min(),
        "last_row": g["row"].max(),
    })
    d = haversine_nmi(r_lat, r_lon, ep["lat"].to_numpy()[episode], ep["lon"].to_numpy()[episode])
    ep["extent"] = pd.Series(d).groupby(episode).max().to_numpy()
    return ep.reset_index(drop=True)
