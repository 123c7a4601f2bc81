"""The demo scenario's configuration (ports, services, vessels; ``data/scenario.toml`` and
``data/ports.csv`` parsed and checked), its settings (seed, period, cadence, noise, dirty-row
rates) and the result it produces. See :mod:`scenario.generator` for how the traffic is made."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
import pandas as pd

from thresholds.errors import StormlaneError
from thresholds.geodesy import haversine_nmi


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
    # Long by design: one check per field of the scenario file, in the file's order, each
    # naming the file, section and field of a bad value.
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
    along_track_speed_sd_frac: float = 0.015  # slow fluctuation within a voyage (calm water: it stands in for the weather)
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
