"""`stormlane audit`: retrospective audit of a sailed voyage against its alternatives."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from pipelines.commands._common import (DbReadOption, JsonOption, ProfileOption, SpeedLossOption, check_output_file,
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
                                              help="Also write the self-contained HTML audit report to this file, and its model beside it (FILE.json: `stormlane report --model` re-renders it)."),
        json_out: bool = JsonOption,
    ) -> None:
        """Evaluate a sailed voyage in the hindcast weather and compare it with the time-optimal and
        minimum-distance routes and the cargo-safe deviation (of the voyage's lane, else of the
        sailed track) for the same departure.

        Two rows for the voyage: as_sailed (its AIS times, the truth) and as_sailed_modelled (the
        same track re-timed by the vessel model from the same departure at the voyage's calm-water
        speed, from its AIS speeds in low sea states, else the profile's). The alternatives are
        sailed by the same model; every delta is against as_sailed_modelled, and the model's bias
        (modelled minus AIS) is printed next to them. Prints the comparison table (time, distance,
        Hs met, fuel, CO2, hours over limits, IMO events) and the findings. An --mmsi window is
        audited under way (a stationary start or end is trimmed); a window holding two or more of
        the ship's voyages is refused: audit them one --voyage at a time.

        --json prints one object with the keys: audit_id; voyage (voyage_id, mmsi, ship_name,
        start_utc, end_utc, lane_id, origin, destination); vessel_profile; operator_profile;
        speed_loss_model (a formula's name or learned:NAME: every route is sailed by it);
        weather; calm_water_speed (speed_kn, source: ais_low_sea or profile, low_sea_h, low_hs_m);
        as_sailed and as_sailed_modelled, and optimal, safe_optimal, least_fuel (by the voyage's AIS
        arrival, a speed setting per leg), min_distance, deviation when computed (each: time_h, dist_nmi, max_hs_m, mean_hs_m, fuel_t, co2_t, exposure_h,
        adverse_h, n_safety_events, no_weather_h, sea_only, land_legs, land_nmi, events,
        waypoints ...); bias (modelled minus AIS: time_h, time_pct, fuel_t, fuel_pct, co2_t,
        co2_pct); reference (the role of the deltas); proposed (a role or null: never a route
        that crosses land or has more no_weather_h than the reference); comparison (per role:
        values and d_<metric> deltas against the reference); optimality (per route: gap_h,
        tolerance_h, holds, constraint); model_check (the sailed track re-timed by each wave
        formula and the learned model against its AIS time); bands (with learned:NAME: P10/P50/P90 time
        and fuel of the reference and the proposed route); least_fuel_saving (fuel_t, reference: the sailed
        track at the constant setting meeting the AIS arrival, reference_fuel_t, saving_pct or saving_note,
        proposal: why least_fuel was or was not proposed); findings; with --report, report and model
        (the HTML file and its model, FILE.json, which `stormlane report --model` re-renders).

        Example (a ship through a storm, between two times):

        \b
          stormlane audit --mmsi 224087350 --start 2025-01-14T21:30Z --end 2025-01-15T10:30Z \\
            --db work/stormlane.duckdb --report audit.html
        """
        xarray_without_dask_arrays()
        from pipelines.audit import run_audit
        from thresholds.errors import StormlaneError

        if voyage is None and (mmsi is None or start is None or end is None):
            raise StormlaneError("give --voyage ID, or --mmsi N with --start ISO and --end ISO")
        if voyage is not None and mmsi is not None:
            raise StormlaneError("give either --voyage or --mmsi/--start/--end, not both")
        from pipelines.commands._common import speed_loss_choice

        summary = run_audit(db, voyage_id=voyage, mmsi=mmsi, start=start, end=end, weather=paths_text(weather),
                            vessel=vessel, profile=profile, report=report, speed_loss_model=speed_loss_choice(speed_loss, db))
        if json_out:
            emit_json(summary)
            return
        v = summary["voyage"]
        typer.echo(f"audit {summary['audit_id']}: MMSI {v['mmsi']} {v['ship_name'] or ''} {v['start_utc']} .. {v['end_utc']}")
        typer.echo(f"vessel profile {summary['vessel_profile']}, operator limits {summary['operator_profile']}, "
                   f"every route sailed by speed-loss model {summary['speed_loss_model']}")
        cols = [("time_h", "time h", 1), ("dist_nmi", "nmi", 1), ("max_hs_m", "max Hs", 2), ("mean_hs_m", "mean Hs", 2),
                ("fuel_t", "fuel t", 2), ("co2_t", "CO2 t", 2), ("exposure_h", "over limits h", 1), ("n_safety_events", "IMO events", 0)]
        typer.echo(f"{'route':<20}" + "".join(f"{label:>14}" for _, label, _ in cols))
        for role, row in summary["comparison"].items():
            typer.echo(f"{role:<20}" + "".join(f"{_fmt(row.get(c), d):>14}" for c, _, d in cols))
        b = summary.get("bias") or {}
        if b:
            typer.echo(f"model bias (modelled - AIS): time {_fmt(b.get('time_h'))} h ({_fmt(b.get('time_pct'), 1)} %), "
                       f"fuel {_fmt(b.get('fuel_t'))} t ({_fmt(b.get('fuel_pct'), 1)} %); deltas are against {summary.get('reference')}")
        typer.echo(f"proposed: {summary['proposed'] or 'none'}")
        for line in summary["findings"]:
            typer.echo(f"- {line}")
        if summary.get("report"):
            typer.echo(f"report: {summary['report']}")
        if summary.get("model"):
            typer.echo(f"model: {summary['model']} (`stormlane report --model` re-renders it)")
