"""Port-to-port voyage segmentation with gap handling.

Each track is cut at its port calls: a voyage runs from the last fix of a call (departure) to
the first fix of the next call (arrival). Calls are the stop episodes that fall in a port or
waypoint cluster (:mod:`lanes.ports`); stops in no cluster (a ship waiting alone at sea) do not
end a voyage. Two consecutive calls at the same port are one call (a berth shift) unless the
vessel left the port area in between (more than ``loop_min_nmi`` beyond the port's radius), which
makes a loop voyage (an excursion, a pilot or bunker run).

The pieces of a track before its first call and after its last call are kept as partial voyages
(origin or destination unknown); a track with no call at all is one "transit" segment. Lane
extraction clusters the partial and transit segments together (see :mod:`lanes.extract`).

Gap handling (why a long silence does not always split). A gap between two fixes ``p1`` and
``p2`` of one voyage splits it only when the vessel *could have called somewhere* during the gap:
when for some known place ``P`` (a detected port or waypoint, or a port of the list)

    (d(p1, P) + d(P, p2)) / v_max + min_call_s <= dt,

with ``v_max`` the vessel's own fast speed (95th percentile of its SOG, times ``speed_margin``)
and ``min_call_s`` the shortest call that would have produced a stop. A ship crossing a strait
with its transponder off for 3 hours is still on the same voyage; a ship silent for 20 hours
near a port may have called there, so the voyage is split into a departure-only and an
arrival-only part and no port-to-port voyage is invented.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from lanes._geo import time_seconds
from thresholds.geodesy import haversine_nmi

VOYAGE_COLUMNS = [
    "voyage_id", "track", "origin_port_id", "dest_port_id", "depart_utc", "arrive_utc",
    "dist_nmi", "n_fixes", "max_gap_s", "kind", "first_row", "last_row",
]

#: Voyage kinds: both ends at different ports, both at the same port, one end only, no port.
KINDS = ("port_to_port", "loop", "departure", "arrival", "transit")


@dataclass(frozen=True)
class VoyageParams:
    """Parameters of voyage segmentation (units in the names)."""

    gap_check_s: float = 1800.0  # gaps shorter than this never split
    min_call_s: float = 1800.0  # shortest plausible port call (incl. manoeuvring)
    speed_margin: float = 1.2
    default_speed_kn: float = 20.0  # when a track has no usable SOG
    min_speed_kn: float = 5.0
    loop_min_nmi: float = 1.0
    min_fixes: int = 2
    min_dist_nmi: float = 0.0

    def __post_init__(self):
        if self.min_fixes < 2:
            raise ValueError("VoyageParams.min_fixes must be at least 2")
        if not (self.default_speed_kn > 0 and self.min_speed_kn > 0 and self.speed_margin > 0):
            raise ValueError("VoyageParams speeds and margin must be positive")


def _kind(origin: int, dest: int) -> str:
    if origin > 0 and dest > 0:
        return "loop" if origin == dest else "port_to_port"
    if origin > 0:
        return "departure"
    if dest > 0:
        return "arrival"
    return "transit"


def track_speed_kn(pts: pd.DataFrame, codes: np.ndarray, n_tracks: int, params: VoyageParams) -> np.ndarray:
    """Fast speed of each track: 95th percentile of its SOG times ``speed_margin``. [kn]"""
    speed = np.full(n_tracks, params.default_speed_kn)
    if "sog_kn" in pts.columns:
        sog = pts["sog_kn"].to_numpy(dtype=float)
        ok = np.isfinite(sog) & (sog > 0)
        if ok.any():
            q = pd.Series(sog[ok]).groupby(codes[ok]).quantile(0.95)
            speed[q.index.to_numpy()] = q.to_numpy() * params.speed_margin
    return np.maximum(speed, params.min_speed_kn)


def could_call(lat1, lon1, lat2, lon2, dt_s, speed_kn, place_lat, place_lon, min_call_s) -> np.ndarray:
    """For each gap, whether a call at one of the places fits in it (see the module docstring)."""
    out = np.zeros(np.size(lat1), dtype=bool)
    if out.size == 0 or np.size(place_lat) == 0:
        return out
    plat = np.asarray(place_lat, dtype=float)[None, :]
    plon = np.asarray(place_lon, dtype=float)[None, :]
    chunk = max(1, 2_000_000 // max(1, plat.size))
    for s in range(0, out.size, chunk):
        e = min(out.size, s + chunk)
        d = haversine_nmi(lat1[s:e, None], lon1[s:e, None], plat, plon) + haversine_nmi(plat, plon, lat2[s:e, None], lon2[s:e, None])
        need_s = d.min(axis=1) / speed_kn[s:e] * 3600.0 + min_call_s
        out[s:e] = need_s <= dt_s[s:e]
    return out


def segment_voyages(pts: pd.DataFrame, stops: pd.DataFrame, stop_port_id: np.ndarray,
                    places: pd.DataFrame | None = None, params: VoyageParams | None = None,
                    id_col: str = "mmsi", ports: pd.DataFrame | None = None) -> pd.DataFrame:
    """Cut every track into voyages between port calls.

    Parameters
    ----------
    pts : DataFrame
        Positions sorted by track and time (:func:`lanes.stops.sort_track_points`), the frame
        the stops' ``first_row``/``last_row`` refer to.
    stops : DataFrame
        Stop episodes (:func:`lanes.stops.detect_stops`).
    stop_port_id : ndarray
        Port id of each stop, 0 when the stop is in no cluster (:func:`lanes.ports.detect_ports`).
    places : DataFrame, optional
        ``lat_deg``, ``lon_deg`` of every place a vessel could call at (detected ports and the
        port list); used by the gap rule. Without places no gap ever splits.
    params : VoyageParams
    id_col : str
        Track id column.
    ports : DataFrame, optional
        ``port_id``, ``lat_deg``, ``lon_deg``, ``radius_nmi`` of the ports; a vessel left a port
        between two calls there when it went beyond ``radius_nmi + loop_min_nmi`` from its
        centroid (without it, from the first call's position).

    Returns
    -------
    DataFrame
        Columns :data:`VOYAGE_COLUMNS`; ``voyage_id`` is ``"<track>_<i>"``; port ids are 0 when
        unknown; ``first_row``/``last_row`` index ``pts`` (inclusive); ``dist_nmi`` is the length
        of the fixes' polyline; ``kind`` one of :data:`KINDS`.
    """
    # Long by design: one vectorised pass over every track whose steps (calls, gaps, loops,
    # kinds) share a dozen per-fix arrays; split, each step would take and return them all.
    params = params or VoyageParams()
    n = len(pts)
    if n == 0:
        return pd.DataFrame({c: pd.Series(dtype=object) for c in VOYAGE_COLUMNS})
    codes, uniq = pd.factorize(pts[id_col], sort=False)
    codes = codes.astype(np.int64)
    n_tracks = len(uniq)
    t = time_seconds(pts["time_utc"])
    lat = pts["lat_deg"].to_numpy(dtype=float)
    lon = pts["lon_deg"].to_numpy(dtype=float)
    track_first = np.flatnonzero(np.r_[True, codes[1:] != codes[:-1]])
    track_last = np.r_[track_first[1:] - 1, n - 1]

    # Port calls in track order; consecutive calls at one port merge unless the ship went away.
    calls = stops.assign(port_id=np.asarray(stop_port_id, dtype=np.int64))
    calls = calls[calls["port_id"] > 0].sort_values("first_row", kind="stable")
    c_first = calls["first_row"].to_numpy(dtype=np.int64)
    c_last = calls["last_row"].to_numpy(dtype=np.int64)
    c_port = calls["port_id"].to_numpy(dtype=np.int64)
    c_code = codes[c_first] if c_first.size else np.empty(0, dtype=np.int64)
    c_lat = calls["lat_deg"].to_numpy(dtype=float)
    c_lon = calls["lon_deg"].to_numpy(dtype=float)
    c_reach = np.full(c_first.size, params.loop_min_nmi)
    if ports is not None and len(ports) and c_first.size:
        p = ports.set_index("port_id")
        c_lat = p.loc[c_port, "lat_deg"].to_numpy(dtype=float)
        c_lon = p.loc[c_port, "lon_deg"].to_numpy(dtype=float)
        c_reach = p.loc[c_port, "radius_nmi"].to_numpy(dtype=float) + params.loop_min_nmi
    if c_first.size > 1:
        keep = np.ones(c_first.size, dtype=bool)
        i = 0
        for j in range(1, c_first.size):
            if c_code[j] == c_code[i] and c_port[j] == c_port[i]:
                between = slice(c_last[i], c_first[j] + 1)
                far = haversine_nmi(lat[between], lon[between], c_lat[i], c_lon[i])
                if far.size == 0 or far.max() <= c_reach[i]:
                    c_last[i] = c_last[j]
                    keep[j] = False
                    continue
            i = j
        c_first, c_last, c_port, c_code = c_first[keep], c_last[keep], c_port[keep], c_code[keep]

    # Raw segments: [track start | call end] -> [call start | track end].
    seg_first, seg_last, seg_origin, seg_dest = [], [], [], []
    call_idx_by_track = np.split(np.arange(c_first.size), np.flatnonzero(np.diff(c_code)) + 1) if c_first.size else []
    calls_of = {int(c_code[idx[0]]): idx for idx in call_idx_by_track if idx.size}
    for k in range(n_tracks):
        idx = calls_of.get(k)
        if idx is None:
            seg_first.append(track_first[k]); seg_last.append(track_last[k]); seg_origin.append(0); seg_dest.append(0)
            continue
        if c_first[idx[0]] > track_first[k]:
            seg_first.append(track_first[k]); seg_last.append(c_first[idx[0]]); seg_origin.append(0); seg_dest.append(c_port[idx[0]])
        for a, b in zip(idx[:-1], idx[1:]):
            seg_first.append(c_last[a]); seg_last.append(c_first[b]); seg_origin.append(c_port[a]); seg_dest.append(c_port[b])
        if c_last[idx[-1]] < track_last[k]:
            seg_first.append(c_last[idx[-1]]); seg_last.append(track_last[k]); seg_origin.append(c_port[idx[-1]]); seg_dest.append(0)
    seg_first = np.asarray(seg_first, dtype=np.int64)
    seg_last = np.asarray(seg_last, dtype=np.int64)
    seg_origin = np.asarray(seg_origin, dtype=np.int64)
    seg_dest = np.asarray(seg_dest, dtype=np.int64)

    # Gap rule: split a segment at every gap in which a call somewhere would have fitted.
    step_dt = np.diff(t)
    gap_rows = np.flatnonzero((step_dt > params.gap_check_s) & (codes[1:] == codes[:-1]))  # gap between r and r+1
    splits = np.empty(0, dtype=np.int64)
    if gap_rows.size and places is not None and len(places):
        speed = track_speed_kn(pts, codes, n_tracks, params)
        ok = could_call(lat[gap_rows], lon[gap_rows], lat[gap_rows + 1], lon[gap_rows + 1], step_dt[gap_rows],
                        speed[codes[gap_rows]], places["lat_deg"].to_numpy(dtype=float),
                        places["lon_deg"].to_numpy(dtype=float), params.min_call_s)
        splits = gap_rows[ok]
    if splits.size:
        # Map each split gap to the segment containing both of its fixes.
        order = np.argsort(seg_first, kind="stable")
        pos = np.searchsorted(seg_first[order], splits, side="right") - 1
        seg_of = order[np.clip(pos, 0, None)]
        inside = (pos >= 0) & (splits + 1 <= seg_last[seg_of])
        new_first, new_last, new_origin, new_dest = [], [], [], []
        split_by_seg: dict[int, list[int]] = {}
        for s, r in zip(seg_of[inside], splits[inside]):
            split_by_seg.setdefault(int(s), []).append(int(r))
        for s in range(seg_first.size):
            rows = split_by_seg.get(s)
            if not rows:
                new_first.append(seg_first[s]); new_last.append(seg_last[s]); new_origin.append(seg_origin[s]); new_dest.append(seg_dest[s])
                continue
            start = seg_first[s]
            origin = seg_origin[s]
            for r in sorted(rows):
                new_first.append(start); new_last.append(r); new_origin.append(origin); new_dest.append(0)
                start, origin = r + 1, 0
            new_first.append(start); new_last.append(seg_last[s]); new_origin.append(0); new_dest.append(seg_dest[s])
        seg_first = np.asarray(new_first, dtype=np.int64)
        seg_last = np.asarray(new_last, dtype=np.int64)
        seg_origin = np.asarray(new_origin, dtype=np.int64)
        seg_dest = np.asarray(new_dest, dtype=np.int64)

    # Lengths, gaps and filters.
    step_d = np.r_[haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]), 0.0] if n > 1 else np.zeros(1)
    # each voyage's own sum (not a difference of one running sum over every track): the same
    # bits whichever other tracks were read with it (the lanes chain reads tracks in buckets)
    dist = np.array([step_d[a:b].sum() if b > a else 0.0 for a, b in zip(seg_first, seg_last)], dtype=float)
    n_fix = seg_last - seg_first + 1
    step_dt_full = np.r_[step_dt, 0.0]
    max_gap = np.array([step_dt_full[a:b].max() if b > a else 0.0 for a, b in zip(seg_first, seg_last)]) if seg_first.size else np.empty(0)
    keep = (n_fix >= params.min_fixes) & (dist >= params.min_dist_nmi)
    seg_first, seg_last, seg_origin, seg_dest = seg_first[keep], seg_last[keep], seg_origin[keep], seg_dest[keep]
    dist, n_fix, max_gap = dist[keep], n_fix[keep], max_gap[keep]

    ids = pts[id_col].to_numpy()
    track_ids = ids[seg_first]
    counter = pd.Series(codes[seg_first]).groupby(codes[seg_first]).cumcount().to_numpy()
    times = pts["time_utc"]
    out = pd.DataFrame({
        "voyage_id": [f"{tid}_{i}" for tid, i in zip(track_ids, counter)],
        "track": track_ids,
        "origin_port_id": seg_origin,
        "dest_port_id": seg_dest,
        "depart_utc": times.iloc[seg_first].reset_index(drop=True),
        "arrive_utc": times.iloc[seg_last].reset_index(drop=True),
        "dist_nmi": dist,
        "n_fixes": n_fix.astype(np.int64),
        "max_gap_s": max_gap,
        "kind": [_kind(o, d) for o, d in zip(seg_origin, seg_dest)],
        "first_row": seg_first,
        "last_row": seg_last,
    })
    for col in ("depart_utc", "arrive_utc"):
        out[col] = pd.to_datetime(out[col], utc=True)
    return out
