"""Where a flow's fanned-out tasks run: the ``--task-runner sequential|dask[:ADDRESS]`` option.

Shared by the flows that fan out (``nightly``: one task per lane; ``lanes``: one task per
origin-destination partition). :func:`parse_task_runner` validates a spec without importing
Prefect (a CLI checks it before starting anything); :func:`make_task_runner` builds the runner.
"""

from __future__ import annotations

import os

from thresholds.errors import StormlaneError

#: What a spec may be, for error messages and ``--help``.
TASK_RUNNER_SPECS = "sequential, dask or dask:ADDRESS (e.g. dask:tcp://10.0.0.5:8786)"


class TaskRunnerError(StormlaneError):
    """A ``--task-runner`` spec that is not ``sequential``, ``dask`` or ``dask:ADDRESS``."""


def parse_task_runner(spec: str | None) -> tuple[str, str | None]:
    """``(kind, address)`` of a spec: ``("sequential", None)``, ``("dask", None)`` (a local
    cluster) or ``("dask", ADDRESS)`` (an existing scheduler); :class:`TaskRunnerError` otherwise."""
    spec = (spec or "sequential").strip()
    if spec == "sequential":
        return "sequential", None
    if spec == "dask":
        return "dask", None
    if spec.startswith("dask:") and spec[5:].strip():
        return "dask", spec[5:].strip()
    raise TaskRunnerError(f"--task-runner {spec!r}: use {TASK_RUNNER_SPECS}")


def make_task_runner(spec: str | None):
    """``sequential`` (one thread), ``dask`` (a local ``distributed`` cluster, one single-threaded
    worker process per core) or ``dask:ADDRESS`` (an existing Dask scheduler)."""
    kind, address = parse_task_runner(spec)
    if kind == "sequential":
        from prefect.task_runners import ThreadPoolTaskRunner

        return ThreadPoolTaskRunner(max_workers=1)
    from prefect_dask import DaskTaskRunner

    if address:
        return DaskTaskRunner(address=address)
    n = max(1, min(os.cpu_count() or 1, 8))
    return DaskTaskRunner(cluster_kwargs={"n_workers": n, "threads_per_worker": 1, "processes": True, "dashboard_address": ":0"})


def retry_transient(task_, task_run, state) -> bool:
    """Retry transient failures (network, a workspace locked by another writer), never bad input
    or missing coverage (a :class:`StormlaneError` says what to change; retrying cannot fix it).

    A Prefect ``retry_condition_fn`` for the I/O tasks of the flows."""
    try:
        state.result()
    except StormlaneError:
        return False
    except Exception:  # noqa: BLE001
        return True
    return False
