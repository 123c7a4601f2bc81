"""``--task-runner dask:ADDRESS`` against a user's cluster (issue 23 item 4): a bad or dead
address is one error line before any work, a worker's error reaches the user as the one line
the sequential run gives, and a worker whose working folder is not the caller's reads the
caller's relative paths."""

from __future__ import annotations

import gzip
import pickle
import socket
import subprocess
import sys
import threading

import duckdb
import pytest

from ais.errors import AisFormatError, AisInputError
from ais_fixtures import DMA_HEADER, DMA_LINES, dma_row
from pipelines.runners import TaskRunnerError, check_scheduler, parse_task_runner
from routing.errors import LandPointError


@pytest.mark.parametrize("spec", ["dask:tcp://10.0.0.5:8786", "dask:10.0.0.5:8786", "dask:tls://sched.example:8786",
                                  "dask:[::1]:8786", "dask:ws://h:1"])
def test_scheduler_addresses_dask_prints_are_taken(spec):
    assert parse_task_runner(spec) == ("dask", spec[5:])


@pytest.mark.parametrize("spec, why", [
    ("dask:nonsense", r"\[PROTOCOL://\]HOST:PORT"),
    ("dask:tcp://h", r"\[PROTOCOL://\]HOST:PORT"),
    ("dask:tcp://h:99999", r"\[PROTOCOL://\]HOST:PORT"),
    ("dask:tcp://h:8786/path", r"\[PROTOCOL://\]HOST:PORT"),
    ("dask:inproc://x", "protocol 'inproc' is not one of tcp, tls"),
    ("dask:http://h:8786", "protocol 'http' is not one of"),
])
def test_a_malformed_scheduler_address_says_what_is_missing(spec, why):
    with pytest.raises(TaskRunnerError, match=why):
        parse_task_runner(spec)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_nothing_listening_is_said_at_once():
    with pytest.raises(TaskRunnerError, match=r"no Dask scheduler answers there \(connection refused\)"):
        check_scheduler(f"dask:tcp://127.0.0.1:{_free_port()}", timeout_s=30)


def test_a_server_that_is_not_dask_is_said(tmp_path):
    """Something else listens (here an HTTP-like server answering every connection): Dask's
    client read its reply as a frame length and failed with a 3 EiB MemoryError."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()

    def answer():
        for _ in range(2):  # the reachability check's connection, then the identity call's
            conn, _ = srv.accept()
            conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4)
            conn.close()

    threading.Thread(target=answer, daemon=True).start()
    with pytest.raises(TaskRunnerError, match="what answers there is not a Dask scheduler"):
        check_scheduler(f"dask:tcp://127.0.0.1:{srv.getsockname()[1]}", timeout_s=10)
    srv.close()


@pytest.mark.parametrize("err", [AisInputError("a/b.csv", "no such file", line=3), AisFormatError("x.csv", "bad header"),
                                 LandPointError("goal on land", "goal", 10.0), TaskRunnerError("t")])
def test_user_errors_survive_the_trip_from_a_worker(err):
    """A task's exception is pickled on the worker: Python's default rebuilds it by calling the
    class with its message, which ``AisInputError(path, message)`` refused (a TypeError traceback
    in place of the user's error line)."""
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is type(err) and str(back) == str(err) and back.__dict__ == err.__dict__


@pytest.mark.slow
def test_the_cluster_fixture_is_a_scheduler_and_its_worker_is_not(dask_address):
    from distributed import Client

    assert check_scheduler(f"dask:{dask_address}") == 2
    with Client(dask_address) as client:
        worker = next(iter(client.scheduler_info()["workers"]))
    with pytest.raises(TaskRunnerError, match="is a Dask worker, not a scheduler"):
        check_scheduler(f"dask:{worker}")


def _cli(cwd, *args):
    return subprocess.run([sys.executable, "-m", "pipelines.cli", *args], capture_output=True, text=True, cwd=cwd)


@pytest.mark.slow
def test_relative_paths_and_a_workers_error_on_a_cluster_elsewhere(tmp_path, dask_address):
    """The cluster's processes run in a folder of their own (``dask_cluster_processes``): the
    caller's relative paths reach them as absolute ones, the workspace records them as given,
    and a file a worker cannot read is the sequential run's one error line."""
    (tmp_path / "in").mkdir()
    lines = DMA_LINES + [dma_row("13/01/2025 01:00:00", 219000001, 55.5, 11.0)]
    with gzip.open(tmp_path / "in" / "day1.csv.gz", "wt") as fh:
        fh.write("\n".join(lines) + "\n")
    (tmp_path / "in" / "day2.csv").write_text("\n".join([DMA_HEADER, dma_row("13/01/2025 02:00:00", 219000002, 55.6, 11.1)]) + "\n")
    runs = {}
    for name, runner in (("seq", "sequential"), ("dask", f"dask:{dask_address}")):
        out = _cli(tmp_path, "ingest-ais", "in", "--db", f"{name}.duckdb", "--task-runner", runner, "--json")
        assert out.returncode == 0, out.stderr
        with duckdb.connect(str(tmp_path / f"{name}.duckdb"), read_only=True) as con:
            runs[name] = (con.sql("SELECT file_id, path, fingerprint FROM ais_files ORDER BY 1").fetchall(),
                          con.sql("SELECT count(*), sum(hash(mmsi, time_utc, lat_deg, lon_deg)) FROM ais_positions").fetchone())
    assert runs["dask"] == runs["seq"]
    assert [p for _, p, _ in runs["seq"][0]] == ["in/day1.csv.gz", "in/day2.csv"]

    (tmp_path / "bad").mkdir()
    rows = [dma_row(f"13/01/2025 {i // 3600 % 24:02d}:{i // 60 % 60:02d}:{i % 60:02d}", 219000001 + i % 7,
                    f"{55 + i * 1e-5:.6f}", f"{11 + i * 1.3e-5:.6f}") for i in range(40_000)]
    data = gzip.compress(("\n".join([DMA_HEADER, *rows]) + "\n").encode())  # 1 MB: inspected by its first part
    (tmp_path / "bad" / "day3.csv.gz").write_bytes(data[: len(data) // 2])  # detected, truncated inside
    errors = {}
    for name, runner in (("seq", "sequential"), ("dask", f"dask:{dask_address}")):
        out = _cli(tmp_path, "ingest-ais", "bad", "--db", f"b{name}.duckdb", "--task-runner", runner)
        assert out.returncode == 2 and "Traceback" not in out.stderr and "ERROR" not in out.stderr, out.stderr
        errors[name] = [line for line in out.stderr.splitlines() if line.startswith("error:")]
    assert errors["seq"][0].startswith("error: bad/day3.csv.gz: truncated gzip: the ") and len(errors["seq"]) == 1
    assert errors["dask"] == errors["seq"]  # raised on a worker, said as the sequential run says it


@pytest.mark.slow
def test_a_dead_scheduler_is_one_line_before_any_work(tmp_path):
    out = _cli(tmp_path, "ingest-ais", ".", "--db", "w.duckdb", "--task-runner", f"dask:tcp://127.0.0.1:{_free_port()}")
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.strip().splitlines()[-1].startswith("error: --task-runner dask:tcp://127.0.0.1:")
    assert not (tmp_path / "w.duckdb").exists()


@pytest.mark.slow
def test_a_scheduler_without_workers_is_said_and_sigterm_stops_the_waiting_ingest(tmp_path):
    """The tasks of a scheduler with no worker wait (a cluster may scale up on demand): the run
    says so in a note line, and SIGTERM ends it; it waited for its submitted stages for ever."""
    import json
    import signal
    import time

    from ais_fixtures import write_dma

    write_dma(tmp_path / "day1.csv")  # two files: the second's stage is still submitted when the first is awaited
    write_dma(tmp_path / "day2.csv", [DMA_HEADER, dma_row("02/01/2025 00:00:00", "219000001", "55.0", "11.5")])
    sched_file = tmp_path / "scheduler.json"
    sched = subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
                              "--dashboard-address", ":0", "--scheduler-file", str(sched_file)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 60
        while not (sched_file.exists() and sched_file.read_text().strip()) and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        run = subprocess.Popen([sys.executable, "-m", "pipelines.cli", "ingest-ais", "day1.csv", "day2.csv", "--db", "w.duckdb",
                                "--task-runner", f"dask:{address}"], cwd=tmp_path, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
        first = run.stderr.readline()
        assert first.strip() == (f"note: the Dask scheduler at {address} has no worker yet: the tasks wait until "
                                 f"one joins (`dask worker {address}`)")
        from distributed import Client

        with Client(address, timeout=30) as client:  # until the flow has submitted its stage, which waits
            while not client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks)):
                assert run.poll() is None and time.monotonic() < deadline + 120, "the stage was never submitted"
                time.sleep(0.5)
        time.sleep(1)
        run.send_signal(signal.SIGTERM)
        try:
            run.wait(timeout=30)
        except subprocess.TimeoutExpired:
            run.kill()
            pytest.fail("the ingest did not stop within 30 s of SIGTERM")
        assert run.returncode == 143  # 128 + SIGTERM, as an exit: the clean-ups ran
        said = run.stderr.read()  # a stop is no crash: none of Prefect's "Crash detected!" ERROR lines
        assert "Crash detected" not in said and "ERROR" not in said, said
        time.sleep(1)
        left = [pid for pid in _processes_in(tmp_path) if pid != sched.pid]
        assert not left, "a process of the stopped command still runs (Prefect's temporary server?)"
    finally:
        sched.terminate()
        sched.wait(timeout=30)


def _processes_in(folder) -> list[int]:
    """The processes whose working folder is ``folder`` (Linux /proc)."""
    import os
    from pathlib import Path

    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if os.path.realpath(entry / "cwd") == os.path.realpath(folder):
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


def test_spool_without_a_dask_runner_is_said_not_ignored(tmp_path):
    from ais_fixtures import write_dma

    write_dma(tmp_path / "day.csv")
    out = _cli(tmp_path, "ingest-ais", "day.csv", "--db", "w.duckdb", "--spool", "sp", "--json")
    assert out.returncode == 0, out.stderr
    assert ("note: --spool is used only with --task-runner dask[:ADDRESS]: this sequential run stages and commits "
            "each file in this process") in out.stderr.splitlines()


@pytest.mark.slow
def test_a_cluster_running_other_code_is_one_line(tmp_path):
    """A scheduler that imports another stormlane (here an empty ``pipelines`` package ahead on
    its path, as a scheduler started before an upgrade holds the old code) cannot unpickle the
    command's tasks: one error line saying what to do, not Dask's RuntimeError traceback."""
    import json
    import os
    import time

    from ais_fixtures import write_dma

    stale = tmp_path / "stale" / "pipelines"
    stale.mkdir(parents=True)
    for name in ("__init__.py", "ingest.py", "ingest_partitioned.py"):
        (stale / name).write_text("")
    sched_file = tmp_path / "scheduler.json"
    env = {**os.environ, "PYTHONPATH": str(stale.parent)}
    sched = subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
                              "--dashboard-address", ":0", "--scheduler-file", str(sched_file)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=stale.parent, env=env)
    try:
        deadline = time.monotonic() + 60
        while not (sched_file.exists() and sched_file.read_text().strip()) and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        write_dma(tmp_path / "day1.csv")
        out = _cli(tmp_path, "ingest-ais", "day1.csv", "--db", "w.duckdb", "--task-runner", f"dask:{address}")
        assert out.returncode == 2, out.stderr
        lines = [line for line in out.stderr.splitlines() if not line.startswith("note: ")]
        assert lines == ["error: the Dask scheduler could not read this command's tasks: the scheduler and its workers "
                         "must run the same stormlane and packages as this process; restart them after installing "
                         "another version (docs/scale.md)"]
    finally:
        sched.terminate()
        sched.wait(timeout=30)
