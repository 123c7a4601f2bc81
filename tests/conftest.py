"""Shared fixtures: the real data under ../shared/data (read in place), Prefect's test harness."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
os.environ.setdefault("DO_NOT_TRACK", "1")

# Property tests (Hypothesis): `make test` (and CI) runs the same examples every time
# ("derandomize": a failure is reproducible, and a pass is not luck); `make fuzz` draws new
# random examples (`--hypothesis-profile=explore`), which is how the land check's edge-of-pixel
# bug was found. A test's own @settings keep their example counts under either profile.
from hypothesis import settings  # noqa: E402

settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile("ci")

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("STORMLANE_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


def pytest_addoption(parser):
    parser.addoption("--run-network", action="store_true", default=False, help="run tests that need the live network")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--run-network"):
        return
    skip = pytest.mark.skip(reason="needs the live network; run with --run-network")
    for item in items:
        if "network" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Root of the real data set (AIS, CMEMS, SIMROUTE output); skips when it is not present."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data not found at {SHARED_DATA} (set STORMLANE_SHARED_DATA to ../shared/data)")
    return SHARED_DATA


def shared_file(shared_data: Path, relative: str) -> Path:
    """One file under the shared data, or skip naming it."""
    path = shared_data / relative
    if not path.exists():
        pytest.skip(f"real data file missing: {path}")
    return path


@pytest.fixture(scope="session")
def prefect_harness():
    """Prefect's test harness (temporary SQLite API, no external server), once per session."""
    from prefect.settings import (
        PREFECT_FLOWS_HEARTBEAT_FREQUENCY,
        PREFECT_SERVER_SERVICES_EVENT_PERSISTER_ENABLED,
        PREFECT_SERVER_SERVICES_TASK_RUN_RECORDER_ENABLED,
        temporary_settings,
    )
    from prefect.testing.utilities import prefect_test_harness

    with temporary_settings(
        {
            PREFECT_FLOWS_HEARTBEAT_FREQUENCY: None,
            PREFECT_SERVER_SERVICES_TASK_RUN_RECORDER_ENABLED: False,
            PREFECT_SERVER_SERVICES_EVENT_PERSISTER_ENABLED: False,
        }
    ):
        # The harness starts a temporary API server (SQLite migrations first); Prefect's default
        # 30 s wait is too short on a fresh venv on 2 busy cores, and a timeout here errors every
        # flow test of the session.
        with prefect_test_harness(server_startup_timeout=int(os.environ.get("STORMLANE_PREFECT_STARTUP_S", "240"))):
            yield


@pytest.fixture
def workspace_path(tmp_path) -> Path:
    return tmp_path / "ws.duckdb"


@pytest.fixture(scope="session")
def dask_address(tmp_path_factory):
    """A Dask cluster of separate processes (``dask scheduler`` + ``dask worker --nworkers 2
    --nthreads 1``), shared by the session's scale-out tests; yields the scheduler address."""
    from pipelines.dask_processes import dask_cluster_processes

    with dask_cluster_processes(tmp_path_factory.mktemp("dask"), n_workers=2) as address:
        yield address
