"""A large AIS file ingested in groups of whole vessels, with the memory of one group.

The ingest's peak memory grew with the rows of its largest file (about 0.37 GB plus 0.69 KB per
row of CSV, measured on 0.26-2.94 M-row files; issue 23): a file is staged and committed whole.
A plain DMA/NOAA CSV file above :data:`GROUP_MIN_BYTES` is now split into MMSI ranges of about
:data:`GROUP_BYTES` each (:func:`ais.io.csv_buckets.split_by_mmsi`), and a Parquet file above
:data:`PARQUET_GROUP_MIN_ROWS` rows into ranges of about :data:`PARQUET_GROUP_ROWS` rows
(:func:`ais.io.parquet_buckets.split_by_keys`), in a scratch folder beside the workspace. Each
group is staged like a file of its own (the same readers, on a private DuckDB) and committed in
turn inside the file's one transaction (:func:`pipelines.storage.ais.classify_and_commit` with
``groups``). Every cross-row rule works within one vessel's rows, so the tables are those of
the whole file's commit; the quarantine and ``source_line`` name the input's lines; the file's
row, fingerprint and counts are the file's. A plain NMEA file above :data:`NMEA_GROUP_MIN_BYTES` is
decoded in chunks and its stage rows dealt into groups (:mod:`ais.io.nmea_chunks`).
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from pathlib import Path

log = logging.getLogger(__name__)

#: Plain CSV files above this size are split. A file up to it is committed whole, which is
#: faster (bench/ingest_large.py, 9.7 M rows in one file: 14.5 s whole against 28.6 s in
#: groups) but holds the whole file: about 0.37 GB + 0.69 KB per row (measured, 0.26-2.94 M
#: rows), so about 5 GB at 1 GiB of 169-byte rows (6.4 M), under issue 23's 6 GB.
GROUP_MIN_BYTES = 1 << 30
#: Plain CSV bytes per group (about 1.2-1.9 M DMA rows): the grouped ingest of one 9.7 M-row
#: file peaked at 1.54 GB resident (0.97 GB of its own; 6.75 GB whole), bench/ingest_large.py.
GROUP_BYTES = 256 << 20
#: Parquet files above this many rows are split (:mod:`ais.io.parquet_buckets`): their bytes
#: say little of their rows (241 MB held 10.5 M rows). Committed whole, a Parquet file peaked
#: at 3.97 GB at 10.5 M rows of typed columns (bench/ingest_large.py --format parquet; 1.78 GB
#: in groups, 1.49 x the time) and at 1.94 GB at 2.93 M rows of text columns: about 0.37 GB +
#: 0.3-0.54 KB per row, so 2.2-3.6 GB at this size, about the CSV threshold's 6.4 M rows.
PARQUET_GROUP_MIN_ROWS = 6_000_000
#: Parquet rows per group: about a CSV group's (256 MiB of 169-byte DMA rows is 1.6 M).
PARQUET_GROUP_ROWS = 1_500_000
#: Plain NMEA files above this size are decoded in chunks and committed in groups
#: (:mod:`ais.io.nmea_chunks`). Read whole, an NMEA file took about 17 bytes of memory per byte
#: (DMA's framing, 111 bytes per message: 2.3 GB at 111 MB, 6.1 GB at 333 MB, measured for
#: issue 23), so about 2.4 GB at this size.
NMEA_GROUP_MIN_BYTES = 128 << 20
#: NMEA stage rows per group: a group's decoded rows are held as a DataFrame (about 1 KB per
#: row with their text). On a 2.99 M-message file: 500,000 rows per group peaked at 1.12 GB in
#: 38.7 s, 1.5 M at 1.79 GB in 44.4 s (one run each, 2026-11-28).
NMEA_GROUP_ROWS = 500_000


def wants_groups(f) -> bool:
    """Whether the file ``f`` (an :class:`ais.io.files.AisFile`) is split: a plain DMA/NOAA CSV
    file above :data:`GROUP_MIN_BYTES`, a plain Parquet file above :data:`PARQUET_GROUP_MIN_ROWS`,
    a plain NMEA file above :data:`NMEA_GROUP_MIN_BYTES`."""
    if f.compressed:
        return False
    if f.format == "nmea":
        return f.size_bytes > NMEA_GROUP_MIN_BYTES
    if f.format == "parquet":
        return parquet_rows(f.path) > PARQUET_GROUP_MIN_ROWS
    return f.format in ("dma", "noaa") and f.size_bytes > GROUP_MIN_BYTES


def parquet_rows(path) -> int:
    """The rows of a Parquet file by its footer; 0 when pyarrow cannot read it (the stage then
    reads it whole, and names what is wrong with it)."""
    import pyarrow.parquet as pq

    try:
        return int(pq.ParquetFile(str(path)).metadata.num_rows)
    except Exception:
        return 0


def split_file(f, scratch, prefix: str = ".stormlane-groups-") -> tuple[Path, list]:
    """Split ``f`` (a DMA/NOAA CSV, Parquet or NMEA file) into groups in a new folder (named
    ``prefix...``) under ``scratch`` (None: the temporary folder); returns (folder, groups). The
    caller removes the folder."""
    from ais.io.csv_buckets import split_by_mmsi
    from pipelines.ingest_stage import csv_layout

    folder = Path(tempfile.mkdtemp(prefix=prefix, dir=scratch))
    try:
        if f.format == "nmea":
            from ais.io.nmea_chunks import split_nmea

            return folder, split_nmea(f.path, NMEA_GROUP_ROWS, folder)
        if f.format == "parquet":
            from ais.io.parquet_buckets import split_by_keys

            keys = parquet_keys(f.path, folder / "keys.npy")
            n = -(-len(keys) // PARQUET_GROUP_ROWS)
            return folder, split_by_keys(f.path, keys, n, folder)
        _, _, _, index = csv_layout(f)
        n = -(-int(f.size_bytes) // GROUP_BYTES)
        return folder, split_by_mmsi(f.path, index["mmsi"], n, folder)
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise


def parquet_keys(path, out: Path):
    """Each row's MMSI as the Parquet stage reads it (its own SQL,
    :func:`pipelines.storage.ais.stage_tables._mmsi_sql`; -1 where it reads none), in file
    order, in the memory-mapped file ``out``: 8 bytes per row on disk, streamed by DuckDB."""
    import duckdb
    import numpy as np

    from ais.io.csv_formats import MMSI_RE
    from ais.io.parquet import column_mapping
    from pipelines.ingest_stage import _Scratch
    from pipelines.storage import ais as store
    from pipelines.storage.ais._sql import _q, _used
    from pipelines.storage.ais.stage_tables import _mmsi_sql

    con = duckdb.connect(config={"threads": os.cpu_count() or 1})
    try:
        cols = dict(store.parquet_columns(_Scratch(con), path))
        column = column_mapping(list(cols), path, types=cols)["mmsi"]
        n = int(con.execute("SELECT count(*) FROM read_parquet($path)", {"path": str(path)}).fetchone()[0])
        keys = np.lib.format.open_memmap(out, mode="w+", dtype=np.int64, shape=(n,))
        sql = (f"SELECT file_row_number AS row, coalesce({_mmsi_sql(_q(column), cols[column])}, -1) AS key "
               "FROM read_parquet($path, file_row_number = true)")
        reader = con.execute(sql, _used(sql, {"path": str(path), "mmsi_re": MMSI_RE})).to_arrow_reader(1 << 20)
        for batch in reader:
            keys[batch.column(0).to_numpy()] = batch.column(1).to_numpy()
        keys.flush()
        return keys
    finally:
        con.close()


def commit_in_groups(ws, source, meta: dict, max_speed_kn: float, before_commit=None, scratch=None) -> dict:
    """Split the plain file ``source`` (an :class:`ais.io.files.AisFile`) in ``scratch`` and
    commit its groups in one transaction; ``meta`` as for
    :func:`pipelines.storage.ais.classify_and_commit` (the file's fingerprint, path, format, size).
    Returns the file's counts; the groups' folder is removed."""
    import time

    from pipelines.ingest_stage import leftover_prefix, remove_leftovers
    from pipelines.storage import ais as store

    t0 = time.perf_counter()
    for p in remove_leftovers(ws, "groups"):
        log.warning("removed %s, left by an ingest into this workspace that did not finish", p)
    folder, groups = split_file(source, scratch, leftover_prefix(ws, "groups"))
    meta.setdefault("timings", {})["split"] = time.perf_counter() - t0
    try:
        return store.classify_and_commit(ws, meta, max_speed_kn=max_speed_kn, before_commit=before_commit,
                                         groups=installers(ws, source, groups, folder))
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def installers(ws, f, groups: list, folder: Path):
    """One function per group: stage the group's file on a private DuckDB and install that stage
    as ``ws``'s ``ais_stage`` (inside the caller's transaction: a reader's failed attempt on the
    private connection cannot abort it); returns the group's commit meta."""
    for group in groups:
        yield lambda group=group: _install(ws, f, group, folder)


def _install(ws, f, group, folder: Path) -> dict:
    """Stage one group and install it in ``ws`` through files memory-mapped from ``folder``.

    Why files: DuckDB keeps an object registered and then dropped inside a transaction alive
    until the commit (measured: every group's scanned rows stayed in memory, +250 MB per
    1.1 M-row group). Memory-mapped, what stays is file pages the kernel can drop."""
    import duckdb

    from ais.io.files import inspect
    from pipelines.ingest_stage import _Scratch, stage_file
    from pipelines.storage import ais as store
    from pipelines.storage.ais import spool

    mem = _Scratch(duckdb.connect(config={"threads": os.cpu_count() or 1}))
    info: dict = {}
    got: dict = {}
    try:
        if f.format == "nmea":  # decoded already: the group's stage rows
            from ais.io.nmea_chunks import read_group

            info = {**store.stage_frame(mem, read_group(group)), "ignored": group.ignored}
        else:
            info = stage_file(mem, inspect(group.path, f.format, with_fingerprint=False))
        if info.get("staging") == "scan":
            out = spool.write_scan(mem.con, info, spool.new_folder(folder), group.path.stem)
            info.pop("scan_table")
            info.pop("scan_fixes")
            got = spool.install_scan(ws, out)
        else:
            _hand_over_table(mem.con, ws.con, folder / f"{group.path.stem}.stage.arrow")
    finally:
        if info.get("line_index") is not None:
            info["line_index"].close()
        mem.con.close()
    return {"ignored": int(info["ignored"]), "line_map": _line_map(group, folder), "folder": str(folder),
            "name": group.path.stem, "release": lambda: _release(folder, group.path.stem), **got}


def _release(folder: Path, stem: str) -> None:
    """After a group's commit steps: empty and remove its files. Truncating first returns the
    pages of the files DuckDB still maps (its dropped views keep their objects until the
    commit, but never read them again) to the kernel and their space to the disk."""
    for path in sorted(Path(folder).glob(f"{stem}*")):
        files = sorted(path.iterdir()) if path.is_dir() else [path]
        for p in files:
            os.truncate(p, 0)
            p.unlink()
        if path.is_dir():
            path.rmdir()


def _line_map(group, folder: Path):
    """The group's (line, input line) table, memory-mapped."""
    import numpy as np
    import pyarrow as pa

    from pipelines.storage.ais import spool

    orig = group.line_numbers()
    path = folder / f"{group.path.stem}.lines.arrow"
    spool.write_ipc(pa.table({"line": np.arange(1, len(orig) + 1, dtype=np.int64), "orig": orig}), path)
    return spool.read_ipc(path)


def _hand_over_table(src, con, path: Path) -> None:
    """A stage the scan did not make: its rows (with their line and raw text) moved to ``con``
    through the memory-mapped file ``path``, with the stage's kind."""
    from pipelines.storage.ais import spool
    from pipelines.storage.ais._sql import _set_stage_kind, _stage_kind

    kind, extra = _stage_kind(src)
    spool.write_ipc(src.execute("SELECT * FROM ais_stage").to_arrow_table(), path)
    con.register("ais_group_rows", spool.read_ipc(path))
    con.execute("CREATE OR REPLACE TEMP VIEW ais_stage AS SELECT * FROM ais_group_rows")
    _set_stage_kind(con, kind, extra)
