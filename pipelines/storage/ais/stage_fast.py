"""The fast CSV stages of large plain files: the compiled scan (:mod:`ais.io.csv_scan`), DuckDB's
scanner split and pyarrow's split, each checked against the text of a sample of lines."""

from __future__ import annotations

import logging
import time
from pathlib import Path

import duckdb
import numpy as np

from ais import clean as C
from ais.io.csv_formats import CsvSpec, NAV_STATUS_WORDS
from pipelines.storage.ais._sql import (
    _NUM_FIELDS, _TEXT_STATIC, _create_stage, _drop_temp, _params, _prepare, _q, _reason_case,
    _set_stage_kind, _used,
)
from pipelines.storage.ais import stage_lines  # CSV_BUFFER_BYTES read at call time (tests set it)
from pipelines.storage.ais.stage_lines import _buffer_option, _csv_params, _csv_split_typing, _csv_typing


log = logging.getLogger(__name__)

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

    ``line_index`` (a :class:`ais.io.lineindex.LineIndex`, or a future of one built in a
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
            pcsv.ReadOptions(block_size=int(stage_lines.CSV_BUFFER_BYTES or ARROW_BLOCK_BYTES), column_names=names, skip_rows=1,
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

    :func:`ais.io.csv_scan.scan_csv` reads the memory-mapped file once (one range per core)
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

    from ais.io.csv_scan import KIND_SPECIAL, TIME_LAYOUTS, scan_csv
    from ais.io.lineindex import LineIndex

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
    _create_exact_stage(con, special, ix, spec, index, int(n_fields), header)
    times["exact_lines"] = time.perf_counter() - t1 - times["spot_check"]
    install_scan_stage(con, tbl, path, {"header": header,
                                        "index": {c: index[c[2:]] + 1 for c in _TEXT_STATIC if c[2:] in index}})
    blank = ix.blank_lines[ix.blank_lines > 1]
    times["total"] = time.perf_counter() - t0
    log.info("%s: scan stage %s", path, {k: round(v, 2) for k, v in times.items()})
    # ``scan_table``: the scanned rows, for a spool (pipelines.storage.ais.spool); a caller
    # committing in place drops it (the stage holds it while registered).
    return {"ignored": int(len(blank)), "python_fallback": False, "staging": "scan", "line_index": ix,
            "exact_lines": int(len(special)), "line_mapping": "scan", "timings": times, "scan_fixes": fixes,
            "scan_table": tbl}


def install_scan_stage(con, tbl, path, extra: dict) -> None:
    """``ais_stage`` of a scanned file: the scanned rows ``tbl`` (an Arrow table, registered as
    ``ais_scan_src``: no copy into DuckDB) and the temp table ``ais_exact`` (the lines typed
    from their text, created by the caller); ``path`` is the plain file the line numbers refer
    to, ``extra`` the stage kind's ``header`` and static-field ``index``."""
    con.register("ais_scan_src", tbl)
    con.execute(f"""CREATE OR REPLACE TEMP VIEW ais_stage AS
        SELECT * FROM ais_exact
        UNION ALL BY NAME SELECT line, CAST(NULL AS VARCHAR) AS raw, '{C.KIND_POSITION}' AS kind, * EXCLUDE (line)
        FROM ais_scan_src""")
    _set_stage_kind(con, "csvfast", {**extra, "path": str(path)})


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

    from ais.io.csv_scan import NULL_TIME

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
