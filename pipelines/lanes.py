"""Prefect flow: traffic lanes from the ingested AIS positions (after ``ingest``).

port lists -> steps 1-5 (:func:`lanes.chain.prepare_chain_in_buckets`: jump filter, stops, ports,
voyages, resampling, over MMSI buckets of whole tracks, :data:`BUCKET_ROWS`): in the flow, with
more than one bucket, each bucket's two passes are tasks on the flow's task runner reading the
positions dataset (:class:`ParquetBuckets`) and only the ports are detected in the flow; with one
bucket, and in ``run_lanes``, :func:`prepare_from_workspace` reads ``ais_positions`` one bucket at
a time in this process -> one task per origin-destination partition
(:func:`lanes.extract.extract_lanes_for_pair`, submitted to the flow's task runner) ->
:func:`lanes.extract.merge_lane_results` -> :func:`lanes.chain.finish_chain` -> writer task (tables
``ports``, ``voyages``, ``lanes``, ``lane_centroids``, ``lane_voyages``).

``run_lanes`` runs the same steps without Prefect, every partition in this process
(:func:`lanes.extract.extract_lanes` is the same partitions and the same merge): what ``stormlane
lanes`` calls by default, so a one-off command does not start a Prefect API. ``lanes_flow`` is
the flow the demo runs; :func:`flow_with_runner` gives it a task runner (``--task-runner
dask[:ADDRESS]``: the buckets and the partitions run on a Dask cluster). Pass 2 writes each partition's
resampled points to its own Parquet files in a folder next to the workspace
(:mod:`pipelines.lanes_partitions`) and each partition task reads only its own, so no process
holds the points of all partitions (on a cluster the workers read and write the files and read the
positions dataset: the workspace's folder must be shared). Both paths give identical tables (tested on a 2-worker cluster of
separate ``dask scheduler``/``dask worker`` processes). Prefect is imported only when the flow is first used.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field

from lanes.chain import (POSITION_COLUMNS, ChainParams, ChainResult, PreparedChain, prepare_chain_in_buckets,
                         voyages_as_table)
from lanes.extract import LaneParams
from lanes.interpolate import ResampleParams
from lanes.ports import PortParams
from lanes.stops import StopParams
from pipelines.config import data_dir
from thresholds.errors import StormlaneError


class LanesInputError(StormlaneError):
    """The workspace has nothing to extract lanes from."""


class LanesSettings(BaseModel):
    """The tunable parameters of the lanes chain (validated before a run starts).

    Defaults suit open-sea traffic at a few hundred positions per vessel-day (the demo scenario);
    dense multi-month areas (the Ushant set) want a smaller ``eps_nmi`` and a larger
    ``min_density`` (see docs/lanes.md).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    step_s: float = Field(300.0, gt=0, description="resampling time step [s]")
    max_interp_gap_s: float = Field(3600.0, gt=0, description="no resampled point inside a longer gap [s]")
    eps_nmi: float = Field(2.0, gt=0, description="DBSCAN spatial eps [nmi]")
    eps_speed_kn: float = Field(3.0, gt=0, description="DBSCAN speed eps [kn]")
    eps_course_deg: float = Field(20.0, gt=0, lt=180, description="DBSCAN course eps [deg]")
    min_density: float = Field(3.0, gt=0, description="DBSCAN core density, in voyages passing within eps")
    min_voyages: int = Field(3, ge=1, description="fewest voyages a lane must have")
    max_points: int = Field(150_000, ge=100, description="per-partition DBSCAN sample size")
    centroid_spacing_nmi: float = Field(5.0, gt=0, description="spacing of lane centroids [nmi]")
    merge_voyage_share: float = Field(0.8, ge=0, le=1, description="clusters sharing this share of their voyages "
                                      "with a larger one of the same port pair are one lane (0 = never)")
    stop_speed_kn: float = Field(0.5, gt=0, description="stopped below this speed [kn]")
    min_stop_s: float = Field(180.0, ge=0, description="shortest stop [s]")
    port_eps_nmi: float = Field(0.135, gt=0, description="DBSCAN eps for stops -> ports [nmi]")
    port_match_nmi: float = Field(2.0, ge=0, description="largest distance to a listed port [nmi]")
    max_jump_speed_kn: float = Field(50.0, gt=0, description="fixes implying more are dropped [kn]")

    def chain_params(self) -> ChainParams:
        resample = ResampleParams(step_s=self.step_s, max_gap_s=max(self.max_interp_gap_s, self.step_s))
        return ChainParams(
            stops=StopParams(max_speed_kn=self.stop_speed_kn, min_duration_s=self.min_stop_s),
            ports=PortParams(eps_nmi=self.port_eps_nmi, match_radius_nmi=self.port_match_nmi),
            resample=resample,
            lanes=LaneParams(eps_nmi=self.eps_nmi, eps_speed_kn=self.eps_speed_kn, eps_course_deg=self.eps_course_deg,
                             min_density=self.min_density, min_voyages=self.min_voyages, max_points=self.max_points,
                             centroid_spacing_nmi=self.centroid_spacing_nmi,
                             merge_voyage_share=self.merge_voyage_share),
            max_jump_speed_kn=self.max_jump_speed_kn,
        )


def default_port_lists() -> list[Path]:
    """``data/ports.csv`` (demo region) and ``data/ports_terminals.csv`` (named terminals elsewhere)."""
    return [p for p in (data_dir() / "ports.csv", data_dir() / "ports_terminals.csv") if p.exists()]


#: Positions the lanes chain reads at once: one bucket of whole tracks (ascending MMSI ranges),
#: about 0.3 GB in pandas with the chain's working copies (measured: bench/scale.py, docs/scale.md).
BUCKET_ROWS = 4_000_000
#: DuckDB's memory limit on the workspace while the positions are read. Under its default (80 %
#: of RAM) DuckDB keeps every block it has read cached: about 15 bytes per stored position for the
#: five columns the chain reads (131 MB after the buckets of 8.57 M rows), the lanes' memory that
#: grew with the rows (docs/scale-history.md, fourth pass). Under this limit the cache is evicted (the
#: blocks are on disk) and a bucket's ORDER BY still fits (4 M rows sorted under 256 MB: the same
#: CPU time as without a limit).
READ_MEMORY_LIMIT_MB = 256
#: The position columns the lanes chain reads: half the CPU of reading all eight.
CHAIN_COLUMNS = ("mmsi", *POSITION_COLUMNS)


def load_port_lists(db: str | Path, ports_csv=None) -> pd.DataFrame:
    """The port lists (one path, several, or the defaults), after checking that the workspace
    holds positions to extract lanes from."""
    from lanes.io.portlist import read_port_lists
    from pipelines.storage import open_workspace

    if ports_csv is None:
        paths = default_port_lists()
    elif isinstance(ports_csv, (str, Path)):
        paths = [Path(ports_csv)]
    else:
        paths = [Path(p) for p in ports_csv]
    known, _ = read_port_lists(paths)
    if not Path(db).exists():
        raise LanesInputError(f"workspace {db} does not exist; run `stormlane ingest-ais PATH --db {db}` first")
    with open_workspace(db) as ws:
        if ws.con.execute("SELECT count(*) FROM (SELECT 1 FROM ais_positions LIMIT 1)").fetchone()[0] == 0:
            raise LanesInputError(f"workspace {db} has no AIS positions; run `stormlane ingest-ais PATH --db {db}` first")
    return known


def mmsi_buckets(per_mmsi: pd.DataFrame, bucket_rows: int = BUCKET_ROWS) -> list[tuple[int, int]]:
    """Ascending, disjoint ``(lo, hi)`` MMSI ranges of at most ``bucket_rows`` positions each
    (a vessel with more is a bucket of its own), from :func:`pipelines.storage.ais.positions_per_mmsi`."""
    mmsi = per_mmsi["mmsi"].to_numpy(dtype=np.int64)
    n = per_mmsi["n"].to_numpy(dtype=np.int64)
    out, start, rows = [], 0, 0
    for i in range(len(mmsi)):
        if rows and rows + n[i] > bucket_rows:
            out.append((int(mmsi[start]), int(mmsi[i - 1])))
            start, rows = i, 0
        rows += int(n[i])
    if len(mmsi):
        out.append((int(mmsi[start]), int(mmsi[-1])))
    return out


def prepare_from_workspace(db: str | Path, known: pd.DataFrame, params: ChainParams,
                           bucket_rows: int = BUCKET_ROWS, points_folder: str | None = None) -> PreparedChain:
    """Steps 1-5 of the chain on the workspace's positions, read bucket by bucket of whole
    tracks (:func:`lanes.chain.prepare_chain_in_buckets`): the positions held at once are one
    bucket's, whatever the workspace holds. With ``points_folder`` the resampled points go to
    partition files there (:class:`pipelines.lanes_partitions.PartitionStore`) instead of
    memory: the result's ``points`` is ``None``."""
    from pipelines.lanes_partitions import PartitionStore
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import positions_per_mmsi, read_positions

    columns = list(CHAIN_COLUMNS)
    with open_workspace(db) as ws:
        ws.con.execute(f"SET memory_limit = '{int(READ_MEMORY_LIMIT_MB)}MB'")
        buckets = mmsi_buckets(positions_per_mmsi(ws), bucket_rows)
        sink = None if points_folder is None else PartitionStore(points_folder, params.lanes.include_loops).add
        return prepare_chain_in_buckets(lambda k: read_positions(ws, mmsi_range=buckets[k], columns=columns),
                                        len(buckets), known, params, points_sink=sink)


@dataclass(frozen=True)
class ParquetBuckets:
    """``read_bucket`` of :func:`lanes.chain.prepare_chain_in_buckets` for any process: bucket
    ``k``'s positions (MMSI range ``buckets[k]``) from the workspace's positions dataset
    (:func:`pipelines.storage.ais.read_positions_parquet`), not from the workspace file."""

    glob: str
    buckets: tuple
    n_rows: int  # the workspace's positions when planned
    columns: tuple = CHAIN_COLUMNS

    def check_read(self, n_read: int) -> None:
        """Refuse a read that did not see every position of the workspace (a part of the dataset
        removed or unreadable since the plan): lanes from part of the traffic would look whole."""
        if int(n_read) != self.n_rows:
            raise LanesInputError(
                f"the positions dataset ({self.glob}) gave {int(n_read):,} positions where the workspace holds "
                f"{self.n_rows:,}: a part was removed or changed during the run; run the command again "
                "(it rewrites the missing parts from the workspace)")

    def __call__(self, k: int) -> pd.DataFrame:
        from pipelines.storage.ais import read_positions_parquet

        return read_positions_parquet(self.glob, self.buckets[k], self.columns, READ_MEMORY_LIMIT_MB)


def plan_buckets(db: str | Path, bucket_rows: int | None = None) -> ParquetBuckets:
    """The MMSI buckets of the workspace's positions (:func:`mmsi_buckets`, default
    :data:`BUCKET_ROWS` each) and the reader of their positions dataset, first made what the
    workspace records (after a crash)."""
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import positions_per_mmsi, positions_root, sync_positions_parquet
    from pipelines.storage.ais.parquet import parquet_glob

    with open_workspace(db) as ws:
        sync_positions_parquet(ws)
        per_mmsi = positions_per_mmsi(ws)
    buckets = mmsi_buckets(per_mmsi, bucket_rows or BUCKET_ROWS)
    return ParquetBuckets(parquet_glob(positions_root(db)), tuple(buckets), n_rows=int(per_mmsi["n"].sum()))


def store_result(db: str | Path, result: ChainResult, settings: LanesSettings) -> dict:
    """Write the result tables (one transaction); return the CLI summary."""
    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import write_lanes

    with open_workspace(db) as ws:
        run_id = write_lanes(ws, result.ports, voyages_as_table(result.voyages), result.lanes.lanes,
                             result.lanes.centroids, result.lane_voyages, result.summary, settings.model_dump())
    return {**summary_counts(result.summary), "run_id": run_id}


def summary_counts(summary: dict) -> dict:
    """The four counts of the CLI contract, in its order."""
    return {k: int(summary[k]) for k in ("ports", "voyages", "lanes", "noise_points")}


def run_lanes(db: str | Path, ports_csv=None, settings: LanesSettings | None = None) -> dict:
    """Reader -> chain -> writer without Prefect; returns the summary (counts, run id, details)."""
    import time

    from pipelines.lanes_partitions import finish_from_partitions, partition_lanes, points_folder, remove_folder, stored_keys

    settings = settings or LanesSettings()
    params = settings.chain_params()
    known = load_port_lists(db, ports_csv)
    folder = points_folder(db)
    try:
        prep = prepare_from_workspace(db, known, params, points_folder=str(folder))
        t = time.perf_counter()
        parts = [(key, partition_lanes(str(folder), params.lanes, key)) for key in stored_keys(folder)]
        result = finish_from_partitions(prep, parts, time.perf_counter() - t)
    finally:
        remove_folder(folder)
    out = store_result(db, result, settings)
    return {**out, "details": result.summary}


def export_geojson(db: str | Path, out: str | Path) -> Path:
    """Write the workspace's ports, lanes and centroids as a GeoJSON FeatureCollection."""
    import json

    from dashboards.lanes_geojson import lanes_geojson
    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import read_lane_centroids, read_lanes, read_ports

    with open_workspace(db) as ws:
        fc = lanes_geojson(read_ports(ws), read_lanes(ws), read_lane_centroids(ws))
    out = Path(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(fc, separators=(",", ":")), encoding="utf-8")
    except OSError as err:
        where = f": {err.filename}" if err.filename and str(err.filename) != str(out) else ""
        raise LanesInputError(f"{out}: cannot write the lanes GeoJSON ({err.strerror or err}{where})") from None
    return out


_FLOW_OBJECTS: dict = {}
_TASKS = ("lanes_flow", "read_task", "plan_task", "prepare_task", "stops_task", "voyages_task", "partition_task",
          "store_task")


def _build_flow() -> dict:
    """Create the Prefect tasks and flow on first use (keeps ``import pipelines.lanes`` light)."""
    if _FLOW_OBJECTS:
        return _FLOW_OBJECTS
    import time

    from prefect import flow, task
    from prefect.cache_policies import NO_CACHE

    from lanes.chain import bucket_stops, bucket_voyages
    from pipelines.lanes_partitions import (PartitionStore, finish_from_partitions, partition_lanes, points_folder,
                                            remove_folder, stored_keys)
    from pipelines.runners import make_task_runner, retry_transient

    io = {"retries": 2, "retry_delay_seconds": [2, 5], "cache_policy": NO_CACHE, "retry_condition_fn": retry_transient}
    plan_task = task(plan_buckets, name="MMSI buckets", **io)
    # a retried pass 2 writes the same partition files under the same names
    stops_task = task(bucket_stops, name="clean, stops (one MMSI bucket)", task_run_name="stops-{k}", **io)
    voyages_task = task(bucket_voyages, name="clean, voyages, resampling (one MMSI bucket)",
                        task_run_name="voyages-{k}", **io)
    on_runner = {bucket_stops: stops_task, bucket_voyages: voyages_task}

    def map_buckets(fn, calls: list[tuple]) -> list:
        """Each bucket's pass as a task on the flow's task runner (all submitted, results in order)."""
        futures = [on_runner[fn].submit(*args) for args in calls]
        return [f.result() for f in futures]

    read_task = task(load_port_lists, name="read port lists", retries=3, retry_delay_seconds=[2, 5, 15],
                     cache_policy=NO_CACHE, retry_condition_fn=retry_transient)
    prepare_task = task(prepare_from_workspace, name="stops, ports, voyages, resampling (by MMSI bucket)",
                        retries=3, retry_delay_seconds=[2, 5, 15], cache_policy=NO_CACHE,
                        retry_condition_fn=retry_transient)
    partition_task = task(partition_lanes, name="lanes of one O-D pair", cache_policy=NO_CACHE,
                          task_run_name="lanes-{key[0]}-{key[1]}")
    store_task = task(store_result, name="store lanes", retries=3, retry_delay_seconds=[2, 5, 15],
                      cache_policy=NO_CACHE, retry_condition_fn=retry_transient)

    # Default runner: one task at a time, like ``run_lanes`` (bounded memory: one bucket or one
    # DBSCAN at a time); ``flow_with_runner("dask[:ADDRESS]")`` fans the buckets and partitions out.
    @flow(name="lanes", task_runner=make_task_runner("sequential"))
    def lanes_flow(db: str, ports_csv: Optional[list[str]] = None, settings: LanesSettings = LanesSettings()) -> dict:
        """Ports, voyages and traffic lanes from the workspace's AIS positions: two tasks per MMSI
        bucket (when there are several), one per O-D pair."""
        params = settings.chain_params()
        known = read_task(db, ports_csv)
        # each partition's points go to its own files next to the workspace; each task reads its own
        folder = str(points_folder(db))
        try:
            reader = plan_task(db)
            if len(reader.buckets) > 1:  # the buckets' passes as tasks, reading the positions dataset
                prep = prepare_chain_in_buckets(reader, len(reader.buckets), known, params, map_buckets=map_buckets,
                                                points_sink=PartitionStore(folder, params.lanes.include_loops).add)
                reader.check_read(prep.n_positions)
            else:  # one bucket: one task reads it once for both passes
                prep = prepare_task(db, known, params, points_folder=folder)
            t = time.perf_counter()
            keys = stored_keys(folder)
            futures = [partition_task.submit(folder, params.lanes, key) for key in keys]
            parts = [(key, f.result()) for key, f in zip(keys, futures)]
            result = finish_from_partitions(prep, parts, time.perf_counter() - t)
        finally:
            remove_folder(folder)
        out = store_task(db, result, settings)
        return {**out, "details": {**result.summary, "partition_tasks": len(keys)}}

    _FLOW_OBJECTS.update(lanes_flow=lanes_flow, read_task=read_task, plan_task=plan_task, prepare_task=prepare_task,
                         stops_task=stops_task, voyages_task=voyages_task, partition_task=partition_task,
                         store_task=store_task)
    return _FLOW_OBJECTS


def flow_with_runner(task_runner: str | None = None):
    """The lanes flow with the chosen task runner (:func:`pipelines.runners.make_task_runner`)."""
    from pipelines.runners import runner_flow

    return runner_flow(_build_flow()["lanes_flow"], task_runner)


def __getattr__(name: str):
    if name in _TASKS:
        return _build_flow()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


if __name__ == "__main__":
    import sys

    print(_build_flow()["lanes_flow"](sys.argv[1] if len(sys.argv) > 1 else "stormlane.duckdb"))
