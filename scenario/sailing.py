"""Sailing one vessel of the demo scenario: routes offset and kept off land, harbour legs, speed
profiles, berth and anchor stays, reporting cadence and signal gaps. See :mod:`scenario.generator`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from scenario.performance_law import ship_traits, speed_factor, surge_sd_kn
from scenario.spec import NAV_AT_ANCHOR, NAV_UNDER_WAY, Port, ScenarioSettings, ScenarioSpec, VesselSpec
from thresholds.geodesy import destination_point, haversine_nmi, initial_bearing_deg, intermediate_point
from thresholds.units import METRES_PER_NMI, wrap_deg


# --------------------------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------------------------


def _land(lat, lon) -> np.ndarray:
    from thresholds.land_raster import is_land  # the 30" mask, read pixel by pixel from its cache

    return np.asarray(is_land(np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)), dtype=bool)


def densify(waypoints: np.ndarray, step_nmi: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Points along a polyline of great-circle legs at most ``step_nmi`` apart (ends included)."""
    lats, lons = [np.array([waypoints[0, 0]])], [np.array([waypoints[0, 1]])]
    for (la1, lo1), (la2, lo2) in zip(waypoints[:-1], waypoints[1:]):
        d = haversine_nmi(la1, lo1, la2, lo2)
        n = max(1, int(math.ceil(d / step_nmi)))
        la, lo = intermediate_point(la1, lo1, la2, lo2, np.arange(1, n + 1) / n)
        lats.append(np.atleast_1d(la))
        lons.append(np.atleast_1d(lo))
    return np.concatenate(lats), np.concatenate(lons)


def polyline_on_land(waypoints: np.ndarray, step_nmi: float = 0.5) -> bool:
    """True when any point of the polyline sampled every ``step_nmi`` lies on land."""
    la, lo = densify(waypoints, step_nmi)
    return bool(_land(la, lo).any())


def _offset_route(wp: np.ndarray, offsets_nmi: np.ndarray) -> np.ndarray:
    """Shift interior waypoints sideways (positive = starboard of the direction of travel)."""
    out = wp.copy()
    for i in range(1, len(wp) - 1):
        b_in = initial_bearing_deg(wp[i - 1, 0], wp[i - 1, 1], wp[i, 0], wp[i, 1])
        b_out = initial_bearing_deg(wp[i, 0], wp[i, 1], wp[i + 1, 0], wp[i + 1, 1])
        mean = math.degrees(math.atan2(math.sin(math.radians(b_in)) + math.sin(math.radians(b_out)),
                                       math.cos(math.radians(b_in)) + math.cos(math.radians(b_out))))
        out[i] = destination_point(wp[i, 0], wp[i, 1], wrap_deg(mean + 90.0), offsets_nmi[i])
    return out


class _Path:
    """A polyline of great-circle legs with arc-length interpolation (vectorised)."""

    def __init__(self, lat: np.ndarray, lon: np.ndarray):
        keep = np.r_[True, haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]) > 1e-6]
        self.lat, self.lon = np.asarray(lat, float)[keep], np.asarray(lon, float)[keep]
        seg = haversine_nmi(self.lat[:-1], self.lon[:-1], self.lat[1:], self.lon[1:])
        self.seg = np.atleast_1d(seg)
        self.cum = np.r_[0.0, np.cumsum(self.seg)]
        self.length = float(self.cum[-1])

    def at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(lat, lon, course)`` at arc lengths ``s``; the course is the great-circle bearing
        towards the end of the current leg (the leg's own bearing within 0.01 nmi of its end)."""
        s = np.clip(np.asarray(s, float), 0.0, self.length)
        i = np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.seg) - 1)
        frac = np.where(self.seg[i] > 0, (s - self.cum[i]) / self.seg[i], 0.0)
        la, lo = intermediate_point(self.lat[i], self.lon[i], self.lat[i + 1], self.lon[i + 1], frac)
        la, lo = np.atleast_1d(la), np.atleast_1d(lo)
        to_end = initial_bearing_deg(la, lo, self.lat[i + 1], self.lon[i + 1])
        leg = initial_bearing_deg(self.lat[i], self.lon[i], self.lat[i + 1], self.lon[i + 1])
        course = np.where(self.cum[i + 1] - s > 0.01, to_end, leg)
        return la, lo, np.atleast_1d(course)


def _noise_offsets_m(rng, n: int, sigma_m: float, lat_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """GPS noise in degrees (north and east components of ``sigma_m`` metres each)."""
    dn = rng.normal(0.0, sigma_m, n)
    de = rng.normal(0.0, sigma_m, n)
    dlat = dn / (METRES_PER_NMI * 60.0)
    dlon = de / (METRES_PER_NMI * 60.0 * np.cos(np.deg2rad(lat_deg)))
    return dlat, dlon


def _sample_times(rng, t0: float, t1: float, interval: int, jitter: int) -> np.ndarray:
    """Integer report times in (t0, t1): a cadence of ``interval`` +- ``jitter`` seconds."""
    if t1 <= t0:
        return np.empty(0, dtype=np.int64)
    n = int((t1 - t0) / max(1, interval - jitter)) + 2
    steps = interval + rng.integers(-jitter, jitter + 1, n)
    first = rng.integers(1, max(2, interval))
    t = np.floor(t0).astype(np.int64) + first + np.r_[0, np.cumsum(steps[:-1])]
    return t[t < t1]


# --------------------------------------------------------------------------------------------
# Sailing one vessel
# --------------------------------------------------------------------------------------------


@dataclass
class _Frames:
    t: list = field(default_factory=list)
    lat: list = field(default_factory=list)
    lon: list = field(default_factory=list)
    sog: list = field(default_factory=list)
    cog: list = field(default_factory=list)
    hdg: list = field(default_factory=list)
    nav: list = field(default_factory=list)
    phase: list = field(default_factory=list)
    voyage: list = field(default_factory=list)

    def add(self, t, lat, lon, sog, cog, hdg, nav, phase, voyage):
        n = len(t)
        if n == 0:
            return
        self.t.append(np.asarray(t, np.int64))
        self.lat.append(np.asarray(lat, float))
        self.lon.append(np.asarray(lon, float))
        self.sog.append(np.asarray(sog, float))
        self.cog.append(np.asarray(cog, float))
        self.hdg.append(np.asarray(hdg, float))
        self.nav.append(np.full(n, nav, np.int16))
        self.phase.append(np.asarray(phase if np.ndim(phase) else np.full(n, phase), dtype=object))
        self.voyage.append(np.full(n, voyage, dtype=object))

    def frame(self) -> pd.DataFrame:
        if not self.t:
            return pd.DataFrame(columns=["time_s", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg",
                                         "nav_status", "phase", "voyage_id"])
        return pd.DataFrame({
            "time_s": np.concatenate(self.t), "lat_deg": np.concatenate(self.lat),
            "lon_deg": np.concatenate(self.lon), "sog_kn": np.concatenate(self.sog),
            "cog_deg": np.concatenate(self.cog), "heading_deg": np.concatenate(self.hdg),
            "nav_status": np.concatenate(self.nav), "phase": np.concatenate(self.phase),
            "voyage_id": np.concatenate(self.voyage),
        })


def _berth_position(rng, port: Port) -> tuple[float, float]:
    """A berth for this ship within 0.25 nmi of the port position."""
    return destination_point(port.lat_deg, port.lon_deg, rng.uniform(0, 360), rng.uniform(0.02, 0.25))


def _stationary(rng, st: ScenarioSettings, frames: _Frames, t0: float, t1: float, lat: float, lon: float,
                heading: float, nav: int, phase: str, voyage: str, swing_nmi: float = 0.0) -> int:
    """Fixes every ``berth_interval_s`` while alongside or at anchor; returns the count."""
    t = _sample_times(rng, t0, t1, st.berth_interval_s, st.interval_jitter_s * 3)
    n = len(t)
    if n == 0:
        return 0
    if swing_nmi > 0:  # at anchor the ship swings round its anchor with wind and current
        ang = np.deg2rad(heading + 40.0 * np.sin((t - t0) / 5400.0))
        hdg = np.rad2deg(ang)
        la, lo = destination_point(np.full(n, lat), np.full(n, lon), wrap_deg(hdg + 180.0), np.full(n, swing_nmi))
        sog = np.abs(rng.normal(0.1, 0.1, n))
    else:
        la, lo = np.full(n, lat), np.full(n, lon)
        hdg = np.full(n, heading) + rng.normal(0, 0.3, n)
        sog = np.abs(rng.normal(0.0, 0.05, n))
    dlat, dlon = _noise_offsets_m(rng, n, st.gps_noise_m, la)
    cog = rng.uniform(0.0, 360.0, n)  # course over ground of a ship at rest is GPS jitter
    frames.add(t, la + dlat, lo + dlon, sog, cog, wrap_deg(hdg), nav, phase, voyage)
    return n


def _speed_profile(length: float, d_h1: float, d_h2: float, v_sea: float, v_h: float,
                   rng, sd_frac: float) -> tuple[np.ndarray, tuple]:
    """Speed (kn) over arc length (nmi): slow at both ends, harbour speed in the harbour legs,
    ramps of up to 3 nmi, and the voyage speed with a slow fluctuation at sea.

    Returns the arc lengths and the parts :func:`_compose_speed` puts together with the seaway's
    speed factor: ``(v_h, w, sea_v, cap)``, the harbour speed, the weight of the sea speed (0 in
    the harbour legs, 1 at sea, ramps between), the set speed at sea, the berth approach cap."""
    ds = min(0.05, length / 50.0) if length > 0 else 0.05
    s = np.linspace(0.0, length, max(3, int(math.ceil(length / ds)) + 1))
    w = np.zeros_like(s)
    sea_v = np.full_like(s, v_h)
    sea0, sea1 = d_h1, length - d_h2
    if sea1 > sea0:
        ramp = min(3.0, (sea1 - sea0) / 4.0)
        knots = np.arange(sea0, sea1 + 15.0, 15.0)
        wobble = np.interp(s, knots, rng.normal(0.0, sd_frac, len(knots)))
        sea_v = v_sea * (1.0 + wobble)
        up = np.clip((s - sea0) / ramp, 0.0, 1.0) if ramp > 0 else (s >= sea0).astype(float)
        down = np.clip((sea1 - s) / ramp, 0.0, 1.0) if ramp > 0 else (s <= sea1).astype(float)
        w = np.minimum(up, down)
    # leaving and reaching the berth (or the anchor) slowly
    cap = 2.5 + np.minimum(s, length - s) * 20.0
    return s, (v_h, w, sea_v, cap)


def _compose_speed(parts: tuple, factor) -> np.ndarray:
    """Speed over arc length from :func:`_speed_profile`'s parts and the seaway's speed factor
    (applied to the set speed at sea; the harbour legs are sheltered)."""
    v_h, w, sea_v, cap = parts
    v = v_h + w * (sea_v * factor - v_h)
    return np.maximum(np.minimum(v, cap), 1.0)


@dataclass
class _Seaway:
    """The weather a ship sails through and how it answers to it (:mod:`scenario.performance_law`)."""

    sample: object  # callable(time_s, lat, lon) -> dict of hs_m, wave_from_deg, tp_s, wind_u_ms, wind_v_ms
    vessel_class: str
    traits: object
    length_m: float
    rng: np.random.Generator

    def factor(self, t_s, lat, lon, course):
        wx = self.sample(np.asarray(t_s, float), lat, lon)
        f, _ = speed_factor(self.vessel_class, self.traits, self.length_m, course, wx["hs_m"], wx["wave_from_deg"],
                            wx["tp_s"], wx["wind_u_ms"], wx["wind_v_ms"])
        return f, np.nan_to_num(np.asarray(wx["hs_m"], float))


#: Arc-length step at which a voyage samples the weather (the speed factor is interpolated
#: between), and the fixed-point passes that settle times and weather. [nmi]
SEAWAY_STEP_NMI = 0.5
SEAWAY_PASSES = 3


def _timeline(s: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Seconds from the start to each arc length of a speed profile (trapezoidal pace)."""
    return np.r_[0.0, np.cumsum(np.diff(s) / (0.5 * (v[:-1] + v[1:])))] * 3600.0


def _sail_profile(path: _Path, t0: float, s: np.ndarray, parts: tuple, sea: _Seaway | None):
    """Speed and time over arc length through the seaway, and Hs along it.

    The speed at a point depends on the weather at the time the ship gets there, which depends
    on the speeds before it: a few fixed-point passes (weather sampled every
    :data:`SEAWAY_STEP_NMI` at the times of the previous pass) settle it; the weather moves over
    hours, a pass changes times by minutes."""
    factor = np.ones_like(s)
    hs = np.zeros_like(s)
    v = _compose_speed(parts, factor)
    dt = _timeline(s, v)
    if sea is None:
        return v, dt, hs
    k = max(1, int(round(SEAWAY_STEP_NMI / max(s[1] - s[0], 1e-9)))) if len(s) > 1 else 1
    idx = np.unique(np.r_[np.arange(0, len(s), k), len(s) - 1])
    la, lo, course = path.at(s[idx])
    for _ in range(SEAWAY_PASSES):
        f, h = sea.factor(t0 + dt[idx], la, lo, course)
        factor = np.interp(s, s[idx], f)
        hs = np.interp(s, s[idx], h)
        v = _compose_speed(parts, factor)
        dt = _timeline(s, v)
    return v, dt, hs


def _move(rng, st: ScenarioSettings, frames: _Frames, path: _Path, t0: float, d_h1: float, d_h2: float,
          v_sea: float, voyage: str, sea: _Seaway | None = None) -> tuple[float, float]:
    """Sail ``path`` from time ``t0``; returns (arrival time, time at sea start offset)."""
    s, parts = _speed_profile(path.length, d_h1, d_h2, v_sea, st.harbour_speed_kn, rng, st.along_track_speed_sd_frac)
    v, dt, hs = _sail_profile(path, t0, s, parts, sea)
    t_arrive = t0 + dt[-1]
    t = _sample_times(rng, t0, t_arrive, st.underway_interval_s, st.interval_jitter_s)
    n = len(t)
    if n:
        sk = np.interp(t - t0, dt, s)
        vk = np.interp(sk, s, v)
        la, lo, cog = path.at(sk)
        dlat, dlon = _noise_offsets_m(rng, n, st.gps_noise_m, la)
        sog = np.maximum(0.0, vk + rng.normal(0.0, st.sog_noise_kn, n))
        if sea is not None:  # surge in a seaway, from the law's own random stream
            sog = np.maximum(0.0, sog + sea.rng.normal(0.0, 1.0, n) * surge_sd_kn(vk, np.interp(sk, s, hs)))
        drift = rng.normal(0.0, 1.5)  # leeway/current: heading differs from COG by a voyage constant
        hdg = cog + drift + rng.normal(0.0, st.heading_noise_deg, n)
        cogn = cog + rng.normal(0.0, st.cog_noise_deg, n)
        phase = np.where((sk < d_h1) | (sk > path.length - d_h2), "harbour", "sea").astype(object)
        frames.add(t, la + dlat, lo + dlon, sog, wrap_deg(cogn), wrap_deg(hdg), NAV_UNDER_WAY, phase, voyage)
    t_sea0 = t0 + float(np.interp(d_h1, s, dt))
    t_sea1 = t0 + float(np.interp(path.length - d_h2, s, dt))
    return t_arrive, (t_sea0, t_sea1)


def _sail_route(rng, st: ScenarioSettings, spec: ScenarioSpec, o: str, d: str) -> tuple[str, np.ndarray, float]:
    """The route from o to d with this voyage's lateral offset, kept off the land mask."""
    route_id, wp = spec.route(o, d)
    n = len(wp)
    base = st.keep_right_nmi + float(np.clip(rng.normal(0.0, st.lateral_sd_nmi), -st.lateral_max_nmi,
                                             st.lateral_max_nmi))
    jitter = rng.normal(0.0, st.waypoint_jitter_nmi, n)
    offsets = np.clip(base + jitter, -st.lateral_max_nmi - 0.5, st.lateral_max_nmi + 0.5)
    offsets[0] = offsets[-1] = 0.0
    if n > 2:
        for scale in (1.0, 0.5, 0.25, 0.0):
            cand = _offset_route(wp, offsets * scale)
            if scale == 0.0 or not polyline_on_land(cand, 0.5):
                return route_id, cand, base * scale
    return route_id, wp, 0.0


def _next_departure(t_ready: float, hours: tuple[int, ...]) -> float:
    """First timetable slot (UTC hour of day) at or after ``t_ready``."""
    if not hours:
        return t_ready
    day0 = math.floor(t_ready / 86400.0) * 86400.0
    for k in range(3):
        for h in hours:
            slot = day0 + k * 86400.0 + h * 3600.0
            if slot >= t_ready:
                return slot
    return t_ready  # pragma: no cover - hours is non-empty so a slot always exists


def _sail_vessel(index: int, v: VesselSpec, rank: int, spec: ScenarioSpec, st: ScenarioSettings, seaway=None):
    """All fixes, voyages, port stays and gaps of one ship over the scenario period.

    ``seaway`` (``callable(time_s, lat, lon) -> dict``) is the weather the ship sails through;
    ``None`` is calm water everywhere."""
    # Long by design: a vessel's whole timetable (berth, harbour legs, sea passage, anchorage,
    # gaps) in sailing order, on one random stream so that the same seed gives the same rows.
    rng = np.random.default_rng([st.seed, 1, index])
    svc = spec.services[v.service]
    rot = svc.rotation
    sea = None
    if seaway is not None:  # the law draws from its own stream, so calm runs keep their numbers
        law_rng = np.random.default_rng([st.seed, 5, index])
        sea = _Seaway(seaway, svc.vessel_class, ship_traits(law_rng, svc.vessel_class), v.length_m, law_rng)
    frames = _Frames()
    voyages, stays = [], []
    start, end = st.start_s, st.end_s
    berth = {p: _berth_position(rng, spec.ports[p]) for p in rot}
    berth_hdg = {p: rng.uniform(0, 360) for p in rot}
    pos = rank % len(rot)
    t_arr = start - rng.uniform(0.0, svc.stay_h[1]) * 3600.0
    k = 0
    while True:
        port = rot[pos]
        stay = rng.uniform(*svc.stay_h) * 3600.0
        t_dep = _next_departure(t_arr + stay, svc.departure_hours_utc)
        if svc.departure_hours_utc:
            t_dep += rng.uniform(0.0, 0.4) * 3600.0  # ferries leave a little late
        lat_b, lon_b = berth[port]
        status = v.status_at_berth
        _stationary(rng, st, frames, max(t_arr, start - 1), min(t_dep, end), lat_b, lon_b, berth_hdg[port],
                    status, "berth", "")
        stays.append({"mmsi": v.mmsi, "port": port, "arrive_s": t_arr, "depart_s": t_dep,
                      "lat_deg": lat_b, "lon_deg": lon_b, "nav_status": status})
        if t_dep >= end:
            break
        dest = rot[(pos + 1) % len(rot)]
        vid = f"{v.mmsi}_{k}"
        route_id, sea_wp, offset = _sail_route(rng, st, spec, port, dest)
        v_sea = v.service_speed_kn * (1.0 + rng.normal(0.0, st.voyage_speed_sd_frac))
        lat_d, lon_d = berth[dest]
        p_o, p_d = spec.ports[port], spec.ports[dest]
        d_h1 = haversine_nmi(lat_b, lon_b, p_o.approach_lat_deg, p_o.approach_lon_deg)
        wait_s = 0.0
        anchorage = None
        if rng.random() < svc.anchorage_wait_prob:
            wait_s = rng.uniform(*svc.anchorage_wait_h) * 3600.0
            for _ in range(8):
                cand = destination_point(p_d.approach_lat_deg, p_d.approach_lon_deg, rng.uniform(0, 360),
                                         st.anchorage_dist_nmi)
                if not _land(*cand):
                    anchorage = cand
                    break
            if anchorage is None:
                wait_s = 0.0
        if anchorage is None:
            pts = np.vstack([[lat_b, lon_b], sea_wp, [lat_d, lon_d]])
            path = _Path(pts[:, 0], pts[:, 1])
            d_h2 = haversine_nmi(p_d.approach_lat_deg, p_d.approach_lon_deg, lat_d, lon_d)
            t_in, (t_sea0, t_sea1) = _move(rng, st, frames, path, t_dep, d_h1, d_h2, v_sea, vid, sea)
            sea_len = path.length - d_h1 - d_h2
        else:
            pts = np.vstack([[lat_b, lon_b], sea_wp, [anchorage[0], anchorage[1]]])
            path = _Path(pts[:, 0], pts[:, 1])
            d_h2 = haversine_nmi(p_d.approach_lat_deg, p_d.approach_lon_deg, *anchorage)
            t_anchor, (t_sea0, t_sea1) = _move(rng, st, frames, path, t_dep, d_h1, d_h2, v_sea, vid, sea)
            sea_len = path.length - d_h1 - d_h2
            _stationary(rng, st, frames, t_anchor, min(t_anchor + wait_s, end), anchorage[0], anchorage[1],
                        rng.uniform(0, 360), NAV_AT_ANCHOR, "anchor", vid, swing_nmi=0.05)
            inner = _Path(np.array([anchorage[0], lat_d]), np.array([anchorage[1], lon_d]))
            if t_anchor + wait_s < end:
                t_in, _ = _move(rng, st, frames, inner, t_anchor + wait_s, inner.length, 0.0, v_sea, vid)
            else:
                t_in = t_anchor + wait_s + inner.length / st.harbour_speed_kn * 3600.0
            path = _Path(np.r_[path.lat, lat_d], np.r_[path.lon, lon_d])
        voyages.append({
            "voyage_id": vid, "mmsi": v.mmsi, "service": svc.id, "origin": port, "dest": dest,
            "route_id": route_id, "depart_s": t_dep, "arrive_s": t_in, "sea_start_s": t_sea0,
            "sea_end_s": t_sea1, "dist_nmi": path.length, "sea_dist_nmi": sea_len,
            "speed_kn": v_sea, "lateral_offset_nmi": offset, "anchorage_wait_h": wait_s / 3600.0,
            "anchorage_lat_deg": anchorage[0] if anchorage else np.nan,
            "anchorage_lon_deg": anchorage[1] if anchorage else np.nan,
            "draught_m": round(v.draught_m * rng.uniform(0.85, 1.0), 1),
            "complete": bool(t_in <= end),
        })
        if t_in >= end:
            break
        t_arr = t_in
        pos = (pos + 1) % len(rot)
        k += 1

    fx = frames.frame()
    fx = fx[(fx.time_s >= start) & (fx.time_s < end)].sort_values("time_s", kind="stable")
    fx = fx.drop_duplicates("time_s", keep="first").reset_index(drop=True)
    fx.insert(0, "mmsi", np.int64(v.mmsi))

    # signal gaps: coverage holes at sea on some voyages, a long transponder outage on some ships
    gaps = []
    received = np.ones(len(fx), bool)
    for voy in voyages:
        if rng.random() < st.gap_prob_per_voyage:
            a, b = voy["sea_start_s"], voy["sea_end_s"]
            dur = rng.uniform(*st.gap_s)
            if b - a > dur + 3600:
                g0 = rng.uniform(a + 1800, b - dur - 1800)
                gaps.append({"mmsi": v.mmsi, "kind": "coverage", "start_s": g0, "end_s": g0 + dur})
    if rng.random() < st.outage_prob_per_vessel:
        dur = rng.uniform(*st.outage_s)
        if end - start > dur + 7200:
            g0 = rng.uniform(start + 3600, end - dur - 3600)
            gaps.append({"mmsi": v.mmsi, "kind": "outage", "start_s": g0, "end_s": g0 + dur})
    for g in gaps:
        inside = (fx.time_s.to_numpy() >= g["start_s"]) & (fx.time_s.to_numpy() < g["end_s"])
        g["fixes_lost"] = int(inside.sum())
        received &= ~inside
    fx["received"] = received
    return fx, voyages, stays, gaps
