"""`stormlane demo`: generate the demo scenario and run every step on it."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from pipelines.commands._common import JsonOption, emit_json


def register(app: typer.Typer) -> None:
    @app.command("demo")
    def demo(
        workdir: Path = typer.Option(Path("demo"), "--workdir", help="Folder for the scenario files and the workspace stormlane.duckdb."),
        seed: int = typer.Option(0, "--seed", help="Scenario seed."),
        days: float = typer.Option(30.0, "--days", min=0.5, help="Days of AIS to generate (from 2025-01-01T00:00Z)."),
        json_out: bool = JsonOption,
    ) -> None:
        """Generate the demo scenario and run the pipeline on it (scenario, ingest, ...), printing each summary."""
        import os

        # quiet and offline (STACK.md): no telemetry look-ups from Prefect
        os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
        os.environ.setdefault("DO_NOT_TRACK", "1")
        # the steps print their own summaries; Prefect's per-task INFO lines would drown them
        os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")
        from pipelines.demo import run_demo

        echo = (lambda line: typer.echo(line, err=True)) if json_out else typer.echo
        results = run_demo(workdir, seed=seed, days=days, echo=echo)
        if json_out:
            emit_json({"workdir": str(workdir), "steps": results})
        elif (results.get("report") or {}).get("report"):
            typer.echo(f"report: {results['report']['report']}")
        sys.stdout.flush()
