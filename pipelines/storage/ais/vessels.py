"""Table ``vessels``: one row per MMSI, the latest non-missing value of each static field."""

from __future__ import annotations

import numpy as np

from ais import clean as C
from pipelines.storage.ais._sql import (
    _STAGE_STATIC_COLUMNS, _TEXT_STATIC, _line_index, _params, _stage_kind, _typed_static_select, _used,
)


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
    # The line of a key ``k`` (its low 32 bits), and each (MMSI, hash of the static fields) with
    # its latest (time, line) key ``k`` and line ``l``.
    line_of_k = "CAST(((k % 4294967296) + 4294967296) % 4294967296 AS BIGINT)"
    by_hash = (f"SELECT mmsi, s_hash, k, tmax, {line_of_k} AS l "
               f"FROM (SELECT mmsi, s_hash, max({key}) AS k, max(time_utc) AS tmax {rows} GROUP BY mmsi, s_hash)")
    statics = list(_TEXT_STATIC)  # the static fields typed from their texts (below: every path but the last)
    if kind in ("csvhash", "csvfast"):
        # Distinct static field tuples by hash (a 64-bit collision inside one MMSI would merge two
        # tuples: odds ~1e-19 per pair); their texts come from re-splitting the latest raw line
        # (fast CSV stage: the line's text from the line index).
        index = extra["index"]
        texts = ", ".join(f"f[{index[c]}] AS {c}" if c in index else f"CAST(NULL AS VARCHAR) AS {c}"
                          for c in _TEXT_STATIC)
        latest = by_hash
        raw_source = "ais_stage"
        if kind == "csvfast":
            import pyarrow as pa

            fixes = (meta or {}).get("scan_fixes")
            if fixes is not None:
                # The scanned rows reduced where they lie (ais._tracks.latest_by_static: 0.04 s
                # instead of 0.2-0.3 s for DuckDB's GROUP BY over the Arrow stage on 5 M rows);
                # only the lines typed from their text (ais_exact) are grouped by DuckDB.
                from ais._tracks import latest_by_static

                g = latest_by_static(fixes["mmsi"], fixes["shash"], fixes["t_us"], fixes["line"], C.MMSI_MIN,
                                     C.MMSI_MAX)
                con.register("ais_latest_scan", pa.table(g))
                registered.append("ais_latest_scan")
                latest = (f"SELECT mmsi, s_hash, k, tmax, {line_of_k} "
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
    elif "static_columns" in extra:
        # A Parquet stage without texts: its rows grouped by (MMSI, hash of the static values),
        # the texts of each group's latest row read from the file (stage_tables.parquet_raw_lines).
        from pipelines.storage.ais.stage_tables import parquet_raw_lines

        texts = ", ".join(f"r.{c}" for c in _TEXT_STATIC)
        combos = f"""
            latest AS MATERIALIZED ({by_hash}),
            combos AS (SELECT latest.mmsi, latest.k, latest.tmax, {texts} FROM latest
                       JOIN {parquet_raw_lines(extra, "SELECT l FROM latest", statics=True, raw=False)} r
                       ON r.line = latest.l),"""
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
