"""The console while the CLI runs a Prefect flow (a night, an ingest or lanes on a cluster): a user
error ends it with one ``error:`` line, Prefect's run errors held back."""

from __future__ import annotations

import contextlib
import logging
import sys

from thresholds.errors import StormlaneError


class _UserErrorsWithoutTraceback(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info and isinstance(record.exc_info[1], StormlaneError):
            record.exc_info, record.exc_text = None, None
        return True


def workspace_locked(err: BaseException | None) -> bool:
    """``err`` is DuckDB's refusal of a workspace another process holds open for writing."""
    if "duckdb" not in sys.modules:  # nothing opened a workspace
        return False
    import duckdb

    return isinstance(err, duckdb.IOException) and "Could not set lock" in str(err)


#: What Dask's scheduler says when it cannot unpickle a client's tasks (``distributed``'s
#: scheduler): a scheduler running other code than the client, e.g. started before an upgrade.
_GRAPH_UNREADABLE = "Error during deserialization of the task graph"

#: The CLI's line for it.
CLUSTER_RUNS_OTHER_CODE = ("the Dask scheduler could not read this command's tasks: the scheduler and its workers "
                           "must run the same stormlane and packages as this process; restart them after installing "
                           "another version (docs/scale.md)")


def cluster_runs_other_code(err: BaseException | None) -> bool:
    """``err`` is the scheduler's refusal of a task graph it cannot unpickle."""
    return isinstance(err, RuntimeError) and _GRAPH_UNREADABLE in str(err)


def stopped_by_user(err: BaseException | None) -> bool:
    """``err`` ends a run the user stopped: Ctrl-C, or SIGTERM (the CLI turns it into exit status
    143). Prefect logs such a stop as "Crash detected!", which is no crash of ours to print."""
    return isinstance(err, KeyboardInterrupt) or (isinstance(err, SystemExit) and err.code in (130, 143))


def is_user_error(err: BaseException | None) -> bool:
    """An error the CLI reports as one ``error:`` line: a :class:`StormlaneError` (bad input,
    missing coverage ...), a workspace locked by another process, or a cluster running other code."""
    return isinstance(err, StormlaneError) or workspace_locked(err) or cluster_runs_other_code(err)


def prefect_console_verbose() -> bool:
    """PREFECT_LOGGING_LEVEL asks for Prefect's INFO or DEBUG lines on the console."""
    import os

    value = os.environ.get("PREFECT_LOGGING_LEVEL", "").strip().upper()
    level = int(value) if value.isdigit() else logging.getLevelName(value) if value else logging.WARNING
    return isinstance(level, int) and level < logging.WARNING


#: Loggers of Prefect's flow and task runs (their records reach the console through the root logger).
RUN_LOGGERS = ("prefect.flow_runs", "prefect.task_runs")


class _HoldRunErrors(logging.Filter):
    """On a console handler: keep the flow and task runs' ERROR records back instead of printing them."""

    def __init__(self) -> None:
        super().__init__()
        self.held: list[logging.LogRecord] = []

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno >= logging.ERROR and record.name.startswith(RUN_LOGGERS):
            self.held.append(record)
            return False
        return True


def prefect_console_handlers() -> list[logging.Handler]:
    """Prefect's console handlers (on the root logger, set up when Prefect is imported)."""
    from prefect.logging.configuration import ensure_logging_setup
    from prefect.logging.handlers import PrefectConsoleHandler

    ensure_logging_setup()  # what `import prefect.main` does first (later calls are incremental: same handlers)
    return [h for h in logging.getLogger().handlers if isinstance(h, PrefectConsoleHandler)]


@contextlib.contextmanager
def user_errors_one_line(hold_console: bool = True, handlers: list[logging.Handler] | None = None):
    """While the CLI runs a flow, a user error ends it with the CLI's one ``error:`` line only.

    Prefect logs a failed run's exception with its traceback: for a :class:`StormlaneError`
    the traceback is dropped (other exceptions keep theirs). With ``hold_console`` the flow and
    task runs' ERROR lines ("Task run failed with exception ...", "Finished in state Failed",
    "Flow run ... Encountered exception") are also kept off the console (``handlers``, default
    Prefect's console handlers) until the run ends: dropped when it ended with a user error
    (:func:`is_user_error`, whose message the CLI prints) or a stop by the user
    (:func:`stopped_by_user`), printed then otherwise (an unexpected crash, or a lane that failed
    in a night that completed). Prefect's API log handler still receives every record.
    """
    loggers = [logging.getLogger(n) for n in RUN_LOGGERS]
    f = _UserErrorsWithoutTraceback()
    for lg in loggers:
        lg.addFilter(f)
    holders = []
    if hold_console:
        for h in prefect_console_handlers() if handlers is None else handlers:
            holder = _HoldRunErrors()
            h.addFilter(holder)
            holders.append((h, holder))
    error = None
    try:
        yield
    except BaseException as err:
        error = err
        raise
    finally:
        for lg in loggers:
            lg.removeFilter(f)
        for h, holder in holders:
            h.removeFilter(holder)
            if not (is_user_error(error) or stopped_by_user(error)):
                for record in holder.held:
                    h.handle(record)
