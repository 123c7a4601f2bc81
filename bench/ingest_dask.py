"""Benchmark of the AIS ingest partitioned by file on Dask (issue 7 item 5) against the sequential one.

Inputs (generated once, untimed, cached): ``FILES`` DMA-style CSV files of ``ROWS`` rows each
(:mod:`bench._ingest_data`: the real 26-column layout, ~0.5 % dirty rows; 200 ships per file,
another seed per file).

* ``ingest_dask``: ``stormlane ingest-ais FILES --db NEW --task-runner dask`` in a fresh process
  (``pipelines.cli.main`` in process: the Prefect ingest flow, a 2-worker ``LocalCluster``
  started for it, stage tasks on the workers, commits here in order);
* ``ingest_sequential`` (baseline): the same command without ``--task-runner`` (every file
  staged and committed in the process).

Throughput counts the rows read. No target was set; the figure of interest is what partitioning
costs or saves on this machine.
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: import `bench` from the repository root
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import tempfile
from pathlib import Path

from bench._harness import Group, Measure, Side, script_main

FILES, ROWS = 2, 250_000
NA_EMPTY = "not repeated here: the ingest's kernels compile in bench/ingest.py's empty-cache runs"


def prepare(folder: str, files: int, rows: int) -> dict:
    from bench._ingest_data import generate_dma_csv

    out = []
    for k in range(files):
        p = Path(folder) / f"aisdk-{k:02d}.csv"
        if not p.exists():
            p.parent.mkdir(parents=True, exist_ok=True)
            tmp = p.with_suffix(".part")
            generate_dma_csv(tmp, rows, n_vessels=200, seed=k)
            tmp.rename(p)
        out.append(p)
    return {"files": len(out), "rows_per_file": rows, "mb": round(sum(p.stat().st_size for p in out) / 1e6, 1)}


def setup(folder: str, files: int, runner: str) -> dict:
    import os

    os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")
    paths = [str(Path(folder) / f"aisdk-{k:02d}.csv") for k in range(files)]
    return {"paths": paths, "runner": runner, "tmp": Path(tempfile.mkdtemp(prefix="stormlane-bench-dask-"))}


def run_ingest(st: dict) -> dict:
    """``stormlane ingest-ais`` in this process into a new workspace."""
    import contextlib
    import io
    import json

    from pipelines.cli import main

    db = st["tmp"] / "bench.duckdb"
    for suffix in ("", ".wal"):
        Path(str(db) + suffix).unlink(missing_ok=True)
    argv = ["ingest-ais", *st["paths"], "--db", str(db), "--json"]
    if st["runner"] != "sequential":
        argv += ["--task-runner", st["runner"]]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        main(argv)
    out = json.loads(buf.getvalue())
    return {"work": int(out["read"]), "loaded": int(out["loaded"]), "quarantined": int(out["quarantined"])}


def build(cfg):
    here = "bench.ingest_dask"
    files, rows = (2, 100_000) if cfg.quick else (FILES, ROWS)
    folder = str(Path(cfg.cache_dir) / f"ingest-dask-{files}x{rows}")
    kw = {"folder": folder, "files": files}
    g = Group(
        "partitioned", f"{files} DMA files x {rows:,} rows: partitioned on Dask against sequential",
        prepare=f"{here}:prepare", prepare_kwargs={"folder": folder, "files": files, "rows": rows},
        sides=[Side("ingest_dask", "`stormlane ingest-ais --task-runner dask` in a fresh process (own 2-worker cluster)",
                    setup=f"{here}:setup", kwargs={**kw, "runner": "dask"}, run=f"{here}:run_ingest",
                    work="rows read", warm_per_process=0, empty_cache=NA_EMPTY,
                    warm_na="not measured: each `--task-runner dask` call starts its own cluster again"),
               Side("ingest_sequential", "`stormlane ingest-ais` (sequential) in a fresh process", setup=f"{here}:setup",
                    kwargs={**kw, "runner": "sequential"}, run=f"{here}:run_ingest", work="rows read",
                    empty_cache=NA_EMPTY)],
        measures=[Measure("ingest_dask", "AIS ingest partitioned on Dask", "ingest_dask", "ingest_sequential",
                          relation="the same files into a new workspace, sequentially (identical tables: tested in "
                                   "tests/test_ingest_partitioned.py)")])
    return [g], ["No target was set for the partitioned ingest."]


if __name__ == "__main__":
    script_main("bench/ingest_dask.py", build)
