"""Weather into the workspace: fetch-or-read -> normalise/merge -> load, as plain functions and a flow.

* :func:`load_weather_paths` is the plain entry point (CLI, demo, tests): read local files with
  :func:`weather.io.read_local` (which normalises and merges onto one grid) and store the grid
  with :func:`pipelines.storage.weather.load_weather`.
* :func:`weather_flow` is the same work as a Prefect flow: optional download tasks (retried, the
  only network step), a read task, a load task. Datasets are passed in memory, so the tasks use
  ``NO_CACHE`` (hashing a month of weather would cost more than reading it).
* :func:`lane_points` turns the lanes component's centroids into the generic path points the
  join takes; :func:`write_scenario_weather_files` is the scenario writer hook that produces
  ``DIR/weather/``; :func:`step_weather` is the demo step.
"""

from __future__ import annotations

import functools
import logging
from pathlib import Path

import pandas as pd
from pydantic import BaseModel, Field

from pipelines.storage import DEFAULT_DB

log = logging.getLogger(__name__)

#: Hours of weather the scenario writes after the end of its AIS period: the nightly run's
#: forecast window (COMMON.md: AIS to 2025-01-31T00Z, weather to 2025-02-02T06Z).
FORECAST_TAIL_H = 54


class FetchRequest(BaseModel):
    """One download: a product of :data:`weather.io.cmems.DATASETS` or ``era5-wind``."""

    product: str = "cmems-wave"
    bbox: tuple[float, float, float, float] = Field(..., description="lon_min, lat_min, lon_max, lat_max")
    start_utc: str
    end_utc: str
    dataset_id: str | None = None


def fetch_files(req: FetchRequest, cache_dir: str | None = None) -> list[Path]:
    """Download (or reuse from the cache) the files of one request."""
    from weather.io.cache import DownloadCache

    cache = DownloadCache(cache_dir) if cache_dir else DownloadCache()
    if req.product.startswith("era5"):
        from weather.io.era5 import get_era5

        paths, _ = get_era5(req.bbox, req.start_utc, req.end_utc, cache=cache)
        return list(paths)
    from weather.io.cmems import get_cmems

    path, _ = get_cmems(req.bbox, req.start_utc, req.end_utc, product=req.product, dataset_id=req.dataset_id, cache=cache)
    return [path]


def read_weather(paths) -> tuple:
    """Reader step: local files -> canonical dataset on one grid, plus metadata."""
    from weather.io import read_local

    return read_local(paths)


def store_weather(db: str | Path, ds, meta: dict, name: str | None = None) -> dict:
    """Writer step: store the grid in the workspace; returns the grid's row (JSON-able)."""
    from pipelines.storage import open_workspace
    from pipelines.storage.weather import get_grid, load_weather

    keep = {k: meta[k] for k in ("product", "base", "variables", "ignored", "start_utc", "end_utc", "bbox", "source_files") if k in meta}
    with open_workspace(db) as ws:
        gid = load_weather(ws, ds, name=name, metadata=keep)
        g = get_grid(ws, gid)
    return {"grid_id": int(g["grid_id"]), "name": str(g["name"]), "product": str(g["product"]), "n_cells": int(g["n_cells"]),
            "n_times": int(g["n_times"]), "start_utc": pd.Timestamp(g["start_utc"]).isoformat(),
            "end_utc": pd.Timestamp(g["end_utc"]).isoformat(), "variables": str(g["variables"]).split(",")}


def load_weather_paths(paths, db: str | Path = DEFAULT_DB, name: str | None = None) -> dict:
    """Plain entry point: read, merge and load weather files into the workspace ``db``."""
    ds, meta = read_weather(paths)
    return store_weather(db, ds, meta, name=name)


def lane_points(ws) -> pd.DataFrame:
    """The lanes' centroid sequences as join points (``path_id`` = ``lane_id``).

    Raises a :class:`weather.errors.WeatherError` when the workspace has no lanes yet.
    """
    from weather.errors import WeatherError

    try:
        from pipelines.storage.lanes import read_lane_centroids
    except ImportError:
        read_lane_centroids = None
    if read_lane_centroids is None:
        raise WeatherError("this installation has no lanes component yet; pass --points CSV")
    try:
        df = read_lane_centroids(ws)
    except Exception as err:  # table missing in an old workspace
        raise WeatherError(f"no lane centroids in the workspace ({err}); run `stormlane lanes` first or pass --points") from None
    if df.empty:
        raise WeatherError("the workspace has no lanes yet; run `stormlane lanes` first or pass --points CSV")
    return df.rename(columns={"lane_id": "path_id"})[["path_id", "seq", "lat_deg", "lon_deg", "speed_kn"]]


def scenario_weather(seed: int, start_utc, end_utc):
    """The scenario's weather from its AIS start to :data:`FORECAST_TAIL_H` hours after its end
    (:func:`weather.scenario.generate_weather`; the fleet sails through it, the files hold it)."""
    from weather.scenario import generate_weather

    start = pd.Timestamp(start_utc)
    end = pd.Timestamp(end_utc) + pd.Timedelta(hours=FORECAST_TAIL_H)
    return generate_weather(int(seed), start=start, end=end)


def write_scenario_weather_files(ctx) -> dict:
    """Scenario writer hook (``pipelines.scenario.SCENARIO_WRITERS``): storm weather under ``DIR/weather/``.

    The weather covers the AIS period plus :data:`FORECAST_TAIL_H` hours (the nightly run's
    forecast window), with the same seed as the AIS.
    """
    from weather.io.scenario_files import write_scenario_weather

    sc = ctx.truth["scenario"]
    seed = int(sc["seed"])
    sw = ctx.weather if ctx.weather is not None else scenario_weather(seed, sc["start_utc"], sc["end_utc"])
    info = write_scenario_weather(ctx.out_dir, seed=seed, weather=sw)
    out_dir = Path(ctx.out_dir)
    info["files"] = [Path(f).relative_to(out_dir).as_posix() for f in info["files"]]
    info["folder"] = "weather"
    storms = ", ".join(f"{s['name']} peak {s['peak_utc']}" for s in info["storms"])
    info["summary"] = (f"{len(info['files'])} files (CMEMS GLOBAL waves 1/12 deg 3-hourly, ERA5 wind 0.25 deg hourly), "
                       f"{info['start_utc']} -> {info['end_utc']}, max Hs {info['waves']['max_hs_m']:.1f} m; storms {storms}")
    return {"weather": info}


def step_weather(ctx) -> dict:
    """Demo step: load ``DIR/weather`` into the demo workspace and report the grid."""
    grid = load_weather_paths(Path(ctx.workdir) / "weather", ctx.db)
    ctx.echo(f"   weather grid {grid['grid_id']} {grid['name']!r}: {grid['n_cells']:,} sea cells x time, "
             f"{grid['start_utc']} -> {grid['end_utc']}, variables {', '.join(grid['variables'])}")
    return grid


@functools.lru_cache(maxsize=1)
def _flow():
    """Build the Prefect flow lazily (importing Prefect costs seconds; the CLI must stay fast)."""
    from prefect import flow, task
    from prefect.cache_policies import NO_CACHE

    fetch_task = task(fetch_files, name="weather-fetch", retries=3, retry_delay_seconds=[2, 5, 15], cache_policy=NO_CACHE)
    read_task = task(read_weather, name="weather-read", cache_policy=NO_CACHE)
    store_task = task(store_weather, name="weather-load", cache_policy=NO_CACHE)

    @flow(name="weather", log_prints=False)
    def weather_flow(paths: list[str] | None = None, fetch: list[FetchRequest] | None = None, db: str = DEFAULT_DB,
                     name: str | None = None, cache_dir: str | None = None) -> dict:
        """Fetch (optional) or read weather files, merge them onto one grid, load it into ``db``."""
        files = [Path(p) for p in (paths or [])]
        for req in fetch or []:
            files += fetch_task(req, cache_dir)
        ds, meta = read_task(files)
        return store_task(db, ds, meta, name)

    return weather_flow


def __getattr__(name):
    if name == "weather_flow":
        return _flow()
    raise AttributeError(name)


if __name__ == "__main__":
    import sys

    print(_flow()(paths=sys.argv[1:]))
