"""`stormlane audit`: retrospective audit of a sailed voyage against its alternatives."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from pipelines.commands._common import (DbReadOption, JsonOption, ProfileOption, SpeedLossOption, check_choice, check_output_file,
                                        emit_json, paths_text, vessel_option, weather_option, xarray_without_dask_arrays)


def _fmt(x, digits=2):
    if x is None:
        return "-"
    try:
        return f"{float(x):.{digits}f}"
    except (TypeError, ValueError):
        return str(x)


def register(app: typer.Typer) -> None:
    @app.command("audit")
    def audit(
        voyage: Optional[str] = typer.Option(None, "--voyage", metavar="ID", help="Voyage id in the workspace (table voyages, written by `stormlane lanes`)."),
        mmsi: Optional[int] = typer.Option(None, "--mmsi", metavar="MMSI", help="Ship's MMSI (with --start and --end instead of --voyage)."),
        start: Optional[str] = typer.Option(None, "--start", metavar="ISO", help="Start of the sailed period, ISO 8601 (UTC if no offset)."),
        end: Optional[str] = typer.Option(None, "--end", metavar="ISO", help="End of the sailed period, ISO 8601."),
        db: Path = DbReadOption,
        weather: Optional[List[Path]] = weather_option("the weather loaded in the workspace (`stormlane weather load`)"),
        vessel: Optional[str] = vessel_option("from the ship's AIS ship type and length"),
        profile: Optional[str] = ProfileOption,
        speed_loss: str = SpeedLossOption,
        report: Optional[Path] = typer.Option(None, "--report", metavar="FILE.html", callback=lambda v: check_output_file(v, "--report"),
                                              help="Also write the self-contained HTML audit report to this file."),
        json_out: bool = JsonOption,
    ) -> None:
        """Evaluate a sailed voyage in the hindcast weather and compare it with the time-optimal and
        minimum-distance routes and the cargo-safe deviation (of the voyage's lane, else of the
        sailed track) for the same departure.

        Prints the comparison table (time, distance, Hs met, fuel, CO2, hours over limits, IMO
        events) and the findings; with --json one object with a key per route. An --mmsi window
        is audited under way (a stationary start or end is trimmed); a window holding two or more
        of the ship's voyages is refused: audit them one --voyage at a time.

        Example (a ship through a storm, between two times):

        \b
          stormlane audit --mmsi 225991460 --start 2025-01-14T21:30Z --end 2025-01-15T06:30Z \\
            --db work/stormlane.duckdb --report audit.html
        """
        xarray_without_dask_arrays()
        from pipelines.audit import run_audit
        from thresholds.errors import StormlaneError

        if voyage is None and (mmsi is None or start is None or end is None):
            raise StormlaneError("give --voyage ID, or --mmsi N with --start ISO and --end ISO")
        if voyage is not None and mmsi is not None:
            raise StormlaneError("give either --voyage or --mmsi/--start/--end, not both")
        from routing.speed_loss import MODELS

        check_choice(speed_loss, MODELS, "--speed-loss")
        summary = run_audit(db, voyage_id=voyage, mmsi=mmsi, start=start, end=end, weather=paths_text(weather),
                            vessel=vessel, profile=profile, report=report, speed_loss_model=speed_loss)
        if json_out:
            emit_json(summary)
            return
        v = summary["voyage"]
        typer.echo(f"audit {summary['audit_id']}: MMSI {v['mmsi']} {v['ship_name'] or ''} {v['start_utc']} .. {v['end_utc']}")
        typer.echo(f"vessel profile {summary['vessel_profile']}, operator limits {summary['operator_profile']}")
        cols = [("time_h", "time h", 1), ("dist_nmi", "nmi", 1), ("max_hs_m", "max Hs", 2), ("mean_hs_m", "mean Hs", 2),
                ("fuel_t", "fuel t", 2), ("co2_t", "CO2 t", 2), ("exposure_h", "over limits h", 1), ("n_safety_events", "IMO events", 0)]
        typer.echo(f"{'route':<14}" + "".join(f"{label:>14}" for _, label, _ in cols))
        for role, row in summary["comparison"].items():
            typer.echo(f"{role:<14}" + "".join(f"{_fmt(row.get(c), d):>14}" for c, _, d in cols))
        typer.echo(f"proposed: {summary['proposed'] or 'none'}")
        for line in summary["findings"]:
            typer.echo(f"- {line}")
        if summary.get("report"):
            typer.echo(f"report: {summary['report']}")
