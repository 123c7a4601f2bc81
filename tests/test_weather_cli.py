"""`stormlane weather ...` commands (JSON contract, errors as one line + exit 2) and the Prefect flow."""

from __future__ import annotations

import json
import subprocess
import sys
import types

import numpy as np
import pandas as pd
import pytest

from conftest import shared_file
from pipelines.cli import main

MED = "weather/simroute_cmems_medsea_wav"


def run_cli(capsys, *args):
    """Run the CLI in-process; returns (exit code, stdout, stderr)."""
    code = 0
    try:
        main(list(args))
    except SystemExit as exc:
        code = exc.code or 0
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def demo_weather_dir(tmp_path_factory):
    """Two days of demo weather written in the products' schemas (storm B window)."""
    from weather.io.scenario_files import write_scenario_weather
    from weather.scenario import generate_weather

    out = tmp_path_factory.mktemp("demo")
    write_scenario_weather(out, weather=generate_weather(seed=1, start="2025-01-31T00:00Z", end="2025-02-02T06:00Z"))
    return out / "weather"


def test_info_json_on_real_cmems(shared_data, capsys):
    code, out, _ = run_cli(capsys, "weather", "info", str(shared_file(shared_data, MED)), "--json")
    assert code == 0
    info = json.loads(out)  # exactly one JSON object on stdout
    assert info["product"] == "CMEMS MEDSEA_ANALYSIS_FORECAST_WAV_006_017"
    assert info["shape"] == [48, 90, 99] and len(info["inputs"]) == 2
    assert info["variables"] == {"hs_m": info["product"], "wave_from_deg": info["product"], "tp_s": info["product"]}


def test_info_table_on_real_cmems(shared_data, capsys):
    """The table: the grid as lat x lon with its step, the box rounded to 0.0001 deg (1/24 deg cells: 38.4375, 42.1458)."""
    code, out, _ = run_cli(capsys, "weather", "info", str(shared_file(shared_data, MED)))
    assert code == 0
    lines = out.splitlines()
    assert lines[:3] == ["CMEMS MEDSEA_ANALYSIS_FORECAST_WAV_006_017",
                         "  time   2020-01-20T00:00Z -> 2020-01-21T23:00Z  (48 steps)",
                         "  grid   90 x 99 (lat x lon), step 0.04167 x 0.04167 deg, bbox [1.5, 38.4375, 5.5833, 42.1458]"]


def test_load_join_and_exceedance(demo_weather_dir, tmp_path, capsys):
    db = tmp_path / "ws.duckdb"
    code, out, _ = run_cli(capsys, "weather", "load", str(demo_weather_dir), "--db", str(db), "--json")
    assert code == 0
    grid = json.loads(out)
    assert grid["variables"] == ["hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms"]
    assert grid["name"].startswith("CMEMS GLOBAL_ANALYSISFORECAST_WAV_001_027 (synthetic) + ERA5")
    pts = pd.DataFrame({"path_id": ["MRS-ALG"] * 3, "seq": [0, 1, 2], "lat_deg": [42.8, 39.5, 37.6],
                        "lon_deg": [5.3, 4.6, 3.1], "speed_kn": [15.0, 15.0, 15.0]})
    csv = tmp_path / "pts.csv"
    pts.to_csv(csv, index=False)
    joined = tmp_path / "joined.csv"
    code, out, _ = run_cli(capsys, "weather", "join", "--points", str(csv), "--depart", "2025-01-31T06:00Z", "--step-h", "6",
                           "--count", "4", "--db", str(db), "--out", str(joined), "--json")
    assert code == 0
    summary = json.loads(out)
    assert summary["n_points"] == 12 and summary["status"] == {"ok": 12}
    table = pd.read_csv(joined)
    assert set(table.columns) >= {"eta_utc", "weather_time_utc", "hs_m", "status", "lat_idx", "lon_idx"}
    assert summary["max_hs_m"]["MRS-ALG"] == pytest.approx(table.hs_m.max(), abs=1e-3)
    # a departure whose ETAs fall after the data: one clear error line, exit 2
    code, out, err = run_cli(capsys, "weather", "join", "--points", str(csv), "--depart", "2025-02-02T00:00Z", "--db", str(db))
    assert code == 2 and out == ""
    assert err.startswith("error: CMEMS GLOBAL_ANALYSISFORECAST_WAV_001_027 (synthetic)") and "no data for ETAs" in err
    assert len(err.strip().splitlines()) == 1
    code, out, _ = run_cli(capsys, "weather", "exceedance", str(demo_weather_dir), "--vessel", "container-large", "--json")
    assert code == 0
    ex = json.loads(out)
    assert ex["limits"] == "container, Lpp >= 200 m (MEPC.1/Circ.850/Rev.2 table, seed Table 1)" and ex["skipped"][0].startswith("beam_seas")
    assert len(ex["steps"]) == 19 and max(s["unsafe_frac"] for s in ex["steps"]) > 0.05  # storm B
    assert all(s["n_sea"] == ex["steps"][0]["n_sea"] for s in ex["steps"])


def test_errors_are_one_line_exit_2(tmp_path):
    res = subprocess.run([sys.executable, "-m", "pipelines.cli", "weather", "load", str(tmp_path / "nope.nc"), "--db",
                          str(tmp_path / "w.duckdb")], capture_output=True, text=True)
    assert res.returncode == 2 and res.stderr.strip() == f"error: {tmp_path / 'nope.nc'}: no such file or directory"
    res = subprocess.run([sys.executable, "-m", "pipelines.cli", "weather", "fetch", "--bbox", "1,2,3", "--start", "2025-01-01",
                          "--end", "2025-01-02"], capture_output=True, text=True)
    assert res.returncode == 2 and "--bbox must be LON_MIN,LAT_MIN,LON_MAX,LAT_MAX" in res.stderr
    res = subprocess.run([sys.executable, "-m", "pipelines.cli", "weather", "--help"], capture_output=True, text=True)
    assert res.returncode == 0 and all(c in res.stdout for c in ("fetch", "info", "load", "join", "exceedance"))


def test_fetch_command_uses_the_cache(tmp_path, monkeypatch, capsys):
    from weather.io.cmems import write_cmems_wave

    calls = []

    def subset(**kw):
        calls.append(kw)
        lat = np.arange(kw["minimum_latitude"], kw["maximum_latitude"] + 1e-9, 1 / 12)
        lon = np.arange(kw["minimum_longitude"], kw["maximum_longitude"] + 1e-9, 1 / 12)
        t = pd.date_range(kw["start_datetime"], kw["end_datetime"], freq="3h").values
        import xarray as xr

        ds = xr.Dataset({"hs_m": (("time_utc", "lat", "lon"), np.ones((t.size, lat.size, lon.size), np.float32))},
                        coords={"time_utc": t, "lat": lat, "lon": lon})
        path = f"{kw['output_directory']}/{kw['output_filename']}"
        write_cmems_wave(ds, path, synthetic=False)
        return types.SimpleNamespace(file_path=path)

    monkeypatch.setitem(sys.modules, "copernicusmarine", types.SimpleNamespace(subset=subset))
    args = ["weather", "fetch", "--bbox", "2,39,3,40", "--start", "2025-01-14T00:00Z", "--end", "2025-01-14T12:00Z",
            "--cache", str(tmp_path / "cache"), "--json"]
    code, out, _ = run_cli(capsys, *args)
    first = json.loads(out)
    assert code == 0 and first["cached"] == [False] and len(calls) == 1
    code, out, _ = run_cli(capsys, *args, "--load", "--db", str(tmp_path / "w.duckdb"))
    second = json.loads(out)
    assert second["cached"] == [True] and len(calls) == 1 and second["files"] == first["files"]
    assert second["grid"]["n_cells"] == 5 * 13 * 13


def test_weather_flow_under_prefect(prefect_harness, demo_weather_dir, tmp_path):
    from pipelines.storage import open_workspace
    from pipelines.storage.weather import list_grids
    from pipelines.weather import weather_flow

    db = tmp_path / "flow.duckdb"
    result = weather_flow(paths=[str(demo_weather_dir)], db=str(db), name="demo")
    assert result["name"] == "demo" and result["n_times"] == 19
    with open_workspace(db) as ws:
        grids = list_grids(ws)
    assert grids.name.tolist() == ["demo"] and int(grids.n_cells.iloc[0]) == result["n_cells"]
