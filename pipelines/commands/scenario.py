"""`stormlane scenario`: generate the demo scenario (AIS files, writers' extras, scenario.json)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from pipelines.commands._common import JsonOption, check_output_dir, emit_json, note


def register(app: typer.Typer) -> None:
    @app.command("scenario")
    def scenario(
        out: Path = typer.Option(..., "--out", metavar="DIR", callback=lambda v: check_output_dir(v, "--out"),
                                 help="Folder to write DIR/ais/, DIR/weather/ and DIR/scenario.json into (created; its folder must exist)."),
        seed: int = typer.Option(0, "--seed", metavar="N", show_default=True, help="Random seed: the same seed writes byte-identical files."),
        start: str = typer.Option("2025-01-01T00:00Z", "--start", metavar="ISO", show_default=True, help="Start of the AIS period (ISO 8601, UTC)."),
        days: float = typer.Option(30.0, "--days", min=0.01, metavar="N", show_default=True, help="Length of the AIS period in days."),
        gzip: bool = typer.Option(False, "--gzip", help="Write .csv.gz / .nmea.gz instead of plain text."),
        vessels: Optional[int] = typer.Option(
            None, "--vessels", min=1, metavar="N",
            help="A fleet of N ships (the demo's 20, then numbered copies) written day by day in bounded memory: "
                 "gzip DMA CSV only, no weather, voyages and port stays in DIR/truth/*.parquet (docs/scale.md)."),
        workers: Optional[int] = typer.Option(
            None, "--workers", min=1, metavar="N",
            help="With --vessels: processes that sail the ships and write the days (default: one per core)."),
        json_out: bool = JsonOption,
    ) -> None:
        """Generate the deterministic Western Mediterranean demo scenario.

        About 20 ships (ro-pax, container, tanker) sail liner services between Barcelona, Palma, Valencia, Marseille, Genova, Tunis, Alger and Cagliari on hand-built sea routes. Their AIS is written as DMA CSV and NMEA (one file per UTC day) with noise, gaps and a share of dirty rows; DIR/scenario.json records everything that was generated.

        With --vessels N it writes a year-scale fleet instead (streaming, bounded memory, the same seed gives
        byte-identical files whatever --workers): a year of 300 ships is about 108 M rows, 4.6 GB of gzip (measured: docs/scale.md).

        Examples (three days around the demo's first storm; a year of 300 ships):

        \b
          stormlane scenario --out mydata --start 2025-01-13T00:00Z --days 3
          stormlane scenario --days 365 --vessels 300 --out year
        """  # noqa: E501
        # Options that change nothing in this mode are said, not silently ignored.
        if vessels is not None and gzip:
            note("--gzip changes nothing with --vessels: the fleet's AIS is always written as gzip")
        if vessels is None and workers is not None:
            note("--workers applies to --vessels only: the demo scenario is written by one process")
        if vessels is not None:
            _fleet(out, seed, start, days, vessels, workers, json_out)
            return
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


def _fleet(out: Path, seed: int, start: str, days: float, vessels: int, workers: int | None, json_out: bool) -> None:
    """``stormlane scenario --vessels N``: the year-scale fleet (:mod:`pipelines.scenario_fleet`)."""
    from pipelines.scenario_fleet import build_fleet_scenario, fleet_summary_lines

    truth = build_fleet_scenario(out, vessels=vessels, seed=seed, start=start, days=days, workers=workers)
    if json_out:
        emit_json({"out": str(out), "seed": seed, "start_utc": truth["scenario"]["start_utc"],
                   "end_utc": truth["scenario"]["end_utc"], "vessels": len(truth["vessels"]),
                   "voyages": truth["truth"]["voyages"]["rows"], "files": len(truth["ais"]["files"]),
                   "bytes": truth["ais"]["bytes"], "expected_ingest": truth["expected_ingest"],
                   "dirty_rows": truth["dirty_rows"]["counts"], "writers": truth["writers"]})
        return
    for line in fleet_summary_lines(truth):
        typer.echo(line)
    typer.echo(f"  wrote {out / 'scenario.json'}")
