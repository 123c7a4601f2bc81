"""AIS ingest partitioned by file: files staged in parallel, committed one by one in order.

The work of :func:`pipelines.ingest.ingest_file` split in two so that a cluster can take the
expensive half:

1. :func:`stage_to_spool` (any process, e.g. a Dask worker): detect the format, hash the file,
   run the same reader as the sequential ingest (:func:`pipelines.ingest_stage.stage_file`) into a
   private in-memory DuckDB and write the stage to the spool folder, named by the fingerprint:
   a file the compiled scan staged (every large DMA/NOAA CSV file) as the scan's own tables, line
   offsets and plain copy (``SPOOL/blake3-<hex>.scan/``, :mod:`pipelines.storage.ais.spool`),
   any other as its typed rows with every line's text (``SPOOL/blake3-<hex>.parquet``).
2. :func:`commit_spooled` (the process that owns the workspace, always one writer): install that
   stage as the workspace's ``ais_stage`` and apply the cross-row and cross-file rules
   (duplicates, speed jumps against the stored tracks) with the same
   :func:`pipelines.storage.ais.classify_and_commit`, one transaction per file: a scanned file's
   commit is the sequential ingest's, on the same arrays.

Files are committed in the sequential ingest's order, so the workspace ends identical to a
sequential run (tested). :func:`plan_files` skips files already loaded before anything is
staged (quick key, then the full fingerprint only when the quick key is known). The spool needs
room for the files staged ahead of the commit (``pipelines.ingest.STAGE_AHEAD_FILES``, each
removed once committed: about 370 bytes per row of a scanned file); with a remote Dask
scheduler the input files and the spool folder must be visible to the workers at the same path.
"""

from __future__ import annotations

import logging
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ais.clean import DEFAULT_MAX_SPEED_KN
from pipelines.ingest_groups import wants_groups
from pipelines.ingest_stage import (
    _Scratch, done_future, loaded_record, plain_copy, scratch_folder, skipped_counts, stage_file,
    stage_or_gzip_error, wants_plain_copy,
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


def stage_to_spool(path: str, fmt: str | None, spool_dir: str, run_tag: str = "") -> dict:
    """Stage one file into ``spool_dir`` (no workspace needed); returns what the commit needs.
    ``run_tag`` names the run in the temporary names (:func:`spool.remove_run_leftovers`).

    A file the compiled scan stages is spooled as the scan's own tables and line offsets
    (:mod:`pipelines.storage.ais.spool`, ``spool_kind`` "scan"); any other (NMEA, Parquet,
    small or non-canonical CSV) as its typed stage with every line's text in one Parquet file
    (``spool_kind`` "parquet")."""
    import duckdb
    import pyarrow.parquet as pq

    from ais.io.files import fingerprint, identity_suffix, inspect, quick_key
    from pipelines.storage import ais as store
    from pipelines.storage.ais import spool

    f = inspect(path, fmt, with_fingerprint=False)
    suffix = identity_suffix(f.path, fmt)
    folder = spool.new_folder(spool_dir, run_tag)
    try:
        with ThreadPoolExecutor(max_workers=1) as pool:
            plain = None
            if wants_plain_copy(f):  # as the sequential ingest: inflated once (hashed on the way), then scanned
                plain, fp = plain_copy(f, folder)
                full = done_future(fp + suffix)
            else:  # the hash releases the GIL: it overlaps the staging
                full = pool.submit(lambda: fingerprint(f.path) + suffix)
            source = plain if plain is not None else f
            if wants_groups(source):  # split and committed in groups where the workspace is
                return _plain_to_spool(f, source, full.result(), folder, spool_dir, suffix)
            mem = _Scratch(duckdb.connect(config={"threads": _stage_threads()}))  # temporary: no workspace tables
            info, raw_from = {}, None
            try:
                info = stage_file(mem, plain) if plain is not None else stage_or_gzip_error(mem, f, full)
                name = spool.spool_name(full.result())
                if info.get("staging") == "scan":
                    if plain is not None:
                        os.replace(plain.path, folder / spool.PLAIN_CSV)
                    out, kind = spool.write_scan(mem.con, info, folder, name), "scan"
                else:
                    out, kind = Path(spool_dir) / f"{name}.parquet", "parquet"
                    # a decompressed copy (zip, zstd) is gone by the commit: its text is spooled
                    raw_from = _raw_from_file(mem.con) if plain is None else None
                    tmp = spool.part_file(out, run_tag)
                    pq.write_table(store.stage_table(store.read_stage(mem, with_raw=raw_from is None)), tmp,
                                   compression="zstd")
                    tmp.replace(out)  # a retried or concurrent stage of the same bytes writes the same content
            finally:
                if info.get("line_index") is not None:
                    info["line_index"].close()
                mem.con.close()
            fp = full.result()
    finally:
        spool.remove(folder)  # renamed away when it holds a scan stage
    return {"path": str(f.path), "format": f.format, "fingerprint": fp, "quick_key": quick_key(f.path) + suffix,
            "size_bytes": f.size_bytes, "ignored": int(info["ignored"]), "spool": str(out), "spool_kind": kind,
            "staging": info.get("staging", f.format), "line_mapping": info.get("line_mapping"),
            "raw_from": raw_from}


def _plain_to_spool(f, source, fp: str, folder: Path, spool_dir, suffix: str) -> dict:
    """A file committed in groups (``pipelines.ingest_groups.wants_groups``: a large CSV, Parquet
    or NMEA file): the worker only inflates and hashes it; the committing process splits it and
    commits its groups
    (:func:`pipelines.ingest_groups.commit_in_groups`), whose memory is one group's. Spooled as
    the plain file: the input itself, or its inflated copy moved to ``<spool>/<name>.plain/``."""
    from ais.io.files import quick_key
    from pipelines.storage.ais import spool

    path = str(Path(f.path).resolve())
    if source is not f:
        os.replace(source.path, folder / spool.PLAIN_CSV)
        final = spool.claim(folder, Path(spool_dir) / f"{spool.spool_name(fp)}.plain", spool.PLAIN_CSV)
        path = str(final / spool.PLAIN_CSV)
    return {"path": str(f.path), "format": f.format, "fingerprint": fp, "quick_key": quick_key(f.path) + suffix,
            "size_bytes": f.size_bytes, "ignored": 0, "spool": path, "spool_kind": "plain", "staging": "groups",
            "line_mapping": None, "raw_from": None}


def _raw_from_file(con) -> dict | None:
    """Where the commit reads the ``raw`` text of a Parquet input's quarantined rows (its path and
    columns), when the stage holds none; None for any other stage. Spooling every row's text
    cost as much as the staging (issue 23)."""
    from pipelines.storage.ais._sql import _stage_kind

    extra = _stage_kind(con)[1]
    return {k: extra.get(k) for k in ("raw_path", "raw_columns", "raw_wkb")} if "raw_path" in extra else None


def commit_spooled(ws, staged: dict, max_speed_kn: float = DEFAULT_MAX_SPEED_KN) -> dict:
    """Clean and commit one spooled stage into the open workspace (one transaction)."""
    import pyarrow.parquet as pq

    from pipelines.storage import ais as store
    from pipelines.storage.ais import spool

    done = store.file_record(ws, staged["fingerprint"])
    if done is not None:  # the same content twice in one batch: the first commit wins
        _remove_spool(staged)
        return skipped_counts(staged["path"], staged["format"], done["file_id"])
    meta = {k: staged[k] for k in ("fingerprint", "quick_key", "path", "format", "size_bytes", "ignored")}
    if staged.get("spool_kind") == "plain":
        return _commit_plain(ws, staged, meta, max_speed_kn)
    got = {"line_index": None}
    try:
        if staged.get("spool_kind") == "scan":
            got = spool.install_scan(ws, staged["spool"])
        else:
            store.stage_arrow(ws, pq.read_table(staged["spool"]))
            if staged.get("raw_from"):  # the quarantined rows' text from the input (typed statics spooled)
                from pipelines.storage.ais._sql import _set_stage_kind

                _set_stage_kind(ws.con, "typed", staged["raw_from"])
        counts = store.classify_and_commit(ws, {**meta, **got}, max_speed_kn=max_speed_kn)
    except BaseException:
        store.discard_stage(ws)
        raise
    finally:
        if got["line_index"] is not None:
            got["line_index"].close()
    return _committed(staged, counts)


def _committed(staged: dict, counts: dict) -> dict:
    """After a spooled file's commit: its spool removed, its counts logged and returned."""
    _remove_spool(staged)
    log.info("%s (%s): read %d, loaded %d, quarantined %d, duplicates %d", staged["path"], staged["format"],
             counts["read"], counts["loaded"], counts["quarantined"], counts["duplicates"])
    return {"path": staged["path"], "format": staged["format"], **counts, "already_loaded": False,
            "staging": staged["staging"], "line_mapping": staged["line_mapping"]}


def _commit_plain(ws, staged: dict, meta: dict, max_speed_kn: float) -> dict:
    """Commit a file spooled as its plain copy (:func:`_plain_to_spool`) in groups."""
    from ais.io.files import inspect
    from pipelines.ingest_groups import commit_in_groups

    source = inspect(staged["spool"], staged["format"], with_fingerprint=False)
    return _committed(staged, commit_in_groups(ws, source, meta, max_speed_kn, scratch=scratch_folder(ws)))


def _remove_spool(staged: dict) -> None:
    from pipelines.storage.ais import spool

    if staged.get("spool_kind") == "plain":
        folder = Path(staged["spool"]).parent
        if folder.name.endswith(".plain"):  # an inflated copy; an input stays
            spool.remove(folder)
    elif staged.get("spool_kind") == "scan":
        spool.remove(staged["spool"])
    else:
        Path(staged["spool"]).unlink(missing_ok=True)


def _stage_threads() -> int:
    """DuckDB threads of one staging: all cores, or one per core a Dask worker was given (a
    worker process per core staging with every core would oversubscribe the machine)."""
    try:
        from distributed import get_worker

        return max(1, int(get_worker().state.nthreads))
    except (ImportError, ValueError, AttributeError):
        return os.cpu_count() or 1
