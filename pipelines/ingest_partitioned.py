"""AIS ingest partitioned by file: files staged in parallel, committed one by one in order.

The work of :func:`pipelines.ingest.ingest_file` split in two so that a cluster can take the
expensive half:

1. :func:`stage_to_spool` (any process, e.g. a Dask worker): detect the format, hash the file,
   run the same reader as the sequential ingest (:func:`pipelines.ingest_stage.stage_file`) into a
   private in-memory DuckDB and write the typed stage - every row with its line, raw text, kind
   and parse error - to ``SPOOL/blake3-<hex>.parquet`` (named by its fingerprint).
2. :func:`commit_spooled` (the process that owns the workspace, always one writer): load that
   stage back (:func:`pipelines.storage.ais.stage_frame`) and apply the cross-row and
   cross-file rules (duplicates, speed jumps against the stored tracks) with the same
   :func:`pipelines.storage.ais.classify_and_commit`, one transaction per file.

Files are committed in the sequential ingest's order, so the workspace ends identical to a
sequential run (tested). :func:`plan_files` skips files already loaded before anything is
staged (quick key, then the full fingerprint only when the quick key is known). The spool needs
room for one Parquet copy of each staged file (removed once committed); with a remote Dask
scheduler the input files and the spool folder must be visible to the workers at the same path.
"""

from __future__ import annotations

import logging
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ais.clean import DEFAULT_MAX_SPEED_KN
from pipelines.ingest_stage import (
    _Scratch, done_future, loaded_record, plain_copy, skipped_counts, stage_file, stage_or_gzip_error,
    wants_plain_copy,
)

log = logging.getLogger(__name__)


def plan_files(ws, files: list, fmt: str | None = None) -> tuple[list[str], dict[str, dict]]:
    """Split ``files`` into those to stage and those already loaded (their skipped counts)."""
    from ais.io.files import identity_suffix, inspect, quick_key

    todo, skipped = [], {}
    for p in files:
        f = inspect(p, fmt, with_fingerprint=False)
        suffix = identity_suffix(f.path, fmt)
        done = loaded_record(ws, f.path, suffix, quick_key(f.path) + suffix)
        if done is None:
            todo.append(str(p))
        else:
            log.info("%s: already loaded as file %s (%s), skipped", f.path, done["file_id"], done["path"])
            skipped[str(p)] = skipped_counts(f.path, f.format, done["file_id"])
    return todo, skipped


def stage_to_spool(path: str, fmt: str | None, spool_dir: str) -> dict:
    """Stage one file into ``spool_dir`` (no workspace needed); returns what the commit needs."""
    import duckdb
    import pyarrow.parquet as pq

    from ais.io.files import fingerprint, identity_suffix, inspect, quick_key
    from pipelines.storage import ais as store

    f = inspect(path, fmt, with_fingerprint=False)
    suffix = identity_suffix(f.path, fmt)
    plain = None
    with ThreadPoolExecutor(max_workers=1) as pool:
        if wants_plain_copy(f):  # as the sequential ingest: inflated once (hashed on the way), then scanned
            plain, fp = plain_copy(f)
            full = done_future(fp + suffix)
        else:  # the hash releases the GIL: it overlaps the staging
            full = pool.submit(lambda: fingerprint(f.path) + suffix)
        mem = _Scratch(duckdb.connect(config={"threads": _stage_threads()}))  # temporary: no workspace tables
        try:
            info = stage_file(mem, plain) if plain is not None else stage_or_gzip_error(mem, f, full)
            try:
                stage = store.read_stage(mem)
            finally:
                if info.get("line_index") is not None:
                    info["line_index"].close()
        finally:
            mem.con.close()
            if plain is not None:
                plain.path.unlink(missing_ok=True)
        fp = full.result()
    out = Path(spool_dir) / f"{fp.replace(':', '-').replace('#', '-')}.parquet"
    tmp = out.with_suffix(f".{os.getpid()}.part")
    pq.write_table(store.stage_table(stage), tmp, compression="zstd")
    tmp.replace(out)  # a retried or concurrent stage of the same bytes writes the same content
    return {"path": str(f.path), "format": f.format, "fingerprint": fp, "quick_key": quick_key(f.path) + suffix,
            "size_bytes": f.size_bytes, "ignored": int(info["ignored"]), "spool": str(out),
            "staging": info.get("staging", f.format), "line_mapping": info.get("line_mapping")}


def commit_spooled(ws, staged: dict, max_speed_kn: float = DEFAULT_MAX_SPEED_KN) -> dict:
    """Clean and commit one spooled stage into the open workspace (one transaction)."""
    import pyarrow.parquet as pq

    from pipelines.storage import ais as store

    done = store.file_record(ws, staged["fingerprint"])
    if done is not None:  # the same content twice in one batch: the first commit wins
        Path(staged["spool"]).unlink(missing_ok=True)
        return skipped_counts(staged["path"], staged["format"], done["file_id"])
    try:
        store.stage_arrow(ws, pq.read_table(staged["spool"]))
        meta = {k: staged[k] for k in ("fingerprint", "quick_key", "path", "format", "size_bytes", "ignored")}
        counts = store.classify_and_commit(ws, {**meta, "line_index": None}, max_speed_kn=max_speed_kn)
    except BaseException:
        store.discard_stage(ws)
        raise
    Path(staged["spool"]).unlink(missing_ok=True)
    log.info("%s (%s): read %d, loaded %d, quarantined %d, duplicates %d", staged["path"], staged["format"],
             counts["read"], counts["loaded"], counts["quarantined"], counts["duplicates"])
    return {"path": staged["path"], "format": staged["format"], **counts, "already_loaded": False,
            "staging": staged["staging"], "line_mapping": staged["line_mapping"]}


def _stage_threads() -> int:
    """DuckDB threads of one staging: all cores, or one per core a Dask worker was given (a
    worker process per core staging with every core would oversubscribe the machine)."""
    try:
        from distributed import get_worker

        return max(1, int(get_worker().state.nthreads))
    except (ImportError, ValueError, AttributeError):
        return os.cpu_count() or 1
