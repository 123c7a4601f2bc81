"""Weather tables and the paths × weather join (the DuckDB side of issue 4).

Tables
------
``weather_grids``
    One row per loaded canonical grid: regular lat/lon axes (first point ``lat0_deg``/``lon0_deg``,
    step, size), time span, product and source files, variables.
``weather_cells``
    One row per (grid, time, sea cell): ``time_utc``, ``lat_idx``, ``lon_idx`` and the canonical
    variables (REAL, NULL = missing). Cells that are NaN in every variable at a time (land) are not
    stored.

The join (:func:`join_points_weather`) works on a **generic table of points** — any path (lane
centroids, a route, a generated test set) given as ``path_id``, ``seq``, ``lat_deg``,
``lon_deg``, ``speed_kn`` — so it does not depend on how lanes are stored:

1. ETAs (:func:`path_etas_sql`): leg i→i+1 takes haversine(c_i, c_{i+1}) / speed_kn(c_i) hours
   (seed ``ais_weather_routing_cargo_loss`` Algorithm 1, line 4); cumulative sums per path,
   added to each departure time.
2. Grid cell by index arithmetic: ``lat_idx = round((lat − lat0)/dlat)``, the nearest grid point
   (grid points are cell centres).
3. Nearest time by ``ASOF JOIN`` on the cell: on a regular time axis one join on ETA + half a
   step; otherwise two (the last time ≤ ETA and the first time ≥ ETA), keeping the closer one
   (ties go to the earlier time either way). ETAs more than half a time step outside
   the grid's span get no weather (status ``outside_time``): never silent extrapolation.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from thresholds.units import EARTH_RADIUS_NMI

COMPONENT = "weather"

CANONICAL_COLUMNS = ("hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms", "current_u_ms", "current_v_ms")

MIGRATIONS = [
    [
        "CREATE SEQUENCE weather_grid_seq START 1",
        """CREATE TABLE weather_grids (
            grid_id      INTEGER PRIMARY KEY DEFAULT nextval('weather_grid_seq'),
            name         VARCHAR NOT NULL UNIQUE,
            product      VARCHAR NOT NULL,
            source_files VARCHAR NOT NULL,
            lat0_deg     DOUBLE NOT NULL,
            dlat_deg     DOUBLE NOT NULL,
            nlat         INTEGER NOT NULL,
            lon0_deg     DOUBLE NOT NULL,
            dlon_deg     DOUBLE NOT NULL,
            nlon         INTEGER NOT NULL,
            start_utc    TIMESTAMPTZ NOT NULL,
            end_utc      TIMESTAMPTZ NOT NULL,
            n_times      INTEGER NOT NULL,
            step_s       DOUBLE,
            variables    VARCHAR NOT NULL,
            n_cells      BIGINT NOT NULL,
            loaded_at    TIMESTAMPTZ NOT NULL DEFAULT now(),
            metadata     VARCHAR
        )""",
        """CREATE TABLE weather_cells (
            grid_id       INTEGER NOT NULL,
            time_utc      TIMESTAMPTZ NOT NULL,
            lat_idx       INTEGER NOT NULL,
            lon_idx       INTEGER NOT NULL,
            hs_m          REAL,
            wave_from_deg REAL,
            tp_s          REAL,
            tm_s          REAL,
            wind_u_ms     REAL,
            wind_v_ms     REAL,
            current_u_ms  REAL,
            current_v_ms  REAL
        )""",
    ],
]


def _errors():
    from weather.errors import CoverageError, WeatherError

    return WeatherError, CoverageError


def _regular_axis(values, name: str, what: str) -> tuple[float, float, int]:
    v = np.asarray(values, dtype=float)
    if v.size == 1:
        return float(v[0]), 1.0, 1
    d = np.diff(v)
    step = float(np.mean(d))
    if not np.allclose(d, step, rtol=0, atol=abs(step) * 1e-3):
        WeatherError, _ = _errors()
        raise WeatherError(f"{what}: {name} axis is irregular (steps {d.min():.6g}..{d.max():.6g}); "
                           "regrid onto a regular grid before loading it into the workspace")
    return float(v[0]), step, int(v.size)


def load_weather(ws, ds, name: str | None = None, metadata: dict | None = None) -> int:
    """Store a canonical dataset as a grid plus its sea cells; replaces a grid of the same name.

    Parameters
    ----------
    ws : Workspace
    ds : xarray.Dataset
        Canonical weather on a regular grid.
    name : str, optional
        Grid name (default: the product label).
    metadata : dict, optional
        Stored as JSON (e.g. the reader's metadata).

    Returns
    -------
    int
        The new ``grid_id``.
    """
    import pyarrow as pa

    product = str(ds.attrs.get("product", "weather"))
    name = name or product
    lat0, dlat, nlat = _regular_axis(ds.lat.values, "latitude", name)
    lon0, dlon, nlon = _regular_axis(ds.lon.values, "longitude", name)
    present = [c for c in CANONICAL_COLUMNS if c in ds.data_vars]
    if not present:
        WeatherError, _ = _errors()
        raise WeatherError(f"{name}: no canonical variables to load")
    times = ds.time_utc.values.astype("datetime64[ns]")
    nt = times.size
    arrays = [np.asarray(ds[c].values, dtype=np.float32) for c in present]  # each (t, lat, lon)
    valid = ~np.isnan(arrays[0])
    for a in arrays[1:]:
        valid |= ~np.isnan(a)
    ti, yi, xi = np.nonzero(valid)
    columns = {
        "time_utc": pa.array(times.astype("datetime64[us]")[ti], type=pa.timestamp("us", tz="UTC")),
        "lat_idx": pa.array(yi.astype(np.int32)),
        "lon_idx": pa.array(xi.astype(np.int32)),
    }
    for c, a in zip(present, arrays):
        vals = a[valid]  # boolean selection, same C order as nonzero()
        columns[c] = pa.array(vals, mask=np.isnan(vals), type=pa.float32())
    table = pa.table(columns)
    # step_s is stored only for a regular time axis (the join then needs one ASOF join, not two)
    steps_ns = np.diff(times).astype("timedelta64[ns]").astype(np.int64)
    step_s = float(steps_ns[0] / 1e9) if nt > 1 and np.all(steps_ns == steps_ns[0]) else None
    select_cols = ", ".join(f"cells.{c}" if c in present else f"NULL AS {c}" for c in CANONICAL_COLUMNS)
    with ws.transaction() as con:
        old = con.execute("SELECT grid_id FROM weather_grids WHERE name = ?", [name]).fetchall()
        for (gid,) in old:
            con.execute("DELETE FROM weather_cells WHERE grid_id = ?", [gid])
            con.execute("DELETE FROM weather_grids WHERE grid_id = ?", [gid])
        grid_id = con.execute(
            """INSERT INTO weather_grids (name, product, source_files, lat0_deg, dlat_deg, nlat, lon0_deg, dlon_deg, nlon,
                                          start_utc, end_utc, n_times, step_s, variables, n_cells, metadata)
               VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) RETURNING grid_id""",
            [name, product, str(ds.attrs.get("source_files", "")), lat0, dlat, nlat, lon0, dlon, nlon,
             pd.Timestamp(times[0]).tz_localize("UTC"), pd.Timestamp(times[-1]).tz_localize("UTC"), nt, step_s,
             ",".join(present), int(table.num_rows), json.dumps(metadata or {}, default=str)],
        ).fetchone()[0]
        con.register("_weather_cells_in", table)
        # Row order inside weather_cells carries no meaning (every read orders or joins), and
        # letting DuckDB drop it halves the insert time of a month of cells.
        con.execute("SET preserve_insertion_order = false")
        try:
            con.execute(
                f"INSERT INTO weather_cells SELECT ? AS grid_id, cells.time_utc, cells.lat_idx, cells.lon_idx, {select_cols} "
                "FROM _weather_cells_in AS cells",
                [grid_id],
            )
        finally:
            con.execute("RESET preserve_insertion_order")
            con.unregister("_weather_cells_in")
    return int(grid_id)


def list_grids(ws) -> pd.DataFrame:
    """The loaded grids, newest first."""
    return ws.con.execute(
        "SELECT grid_id, name, product, start_utc, end_utc, n_times, nlat, nlon, dlat_deg, dlon_deg, variables, n_cells, loaded_at "
        "FROM weather_grids ORDER BY grid_id DESC"
    ).df()


def get_grid(ws, grid: int | str | None = None) -> dict:
    """One grid's row as a dict (by id or name; default the most recently loaded)."""
    WeatherError, _ = _errors()
    if grid is None:
        row = ws.con.execute("SELECT * FROM weather_grids ORDER BY grid_id DESC LIMIT 1").df()
    elif isinstance(grid, (int, np.integer)):
        row = ws.con.execute("SELECT * FROM weather_grids WHERE grid_id = ?", [int(grid)]).df()
    else:
        row = ws.con.execute("SELECT * FROM weather_grids WHERE name = ?", [str(grid)]).df()
    if row.empty:
        names = [r[0] for r in ws.con.execute("SELECT name FROM weather_grids ORDER BY grid_id").fetchall()]
        raise WeatherError(f"no weather grid {grid!r} in the workspace (loaded: {', '.join(names) or 'none'}; "
                           "run `stormlane weather load PATH...`)")
    return row.iloc[0].to_dict()


def read_cells(ws, grid: int | str | None = None, start=None, end=None) -> pd.DataFrame:
    """Stored cells of a grid (optionally a time window), with cell-centre lat/lon."""
    g = get_grid(ws, grid)
    sql = ("SELECT c.*, ? + c.lat_idx * ? AS lat_deg, ? + c.lon_idx * ? AS lon_deg FROM weather_cells c WHERE c.grid_id = ?")
    params = [g["lat0_deg"], g["dlat_deg"], g["lon0_deg"], g["dlon_deg"], int(g["grid_id"])]
    if start is not None:
        sql += " AND c.time_utc >= ?"
        params.append(pd.Timestamp(start))
    if end is not None:
        sql += " AND c.time_utc <= ?"
        params.append(pd.Timestamp(end))
    return ws.con.execute(sql + " ORDER BY c.time_utc, c.lat_idx, c.lon_idx", params).df()


def _validate_points(points: pd.DataFrame) -> pd.DataFrame:
    WeatherError, _ = _errors()
    need = {"path_id", "seq", "lat_deg", "lon_deg", "speed_kn"}
    missing = need - set(points.columns)
    if missing:
        raise WeatherError(f"path points need columns {sorted(need)}; missing {sorted(missing)}")
    p = points[list(need)].copy()
    p["path_id"] = p["path_id"].astype(str)
    p["seq"] = p["seq"].astype(np.int64)
    for c in ("lat_deg", "lon_deg", "speed_kn"):
        p[c] = p[c].astype(float)
    bad = p[~np.isfinite(p["lat_deg"]) | ~np.isfinite(p["lon_deg"])]
    if not bad.empty:
        r = bad.iloc[0]
        raise WeatherError(f"path {r.path_id!r} point {r.seq}: position is not a number")
    p = p.sort_values(["path_id", "seq"])
    last = p.groupby("path_id")["seq"].transform("max")
    bad = p[(p["seq"] < last) & ~(p["speed_kn"] > 0)]
    if not bad.empty:
        r = bad.iloc[0]
        raise WeatherError(f"path {r.path_id!r} point {r.seq}: speed_kn must be > 0 to sail the next leg (got {r.speed_kn})")
    if p.duplicated(["path_id", "seq"]).any():
        r = p[p.duplicated(["path_id", "seq"])].iloc[0]
        raise WeatherError(f"path {r.path_id!r}: duplicate seq {r.seq}")
    return p


def _departures_frame(departures, points: pd.DataFrame) -> pd.DataFrame:
    """Departures as (path_id, departure_utc): a list applies to every path."""
    if isinstance(departures, pd.DataFrame):
        d = departures.copy()
        if "departure_utc" not in d:
            raise ValueError("departures frame needs a departure_utc column")
        if "path_id" not in d:
            d = d.merge(pd.DataFrame({"path_id": points["path_id"].unique()}), how="cross")
    else:
        times = pd.DatetimeIndex(pd.to_datetime(list(np.atleast_1d(departures)), utc=True))
        d = pd.DataFrame({"departure_utc": times}).merge(pd.DataFrame({"path_id": points["path_id"].unique()}), how="cross")
    d["path_id"] = d["path_id"].astype(str)
    t = pd.to_datetime(d["departure_utc"], utc=True)
    d["departure_utc"] = t
    return d[["path_id", "departure_utc"]].drop_duplicates()


def path_etas_sql(con, points_rel: str, departures_rel: str) -> str:
    """SQL computing ETAs of every point of every path for every departure (see module docstring).

    ``points_rel`` / ``departures_rel`` are names of registered relations (generated here, quoted).
    The haversine radius is bound as the first parameter.
    """
    return f"""
        WITH legs AS (
            SELECT path_id, seq, lat_deg, lon_deg, speed_kn,
                   lag(lat_deg) OVER w AS plat, lag(lon_deg) OVER w AS plon, lag(speed_kn) OVER w AS pspeed
            FROM "{points_rel}" WINDOW w AS (PARTITION BY path_id ORDER BY seq)
        ), hours AS (
            SELECT *, CASE WHEN plat IS NULL THEN 0.0 ELSE
                2.0 * $radius * asin(sqrt(least(1.0,
                    pow(sin(radians(lat_deg - plat) / 2.0), 2)
                    + cos(radians(plat)) * cos(radians(lat_deg)) * pow(sin(radians(lon_deg - plon) / 2.0), 2))))
                / pspeed END AS leg_h,
                CASE WHEN plat IS NULL THEN 0.0 ELSE
                2.0 * $radius * asin(sqrt(least(1.0,
                    pow(sin(radians(lat_deg - plat) / 2.0), 2)
                    + cos(radians(plat)) * cos(radians(lat_deg)) * pow(sin(radians(lon_deg - plon) / 2.0), 2)))) END AS leg_nmi
            FROM legs
        ), cum AS (
            SELECT path_id, seq, lat_deg, lon_deg, speed_kn,
                   sum(leg_h) OVER (PARTITION BY path_id ORDER BY seq ROWS UNBOUNDED PRECEDING) AS elapsed_h,
                   sum(leg_nmi) OVER (PARTITION BY path_id ORDER BY seq ROWS UNBOUNDED PRECEDING) AS dist_nmi
            FROM hours
        )
        SELECT cum.path_id, d.departure_utc, cum.seq, cum.lat_deg, cum.lon_deg, cum.speed_kn, cum.dist_nmi, cum.elapsed_h,
               d.departure_utc + to_microseconds(CAST(round(cum.elapsed_h * 3600e6) AS BIGINT)) AS eta_utc
        FROM cum JOIN "{departures_rel}" d ON d.path_id = cum.path_id
    """


def compute_etas(ws, points: pd.DataFrame, departures) -> pd.DataFrame:
    """ETAs of path points for each departure, in DuckDB (no weather). Columns as the join's first ones."""
    p = _validate_points(points)
    d = _departures_frame(departures, p)
    con = ws.con
    con.register("_wx_points", p)
    con.register("_wx_departures", d)
    try:
        out = con.execute(path_etas_sql(con, "_wx_points", "_wx_departures") + " ORDER BY path_id, departure_utc, seq",
                          {"radius": EARTH_RADIUS_NMI}).df()
    finally:
        con.unregister("_wx_points")
        con.unregister("_wx_departures")
    for c in ("departure_utc", "eta_utc"):
        out[c] = pd.to_datetime(out[c], utc=True)
    return out


def join_points_weather(ws, points: pd.DataFrame, departures, grid: int | str | None = None,
                        on_missing: str = "raise") -> pd.DataFrame:
    """Weather at every point of every path for every departure: ETA, grid cell, nearest time.

    Parameters
    ----------
    ws : Workspace
    points : DataFrame
        ``path_id``, ``seq`` (0..n-1 in sailing order), ``lat_deg``, ``lon_deg``, ``speed_kn``
        (typical speed at that point, used for the leg that starts there).
    departures : list of datetimes or DataFrame
        Departure times applied to every path, or a frame with ``path_id`` and ``departure_utc``.
    grid : int or str, optional
        Grid id or name (default: the latest loaded).
    on_missing : {"raise", "flag"}
        Points outside the grid's bbox or time span raise :class:`weather.errors.CoverageError`
        (naming product, span and count), or are returned with ``status`` and NULL weather.

    Returns
    -------
    DataFrame
        One row per (path_id, departure_utc, seq): position, ``dist_nmi``, ``elapsed_h``,
        ``eta_utc``, ``lat_idx``/``lon_idx``, ``cell_lat_deg``/``cell_lon_deg``,
        ``weather_time_utc``, the canonical variables, and ``status`` in {"ok", "land",
        "outside_grid", "outside_time"}.
    """
    # Long by design: it builds one SQL statement (ETAs, cells, the two ASOF joins) whose parts
    # only make sense together; the statement is the unit that is tested against xarray.
    _, CoverageError = _errors()
    if on_missing not in ("raise", "flag"):
        raise ValueError(f"on_missing must be 'raise' or 'flag', not {on_missing!r}")
    g = get_grid(ws, grid)
    p = _validate_points(points)
    d = _departures_frame(departures, p)
    regular = g["step_s"] is not None and not pd.isna(g["step_s"])  # NULL step = irregular time axis
    half_step_us = int(round(float(g["step_s"]) * 1e6 / 2.0)) if regular else 0
    pick = ", ".join(
        f"CASE WHEN status = 'ok' THEN (CASE WHEN use_next THEN next_{c} ELSE prev_{c} END) END AS {c}" for c in CANONICAL_COLUMNS
    )
    pts_sql = f"""
        CREATE OR REPLACE TEMP TABLE _wx_pts AS
        SELECT etas.*,
               CAST(round((lat_deg - $lat0) / $dlat) AS INTEGER) AS lat_idx,
               CAST(round((lon_deg - $lon0) / $dlon) AS INTEGER) AS lon_idx
        FROM ({path_etas_sql(ws.con, "_wx_points", "_wx_departures")}) AS etas
    """
    prev_cols = ", ".join(f"w.{c} AS prev_{c}" for c in CANONICAL_COLUMNS)
    next_cols = ", ".join(f"w.{c} AS next_{c}" for c in CANONICAL_COLUMNS)
    if regular:
        # Regular time axis: ONE ASOF join on ETA + half a step finds the nearest time (the last
        # time strictly before ETA + step/2; an ETA exactly midway takes the earlier time).
        time_join = f"""both_sides AS (
            SELECT p.*, w.time_utc AS prev_time, {prev_cols},
                   CAST(NULL AS TIMESTAMPTZ) AS next_time, {", ".join(f"NULL AS next_{c}" for c in CANONICAL_COLUMNS)}
            FROM _wx_pts p ASOF LEFT JOIN cells w
              ON p.lat_idx = w.lat_idx AND p.lon_idx = w.lon_idx AND p.eta_utc + to_microseconds($half) > w.time_utc
        ),"""
    else:
        # Irregular times: the last time <= ETA and the first time >= ETA, keep the closer one.
        time_join = f"""prev AS (
            SELECT p.*, w.time_utc AS prev_time, {prev_cols}
            FROM _wx_pts p ASOF LEFT JOIN cells w
              ON p.lat_idx = w.lat_idx AND p.lon_idx = w.lon_idx AND p.eta_utc >= w.time_utc
        ),
        both_sides AS (
            SELECT prev.*, w.time_utc AS next_time, {next_cols}
            FROM prev ASOF LEFT JOIN cells w
              ON prev.lat_idx = w.lat_idx AND prev.lon_idx = w.lon_idx AND prev.eta_utc <= w.time_utc
        ),"""
    sql = f"""
        WITH keys AS (SELECT DISTINCT lat_idx, lon_idx FROM _wx_pts),
        span AS (SELECT min(eta_utc) AS t0, max(eta_utc) AS t1 FROM _wx_pts),
        cells AS (  -- only the cells and times the paths can touch (a hash semi-join before the ASOF joins)
            SELECT w.* FROM weather_cells w SEMI JOIN keys k ON w.lat_idx = k.lat_idx AND w.lon_idx = k.lon_idx
            WHERE w.grid_id = $grid_id
              AND w.time_utc >= (SELECT t0 FROM span) - to_microseconds($pad)
              AND w.time_utc <= (SELECT t1 FROM span) + to_microseconds($pad)
        ),
        {time_join}
        chosen AS (
            SELECT *,
                   (prev_time IS NULL) OR (next_time IS NOT NULL AND (next_time - eta_utc) < (eta_utc - prev_time)) AS use_next,
                   CASE
                     WHEN lat_idx < 0 OR lat_idx >= $nlat OR lon_idx < 0 OR lon_idx >= $nlon THEN 'outside_grid'
                     WHEN eta_utc < $start - to_microseconds($half) OR eta_utc > $end + to_microseconds($half) THEN 'outside_time'
                     WHEN prev_time IS NULL AND next_time IS NULL THEN 'land'
                     ELSE 'ok' END AS status
            FROM both_sides
        )
        SELECT path_id, departure_utc, seq, lat_deg, lon_deg, speed_kn, dist_nmi, elapsed_h, eta_utc,
               lat_idx, lon_idx, $lat0 + lat_idx * $dlat AS cell_lat_deg, $lon0 + lon_idx * $dlon AS cell_lon_deg,
               CASE WHEN status = 'ok' THEN (CASE WHEN use_next THEN next_time ELSE prev_time END) END AS weather_time_utc,
               {pick}, status
        FROM chosen
        ORDER BY path_id, departure_utc, seq
    """
    grid_params = {"lat0": float(g["lat0_deg"]), "dlat": float(g["dlat_deg"]), "lon0": float(g["lon0_deg"]),
                   "dlon": float(g["dlon_deg"])}
    # Cells are read two time steps beyond the ETA window on each side (the whole span when the
    # grid's times are irregular), so the nearest time on both sides is always among them.
    span_us = int((pd.Timestamp(g["end_utc"]) - pd.Timestamp(g["start_utc"])) / pd.Timedelta(microseconds=1))
    pad_us = 4 * half_step_us if regular else span_us + 1
    params = {
        **grid_params, "grid_id": int(g["grid_id"]), "nlat": int(g["nlat"]), "nlon": int(g["nlon"]),
        "start": pd.Timestamp(g["start_utc"]), "end": pd.Timestamp(g["end_utc"]), "half": half_step_us, "pad": pad_us,
    }
    con = ws.con
    con.register("_wx_points", p)
    con.register("_wx_departures", d)
    try:
        con.execute(pts_sql, {"radius": EARTH_RADIUS_NMI, **grid_params})
        out = con.execute(sql, params).df()
    finally:
        con.unregister("_wx_points")
        con.unregister("_wx_departures")
        con.execute("DROP TABLE IF EXISTS _wx_pts")
    for c in ("departure_utc", "eta_utc", "weather_time_utc"):
        out[c] = pd.to_datetime(out[c], utc=True)
    if on_missing == "raise":
        out_t = out[out["status"] == "outside_time"]
        out_g = out[out["status"] == "outside_grid"]
        span = f"{pd.Timestamp(g['start_utc']).tz_convert('UTC'):%Y-%m-%dT%H:%MZ} -> {pd.Timestamp(g['end_utc']).tz_convert('UTC'):%Y-%m-%dT%H:%MZ}"
        if not out_t.empty:
            raise CoverageError(
                f"{g['product']}, {g['variables']}: no data for ETAs {out_t.eta_utc.min():%Y-%m-%dT%H:%MZ} -> "
                f"{out_t.eta_utc.max():%Y-%m-%dT%H:%MZ} ({len(out_t)} path points; data cover {span})"
            )
        if not out_g.empty:
            lat0, lon0 = float(g["lat0_deg"]), float(g["lon0_deg"])
            lat1 = lat0 + (int(g["nlat"]) - 1) * float(g["dlat_deg"])
            lon1 = lon0 + (int(g["nlon"]) - 1) * float(g["dlon_deg"])
            raise CoverageError(
                f"{g['product']}, {g['variables']}: {len(out_g)} path points outside the grid, e.g. "
                f"{out_g.lat_deg.iloc[0]:.4f}N {out_g.lon_deg.iloc[0]:.4f}E (data cover lon {lon0:g}..{lon1:g}, lat {lat0:g}..{lat1:g})"
            )
    return out
