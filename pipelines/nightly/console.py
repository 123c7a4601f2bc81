"""The console while the CLI runs a night: a user error ends it with one ``error:`` line
(:mod:`pipelines.prefect_console`), and the progress of the lanes' reroutes."""

from __future__ import annotations

import contextlib

from pipelines.prefect_console import RUN_LOGGERS, is_user_error, prefect_console_handlers, user_errors_one_line

__all__ = ["RUN_LOGGERS", "is_user_error", "prefect_console_handlers", "reroute_progress", "user_errors_one_line"]


def _future_result(future):
    """A task future's value, or an exception describing why the task did not complete."""
    future.wait()
    state = future.state
    if state.is_completed():
        return future.result()
    res = future.result(raise_on_failure=False)
    return res if isinstance(res, BaseException) else RuntimeError(f"task {state.name}: {state.message}")


#: Callbacks ``(done, total)`` told as each lane's reroute completes (the CLI's progress bar).
_PROGRESS_CALLBACKS: list = []


@contextlib.contextmanager
def reroute_progress(callback):
    """Call ``callback(done, total)`` as the lanes of a night finish (in submission order)."""
    _PROGRESS_CALLBACKS.append(callback)
    try:
        yield
    finally:
        _PROGRESS_CALLBACKS.remove(callback)


def _results_with_progress(futures: list) -> list:
    results = []
    for cb in _PROGRESS_CALLBACKS:
        cb(0, len(futures))
    for f in futures:
        results.append(_future_result(f))
        for cb in _PROGRESS_CALLBACKS:
            cb(len(results), len(futures))
    return results
