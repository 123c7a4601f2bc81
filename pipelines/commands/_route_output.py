"""What `stormlane route` prints for one plan: the note: lines, the JSON object or the table, and the export file."""

from __future__ import annotations

from pathlib import Path

import typer

from pipelines.commands._common import emit_json
from pipelines.commands._route_fuel import echo_fuel, fuel_notes


def show_plan(plan, vessel, ship, *, safety: str, fuel: bool, learned: bool, out: Path | None, json_out: bool) -> None:
    """Print the plan's routes (JSON or table), after its notes; write them to ``out`` when given."""
    from routing.planner import FUEL_ROUTE_NAMES, ROUTE_NAMES, SAFE_ROUTE_NAMES

    names = ROUTE_NAMES + (SAFE_ROUTE_NAMES if safety != "none" else ()) + tuple(n for n in FUEL_ROUTE_NAMES if n in plan.routes)
    notes = list(plan.notes)  # the model and what it rests on, said in every output
    notes += _snap_notes(plan)
    if fuel:
        notes += fuel_notes(plan)
    held = {name: h for name in names if (h := plan.routes[name].properties.get("weather_held_after_h"))}
    if held:
        notes.append("the weather ends before arrival; its last field was held for the last "
                     + ", ".join(f"{h:.2f} h of {name}" for name, h in held.items()))
    band = None
    if learned:
        from pipelines.learn import eta_band

        band = eta_band(plan)
    if out is not None:
        from dashboards.exports import write_routes

        written = write_routes([plan.routes[name] for name in names], out)
        typer.echo(f"wrote {', '.join(map(str, written))}", err=True)
    if json_out:
        data = plan.to_dict()
        for name, h in held.items():
            data[name]["weather_held_after_h"] = h
        if band is not None:
            data["eta_band"] = band
        data["notes"] = notes  # what the table prints as note: lines (empty: nothing to say)
        emit_json(data)
        return
    _echo_table(plan, names, vessel, ship, safety, fuel)
    if band is not None:
        typer.echo(f"{band['route']} sailing time P10-P50-P90 by the learned model's quantiles: {band['time_h_p10']:.2f} - "
                   f"{band['time_h_p50']:.2f} - {band['time_h_p90']:.2f} h ({band['assumption']})")
    if held:
        typer.echo(f"note: {notes[-1]}")


def _snap_notes(plan) -> list[str]:
    """A start or goal moved to sea by more than half a mesh step, said on stderr at once and in the notes."""
    notes = []
    for what, key in (("start", "start_snap_nmi"), ("goal", "goal_snap_nmi")):
        moved = plan.routes["optimal"].properties.get(key, 0.0)
        if moved > 0.5 * plan.mesh.grid.dlat_deg * 60.0:
            notes.append(f"{what} moved {moved:.2f} nmi to the nearest sea node")
            typer.echo(f"note: {notes[-1]}", err=True)
    return notes


def _echo_table(plan, names, vessel, ship, safety: str, fuel_cols: bool) -> None:
    """The route table: one line per route (time, distance, max Hs, waypoints; hours over limits and fuel when asked)."""
    typer.echo(f"great circle {plan.great_circle_nmi:.2f} nmi; mesh {plan.mesh.grid.ny} x {plan.mesh.grid.nx} "
               f"({plan.mesh.grid.dlat_deg * 60:.3g} nmi, {plan.mesh.edges} edges), vessel {vessel.name}, "
               f"{ship.speed_kn:g} kn, {ship.model}")  # fmt: skip
    for line in plan.notes:
        typer.echo(f"note: {line}")
    over = safety != "none"
    if over:
        sf = plan.stats["safety"]
        typer.echo(f"safety {sf['requested']}" + (f" (ran {sf['mode']}: no route keeps within the limits)" if sf["fallback"] else "")
                   + f"; limits {sf['operator_limits'] or 'none'}, IMO rules {'on' if sf['imo_rules'] else 'off'}"
                   + (f"; not evaluated: {'; '.join(sf['rules_not_evaluated'])}" if sf["rules_not_evaluated"] else ""))
    typer.echo(f"{'route':<26}{'time_h':>9}{'dist_nmi':>10}{'max_hs_m':>10}{'waypoints':>11}" + (f"{'over_limits_h':>15}" if over else "")
               + (f"{'fuel_t':>10}{'co2_t':>10}" if fuel_cols else ""))
    for name in names:
        r = plan.routes[name]
        hs = "" if r.max_hs_m != r.max_hs_m else f"{r.max_hs_m:.2f}"
        line = f"{name:<26}{r.time_h:>9.2f}{r.dist_nmi:>10.2f}{hs:>10}{r.n_waypoints:>11d}"
        if over:
            line += f"{r.properties['hours_over_limits']:>15.2f}" if "hours_over_limits" in r.properties else f"{'':>15}"
        if fuel_cols:
            line += f"{r.properties['fuel_t']:>10.3f}{r.properties['co2_t']:>10.3f}"
        typer.echo(line)
    if fuel_cols:
        echo_fuel(plan)
