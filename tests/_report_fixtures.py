"""A small, deterministic report model for the renderer tests (a TEST FIXTURE, not a result).

Barcelona -> Palma, a Gaussian storm on an 0.1-degree grid west of Mallorca, four routes with
hand-picked waypoints; the weather met at each waypoint is read off the same analytic field;
the metrics tables are typed in by hand. Nothing here is presented as a computed result: the
report title says so.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from thresholds import land_raster as globe  # the package's 30" mask through its cache

from dashboards.model import LaneDeparture, LaneLine, NightlyReport, Provenance, RouteSet, SpeedLossCurve, VoyageAudit, WeatherSnapshot
from routing.route import Route

T0 = pd.Timestamp("2025-01-31T06:00Z")
STORM_LAT, STORM_LON = 40.3, 2.4


def storm_hs(lat, lon):
    """Analytic storm: 1 m background plus a 5.5 m Gaussian bump. [m]"""
    return 1.0 + 5.5 * np.exp(-((lat - STORM_LAT) ** 2 / 0.3 + (lon - STORM_LON) ** 2 / 0.5))


def snapshot() -> WeatherSnapshot:
    lat = np.round(np.arange(38.8, 42.01, 0.1), 3)
    lon = np.round(np.arange(0.0, 4.51, 0.1), 3)
    lat_g, lon_g = np.meshgrid(lat, lon, indexing="ij")
    hs = storm_hs(lat_g, lon_g)
    hs[globe.is_land(lat_g, lon_g)] = np.nan
    wave_from = np.full(hs.shape, 330.0)
    wave_from[np.isnan(hs)] = np.nan
    return WeatherSnapshot(time_utc=T0 + pd.Timedelta(hours=6), lat_deg=lat, lon_deg=lon, hs_m=hs, wave_from_deg=wave_from, product="fixture: analytic storm")


def make_route(name, lat, lon, speed_kn, t0=T0) -> Route:
    lat = np.asarray(lat, dtype=float)
    lon = np.asarray(lon, dtype=float)
    speed = np.asarray(speed_kn, dtype=float)
    # Leg times from an equirectangular distance (fixture only; not a project function).
    dy = np.diff(lat) * 60.0
    dx = np.diff(lon) * 60.0 * np.cos(np.deg2rad(0.5 * (lat[1:] + lat[:-1])))
    hours = np.hypot(dx, dy) / speed
    times = t0 + pd.to_timedelta(np.concatenate([[0.0], np.cumsum(hours)]), unit="h")
    return Route(name=name, lat_deg=lat, lon_deg=lon, time_utc=pd.DatetimeIndex(times), leg_speed_kn=speed,
                 weather={"hs_m": storm_hs(lat, lon), "wave_from_deg": np.full(lat.size, 330.0)},
                 properties={"origin": "Barcelona", "destination": "Palma"})


def routes(t0=T0) -> dict:
    return {
        "historical": make_route("historical", [41.30, 40.5, 39.75, 39.45, 39.52], [2.25, 2.2, 2.25, 2.45, 2.62], [14.0, 11.5, 13.0, 15.0], t0),
        "deviation": make_route("deviation", [41.30, 40.5, 39.8, 39.45, 39.52], [2.25, 1.6, 1.9, 2.45, 2.62], [15.0, 14.5, 15.0, 15.5], t0),
        "optimal": make_route("optimal", [41.30, 40.9, 40.3, 39.7, 39.45, 39.52], [2.25, 1.8, 1.35, 1.95, 2.45, 2.62], [16.0, 15.8, 15.6, 15.5, 15.9], t0),
        "min_distance": make_route("min_distance", [41.30, 40.4, 39.6, 39.52], [2.25, 2.2, 2.3, 2.62], [13.0, 10.5, 12.0], t0),
    }


METRICS = pd.DataFrame(
    {
        "time_h": [9.10, 8.20, 8.00, 9.60],
        "dist_nmi": [111.0, 121.0, 126.0, 106.0],
        "max_hs_m": [6.31, 3.20, 2.90, 6.40],
        "fuel_t": [30.0, 28.5, 29.1, 32.4],
        "co2_t": [93.6, 88.9, 90.8, 101.1],
        "n_safety_events": [3, 0, 0, 4],
    },
    index=["historical", "deviation", "optimal", "min_distance"],
)

EVENTS = pd.DataFrame(
    {
        "route": ["historical", "historical", "historical", "min_distance"],
        "criterion": ["surf-riding/broaching", "parametric roll", "operator hs_m > 4.5", "operator hs_m > 4.5"],
        "start_utc": pd.to_datetime(["2025-01-31T10:00Z", "2025-01-31T10:30Z", "2025-01-31T09:40Z", "2025-01-31T09:50Z"], utc=True),
        "end_utc": pd.to_datetime(["2025-01-31T11:00Z", "2025-01-31T11:15Z", "2025-01-31T12:10Z", "2025-01-31T12:30Z"], utc=True),
        "duration_h": [1.0, 0.75, 2.5, 2.67],
    }
)

EXPOSURE = pd.DataFrame({"route": ["historical", "min_distance"], "limit": ["hs_m > 4.5", "hs_m > 4.5"], "exposure_h": [2.5, 2.67]})


def speed_loss() -> SpeedLossCurve:
    hs = np.arange(0.0, 8.01, 0.5)
    rows = []
    for angle, f in ((0.0, 0.0248), (90.0, 0.0165), (180.0, 0.0083)):  # Bowditch-like coefficients, kn/ft^2
        v = np.maximum(16.0 - f * (hs / 0.3048) ** 2, 2.0)
        rows.append(pd.DataFrame({"hs_m": hs, "encounter_deg": angle, "speed_kn": v}))
    return SpeedLossCurve(vessel="container-lt200", model="bowditch", speed_kn=16.0, table=pd.concat(rows, ignore_index=True), min_speed_kn=2.0)


def provenance() -> Provenance:
    return Provenance(
        weather_products=["fixture: analytic storm"],
        weather_files=["(none: test fixture)"],
        weather_start_utc=pd.Timestamp("2025-01-31T00:00Z"),
        weather_end_utc=pd.Timestamp("2025-02-02T00:00Z"),
        weather_source="test fixture",
        ais_sources=["(none: test fixture)"],
        speed_loss_model="bowditch",
        thresholds_profile="container<200m",
        limits={"hs_m": 4.5, "wind_ms": 19.0},
        vessel={"name": "container-lt200", "speed_kn": 16.0, "lpp_m": 180.0},
        software={"stormlane": "test", "numpy": np.__version__},
        methods=["Fixture model built in tests/_report_fixtures.py; numbers are typed in, not computed."],
    )


def route_set(t0=T0, **kw) -> RouteSet:
    rs = routes(t0)
    metrics = METRICS.copy()
    # Time and distance as the fixture routes carry them, so map legend and table agree.
    metrics["time_h"] = [round(rs[r].time_h, 2) for r in metrics.index]
    metrics["dist_nmi"] = [round(rs[r].dist_nmi, 1) for r in metrics.index]
    return RouteSet(routes=rs, metrics=metrics, events=EVENTS.copy(), exposure=EXPOSURE.copy(), weather=snapshot(), proposed="optimal", **kw)


#: The fixture night's rule chips for every adverse case: structured as the screen gives them.
REASONS = [{"rule": "hs", "value": 6.31, "limit": 4.5, "unit": "m", "time_utc": "2025-01-31T10:00:00+00:00", "n_points": 4,
            "text": "hs: 6.31 m > 4.5 m at 2025-01-31T10:00Z, 40.50N 2.20E"},
           {"rule": "surf_riding", "value": 14.2, "limit": 13.1, "time_utc": "2025-01-31T10:30:00+00:00", "n_points": 2,
            "text": "surf_riding: 14.2 kn > 13.1 kn at 2025-01-31T10:30Z, 40.40N 2.21E"}]


def lanes(origin="Barcelona") -> list:
    """Four lanes for the fleet map: L1, L2 (adverse, rerouted), L9 (failed), L4 (no rule fired)."""
    hist = routes()["historical"]
    return [LaneLine("L1", origin, "Palma", "container-lt200", hist.lat_deg, hist.lon_deg),
            LaneLine("L2", origin, "Palma", "container-lt200", hist.lat_deg + 0.05, hist.lon_deg - 0.1),
            LaneLine("L9", "Genoa", "Tunis", "bulk", [41.0, 40.2, 39.0], [3.5, 3.9, 4.2]),
            LaneLine("L4", "Valencia", "Ibiza", "ropax", [39.45, 39.2, 38.9], [0.0, 0.8, 1.4])]


def grid(n_adverse: int) -> pd.DataFrame:
    """One row per lane x departure (3 departures, 3 h apart from ``T0``): lane L<k+1> adverse at
    its k-th departure with case k+1 (3 h at risk avoided, time-optimal proposed); L9 failed at
    ``T0`` (the last case); every other cell passed."""
    rows = []
    ids = [f"L{k + 1}" for k in range(n_adverse)] + ["L9", "L4"]
    for lane in ids:
        for j in range(3):
            t = T0 + pd.Timedelta(hours=3 * j)
            row = {"lane_id": lane, "depart_utc": t, "status": "ok", "rules": "", "risk_h": np.nan, "risk_avoided_h": np.nan,
                   "proposed": None, "case": np.nan}
            if lane == "L9" and j == 0:
                row.update(status="failed", case=float(n_adverse + 1))
            elif lane not in ("L9", "L4") and j == int(lane[1:]) - 1:
                row.update(status="adverse", rules="hs,surf_riding", risk_h=5.5, risk_avoided_h=3.0, proposed="optimal",
                           case=float(j + 1))
            rows.append(row)
    return pd.DataFrame(rows)


def nightly(origin="Barcelona", n_adverse=2) -> NightlyReport:
    deps = []
    for k in range(n_adverse):
        t0 = T0 + pd.Timedelta(hours=3 * k)
        deps.append(
            LaneDeparture(
                lane_id=f"L{k + 1}", origin=origin, destination="Palma", depart_utc=t0, status="adverse",
                rules=["operator: hs_m 6.31 > 4.5", "IMO MSC.1/Circ.1228: surf-riding/broaching"],
                worst_time_utc=t0 + pd.Timedelta(hours=4), worst_lat_deg=40.5, worst_lon_deg=2.2, worst_hs_m=6.31,
                routes=route_set(t0, exports={"RTZ": f"exports/L{k + 1}_optimal.rtz", "GPX": f"exports/L{k + 1}.gpx"}),
                risk_avoided=3.0, events_avoided=3, vessel="container-lt200", reasons=[dict(r) for r in REASONS],
            )
        )
    deps.append(LaneDeparture(lane_id="L9", origin="Genoa", destination="Tunis", depart_utc=T0, status="failed", error="NoRouteError: goal (36.8N 10.3E) unreachable from the mesh"))
    return NightlyReport(
        run_id="fixture-run", started_utc=pd.Timestamp("2025-01-31T02:00:00Z"), finished_utc=pd.Timestamp("2025-01-31T02:00:42Z"),
        now_utc=T0 - pd.Timedelta(hours=6), window_start_utc=T0 - pd.Timedelta(hours=6), window_end_utc=T0 + pd.Timedelta(hours=42),
        departure_step_h=3.0, lanes_checked=7, departures_checked=112, departures=deps, provenance=provenance(), speed_loss=speed_loss(),
        title="stormlane nightly reroute report (TEST FIXTURE)", lanes=lanes(origin), grid=grid(n_adverse),
    )


def audit(ship_name="MV FIXTURE") -> VoyageAudit:
    return VoyageAudit(
        mmsi=224000001, depart_utc=T0, arrive_utc=T0 + pd.Timedelta(hours=9.1), routes=route_set(),
        ship_name=ship_name, callsign="EA1234", ais_destination="PALMA", imo=9000001, ship_type=70, voyage_id="V42",
        origin="Barcelona", destination="Palma", vessel_profile="container-lt200",
        findings=["Fixture finding: the sailed track met Hs 6.31 m, above the 4.5 m limit, for 2.5 h."],
        provenance=provenance(), speed_loss=speed_loss(), generated_utc=pd.Timestamp("2025-02-01T00:00Z"),
        title="stormlane voyage audit (TEST FIXTURE)",
    )
