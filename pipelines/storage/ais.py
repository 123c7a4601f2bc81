"""AIS tables: files, positions, vessels, quarantine - and the SQL of the bulk ingest.

Tables (component ``ais``):

``ais_files``
    one row per loaded file: ``file_id``, ``fingerprint`` (SHA-256 of the bytes, unique),
    ``path``, ``format``, ``size_bytes``, the counts (``n_read`` = ``n_loaded`` +
    ``n_quarantined`` + ``n_duplicates``; ``n_static``, ``n_ignored``), ``reasons`` (JSON),
    ``max_speed_kn``, ``loaded_at``.
``ais_positions``
    the canonical positions (``mmsi``, ``time_utc`` TIMESTAMPTZ, ``lat_deg``, ``lon_deg``,
    ``sog_kn``, ``cog_deg``, ``heading_deg``, ``nav_status``) plus ``file_id`` and
    ``source_line``. (mmsi, time_utc) is unique: the ingest counts later rows with the same key
    as duplicates.
``vessels``
    static data, one row per MMSI, the latest non-missing value of each field wins.
``ais_quarantine``
    every row not loaded: ``file_id``, ``line`` (CSV/NMEA line, Parquet row, 1-based),
    ``reason`` (a code of :mod:`lanes.clean`), ``raw`` text, ``mmsi`` and ``time_utc`` when known.
    Duplicates are kept here too, with their ``duplicate*`` code.

Bulk ingest, per file: the reader fills the temporary typed stage ``ais_stage`` (CSV straight
from DuckDB's ``read_csv`` over raw lines, Parquet from ``read_parquet``, NMEA from the Python
decoder), then :func:`classify_and_commit` applies the rules of :mod:`lanes.clean` as SQL (the
speed-jump kernel runs in numpy on the few tracks with a candidate jump) and writes everything
in **one transaction**: a crash leaves the workspace as before the file. Readers in the same
process use their own cursor (``ws.con.cursor()``) and see the state before or after a file,
never half of it (DuckDB MVCC); other processes wait for the writer's file lock
(:func:`open_for_reading`).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import duckdb
import numpy as np
import pandas as pd

from lanes import clean as C
from thresholds.units import EARTH_RADIUS_NMI
from lanes.io.csv_formats import NAV_STATUS_WORDS, NULL_WORDS, SHIP_TYPE_WORDS, CsvSpec, split_csv_line

COMPONENT = "ais"

MIGRATIONS = [
    [
        "CREATE SEQUENCE ais_file_id_seq START 1",
        """CREATE TABLE ais_files (
            file_id       INTEGER PRIMARY KEY,
            fingerprint   VARCHAR NOT NULL UNIQUE,
            path          VARCHAR NOT NULL,
            format        VARCHAR NOT NULL,
            size_bytes    BIGINT NOT NULL,
            n_read        BIGINT NOT NULL,
            n_loaded      BIGINT NOT NULL,
            n_quarantined BIGINT NOT NULL,
            n_duplicates  BIGINT NOT NULL,
            n_static      BIGINT NOT NULL,
            n_ignored     BIGINT NOT NULL,
            reasons       VARCHAR NOT NULL,
            max_speed_kn  DOUBLE NOT NULL,
            loaded_at     TIMESTAMPTZ NOT NULL DEFAULT now()
        )""",
        """CREATE TABLE ais_positions (
            mmsi        BIGINT NOT NULL,
            time_utc    TIMESTAMPTZ NOT NULL,
            lat_deg     DOUBLE NOT NULL,
            lon_deg     DOUBLE NOT NULL,
            sog_kn      DOUBLE,
            cog_deg     DOUBLE,
            heading_deg DOUBLE,
            nav_status  DOUBLE,
            file_id     INTEGER NOT NULL,
            source_line BIGINT NOT NULL
        )""",
        """CREATE TABLE vessels (
            mmsi        BIGINT PRIMARY KEY,
            imo         BIGINT,
            name        VARCHAR,
            callsign    VARCHAR,
            ship_type   INTEGER,
            length_m    DOUBLE,
            beam_m      DOUBLE,
            draught_m   DOUBLE,
            destination VARCHAR,
            updated_utc TIMESTAMPTZ,
            file_id     INTEGER NOT NULL
        )""",
        """CREATE TABLE ais_quarantine (
            file_id  INTEGER NOT NULL,
            line     BIGINT NOT NULL,
            reason   VARCHAR NOT NULL,
            raw      VARCHAR,
            mmsi     BIGINT,
            time_utc TIMESTAMPTZ
        )""",
    ],
]

_NUM_FIELDS = ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg")
_FLOAT_COLS = ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status", "length_m", "beam_m", "draught_m")
_TOL = C.SENTINEL_TOL


def _q(name: str) -> str:
    """Quote an identifier this module generated itself."""
    return '"' + name.replace('"', '""') + '"'


def _prepare(con: duckdb.DuckDBPyConnection) -> None:
    """Session settings and helpers of the ingest SQL (idempotent per connection)."""
    con.execute("SET TimeZone = 'UTC'")
    con.execute(
        "CREATE OR REPLACE TEMP MACRO ais_num(x) AS "
        "CASE WHEN contains(x, '_') THEN NULL ELSE nullif(TRY_CAST(x AS DOUBLE), 'nan'::DOUBLE) END"
    )
    try:
        con.create_function("ais_csv_split", split_csv_line, ["VARCHAR"], "VARCHAR[]", side_effects=False)
    except (duckdb.CatalogException, duckdb.NotImplementedException, RuntimeError):
        pass  # already registered on this connection


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------
def file_record(ws, fingerprint: str) -> dict | None:
    """The ``ais_files`` row of an already loaded file content, or None."""
    cur = ws.con.execute(
        "SELECT file_id, path, format, n_read, n_loaded, n_quarantined, n_duplicates, n_static, n_ignored, reasons "
        "FROM ais_files WHERE fingerprint = ?",
        [fingerprint],
    )
    row = cur.fetchone()
    if row is None:
        return None
    keys = ["file_id", "path", "format", "read", "loaded", "quarantined", "duplicates", "static", "ignored", "reasons"]
    rec = dict(zip(keys, row))
    rec["reasons"] = json.loads(rec["reasons"])
    return rec


def read_files(ws) -> pd.DataFrame:
    """All loaded files with their counts, oldest first."""
    return ws.con.execute("SELECT * FROM ais_files ORDER BY file_id").fetchdf()


# ---------------------------------------------------------------------------------------------
# Staging
# ---------------------------------------------------------------------------------------------
def _lines_table(ws, path: Path, gz: bool) -> bool:
    """Fill ``ais_lines`` with the file's physical lines in order (``rowid`` = line - 1).

    DuckDB's CSV scanner reads the lines in parallel; files it refuses (stray ``\\r``, invalid
    UTF-8, control characters) are split by Python with the same rules instead. Returns True when
    the Python fallback was used.
    """
    con = ws.con
    try:
        con.execute(
            "CREATE OR REPLACE TEMP TABLE ais_lines AS SELECT line AS raw FROM read_csv(?, columns={'line': 'VARCHAR'}, "
            "header=false, delim=?, quote='', escape='', auto_detect=false, compression=?, max_line_size=?)",
            [str(path), "\x01", "gzip" if gz else "none", 1 << 24],
        )
        return False
    except duckdb.Error:
        from lanes.io.csv_formats import read_lines
        import pyarrow as pa

        lines = read_lines(path)
        tbl = pa.table({"raw": pa.array([x if x != "" else None for x in lines], type=pa.string())})
        con.register("ais_lines_py", tbl)
        try:
            con.execute("CREATE OR REPLACE TEMP TABLE ais_lines AS SELECT raw FROM ais_lines_py")
        finally:
            con.unregister("ais_lines_py")
        return True


def header_line(ws) -> str | None:
    row = ws.con.execute("SELECT raw FROM ais_lines WHERE rowid = 0").fetchone()
    return row[0] if row else None


def stage_csv(ws, path: Path, gz: bool, spec: CsvSpec, index: dict[str, int], n_fields: int) -> dict:
    """Type a DMA/NOAA CSV file into ``ais_stage`` (rules in :mod:`lanes.io.csv_formats`).

    ``index`` maps stage fields to 0-based columns of the header (``n_fields`` columns).
    Returns ``{"ignored": empty lines, "python_fallback": bool}``.
    """
    _prepare(ws.con)
    fallback = _lines_table(ws, path, gz)
    con = ws.con

    def txt(fld):
        if fld not in index:
            return "CAST(NULL AS VARCHAR)"
        return f"CASE WHEN nf_ok THEN trim(f[{index[fld] + 1}], ' \t') END"

    words_nav = (list(NAV_STATUS_WORDS), list(NAV_STATUS_WORDS.values()))
    words_ship = (list(SHIP_TYPE_WORDS), list(SHIP_TYPE_WORDS.values()))
    perr_cases = " ".join(
        f"WHEN t_{fld} <> '' AND n_{fld} IS NULL THEN '{code}'"
        for fld, code in (("lat_deg", C.BAD_LAT), ("lon_deg", C.BAD_LON), ("sog_kn", C.BAD_SOG),
                          ("cog_deg", C.BAD_COG), ("heading_deg", C.BAD_HEADING), ("nav_status", C.BAD_NAV_STATUS))
    )
    fields = ["mmsi", "time_utc", *_NUM_FIELDS, "nav_status", "imo", "ship_type", "name", "callsign", "destination",
              "length_m", "beam_m", "draught_m"]
    texts = ",\n".join(f"{txt(fld)} AS t_{fld}" for fld in fields)
    sql = f"""
    CREATE OR REPLACE TEMP TABLE ais_stage AS
    WITH src AS (
        SELECT rowid + 1 AS line, raw,
               CASE WHEN contains(raw, '"') THEN ais_csv_split(raw) ELSE string_split(raw, ',') END AS f
        FROM ais_lines WHERE rowid >= 1 AND raw IS NOT NULL AND raw <> ''
    ), g AS (
        SELECT line, raw, len(f) = {int(n_fields)} AS nf_ok, {texts} FROM src
    ), n AS (
        SELECT *,
            {", ".join(f"ais_num(t_{fld}) AS n_{fld}" for fld in _NUM_FIELDS)},
            coalesce(ais_num(t_nav_status), MAP($nav_k::VARCHAR[], $nav_v::INTEGER[])[lower(t_nav_status)]) AS n_nav_status,
            CASE WHEN upper(t_imo) LIKE 'IMO%' THEN trim(t_imo[4:], ' \t') ELSE t_imo END AS v_imo,
            coalesce(ais_num(t_ship_type), MAP($ship_k::VARCHAR[], $ship_v::INTEGER[])[lower(t_ship_type)]) AS n_ship_type
        FROM g
    )
    SELECT line, raw, '{C.KIND_POSITION}' AS kind,
        CASE WHEN NOT nf_ok THEN '{C.BAD_LINE}' {perr_cases} END AS parse_error,
        CASE WHEN length(t_mmsi) = 9 AND ltrim(t_mmsi, '0123456789') = '' THEN CAST(t_mmsi AS BIGINT) END AS mmsi,
        CAST(try_strptime(t_time_utc, $time_formats::VARCHAR[]) AS TIMESTAMPTZ) AS time_utc,
        {", ".join(f"n_{fld} AS {fld}" for fld in _NUM_FIELDS)},
        CAST(n_nav_status AS DOUBLE) AS nav_status,
        CASE WHEN length(v_imo) BETWEEN 1 AND 9 AND ltrim(v_imo, '0123456789') = '' AND CAST(v_imo AS BIGINT) > 0
             THEN CAST(v_imo AS BIGINT) END AS imo,
        CASE WHEN NOT list_contains($null_words::VARCHAR[], lower(t_name)) THEN t_name END AS name,
        CASE WHEN NOT list_contains($null_words::VARCHAR[], lower(t_callsign)) THEN t_callsign END AS callsign,
        CAST(CASE WHEN n_ship_type BETWEEN 1 AND 99 AND n_ship_type = floor(n_ship_type) THEN n_ship_type END AS INTEGER)
            AS ship_type,
        CASE WHEN ais_num(t_length_m) > 0 THEN ais_num(t_length_m) END AS length_m,
        CASE WHEN ais_num(t_beam_m) > 0 THEN ais_num(t_beam_m) END AS beam_m,
        CASE WHEN ais_num(t_draught_m) > 0 THEN ais_num(t_draught_m) END AS draught_m,
        CASE WHEN NOT list_contains($null_words::VARCHAR[], lower(t_destination)) THEN t_destination END AS destination
    FROM n
    """
    con.execute(sql, {
        "nav_k": words_nav[0], "nav_v": words_nav[1], "ship_k": words_ship[0], "ship_v": words_ship[1],
        "time_formats": list(spec.time_formats), "null_words": list(NULL_WORDS),
    })
    ignored = con.execute("SELECT count(*) FROM ais_lines WHERE rowid >= 1 AND (raw IS NULL OR raw = '')").fetchone()[0]
    return {"ignored": int(ignored), "python_fallback": fallback}


def parquet_columns(ws, path: Path) -> list[tuple[str, str]]:
    """(name, DuckDB type) of the columns of a Parquet file."""
    return [(r[0], r[1]) for r in ws.con.execute("DESCRIBE SELECT * FROM read_parquet(?)", [str(path)]).fetchall()]


def stage_parquet(ws, path: Path, mapping: dict[str, str]) -> dict:
    """Type a Parquet file into ``ais_stage``. ``mapping``: stage field -> source column.

    Numbers are cast with ``TRY_CAST``; a value that does not cast is a parse error of its
    field. Timestamps without a time zone are taken as UTC. ``raw`` is the row's source values
    joined by commas; ``line`` is the 1-based row number.
    """
    _prepare(ws.con)
    con = ws.con
    cols = dict(parquet_columns(ws, path))

    def src(fld):
        return _q(mapping[fld]) if fld in mapping else "NULL"

    def num(fld):
        if fld not in mapping:
            return "CAST(NULL AS DOUBLE)"
        return f"nullif(TRY_CAST({src(fld)} AS DOUBLE), 'nan'::DOUBLE)"

    tcol = mapping.get("time_utc")
    ttype = cols.get(tcol, "")
    if "TIME ZONE" in ttype or ttype.startswith("TIMESTAMP"):
        time_expr = f"CAST({src('time_utc')} AS TIMESTAMPTZ)"
    else:
        time_expr = f"TRY_CAST({src('time_utc')} AS TIMESTAMPTZ)"
    mtype = cols.get(mapping.get("mmsi"), "")
    if any(k in mtype for k in ("INT", "DECIMAL", "DOUBLE", "FLOAT")):
        mmsi_expr = f"CASE WHEN {src('mmsi')} = floor({src('mmsi')}) THEN CAST({src('mmsi')} AS BIGINT) END"
    else:
        mmsi_expr = (f"CASE WHEN length(trim(CAST({src('mmsi')} AS VARCHAR))) = 9 AND "
                     f"ltrim(trim(CAST({src('mmsi')} AS VARCHAR)), '0123456789') = '' "
                     f"THEN CAST(trim(CAST({src('mmsi')} AS VARCHAR)) AS BIGINT) END")
    perr = " ".join(
        f"WHEN {src(fld)} IS NOT NULL AND {num(fld)} IS NULL THEN '{code}'"
        for fld, code in (("lat_deg", C.BAD_LAT), ("lon_deg", C.BAD_LON), ("sog_kn", C.BAD_SOG),
                          ("cog_deg", C.BAD_COG), ("heading_deg", C.BAD_HEADING), ("nav_status", C.BAD_NAV_STATUS))
        if fld in mapping
    )
    raw = "concat_ws(',', " + ", ".join(f"coalesce(CAST({_q(c)} AS VARCHAR), '')" for c in cols) + ")"

    def pos_num(fld):
        return f"CASE WHEN {num(fld)} > 0 THEN {num(fld)} END" if fld in mapping else "CAST(NULL AS DOUBLE)"

    def text(fld):
        if fld not in mapping:
            return "CAST(NULL AS VARCHAR)"
        t = f"trim(CAST({src(fld)} AS VARCHAR), ' \t')"
        return f"CASE WHEN NOT list_contains($null_words::VARCHAR[], lower({t})) THEN {t} END"

    imo = "CAST(NULL AS BIGINT)"
    if "imo" in mapping:
        v = f"regexp_replace(trim(CAST({src('imo')} AS VARCHAR), ' \t'), '^[Ii][Mm][Oo]', '')"
        imo = (f"CASE WHEN length({v}) BETWEEN 1 AND 9 AND ltrim({v}, '0123456789') = '' AND CAST({v} AS BIGINT) > 0 "
               f"THEN CAST({v} AS BIGINT) END")
    ship = "CAST(NULL AS INTEGER)"
    if "ship_type" in mapping:
        ship = (f"CAST(CASE WHEN {num('ship_type')} BETWEEN 1 AND 99 AND {num('ship_type')} = floor({num('ship_type')}) "
                f"THEN {num('ship_type')} END AS INTEGER)")
    sql = f"""
    CREATE OR REPLACE TEMP TABLE ais_stage AS
    SELECT file_row_number + 1 AS line, {raw} AS raw, '{C.KIND_POSITION}' AS kind,
        CASE {perr or "WHEN false THEN NULL"} END AS parse_error,
        {mmsi_expr} AS mmsi,
        {time_expr} AS time_utc,
        {", ".join(f"{num(fld)} AS {fld}" for fld in (*_NUM_FIELDS, "nav_status"))},
        {imo} AS imo, {text('name')} AS name, {text('callsign')} AS callsign, {ship} AS ship_type,
        {pos_num('length_m')} AS length_m, {pos_num('beam_m')} AS beam_m, {pos_num('draught_m')} AS draught_m,
        {text('destination')} AS destination
    FROM read_parquet($path, file_row_number = true)
    """
    params = {"path": str(path)}
    if "$null_words" in sql:
        params["null_words"] = list(NULL_WORDS)
    con.execute(sql, params)
    return {"ignored": 0, "python_fallback": False}


def stage_frame(ws, stage: pd.DataFrame) -> dict:
    """Put a typed stage built in Python (NMEA, or any reader) into ``ais_stage``."""
    _prepare(ws.con)
    st = C.conform_stage(stage)
    df = st.copy()
    for col in ("mmsi", "imo", "ship_type"):
        df[col] = df[col].astype("float64")  # NA -> NaN -> NULL on the DuckDB side
    ws.con.register("ais_stage_df", df)
    try:
        ws.con.execute(
            """CREATE OR REPLACE TEMP TABLE ais_stage AS SELECT
                CAST(line AS BIGINT) AS line, CAST(raw AS VARCHAR) AS raw, CAST(kind AS VARCHAR) AS kind,
                CAST(parse_error AS VARCHAR) AS parse_error, CAST(mmsi AS BIGINT) AS mmsi,
                CAST(time_utc AS TIMESTAMPTZ) AS time_utc,
                lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, nav_status,
                CAST(imo AS BIGINT) AS imo, CAST(name AS VARCHAR) AS name, CAST(callsign AS VARCHAR) AS callsign,
                CAST(ship_type AS INTEGER) AS ship_type, length_m, beam_m, draught_m,
                CAST(destination AS VARCHAR) AS destination
            FROM ais_stage_df"""
        )
    finally:
        ws.con.unregister("ais_stage_df")
    return {"ignored": 0, "python_fallback": False}


def read_stage(ws) -> pd.DataFrame:
    """The current typed stage as a DataFrame (for tests comparing the SQL and pandas typing)."""
    df = ws.con.execute("SELECT * FROM ais_stage ORDER BY line").fetchdf()
    return C.conform_stage(df)


# ---------------------------------------------------------------------------------------------
# Cleaning (rules of lanes.clean, as SQL) and the one-transaction commit
# ---------------------------------------------------------------------------------------------
def _classify_sql() -> str:
    rec = ", ".join(f"'{c}'" for c in C.RECORD_CODES)
    return f"""
    CREATE OR REPLACE TEMP TABLE ais_cls AS
    SELECT line, raw, mmsi, time_utc, lat_deg,
        CASE WHEN abs(lon_deg - 180.0) <= {_TOL} THEN -180.0 ELSE lon_deg END AS lon_deg,
        CASE WHEN sog_kn >= {C.SOG_NA_MIN_KN - _TOL} AND sog_kn <= {C.SOG_NA_KN + _TOL} THEN NULL ELSE sog_kn END AS sog_kn,
        CASE WHEN abs(cog_deg - {C.COG_NA_DEG}) <= {_TOL} THEN NULL ELSE cog_deg END AS cog_deg,
        CASE WHEN abs(heading_deg - {C.HEADING_NA_DEG}) <= {_TOL} THEN NULL ELSE heading_deg END AS heading_deg,
        nav_status,
        CASE
            WHEN parse_error IN ({rec}) THEN parse_error
            WHEN mmsi IS NULL OR mmsi < {C.MMSI_MIN} OR mmsi > {C.MMSI_MAX} THEN '{C.BAD_MMSI}'
            WHEN time_utc IS NULL OR time_utc < $tmin OR time_utc >= $tmax THEN '{C.BAD_TIME}'
            WHEN parse_error IS NOT NULL THEN parse_error
            WHEN lat_deg IS NULL OR lon_deg IS NULL OR abs(lat_deg - {C.LAT_NA_DEG}) <= {_TOL}
                 OR abs(lon_deg - {C.LON_NA_DEG}) <= {_TOL} THEN '{C.NO_POSITION}'
            WHEN lat_deg < -90.0 OR lat_deg > 90.0 THEN '{C.BAD_LAT}'
            WHEN lon_deg < -180.0 OR lon_deg > 180.0 THEN '{C.BAD_LON}'
            WHEN sog_kn < 0.0 OR sog_kn > {C.SOG_NA_KN + _TOL} THEN '{C.BAD_SOG}'
            WHEN cog_deg < 0.0 OR cog_deg > {C.COG_NA_DEG + _TOL} THEN '{C.BAD_COG}'
            WHEN (heading_deg < 0.0 OR heading_deg >= 360.0) AND abs(heading_deg - {C.HEADING_NA_DEG}) > {_TOL}
                 THEN '{C.BAD_HEADING}'
            WHEN nav_status < 0 OR nav_status > {C.NAV_STATUS_MAX} OR nav_status <> floor(nav_status)
                 THEN '{C.BAD_NAV_STATUS}'
        END AS reason
    FROM ais_stage WHERE kind <> '{C.KIND_STATIC}'
    """


_VALUES = ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status")


def _dedupe_sql() -> str:
    same = " AND ".join(
        f"(CASE WHEN in_db THEN p_{v} ELSE f_{v} END) IS NOT DISTINCT FROM {v}" for v in _VALUES
    )
    firsts = ", ".join(f"first_value(o.{v}) OVER w AS f_{v}" for v in _VALUES)
    pvals = ", ".join(f"p.{v} AS p_{v}" for v in _VALUES)
    return f"""
    CREATE OR REPLACE TEMP TABLE ais_dup AS
    WITH rng AS (SELECT min(time_utc) AS t0, max(time_utc) AS t1 FROM ais_ok),
    old AS (
        SELECT p.mmsi, p.time_utc, {", ".join(f"p.{v}" for v in _VALUES)}
        FROM ais_positions p, rng WHERE p.time_utc BETWEEN rng.t0 AND rng.t1
    ),
    keys AS (
        SELECT mmsi, time_utc FROM ais_ok GROUP BY mmsi, time_utc HAVING count(*) > 1
        UNION
        SELECT o.mmsi, o.time_utc FROM ais_ok o SEMI JOIN old USING (mmsi, time_utc)
    ),
    cand AS (
        SELECT o.*, p.mmsi IS NOT NULL AS in_db, {pvals},
               first_value(o.line) OVER w AS first_line, {firsts}
        FROM ais_ok o SEMI JOIN keys USING (mmsi, time_utc)
        LEFT JOIN old p USING (mmsi, time_utc)
        WINDOW w AS (PARTITION BY o.mmsi, o.time_utc ORDER BY o.line)
    )
    SELECT line, CASE WHEN {same} THEN '{C.DUPLICATE}' ELSE '{C.DUPLICATE_TIME}' END AS reason
    FROM cand WHERE in_db OR line <> first_line
    """


def _jump_candidates_sql() -> str:
    # A superset of the tracks the numpy kernel must look at: any consecutive pair implying more
    # than 0.999 x the limit (the margin absorbs float differences between SQL and numpy).
    r = float(EARTH_RADIUS_NMI)
    return f"""
    WITH l AS (
        SELECT mmsi, time_utc, lat_deg, lon_deg,
            lag(time_utc) OVER w AS t0, lag(lat_deg) OVER w AS lat0, lag(lon_deg) OVER w AS lon0
        FROM ais_track WINDOW w AS (PARTITION BY mmsi ORDER BY time_utc)
    )
    SELECT DISTINCT mmsi FROM l
    WHERE t0 IS NOT NULL AND
        2.0 * {r} * asin(sqrt(least(1.0,
            pow(sin(radians(lat_deg - lat0) / 2.0), 2)
            + cos(radians(lat0)) * cos(radians(lat_deg)) * pow(sin(radians(lon_deg - lon0) / 2.0), 2))))
        > 0.999 * $vmax * (epoch_us(time_utc) - epoch_us(t0)) / 3.6e9
    """


_CONTEXT_SQL = """
CREATE OR REPLACE TEMP TABLE ais_track AS
WITH span AS (SELECT mmsi, min(time_utc) AS t0, max(time_utc) AS t1 FROM ais_keep GROUP BY mmsi),
ex AS (SELECT p.mmsi, p.time_utc, p.lat_deg, p.lon_deg, s.t0, s.t1 FROM ais_positions p JOIN span s USING (mmsi))
SELECT line, mmsi, time_utc, lat_deg, lon_deg FROM ais_keep
UNION ALL
SELECT -1, mmsi, time_utc, lat_deg, lon_deg FROM ex WHERE time_utc BETWEEN t0 AND t1
UNION ALL
SELECT -1, mmsi, max(time_utc), arg_max(lat_deg, time_utc), arg_max(lon_deg, time_utc) FROM ex
WHERE time_utc < t0 GROUP BY mmsi
UNION ALL
SELECT -1, mmsi, min(time_utc), arg_min(lat_deg, time_utc), arg_min(lon_deg, time_utc) FROM ex
WHERE time_utc > t1 GROUP BY mmsi
"""


def classify_and_commit(ws, meta: dict, max_speed_kn: float = C.DEFAULT_MAX_SPEED_KN, before_commit=None) -> dict:
    """Clean ``ais_stage`` and write positions, quarantine, vessels and the file row in ONE
    transaction. ``meta``: ``fingerprint``, ``path``, ``format``, ``size_bytes``, ``ignored``.

    Returns the file's counts: ``read``, ``loaded``, ``quarantined``, ``duplicates``,
    ``static``, ``ignored``, ``reasons``, ``file_id``. ``before_commit`` (tests only) is called
    inside the transaction just before the commit (to kill the process there, or to look at
    the workspace from another cursor).
    """
    con = ws.con
    _prepare(con)
    params_t = {"tmin": C.TIME_MIN_UTC.to_pydatetime(), "tmax": C.TIME_MAX_UTC.to_pydatetime()}
    with ws.transaction():
        if file_record(ws, meta["fingerprint"]) is not None:
            raise RuntimeError(f"{meta['path']}: loaded concurrently by another ingest")
        file_id = int(con.execute("SELECT nextval('ais_file_id_seq')").fetchone()[0])
        con.execute(_classify_sql(), params_t)
        con.execute(
            "CREATE OR REPLACE TEMP TABLE ais_ok AS SELECT line, mmsi, time_utc, "
            + ", ".join(_VALUES) + " FROM ais_cls WHERE reason IS NULL"
        )
        con.execute(_dedupe_sql())
        con.execute("CREATE OR REPLACE TEMP TABLE ais_keep AS SELECT * FROM ais_ok ANTI JOIN ais_dup USING (line)")
        # Stored fixes around this file's tracks are context (never flagged) for the jump rule.
        con.execute(_CONTEXT_SQL)
        cand = con.execute(_jump_candidates_sql(), {"vmax": float(max_speed_kn)}).fetchnumpy()["mmsi"]
        jumped = np.empty(0, dtype=np.int64)
        if len(cand):
            con.register("ais_cand_df", pd.DataFrame({"mmsi": np.asarray(cand, dtype=np.int64)}))
            try:
                tr = con.execute(
                    "SELECT line, mmsi, epoch_us(time_utc) AS t_us, lat_deg, lon_deg FROM ais_track "
                    "SEMI JOIN ais_cand_df USING (mmsi) ORDER BY mmsi, time_utc"
                ).fetchnumpy()
            finally:
                con.unregister("ais_cand_df")
            t_s = (np.asarray(tr["t_us"], dtype=np.int64) * 1000) / 1e9
            lines = np.asarray(tr["line"], dtype=np.int64)
            mask = C.speed_jump_mask(np.asarray(tr["mmsi"]), t_s, np.asarray(tr["lat_deg"]),
                                     np.asarray(tr["lon_deg"]), max_speed_kn, fixed=lines < 0)
            jumped = lines[mask]
        con.register("ais_jump_df", pd.DataFrame({"line": jumped}))
        try:
            con.execute("CREATE OR REPLACE TEMP TABLE ais_jump AS SELECT CAST(line AS BIGINT) AS line FROM ais_jump_df")
        finally:
            con.unregister("ais_jump_df")

        loaded = con.execute(
            "INSERT INTO ais_positions SELECT mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, "
            "nav_status, ?, line FROM ais_keep ANTI JOIN ais_jump USING (line)",
            [file_id],
        ).fetchone()[0]
        con.execute(
            f"""INSERT INTO ais_quarantine
            SELECT ?, c.line, coalesce(c.reason, d.reason, '{C.SPEED_JUMP}'), c.raw, c.mmsi, c.time_utc
            FROM ais_cls c LEFT JOIN ais_dup d USING (line) LEFT JOIN ais_jump j USING (line)
            WHERE c.reason IS NOT NULL OR d.line IS NOT NULL OR j.line IS NOT NULL""",
            [file_id],
        )
        reasons = dict(con.execute(
            "SELECT reason, count(*) FROM ais_quarantine WHERE file_id = ? GROUP BY reason ORDER BY reason", [file_id]
        ).fetchall())
        read = int(con.execute("SELECT count(*) FROM ais_cls").fetchone()[0])
        static = int(con.execute(f"SELECT count(*) FROM ais_stage WHERE kind = '{C.KIND_STATIC}'").fetchone()[0])
        _upsert_vessels(con, file_id)
        dups = int(sum(v for k, v in reasons.items() if k in C.DUPLICATE_CODES))
        counts = {
            "file_id": file_id,
            "read": read,
            "loaded": int(loaded),
            "quarantined": int(sum(reasons.values())) - dups,
            "duplicates": dups,
            "static": static,
            "ignored": int(meta.get("ignored", 0)),
            "reasons": {str(k): int(v) for k, v in reasons.items()},
        }
        if counts["read"] != counts["loaded"] + counts["quarantined"] + counts["duplicates"]:
            raise AssertionError(f"{meta['path']}: counts do not add up: {counts}")
        con.execute(
            """INSERT INTO ais_files (file_id, fingerprint, path, format, size_bytes, n_read, n_loaded, n_quarantined,
                   n_duplicates, n_static, n_ignored, reasons, max_speed_kn)
               VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)""",
            [file_id, meta["fingerprint"], str(meta["path"]), meta["format"], int(meta["size_bytes"]), read,
             counts["loaded"], counts["quarantined"], dups, static, counts["ignored"],
             json.dumps(counts["reasons"], sort_keys=True), float(max_speed_kn)],
        )
        if before_commit is not None:
            before_commit()
    _drop_temp(con)
    return counts


def _upsert_vessels(con, file_id: int) -> None:
    """Latest non-missing static value per MMSI of this file, merged into ``vessels``."""
    key = "{'t': coalesce(time_utc, TIMESTAMPTZ '1677-09-22 00:00:00+00'), 'l': line}"
    aggs = ",\n".join(
        f"arg_max({c}, {key}) FILTER (WHERE {c} IS NOT NULL) AS {c}" for c in C.STATIC_COLUMNS
    )
    any_set = " OR ".join(f"{c} IS NOT NULL" for c in C.STATIC_COLUMNS)
    merge = ",\n".join(
        f"{c} = CASE WHEN vessels.updated_utc IS NULL OR EXCLUDED.updated_utc >= vessels.updated_utc "
        f"THEN coalesce(EXCLUDED.{c}, vessels.{c}) ELSE coalesce(vessels.{c}, EXCLUDED.{c}) END"
        for c in C.STATIC_COLUMNS
    )
    con.execute(
        f"""INSERT INTO vessels
        SELECT mmsi, {", ".join(C.STATIC_COLUMNS)}, updated_utc, ? AS file_id FROM (
            SELECT mmsi, max(time_utc) AS updated_utc, {aggs}
            FROM ais_stage WHERE mmsi BETWEEN {C.MMSI_MIN} AND {C.MMSI_MAX} GROUP BY mmsi
        ) WHERE {any_set}
        ON CONFLICT (mmsi) DO UPDATE SET {merge},
            updated_utc = greatest(vessels.updated_utc, EXCLUDED.updated_utc),
            file_id = EXCLUDED.file_id""",
        [file_id],
    )


def _drop_temp(con) -> None:
    for t in ("ais_lines", "ais_stage", "ais_cls", "ais_ok", "ais_dup", "ais_keep", "ais_track", "ais_jump"):
        con.execute(f"DROP TABLE IF EXISTS temp.{_q(t)}")


def discard_stage(ws) -> None:
    """Drop the temporary staging tables (after an error)."""
    _drop_temp(ws.con)


# ---------------------------------------------------------------------------------------------
# Readers
# ---------------------------------------------------------------------------------------------
def _utc(df: pd.DataFrame, cols=("time_utc",)) -> pd.DataFrame:
    for c in cols:
        if c in df.columns:
            df[c] = pd.to_datetime(df[c], utc=True).astype("datetime64[ns, UTC]")
    return df


def read_positions(ws, mmsi=None, start=None, end=None) -> pd.DataFrame:
    """Canonical positions sorted by ``mmsi``, ``time_utc``.

    Parameters
    ----------
    mmsi : int or list of int, optional
        Only these vessels.
    start, end : datetime-like, optional
        Only ``start <= time_utc < end`` (naive values are taken as UTC).
    """
    where, params = [], []
    if mmsi is not None:
        ids = [int(m) for m in (mmsi if np.ndim(mmsi) else [mmsi])]
        where.append("list_contains(?, mmsi)")
        params.append(ids)
    for bound, op in ((start, ">="), (end, "<")):
        if bound is not None:
            ts = pd.Timestamp(bound)
            ts = ts.tz_localize("UTC") if ts.tzinfo is None else ts.tz_convert("UTC")
            where.append(f"time_utc {op} ?")
            params.append(ts.to_pydatetime())
    sql = ("SELECT mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, nav_status "
           "FROM ais_positions")
    if where:
        sql += " WHERE " + " AND ".join(where)
    sql += " ORDER BY mmsi, time_utc"
    df = ws.con.execute(sql, params).fetchdf()
    df["mmsi"] = df["mmsi"].astype("int64")
    for c in C.POSITION_COLUMNS[2:]:
        df[c] = df[c].astype("float64")
    return _utc(df)


def read_vessels(ws) -> pd.DataFrame:
    """Static vessel data, one row per MMSI, sorted by MMSI."""
    df = ws.con.execute(
        "SELECT mmsi, imo, name, callsign, ship_type, length_m, beam_m, draught_m, destination, updated_utc "
        "FROM vessels ORDER BY mmsi"
    ).fetchdf()
    return _utc(df, ("updated_utc",))


def read_quarantine(ws, file_id: int | None = None) -> pd.DataFrame:
    """Quarantined rows with the file they came from, in file and line order."""
    sql = ("SELECT q.file_id, f.path, q.line, q.reason, q.raw, q.mmsi, q.time_utc FROM ais_quarantine q "
           "JOIN ais_files f USING (file_id)")
    params = []
    if file_id is not None:
        sql += " WHERE q.file_id = ?"
        params.append(int(file_id))
    sql += " ORDER BY q.file_id, q.line"
    return _utc(ws.con.execute(sql, params).fetchdf())


def open_for_reading(path, wait_s: float = 60.0, poll_s: float = 0.2):
    """Open a workspace read-only from another process, waiting while a writer holds the lock.

    DuckDB allows one writing process per database file; a reader in another process cannot
    open it until the writer closes it. Since each file is committed atomically, the reader
    then sees the state after the writer's last committed file, never a half-loaded file.
    """
    from pipelines.storage import Workspace

    deadline = time.monotonic() + wait_s
    while True:
        try:
            ws = Workspace(path, read_only=True)
            ws.con.execute("SET TimeZone = 'UTC'")
            return ws
        except duckdb.IOException:
            if time.monotonic() >= deadline:
                raise
            time.sleep(poll_s)
