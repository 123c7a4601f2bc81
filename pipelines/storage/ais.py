"""AIS tables: files, positions, vessels, quarantine - and the SQL of the bulk ingest.

Tables (component ``ais``):

``ais_files``
    one row per loaded file: ``file_id``, ``fingerprint`` (``blake3:<hex>`` of the bytes, unique; ``sha256:<hex>`` for
    files loaded by earlier versions),
    (``ais_file_keys``: ``quick_key`` = size + SHA-256 of the first and last MiB),
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
import logging
import time
from concurrent.futures import Future
from pathlib import Path

import duckdb
import numpy as np
import pandas as pd

from lanes import clean as C
from lanes.io.files import content_has
from lanes.io.csv_formats import MMSI_RE, NAV_STATUS_WORDS, NULL_WORDS, SHIP_TYPE_WORDS, WS, CsvSpec, split_csv_line
from thresholds.units import EARTH_RADIUS_NMI

log = logging.getLogger(__name__)

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
    # v2: a cheap identity (size + first/last MiB) so that new files are staged while their
    # full SHA-256 is still being computed.
    # (A separate table, not ALTER TABLE ais_files: DuckDB 1.5.6 cannot replay that ALTER from
    # its WAL after a crash - "GetDefaultDatabase with no default database set".)
    [
        """CREATE TABLE ais_file_keys (
            file_id   INTEGER PRIMARY KEY,
            quick_key VARCHAR NOT NULL
        )""",
    ],
]

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


def _prepare(con: duckdb.DuckDBPyConnection) -> None:
    """Session settings and helpers of the ingest SQL (idempotent per connection)."""
    con.execute("SET TimeZone = 'UTC'")
    # DuckDB's own progress bar would print to stdout (and break --json); ours is on stderr.
    con.execute("SET enable_progress_bar = false")
    con.execute("CREATE OR REPLACE TEMP MACRO ais_num(x) AS nullif(TRY_CAST(x AS DOUBLE), 'nan'::DOUBLE)")
    # A parsed time outside pandas' nanosecond range is no time (as in the pure path).
    con.execute(f"CREATE OR REPLACE TEMP MACRO ais_time(t) AS CASE WHEN t BETWEEN TIMESTAMP '{_PD_TMIN}' "
                f"AND TIMESTAMP '{_PD_TMAX}' THEN t END")
    try:
        con.create_function("ais_csv_split", split_csv_line, ["VARCHAR"], "VARCHAR[]", side_effects=False)
    except (duckdb.CatalogException, duckdb.NotImplementedException, RuntimeError):
        pass  # already registered on this connection


def _params() -> dict:
    """Named parameters shared by the staging and cleaning SQL (constants of lanes.clean and
    lanes.io.csv_formats, always bound, never formatted into the SQL)."""
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


def quick_key_known(ws, quick: str) -> bool:
    """Whether a loaded file has this quick key (then the full fingerprint decides)."""
    return ws.con.execute(
        "SELECT count(*) FROM ais_files f LEFT JOIN ais_file_keys k USING (file_id) "
        "WHERE k.quick_key = ? OR k.quick_key IS NULL", [quick]).fetchone()[0] > 0


def fingerprint_algos(ws, quick: str) -> set[str]:
    """Hash algorithms (the fingerprints' prefixes) of the loaded files that have this quick key
    or none (files loaded before quick keys existed)."""
    rows = ws.con.execute(
        "SELECT DISTINCT split_part(f.fingerprint, ':', 1) FROM ais_files f LEFT JOIN ais_file_keys k USING (file_id) "
        "WHERE k.quick_key = ? OR k.quick_key IS NULL", [quick]).fetchall()
    return {r[0] for r in rows}


def read_files(ws) -> pd.DataFrame:
    """All loaded files with their counts, oldest first."""
    return ws.con.execute("SELECT * FROM ais_files ORDER BY file_id").fetchdf()


# ---------------------------------------------------------------------------------------------
# Staging: every reader fills ``ais_stage`` (typed values + the rule 1-6 reason ``reason0``)
# ---------------------------------------------------------------------------------------------
def _reason_case() -> str:
    """Rules 1-6 of lanes.clean as one CASE over the typed columns (first match wins).

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
_LINE_DELIM = "\x01"
_CSV_LINES = ("read_csv(?, columns={'raw': 'VARCHAR'}, header=false, delim=?, quote='', escape='', "
              "auto_detect=false, compression=?, max_line_size=?)")
#: DuckDB CSV buffer size, None = DuckDB's default. Tests set it small so that even a small file
#: is scanned as many parallel chunks (the stages number rows by their order).
CSV_BUFFER_BYTES = None


def _buffer_option() -> str:
    return "" if CSV_BUFFER_BYTES is None else f", buffer_size = {int(CSV_BUFFER_BYTES)}"


def _csv_typing(index: dict[str, int], fld, inner: str, passthrough: str = "") -> str:
    """The typing SELECT of the CSV stages (rules in :mod:`lanes.io.csv_formats`), shared by
    both paths so that they type every field with the same expressions.

    ``inner`` yields ``raw``, ``is_data`` (a record, not a header/empty line), ``nf_ok`` (the
    right number of fields) and the fields ``fld(name)`` refers to; ``passthrough`` (e.g.
    ``"line, "``) names columns carried through."""

    def blank(x):
        return f"({x} IS NULL OR trim({x}, $ws) = '')"

    # A field's parse error: its value did not type although its text is not blank (the blank
    # test only runs on the few rows whose cast failed).
    perr = " ".join(
        f"WHEN {name} IS NULL AND NOT {blank(fld(name))} THEN '{code}'"
        for name, code in (("lat_deg", C.BAD_LAT), ("lon_deg", C.BAD_LON), ("sog_kn", C.BAD_SOG),
                           ("cog_deg", C.BAD_COG), ("heading_deg", C.BAD_HEADING), ("nav_status", C.BAD_NAV_STATUS))
        if name in index
    )
    nav = "CAST(NULL AS DOUBLE)"
    if "nav_status" in index:
        x = fld("nav_status")
        # The status words exactly as written first (a CASE on bound constants is cheap), then a
        # number, then the words after trimming white space (trim with a character set is not).
        words = " ".join(f"WHEN $navw{i} THEN $navc{i}" for i in range(len(NAV_STATUS_WORDS)))
        nav = (f"CASE lower({x}) {words} ELSE coalesce(ais_num({x}), "
               f"MAP($nav_k::VARCHAR[], $nav_v::INTEGER[])[lower(trim({x}, $ws))]) END")
    # Fast path of the parse-error CASE: a row of the right length whose fields all typed.
    all_typed = " AND ".join(["nf_ok"] + [f"{n} IS NOT NULL" for n in ("lat_deg", "lon_deg", "sog_kn", "cog_deg",
                                                                      "heading_deg", "nav_status") if n in index])
    return f"""
        SELECT {passthrough}raw, CASE WHEN is_data THEN '{C.KIND_POSITION}' ELSE '{C.KIND_IGNORED}' END AS kind,
            CASE WHEN NOT is_data OR {all_typed} THEN NULL WHEN NOT nf_ok THEN '{C.BAD_LINE}' {perr} END AS parse_error,
            mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, nav_status,
            {", ".join(f"CAST(NULL AS {t}) AS {c}" for c, t in _STATIC_TYPES.items())},
            {", ".join(f"CAST(NULL AS VARCHAR) AS {c}" for c in _TEXT_STATIC)},
            s_hash
        FROM (
            SELECT *,
                CASE WHEN regexp_full_match({fld('mmsi')}, $mmsi_re) THEN CAST({fld('mmsi')} AS BIGINT) END AS mmsi,
                ais_time(try_strptime({fld('time_utc')}, $time_formats::VARCHAR[])) AS time_utc,
                {", ".join(f"ais_num({fld(n)}) AS {n}" for n in _NUM_FIELDS)},
                CAST({nav} AS DOUBLE) AS nav_status,
                hash({", ".join(fld(c[2:]) for c in _TEXT_STATIC)}) AS s_hash
            FROM ({inner})
        )
        """


def _csv_split_typing(index: dict[str, int], n_fields: int, source: str, passthrough: str = "") -> str:
    """:func:`_csv_typing` of raw lines (column ``raw`` of ``source``) split in SQL."""

    def fld(name):
        return f"f[{index[name] + 1}]" if name in index else "CAST(NULL AS VARCHAR)"

    inner = f"""
        SELECT {passthrough}raw, f, len(f) = {int(n_fields)} AS nf_ok, is_data FROM (
            SELECT {passthrough}raw,
                raw IS NOT NULL AND raw <> '' AND raw <> $header AND raw <> $bom_header AS is_data,
                CASE WHEN contains(raw, '"') THEN ais_csv_split(raw) ELSE string_split(raw, ',') END AS f
            FROM {source}
        )"""
    return _csv_typing(index, fld, inner, passthrough)


def _csv_params(spec: CsvSpec, header: str) -> dict:
    params = {"mmsi_re": MMSI_RE, "time_formats": list(spec.time_formats), "header": header,
              "bom_header": "\ufeff" + header}
    for i, (word, code) in enumerate(NAV_STATUS_WORDS.items()):
        params[f"navw{i}"], params[f"navc{i}"] = word, float(code)
    return params


def stage_csv(ws, path: Path, gz: bool, spec: CsvSpec, index: dict[str, int], n_fields: int, header: str) -> dict:
    """Type a DMA/NOAA CSV file into ``ais_stage`` (rules in :mod:`lanes.io.csv_formats`).

    One stage row per physical line, in file order (``line`` = rowid + 1): DuckDB's parallel
    CSV scanner reads the raw lines (one VARCHAR column, no quoting) and the same statement
    splits and types them. Files the scanner refuses (a stray ``\r``, invalid UTF-8, control
    characters) are split by Python with the same rules (``read_lines``) and staged from Arrow.
    The header line, lines equal to it (concatenated files) and empty lines are kind "X"
    (not data; empty ones count as ``ignored``). ``index`` maps stage fields to 0-based columns
    of the header line ``header`` (``n_fields`` columns). Static fields stay text (``s_*``); they are typed per
    distinct value when merged into ``vessels``.
    """
    _prepare(ws.con)
    con = ws.con
    params = _csv_params(spec, header)
    fallback = False
    try:
        if content_has(path, _LINE_DELIM.encode()):
            # DuckDB drops a delimiter that ends a line ('x\x01' reads as 'x'; one inside a
            # line is an error): such content goes to Python's splitter
            raise duckdb.InvalidInputException(f"the content holds the line reader's delimiter {_LINE_DELIM!r}")
        sql = _csv_split_typing(index, n_fields, _CSV_LINES.replace("?", "$p_path", 1).replace("?", "$p_delim", 1)
                                .replace("?", "$p_comp", 1).replace("?", "$p_max", 1)[:-1] + _buffer_option() + ")")
        _create_stage(con, sql, {**params, "p_path": str(path), "p_delim": _LINE_DELIM,
                                 "p_comp": "gzip" if gz else "none",
                                 "p_max": (1 << 24) if CSV_BUFFER_BYTES is None else int(CSV_BUFFER_BYTES) // 2},
                      line_from_rowid=True)
    except (duckdb.InvalidInputException, duckdb.ConversionException, duckdb.IOException):
        from lanes.io.csv_formats import read_lines
        import pyarrow as pa

        fallback = True
        lines = read_lines(path)
        tbl = pa.table({"raw": pa.array([x if x != "" else None for x in lines], type=pa.string())})
        con.register("ais_lines_py", tbl)
        try:
            _create_stage(con, _csv_split_typing(index, n_fields, "ais_lines_py"), params, line_from_rowid=True)
        finally:
            con.unregister("ais_lines_py")
    _set_stage_kind(con, "csvhash", {"index": {c: index[c[2:]] + 1 for c in _TEXT_STATIC if c[2:] in index}})
    ignored = con.execute(
        f"SELECT count(*) FROM ais_stage_t WHERE kind = '{C.KIND_IGNORED}' AND (raw IS NULL OR raw = '')"
    ).fetchone()[0]
    return {"ignored": int(ignored), "python_fallback": fallback, "staging": "python" if fallback else "lines"}


#: Columns of the scanned rows kept by the fast CSV stage.
_FAST_COLUMNS = ("hdr_like", "parse_error", "mmsi", "time_utc", *_NUM_FIELDS, "nav_status", "s_hash")

#: Above this share of lines needing the line-by-line typing, the raw-lines path is as fast.
FAST_MAX_EXACT_FRAC = 0.02


def _fast_names(index: dict[str, int], n_fields: int, header: str) -> tuple[list, list, str, dict]:
    """Column names ``c0..c{n-1}``, the used ones, the "looks like the header" test and its
    parameters, shared by the scanners of the fast CSV stages.

    A line equal to the header (files concatenated) is no record. Comparing every field would
    make the scanner materialise all of them; rows whose time field equals the header's are
    flagged instead (a line equal to the header must be one) and typed from their text."""
    names = [f"c{i}" for i in range(int(n_fields))]
    used = sorted({names[i] for i in index.values()}, key=names.index)
    header_fields = header.split(",")
    t_col = index.get("time_utc", min(index.values()))
    h_field = header_fields[t_col] if len(header_fields) == len(names) else None
    hdr = "false" if h_field is None else (f"{names[t_col]} IN ($h_t, $bom_h_t)" if t_col == 0
                                           else f"{names[t_col]} = $h_t")
    params = {} if h_field is None else {"h_t": h_field, "bom_h_t": "\ufeff" + h_field}
    return names, used, hdr, params


def _fast_stage_sql(index: dict[str, int], names: list, inner: str) -> str:
    """The statement typing the scanned rows into ``ais_fast`` (only what varies per row is
    kept: every row is a position record; raw text and static values come from the line when
    needed, and the view ``ais_stage`` adds the constant columns)."""

    def fld(name):
        return names[index[name]] if name in index else "CAST(NULL AS VARCHAR)"

    return (f"CREATE OR REPLACE TEMP TABLE ais_fast AS WITH typed AS "
            f"({_csv_typing(index, fld, inner, passthrough='hdr_like, ')}) "
            f"SELECT {', '.join(_FAST_COLUMNS)}, {_reason_case()} AS reason0 FROM typed")


def stage_csv_fast(ws, path: Path, spec: CsvSpec, index: dict[str, int], n_fields: int, header: str,
                   line_index) -> dict | None:
    """Fast path of :func:`stage_csv` for an uncompressed DMA/NOAA file, DuckDB's scanner.

    DuckDB's parallel CSV scanner splits every line into its ``n_fields`` columns (no quoting,
    so one record is one physical line; every column VARCHAR, empty fields kept as ``''``) and
    the statement types them with the very expressions of :func:`stage_csv`
    (:func:`_csv_typing`). What the scanner cannot be trusted with is typed from the line's text
    by :func:`stage_csv`'s own statement: lines with a double quote (quoted fields) and the rows
    it rejects (another number of fields; they land in its rejects table with their line).

    ``line_index`` (a :class:`lanes.io.lineindex.LineIndex`, or a future of one built in a
    thread meanwhile) gives the rest (see :func:`_finish_fast_stage`). Returns the stage info,
    or None (nothing staged) when the file needs the exact raw-lines path: a stray ``\r``, a
    check that fails, a scanner error, or more than :data:`FAST_MAX_EXACT_FRAC` of the lines to
    type line by line.
    """
    con = ws.con
    _prepare(con)
    con.execute("SET preserve_insertion_order = true")
    names, used, hdr, hparams = _fast_names(index, n_fields, header)
    inner = f"""
        SELECT CAST(NULL AS VARCHAR) AS raw, true AS is_data, true AS nf_ok, {hdr} AS hdr_like, {", ".join(used)}
        FROM read_csv($path, skip = 1, header = false, delim = ',', quote = '', escape = '', comment = '',
                      auto_detect = false, columns = $cols, force_not_null = $names, store_rejects = true,
                      rejects_table = 'ais_rejects', rejects_scan = 'ais_reject_scans'{_buffer_option()})"""
    params = {**_csv_params(spec, header), "path": str(path), "cols": dict.fromkeys(names, "VARCHAR"),
              "names": names, **hparams}
    for t in ("ais_rejects", "ais_reject_scans"):
        con.execute(f"DROP TABLE IF EXISTS temp.{_q(t)}")
    try:
        sql = _fast_stage_sql(index, names, inner)
        con.execute(sql, _used(sql, {**_params(), **params}))
    except (duckdb.InvalidInputException, duckdb.ConversionException, duckdb.IOException) as err:
        log.info("%s: CSV scanner refused the file (%s); exact raw-lines path", path, str(err).split("\n")[0])
        _drop_temp(con)
        return None
    reported = con.execute("SELECT DISTINCT line, csv_line FROM ais_rejects").fetchall()
    ix = line_index.result() if hasattr(line_index, "result") else line_index
    if ix.stray_cr:
        return _give_up(con, path, "a carriage return inside a line")
    rej = _verified_reject_lines(reported, ix)
    if rej is None:
        return _give_up(con, path, "a rejected row does not match the text of its line")
    return _finish_fast_stage(con, path, spec, index, n_fields, header, ix, rej, "typed")


#: Bytes per block of pyarrow's CSV reader (one block is parsed by one thread).
ARROW_BLOCK_BYTES = 16 << 20


def stage_csv_arrow(ws, path: Path, spec: CsvSpec, index: dict[str, int], n_fields: int, header: str,
                    line_index) -> dict | None:
    """Fast path of :func:`stage_csv` for an uncompressed DMA/NOAA file, pyarrow's CSV reader.

    Like :func:`stage_csv_fast`, but the lines are split by pyarrow's multithreaded CSV reader
    (quoting off, so one record is one physical line; only the used columns, all as text, empty
    fields kept as ``''``, empty lines skipped), which is several times faster than DuckDB's
    scanner here. DuckDB then types the Arrow table with the very expressions of
    :func:`stage_csv` (:func:`_csv_typing`). Rows with another number of fields are skipped by
    pyarrow's ``invalid_row_handler``, which only knows their text: their lines are the lines
    of the file with that text (found through the line index; every line with a rejected text
    must have been rejected as often as reported, else the fast path is given up), and they
    are typed from their text by :func:`stage_csv`'s own statement, as are quoted lines and
    repeated headers. The checks of :func:`_finish_fast_stage` follow.

    Returns the stage info (``staging`` = ``"arrow"``), or None (nothing staged) when another
    path is needed: a file pyarrow refuses (e.g. invalid UTF-8), a stray ``\r``, a check that
    fails, or too many lines to type line by line.
    """
    import pyarrow as pa
    import pyarrow.csv as pcsv

    con = ws.con
    _prepare(con)
    con.execute("SET preserve_insertion_order = true")
    names, used, hdr, hparams = _fast_names(index, n_fields, header)
    rejected: list[str] = []

    def on_invalid(row):
        rejected.append(row.text)
        return "skip"

    try:
        tbl = pcsv.read_csv(
            str(path),
            pcsv.ReadOptions(block_size=int(CSV_BUFFER_BYTES or ARROW_BLOCK_BYTES), column_names=names, skip_rows=1,
                             use_threads=True),
            pcsv.ParseOptions(delimiter=",", quote_char=False, double_quote=False, escape_char=False,
                              newlines_in_values=False, ignore_empty_lines=True, invalid_row_handler=on_invalid),
            pcsv.ConvertOptions(include_columns=used, column_types=dict.fromkeys(used, pa.string()),
                                strings_can_be_null=False, quoted_strings_can_be_null=False, null_values=[],
                                check_utf8=True))
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError, OSError, UnicodeDecodeError) as err:
        log.info("%s: pyarrow's CSV reader refused the file (%s)", path, str(err).split("\n")[0])
        return None
    ix = line_index.result() if hasattr(line_index, "result") else line_index
    if ix.stray_cr:
        return _give_up(con, path, "a carriage return inside a line")
    rej = _reject_lines_by_text(rejected, ix)
    if rej is None:
        return _give_up(con, path, "the rejected rows' texts do not match whole lines")
    if len(rej) > max(1000, FAST_MAX_EXACT_FRAC * ix.n_lines):
        return _give_up(con, path, f"{len(rej)} of {ix.n_lines} lines have another number of fields")
    inner = (f"SELECT CAST(NULL AS VARCHAR) AS raw, true AS is_data, true AS nf_ok, {hdr} AS hdr_like, "
             f"{', '.join(used)} FROM ais_arrow_src")
    params = {**_csv_params(spec, header), **hparams}
    con.register("ais_arrow_src", tbl)
    try:
        sql = _fast_stage_sql(index, names, inner)
        con.execute(sql, _used(sql, {**_params(), **params}))
    finally:
        con.unregister("ais_arrow_src")
    del tbl
    return _finish_fast_stage(con, path, spec, index, n_fields, header, ix, rej, "arrow")


def stage_csv_scan(ws, path: Path, spec: CsvSpec, index: dict[str, int], n_fields: int, header: str,
                   line_index=None) -> dict | None:
    """Fast path of :func:`stage_csv` for an uncompressed DMA/NOAA file, one compiled pass.

    :func:`lanes.io.csv_scan.scan_csv` reads the memory-mapped file once (one range per core)
    and finds every line's offsets (the line index) and, for the lines whose used fields are
    all written canonically, their typed values, which are by construction those of
    :func:`stage_csv`'s rules. Every other line (quotes, another number of fields, a ``\r``,
    non-canonical numbers or times, repeated headers) is typed from its text by
    :func:`stage_csv`'s own statement. A sample of the scanned rows is typed again from its
    text and compared before anything is used. ``line_index`` is ignored (the scan builds it).

    Returns the stage info (``staging`` = ``"scan"``), or None (nothing staged) when another
    path is needed: a time format without a canonical layout, more than
    :data:`FAST_MAX_EXACT_FRAC` of the lines to type from their text, or a failed check.
    """
    import pyarrow as pa

    from lanes.io.csv_scan import KIND_SPECIAL, TIME_LAYOUTS, scan_csv
    from lanes.io.lineindex import LineIndex

    if tuple(spec.time_formats) not in TIME_LAYOUTS:
        return None
    con = ws.con
    _prepare(con)
    res = {}
    statics = tuple(c[2:] for c in _TEXT_STATIC)

    def offsets(buf):
        r = scan_csv(buf, index, int(n_fields), tuple(spec.time_formats), NAV_STATUS_WORDS, statics)
        res["scan"] = r
        return None if r is None else (r.starts, r.ends, r.quote_lines, r.stray_cr)

    times = {}
    t0 = time.perf_counter()
    ix = LineIndex(path, offsets_from=offsets)
    times["scan"] = time.perf_counter() - t0
    r = res.get("scan")
    if r is None:
        ix.close()
        return None
    special = np.flatnonzero(r.kind == KIND_SPECIAL) + 1
    special = special[special > 1]  # line 1 is the header
    if len(special) > max(1000, FAST_MAX_EXACT_FRAC * ix.n_lines):
        ix.close()
        log.info("%s: %d of %d lines not canonical; leaving the scan path", path, len(special), ix.n_lines)
        return None
    tbl, fixes = _scan_table(con, r)
    del r, res["scan"]
    times["arrow"] = time.perf_counter() - t0 - times["scan"]
    t1 = time.perf_counter()
    if not _spot_check_lines(con, tbl, ix, header, spec, index, int(n_fields)):
        ix.close()
        return _give_up(con, path, "sampled rows differ from their lines")
    times["spot_check"] = time.perf_counter() - t1
    # The scanned rows stay in Arrow memory (no copy into DuckDB); the stage view reads them.
    con.register("ais_scan_src", tbl)
    del tbl
    _create_exact_stage(con, special, ix, spec, index, int(n_fields), header)
    times["exact_lines"] = time.perf_counter() - t1 - times["spot_check"]
    con.execute(f"""CREATE OR REPLACE TEMP VIEW ais_stage AS
        SELECT * FROM ais_exact
        UNION ALL BY NAME SELECT line, CAST(NULL AS VARCHAR) AS raw, '{C.KIND_POSITION}' AS kind, * EXCLUDE (line)
        FROM ais_scan_src""")
    _set_stage_kind(con, "csvfast", {"path": str(path), "header": header,
                                     "index": {c: index[c[2:]] + 1 for c in _TEXT_STATIC if c[2:] in index}})
    blank = ix.blank_lines[ix.blank_lines > 1]
    times["total"] = time.perf_counter() - t0
    log.info("%s: scan stage %s", path, {k: round(v, 2) for k, v in times.items()})
    return {"ignored": int(len(blank)), "python_fallback": False, "staging": "scan", "line_index": ix,
            "exact_lines": int(len(special)), "line_mapping": "scan", "timings": times, "scan_fixes": fixes}


#: Rows per record batch of the scan's Arrow table (DuckDB's row group size).
SCAN_BATCH_ROWS = 122_880


def _scan_table(con, r):
    """(table, fixes): the Arrow table of the canonical rows of a scan (the columns of
    ``ais_fast``), and the same rows' ``line``, ``mmsi``, ``t_us``, ``lat``, ``lon`` as numpy
    arrays (the table's own buffers) with ``ok`` = no ``reason0``, for the first-load kernel.
    (A table of every line filtered by a view was measured slower: DuckDB filters the Arrow scan
    on every read of the stage.) ``fixes`` also holds ``shash`` (for the vessels merge).

    ``reason0`` (rules 1-6): a row that clearly passes every check of :func:`_reason_case`'s
    clean-row conjunction (tested in numpy with no value near a bound: exact integer and float
    comparisons, sentinel tolerances not needed) has none; the few others get the CASE itself,
    evaluated by DuckDB on just those rows."""
    import pyarrow as pa

    from lanes.io.csv_scan import NULL_TIME

    skip = 1 if len(r.line) and r.line[0] == 1 else 0  # the header line
    line, mm, t_us, shash = r.line[skip:], r.mmsi[skip:], r.t_us[skip:], r.shash[skip:]
    n = len(line)
    cols = {"line": pa.array(line), "parse_error": pa.nulls(n, pa.string()), "mmsi": pa.array(mm, mask=mm < 0),
            "time_utc": pa.array(t_us.view("datetime64[us]"), mask=t_us == NULL_TIME)}
    vals = {}
    for name in (*_NUM_FIELDS, "nav_status"):
        if name in r.fields:
            v = r.vals[r.fields.index(name)][skip:]
            vals[name] = v
            cols[name] = pa.array(v, mask=np.isnan(v))
        else:
            cols[name] = pa.nulls(n, pa.float64())
    cols["s_hash"] = pa.array(shash)
    tmin = int(C.TIME_MIN_UTC.value // 1000)
    tmax = int(C.TIME_MAX_UTC.value // 1000)
    clean = (mm >= C.MMSI_MIN) & (mm <= C.MMSI_MAX) & (t_us >= tmin) & (t_us < tmax)
    with np.errstate(invalid="ignore"):
        for name, ok in (("lat_deg", lambda x: (x >= -90.0) & (x <= 90.0)),
                         ("lon_deg", lambda x: (x >= -180.0) & (x <= 180.0)),
                         ("sog_kn", lambda x: np.isnan(x) | ((x >= 0.0) & (x <= C.SOG_NA_KN))),
                         ("cog_deg", lambda x: np.isnan(x) | ((x >= 0.0) & (x <= C.COG_NA_DEG))),
                         ("heading_deg", lambda x: np.isnan(x) | ((x >= 0.0) & (x < 360.0)) | (x == C.HEADING_NA_DEG)),
                         ("nav_status", lambda x: np.isnan(x) | ((x >= 0) & (x <= C.NAV_STATUS_MAX) & (x == np.floor(x))))):
            if name in vals:
                clean &= ok(vals[name])
            elif name in ("lat_deg", "lon_deg"):
                clean[:] = False
    fixes = {"line": line, "mmsi": mm, "t_us": t_us, "lat": vals.get("lat_deg", np.full(n, np.nan)),
             "lon": vals.get("lon_deg", np.full(n, np.nan)), "ok": clean, "shash": shash}
    del vals
    tbl = pa.table(cols)
    del cols
    other = np.flatnonzero(~clean)
    reason = pa.nulls(n, pa.string())
    if len(other):
        con.register("ais_scan_other", tbl.take(pa.array(other)))
        try:
            sql = (f"SELECT {_reason_case()} AS reason0 FROM (SELECT *, '{C.KIND_POSITION}' AS kind "
                   f"FROM ais_scan_other)")
            got = con.execute(sql, _used(sql, _params())).to_arrow_table().column("reason0").to_pylist()
        finally:
            con.unregister("ais_scan_other")
        clean[other] = [x is None for x in got]
        codes = sorted({x for x in got if x is not None})
        if codes:
            code_of = {c: i for i, c in enumerate(codes)}
            idx = np.full(n, -1, dtype=np.int32)
            idx[other] = [code_of[x] if x is not None else -1 for x in got]
            reason = pa.DictionaryArray.from_arrays(pa.array(idx, mask=idx < 0), pa.array(codes, pa.string())) \
                .cast(pa.string())
    # In record batches of DuckDB's row-group size: DuckDB scans a one-chunk Arrow table on one
    # thread, and every read of the stage (the fixes to numpy, the insert, vessels) with it.
    tbl = tbl.append_column("reason0", reason)
    return pa.Table.from_batches(tbl.to_batches(max_chunksize=SCAN_BATCH_ROWS), schema=tbl.schema), fixes


def _spot_check_lines(con, tbl, ix, header, spec, index, n_fields: int, n: int = 64) -> bool:
    """Type ``n`` rows of the scanned Arrow table ``tbl`` spread over the file (and up to ``n``
    quarantined ones) again from their line's text and compare every typed value (not the
    static hash, which the scan computes its own way)."""
    import pyarrow as pa

    m = tbl.num_rows
    if m == 0:
        return True
    pick = np.unique(np.linspace(0, m - 1, min(n, m)).astype(np.int64))
    bad = np.flatnonzero(tbl.column("reason0").is_valid().to_numpy(zero_copy_only=False))[:n]
    rows = np.union1d(pick, bad)
    sample = tbl.take(pa.array(rows))
    lines = np.asarray(sample.column("line").to_numpy(), dtype=np.int64)
    _typed_lines(con, lines, ix.text(lines), spec, index, n_fields, header, "ais_spot")
    con.register("ais_spot_fast", sample)
    try:
        vals = ", ".join(("parse_error", "mmsi", "time_utc", *_NUM_FIELDS, "nav_status", "reason0"))
        differ = con.execute(f"""SELECT count(*) FROM (
                SELECT line, '{C.KIND_POSITION}' AS kind, {vals} FROM ais_spot_fast
                EXCEPT SELECT line, kind, {vals} FROM ais_spot)""").fetchone()[0]
        n_spot = con.execute("SELECT count(*) FROM ais_spot").fetchone()[0]
    finally:
        con.unregister("ais_spot_fast")
        con.execute("DROP TABLE IF EXISTS temp.ais_spot")
    return differ == 0 and n_spot == len(rows)


def _reject_lines_by_text(texts: list, ix) -> np.ndarray | None:
    """The lines of rows a scanner rejected, given only their texts (pyarrow does not number
    them when it reads in parallel).

    A rejected row has another number of fields than the header, so every line with the same
    text is rejected as well: the rejected lines are all lines whose text is one of ``texts``,
    and each text must occur on exactly as many lines as it was reported. Candidates are the
    lines of the same byte length (from the line index), compared byte by byte. None when the
    texts do not match the file that way (the caller then leaves the fast path)."""
    from collections import Counter

    if not texts:
        return np.empty(0, dtype=np.int64)
    want = Counter()
    for t in texts:
        if t is None:
            return None
        b = t.encode("utf-8", errors="surrogateescape")
        want[b[:-1] if b.endswith(b"\r") else b] += 1
    found = ix.lines_equal_to(set(want))
    seen = Counter(ix.raw(found))
    if seen != want:
        return None
    return found


def _give_up(con, path, why: str):
    log.info("%s: %s; leaving the fast CSV path", path, why)
    _drop_temp(con)
    return None


def _finish_fast_stage(con, path, spec, index, n_fields: int, header: str, ix, rej: np.ndarray,
                       label: str) -> dict | None:
    """The common tail of the fast CSV stages, once ``ais_fast`` holds the scanned rows in file
    order and ``rej`` the (verified) lines the scanner rejected:

    * the line of every scanned row: rows come out in file order, so the k-th row is the k-th
      line that is not the header, an empty line or a rejected line (with none of those,
      ``line = rowid + 2``, no mapping at all);
    * checks before anything is used: ``rows + rejected + header + empty lines == lines in the
      file``; a sample of rows is typed again from its line's text and compared;
    * the raw text of a row, read from the index only when the row is quarantined.
    """
    import pyarrow as pa

    n_fast = int(con.execute("SELECT count(*) FROM ais_fast").fetchone()[0])
    blank = ix.blank_lines[ix.blank_lines > 1]
    excluded = np.union1d(np.union1d(np.array([1], dtype=np.int64), blank), rej)
    if len(excluded) != 1 + len(blank) + len(rej) or n_fast + len(excluded) != ix.n_lines:
        return _give_up(con, path, f"line count does not add up (rows {n_fast} + rejected {len(rej)} + header 1 + "
                                   f"empty {len(blank)} vs {ix.n_lines} lines)")
    hdr_rows = np.asarray(con.execute("SELECT rowid FROM ais_fast WHERE hdr_like ORDER BY rowid")
                          .fetchnumpy()["rowid"], dtype=np.int64)
    # The k-th row (0-based) is the line L with L - #{excluded <= L} = k + 1; with no empty or
    # rejected line that is simply line = rowid + 2.
    simple = len(excluded) == 1
    k = np.arange(n_fast, dtype=np.int64)
    fast_line = k + 2 if simple else k + 1 + np.searchsorted(excluded - 1 - np.arange(len(excluded)), k, side="right")
    del k
    special = np.union1d(np.union1d(rej, ix.quote_lines), fast_line[hdr_rows])
    special = special[special > 1]
    if len(special) > max(1000, FAST_MAX_EXACT_FRAC * ix.n_lines):
        return _give_up(con, path, f"{len(special)} of {ix.n_lines} lines need the line-by-line typing")
    skip = np.zeros(n_fast, dtype=bool)  # rows of lines typed from their text instead
    pos = np.searchsorted(fast_line, special)
    hit = pos < n_fast
    hit[hit] = fast_line[pos[hit]] == special[hit]
    skip[pos[hit]] = True
    if not _spot_check(con, ix, fast_line, skip, header, spec, index, int(n_fields)):
        return _give_up(con, path, "sampled rows differ from their lines")
    if simple:
        con.register("ais_fast_skip", pa.table({"r": pa.array(pos[hit].astype(np.int64))}))
        fast_sql = """SELECT rowid + 2 AS line, * EXCLUDE (hdr_like) FROM ais_fast
                      WHERE rowid NOT IN (SELECT r FROM ais_fast_skip)"""
    else:
        con.register("ais_fast_pos", pa.table({"line": fast_line, "skip": skip}))
        fast_sql = """SELECT p.line, f.* EXCLUDE (hdr_like) FROM ais_fast f POSITIONAL JOIN ais_fast_pos p
                      WHERE NOT p.skip"""
    _create_exact_stage(con, special, ix, spec, index, int(n_fields), header)
    con.execute(f"""CREATE OR REPLACE TEMP VIEW ais_stage AS
        SELECT * FROM ais_exact
        UNION ALL BY NAME SELECT line, CAST(NULL AS VARCHAR) AS raw, '{C.KIND_POSITION}' AS kind, * EXCLUDE (line)
        FROM ({fast_sql})""")
    _set_stage_kind(con, "csvfast", {"path": str(path), "header": header,
                                     "index": {c: index[c[2:]] + 1 for c in _TEXT_STATIC if c[2:] in index}})
    return {"ignored": int(len(blank)), "python_fallback": False, "staging": label, "line_index": ix,
            "exact_lines": int(len(special)), "line_mapping": "rowid" if simple else "ordinal"}


def _verified_reject_lines(reported: list, ix) -> np.ndarray | None:
    """The lines of the rows DuckDB's scanner rejected, each checked against the line index.

    ``reported``: distinct ``(line, csv_line)`` pairs of the rejects table. A pair whose text
    (without the empty lines DuckDB sometimes prefixes, nor a trailing ``\\r``) is the text of
    its line is kept. DuckDB 1.5 can also report an error of a row a second time under the
    number of an empty line before it; such a pair is dropped when its text is that of a
    verified rejected line. Any other mismatch returns None (the numbering cannot be trusted).
    """
    if not reported:
        return np.empty(0, dtype=np.int64)
    lines = np.asarray([r[0] if r[0] is not None else -1 for r in reported], dtype=np.int64)
    texts = []
    for _, t in reported:
        t = (t or "").lstrip("\r\n")
        texts.append(t[:-1] if t.endswith("\r") else t)
    inside = (lines >= 1) & (lines <= ix.n_lines)
    actual = dict(zip(lines[inside].tolist(), ix.text(lines[inside]))) if inside.any() else {}
    ok = [L for L, t in zip(lines.tolist(), texts) if actual.get(L) == t]
    good = {actual[L] for L in ok}
    if any(actual.get(L) != t and t not in good for L, t in zip(lines.tolist(), texts)):
        return None
    return np.unique(np.asarray(ok, dtype=np.int64))


def _typed_lines(con, lines: np.ndarray, texts: list, spec, index, n_fields: int, header: str,
                 table: str, extra: dict | None = None) -> None:
    """Type the given lines with :func:`stage_csv`'s statement into the temp table ``table``."""
    import pyarrow as pa

    con.register("ais_lines_df", pa.table({"line": pa.array(np.asarray(lines, dtype=np.int64)),
                                           "raw": pa.array(texts, pa.string())}))
    try:
        _create_stage(con, _csv_split_typing(index, n_fields, "ais_lines_df", passthrough="line, "),
                      {**_csv_params(spec, header), **(extra or {})}, table=table)
    finally:
        con.unregister("ais_lines_df")


def _spot_check(con, ix, fast_line, skip, header, spec, index, n_fields: int, n: int = 64) -> bool:
    """Type ``n`` scanned rows spread over the file (and up to ``n`` quarantined ones) again
    from their line's text and compare: a wrong line mapping shows here."""
    ok_rows = np.flatnonzero(~skip)
    if len(ok_rows) == 0:
        return True
    pick = ok_rows[np.unique(np.linspace(0, len(ok_rows) - 1, min(n, len(ok_rows))).astype(np.int64))]
    bad = np.asarray(con.execute("SELECT rowid FROM ais_fast WHERE reason0 IS NOT NULL LIMIT ?",
                                 [int(n)]).fetchnumpy()["rowid"], dtype=np.int64)
    bad = bad[~skip[bad]]
    rows = np.union1d(pick, bad)
    lines = fast_line[rows]
    _typed_lines(con, lines, ix.text(lines), spec, index, n_fields, header, "ais_spot")
    con.register("ais_spot_rows", _rows_table(rows, lines))
    try:
        vals = ", ".join(("parse_error", "mmsi", "time_utc", *_NUM_FIELDS, "nav_status", "s_hash", "reason0"))
        differ = con.execute(f"""SELECT count(*) FROM (
                SELECT r.line, '{C.KIND_POSITION}' AS kind, {vals} FROM ais_fast f JOIN ais_spot_rows r ON f.rowid = r.r
                EXCEPT SELECT line, kind, {vals} FROM ais_spot)""").fetchone()[0]
        n_spot = con.execute("SELECT count(*) FROM ais_spot").fetchone()[0]
    finally:
        con.unregister("ais_spot_rows")
        con.execute("DROP TABLE IF EXISTS temp.ais_spot")
    return differ == 0 and n_spot == len(rows)


def _rows_table(rows: np.ndarray, lines: np.ndarray):
    import pyarrow as pa

    return pa.table({"r": pa.array(rows.astype(np.int64)), "line": pa.array(lines.astype(np.int64))})


def _create_exact_stage(con, special: np.ndarray, ix, spec, index, n_fields: int, header: str) -> None:
    """The lines the scanner cannot be trusted with, typed from their text, as ``ais_exact``."""
    _typed_lines(con, special, ix.text(special), spec, index, n_fields, header, "ais_exact")


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


def parquet_columns(ws, path: Path, shown=None) -> list[tuple[str, str]]:
    """(name, DuckDB type) of the columns of a Parquet file; :class:`AisFormatError` (naming
    ``shown``, default ``path``) when it is not one (e.g. ``--format parquet`` forced on a CSV
    file)."""
    try:
        rows = ws.con.execute("DESCRIBE SELECT * FROM read_parquet(?)", [str(path)]).fetchall()
    except (duckdb.InvalidInputException, duckdb.IOException) as err:
        from lanes.errors import AisFormatError

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
        if fld not in mapping:
            return "CAST(NULL AS DOUBLE)"
        return f"nullif(TRY_CAST({src(fld)} AS DOUBLE), 'nan'::DOUBLE)"

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
        f"WHEN {src(fld)} IS NOT NULL AND {num(fld)} IS NULL THEN '{code}'"
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
    FROM read_parquet($path, file_row_number = true)
    """
    _create_stage(ws.con, typed, {"path": str(path), "mmsi_re": MMSI_RE})
    _set_stage_kind(ws.con, "text")
    return {"ignored": 0, "python_fallback": False}


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
    """Put an Arrow table with the columns of :data:`lanes.clean.STAGE_COLUMNS` (``time_utc``
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


def read_stage(ws) -> pd.DataFrame:
    """The current typed stage as a DataFrame, statics typed (tests compare it with pandas)."""
    cols = ["mmsi", "timezone('UTC', time_utc) AS time_utc", *_NUM_FIELDS, "nav_status", _typed_static_select()]
    source = "ais_stage"
    kind, extra = _stage_kind(ws.con)
    registered = False
    if kind == "csvfast":  # rows from the scanner: the raw text from their line
        import pyarrow as pa

        from lanes.io.lineindex import LineIndex

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


# ---------------------------------------------------------------------------------------------
# Cleaning (rules 7-8 of lanes.clean as SQL + the numpy jump kernel) and the one-transaction commit
# ---------------------------------------------------------------------------------------------
_OK = f"kind = '{C.KIND_POSITION}' AND reason0 IS NULL"


def _dedupe_sql(has_old: bool, stage: str = "ais_stage") -> str:
    """Rows (line, reason) that repeat the (mmsi, time) of an earlier row of the file or of a
    stored row: ``duplicate`` when all normalised values agree, else ``duplicate_time``."""
    firsts = ", ".join(f"first_value({v}) OVER w AS f_{v}" for v in _VALUES)
    if has_old:
        same = " AND ".join(f"(CASE WHEN in_db THEN p_{v} ELSE f_{v} END) IS NOT DISTINCT FROM {v}" for v in _VALUES)
        old = f"""old AS (
            SELECT p.mmsi, make_timestamp(epoch_us(p.time_utc)) AS time_utc, {", ".join(f"p.{v} AS p_{v}" for v in _VALUES)}
            FROM ais_positions p SEMI JOIN (SELECT DISTINCT mmsi FROM {stage} WHERE {_OK}) USING (mmsi)
            WHERE p.time_utc BETWEEN (SELECT min(time_utc) FROM {stage} WHERE {_OK})
                                 AND (SELECT max(time_utc) FROM {stage} WHERE {_OK})
        ),"""
        keys_old = "UNION SELECT mmsi, time_utc FROM old"
        join_old = "LEFT JOIN old USING (mmsi, time_utc)"
        in_db = "old.p_lat_deg IS NOT NULL AS in_db, " + ", ".join(f"old.p_{v}" for v in _VALUES) + ","
    else:
        same = " AND ".join(f"f_{v} IS NOT DISTINCT FROM {v}" for v in _VALUES)
        old = keys_old = join_old = ""
        in_db = "false AS in_db,"
    return f"""
    CREATE OR REPLACE TEMP TABLE ais_dup AS
    WITH {old}
    keys AS (
        SELECT mmsi, time_utc FROM {stage} WHERE {_OK} GROUP BY mmsi, time_utc HAVING count(*) > 1
        {keys_old}
    ),
    cand AS (
        SELECT s.line, s.mmsi, s.time_utc, {_norm('s')} FROM {stage} s SEMI JOIN keys USING (mmsi, time_utc)
        WHERE s.kind = '{C.KIND_POSITION}' AND s.reason0 IS NULL
    ),
    ranked AS (
        SELECT cand.*, {in_db} first_value(line) OVER w AS first_line, {firsts}
        FROM cand {join_old}
        WINDOW w AS (PARTITION BY mmsi, time_utc ORDER BY line)
    )
    SELECT line, CASE WHEN {same} THEN '{C.DUPLICATE}' ELSE '{C.DUPLICATE_TIME}' END AS reason
    FROM ranked WHERE in_db OR line <> first_line
    """


def _track_sql(has_old: bool, stage: str = "ais_stage") -> str:
    """Fixes of the tracks that may hold a speed jump, sorted (line -1 = stored context fix).

    A track is fetched when any consecutive pair implies more than 0.999 x the limit: a superset
    of what the numpy kernel flags (the margin absorbs float differences between SQL and numpy).
    """
    r = float(EARTH_RADIUS_NMI)
    lon = _NORM["lon_deg"]
    new = (f"SELECT s.line, s.mmsi, s.time_utc, s.lat_deg, {lon.replace('lon_deg', 's.lon_deg')} AS lon_deg "
           f"FROM {stage} s ANTI JOIN ais_dup d USING (line) WHERE s.kind = '{C.KIND_POSITION}' AND s.reason0 IS NULL")
    ctx = ""
    if has_old:
        ctx = f"""
        UNION ALL SELECT -1, mmsi, time_utc, lat_deg, lon_deg FROM ex WHERE time_utc BETWEEN t0 AND t1
        UNION ALL SELECT -1, mmsi, max(time_utc), arg_max(lat_deg, time_utc), arg_max(lon_deg, time_utc) FROM ex
            WHERE time_utc < t0 GROUP BY mmsi
        UNION ALL SELECT -1, mmsi, min(time_utc), arg_min(lat_deg, time_utc), arg_min(lon_deg, time_utc) FROM ex
            WHERE time_utc > t1 GROUP BY mmsi"""
        pre = f"""new AS ({new}),
        span AS (SELECT mmsi, min(time_utc) AS t0, max(time_utc) AS t1 FROM new GROUP BY mmsi),
        ex AS (SELECT p.mmsi, make_timestamp(epoch_us(p.time_utc)) AS time_utc, p.lat_deg, p.lon_deg, s.t0, s.t1
               FROM ais_positions p JOIN span s USING (mmsi)),
        t AS (SELECT * FROM new {ctx}),"""
    else:
        pre = f"t AS ({new}),"
    return f"""
    WITH {pre}
    l AS (
        SELECT *, lag(time_utc) OVER w AS t0_, lag(lat_deg) OVER w AS lat0, lag(lon_deg) OVER w AS lon0
        FROM t WINDOW w AS (PARTITION BY mmsi ORDER BY time_utc)
    ),
    b AS MATERIALIZED (
        SELECT *, coalesce(
            2.0 * {r} * asin(sqrt(least(1.0,
                pow(sin(radians(lat_deg - lat0) / 2.0), 2)
                + cos(radians(lat0)) * cos(radians(lat_deg)) * pow(sin(radians(lon_deg - lon0) / 2.0), 2))))
            > 0.999 * $vmax * (epoch_us(time_utc) - epoch_us(t0_)) / 3.6e9, false) AS brk
        FROM l
    ),
    cm AS (SELECT DISTINCT mmsi FROM b WHERE brk)
    SELECT line, mmsi, epoch_us(time_utc) AS t_us, lat_deg, lon_deg FROM b SEMI JOIN cm USING (mmsi)
    ORDER BY mmsi, time_utc
    """


def _first_load_fetch(con) -> dict:
    """The fixes that passed rules 1-6, as numpy arrays (line, mmsi, t_us, lat, lon), by line."""
    d = con.execute(f"SELECT line, mmsi, epoch_us(time_utc) AS t_us, lat_deg, lon_deg "
                    f"FROM ais_stage WHERE {_OK}").fetchnumpy()
    out = {"line": np.asarray(d["line"], dtype=np.int64), "mmsi": np.asarray(d["mmsi"], dtype=np.int64),
           "t_us": np.asarray(d["t_us"], dtype=np.int64), "lat": np.asarray(d["lat_deg"], dtype=float),
           "lon": np.asarray(d["lon_deg"], dtype=float)}
    line = out["line"]
    if len(line) > 1 and not (line[1:] > line[:-1]).all():
        order = np.argsort(line, kind="stable")
        out = {k: v[order] for k, v in out.items()}
    return out


def _no_fixes() -> dict:
    e = np.empty(0)
    return {"line": e.astype(np.int64), "mmsi": e.astype(np.int64), "t_us": e.astype(np.int64), "lat": e, "lon": e}


def _first_load_kernel(scan: dict, exact: dict, max_speed_kn: float) -> dict:
    """The numpy part of :func:`_first_load_outcomes` (no database): the rows repeating the
    (mmsi, time) key of an earlier row (``dup``, with the first row of their run ``ref``) and
    the speed jumps among the others (``jump``), by :func:`lanes._tracks.first_load_rules` over
    ``scan``'s rows with ``ok`` and ``exact``'s rows, merged by line."""
    from lanes._tracks import first_load_rules

    if "ok" not in scan:
        scan = {**scan, "ok": np.ones(len(scan["line"]), dtype=bool)}
    return first_load_rules(scan, exact, max_speed_kn)


def _first_load_finish(con, k: dict) -> tuple[np.ndarray, list]:
    """(lines, reasons) from :func:`_first_load_kernel`'s result: a repeated key is
    ``duplicate`` when all normalised values equal those of the first row of its run (compared
    on those few rows only), else ``duplicate_time``."""
    out_lines, out_reasons = [], []
    if len(k["dup"]):
        dup, ref = k["dup"], k["ref"]
        need = np.union1d(dup, ref)
        con.register("ais_need_df", pd.DataFrame({"line": need}))
        try:
            vals = con.execute(f"SELECT line, {_norm()} FROM ais_stage SEMI JOIN ais_need_df USING (line) "
                               f"WHERE {_OK} ORDER BY line").fetchnumpy()
        finally:
            con.unregister("ais_need_df")
        at = np.searchsorted(np.asarray(vals["line"], dtype=np.int64), dup)
        at_ref = np.searchsorted(np.asarray(vals["line"], dtype=np.int64), ref)
        equal = np.ones(len(dup), dtype=bool)
        for v in _VALUES:
            col = vals[v]
            x = np.asarray(col.filled(np.nan) if np.ma.isMaskedArray(col) else col, dtype=float)
            a, b = x[at], x[at_ref]
            equal &= (a == b) | (np.isnan(a) & np.isnan(b))
        out_lines.append(dup)
        out_reasons += [C.DUPLICATE if e else C.DUPLICATE_TIME for e in equal]
    out_lines.append(k["jump"])
    out_reasons += [C.SPEED_JUMP] * len(k["jump"])
    return np.concatenate(out_lines), out_reasons


def _first_load_outcomes(con, max_speed_kn: float, scan_fixes: dict | None = None) -> tuple[np.ndarray, list]:
    """Rules 7-8 for a file whose (mmsi, time) keys meet no stored position: (lines, reasons)
    of the duplicates and speed jumps among the rows that passed rules 1-6.

    The accepted fixes are sorted by (track, time, line); a row with the key of the row before
    it duplicates the first row of its run (values compared on those few rows only), and the
    kept fixes go through :func:`lanes.clean.speed_jump_mask`. ``scan_fixes``: the scanned
    rows of a scan-staged CSV file, read in place (only the lines typed from their text, in
    ``ais_exact``, are fetched); else every fix is fetched from the stage."""
    if scan_fixes is not None:
        d = con.execute(f"SELECT line, mmsi, epoch_us(time_utc) AS t_us, lat_deg AS lat, lon_deg AS lon "
                        f"FROM ais_exact WHERE {_OK} ORDER BY line").fetchnumpy()
        exact = {k: np.asarray(d[k], dtype=v.dtype) for k, v in _no_fixes().items()}
        return _first_load_finish(con, _first_load_kernel(scan_fixes, exact, max_speed_kn))
    return _first_load_finish(con, _first_load_kernel(_first_load_fetch(con), _no_fixes(), max_speed_kn))


def _stored_sql_outcomes(con, max_speed_kn: float, stage: str = "ais_stage") -> np.ndarray:
    """Rules 7-8 of the rows of ``stage`` against the stored positions, in SQL: ``ais_dup``
    (duplicates of a stored row or an earlier row) is created; returns the speed-jump lines
    (the jump kernel with the stored fixes as fixed context)."""
    con.execute(_dedupe_sql(True, stage))
    tr = con.execute(_track_sql(True, stage), {"vmax": float(max_speed_kn)}).fetchnumpy()
    if not len(tr["line"]):
        return np.empty(0, np.int64)
    lines = np.asarray(tr["line"], dtype=np.int64)
    t_s = (np.asarray(tr["t_us"], dtype=np.int64) * 1000) / 1e9
    mask = C.speed_jump_mask(np.asarray(tr["mmsi"]), t_s, np.asarray(tr["lat_deg"], dtype=float),
                             np.asarray(tr["lon_deg"], dtype=float), max_speed_kn, fixed=lines < 0)
    return lines[mask]


def _outcomes_with_stored(con, max_speed_kn: float, scan_fixes: dict) -> tuple[np.ndarray, list]:
    """Rules 7-8 for a scanned file when positions are stored: (lines, reasons).

    An MMSI with no stored fix at or after its first accepted fix in the file (a file that
    continues the stored tracks, the daily case) goes through the streaming pass of a first
    load, its last stored fix opening its track as fixed context
    (:func:`lanes._tracks.first_load_rules`): exactly what the SQL path gives it, since its
    only context is that fix and no stored key can repeat one of its keys. The other MMSIs
    (stored fixes inside or after the file's span, or the track going back in time in the
    file) take the SQL path (:func:`_stored_sql_outcomes` on their rows only)."""
    import pyarrow as pa

    from lanes._tracks import first_load_rules

    d = con.execute(f"""
        WITH span AS (SELECT mmsi, min(time_utc) AS t0 FROM ais_stage WHERE {_OK} GROUP BY mmsi),
        p AS (SELECT p.mmsi, make_timestamp(epoch_us(p.time_utc)) AS pt, p.lat_deg, p.lon_deg
              FROM ais_positions p SEMI JOIN span USING (mmsi))
        SELECT span.mmsi, bool_or(p.pt >= span.t0) AS later,
               coalesce(epoch_us(max(p.pt) FILTER (WHERE p.pt < span.t0)), 0) AS t_us,
               coalesce(arg_max(p.lat_deg, p.pt) FILTER (WHERE p.pt < span.t0), 0.0) AS lat,
               coalesce(arg_max(p.lon_deg, p.pt) FILTER (WHERE p.pt < span.t0), 0.0) AS lon
        FROM span JOIN p USING (mmsi) GROUP BY span.mmsi""").fetchnumpy()
    context = {"mmsi": np.asarray(d["mmsi"], dtype=np.int64), "skip": np.asarray(d["later"], dtype=bool),
               "t_us": np.asarray(d["t_us"], dtype=np.int64), "lat": np.asarray(d["lat"], dtype=float),
               "lon": np.asarray(d["lon"], dtype=float)}
    e = con.execute(f"SELECT line, mmsi, epoch_us(time_utc) AS t_us, lat_deg AS lat, lon_deg AS lon "
                    f"FROM ais_exact WHERE {_OK} ORDER BY line").fetchnumpy()
    exact = {k: np.asarray(e[k], dtype=v.dtype) for k, v in _no_fixes().items()}
    k = first_load_rules(scan_fixes, exact, max_speed_kn, context)
    jumps = np.empty(0, np.int64)
    if len(k["fallback"]):
        con.register("ais_fb_df", pa.table({"mmsi": k["fallback"]}))
        try:
            con.execute("CREATE OR REPLACE TEMP TABLE ais_fb AS SELECT mmsi FROM ais_fb_df")
        finally:
            con.unregister("ais_fb_df")
        con.execute("CREATE OR REPLACE TEMP VIEW ais_stage_fb AS SELECT * FROM ais_stage SEMI JOIN ais_fb USING (mmsi)")
        jumps = _stored_sql_outcomes(con, max_speed_kn, "ais_stage_fb")
    else:
        con.execute("CREATE OR REPLACE TEMP TABLE ais_dup (line BIGINT, reason VARCHAR)")
    lines, reasons = _first_load_finish(con, {"dup": k["dup"], "ref": k["ref"], "jump": np.r_[k["jump"], jumps]})
    return lines, reasons


def _line_index(con, meta: dict):
    """The line index of a fast-staged CSV file (from the stage info, else built again)."""
    if meta.get("line_index") is not None:
        return meta["line_index"]
    kind, extra = _stage_kind(con)
    if kind != "csvfast":
        return None
    from lanes.io.lineindex import LineIndex

    meta["line_index"] = LineIndex(extra["path"])
    meta["line_index_owned"] = True
    return meta["line_index"]


def _fill_raw(con, meta: dict) -> None:
    """Raw text for the quarantined rows staged without it (fast CSV path), from the line index."""
    import pyarrow as pa

    need = np.asarray(con.execute("SELECT line FROM ais_q WHERE raw IS NULL ORDER BY line").fetchnumpy()["line"],
                      dtype=np.int64)
    if len(need) == 0:
        return
    ix = _line_index(con, meta)
    con.register("ais_raw_df", pa.table({"line": need, "raw": pa.array(ix.text(need), pa.string())}))
    try:
        con.execute("UPDATE ais_q SET raw = r.raw FROM ais_raw_df r WHERE ais_q.line = r.line")
    finally:
        con.unregister("ais_raw_df")


class AlreadyLoaded(Exception):
    """The file's fingerprint is already in ``ais_files`` (``record``): nothing is committed."""

    def __init__(self, record: dict):
        super().__init__(f"already loaded as file {record['file_id']} ({record['path']})")
        self.record = record


def classify_and_commit(ws, meta: dict, max_speed_kn: float = C.DEFAULT_MAX_SPEED_KN, before_commit=None) -> dict:
    """Clean ``ais_stage`` and write positions, quarantine, vessels and the file row in ONE
    transaction. ``meta``: ``fingerprint``, ``path``, ``format``, ``size_bytes``, ``ignored``.
    ``fingerprint`` may be a future (a hash still running in a thread): it is awaited only when
    the file's row is written, at the end of the transaction.

    Returns the file's counts: ``read``, ``loaded``, ``quarantined``, ``duplicates``,
    ``static``, ``ignored``, ``reasons``, ``file_id``. ``before_commit`` (tests only) is called
    inside the transaction just before the commit (to kill the process there, or to look at
    the workspace from another cursor).
    """
    con = ws.con
    _prepare(con)
    # Wall seconds of each step, for the benchmark's breakdown (``meta["timings"]``).
    timings = meta.setdefault("timings", {})
    clock = [time.perf_counter()]

    def lap(name: str) -> None:
        now = time.perf_counter()
        timings[name] = now - clock[0]
        clock[0] = now

    with ws.transaction():
        file_id = int(con.execute("SELECT nextval('ais_file_id_seq')").fetchone()[0])
        has_old = bool(con.execute("SELECT EXISTS (SELECT 1 FROM ais_positions)").fetchone()[0])
        out_lines, out_reasons = [], []
        scan_fixes = meta.get("scan_fixes") if _stage_kind(con)[0] == "csvfast" else None
        if has_old and scan_fixes is not None:
            lines, reasons = _outcomes_with_stored(con, float(max_speed_kn), scan_fixes)
            out_lines.append(lines)
            out_reasons += reasons
        elif has_old:
            jumps = _stored_sql_outcomes(con, float(max_speed_kn))
            out_lines.append(jumps)
            out_reasons += [C.SPEED_JUMP] * len(jumps)
        else:
            # First load of these positions: the accepted fixes go to numpy once, sorted by
            # track; repeated (mmsi, time) keys and the jump kernel run there.
            # (Overlapping the kernel with DuckDB's insert in a thread was measured slower: the
            # Arrow-backed stage scan and the kernel's Python parts contend for the GIL, and
            # deleting the flagged rows after the insert makes the commit far costlier.)
            con.execute("CREATE OR REPLACE TEMP TABLE ais_dup (line BIGINT, reason VARCHAR)")
            lines, reasons = _first_load_outcomes(con, float(max_speed_kn), scan_fixes)
            out_lines.append(lines)
            out_reasons += reasons
        del scan_fixes
        all_lines = np.concatenate(out_lines) if out_lines else np.empty(0, dtype=np.int64)
        con.register("ais_out_df", pd.DataFrame({"line": all_lines.astype(np.int64),
                                                 "reason": pd.Series(out_reasons, dtype=object)}))
        try:
            con.execute(
                """CREATE OR REPLACE TEMP TABLE ais_out AS
                SELECT line, reason FROM ais_dup
                UNION ALL SELECT CAST(line AS BIGINT), CAST(reason AS VARCHAR) FROM ais_out_df"""
            )
        finally:
            con.unregister("ais_out_df")
        lap("rules_7_8")

        loaded = con.execute(
            f"""INSERT INTO ais_positions
            SELECT mmsi, make_timestamptz(epoch_us(time_utc)), {_norm()}, ?, line
            FROM ais_stage ANTI JOIN ais_out USING (line) WHERE {_OK}""",
            [file_id],
        ).fetchone()[0]
        lap("insert")
        con.execute(
            """CREATE OR REPLACE TEMP TABLE ais_q AS
            SELECT s.line, coalesce(s.reason0, o.reason) AS reason, s.raw,
                   CASE WHEN s.reason0 IS DISTINCT FROM ? THEN s.mmsi END AS mmsi,
                   CASE WHEN s.reason0 IS DISTINCT FROM ? THEN make_timestamptz(epoch_us(s.time_utc)) END AS time_utc
            FROM ais_stage s LEFT JOIN ais_out o USING (line)
            WHERE s.kind = ? AND (s.reason0 IS NOT NULL OR o.reason IS NOT NULL)""",
            [C.BAD_LINE, C.BAD_LINE, C.KIND_POSITION],
        )
        _fill_raw(con, meta)
        con.execute("INSERT INTO ais_quarantine SELECT ?, line, reason, raw, mmsi, time_utc FROM ais_q", [file_id])
        reasons = dict(con.execute("SELECT reason, count(*) FROM ais_q GROUP BY reason ORDER BY reason").fetchall())
        read, static = con.execute(
            "SELECT count(*) FILTER (WHERE kind = ?), count(*) FILTER (WHERE kind = ?) FROM ais_stage",
            [C.KIND_POSITION, C.KIND_STATIC],
        ).fetchone()
        ignored = int(meta.get("ignored", 0))
        if meta.get("format") in ("dma", "noaa"):
            # lines repeating the header (files concatenated with their headers) are not data
            # either: with the empty lines, lines = 1 + read + ignored
            ignored += int(con.execute(
                "SELECT count(*) FROM ais_stage WHERE kind = ? AND line > 1 AND raw IS NOT NULL AND raw <> ''",
                [C.KIND_IGNORED]).fetchone()[0])
        lap("quarantine")
        _upsert_vessels(con, file_id, meta)
        lap("vessels")
        dups = int(sum(v for k, v in reasons.items() if k in C.DUPLICATE_CODES))
        counts = {
            "file_id": file_id,
            "read": int(read),
            "loaded": int(loaded),
            "quarantined": int(sum(reasons.values())) - dups,
            "duplicates": dups,
            "static": int(static),
            "ignored": ignored,
            "reasons": {str(k): int(v) for k, v in reasons.items()},
        }
        if counts["read"] != counts["loaded"] + counts["quarantined"] + counts["duplicates"]:
            raise AssertionError(f"{meta['path']}: counts do not add up: {counts}")
        fingerprint = meta["fingerprint"]
        if isinstance(fingerprint, Future):
            fingerprint = fingerprint.result()
        lap("fingerprint_wait")
        rec = file_record(ws, fingerprint)
        if rec is not None:  # the same content under another name or compression: roll back
            raise AlreadyLoaded(rec)
        con.execute(
            """INSERT INTO ais_files (file_id, fingerprint, path, format, size_bytes, n_read, n_loaded, n_quarantined,
                   n_duplicates, n_static, n_ignored, reasons, max_speed_kn)
               VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)""",
            [file_id, fingerprint, str(meta["path"]), meta["format"], int(meta["size_bytes"]), counts["read"],
             counts["loaded"], counts["quarantined"], dups, counts["static"], counts["ignored"],
             json.dumps(counts["reasons"], sort_keys=True), float(max_speed_kn)],
        )
        if meta.get("quick_key"):
            con.execute("INSERT INTO ais_file_keys VALUES (?, ?)", [file_id, meta["quick_key"]])
        if before_commit is not None:
            before_commit()
    lap("commit")
    _drop_temp(con)
    return counts


def _upsert_vessels(con, file_id: int, meta: dict | None = None) -> None:
    """Latest non-missing static value per MMSI of this file, merged into ``vessels``.

    The stage is first reduced to its distinct (MMSI, static values) combinations with their
    latest (time, line); typing the text values on those few rows gives the same result as
    typing every row.
    """
    kind, extra = _stage_kind(con)
    registered = []
    # The (time, line) order of rows as one 128-bit integer (lines are below 2^32), far cheaper
    # to aggregate than a struct.
    key = "(epoch_us(coalesce(time_utc, TIMESTAMP '1677-09-22 00:00:00'))::HUGEINT * 4294967296 + line)"
    rows = (f"FROM ais_stage WHERE kind <> '{C.KIND_IGNORED}' AND mmsi BETWEEN {C.MMSI_MIN} AND {C.MMSI_MAX} "
            f"AND parse_error IS DISTINCT FROM '{C.BAD_LINE}'")
    if kind in ("csvhash", "csvfast"):
        # Distinct static field tuples by hash (a 64-bit collision inside one MMSI would merge two
        # tuples: odds ~1e-19 per pair); their texts come from re-splitting the latest raw line
        # (fast CSV stage: the line's text from the line index).
        index = extra["index"]
        texts = ", ".join(f"f[{index[c]}] AS {c}" if c in index else f"CAST(NULL AS VARCHAR) AS {c}"
                          for c in _TEXT_STATIC)
        latest = (f"SELECT mmsi, s_hash, k, tmax, CAST(((k % 4294967296) + 4294967296) % 4294967296 AS BIGINT) AS l "
                  f"FROM (SELECT mmsi, s_hash, max({key}) AS k, max(time_utc) AS tmax {rows} GROUP BY mmsi, s_hash)")
        raw_source = "ais_stage"
        if kind == "csvfast":
            import pyarrow as pa

            fixes = (meta or {}).get("scan_fixes")
            if fixes is not None:
                # The scanned rows reduced where they lie (lanes._tracks.latest_by_static: 0.04 s
                # instead of 0.2-0.3 s for DuckDB's GROUP BY over the Arrow stage on 5 M rows);
                # only the lines typed from their text (ais_exact) are grouped by DuckDB.
                from lanes._tracks import latest_by_static

                g = latest_by_static(fixes["mmsi"], fixes["shash"], fixes["t_us"], fixes["line"], C.MMSI_MIN,
                                     C.MMSI_MAX)
                con.register("ais_latest_scan", pa.table(g))
                registered.append("ais_latest_scan")
                latest = (f"SELECT mmsi, s_hash, k, tmax, CAST(((k % 4294967296) + 4294967296) % 4294967296 AS BIGINT) "
                          f"AS l FROM (SELECT mmsi, shash AS s_hash, t_us::HUGEINT * 4294967296 + line AS k, "
                          f"make_timestamp(t_max) AS tmax FROM ais_latest_scan "
                          f"UNION ALL SELECT mmsi, s_hash, max({key}) AS k, max(time_utc) AS tmax "
                          f"{rows.replace('FROM ais_stage', 'FROM ais_exact')} GROUP BY mmsi, s_hash)")
            con.execute(f"CREATE OR REPLACE TEMP TABLE ais_latest AS {latest}")
            need = np.asarray(con.execute("SELECT DISTINCT l FROM ais_latest ORDER BY l").fetchnumpy()["l"],
                              dtype=np.int64)
            ix = _line_index(con, meta or {})
            con.register("ais_latest_raw", pa.table({"line": pa.array(need),
                                                     "raw": pa.array(ix.text(need), pa.string())}))
            registered.append("ais_latest_raw")
            latest, raw_source = "SELECT * FROM ais_latest", "ais_latest_raw"
        combos = f"""
            latest AS ({latest}),
            split AS (
                SELECT latest.mmsi, latest.k, latest.tmax,
                       CASE WHEN contains(s.raw, '"') THEN ais_csv_split(s.raw) ELSE string_split(s.raw, ',') END AS f
                FROM latest JOIN {raw_source} s ON s.line = latest.l
            ),
            combos AS (SELECT mmsi, k, tmax, {texts} FROM split),"""
        typed = f"typed AS (SELECT mmsi, k, tmax, {_typed_static_select(list(_TEXT_STATIC))} FROM combos),"
    else:
        # Group by the columns that can hold values (Parquet: text; NMEA: typed).
        statics = list(_STAGE_STATIC_COLUMNS.get(kind, C.STATIC_COLUMNS))
        combos = f"""
            combos AS (
                SELECT mmsi, {", ".join(statics)}, max({key}) AS k, max(time_utc) AS tmax
                {rows} GROUP BY mmsi, {", ".join(statics)}
            ),"""
        typed = f"typed AS (SELECT mmsi, k, tmax, {_typed_static_select(statics)} FROM combos),"
    aggs = ",\n".join(f"arg_max({c}, k) FILTER (WHERE {c} IS NOT NULL) AS {c}" for c in C.STATIC_COLUMNS)
    any_set = " OR ".join(f"{c} IS NOT NULL" for c in C.STATIC_COLUMNS)
    merge = ",\n".join(
        f"{c} = CASE WHEN vessels.updated_utc IS NULL OR EXCLUDED.updated_utc >= vessels.updated_utc "
        f"THEN coalesce(EXCLUDED.{c}, vessels.{c}) ELSE coalesce(vessels.{c}, EXCLUDED.{c}) END"
        for c in C.STATIC_COLUMNS
    )
    sql = f"""INSERT INTO vessels
        WITH {combos}
        {typed}
        agg AS (SELECT mmsi, make_timestamptz(epoch_us(max(tmax))) AS updated_utc, {aggs} FROM typed GROUP BY mmsi)
        SELECT mmsi, {", ".join(C.STATIC_COLUMNS)}, updated_utc, $file_id AS file_id FROM agg WHERE {any_set}
        ON CONFLICT (mmsi) DO UPDATE SET {merge},
            updated_utc = greatest(vessels.updated_utc, EXCLUDED.updated_utc),
            file_id = EXCLUDED.file_id"""
    try:
        con.execute(sql, _used(sql, {**_params(), "file_id": file_id}))
    finally:
        for name in registered:
            con.unregister(name)


def _drop_temp(con) -> None:
    con.execute("DROP VIEW IF EXISTS temp.ais_stage_fb")
    con.execute("DROP VIEW IF EXISTS temp.ais_stage")
    for name in ("ais_scan_src", "ais_spot_fast", "ais_fast_pos", "ais_fast_skip", "ais_raw_df", "ais_latest_raw", "ais_lines_df", "ais_spot_rows"):
        try:
            con.unregister(name)
        except Exception:  # noqa: BLE001 - not registered
            pass
    for t in ("ais_stage_t", "ais_dup", "ais_out", "ais_q", "ais_stage_info", "ais_fast", "ais_exact", "ais_spot", "ais_latest", "ais_rejects",
              "ais_reject_scans", "ais_fb"):
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
