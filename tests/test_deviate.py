"""Cargo-safe deviation (Spyrou-Sioula et al. 2022, Algorithm 1) on generated storms and an island.

The weather, thresholds and land test here are the test's own small numpy implementations, so the
expected behaviour never comes from other project functions.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from routing.deviate import SafeCellIndex, deviate_lane

R_NMI = 6371008.8 / 1852.0
T0 = pd.Timestamp("2025-01-14T00:00Z")
HS_LIMIT_M = 4.5


def hav_nmi(lat1, lon1, lat2, lon2):
    p1, p2 = math.radians(lat1), math.radians(lat2)
    a = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(math.radians(lon2 - lon1) / 2) ** 2
    return 2 * R_NMI * math.asin(math.sqrt(a))


def bearing_deg(lat1, lon1, lat2, lon2):
    p1, p2, dl = math.radians(lat1), math.radians(lat2), math.radians(lon2 - lon1)
    y = math.sin(dl) * math.cos(p2)
    x = math.cos(p1) * math.sin(p2) - math.sin(p1) * math.cos(p2) * math.cos(dl)
    return math.degrees(math.atan2(y, x)) % 360.0


class Grid:
    """A 0.05-degree grid, hourly, with a moving storm blob, optional land box and wave direction."""

    def __init__(
        self, storm_amp_m=5.0, storm_sigma_deg=0.15, storm_lon0=1.6, storm_speed_deg_h=0.02, land=None, background_m=2.0,
        wave_from_deg=270.0, storm_lat=41.0, storm_sigma_lon_deg=None,
    ):
        self.lat = np.round(np.arange(40.0, 42.0001, 0.05), 6)
        self.lon = np.round(np.arange(0.0, 4.0001, 0.05), 6)
        self.times = pd.date_range(T0, periods=49, freq="1h")
        hours = np.arange(49, dtype=float)
        lon2, lat2 = np.meshgrid(self.lon, self.lat)
        xc = storm_lon0 + storm_speed_deg_h * hours
        sx = storm_sigma_lon_deg or storm_sigma_deg
        r2 = ((lon2[None] - xc[:, None, None]) / sx) ** 2 + ((lat2[None] - storm_lat) / storm_sigma_deg) ** 2
        self.hs = background_m + storm_amp_m * np.exp(-r2)
        self.land = np.zeros(lon2.shape, dtype=bool)
        if land is not None:
            lat_min, lat_max, lon_min, lon_max = land
            self.land = (lat2 >= lat_min) & (lat2 <= lat_max) & (lon2 >= lon_min) & (lon2 <= lon_max)
            self.hs[:, self.land] = np.nan
        self.land_box = land
        self.wave_from = np.full(self.hs.shape, wave_from_deg)
        self.wave_from[:, self.land] = np.nan

    def _idx(self, times, lat, lon):
        ti = np.clip(np.round((pd.DatetimeIndex(times) - self.times[0]) / pd.Timedelta(hours=1)).astype(int), 0, len(self.times) - 1)
        iy = np.clip(np.round((np.asarray(lat) - self.lat[0]) / 0.05).astype(int), 0, self.lat.size - 1)
        ix = np.clip(np.round((np.asarray(lon) - self.lon[0]) / 0.05).astype(int), 0, self.lon.size - 1)
        return ti, iy, ix

    def weather_at(self, times, lat, lon):
        ti, iy, ix = self._idx(times, lat, lon)
        return {"hs_m": self.hs[ti, iy, ix], "wave_from_deg": self.wave_from[ti, iy, ix]}

    def passing_mask(self, k):
        with np.errstate(invalid="ignore"):
            return (self.hs[k] <= HS_LIMIT_M) & ~self.land

    def leg_at_sea(self, lat1, lon1, lat2, lon2):
        if self.land_box is None:
            return True
        lat_min, lat_max, lon_min, lon_max = self.land_box
        for f in np.linspace(0.0, 1.0, 200):
            la, lo = lat1 + f * (lat2 - lat1), lon1 + f * (lon2 - lon1)
            if lat_min - 0.025 <= la <= lat_max + 0.025 and lon_min - 0.025 <= lo <= lon_max + 0.025:
                return False
        return True

    def cells(self):
        return SafeCellIndex(self.lat, self.lon, self.times, self.passing_mask)


def check(weather, heading_deg, speed_kn):
    """Hs limit, and beam seas (60-120 / 240-300 deg relative) above 3 m."""
    hs = np.asarray(weather["hs_m"], dtype=float)
    rel = np.mod(np.asarray(weather["wave_from_deg"], dtype=float) - heading_deg, 360.0)
    with np.errstate(invalid="ignore"):
        beam = (((rel >= 60) & (rel <= 120)) | ((rel >= 240) & (rel <= 300))) & (hs > 3.0)
        return {"hs_m": hs > HS_LIMIT_M, "beam_seas": beam}


def passes(weather, heading):
    return not any(bool(np.any(v)) for v in check(weather, heading, 12.0).values())


def lane(n=19, lat=41.0, lon0=0.2, lon1=3.8, speed=12.0):
    lons = np.linspace(lon0, lon1, n)
    return np.full(n, lat), lons, np.full(n, speed)


def run(grid, lat, lon, spd, depart=T0, **kw):
    return deviate_lane(
        lat, lon, spd, depart, weather_at=grid.weather_at, check=check, cells=grid.cells(), leg_at_sea=grid.leg_at_sea, **kw
    )


def test_calm_weather_deviation_equals_lane():
    grid = Grid(storm_amp_m=0.0)
    lat, lon, spd = lane()
    route = run(grid, lat, lon, spd)
    np.testing.assert_array_equal(route.lat_deg, lat)
    np.testing.assert_array_equal(route.lon_deg, lon)
    assert route.properties["n_deviated"] == 0 and route.properties["n_unresolved"] == 0
    assert [s["status"] for s in route.properties["steps"]] == ["endpoint"] + ["lane"] * 17 + ["endpoint"]
    # ETAs from the typical speed: cumulative haversine / 12 kn
    cum = np.cumsum([0.0] + [hav_nmi(lat[i], lon[i], lat[i + 1], lon[i + 1]) for i in range(len(lat) - 1)])
    expected = T0 + pd.to_timedelta(cum / 12.0, unit="h")
    assert np.abs((route.time_utc - expected) / pd.Timedelta(seconds=1)).max() < 1e-3
    np.testing.assert_allclose(route.leg_speed_kn, 12.0)
    np.testing.assert_allclose(route.weather["hs_m"], 2.0)


def test_storm_crossing_lane_every_point_passes_when_a_cell_is_in_reach():
    grid = Grid()
    lat, lon, spd = lane()
    route = run(grid, lat, lon, spd)
    props = route.properties
    # the storm (Hs up to 7 m, > 4.5 m within ~7.5 nmi of its centre) sits on the lane
    assert props["n_deviated"] >= 2
    assert props["n_unresolved"] == 0
    for i in range(1, route.n_waypoints):
        la, lo, t = route.lat_deg[i], route.lon_deg[i], route.time_utc[i]
        w = grid.weather_at([t], [la], [lo])
        heading = bearing_deg(route.lat_deg[i - 1], route.lon_deg[i - 1], la, lo)
        assert passes(w, heading), f"waypoint {i} at {la:.3f},{lo:.3f} {t} breaks the limits: {w}"
    # the lane itself would have met the storm: at least one centroid breaks the Hs limit at its lane ETA
    cum = np.cumsum([0.0] + [hav_nmi(lat[i], lon[i], lat[i + 1], lon[i + 1]) for i in range(len(lat) - 1)])
    lane_w = grid.weather_at(T0 + pd.to_timedelta(cum / 12.0, unit="h"), lat, lon)
    assert np.nanmax(lane_w["hs_m"]) > HS_LIMIT_M
    assert route.max_hs_m <= HS_LIMIT_M
    # legs not flagged are clear at every cell they pass (sampled by the test at their own times)
    for i, step in enumerate(props["steps"][1:], start=1):
        if step["leg_rules_fired"]:
            continue
        for f in np.linspace(0.0, 1.0, 41):
            la = route.lat_deg[i - 1] + f * (route.lat_deg[i] - route.lat_deg[i - 1])
            lo = route.lon_deg[i - 1] + f * (route.lon_deg[i] - route.lon_deg[i - 1])
            t = route.time_utc[i - 1] + f * (route.time_utc[i] - route.time_utc[i - 1])
            assert grid.weather_at([t], [la], [lo])["hs_m"][0] <= HS_LIMIT_M + 0.3, f"leg {i} meets the storm but is not flagged"
    assert props["n_legs_adverse"] == sum(bool(s["leg_rules_fired"]) for s in props["steps"])
    # deviated points moved no further than 3 h of sailing, and at most to the 10 nearest cells
    for step in props["steps"]:
        assert step["moved_nmi"] <= 12.0 * 3.0 + 1e-9
        assert step["candidates_tried"] <= 10
        if step["status"] == "deviated":
            assert "hs_m" in step["rules_fired"]


def test_etas_consistent_with_distances_and_speeds():
    grid = Grid(storm_lat=41.06)  # storm centre north of the lane: the detour goes south
    lat, lon, spd = lane(speed=12.0)
    spd = spd.copy()
    spd[5:10] = 9.0  # typical speed varies along the lane
    route = run(grid, lat, lon, spd)
    dt_h = np.diff(route.time_utc.asi8) / 3.6e12
    dist = np.array([hav_nmi(route.lat_deg[i], route.lon_deg[i], route.lat_deg[i + 1], route.lon_deg[i + 1]) for i in range(route.n_waypoints - 1)])
    np.testing.assert_allclose(dt_h, dist / route.leg_speed_kn, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(route.leg_speed_kn, spd[:-1])
    # ETAs are recomputed along the deviated path, not copied from the lane's timing
    assert route.properties["n_deviated"] >= 1
    lane_eta = T0 + pd.to_timedelta(np.cumsum([0.0] + [hav_nmi(lat[i], lon[i], lat[i + 1], lon[i + 1]) / spd[i] for i in range(len(lat) - 1)]), unit="h")
    moved = [i for i, s in enumerate(route.properties["steps"]) if s["status"] == "deviated"]
    assert any(abs((route.time_utc[i] - lane_eta[i]) / pd.Timedelta(seconds=1)) > 1.0 for i in moved)


def test_storm_everywhere_flags_unresolved_steps():
    grid = Grid(storm_amp_m=0.0, background_m=6.0)  # Hs 6 m everywhere: nothing passes
    lat, lon, spd = lane(n=6)
    route = run(grid, lat, lon, spd)
    steps = route.properties["steps"]
    assert [s["status"] for s in steps] == ["endpoint", "unresolved", "unresolved", "unresolved", "unresolved", "endpoint"]
    assert all("hs_m" in s["rules_fired"] for s in steps)
    assert route.properties["n_unresolved"] == 4
    assert route.properties["n_endpoint_adverse"] == 2
    np.testing.assert_array_equal(route.lon_deg, lon)  # kept (and flagged), not silently


def test_deviation_never_crosses_land():
    # A long storm just south of the lane and a small island just north of it: the nearest passing
    # cells lie north of the storm, some behind the island; every accepted leg must stay clear of it.
    island = (41.03, 41.06, 1.45, 1.55)
    grid = Grid(land=island, storm_sigma_deg=0.1, storm_sigma_lon_deg=0.5, storm_lat=40.98, storm_speed_deg_h=0.0, storm_lon0=1.75)
    lat, lon, spd = lane()
    assert all(grid.leg_at_sea(lat[i], lon[i], lat[i + 1], lon[i + 1]) for i in range(len(lat) - 1))  # the lane is at sea
    lat, lon, spd = lane()
    route = run(grid, lat, lon, spd)
    assert route.properties["n_deviated"] >= 1
    for i in range(route.n_waypoints - 1):
        assert grid.leg_at_sea(route.lat_deg[i], route.lon_deg[i], route.lat_deg[i + 1], route.lon_deg[i + 1]), f"leg {i} crosses the island"
    # without the land check the paper's algorithm would accept a cell whose leg clips the island
    unchecked = deviate_lane(lat, lon, spd, T0, weather_at=grid.weather_at, check=check, cells=grid.cells(), leg_at_sea=None)
    crossings = [
        i for i in range(unchecked.n_waypoints - 1)
        if not grid.leg_at_sea(unchecked.lat_deg[i], unchecked.lon_deg[i], unchecked.lat_deg[i + 1], unchecked.lon_deg[i + 1])
    ]
    assert crossings, "the island case should need the land check"


def test_beam_seas_rejects_candidates_by_heading():
    # Waves from the north: the lane heads east (beam seas) but Hs there is 2 m (< 3 m, allowed);
    # inside the storm both rules fire and candidates reached on a beam heading must be refused.
    grid = Grid(wave_from_deg=0.0)
    lat, lon, spd = lane()
    route = run(grid, lat, lon, spd)
    for i in range(1, route.n_waypoints):
        w = grid.weather_at([route.time_utc[i]], [route.lat_deg[i]], [route.lon_deg[i]])
        heading = bearing_deg(route.lat_deg[i - 1], route.lon_deg[i - 1], route.lat_deg[i], route.lon_deg[i])
        status = route.properties["steps"][i]["status"]
        if status != "unresolved":
            assert passes(w, heading)


def test_safe_cell_index_nearest_order_and_radius():
    grid = Grid()
    idx = grid.cells()
    la, lo, d = idx.nearest(T0, 41.0, 1.6, k=10)
    assert la.size == 10
    assert np.all(np.diff(d) >= 0)
    ti = 0
    for a, b in zip(la, lo):
        iy, ix = int(round((a - 40.0) / 0.05)), int(round(b / 0.05))
        assert grid.hs[ti, iy, ix] <= HS_LIMIT_M
    # brute force: no passing cell is closer than the nearest returned one
    lon2, lat2 = np.meshgrid(grid.lon, grid.lat)
    ok = grid.passing_mask(0)
    brute = min(hav_nmi(41.0, 1.6, a, b) for a, b in zip(lat2[ok], lon2[ok]))
    assert d[0] == pytest.approx(brute, abs=1e-9)
    la, lo, d = idx.nearest(T0, 41.0, 1.6, k=10, max_dist_nmi=d[0] + 1e-6)
    assert np.all(d <= brute + 1e-6)
    assert idx.time_index(T0 + pd.Timedelta(minutes=31)) == 1
    assert idx.time_index(T0 - pd.Timedelta(hours=5)) == 0
    assert idx.time_index(T0 + pd.Timedelta(days=30)) == 48


def test_bad_input_is_reported():
    grid = Grid()
    with pytest.raises(ValueError, match=">= 2 centroids"):
        run(grid, [41.0], [1.0], [12.0])
    with pytest.raises(ValueError, match="no usable speed"):
        run(grid, [41.0, 41.0], [1.0, 1.2], [np.nan, 12.0])
    route = run(grid, [41.0, 41.0, 41.0], [0.2, 0.4, 0.6], [0.0, np.nan, 5.0], default_speed_kn=10.0)
    np.testing.assert_allclose(route.leg_speed_kn, [10.0, 10.0])
    with pytest.raises(ValueError, match="timezone-aware"):
        SafeCellIndex(grid.lat, grid.lon, pd.date_range("2025-01-01", periods=3, freq="h"), grid.passing_mask)


def test_threshold_inputs_from_a_gridded_field():
    """The real thresholds on a PointSampler: the deviation avoids Hs above the Lpp < 200 m limit."""
    from routing.deviate import threshold_inputs
    from routing.sampling import PointSampler
    from thresholds.operator import OperatorLimits
    from thresholds.vessel import Vessel

    grid = Grid()
    hs = np.nan_to_num(grid.hs, nan=np.nan)
    sampler = PointSampler(grid.times.asi8, grid.lat, grid.lon, {"hs_m": hs, "wave_from_deg": grid.wave_from, "tm_s": np.full(hs.shape, 5.0)})
    vessel = Vessel("t", "container", 12.0, 150.0, 25.0, 8.0, 15000.0, 9000.0, 18.0, 120.0, 180.0)
    weather_at, chk, cells = threshold_inputs(sampler, vessel, OperatorLimits(name="t", hs_max_m=4.5))
    lat, lon, spd = lane()
    route = deviate_lane(lat, lon, spd, T0, weather_at=weather_at, check=chk, cells=cells)
    assert route.properties["n_deviated"] >= 1 and route.properties["n_unresolved"] == 0
    assert np.nanmax(route.weather["hs_m"]) <= 4.5
    # the heading-free mask is the Hs rule on sea cells
    np.testing.assert_array_equal(cells._passing_mask(0), grid.hs[0] <= 4.5)


def test_lane_route_timing():
    from routing.deviate import lane_route

    lat, lon, spd = lane(n=4)
    spd = np.array([12.0, 10.0, 8.0, 0.0])  # the last speed is never used
    r = lane_route(lat, lon, spd, "2025-01-14T00:00Z")
    hours = np.cumsum([0.0] + [hav_nmi(lat[i], lon[i], lat[i + 1], lon[i + 1]) / spd[i] for i in range(3)])
    np.testing.assert_allclose((r.time_utc - T0) / pd.Timedelta(hours=1), hours, rtol=1e-9)
    np.testing.assert_allclose(r.leg_speed_kn, [12.0, 10.0, 8.0])
    assert r.name == "historical"
    with pytest.raises(ValueError, match="no usable speed"):
        lane_route(lat, lon, [12.0, np.nan, 8.0, 8.0], T0)


def test_leg_judge_reports_the_highest_hs_met_between_the_ends():
    from routing.deviate_walk import Judge as _Judge

    grid = Grid(storm_speed_deg_h=0.0)  # a still storm: 7 m at 41.0 N 1.6 E, 2 m far from it
    judge = _Judge(grid.weather_at, check, spacing_nmi=3.0)
    t = [T0.value] * 3
    # across the centre along its meridian (72 nmi: interior points every 3 nmi, the middle one at
    # the centre), beside it (4 sigma north: 2 m), and a leg too short to have interior points
    lat1, lon1, lat2, lon2 = [40.4, 41.6, 41.0], [1.6, 1.0, 1.6], [41.6, 41.6, 41.0], [1.6, 2.2, 1.61]
    rules, hs = judge.legs_with_hs(lat1, lon1, t, lat2, lon2, [12.0] * 3)
    assert hs[0] == pytest.approx(7.0, abs=1e-6) and "hs_m" in rules[0]
    assert hs[1] == pytest.approx(2.0, abs=1e-6) and rules[1] == []
    assert np.isnan(hs[2]) and rules[2] == []
    assert judge.legs(lat1, lon1, t, lat2, lon2, [12.0] * 3) == rules
