"""Stages from tables: Parquet files, typed DataFrames (NMEA) and Arrow tables; reading a stage back."""

from __future__ import annotations

from pathlib import Path

import duckdb
import numpy as np
import pandas as pd

from ais import clean as C
from ais.io.csv_formats import MMSI_RE
from ais.io.parquet import is_geometry
from pipelines.storage.ais._sql import (
    _NUM_FIELDS, _STATIC_TYPES, _TEXT_STATIC, _create_stage, _params, _prepare, _q, _set_stage_kind,
    _stage_kind, _typed_static_select, _used,
)


def parquet_columns(ws, path: Path, shown=None) -> list[tuple[str, str]]:
    """(name, DuckDB type) of the columns of a Parquet file; :class:`AisFormatError` (naming
    ``shown``, default ``path``) when it is not one (e.g. ``--format parquet`` forced on a CSV
    file)."""
    try:
        rows = ws.con.execute("DESCRIBE SELECT * FROM read_parquet(?)", [str(path)]).fetchall()
    except (duckdb.InvalidInputException, duckdb.IOException) as err:
        from ais.errors import AisFormatError

        why = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise AisFormatError(shown or path, f"not a readable Parquet file ({why})") from None
    return [(r[0], r[1]) for r in rows]


def stage_parquet(ws, path: Path, mapping: dict[str, str]) -> dict:
    """Type a Parquet file into ``ais_stage``. ``mapping``: stage field -> source column.

    Numbers are cast with ``TRY_CAST``; a value that does not cast is a parse error of its
    field. Timestamps without a time zone are taken as UTC. ``raw`` is the row's source values
    joined by commas; ``line`` is the 1-based row number.
    """
    _prepare(ws.con)
    cols = dict(parquet_columns(ws, path))

    def src(fld):
        return _q(mapping[fld]) if fld in mapping else "NULL"

    def num(fld):
        """The field as a double, NaN as NULL (isnan: a NaN read from Parquet need not equal
        'nan'::DOUBLE, so nullif kept it: the SQL path then differed from the pure and spooled ones)."""
        if fld not in mapping:
            return "CAST(NULL AS DOUBLE)"
        value = f"TRY_CAST({src(fld)} AS DOUBLE)"
        if fld in ("lat_deg", "lon_deg") and is_geometry(mapping):  # a point geometry (ais.io.parquet)
            axis = "y" if fld == "lat_deg" else "x"
            if _wkb_column(mapping, cols):
                return f"{_WKB_PREFIX}{axis}"  # decoded once per row in the FROM below; NULL where no point
            value = f"TRY_CAST({src(fld)}.{axis} AS DOUBLE)"  # GeoArrow's point struct
        return f"CASE WHEN isnan({value}) THEN NULL ELSE {value} END"

    def unreadable(fld):
        """A value present that gives no number: text that is none (or 'nan', as the pure path),
        a geometry that is no point. A float column's NaN is a missing value, not an error."""
        geometric = fld in ("lat_deg", "lon_deg") and is_geometry(mapping)
        if cols.get(mapping[fld], "") in ("DOUBLE", "FLOAT") and not geometric:
            return "false"
        return f"{src(fld)} IS NOT NULL AND {num(fld)} IS NULL"

    ttype = cols.get(mapping.get("time_utc"), "")
    if "TIME ZONE" in ttype:
        time_expr = f"CAST(CAST({src('time_utc')} AS TIMESTAMPTZ) AS TIMESTAMP)"
    elif ttype.startswith("TIMESTAMP") or ttype == "DATE":
        time_expr = f"CAST({src('time_utc')} AS TIMESTAMP)"
    else:
        time_expr = f"CAST(TRY_CAST({src('time_utc')} AS TIMESTAMPTZ) AS TIMESTAMP)"
    mtype = cols.get(mapping.get("mmsi"), "")
    if any(k in mtype for k in ("INT", "DECIMAL", "DOUBLE", "FLOAT")):
        mmsi_expr = f"CASE WHEN {src('mmsi')} = floor({src('mmsi')}) THEN CAST({src('mmsi')} AS BIGINT) END"
    else:
        m = f"CAST({src('mmsi')} AS VARCHAR)"
        mmsi_expr = f"CASE WHEN regexp_full_match({m}, $mmsi_re) THEN CAST({m} AS BIGINT) END"
    perr = " ".join(
        f"WHEN {unreadable(fld)} THEN '{code}'"
        for fld, code in (("lat_deg", C.BAD_LAT), ("lon_deg", C.BAD_LON), ("sog_kn", C.BAD_SOG),
                          ("cog_deg", C.BAD_COG), ("heading_deg", C.BAD_HEADING), ("nav_status", C.BAD_NAV_STATUS))
        if fld in mapping
    )
    raw = "concat_ws(',', " + ", ".join(f"coalesce(CAST({_q(c)} AS VARCHAR), '')" for c in cols) + ")"
    statics = ", ".join(
        (f"CAST({src(c)} AS VARCHAR) AS s_{c}" if c in mapping else f"CAST(NULL AS VARCHAR) AS s_{c}")
        for c in C.STATIC_COLUMNS
    )
    typed = f"""
    SELECT file_row_number + 1 AS line, {raw} AS raw, '{C.KIND_POSITION}' AS kind,
        CASE {perr or "WHEN false THEN NULL"} END AS parse_error,
        {mmsi_expr} AS mmsi, {time_expr} AS time_utc,
        {", ".join(f"{num(fld)} AS {fld}" for fld in (*_NUM_FIELDS, "nav_status"))},
        {", ".join(f"CAST(NULL AS {t}) AS {c}" for c, t in _STATIC_TYPES.items())},
        {statics}, CAST(NULL AS UBIGINT) AS s_hash
    FROM {_parquet_rows(mapping, cols)}
    """
    _create_stage(ws.con, typed, {"path": str(path), "mmsi_re": MMSI_RE})
    _set_stage_kind(ws.con, "text")
    return {"ignored": 0, "python_fallback": False}


#: The columns a WKB point geometry is decoded into, once per row (the value and the parse-error
#: check both read them; calling the decoding function in each would decode each point twice).
_WKB_PREFIX = "__stormlane_wkb_"


def _wkb_column(mapping: dict[str, str], cols: dict[str, str]) -> str | None:
    """The column the positions come from when it is a WKB point geometry (not GeoArrow's struct)."""
    geometry = mapping.get("lat_deg")
    if is_geometry(mapping) and not cols.get(geometry, "").upper().startswith("STRUCT"):
        return geometry
    return None


def _parquet_rows(mapping: dict[str, str], cols: dict[str, str]) -> str:
    """The FROM of :func:`stage_parquet`: the file's rows, with a WKB point decoded to x and y."""
    rows = "read_parquet($path, file_row_number = true)"
    wkb = _wkb_column(mapping, cols)
    if wkb is None:
        return rows
    return f"(SELECT *, ais_wkb_x({_q(wkb)}) AS {_WKB_PREFIX}x, ais_wkb_y({_q(wkb)}) AS {_WKB_PREFIX}y FROM {rows})"


def stage_frame(ws, stage: pd.DataFrame) -> dict:
    """Put a typed stage built in Python (NMEA, or any reader) into ``ais_stage``."""
    return stage_arrow(ws, stage_table(stage))


def stage_table(stage: pd.DataFrame):
    """A typed stage DataFrame as the Arrow table :func:`stage_arrow` reads (``time_utc`` naive
    UTC). Arrow keeps NULLs as NULLs (nullable ints, NaT, None) and scans faster than object
    columns."""
    import pyarrow as pa

    df = C.conform_stage(stage) if list(stage.dtypes.astype(str)) != list(C.STAGE_COLUMNS.values()) else stage
    return pa.Table.from_pandas(df.assign(time_utc=df["time_utc"].dt.tz_convert(None)), preserve_index=False)


def stage_arrow(ws, tbl) -> dict:
    """Put an Arrow table with the columns of :data:`ais.clean.STAGE_COLUMNS` (``time_utc``
    naive UTC) into ``ais_stage`` - what :func:`stage_frame` does after its conversion."""
    _prepare(ws.con)
    ws.con.register("ais_stage_df", tbl)
    try:
        typed = f"""SELECT
                CAST(line AS BIGINT) AS line, CAST(raw AS VARCHAR) AS raw, CAST(kind AS VARCHAR) AS kind,
                CAST(parse_error AS VARCHAR) AS parse_error, CAST(mmsi AS BIGINT) AS mmsi,
                CAST(time_utc AS TIMESTAMP) AS time_utc,
                lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, nav_status,
                CAST(imo AS BIGINT) AS imo, CAST(name AS VARCHAR) AS name, CAST(callsign AS VARCHAR) AS callsign,
                CAST(ship_type AS INTEGER) AS ship_type, length_m, beam_m, draught_m,
                CAST(destination AS VARCHAR) AS destination,
                {", ".join(f"CAST(NULL AS VARCHAR) AS {c}" for c in _TEXT_STATIC)},
                CAST(NULL AS UBIGINT) AS s_hash
            FROM ais_stage_df"""
        _create_stage(ws.con, typed)
        _set_stage_kind(ws.con, "typed")
    finally:
        ws.con.unregister("ais_stage_df")
    return {"ignored": 0, "python_fallback": False}


def read_stage(ws) -> pd.DataFrame:
    """The current typed stage as a DataFrame, statics typed (tests compare it with pandas)."""
    cols = ["mmsi", "timezone('UTC', time_utc) AS time_utc", *_NUM_FIELDS, "nav_status", _typed_static_select()]
    source = "ais_stage"
    kind, extra = _stage_kind(ws.con)
    registered = False
    if kind == "csvfast":  # rows from the scanner: the raw text from their line
        import pyarrow as pa

        from ais.io.lineindex import LineIndex

        need = np.asarray(ws.con.execute("SELECT line FROM ais_stage WHERE raw IS NULL ORDER BY line")
                          .fetchnumpy()["line"], dtype=np.int64)
        with LineIndex(extra["path"]) as ix:
            ws.con.register("ais_rs_raw", pa.table({"line": pa.array(need), "raw": pa.array(ix.text(need), pa.string())}))
        registered = True
        source = ("(SELECT s.* REPLACE (coalesce(s.raw, r.raw) AS raw) FROM ais_stage s "
                  "LEFT JOIN ais_rs_raw r USING (line))")
    if kind in ("csvhash", "csvfast"):  # the static texts, re-split from the raw lines
        index = extra["index"]
        texts = ", ".join(f"f[{index[c]}] AS {c}" if c in index else f"CAST(NULL AS VARCHAR) AS {c}"
                          for c in _TEXT_STATIC)
        source = (f"(SELECT * EXCLUDE (f, {', '.join(_TEXT_STATIC)}), {texts} FROM (SELECT *, "
                  f"CASE WHEN contains(raw, '\"') THEN ais_csv_split(raw) ELSE string_split(raw, ',') END AS f "
                  f"FROM {source}))")
    # A bad line keeps no typed field (the bulk path leaves whatever its fields typed to).
    sql = (f"SELECT line, raw, kind, parse_error, "
           f"COLUMNS(c -> c NOT IN ('line', 'raw', 'kind', 'parse_error')) FROM ("
           f"  SELECT line, raw, kind, parse_error, {', '.join(cols)} FROM {source}) s "
           f"WHERE kind <> '{C.KIND_IGNORED}' ORDER BY line")
    try:
        df = ws.con.execute(sql, _used(sql, _params())).fetchdf()
    finally:
        if registered:
            ws.con.unregister("ais_rs_raw")
    bad = df["parse_error"] == C.BAD_LINE
    keep = {"line", "raw", "kind", "parse_error"}
    df.loc[bad, [c for c in df.columns if c not in keep]] = None
    return C.conform_stage(df)
