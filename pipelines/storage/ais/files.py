"""Table ``ais_files`` (and ``ais_file_keys``): which files are loaded, under which fingerprints."""

from __future__ import annotations

import json

import pandas as pd


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
