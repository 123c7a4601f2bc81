"""The positions as a partitioned GeoParquet dataset beside the workspace (issue 23).

Every file the ingest commits into ``ais_positions`` is also written, by the same load, to

    <workspace folder>/<workspace stem>.parquet/positions/day=YYYY-MM-DD/file-<file_id>.parquet

one file per (AIS file, UTC day of its rows), hive-style by day, rows sorted by ``mmsi`` then
``time_utc``, in row groups of :data:`ROW_GROUP_ROWS` (their ``mmsi`` statistics let a reader
of a few vessels skip the rest). So Dask workers, DuckDB (``read_parquet('.../positions/**/*.parquet',
hive_partitioning = true)``), pyarrow, GDAL or geopandas read the positions without going through
the workspace's single writer (DuckDB's file lock).

Columns: ``mmsi``, ``time_utc`` (UTC, microseconds), ``sog_kn``, ``cog_deg``, ``heading_deg``,
``nav_status``, ``file_id``, ``source_line`` as in ``ais_positions``; the position as the
GeoParquet geometry column ``geometry`` in the native ``point`` encoding (a struct of doubles
``x`` = ``lon_deg`` and ``y`` = ``lat_deg``, bit for bit the workspace's values); and the
GeoParquet 1.1 bounding-box covering column ``bbox`` (``xmin``, ``ymin``, ``xmax``, ``ymax`` as
FLOAT, each rounded outward so that the box contains the point) [1]. The file metadata key
``geo`` holds the GeoParquet 1.1.0 metadata (primary column, encoding, geometry type, the file's
bbox, the covering; no ``crs``: longitude/latitude on WGS 84, OGC:CRS84). Encodings: byte-stream
split for the coordinates, delta for times and lines, dictionaries for the small-valued columns,
zstd: about 25 bytes per position (the workspace holds about 32).

Consistency with the workspace (one writer, crash-safe as the ingest):

1. inside the file's transaction, :func:`start_file_parts` writes each part under a hidden
   temporary name (``.file-<id>.parquet.<pid>.tmp``, which readers skip) from the rows being
   inserted (in a thread, while the transaction goes on) and :meth:`PendingParts.finish` records
   it in ``ais_parquet_parts`` (file id, day, rows) before the commit;
2. after the commit, :func:`publish` renames each part to its final name (atomic);
3. :func:`sync_positions_parquet` (run by every ingest before it loads and by the lanes before
   they read) makes the folder what ``ais_parquet_parts`` says: a part recorded but missing is
   renamed from its temporary file (a crash between 1's commit and 2) or written again from the
   workspace (a deleted folder, a workspace from before this dataset); temporary files of
   uncommitted loads and parts not recorded are removed.

So the dataset always converges to the workspace's positions, a rerun writes nothing, and the
files written again are byte-identical to the first ones (the same rows through the same
writer).

References
----------
.. [1] Open Geospatial Consortium, "GeoParquet specification," version 1.1.0,
       https://geoparquet.org/releases/v1.1.0/ (columns, "covering", bounding box columns,
       native "point" encoding).
"""

from __future__ import annotations

import json
import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Rows per Parquet row group (its mmsi min/max prune the groups a vessel bucket does not need).
ROW_GROUP_ROWS = 65_536
GEOPARQUET_VERSION = "1.1.0"
_PART_RE = re.compile(r"^file-(\d{9})\.parquet$")
_TMP_RE = re.compile(r"^\.file-(\d{9})\.parquet\.\d+\.tmp$")
_DAY_RE = re.compile(r"^day=(\d{4}-\d{2}-\d{2})$")
#: The canonical columns of a position, in ``ais_positions`` order.
CANONICAL_COLUMNS = ("mmsi", "time_utc", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status",
                     "file_id", "source_line")


def dataset_root(db_path) -> Path | None:
    """``<folder>/<stem>.parquet`` beside the workspace file; None for an in-memory workspace."""
    if db_path is None or str(db_path) in ("", ":memory:"):
        return None
    p = Path(db_path)
    return p.parent / f"{p.stem}.parquet"


def positions_root(db_path) -> Path | None:
    """The positions dataset folder of the workspace at ``db_path`` (None in memory)."""
    root = dataset_root(db_path)
    return None if root is None else root / "positions"


def part_name(file_id: int) -> str:
    return f"file-{int(file_id):09d}.parquet"


@dataclass(frozen=True)
class Part:
    """One written part: its final path and the temporary file it is published from."""

    path: Path
    tmp: Path
    rows: int


def _bbox_bounds(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """FLOAT bounds that contain each double value: float32 rounded down and up."""
    f = values.astype(np.float32)
    back = f.astype(np.float64)
    lo = np.where(back > values, np.nextafter(f, np.float32(-np.inf)), f)
    hi = np.where(back < values, np.nextafter(f, np.float32(np.inf)), f)
    return lo.astype(np.float32), hi.astype(np.float32)


def bbox_of(lon: np.ndarray, lat: np.ndarray) -> list[float]:
    """[xmin, ymin, xmax, ymax] of points (at least one)."""
    return [float(lon.min()), float(lat.min()), float(lon.max()), float(lat.max())]


def geoparquet_table(table, extent: list | None = None):
    """Canonical positions (an Arrow table with :data:`CANONICAL_COLUMNS`) as the dataset's
    GeoParquet table: ``geometry`` and ``bbox`` instead of ``lat_deg``/``lon_deg``, the ``geo``
    metadata with the table's bounding box (``extent``, [xmin, ymin, xmax, ymax], when the table
    is one slice of a part written in slices)."""
    import pyarrow as pa

    lat = table.column("lat_deg").to_numpy()
    lon = table.column("lon_deg").to_numpy()
    xlo, xhi = _bbox_bounds(lon)
    ylo, yhi = _bbox_bounds(lat)
    geometry = pa.StructArray.from_arrays([pa.array(lon, pa.float64()), pa.array(lat, pa.float64())], names=["x", "y"])
    bbox = pa.StructArray.from_arrays([pa.array(xlo), pa.array(ylo), pa.array(xhi), pa.array(yhi)],
                                      names=["xmin", "ymin", "xmax", "ymax"])
    out = table.drop_columns(["lat_deg", "lon_deg"]).append_column("geometry", geometry).append_column("bbox", bbox)
    # one time type whatever the session's TimeZone setting (``UTC`` or ``Etc/UTC``): the parts
    # written again by :func:`sync_positions_parquet` are then byte-identical
    k = out.schema.get_field_index("time_utc")
    out = out.set_column(k, "time_utc", out.column(k).cast(pa.timestamp("us", tz="UTC")))
    if extent is None:
        extent = bbox_of(lon, lat) if len(lat) else []
    geo = {
        "version": GEOPARQUET_VERSION,
        "primary_column": "geometry",
        "columns": {"geometry": {
            "encoding": "point",
            "geometry_types": ["Point"],
            "bbox": extent,
            "covering": {"bbox": {k: ["bbox", k] for k in ("xmin", "ymin", "xmax", "ymax")}},
        }},
    }
    if not extent:
        del geo["columns"]["geometry"]["bbox"]
    return out.replace_schema_metadata({b"geo": json.dumps(geo, separators=(",", ":")).encode()})


def writer_options() -> dict:
    """The dataset's Parquet writer options (module docstring: encodings, zstd)."""
    floats = ["geometry.x", "geometry.y", "bbox.xmin", "bbox.ymin", "bbox.xmax", "bbox.ymax"]
    encodings = {c: "BYTE_STREAM_SPLIT" for c in floats}
    encodings.update({"time_utc": "DELTA_BINARY_PACKED", "source_line": "DELTA_BINARY_PACKED"})
    return {"compression": "zstd", "use_dictionary": ["mmsi", "file_id", "sog_kn", "cog_deg", "heading_deg",
                                                      "nav_status"], "column_encoding": encodings}


def write_geoparquet(table, path: Path) -> None:
    """Write a :func:`geoparquet_table` with the dataset's encodings (module docstring)."""
    import pyarrow.parquet as pq

    pq.write_table(table, str(path), row_group_size=ROW_GROUP_ROWS, **writer_options())


def _file_rows_sql(source: str = "ais_positions") -> str:
    cols = ", ".join(CANONICAL_COLUMNS)
    return f"SELECT {cols} FROM {source} WHERE file_id = ?"


def _fetch_arrow(con, sql: str, params: list):
    res = con.execute(sql, params)
    table = res.to_arrow_table() if hasattr(res, "to_arrow_table") else res.fetch_arrow_table()
    return table.read_all() if hasattr(table, "read_all") else table


_US_PER_DAY = 86_400_000_000


def _sorted_by_day(table):
    """(table sorted by UTC day, ``mmsi``, ``time_utc``; [(day "YYYY-MM-DD", first row, rows)]).

    Sorted in numpy (one lexsort of integer keys: (mmsi, time_utc) is unique within a file, so
    the order is total and the same as SQL's ``ORDER BY day, mmsi, time_utc``), measured about
    3 times cheaper than DuckDB's sort of a transaction's fresh rows into Arrow."""
    t_us = table.column("time_utc").combine_chunks().cast("int64").to_numpy()
    mmsi = table.column("mmsi").combine_chunks().to_numpy()
    day = np.floor_divide(t_us, _US_PER_DAY)
    order = np.lexsort((t_us, mmsi, day))
    table = table.take(order).combine_chunks()
    values, first, counts = np.unique(day[order], return_index=True, return_counts=True)
    names = np.datetime_as_string(values.astype("datetime64[D]"), unit="D")
    return table, [(str(d), int(i), int(n)) for d, i, n in zip(names, first, counts)]


def _write_parts(con, root: Path, file_id: int, tmp: bool, days: set | None = None,
                 source: str = "ais_positions") -> list[Part]:
    """The parts of one committed or being-committed file, from ``source`` (``ais_positions``,
    or a table of just the file's rows in its columns; only the parts of ``days``,
    ``YYYY-MM-DD`` strings, when given)."""
    return _write_table_parts(_fetch_arrow(con, _file_rows_sql(source), [int(file_id)]), root, file_id, tmp, days)


def new_part(root: Path, day: str, file_id: int, rows: int) -> Part:
    """The part of (``file_id``, ``day``): its final path, its temporary one (its day's folder made)."""
    folder = root / f"day={day}"
    folder.mkdir(parents=True, exist_ok=True)
    final = folder / part_name(file_id)
    return Part(final, folder / f".{final.name}.{os.getpid()}.tmp", rows)


def record_parts(con, file_id: int, parts: list[Part]) -> None:
    """Record written parts in ``ais_parquet_parts`` (inside the file's transaction)."""
    for p in parts:
        con.execute("INSERT INTO ais_parquet_parts VALUES (?, ?, ?)", [int(file_id), p.path.parent.name[4:], p.rows])


def _write_table_parts(table, root: Path, file_id: int, tmp: bool, days: set | None = None) -> list[Part]:
    """Sort an Arrow table of one file's rows and write its parts (numpy, pyarrow and the file
    system only: safe in a thread while the caller's DuckDB connection works on)."""
    if table.num_rows == 0:
        return []
    table, slices = _sorted_by_day(table)
    parts = []
    try:
        for day, start, n in slices:
            if days is not None and day not in days:
                continue
            parts.append(new_part(root, day, file_id, n))
            write_geoparquet(geoparquet_table(table.slice(start, n)), parts[-1].tmp)
            if not tmp:
                os.replace(parts[-1].tmp, parts[-1].path)
    except BaseException:
        if tmp:
            discard(parts)
        raise
    return parts


class PendingParts:
    """A file's parts being written in a thread inside its transaction (:func:`start_file_parts`).

    Why a thread: sorting and writing the parts (numpy, pyarrow and zstd, which release the
    GIL) is about 40 % of a single-file ingest's CPU time (4.2 of 9.9 s on the 5 M-row DMA
    file of bench/ingest.py, measured 2026-11-27); it overlaps with the transaction's DuckDB
    work (insert, track ends, quarantine, vessels) on the second core."""

    def __init__(self, ws, file_id: int, table, root: Path):
        from concurrent.futures import ThreadPoolExecutor

        self._ws, self._file_id = ws, int(file_id)
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="stormlane-parquet")
        self._future = self._pool.submit(_write_table_parts, table, root, file_id, True)

    def finish(self) -> list[Part]:
        """Wait for the parts (re-raising the writer's error) and record them in
        ``ais_parquet_parts`` (still inside the transaction)."""
        try:
            parts = self._future.result()
        finally:
            self._pool.shutdown(wait=True)
        record_parts(self._ws.con, self._file_id, parts)
        return parts

    def abandon(self) -> None:
        """After an error in the transaction: wait for the writer and remove what it wrote."""
        self._pool.shutdown(wait=True)
        if self._future.exception() is None:
            discard(self._future.result())


def start_file_parts(ws, file_id: int, source: str) -> PendingParts | None:
    """Inside the file's transaction: read the file's rows from ``source`` (a table holding the
    rows being inserted, in the canonical columns) and start writing its parts under temporary
    names in a thread; :meth:`PendingParts.finish` records them, :func:`publish` renames them
    after the commit. None for an in-memory workspace."""
    root = positions_root(getattr(ws, "path", None))
    if root is None:
        return None
    table = _fetch_arrow(ws.con, _file_rows_sql(source), [int(file_id)])
    return PendingParts(ws, file_id, table, root)


def publish(parts: list[Part]) -> None:
    """After the commit: give each part its final name (an atomic rename)."""
    for p in parts:
        os.replace(p.tmp, p.path)


def discard(parts: list[Part]) -> None:
    """After a rollback: remove the temporary files."""
    for p in parts:
        p.tmp.unlink(missing_ok=True)


def _scan(root: Path) -> tuple[dict, dict]:
    """What is on disk: final parts {(file_id, day): path} and temporary files {(file_id, day):
    [paths]} (files with other names are left alone)."""
    finals, temps = {}, {}
    if not root.is_dir():
        return finals, temps
    for d in os.scandir(root):
        m = _DAY_RE.match(d.name)
        if not (m and d.is_dir()):
            continue
        for f in os.scandir(d.path):
            pm, tm = _PART_RE.match(f.name), _TMP_RE.match(f.name)
            if pm:
                finals[(int(pm.group(1)), m.group(1))] = Path(f.path)
            elif tm:
                temps.setdefault((int(tm.group(1)), m.group(1)), []).append(Path(f.path))
    return finals, temps


def sync_positions_parquet(ws) -> dict:
    """Make the dataset what ``ais_parquet_parts`` records (module docstring, step 3).

    Returns counts: ``parts`` (recorded), ``published`` (renamed from a temporary file),
    ``written`` (written again from the workspace), ``removed`` (temporary files of loads that
    did not commit, parts that are not recorded, a grouped commit's spill folder)."""
    root = positions_root(getattr(ws, "path", None))
    out = {"parts": 0, "published": 0, "written": 0, "removed": 0}
    if root is None:
        return out
    check_dataset_folders(Path(ws.path))
    rows = ws.con.execute("SELECT file_id, strftime(day, '%Y-%m-%d'), n_rows FROM ais_parquet_parts").fetchall()
    want = {(int(f), d): int(n) for f, d, n in rows}
    out["parts"] = len(want)
    finals, temps = _scan(root)
    missing: dict = {}
    for key in want:
        if key in finals:
            continue
        tmp = temps.get(key)
        if tmp:
            os.replace(tmp[0], root / f"day={key[1]}" / part_name(key[0]))
            out["published"] += 1
        else:
            missing.setdefault(key[0], set()).add(key[1])
    for file_id, days in sorted(missing.items()):
        out["written"] += len(_write_parts(ws.con, root, file_id, tmp=False, days=days))
    finals, temps = _scan(root)
    for key, path in finals.items():
        if key not in want:
            path.unlink(missing_ok=True)
            out["removed"] += 1
    for paths in temps.values():
        for path in paths:
            path.unlink(missing_ok=True)
            out["removed"] += 1
    for spill in root.parent.glob(".groups-*.tmp"):  # a grouped commit's spill (parquet_groups) left by a kill
        shutil.rmtree(spill, ignore_errors=True)
        out["removed"] += 1
    return out


def check_dataset_folders(db_path: Path) -> None:
    """The dataset's folders must be folders: a file named ``<workspace stem>.parquet`` beside
    the workspace (an AIS input named like the workspace, say) made every commit fail with "Not a
    directory" after the file was staged. Now one error line before any work, naming both
    (checked by the ingest before it opens the workspace, and by every sync)."""
    from pipelines.storage import WorkspaceError

    if dataset_root(db_path) is None:
        return
    for folder in (dataset_root(db_path), positions_root(db_path)):
        if folder.exists() and not folder.is_dir():
            raise WorkspaceError(
                f"workspace {db_path} keeps its positions dataset in the folder {folder}, but that is a file; "
                f"give --db another name (or move {folder.name} elsewhere)")


def parquet_glob(root: Path) -> str:
    """The glob of every part of a positions dataset."""
    return str(Path(root) / "day=*" / "file-*.parquet")


#: A DuckDB ``SELECT`` of the dataset in the canonical columns (``lat_deg``/``lon_deg`` from the
#: geometry); its one parameter is the glob (:func:`parquet_glob`).
POSITIONS_SELECT = ("SELECT mmsi, time_utc, geometry.y AS lat_deg, geometry.x AS lon_deg, sog_kn, cog_deg, heading_deg, "
                    "nav_status, file_id, source_line FROM read_parquet(?, hive_partitioning = true)")
