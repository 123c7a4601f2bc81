"""Rules 7-8 of :mod:`ais.clean` (duplicates, speed jumps) over the stage and the one-transaction
commit of a file into ``ais_positions``, ``ais_quarantine``, ``vessels`` and ``ais_files``."""

from __future__ import annotations

import json
import time
from concurrent.futures import Future
from pathlib import Path

import numpy as np
import pandas as pd

from ais import clean as C
from pipelines.storage.ais._sql import _NORM, _VALUES, _drop_temp, _line_index, _norm, _prepare, _stage_kind
from pipelines.storage.ais import parquet
from pipelines.storage.ais.files import file_record
from pipelines.storage.ais.stage_tables import parquet_raw_lines
from pipelines.storage.ais.vessels import _upsert_vessels
from thresholds.units import EARTH_RADIUS_NMI


# ---------------------------------------------------------------------------------------------
# Cleaning (rules 7-8 of ais.clean as SQL + the numpy jump kernel) and the one-transaction commit
# ---------------------------------------------------------------------------------------------
_OK = f"kind = '{C.KIND_POSITION}' AND reason0 IS NULL"


def _dedupe_sql(has_old: bool, stage: str = "ais_stage") -> str:
    """Rows (line, reason) that repeat the (mmsi, time) of an earlier row of the file or of a
    stored row: ``duplicate`` when all normalised values agree, else ``duplicate_time``.

    Stored rows are read only for the MMSIs whose latest stored fix (``ais_track_ends``) is at
    or after their first staged fix: the others' stored keys are all earlier than any of theirs."""
    firsts = ", ".join(f"first_value({v}) OVER w AS f_{v}" for v in _VALUES)
    if has_old:
        same = " AND ".join(f"(CASE WHEN in_db THEN p_{v} ELSE f_{v} END) IS NOT DISTINCT FROM {v}" for v in _VALUES)
        old = f"""old AS (
            SELECT p.mmsi, make_timestamp(epoch_us(p.time_utc)) AS time_utc, {", ".join(f"p.{v} AS p_{v}" for v in _VALUES)}
            FROM ais_positions p SEMI JOIN (
                SELECT s.mmsi FROM (SELECT mmsi, min(time_utc) AS t0 FROM {stage} WHERE {_OK} GROUP BY mmsi) s
                JOIN ais_track_ends e USING (mmsi) WHERE make_timestamp(epoch_us(e.time_utc)) >= s.t0) USING (mmsi)
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

    The stored context of an MMSI is its last stored fix before its first fix in the stage, its
    stored fixes within the stage's span and its first stored fix after it. When the MMSI's
    latest stored fix (``ais_track_ends``) is before its first staged fix (a file continuing
    the stored track, the daily case) that fix is the whole context; only the other MMSIs
    (stored fixes at or after their first staged one: overlapping or out-of-order files) read
    their stored history. So a file's check costs its own rows plus one row per vessel, not the
    stored table (issue 23: the whole-history join grew with the workspace).
    """
    r = float(EARTH_RADIUS_NMI)
    lon = _NORM["lon_deg"]
    new = (f"SELECT s.line, s.mmsi, s.time_utc, s.lat_deg, {lon.replace('lon_deg', 's.lon_deg')} AS lon_deg "
           f"FROM {stage} s ANTI JOIN ais_dup d USING (line) WHERE s.kind = '{C.KIND_POSITION}' AND s.reason0 IS NULL")
    if has_old:
        pre = f"""new AS ({new}),
        span AS (SELECT mmsi, min(time_utc) AS t0, max(time_utc) AS t1 FROM new GROUP BY mmsi),
        te AS (SELECT span.*, make_timestamp(epoch_us(e.time_utc)) AS te_t, e.lat_deg, e.lon_deg
               FROM span JOIN ais_track_ends e USING (mmsi)),
        ex AS (SELECT p.mmsi, make_timestamp(epoch_us(p.time_utc)) AS time_utc, p.lat_deg, p.lon_deg, o.t0, o.t1
               FROM ais_positions p JOIN (SELECT mmsi, t0, t1 FROM te WHERE te_t >= t0) o USING (mmsi)),
        t AS (SELECT * FROM new
            UNION ALL SELECT -1, mmsi, te_t, lat_deg, lon_deg FROM te WHERE te_t < t0
            UNION ALL SELECT -1, mmsi, time_utc, lat_deg, lon_deg FROM ex WHERE time_utc BETWEEN t0 AND t1
            UNION ALL SELECT -1, mmsi, max(time_utc), arg_max(lat_deg, time_utc), arg_max(lon_deg, time_utc) FROM ex
                WHERE time_utc < t0 GROUP BY mmsi
            UNION ALL SELECT -1, mmsi, min(time_utc), arg_min(lat_deg, time_utc), arg_min(lon_deg, time_utc) FROM ex
                WHERE time_utc > t1 GROUP BY mmsi),"""
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
    the speed jumps among the others (``jump``), by :func:`ais._tracks.first_load_rules` over
    ``scan``'s rows with ``ok`` and ``exact``'s rows, merged by line."""
    from ais._tracks import first_load_rules

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
    kept fixes go through :func:`ais.clean.speed_jump_mask`. ``scan_fixes``: the scanned
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
    (:func:`ais._tracks.first_load_rules`): exactly what the SQL path gives it, since its
    only context is that fix and no stored key can repeat one of its keys. The other MMSIs
    (stored fixes inside or after the file's span, or the track going back in time in the
    file) take the SQL path (:func:`_stored_sql_outcomes` on their rows only)."""
    import pyarrow as pa

    from ais._tracks import first_load_rules

    # Each MMSI's latest stored fix (``ais_track_ends``) says both things: a stored fix at or
    # after the file's first one exists iff the latest does, and otherwise the latest is the
    # last stored fix before the file (the context). No stored history is read.
    d = con.execute(f"""
        WITH span AS (SELECT mmsi, min(time_utc) AS t0 FROM ais_stage WHERE {_OK} GROUP BY mmsi)
        SELECT span.mmsi, e.time_utc >= span.t0 AS later,
               CASE WHEN e.time_utc < span.t0 THEN epoch_us(e.time_utc) ELSE 0 END AS t_us,
               CASE WHEN e.time_utc < span.t0 THEN e.lat_deg ELSE 0.0 END AS lat,
               CASE WHEN e.time_utc < span.t0 THEN e.lon_deg ELSE 0.0 END AS lon
        FROM span JOIN (SELECT mmsi, make_timestamp(epoch_us(time_utc)) AS time_utc, lat_deg, lon_deg
                        FROM ais_track_ends) e USING (mmsi)
        ORDER BY span.mmsi""").fetchnumpy()
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


def _insert_quarantine(con, meta: dict, file_id: int) -> None:
    """``ais_q`` into ``ais_quarantine`` under the input's lines (:func:`_line_source`), with the
    raw text of the rows staged without it: from the Parquet file
    (:func:`stage_tables.parquet_raw_lines`) or from the line index (fast CSV path).

    Joined in the insert, not updated into ``ais_q`` first: a Parquet file of 2.9 M rows all
    quarantined (DMA status words in its status column) ran out of DuckDB's 1 GB memory in that
    ``UPDATE`` (issue 23)."""
    import pyarrow as pa

    line, join = _line_source(meta)
    insert = (f"INSERT INTO ais_quarantine SELECT ?, {line}, q.reason, coalesce(q.raw, r.raw), q.mmsi, q.time_utc "
              "FROM ais_q q LEFT JOIN {raw} r USING (line) " + join)
    extra = _stage_kind(con)[1]
    if "raw_path" in extra:
        con.execute(insert.format(raw=parquet_raw_lines(extra, "SELECT line FROM ais_q WHERE raw IS NULL")), [file_id])
        return
    need = np.asarray(con.execute("SELECT line FROM ais_q WHERE raw IS NULL ORDER BY line").fetchnumpy()["line"],
                      dtype=np.int64)
    texts = _line_index(con, meta).text_array(need) if len(need) else pa.array([], pa.large_string())
    con.register("ais_raw_df", pa.table({"line": need, "raw": texts}))
    try:
        con.execute(insert.format(raw="ais_raw_df"), [file_id])
    finally:
        con.unregister("ais_raw_df")


class AlreadyLoaded(Exception):
    """The file's fingerprint is already in ``ais_files`` (``record``): nothing is committed."""

    def __init__(self, record: dict):
        super().__init__(f"already loaded as file {record['file_id']} ({record['path']})")
        self.record = record


def _has_positions(con) -> bool:
    return bool(con.execute("SELECT EXISTS (SELECT 1 FROM ais_positions)").fetchone()[0])


def _rules_7_8(con, meta: dict, max_speed_kn: float) -> None:
    """Rules 7-8 (repeated keys, speed jumps) of the staged rows into the temp table ``ais_out``
    (line, reason): the streaming pass on a first load, else with the stored fixes as context.
    ``meta["has_old"]``: whether positions were stored before the file (a group of a file split
    by MMSI is a first load when the file is: the groups hold other vessels)."""
    has_old = meta.get("has_old")
    if has_old is None:
        has_old = _has_positions(con)
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


def _write_quarantine(con, meta: dict, file_id: int) -> tuple[dict, int, int, int]:
    """Every staged row not loaded into ``ais_quarantine`` (with its raw text, under the input's
    line: :func:`_line_source`); returns the reason counts and the read, static and ignored
    counts of the stage."""
    con.execute(
        """CREATE OR REPLACE TEMP TABLE ais_q AS
        SELECT s.line, coalesce(s.reason0, o.reason) AS reason, s.raw,
               CASE WHEN s.reason0 IS DISTINCT FROM ? THEN s.mmsi END AS mmsi,
               CASE WHEN s.reason0 IS DISTINCT FROM ? THEN make_timestamptz(epoch_us(s.time_utc)) END AS time_utc
        FROM ais_stage s LEFT JOIN ais_out o USING (line)
        WHERE s.kind = ? AND (s.reason0 IS NOT NULL OR o.reason IS NOT NULL)""",
        [C.BAD_LINE, C.BAD_LINE, C.KIND_POSITION],
    )
    _insert_quarantine(con, meta, file_id)
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
    return reasons, int(read), int(static), ignored


def _write_file_row(ws, meta: dict, fingerprint: str, file_id: int, counts: dict, max_speed_kn: float) -> None:
    """The file's row in ``ais_files`` (and its quick key); a file whose content is loaded already
    (another name or compression) rolls back as :class:`AlreadyLoaded`."""
    rec = file_record(ws, fingerprint)
    if rec is not None:  # the same content under another name or compression: roll back
        raise AlreadyLoaded(rec)
    ws.con.execute(
        """INSERT INTO ais_files (file_id, fingerprint, path, format, size_bytes, n_read, n_loaded, n_quarantined,
               n_duplicates, n_static, n_ignored, reasons, max_speed_kn)
           VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)""",
        [file_id, fingerprint, str(meta["path"]), meta["format"], int(meta["size_bytes"]), counts["read"],
         counts["loaded"], counts["quarantined"], counts["duplicates"], counts["static"], counts["ignored"],
         json.dumps(counts["reasons"], sort_keys=True), float(max_speed_kn)],
    )
    if meta.get("quick_key"):
        ws.con.execute("INSERT INTO ais_file_keys VALUES (?, ?)", [file_id, meta["quick_key"]])


def _update_track_ends(con, file_id: int) -> None:
    """Each MMSI's latest stored fix, after the file's positions (``ais_new``) were inserted
    (same transaction)."""
    con.execute(
        """INSERT INTO ais_track_ends
           SELECT mmsi, max(time_utc), arg_max(lat_deg, time_utc), arg_max(lon_deg, time_utc)
           FROM ais_new WHERE file_id = ? GROUP BY mmsi
           ON CONFLICT (mmsi) DO UPDATE SET time_utc = excluded.time_utc, lat_deg = excluded.lat_deg,
               lon_deg = excluded.lon_deg
           WHERE excluded.time_utc > ais_track_ends.time_utc""", [int(file_id)])


def _next_file_id(con) -> int:
    """The file's id: one more than the largest stored, taken inside its transaction (one writer).
    A file rolled back (the same content under another name or compression, known only by its
    fingerprint at the end: :class:`AlreadyLoaded`) then uses no id, so the sequential ingest
    and the partitioned one (which skips such a file before its transaction) number the files
    alike. DuckDB's sequences are not transactional: ``nextval`` counted the rolled-back file
    too (the schema's ``ais_file_id_seq`` is no longer drawn from). The tables keyed by file id
    are all asked, so that a file row removed by hand never hands its id to another file."""
    return int(con.execute(
        "SELECT greatest((SELECT max(file_id) FROM ais_files), (SELECT max(file_id) FROM ais_file_keys), "
        "(SELECT max(file_id) FROM ais_parquet_parts), 0) + 1").fetchone()[0])


def _line_source(meta: dict) -> tuple[str, str]:
    """(SQL of a stage row's line in the input, the join it needs): the stage's own line, or for
    a group of a file split by MMSI (``meta["line_map"]``, registered as ``ais_line_map`` by
    :func:`_commit_groups`) the input's line of the group's line."""
    if meta.get("line_map") is None:
        return "line", ""
    return "ais_line_map.orig", "JOIN ais_line_map USING (line)"


class _Laps:
    """Wall seconds of each step, summed over a file's groups (``meta["timings"]``)."""

    def __init__(self, meta: dict):
        self.timings = meta.setdefault("timings", {})
        self.clock = time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.timings[name] = self.timings.get(name, 0.0) + now - self.clock
        self.clock = now


def _commit_rows(ws, meta: dict, file_id: int, max_speed_kn: float, laps: _Laps, start_parts) -> dict:
    """Inside the file's transaction: rules 7-8 of the installed stage, then its positions (with
    the track ends), quarantine and vessels. ``start_parts(new)`` is called once the rows to
    insert are in ``ais_new`` (the Parquet parts are written from them; ``new``: those rows as
    an Arrow table when they are one, a group's, else None). Returns the stage's counts."""
    con = ws.con
    _rules_7_8(con, meta, max_speed_kn)
    laps("rules_7_8")
    # The rows once, in a temporary table (a group's: a mapped file, below): inserted, then read
    # again for the track ends and the Parquet parts without scanning the stored positions
    # (issue 23: that scan grew with the workspace).
    line, join = _line_source(meta)
    rows = (f"SELECT mmsi, make_timestamptz(epoch_us(time_utc)) AS time_utc, {_norm()}, "
            f"CAST(? AS INTEGER) AS file_id, {line} AS source_line "
            f"FROM ais_stage ANTI JOIN ais_out USING (line) {join} WHERE {_OK}")
    new = None
    if meta.get("line_map") is None:
        con.execute(f"CREATE OR REPLACE TEMP TABLE ais_new AS {rows}", [file_id])
    else:
        # A group's rows as a memory-mapped file: DuckDB keeps a temporary table (or a registered
        # object) dropped inside a transaction until the commit (measured: +125 MB per 1.1 M-row
        # group as a table, the file's groups adding up).
        from pipelines.storage.ais import spool

        path = Path(meta["folder"]) / f"{meta['name']}.new.arrow"
        spool.write_ipc(parquet._fetch_arrow(con, rows, [file_id]), path)
        new = spool.read_ipc(path)
        con.register("ais_new", new)
    start_parts(new)
    loaded = con.execute("INSERT INTO ais_positions SELECT * FROM ais_new").fetchone()[0]
    _update_track_ends(con, file_id)
    laps("insert")
    reasons, read, static, ignored = _write_quarantine(con, meta, file_id)
    laps("quarantine")
    _upsert_vessels(con, file_id, meta)
    laps("vessels")
    return {"loaded": int(loaded), "reasons": reasons, "read": read, "static": static, "ignored": ignored}


def _commit_groups(ws, meta: dict, groups, file_id: int, max_speed_kn: float, laps: _Laps, sink) -> list[dict]:
    """:func:`_commit_rows` of each group of a file split by MMSI, one after the other inside the
    file's transaction; each ``install()`` of ``groups`` puts its group's stage in place and
    returns its meta: ``line_map`` (an Arrow table of the group's ``line`` and the input's
    ``orig``), ``ignored``, ``folder`` and ``name`` (where its rows to insert are mapped from),
    and a scan stage's ``line_index`` and ``scan_fixes``. Every group
    is a first load when the file is (the groups hold other vessels)."""
    con = ws.con
    has_old = _has_positions(con)
    out = []
    for install in groups:
        gmeta = {"path": meta["path"], "format": meta["format"], "timings": laps.timings, "has_old": has_old,
                 **install()}
        laps("stage")
        con.register("ais_line_map", gmeta["line_map"])
        try:
            counts = _commit_rows(ws, gmeta, file_id, max_speed_kn, laps,
                                  lambda new: sink.add(new) if sink is not None else None)
        finally:
            con.unregister("ais_line_map")
            if gmeta.get("line_index") is not None:
                gmeta["line_index"].close()
            _drop_temp(con)
            if gmeta.get("release") is not None:
                gmeta["release"]()
        out.append(counts)
    return out


def _file_counts(file_id: int, parts: list[dict], meta: dict) -> dict:
    """The file's counts from those of its stage (or groups); checks read = loaded + quarantined
    + duplicates."""
    reasons: dict = {}
    for p in parts:
        for k, v in p["reasons"].items():
            reasons[str(k)] = reasons.get(str(k), 0) + int(v)
    reasons = dict(sorted(reasons.items()))
    dups = int(sum(v for k, v in reasons.items() if k in C.DUPLICATE_CODES))
    counts = {"file_id": file_id, "read": sum(int(p["read"]) for p in parts),
              "loaded": sum(p["loaded"] for p in parts), "quarantined": int(sum(reasons.values())) - dups,
              "duplicates": dups, "static": sum(int(p["static"]) for p in parts),
              "ignored": sum(int(p["ignored"]) for p in parts), "reasons": reasons}
    if counts["read"] != counts["loaded"] + counts["quarantined"] + counts["duplicates"]:
        raise AssertionError(f"{meta['path']}: counts do not add up: {counts}")
    return counts


def classify_and_commit(ws, meta: dict, max_speed_kn: float = C.DEFAULT_MAX_SPEED_KN, before_commit=None,
                        groups=None) -> dict:
    """Clean ``ais_stage`` and write positions, quarantine, vessels and the file row in ONE
    transaction. ``meta``: ``fingerprint``, ``path``, ``format``, ``size_bytes``, ``ignored``.
    ``fingerprint`` may be a future (a hash still running in a thread): it is awaited only when
    the file's row is written, at the end of the transaction. ``groups`` (a large CSV file split
    by MMSI, :mod:`ais.io.csv_buckets`): instead of one installed stage, functions installing
    each group's stage in turn (:func:`_commit_groups`), all committed in this transaction.

    Returns the file's counts: ``read``, ``loaded``, ``quarantined``, ``duplicates``,
    ``static``, ``ignored``, ``reasons``, ``file_id``. ``before_commit`` (tests only) is called
    inside the transaction just before the commit (to kill the process there, or to look at
    the workspace from another cursor).
    """
    from pipelines.storage.ais.parquet_groups import GroupParts

    con = ws.con
    _prepare(con)
    laps = _Laps(meta)
    # The transaction by hand (not ws.transaction()): the Parquet parts written inside it are
    # published after its commit, or removed after its rollback.
    parts: list = []
    pending = None
    con.execute("BEGIN TRANSACTION")
    try:
        file_id = _next_file_id(con)
        if groups is None:
            def start_parts(_new) -> None:
                nonlocal pending  # known to the rollback below as soon as the writer runs
                pending = parquet.start_file_parts(ws, file_id, source="ais_new")

            per_stage = [_commit_rows(ws, meta, file_id, max_speed_kn, laps, start_parts)]
        else:
            pending = GroupParts.start(ws, file_id)
            per_stage = _commit_groups(ws, meta, groups, file_id, max_speed_kn, laps, pending)
        counts = _file_counts(file_id, per_stage, meta)
        fingerprint = meta["fingerprint"]
        if isinstance(fingerprint, Future):
            fingerprint = fingerprint.result()
        laps("fingerprint_wait")
        _write_file_row(ws, meta, fingerprint, file_id, counts, max_speed_kn)
        parts = pending.finish() if pending is not None else []
        pending = None
        laps("parquet_wait")
        if before_commit is not None:
            before_commit()
    except BaseException:
        con.execute("ROLLBACK")
        if pending is not None:
            pending.abandon()
        parquet.discard(parts)
        raise
    try:
        con.execute("COMMIT")
    except BaseException:
        parquet.discard(parts)
        raise
    parquet.publish(parts)
    laps("commit")
    _drop_temp(con)
    _checkpoint(con)
    laps("checkpoint")
    return counts


#: DuckDB's memory limit on the workspace connection of an ingest [MB]. DuckDB keeps the blocks
#: it wrote cached while it is under its limit (default 80 % of RAM): about 20 bytes per loaded
#: row, 169 MB after 8.61 M rows, so the ingest's peak grew with the rows. Under this limit the
#: cache is evicted (the blocks are on disk) and larger temporary tables spill to
#: ``<workspace>.tmp``. Measured (300-ship fleet, issue 23): with a 100 MB limit the peak RSS was
#: 613 MB at 2.05 M rows and 628 MB at 8.61 M rows, the same CPU time; but the raw-lines CSV
#: reader allocates 256 MiB buffers (a 256 MB limit failed on it), hence 1 GB: the cache
#: grows to it (about 50 M rows) and no further.
INGEST_MEMORY_LIMIT_MB = 1024


def limit_ingest_memory(ws) -> None:
    """Cap DuckDB's memory on a workspace opened for an ingest (:data:`INGEST_MEMORY_LIMIT_MB`)."""
    ws.con.execute(f"SET memory_limit = '{int(INGEST_MEMORY_LIMIT_MB)}MB'")


def _checkpoint(con) -> None:
    """Checkpoint after each file, so that each checkpoint folds one file's rows into the
    database file. DuckDB writes a large insert's row groups straight to the file and logs only
    their metadata, so the write-ahead log never reaches the automatic checkpoint threshold
    during an ingest: the checkpoint at close then processed every file at once and its peak
    memory grew with the rows loaded (measured, 300-ship fleet: +60 MB after 2.05 M rows,
    +490 MB after 8.61 M rows; issue 23). Skipped when another transaction is open."""
    import duckdb

    try:
        con.execute("CHECKPOINT")
    except duckdb.TransactionException:
        pass


def discard_stage(ws) -> None:
    """Drop the temporary staging tables (after an error)."""
    _drop_temp(ws.con)
