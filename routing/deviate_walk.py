"""The walk of the cargo-safe deviation (Algorithm 1 of [1]_, as improved in :mod:`routing.deviate`).

:class:`Walk` holds the walk's state (current position, time, progress along the lane, the steps
taken) and advances it one adverse step at a time; :class:`Judge` looks the weather up and applies
the thresholds to many points or legs at once; :class:`LaneAlong` measures progress along the lane;
:func:`least_adverse` is the fall-back when no passing cell is in reach. Every behaviour is
described (and its reason given) in :mod:`routing.deviate`'s docstring.

References
----------
.. [1] K. Spyrou-Sioula et al., "AIS-enabled weather routing for cargo loss prevention," J. Mar.
       Sci. Eng., vol. 10, no. 11, 1755, 2022, doi:10.3390/jmse10111755, §3.3 and Algorithm 1.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from thresholds.geodesy import haversine_nmi, initial_bearing_deg, intermediate_point

log = logging.getLogger("routing.deviate")


@dataclass
class DeviationStep:
    """What happened at one waypoint of the deviation (kept for reports and tests)."""

    seq: int
    status: str  # "endpoint", "lane", "deviated", "unresolved"
    centroid_lat_deg: float
    centroid_lon_deg: float
    lat_deg: float
    lon_deg: float
    time_utc: pd.Timestamp
    speed_kn: float
    rules_fired: list = field(default_factory=list)
    moved_nmi: float = 0.0
    candidates_tried: int = 0
    leg_rules_fired: list = field(default_factory=list)


class LaneAlong:
    """Distance along a lane's centroid polyline of the nearest point of the polyline. [nmi]

    Local equirectangular frame about the lane's mean latitude (the lanes are a few hundred nmi
    at most; the frame only ranks positions along the lane).
    """

    def __init__(self, lat, lon):
        self.cos0 = float(np.cos(np.deg2rad(np.mean(lat))))
        self.x = np.asarray(lon, dtype=float) * self.cos0 * 60.0
        self.y = np.asarray(lat, dtype=float) * 60.0
        seg = np.hypot(np.diff(self.x), np.diff(self.y))
        self.seg = np.where(seg > 0, seg, 1e-12)
        self.cum_nmi = np.concatenate([[0.0], np.cumsum(seg)])

    def along(self, lat, lon) -> np.ndarray:
        px = np.asarray(lon, dtype=float).reshape(-1, 1) * self.cos0 * 60.0
        py = np.asarray(lat, dtype=float).reshape(-1, 1) * 60.0
        x0, y0, dx, dy = self.x[:-1], self.y[:-1], np.diff(self.x), np.diff(self.y)
        t = np.clip(((px - x0) * dx + (py - y0) * dy) / self.seg**2, 0.0, 1.0)
        d2 = (x0 + t * dx - px) ** 2 + (y0 + t * dy - py) ** 2
        j = np.argmin(d2, axis=1)
        rows = np.arange(px.shape[0])
        return self.cum_nmi[j] + t[rows, j] * self.seg[j]


def least_adverse(judge, cells, lane_along, cur_lat, cur_lon, cur_ns, cur_along, tgt_lat, tgt_lon, next_lat, next_lon,
                   speed_kn, radius_nmi, n_rules_target, hs_target, at_sea, max_tries: int = 30):
    """The reachable grid cell ahead with the fewest rules fired, then the lowest Hs, when it is
    clearly better than the lane centroid (fewer rules, or Hs lower by >= 0.25 m); else None."""
    ny, nx = cells.lat_deg.size, cells.lon_deg.size
    dlat = radius_nmi / 60.0
    dlon = dlat / max(np.cos(np.deg2rad(tgt_lat)), 1e-3)
    jj = np.flatnonzero(np.abs(cells.lat_deg - tgt_lat) <= dlat)
    ii = np.flatnonzero(np.abs(cells.lon_deg - tgt_lon) <= dlon)
    stride = max(1, int(np.ceil(np.sqrt(jj.size * ii.size / 200.0))))  # at most ~200 cells judged
    jj, ii = jj[::stride], ii[::stride]
    if jj.size == 0 or ii.size == 0 or ny == 0 or nx == 0:
        return None
    la = np.repeat(cells.lat_deg[jj], ii.size)
    lo = np.tile(cells.lon_deg[ii], jj.size)
    dist = np.asarray(haversine_nmi(tgt_lat, tgt_lon, la, lo), dtype=float).reshape(-1)
    keep = (dist <= radius_nmi) & (lane_along.along(la, lo) > cur_along + 1e-6)
    la, lo, dist = la[keep], lo[keep], dist[keep]
    dc = np.asarray(haversine_nmi(cur_lat, cur_lon, la, lo), dtype=float).reshape(-1)
    keep = dc > 0
    la, lo, dist, dc = la[keep], lo[keep], dist[keep], dc[keep]
    if la.size == 0:
        return None
    eta = cur_ns + np.round(dc / speed_kn * 3.6e12).astype(np.int64)
    hdg = np.asarray(initial_bearing_deg(cur_lat, cur_lon, la, lo), dtype=float).reshape(-1)
    w, fired = judge.points(eta, la, lo, hdg, np.full(la.size, speed_kn))
    hs = w.get("hs_m", np.full(la.size, np.nan))
    n_rules = np.array([len(f) for f in fired])
    hs_key = np.where(np.isfinite(hs), hs, np.inf)
    order = np.lexsort((dist, hs_key, n_rules))
    hs_t = hs_target if np.isfinite(hs_target) else np.inf
    for q in order[:max_tries]:
        better = n_rules[q] < n_rules_target or (n_rules[q] == n_rules_target and hs_key[q] <= hs_t - 0.25)
        if not better:
            return None
        if not (at_sea(cur_lat, cur_lon, float(la[q]), float(lo[q])) and at_sea(float(la[q]), float(lo[q]), next_lat, next_lon)):
            continue
        leg = judge.legs([cur_lat], [cur_lon], [cur_ns], [la[q]], [lo[q]], [speed_kn])[0]
        return float(la[q]), float(lo[q]), int(eta[q]), {k: v[q : q + 1] for k, v in w.items()}, leg, float(dist[q])
    return None


def utc_times(t_ns) -> pd.DatetimeIndex:
    return pd.DatetimeIndex(np.asarray(t_ns, dtype=np.int64).astype("datetime64[ns]")).tz_localize("UTC")


class Judge:
    """Vectorised weather look-ups and threshold checks for many points or legs at once."""

    def __init__(self, weather_at: WeatherAt, check: ThresholdCheck, spacing_nmi: float):
        self.weather_at = weather_at
        self.check = check
        self.spacing_nmi = spacing_nmi

    def points(self, t_ns, lat, lon, heading, speed):
        """Weather at the points and, per point, the list of rules broken there."""
        lat = np.asarray(lat, dtype=float).reshape(-1)
        lon = np.asarray(lon, dtype=float).reshape(-1)
        if lat.size == 0:
            return {}, []
        raw = self.weather_at(utc_times(t_ns), lat, lon)
        w = {k: np.asarray(v, dtype=float).reshape(-1) for k, v in raw.items()}
        flags = self.check(w, np.asarray(heading, dtype=float).reshape(-1), np.asarray(speed, dtype=float).reshape(-1))
        names = list(flags)
        mat = np.zeros((lat.size, len(names)), dtype=bool)
        for j, name in enumerate(names):
            mat[:, j] = np.broadcast_to(np.asarray(flags[name], dtype=bool), (lat.size,))
        return w, [[names[j] for j in np.flatnonzero(row)] for row in mat]

    def legs(self, lat1, lon1, t1_ns, lat2, lon2, speed):
        """Per leg, the rules broken at its interior points (one per grid spacing, at their own times)."""
        return self.legs_with_hs(lat1, lon1, t1_ns, lat2, lon2, speed)[0]

    def legs_with_hs(self, lat1, lon1, t1_ns, lat2, lon2, speed):
        """:meth:`legs`, and per leg the highest Hs at those interior points (NaN: none, or no Hs)."""
        lat1, lon1, lat2, lon2 = (np.asarray(x, dtype=float).reshape(-1) for x in (lat1, lon1, lat2, lon2))
        t1 = np.asarray(t1_ns, dtype=np.int64).reshape(-1)
        speed = np.asarray(speed, dtype=float).reshape(-1)
        n_legs = lat1.size
        out: list[list[str]] = [[] for _ in range(n_legs)]
        hs_max = np.full(n_legs, np.nan)
        if n_legs == 0 or self.spacing_nmi <= 0:
            return out, hs_max
        d = np.asarray(haversine_nmi(lat1, lon1, lat2, lon2), dtype=float).reshape(-1)
        k = np.maximum(np.ceil(d / self.spacing_nmi).astype(int) - 1, 0)
        if k.sum() == 0:
            return out, hs_max
        leg = np.repeat(np.arange(n_legs), k)
        j = np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k) + 1
        frac = j / (k[leg] + 1)
        la, lo = intermediate_point(lat1[leg], lon1[leg], lat2[leg], lon2[leg], frac)
        la = np.asarray(la, dtype=float).reshape(-1)
        lo = np.asarray(lo, dtype=float).reshape(-1)
        t = t1[leg] + np.round(frac * d[leg] / speed[leg] * 3.6e12).astype(np.int64)
        heading = np.asarray(initial_bearing_deg(la, lo, lat2[leg], lon2[leg]), dtype=float).reshape(-1)
        w, fired = self.points(t, la, lo, heading, speed[leg])
        for i, rules in zip(leg, fired):
            for r in rules:
                if r not in out[i]:
                    out[i].append(r)
        hs = w.get("hs_m")
        if hs is not None and np.isfinite(hs).any():
            # the interior points are grouped by leg (np.repeat): one reduction per leg with points
            has = np.flatnonzero(k > 0)
            starts = np.r_[0, np.cumsum(k[has])[:-1]]
            hs_max[has] = np.fmax.reduceat(hs, starts)
        return out, hs_max



class Walk:
    """Algorithm 1's walk along a lane from its departure, with the improvements of
    :mod:`routing.deviate`: optimistic passes over the rest of the lane, a deviation to the nearest
    passing cell ahead at each adverse centroid (or leg over land), the least adverse cell or the
    centroid itself when none passes. :meth:`run` fills :attr:`steps` (one per waypoint),
    :attr:`weathers` (the weather met at each) and :attr:`skipped` (lane centroids overtaken)."""

    def __init__(self, lat, lon, spd, t0: pd.Timestamp, judge: Judge, cells, leg_at_sea, horizon_h: float,
                 max_candidates: int):
        self.lat, self.lon, self.spd = lat, lon, spd
        self.judge, self.cells, self.leg_at_sea = judge, cells, leg_at_sea
        self.horizon_h, self.max_candidates = horizon_h, max_candidates
        self.lane_along = LaneAlong(lat, lon)
        self.skipped: list[int] = []
        self._lane_at_sea: dict[int, bool] = {}
        w0, fired0 = judge.points([t0.value], lat[:1], lon[:1], [initial_bearing_deg(lat[0], lon[0], lat[1], lon[1])], spd[:1])
        self.steps: list[DeviationStep] = [DeviationStep(0, "endpoint", lat[0], lon[0], lat[0], lon[0], t0, float(spd[0]), fired0[0])]
        self.weathers = [{k: v[:1] for k, v in w0.items()}]
        self._move(float(lat[0]), float(lon[0]), t0.value, True, 0.0)

    def _move(self, lat: float, lon: float, t_ns: int, is_lane: bool, along_nmi: float) -> None:
        """The ship is now at (lat, lon) at ``t_ns``; ``is_lane``: on a lane centroid."""
        self.cur_lat, self.cur_lon, self.cur_ns, self.cur_is_lane, self.cur_along = lat, lon, int(t_ns), is_lane, along_nmi

    def at_sea(self, la1, lo1, la2, lo2, lane_leg: int | None = None) -> bool:
        """The land check of one leg; a lane leg is checked once, however often a pass re-reads it."""
        if self.leg_at_sea is None or (la1 == la2 and lo1 == lo2):
            return True
        if lane_leg is not None:
            if lane_leg not in self._lane_at_sea:
                self._lane_at_sea[lane_leg] = bool(self.leg_at_sea(la1, lo1, la2, lo2))
            return self._lane_at_sea[lane_leg]
        return bool(self.leg_at_sea(la1, lo1, la2, lo2))

    def run(self) -> None:
        n, i = self.lat.size, 1
        while i < n:
            i = self._advance(i)

    def _advance(self, i: int) -> int:
        """One optimistic pass from centroid ``i`` and, at its first adverse step, one deviation.
        Returns the next centroid to walk to (the lane's length when the walk is over)."""
        lat, lon, n = self.lat, self.lon, self.lat.size
        # Optimistic pass: time the rest of the lane from the current point as if nothing more were
        # moved, and judge every remaining centroid at once. Up to the first adverse centroid this
        # is exactly what the step-by-step walk of Algorithm 1 computes.
        prev_lat = np.concatenate([[self.cur_lat], lat[i : n - 1]])
        prev_lon = np.concatenate([[self.cur_lon], lon[i : n - 1]])
        tgt_lat, tgt_lon, v = lat[i:n], lon[i:n], self.spd[i - 1 : n - 1]
        d = np.asarray(haversine_nmi(prev_lat, prev_lon, tgt_lat, tgt_lon), dtype=float).reshape(-1)
        eta_ns = self.cur_ns + np.round(np.cumsum(d / v) * 3.6e12).astype(np.int64)
        heading = np.asarray(initial_bearing_deg(prev_lat, prev_lon, tgt_lat, tgt_lon), dtype=float).reshape(-1)
        w, fired = self.judge.points(eta_ns, tgt_lat, tgt_lon, heading, v)
        m = tgt_lat.size
        bad, sea = m, []  # first step to act on (adverse centroid or leg over land), m = none
        for j in range(m):
            first_leg_is_lane = j > 0 or self.cur_is_lane
            sea.append(self.at_sea(prev_lat[j], prev_lon[j], tgt_lat[j], tgt_lon[j],
                                   lane_leg=i + j - 1 if first_leg_is_lane else None))
            if (fired[j] or not sea[j]) and i + j < n - 1:
                bad = j
                break
        # Accept the lane centroids before it (and the arrival, which is never moved).
        prev_ns = np.concatenate([[self.cur_ns], eta_ns[:-1]])
        leg_flags = self.judge.legs(prev_lat[:bad], prev_lon[:bad], prev_ns[:bad], tgt_lat[:bad], tgt_lon[:bad], v[:bad])
        for j in range(bad):
            k = i + j
            is_end = k == n - 1
            rules = list(fired[j]) + ([] if sea[j] else ["leg_crosses_land"])
            self.steps.append(DeviationStep(k, "endpoint" if is_end else "lane", lat[k], lon[k], lat[k], lon[k],
                                            pd.Timestamp(int(eta_ns[j]), tz="UTC"), float(v[j]), rules if is_end else [],
                                            leg_rules_fired=leg_flags[j]))
            self.weathers.append({key: val[j : j + 1] for key, val in w.items()})
        if bad >= m:
            return n
        if bad:
            self._move(float(tgt_lat[bad - 1]), float(tgt_lon[bad - 1]), int(eta_ns[bad - 1]), True,
                       float(self.lane_along.cum_nmi[i + bad - 1]))
        k, vk = i + bad, float(v[bad])
        rules = list(fired[bad]) + ([] if sea[bad] else ["leg_crosses_land"])
        chosen, n_candidates = self._deviate(k, vk, int(eta_ns[bad]), rules)
        if chosen is None:
            log.info("lane step %d: no passing cell within %.1f nmi (%s)", k, vk * self.horizon_h, ", ".join(rules))
            chosen = self._unresolved(k, vk, int(eta_ns[bad]), rules, n_candidates,
                                      {key: val[bad : bad + 1] for key, val in w.items()}, len(fired[bad]))
        self.steps.append(chosen)
        i = k + 1
        # Lane centroids the deviation has already passed (projection behind the current point)
        # are not sailed back to; the arrival is always kept.
        while i < n - 1 and self.lane_along.cum_nmi[i] <= self.cur_along + 1e-6:
            self.skipped.append(i)
            i += 1
        return i

    def _deviate(self, k: int, vk: float, eta_k_ns: int, rules: list) -> tuple[DeviationStep | None, int]:
        """[1], Alg. 1 line 7: the nearest passing cell, best-first, <= ``max_candidates`` ahead along
        the lane, within ``horizon_h`` of sailing, whose legs there and on to the next centroid stay
        at sea; the first with a clear leg, else the one whose leg breaks the fewest rules, then
        meets the lowest Hs. Returns (the step or None, the number of candidates looked at)."""
        lat, lon, judge = self.lat, self.lon, self.judge
        c_lat, c_lon, c_dist = self.cells.nearest(pd.Timestamp(eta_k_ns, tz="UTC"), float(lat[k]), float(lon[k]),
                                                  k=4 * self.max_candidates, max_dist_nmi=vk * self.horizon_h)
        ahead = (self.lane_along.along(c_lat, c_lon) > self.cur_along + 1e-6 if c_lat.size else np.zeros(0, dtype=bool))
        c_lat, c_lon, c_dist = (x[ahead][: self.max_candidates] for x in (c_lat, c_lon, c_dist))
        if not c_lat.size:
            return None, 0
        cur_lat, cur_lon, cur_ns = self.cur_lat, self.cur_lon, self.cur_ns
        dc = np.asarray(haversine_nmi(cur_lat, cur_lon, c_lat, c_lon), dtype=float).reshape(-1)
        eta_c = cur_ns + np.round(dc / vk * 3.6e12).astype(np.int64)  # ETAs along the deviated path
        hdg_c = np.asarray(initial_bearing_deg(cur_lat, cur_lon, c_lat, c_lon), dtype=float).reshape(-1)
        wc, fired_c = judge.points(eta_c, c_lat, c_lon, hdg_c, np.full(c_lat.size, vk))
        usable = [
            q for q in range(c_lat.size)
            if dc[q] > 0 and not fired_c[q]
            and self.at_sea(cur_lat, cur_lon, float(c_lat[q]), float(c_lon[q]))
            and self.at_sea(float(c_lat[q]), float(c_lon[q]), float(lat[k + 1]), float(lon[k + 1]))
        ]  # the leg there, and on to the next centroid, must stay at sea
        if not usable:
            return None, int(c_lat.size)
        u = np.array(usable)
        flags, leg_hs = judge.legs_with_hs(np.full(u.size, cur_lat), np.full(u.size, cur_lon), np.full(u.size, cur_ns),
                                           c_lat[u], c_lon[u], np.full(u.size, vk))
        clear = [q for q, f in zip(usable, flags) if not f]
        if clear:
            q, leg_fired = clear[0], []
        else:  # no clear leg: the one meeting the fewest rules, then the lowest Hs, then the nearest
            key = [(len(f), h if np.isfinite(h) else np.inf, r) for r, (f, h) in enumerate(zip(flags, leg_hs))]
            r = min(key)[2]
            q, leg_fired = usable[r], flags[r]
        step = DeviationStep(k, "deviated", lat[k], lon[k], float(c_lat[q]), float(c_lon[q]), pd.Timestamp(int(eta_c[q]), tz="UTC"),
                             vk, rules, float(c_dist[q]), int(q) + 1, list(leg_fired))
        self.weathers.append({key: val[q : q + 1] for key, val in wc.items()})
        self._move(float(c_lat[q]), float(c_lon[q]), int(eta_c[q]), False,
                   float(self.lane_along.along(c_lat[q : q + 1], c_lon[q : q + 1])[0]))
        return step, int(c_lat.size)

    def _unresolved(self, k: int, vk: float, eta_k_ns: int, rules: list, n_candidates: int, w_k: dict,
                    n_rules_k: int) -> DeviationStep:
        """Nothing passes within reach: sail to the least adverse reachable cell ahead (fewest rules
        fired, then lowest Hs; the lane centroid unless a cell is clearly calmer), flagged
        "unresolved" with the rules that fired at the centroid."""
        lat, lon = self.lat, self.lon
        hs_k = float(w_k["hs_m"][0]) if "hs_m" in w_k else float("nan")
        alt = least_adverse(self.judge, self.cells, self.lane_along, self.cur_lat, self.cur_lon, self.cur_ns, self.cur_along,
                            float(lat[k]), float(lon[k]), float(lat[k + 1]), float(lon[k + 1]), vk, vk * self.horizon_h,
                            n_rules_k, hs_k, self.at_sea)
        if alt is None:
            leg_fired = self.judge.legs([self.cur_lat], [self.cur_lon], [self.cur_ns], [lat[k]], [lon[k]], [vk])[0]
            step = DeviationStep(k, "unresolved", lat[k], lon[k], lat[k], lon[k], pd.Timestamp(eta_k_ns, tz="UTC"), vk,
                                 rules, 0.0, n_candidates, leg_fired)
            self.weathers.append(w_k)
            self._move(float(lat[k]), float(lon[k]), eta_k_ns, True, float(self.lane_along.cum_nmi[k]))
            return step
        a_lat, a_lon, a_ns, a_w, a_leg, a_moved = alt
        step = DeviationStep(k, "unresolved", lat[k], lon[k], a_lat, a_lon, pd.Timestamp(int(a_ns), tz="UTC"), vk,
                             rules, a_moved, n_candidates, a_leg)
        self.weathers.append(a_w)
        self._move(a_lat, a_lon, int(a_ns), False, float(self.lane_along.along([a_lat], [a_lon])[0]))
        return step
