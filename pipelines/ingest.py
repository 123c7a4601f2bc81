"""AIS ingest: files -> cleaned ``ais_positions``, ``vessels``, ``ais_quarantine``.

``ingest_paths`` is the plain entry point (used by the CLI, the demo and tests);
``ingest_flow`` is the same work as a Prefect flow: a discovery task, then per file a reader
task (stage the file), a cleaning-and-commit task (the rules of :mod:`ais.clean` run as SQL
in :mod:`pipelines.storage.ais`, one transaction per file), and a summary.

Each file is loaded at most once (BLAKE3 of its bytes in ``ais_files``); rows whose
(mmsi, time_utc) is already stored count as duplicates, so overlapping files add nothing twice.
Counts of the summary, per file and in total: ``read = loaded + quarantined + duplicates``.
For CSV and Parquet ``read`` counts data rows (empty lines are ``ignored``); for NMEA it
counts AIS messages after multipart assembly plus sentences that could not form one (see
:mod:`ais.io.nmea`); static messages 5/24 are counted in ``static`` and joined to
``vessels``.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
import uuid
from pathlib import Path
from typing import Callable, Iterable, Optional

from ais.clean import DEFAULT_MAX_SPEED_KN
from ais.io.files import expand_paths, inspect
from pipelines.ingest_stage import (
    PlainCopiesAhead, check_inputs, done_future, leftover_prefix, loaded_record, plain_copy, remove_leftovers,
    scratch_folder, skipped_counts, stage_file, stage_or_gzip_error, wants_plain_copy,
)
from pipelines.ingest_groups import commit_in_groups, wants_groups
from pipelines.runners import retry_transient
from thresholds.errors import StormlaneError

log = logging.getLogger(__name__)

SUMMARY_KEYS = ("files", "read", "loaded", "quarantined", "duplicates", "reasons", "static", "ignored", "already_loaded")


def empty_summary() -> dict:
    return {"files": 0, "read": 0, "loaded": 0, "quarantined": 0, "duplicates": 0, "reasons": {},
            "static": 0, "ignored": 0, "already_loaded": 0}


def add_to_summary(summary: dict, counts: dict) -> dict:
    """Add one file's counts to a running summary (in place) and return it."""
    summary["files"] += 1
    for k in ("read", "loaded", "quarantined", "duplicates", "static", "ignored"):
        summary[k] += int(counts.get(k, 0))
    if counts.get("already_loaded"):
        summary["already_loaded"] += 1
    for code, n in counts.get("reasons", {}).items():
        summary["reasons"][code] = summary["reasons"].get(code, 0) + int(n)
    summary["reasons"] = dict(sorted(summary["reasons"].items()))
    return summary


def ingest_file(ws, path, fmt: str | None = None, max_speed_kn: float = DEFAULT_MAX_SPEED_KN,
                progress: Callable[[int], None] | None = None, before_commit=None, plain_ahead=None) -> dict:
    """Load one AIS file into an open workspace; returns its counts (see module docstring).
    ``plain_ahead``: a future of the file's plain copy made ahead (:class:`PlainCopiesAhead`)."""
    from pipelines.storage import ais as store

    from concurrent.futures import ThreadPoolExecutor

    from ais.io.files import fingerprint, identity_suffix, quick_key

    f = inspect(path, fmt, with_fingerprint=False)
    suffix = identity_suffix(f.path, fmt)  # bytes forced into another format are another input
    quick = quick_key(f.path) + suffix
    pool = ThreadPoolExecutor(max_workers=1)

    def content_fingerprint() -> str:
        return fingerprint(f.path) + suffix

    # The fingerprint (BLAKE3) of the whole file runs in a thread (it releases the GIL) while the
    # file is cleaned and committed; it is needed only for the file's row. It starts after the
    # staging, whose fast scan keeps both cores busy, so that it fills the single-threaded steps
    # of the commit instead. Only when a loaded file has the same quick key (size + first and
    # last MiB) is the full hash computed first, to skip an already loaded file.
    full = plain = None
    try:
        if plain_ahead is not None:  # a truncated or corrupt gzip file raises here, named
            plain, fp = plain_ahead.result()
            full = done_future(fp + suffix)
        if store.quick_key_known(ws, quick):
            full = full or pool.submit(content_fingerprint)
            done = loaded_record(ws, f.path, suffix, quick, full)
        else:
            done = None
    except BaseException:
        pool.shutdown(wait=True)
        _remove(plain)
        raise
    if done is not None:
        pool.shutdown(wait=True)
        _remove(plain)
        log.info("%s: already loaded as file %s (%s), skipped", f.path, done["file_id"], done["path"])
        if progress is not None:
            progress(f.size_bytes)
        return skipped_counts(f.path, f.format, done["file_id"])
    info = None
    t_stage = time.perf_counter()
    try:
        if plain is None and wants_plain_copy(f):
            # A large gzip CSV file, or a zip archive's or zstd file: decompressed once into a plain copy
            # beside the workspace (hashed on the way: its fingerprint), which the stage reads.
            plain, fp = plain_copy(f, scratch_folder(ws), leftover_prefix(ws, "gunzip"))
            full = done_future(fp + suffix)
        elif full is None and f.compressed:
            # A gzip file's fingerprint reads the whole stream, which proves it complete: started
            # at once, beside the staging (whose gzip reading is single-threaded).
            full = pool.submit(content_fingerprint)
        source = plain if plain is not None else f
        grouped = wants_groups(source)
        if grouped:
            # A large plain CSV file: split into groups of whole vessels, each staged and
            # committed in turn inside the file's one transaction (pipelines.ingest_groups).
            info = {"ignored": 0, "staging": "groups"}
        elif plain is not None:
            info = stage_file(ws, plain)
            if progress is not None:
                progress(f.size_bytes // 2)
        else:
            info = stage_or_gzip_error(ws, f, full, progress)
        t_stage = time.perf_counter() - t_stage
        if full is None:
            full = pool.submit(content_fingerprint)
        meta = {"fingerprint": full, "quick_key": quick, "path": str(f.path), "format": f.format,
                "size_bytes": f.size_bytes, "ignored": info["ignored"], "line_index": info.get("line_index"),
                "scan_fixes": info.pop("scan_fixes", None)}
        info.pop("scan_table", None)  # held by the stage while it is registered, no longer
        if grouped:
            counts = commit_in_groups(ws, source, meta, max_speed_kn, before_commit, scratch_folder(ws))
        else:
            counts = store.classify_and_commit(ws, meta, max_speed_kn=max_speed_kn, before_commit=before_commit)
    except store.AlreadyLoaded as same:
        # the same content under another name or compression (x.csv and x.csv.gz), found by
        # its fingerprint only now: nothing was committed
        store.discard_stage(ws)
        log.info("%s: same content as file %s (%s), skipped", f.path, same.record["file_id"], same.record["path"])
        if progress is not None:
            progress(f.size_bytes - f.size_bytes // 2)
        return skipped_counts(f.path, f.format, same.record["file_id"])
    except BaseException:
        store.discard_stage(ws)
        raise
    finally:
        pool.shutdown(wait=True)
        if info is not None and info.get("line_index") is not None:
            info["line_index"].close()
        if plain is not None:
            plain.path.unlink(missing_ok=True)
    if progress is not None:
        progress(f.size_bytes - f.size_bytes // 2)
    log.info("%s (%s): read %d, loaded %d, quarantined %d, duplicates %d", f.path, f.format, counts["read"],
             counts["loaded"], counts["quarantined"], counts["duplicates"])
    # Wall seconds: the stage (and its own phases, when it reports them), then the commit's steps.
    timings = {"stage": t_stage, **{f"stage_{k}": v for k, v in (info.get("timings") or {}).items()},
               **meta.get("timings", {})}
    return {"path": str(f.path), "format": f.format, **counts, "already_loaded": False,
            "staging": info.get("staging", f.format), "line_mapping": info.get("line_mapping"), "timings": timings}


def _remove(plain) -> None:
    if plain is not None:
        plain.path.unlink(missing_ok=True)


def ingest_paths(paths: Iterable, db, fmt: str | None = None, max_speed_kn: float = DEFAULT_MAX_SPEED_KN,
                 progress: Callable[[int], None] | None = None) -> dict:
    """Ingest AIS files (or directories of them) into the workspace ``db``.

    Parameters
    ----------
    paths : iterable of path-like
        Files, or directories (every AIS file inside, recursively).
    db : path-like
        The DuckDB workspace file (created when missing).
    fmt : {"dma", "noaa", "nmea", "parquet"}, optional
        Force the format of every file instead of detecting it from the content.
    max_speed_kn : float
        Implied-speed limit between consecutive fixes of one MMSI. [kn]
    progress : callable, optional
        Called with a number of bytes as files are processed (total: :func:`total_bytes`).

    Returns
    -------
    dict
        ``{"files", "read", "loaded", "quarantined", "duplicates", "reasons", "static",
        "ignored", "already_loaded"}`` summed over the files, plus ``"per_file"``.
    """
    from pipelines.storage import ais as store
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import check_dataset_folders, limit_ingest_memory, sync_positions_parquet

    files = input_files(paths, fmt, db)
    check_dataset_folders(db)  # before the workspace file is made
    summary = empty_summary()
    per_file = []
    with open_workspace(db) as ws:
        limit_ingest_memory(ws)
        sync_positions_parquet(ws)  # the positions dataset as the workspace says (after a crash)
        for p in remove_leftovers(ws, "gunzip"):
            log.warning("removed %s, left by an ingest into this workspace that did not finish", p)
        ahead = PlainCopiesAhead(files, fmt, scratch_folder(ws), lambda quick: store.quick_key_known(ws, quick),
                                 leftover_prefix(ws, "gunzip"))
        try:
            for i, p in enumerate(files):
                try:
                    counts = ingest_file(ws, p, fmt=fmt, max_speed_kn=max_speed_kn, progress=progress,
                                         plain_ahead=ahead.take(i))
                except StormlaneError as err:
                    raise _with_committed(err, per_file)
                add_to_summary(summary, counts)
                per_file.append(counts)
        finally:
            ahead.close()
    summary["per_file"] = per_file
    return summary


def _with_committed(err: Exception, per_file: list) -> Exception:
    """``err`` (same type) with a note naming the files of the batch committed before it
    failed: each file is its own transaction, so they stay loaded and a rerun skips them."""
    done = [c["path"] for c in per_file if not c.get("already_loaded")]
    if done and err.args:
        shown = ", ".join(done[:3]) + (f" and {len(done) - 3} more" if len(done) > 3 else "")
        err.args = (f"{err.args[0]} (the {len(done)} file(s) before it are loaded and stay so: {shown}; "
                    "a rerun skips them)",) + err.args[1:]
    return err


#: Why a whole file was quarantined, for the reason codes that say something about the file
#: rather than about single rows (docs/ingest.md lists every code).
_FILE_LEVEL_WHY = {
    "bad_time": "{n} of its {read} {unit} have no time{hint}",
    "bad_sentence": "{n} of its {read} lines are not AIS sentences (!AIVDM/!AIVDO){hint}",
    "bad_line": "{n} of its {read} lines do not have the header's number of fields{hint}",
}
_NMEA_TIME_HINT = (": NMEA needs a tag block with a c: time (\\c:1736899200*hh\\!AIVDM,...) or $PGHP lines; "
                   "a plain receiver log without either cannot be placed in time")


def _time_layout_hint(fmt: str | None) -> str:
    """What a CSV or Parquet file's times must look like: its rows "have no time" said alone read
    as if the column were empty when it held times in another layout (``...T00:00:00Z``, month-first)."""
    from datetime import datetime

    from ais.clean import TIME_MAX_UTC, TIME_MIN_UTC
    from ais.io.csv_formats import SPECS

    years = f"within {TIME_MIN_UTC.year}-{TIME_MAX_UTC.year - 1}"  # the clean times' span [min, max)
    if fmt == "parquet":
        return f" readable as a timestamp or ISO 8601 text {years}"
    spec = SPECS.get(fmt)
    if spec is None or not spec.time_formats:
        return ""
    shown = " or ".join(f"'{datetime(2025, 1, 31, 23, 59, 0).strftime(f)}'" for f in spec.time_formats)
    return f" readable in the {fmt} layout ({shown}, UTC) {years}"


def nothing_loaded_reason(counts: dict) -> str | None:
    """Why a file loaded no position at all, in one line; None when it loaded some, was loaded
    before, or held no AIS record (that is the caller's ``ignored`` count).

    The reason is the code that took most of its rows, said for the file (no times in an NMEA
    file, no AIS sentence in a file forced to be NMEA, ...), then the other codes with counts.
    """
    read, loaded = int(counts.get("read", 0)), int(counts.get("loaded", 0))
    if loaded or counts.get("already_loaded"):
        return None
    if read == 0:
        ignored = int(counts.get("ignored", 0))
        return f"it holds no AIS record ({ignored:,} line(s) without one)" if ignored else "it holds no AIS record"
    reasons = {k: int(v) for k, v in (counts.get("reasons") or {}).items() if v}
    if int(counts.get("duplicates", 0)) == read:
        return f"all {read:,} rows are already in the workspace (duplicates)"
    code, n = max(reasons.items(), key=lambda kv: (kv[1], kv[0])) if reasons else ("", 0)
    nmea = counts.get("format") == "nmea"
    template = _FILE_LEVEL_WHY.get(code)
    if template:
        hint = _NMEA_TIME_HINT if (code == "bad_time" and nmea) else (
            f" (is it really {counts.get('format')}?)" if code in ("bad_sentence", "bad_line") else
            _time_layout_hint(counts.get("format")) if code == "bad_time" else "")
        head = template.format(n=f"{n:,}", read=f"{read:,}", unit="messages" if nmea else "rows", hint=hint)
    else:
        from ais.clean import REASONS

        head = f"all {read:,} rows were quarantined, most as {code} ({REASONS.get(code, code)}: {n:,})"
    rest = [f"{k} {v:,}" for k, v in sorted(reasons.items(), key=lambda kv: (-kv[1], kv[0])) if k != code]
    return head + (f"; also {', '.join(rest)}" if rest else "")


def without_own_dataset(files: list, db) -> tuple[list, str | None]:
    """``(files, what was skipped)``: the files outside the workspace's own positions dataset
    (``<stem>.parquet/`` beside it, :func:`pipelines.storage.ais.parquet.dataset_root`), found
    when the workspace sits inside an input folder. Its parts are this ingest's own output: read
    again they would load nothing (every row a duplicate) after re-reading every row (a year:
    100 M rows). The text says what was skipped, for the caller's note; None when nothing was."""
    from pipelines.storage.ais.parquet import dataset_root

    root = dataset_root(db)
    if root is None:
        return list(files), None
    root = root.resolve()
    kept = [f for f in files if root not in Path(f).resolve().parents]  # inside it (a file of its name is refused later)
    n = len(files) - len(kept)
    if n == 0:
        return kept, None
    if not kept:
        from ais.errors import AisInputError

        raise AisInputError(root, "this workspace's own positions dataset is its output, not an input, and the inputs hold no other AIS file")
    return kept, f"{n:,} file{'s' if n != 1 else ''} of this workspace's own positions dataset ({root}) skipped: its output, not an input"


def total_bytes(paths: Iterable) -> int:
    """Bytes of all files :func:`ingest_paths` would read (for a progress bar)."""
    return sum(p.stat().st_size for p in expand_paths(paths))


# ---------------------------------------------------------------------------------------------
# Prefect flow (thin: discovery -> per file: stage, clean + commit -> summary). Built on first
# access so that the CLI and ``ingest_paths`` do not pay Prefect's import time.
# ---------------------------------------------------------------------------------------------
def input_files(paths, fmt: Optional[str] = None, db=None) -> list[Path]:
    """The AIS files named by ``paths`` (:func:`ais.io.files.expand_paths`), checked
    (:func:`check_inputs`), without the workspace's own dataset (:func:`without_own_dataset`,
    a warning saying so)."""
    files, skipped = without_own_dataset(expand_paths(paths), db)
    if skipped:
        log.warning(skipped)
    check_inputs(files, fmt)
    return files


def _discover(paths: list[str], fmt: Optional[str] = None, db=None) -> list[str]:
    return [str(p) for p in input_files(paths, fmt, db)]


#: Workspaces the flow's file tasks share (one connection per flow run and workspace: opening
#: and closing - a checkpoint - cost ~0.15 s per file, a third of the demo's ingest time).
_FLOW_WORKSPACES: dict = {}


def _on_flow_workspace(db: str, step, *args):
    """``step(ws, *args)`` on the flow's shared connection to ``db``."""
    try:
        return step(_flow_workspace(db), *args)
    except BaseException:
        _close_flow_workspace(db)  # a retry starts from a fresh connection
        raise


def _ingest_one(db: str, path: str, fmt: str | None, max_speed_kn: float) -> dict:
    return _on_flow_workspace(db, ingest_file, path, fmt, max_speed_kn)


def _close_flow_workspace(db: str) -> None:
    ws = _FLOW_WORKSPACES.pop(db, None)
    if ws is not None:
        ws.close()


def _summarise(per_file: list[dict]) -> dict:
    summary = empty_summary()
    for counts in per_file:
        add_to_summary(summary, counts)
    summary["per_file"] = per_file
    return summary


_FLOW_OBJECTS: dict = {}
#: Files staged ahead of the commit in a partitioned ingest (staged or staging, not yet committed):
#: the spool's bound, about 370 bytes per row of each (a plain copy of a gzip input, the scanned
#: columns, the fixes). One writer commits a 0.3 M-row daily file in about 0.45 s and one worker
#: stages it in about 0.4-0.5 s (issue 23, 2-core machine), so a few files ahead keep the writer busy.
STAGE_AHEAD_FILES = 4
_TASKS = ("ingest_flow", "discover_task", "ingest_file_task", "stage_task", "commit_task", "summarise_task")


def _plan(db: str, files: list[str], fmt: str | None) -> tuple[list[str], dict]:
    from pipelines.ingest_partitioned import plan_files

    return _on_flow_workspace(db, plan_files, files, fmt)


def _commit_one(db: str, staged: dict, max_speed_kn: float) -> dict:
    from pipelines.ingest_partitioned import commit_spooled

    return _on_flow_workspace(db, commit_spooled, staged, max_speed_kn)


def _flow_workspace(db: str):
    from pipelines.storage import open_workspace

    from pipelines.storage.ais import limit_ingest_memory, sync_positions_parquet

    ws = _FLOW_WORKSPACES.get(db)
    if ws is None:
        ws = _FLOW_WORKSPACES[db] = open_workspace(db)
        limit_ingest_memory(ws)
        sync_positions_parquet(ws)  # the positions dataset as the workspace says (after a crash)
    return ws


def _build_flow() -> dict:
    if _FLOW_OBJECTS:
        return _FLOW_OBJECTS
    from prefect import flow, task
    from prefect.cache_policies import NO_CACHE

    from pipelines.ingest_partitioned import stage_to_spool
    from pipelines.runners import make_task_runner

    discover_task = task(_discover, name="discover-ais-files")
    ingest_file_task = task(_ingest_one, name="ingest-ais-file", retries=2, retry_delay_seconds=[2, 5],
                            retry_condition_fn=retry_transient)
    plan_task = task(_plan, name="skip-loaded-ais-files", cache_policy=NO_CACHE)
    stage_task = task(stage_to_spool, name="stage-ais-file", retries=2, retry_delay_seconds=[2, 5],
                      retry_condition_fn=retry_transient, cache_policy=NO_CACHE,
                      task_run_name="stage-{path}")
    commit_task = task(_commit_one, name="commit-ais-file", retries=2, retry_delay_seconds=[2, 5],
                       retry_condition_fn=retry_transient, cache_policy=NO_CACHE)
    summarise_task = task(_summarise, name="summarise-ingest")

    def _stage_and_commit(files: list[str], db: str, fmt, max_speed_kn: float, spool_dir: str) -> list[dict]:
        """Stage the files on the task runner at most :data:`STAGE_AHEAD_FILES` ahead and commit
        them here in order. Then the run's temporary spool names are removed: a stage killed
        mid-write (a worker lost) leaves its folder, and a failed run's stages still running are
        awaited first (their complete stages stay in the spool for the rerun)."""
        from pipelines.storage.ais.spool import remove_run_leftovers

        run_tag = uuid.uuid4().hex[:12]
        todo, skipped = plan_task(db, files, fmt)
        staged: dict = {}
        per_file = []
        try:
            for p in files:
                while todo and len(staged) < STAGE_AHEAD_FILES:  # the spool holds this many at most
                    # absolute paths: a worker's working folder is its own, not this process's
                    staged[todo[0]] = stage_task.submit(os.path.abspath(todo[0]), fmt, os.path.abspath(spool_dir),
                                                        run_tag)
                    todo = todo[1:]
                # the stage's own exception, raised here (a failed future handed to a task is not run)
                counts = skipped[p] if p in skipped else commit_task(db, {**_staged(p, staged.pop(p)), "path": p},
                                                                     max_speed_kn)
                per_file.append(_file_done(counts))
        except BaseException as err:
            if not isinstance(err, Exception):  # stopped (SIGTERM, Ctrl-C): stop the stages too
                for future in staged.values():
                    _cancel(future)
                staged = {}
            raise
        finally:
            for future in staged.values():
                future.wait()
            left = remove_run_leftovers(spool_dir, run_tag)
            if left:
                log.warning("removed %d unfinished stage(s) from %s: %s", len(left), spool_dir,
                            ", ".join(p.name for p in left))
        return per_file

    @flow(name="ingest-ais", task_runner=make_task_runner("sequential"))
    def ingest_flow(paths: list[str], db: str, fmt: Optional[str] = None,
                    max_speed_kn: float = DEFAULT_MAX_SPEED_KN, spool_dir: Optional[str] = None) -> dict:
        """Prefect flow: ingest AIS files into the workspace ``db``; returns the same summary
        as :func:`ingest_paths`.

        Without ``spool_dir`` each file is staged and committed in this process. With it the
        files are partitioned: each is staged by a task submitted to the flow's task runner
        (e.g. Dask workers, see :mod:`pipelines.ingest_partitioned`) while this process commits
        them one by one in the same order, so the workspace ends the same."""
        files = discover_task(paths, fmt, db)
        try:
            if spool_dir is None:
                per_file = [ingest_file_task(db, p, fmt, max_speed_kn) for p in files]
            else:
                per_file = _stage_and_commit(files, db, fmt, max_speed_kn, spool_dir)
        finally:
            _close_flow_workspace(db)
        return summarise_task(per_file)

    _FLOW_OBJECTS.update(ingest_flow=ingest_flow, discover_task=discover_task, ingest_file_task=ingest_file_task,
                         stage_task=stage_task, commit_task=commit_task, summarise_task=summarise_task)
    return _FLOW_OBJECTS


def _staged(path: str, future) -> dict:
    """The stage of ``path`` from its task; an input error of the file is raised naming it as the
    user did (the task was given its absolute path), as the sequential ingest says it."""
    from ais.errors import AisInputError

    try:
        return future.result()
    except AisInputError as err:
        if err.path != path and err.path == os.path.abspath(path):
            raise type(err)(path, err.detail, err.line) from None
        raise


def _cancel(future) -> None:
    """Cancel a submitted stage: a stopped run does not wait for stages that may never run (a
    scheduler with no worker) or that a rerun stages again."""
    wrapped = getattr(future, "wrapped_future", None)  # Dask's future under Prefect's
    cancel = getattr(wrapped, "cancel", None) or getattr(future, "cancel", None)
    if cancel is not None:
        cancel()


#: Called with each file's counts by the partitioned flow (the CLI's progress bar).
_COMMIT_CALLBACKS: list = []


def _file_done(counts: dict) -> dict:
    for cb in _COMMIT_CALLBACKS:
        cb(counts)
    return counts


@contextlib.contextmanager
def commit_progress(callback):
    """Call ``callback(counts)`` as the partitioned ingest flow is done with each file
    (committed, or skipped as already loaded)."""
    _COMMIT_CALLBACKS.append(callback)
    try:
        yield
    finally:
        _COMMIT_CALLBACKS.remove(callback)


def flow_with_runner(task_runner: str | None = None):
    """The ingest flow with the chosen task runner (:func:`pipelines.runners.make_task_runner`);
    pass ``spool_dir`` to partition it by file."""
    from pipelines.runners import runner_flow

    return runner_flow(_build_flow()["ingest_flow"], task_runner)


def __getattr__(name: str):
    if name in _TASKS:
        return _build_flow()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


if __name__ == "__main__":
    import sys

    print(_build_flow()["ingest_flow"](sys.argv[1:], "stormlane.duckdb"))
