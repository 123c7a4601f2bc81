"""Weather readers on every real file in ../shared/data/weather, checked against an independent
decoding of the raw packed values (netCDF4 with automatic masking/scaling switched off, or
ecCodes for GRIB), plus land = NaN and the direction conventions."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from conftest import shared_file
from thresholds.units import MS_PER_KN
from weather.errors import CoverageError, WeatherFileError

MED = "weather/simroute_cmems_medsea_wav/Waves_MEDSEA_20200120.nc"
MED2 = "weather/simroute_cmems_medsea_wav/Waves_MEDSEA_20200121.nc"
BALTIC = "weather/wrt_cmems_gfs_baltic/reduced_testdata_weather.nc"
CUR_NATIVE = "weather/shiprouting_cmems_glo_cur/cmems_mod_glo_phy-cur_anfc_0.083deg_P1D-m_2024-01_100W-020E_10N-65N.nc"
CUR_COARSE = "weather/shiprouting_cmems_glo_cur/cmems_mod_glo_phy-cur_anfc_0.083deg_P1D-m_2024-01_1deg_5day.nc"
GRIB_WMED = "weather/gweatherrouting_gfs_grib1/20130311_120424_.grb"
GRIB_ATL = "weather/gweatherrouting_gfs_grib1/20130214_132805_.grb"
ZARR = "weather/weather_routing_era5/test_ds.zarr"
LSM = "weather/weather_routing_era5/era5_land-sea-mask.nc"
ETOPO = "weather/wrt_etopo2022_depth/reduced_testdata_depth.nc"


def raw_variable(path, name):
    """(raw array, attrs) straight from netCDF4, no masking or scaling."""
    import netCDF4

    with netCDF4.Dataset(path) as nc:
        var = nc.variables[name]
        var.set_auto_maskandscale(False)
        return np.asarray(var[:]), {k: var.getncattr(k) for k in var.ncattrs()}


def raw_coord(path, name):
    import netCDF4

    with netCDF4.Dataset(path) as nc:
        return np.asarray(nc.variables[name][:], dtype=float)


def decode_packed(raw, attrs):
    """Independent CF decoding: fill/missing -> NaN, then raw * scale_factor + add_offset."""
    fills = {attrs.get("_FillValue"), attrs.get("missing_value")} - {None}
    out = raw.astype(np.float64) * float(attrs.get("scale_factor", 1.0)) + float(attrs.get("add_offset", 0.0))
    for f in fills:
        out = np.where(raw == f, np.nan, out)
    return out


def sample_points(shape, n=60, seed=0):
    rng = np.random.default_rng(seed)
    return tuple(rng.integers(0, s, n) for s in shape)


# ------------------------------------------------------------------ CMEMS MEDSEA (packed int16)


@pytest.mark.parametrize("relative", [MED, MED2])
def test_cmems_medsea_values_equal_raw_packed(shared_data, relative):
    from weather.io.cmems import read_cmems

    path = shared_file(shared_data, relative)
    ds, meta = read_cmems(path)
    assert meta["product"] == "CMEMS MEDSEA_ANALYSIS_FORECAST_WAV_006_017"
    assert ds.hs_m.dims == ("time_utc", "lat", "lon") and ds.hs_m.shape == (24, 90, 99)
    lat = raw_coord(path, "latitude")
    lon = raw_coord(path, "longitude")
    assert np.all(np.diff(lat) > 0) and np.all(np.diff(lon) > 0)  # the file is already ascending
    secs = raw_coord(path, "time")  # seconds since 1970-01-01
    expected_t = pd.to_datetime(secs, unit="s").values
    np.testing.assert_array_equal(ds.time_utc.values, expected_t)
    for src, dst in (("VHM0", "hs_m"), ("VTPK", "tp_s"), ("VMDR", "wave_from_deg")):
        raw, attrs = raw_variable(path, src)
        assert raw.dtype == np.int16 and attrs["_FillValue"] == -32767
        expected = decode_packed(raw, attrs)
        it, iy, ix = sample_points(raw.shape)
        got = ds[dst].values[it, iy, ix]
        # float32 storage of a value quantised to the scale factor: relative error <= 1e-6
        np.testing.assert_allclose(got, expected[it, iy, ix], rtol=2e-6, atol=1e-5, equal_nan=True)
        # land: every fill value is NaN and nothing else is
        np.testing.assert_array_equal(np.isnan(ds[dst].values), raw == -32767)
    # VMDR is packed with add_offset 180: check one sea value by hand
    raw, attrs = raw_variable(path, "VMDR")
    k = np.argwhere(raw[0] != -32767)[0]
    assert ds.wave_from_deg.values[0, k[0], k[1]] == pytest.approx(raw[0, k[0], k[1]] * 0.01 + 180.0, abs=1e-4)


def test_cmems_medsea_direction_is_coming_from(shared_data):
    """Storm Gloria (2020-01-20/21) was an easterly storm in the Balearic Sea: where Hs > 6 m the
    waves must come FROM the east (VMDR standard_name sea_surface_wave_from_direction, kept as is)."""
    from weather.io.cmems import read_cmems

    path = shared_file(shared_data, MED)
    _, attrs = raw_variable(path, "VMDR")
    assert attrs["standard_name"] == "sea_surface_wave_from_direction"
    ds, _ = read_cmems(path)
    big = ds.hs_m.values > 6.0
    assert big.sum() > 100
    d = ds.wave_from_deg.values[big]
    mean_dir = np.rad2deg(np.arctan2(np.sin(np.deg2rad(d)).mean(), np.cos(np.deg2rad(d)).mean())) % 360
    assert 30.0 < mean_dir < 120.0  # from the NE-E sector, not the opposite (flow-to would be ~250)


def test_cmems_two_days_concatenate_in_read_local(shared_data):
    from weather.io import read_local

    folder = shared_file(shared_data, "weather/simroute_cmems_medsea_wav")
    ds, meta = read_local(folder)
    assert ds.time_utc.size == 48
    assert meta["start_utc"] == "2020-01-20T00:00Z" and meta["end_utc"] == "2020-01-21T23:00Z"
    assert np.all(np.diff(ds.time_utc.values) == np.timedelta64(1, "h"))
    assert float(np.nanmax(ds.hs_m.values)) == pytest.approx(8.94, abs=0.01)  # PROVENANCE: "Hs up to 8.94 m"


# ------------------------------------------------------------------ 52North merged Baltic file (float64, NaN land)


def test_baltic_merged_file(shared_data):
    from weather.io.netcdf import read_netcdf

    path = shared_file(shared_data, BALTIC)
    ds, meta = read_netcdf(path)
    assert set(ds.data_vars) == {"hs_m", "wave_from_deg", "tp_s", "wind_u_ms", "wind_v_ms", "current_u_ms", "current_v_ms"}
    assert meta["variables"]["current_u_ms"] == "utotal"  # total currents preferred over uo
    # time: "hours since 2023-07-20T10:00:00", 3-hourly
    assert pd.Timestamp(ds.time_utc.values[0]) == pd.Timestamp("2023-07-20T10:00")
    assert np.all(np.diff(ds.time_utc.values) == np.timedelta64(3, "h"))
    raw, _ = raw_variable(path, "VHM0")
    np.testing.assert_allclose(ds.hs_m.values, raw.astype(np.float32), equal_nan=True)
    # PROVENANCE: land = NaN, 43 % of wave cells
    assert np.isnan(ds.hs_m.values[0]).mean() == pytest.approx(0.43, abs=0.02)
    heights = raw_coord(path, "height_above_ground")
    k10 = int(np.flatnonzero(np.isclose(heights, 10.0))[0])
    rawu, _ = raw_variable(path, "u-component_of_wind_height_above_ground")
    np.testing.assert_allclose(ds.wind_u_ms.values, rawu[:, k10].astype(np.float32), equal_nan=True)
    rawc, _ = raw_variable(path, "utotal")
    np.testing.assert_allclose(ds.current_u_ms.values, rawc[0].astype(np.float32), equal_nan=True)
    # values quoted in PROVENANCE: Hs 0.09-0.93 m, wind u up to 11.8 m/s, |currents| < 0.25 m/s
    assert 0.05 < np.nanmin(ds.hs_m.values) < 0.15 and 0.85 < np.nanmax(ds.hs_m.values) < 1.0
    assert np.nanmax(np.abs(ds.current_u_ms.values)) < 0.25


# ------------------------------------------------------------------ CMEMS currents (float32, NaN land)


@pytest.mark.parametrize("relative", [CUR_NATIVE, CUR_COARSE])
def test_cmems_currents(shared_data, relative):
    from weather.io.cmems import read_cmems

    path = shared_file(shared_data, relative)
    ds, meta = read_cmems(path)
    assert meta["product"].startswith("CMEMS cmems_mod_glo_phy-cur_anfc_0.083deg_P1D-m")
    lat = raw_coord(path, "latitude")
    lon = raw_coord(path, "longitude")
    raw, _ = raw_variable(path, "uo")
    order_y = np.argsort(lat)
    order_x = np.argsort(((lon + 180) % 360) - 180)
    expected = raw[:, order_y][:, :, order_x]
    it, iy, ix = sample_points(expected.shape, n=200)
    np.testing.assert_array_equal(ds.current_u_ms.values[it, iy, ix], expected[it, iy, ix].astype(np.float32))
    assert np.isnan(ds.current_u_ms.values).any()  # land
    assert ds.lon.values.min() >= -180 and ds.lon.values.max() < 180


# ------------------------------------------------------------------ GFS GRIB1 via cfgrib, checked with ecCodes


def eccodes_first_message(path, short_name):
    import eccodes

    with open(path, "rb") as fh:
        while True:
            h = eccodes.codes_grib_new_from_file(fh)
            if h is None:
                raise AssertionError(f"no {short_name} in {path}")
            try:
                if eccodes.codes_get(h, "shortName") == short_name and eccodes.codes_get(h, "level") == 10:
                    nj, ni = eccodes.codes_get(h, "Nj"), eccodes.codes_get(h, "Ni")
                    first = eccodes.codes_get(h, "latitudeOfFirstGridPointInDegrees")
                    last = eccodes.codes_get(h, "latitudeOfLastGridPointInDegrees")
                    vals = eccodes.codes_get_values(h).reshape(nj, ni)
                    return vals, first, last, eccodes.codes_get(h, "jScansPositively")
            finally:
                eccodes.codes_release(h)


@pytest.mark.parametrize("relative, lat_range, steps", [(GRIB_WMED, (37.0, 44.0), 65), (GRIB_ATL, (25.0, 48.0), 13)])
def test_gfs_grib_winds_and_latitude_fix(shared_data, relative, lat_range, steps):
    from weather.io.gfs import read_gfs

    path = shared_file(shared_data, relative)
    ds, meta = read_gfs(path)
    assert ds.time_utc.size == steps
    # the files' jDirectionIncrement is corrupt (33.268 deg): latitudes rebuilt from first/last point
    assert ds.lat.values[0] == lat_range[0] and ds.lat.values[-1] == lat_range[1]
    np.testing.assert_allclose(np.diff(ds.lat.values), 0.5)
    assert "jDirectionIncrement 33.268" in meta["grid_fix"]
    for short, name in (("10u", "wind_u_ms"), ("10v", "wind_v_ms")):
        vals, first, last, j_pos = eccodes_first_message(path, short)
        assert j_pos == 0 and first > last  # rows run north to south in the file
        np.testing.assert_allclose(ds[name].values[0], vals[::-1].astype(np.float32), rtol=1e-6)
    assert ds.attrs["run_utc"] == meta["run_utc"]
    assert pd.Timestamp(ds.time_utc.values[0]) == pd.Timestamp(meta["run_utc"].replace("Z", ""))


# ------------------------------------------------------------------ derived ERA5 wind in zarr


def test_era5_zarr_speed_direction(shared_data):
    import zarr  # noqa: F401  (the reader needs it)
    import xarray as xr

    from thresholds.units import dir_from_uv
    from weather.io.wind_zarr import read_wind_zarr

    path = shared_file(shared_data, ZARR)
    ds, meta = read_wind_zarr(path)
    raw = xr.open_zarr(path)
    tws = raw.tws.values[:, ::-1, :]  # file latitudes run -10 -> -50; ours ascend
    twd = raw.twd.values[:, ::-1, :]
    speed_kn = np.hypot(ds.wind_u_ms.values, ds.wind_v_ms.values) / MS_PER_KN
    np.testing.assert_allclose(speed_kn, tws, rtol=1e-5, atol=1e-4)
    # direction convention: twd is "from"; rebuild it from the components (WMO: u>0 -> from 270)
    strong = tws > 5.0
    got = dir_from_uv(ds.wind_u_ms.values[strong], ds.wind_v_ms.values[strong])
    diff = np.abs((got - twd[strong] + 180.0) % 360.0 - 180.0)
    assert diff.max() < 1e-2
    assert meta["shape"] == [20, 161, 281]


def test_era5_zarr_through_the_cli(shared_data):
    """The CLI tells xarray its process holds no dask arrays (a faster start); the zarr store must
    then open numpy-backed, or ``weather info`` and ``route --weather`` died with a traceback
    ("Could not find a Chunk Manager which recognises type dask.array.core.Array"). A fresh
    process, as a user's command."""
    import subprocess
    import sys

    path = str(shared_file(shared_data, ZARR))
    cmd = [sys.executable, "-m", "pipelines.cli"]
    info = subprocess.run([*cmd, "weather", "info", path], capture_output=True, text=True, timeout=300)
    assert info.returncode == 0 and "Traceback" not in info.stderr, info.stderr
    assert "2022-01-01T00:00Z -> 2022-01-10T12:00Z  (20 steps)" in info.stdout and "wind_u_ms" in info.stdout
    route = subprocess.run([*cmd, "route", "--from", "-34.0,18.0", "--to", "-23.0,-43.0", "--depart", "2022-01-02T00:00Z",
                            "--weather", path, "--speed-loss", "kwon", "--json"], capture_output=True, text=True, timeout=300)
    assert route.returncode == 0, route.stderr
    out = json.loads(route.stdout)
    assert out["optimal"]["time_h"] > out["min_distance_calm"]["time_h"]  # the wind slows the ship


# ------------------------------------------------------------------ files that are not weather, bad files


@pytest.mark.parametrize("relative, names", [(LSM, "lsm"), (ETOPO, "crs, z")])
def test_non_weather_files_are_refused_by_name(shared_data, relative, names):
    from weather.io.netcdf import read_netcdf

    path = shared_file(shared_data, relative)
    with pytest.raises(WeatherFileError, match=rf"not a recognised weather product \(variables: {names}"):
        read_netcdf(path)


def test_missing_and_garbage_files(tmp_path):
    from weather.io import read_local

    with pytest.raises(WeatherFileError, match="no such file"):
        read_local(tmp_path / "nope.nc")
    junk = tmp_path / "junk.nc"
    junk.write_bytes(b"this is not netcdf")
    with pytest.raises(WeatherFileError, match="junk.nc: not a readable NetCDF file"):
        read_local(junk)
    (tmp_path / "empty").mkdir()
    with pytest.raises(WeatherFileError, match="holds no weather files"):
        read_local(tmp_path / "empty")


def test_truncated_real_files_are_refused_as_truncated(shared_data, tmp_path, capsys):
    # The first 100 kB of a real file: the classic (CDF-1) MEDSEA file opens without complaint and
    # reads the missing data as fill values, so this used to say "duplicate latitude or longitude
    # values"; the HDF5 one failed with a bare "HDF error".
    from pipelines.cli import main
    from weather.io import read_local

    for relative, kind in ((MED, "NetCDF classic"), (CUR_NATIVE, "NetCDF-4/HDF5")):
        src = shared_file(shared_data, relative)
        cut = tmp_path / f"cut_{src.name}"
        cut.write_bytes(src.read_bytes()[:100_000])
        size = src.stat().st_size
        with pytest.raises(WeatherFileError, match=rf"cut_.*: truncated {kind} file: 100000 bytes on disk, its header says {size}"):
            read_local(cut)
        with pytest.raises(SystemExit) as exc:
            main(["weather", "info", str(cut)])
        err = capsys.readouterr().err.strip()
        assert exc.value.code == 2 and len(err.splitlines()) == 1
        assert err.startswith(f"error: {cut}: truncated {kind} file") and "duplicate" not in err


@pytest.mark.parametrize("fmt", ["NETCDF3_CLASSIC", "NETCDF3_64BIT_OFFSET", "NETCDF3_64BIT_DATA", "NETCDF4", "NETCDF4_CLASSIC"])
def test_truncated_netcdf_is_detected_at_every_length(tmp_path, fmt):
    """Complete files of every NetCDF format pass; every cut of the header or the data fails:
    every length through the first 2 KiB (the classic header, HDF5's superblock) and every 37th
    after it, and the last cut (checking all 18,012 cuts of the 18 kB HDF5 file took 48 s of the
    suite under load; beyond the header each cut is the same comparison of the size on disk with
    the end the header records)."""
    import netCDF4

    from weather.io.netcdf import check_complete

    path = tmp_path / "full.nc"
    with netCDF4.Dataset(path, "w", format=fmt) as nc:
        nc.createDimension("time", None)  # record variables: sizes from the record count
        nc.createDimension("lat", 7)
        nc.title = "t" * 5
        nc.createVariable("lat", "f4", ("lat",))[:] = np.arange(7)
        nc.createVariable("VHM0", "i2", ("time", "lat"))[0:6] = 1
        nc.createVariable("flag", "i1", ("time",))[0:6] = 1
    data = path.read_bytes()
    check_complete(path)
    cut = tmp_path / "cut.nc"
    lengths = [*range(4, min(2048, len(data) - 3)), *range(2048, len(data) - 3, 37), len(data) - 4]
    for n in lengths:  # the last record's padding (up to 3 bytes) is optional
        cut.write_bytes(data[:n])
        with pytest.raises(WeatherFileError, match="cut.nc: truncated NetCDF"):
            check_complete(cut)


def test_products_without_overlap_are_refused(shared_data):
    from weather.io import read_local

    med = shared_file(shared_data, "weather/simroute_cmems_medsea_wav")
    gfs = shared_file(shared_data, GRIB_WMED)  # 2013 winds, 2020 waves
    with pytest.raises(CoverageError, match=r"NOAA GFS GRIB \(10 m wind\), wind_u_ms, wind_v_ms: covers 2013-03-11T06:00Z"):
        read_local([med, gfs])
