"""SQL helpers shared by the AIS staging and commit: session setup, bound parameters, the rule 1-6
reason expression, normalised values, the stage table and its kind, temporary tables."""

from __future__ import annotations

import json

import duckdb
import pandas as pd

from ais import clean as C
from ais.io.csv_formats import NAV_STATUS_WORDS, NULL_WORDS, SHIP_TYPE_WORDS, WS, split_csv_line


_NUM_FIELDS = ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg")
_TOL = C.SENTINEL_TOL
_TEXT_STATIC = tuple("s_" + c for c in C.STATIC_COLUMNS)
#: The range of pandas nanosecond timestamps, whole seconds (the pure path reads times outside
#: it as missing; the typed scanner would read them).
_PD_TMIN = pd.Timestamp.min.ceil("s").to_pydatetime()
_PD_TMAX = pd.Timestamp.max.floor("s").to_pydatetime()


def _q(name: str) -> str:
    """Quote an identifier this module generated itself."""
    return '"' + name.replace('"', '""') + '"'


def parquet_as_stored(con: duckdb.DuckDBPyConnection) -> None:
    """Read a GeoParquet file's WKB column as the bytes it stores. DuckDB 1.5 reads it as its
    ``GEOMETRY`` type by default: one value that is no valid WKB then failed the whole file's
    read ("Unexpected end of binary data"), and the quarantined rows' text could not be built
    (``octet_length`` takes no ``GEOMETRY``). The stage decodes the points itself
    (:func:`ais.io.parquet.wkb_point_xy`; a value that is no point is a bad position)."""
    con.execute("SET enable_geoparquet_conversion = false")


def _prepare(con: duckdb.DuckDBPyConnection) -> None:
    """Session settings and helpers of the ingest SQL (idempotent per connection)."""
    con.execute("SET TimeZone = 'UTC'")
    # DuckDB's own progress bar would print to stdout (and break --json); ours is on stderr.
    con.execute("SET enable_progress_bar = false")
    parquet_as_stored(con)
    con.execute("CREATE OR REPLACE TEMP MACRO ais_num(x) AS nullif(TRY_CAST(x AS DOUBLE), 'nan'::DOUBLE)")
    # A parsed time outside pandas' nanosecond range is no time (as in the pure path).
    con.execute(f"CREATE OR REPLACE TEMP MACRO ais_time(t) AS CASE WHEN t BETWEEN TIMESTAMP '{_PD_TMIN}' "
                f"AND TIMESTAMP '{_PD_TMAX}' THEN t END")
    try:
        con.create_function("ais_csv_split", split_csv_line, ["VARCHAR"], "VARCHAR[]", side_effects=False)
    except (duckdb.CatalogException, duckdb.NotImplementedException, RuntimeError):
        pass  # already registered on this connection


def _params() -> dict:
    """Named parameters shared by the staging and cleaning SQL (constants of ais.clean and
    ais.io.csv_formats, always bound, never formatted into the SQL)."""
    return {
        "ws": WS,
        "null_words": list(NULL_WORDS),
        "nav_k": list(NAV_STATUS_WORDS),
        "nav_v": list(NAV_STATUS_WORDS.values()),
        "ship_k": list(SHIP_TYPE_WORDS),
        "ship_v": list(SHIP_TYPE_WORDS.values()),
        "tmin": C.TIME_MIN_UTC.tz_convert(None).to_pydatetime(),
        "tmax": C.TIME_MAX_UTC.tz_convert(None).to_pydatetime(),
    }


def _used(sql: str, params: dict) -> dict:
    """Only the named parameters a statement refers to (DuckDB refuses unused ones)."""
    return {k: v for k, v in params.items() if f"${k}" in sql}


# ---------------------------------------------------------------------------------------------
# Staging: every reader fills ``ais_stage`` (typed values + the rule 1-6 reason ``reason0``)
# ---------------------------------------------------------------------------------------------
def _reason_case() -> str:
    """Rules 1-6 of ais.clean as one CASE over the typed columns (first match wins).

    The common case (a clean row) is tested first as one conjunction, which DuckDB evaluates
    much faster than walking the WHEN branches for every row."""
    # Equalities, not an IN list: DuckDB plans a long IN list as a hash (mark) join, which does
    # not keep the scan's row order - and the CSV stages number their rows by that order.
    rec = " OR ".join(f"parse_error = '{c}'" for c in C.RECORD_CODES)
    clean_row = f"""kind = '{C.KIND_POSITION}' AND parse_error IS NULL
        AND mmsi >= {C.MMSI_MIN} AND mmsi <= {C.MMSI_MAX} AND time_utc >= $tmin AND time_utc < $tmax
        AND lat_deg >= -90.0 AND lat_deg <= 90.0 AND lon_deg >= -180.0 AND lon_deg <= 180.0
        AND coalesce(sog_kn >= 0.0 AND sog_kn <= {C.SOG_NA_KN + _TOL}, true)
        AND coalesce(cog_deg >= 0.0 AND cog_deg <= {C.COG_NA_DEG + _TOL}, true)
        AND coalesce((heading_deg >= 0.0 AND heading_deg < 360.0) OR abs(heading_deg - {C.HEADING_NA_DEG}) <= {_TOL}, true)
        AND coalesce(nav_status >= 0 AND nav_status <= {C.NAV_STATUS_MAX} AND nav_status = floor(nav_status), true)"""
    return f"""CASE
        WHEN {clean_row} THEN NULL
        WHEN kind <> '{C.KIND_POSITION}' THEN NULL
        WHEN {rec} THEN parse_error
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
    END"""


# Time stamps: the stage holds TIMESTAMP (UTC); the tables TIMESTAMPTZ. Both are microseconds
# since the epoch, so make_timestamp(tz)(epoch_us(..)) converts exactly and far cheaper than
# CAST, which goes through ICU's calendar for every value.

# Normalised values (rule 6: sentinels of the motion fields to NULL, lon 180 -> -180).
_NORM = {
    "lat_deg": "lat_deg",
    "lon_deg": f"CASE WHEN abs(lon_deg - 180.0) <= {_TOL} THEN -180.0 ELSE lon_deg END",
    "sog_kn": f"CASE WHEN sog_kn >= {C.SOG_NA_MIN_KN - _TOL} AND sog_kn <= {C.SOG_NA_KN + _TOL} THEN NULL ELSE sog_kn END",
    "cog_deg": f"CASE WHEN abs(cog_deg - {C.COG_NA_DEG}) <= {_TOL} THEN NULL ELSE cog_deg END",
    "heading_deg": f"CASE WHEN abs(heading_deg - {C.HEADING_NA_DEG}) <= {_TOL} THEN NULL ELSE heading_deg END",
    "nav_status": "nav_status",
}
_VALUES = tuple(_NORM)


def _norm(alias: str = "") -> str:
    pre = f"{alias}." if alias else ""
    out = []
    for col, expr in _NORM.items():
        e = expr
        for c in _NORM:
            e = e.replace(c, pre + c) if pre else e
        out.append(f"{e} AS {col}")
    return ", ".join(out)


def _create_stage(con, typed_sql: str, extra_params: dict | None = None, line_from_rowid: bool = False,
                  table: str = "ais_stage_t") -> None:
    """``ais_stage`` = the reader's typed SELECT plus ``reason0`` (rules 1-6).

    Stored as ``ais_stage_t``; ``ais_stage`` is a view adding ``line`` = rowid + 1 when the
    reader keeps one row per physical line in file order (CSV: insertion order is preserved).
    With another ``table`` only that table is created (the caller builds the view)."""
    sql = (f"CREATE OR REPLACE TEMP TABLE {_q(table)} AS WITH typed AS ({typed_sql}) "
           f"SELECT *, {_reason_case()} AS reason0 FROM typed")
    params = {**_params(), **(extra_params or {})}
    con.execute(sql, _used(sql, params))
    if table == "ais_stage_t":
        line = "rowid + 1 AS line, " if line_from_rowid else ""
        con.execute(f"CREATE OR REPLACE TEMP VIEW ais_stage AS SELECT {line}* FROM ais_stage_t")


#: The delimiter of DuckDB's raw-lines read (one column per line: a byte no AIS text holds).


_STATIC_TYPES = {"imo": "BIGINT", "name": "VARCHAR", "callsign": "VARCHAR", "ship_type": "INTEGER",
                 "length_m": "DOUBLE", "beam_m": "DOUBLE", "draught_m": "DOUBLE", "destination": "VARCHAR"}


def _static_typing(col: str) -> str:
    """SQL typing the static text column ``s_<col>`` (same rules as csv_formats.type_static)."""
    x = f"s_{col}"
    t = f"trim({x}, $ws)"
    if col == "imo":
        v = f"(CASE WHEN upper({t}) LIKE 'IMO%' THEN trim({t}[4:], $ws) ELSE {t} END)"
        return (f"CASE WHEN length({v}) BETWEEN 1 AND 9 AND ltrim({v}, '0123456789') = '' AND CAST({v} AS BIGINT) > 0 "
                f"THEN CAST({v} AS BIGINT) END")
    if col == "ship_type":
        n = f"coalesce(ais_num({x}), MAP($ship_k::VARCHAR[], $ship_v::INTEGER[])[lower({t})])"
        return f"CAST(CASE WHEN {n} BETWEEN 1 AND 99 AND {n} = floor({n}) THEN {n} END AS INTEGER)"
    if col in ("length_m", "beam_m", "draught_m"):
        return f"CASE WHEN ais_num({x}) > 0 THEN ais_num({x}) END"
    return f"CASE WHEN NOT list_contains($null_words::VARCHAR[], lower({t})) THEN {t} END"


def _typed_static_select(available=None) -> str:
    """Typed static columns: the typed column, else the typed text column ``s_<name>``."""
    out = []
    for c in C.STATIC_COLUMNS:
        have_typed = available is None or c in available
        have_text = available is None or f"s_{c}" in available
        if have_typed and have_text:
            out.append(f"coalesce({c}, {_static_typing(c)}) AS {c}")
        elif have_text:
            out.append(f"{_static_typing(c)} AS {c}")
        elif have_typed:
            out.append(f"{c} AS {c}")
        else:
            out.append(f"CAST(NULL AS {_STATIC_TYPES[c]}) AS {c}")
    return ", ".join(out)


#: Which static columns a stage fills: text (CSV, Parquet) or typed (NMEA and other frames).
_STAGE_STATIC_COLUMNS = {"text": _TEXT_STATIC, "typed": tuple(C.STATIC_COLUMNS)}


def _stage_kind(con) -> tuple[str, dict]:
    row = con.execute("SELECT value, extra FROM ais_stage_info WHERE key = 'statics'").fetchone()
    return (row[0], json.loads(row[1])) if row else ("typed", {})


def _set_stage_kind(con, kind: str, extra: dict | None = None) -> None:
    """How the stage holds static data: "text" (``s_*``), "typed" (typed columns) or "csvhash"
    (a hash of the static fields per row; the text is re-split from ``raw`` for the few rows
    that are the latest of their (MMSI, hash) group)."""
    con.execute("CREATE OR REPLACE TEMP TABLE ais_stage_info AS SELECT 'statics' AS key, ? AS value, ? AS extra",
                [kind, json.dumps(extra or {})])


def _line_index(con, meta: dict):
    """The line index of a fast-staged CSV file (from the stage info, else built again)."""
    if meta.get("line_index") is not None:
        return meta["line_index"]
    kind, extra = _stage_kind(con)
    if kind != "csvfast":
        return None
    from ais.io.lineindex import LineIndex

    meta["line_index"] = LineIndex(extra["path"])
    meta["line_index_owned"] = True
    return meta["line_index"]


def _drop_temp(con) -> None:
    con.execute("DROP VIEW IF EXISTS temp.ais_stage_fb")
    con.execute("DROP VIEW IF EXISTS temp.ais_stage")
    for name in ("ais_scan_src", "ais_spot_fast", "ais_fast_pos", "ais_fast_skip", "ais_raw_df", "ais_latest_raw", "ais_lines_df", "ais_spot_rows",
                 "ais_new", "ais_group_rows"):
        try:
            con.unregister(name)
        except Exception:  # noqa: BLE001 - not registered
            pass
    for t in ("ais_stage_t", "ais_dup", "ais_out", "ais_q", "ais_stage_info", "ais_fast", "ais_exact", "ais_spot", "ais_latest", "ais_rejects",
              "ais_reject_scans", "ais_fb", "ais_new"):
        con.execute(f"DROP TABLE IF EXISTS temp.{_q(t)}")
