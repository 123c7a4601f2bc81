"""A Dask cluster of separate processes on this machine: ``dask scheduler`` and ``dask worker``.

What a user's cluster is, in miniature: the scheduler and the workers are their own processes
(started from the command line, not by the client), the client reaches them by address only.
:func:`dask_cluster_processes` starts one and stops it; the scale benchmark
(``bench/scale.py``) and the cluster test use it, and ``--task-runner dask:ADDRESS`` is pointed
at the address it yields (docs/scale.md says how to do the same on real machines).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path


class ClusterStartError(RuntimeError):
    """The scheduler or the workers did not come up in time."""


def _wait_workers(address: str, n_workers: int, timeout_s: float) -> None:
    from distributed import Client

    with Client(address, timeout=timeout_s) as client:
        client.wait_for_workers(n_workers, timeout=timeout_s)


@contextlib.contextmanager
def dask_cluster_processes(workdir: Path, n_workers: int = 2, threads_per_worker: int = 1,
                           memory_limit: str = "0", timeout_s: float = 180.0):
    """Start ``dask scheduler`` and one ``dask worker`` process with ``n_workers`` worker
    processes (nannies) of ``threads_per_worker`` threads; yield the scheduler address
    (``tcp://127.0.0.1:PORT``); stop both (SIGTERM, then SIGKILL after 10 s) on exit.

    ``memory_limit`` "0" leaves the workers unlimited (the nanny would otherwise restart a worker
    over 95 % of its share of the machine's memory). Logs go to ``workdir/dask-*.log``."""
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    sched_file = workdir / "scheduler.json"
    sched_file.unlink(missing_ok=True)
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}  # workers may start process pools
    procs: list[subprocess.Popen] = []
    logs = []
    try:
        log = open(workdir / "dask-scheduler.log", "wb")
        logs.append(log)
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address",
             ":0", "--scheduler-file", str(sched_file), "--no-show"],
            stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True, cwd=workdir))
        deadline = time.monotonic() + timeout_s
        while not sched_file.exists() or not sched_file.read_text().strip():
            if procs[0].poll() is not None or time.monotonic() > deadline:
                raise ClusterStartError(f"dask scheduler did not start (see {workdir / 'dask-scheduler.log'})")
            time.sleep(0.2)
        time.sleep(0.2)  # the file is written whole, but give the writer its close
        address = json.loads(sched_file.read_text())["address"]
        log = open(workdir / "dask-worker.log", "wb")
        logs.append(log)
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "worker", address, "--nworkers", str(n_workers), "--nthreads",
             str(threads_per_worker), "--memory-limit", memory_limit, "--local-directory", str(workdir / "worker"),
             "--no-dashboard"],
            stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True, cwd=workdir))
        _wait_workers(address, n_workers, max(1.0, deadline - time.monotonic()))
        yield address
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        for log in logs:
            log.close()
