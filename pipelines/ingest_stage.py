"""One AIS file into the workspace's stage, and whether it was loaded before.

The reader step shared by the sequential ingest (:mod:`pipelines.ingest`) and the ingest
partitioned by file (:mod:`pipelines.ingest_partitioned`): the checks that can be made on every
file before any is loaded (:func:`check_inputs`), the stage of one file (:func:`stage_file`:
the fast CSV stages for large plain files, else the raw-lines path, Parquet, NMEA), and the
already-loaded check by quick key and fingerprint (:func:`loaded_record`).
"""

from __future__ import annotations

import contextlib
import logging
import os
from pathlib import Path
from typing import Callable

from ais.io.files import AisFile, inspect

log = logging.getLogger(__name__)

#: Uncompressed CSV files from this size on take the scanner-split fast path
#: (:func:`pipelines.storage.ais.stage_csv_fast`); below it the raw-lines path costs less, its
#: fixed cost per file being lower (measured on the demo's 2-3 MB files: 10 s CPU for 60 files
#: against 14 s; on 846 MB the fast path takes ~35 % less CPU).
FAST_CSV_MIN_BYTES = 16 << 20
#: Scanners of the fast CSV stage, tried in this order: "scan" (``stage_csv_scan``, one compiled pass),
#: "arrow" (``stage_csv_arrow``, pyarrow's reader), "duckdb" (``stage_csv_fast``, DuckDB's scanner).
FAST_CSV_ENGINES = ("scan", "duckdb")


#: gzip DMA/NOAA files from this compressed size on are decompressed once into a temporary plain
#: file, hashed on the way (that is their fingerprint), and take the fast CSV stage
#: (:func:`plain_copy`); smaller ones are read by the raw-lines path straight from the gzip stream.
#: Measured on the 300-ship fleet's daily files (12 MB gzip, 0.29 M rows, issue 23): the
#: raw-lines stage of the gzip stream took 2.3 s wall per file, the decompression 0.3 s and the
#: compiled scan of the plain copy 0.3 s. At AIS CSV's compression (about 5:1) 4 MiB of gzip is
#: about the fast stage's own threshold (:data:`FAST_CSV_MIN_BYTES`) of content.
GZIP_PLAIN_MIN_BYTES = 4 << 20


def wants_plain_copy(f: AisFile) -> bool:
    """Whether :func:`plain_copy` is the way to stage ``f``: a large gzip DMA/NOAA CSV, NMEA or
    Parquet file, and every zip archive's or zstd file (the readers take plain files and gzip
    streams)."""
    large_gzip_csv = f.gzip and f.format in ("dma", "noaa") and f.size_bytes >= GZIP_PLAIN_MIN_BYTES
    # a large gzip NMEA or Parquet file: its plain copy's size (rows) decides whether it is
    # committed in groups (pipelines.ingest_groups.wants_groups)
    large_gzip_other = f.gzip and f.format in ("nmea", "parquet") and f.size_bytes >= GZIP_PLAIN_MIN_BYTES
    return bool(f.staged_from_plain_copy or (large_gzip_csv and FAST_CSV_ENGINES) or large_gzip_other)


def done_future(value):
    """A future already holding ``value`` (a fingerprint known before the staging: the plain
    copy's, where the callers otherwise hold a future of one being computed)."""
    from concurrent.futures import Future

    fut = Future()
    fut.set_result(value)
    return fut


def plain_copy(f: AisFile, folder=None, prefix: str = ".stormlane-gunzip-") -> tuple[AisFile, str]:
    """Decompress the gzip, zstd or zip file ``f`` into a temporary plain file in ``folder`` (default: the
    temporary folder) and hash the content on the way: returns the plain file (its
    :class:`AisFile`; the caller removes it) and the content's fingerprint, the same
    ``"blake3:<hex>"`` as :func:`ais.io.files.fingerprint` of ``f`` (BLAKE3 of the decompressed
    bytes), so that the file is decompressed once. A truncated or corrupt stream raises
    :class:`ais.errors.AisInputError` naming ``f`` (:func:`ais.io.files.inflate_into`)."""
    import tempfile
    from dataclasses import replace

    import blake3

    from ais.io.files import inflate_into

    fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=".csv", dir=folder)
    h = blake3.blake3(max_threads=1)
    try:
        with os.fdopen(fd, "wb") as out:

            def sink(block: bytes) -> None:
                h.update(block)
                out.write(block)

            size = inflate_into(f.path, sink)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return replace(f, path=Path(tmp), gzip=False, zip=False, zstd=False, size_bytes=int(size)), "blake3:" + h.hexdigest()


class PlainCopiesAhead:
    """Plain copies (:func:`plain_copy`) of a batch's large gzip CSV files, each made in a thread
    while the file before it is staged and committed: the inflate, the hash and the write release
    the GIL, so they take the second core during the commit's single-threaded steps (the plain
    copy was 1.2 of the 4.7 CPU us per row of the 300-ship fleet's daily files, issue 23).

    One file ahead (one extra copy on disk at most), and only files whose quick key the
    workspace does not know (``known(quick_key)``): a file loaded before is recognised by its
    hash alone, as without copies ahead. The caller owns a taken copy (removes it); copies not
    taken are removed by :meth:`close`."""

    def __init__(self, files: list, fmt: str | None, folder, known: Callable[[str], bool],
                 prefix: str = ".stormlane-gunzip-"):
        from concurrent.futures import ThreadPoolExecutor

        self._files, self._fmt, self._folder, self._known = [Path(p) for p in files], fmt, folder, known
        self._prefix = prefix
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plain-copy")
        self._ahead: dict = {}

    def take(self, i: int):
        """File ``i``'s plain copy as a future of ``(AisFile, fingerprint)``, or None (not made
        ahead); starts file ``i + 1``'s."""
        fut = self._ahead.pop(i, None)
        if i + 1 < len(self._files) and i + 1 not in self._ahead:
            nxt = self._start(i + 1)
            if nxt is not None:
                self._ahead[i + 1] = nxt
        return fut

    def _start(self, j: int):
        from ais.io.files import identity_suffix, quick_key

        try:
            f = inspect(self._files[j], self._fmt, with_fingerprint=False)
            if not wants_plain_copy(f) or self._known(quick_key(f.path) + identity_suffix(f.path, self._fmt)):
                return None
        except Exception:  # the file's own turn meets the same problem and names it, in order
            return None
        return self._pool.submit(plain_copy, f, self._folder, self._prefix)

    def close(self) -> None:
        """Wait for the copy under way and remove every copy not taken."""
        for fut in self._ahead.values():
            if not fut.cancel():
                with contextlib.suppress(Exception):
                    fut.result()[0].path.unlink(missing_ok=True)
        self._ahead.clear()
        self._pool.shutdown(wait=True)


class _Scratch:
    """A private in-memory DuckDB in the place of a workspace (the readers only use ``con``)."""

    def __init__(self, con):
        self.con = con


def scratch_folder(ws):
    """Where temporary copies of inputs go: beside the workspace file (on disk, not in a RAM
    temporary folder), else the temporary folder."""
    path = getattr(ws, "path", None)
    return None if path is None or str(path) in ("", ":memory:") else Path(path).parent


def leftover_prefix(ws, kind: str) -> str:
    """The name prefix of the temporary copies (``kind`` "gunzip") or folders ("groups") an
    ingest into ``ws`` makes in :func:`scratch_folder`: the workspace file's stem in it, so that
    the next ingest into the same workspace can tell its own leftovers (:func:`remove_leftovers`)."""
    stem = Path(ws.path).stem if scratch_folder(ws) is not None else "memory"
    return f".stormlane-{kind}-{stem}-"


def remove_leftovers(ws, kind: str) -> list[Path]:
    """Remove what a killed ingest into ``ws`` left beside it (:func:`leftover_prefix`: a plain
    copy or a group folder, about the size of its input). Safe: only the process holding the
    workspace's write lock makes them. Returns what was removed."""
    from pipelines.storage.ais.spool import remove_paths

    scratch = scratch_folder(ws)
    if scratch is None:
        return []
    prefix = leftover_prefix(ws, kind)
    # the rest of the name is tempfile's random part (no "-"): not workspace w-2's beside w
    return remove_paths(sorted(p for p in Path(scratch).glob(prefix + "*") if "-" not in p.name[len(prefix):]))


def skipped_counts(path, fmt: str, file_id: int) -> dict:
    """Per-file counts of a file whose bytes are already loaded (nothing read, nothing added)."""
    return {"path": str(path), "format": fmt, "read": 0, "loaded": 0, "quarantined": 0, "duplicates": 0,
            "static": 0, "ignored": 0, "reasons": {}, "already_loaded": True, "file_id": int(file_id)}


def csv_layout(f: AisFile) -> tuple:
    """(spec, header line, header fields, stage field -> column) of a DMA/NOAA CSV file;
    :class:`ais.errors.AisFormatError` when its header lacks a needed column."""
    from ais.errors import AisFormatError
    from ais.io.csv_formats import SPECS, resolve_columns, split_csv_line
    from ais.io.files import head_text

    spec = SPECS[f.format]
    first = head_text(f.path, 1 << 16).split("\n", 1)[0]
    if "\r" in first.rstrip("\r"):
        raise AisFormatError(f.path, "lines end in a carriage return alone (classic Mac OS line ends): convert "
                                     "them to LF or CRLF", line=1)
    first = first.rstrip("\r")
    if not first.strip():
        raise AisFormatError(f.path, f"line 1 is empty: the {f.format.upper()} CSV header must be the first line",
                             line=1)
    header = split_csv_line(first)
    return spec, first, header, resolve_columns(spec, header, f.path)


def check_inputs(files: list, fmt: str | None = None) -> None:
    """What can be checked of every file before any is loaded, so that a batch with a file of
    unknown format or a CSV header or Parquet schema lacking a needed column fails with nothing
    committed: the format (detected or forced), the CSV header, the Parquet columns. (Bad rows
    are never an error; a truncated gzip file is found while it is read.)"""
    import duckdb

    from ais.io.parquet import column_mapping
    from pipelines.storage import ais as store

    con = None
    try:
        for p in files:
            f = inspect(p, fmt, with_fingerprint=False)
            if f.format in ("dma", "noaa"):
                csv_layout(f)
            elif f.format == "parquet" and not f.compressed:
                if con is None:
                    con = duckdb.connect()
                cols = store.parquet_columns(_Scratch(con), f.path)
                column_mapping([c for c, _ in cols], f.path, types=dict(cols))
    finally:
        if con is not None:
            con.close()


def stage_file(ws, f: AisFile, progress: Callable[[int], None] | None = None) -> dict:
    """Reader step: put one file's typed rows into the workspace's temporary stage. A zip
    archive's or zstd file is staged from its plain copy (:func:`plain_copy`, which the caller keeps
    while the stage is committed: the scan's stage reads quarantined lines from it)."""
    from pipelines.storage import ais as store

    if f.staged_from_plain_copy:
        raise ValueError(f"{f.path}: a zip archive's or zstd file is staged from its plain copy (plain_copy)")
    if f.format in ("dma", "noaa"):
        spec, first, header, index = csv_layout(f)
        info = None
        if not f.gzip and f.size_bytes >= FAST_CSV_MIN_BYTES:
            # The fast stages in FAST_CSV_ENGINES order; None = that one cannot be trusted with
            # this file, next one. The scan builds its own line index; the other two get one
            # built in a thread meanwhile.
            from concurrent.futures import ThreadPoolExecutor

            from ais.io.lineindex import LineIndex

            stagers = {"scan": store.stage_csv_scan, "arrow": store.stage_csv_arrow, "duckdb": store.stage_csv_fast}
            engines = list(FAST_CSV_ENGINES)
            if engines and engines[0] == "scan":  # it builds its own line index
                info = store.stage_csv_scan(ws, f.path, spec, index, len(header), first)
                engines = engines[1:]
            if info is None and engines:
                with ThreadPoolExecutor(max_workers=1) as pool:
                    ix = pool.submit(LineIndex, f.path)
                    try:
                        for engine in engines:
                            info = stagers[engine](ws, f.path, spec, index, len(header), first, ix)
                            if info is not None:
                                break
                    finally:
                        if info is None:
                            ix.result().close()
        if info is None:
            info = store.stage_csv(ws, f.path, f.gzip, spec, index, len(header), header=first)
    elif f.format == "parquet":
        from ais.io.parquet import column_mapping

        with _plain_file(f) as src:  # DuckDB reads Parquet from a plain file only
            cols = store.parquet_columns(ws, src, shown=f.path)
            # A decompressed copy is gone by the commit: its rows' text is then staged with them.
            info = store.stage_parquet(ws, src, column_mapping([c for c, _ in cols], f.path, types=dict(cols)),
                                       raw_from_file=not f.compressed)
    else:
        from ais.io.nmea import read_nmea

        stage, meta = read_nmea(f.path)
        info = store.stage_frame(ws, stage)
        info["ignored"] = meta["ignored"]
    if progress is not None:
        progress(f.size_bytes // 2)
    return info


@contextlib.contextmanager
def _plain_file(f: AisFile):
    """The path of ``f``'s content as a plain file: itself, or (compressed) a temporary decompressed
    copy, removed on exit (the stage is a table by then)."""
    if not f.compressed:
        yield f.path
        return
    import tempfile

    from ais.io.files import inflate_into

    fd, tmp = tempfile.mkstemp(prefix="stormlane-", suffix=".parquet")
    try:
        with os.fdopen(fd, "wb") as out:
            inflate_into(f.path, out.write)
        yield Path(tmp)
    finally:
        Path(tmp).unlink(missing_ok=True)


def stage_or_gzip_error(ws, f: AisFile, full, progress: Callable[[int], None] | None = None) -> dict:
    """:func:`stage_file`; when that fails on a gzip file whose fingerprint (``full``, a future
    reading the whole stream) found it truncated or corrupt, that error is raised instead of
    whatever the reader made of the partial content."""
    from ais.errors import AisInputError

    try:
        return stage_file(ws, f, progress)
    except Exception as err:
        if full is not None and f.compressed and isinstance(full.exception(), AisInputError):
            raise full.exception() from err
        raise


def loaded_record(ws, path, suffix: str, quick: str, current=None) -> dict | None:
    """The ``ais_files`` row of a loaded file with the same bytes (and forced format), or None.

    Hashes the whole file only when a loaded file has the same quick key (or none): in each
    algorithm the matching files' fingerprints were stored with (the current one first, so
    that a workspace filled by earlier versions, SHA-256, still recognises its files).
    ``current``: a future of the current algorithm's fingerprint, already running."""
    from ais.io.files import FINGERPRINT_ALGOS, fingerprint
    from pipelines.storage import ais as store

    if not store.quick_key_known(ws, quick):
        return None
    stored = store.fingerprint_algos(ws, quick)
    for algo in FINGERPRINT_ALGOS:
        if algo not in stored:
            continue
        if algo == FINGERPRINT_ALGOS[0] and current is not None:
            fp = current.result()
        else:
            fp = fingerprint(path, algo) + suffix
        rec = store.file_record(ws, fp)
        if rec is not None:
            return rec
    return None
