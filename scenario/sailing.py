"""Sailing one vessel of the demo scenario: routes offset and kept off land, harbour legs, speed
profiles, berth and anchor stays, reporting cadence and signal gaps. See :mod:`scenario.generator`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from scenario.performance_law import ship_traits, speed_factor, surge_sd_kn
from scenario.spec import NAV_AT_ANCHOR, NAV_UNDER_WAY, Port, ScenarioSettings, ScenarioSpec, VesselSpec
from thresholds.geodesy import destination_point, haversine_nmi, initial_bearing_deg
from thresholds.units import EARTH_RADIUS_NMI, METRES_PER_NMI, wrap_deg


# --------------------------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------------------------


def _land(lat, lon) -> np.ndarray:
    from thresholds.land_raster import is_land  # the 30" mask, read pixel by pixel from its cache

    return np.asarray(is_land(np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)), dtype=bool)


def _squares(x: np.ndarray) -> np.ndarray:
    """``x ** 2`` element by element as float64 scalars square (the C library's ``pow``; numpy
    squares an array by multiplication, which differs in the last bit for some values)."""
    return np.array([v ** 2 for v in x.tolist()], dtype=float)


class _Legs:
    """The per-leg terms of the great-circle formulas of :mod:`thresholds.geodesy` (Williams'
    Aviation Formulary: haversine distance, intermediate point, initial course) for legs from
    ``(lat1, lon1)`` to ``(lat2, lon2)`` (degrees, arrays), computed once per leg.

    :meth:`points` and :meth:`course_to_end` then give, for points on the legs, the same
    numbers to the last bit (tested) as ``intermediate_point`` and ``initial_bearing_deg`` called
    on the legs' ends gathered per point, for a fraction of the trigonometry. ``square`` is how
    the haversine term squares: numpy's array square for array ends (``_Path``), the scalar
    ``pow`` where the reference called the functions on one leg's scalar ends (``densify``)."""

    def __init__(self, lat1_deg, lon1_deg, lat2_deg, lon2_deg, square=np.square):
        self.lat1, self.lon1, self.lat2, self.lon2 = (np.deg2rad(np.asarray(x, dtype=float))
                                                      for x in (lat1_deg, lon1_deg, lat2_deg, lon2_deg))
        self.cos_lat1, self.cos_lat2 = np.cos(self.lat1), np.cos(self.lat2)
        self.sin_lat1, self.sin_lat2 = np.sin(self.lat1), np.sin(self.lat2)
        a = square(np.sin((self.lat2 - self.lat1) / 2.0)) + self.cos_lat1 * self.cos_lat2 * square(
            np.sin((self.lon2 - self.lon1) / 2.0))
        self.root = np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))  # half the central angle
        self.d = 2.0 * self.root
        self.sin_d = np.sin(self.d)

    def length_nmi(self) -> np.ndarray:
        """Each leg's great-circle length (``haversine_nmi``). [nmi]"""
        return 2.0 * EARTH_RADIUS_NMI * self.root

    def points(self, k: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(lat, lon)`` at fraction ``f`` of leg ``k`` (``intermediate_point``). [deg]"""
        d, sin_d = self.d[k], self.sin_d[k]
        with np.errstate(invalid="ignore", divide="ignore"):
            A = np.where(sin_d > 1e-15, np.sin((1.0 - f) * d) / sin_d, 1.0 - f)
            B = np.where(sin_d > 1e-15, np.sin(f * d) / sin_d, f)
        c1, c2 = self.cos_lat1[k], self.cos_lat2[k]
        x = A * c1 * np.cos(self.lon1)[k] + B * c2 * np.cos(self.lon2)[k]
        y = A * c1 * np.sin(self.lon1)[k] + B * c2 * np.sin(self.lon2)[k]
        z = A * self.sin_lat1[k] + B * self.sin_lat2[k]
        lat = np.rad2deg(np.arctan2(z, np.hypot(x, y)))
        lon = (np.rad2deg(np.arctan2(y, x)) + 180.0) % 360.0 - 180.0
        return lat, lon

    def course_to_end(self, lat_deg: np.ndarray, lon_deg: np.ndarray, k: np.ndarray) -> np.ndarray:
        """Initial course from each point towards the end of its leg ``k``
        (``initial_bearing_deg``), in [0, 360). [deg]"""
        lat1, lon1 = np.deg2rad(lat_deg), np.deg2rad(lon_deg)
        dlon = self.lon2[k] - lon1
        cos_lat2 = self.cos_lat2[k]
        y = np.sin(dlon) * cos_lat2
        x = np.cos(lat1) * self.sin_lat2[k] - np.sin(lat1) * cos_lat2 * np.cos(dlon)
        return np.mod(np.rad2deg(np.arctan2(y, x)), 360.0)


def densify(waypoints: np.ndarray, step_nmi: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Points along a polyline of great-circle legs at most ``step_nmi`` apart (ends included):
    each leg of ``d`` nmi cut into ``ceil(d / step_nmi)`` equal parts, all legs in one pass
    (:class:`_Legs`; the same points to the last bit as one ``intermediate_point`` call per leg)."""
    legs = _Legs(waypoints[:-1, 0], waypoints[:-1, 1], waypoints[1:, 0], waypoints[1:, 1], square=_squares)
    n = np.maximum(1, np.ceil(legs.length_nmi() / step_nmi)).astype(np.int64)
    k = np.repeat(np.arange(len(n)), n)
    f = (np.arange(len(k)) - np.repeat(np.cumsum(n) - n, n) + 1) / n[k]
    la, lo = legs.points(k, f)
    return np.concatenate(([waypoints[0, 0]], la)), np.concatenate(([waypoints[0, 1]], lo))


def polyline_on_land(waypoints: np.ndarray, step_nmi: float = 0.5) -> bool:
    """True when any point of the polyline sampled every ``step_nmi`` lies on land."""
    la, lo = densify(waypoints, step_nmi)
    return bool(_land(la, lo).any())


def _offset_route(wp: np.ndarray, offsets_nmi: np.ndarray) -> np.ndarray:
    """Shift interior waypoints sideways (positive = starboard of the direction of travel): each
    by its offset, square to the mean of the courses in and out (all waypoints at once)."""
    out = wp.copy()
    if len(wp) < 3:
        return out
    course = initial_bearing_deg(wp[:-1, 0], wp[:-1, 1], wp[1:, 0], wp[1:, 1]).tolist()
    # the mean course by the math module, as the one-waypoint-at-a-time code did (the last bit)
    mean = np.array([math.degrees(math.atan2(math.sin(math.radians(b_in)) + math.sin(math.radians(b_out)),
                                             math.cos(math.radians(b_in)) + math.cos(math.radians(b_out))))
                     for b_in, b_out in zip(course[:-1], course[1:])])
    lat, lon = destination_point(wp[1:-1, 0], wp[1:-1, 1], wrap_deg(mean + 90.0), offsets_nmi[1:-1])
    out[1:-1, 0], out[1:-1, 1] = lat, lon
    return out


class _Path:
    """A polyline of great-circle legs with arc-length interpolation (vectorised)."""

    def __init__(self, lat: np.ndarray, lon: np.ndarray):
        keep = np.concatenate(([True], haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]) > 1e-6))
        self.lat, self.lon = np.asarray(lat, float)[keep], np.asarray(lon, float)[keep]
        self.legs = _Legs(self.lat[:-1], self.lon[:-1], self.lat[1:], self.lon[1:])
        self.seg = np.atleast_1d(self.legs.length_nmi())
        self.cum = np.concatenate(([0.0], np.cumsum(self.seg)))
        self.length = float(self.cum[-1])
        self.leg_course = initial_bearing_deg(self.lat[:-1], self.lon[:-1], self.lat[1:], self.lon[1:])

    def at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(lat, lon, course)`` at arc lengths ``s``; the course is the great-circle bearing
        towards the end of the current leg (the leg's own bearing within 0.01 nmi of its end)."""
        s = np.clip(np.asarray(s, float), 0.0, self.length)
        i = np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.seg) - 1)
        frac = np.where(self.seg[i] > 0, (s - self.cum[i]) / self.seg[i], 0.0)
        la, lo = self.legs.points(i, frac)
        course = np.where(self.cum[i + 1] - s > 0.01, self.legs.course_to_end(la, lo, i), self.leg_course[i])
        return np.atleast_1d(la), np.atleast_1d(lo), np.atleast_1d(course)


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
    t = np.floor(t0).astype(np.int64) + first + np.concatenate(([0], np.cumsum(steps[:-1])))
    return t[t < t1]


# --------------------------------------------------------------------------------------------
# Sailing one vessel
# --------------------------------------------------------------------------------------------


#: The phases a fix is in (``phase`` of the fixes); :meth:`_Frames.add` takes one or their codes.
PHASES = ("berth", "anchor", "harbour", "sea")


@dataclass
class _Frames:
    """The fixes of one ship in sailing order, chunk by chunk (one chunk per stay or passage)."""

    t: list = field(default_factory=list)
    lat: list = field(default_factory=list)
    lon: list = field(default_factory=list)
    sog: list = field(default_factory=list)
    cog: list = field(default_factory=list)
    hdg: list = field(default_factory=list)
    nav: list = field(default_factory=list)  # one status per chunk
    phase: list = field(default_factory=list)  # per chunk: int8 codes of PHASES, one per fix
    voyage: list = field(default_factory=list)  # one voyage id per chunk

    def add(self, t, lat, lon, sog, cog, hdg, nav, phase, voyage):
        """A chunk of fixes; ``phase`` is a name of :data:`PHASES` or an array of their codes."""
        n = len(t)
        if n == 0:
            return
        self.t.append(np.asarray(t, np.int64))
        self.lat.append(np.asarray(lat, float))
        self.lon.append(np.asarray(lon, float))
        self.sog.append(np.asarray(sog, float))
        self.cog.append(np.asarray(cog, float))
        self.hdg.append(np.asarray(hdg, float))
        self.nav.append(nav)
        self.phase.append(np.full(n, PHASES.index(phase), np.int8) if isinstance(phase, str) else phase)
        self.voyage.append(voyage)

    def frame(self, start_s: float, end_s: float, mmsi: int) -> pd.DataFrame:
        """The fixes in ``[start_s, end_s)`` by time (stable), the first of any fixes sharing a
        second, with ``mmsi`` as their first column; taken once per column (numpy), as pandas'
        filter, ``sort_values(kind="stable")`` and ``drop_duplicates(keep="first")`` would."""
        if not self.t:
            fx = pd.DataFrame(columns=["time_s", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg",
                                       "nav_status", "phase", "voyage_id"])
            fx.insert(0, "mmsi", np.int64(mmsi))
            return fx
        t = np.concatenate(self.t)
        inside = np.flatnonzero((t >= start_s) & (t < end_s))
        order = inside[np.argsort(t[inside], kind="stable")]
        ts = t[order]
        keep = order[np.concatenate(([True], ts[1:] != ts[:-1]))] if len(ts) else order
        cols = {"mmsi": np.full(len(keep), mmsi, dtype=np.int64), "time_s": t[keep]}
        for name, parts in (("lat_deg", self.lat), ("lon_deg", self.lon), ("sog_kn", self.sog),
                            ("cog_deg", self.cog), ("heading_deg", self.hdg)):
            cols[name] = np.concatenate(parts)[keep]
        chunk = np.repeat(np.arange(len(self.t)), [len(x) for x in self.t])[keep]
        cols["nav_status"] = np.asarray(self.nav, dtype=np.int16)[chunk]
        cols["phase"] = np.array(PHASES, dtype=object)[np.concatenate(self.phase)[keep]]
        cols["voyage_id"] = np.array(self.voyage, dtype=object)[chunk]
        return pd.DataFrame(cols)


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
    return np.concatenate(([0.0], np.cumsum(np.diff(s) / (0.5 * (v[:-1] + v[1:]))))) * 3600.0


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
        phase = np.where((sk < d_h1) | (sk > path.length - d_h2), PHASES.index("harbour"),
                         PHASES.index("sea")).astype(np.int8)
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

    fx = frames.frame(start, end, v.mmsi)

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
