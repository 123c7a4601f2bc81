"""The demo AIS scenario: a deterministic fleet sailing liner services in the Western Mediterranean.

Pure: the caller passes the parsed configuration (``data/scenario.toml`` and ``data/ports.csv``,
read by :mod:`pipelines.scenario`) and gets DataFrames back; the writers in
:mod:`lanes.io.writers` turn them into DMA CSV and NMEA files.

How the traffic is made
-----------------------
* Every vessel belongs to one service (a rotation of ports). It starts alongside at one port of
  the rotation (vessels of a service are staggered) and sails voyage after voyage: berth ->
  harbour leg -> the service route between the two approach points -> harbour leg -> berth,
  then stays alongside (ro-pax lines wait for the next timetable slot; cargo ships stay a
  random time; tankers sometimes wait at an anchorage before berthing).
* Each voyage sails the route with a lateral offset (a keep-right bias plus a random offset
  per voyage, and a small jitter per waypoint), checked against the land mask and shrunk when it
  would touch land, and with a voyage speed drawn around the vessel's service speed plus a
  slow along-track fluctuation. Lanes therefore have a width of about 1-2 nmi and emerge from
  clustering rather than being a single line.
* Reporting cadence. Class A transponders report every 2-10 s under way and every 3 min at
  anchor or moored (ITU-R M.1371-5, Annex 1, Table 1). Public archives thin that: NOAA
  MarineCadastre keeps about one fix per minute (the New York Harbor day under ../shared has a
  median interval of 70 s). The scenario follows the archives: one fix every 60 s (+-4 s)
  under way and every 180 s alongside or at anchor, which keeps 30 days of 20 ships at about
  0.6 M rows, small enough for a demo and dense enough for lanes.
* Positions carry GPS noise (8 m, 1 sigma), SOG/COG/heading carry sensor noise, and signal
  gaps drop fixes: a coverage gap at sea on some voyages and a long transponder outage on some
  vessels.
* A small share of dirty rows of every kind the ingest must quarantine is added on top of the
  clean fixes (:data:`DIRTY_KINDS`); one kind, ``sentinel_fields``, edits clean rows in place
  (SOG 102.3 / COG 360 / heading 511 mean "not available" and are loaded as NULL).

All randomness comes from ``numpy.random.default_rng`` seeded with ``(seed, vessel index)`` or
``(seed, stream id)``, so the same seed gives the same rows.

References
----------
.. [1] ITU-R M.1371-5, "Technical characteristics for an automatic identification system using
       time division multiple access in the VHF maritime mobile band," 2014, Annex 1 Table 1
       (reporting intervals), Annex 8 (message fields and not-available values).
.. [2] ITU-R M.585-9, "Assignment and use of identities in the maritime mobile service," 2022
       (MMSI structure, maritime identification digits).
.. [3] IMO Resolution A.1117(30), "IMO ship identification number scheme," 2017 (check digit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np
import pandas as pd

from thresholds.errors import StormlaneError
from thresholds.geodesy import destination_point, haversine_nmi, initial_bearing_deg, intermediate_point
from thresholds.units import METRES_PER_NMI, wrap_deg

#: Default scenario period (COMMON.md "Demo scenario").
DEFAULT_START_UTC = pd.Timestamp("2025-01-01T00:00:00Z")
DEFAULT_DAYS = 30.0

#: Output formats a vessel can be written in.
AIS_FORMATS = ("dma_csv", "nmea")
VESSEL_CLASSES = ("ro-pax", "container", "tanker")

#: Dirty-row kinds. ``sentinel_fields`` edits a clean row in place (it must load, with NULLs);
#: every other kind is an extra row the ingest must reject (quarantine or duplicate).
DIRTY_KINDS = (
    "sentinel_position",  # lat 91 / lon 181: position not available
    "out_of_range",  # |lat| > 90 or |lon| > 180 (not the sentinel)
    "invalid_mmsi",  # not 9 digits, or MID outside 201-775
    "bad_timestamp",  # unparsable timestamp text (CSV only)
    "speed_jump",  # a fix 20-45 nmi off the track between two fixes 60 s apart
    "duplicate_exact",  # the same line twice
    "duplicate_timestamp",  # same MMSI and timestamp, different content
    "malformed_row",  # a CSV line cut short (too few fields)
    "bad_checksum",  # an NMEA sentence whose checksum does not match (NMEA only)
    "sentinel_fields",  # SOG 102.3 / COG 360 / heading 511 on a good fix (loads with NULLs)
)
#: Kinds possible per output format.
FORMAT_KINDS = {
    "dma_csv": tuple(k for k in DIRTY_KINDS if k != "bad_checksum"),
    "nmea": tuple(k for k in DIRTY_KINDS if k not in ("bad_timestamp", "malformed_row")),
}
#: Share of the clean position rows of a format that get each dirty kind (about 0.6 % in all).
DEFAULT_DIRTY_RATES: Mapping[str, float] = {
    "sentinel_position": 0.0004,
    "out_of_range": 0.0002,
    "invalid_mmsi": 0.0003,
    "bad_timestamp": 0.0002,
    "speed_jump": 0.0005,
    "duplicate_exact": 0.0020,
    "duplicate_timestamp": 0.0008,
    "malformed_row": 0.0001,
    "bad_checksum": 0.0005,
    "sentinel_fields": 0.0015,
}

#: Maritime identification digits of the Mediterranean flags the fleet may fly [2].
MED_MIDS = {
    "ES": (224, 225),
    "FR": (226, 227, 228),
    "IT": (247,),
    "MT": (215, 229, 248, 249, 256),
    "GR": (237, 239, 240, 241),
    "CY": (209, 210, 212),
    "DZ": (605,),
    "TN": (672,),
    "MA": (242,),
    "LY": (642,),
    "MC": (254,),
    "HR": (238,),
}
#: AIS navigational status codes used here [1].
NAV_UNDER_WAY = 0
NAV_AT_ANCHOR = 1
NAV_MOORED = 5

_EPOCH = pd.Timestamp("1970-01-01T00:00:00Z")


class ScenarioConfigError(StormlaneError):
    """The scenario configuration (``data/scenario.toml`` / ``data/ports.csv``) is invalid."""


# --------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Port:
    """A port: berth position (inside the basin) and an approach point at sea."""

    locode: str
    name: str
    lat_deg: float
    lon_deg: float
    approach_lat_deg: float
    approach_lon_deg: float

    @property
    def ais_destination(self) -> str:
        """What crews type into the AIS destination field: the first word of the name."""
        return self.name.replace("(", " ").split()[0].upper()[:20]


@dataclass(frozen=True)
class Service:
    """A liner service: the ports sailed in order (and back to the first)."""

    id: str
    name: str
    vessel_class: str
    rotation: tuple[str, ...]
    stay_h: tuple[float, float]
    departure_hours_utc: tuple[int, ...] = ()
    anchorage_wait_prob: float = 0.0
    anchorage_wait_h: tuple[float, float] = (3.0, 12.0)

    def legs(self) -> list[tuple[str, str]]:
        """The (origin, destination) pairs of one rotation."""
        n = len(self.rotation)
        return [(self.rotation[i], self.rotation[(i + 1) % n]) for i in range(n)]


@dataclass(frozen=True)
class VesselSpec:
    """One ship of the fleet (static AIS data and particulars)."""

    mmsi: int
    imo: int
    name: str
    callsign: str
    flag: str
    service: str
    ship_type: int
    length_m: float
    beam_m: float
    draught_m: float
    dwt_t: float
    service_speed_kn: float
    to_bow: int
    to_stern: int
    to_port: int
    to_starboard: int
    ais_format: str = "dma_csv"
    status_at_berth: int = NAV_MOORED
    profile: str = ""  # vessel profile name in data/vessels/ (class parameters for evaluations)


@dataclass(frozen=True)
class ScenarioSpec:
    """Ports, routes (approach to approach, keyed by ``(origin, dest)``), services and fleet."""

    ports: dict[str, Port]
    routes: dict[tuple[str, str], np.ndarray]
    services: dict[str, Service]
    vessels: tuple[VesselSpec, ...]

    def route(self, origin: str, dest: str) -> tuple[str, np.ndarray]:
        """``(route_id, waypoints[n, 2])`` from origin's approach to dest's approach."""
        if (origin, dest) in self.routes:
            return f"{origin}-{dest}", self.routes[(origin, dest)]
        if (dest, origin) in self.routes:
            return f"{dest}-{origin}", self.routes[(dest, origin)][::-1].copy()
        raise ScenarioConfigError(f"no route between {origin} and {dest} in the scenario routes")


def mmsi_problem(mmsi: int) -> str | None:
    """Why an MMSI is not a valid ship station identity [2], or ``None`` when it is."""
    if not 100_000_000 <= int(mmsi) <= 999_999_999:
        return "not 9 digits"
    mid = int(mmsi) // 1_000_000
    if not 201 <= mid <= 775:
        return f"MID {mid} outside the ship range 201-775"
    return None


def imo_check_digit_ok(imo: int) -> bool:
    """IMO number check: the 7th digit equals sum(d_i * (7 - i)) mod 10 over the first six [3]."""
    s = f"{int(imo):07d}"
    if len(s) != 7:
        return False
    total = sum(int(c) * w for c, w in zip(s[:6], range(7, 1, -1)))
    return total % 10 == int(s[6])


def _pair(value, what: str, source: str) -> tuple[float, float]:
    try:
        lo, hi = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ScenarioConfigError(f"{source}: {what} must be a pair [min, max], got {value!r}") from None
    if not 0 <= lo <= hi:
        raise ScenarioConfigError(f"{source}: {what} must satisfy 0 <= min <= max, got {value!r}")
    return lo, hi


def parse_ports(ports: pd.DataFrame, source: str = "ports.csv") -> dict[str, Port]:
    """Ports from the ``data/ports.csv`` table (columns of COMMON.md)."""
    need = ["locode", "name", "lat_deg", "lon_deg", "approach_lat_deg", "approach_lon_deg"]
    missing = [c for c in need if c not in ports.columns]
    if missing:
        raise ScenarioConfigError(f"{source}: missing column(s) {', '.join(missing)}")
    out = {}
    for i, row in enumerate(ports.itertuples(index=False), start=2):
        vals = [row.lat_deg, row.lon_deg, row.approach_lat_deg, row.approach_lon_deg]
        if not all(np.isfinite(vals)) or abs(row.lat_deg) > 90 or abs(row.approach_lat_deg) > 90:
            raise ScenarioConfigError(f"{source} line {i}: bad coordinates for {row.locode}")
        out[str(row.locode)] = Port(str(row.locode), str(row.name), *map(float, vals))
    return out


def parse_scenario_spec(doc: Mapping, ports: pd.DataFrame, source: str = "scenario.toml") -> ScenarioSpec:
    """Validate the parsed ``scenario.toml`` document against the port table.

    Raises :class:`ScenarioConfigError` naming the file and the offending key.
    """
    port_map = parse_ports(ports)
    routes: dict[tuple[str, str], np.ndarray] = {}
    for key, body in dict(doc.get("routes", {})).items():
        where = f"{source} [routes.{key}]"
        parts = key.split("-")
        if len(parts) != 2 or not all(parts):
            raise ScenarioConfigError(f"{where}: route keys are ORIGIN-DEST UN/LOCODEs")
        o, d = parts
        for code in (o, d):
            if code not in port_map:
                raise ScenarioConfigError(f"{where}: port {code} is not in ports.csv")
        try:
            wp = np.asarray(body["waypoints"], dtype=float)
        except (KeyError, TypeError, ValueError):
            raise ScenarioConfigError(f"{where}: needs waypoints = [[lat, lon], ...]") from None
        if wp.ndim != 2 or wp.shape[1] != 2 or len(wp) < 2:
            raise ScenarioConfigError(f"{where}: waypoints must be at least two [lat, lon] pairs")
        if np.any(np.abs(wp[:, 0]) > 90) or np.any(np.abs(wp[:, 1]) > 180):
            raise ScenarioConfigError(f"{where}: waypoint out of range")
        for end, code in ((wp[0], o), (wp[-1], d)):
            p = port_map[code]
            if haversine_nmi(end[0], end[1], p.approach_lat_deg, p.approach_lon_deg) > 0.1:
                raise ScenarioConfigError(
                    f"{where}: must start/end at the approach point of {code} "
                    f"({p.approach_lat_deg}, {p.approach_lon_deg}), got ({end[0]}, {end[1]})"
                )
        if (d, o) in routes:
            raise ScenarioConfigError(f"{where}: the reverse route {d}-{o} is already defined")
        routes[(o, d)] = wp

    services: dict[str, Service] = {}
    for i, body in enumerate(doc.get("services", [])):
        sid = body.get("id")
        where = f"{source} [[services]] #{i + 1} ({sid})"
        if not sid or sid in services:
            raise ScenarioConfigError(f"{where}: every service needs a unique id")
        vclass = body.get("vessel_class")
        if vclass not in VESSEL_CLASSES:
            raise ScenarioConfigError(f"{where}: vessel_class must be one of {VESSEL_CLASSES}, got {vclass!r}")
        rotation = tuple(body.get("rotation", ()))
        if len(rotation) < 2 or any(p not in port_map for p in rotation):
            raise ScenarioConfigError(f"{where}: rotation must list at least two ports of ports.csv")
        hours = tuple(int(h) for h in body.get("departure_hours_utc", ()))
        if any(not 0 <= h < 24 for h in hours):
            raise ScenarioConfigError(f"{where}: departure_hours_utc must be 0-23")
        prob = float(body.get("anchorage_wait_prob", 0.0))
        if not 0 <= prob <= 1:
            raise ScenarioConfigError(f"{where}: anchorage_wait_prob must be in [0, 1]")
        svc = Service(
            id=sid,
            name=str(body.get("name", sid)),
            vessel_class=vclass,
            rotation=rotation,
            stay_h=_pair(body.get("stay_h", (2.0, 4.0)), "stay_h", where),
            departure_hours_utc=tuple(sorted(hours)),
            anchorage_wait_prob=prob,
            anchorage_wait_h=_pair(body.get("anchorage_wait_h", (3.0, 12.0)), "anchorage_wait_h", where),
        )
        services[sid] = svc

    spec_partial = ScenarioSpec(port_map, routes, services, ())
    for svc in services.values():
        for o, d in svc.legs():
            try:
                spec_partial.route(o, d)
            except ScenarioConfigError:
                raise ScenarioConfigError(f"{source} service {svc.id}: no route for the leg {o}-{d}") from None

    vessels = []
    seen = set()
    fields_ = VesselSpec.__dataclass_fields__
    for i, body in enumerate(doc.get("vessels", [])):
        where = f"{source} [[vessels]] #{i + 1} ({body.get('name', '?')})"
        unknown = set(body) - set(fields_)
        if unknown:
            raise ScenarioConfigError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}")
        try:
            v = VesselSpec(**body)
        except TypeError as err:
            raise ScenarioConfigError(f"{where}: {err}") from None
        problem = mmsi_problem(v.mmsi)
        if problem:
            raise ScenarioConfigError(f"{where}: MMSI {v.mmsi} is {problem}")
        if v.mmsi in seen:
            raise ScenarioConfigError(f"{where}: MMSI {v.mmsi} used twice")
        seen.add(v.mmsi)
        if v.flag not in MED_MIDS or v.mmsi // 1_000_000 not in MED_MIDS[v.flag]:
            raise ScenarioConfigError(f"{where}: MMSI {v.mmsi} does not carry a MID of flag {v.flag}")
        if not imo_check_digit_ok(v.imo):
            raise ScenarioConfigError(f"{where}: IMO {v.imo} fails the check digit")
        if v.service not in services:
            raise ScenarioConfigError(f"{where}: unknown service {v.service!r}")
        if v.ais_format not in AIS_FORMATS:
            raise ScenarioConfigError(f"{where}: ais_format must be one of {AIS_FORMATS}")
        if not 1 <= v.ship_type <= 99:
            raise ScenarioConfigError(f"{where}: ship_type must be an AIS code 1-99")
        if abs(v.to_bow + v.to_stern - v.length_m) > 1 or abs(v.to_port + v.to_starboard - v.beam_m) > 1:
            raise ScenarioConfigError(f"{where}: to_bow+to_stern must match length_m and to_port+to_starboard beam_m (within 1 m)")
        if not 3.0 <= v.service_speed_kn <= 40.0:
            raise ScenarioConfigError(f"{where}: service_speed_kn must be 3-40")
        vessels.append(v)
    if not vessels:
        raise ScenarioConfigError(f"{source}: no [[vessels]]")
    return ScenarioSpec(port_map, routes, services, tuple(vessels))


@dataclass(frozen=True)
class ScenarioSettings:
    """Knobs of the generator; the defaults make the demo scenario (see the module notes)."""

    seed: int = 0
    start_utc: pd.Timestamp = DEFAULT_START_UTC
    days: float = DEFAULT_DAYS
    underway_interval_s: int = 60
    berth_interval_s: int = 180
    interval_jitter_s: int = 4
    static_interval_s: int = 1800  # NMEA message 5 (class A sends it every 6 min; thinned)
    gps_noise_m: float = 8.0
    sog_noise_kn: float = 0.1
    cog_noise_deg: float = 0.8
    heading_noise_deg: float = 0.7
    harbour_speed_kn: float = 8.0
    voyage_speed_sd_frac: float = 0.025  # voyage-to-voyage speed spread
    along_track_speed_sd_frac: float = 0.015  # slow fluctuation within a voyage
    keep_right_nmi: float = 0.5
    lateral_sd_nmi: float = 0.6
    lateral_max_nmi: float = 2.0
    waypoint_jitter_nmi: float = 0.25
    anchorage_dist_nmi: float = 1.5
    gap_prob_per_voyage: float = 0.3
    gap_s: tuple[int, int] = (600, 3 * 3600)
    outage_prob_per_vessel: float = 0.25
    outage_s: tuple[int, int] = (6 * 3600, 16 * 3600)
    dirty_rates: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_DIRTY_RATES))
    dirty_min_per_kind: int = 2

    def __post_init__(self):
        start = pd.Timestamp(self.start_utc)
        start = start.tz_localize("UTC") if start.tzinfo is None else start.tz_convert("UTC")
        object.__setattr__(self, "start_utc", start)
        if not self.days > 0:
            raise ScenarioConfigError(f"days must be positive, got {self.days}")
        unknown = set(self.dirty_rates) - set(DIRTY_KINDS)
        if unknown:
            raise ScenarioConfigError(f"unknown dirty kind(s): {', '.join(sorted(unknown))}")

    @property
    def start_s(self) -> int:
        return int((self.start_utc - _EPOCH).total_seconds())

    @property
    def end_s(self) -> int:
        return self.start_s + int(round(self.days * 86400))


# --------------------------------------------------------------------------------------------
# Result
# --------------------------------------------------------------------------------------------


@dataclass
class Scenario:
    """What the generator made.

    Attributes
    ----------
    vessels : DataFrame
        One row per ship: static data (``mmsi``, ``imo``, ``name``, ``callsign``, ``ship_type``,
        ``length_m``, ``beam_m``, ``draught_m``, ...), ``service``, ``vessel_class``, ``ais_format``.
    fixes : DataFrame
        Every true fix the ships reported (``received`` False when a gap swallowed it), with
        ``time_s`` (Unix seconds), position, ``sog_kn``, ``cog_deg``, ``heading_deg``,
        ``nav_status``, ``phase`` (berth/harbour/sea/anchor) and ``voyage_id`` (empty alongside).
    records : DataFrame
        What the writers write, one row per line/message: received fixes, NMEA static messages
        (``msg_type`` 5) and dirty rows (``dirty_kind`` not empty), in output order.
    voyages, port_stays, gaps : DataFrame
        Ground truth for the lanes, voyages and audits.
    """

    settings: ScenarioSettings
    spec: ScenarioSpec
    vessels: pd.DataFrame
    fixes: pd.DataFrame
    records: pd.DataFrame
    voyages: pd.DataFrame
    port_stays: pd.DataFrame
    gaps: pd.DataFrame


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
                   rng, sd_frac: float) -> tuple[np.ndarray, np.ndarray]:
    """Speed (kn) over arc length (nmi): slow at both ends, harbour speed in the harbour legs,
    ramps of up to 3 nmi, and the voyage speed with a slow fluctuation at sea."""
    ds = min(0.05, length / 50.0) if length > 0 else 0.05
    s = np.linspace(0.0, length, max(3, int(math.ceil(length / ds)) + 1))
    v = np.full_like(s, v_h)
    sea0, sea1 = d_h1, length - d_h2
    if sea1 > sea0:
        ramp = min(3.0, (sea1 - sea0) / 4.0)
        knots = np.arange(sea0, sea1 + 15.0, 15.0)
        wobble = np.interp(s, knots, rng.normal(0.0, sd_frac, len(knots)))
        sea_v = v_sea * (1.0 + wobble)
        up = np.clip((s - sea0) / ramp, 0.0, 1.0) if ramp > 0 else (s >= sea0).astype(float)
        down = np.clip((sea1 - s) / ramp, 0.0, 1.0) if ramp > 0 else (s <= sea1).astype(float)
        w = np.minimum(up, down)
        v = v_h + w * (sea_v - v_h)
    # leaving and reaching the berth (or the anchor) slowly
    v = np.minimum(v, 2.5 + np.minimum(s, length - s) * 20.0)
    return s, np.maximum(v, 1.0)


def _move(rng, st: ScenarioSettings, frames: _Frames, path: _Path, t0: float, d_h1: float, d_h2: float,
          v_sea: float, voyage: str) -> tuple[float, float]:
    """Sail ``path`` from time ``t0``; returns (arrival time, time at sea start offset)."""
    s, v = _speed_profile(path.length, d_h1, d_h2, v_sea, st.harbour_speed_kn, rng, st.along_track_speed_sd_frac)
    dt = np.r_[0.0, np.cumsum(np.diff(s) / (0.5 * (v[:-1] + v[1:])))] * 3600.0
    t_arrive = t0 + dt[-1]
    t = _sample_times(rng, t0, t_arrive, st.underway_interval_s, st.interval_jitter_s)
    n = len(t)
    if n:
        sk = np.interp(t - t0, dt, s)
        vk = np.interp(sk, s, v)
        la, lo, cog = path.at(sk)
        dlat, dlon = _noise_offsets_m(rng, n, st.gps_noise_m, la)
        sog = np.maximum(0.0, vk + rng.normal(0.0, st.sog_noise_kn, n))
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


def _sail_vessel(index: int, v: VesselSpec, rank: int, spec: ScenarioSpec, st: ScenarioSettings):
    """All fixes, voyages, port stays and gaps of one ship over the scenario period."""
    rng = np.random.default_rng([st.seed, 1, index])
    svc = spec.services[v.service]
    rot = svc.rotation
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
            t_in, (t_sea0, t_sea1) = _move(rng, st, frames, path, t_dep, d_h1, d_h2, v_sea, vid)
            sea_len = path.length - d_h1 - d_h2
        else:
            pts = np.vstack([[lat_b, lon_b], sea_wp, [anchorage[0], anchorage[1]]])
            path = _Path(pts[:, 0], pts[:, 1])
            d_h2 = haversine_nmi(p_d.approach_lat_deg, p_d.approach_lon_deg, *anchorage)
            t_anchor, (t_sea0, t_sea1) = _move(rng, st, frames, path, t_dep, d_h1, d_h2, v_sea, vid)
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


# --------------------------------------------------------------------------------------------
# Records: what gets written, dirty rows included
# --------------------------------------------------------------------------------------------

_RECORD_COLUMNS = [
    "mmsi", "time_s", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status", "msg_type",
    "channel", "fmt", "vessel_index", "voyage_id", "destination", "eta_s", "draught_m", "dirty_kind",
    "dirty_detail", "time_text", "sort_s", "sort_sub",
]


def _quantise(df: pd.DataFrame) -> pd.DataFrame:
    """Round to what AIS carries: 1/10 000 min positions, 0.1 kn, 0.1 deg, whole-degree heading."""
    df["lat_deg"] = np.round(df["lat_deg"].to_numpy() * 600000.0) / 600000.0
    df["lon_deg"] = np.round(df["lon_deg"].to_numpy() * 600000.0) / 600000.0
    df["sog_kn"] = np.round(np.minimum(df["sog_kn"].to_numpy(), 102.2), 1)
    df["cog_deg"] = np.round(df["cog_deg"].to_numpy(), 1) % 360.0
    df["heading_deg"] = np.round(df["heading_deg"].to_numpy()) % 360.0
    return df


def _voyage_context(records: pd.DataFrame, voyages: pd.DataFrame, spec: ScenarioSpec) -> pd.DataFrame:
    """Destination, ETA and draught as the crew would have typed them at each record's time."""
    records["destination"] = ""
    records["eta_s"] = np.int64(-1)
    records["draught_m"] = np.nan
    if voyages.empty:
        return records
    for mmsi, idx in records.groupby("mmsi").groups.items():
        vv = voyages[voyages.mmsi == mmsi].sort_values("depart_s")
        if vv.empty:
            continue
        t = records.loc[idx, "time_s"].to_numpy()
        # the voyage in progress or the next one: first voyage whose arrival is after t
        j = np.searchsorted(vv["arrive_s"].to_numpy(), t, side="right")
        j = np.clip(j, 0, len(vv) - 1)
        names = np.array([spec.ports[p].ais_destination for p in vv["dest"]], dtype=object)
        records.loc[idx, "destination"] = names[j]
        records.loc[idx, "eta_s"] = np.round(vv["arrive_s"].to_numpy()[j] / 60.0).astype(np.int64) * 60
        records.loc[idx, "draught_m"] = vv["draught_m"].to_numpy()[j]
    return records


def _static_records(rng, st: ScenarioSettings, fixes: pd.DataFrame, vessels: pd.DataFrame) -> pd.DataFrame:
    """NMEA message 5 (static and voyage data) every ``static_interval_s`` while received."""
    out = []
    for vi, v in vessels.iterrows():
        if v["ais_format"] != "nmea":
            continue
        fx = fixes[(fixes.mmsi == v["mmsi"]) & fixes.received]
        if fx.empty:
            continue
        t = _sample_times(rng, st.start_s, st.end_s, st.static_interval_s, 30)
        # keep only times when the transponder was heard (a received fix within 10 min)
        ft = fx["time_s"].to_numpy()
        j = np.clip(np.searchsorted(ft, t), 1, len(ft) - 1)
        near = np.minimum(np.abs(ft[j] - t), np.abs(ft[j - 1] - t)) <= 600
        t = t[near]
        if len(t) == 0:
            continue
        t = t[~np.isin(t, ft)]  # never share a second with a position report of the same ship
        out.append(pd.DataFrame({"mmsi": np.int64(v["mmsi"]), "time_s": t, "msg_type": 5, "vessel_index": vi}))
    if not out:
        return pd.DataFrame(columns=["mmsi", "time_s", "msg_type", "vessel_index"])
    return pd.concat(out, ignore_index=True)


def _pick_bases(rng, eligible: np.ndarray, n: int) -> np.ndarray:
    """``n`` distinct indices drawn from the True entries of ``eligible`` (sorted)."""
    pool = np.flatnonzero(eligible)
    n = min(n, len(pool))
    if n == 0:
        return np.empty(0, dtype=np.int64)
    return np.sort(rng.choice(pool, size=n, replace=False))


def _bad_mmsi(rng, mmsi: int) -> int:
    variant = rng.integers(0, 4)
    if variant == 0:  # a digit lost: 8 digits
        return mmsi // 10
    if variant == 1:  # MID 111: SAR aircraft, not a ship
        return 111_000_000 + mmsi % 1_000_000
    if variant == 2:  # MID 970: AIS-SART, not a ship
        return 970_000_000 + mmsi % 1_000_000
    return mmsi % 10_000_000  # leading digits lost: 7 digits


_BAD_TIMES = ("32/01/2025 10:00:00", "{d}/13/2025 07:15:00", "{d}/01/2025 25:61:00", "", "not-a-time",
              "2025-01-{d}T??:00:00", "00/00/0000 00:00:00")


def _inject_dirty(rng, st: ScenarioSettings, recs: pd.DataFrame) -> pd.DataFrame:
    """Add dirty rows to the clean position records (see :data:`DIRTY_KINDS`).

    ``recs`` must be sorted by mmsi and time with a fresh RangeIndex.
    """
    # a record can seed a dirty row when it is an under-way position report at sea with its
    # neighbours (same ship) 50-70 s away, so an injected row between them is unambiguous
    t = recs["time_s"].to_numpy()
    m = recs["mmsi"].to_numpy()
    same_prev = np.r_[False, m[1:] == m[:-1]]
    same_next = np.r_[same_prev[1:], False]
    gap_prev = np.r_[0, np.diff(t)]
    gap_next = np.r_[np.diff(t), 0]
    base_ok = (
        same_prev & same_next & (gap_prev >= 50) & (gap_prev <= 70) & (gap_next >= 50) & (gap_next <= 70)
        & (recs["phase"].to_numpy() == "sea") & (recs["msg_type"].to_numpy() != 5)
    )
    used = np.zeros(len(recs), bool)
    extra = []
    for fmt in AIS_FORMATS:
        in_fmt = (recs["fmt"].to_numpy() == fmt) & (recs["msg_type"].to_numpy() != 5)
        n_fmt = int(in_fmt.sum())
        if n_fmt == 0:
            continue
        for kind in FORMAT_KINDS[fmt]:
            rate = float(st.dirty_rates.get(kind, 0.0))
            if rate <= 0:
                continue
            n = max(st.dirty_min_per_kind, int(round(rate * n_fmt)))
            bases = _pick_bases(rng, base_ok & in_fmt & ~used, n)
            used[bases] = True
            k = len(bases)
            if k == 0:
                continue
            if kind == "sentinel_fields":
                which = rng.integers(1, 8, k)  # bit mask over SOG / COG / heading
                sog, cog, hdg = (which & 1) > 0, (which & 2) > 0, (which & 4) > 0
                recs.loc[bases[sog], "sog_kn"] = 102.3
                recs.loc[bases[cog], "cog_deg"] = 360.0
                recs.loc[bases[hdg], "heading_deg"] = 511.0
                recs.loc[bases, "dirty_kind"] = kind
                recs.loc[bases, "dirty_detail"] = [
                    ",".join(n for n, f in (("sog_kn", a), ("cog_deg", b), ("heading_deg", c)) if f)
                    for a, b, c in zip(sog, cog, hdg)
                ]
                continue
            sub = recs.loc[bases].copy()
            sub["dirty_kind"] = kind
            sub["sort_sub"] = 1
            delta = rng.integers(15, 36, k)
            lat, lon = sub["lat_deg"].to_numpy(), sub["lon_deg"].to_numpy()
            if kind == "sentinel_position":
                sub["lat_deg"], sub["lon_deg"] = 91.0, 181.0
                sub["time_s"] += delta
                sub["dirty_detail"] = "lat=91,lon=181"
            elif kind == "out_of_range":
                on_lat = rng.random(k) < 0.5
                sign = rng.choice([-1.0, 1.0], k)
                bad_lat = np.round(rng.uniform(92.0, 99.0, k), 4) * sign
                bad_lon = np.round(rng.uniform(182.0, 199.0, k), 4) * sign
                sub["lat_deg"] = np.where(on_lat, bad_lat, lat)
                sub["lon_deg"] = np.where(on_lat, lon, bad_lon)
                sub["time_s"] += delta
                sub["dirty_detail"] = [f"lat={a}" if f else f"lon={b}" for f, a, b in zip(on_lat, bad_lat, bad_lon)]
            elif kind == "invalid_mmsi":
                bad = [_bad_mmsi(rng, int(x)) for x in sub["mmsi"]]
                sub["mmsi"] = np.asarray(bad, dtype=np.int64)
                sub["vessel_index"] = -1
                sub["dirty_detail"] = [f"mmsi={x}" for x in bad]
            elif kind == "bad_timestamp":
                texts = [_BAD_TIMES[i].format(d=f"{d:02d}") for i, d in
                         zip(rng.integers(0, len(_BAD_TIMES), k), rng.integers(1, 29, k))]
                sub["time_text"] = texts
                sub["dirty_detail"] = [f"timestamp={x!r}" for x in texts]
            elif kind == "speed_jump":
                dist = rng.uniform(20.0, 45.0, k)
                sub["lat_deg"], sub["lon_deg"] = destination_point(lat, lon, rng.uniform(0, 360, k), dist)
                sub["time_s"] += delta
                sub["dirty_detail"] = [f"jump {d:.1f} nmi in {s} s" for d, s in zip(dist, delta)]
            elif kind == "duplicate_exact":
                sub["dirty_detail"] = "copy of the previous report"
            elif kind == "duplicate_timestamp":
                dist = rng.uniform(0.03, 0.15, k)
                sub["lat_deg"], sub["lon_deg"] = destination_point(lat, lon, rng.uniform(0, 360, k), dist)
                sub["sog_kn"] = np.maximum(0.0, sub["sog_kn"].to_numpy() + rng.choice([-0.4, 0.3], k))
                sub["dirty_detail"] = [f"same second, {d * METRES_PER_NMI:.0f} m apart" for d in dist]
            elif kind == "malformed_row":
                sub["dirty_detail"] = "line cut short"
            elif kind == "bad_checksum":
                sub["time_s"] += delta
                sub["dirty_detail"] = "payload corrupted, checksum mismatch"
            extra.append(sub)
    if extra:
        recs = pd.concat([recs, *extra], ignore_index=True)
    return recs


def generate_scenario(spec: ScenarioSpec, settings: ScenarioSettings | None = None) -> Scenario:
    """Sail the fleet of ``spec`` over the period of ``settings``; deterministic by seed.

    Parameters
    ----------
    spec : ScenarioSpec
        Ports, routes, services and fleet (:func:`parse_scenario_spec`).
    settings : ScenarioSettings, optional
        Seed, period, cadences, noise and dirty-row rates; defaults make the demo scenario.

    Returns
    -------
    Scenario
        Truth tables and the records to write.

    Examples
    --------
    >>> import pandas as pd
    >>> ports = pd.DataFrame({"locode": ["ESBCN", "ESPMI"], "name": ["Barcelona", "Palma"],
    ...     "lat_deg": [41.352, 39.56], "lon_deg": [2.17, 2.63],
    ...     "approach_lat_deg": [41.31, 39.52], "approach_lon_deg": [2.22, 2.62]})
    >>> doc = {"routes": {"ESBCN-ESPMI": {"waypoints": [[41.31, 2.22], [39.62, 2.20], [39.44, 2.36],
    ...        [39.40, 2.53], [39.52, 2.62]]}},
    ...        "services": [{"id": "S", "vessel_class": "ro-pax", "rotation": ["ESBCN", "ESPMI"]}],
    ...        "vessels": [{"mmsi": 224087350, "imo": 9412220, "name": "A", "callsign": "EAKQ", "flag": "ES",
    ...        "service": "S", "ship_type": 60, "length_m": 186, "beam_m": 26, "draught_m": 6.6,
    ...        "dwt_t": 7200, "service_speed_kn": 21, "to_bow": 150, "to_stern": 36, "to_port": 13,
    ...        "to_starboard": 13}]}
    >>> sc = generate_scenario(parse_scenario_spec(doc, ports), ScenarioSettings(days=1))
    >>> len(sc.voyages) >= 2
    True
    """
    st = settings or ScenarioSettings()
    vessel_rows = []
    all_fixes, all_voyages, all_stays, all_gaps = [], [], [], []
    rank_in_service: dict[str, int] = {}
    for i, v in enumerate(spec.vessels):
        rank = rank_in_service.get(v.service, 0)
        rank_in_service[v.service] = rank + 1
        fx, voy, stays, gaps = _sail_vessel(i, v, rank, spec, st)
        all_fixes.append(fx)
        all_voyages += voy
        all_stays += stays
        all_gaps += gaps
        row = {k: getattr(v, k) for k in VesselSpec.__dataclass_fields__}
        row["vessel_class"] = spec.services[v.service].vessel_class
        vessel_rows.append(row)
    vessels = pd.DataFrame(vessel_rows)
    fixes = pd.concat(all_fixes, ignore_index=True)
    fixes = _quantise(fixes)
    voyages = pd.DataFrame(all_voyages)
    stays = pd.DataFrame(all_stays)
    gaps = pd.DataFrame(all_gaps, columns=["mmsi", "kind", "start_s", "end_s", "fixes_lost"])

    rng = np.random.default_rng([st.seed, 2])
    fmt_of = dict(zip(vessels["mmsi"], vessels["ais_format"]))
    idx_of = {m: i for i, m in enumerate(vessels["mmsi"])}
    recs = fixes[fixes.received].drop(columns=["received"]).copy()
    recs["msg_type"] = np.where(rng.random(len(recs)) < 0.15, 3, 1)  # some "special" position reports
    static = _static_records(rng, st, fixes, vessels)
    if len(static):
        static["phase"] = ""
        static["voyage_id"] = ""
        recs = pd.concat([recs, static], ignore_index=True)
    recs["fmt"] = recs["mmsi"].map(fmt_of)
    recs["vessel_index"] = recs["mmsi"].map(idx_of).astype(np.int64)
    recs["channel"] = np.where(rng.random(len(recs)) < 0.5, "A", "B")
    recs["dirty_kind"] = ""
    recs["dirty_detail"] = ""
    recs["time_text"] = ""  # only read for dirty_kind == "bad_timestamp"
    recs["sort_s"] = recs["time_s"]
    recs["sort_sub"] = 0
    recs = recs.sort_values(["mmsi", "time_s"], kind="stable").reset_index(drop=True)
    recs = _inject_dirty(rng, st, recs)
    recs = _voyage_context(recs, voyages, spec)
    recs["time_s"] = recs["time_s"].astype(np.int64)
    recs["sort_s"] = recs["sort_s"].astype(np.int64)
    # output order: by time; an injected copy follows its original
    recs = recs.sort_values(["sort_s", "mmsi", "sort_sub"], kind="stable").reset_index(drop=True)
    recs = recs[[c for c in _RECORD_COLUMNS if c in recs.columns] + ["phase"]]
    for col in ("sog_kn", "cog_deg", "heading_deg"):
        recs[col] = recs[col].astype(float)
    recs["nav_status"] = recs["nav_status"].fillna(-1).astype(np.int64)
    return Scenario(st, spec, vessels, fixes, recs, voyages, stays, gaps)


def with_settings(settings: ScenarioSettings, **changes) -> ScenarioSettings:
    """A copy of ``settings`` with some fields changed (validated again)."""
    return replace(settings, **changes)


def to_utc(seconds) -> pd.DatetimeIndex | pd.Timestamp:
    """Unix seconds to tz-aware UTC timestamps."""
    return pd.to_datetime(seconds, unit="s", utc=True)
