"""`stormlane workspace`: create or migrate a workspace and show its schema versions and tables."""

from __future__ import annotations

from pathlib import Path

import typer

from pipelines.commands._common import DbOption, JsonOption, emit_json


def register(app: typer.Typer) -> None:
    @app.command("workspace")
    def workspace(db: Path = DbOption, json_out: bool = JsonOption) -> None:
        """Create or migrate the DuckDB workspace and list its components and tables.

        Example:

        \b
          stormlane workspace --db work/stormlane.duckdb
        """
        from pipelines.storage import open_workspace
        from pipelines.storage.core import describe

        with open_workspace(db) as ws:
            info = describe(ws)
        if json_out:
            emit_json(info)
            return
        typer.echo(f"workspace {db}")
        for component, version in info["schema"].items():
            typer.echo(f"  schema {component}: v{version}")
        for table, rows in info["tables"].items():
            typer.echo(f"  {table}: {rows:,} rows")
