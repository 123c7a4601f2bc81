"""Acquisition with the real clients' call shapes, mocking only the remote services.

The fake ``copernicusmarine.subset`` / ``cdsapi.Client.retrieve`` write files in the products'
exact schemas (our writers), so the same reading path as real downloads is exercised.
"""

from __future__ import annotations

import sys
import types

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from weather.errors import FetchError
from weather.io.cache import DownloadCache, Request
from weather.io.cmems import get_cmems, read_cmems, write_cmems_wave
from weather.io.era5 import cds_request, get_era5, month_chunks, read_era5, write_era5


def canonical_waves(bbox, start, end, step_h=3):
    lat = np.arange(bbox[1], bbox[3] + 1e-9, 1 / 12)
    lon = np.arange(bbox[0], bbox[2] + 1e-9, 1 / 12)
    t = pd.date_range(pd.Timestamp(start).tz_localize(None), pd.Timestamp(end).tz_localize(None), freq=f"{step_h}h").values
    shape = (t.size, lat.size, lon.size)
    base = np.linspace(0.5, 3.0, int(np.prod(shape))).reshape(shape)
    return xr.Dataset({"hs_m": (("time_utc", "lat", "lon"), base.astype(np.float32)),
                       "wave_from_deg": (("time_utc", "lat", "lon"), np.full(shape, 300.0, np.float32)),
                       "tp_s": (("time_utc", "lat", "lon"), (4 * np.sqrt(base)).astype(np.float32)),
                       "tm_s": (("time_utc", "lat", "lon"), (3.5 * np.sqrt(base)).astype(np.float32))},
                      coords={"time_utc": t, "lat": lat, "lon": lon})


class FakeCopernicusMarine:
    """Stands in for the copernicusmarine module: records calls and writes a CMEMS-schema file."""

    def __init__(self, behaviour=("ok",)):
        self.calls = []
        self.behaviour = list(behaviour)

    def subset(self, **kw):
        self.calls.append(kw)
        what = self.behaviour.pop(0) if self.behaviour else "ok"
        if what == "none":
            return None  # what the real client does without credentials
        if what == "raise":
            raise ConnectionError("HTTPSConnectionPool: Max retries exceeded")
        bbox = (kw["minimum_longitude"], kw["minimum_latitude"], kw["maximum_longitude"], kw["maximum_latitude"])
        path = f"{kw['output_directory']}/{kw['output_filename']}"
        write_cmems_wave(canonical_waves(bbox, kw["start_datetime"], kw["end_datetime"]), path, synthetic=False)
        return types.SimpleNamespace(file_path=path, status="000")


@pytest.fixture
def fake_cm(monkeypatch):
    fake = FakeCopernicusMarine()
    monkeypatch.setitem(sys.modules, "copernicusmarine", fake)
    return fake


def test_cmems_fetch_downloads_once_then_uses_the_cache(tmp_path, fake_cm):
    cache = DownloadCache(tmp_path / "cache")
    bbox = (2.0, 39.0, 3.0, 40.0)
    path, info = get_cmems(bbox, "2025-01-14T00:00Z", "2025-01-15T00:00Z", cache=cache)
    assert info["cached"] is False and info["attempts"] == 1
    call = fake_cm.calls[0]
    assert call["dataset_id"] == "cmems_mod_glo_wav_anfc_0.083deg_PT3H-i"
    assert call["variables"] == ["VHM0", "VMDR", "VTPK", "VTM10"]
    assert (call["minimum_longitude"], call["maximum_latitude"]) == (2.0, 40.0)
    assert call["start_datetime"] == "2025-01-14T00:00" and call["disable_progress_bar"] is True
    assert "username" not in call and "password" not in call  # credentials are the client's business
    ds, meta = read_cmems(path)
    assert ds.time_utc.size == 9 and meta["product"] == "CMEMS GLOBAL_ANALYSISFORECAST_WAV_001_027"
    again, info2 = get_cmems(bbox, pd.Timestamp("2025-01-14T01:00+01:00"), "2025-01-15T00:00Z", cache=cache)
    assert again == path and info2["cached"] is True and len(fake_cm.calls) == 1  # same request in another tz
    other, info3 = get_cmems((2.0, 39.0, 3.5, 40.0), "2025-01-14T00:00Z", "2025-01-15T00:00Z", cache=cache)
    assert other != path and len(fake_cm.calls) == 2


def test_cmems_without_credentials_fails_at_once(tmp_path, fake_cm):
    fake_cm.behaviour = ["none"]
    with pytest.raises(FetchError, match="copernicusmarine client returned nothing.*copernicusmarine login"):
        get_cmems((2, 39, 3, 40), "2025-01-14", "2025-01-15", cache=DownloadCache(tmp_path))
    assert len(fake_cm.calls) == 1  # no retry: credentials do not appear by retrying


def test_cmems_network_errors_are_retried_a_bounded_number_of_times(tmp_path, fake_cm):
    sleeps = []
    fake_cm.behaviour = ["raise", "raise", "ok"]
    path, info = get_cmems((2, 39, 3, 40), "2025-01-14", "2025-01-15", cache=DownloadCache(tmp_path), sleep=sleeps.append)
    assert info["attempts"] == 3 and sleeps == [2.0, 5.0] and path.exists()
    fake_cm.behaviour = ["raise"] * 5
    with pytest.raises(FetchError, match=r"download failed after 3 attempts: ConnectionError"):
        get_cmems((2, 39, 3.5, 40), "2025-01-14", "2025-01-15", cache=DownloadCache(tmp_path), sleep=sleeps.append)
    assert not list((tmp_path / "cmems-wave").glob(".*partial*"))  # no half files left behind


class FakeCdsClient:
    instances = []

    def __init__(self, **kw):
        self.kw = kw
        self.requests = []
        FakeCdsClient.instances.append(self)

    def retrieve(self, dataset, request, target):
        self.requests.append((dataset, request))
        days = [pd.Timestamp(f"{y}-{m}-{d}") for y in request["year"] for m in request["month"] for d in request["day"]]
        t = pd.date_range(min(days), max(days) + pd.Timedelta(hours=23), freq="1h").values
        north, west, south, east = request["area"]
        lat = np.arange(south, north + 1e-9, 0.25)
        lon = np.arange(west, east + 1e-9, 0.25)
        shape = (t.size, lat.size, lon.size)
        ds = xr.Dataset({"wind_u_ms": (("time_utc", "lat", "lon"), np.full(shape, 5.0, np.float32)),
                         "wind_v_ms": (("time_utc", "lat", "lon"), np.full(shape, -2.0, np.float32))},
                        coords={"time_utc": t, "lat": lat, "lon": lon})
        write_era5(ds, target, layout="valid_time", synthetic=False)


def test_era5_fetch_per_month_with_bounded_client(tmp_path, monkeypatch):
    FakeCdsClient.instances = []
    monkeypatch.setitem(sys.modules, "cdsapi", types.SimpleNamespace(Client=FakeCdsClient))
    cache = DownloadCache(tmp_path)
    paths, info = get_era5((-1.5, 35.5, 11.5, 45.0), "2025-01-31T00:00Z", "2025-02-01T12:00Z", cache=cache)
    assert info["cached"] == [False, False] and len(paths) == 2
    client = FakeCdsClient.instances[0]
    assert client.kw["retry_max"] == 3 and client.kw["sleep_max"] == 10.0 and client.kw["timeout"] == 60.0
    (ds_name, req1), (_, req2) = client.requests
    assert ds_name == "reanalysis-era5-single-levels"
    assert req1["area"] == [45.0, -1.5, 35.5, 11.5] and req1["data_format"] == "netcdf"
    assert (req1["year"], req1["month"], req1["day"]) == (["2025"], ["01"], ["31"])
    assert req2["day"] == ["01"] and req2["time"][0] == "00:00" and req2["time"][-1] == "12:00"
    ds, meta = read_era5(paths[0])
    assert meta["product"] == "ERA5 single levels (valid_time layout)"
    np.testing.assert_allclose(ds.wind_u_ms.values, 5.0)
    paths2, info2 = get_era5((-1.5, 35.5, 11.5, 45.0), "2025-01-31T00:00Z", "2025-02-01T12:00Z", cache=cache)
    assert info2["cached"] == [True, True] and paths2 == paths and len(FakeCdsClient.instances) == 1


def test_era5_missing_configuration_is_a_clear_error(tmp_path, monkeypatch):
    def no_rc(**kw):
        raise Exception("Missing/incomplete configuration file: /root/.cdsapirc")

    monkeypatch.setitem(sys.modules, "cdsapi", types.SimpleNamespace(Client=no_rc))
    with pytest.raises(FetchError, match=r"cdsapi client cannot start: Missing/incomplete configuration file.*~/.cdsapirc"):
        get_era5((0, 40, 1, 41), "2025-01-01", "2025-01-02", cache=DownloadCache(tmp_path))


def test_month_chunks_and_request_keys():
    chunks = month_chunks("2024-12-30T12:00Z", "2025-02-01T03:00Z")
    assert [(a.strftime("%Y-%m-%dT%H"), b.strftime("%Y-%m-%dT%H")) for a, b in chunks] == [
        ("2024-12-30T12", "2024-12-31T23"), ("2025-01-01T00", "2025-01-31T23"), ("2025-02-01T00", "2025-02-01T03")]
    r = cds_request(["10m_u_component_of_wind"], (0, 40, 1, 41), chunks[2][0], chunks[2][1])
    assert r["time"] == ["00:00", "01:00", "02:00", "03:00"]
    a = Request.make("cmems-wave", "x", ["VTPK", "VHM0"], (2, 39, 3, 40), "2025-01-01T00:00Z", "2025-01-02T00:00Z")
    b = Request.make("cmems-wave", "x", ["VHM0", "VTPK"], (2.00001, 39, 3, 40), "2025-01-01T01:00+01:00", "2025-01-02")
    assert a.key == b.key  # variable order, sub-1e-4 bbox noise and time zones do not change the key
    with pytest.raises(ValueError, match="lon_min < lon_max"):
        Request.make("p", "x", [], (3, 39, 2, 40), "2025-01-01", "2025-01-02")
