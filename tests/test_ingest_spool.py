"""The partitioned ingest's hand-over between processes (issue 23): a scanned file's spool, the
spool's bound, and the Dask workers' Prefect API.

* A large file staged by the compiled scan in ANOTHER process (a fresh interpreter; a worker of
  the real cluster of separate processes) is spooled as the scan's own tables (``spool_kind``
  "scan": no line text retyped) and committed here: the workspace equals the sequential
  ingest's, row for row, and the spool is empty afterwards.
* The partitioned flow stages at most ``STAGE_AHEAD_FILES`` files ahead of its commit, and removes
  what its stages killed mid-write left in the spool.
* A flow on Dask workers of this machine gives its tasks this process's Prefect API (no worker
  starts a temporary server of its own).
"""

from __future__ import annotations

import gzip
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from ais_fixtures import DMA_HEADER, DMA_LINES, dma_row, write_dma
from pipelines.ingest import ingest_paths
from pipelines.ingest_partitioned import commit_spooled, stage_to_spool
from pipelines.runners import _loopback
from pipelines.storage import open_workspace
from test_ingest_partitioned import _assert_same_workspace

#: Stages one file in a fresh interpreter with the fast paths forced (the test's files are small).
_STAGE_ELSEWHERE = textwrap.dedent("""
    import json, sys
    from pipelines import ingest_stage
    ingest_stage.FAST_CSV_MIN_BYTES = 0
    ingest_stage.GZIP_PLAIN_MIN_BYTES = 0
    from pipelines.ingest_partitioned import stage_to_spool
    print(json.dumps(stage_to_spool(sys.argv[1], None, sys.argv[2])))
""")


def _day(tmp_path, name: str, day: int, gz: bool):
    rows = [dma_row(f"{day:02d}/01/2025 00:{m:02d}:{s:02d}", str(219300000 + v),
                    f"{54 + v * 0.05 + m * 1e-3 + day * 0.01:.6f}", f"{8 + s * 1e-4:.6f}", name=f"SHIP {v}")
            for m in range(20) for s in range(0, 60, 10) for v in range(5)]
    rows[40:40] = DMA_LINES[1:]  # dirty rows of every kind, a quoted name, a blank line
    if day == 3:  # a fix 33 nmi from the stored track 1 min later: a jump only against day 2
        rows.append(dma_row("03/01/2025 00:20:00", "219300001", "55.100000", "9.000000", name="SHIP 1"))
    path = write_dma(tmp_path / f"{name}.csv", [DMA_HEADER] + rows)
    if gz:
        path.with_suffix(".csv.gz").write_bytes(gzip.compress(path.read_bytes()))
        path.unlink()
        path = path.with_suffix(".csv.gz")
    return str(path)


@pytest.mark.parametrize("gz", [False, True], ids=["plain", "gzip"])
def test_a_scan_staged_in_another_process_commits_as_the_sequential_ingest(tmp_path, monkeypatch, gz):
    from pipelines import ingest_stage

    files = [_day(tmp_path, f"d{d}", d, gz) for d in (2, 3)]
    monkeypatch.setattr(ingest_stage, "FAST_CSV_MIN_BYTES", 0)
    monkeypatch.setattr(ingest_stage, "GZIP_PLAIN_MIN_BYTES", 0)
    seq = ingest_paths(files, tmp_path / "seq.duckdb")
    assert {f["staging"] for f in seq["per_file"]} == {"scan"}
    (spool := tmp_path / "spool").mkdir()
    staged = []
    for p in files:
        out = subprocess.run([sys.executable, "-c", _STAGE_ELSEWHERE, p, str(spool)], capture_output=True,
                             text=True, check=True, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
        staged.append(json.loads(out.stdout.strip().splitlines()[-1]))
    assert [s["spool_kind"] for s in staged] == ["scan", "scan"]
    names = sorted(p.name for p in spool.iterdir())
    assert len(names) == 2 and all(n.endswith(".scan") for n in names), names  # no half-written folder left
    with open_workspace(tmp_path / "part.duckdb") as ws:
        per_file = [commit_spooled(ws, s) for s in staged]
    _assert_same_workspace(tmp_path / "part.duckdb", tmp_path / "seq.duckdb")
    keys = ("read", "loaded", "quarantined", "duplicates", "static", "ignored", "reasons")
    assert [{k: f[k] for k in keys} for f in per_file] == [{k: f[k] for k in keys} for f in seq["per_file"]]
    # day 3 (checked against day 2's stored tracks) has the one jump more that day 2 has not
    assert per_file[1]["reasons"]["speed_jump"] == per_file[0]["reasons"]["speed_jump"] + 1
    assert list(spool.iterdir()) == []


@pytest.mark.slow
def test_scanned_files_staged_on_cluster_workers_commit_as_the_sequential_ingest(tmp_path, monkeypatch, dask_address):
    """The same on the real cluster of separate processes: the stage tasks run on its workers
    (the fast paths forced there for the call, then restored: the workers serve other tests)."""
    from distributed import Client

    from pipelines import ingest_stage

    files = [_day(tmp_path, f"d{d}", d, gz=True) for d in (2, 3)]
    monkeypatch.setattr(ingest_stage, "FAST_CSV_MIN_BYTES", 0)
    monkeypatch.setattr(ingest_stage, "GZIP_PLAIN_MIN_BYTES", 0)
    seq = ingest_paths(files, tmp_path / "seq.duckdb")

    def stage_forced(path: str, spool_dir: str) -> dict:
        import os

        from pipelines import ingest_stage as m
        from pipelines.ingest_partitioned import stage_to_spool

        old = m.FAST_CSV_MIN_BYTES, m.GZIP_PLAIN_MIN_BYTES
        m.FAST_CSV_MIN_BYTES = m.GZIP_PLAIN_MIN_BYTES = 0
        try:
            return {**stage_to_spool(path, None, spool_dir), "pid": os.getpid()}
        finally:
            m.FAST_CSV_MIN_BYTES, m.GZIP_PLAIN_MIN_BYTES = old

    (spool := tmp_path / "spool").mkdir()
    with Client(dask_address) as client:
        staged = client.gather([client.submit(stage_forced, p, str(spool), pure=False) for p in files])
    assert [s["spool_kind"] for s in staged] == ["scan", "scan"] and os.getpid() not in {s["pid"] for s in staged}
    with open_workspace(tmp_path / "part.duckdb") as ws:
        per_file = [commit_spooled(ws, s) for s in staged]
    _assert_same_workspace(tmp_path / "part.duckdb", tmp_path / "seq.duckdb")
    assert [f["reasons"] for f in per_file] == [f["reasons"] for f in seq["per_file"]]
    assert list(spool.iterdir()) == []


def test_the_same_bytes_staged_twice_keep_one_whole_spool(tmp_path, monkeypatch):
    from pipelines import ingest_stage

    monkeypatch.setattr(ingest_stage, "FAST_CSV_MIN_BYTES", 0)
    path = _day(tmp_path, "d2", 2, gz=False)
    (spool := tmp_path / "spool").mkdir()
    a, b = stage_to_spool(path, None, str(spool)), stage_to_spool(path, None, str(spool))
    assert a["spool"] == b["spool"] and [p.name for p in spool.iterdir()] == [os.path.basename(a["spool"])]
    with open_workspace(tmp_path / "w.duckdb") as ws:
        first, second = commit_spooled(ws, a), commit_spooled(ws, b)
    assert first["loaded"] > 0 and second["already_loaded"] and list(spool.iterdir()) == []


def test_the_partitioned_flow_stages_a_bounded_number_of_files_ahead(tmp_path, monkeypatch, prefect_harness):
    import pipelines.ingest as ingest
    import pipelines.ingest_partitioned as part

    files = [_day(tmp_path, f"d{d}", d, gz=False) for d in (2, 3, 4, 5, 6)]
    (spool := tmp_path / "spool").mkdir()
    seen = []
    commit = part.commit_spooled

    def counting(ws, staged, max_speed_kn):
        seen.append(len(list(spool.iterdir())))
        return commit(ws, staged, max_speed_kn)

    monkeypatch.setattr(part, "commit_spooled", counting)
    monkeypatch.setattr(ingest, "STAGE_AHEAD_FILES", 2)
    out = ingest.flow_with_runner("sequential")(paths=files, db=str(tmp_path / "w.duckdb"), spool_dir=str(spool))
    assert out["files"] == 5 and out["loaded"] > 0 and len(seen) == 5
    assert max(seen) == 2, seen  # never more than 2 staged and not yet committed


def test_the_partitioned_flow_removes_what_its_killed_stages_left(tmp_path, monkeypatch, prefect_harness):
    """A stage whose process dies mid-write (a lost worker) never runs its own clean-up: its
    temporary folder is removed when the flow ends, another run's is kept (a shared spool)."""
    import pipelines.ingest as ingest
    from pipelines.storage.ais import spool as spool_mod

    files = [_day(tmp_path, f"d{d}", d, gz=False) for d in (2, 3)]
    (spool := tmp_path / "spool").mkdir()
    other = spool_mod.new_folder(spool, "otherrun")  # a concurrent run's stage in progress
    new_folder = spool_mod.new_folder

    def killed_then_retried(spool_dir, run_tag=""):
        new_folder(spool_dir, run_tag)  # the first attempt, killed before its clean-up
        (spool_mod.part_file(Path(spool_dir) / "x.parquet", run_tag)).write_bytes(b"partial")
        return new_folder(spool_dir, run_tag)

    monkeypatch.setattr(spool_mod, "new_folder", killed_then_retried)
    out = ingest.flow_with_runner("sequential")(paths=files, db=str(tmp_path / "w.duckdb"), spool_dir=str(spool))
    assert out["files"] == 2 and out["loaded"] > 0
    assert sorted(spool.iterdir()) == [other]


def test_a_failed_stage_raises_its_own_error_from_the_flow(tmp_path, monkeypatch, prefect_harness):
    import pipelines.ingest as ingest
    from pipelines.storage.ais import spool as spool_mod

    files = [_day(tmp_path, f"d{d}", d, gz=False) for d in (2, 3)]
    (spool := tmp_path / "spool").mkdir()

    new_folder, calls = spool_mod.new_folder, []

    def full_disk(spool_dir, run_tag=""):  # the second file's stage, and its retries
        calls.append(run_tag)
        if len(calls) > 1:
            raise OSError(28, "No space left on device")
        return new_folder(spool_dir, run_tag)

    monkeypatch.setattr(spool_mod, "new_folder", full_disk)
    with pytest.raises(OSError, match="No space left"):
        ingest.flow_with_runner("sequential")(paths=files, db=str(tmp_path / "w.duckdb"), spool_dir=str(spool))


def test_loopback_addresses():
    assert _loopback("tcp://127.0.0.1:8786") and _loopback("localhost:8786") and _loopback("tcp://[::1]:8786")
    assert not _loopback("tcp://10.0.0.5:8786") and not _loopback("tls://scheduler.example:8786")


_API_ON_WORKERS = textwrap.dedent("""
    import json, sys
    from prefect import flow, task
    from pipelines.runners import runner_flow

    @task
    def api_url():
        from prefect.settings import get_current_settings
        return get_current_settings().api.url

    @flow
    def probe():
        return api_url.submit().result()

    print(json.dumps({"worker_api": runner_flow(probe, "dask:" + sys.argv[1])()}))
""")


@pytest.mark.slow
def test_local_dask_workers_use_the_calling_process_prefect_api(dask_address):
    env = {k: v for k, v in os.environ.items() if not k.startswith("PREFECT_API")}
    env.update(PYTHONPATH=os.pathsep.join(sys.path), PREFECT_LOGGING_LEVEL="WARNING")
    out = subprocess.run([sys.executable, "-c", _API_ON_WORKERS, dask_address], capture_output=True, text=True,
                         env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])["worker_api"]
    # the calling process's temporary server (a worker's own would be another port, and None here)
    assert got and got.startswith("http://127.0.0.1:"), got
