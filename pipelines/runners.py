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
        return "dask", _scheduler_address(spec[5:].strip())
    raise TaskRunnerError(f"--task-runner {spec!r}: use {TASK_RUNNER_SPECS}")


#: The protocols a Dask scheduler listens on that another process can reach (``inproc://`` is
#: one process's own; Dask's documentation, "Communications: Protocols").
_SCHEDULER_PROTOCOLS = ("tcp", "tls", "ws", "wss", "ucx")


def _scheduler_address(address: str) -> str:
    """``address`` when it names a host and a port (``[PROTOCOL://]HOST:PORT``, the forms
    ``dask scheduler`` prints); :class:`TaskRunnerError` naming what is missing otherwise."""
    parts = _split(address)
    bad = f"--task-runner dask:{address}: "
    if parts.scheme not in _SCHEDULER_PROTOCOLS:
        raise TaskRunnerError(bad + f"the protocol {parts.scheme!r} is not one of {', '.join(_SCHEDULER_PROTOCOLS)}")
    try:
        port = parts.port
    except ValueError:
        port = None
    if not parts.hostname or port is None or parts.path not in ("", "/"):
        raise TaskRunnerError(bad + "a scheduler's address is [PROTOCOL://]HOST:PORT, e.g. dask:tcp://10.0.0.5:8786")
    return address


def _split(address: str):
    """A scheduler address's parts (``urllib.parse.urlsplit``); no protocol is Dask's default, tcp."""
    from urllib.parse import urlsplit

    return urlsplit(address if "://" in address else f"tcp://{address}")


def check_scheduler(spec: str | None, timeout_s: float = 10.0) -> int | None:
    """The number of workers of the scheduler that ``spec`` names (``dask:ADDRESS``; ``None``
    for the other specs), asked before a command starts any work. :class:`TaskRunnerError` in
    one line when nothing answers at the address, or what answers is not a Dask scheduler
    (otherwise Prefect's Dask runner fails with a traceback, after Dask's 30 s connect timeout
    when nothing answers). Asked with the ``identity`` call every Dask server answers."""
    _, address = parse_task_runner(spec)
    if not address:
        return None
    _listening(address, timeout_s)
    import asyncio

    from distributed.core import rpc

    async def identity() -> dict:
        server = rpc(address, timeout=timeout_s)
        try:
            return await asyncio.wait_for(server.identity(), timeout_s)
        finally:
            await server.close_rpc()

    bad = f"--task-runner dask:{address}: "
    try:
        info = asyncio.run(identity())
    except (OSError, TimeoutError) as err:
        raise TaskRunnerError(bad + f"no Dask scheduler answered within {timeout_s:g} s ({type(err).__name__}); "
                              "start one with `dask scheduler` or check the address") from None
    except Exception as err:  # noqa: BLE001  (whatever answered spoke another protocol)
        raise TaskRunnerError(bad + f"what answers there is not a Dask scheduler ({type(err).__name__})") from None
    kind = info.get("type") if isinstance(info, dict) else None
    if kind != "Scheduler":
        raise TaskRunnerError(bad + f"what answers there is a Dask {(kind or 'server').lower()}, not a scheduler")
    return len(info.get("workers") or {})


def _listening(address: str, timeout_s: float) -> None:
    """:class:`TaskRunnerError` at once when nothing listens at a TCP-based scheduler address
    (refused, unknown host, unreachable): Dask's own connect retries these until its timeout."""
    import socket

    parts = _split(address)
    if parts.scheme not in ("tcp", "tls", "ws", "wss"):
        return
    try:
        socket.create_connection((parts.hostname, parts.port), timeout=timeout_s).close()
    except OSError as err:
        why = "unknown host" if isinstance(err, socket.gaierror) else (err.strerror or type(err).__name__).lower()
        raise TaskRunnerError(f"--task-runner dask:{address}: no Dask scheduler answers there ({why}); "
                              "start one with `dask scheduler` or check the address") from None


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
    _quiet_local_cluster()
    n = max(1, min(os.cpu_count() or 1, 8))
    return DaskTaskRunner(cluster_kwargs={"n_workers": n, "threads_per_worker": 1, "processes": True, "dashboard_address": ":0",
                                          "preload": ["pipelines.dask_quiet_close"]})


def _quiet_local_cluster() -> None:
    """A local cluster's scheduler and nannies live in this process and log each start, worker
    and close at INFO (about 35 lines a run) through the root logger to Prefect's console: kept to
    WARNING unless PREFECT_LOGGING_LEVEL asks for INFO or DEBUG (as Prefect's own lines)."""
    import logging

    from pipelines.prefect_console import prefect_console_verbose

    if not prefect_console_verbose():
        logging.getLogger("distributed").setLevel(logging.WARNING)


def runner_flow(flow_obj, spec: str | None):
    """``flow_obj`` with the task runner of ``spec`` (:func:`make_task_runner`). In this process or
    with Dask workers on this machine (``sequential``, ``dask``, or a scheduler at a loopback
    address) and no Prefect API configured, a call of it runs against the temporary API server
    of :mod:`pipelines.prefect_api` (the command may have started it early) and hands its address
    to the tasks (Prefect sends the settings with each task): otherwise every
    worker process starts a temporary server of its own at its first task (measured, issue 23:
    4-8 s of a 2-core machine and about 200 MB per worker, and the workers' task runs recorded
    there instead of beside the flow's). Workers on other machines cannot reach a server bound to
    this machine's loopback: point every process at one Prefect server (``PREFECT_API_URL``)."""
    flow_obj = flow_obj.with_options(task_runner=make_task_runner(spec))
    return _SharedApiFlow(flow_obj) if uses_local_api(spec) else flow_obj


def uses_local_api(spec: str | None) -> bool:
    """Whether a flow on this runner runs against this process's Prefect API when none is
    configured (:func:`runner_flow`, :mod:`pipelines.prefect_api`): in this process, or with Dask
    workers on this machine (a scheduler elsewhere has workers that cannot reach it)."""
    _, address = parse_task_runner(spec)
    return not (address and not _loopback(address))


def _loopback(address: str) -> bool:
    host = _split(address).hostname or ""
    return host in ("localhost", "::1") or host.startswith("127.")


class _SharedApiFlow:
    """A flow whose calls run with this process's Prefect API given to its tasks (see
    :func:`runner_flow`); everything else is the flow's."""

    def __init__(self, flow_obj):
        self._flow = flow_obj

    def __call__(self, *args, **kwargs):
        from prefect.settings import PREFECT_API_URL, temporary_settings

        from pipelines import prefect_api

        # the configured API, else a temporary server (started early by the command, else now)
        with temporary_settings({PREFECT_API_URL: prefect_api.api_url()}):
            return self._flow(*args, **kwargs)

    def __getattr__(self, name):
        return getattr(self._flow, name)


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
