"""`stormlane ingest-ais`: load AIS files (DMA/NOAA CSV, NMEA, Parquet; gzip) into the workspace."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from pipelines.commands._common import DbOption, JsonOption, emit_json, interactive, progress


def register(app: typer.Typer) -> None:
    @app.command("ingest-ais")
    def ingest_ais(
        paths: List[Path] = typer.Argument(..., help="AIS files, or directories (every AIS file inside, recursively)."),
        db: Path = DbOption,
        fmt: Optional[str] = typer.Option(
            None, "--format", help="Force the format instead of detecting it: dma, noaa, nmea or parquet."
        ),
        max_speed_kn: float = typer.Option(
            60.0, "--max-speed-kn", min=1.0,
            help="Quarantine fixes whose implied speed from/to their neighbours exceeds this. [kn]",
        ),
        json_out: bool = JsonOption,
    ) -> None:
        """Clean and load AIS files; bad rows go to the quarantine with a reason code.

        Prints read = loaded + quarantined + duplicates (per reason code). Files already loaded
        (same SHA-256) are skipped; rows whose MMSI and time are already stored are duplicates.
        """
        from lanes.io.files import FORMATS
        from pipelines.ingest import ingest_paths, total_bytes
        from thresholds.errors import StormlaneError

        if fmt is not None and fmt not in FORMATS:
            raise StormlaneError(f"--format {fmt!r} is not one of {', '.join(FORMATS)}")
        show = interactive() and not json_out
        total = total_bytes(paths) if show else None
        with progress("ingest AIS", total=total, enabled=show) as advance:
            summary = ingest_paths(paths, db, fmt=fmt, max_speed_kn=max_speed_kn, progress=advance)
        per_file = summary.pop("per_file")
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
