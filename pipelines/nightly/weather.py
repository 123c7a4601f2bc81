"""Nightly stage 2, weather: where it comes from (files, downloads, the workspace), what a night
needs of it (box and span), and the cut to that."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from pipelines.nightly.night import WEATHER_PAD_DEG, NightlyError, NightlyParams, NightlyWeatherError, NightPath
from pipelines.nightly.paths import _require_weather_files, nothing_to_sail

def weather_credentials_configured() -> bool:
    """True when both download clients have credentials configured through their own mechanisms
    (environment variables or their configuration files; only their presence is checked)."""
    import os

    home = Path.home()
    cmems = bool(os.environ.get("COPERNICUSMARINE_SERVICE_USERNAME")) or (home / ".copernicusmarine" / ".copernicusmarine-credentials").is_file()
    cds = bool(os.environ.get("CDSAPI_KEY")) or (home / ".cdsapirc").is_file()
    return cmems and cds


def choose_weather_source(params: NightlyParams) -> str:
    """``files`` when --weather is given, ``fetch`` when asked or when the clients have credentials,
    else ``workspace`` (the grid loaded by ``stormlane weather load`` / the demo)."""
    if params.weather_source != "auto":
        if params.weather_source == "files" and not params.weather:
            raise NightlyError("weather source 'files' needs --weather FILE_OR_DIR")
        return params.weather_source
    if params.weather:
        return "files"
    if weather_credentials_configured():
        return "fetch"
    return "workspace"


def paths_bbox(paths: list[NightPath]) -> tuple[float, float, float, float]:
    """``(lon_min, lat_min, lon_max, lat_max)`` of every centroid."""
    frames = [p.centroids for p in paths if len(p.centroids)]
    if not frames:
        raise NightlyError("no lane has centroids to check")
    c = pd.concat(frames)
    return float(c["lon_deg"].min()), float(c["lat_deg"].min()), float(c["lon_deg"].max()), float(c["lat_deg"].max())


def weather_span_needed(paths: list[NightPath], departures: pd.DatetimeIndex) -> tuple[pd.Timestamp, pd.Timestamp]:
    """First departure and the latest arrival (departure + sailing time) of the night."""
    starts, ends = [], []
    for p in paths:
        deps = list(p.departures) or list(departures)
        if not deps or p.error:
            continue
        starts.append(min(deps))
        ends.append(max(deps) + pd.Timedelta(hours=p.hours))
    if not starts:
        raise NightlyError(nothing_to_sail(paths))
    return min(starts), max(ends)


def fetch_requests(paths: list[NightPath], departures: pd.DatetimeIndex, pad_deg: float = WEATHER_PAD_DEG) -> list:
    """The downloads of a night: CMEMS waves and ERA5 wind over the lanes' box and time span."""
    from pipelines.weather import FetchRequest

    lon0, lat0, lon1, lat1 = paths_bbox(paths)
    t0, t1 = weather_span_needed(paths, departures)
    bbox = (lon0 - pad_deg, lat0 - pad_deg, lon1 + pad_deg, lat1 + pad_deg)
    start = (t0 - pd.Timedelta(hours=3)).floor("h").isoformat()
    end = (t1 + pd.Timedelta(hours=3)).ceil("h").isoformat()
    return [FetchRequest(product="cmems-wave", bbox=bbox, start_utc=start, end_utc=end),
            FetchRequest(product="era5-wind", bbox=bbox, start_utc=start, end_utc=end)]


def fetch_weather(request, cache_dir: str | None = None) -> list[str]:
    """Network step: download one request with the real client (or reuse the cache)."""
    from pipelines.weather import fetch_files

    return [str(p) for p in fetch_files(request, cache_dir)]


#: A weather read made before the flow started (:func:`pipelines.nightly.plan.read_weather_before`,
#: the CLI's preflight), taken by the flow's read of the same inputs in the same process: the
#: files are read once, and a night they do not cover fails before Prefect starts.
_READ_BEFORE: dict = {}


def _inputs_key(source: str, files, db, start: pd.Timestamp, end: pd.Timestamp) -> tuple:
    """What a weather read depends on: the source, each file's (or folder's files') size and
    modification time, the workspace's, the span."""

    def ident(p):
        p = Path(p)
        found = sorted(q for q in p.rglob("*") if q.is_file()) if p.is_dir() else [p]
        return tuple((str(q), q.stat().st_size, q.stat().st_mtime_ns) for q in found if q.exists())

    return (source, tuple(str(f) for f in files), tuple(ident(f) for f in files), str(db), ident(db),
            pd.Timestamp(start).value, pd.Timestamp(end).value)


def keep_read_for_flow(source: str, files, db, start, end, read: tuple) -> None:
    """Hand ``read`` (a :func:`read_weather_source` result) to the flow's read of the same inputs."""
    _READ_BEFORE.clear()
    _READ_BEFORE[_inputs_key(source, files, db, start, end)] = read


def read_weather_source(source: str, files, db, start: pd.Timestamp, end: pd.Timestamp) -> tuple:
    """I/O step: the canonical weather Dataset and its metadata, from files or the workspace grid
    (the read made before the flow, when its inputs are unchanged: :func:`keep_read_for_flow`)."""
    if _READ_BEFORE:
        got = _READ_BEFORE.pop(_inputs_key(source, files, db, start, end), None)
        _READ_BEFORE.clear()
        if got is not None:
            return got
    if source in ("files", "fetch"):
        from weather.io import read_local

        _require_weather_files(files)
        if not files:
            raise NightlyWeatherError("no weather files to read")
        ds, meta = read_local([str(f) for f in files])
        meta = dict(meta)
        meta["source"] = "downloaded (copernicusmarine + cdsapi, cached)" if source == "fetch" else "local files"
        meta.setdefault("files", [str(f) for f in files])
        return ds, meta
    from pipelines.audit_inputs import AuditError, weather_from_workspace
    from pipelines.storage import open_workspace

    with open_workspace(db) as ws:
        try:
            ds, meta = weather_from_workspace(ws, start, end, pad_h=6.0)
        except AuditError as err:
            raise NightlyWeatherError(f"{err} (or run with --weather DIR, or --fetch with download credentials)") from None
    return ds, dict(meta)


def subset_weather(ds, paths: list[NightPath], start: pd.Timestamp, end: pd.Timestamp, pad_deg: float = WEATHER_PAD_DEG):
    """The weather the night can touch, over the lanes' box widened by ``pad_deg`` (or 20 % of the
    widest lane's span, when more).

    Times run from the last one at or before ``start`` (the first departure) to the first at or
    after ``end`` plus a detour allowance (the longest lane's sailing time, at least 24 h): an A*
    route or a deviation may arrive later than the lane would, and it must meet the same weather
    whatever other lanes the night checks (a night on a subset of lanes gives the same routes).
    """
    times = pd.DatetimeIndex(ds["time_utc"].values).tz_localize("UTC")
    longest = max((p.hours for p in paths), default=0.0)
    end = end + pd.Timedelta(hours=max(24.0, longest))
    i0 = max(int(np.searchsorted(times.asi8, start.value, side="right")) - 1, 0)
    i1 = min(int(np.searchsorted(times.asi8, end.value, side="left")) + 1, times.size)
    spans = [max(np.ptp(p.centroids["lat_deg"]), np.ptp(p.centroids["lon_deg"])) for p in paths if len(p.centroids) > 1]
    pad = max(pad_deg, 0.2 * max(spans, default=0.0))
    lon0, lat0, lon1, lat1 = paths_bbox(paths)
    sub = ds.isel(time_utc=slice(i0, i1)).sel(lat=slice(lat0 - pad, lat1 + pad), lon=slice(lon0 - pad, lon1 + pad))
    if sub.sizes["lat"] < 2 or sub.sizes["lon"] < 2:
        raise NightlyWeatherError(
            f"{ds.attrs.get('product', 'weather')}: the grid (lat {float(ds.lat.min()):g}..{float(ds.lat.max()):g}, lon "
            f"{float(ds.lon.min()):g}..{float(ds.lon.max()):g}) does not cover the lanes (lat {lat0:g}..{lat1:g}, lon {lon0:g}..{lon1:g})"
        )
    return sub
