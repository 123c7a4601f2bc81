"""Benchmark of the AIS ingest partitioned by file on Dask (issue 7 item 5) against the sequential one.

Run: ``.venv/bin/python bench/ingest_dask.py [--files 8] [--rows 250000] [--workers 2]``

Generates ``--files`` DMA-style CSV files (``bench/ingest.py``'s generator: the real 26-column
layout, ~0.5 % dirty rows; 200 ships per file, another seed per file) and ingests them three ways into fresh workspaces:

1. sequential: ``pipelines.ingest.ingest_paths`` (every file staged and committed in this process);
2. partitioned on a ``distributed.LocalCluster`` started beforehand (the Prefect ingest flow with
   ``spool_dir``: stage tasks on the workers, commits here, in order);
3. the same, timing the cluster's start-up too (what ``stormlane ingest-ais --task-runner dask`` pays).

Prints wall times, the stage/commit split and checks that the three workspaces hold the same
rows. No target is set by the issue for the ingest; the figure of interest is what partitioning
costs or saves on this machine.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")


def _generator():
    spec = importlib.util.spec_from_file_location("bench_ingest", ROOT / "bench" / "ingest.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.generate_dma_csv


def _rows(db) -> tuple:
    from pipelines.storage import open_workspace

    with open_workspace(db) as ws:
        return tuple(ws.con.execute(f"SELECT count(*), sum(hash(r)) FROM {t} r").fetchone()
                     for t in ("ais_positions", "ais_quarantine", "vessels"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--files", type=int, default=8)
    ap.add_argument("--rows", type=int, default=250_000, help="rows per file")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)

    from distributed import Client, LocalCluster
    from prefect.testing.utilities import prefect_test_harness

    from pipelines.ingest import flow_with_runner, ingest_paths

    tmp = Path(tempfile.mkdtemp(prefix="stormlane-bench-dask-"))
    gen = _generator()
    files = []
    for k in range(args.files):
        p = tmp / f"aisdk-{k:02d}.csv"
        gen(p, args.rows, n_vessels=200, seed=k)
        files.append(str(p))
    size_mb = sum(Path(f).stat().st_size for f in files) / 1e6
    print(f"{args.files} files x {args.rows:,} rows ({size_mb:.0f} MB), {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.1f}")

    t = time.perf_counter()
    seq = ingest_paths(files, tmp / "seq.duckdb")
    t_seq = time.perf_counter() - t
    print(f"sequential (ingest_paths)                  {t_seq:6.1f} s  {seq['read'] / t_seq / 1e6:.2f} M rows/s")

    with prefect_test_harness(server_startup_timeout=240):
        spool = tmp / "spool"
        spool.mkdir()
        t0 = time.perf_counter()
        with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
            t_start = time.perf_counter() - t0
            with Client(cluster):
                flow = flow_with_runner(f"dask:{cluster.scheduler_address}")
                t = time.perf_counter()
                out = flow(paths=files, db=str(tmp / "dask.duckdb"), spool_dir=str(spool))
                t_warm = time.perf_counter() - t
    print(f"partitioned, {args.workers} Dask workers (cluster up)   {t_warm:6.1f} s  "
          f"{out['read'] / t_warm / 1e6:.2f} M rows/s")
    print(f"  + cluster start-up                       {t_start:6.1f} s  (total {t_warm + t_start:.1f} s)")
    same = _rows(tmp / "seq.duckdb") == _rows(tmp / "dask.duckdb")
    print(f"same rows in both workspaces: {same}; read {seq['read']:,} = loaded {seq['loaded']:,} + quarantined "
          f"{seq['quarantined']:,} + duplicates {seq['duplicates']:,}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
