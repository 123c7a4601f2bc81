"""The lanes' resampled points on disk, one folder per origin-destination partition (issue 23).

The lanes chain reads the positions one bucket of whole tracks at a time, but held the
resampled points of every bucket together until the DBSCAN partitions ran: about 23 bytes per
position, the last memory of ``stormlane lanes`` that grew with the rows. Here pass 2 hands each
bucket's resampled points to :meth:`PartitionStore.add`, which writes every partition's share to
``FOLDER/<origin>_<dest>/bucket-<k>.parquet``; each partition task then reads only its own files
(:func:`partition_lanes`), in bucket order, so it receives exactly the rows, in the same order,
that :func:`lanes.extract.partition_rows` gives it from the whole frame, and computes the same
lanes (tested against the in-memory chain). The lanes and the lane-voyage rows of every
partition are merged as before; no per-point array of the whole set is built.

Memory: one bucket's positions and resampled points in pass 2, then one partition's points at a
time (a partition is one O-D pair: its share of the points, not all of them). On a Dask cluster
the workers read the partition files themselves: the folder is created next to the workspace
(like the ingest's spool), so it must be on a file system the workers share.
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

import pandas as pd

from lanes.chain import ChainResult, PreparedChain, finish_chain
from lanes.extract import (LaneParams, LaneResult, extract_lanes_for_pair, lane_voyage_table, merge_lane_results,
                           merge_lane_voyage_tables, partition_rows)


def _key_folder(root: Path, key: tuple[int, int]) -> Path:
    return Path(root) / f"{int(key[0])}_{int(key[1])}"


class PartitionStore:
    """Resampled points written partition by partition under ``folder`` (see the module docstring)."""

    def __init__(self, folder: str | Path, include_loops: bool = True):
        self.folder = Path(folder)
        self.include_loops = include_loops

    def add(self, k: int, points: pd.DataFrame) -> None:
        """Write bucket ``k``'s resampled points, each partition's rows to its own file (the
        partitions written are :func:`stored_keys` of the folder)."""
        for key, rows in partition_rows(points, self.include_loops):
            folder = _key_folder(self.folder, key)
            folder.mkdir(parents=True, exist_ok=True)
            points.iloc[rows].to_parquet(folder / f"bucket-{int(k):06d}.parquet", index=False)


def stored_keys(folder: str | Path) -> list[tuple[int, int]]:
    """The partitions with files under ``folder``, ascending."""
    keys = []
    for sub in Path(folder).iterdir():
        if sub.is_dir() and any(sub.glob("bucket-*.parquet")):
            o, d = sub.name.split("_")
            keys.append((int(o), int(d)))
    return sorted(keys)


def read_partition(folder: str | Path, key: tuple[int, int]) -> pd.DataFrame:
    """One partition's points, its bucket files in bucket order."""
    files = sorted(_key_folder(Path(folder), key).glob("bucket-*.parquet"))
    return pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)


def partition_lanes(folder: str, params: LaneParams, key: tuple[int, int]) -> tuple[LaneResult, pd.DataFrame]:
    """Lanes of partition ``key`` from its files (:func:`lanes.extract.extract_lanes_for_pair`)
    and its rows of the lane-voyage table; the per-point lanes are dropped (not sent back)."""
    points = read_partition(folder, key)
    res = extract_lanes_for_pair(points, params, key)
    return replace(res, point_lane=None), lane_voyage_table(points, res.point_lane)


def finish_from_partitions(prep: PreparedChain, parts: list, lanes_s: float) -> ChainResult:
    """The chain's result from the ``(key, (LaneResult, lane-voyage rows))`` of every partition
    (:func:`partition_lanes`): the lanes merged without a per-point array, the lane-voyage rows
    merged partition by partition (:func:`lanes.chain.finish_chain`)."""
    lanes = merge_lane_results(None, [(key, None, res) for key, (res, _) in parts])
    return finish_chain(prep, lanes, lanes_s, merge_lane_voyage_tables([lv for _, (_, lv) in parts]))


def points_folder(db: str | Path) -> Path:
    """A new folder for one run's partition files, next to the workspace (see the module docstring)."""
    db = Path(db).resolve()
    return Path(tempfile.mkdtemp(prefix=f".{db.name}.lanes-points-", dir=db.parent))


def remove_folder(folder: str | Path) -> None:
    shutil.rmtree(folder, ignore_errors=True)
