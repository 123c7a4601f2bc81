"""Preloaded into the worker processes of the local cluster that ``--task-runner dask`` starts
(:func:`pipelines.runners.make_task_runner`): the close of a local cluster stays quiet.

The cluster closes its scheduler (in the command's process) while a worker may still send its
periodic heartbeat; the worker then logs "Failed to communicate with scheduler during heartbeat"
with a traceback on the console after a run that succeeded (about 1 run in 4 of ``stormlane
lanes --task-runner dask`` here; a known race of ``distributed``'s shutdown, dask/distributed
issues 7105 and 9032). On a local cluster a scheduler that stops answering is the command
closing it, so that one record is dropped; every other worker record is kept.
"""

from __future__ import annotations

import logging

#: The worker's record of a heartbeat that found no scheduler (``distributed.worker.Worker.heartbeat``).
HEARTBEAT_FAILED = "Failed to communicate with scheduler during heartbeat"


class _DropHeartbeatAtClose(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith(HEARTBEAT_FAILED)


def dask_setup(worker) -> None:
    """``distributed``'s preload hook, run in each worker process at its start."""
    logging.getLogger("distributed.worker").addFilter(_DropHeartbeatAtClose())
