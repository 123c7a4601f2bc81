"""``--task-runner dask`` (a local cluster the command starts and stops): the same tables as the
sequential run, and a console as quiet as it. The cluster's scheduler and nannies live in the
command's process and logged about 35 INFO lines a run to the console; a worker's heartbeat
after the scheduler closed printed a traceback after a run that succeeded, about 1 run in 4
(:mod:`pipelines.dask_quiet_close`)."""

from __future__ import annotations

import subprocess
import sys

import duckdb

from ais_fixtures import DMA_HEADER, dma_row


def _day(path, day: int) -> None:
    """Three ships sailing east for two hours, a fix a minute."""
    rows = [dma_row(f"{day:02d}/01/2025 {m // 60:02d}:{m % 60:02d}:00", f"21900000{k}", f"{55 + k * 0.1:.6f}",
                    f"{11 + m * 0.003:.6f}") for k in range(3) for m in range(120)]
    path.write_text("\n".join([DMA_HEADER, *rows]) + "\n")


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pipelines.cli", *map(str, args)], capture_output=True, text=True, timeout=300)


def _tables(db) -> dict:
    with duckdb.connect(str(db), read_only=True) as con:
        return {t: con.sql(f"SELECT count(*), sum(hash(COLUMNS(* EXCLUDE (file_id))))::VARCHAR FROM {t}").fetchall()
                for t in ("ais_positions", "ais_quarantine")}


def test_a_local_cluster_ingest_gives_the_sequential_tables_and_a_quiet_console(tmp_path):
    (tmp_path / "ais").mkdir()
    for day in (1, 2):
        _day(tmp_path / "ais" / f"aisdk-2025-01-0{day}.csv", day)
    seq = _cli("ingest-ais", tmp_path / "ais", "--db", tmp_path / "seq.duckdb")
    assert seq.returncode == 0, seq.stderr
    dask = _cli("ingest-ais", tmp_path / "ais", "--db", tmp_path / "dask.duckdb", "--task-runner", "dask")
    assert dask.returncode == 0, dask.stderr
    assert dask.stdout == seq.stdout.replace("seq.duckdb", "dask.duckdb")
    assert dask.stderr == seq.stderr == ""  # no cluster log line, no traceback at its close
    assert _tables(tmp_path / "dask.duckdb") == _tables(tmp_path / "seq.duckdb")


def test_only_the_heartbeat_record_of_a_closing_cluster_is_dropped():
    """The record the filter drops is the one ``distributed``'s worker writes (an upgrade that
    rewords it fails here, not silently on the console); every other record passes."""
    import inspect
    import logging

    from distributed.worker import Worker

    from pipelines.dask_quiet_close import HEARTBEAT_FAILED, _DropHeartbeatAtClose

    assert f'"{HEARTBEAT_FAILED}.' in inspect.getsource(Worker.heartbeat)
    keep = _DropHeartbeatAtClose()

    def record(msg):
        return logging.LogRecord("distributed.worker", logging.ERROR, __file__, 1, msg, None, None)

    assert not keep.filter(record(f"{HEARTBEAT_FAILED}."))
    assert keep.filter(record("Unexpected exception during heartbeat. Closing worker."))
    assert keep.filter(record("Compute Failed"))
