"""`stormlane lanes`: ports, voyages and DBSCAN traffic lanes from the workspace's AIS positions."""

from __future__ import annotations

from pathlib import Path

import typer

from pipelines.commands._common import (DbReadOption, JsonOption, check_output_file, checked_task_runner, emit_json,
                                        flow_errors_one_line, quiet_prefect, start_prefect_api, warning, count)


def register(app: typer.Typer) -> None:
    @app.command("lanes")
    def lanes_command(
        db: Path = DbReadOption,
        json_out: bool = JsonOption,
        geojson: Path = typer.Option(None, "--geojson", metavar="FILE", callback=lambda v: check_output_file(v, "--geojson"),
                                     help="Also write ports, lanes and centroids as GeoJSON to FILE."),
        ports_csv: list[Path] = typer.Option(None, "--ports", metavar="CSV",
                                             help="Port list CSV; several after one --ports, or --ports repeated (default: "
                                                  "data/ports.csv and data/ports_terminals.csv)."),
        step_s: float = typer.Option(300.0, "--step-s", metavar="S", show_default=True, help="Resampling time step (s)."),
        eps_nmi: float = typer.Option(2.0, "--eps-nmi", metavar="NMI", show_default=True, help="Lane DBSCAN spatial eps (nmi)."),
        eps_speed_kn: float = typer.Option(3.0, "--eps-speed-kn", metavar="KN", show_default=True, help="Lane DBSCAN speed eps (kn)."),
        eps_course_deg: float = typer.Option(20.0, "--eps-course-deg", metavar="DEG", show_default=True, help="Lane DBSCAN course eps (deg)."),
        min_density: float = typer.Option(3.0, "--min-density", metavar="N", show_default=True,
                                          help="Lane DBSCAN core density: voyages passing within eps."),
        min_voyages: int = typer.Option(3, "--min-voyages", metavar="N", show_default=True, help="Fewest voyages in a lane."),
        port_eps_nmi: float = typer.Option(0.135, "--port-eps-nmi", metavar="NMI", show_default=True, help="Stop DBSCAN eps for ports (nmi)."),
        merge_voyage_share: float = typer.Option(0.8, "--merge-voyage-share", metavar="FRAC", show_default=True,
                                                 help="Within a port pair, a cluster sharing this share of its voyages with a larger one "
                                                      "(its harbour approach, the leg after a sharp turn) is part of that lane; 0 keeps every cluster a lane."),
        task_runner: str = typer.Option("sequential", "--task-runner", metavar="sequential|dask[:ADDRESS]", show_default=True,
                                        help="Where the per origin-destination lane extraction runs: in this process (no Prefect), "
                                             "or through the Prefect lanes flow on a local Dask cluster or an existing Dask scheduler."),
    ) -> None:
        """Detect ports, cut voyages and extract traffic lanes (replaces the previous result).

        With --json prints exactly {"ports": N, "voyages": N, "lanes": N, "noise_points": N}:
        ports and waypoints found, port-to-port voyages, lanes, and resampled points left as
        DBSCAN noise (slow or unclustered).

        --task-runner sequential (the default) runs the chain in this process without Prefect, so a
        one-off command starts no Prefect API. dask or dask:ADDRESS runs the Prefect lanes flow
        instead: the serial steps (clean, stops, ports, voyages, resampling) here, then one task per
        origin-destination pair on a local Dask cluster (one single-threaded worker process per
        core) or on the scheduler at ADDRESS (e.g. dask:tcp://10.0.0.5:8786); the tables are
        identical to the sequential run's. The spec is checked before anything starts.

        Example:

        \b
          stormlane lanes --db work/stormlane.duckdb --geojson work/lanes.geojson
        """
        from pydantic import ValidationError

        from pipelines.lanes import LanesSettings, export_geojson, run_lanes, summary_counts
        from thresholds.errors import StormlaneError

        kind = checked_task_runner(task_runner)  # a bad spec or no scheduler fails here, before any work

        try:
            settings = LanesSettings(step_s=step_s, eps_nmi=eps_nmi, eps_speed_kn=eps_speed_kn, eps_course_deg=eps_course_deg,
                                     min_density=min_density, min_voyages=min_voyages, port_eps_nmi=port_eps_nmi,
                                     merge_voyage_share=merge_voyage_share)
        except ValidationError as err:
            first = err.errors()[0]
            raise StormlaneError(f"bad option {first['loc'][0]}: {first['msg']}") from None
        if kind == "sequential":
            out = run_lanes(db, ports_csv or None, settings)
        else:
            out = _run_flow(db, ports_csv, settings, task_runner)
        if geojson is not None:
            export_geojson(db, geojson)
        if out["lanes"] == 0:
            warning(no_lanes_reason(out, settings))
        if json_out:
            emit_json(summary_counts(out))
            return
        d = out["details"]
        typer.echo(f"lanes run {out['run_id']} on {db}")
        typer.echo(f"  positions {d['positions']:,} ({d['dropped_jumps']:,} dropped as position jumps), stops {d['stops']:,}")
        typer.echo(f"  ports {out['ports']} ({d['named_ports']} named from the port list, the rest numbered waypoints)")
        kinds = ", ".join(f"{k} {v}" for k, v in sorted(d["voyage_kinds"].items())) or "none"
        typer.echo(f"  voyages port-to-port {out['voyages']} (all segments: {kinds})")
        typer.echo(f"  lanes {out['lanes']} from {d['resampled_points']:,} resampled points; noise {out['noise_points']:,}"
                   f" (of which {d['slow_points']:,} slower than the lane speed floor)")
        if geojson is not None:
            typer.echo(f"  GeoJSON written to {geojson}")


def _run_flow(db: Path, ports_csv, settings, task_runner: str) -> dict:
    """The Prefect lanes flow with the partitions on the Dask task runner (quiet, offline Prefect;
    a user error is the one ``error:`` line)."""
    quiet_prefect(console_info=False)
    from pipelines.lanes import LanesInputError, flow_with_runner

    if not Path(db).exists():  # fail as one line before Prefect and the cluster start
        raise LanesInputError(f"workspace {db} does not exist; run `stormlane ingest-ais PATH --db {db}` first")
    start_prefect_api(task_runner)
    paths = [str(p) for p in ports_csv] if ports_csv else None
    with flow_errors_one_line():
        return flow_with_runner(task_runner)(db=str(db), ports_csv=paths, settings=settings)


def no_lanes_reason(out: dict, settings) -> str:
    """Why a run found no lane, from the first step of the chain that gave nothing (the user's next option to change)."""
    d = out["details"]
    if d["stops"] == 0:
        return (f"no lanes: no vessel stopped (below {settings.stop_speed_kn:g} kn for {settings.min_stop_s / 60:g} min or more), "
                "so no ports were found; lanes are built from voyages between ports")
    if out["ports"] < 2:
        return f"no lanes: {count(out['ports'], 'port')} found from {d['stops']:,} stops; lanes are built from voyages between two ports"
    if out["voyages"] == 0:
        return f"no lanes: no voyage sailed from one of the {out['ports']} ports to another"
    return (f"no lanes: the {out['voyages']:,} port-to-port voyages formed no cluster of at least {settings.min_voyages} voyages "
            f"(--min-voyages, --min-density {settings.min_density:g}, --eps-nmi {settings.eps_nmi:g})")
