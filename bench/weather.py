"""Benchmark of the weather join (issue 4): 50 lanes x 48 departures, beside xarray doing the same.

Inputs (generated once, untimed, cached): the demo month of weather in the products' own
schemas (CMEMS GLOBAL waves 1/12 deg 3-hourly, 2025-01-01 -> 2025-02-02T06, and ERA5 10 m wind
0.25 deg hourly in two monthly files, with the demo's storms); 50 lanes of 30 centroids as
great circles between the demo ports' approach points; 48 hourly departures from 2025-01-12.

* ``join_ours``: ``weather.io.read_local`` (decode, normalise, regrid the wind bilinearly onto
  the wave grid and linearly in time), ``load_weather`` into a new workspace (the grid's sea
  cells in DuckDB) and ``join_points_weather`` (ETAs from cumulative distance / speed, the
  grid cell by index arithmetic, the nearest time by an ASOF join): 72 000 path points.
* ``join_xarray`` (baseline, the same task the plain-xarray way, nothing stored): open the
  same files, ``Dataset.interp`` the wind onto the wave grid and times, ETAs with numpy, then
  one vectorised ``Dataset.sel(..., method="nearest")`` at the 72 000 points.

Throughput counts the path points given weather. Target (issue 4): under 5 s on 2 cores.
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: `import weather` must find the package, not this file
    import sys
    from pathlib import Path

    _here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _here]
    sys.path.insert(0, str(_here.parent))

import tempfile
from pathlib import Path

from bench._harness import Group, Measure, Side, Target, script_main, source_stamp

N_LANES, N_POINTS, N_DEPARTURES = 50, 30, 48
FIRST_DEPARTURE = "2025-01-12T00:00Z"


def prepare(folder: str) -> dict:
    """Write the demo weather unless a previous run left it."""
    from weather.io.scenario_files import write_scenario_weather

    wx = Path(folder) / "weather"
    files = sorted(wx.glob("*.nc")) if wx.is_dir() else []
    if len(files) < 3 or not (Path(folder) / "done").exists():
        write_scenario_weather(folder, seed=0)
        (Path(folder) / "done").write_text("ok")
        files = sorted(wx.glob("*.nc"))
    return {"files": [f.name for f in files], "mb": round(sum(f.stat().st_size for f in files) / 1e6, 1)}


def lane_points():
    """50 lanes x 30 centroids: great circles between the demo ports' approach points."""
    import itertools

    import numpy as np
    import pandas as pd

    from pipelines.config import data_dir
    from thresholds.geodesy import intermediate_point

    ports = pd.read_csv(data_dir() / "ports.csv")
    pairs = list(itertools.permutations(range(len(ports)), 2))[:N_LANES]
    rows = []
    for k, (a, b) in enumerate(pairs):
        A, B = ports.iloc[a], ports.iloc[b]
        lat, lon = intermediate_point(A.approach_lat_deg, A.approach_lon_deg, B.approach_lat_deg, B.approach_lon_deg,
                                      np.linspace(0.0, 1.0, N_POINTS))
        speed = 12.0 + 4.0 * ((k % 5) / 4.0)
        rows += [(f"{A.locode}-{B.locode}", i, lat[i], lon[i], speed) for i in range(N_POINTS)]
    return pd.DataFrame(rows, columns=["path_id", "seq", "lat_deg", "lon_deg", "speed_kn"])


def setup(folder: str) -> dict:
    import pandas as pd

    return {"weather": Path(folder) / "weather", "points": lane_points(),
            "departures": pd.date_range(FIRST_DEPARTURE, periods=N_DEPARTURES, freq="1h"),
            "tmp": Path(tempfile.mkdtemp(prefix="stormlane-bench-weather-"))}


def run_ours(st: dict) -> dict:
    from pipelines.storage import open_workspace
    from pipelines.storage.weather import join_points_weather, load_weather
    from weather.io import read_local

    db = st["tmp"] / "bench.duckdb"
    for suffix in ("", ".wal"):
        Path(str(db) + suffix).unlink(missing_ok=True)
    ds, _ = read_local(st["weather"])
    with open_workspace(db) as ws:
        load_weather(ws, ds, name="bench")
        out = join_points_weather(ws, st["points"], st["departures"], grid="bench", on_missing="flag")
    return {"work": int(len(out)), "status": {str(k): int(v) for k, v in out.status.value_counts().items()},
            "mean_hs_m": round(float(out.hs_m.mean()), 4)}


def _etas(points, departures):
    """ETA of every point for every departure: cumulative great-circle distance / the speed of
    the leg's first point (as ``join_points_weather`` computes them)."""
    import numpy as np

    from thresholds.geodesy import haversine_nmi

    lat, lon, eta = [], [], []
    for _, p in points.groupby("path_id", sort=False):
        p = p.sort_values("seq")
        la, lo, v = (p[c].to_numpy(dtype=float) for c in ("lat_deg", "lon_deg", "speed_kn"))
        legs_h = haversine_nmi(la[:-1], lo[:-1], la[1:], lo[1:]) / v[:-1]
        elapsed_ns = (np.concatenate([[0.0], np.cumsum(legs_h)]) * 3.6e12).astype("int64")
        for d in departures.asi8:
            lat.append(la)
            lon.append(lo)
            eta.append(d + elapsed_ns)
    return np.concatenate(lat), np.concatenate(lon), np.concatenate(eta).astype("datetime64[ns]")


def run_xarray(st: dict) -> dict:
    import numpy as np
    import xarray as xr

    files = sorted(st["weather"].glob("*.nc"))
    waves = xr.open_dataset(next(f for f in files if "wav" in f.name))
    wind = xr.concat([xr.open_dataset(f) for f in files if "era5" in f.name], dim="time")
    wind = wind.sortby("latitude").interp(latitude=waves.latitude, longitude=waves.longitude, time=waves.time)
    merged = xr.merge([waves, wind[["u10", "v10"]]])
    lat, lon, eta = _etas(st["points"], st["departures"])
    p = "point"
    at = merged.sel(latitude=xr.DataArray(lat, dims=p), longitude=xr.DataArray(lon, dims=p),
                    time=xr.DataArray(eta, dims=p), method="nearest").load()
    return {"work": int(lat.size), "mean_hs_m": round(float(np.nanmean(at.VHM0.values)), 4)}


def build(cfg):
    here = "bench.weather"
    folder = str(Path(cfg.cache_dir) / f"weather-demo-month-{source_stamp('weather')}")
    g = Group(
        "join", f"{N_LANES} lanes x {N_DEPARTURES} departures x {N_POINTS} centroids (72 000 points), demo month",
        prepare=f"{here}:prepare", prepare_kwargs={"folder": folder},
        sides=[Side("join_ours", "read_local + load_weather into a new workspace + join_points_weather",
                    setup=f"{here}:setup", kwargs={"folder": folder}, run=f"{here}:run_ours",
                    work="points (path points given weather)"),
               Side("join_xarray", "xarray: open the files, interp the wind onto the wave grid and times, "
                    "numpy ETAs, one vectorised nearest sel", setup=f"{here}:setup", kwargs={"folder": folder},
                    run=f"{here}:run_xarray", ours=False, work="points (path points given weather)")],
        measures=[Measure("weather_join", "weather join, 72 000 path points", "join_ours", "join_xarray",
                          relation="same files and points; ours also stores the grid's sea cells in a DuckDB workspace "
                                   "and flags points on land or outside the data, the baseline stores nothing",
                          targets=[Target("< 5 s (cold)", "cold.wall_s", "<", 5.0, "s", "issue 4")])])
    return [g], []


if __name__ == "__main__":
    script_main("bench/weather.py", build)
