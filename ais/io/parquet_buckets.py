"""Split a large Parquet AIS file into Parquet files of whole vessels: MMSI ranges of about equal rows.

The Parquet twin of :mod:`ais.io.csv_buckets` (issue 23): the ingest applies its cross-row
rules within one vessel's rows only, so a file cut into groups of whole vessels and committed
group after group gives exactly the whole file's result, with the memory of one group. Each
group is a Parquet file with the input's own Arrow schema (its key-value metadata, GeoParquet's
``geo`` included) holding the group's rows in their input order; beside it the input's row
number (1-based: the Parquet stage's ``line``) of each of its rows.

A row's group is decided by its MMSI as the ingest reads it (``keys``: computed by the caller
with the stage's own SQL, :func:`pipelines.ingest_groups.parquet_keys`); rows without one (a
missing or unreadable MMSI, key < 0) have no cross-row rule and go to the first group. The
groups are MMSI ranges (:func:`ais.io.csv_buckets.mmsi_bounds`), in MMSI order.

Memory: one batch of :data:`BATCH_ROWS` rows, and the keys as a memory-mapped file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ais.io.csv_buckets import Group, _add_counts, by_group, mmsi_bounds

#: Rows read per batch (the split's working memory: about 0.2 KB each for AIS columns).
BATCH_ROWS = 1 << 17
#: Keys counted per step when choosing the ranges.
_COUNT_ROWS = 1 << 22


def range_bounds(keys: np.ndarray, n_groups: int) -> np.ndarray:
    """The upper MMSI bounds of at most ``n_groups`` ranges of about equal rows, from every
    row's key (counted in steps: memory grows with vessels, not rows)."""
    mmsi, rows = np.empty(0, np.int64), np.empty(0, np.int64)
    no_key = 0
    for a in range(0, len(keys), _COUNT_ROWS):
        k = np.asarray(keys[a:a + _COUNT_ROWS])
        ok = k >= 0
        mmsi, rows = _add_counts(mmsi, rows, k[ok])
        no_key += int(len(k) - ok.sum())
    return mmsi_bounds(mmsi, rows, max(1, int(n_groups)), no_key)


def split_by_keys(path, keys: np.ndarray, n_groups: int, folder) -> list[Group]:
    """Split the Parquet file ``path`` into at most ``n_groups`` files of whole vessels in
    ``folder`` (``group-NNNN.parquet``, module docstring), by ``keys`` (one int64 per row in
    file order, < 0 for none). Groups without rows are left out."""
    import pyarrow.parquet as pq

    folder = Path(folder)
    bounds = range_bounds(keys, n_groups)
    n = len(bounds) + 1
    names = [folder / f"group-{g:04d}.parquet" for g in range(n)]
    line_files = [folder / f"group-{g:04d}.lines.i64" for g in range(n)]
    counts = np.zeros(n, dtype=np.int64)
    with pq.ParquetFile(str(path)) as pf:
        if pf.metadata.num_rows != len(keys):
            raise ValueError(f"{path}: {pf.metadata.num_rows} rows, {len(keys)} keys")
        schema = pf.schema_arrow
        writers = [pq.ParquetWriter(str(p), schema) for p in names]
        louts = [open(p, "wb") for p in line_files]
        try:
            start = 0
            for batch in pf.iter_batches(batch_size=BATCH_ROWS, use_threads=True):
                order, cuts = by_group(np.asarray(keys[start:start + batch.num_rows]), bounds)
                for g in range(n):
                    rows = order[cuts[g]:cuts[g + 1]]
                    if len(rows):
                        writers[g].write_batch(batch.take(rows))
                        (rows + (start + 1)).astype(np.int64).tofile(louts[g])
                        counts[g] += len(rows)
                start += batch.num_rows
        finally:
            for w in writers:
                w.close()
            for f in louts:
                f.close()
    groups = []
    for g in range(n):
        npy = line_files[g].with_suffix(".npy")
        if counts[g]:
            np.save(npy, np.fromfile(line_files[g], dtype=np.int64))
            groups.append(Group(names[g], npy, int(counts[g])))
        else:
            names[g].unlink()
        line_files[g].unlink()
    return groups
