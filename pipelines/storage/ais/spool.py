"""A scanned file's stage written to a spool folder by one process and committed by another.

The ingest partitioned by file (:mod:`pipelines.ingest_partitioned`) stages files on Dask
workers and commits them in the process that owns the workspace. A file the compiled scan
staged (:func:`pipelines.storage.ais.stage_csv_scan`, every large DMA/NOAA CSV file) is handed
over as exactly what the sequential ingest's commit reads, so the commit is the same code on the
same values:

``SPOOL/<fingerprint>.scan/``
    ``scan.arrow``   the scanned rows (``ais_scan_src``), Arrow IPC, uncompressed: the commit
                     maps it into memory (no parse, no copy);
    ``exact.arrow``  the lines typed from their text (``ais_exact``);
    ``fixes.arrow``  the scanned fixes the first-load kernel reads (``scan_fixes``);
    ``lines.npz``    the line index's offsets (the commit reads quarantined lines' text and the
                     latest static fields from the plain file through it);
    ``lines.csv``    the plain (inflated) copy of a gzip input; a plain input is read in place
                     (the workers and the committing process see it at the same path).

(Issue 23: the earlier spool typed every line's text into a DataFrame and Parquet, 1.7 + 0.9 CPU
s per 0.3 M-row daily file, and its commit ran the speed-jump rules in SQL: 1.75 times the
sequential commit's cost.) The folder is written under a temporary name and renamed when
complete, so a folder under its final name is whole; the committing process removes it.
"""

from __future__ import annotations

import json
import os
import shutil
import uuid
from pathlib import Path

import numpy as np

from ais.io.ipc import read_ipc, write_ipc

#: The spool folder's files (see the module docstring).
SCAN_ARROW, EXACT_ARROW, FIXES_ARROW, LINES_NPZ, PLAIN_CSV, META_JSON = (
    "scan.arrow", "exact.arrow", "fixes.arrow", "lines.npz", "lines.csv", "stage.json")


def new_folder(spool_dir, run_tag: str = "") -> Path:
    """A fresh temporary folder in ``spool_dir`` for one stage of the run ``run_tag`` (renamed by
    :func:`write_scan`)."""
    d = Path(spool_dir) / f".stage-{run_tag}-{uuid.uuid4().hex}.part"
    d.mkdir(parents=True)
    return d


def part_file(out: Path, run_tag: str = "") -> Path:
    """The temporary name of a spooled Parquet stage ``out`` while one process writes it."""
    return out.with_suffix(f".{run_tag}-{os.getpid()}.part")


def remove_run_leftovers(spool_dir, run_tag: str) -> list[Path]:
    """Remove the temporary folders and files the run ``run_tag`` left in ``spool_dir``: a stage
    whose process was killed mid-write never reached its own clean-up. Other runs' (a spool
    shared by several workspaces) are kept. Returns what was removed."""
    spool = Path(spool_dir)
    return remove_paths(sorted([*spool.glob(f".stage-{run_tag}-*.part"), *spool.glob(f"*.{run_tag}-*.part")]))


def remove_paths(paths: list[Path]) -> list[Path]:
    """Remove each of ``paths`` (a folder with what it holds); returns them."""
    for p in paths:
        if p.is_dir():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)
    return paths


def write_scan(con, info: dict, folder: Path, name: str) -> Path:
    """Write the scan stage on ``con`` (``info`` from ``stage_csv_scan``) into ``folder`` (made
    by :func:`new_folder`; a plain copy of a gzip input already in it as :data:`PLAIN_CSV`) and
    rename it to ``<spool>/<name>.scan``; returns that path. Another complete folder of the same
    name (a retried or concurrent stage of the same bytes) is kept and this one removed."""
    import pyarrow as pa

    from pipelines.storage.ais._sql import _stage_kind

    write_ipc(info["scan_table"], folder / SCAN_ARROW)
    write_ipc(con.execute("SELECT * FROM ais_exact").to_arrow_table(), folder / EXACT_ARROW)
    write_ipc(pa.table({k: np.ascontiguousarray(v) for k, v in info["scan_fixes"].items()}), folder / FIXES_ARROW)
    ix = info["line_index"]
    np.savez(folder / LINES_NPZ, starts=ix.starts, ends=ix.ends, quote_lines=ix.quote_lines,
             stray_cr=np.asarray(bool(ix.stray_cr)))
    kind, extra = _stage_kind(con)
    plain = folder / PLAIN_CSV
    extra = {**extra, "path": PLAIN_CSV if plain.exists() else str(Path(extra["path"]).resolve())}
    (folder / META_JSON).write_text(json.dumps({"kind": kind, "extra": extra}))
    return claim(folder, folder.parent / f"{name}.scan", META_JSON)


def spool_name(fingerprint: str) -> str:
    """A spooled stage's file name from its input's fingerprint (no ``:`` or ``#``)."""
    return fingerprint.replace(":", "-").replace("#", "-")


def claim(folder: Path, final: Path, marker: str) -> Path:
    """Rename the complete ``folder`` to ``final``; returns ``final``. Another complete folder of
    that name (``marker`` in it: a retried or concurrent stage of the same bytes) is kept and
    this one removed."""
    try:
        folder.rename(final)
    except OSError:
        if not (final / marker).exists():
            raise
        shutil.rmtree(folder, ignore_errors=True)
    return final


def install_scan(ws, folder) -> dict:
    """Install a spooled scan stage as the workspace's ``ais_stage`` (as ``stage_csv_scan``
    would); returns the commit's ``line_index`` (to close) and ``scan_fixes``."""
    from ais.io.lineindex import LineIndex
    from pipelines.storage.ais._sql import _prepare
    from pipelines.storage.ais.stage_fast import install_scan_stage

    folder = Path(folder)
    meta = json.loads((folder / META_JSON).read_text())
    extra = dict(meta["extra"])
    plain = folder / extra["path"]  # an absolute path stays itself
    with np.load(folder / LINES_NPZ) as z:
        offsets = (z["starts"], z["ends"], z["quote_lines"], bool(z["stray_cr"]))
    ix = LineIndex(plain, offsets_from=lambda buf: offsets)
    try:
        con = ws.con
        _prepare(con)
        con.register("ais_exact_df", read_ipc(folder / EXACT_ARROW))
        try:
            con.execute("CREATE OR REPLACE TEMP TABLE ais_exact AS SELECT * FROM ais_exact_df")
        finally:
            con.unregister("ais_exact_df")
        extra.pop("path")
        install_scan_stage(con, read_ipc(folder / SCAN_ARROW), plain, extra)
        fix = read_ipc(folder / FIXES_ARROW)
        fixes = {name: fix.column(name).to_numpy() for name in fix.column_names}
    except BaseException:
        ix.close()
        raise
    return {"line_index": ix, "scan_fixes": fixes}


def remove(folder) -> None:
    """Remove a spooled stage (committed, or the same bytes committed before)."""
    shutil.rmtree(folder, ignore_errors=True)
