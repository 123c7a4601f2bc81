"""`stormlane demo`: generate the demo scenario and run every step on it."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from pipelines.commands._common import JsonOption, check_output_dir, emit_json, note, xarray_without_dask_arrays


def register(app: typer.Typer) -> None:
    @app.command("demo")
    def demo(
        workdir: Path = typer.Option(Path("demo"), "--out", metavar="DIR", show_default=True,
                                     callback=lambda v: check_output_dir(v, "--out"),
                                     help="Folder for the scenario files, the workspace stormlane.duckdb and the reports (created; "
                                          "its folder must exist)."),
        seed: int = typer.Option(0, "--seed", metavar="N", show_default=True, help="Scenario seed."),
        days: float = typer.Option(30.0, "--days", min=0.5, metavar="N", show_default=True, help="Days of AIS to generate (from 2025-01-01T00:00Z)."),
        json_out: bool = JsonOption,
        old_workdir: Path = typer.Option(None, "--workdir", hidden=True, callback=lambda v: check_output_dir(v, "--workdir"),
                                         help="Deprecated name of --out."),
    ) -> None:
        """Generate the demo scenario and run every step on it (scenario, ingest, lanes, weather, audit,
        nightly, report), printing each summary; `make demo` runs it.

        Example:

        \b
          stormlane demo --out demo
        """
        import os

        if old_workdir is not None:
            note("--workdir is deprecated: use --out")
            workdir = old_workdir

        # quiet and offline (STACK.md): no telemetry look-ups from Prefect
        os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
        os.environ.setdefault("DO_NOT_TRACK", "1")
        # the steps print their own summaries; Prefect's per-task INFO lines would drown them
        os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")
        xarray_without_dask_arrays()
        from pipelines.demo import run_demo

        echo = (lambda line: typer.echo(line, err=True)) if json_out else typer.echo
        results = run_demo(workdir, seed=seed, days=days, echo=echo)
        if json_out:
            emit_json({"workdir": str(workdir), "steps": results})
        elif (results.get("report") or {}).get("report"):
            typer.echo(f"report: {results['report']['report']}")
        sys.stdout.flush()
