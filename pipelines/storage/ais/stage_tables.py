"""Stages from tables: Parquet files, typed DataFrames (NMEA) and Arrow tables; reading a stage back."""

from __future__ import annotations

from pathlib import Path

import duckdb
import numpy as np
import pandas as pd

from ais import clean as C
from ais.io.csv_formats import MMSI_RE
from ais.io.parquet import WKB_POINT_HEADS, _blob_text, is_geometry
from pipelines.storage.ais._sql import (
    _NUM_FIELDS, _STATIC_TYPES, _TEXT_STATIC, _create_stage, _params, _prepare, _q, _set_stage_kind,
    _stage_kind, _typed_static_select, _used, parquet_as_stored,
)


def parquet_columns(ws, path: Path, shown=None) -> list[tuple[str, str]]:
    """(name, DuckDB type) of the columns of a Parquet file; :class:`AisFormatError` (naming
    ``shown``, default ``path``) when it is not one (e.g. ``--format parquet`` forced on a CSV
    file)."""
    parquet_as_stored(ws.con)
    try:
        rows = ws.con.execute("DESCRIBE SELECT * FROM read_parquet(?)", [str(path)]).fetchall()
    except (duckdb.InvalidInputException, duckdb.IOException) as err:
        from ais.errors import AisFormatError

        why = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise AisFormatError(shown or path, f"not a readable Parquet file ({why})") from None
    return [(r[0], r[1]) for r in rows]


def stage_parquet(ws, path: Path, mapping: dict[str, str], raw_from_file: bool = True) -> dict:
    """Type a Parquet file into ``ais_stage``. ``mapping``: stage field -> source column.

    Numbers are cast with ``TRY_CAST``; a value that does not cast is a parse error of its
    field. Timestamps without a time zone are taken as UTC. ``line`` is the 1-based row number;
    a row's ``raw`` text is its source values joined by commas (:func:`parquet_raw_sql`).

    With ``raw_from_file`` (the file stays readable until the commit) no text is staged: ``raw``
    is read from the file for the quarantined rows only (:func:`parquet_raw_lines`), and the
    static fields' texts for the latest row of each vessel's distinct static values only, found
    by a hash of them (``s_hash``, as the fast CSV stages do). Writing every row's values as
    text took a third of the stage's CPU (1.8 of 5.3 us per row on a NOAA-style daily file), and
    the static numbers' texts 0.9 us more (issue 23).
    """
    _prepare(ws.con)
    cols = dict(parquet_columns(ws, path))
    wkb, f32 = _side_columns(mapping, cols)
    side = wkb is not None or bool(f32)  # columns computed in numpy, joined by row (_side_table)

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
            if wkb:
                return f"{_WKB_PREFIX}{axis}"  # decoded in numpy and joined by row (_parquet_rows)
            value = f"TRY_CAST({src(fld)}.{axis} AS DOUBLE)"  # GeoArrow's point struct
        elif fld in f32:
            value = f"{_F32_PREFIX}{fld}"  # widened in numpy and joined by row (_side_table)
        elif fld == "nav_status" and cols.get(mapping[fld], "") == "VARCHAR":
            # text: a number, or a DMA status word as the CSV readers take it (a DMA CSV file
            # converted to Parquet keeps its words: every row was quarantined as bad_nav_status)
            value = f"coalesce({value}, MAP($nav_k::VARCHAR[], $nav_v::INTEGER[])[lower(trim({src(fld)}, $ws))])"
        return f"CASE WHEN isnan({value}) THEN NULL ELSE {value} END"

    def unreadable(fld):
        """A value present that gives no number: text that is none (or 'nan', as the pure path),
        a geometry that is no point. A float column's NaN is a missing value, not an error."""
        geometric = fld in ("lat_deg", "lon_deg") and is_geometry(mapping)
        if cols.get(mapping[fld], "") in ("DOUBLE", "FLOAT") and not geometric:
            return "false"
        return f"{src(fld)} IS NOT NULL AND {num(fld)} IS NULL"

    perr = " ".join(
        f"WHEN {unreadable(fld)} THEN '{code}'"
        for fld, code in (("lat_deg", C.BAD_LAT), ("lon_deg", C.BAD_LON), ("sog_kn", C.BAD_SOG),
                          ("cog_deg", C.BAD_COG), ("heading_deg", C.BAD_HEADING), ("nav_status", C.BAD_NAV_STATUS))
        if fld in mapping
    )
    statics = ", ".join(
        (f"CAST({src(c)} AS VARCHAR) AS s_{c}" if c in mapping and not raw_from_file else f"CAST(NULL AS VARCHAR) AS s_{c}")
        for c in C.STATIC_COLUMNS
    )
    raw = "CAST(NULL AS VARCHAR)" if raw_from_file else parquet_raw_sql(list(cols), wkb)
    typed = f"""
    SELECT file_row_number + 1 AS line, {raw} AS raw, '{C.KIND_POSITION}' AS kind,
        CASE {perr or "WHEN false THEN NULL"} END AS parse_error,
        {_mmsi_sql(src('mmsi'), cols.get(mapping.get("mmsi"), ""))} AS mmsi,
        {_time_sql(src('time_utc'), cols.get(mapping.get("time_utc"), ""))} AS time_utc,
        {", ".join(f"{num(fld)} AS {fld}" for fld in (*_NUM_FIELDS, "nav_status"))},
        {", ".join(f"CAST(NULL AS {t}) AS {c}" for c, t in _STATIC_TYPES.items())},
        {statics}, {_statics_hash(mapping) if raw_from_file else "CAST(NULL AS UBIGINT)"} AS s_hash
    FROM {_parquet_rows(side)}
    """
    if side:
        ws.con.register(_SIDE_TABLE, _side_table(path, wkb, f32))
    try:
        _create_stage(ws.con, typed, {"path": str(path), "mmsi_re": MMSI_RE})
    finally:
        if side:
            ws.con.unregister(_SIDE_TABLE)
    extra = {"raw_path": str(path), "raw_columns": list(cols), "raw_wkb": wkb,
             "static_columns": {c: mapping[c] for c in C.STATIC_COLUMNS if c in mapping}}
    _set_stage_kind(ws.con, "text", extra if raw_from_file else None)
    return {"ignored": 0, "python_fallback": False}


def _time_sql(value: str, ttype: str) -> str:
    """A Parquet time column as a naive UTC timestamp. A finite time with a time zone is read
    through its epoch microseconds: the cast to TIMESTAMP went through ICU's calendar per row
    (0.8 CPU us per row, issue 23); ``infinity`` keeps that cast."""
    if "TIME ZONE" in ttype:
        return (f"CASE WHEN isfinite({value}) THEN make_timestamp(epoch_us({value})) "
                f"ELSE CAST(CAST({value} AS TIMESTAMPTZ) AS TIMESTAMP) END")
    if ttype.startswith("TIMESTAMP") or ttype == "DATE":
        return f"CAST({value} AS TIMESTAMP)"
    return f"CAST(TRY_CAST({value} AS TIMESTAMPTZ) AS TIMESTAMP)"


def _mmsi_sql(value: str, mtype: str) -> str:
    """A Parquet MMSI column as BIGINT: a whole number, or text of digits (:data:`MMSI_RE`)."""
    if any(k in mtype for k in ("INT", "DECIMAL", "DOUBLE", "FLOAT")):
        return f"CASE WHEN {value} = floor({value}) THEN CAST({value} AS BIGINT) END"
    text = f"CAST({value} AS VARCHAR)"
    return f"CASE WHEN regexp_full_match({text}, $mmsi_re) THEN CAST({text} AS BIGINT) END"


def parquet_raw_sql(columns: list[str], wkb: str | None = None) -> str:
    """A Parquet row's ``raw`` text: its values in column order as text, joined by commas (a
    missing value empty); a 2D point of the WKB geometry column ``wkb`` as its WKT (DuckDB's
    ``ST_AsText``, as :func:`ais.io.parquet.geometry_text` writes it on the pure path)."""
    def text(c: str) -> str:
        value = f"CAST({_q(c)} AS VARCHAR)"
        if c == wkb:
            heads = " OR ".join(f"starts_with({value}, '{_blob_text(head)}')" for head in WKB_POINT_HEADS)
            value = f"CASE WHEN octet_length({_q(c)}) = 21 AND ({heads}) THEN ST_AsText(ST_GeomFromWKB({_q(c)})) ELSE {value} END"
        return f"coalesce({value}, '')"

    return "concat_ws(',', " + ", ".join(text(c) for c in columns) + ")"


def parquet_raw_lines(extra: dict, lines_sql: str, statics: bool = False, raw: bool = True) -> str:
    """``(line, raw)`` of the rows of a Parquet stage staged without their text (the stage
    info's ``extra``: ``raw_path``, ``raw_columns``, ``static_columns``) whose line is in
    ``lines_sql`` (a query of one column ``line``); with ``statics`` also their static fields'
    texts ``s_<field>`` (as :func:`stage_parquet` stages them with their text); without ``raw``
    only those (``line`` and the texts)."""
    texts = [f"{_static_text(extra, c)} AS s_{c}" for c in C.STATIC_COLUMNS] if statics else []
    values = ", ".join(["file_row_number + 1 AS line", *([f"{parquet_raw_sql(extra['raw_columns'], extra.get('raw_wkb'))} AS raw"] if raw else []),
                        *texts])
    return f"(SELECT {values} FROM {_file_rows(extra)} WHERE file_row_number + 1 IN ({lines_sql}))"


def _statics_hash(mapping: dict[str, str]) -> str:
    """A 64-bit hash of a row's static source values (DuckDB's ``hash``), NULL when the file has
    no static column: rows of one vessel with equal values share it. Values equal as values but
    not as text (0.0 and -0.0, NaN and -NaN) share it too, and the text is then the latest
    row's: the outcome of typing each text apart, since such texts type alike (both missing as
    numbers, both kept as text)."""
    columns = [_q(mapping[c]) for c in C.STATIC_COLUMNS if c in mapping]
    return f"hash({', '.join(columns)})" if columns else "CAST(NULL AS UBIGINT)"


def _static_text(extra: dict, field: str) -> str:
    column = extra["static_columns"].get(field)
    return "CAST(NULL AS VARCHAR)" if column is None else f"CAST({_q(column)} AS VARCHAR)"


def _file_rows(extra: dict) -> str:
    path = extra["raw_path"].replace("'", "''")
    return f"read_parquet('{path}', file_row_number = true)"


#: The columns a WKB point geometry is decoded into (x, y), those binary32 fields are widened
#: into, and the table of them by row number (:func:`_side_table`).
_WKB_PREFIX = "__stormlane_wkb_"
_F32_PREFIX = "__stormlane_f32_"
_SIDE_TABLE = "ais_side_columns_df"


def _side_columns(mapping: dict[str, str], cols: dict[str, str]) -> tuple[str | None, dict[str, str]]:
    """What is read beside the SQL: the WKB point column of the positions (or None), and the
    position fields stored as binary32 ``FLOAT`` (field -> column), widened as the decimals they
    were written from (:func:`ais.io.float32.widen_float32`: an SOG of 5.9f is 5.9, as its CSV
    text reads, not 5.900000095...; DuckDB's cast widens bit for bit, and its text of a FLOAT is
    not always the shortest: -162.921875 for -162.92188f)."""
    geometric = ("lat_deg", "lon_deg") if is_geometry(mapping) else ()
    f32 = {fld: mapping[fld] for fld in (*_NUM_FIELDS, "nav_status")
           if fld in mapping and fld not in geometric and cols.get(mapping[fld], "") == "FLOAT"}
    return _wkb_column(mapping, cols), f32


def _wkb_column(mapping: dict[str, str], cols: dict[str, str]) -> str | None:
    """The column the positions come from when it is a WKB point geometry (not GeoArrow's struct)."""
    geometry = mapping.get("lat_deg")
    if is_geometry(mapping) and not cols.get(geometry, "").upper().startswith("STRUCT"):
        return geometry
    return None


def _side_table(path: Path, wkb: str | None, f32: dict[str, str]):
    """The columns of :func:`_side_columns` as an Arrow table (``row``: 0-based row number; the
    WKB points' x and y, NULL where a value is no point; each binary32 field widened, NaN where
    missing), read batch by batch and computed in numpy (:func:`ais.io.parquet.wkb_point_xy`,
    :func:`ais.io.float32.widen_float32`). A DuckDB function over the WKB column took 0.8 CPU us
    per row, most of it converting each vector of BLOBs to Arrow; this takes about 0.1 (issue 23)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from ais.io.float32 import widen_float32
    from ais.io.parquet import wkb_point_xy

    names = list(dict.fromkeys(([wkb] if wkb else []) + list(f32.values())))
    keys = ([f"{_WKB_PREFIX}x", f"{_WKB_PREFIX}y"] if wkb else []) + [f"{_F32_PREFIX}{fld}" for fld in f32]
    out: dict[str, list] = {k: [np.zeros(0)] for k in keys}
    with pq.ParquetFile(str(path)) as pf:
        for batch in pf.iter_batches(columns=names, batch_size=1 << 16):
            if wkb:
                x, y = wkb_point_xy(batch.column(wkb))
                out[f"{_WKB_PREFIX}x"].append(x)
                out[f"{_WKB_PREFIX}y"].append(y)
            for fld, column in f32.items():
                values = batch.column(column).to_numpy(zero_copy_only=False)  # a missing value as NaN
                out[f"{_F32_PREFIX}{fld}"].append(widen_float32(values))
    arrays = {k: np.concatenate(v) for k, v in out.items()}
    n = len(arrays[keys[0]])
    return pa.table({"row": pa.array(np.arange(n, dtype=np.int64)),
                     **{k: pa.array(v, pa.float64(), mask=np.isnan(v) if k.startswith(_WKB_PREFIX) else None)
                        for k, v in arrays.items()}})


def _parquet_rows(side: bool) -> str:
    """The FROM of :func:`stage_parquet`: the file's rows, with the side columns (``side``) joined
    by row number from :func:`_side_table` (registered as :data:`_SIDE_TABLE` meanwhile)."""
    rows = "read_parquet($path, file_row_number = true)"
    return f"{rows} LEFT JOIN {_SIDE_TABLE} ON file_row_number = {_SIDE_TABLE}.row" if side else rows


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


def read_stage(ws, with_raw: bool = True) -> pd.DataFrame:
    """The current typed stage as a DataFrame, statics typed (tests compare it with pandas).
    ``with_raw=False``: a Parquet stage's ``raw`` left missing (its commit reads it from the file)."""
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
    if "raw_path" in extra:  # a Parquet stage: the texts from the file (static ones unless spooled typed)
        statics = "static_columns" in extra
        texts = "".join(f", r.s_{c} AS s_{c}" for c in C.STATIC_COLUMNS) if statics else ""
        raw = "coalesce(s.raw, r.raw)" if with_raw else "s.raw"
        rows = parquet_raw_lines(extra, "SELECT line FROM ais_stage", statics=statics, raw=with_raw)
        source = f"(SELECT s.* REPLACE ({raw} AS raw{texts}) FROM ais_stage s LEFT JOIN {rows} r USING (line))"
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
