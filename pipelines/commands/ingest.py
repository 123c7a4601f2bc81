"""`stormlane ingest-ais`: load AIS files (DMA/NOAA CSV, NMEA, Parquet; gzip) into the workspace."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from pipelines.commands._common import (DbOption, JsonOption, check_output_dir, checked_task_runner, emit_json,
                                        flow_errors_one_line, interactive, note, progress, quiet_prefect,
                                        start_prefect_api, warning, warnings_as_lines)


def register(app: typer.Typer) -> None:
    @app.command("ingest-ais")
    def ingest_ais(
        # Text, not Path: typer would turn an empty argument into "." (the whole working folder).
        paths: List[str] = typer.Argument(..., metavar="PATH...", help="AIS files, or folders (every AIS file inside, recursively)."),
        db: Path = DbOption,
        fmt: Optional[str] = typer.Option(
            None, "--format", metavar="dma|noaa|nmea|parquet", help="Force the format instead of detecting it from the content."
        ),
        max_speed_kn: float = typer.Option(
            60.0, "--max-speed-kn", min=1.0, metavar="KN", show_default=True,
            help="Quarantine fixes whose implied speed from/to their neighbours exceeds this. [kn]",
        ),
        task_runner: str = typer.Option(
            "sequential", "--task-runner", metavar="sequential|dask[:ADDRESS]", show_default=True,
            help="Where the files are staged: in this process, or partitioned by file on a local Dask cluster or "
                 "an existing Dask scheduler (this process still commits them one by one, in order).",
        ),
        spool: Optional[Path] = typer.Option(
            None, "--spool", metavar="DIR", callback=lambda v: check_output_dir(v, "--spool"),
            help="Folder for the staged files of a Dask run (default: a temporary folder next to "
                 "the workspace; with a remote scheduler, a folder the workers see at the same path).",
        ),
        json_out: bool = JsonOption,
    ) -> None:
        """Clean and load AIS files; bad rows go to the quarantine with a reason code.

        Prints read = loaded + quarantined + duplicates (per reason code). Files already loaded
        (same content, compressed or not: BLAKE3 fingerprint) are skipped; rows whose MMSI and time are already stored are
        duplicates.
        With --task-runner dask[:ADDRESS] the files are staged in parallel on Dask workers and
        committed by this process in the same order: the workspace ends the same as sequentially.
        A file whose rows were all quarantined gets one warning line saying why.

        Example:

        \b
          stormlane ingest-ais ais/ more/aisdk-2025-01-14.csv.gz --db work/stormlane.duckdb
        """
        from ais.io.files import FORMATS, expand_paths
        from pipelines.ingest import ingest_paths, nothing_loaded_reason, total_bytes, without_own_dataset
        from thresholds.errors import StormlaneError

        if fmt is not None and fmt not in FORMATS:
            raise StormlaneError(f"--format {fmt!r} is not one of {', '.join(FORMATS)}")
        kind = checked_task_runner(task_runner)  # a bad spec or no scheduler fails here, before any work
        if spool is not None and kind == "sequential":  # said, not silently ignored
            note("--spool is used only with --task-runner dask[:ADDRESS]: this sequential run stages and "
                 "commits each file in this process")
        show = interactive() and not json_out
        with warnings_as_lines("ais"):  # files skipped in a folder (hidden, empty, links to nothing)
            found, own = without_own_dataset(expand_paths(paths), db)  # once: each skipped file is said once
            if own:
                note(own)
            paths = [str(f) for f in found]
            if kind == "sequential":
                total = total_bytes(paths) if show else None
                with progress("ingest AIS", total=total, enabled=show) as advance:
                    summary = ingest_paths(paths, db, fmt=fmt, max_speed_kn=max_speed_kn, progress=advance)
            else:
                summary = _run_partitioned(paths, db, fmt, max_speed_kn, task_runner, spool, show)
        per_file = summary.pop("per_file")
        for f in per_file:  # an input that loads nothing says why, in one line (also with --json)
            why = nothing_loaded_reason(f)
            if why:
                warning(f"{f['path']}: nothing loaded: {why}")
        if json_out:
            emit_json(summary)
            return
        for f in per_file:
            if f.get("already_loaded"):
                typer.echo(f"{f['path']}: already loaded, skipped")
            else:
                typer.echo(
                    f"{f['path']} ({f['format']}): read {f['read']:,}, loaded {f['loaded']:,}, "
                    f"quarantined {f['quarantined']:,}, duplicates {f['duplicates']:,}"
                    + (f", static {f['static']:,}" if f.get("static") else "")
                )
        typer.echo(
            f"total: {summary['files']} file(s), read {summary['read']:,} = loaded {summary['loaded']:,} + "
            f"quarantined {summary['quarantined']:,} + duplicates {summary['duplicates']:,}"
        )
        if summary["static"]:
            typer.echo(f"static messages joined to vessels: {summary['static']:,}")
        if summary["ignored"]:
            typer.echo(f"lines without AIS records (blank, non-AIS sentences): {summary['ignored']:,}")
        for code, n in summary["reasons"].items():
            typer.echo(f"  {code}: {n:,}")


def _run_partitioned(paths, db: Path, fmt, max_speed_kn: float, task_runner: str, spool, show: bool) -> dict:
    """The Prefect ingest flow partitioned by file on the Dask task runner."""
    import shutil
    import tempfile

    from pipelines.ingest import commit_progress, flow_with_runner, input_files
    from pipelines.storage.ais import check_dataset_folders

    found = input_files(paths, fmt, db)  # bad paths, formats and headers fail here, before the cluster starts
    check_dataset_folders(db)  # as ingest_paths does: before the workspace file is made
    start_prefect_api(task_runner)
    files = [str(p) for p in found]
    db = Path(db)
    own = spool is None
    spool_dir = Path(tempfile.mkdtemp(prefix=".stormlane-spool-", dir=db.parent)) if own else Path(spool)
    spool_dir.mkdir(parents=True, exist_ok=True)
    quiet_prefect(console_info=False)
    try:
        with flow_errors_one_line(), \
                progress("ingest AIS (files)", total=len(files), enabled=show) as advance, \
                commit_progress(lambda counts: advance(1)):
            return flow_with_runner(task_runner)(paths=files, db=str(db), fmt=fmt, max_speed_kn=max_speed_kn,
                                                 spool_dir=str(spool_dir))
    finally:
        if own:
            shutil.rmtree(spool_dir, ignore_errors=True)
