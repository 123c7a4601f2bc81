"""`stormlane schedule` serves a real Prefect deployment with a cron schedule (issue 7 acceptance).

A local Prefect server runs in a subprocess (its own PREFECT_HOME); `stormlane schedule` runs in
another; the test reads the deployment back through the Prefect API and stops both by PID.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(proc: subprocess.Popen, timeout: float = 20.0) -> None:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=timeout)


def _wait_for(check, timeout: float, what: str, procs=()):
    t0 = time.monotonic()
    last = None
    while time.monotonic() - t0 < timeout:
        for p in procs:
            if p.poll() is not None:
                raise AssertionError(f"{what}: process {p.args[:3]} exited with {p.returncode}")
        try:
            value = check()
            if value:
                return value
        except Exception as err:  # noqa: BLE001 - not up yet
            last = err
        time.sleep(0.5)
    raise AssertionError(f"{what}: not ready after {timeout:.0f} s ({last})")


@pytest.mark.slow
def test_schedule_serves_the_nightly_deployment_with_its_cron(tmp_path):
    import httpx
    from prefect.client.orchestration import get_client
    from prefect.settings import PREFECT_API_URL, temporary_settings

    port = _free_port()
    url = f"http://127.0.0.1:{port}/api"
    env = {**os.environ, "PREFECT_HOME": str(tmp_path / "prefect-home"), "PREFECT_API_URL": url,
           "PREFECT_SERVER_ANALYTICS_ENABLED": "false", "DO_NOT_TRACK": "1", "PREFECT_LOGGING_LEVEL": "WARNING"}
    logs = tmp_path / "logs"
    logs.mkdir()
    server = subprocess.Popen([str(BIN / "prefect"), "server", "start", "--host", "127.0.0.1", "--port", str(port)], env=env,
                              stdout=open(logs / "server.log", "wb"), stderr=subprocess.STDOUT)
    served = None
    try:
        _wait_for(lambda: httpx.get(f"{url}/health", timeout=2).status_code == 200, 120, "prefect server", [server])
        db = tmp_path / "ws.duckdb"
        from pipelines.storage import open_workspace

        open_workspace(db).close()  # schedule reads a workspace, never creates one
        served = subprocess.Popen(
            [str(BIN / "stormlane"), "schedule", "--cron", "0 2 * * *", "--timezone", "Europe/Paris", "--db", str(db),
             "--out", str(tmp_path / "nights")],
            env=env, stdout=open(logs / "schedule.log", "wb"), stderr=subprocess.STDOUT, cwd=tmp_path,
        )
        with temporary_settings({PREFECT_API_URL: url}):
            with get_client(sync_client=True) as client:
                dep = _wait_for(lambda: client.read_deployment_by_name("nightly-reroute/nightly"), 120, "deployment", [served])
                assert len(dep.schedules) == 1
                sched = dep.schedules[0]
                assert sched.active
                assert sched.schedule.cron == "0 2 * * *"
                assert sched.schedule.timezone == "Europe/Paris"
                assert dep.parameters["db"] == str(db.resolve())
                assert dep.parameters["out_root"] == str((tmp_path / "nights").resolve())
                assert dep.entrypoint == "pipelines.nightly.nightly_reroute"
        assert served.poll() is None  # still serving
    finally:
        if served is not None:
            _stop(served)
        _stop(server)
    assert served.returncode is not None and server.returncode is not None
