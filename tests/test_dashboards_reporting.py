"""Glue from flow results to the report model (pipelines/reporting.py)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from pipelines.reporting import limits_for_report, provenance, routes_bbox, speed_loss_curve, weather_snapshot, worst_point
from routing.route import Route
from thresholds.operator import OperatorLimits
from thresholds.vessel import Vessel

VESSEL = Vessel(name="feeder", vessel_class="container", speed_kn=16.0, lpp_m=150.0, beam_m=25.0, draught_m=8.0, dwt_t=12000.0,
                installed_power_kw=10000.0, design_speed_kn=18.0, engine_rpm=500.0, sfoc_g_kwh=200.0, min_speed_kn=2.0)


def dataset():
    times = pd.date_range("2025-01-31T00:00", periods=3, freq="3h")  # naive = UTC in the canonical Dataset
    lat = np.array([39.0, 39.5, 40.0, 40.5, 41.0])
    lon = np.array([1.0, 1.5, 2.0, 2.5, 3.0, 3.5])
    hs = np.arange(3 * 5 * 6, dtype=float).reshape(3, 5, 6)
    wave = np.full((3, 5, 6), 300.0)
    return xr.Dataset({"hs_m": (("time_utc", "lat", "lon"), hs), "wave_from_deg": (("time_utc", "lat", "lon"), wave)},
                      coords={"time_utc": times, "lat": lat, "lon": lon}, attrs={"product": "cmems-test", "source_files": ["a.nc", "b.nc"]})


def test_weather_snapshot_nearest_time_and_box():
    snap = weather_snapshot(dataset(), pd.Timestamp("2025-01-31T04:00Z"), bbox=(2.0, 2.5, 39.5, 40.0), pad_deg=0.5)
    assert snap.time_utc == pd.Timestamp("2025-01-31T03:00Z")  # nearest of 00, 03, 06
    np.testing.assert_array_equal(snap.lat_deg, [39.0, 39.5, 40.0, 40.5])
    np.testing.assert_array_equal(snap.lon_deg, [1.5, 2.0, 2.5, 3.0])
    # hs[t=1, lat 0..3, lon 1..4] of the arange: 30 + 6*i + j
    np.testing.assert_array_equal(snap.hs_m, 30 + 6 * np.arange(4)[:, None] + np.arange(1, 5)[None, :])
    assert snap.wave_from_deg.shape == (4, 4) and snap.product == "cmems-test"


def test_speed_loss_curve_bowditch_by_hand():
    curve = speed_loss_curve(VESSEL, "bowditch", hs_max_m=8.0, step_m=1.0, angles_deg=(0.0, 90.0, 180.0))
    t = curve.table
    assert sorted(t["encounter_deg"].unique()) == [0.0, 90.0, 180.0]
    h_ft = 2.0 / 0.3048  # Bowditch: v = v0 - f H^2, H in feet; f = 0.0248 head, 0.0165 beam, 0.0083 following
    for angle, f in ((0.0, 0.0248), (90.0, 0.0165), (180.0, 0.0083)):
        v = t[(t["encounter_deg"] == angle) & (t["hs_m"] == 2.0)]["speed_kn"].item()
        assert v == pytest.approx(16.0 - f * h_ft**2, abs=1e-9)
    # Head seas at 8 m: 16 - 0.0248 * 26.25^2 < 2 -> the floor.
    assert t[(t["encounter_deg"] == 0.0) & (t["hs_m"] == 8.0)]["speed_kn"].item() == pytest.approx(2.0)
    assert curve.speed_kn == 16.0 and curve.min_speed_kn == 2.0 and curve.model == "bowditch"


def test_limits_provenance_and_worst_point():
    lim = OperatorLimits(name="container, Lpp < 200 m", hs_max_m=4.5, wind_max_ms=19.0, period_max_s=8.0, beam_sectors_deg=((60, 120), (240, 300)))
    out = limits_for_report(lim)
    assert out["hs_m"] == 4.5 and out["wind_ms"] == 19.0 and out["period_max_s"] == 8.0
    assert out["beam_sectors_deg"] == "60-120, 240-300"
    prov = provenance(weather_ds=dataset(), vessel=VESSEL, speed_loss_model="bowditch", limits=lim, weather_source="local files")
    assert prov.weather_products == ["cmems-test"] and prov.weather_files == ["a.nc", "b.nc"]
    assert prov.weather_start_utc == pd.Timestamp("2025-01-31T00:00Z") and prov.weather_end_utc == pd.Timestamp("2025-01-31T06:00Z")
    assert prov.thresholds_profile == "container, Lpp < 200 m" and prov.vessel["name"] == "feeder"
    r = Route("historical", [40.0, 40.5, 41.0], [2.0, 2.2, 2.4], pd.date_range("2025-01-31", periods=3, freq="h", tz="UTC"), [10.0, 10.0],
              weather={"hs_m": [1.0, 5.5, np.nan]})
    w = worst_point(r)
    assert (w["lat_deg"], w["lon_deg"], w["hs_m"]) == (40.5, 2.2, 5.5) and w["time_utc"] == pd.Timestamp("2025-01-31T01:00Z")
    assert routes_bbox({"a": r}) == (2.0, 2.4, 40.0, 41.0)


def test_lane_departure_model_adverse_and_failed():
    from dashboards.model import LaneDeparture
    from pipelines.reporting import lane_departure_model
    from routing.audit import audit_routes

    t0 = pd.Timestamp("2025-01-31T00:00Z")

    def weather(times, lat, lon):
        lat = np.asarray(lat, dtype=float)
        return {"hs_m": np.where(lat < 40.25, 5.0, 1.0), "wave_from_deg": np.full(lat.size, 270.0), "tm_s": np.full(lat.size, 5.0)}

    def straight(lat, name):
        return Route(name, [lat] * 3, [1.5, 2.25, 3.0], t0 + pd.to_timedelta([0.0, 2.9, 5.8], unit="h"), [12.0, 12.0])

    out = audit_routes(straight(40.0, "as_sailed"), weather, VESSEL, limits=OperatorLimits(name="t", hs_max_m=4.5),
                       alternatives={"deviation": straight(40.5, "deviation")})
    dep = lane_departure_model(lane_id=3, origin="Barcelona", destination="Palma", depart_utc=t0, rules=["hs_m 5.0 > 4.5"],
                               evaluations=out["evaluations"], table=out["table"], proposed=out["proposed"], weather_ds=dataset())
    assert isinstance(dep, LaneDeparture) and dep.status == "adverse" and dep.lane_id == "3"
    assert dep.worst_hs_m == 5.0 and dep.worst_lat_deg == 40.0 and dep.worst_time_utc == t0  # first point of the highest Hs
    assert dep.routes.proposed == "deviation" and set(dep.routes.routes) == {"as_sailed", "deviation"}
    snap = dep.routes.weather
    assert snap.time_utc == pd.Timestamp("2025-01-31T00:00Z")  # nearest step to the worst time
    assert snap.lon_deg.min() >= 1.5 - 1.0 and snap.lat_deg.max() <= 40.5 + 1.0
    failed = lane_departure_model(lane_id="L9", origin="Genoa", destination="Tunis", depart_utc=t0, error="NoRouteError: unreachable")
    assert failed.status == "failed" and failed.error == "NoRouteError: unreachable" and failed.routes is None


def test_hs_plot_profile_shows_the_peak_a_long_leg_crosses_between_waypoints():
    from dashboards import model as report_model
    from dashboards import model_json
    from dashboards.plots import series_png
    from pipelines.reporting import route_set_from_evaluations
    from routing.evaluate import evaluate_route

    t0 = pd.Timestamp("2025-01-31T00:00Z")

    def weather(times, lat, lon):
        lon = np.asarray(lon, dtype=float)
        # a 7 m peak at 2.25 E, 1.5 m elsewhere: both waypoints of the long leg are calm
        return {"hs_m": 1.5 + 5.5 * np.exp(-(((lon - 2.25) / 0.1) ** 2)), "wave_from_deg": np.full(lon.size, 270.0)}

    route = Route("historical", [40.0, 40.0], [1.5, 3.0], t0 + pd.to_timedelta([0.0, 5.8], unit="h"), [12.0])
    ev = evaluate_route(route, weather, VESSEL)
    rs = route_set_from_evaluations({"historical": ev})
    prof = rs.profiles["historical"]
    assert len(prof) == len(ev.samples) == 24  # 5.8 h in pieces of at most 15 min
    assert prof["hs_m"].max() == pytest.approx(ev.summary["max_hs_m"], abs=1e-3) and prof["hs_m"].max() > 6.0
    assert np.nanmax(ev.route.weather["hs_m"]) < 1.6  # what a plot of the waypoints alone would show
    # the plot draws the profile (a different image than from the waypoints), and the profiles
    # survive the model's JSON codec (report.json, re-rendered by `stormlane report`)
    assert series_png(rs.routes, profiles=rs.profiles) != series_png(rs.routes)
    back = model_json._decode(model_json._encode(rs))
    pd.testing.assert_frame_equal(back.profiles["historical"], prof, check_dtype=False)
    with pytest.raises(report_model.ReportError, match=r"profiles\['optimal'\] has no route"):
        report_model.RouteSet(routes=rs.routes, profiles={"optimal": prof})
    with pytest.raises(report_model.ReportError, match="columns time_utc and hs_m"):
        report_model.RouteSet(routes=rs.routes, profiles={"historical": prof.rename(columns={"hs_m": "h"})})
