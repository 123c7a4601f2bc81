"""`stormlane route`: time-optimal and minimum-distance routes through the weather (A* on a mesh)."""

from __future__ import annotations

from pathlib import Path

import typer

from pipelines.commands._route_fuel import echo_window, fuel_spec, window_times
from pipelines.commands._route_output import show_plan
from pipelines.commands._common import (SPEED_LOSS_MODELS, VESSEL_WITHOUT_AIS, JsonOption, LearnedDbOption, ProfileOption, check_output_file, emit_json,
                                        note, vessel_option, weather_option, xarray_without_dask_arrays)

SAFETY_MODES = ("none", "soft", "hard")


def _floats(text: str, n: int, what: str, option: str) -> tuple[float, ...]:
    parts = [p.strip() for p in str(text).split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != n:
        raise typer.BadParameter(f"expected {what}, got {text!r}", param_hint=option)
    return values


def _latlon(text: str, option: str) -> tuple[float, float]:
    lat, lon = _floats(text, 2, "LAT,LON in decimal degrees", option)
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise typer.BadParameter(f"{text!r} is not a position: lat in [-90, 90], lon in [-180, 180]", param_hint=option)
    return lat, lon


def register(app: typer.Typer) -> None:
    # Long only by the command's signature: every option is declared there with its help text.
    @app.command("route")
    def route(
        from_: str = typer.Option(..., "--from", metavar="LAT,LON", help="Start position, decimal degrees."),
        to: str = typer.Option(..., "--to", metavar="LAT,LON", help="Goal position, decimal degrees."),
        depart: str = typer.Option(None, "--depart", metavar="ISO", help="Departure time, ISO 8601 (UTC if no offset is given); or --depart-window."),
        depart_window: str = typer.Option(None, "--depart-window", metavar="START/END", help="Route every departure START, START + --step, ... END "
                                          "with --objective (every --step-h hours) and rank them (arrival, time, fuel, CO2, max Hs, hours over limits), the best marked."),
        step_h: float = typer.Option(None, "--step-h", min=0.01, metavar="H", help="Hours between the departures of --depart-window."),
        weather: list[Path] = weather_option("the sea is calm"),
        vessel: str = vessel_option(VESSEL_WITHOUT_AIS),
        speed_kn: float = typer.Option(None, "--speed-kn", min=0.1, metavar="KN", help="Calm-water speed in knots; default the vessel's service speed."),
        speed_loss: str = typer.Option("bowditch", "--speed-loss", metavar="|".join(SPEED_LOSS_MODELS), show_default=True,
                                       help="Speed-loss model: in waves (bowditch, aertssen, khokhlov), in the wind (kwon), or "
                                            "learned:NAME, a model learned from the fleet's AIS (`stormlane learn performance`; "
                                            "read from --db)."),
        aertssen_bands: str = typer.Option(
            "wmo", "--aertssen-bands", metavar="wmo|simroute", show_default=True,
            help="Aertssen's Hs -> Beaufort convention: wmo (WMO probable maximum heights as class upper edges) or simroute "
                 "(SIMROUTE's code: the tabulated Hs as lower edges).",
        ),
        mesh_nmi: float = typer.Option(None, "--mesh-nmi", min=0.01, metavar="NMI", help="Mesh step in nmi, taken as X/60 deg on both axes (SIMROUTE's convention). Default: the weather's grid step (1.5 nmi without weather), halved where start and goal do not connect through a narrow passage or a port has no sea node within --snap-nmi (a note says so)."),
        mesh_deg: float = typer.Option(None, "--mesh-deg", min=0.0001, metavar="DEG", help="Mesh step in degrees on both axes."),
        bbox: str = typer.Option(None, "--bbox", metavar="LONMIN,LATMIN,LONMAX,LATMAX", help="Mesh extent; default the great circle's box plus a margin, widened (a note says so) where the sea way leaves it."),
        edges: int = typer.Option(48, "--edges", metavar="8|16|24|48", help="Edges per node.", show_default=True),
        ignore_land: bool = typer.Option(False, "--ignore-land", help="Route on an all-sea sphere (accuracy tests)."),
        snap_nmi: float = typer.Option(10.0, "--snap-nmi", min=0.0, metavar="NMI", show_default=True, help="How far (nmi) a start or goal on land may move to the nearest sea node."),
        safety: str = typer.Option(
            "none", "--safety", metavar="hard|soft|none", show_default=True,
            help="Also route under the vessel's limits (operator profile + IMO MSC.1/Circ.1228): hard forbids cells over the limits "
                 "(falling back to soft, said in the output, when no route keeps within them), soft charges --safety-penalty per hour over them.",
        ),
        profile: str = ProfileOption,
        operator: str = typer.Option(None, "--operator", hidden=True, help="Deprecated name of --profile."),
        safety_penalty: float = typer.Option(
            10.0, "--safety-penalty", min=0.0, metavar="H", show_default=True, help="Soft safety: extra hours of cost per hour sailed over the limits."
        ),
        objective: str = typer.Option("time", "--objective", metavar="time|fuel|co2", show_default=True,
                                      help="What the extra route minimises: time (the time-optimal route only), fuel or co2 (least_fuel: a speed "
                                           "setting per leg, arriving by --arrive-by, default the time-optimal arrival; CO2 is proportional to fuel)."),
        speeds: str = typer.Option(None, "--speeds", metavar="KN,KN,...", help="Calm-water speed settings to choose from on every leg (fuel/co2)."),
        speed_range: str = typer.Option(None, "--speed-range", metavar="MIN,MAX", help="Speed settings evenly over MIN..MAX kn (with --speed-steps); "
                                        "default 60 % of the service speed up to the speed at the engine's maximum power, plus the service speed."),
        speed_steps: int = typer.Option(None, "--speed-steps", min=1, metavar="K", help="Number of settings over --speed-range (default 8)."),
        arrive_by: str = typer.Option(None, "--arrive-by", "--eta", metavar="ISO", help="Latest arrival (fuel/co2): least fuel among routes arriving no later."),
        pareto: bool = typer.Option(False, "--pareto", help="Also the time-fuel front: a handful of non-dominated (arrival, fuel) routes (fuel/co2)."),
        fuel_buckets: int = typer.Option(5, "--fuel-buckets", min=1, metavar="K", show_default=True, help="Time buckets per quarter-hour of the least-fuel labels (finer: smaller gap, slower)."),
        fuel_corridor: str = typer.Option("0", "--fuel-corridor", metavar="W|full", show_default=True,
                                          help="Graph of the least-fuel search: W mesh nodes around the time-optimal paths of every setting and the "
                                               "minimum-distance path, or full (the whole mesh; exact but slow on large meshes)."),
        db: Path = LearnedDbOption,
        json_out: bool = JsonOption,
        out: Path = typer.Option(None, "--out", metavar="FILE.geojson|gpx|rtz", callback=lambda v: check_output_file(v, "--out"),
                                 help="Also write the routes to this file (the format from the suffix)."),
    ) -> None:
        """Compute the time-optimal route (raw grid and smoothed) and the minimum-distance route.

        The optimal route minimises the sailing time with the speed loss in waves, by a time-dependent A* on a lat/lon mesh whose edges never touch land; the minimum-distance route is the shortest sea path on the same mesh, sailed through the same weather and in calm water. With --json one object is printed: great_circle_nmi and, for optimal, optimal_smoothed, min_distance and min_distance_calm, time_h, dist_nmi, max_hs_m and waypoints (lists of lat, lon, ISO time); a route that arrives after the last weather time (whose last field is then held) also has weather_held_after_h; "speed_loss" names the model with its convention or range; "notes" lists what the table prints as note: lines, first the speed-loss model and what it rests on (a wave direction the weather lacks is taken as head seas; Kwon reads the wind; an antimeridian crossing), then points moved to sea and weather held. With --speed-loss learned:NAME (a model of `stormlane learn performance`, read from --db) the JSON also has eta_band: the optimal_smoothed route re-timed by the model's P10/P50/P90 speed tables (time_h_p10, time_h_p50, time_h_p90, assumption).

A speed-loss model outside its published range is refused (Khokhlov: D·v0 above 20 000 dwt x 20 kn, where its factor leaves the fitted range toward 0; a ship outside 4 000-20 000 dwt or 9-20 kn below that is routed with a note saying so; Kwon: Cb 0.55-0.85, a positive speed-reduction coefficient), and a model whose variable the weather lacks is refused naming it and the files (waves for bowditch, aertssen, khokhlov; the 10 m wind for kwon). The ship may wait or slow down where that arrives earlier (the optimum under weather whose sailing times jump with time). Routes may cross the antimeridian (--bbox 170,30,-160,50 or 170,30,200,50).

        With --objective fuel|co2 two more routes: least_fuel (a speed setting per leg out of --speeds or --speed-range/--speed-steps, each leg slowed by the speed-loss model at its setting, never above the engine's maximum power; STEAM2 fuel; waits allowed; the least fuel arriving by --arrive-by, default the time-optimal route's arrival; an arrival no route can meet is refused with the earliest possible one) and min_distance_same_arrival (the minimum-distance route at the one constant setting that arrives at the same time: the reference of the saving); every route reports fuel_t and co2_t, and a "fuel" object gives the search's lower bound and gap, the reference and the saving (and with --pareto the time-fuel front).

        With --safety soft|hard two more routes respect the vessel's limits (safe_optimal, safe_optimal_smoothed), every route reports hours_over_limits (operator + IMO rules at its own ETAs), hours_by_rule and unsafe_cell_h, and a "safety" object says which mode ran (hard falls back to soft when no route keeps within the limits).

        Example (Palma to Barcelona in Storm Gloria, SIMROUTE's R6 case):

        \b
          stormlane route --from 39.225,2.900 --to 41.500,2.775 --depart 2020-01-20T09:00Z \\
            --weather Waves_MEDSEA_20200120.nc Waves_MEDSEA_20200121.nc --vessel simroute-r6 --out r6.gpx
        """  # noqa: E501
        # Long by its option declarations above; the body checks them, loads the ship and the weather, plans, prints.
        import logging

        from pipelines.learn import parse_learned
        from routing.planner import RouteRequest, plan_routes

        learned = parse_learned(speed_loss)
        _check_choices(mesh_nmi, mesh_deg, edges, speed_loss, learned, aertssen_bands, safety)
        if operator is not None:
            note("--operator is deprecated: use --profile")
            profile = profile or operator
        start, goal = _latlon(from_, "--from"), _latlon(to, "--to")
        box = _floats(bbox, 4, "LONMIN,LATMIN,LONMAX,LATMAX", "--bbox") if bbox else None
        window, t = _departures(depart, depart_window, step_h)
        _check_window_options(window, out, safety, pareto, profile)

        logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
        ship_vessel, ship = _ship(vessel, speed_loss, learned, speed_kn, aertssen_bands, db)
        fspec = fuel_spec(ship_vessel, objective, speeds, speed_range, speed_steps, arrive_by, pareto, fuel_buckets, fuel_corridor)
        _check_learned_settings(speed_loss, learned, db, ship_vessel, fspec)
        field = _weather_field(list(weather or []), t, () if ignore_land else (("start", start), ("goal", goal)))
        spacing = mesh_deg if mesh_deg is not None else (mesh_nmi / 60.0 if mesh_nmi is not None else None)
        req = RouteRequest(
            start, goal, t, ship, spacing_deg=spacing, bbox=box, edges=edges, ignore_land=ignore_land,
            snap_limit_nmi=snap_nmi, vessel_name=ship_vessel.name,
        )  # fmt: skip
        from pipelines.config import load_operator_profile

        limits = load_operator_profile(profile) if safety != "none" or window is not None else None
        if window is not None:
            from routing.planner_window import plan_window

            result = plan_window(req, field, window, objective=objective, fuel=fspec, vessel=ship_vessel, limits=limits)
            if json_out:
                emit_json(result)
            else:
                echo_window(result)
            return
        plan = plan_routes(req, field, safety=safety, vessel=ship_vessel, limits=limits, penalty_per_h=safety_penalty, fuel=fspec)
        show_plan(plan, ship_vessel, ship, safety=safety, fuel=fspec is not None, learned=learned is not None, out=out, json_out=json_out)


def _check_choices(mesh_nmi, mesh_deg, edges: int, speed_loss: str, learned, aertssen_bands: str, safety: str) -> None:
    """One `error:` line for an option outside its choices (typer's BadParameter, exit 2)."""
    from routing.speed_loss import AERTSSEN_BANDS, MODELS

    if mesh_nmi is not None and mesh_deg is not None:
        raise typer.BadParameter("give either --mesh-nmi or --mesh-deg, not both", param_hint="--mesh-nmi/--mesh-deg")
    if edges not in (8, 16, 24, 48):
        raise typer.BadParameter(f"{edges} is not one of 8, 16, 24, 48", param_hint="--edges")
    if learned is None and speed_loss not in MODELS:
        raise typer.BadParameter(f"{speed_loss!r} is not one of {', '.join(MODELS)}, learned:NAME", param_hint="--speed-loss")
    if aertssen_bands not in AERTSSEN_BANDS:
        raise typer.BadParameter(f"{aertssen_bands!r} is not one of {', '.join(AERTSSEN_BANDS)}", param_hint="--aertssen-bands")
    if safety not in SAFETY_MODES:
        raise typer.BadParameter(f"{safety!r} is not one of {', '.join(SAFETY_MODES)}", param_hint="--safety")


def _check_window_options(window, out, safety: str, pareto: bool, profile) -> None:
    """Options of one departure's plan refused with --depart-window, which ranks the departures (rows only): before,
    --out wrote nothing and --safety/--pareto were dropped without a word. --profile names the limits of the window's
    hours over them; for one departure it applies with --safety."""
    if window is not None:
        given = [name for name, v in (("--out", out), ("--safety", None if safety == "none" else safety), ("--pareto", pareto or None))
                 if v is not None]
        if given:
            raise typer.BadParameter(f"{', '.join(given)} {'applies' if len(given) == 1 else 'apply'} to one --depart, not to --depart-window (a table of departures): "
                                     "route the chosen departure with --depart", param_hint="--depart-window")
    elif profile is not None and safety == "none":
        raise typer.BadParameter("--profile applies with --safety soft|hard", param_hint="--profile")


def _departures(depart: str | None, depart_window: str | None, step_h: float | None):
    """(window departures or None, the first departure): exactly one of --depart and --depart-window."""
    from pipelines.times import utc_or_none

    if (depart is None) == (depart_window is None):
        raise typer.BadParameter("give --depart ISO or --depart-window START/END --step-h H", param_hint="--depart")
    window = window_times(depart_window, step_h) if depart_window is not None else None
    t = window[0] if window else utc_or_none(depart)
    if t is None:
        raise typer.BadParameter(f"{depart!r} is not an ISO 8601 time", param_hint="--depart")
    return window, t


def _ship(vessel: str | None, speed_loss: str, learned, speed_kn: float | None, aertssen_bands: str, db: Path):
    """(the vessel profile, the ShipModel the search sails): a learned model is tabulated once for this request."""
    from pipelines.config import load_vessel
    from pipelines.vessels import DEFAULT_VESSEL
    from routing.astar import ShipModel

    ship_vessel = load_vessel(vessel or DEFAULT_VESSEL)
    if learned is None:
        return ship_vessel, ShipModel.from_vessel(ship_vessel, speed_loss, speed_kn=speed_kn, aertssen_bands=aertssen_bands)
    from pipelines.commands._common import speed_loss_choice

    return ship_vessel, speed_loss_choice(speed_loss, db).ship(ship_vessel, speed_kn=speed_kn)


def _check_learned_settings(speed_loss: str, learned, db: Path, vessel, fspec) -> None:
    """With a learned model, every least-fuel setting within the calm-water speeds it saw (one `error:` line)."""
    if learned is None or fspec is None:
        return
    from pipelines.commands._common import speed_loss_choice

    speed_loss_choice(speed_loss, db).check_settings(vessel, fspec.speeds_kn)


def _weather_field(files: list[Path], depart_utc, points):
    """The weather field of the files (None: calm sea); a missing file is one error naming it."""
    if not files:
        return None
    xarray_without_dask_arrays()
    from pipelines.routing_weather import load_weather, require_weather_files

    require_weather_files(files)
    field, _meta = load_weather([str(f) for f in files], depart_utc=depart_utc, points=points)
    return field
