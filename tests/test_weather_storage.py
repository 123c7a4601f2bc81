"""DuckDB weather tables and the paths x weather join (ETAs, grid cell, nearest time by ASOF JOIN)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from pipelines.storage import open_workspace
from pipelines.storage.weather import compute_etas, get_grid, join_points_weather, list_grids, load_weather, read_cells
from weather.errors import CoverageError, WeatherError

R_NMI = 6371008.8 / 1852.0  # mean Earth radius in nmi (IUGG R1)


def hav_nmi(lat1, lon1, lat2, lon2):
    p1, p2 = math.radians(lat1), math.radians(lat2)
    a = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(math.radians(lon2 - lon1) / 2) ** 2
    return 2 * R_NMI * math.asin(math.sqrt(a))


def tiny_grid():
    lat = 40.0 + 0.25 * np.arange(5)
    lon = 2.0 + 0.25 * np.arange(6)
    t = pd.date_range("2025-01-01", periods=5, freq="3h").values
    T, Y, X = np.meshgrid(np.arange(5), np.arange(5), np.arange(6), indexing="ij")
    hs = (1.0 + 0.1 * T + 0.01 * Y + 0.001 * X).astype(np.float32)  # every cell/time distinct
    hs[:, 0, 0] = np.nan  # land
    wd = np.full(hs.shape, 270.0, dtype=np.float32)
    wd[:, 0, 0] = np.nan
    return xr.Dataset({"hs_m": (("time_utc", "lat", "lon"), hs), "wave_from_deg": (("time_utc", "lat", "lon"), wd)},
                      coords={"time_utc": t, "lat": lat, "lon": lon}, attrs={"product": "tiny", "source_files": "mem"})


@pytest.fixture
def ws(tmp_path):
    with open_workspace(tmp_path / "w.duckdb") as w:
        yield w


def test_load_stores_sea_cells_and_grid_axes(ws):
    ds = tiny_grid()
    gid = load_weather(ws, ds, name="tiny", metadata={"k": 1})
    g = get_grid(ws, "tiny")
    assert g["grid_id"] == gid and (g["nlat"], g["nlon"], g["n_times"]) == (5, 6, 5)
    assert g["lat0_deg"] == 40.0 and g["dlat_deg"] == pytest.approx(0.25) and g["step_s"] == 10800.0
    assert g["n_cells"] == 5 * (5 * 6 - 1)  # land cell not stored
    cells = read_cells(ws, "tiny")
    row = cells[(cells.lat_idx == 2) & (cells.lon_idx == 3)].iloc[1]
    assert row.hs_m == pytest.approx(1.0 + 0.1 * 1 + 0.01 * 2 + 0.001 * 3, abs=1e-6)
    assert row.lat_deg == pytest.approx(40.5) and row.lon_deg == pytest.approx(2.75)
    assert pd.isna(row.tp_s)  # variables the grid lacks are NULL
    # loading the same name again replaces it
    gid2 = load_weather(ws, ds, name="tiny")
    assert gid2 != gid and len(list_grids(ws)) == 1
    assert ws.con.execute("SELECT count(*) FROM weather_cells").fetchone()[0] == 145
    with pytest.raises(WeatherError, match="no weather grid 'other'.*loaded: tiny"):
        get_grid(ws, "other")


def test_irregular_grid_is_refused(ws):
    ds = tiny_grid().isel(lat=[0, 1, 3])
    with pytest.raises(WeatherError, match="latitude axis is irregular"):
        load_weather(ws, ds)


def test_etas_cumulative_distance_over_typical_speed(ws):
    pts = pd.DataFrame({"path_id": ["a"] * 3 + ["b"] * 2, "seq": [0, 1, 2, 0, 1],
                        "lat_deg": [40.0, 40.5, 40.5, 41.0, 41.0], "lon_deg": [2.0, 2.0, 3.0, 2.0, 2.5],
                        "speed_kn": [10.0, 15.0, 12.0, 20.0, 0.0]})
    out = compute_etas(ws, pts, ["2025-01-01T00:00Z", "2025-01-01T06:00Z"])
    assert len(out) == 10
    a = out[(out.path_id == "a") & (out.departure_utc == pd.Timestamp("2025-01-01T06:00Z"))].sort_values("seq")
    d1 = hav_nmi(40.0, 2.0, 40.5, 2.0)  # 30.02 nmi at 10 kn (speed of the leg's start point)
    d2 = hav_nmi(40.5, 2.0, 40.5, 3.0)  # 45.6 nmi at 15 kn
    np.testing.assert_allclose(a.elapsed_h.values, [0.0, d1 / 10.0, d1 / 10.0 + d2 / 15.0], rtol=1e-12)
    np.testing.assert_allclose(a.dist_nmi.values, [0.0, d1, d1 + d2], rtol=1e-12)
    eta = pd.Timestamp("2025-01-01T06:00Z") + pd.to_timedelta(d1 / 10.0 + d2 / 15.0, unit="h")
    assert abs((a.eta_utc.iloc[2] - eta).total_seconds()) < 1e-3
    assert str(a.eta_utc.dt.tz) == "UTC"
    bad = pts.copy()
    bad.loc[0, "speed_kn"] = 0.0
    with pytest.raises(WeatherError, match="path 'a' point 0: speed_kn must be > 0"):
        compute_etas(ws, bad, ["2025-01-01T00:00Z"])


def test_join_nearest_cell_and_time_and_statuses(ws):
    load_weather(ws, tiny_grid(), name="tiny")
    # one single-point path per situation, so each ETA is the departure time
    pts = pd.DataFrame({"path_id": ["a", "b", "c", "d"], "seq": [0, 0, 0, 0], "lat_deg": [40.51, 40.49, 40.01, 40.99],
                        "lon_deg": [2.62, 2.64, 2.01, 3.40], "speed_kn": [10.0] * 4})
    deps = pd.to_datetime(["2025-01-01T04:29Z", "2025-01-01T04:31Z"])
    out = join_points_weather(ws, pts, deps, grid="tiny", on_missing="flag")
    first = out[(out.departure_utc == pd.Timestamp("2025-01-01T04:29Z")) & (out.path_id == "a")].iloc[0]
    # 40.51 -> lat_idx 2, 2.62 -> lon_idx 2 (2.5) ; 04:29 is nearer 03:00 than 06:00 -> time index 1
    assert (first.lat_idx, first.lon_idx) == (2, 2)
    assert first.weather_time_utc == pd.Timestamp("2025-01-01T03:00Z")
    assert first.hs_m == pytest.approx(1.0 + 0.1 + 0.02 + 0.002, abs=1e-6)
    later = out[(out.departure_utc == pd.Timestamp("2025-01-01T04:31Z")) & (out.path_id == "a")].iloc[0]
    assert later.weather_time_utc == pd.Timestamp("2025-01-01T06:00Z")  # 04:31 is nearer 06:00
    b = out[out.path_id == "b"].iloc[0]  # 40.49 -> lat_idx 2 (40.5), 2.64 -> lon_idx 3 (2.75)
    assert (b.lat_idx, b.lon_idx) == (2, 3)
    assert out[out.path_id == "c"].status.tolist() == ["land", "land"]  # 40.01N 2.01E is the land cell
    assert out[out.path_id == "c"].hs_m.isna().all()
    assert out[out.path_id == "d"].status.tolist() == ["outside_grid", "outside_grid"]  # lon 3.40 rounds past the last column (3.25)
    with pytest.raises(CoverageError, match=r"tiny, hs_m,wave_from_deg: 2 path points outside the grid"):
        join_points_weather(ws, pts, deps, grid="tiny")


def test_join_refuses_etas_outside_the_time_span(ws):
    load_weather(ws, tiny_grid(), name="tiny")
    pts = pd.DataFrame({"path_id": ["p", "p"], "seq": [0, 1], "lat_deg": [40.5, 40.5], "lon_deg": [2.5, 3.0], "speed_kn": [5.0, 5.0]})
    # grid ends 12:00 with half a step (1.5 h) of tolerance; the leg is 0.5 deg of longitude at
    # 40.5N = 22.8 nmi, 4.56 h at 5 kn: from a 09:00 departure the second point arrives 13:34.
    out = join_points_weather(ws, pts, ["2025-01-01T08:00Z"], on_missing="flag")
    assert out.status.tolist() == ["ok", "ok"] and out.weather_time_utc.iloc[1] == pd.Timestamp("2025-01-01T12:00Z")
    out = join_points_weather(ws, pts, ["2025-01-01T09:00Z"], on_missing="flag")
    assert out.status.tolist() == ["ok", "outside_time"] and pd.isna(out.hs_m.iloc[1])
    with pytest.raises(CoverageError, match=r"tiny, hs_m,wave_from_deg: no data for ETAs 2025-01-01T14:00Z -> 2025-01-01T.*data cover 2025-01-01T00:00Z -> 2025-01-01T12:00Z"):
        join_points_weather(ws, pts, ["2025-01-01T14:00Z"])


@pytest.fixture(scope="module")
def demo_week():
    """Five days of the demo weather (storm A) on the wave grid with the wind merged onto it.
    (The file round trip of the same weather is tested in test_weather_grid.py.)"""
    from weather.regrid import merge_onto
    from weather.scenario import generate_weather

    sw = generate_weather(seed=3, start="2025-01-13T00:00Z", end="2025-01-17T21:00Z")
    return merge_onto(sw.waves, [sw.wind])


def lane_points():
    """Generated centroid sets between the demo ports' approach points (lanes helper not needed)."""
    ports = {"BCN": (41.31, 2.22), "PMI": (39.52, 2.62), "VLC": (39.43, -0.26), "MRS": (43.30, 5.30),
             "ALG": (36.795, 3.09), "CAG": (39.18, 9.11)}
    pairs = [("BCN", "PMI"), ("VLC", "PMI"), ("MRS", "ALG"), ("BCN", "CAG"), ("PMI", "MRS")]
    rows = []
    for a, b in pairs:
        (la1, lo1), (la2, lo2) = ports[a], ports[b]
        for i, f in enumerate(np.linspace(0, 1, 25)):
            rows.append((f"{a}-{b}", i, la1 + f * (la2 - la1), lo1 + f * (lo2 - lo1), 12.0 + 2.0 * (i % 3)))
    return pd.DataFrame(rows, columns=["path_id", "seq", "lat_deg", "lon_deg", "speed_kn"])


def test_join_equals_xarray_on_demo_lanes(ws, demo_week):
    ds = demo_week
    load_weather(ws, ds, name="demo")
    pts = lane_points()
    deps = pd.date_range("2025-01-13T12:00Z", "2025-01-15T12:00Z", freq="6h")
    out = join_points_weather(ws, pts, deps, grid="demo")
    ok = out[out.status == "ok"]
    assert len(ok) > 0.85 * len(out)  # a few coastal points fall on land cells
    land = out[out.status == "land"]
    # land status <=> the nearest grid cell is NaN in hs_m at every time
    near_land = ds.hs_m.sel(lat=xr.DataArray(land.lat_deg.values, dims="p"), lon=xr.DataArray(land.lon_deg.values, dims="p"),
                            method="nearest")
    assert bool(np.isnan(near_land.values).all())
    eta = ok.eta_utc.dt.tz_localize(None).values
    sel = dict(lat=xr.DataArray(ok.lat_deg.values, dims="p"), lon=xr.DataArray(ok.lon_deg.values, dims="p"),
               time_utc=xr.DataArray(eta, dims="p"))
    nearest = ds.sel(**sel, method="nearest")
    for v in ("hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms"):
        np.testing.assert_array_equal(ok[v].to_numpy(dtype=np.float32), nearest[v].values)  # same cell, same time
    # Against linear interpolation in space and time: the nearest value lies within the range of the
    # 2 x 2 x 2 neighbours that bilinear/linear interpolation mixes, so |nearest - interp| <= that range.
    interp = ds.hs_m.interp(**sel)
    lat_v, lon_v = ds.lat.values, ds.lon.values
    t_v = ds.time_utc.values
    iy = np.clip(np.searchsorted(lat_v, ok.lat_deg.values) - 1, 0, lat_v.size - 2)
    ix = np.clip(np.searchsorted(lon_v, ok.lon_deg.values) - 1, 0, lon_v.size - 2)
    it = np.clip(np.searchsorted(t_v, eta) - 1, 0, t_v.size - 2)
    cube = np.stack([ds.hs_m.values[it + a, iy + b, ix + c] for a in (0, 1) for b in (0, 1) for c in (0, 1)])
    spread = np.nanmax(cube, axis=0) - np.nanmin(cube, axis=0)
    diff = np.abs(ok.hs_m.to_numpy() - interp.values)
    has_interp = np.isfinite(interp.values)
    assert has_interp.mean() > 0.8
    assert np.all(diff[has_interp] <= spread[has_interp] + 1e-6)
    assert np.median(diff[has_interp]) < 0.1  # m: the grid is fine (1/12 deg, 3 h)


def test_join_irregular_time_axis_uses_both_sides(ws):
    """Daily files concatenated with a gap: times 00, 03, 06, 12 h. Nearest time on both sides."""
    ds = tiny_grid().isel(time_utc=[0, 1, 2, 4])  # 00:00, 03:00, 06:00, 12:00
    load_weather(ws, ds, name="gappy")
    assert get_grid(ws, "gappy")["step_s"] is None or pd.isna(get_grid(ws, "gappy")["step_s"])
    pts = pd.DataFrame({"path_id": ["a"], "seq": [0], "lat_deg": [40.5], "lon_deg": [2.5], "speed_kn": [10.0]})
    out = join_points_weather(ws, pts, pd.to_datetime(["2025-01-01T08:59Z", "2025-01-01T09:01Z", "2025-01-01T09:00Z"]),
                              grid="gappy")
    got = dict(zip(out.departure_utc, out.weather_time_utc))
    assert got[pd.Timestamp("2025-01-01T08:59Z")] == pd.Timestamp("2025-01-01T06:00Z")
    assert got[pd.Timestamp("2025-01-01T09:01Z")] == pd.Timestamp("2025-01-01T12:00Z")
    assert got[pd.Timestamp("2025-01-01T09:00Z")] == pd.Timestamp("2025-01-01T06:00Z")  # tie -> earlier
    # the regular grid breaks ties the same way: 01:30 is midway between 00:00 and 03:00
    load_weather(ws, tiny_grid(), name="regular")
    out = join_points_weather(ws, pts, ["2025-01-01T01:30Z", "2025-01-01T01:31Z"], grid="regular")
    assert out.weather_time_utc.tolist() == [pd.Timestamp("2025-01-01T00:00Z"), pd.Timestamp("2025-01-01T03:00Z")]
