"""The raw-lines CSV stage: DuckDB reads every line as text, SQL splits and types it (files below
16 MiB, gzip, and the last fallback of the fast stages)."""

from __future__ import annotations

from pathlib import Path

import duckdb

from ais import clean as C
from ais.io.csv_formats import CsvSpec, MMSI_RE, NAV_STATUS_WORDS
from ais.io.files import content_has
from pipelines.storage.ais._sql import (
    _NUM_FIELDS, _STATIC_TYPES, _TEXT_STATIC, _create_stage, _prepare, _set_stage_kind,
)


_LINE_DELIM = "\x01"
_CSV_LINES = ("read_csv(?, columns={'raw': 'VARCHAR'}, header=false, delim=?, quote='', escape='', "
              "auto_detect=false, compression=?, max_line_size=?)")
#: DuckDB CSV buffer size, None = DuckDB's default. Tests set it small so that even a small file
#: is scanned as many parallel chunks (the stages number rows by their order).
CSV_BUFFER_BYTES = None


def _buffer_option() -> str:
    return "" if CSV_BUFFER_BYTES is None else f", buffer_size = {int(CSV_BUFFER_BYTES)}"


def _csv_typing(index: dict[str, int], fld, inner: str, passthrough: str = "") -> str:
    """The typing SELECT of the CSV stages (rules in :mod:`ais.io.csv_formats`), shared by
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
    """Type a DMA/NOAA CSV file into ``ais_stage`` (rules in :mod:`ais.io.csv_formats`).

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
        if content_has(path, _LINE_DELIM.encode(), stray_cr=True):
            # DuckDB drops a delimiter that ends a line ('x\x01' reads as 'x'; one inside a
            # line is an error), and in a CRLF file it ends a line at a \r alone (a line of the
            # rules, split on \n, is two rows then): such content goes to Python's splitter
            raise duckdb.InvalidInputException("the content holds the line reader's delimiter "
                                               f"{_LINE_DELIM!r} or a \\r not before a \\n")
        sql = _csv_split_typing(index, n_fields, _CSV_LINES.replace("?", "$p_path", 1).replace("?", "$p_delim", 1)
                                .replace("?", "$p_comp", 1).replace("?", "$p_max", 1)[:-1] + _buffer_option() + ")")
        _create_stage(con, sql, {**params, "p_path": str(path), "p_delim": _LINE_DELIM,
                                 "p_comp": "gzip" if gz else "none",
                                 "p_max": (1 << 24) if CSV_BUFFER_BYTES is None else int(CSV_BUFFER_BYTES) // 2},
                      line_from_rowid=True)
    except (duckdb.InvalidInputException, duckdb.ConversionException, duckdb.IOException):
        from ais.io.csv_formats import read_lines
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
