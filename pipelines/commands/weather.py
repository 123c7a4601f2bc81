"""`stormlane weather ...`: fetch, inspect and load weather; join paths with it; exceedance shares.

Commands
--------
``weather fetch``       download a CMEMS / ERA5 subset into the cache (no download when cached)
``weather info``        read local files (CMEMS / ERA5 / GRIB / zarr) and describe the merged grid
``weather load``        read local files, merge onto one grid and store it in the workspace
``weather join``        weather at every point of a set of paths for a set of departures
``weather exceedance``  share of sea cells breaking a vessel's limits, per time step
"""

from __future__ import annotations

from pathlib import Path

import typer

from pipelines.commands._common import (VESSEL_WITHOUT_AIS, DbOption, DbReadOption, JsonOption, LearnedDbOption, ProfileOption, check_choice,
                                        check_output_dir, check_output_file, emit_json, progress, vessel_option,
                                        xarray_without_dask_arrays)

#: Products `weather fetch` downloads.
PRODUCTS = ("cmems-wave", "cmems-wave-med", "cmems-current", "cmems-current-daily", "era5-wind")

weather_app = typer.Typer(help="Weather: fetch (CMEMS/ERA5), inspect, load into the workspace, join with paths.",
                          no_args_is_help=True, rich_markup_mode=None)

#: Weather files or folders given as the command's arguments.
PathsArgument = typer.Argument(..., metavar="FILE|DIR...", help="Weather files or folders (CMEMS/ERA5 NetCDF, GFS GRIB, zarr).")


def _bbox(text: str) -> tuple[float, float, float, float]:
    from weather.errors import WeatherError

    try:
        parts = [float(x) for x in text.split(",")]
    except ValueError:
        parts = []
    if len(parts) != 4:
        raise WeatherError(f"--bbox must be LON_MIN,LAT_MIN,LON_MAX,LAT_MAX (got {text!r})")
    return tuple(parts)  # type: ignore[return-value]


def _summary(meta: dict) -> dict:
    keep = ("product", "base", "variables", "ignored", "start_utc", "end_utc", "bbox", "shape", "grid_step_deg", "source_files")
    return {k: meta[k] for k in keep if k in meta}


@weather_app.command("fetch")
def fetch(
    product: str = typer.Option("cmems-wave", "--product", metavar="cmems-wave|cmems-wave-med|cmems-current|cmems-current-daily|era5-wind",
                                show_default=True, help="The product to download."),
    bbox: str = typer.Option(..., "--bbox", metavar="LONMIN,LATMIN,LONMAX,LATMAX", help="Area in degrees."),
    start: str = typer.Option(..., "--start", metavar="ISO", help="Start time, ISO 8601 (UTC if no offset)."),
    end: str = typer.Option(..., "--end", metavar="ISO", help="End time, ISO 8601 (UTC if no offset)."),
    dataset_id: str = typer.Option(None, "--dataset-id", metavar="ID", help="Override the CMEMS dataset id."),
    cache: Path = typer.Option(None, "--cache", metavar="DIR", callback=lambda v: check_output_dir(v, "--cache"),
                               help="Download cache folder (default $STORMLANE_CACHE or ~/.cache/stormlane/weather; created, "
                                    "its folder must exist)."),
    load: bool = typer.Option(False, "--load", help="Also load the downloaded files into the workspace (--db)."),
    db: Path = DbOption,
    json_out: bool = JsonOption,
) -> None:
    """Download a weather subset with the official client (copernicusmarine or cdsapi), cached.

    Credentials come from the clients' own configuration (`copernicusmarine login`, ~/.cdsapirc).

    Example:

    \b
      stormlane weather fetch --product cmems-wave --bbox -1.5,35.5,11.5,45 --start 2025-01-13 --end 2025-01-18 \\
        --load --db work/stormlane.duckdb
    """
    from pipelines.times import utc_or_none
    from weather.errors import WeatherError
    from weather.io.cache import DownloadCache

    xarray_without_dask_arrays()

    check_choice(product, PRODUCTS, "--product")

    for option, text in (("--start", start), ("--end", end)):
        if utc_or_none(text) is None:
            raise WeatherError(f"{option} {text!r} is not an ISO 8601 time")
    box = _bbox(bbox)
    store = DownloadCache(cache) if cache else DownloadCache()
    if product.startswith("era5"):
        from weather.io.era5 import get_era5

        paths, info = get_era5(box, start, end, cache=store)
        cached = info["cached"]
    else:
        from weather.io.cmems import get_cmems

        path, info = get_cmems(box, start, end, product=product, dataset_id=dataset_id, cache=store)
        paths, cached = [path], [info["cached"]]
    out = {"product": product, "files": [str(p) for p in paths], "cached": cached}
    if load:
        out["grid"] = _load(paths, db, None)
    if json_out:
        emit_json(out)
        return
    for p, c in zip(paths, cached):
        typer.echo(f"{p}  ({'cached' if c else 'downloaded'})")
    if load:
        typer.echo(f"loaded into {db}: grid {out['grid']['grid_id']} {out['grid']['name']!r}")


@weather_app.command("info")
def info(
    paths: list[Path] = PathsArgument,
    json_out: bool = JsonOption,
) -> None:
    """Read local weather files, merge them onto one grid and describe the result (nothing stored).

    Example:

    \b
      stormlane weather info mydata/weather
    """
    xarray_without_dask_arrays()
    from weather.io import read_local

    _, meta = read_local(paths)
    summary = _summary(meta)
    summary["inputs"] = [{k: m[k] for k in ("path", "product", "start_utc", "end_utc", "shape") if k in m} for m in meta["inputs"]]
    if json_out:
        emit_json(summary)
        return
    typer.echo(f"{summary['product']}")
    typer.echo(f"  time   {summary['start_utc']} -> {summary['end_utc']}  ({summary['shape'][0]} steps)")
    box = ", ".join(f"{v:.4f}".rstrip("0").rstrip(".") for v in summary["bbox"])  # 0.0001 deg ~ 11 m; --json has every digit
    dlat, dlon = summary.get("grid_step_deg") or (None, None)  # [lat, lon] (weather.io.netcdf.summary)
    step = f", step {dlat:.4g} x {dlon:.4g} deg" if dlat and dlon else ""
    typer.echo(f"  grid   {summary['shape'][1]} x {summary['shape'][2]} (lat x lon){step}, bbox [{box}]")
    for var, prod in summary["variables"].items():
        typer.echo(f"  {var:<14} from {prod}")
    for ign in summary.get("ignored", []):
        typer.echo(f"  ignored: {ign}")


def _load(paths, db: Path, name: str | None) -> dict:
    from pipelines.storage import open_workspace
    from pipelines.storage.weather import get_grid, load_weather
    xarray_without_dask_arrays()
    from weather.io import read_local

    with progress("reading weather", total=None) as _:
        ds, meta = read_local(paths)
    with open_workspace(db) as ws:
        gid = load_weather(ws, ds, name=name, metadata=_summary(meta))
        g = get_grid(ws, gid)
    return {"grid_id": int(g["grid_id"]), "name": g["name"], "product": g["product"], "n_cells": int(g["n_cells"]),
            "start_utc": str(g["start_utc"]), "end_utc": str(g["end_utc"]), "variables": g["variables"].split(",")}


@weather_app.command("load")
def load(
    paths: list[Path] = PathsArgument,
    db: Path = DbOption,
    name: str = typer.Option(None, "--name", metavar="NAME", help="Grid name in the workspace (default: the product label); replaces a grid of that name."),
    json_out: bool = JsonOption,
) -> None:
    """Read weather files, merge them onto one grid and store it in the workspace (tables weather_grids, weather_cells).

    Example:

    \b
      stormlane weather load mydata/weather --db work/stormlane.duckdb
    """
    grid = _load(paths, db, name)
    if json_out:
        emit_json(grid)
        return
    typer.echo(f"grid {grid['grid_id']} {grid['name']!r}: {grid['n_cells']:,} sea cells, "
               f"{grid['start_utc']} -> {grid['end_utc']}, variables {', '.join(grid['variables'])}")


def _departures(depart: list[str], every_h: float | None, count: int):
    import pandas as pd

    from pipelines.times import utc_or_none
    from weather.errors import WeatherError

    if not depart:
        raise WeatherError("give at least one --depart time")
    times = []
    for text in depart:
        t = utc_or_none(text)
        if t is None:
            raise WeatherError(f"--depart {text!r} is not an ISO 8601 time")
        times.append(t)
    if every_h is not None:
        if len(times) != 1:
            raise WeatherError("--step-h needs exactly one --depart (the first departure)")
        if not every_h > 0:
            raise WeatherError(f"--step-h {every_h:g}: hours between departures must be > 0")
        if count < 1:
            raise WeatherError(f"--count {count}: need at least one departure")
        times = list(pd.date_range(times[0], periods=count, freq=pd.Timedelta(hours=every_h)))
    return times


#: Columns of a ``weather join --points`` CSV that must hold numbers.
POINT_NUMBERS = ("seq", "lat_deg", "lon_deg", "speed_kn")


def _read_points(path: Path):
    """The ``--points`` CSV; a value that is not a number (or a speed that is not > 0) is
    reported by file, line and field."""
    import numpy as np
    import pandas as pd

    from weather.errors import WeatherError

    try:
        pts = pd.read_csv(path, skip_blank_lines=False)
    except (OSError, ValueError) as err:
        raise WeatherError(f"{path}: cannot read points CSV ({err})") from None
    pts.index = pts.index + 2  # file line of each row (header = line 1)
    pts = pts.dropna(how="all")
    for col in POINT_NUMBERS:
        if col not in pts:
            continue  # join_points_weather names every missing column
        num = pd.to_numeric(pts[col], errors="coerce").astype(float)
        bad = ~np.isfinite(num) | ((num <= 0) if col == "speed_kn" else False)
        if bad.any():
            line = int(pts.index[np.flatnonzero(bad.to_numpy())[0]])
            what = "a speed > 0 kn" if col == "speed_kn" else "a number"
            raw = pts[col].loc[line]
            raise WeatherError(f"{path}: line {line}: field {col!r} " + ("is empty" if pd.isna(raw) else f"{str(raw)!r} is not {what}"))
        pts[col] = num
    return pts.reset_index(drop=True)


@weather_app.command("join")
def join(
    points: Path = typer.Option(None, "--points", metavar="CSV", help="CSV with path_id,seq,lat_deg,lon_deg,speed_kn (default: the workspace's lane centroids)."),
    depart: list[str] = typer.Option([], "--depart", metavar="ISO", help="Departure times, ISO 8601; several after one --depart, or --depart repeated."),
    every_h: float = typer.Option(None, "--step-h", metavar="H", help="Hours between departures, starting at the single --depart (with --count)."),
    count: int = typer.Option(1, "--count", metavar="N", show_default=True, help="Number of departures with --step-h."),
    grid: str = typer.Option(None, "--grid", metavar="ID|NAME", help="Grid id or name (default: the latest loaded)."),
    out: Path = typer.Option(None, "--out", metavar="FILE.csv|parquet", callback=lambda v: check_output_file(v, "--out"),
                             help="Write every joined point to this CSV or Parquet file."),
    flag_missing: bool = typer.Option(False, "--flag-missing", help="Mark points outside the data instead of failing."),
    db: Path = DbReadOption,
    json_out: bool = JsonOption,
) -> None:
    """Weather at every point of every path for each departure (ETA -> grid cell -> nearest time).

    Example (the lanes of the workspace, 8 departures 3 h apart):

    \b
      stormlane weather join --db work/stormlane.duckdb --depart 2025-01-14T00:00Z --step-h 3 --count 8
    """
    import pandas as pd

    from pipelines.storage import open_workspace
    from pipelines.storage.weather import join_points_weather
    from pipelines.weather import lane_points
    from weather.errors import WeatherError

    deps = _departures(depart, every_h, count)
    pts = None if points is None else _read_points(points)
    with open_workspace(db) as ws:
        if pts is None:
            pts = lane_points(ws)
        g = None if grid is None else (int(grid) if grid.isdigit() else grid)
        res = join_points_weather(ws, pts, deps, grid=g, on_missing="flag" if flag_missing else "raise")
    if out is not None:
        if out.suffix == ".parquet":
            res.to_parquet(out, index=False)
        else:
            res.to_csv(out, index=False)
    per_path = res.groupby("path_id").agg(n=("seq", "size"), max_hs_m=("hs_m", "max"))
    summary = {"n_points": int(len(res)), "n_paths": int(res.path_id.nunique()), "n_departures": len(deps),
               "status": {k: int(v) for k, v in res.status.value_counts().items()},
               "max_hs_m": per_path["max_hs_m"].astype(float).round(3).to_dict(), "out": None if out is None else str(out)}
    if json_out:
        emit_json(summary)
        return
    typer.echo(f"{summary['n_points']:,} points ({summary['n_paths']} paths x {len(deps)} departures); status {summary['status']}")
    for pid, row in per_path.iterrows():
        typer.echo(f"  {pid:<20} max Hs {row.max_hs_m:.2f} m")


@weather_app.command("exceedance")
def exceedance(
    paths: list[Path] = PathsArgument,
    vessel: str = vessel_option(VESSEL_WITHOUT_AIS),
    profile: str = ProfileOption,
    headings: int = typer.Option(0, "--headings", metavar="N", show_default=True, help="Evaluate N equally spaced headings (0 = heading-free rules only)."),
    learned: str = typer.Option(None, "--learned", metavar="NAME", help="Also print, beside the vessel's operator limits, the sea state "
                                "above which AIS shows its class slowing down voluntarily, as the stored model NAME learned it "
                                "(`stormlane learn performance`; read from --db): evidence, not a limit."),
    db: Path = LearnedDbOption,
    json_out: bool = JsonOption,
) -> None:
    """Per time step: share of sea cells breaking the vessel's operator limits and IMO rules.

    With --learned NAME, the learned voluntary slow-down of the vessel's class (Hs and heading
    sector, from the fleet's AIS) is printed beside the operator's Hs limit (--json:
    learned_limits with model and rows: ship_class, operator_hs_max_m, learned_hs_m,
    learned_interval_hs_m, learned_sectors).

    Example (Storm Gloria for a large container ship):

    \b
      stormlane weather exceedance Waves_MEDSEA_20200120.nc Waves_MEDSEA_20200121.nc --vessel container-large
    """
    import numpy as np

    from pipelines.config import load_operator_profile, load_vessel
    from weather.exposure import exceedance_by_time
    xarray_without_dask_arrays()
    from weather.io import read_local

    ds, meta = read_local(paths)
    from pipelines.vessels import DEFAULT_VESSEL

    v = load_vessel(vessel or DEFAULT_VESSEL)
    prof = load_operator_profile(profile)
    hdg = None if headings <= 0 else np.arange(headings) * 360.0 / headings
    table, skipped = exceedance_by_time(ds, v, prof, headings_deg=hdg)
    limits = prof.limits_for(v.vessel_class, v.lpp_m)
    beside = None
    if learned is not None:
        from pipelines.commands._common import check_workspace
        from pipelines.learn import learned_limits
        from pipelines.storage.performance import check_name

        beside = learned_limits(check_workspace(db), check_name(learned), profile=profile, vessels=[v])
    if json_out:
        rows = [{"time_utc": t.strftime("%Y-%m-%dT%H:%MZ"), **{k: (float(x) if k == "unsafe_frac" else int(x)) for k, x in r.items()}}
                for t, r in table.iterrows()]
        emit_json({"product": meta["product"], "vessel": v.name, "profile": prof.name, "limits": limits.name,
                   "skipped": list(skipped), "mean_unsafe_frac": float(table.unsafe_frac.mean()), "steps": rows,
                   **({"learned_limits": beside} if beside is not None else {})})
        return
    typer.echo(f"{meta['product']} | vessel {v.name} | profile {prof.name}: {limits.name}")
    if beside is not None:
        from pipelines.learn import limit_line

        for r in beside["rows"]:
            typer.echo(f"  beside the limits, {beside['model']} (AIS evidence, not a limit): {limit_line(r)}")
    for s in skipped:
        typer.echo(f"  not evaluated: {s}")
    rule_cols = [c for c in table.columns if c.startswith("n_") and c not in ("n_sea", "n_unsafe")]
    typer.echo("time_utc            sea    unsafe  share  " + "  ".join(c[2:] for c in rule_cols))
    for t, r in table.iterrows():
        typer.echo(f"{t:%Y-%m-%dT%H:%MZ}  {int(r.n_sea):6d} {int(r.n_unsafe):6d}  {r.unsafe_frac:6.1%}  "
                   + "  ".join(f"{int(r[c]):{len(c) - 2}d}" for c in rule_cols))


def register(app: typer.Typer) -> None:
    app.add_typer(weather_app, name="weather")
