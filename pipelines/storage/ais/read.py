"""Readers of the AIS tables (positions, vessels, quarantine) and waiting for a writer's lock."""

from __future__ import annotations

import time

import duckdb
import numpy as np
import pandas as pd

from ais import clean as C


# ---------------------------------------------------------------------------------------------
# Readers
# ---------------------------------------------------------------------------------------------
def _utc(df: pd.DataFrame, cols=("time_utc",)) -> pd.DataFrame:
    for c in cols:
        if c in df.columns:
            df[c] = pd.to_datetime(df[c], utc=True).astype("datetime64[ns, UTC]")
    return df


def read_positions(ws, mmsi=None, start=None, end=None, mmsi_range=None, columns=None) -> pd.DataFrame:
    """Canonical positions sorted by ``mmsi``, ``time_utc``.

    Parameters
    ----------
    mmsi : int or list of int, optional
        Only these vessels.
    start, end : datetime-like, optional
        Only ``start <= time_utc < end`` (naive values are taken as UTC).
    mmsi_range : (int, int), optional
        Only ``lo <= mmsi <= hi`` (a bucket of whole tracks).
    columns : list of str, optional
        Only these of the canonical columns, in the canonical order (default: all). The lanes
        read five of the eight: about half the CPU of reading all (issue 23, docs/scale.md).
    """
    cols = [c for c in C.POSITION_COLUMNS if columns is None or c in columns]
    unknown = sorted(set(columns or ()) - set(C.POSITION_COLUMNS))
    if unknown:
        raise ValueError(f"read_positions: unknown column(s) {unknown}; the canonical columns are {C.POSITION_COLUMNS}")
    where, params = [], []
    if mmsi is not None:
        ids = [int(m) for m in (mmsi if np.ndim(mmsi) else [mmsi])]
        where.append("list_contains(?, mmsi)")
        params.append(ids)
    if mmsi_range is not None:
        where.append("mmsi BETWEEN ? AND ?")
        params += [int(mmsi_range[0]), int(mmsi_range[1])]
    for bound, op in ((start, ">="), (end, "<")):
        if bound is not None:
            ts = pd.Timestamp(bound)
            ts = ts.tz_localize("UTC") if ts.tzinfo is None else ts.tz_convert("UTC")
            where.append(f"time_utc {op} ?")
            params.append(ts.to_pydatetime())
    sql = f"SELECT {', '.join(cols)} FROM ais_positions"
    if where:
        sql += " WHERE " + " AND ".join(where)
    sql += " ORDER BY mmsi, time_utc"
    return _canonical(ws.con.execute(sql, params).fetchdf())


def _canonical(df: pd.DataFrame) -> pd.DataFrame:
    """The canonical dtypes of a positions frame (what :func:`read_positions` returns)."""
    if "mmsi" in df.columns:
        df["mmsi"] = df["mmsi"].astype("int64")
    for c in C.POSITION_COLUMNS[2:]:
        if c in df.columns:
            df[c] = df[c].astype("float64")
    return _utc(df)


#: A position column of the GeoParquet dataset (``pipelines.storage.ais.parquet``): the point's
#: coordinates are its ``geometry`` (x = longitude, y = latitude), the other columns their own.
_PARQUET_COLUMN = {"lat_deg": "geometry.y", "lon_deg": "geometry.x"}


def read_positions_parquet(glob: str, mmsi_range: tuple[int, int], columns, memory_limit_mb: int) -> pd.DataFrame:
    """Canonical positions with ``lo <= mmsi <= hi`` from the positions dataset's parts
    (``glob``), sorted by ``mmsi``, ``time_utc``: the same frame as :func:`read_positions` of the
    workspace the dataset belongs to (kept consistent with it by every ingest; tested), read
    without the workspace (any process that sees the files, e.g. a Dask worker). The parts are
    sorted by MMSI within each day, so DuckDB skips the row groups outside the range.

    The sort spills beyond ``memory_limit_mb`` to a temporary folder of this call's own (an
    in-memory DuckDB spills to ``.tmp`` in the working directory, where two worker processes
    started in the same folder overwrote each other's spill files: seen at 108 M rows)."""
    import tempfile

    cols = [c for c in C.POSITION_COLUMNS if c in columns]
    select = ", ".join(f"{_PARQUET_COLUMN[c]} AS {c}" if c in _PARQUET_COLUMN else c for c in cols)
    with tempfile.TemporaryDirectory(prefix="stormlane-read-") as spill:
        con = duckdb.connect(config={"memory_limit": f"{int(memory_limit_mb)}MB", "temp_directory": spill})
        try:
            con.execute("SET TimeZone = 'UTC'")
            df = con.execute(f"SELECT {select} FROM read_parquet(?, hive_partitioning = false) "
                             "WHERE mmsi BETWEEN ? AND ? ORDER BY mmsi, time_utc",
                             [glob, int(mmsi_range[0]), int(mmsi_range[1])]).fetchdf()
        finally:
            con.close()
    return _canonical(df)


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


def positions_per_mmsi(ws) -> pd.DataFrame:
    """``mmsi``, ``n`` (stored positions) per vessel, by ``mmsi``: what bucketing by vessel needs."""
    return ws.con.execute("SELECT mmsi, count(*) AS n FROM ais_positions GROUP BY mmsi ORDER BY mmsi").fetchdf()
