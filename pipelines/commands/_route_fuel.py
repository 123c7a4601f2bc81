"""The fuel objective of `stormlane route`: options -> :class:`routing.fuel.FuelSpec`, and the lines
the table prints about the least-fuel route, its reference and the time-fuel front."""

from __future__ import annotations

import math

import typer

OBJECTIVES = ("time", "fuel", "co2")


def _float_list(text: str, option: str) -> list[float]:
    try:
        out = [float(p) for p in str(text).split(",") if p.strip()]
    except ValueError:
        out = []
    if not out or not all(math.isfinite(x) for x in out):  # ',' gave a traceback; 'inf' a numpy warning and 'nan kn'
        raise typer.BadParameter(f"expected comma-separated finite speeds in knots, got {text!r}", param_hint=option)
    return out


def fuel_spec(vessel, objective: str, speeds: str | None, speed_range: str | None, speed_steps: int | None, arrive_by: str | None,
              pareto: bool, buckets: int, corridor: str):
    """The FuelSpec of the options, or None for ``--objective time`` (which refuses the fuel options)."""
    from pipelines.times import utc_or_none
    from routing.emissions import Engine
    from routing.fuel import DEFAULT_PARETO_ROUTES, FuelSpec, speed_settings

    if objective not in OBJECTIVES:
        raise typer.BadParameter(f"{objective!r} is not one of {', '.join(OBJECTIVES)}", param_hint="--objective")
    if objective == "time":
        given = [name for name, v in (("--speeds", speeds), ("--speed-range", speed_range), ("--speed-steps", speed_steps),
                                      ("--arrive-by/--eta", arrive_by), ("--pareto", pareto or None)) if v is not None]  # fmt: skip
        if given:
            raise typer.BadParameter(f"{', '.join(given)} apply with --objective fuel|co2", param_hint="--objective")
        return None
    if speeds is not None and (speed_range is not None or speed_steps is not None):
        raise typer.BadParameter("give either --speeds or --speed-range/--speed-steps, not both", param_hint="--speeds")
    rng = None
    if speed_range is not None:
        rng = _float_list(speed_range, "--speed-range")
        if len(rng) != 2 or not 0 < rng[0] <= rng[1]:
            raise typer.BadParameter(f"expected MIN,MAX in knots with 0 < MIN <= MAX, got {speed_range!r}", param_hint="--speed-range")
    engine = Engine.from_vessel(vessel)
    try:
        settings = speed_settings(vessel, engine, _float_list(speeds, "--speeds") if speeds is not None else None, rng, speed_steps)
    except ValueError as e:
        raise typer.BadParameter(str(e), param_hint="--speeds/--speed-range") from None
    when = None
    if arrive_by is not None:
        when = utc_or_none(arrive_by)
        if when is None:
            raise typer.BadParameter(f"{arrive_by!r} is not an ISO 8601 time", param_hint="--arrive-by")
    width = None if corridor == "full" else _corridor(corridor)
    return FuelSpec(settings, engine, when, objective, buckets_per_subslice=buckets, pareto=DEFAULT_PARETO_ROUTES if pareto else 0,
                    corridor=width, between_settings=speeds is None)  # fmt: skip


def _corridor(text: str) -> int:
    try:
        w = int(text)
    except ValueError:
        w = -1
    if w < 0:
        raise typer.BadParameter(f"expected a width in mesh nodes (0, 1, 2 ...) or 'full', got {text!r}", param_hint="--fuel-corridor")
    return w


def slack_note(plan) -> str | None:
    """When the least-fuel route arrives well before the deadline, or waits on the way, because every leg already
    sails at the slowest setting offered (the fuel per mile keeps falling with speed, so only the settings' floor
    stops it), say so: the time left is the settings' limit, not the optimum's. The legs off the mesh's start and
    goal nodes, sailed at the service speed whatever the settings, do not count."""
    f, route = plan.stats.get("fuel"), plan.routes.get("least_fuel")
    if not f or route is None or not f.get("deadline_utc") or not f.get("speeds_kn"):
        return None
    import numpy as np  # here, not at the top: `stormlane --help` imports this module
    import pandas as pd

    slack_h = (pd.Timestamp(f["deadline_utc"]) - route.time_utc[-1]).total_seconds() / 3600.0
    setting = np.asarray(route.properties.get("speed_setting_kn") or [], dtype=float)
    leg_h = np.diff(route.time_utc.asi8) / 3.6e12
    stage = getattr(plan, "stage", None) if f.get("least_fuel_from") == "search" else None  # a candidate sails one setting throughout
    first, last = int(bool(getattr(stage, "lead", False))), setting.size - int(bool(getattr(stage, "tail", False)))
    setting, leg_h = setting[first:last], leg_h[first:last]
    wait_h = float(leg_h[setting <= 0.0].sum()) if leg_h.size == setting.size else 0.0
    sailed = setting[setting > 0.0]
    lowest = min(float(s) for s in f["speeds_kn"])
    if (slack_h < 1.0 / 60.0 and wait_h < 1.0 / 60.0) or not sailed.size or float(sailed.max()) > lowest + 1e-9:
        return None
    waits = f", after waiting {wait_h:.2f} h on the way," if wait_h >= 1.0 / 60.0 else ""
    return (f"least fuel arrives {slack_h:.2f} h before the deadline{waits} with every leg at the slowest setting offered "
            f"({lowest:g} kn): lower --speeds or --speed-range {'could' if waits else 'would'} use that time")


def fuel_notes(plan) -> list[str]:
    """The least-fuel route's notes (:func:`slack_note`, :func:`limits_note`): the table's ``note:`` lines and
    ``--json``'s ``notes`` alike."""
    return [n for n in (slack_note(plan), limits_note(plan)) if n is not None]


def limits_note(plan) -> str | None:
    """Beside the safe routes (``--safety``), that the least-fuel route does not avoid the limits (its hours over them
    are in the table, judged like every route's)."""
    if not plan.stats.get("safety") or "least_fuel" not in plan.routes:
        return None
    return "the least-fuel search does not avoid the vessel's limits: least_fuel's hours over them are evaluated like every route's"


def echo_fuel(plan) -> None:
    """The least-fuel summary under the route table: the deadline, the search's gap, the reference and the saving, the front."""
    f = plan.stats["fuel"]
    first, second = ("co2_t", "fuel_t") if f["objective"] == "co2" else ("fuel_t", "co2_t")
    typer.echo(f"least {first[:-2]}: {f[first]:.3f} t ({second[:-2]} {f[second]:.3f} t), arriving by {f['deadline_utc']} "
               f"({f['deadline_source']}); settings {', '.join(f'{s:g}' for s in f['speeds_kn'])} kn; from {f['least_fuel_from']}")
    for extra in fuel_notes(plan):
        typer.echo(f"note: {extra}")
    if f.get("lower_bound_fuel_t") is not None:
        gap = f"gap {f['gap_pct']:.2f} %" if f.get("gap_pct") is not None else f"no gap: {f['bound_note']}"
        typer.echo(f"search: {f['graph']}; lower bound {f['lower_bound_fuel_t']:.3f} t fuel over mesh routes at the offered "
                   f"settings ({gap})")
    ref = f.get("reference")
    if ref is None:
        typer.echo(f"note: {f.get('saving_note')}")
    else:
        typer.echo(f"saving {f['saving_pct']:.2f} % ({f['saving_fuel_t']:.3f} t fuel) against {ref['route']}: the minimum-distance route "
                   f"at a constant {ref['setting_kn']:g} kn arriving at the same time ({ref['arrive_utc']})")
    for row in f.get("pareto", []):
        mark = "  (least fuel)" if row.get("least_fuel") else ""
        typer.echo(f"front: arrive {row['arrive_utc']}  time {row['time_h']:.2f} h  fuel {row['fuel_t']:.3f} t  CO2 {row['co2_t']:.3f} t{mark}")


def window_times(text: str, step_h: float | None):
    """``--depart-window START/END`` and ``--step-h H`` -> the departures (UTC)."""
    from pipelines.times import utc_or_none
    from routing.planner_window import departures

    parts = str(text).split("/")
    ends = [utc_or_none(p) for p in parts] if len(parts) == 2 else [None]
    if len(parts) != 2 or None in ends:
        raise typer.BadParameter(f"expected START/END as two ISO 8601 times, got {text!r}", param_hint="--depart-window")
    if step_h is None:
        raise typer.BadParameter("--depart-window needs --step-h H (hours between departures)", param_hint="--step-h")
    try:
        return departures(ends[0], ends[1], float(step_h))
    except ValueError as e:
        raise typer.BadParameter(str(e), param_hint="--depart-window") from None


def echo_window(result: dict) -> None:
    """The departure table, best first marked with '*', in departure order."""
    fuel = result["objective"] != "time"
    typer.echo(f"departure window: {len(result['rows'])} departures, objective {result['objective']}, best marked *")
    for line in result.get("notes", []):
        typer.echo(f"note: {line}")
    typer.echo(f"  {'depart_utc':<27}{'arrive_utc':<27}{'time_h':>8}{'dist_nmi':>10}{'fuel_t':>9}{'co2_t':>9}{'max_hs_m':>9}{'over_lim_h':>11}")
    for r in result["rows"]:
        mark = "*" if r["best"] else " "
        if r.get("route") is None:
            typer.echo(f"{mark} {r['depart_utc']:<27}error: {r['error']}")
            continue
        hs = "" if r["max_hs_m"] is None else f"{r['max_hs_m']:.2f}"
        over = "" if r.get("hours_over_limits") is None else f"{r['hours_over_limits']:.2f}"
        f_t = f"{r['fuel_t']:.3f}" if r.get("fuel_t") is not None else ""
        c_t = f"{r['co2_t']:.3f}" if r.get("co2_t") is not None else ""
        typer.echo(f"{mark} {r['depart_utc']:<27}{r['arrive_utc']:<27}{r['time_h']:>8.2f}{r['dist_nmi']:>10.2f}{f_t:>9}{c_t:>9}{hs:>9}{over:>11}")
    import pandas as pd  # here, not at the top: `stormlane --help` imports this module

    held = [f"{r['weather_held_after_h']:.2f} h of the {r['depart_utc']} departure" for r in result["rows"] if r.get("weather_held_after_h")]
    if held:
        typer.echo(f"note: the weather ends before arrival; its last field was held for the last {', '.join(held)}")
    arrivals = [pd.Timestamp(r["arrive_utc"]) for r in result["rows"] if r.get("arrive_utc")]
    if fuel and arrivals and max(arrivals) - min(arrivals) > pd.Timedelta(minutes=1):
        typer.echo("note: the departures arrive at different times: their fuel differences are not savings")
