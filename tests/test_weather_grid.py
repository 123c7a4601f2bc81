"""Regridding, coverage checks, the product-schema writers and the demo storm generator."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from weather.canonical import normalise_weather, validate_canonical
from weather.coverage import check_coverage, check_points
from weather.errors import CoverageError, WeatherFileError
from weather.regrid import bilinear_2d, interp_time, merge_onto, regrid_space


def make_weather_grid(values_fn, lat, lon, times, name="hs_m", product="test"):
    t = pd.to_datetime(times).values.astype("datetime64[ns]")
    T, Y, X = np.meshgrid(np.arange(len(t)), lat, lon, indexing="ij")
    data = values_fn(T, Y, X).astype(np.float32)
    return xr.Dataset({name: (("time_utc", "lat", "lon"), data)}, coords={"time_utc": t, "lat": lat, "lon": lon},
                      attrs={"product": product})


# ------------------------------------------------------------------ bilinear


def test_bilinear_reproduces_bilinear_functions_exactly():
    # f = 1 + 2 lat + 3 lon + 0.5 lat lon is reproduced exactly by bilinear interpolation
    lat = np.array([40.0, 40.25, 40.5])
    lon = np.array([2.0, 2.25, 2.5, 2.75])
    Y, X = np.meshgrid(lat, lon, indexing="ij")
    f = 1 + 2 * Y + 3 * X + 0.5 * Y * X
    tl = np.array([40.0, 40.1, 40.37, 40.5])
    tg = np.array([2.0, 2.03, 2.6, 2.75])
    got = bilinear_2d(f, lat, lon, tl, tg)
    TY, TX = np.meshgrid(tl, tg, indexing="ij")
    np.testing.assert_allclose(got, 1 + 2 * TY + 3 * TX + 0.5 * TY * TX, rtol=1e-12)


def test_bilinear_nan_corners_renormalised_and_outside_nan():
    f = np.array([[1.0, np.nan], [3.0, 5.0]])
    # centre of the cell: corners 1, 3, 5 with equal weights 1/4 each -> (1 + 3 + 5)/3 = 3
    assert bilinear_2d(f, [0, 1], [0, 1], [0.5], [0.5])[0, 0] == pytest.approx(3.0)
    # all corners NaN -> NaN; outside the grid -> NaN (no extrapolation)
    assert np.isnan(bilinear_2d(np.full((2, 2), np.nan), [0, 1], [0, 1], [0.5], [0.5])[0, 0])
    assert np.isnan(bilinear_2d(f, [0, 1], [0, 1], [1.01], [0.5])[0, 0])
    assert np.isnan(bilinear_2d(f, [0, 1], [0, 1], [0.5], [-0.01])[0, 0])


def test_direction_regridding_through_components():
    # 350 and 10 average to 0 (not 180); 90 and 180 to 135
    ds = make_weather_grid(lambda t, y, x: np.where(x == 0, 350.0, 10.0), [0.0], [0.0, 1.0], ["2025-01-01"], "wave_from_deg")
    out = regrid_space(ds, [0.0], [0.5])
    assert float(out.wave_from_deg[0, 0, 0]) % 360 == pytest.approx(0.0, abs=1e-4)
    ds = make_weather_grid(lambda t, y, x: np.where(x == 0, 90.0, 180.0), [0.0], [0.0, 1.0], ["2025-01-01"], "wave_from_deg")
    assert float(regrid_space(ds, [0.0], [0.5]).wave_from_deg[0, 0, 0]) == pytest.approx(135.0, abs=1e-4)


def test_time_interpolation_linear_and_exact_at_stored_times():
    times = ["2025-01-01T00:00", "2025-01-01T03:00"]
    ds = make_weather_grid(lambda t, y, x: 2.0 + 3.0 * t + 0 * y, [40.0, 41.0], [2.0, 3.0], times)
    ds["hs_m"][1, 0, 0] = np.nan  # a land cell at the second time
    out = interp_time(ds, pd.to_datetime(["2025-01-01T00:00", "2025-01-01T01:00", "2025-01-01T04:00"]).values)
    assert out.hs_m.values[0, 1, 1] == pytest.approx(2.0)  # exact time kept (even next to a NaN)
    assert out.hs_m.values[0, 0, 0] == pytest.approx(2.0)
    assert out.hs_m.values[1, 1, 1] == pytest.approx(3.0)  # one third of the way: 2 + 3 * 1/3
    assert np.isnan(out.hs_m.values[1, 0, 0])  # NaN neighbour -> NaN
    assert np.isnan(out.hs_m.values[2]).all()  # after the span: NaN, never extrapolated


def test_merge_keeps_wave_land_nan():
    waves = make_weather_grid(lambda t, y, x: 1.0 + 0 * x, np.arange(40.0, 41.01, 0.25), np.arange(2.0, 3.01, 0.25),
                              ["2025-01-01T00:00", "2025-01-01T03:00"], product="waves")
    waves["hs_m"][:, 0, 0] = np.nan  # land in the wave product
    wind = make_weather_grid(lambda t, y, x: 10.0 + 2.0 * t + 0 * x, [40.0, 41.0], [2.0, 3.0],
                             ["2025-01-01T00:00", "2025-01-01T01:00", "2025-01-01T02:00", "2025-01-01T03:00"],
                             name="wind_u_ms", product="wind")
    merged = merge_onto(waves, [wind])
    assert merged.attrs["product"] == "waves + wind"
    assert np.isnan(merged.wind_u_ms.values[:, 0, 0]).all()
    np.testing.assert_allclose(merged.wind_u_ms.values[:, 1:, 1:].mean(axis=(1, 2)), [10.0, 16.0], rtol=1e-6)


# ------------------------------------------------------------------ normalisation


def test_normalise_flips_axes_wraps_lon_and_converts_knots():
    t = pd.to_datetime(["2025-01-01T03:00", "2025-01-01T00:00"]).values
    raw = xr.Dataset(
        {"tws": (("time", "latitude", "longitude"), np.arange(2 * 2 * 3, dtype=float).reshape(2, 2, 3), {"units": "knots"})},
        coords={"time": t, "latitude": [41.0, 40.0], "longitude": [350.0, 355.0, 5.0]},
    )
    raw["u10"] = raw["tws"]
    ds = normalise_weather(raw, {"u10": "wind_u_ms"}, product="p", source_files=["f.nc"])
    validate_canonical(ds)
    np.testing.assert_allclose(ds.lon.values, [-10.0, -5.0, 5.0])
    np.testing.assert_allclose(ds.lat.values, [40.0, 41.0])
    assert pd.Timestamp(ds.time_utc.values[0]) == pd.Timestamp("2025-01-01T00:00")
    # original [t=1 (00:00), lat=40 (row 1), lon=350 (col 0)] = 9 knots
    assert ds.wind_u_ms.values[0, 0, 0] == pytest.approx(9 * 1852 / 3600, rel=1e-6)
    raw["u10"].attrs["units"] = "furlongs"
    with pytest.raises(WeatherFileError, match="'u10' has units 'furlongs'"):
        normalise_weather(raw, {"u10": "wind_u_ms"}, product="p", source_files=["f.nc"])
    with pytest.raises(WeatherFileError, match="none of the expected variables VHM0"):
        normalise_weather(raw, {"VHM0": "hs_m"}, product="p", source_files=["f.nc"])


# ------------------------------------------------------------------ coverage


def test_coverage_errors_name_product_variable_and_span():
    ds = make_weather_grid(lambda t, y, x: 1.0 + 0 * x, [40.0, 41.0], [2.0, 3.0],
                           ["2025-01-01T00:00", "2025-01-01T03:00", "2025-01-01T06:00"], product="CMEMS demo")
    ds["wind_u_ms"] = ds.hs_m.copy()
    ds["wind_u_ms"][2] = np.nan
    check_coverage(ds, variables=["hs_m"], start="2025-01-01T00:00Z", end="2025-01-01T06:00Z", bbox=(2.0, 40.0, 3.0, 41.0))
    with pytest.raises(CoverageError, match=r"CMEMS demo, hs_m: no data for 2025-01-01T06:00Z -> 2025-01-02T00:00Z \(data cover 2025-01-01T00:00Z -> 2025-01-01T06:00Z\)"):
        check_coverage(ds, variables=["hs_m"], start="2025-01-01T03:00Z", end="2025-01-02T00:00Z")
    with pytest.raises(CoverageError, match=r"no data for 2024-12-31T21:00Z -> 2025-01-01T00:00Z"):
        check_coverage(ds, variables=["hs_m"], start="2024-12-31T21:00Z", end="2025-01-01T03:00Z")
    with pytest.raises(CoverageError, match=r"bbox lon 2\.5\.\.3\.5, lat 40\.2\.\.40\.8 is not covered"):
        check_coverage(ds, variables=["hs_m"], bbox=(2.5, 40.2, 3.5, 40.8))
    with pytest.raises(CoverageError, match=r"CMEMS demo, wind_u_ms: no data at 1 time step\(s\): 2025-01-01T06:00Z -> 2025-01-01T06:00Z"):
        check_coverage(ds, variables=["wind_u_ms"], start="2025-01-01T00:00Z", end="2025-01-01T06:00Z")
    with pytest.raises(CoverageError, match="no variable 'tp_s'"):
        check_coverage(ds, variables=["tp_s"])
    with pytest.raises(CoverageError, match="not covered"):
        check_points(ds, [40.5, 42.0], [2.5, 2.5], pd.to_datetime(["2025-01-01T01:00Z", "2025-01-01T02:00Z"]), variables=["hs_m"])


# ------------------------------------------------------------------ writers in the products' schemas


def small_canonical(seed=0):
    rng = np.random.default_rng(seed)
    lat = 40.0 + np.arange(5) / 12.0
    lon = -1.0 + np.arange(6) / 12.0
    t = pd.date_range("2025-01-01", periods=4, freq="3h").values
    shape = (4, 5, 6)
    hs = rng.uniform(0.2, 9.0, shape)
    hs[:, 0, 0] = np.nan
    d = rng.uniform(0, 359.99, shape)
    d[:, 0, 0] = np.nan
    ds = xr.Dataset(
        {"hs_m": (("time_utc", "lat", "lon"), hs.astype(np.float32)),
         "wave_from_deg": (("time_utc", "lat", "lon"), d.astype(np.float32)),
         "tp_s": (("time_utc", "lat", "lon"), rng.uniform(3, 16, shape).astype(np.float32)),
         "tm_s": (("time_utc", "lat", "lon"), rng.uniform(3, 12, shape).astype(np.float32)),
         "wind_u_ms": (("time_utc", "lat", "lon"), rng.uniform(-30, 30, shape).astype(np.float32)),
         "wind_v_ms": (("time_utc", "lat", "lon"), rng.uniform(-30, 30, shape).astype(np.float32))},
        coords={"time_utc": t, "lat": lat, "lon": lon},
    )
    for name in ("tp_s", "tm_s"):
        ds[name][:, 0, 0] = np.nan  # land in every wave variable
    return ds


def test_cmems_wave_writer_schema_and_round_trip(tmp_path):
    import netCDF4

    from weather.io.cmems import read_cmems, write_cmems_wave

    ds = small_canonical()
    path = write_cmems_wave(ds, tmp_path / "w.nc")
    with netCDF4.Dataset(path) as nc:
        assert nc.getncattr("product_id") == "GLOBAL_ANALYSISFORECAST_WAV_001_027"
        assert nc.getncattr("stormlane_synthetic") == "true"
        assert list(nc.dimensions) == ["time", "latitude", "longitude"]
        assert nc.variables["time"].units == "hours since 1950-01-01"
        for name, scale, offset in (("VHM0", 0.001, 0.0), ("VMDR", 0.01, 180.0), ("VTPK", 0.001, 0.0), ("VTM10", 0.001, 0.0)):
            v = nc.variables[name]
            v.set_auto_maskandscale(False)
            assert v.dtype == np.int16 and v.dimensions == ("time", "latitude", "longitude")
            assert v.getncattr("_FillValue") == -32767 and v.getncattr("missing_value") == -32767
            assert v.getncattr("scale_factor").dtype == np.float32
            assert v.getncattr("scale_factor") == np.float32(scale) and v.getncattr("add_offset") == np.float32(offset)
            assert v[0, 0, 0] == -32767  # land
        assert nc.variables["VMDR"].standard_name == "sea_surface_wave_from_direction"
    back, meta = read_cmems(path)
    assert meta["product"] == "CMEMS GLOBAL_ANALYSISFORECAST_WAV_001_027 (synthetic)"
    np.testing.assert_allclose(back.hs_m.values, ds.hs_m.values, atol=0.0005 + 1e-6, equal_nan=True)
    np.testing.assert_allclose(back.tp_s.values, ds.tp_s.values, atol=0.0005 + 1e-6)
    dd = np.abs((back.wave_from_deg.values - ds.wave_from_deg.values + 180) % 360 - 180)
    assert np.nanmax(dd) <= 0.005 + 1e-4


@pytest.mark.parametrize("layout", ["time", "valid_time"])
def test_era5_writer_layouts_round_trip(tmp_path, layout):
    import netCDF4

    from weather.io.era5 import read_era5, write_era5

    ds = small_canonical()[["wind_u_ms", "wind_v_ms"]]
    path = write_era5(ds, tmp_path / f"era5_{layout}.nc", layout=layout)
    with netCDF4.Dataset(path) as nc:
        assert layout in nc.dimensions
        lat = nc.variables["latitude"][:]
        assert lat[0] > lat[-1]  # ERA5 latitudes run north to south
        v = nc.variables["u10"]
        v.set_auto_maskandscale(False)
        raw = np.asarray(v[:])
        if layout == "time":
            assert nc.data_model == "NETCDF3_64BIT_OFFSET"
            assert nc.variables["time"].units == "hours since 1900-01-01 00:00:00.0"
            assert raw.dtype == np.int16
            scale, offset = float(v.scale_factor), float(v.add_offset)
            # grib_to_netcdf packing: scale = range / 65534
            rng = float(np.nanmax(ds.wind_u_ms.values) - np.nanmin(ds.wind_u_ms.values))
            assert scale == pytest.approx(rng / 65534, rel=1e-9)
            decoded = raw * scale + offset
        else:
            assert nc.variables["valid_time"].units == "seconds since 1970-01-01"
            assert raw.dtype == np.float32 and v.GRIB_shortName == "10u"
            decoded = raw.astype(np.float64)
    np.testing.assert_allclose(decoded[:, ::-1, :], ds.wind_u_ms.values, atol=scale if layout == "time" else 1e-6)
    back, meta = read_era5(path)
    assert meta["product"] == f"ERA5 single levels ({layout} layout) (synthetic)"
    np.testing.assert_allclose(back.wind_u_ms.values, ds.wind_u_ms.values, atol=0.001)


def test_era5_old_layout_0_360_longitudes_and_expver(tmp_path):
    """A hand-made file in the grib_to_netcdf layout crossing the meridian (lon 359.5, 0, 0.5) with
    an ERA5/ERA5T ``expver`` dimension: longitudes wrap, expver slices merge."""
    import netCDF4

    from weather.io.era5 import read_era5

    path = tmp_path / "era5_expver.nc"
    with netCDF4.Dataset(path, "w", format="NETCDF3_64BIT_OFFSET") as nc:
        nc.createDimension("longitude", 3)
        nc.createDimension("latitude", 2)
        nc.createDimension("expver", 2)
        nc.createDimension("time", 2)
        nc.createVariable("longitude", "f4", ("longitude",))[:] = [359.5, 0.0, 0.5]
        nc.variables["longitude"].units = "degrees_east"
        nc.createVariable("latitude", "f4", ("latitude",))[:] = [41.0, 40.5]
        nc.variables["latitude"].units = "degrees_north"
        nc.createVariable("expver", "i4", ("expver",))[:] = [1, 5]
        t = nc.createVariable("time", "i4", ("time",))
        t.units = "hours since 1900-01-01 00:00:00.0"
        t.calendar = "gregorian"
        t[:] = [1078920, 1078921]  # 2023-01-31T00:00, 01:00: (datetime(2023,1,31) - datetime(1900,1,1)) / 1 h
        u = nc.createVariable("u10", "i2", ("time", "expver", "latitude", "longitude"), fill_value=np.int16(-32767))
        u.scale_factor = 0.001
        u.add_offset = 0.0
        u.missing_value = np.int16(-32767)
        u.units = "m s**-1"
        u.set_auto_maskandscale(False)
        data = np.full((2, 2, 2, 3), -32767, dtype=np.int16)
        data[0, 0] = [[1000, 2000, 3000], [4000, 5000, 6000]]  # final ERA5 at the first time
        data[1, 1] = [[7000, 8000, 9000], [1100, 1200, 1300]]  # ERA5T at the second
        u[:] = data
    ds, meta = read_era5(path)
    np.testing.assert_allclose(ds.lon.values, [-0.5, 0.0, 0.5])
    assert pd.Timestamp(ds.time_utc.values[0]) == pd.Timestamp("2023-01-31T00:00")
    # lat ascending: row 40.5 first; lon -0.5 (=359.5) first
    np.testing.assert_allclose(ds.wind_u_ms.values[0], [[4.0, 5.0, 6.0], [1.0, 2.0, 3.0]], rtol=1e-6)
    np.testing.assert_allclose(ds.wind_u_ms.values[1], [[1.1, 1.2, 1.3], [7.0, 8.0, 9.0]], rtol=1e-6)


# ------------------------------------------------------------------ demo storms


@pytest.fixture(scope="module")
def scenario_weather():
    from weather.scenario import generate_weather

    return generate_weather(seed=0)


def test_scenario_grids_and_determinism(scenario_weather):
    from weather.scenario import generate_weather, make_storms

    w = scenario_weather.waves
    assert w.hs_m.shape == (259, 115, 157)  # 2025-01-01T00 -> 2025-02-02T06 every 3 h; 1/12 deg
    assert float(w.lat[0]) == 35.5 and float(w.lat[-1]) == pytest.approx(45.0)
    assert float(w.lon[0]) == -1.5 and float(w.lon[-1]) == pytest.approx(11.5)
    assert scenario_weather.wind.wind_u_ms.shape == (775, 39, 53)  # hourly, 0.25 deg
    assert make_storms(0) == make_storms(0) and make_storms(0) != make_storms(1)
    # land from the 30'' mask: Palma's basin and the middle of Sardinia are land, the Balearic Sea is not
    iy, ix = int(round((40.0 - 35.5) * 12)), int(round((9.0 + 1.5) * 12))
    assert np.isnan(w.hs_m.values[:, iy, ix]).all()
    iy, ix = int(round((39.0 - 35.5) * 12)), int(round((5.0 + 1.5) * 12))
    assert np.isfinite(w.hs_m.values[:, iy, ix]).all()
    window = generate_weather(seed=0, start="2025-01-14T00:00Z", end="2025-01-15T00:00Z")
    np.testing.assert_array_equal(window.waves.hs_m.values, w.hs_m.sel(time_utc=slice("2025-01-14", "2025-01-15T00:00")).values)
    np.testing.assert_array_equal(window.wind.wind_u_ms.values,
                                  scenario_weather.wind.wind_u_ms.sel(time_utc=slice("2025-01-14", "2025-01-15T00:00")).values)


def test_scenario_storms_in_their_windows(scenario_weather):
    w = scenario_weather.waves
    hs_max = pd.Series(np.nanmax(w.hs_m.values, axis=(1, 2)), index=pd.DatetimeIndex(w.time_utc.values))
    assert hs_max["2025-01-14T00":"2025-01-16T00"].max() > 6.5  # storm A, above the 6 m limit
    assert hs_max["2025-01-31T00":"2025-02-02T00"].max() > 6.5  # storm B in the forecast window
    assert hs_max["2025-01-07T00":"2025-01-10T12"].max() > 6.5  # storm C (issue 21: heavy seas on the cargo routes)
    calm = pd.concat([hs_max[:"2025-01-06T12"], hs_max["2025-01-11T00":"2025-01-13T00"], hs_max["2025-01-17T00":"2025-01-30T00"]])
    assert calm.max() < 4.0
    # storm A crosses the Barcelona-Palma lane (about 40.5N 2.4E) on 2025-01-14/15
    iy, ix = int(round((40.5 - 35.5) * 12)), int(round((2.4 + 1.5) * 12))
    lane = pd.Series(w.hs_m.values[:, iy, ix], index=hs_max.index)
    assert lane["2025-01-14T06":"2025-01-15T18"].max() > 4.5
    desc = scenario_weather.describe()
    assert [s["name"] for s in desc["storms"]] == ["A", "B", "C"] and desc["synthetic"] is True


def test_scenario_files_read_back_through_the_readers(tmp_path):
    from weather.io import read_local
    from weather.io.scenario_files import write_scenario_weather
    from weather.scenario import generate_weather

    # the forecast window (storm B), which spans the January/February ERA5 files
    scenario_weather = generate_weather(seed=0, start="2025-01-31T00:00Z", end="2025-02-02T06:00Z")
    info = write_scenario_weather(tmp_path, weather=scenario_weather)
    assert (info["start_utc"], info["end_utc"]) == ("2025-01-31T00:00:00Z", "2025-02-02T06:00:00Z")  # the window written
    names = [p.split("/")[-1] for p in info["files"]]
    assert names[0] == "cmems_mod_glo_wav_anfc_0.083deg_PT3H-i_VHM0-VMDR-VTM10-VTPK_1.50W-11.50E_35.50N-45.00N_2025-01-31-2025-02-02.nc"
    assert names[1:] == ["era5_reanalysis-era5-single-levels_10m_wind_2025-01.nc",
                         "era5_reanalysis-era5-single-levels_10m_wind_2025-02.nc"]
    ds, meta = read_local(tmp_path / "weather")
    assert meta["base"] == "CMEMS GLOBAL_ANALYSISFORECAST_WAV_001_027 (synthetic)"
    np.testing.assert_allclose(ds.hs_m.values, scenario_weather.waves.hs_m.values, atol=0.0005 + 1e-6, equal_nan=True)
    # wind: regridded from 0.25 deg hourly onto the wave grid at the 3-hourly wave times
    wind = scenario_weather.wind.sel(time_utc=ds.time_utc.values).interp(lat=ds.lat.values, lon=ds.lon.values)
    sea = np.isfinite(ds.hs_m.values)
    err = np.abs(ds.wind_u_ms.values - wind.wind_u_ms.values)[sea]
    assert err.max() < 0.01  # bilinear both ways; int16 packing of ERA5 (range/65534 ~ 1 mm/s)
