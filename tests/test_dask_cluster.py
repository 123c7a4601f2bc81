"""``--task-runner dask:ADDRESS`` against a cluster of separate processes (issue 23 item 4).

A 20-ship fleet over 4 days (4 daily gzip files in the DMA layout) is ingested and its lanes
built twice through the CLI: sequentially, and with the file staging and the lane partitions
on a ``dask scheduler`` + ``dask worker`` started as their own processes (the ``dask_address``
fixture). Every table, the Parquet dataset's bytes and the lanes are identical; a rerun on the
cluster adds nothing; the tasks ran on the cluster's workers.
"""

from __future__ import annotations

import pandas as pd
import pytest

from test_ais_crash import snapshot
from test_lanes_scaleout import TABLES, _tables


def _parts(db):
    from pipelines.storage.ais import positions_root

    root = positions_root(db)
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*.parquet"))}


def test_ingest_and_lanes_on_separate_dask_processes_equal_the_sequential_run(tmp_path, dask_address,
                                                                                prefect_harness):
    from distributed import Client, get_task_stream

    from pipelines.cli import main
    from pipelines.scenario_fleet import build_fleet_scenario

    build_fleet_scenario(tmp_path / "sc", vessels=20, seed=5, start="2025-03-01T00:00Z", days=4, workers=1)
    ais = str(tmp_path / "sc" / "ais")
    seq, dsk = tmp_path / "seq.duckdb", tmp_path / "dask.duckdb"
    assert main(["ingest-ais", ais, "--db", str(seq), "--json"]) is None
    assert main(["lanes", "--db", str(seq), "--json"]) is None
    runner = f"dask:{dask_address}"
    with Client(dask_address) as client, get_task_stream(client) as stream:
        workers = set(client.scheduler_info()["workers"])
        assert len(workers) == 2
        assert main(["ingest-ais", ais, "--db", str(dsk), "--task-runner", runner, "--json"]) is None
        before = snapshot(dsk), _parts(dsk)
        assert main(["ingest-ais", ais, "--db", str(dsk), "--task-runner", runner, "--json"]) is None
        assert (snapshot(dsk), _parts(dsk)) == before  # a rerun adds nothing
        assert main(["lanes", "--db", str(dsk), "--task-runner", runner, "--json"]) is None
    # one stage task per daily file (the rerun stages none), one task per O-D partition, all on
    # the cluster's workers
    keys = [str(t["key"]) for t in stream.data]
    ran_on = {t["worker"] for t in stream.data}
    assert sum("stage_to_spool" in k for k in keys) == 4 and sum("partition_lanes" in k for k in keys) >= 7, keys
    assert ran_on <= workers, ran_on

    assert snapshot(dsk) == snapshot(seq) and len(snapshot(seq)[1]) > 70_000
    assert _parts(dsk) == _parts(seq) and len(_parts(seq)) >= 4
    got, want = _tables(dsk), _tables(seq)
    assert want["counts"]["lanes"] > 0 and got["counts"] == want["counts"]
    for name in TABLES:
        pd.testing.assert_frame_equal(got[name], want[name], check_exact=True, obj=name)
