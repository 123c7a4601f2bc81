"""Routes across the antimeridian: one continuous longitude frame for the mesh, weather read across
the seam (-180..180 and 0..360 products), routes reported in -180..180, a real trans-Pacific route."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from pipelines.routing_weather import field_from_dataset
from routing.astar import ShipModel
from routing.field import WeatherField
from routing.mesh import MeshGrid
from routing.planner import RouteRequest, default_bbox, plan_routes
from thresholds.geodesy import haversine_nmi, intermediate_point

T0 = pd.Timestamp("2024-01-10T00:00Z")


@pytest.mark.parametrize("start,goal", [((30.0, 170.0), (40.0, -165.0)), ((40.0, -165.0), (30.0, 170.0)),
                                        ((-20.0, -172.0), (-35.0, 175.0))])  # fmt: skip
def test_open_ocean_great_circle_across_180_both_ways(start, goal):
    req = RouteRequest(start, goal, T0, ShipModel(15.0, "none"), spacing_deg=0.25, edges=48, ignore_land=True)
    plan = plan_routes(req)
    gc = float(haversine_nmi(*start, *goal))
    sm = plan.routes["optimal_smoothed"]
    assert sm.dist_nmi == pytest.approx(gc, rel=5e-4)  # the smoothed route is the great circle within 0.05 %
    assert sm.time_h == pytest.approx(gc / 15.0, rel=5e-4)
    grid = plan.mesh.grid
    assert grid.lon_deg[0] < 180.0 < grid.lon_deg[-1] or grid.lon_deg[0] < -180.0 < grid.lon_deg[-1]  # one frame, across
    for r in plan.routes.values():
        assert np.all((r.lon_deg >= -180.0) & (r.lon_deg < 180.0))  # reported in -180..180
        assert (r.lat_deg[0], r.lon_deg[0]) == pytest.approx(start) and (r.lat_deg[-1], r.lon_deg[-1]) == pytest.approx(goal)
        assert r.dist_nmi < 1.02 * gc  # across the antimeridian, not the long way round
    assert any("antimeridian" in n for n in plan.notes)


def test_default_box_and_given_box_across_180():
    lo, la0, hi, la1 = default_bbox((30.0, 170.0), (40.0, -165.0))
    assert 160.0 < lo < 170.0 and 195.0 < hi < 210.0 and hi - lo < 60.0
    a = plan_routes(RouteRequest((30.0, 170.0), (40.0, -165.0), T0, ShipModel(15.0, "none"), spacing_deg=0.5,
                                 bbox=(165.0, 25.0, -160.0, 45.0), ignore_land=True))  # lon_max < lon_min: across
    b = plan_routes(RouteRequest((30.0, 170.0), (40.0, -165.0), T0, ShipModel(15.0, "none"), spacing_deg=0.5,
                                 bbox=(165.0, 25.0, 200.0, 45.0), ignore_land=True))  # the same box in one frame
    assert a.mesh.grid == b.mesh.grid
    assert a.routes["optimal"].time_h == pytest.approx(b.routes["optimal"].time_h, rel=1e-12)


def periodic_hs(lon_deg):
    """A smooth field periodic in longitude: its value at 180 E and at 180 W are the same."""
    return 3.0 + 2.0 * np.cos(np.radians(lon_deg)) + np.sin(2.0 * np.radians(lon_deg))


def global_dataset(lon):
    lat = np.arange(-10.0, 10.01, 1.0)
    time = pd.date_range(T0.tz_localize(None), periods=2, freq="6h")
    hs = np.broadcast_to(periodic_hs(lon)[None, None, :], (2, lat.size, lon.size)).astype(np.float32)
    return xr.Dataset({"hs_m": (("time_utc", "lat", "lon"), hs), "wave_from_deg": (("time_utc", "lat", "lon"), np.zeros_like(hs))},
                      coords={"time_utc": time, "lat": lat, "lon": lon})


@pytest.mark.parametrize("lon", [np.arange(-180.0, 180.0, 0.5), np.arange(0.0, 360.0, 0.5), np.arange(150.0, 215.01, 0.5)],
                         ids=["-180..180", "0..360", "regional 150..215 (0..360)"])
def test_weather_read_across_the_seam(lon):
    field = field_from_dataset(global_dataset(lon))
    assert field.lon_deg.min() >= -180.0 and field.lon_deg.max() < 180.0
    grid = MeshGrid.from_bbox((170.0, -5.0, 195.0, 5.0), 0.25)  # 170 E .. 165 W in one frame
    mw = field.on_mesh(grid.lat_deg, grid.lon_deg, T0.value)
    assert mw.weather_sea.all()  # every node has weather, both sides of 180
    hs = mw.wave[0, :, 0].reshape(grid.ny, grid.nx)
    # bilinear between 0.5 deg grid points of a smooth field: within the interpolation error
    np.testing.assert_allclose(hs, np.broadcast_to(periodic_hs(grid.lon_deg), hs.shape), atol=2e-4)
    assert field.covers(0.0, -170.0) and field.covers(0.0, 179.9)


def test_a_regional_product_is_not_interpolated_across_its_gap():
    # 150 E .. 160 E and 170 W .. 160 W only: nothing in between, no value invented there
    lon = np.r_[np.arange(150.0, 160.01, 0.5), np.arange(190.0, 200.01, 0.5)]
    field = field_from_dataset(global_dataset(lon))
    grid = MeshGrid.from_bbox((150.0, -2.0, 200.0, 2.0), 0.5)
    mw = field.on_mesh(grid.lat_deg, grid.lon_deg, T0.value)
    has = mw.weather_sea[0]
    assert has[grid.lon_deg <= 160.25].all() and has[grid.lon_deg >= 189.75].all()
    assert not has[(grid.lon_deg > 160.5) & (grid.lon_deg < 189.5)].any()
    assert not field.covers(0.0, 175.0) and field.covers(0.0, -165.0)


def test_route_through_weather_across_the_seam_matches_the_same_route_in_shifted_weather():
    # the same sea, described in -180..180 or moved 40 deg west (no seam): the same times
    lon = np.arange(-180.0, 180.0, 0.5)
    a = field_from_dataset(global_dataset(lon))
    ship = ShipModel(14.0, "bowditch")
    pa = plan_routes(RouteRequest((0.0, 175.0), (4.0, -175.0), T0, ship, spacing_deg=0.25, ignore_land=True), a)
    shifted = WeatherField(a.time_ns, a.lat_deg, a.lon_deg, {"hs_m": np.roll(a.variables["hs_m"], -80, axis=2),
                                                             "wave_from_deg": a.variables["wave_from_deg"]})
    pb = plan_routes(RouteRequest((0.0, 135.0), (4.0, 145.0), T0, ship, spacing_deg=0.25, ignore_land=True), shifted)
    for name in ("optimal_smoothed", "min_distance"):
        assert pa.routes[name].time_h == pytest.approx(pb.routes[name].time_h, rel=1e-6)


def test_real_trans_pacific_route_around_the_aleutians():
    # Yokohama approaches -> Vancouver approaches (Juan de Fuca): the great circle crosses Honshu's
    # coast and the Aleutians; the route goes round them, across 180 deg, all at sea (16 edges: 48
    # thread Unimak Pass but take 10 s to build the mesh's edge masks).
    start, goal = (34.9, 140.0), (48.4, -125.2)
    req = RouteRequest(start, goal, T0, ShipModel(18.0, "none"), spacing_deg=0.25, edges=16, snap_limit_nmi=20.0)
    plan = plan_routes(req)
    sm = plan.routes["optimal_smoothed"]
    gc = float(haversine_nmi(*start, *goal))
    assert sm.dist_nmi >= gc
    assert sm.dist_nmi < 1.05 * gc  # round the islands, not the long way
    crossing = np.abs(np.diff(sm.lon_deg)) > 180.0
    assert crossing.sum() == 1  # crosses the antimeridian once
    from thresholds.land_raster import is_ocean  # point look-ups in the 30" raster, any longitude

    for i in range(sm.n_waypoints - 1):  # every leg at sea: independent sampling every ~0.2 nmi
        n = max(2, int(sm.leg_dist_nmi[i] / 0.2) + 2)
        lat, lon = intermediate_point(sm.lat_deg[i], sm.lon_deg[i], sm.lat_deg[i + 1], sm.lon_deg[i + 1], np.linspace(0, 1, n))
        ends = (np.arange(n) == 0) | (np.arange(n) == n - 1)
        assert (is_ocean(np.asarray(lat), np.asarray(lon)) | ends).all(), f"leg {i} crosses land"
    assert math.isclose(sm.time_h, sm.dist_nmi / 18.0, rel_tol=1e-9)  # calm water


@pytest.mark.parametrize("goal", [(35.0, -165.0), (35.0, 180.0)], ids=["across", "to 180 exactly"])
def test_route_cli_exports_across_the_antimeridian(tmp_path, capsys, goal):
    # GeoJSON splits each line at the seam (RFC 7946, 3.1.9), GPX and RTZ carry longitudes wrapped to [-180, 180)
    import json

    import shapely.geometry

    from dashboards.exports import read_gpx, read_rtz
    from pipelines.cli import main

    args = ["route", "--from", "40,170", "--to", f"{goal[0]},{goal[1]}", "--depart", "2024-01-10T00:00Z", "--mesh-nmi", "30",
            "--speed-loss", "none", "--ignore-land"]  # fmt: skip
    for ext in ("geojson", "gpx", "rtz"):
        main(args + ["--out", str(tmp_path / f"r.{ext}")])
    capsys.readouterr()
    data = json.loads((tmp_path / "r.geojson").read_text())
    lines = {f["properties"]["route"]: f["geometry"] for f in data["features"] if f["properties"]["feature"] == "route"}
    assert set(lines) == {"optimal", "optimal_smoothed", "min_distance", "min_distance_calm"}
    for geom in lines.values():
        assert shapely.geometry.shape(geom).is_valid
        if goal[1] == 180.0:  # ends on the seam: one line, to 180 from the west
            assert geom["type"] == "LineString" and geom["coordinates"][-1] == [180.0, 35.0]
        else:
            west, east = geom["coordinates"]
            assert geom["type"] == "MultiLineString" and west[-1][0] == 180.0 and east[0] == [-180.0, west[-1][1]]
            assert west[0] == [170.0, 40.0] and east[-1] == [-165.0, 35.0]
    points = [f["geometry"]["coordinates"][0] for f in data["features"] if f["geometry"]["type"] == "Point"]
    assert all(-180.0 <= lon < 180.0 for lon in points)
    routes = read_gpx(tmp_path / "r.gpx") + [read_rtz(p) for p in sorted(tmp_path.glob("r_*.rtz"))]
    assert len(routes) == 8
    for r in routes:
        assert np.all((r.lon_deg >= -180.0) & (r.lon_deg < 180.0))
        assert (r.lat_deg[0], r.lon_deg[0]) == pytest.approx((40.0, 170.0))
        assert (r.lat_deg[-1], r.lon_deg[-1]) == pytest.approx((goal[0], -180.0 if goal[1] == 180.0 else goal[1]))
        gc = float(haversine_nmi(40.0, 170.0, *goal))
        assert gc <= r.dist_nmi < 1.02 * gc  # read back across the seam, not the long way round
