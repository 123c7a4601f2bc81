"""`stormlane scenario`: generate the demo scenario (AIS files, writers' extras, scenario.json)."""

from __future__ import annotations

from pathlib import Path

import typer

from pipelines.commands._common import JsonOption, check_output_dir, emit_json


def register(app: typer.Typer) -> None:
    @app.command("scenario")
    def scenario(
        out: Path = typer.Option(..., "--out", metavar="DIR", callback=lambda v: check_output_dir(v, "--out"),
                                 help="Folder to write DIR/ais/, DIR/weather/ and DIR/scenario.json into (created; its folder must exist)."),
        seed: int = typer.Option(0, "--seed", metavar="N", show_default=True, help="Random seed: the same seed writes byte-identical files."),
        start: str = typer.Option("2025-01-01T00:00Z", "--start", metavar="ISO", show_default=True, help="Start of the AIS period (ISO 8601, UTC)."),
        days: float = typer.Option(30.0, "--days", min=0.01, metavar="N", show_default=True, help="Length of the AIS period in days."),
        gzip: bool = typer.Option(False, "--gzip", help="Write .csv.gz / .nmea.gz instead of plain text."),
        json_out: bool = JsonOption,
    ) -> None:
        """Generate the deterministic Western Mediterranean demo scenario.

        About 20 ships (ro-pax, container, tanker) sail liner services between Barcelona, Palma, Valencia, Marseille, Genova, Tunis, Alger and Cagliari on hand-built sea routes. Their AIS is written as DMA CSV and NMEA (one file per UTC day) with noise, gaps and a share of dirty rows; DIR/scenario.json records everything that was generated.

        Example (three days around the demo's first storm):

        \b
          stormlane scenario --out mydata --start 2025-01-13T00:00Z --days 3
        """  # noqa: E501
        from pipelines.scenario import build_scenario, summary_lines

        truth = build_scenario(out, seed=seed, start=start, days=days, gzip=gzip)
        if json_out:
            emit_json({
                "out": str(out),
                "seed": seed,
                "start_utc": truth["scenario"]["start_utc"],
                "end_utc": truth["scenario"]["end_utc"],
                "vessels": len(truth["vessels"]),
                "services": len(truth["services"]),
                "voyages": len(truth["voyages"]),
                "files": len(truth.get("ais", {}).get("files", [])),
                "expected_ingest": truth.get("expected_ingest", {}),
                "dirty_rows": truth.get("dirty_rows", {}).get("counts", {}),
                "writers": truth.get("writers", []),
            })
            return
        for line in summary_lines(truth):
            typer.echo(line)
        typer.echo(f"  wrote {out / 'scenario.json'}")
