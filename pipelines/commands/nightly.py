"""`stormlane nightly` (one night now) and `stormlane schedule` (the nightly deployment on a cron)."""

from __future__ import annotations

from pathlib import Path

import typer

from pipelines.commands._common import (VESSEL_FROM_AIS, DbReadOption, JsonOption, ProfileOption, SpeedLossOption,
                                        TaskRunnerOption, check_output_dir, checked_task_runner, count, emit_json,
                                        flow_errors_one_line, paths_text, progress, quiet_prefect, start_prefect_api,
                                        vessel_option, warning, weather_option, xarray_without_dask_arrays)

#: Deployment name used by `stormlane schedule` (the flow is ``nightly-reroute``).
DEPLOYMENT_NAME = "nightly"


# The options of one night, shared by `nightly` and `schedule` (one definition, one help text).
WeatherNight = weather_option("downloaded with --fetch (or when download credentials are configured), else the weather "
                              "loaded in the workspace")
FetchOption = typer.Option(False, "--fetch", help="Download the night's weather with copernicusmarine + cdsapi (needs their credentials; cached).")
WindowOption = typer.Option(48.0, "--window-h", min=0.1, metavar="H", show_default=True, help="Departure window length in hours.")
StepOption = typer.Option(3.0, "--step-h", min=0.1, metavar="H", show_default=True, help="Hours between departures.")
VoyagesOption = typer.Option(None, "--voyages", metavar="CSV",
                             help="Planned voyages (vessel, origin, destination, depart_utc) instead of every lane x window.")
LaneOption = typer.Option(None, "--lane", metavar="ID", help="Only these lanes; several after one --lane, or --lane repeated.")
SafetyOption = typer.Option("hard", "--safety", metavar="hard|soft|none", show_default=True,
                            help="Also route a safe time-optimal A* under the vessel's limits (hard: never through an unsafe cell, "
                                 "soft if none; none: skip it).")
MaxDetailOption = typer.Option(10, "--max-detail", min=0, metavar="N", show_default=True,
                               help="Adverse lane-departures drawn with a map and plots in the report.")
LeastFuelOption = typer.Option(True, "--least-fuel/--no-least-fuel", show_default=True,
                               help="Also route the least-fuel route (speed setting per leg) arriving by the lane's arrival "
                                    "(role least_fuel; it ignores the vessel's limits, the safety-first proposal rules decide).")
RankDeparturesOption = typer.Option("none", "--rank-departures", metavar="time|fuel|none", show_default=True,
                                    help="Per lane with adverse departures, route every departure of the window (least time, or "
                                         "least fuel arriving by its own time-optimal arrival) and rank them, best marked: in "
                                         "--json (departure_windows) and the report.")
NoReportOption = typer.Option(False, "--no-report", help="Store the results only (no HTML report or exports).")
ExportsOption = typer.Option("proposed", "--exports", metavar="proposed|all|none", show_default=True,
                             help="Route exports in DIR/exports.zip (with index.csv): the proposed routes only (RTZ, GPX, "
                                  "GeoJSON), every route of every adverse case, or none.")


def register(app: typer.Typer) -> None:
    # Long only by declaring two commands (nightly, schedule) with their options and help.
    @app.command("nightly")
    def nightly(
        db: Path = DbReadOption,
        out: Path = typer.Option(None, "--out", metavar="DIR", callback=lambda v: check_output_dir(v, "--out"),
                                 help="Folder for report.html, report.json and exports.zip (default nightly/<now>)."),
        weather: list[Path] = WeatherNight,
        fetch: bool = FetchOption,
        now: str = typer.Option(None, "--now", metavar="ISO", help="Forecast reference time (default: the current hour, UTC); departures start here."),
        window_h: float = WindowOption,
        step_h: float = StepOption,
        voyages: Path = VoyagesOption,
        lane: list[str] = LaneOption,
        vessel: str = vessel_option(VESSEL_FROM_AIS),
        profile: str = ProfileOption,
        speed_loss: str = SpeedLossOption,
        safety: str = SafetyOption,
        max_detail: int = MaxDetailOption,
        least_fuel: bool = LeastFuelOption,
        rank_departures: str = RankDeparturesOption,
        no_report: bool = NoReportOption,
        exports: str = ExportsOption,
        task_runner: str = TaskRunnerOption,
        json_out: bool = JsonOption,
    ) -> None:
        """Run one nightly reroute now: screen every lane x departure of the forecast window against the vessel's limits, reroute the adverse ones (cargo-safe deviation and time-optimal A*), evaluate, rank, store under a run id and write the report.

        Weather: --weather files or folders; --fetch (or download credentials configured) uses the real clients; otherwise the grid loaded in the workspace. A window whose departures the weather does not cover fails at once; voyages sailing on after the weather's last time are screened on their part with weather only, said in one warning line (beyond_weather in --json). With --json one object is printed: run_id, counts (lanes_checked, departures_checked, adverse, failed, reroutes, lanes_at_risk, lanes_with_reroute, beyond_weather, beyond_weather_ok), the sums over the proposed reroutes (risk_avoided_h, events_avoided, delta_time_h, delta_fuel_t, delta_co2_t: proposed minus the lane as planned), report, model, exports_zip, timings_s and the top-ranked lane-departures with the ranking key (risk_avoided_h): the figures of the report's overview.

        Example (the next 24 h of departures from a given time, with local forecast files):

        \b
          stormlane nightly --db work/stormlane.duckdb --weather forecast/ --now 2025-01-15T00:00Z \\
            --window-h 24 --out work/nightly
        """  # noqa: E501
        quiet_prefect(console_info=False)
        xarray_without_dask_arrays()
        from pipelines.nightly import NightlyParams, flow_with_runner, preflight, reroute_progress

        source = "fetch" if fetch else ("files" if weather else "auto")
        params = NightlyParams.checked(
            db=str(db), out=str(out) if out else None, weather=paths_text(weather), weather_source=source, now=now,
            window_h=window_h, step_h=step_h, voyages=str(voyages) if voyages else None, lanes=list(lane or []) or None,
            vessel=vessel, profile=profile, speed_loss=speed_loss, safety=safety, max_detail=max_detail, report=not no_report,
            exports=exports, least_fuel=least_fuel, rank_departures=rank_departures,
        )
        checked_task_runner(task_runner)  # a bad spec or no scheduler fails here, before any work
        preflight(params)
        start_prefect_api(task_runner)
        # a user error inside the flow (e.g. weather not covering the window) ends with the one
        # `error:` line: Prefect's run ERROR lines stay off the console unless PREFECT_LOGGING_LEVEL
        # asks for Prefect's INFO/DEBUG lines
        with flow_errors_one_line(), progress("rerouting lanes") as advance:
            with reroute_progress(lambda done, total: advance(1 if done else 0, total=total)):
                summary = flow_with_runner(task_runner)(**params.model_dump())
        warn_beyond_weather(summary)
        if json_out:
            emit_json(summary)
            return
        print_summary(summary)

    @app.command("schedule")
    def schedule(
        cron: str = typer.Option("0 2 * * *", "--cron", metavar="CRON", show_default=True, help="Cron expression of the nightly run (minute hour day month weekday)."),
        timezone: str = typer.Option("UTC", "--timezone", metavar="TZ", show_default=True, help="IANA time zone of the cron expression (e.g. Europe/Madrid)."),
        name: str = typer.Option(DEPLOYMENT_NAME, "--name", metavar="NAME", show_default=True, help="Deployment name (the flow is nightly-reroute)."),
        db: Path = DbReadOption,
        out: Path = typer.Option(None, "--out", metavar="DIR", callback=lambda v: check_output_dir(v, "--out"),
                                 help="Report folder root; each night writes <DIR>/<now> (default nightly/<now>)."),
        weather: list[Path] = WeatherNight,
        fetch: bool = FetchOption,
        window_h: float = WindowOption,
        step_h: float = StepOption,
        voyages: Path = VoyagesOption,
        lane: list[str] = LaneOption,
        vessel: str = vessel_option(VESSEL_FROM_AIS),
        profile: str = ProfileOption,
        speed_loss: str = SpeedLossOption,
        safety: str = SafetyOption,
        max_detail: int = MaxDetailOption,
        least_fuel: bool = LeastFuelOption,
        rank_departures: str = RankDeparturesOption,
        no_report: bool = NoReportOption,
        exports: str = ExportsOption,
    ) -> None:
        """Serve the nightly reroute as a Prefect deployment on a cron schedule (runs until stopped).

        It registers the deployment 'nightly-reroute/<name>' with the Prefect API in PREFECT_API_URL (start one with `prefect server start`) and runs each scheduled night in a subprocess, with the options of `stormlane nightly`; the forecast time of a run is its scheduled time. Stop it with Ctrl-C or SIGTERM. docs/nightly.md shows how to run it under systemd.

        Example (every night at 02:00 UTC):

        \b
          stormlane schedule --cron "0 2 * * *" --timezone UTC --db /srv/stormlane/ws.duckdb \\
            --out /srv/stormlane/nightly --weather /srv/stormlane/forecast
        """  # noqa: E501
        quiet_prefect()
        from prefect.schedules import Cron

        from pipelines.nightly import _flow

        try:
            sched = Cron(cron, timezone=timezone)
        except Exception as err:  # noqa: BLE001 - prefect validates cron and time zone
            raise typer.BadParameter(str(err), param_hint="--cron/--timezone") from None
        from pipelines.nightly import NightlyParams

        # the same checks as `stormlane nightly`, before anything is registered; paths made
        # absolute, since each night runs in a subprocess
        checked = NightlyParams.checked(
            db=str(db.resolve()), out_root=str(out.resolve()) if out else None, weather=[str(Path(w).resolve()) for w in weather or []],
            weather_source="fetch" if fetch else ("files" if weather else "auto"), window_h=window_h, step_h=step_h,
            voyages=str(voyages.resolve()) if voyages else None, lanes=list(lane or []) or None, vessel=vessel, profile=profile,
            speed_loss=speed_loss, safety=safety, max_detail=max_detail, report=not no_report, exports=exports,
            least_fuel=least_fuel, rank_departures=rank_departures,
        )
        params = checked.model_dump(exclude={"now", "out", "cache_dir"}, exclude_none=True)
        from prefect.deployments.runner import EntrypointType

        _flow().serve(name=name, schedules=[sched], parameters=params, entrypoint_type=EntrypointType.MODULE_PATH,
                      description=f"stormlane nightly reroute, cron {cron!r} ({timezone})", pause_on_shutdown=False)


def _num(x, spec: str, unit: str = "") -> str:
    if x is None:
        return "-"
    text = format(x, spec)
    if text.startswith("-") and float(text) == 0.0:  # a tiny negative rounds to "-0.0": the page says "+0.0"
        text = format(0.0, spec)
    return f"{text}{unit}"


def warn_beyond_weather(summary: dict) -> None:
    """One ``warning:`` line when lane-departures sail on after the weather's last time (the
    report's overview says the same): their centroids after it were not screened; and one when
    rerouted lanes were faster than their vessel can sail (sailed at its maximum-power speed)."""
    from dashboards.nightly_page import speed_capped_text
    from pipelines.nightly.store import beyond_weather_line

    for line in (beyond_weather_line(summary), speed_capped_text(summary.get("speed_capped"))):
        if line is not None:
            warning(line)


def print_summary(summary: dict) -> None:
    """The terminal summary: the report overview's figures (the same dict, ``overview_of``)."""
    s = summary
    w = s["window"]
    spacing = (f"{count(w['departures'], 'planned departure')} from {w['start_utc']} to {w['end_utc']}"
               if w.get("step_h") is None else f"{count(w['departures'], 'departure')} every {w['step_h']:g} h")
    typer.echo(f"night {s['run_id']} (now {s['now_utc']}, {spacing}): {count(s['lanes_checked'], 'lane')}, "
               f"{count(s['departures_checked'], 'lane-departure')} checked, {s['adverse']} adverse on "
               f"{count(s['lanes_at_risk'], 'lane')}, {s['reroutes']} with a proposed reroute, {s['failed']} failed")
    if s["reroutes"]:
        typer.echo(f"proposed reroutes (against the lane as planned, same vessel model: {s.get('speed_loss_model', 'bowditch')}): "
                   f"{_num(s['risk_avoided_h'], '.1f', ' h')} "
                   f"at risk avoided, {s['events_avoided']} IMO events avoided, time {_num(s['delta_time_h'], '+.1f', ' h')}, "
                   f"fuel {_num(s['delta_fuel_t'], '+.1f', ' t')}, CO2 {_num(s['delta_co2_t'], '+.1f', ' t')}")
    beside = s.get("learned_limits")
    for r in (beside or {}).get("rows", []):
        from pipelines.learn import limit_line

        typer.echo(f"beside the limits, {beside['model']} (AIS evidence, not a limit): {limit_line(r)}")
    if s["top"]:
        typer.echo(f"  {'#':>3}  {'lane':<10} {'departure':<17} {'at risk avoided':>15}  {'proposed':<14} {'time':>7}  rules")
    for row in s["top"]:
        if row["status"] == "failed":
            typer.echo(f"  {row['rank']:>3}. {row['lane']:<10} {row['depart_utc'][:16]}Z  failed: {row['error']}")
            continue
        typer.echo(f"  {row['rank']:>3}. {row['lane']:<10} {row['depart_utc'][:16]}Z {_num(row['risk_avoided_h'], '.1f', ' h'):>15}  "
                   f"{row['proposed'] or 'no safer route':<14} {_num(row['delta_time_h'], '+.1f', ' h'):>7}  {row['rules']}")
    if s.get("report"):
        typer.echo(f"report: {s['report']}")
    if s.get("exports_zip"):
        typer.echo(f"exports: {s['exports_zip']} ({s['exports']} files, index.csv)")
