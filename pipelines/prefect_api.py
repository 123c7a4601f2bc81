"""A temporary local Prefect API for one command, started as soon as the command knows it needs one.

A flow run with no Prefect API configured (``PREFECT_API_URL``, in the environment or the
active profile) makes Prefect start a temporary API server (Prefect's documentation, "Prefect
server": a temporary server is started for a run when no API is set). Tasks on Dask workers of this
machine must report to that same server (:func:`pipelines.runners.runner_flow`). Measured on
this 2-core machine (issue 23), Prefect's own way of starting it took 8 s before the flow's first
task: importing Prefect's server module in the calling process (2.8-3.4 s, only to start a
subprocess) and then the server's start (4.6-5.0 s), one after the other; a one-file ingest on a
Dask cluster took 14.4 s against 2.3 s in one process.

:func:`start_early` starts the server's process at once, without that import, so that it boots
on the other core while the command goes on importing and checking its inputs; :func:`api_url`
waits for it to answer. The server is Prefect's own application (``create_app`` with
``ephemeral=True``: no UI, the background services of a temporary server) under uvicorn, the
ASGI server Prefect runs it with; it stops when the command exits. Its log goes to a temporary
file, whose exception line (else last line) an error quotes.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import socket
import subprocess
import sys
import tempfile
import time

from thresholds.errors import StormlaneError

#: Seconds to wait for the server to answer: Prefect's own setting for its temporary server
#: (``pipelines/__init__.py`` raises its default: the first start on a fresh venv runs the
#: database migrations).
_STARTUP_ENV = "PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS"
#: A port taken between choosing it and the server binding it: tried again this many times.
_PORT_ATTEMPTS = 3

#: The environment variable naming the server's log file to the server process.
_LOG_ENV = "STORMLANE_PREFECT_API_LOG"

_server: "_Server | None" = None


class PrefectApiError(StormlaneError):
    """The temporary Prefect API server did not start."""


def app():
    """The ASGI application the server process runs (``uvicorn --factory``). The process also
    stops when the command's process is gone without stopping it (killed)."""
    import threading

    from prefect.server.api.server import create_app

    threading.Thread(target=_stop_with_parent, args=(os.getppid(),), daemon=True).start()
    return create_app(ephemeral=True, final=True)


def _stop_with_parent(parent: int, poll_s: float = 1.0) -> None:
    """SIGTERM this process (uvicorn's graceful stop) once its parent ``parent`` has exited."""
    import signal

    while os.getppid() == parent:
        time.sleep(poll_s)
    with contextlib.suppress(OSError):  # the parent's stop() would have removed the log
        os.unlink(os.environ.get(_LOG_ENV, ""))
    os.kill(os.getpid(), signal.SIGTERM)


def configured_url() -> str | None:
    """The Prefect API this process is configured with (environment or profile), or None."""
    from prefect.settings import get_current_settings

    return get_current_settings().api.url or None


def _configured_cheaply() -> bool:
    """Whether a Prefect API is configured, as far as can be told without importing Prefect:
    ``PREFECT_API_URL`` in the environment, or Prefect's settings once it is imported anyway."""
    if os.environ.get("PREFECT_API_URL"):
        return True
    return "prefect.settings" in sys.modules and configured_url() is not None


def start_early() -> None:
    """Start the temporary server's process now, not waited for, unless a Prefect API is
    configured (once per process). Decided without importing Prefect (1-2 s,
    :func:`_configured_cheaply`): a URL set only in a Prefect profile or settings file is found by
    :func:`api_url`, which then stops this server."""
    global _server
    if _server is None and not _configured_cheaply():
        _server = _Server()
        atexit.register(_server.stop)


def api_url() -> str:
    """The configured Prefect API, else the temporary server's URL (started now if
    :func:`start_early` was not called) once it answers; :class:`PrefectApiError` in one line if
    it does not."""
    global _server
    url = configured_url()
    if url is not None:
        if _server is not None:
            _server.stop()
            _server = None
        return url
    start_early()
    return _server.wait()


class _Server:
    def __init__(self):
        self._log = tempfile.NamedTemporaryFile(prefix="stormlane-prefect-api-", suffix=".log", delete=False)
        self._ready = None
        self._launch()

    def _launch(self) -> None:
        with socket.socket() as s:  # a free port now; _PORT_ATTEMPTS covers losing it before uvicorn binds it
            s.bind(("127.0.0.1", 0))
            self.port = s.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}/api"
        cmd = [sys.executable, "-m", "uvicorn", "--factory", f"{__name__}:app", "--host", "127.0.0.1",
               "--port", str(self.port), "--log-level", "error", "--lifespan", "on"]
        self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=self._log, stderr=self._log,
                                     env={**os.environ, "PREFECT_UI_ENABLED": "0", _LOG_ENV: self._log.name})

    def wait(self) -> str:
        import urllib.error
        import urllib.request

        if self._ready:
            return self.url
        direct = urllib.request.build_opener(urllib.request.ProxyHandler({}))  # loopback: no proxy
        timeout_s = os.environ.get(_STARTUP_ENV, "180")
        deadline = time.monotonic() + float(timeout_s)
        attempts = 1
        while time.monotonic() < deadline:
            code = self.proc.poll()
            if code is not None:
                if attempts < _PORT_ATTEMPTS and "address already in use" in self._last_line().lower():
                    attempts += 1
                    self._launch()
                    continue
                raise PrefectApiError(f"the temporary Prefect API server exited (code {code}): {self._last_line()}"
                                      " (or set PREFECT_API_URL to a running `prefect server start`)")
            try:
                with direct.open(f"{self.url}/health", timeout=2) as r:
                    if r.status == 200:
                        self._ready = True
                        return self.url
            except (urllib.error.URLError, OSError):
                pass
            time.sleep(0.1)
        raise PrefectApiError(f"the temporary Prefect API server did not answer within {timeout_s} s "
                              f"({_STARTUP_ENV}); set PREFECT_API_URL to a running `prefect server start`")

    def _last_line(self) -> str:
        """The log's last exception line (``SomeError: why``), else its last line."""
        import re

        with open(self._log.name, encoding="utf-8", errors="replace") as f:
            lines = [ln.strip() for ln in f if ln.strip()]
        errors = [ln for ln in lines if re.match(r"^[\w.]+(Error|Exception|Exit)\b.*:", ln)]
        return (errors or lines or ["no output"])[-1]

    def stop(self) -> None:
        if self._log.closed:
            return
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._log.close()
        os.unlink(self._log.name)
