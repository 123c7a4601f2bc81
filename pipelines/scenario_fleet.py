"""``stormlane scenario --vessels N``: a year-scale fleet written day by day in bounded memory.

The ships of :func:`scenario.fleet.fleet_spec` are sailed one at a time
(:func:`scenario.fleet.sail_ship`), each ship's records spilled to an Arrow IPC file in
``DIR/.fleet-spill/`` with one record batch per UTC day (buffers LZ4-compressed: about 43 bytes
per row, removed at the end); then each day is read back from every
ship's spill (a memory-mapped batch each), put in output order and written as
``DIR/ais/aisdk-YYYY-MM-DD.csv.gz`` (the DMA CSV layout of :func:`scenario.writers.write_dma_csv`,
gzip level 6, the ``gzip`` tool's default). Both phases run on a pool of worker processes, one
ship or one day per task; every ship and day has its own random streams and the output does not
depend on the number of processes (byte-identical files, tested).

Memory: a worker holds one ship's records for the whole period (about 0.4 M rows and 150 MB for
a ship-year at the demo's cadence) or one day of the fleet (about 1,100 rows per ship); the
parent holds the vessel table and per-file counts. Nothing grows with the number of ship-days
but the files on disk. The truth that does grow with it (voyages, port stays, gaps) goes to
``DIR/truth/*.parquet`` ship by ship; ``DIR/scenario.json`` holds the settings, the fleet, the
files with their counts and ``expected_ingest`` (the rows a correct ingest loads and rejects,
and the dirty rows by kind; not every dirty row's line, unlike the demo's).
"""

from __future__ import annotations

import json
import os
import shutil
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from pipelines.scenario import (
    AIS_PATTERNS, DIRTY_KINDS, EXPECTED_REASON, ScenarioConfigError, ScenarioSettings, describe_setup, file_entries,
    checked_seed_start, load_scenario_spec, make_out_dir,
)

#: Gzip level of the daily files: the ``gzip`` tool's default (the public archives' zip files use deflate too).
GZIP_LEVEL = 6
#: Record columns kept in the spill (what the DMA writer and the file counts read).
SPILL_COLUMNS = ("time_s", "mmsi", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status", "msg_type",
                 "fmt", "vessel_index", "destination", "eta_s", "draught_m", "dirty_kind", "time_text", "sort_s",
                 "sort_sub")
TRUTH_TABLES = ("voyages", "port_stays", "gaps")
#: Buffer compression of the spill's record batches (Arrow IPC, LZ4 frame): about 43 bytes per
#: row instead of 143 for about 0.2 CPU us per row written and 0.13 read (measured on one
#: ship-period; zstd level 1 makes 29 bytes for about 1.6 us per row written and read).
SPILL_COMPRESSION = "lz4"


@dataclass(frozen=True)
class FleetJob:
    """What every worker needs: the configuration, the fleet size, the settings, the folders."""

    config: str | None
    ports: str | None
    n_vessels: int
    settings: ScenarioSettings
    out_dir: str
    spill_dir: str

    def spec(self):
        from scenario.fleet import fleet_spec

        return fleet_spec(load_scenario_spec(self.config and Path(self.config), self.ports and Path(self.ports)),
                          self.n_vessels)

    @property
    def day0_s(self) -> int:
        return self.settings.start_s // 86400 * 86400

    @property
    def n_days(self) -> int:
        return int(-(-(self.settings.end_s - self.day0_s) // 86400))


_WORKER: dict = {}


def _worker_state(job: FleetJob) -> dict:
    """The spec and vessel table, built once per worker process."""
    if _WORKER.get("job") != job:
        from scenario.generator import service_ranks, vessel_table

        spec = job.spec()
        _WORKER.update(job=job, spec=spec, vessels=vessel_table(spec), ranks=service_ranks(spec))
    return _WORKER


def spill_ship(job: FleetJob, index: int) -> dict:
    """Sail ship ``index`` and spill its records, one Arrow record batch per day; returns its
    truth tables (small) and counts."""
    import pyarrow as pa

    from scenario.fleet import sail_ship

    state = _worker_state(job)
    res = sail_ship(state["spec"], job.settings, index, state["vessels"], state["ranks"], frame=False)
    recs = res["records"]
    table = pa.table({c: recs[c] for c in SPILL_COLUMNS})
    day = (recs["sort_s"] - job.day0_s) // 86400
    bounds = np.searchsorted(day, np.arange(job.n_days + 1))  # records are in output order (by sort_s)
    path = Path(job.spill_dir) / f"ship-{index:06d}.arrow"
    whole = table.combine_chunks().to_batches()[0] if len(table) else pa.RecordBatch.from_pylist([], schema=table.schema)
    options = pa.ipc.IpcWriteOptions(compression=SPILL_COMPRESSION)
    with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_file(sink, table.schema, options=options) as writer:
        for d in range(job.n_days):
            writer.write_batch(whole.slice(int(bounds[d]), int(bounds[d + 1] - bounds[d])))
    return {"index": index, "voyages": res["voyages"], "port_stays": res["stays"], "gaps": res["gaps"],
            "fixes": res["fixes"], "records": int(len(recs["time_s"]))}


def write_day(job: FleetJob, d: int) -> dict:
    """Day ``d`` of every ship's spill, in output order, as one gzip DMA CSV file; returns the
    file's entry (the fields of :func:`pipelines.scenario.file_entries` and its bytes)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    from scenario.writers import DMA_COLUMNS, dma_statics, write_dma_rows

    state = _worker_state(job)
    batches = []
    for index in range(job.n_vessels):
        with pa.memory_map(str(Path(job.spill_dir) / f"ship-{index:06d}.arrow")) as src:
            batch = pa.ipc.open_file(src).get_batch(d)
            if batch.num_rows:
                batches.append(batch)
    if not batches:
        return {}
    table = pa.Table.from_batches(batches).combine_chunks()
    keep = np.flatnonzero(pc.and_(pc.equal(table["fmt"], "dma_csv"), pc.not_equal(table["msg_type"], 5))
                          .to_numpy(zero_copy_only=False))
    # output order: by time, then MMSI, then an injected copy after its original (a stable sort,
    # as pandas' sort_values(kind="stable") on the three columns)
    cols = {c: table[c].to_numpy() for c in ("sort_s", "mmsi", "sort_sub")}
    order = keep[np.lexsort((cols["sort_sub"][keep], cols["mmsi"][keep], cols["sort_s"][keep]))]
    day = table.take(pa.array(order))
    if "statics" not in state:
        state["statics"] = dma_statics(state["vessels"])
    name = f"aisdk-{pd.Timestamp(job.day0_s + d * 86400, unit='s').strftime('%Y-%m-%d')}.csv.gz"
    size = write_dma_rows(Path(job.out_dir) / "ais" / name,
                          {c: (day[c].combine_chunks() if pa.types.is_string(day.schema.field(c).type)
                               else day[c].to_numpy()) for c in DMA_COLUMNS},
                          state["statics"], gzip=True, compresslevel=GZIP_LEVEL)
    return _file_entry("ais/" + name, day, size)


def _file_entry(name: str, day, size: int) -> dict:
    """A written day's entry in scenario.json (:func:`pipelines.scenario.file_entries` of its rows'
    format, message type and dirty kind, counted by Arrow first) and its bytes on disk."""
    keys = ["fmt", "msg_type", "dirty_kind"]
    counts = day.select(keys).group_by(keys, use_threads=False).aggregate([([], "count_all")])
    counts = counts.to_pandas(use_threads=False)
    counts = counts.rename(columns={"count_all": "rows"}).sort_values(keys, kind="stable")
    (entry,) = file_entries(counts.assign(file=name))
    return {**entry, "bytes": int(size)}


def _init_worker() -> None:
    """Arrow allocations of the workers from the system allocator: mimalloc (pyarrow's default)
    keeps the pages of the writer's per-day text arrays, which showed as peak memory growing with
    the fleet-days (measured: +39 MB against +23 MB from 2 ships x 2 days to 10 x 10)."""
    import pyarrow as pa

    pa.set_memory_pool(pa.system_memory_pool())


def _pool(workers: int):
    import multiprocessing

    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_init_worker)


def build_fleet_scenario(out_dir: Path, *, vessels: int, seed: int = 0, start=None, days: float = 365.0,
                         workers: int | None = None, config: Path | None = None, ports: Path | None = None,
                         **settings) -> dict:
    """Write a fleet of ``vessels`` ships over ``days`` days into ``out_dir`` (see the module
    docstring) and return the ``scenario.json`` content. ``workers``: processes (default: one
    per core, at most one per ship)."""
    # Long by design: the two phases (ships -> spill, days -> files) and the truth written as
    # they finish, in ship and day order, so that nothing waits for the whole fleet in memory.
    start_ts = checked_seed_start(seed, start)
    if int(vessels) < 1:
        raise ScenarioConfigError(f"--vessels {vessels}: a fleet needs at least one vessel")
    out_dir = make_out_dir(out_dir)
    st = ScenarioSettings(seed=int(seed), start_utc=start_ts, days=float(days), **settings)
    job = FleetJob(str(config) if config else None, str(ports) if ports else None, int(vessels), st,
                   str(out_dir), str(out_dir / ".fleet-spill"))
    spec = _worker_state(job)["spec"]
    ais_dir, truth_dir = out_dir / "ais", out_dir / "truth"
    for folder in (ais_dir, truth_dir):
        folder.mkdir(exist_ok=True)
    for pattern in AIS_PATTERNS:
        for old in ais_dir.glob(pattern):
            old.unlink()
    shutil.rmtree(job.spill_dir, ignore_errors=True)
    Path(job.spill_dir).mkdir()
    workers = max(1, min(int(workers or os.cpu_count() or 1), job.n_vessels))
    counts = {"voyages": 0, "complete_voyages": 0, "port_stays": 0, "gaps": 0, "fixes": 0}
    try:
        with _pool(workers) as pool:
            writers = {}
            try:
                for res in pool.map(spill_ship, [job] * job.n_vessels, range(job.n_vessels)):
                    _append_truth(writers, truth_dir, res)
                    counts["voyages"] += len(res["voyages"])
                    counts["complete_voyages"] += int(res["voyages"]["complete"].sum()) if len(res["voyages"]) else 0
                    counts["port_stays"] += len(res["port_stays"])
                    counts["gaps"] += len(res["gaps"])
                    counts["fixes"] += res["fixes"]
            finally:
                for w in writers.values():
                    w.close()
            files = [e for e in pool.map(write_day, [job] * job.n_days, range(job.n_days)) if e]
    finally:
        shutil.rmtree(job.spill_dir, ignore_errors=True)
    truth = describe_setup(st, spec, _worker_state(job)["vessels"])
    truth["scenario"]["fleet"] = {"vessels": int(vessels), "workers": workers, "gzip_level": GZIP_LEVEL}
    truth["truth"] = {name: {"file": f"truth/{name}.parquet", "rows": counts[name]} for name in TRUTH_TABLES}
    truth["truth"]["voyages"]["complete"] = counts["complete_voyages"]
    truth["truth"]["fixes"] = counts["fixes"]
    truth.update(_ais_summary(files))
    truth["writers"] = ["ais"]
    (out_dir / "scenario.json").write_text(json.dumps(truth, indent=1) + "\n", encoding="utf-8")
    return truth


def _append_truth(writers: dict, folder: Path, res: dict) -> None:
    """Add one ship's voyages, port stays and gaps to the truth Parquet files (ship order)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    for name in TRUTH_TABLES:
        df = res[name]
        if not len(df):
            continue
        table = pa.Table.from_pandas(df, preserve_index=False)
        if name not in writers:
            writers[name] = pq.ParquetWriter(str(folder / f"{name}.parquet"), table.schema, compression="zstd")
        writers[name].write_table(table.cast(writers[name].schema))


def _ais_summary(files: list[dict]) -> dict:
    """``ais``, ``dirty_rows`` and ``expected_ingest`` of scenario.json from the files' entries."""
    dirty = {k: sum(f["dirty"].get(k, 0) for f in files) for k in DIRTY_KINDS}
    positions = sum(f["position_records"] for f in files)
    clean = sum(f["clean_positions"] for f in files)
    return {
        "ais": {"folder": "ais", "files": files,
                "bytes": sum(f["bytes"] for f in files),
                "formats": {"dma_csv": "Danish Maritime Authority CSV export, one gzip file per UTC day, header line 1"}},
        "dirty_rows": {"counts": dirty, "by_format": {"dma_csv": dirty}, "expected_reason": EXPECTED_REASON},
        "expected_ingest": {"position_records": positions, "loaded": clean, "rejected": positions - clean,
                            "static_messages": 0},
    }


def fleet_summary_lines(truth: dict) -> list[str]:
    """A few human lines about a written fleet scenario."""
    sc, exp = truth["scenario"], truth["expected_ingest"]
    files = truth["ais"]["files"]
    return [
        f"fleet scenario seed {sc['seed']}: {sc['start_utc']} -> {sc['end_utc']}, {sc['fleet']['vessels']} vessels, "
        f"{truth['truth']['voyages']['rows']:,} voyages",
        f"  ais: {len(files)} gzip DMA CSV files, {truth['ais']['bytes'] / 1e6:,.1f} MB, {exp['position_records']:,} "
        f"position rows ({exp['loaded']:,} clean, {exp['rejected']:,} dirty)",
        f"  truth: {', '.join(v['file'] for k, v in truth['truth'].items() if isinstance(v, dict))}",
        f"  files: {files[0]['file']} .. {files[-1]['file']}" if files else "  no file written",
    ]
