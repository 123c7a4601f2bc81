"""`stormlane deviate`: cargo-safe deviation of one lane for one departure."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from pipelines.commands._common import (VESSEL_FROM_AIS, DbReadOption, JsonOption, ProfileOption, SpeedLossOption, emit_json, paths_text,
                                        speed_loss_choice, vessel_option, weather_option, xarray_without_dask_arrays)


def register(app: typer.Typer) -> None:
    @app.command("deviate")
    def deviate(
        lane: str = typer.Option(..., "--lane", metavar="ID", help="Lane id in the workspace (see `stormlane lanes`)."),
        depart: str = typer.Option(..., "--depart", metavar="ISO", help="Departure time, ISO 8601 (UTC if no offset)."),
        db: Path = DbReadOption,
        weather: Optional[List[Path]] = weather_option("the weather loaded in the workspace (`stormlane weather load`)"),
        vessel: Optional[str] = vessel_option(VESSEL_FROM_AIS),
        profile: Optional[str] = ProfileOption,
        speed_loss: str = SpeedLossOption,
        json_out: bool = JsonOption,
    ) -> None:
        """Walk the lane's centroids from the departure and move every adverse one to the nearest
        cell that passes the vessel's thresholds (R-tree, <= 10 candidates, within 3 h of sailing),
        keeping legs at sea (a leg over land is replaced by the shortest sea path; a deviation that
        cannot be repaired is not proposed) and recomputing ETAs; prints what moved and the
        comparison with the lane as planned. Both are sailed by the same vessel model from the
        departure: the lane's typical AIS speed minus the speed loss (--speed-loss, a formula or
        learned:NAME). --json adds speed_loss_model, speed_kn,
        reference ("lane"), proposed (false with the reason in notes) and each route's sea_only,
        land_legs, land_nmi, no_weather_h.

        Example:

        \b
          stormlane deviate --lane 1-2-1 --depart 2025-01-15T00:00Z --db work/stormlane.duckdb
        """
        xarray_without_dask_arrays()
        from pipelines.deviate import deviate_in_workspace

        out = deviate_in_workspace(db, lane, depart, weather=paths_text(weather), vessel=vessel, profile=profile,
                                   speed_loss=speed_loss_choice(speed_loss, db))
        if json_out:
            emit_json(out)
            return
        a, b = out["lane"], out["deviation"]
        typer.echo(f"lane {out['lane_id']} departing {out['depart_utc']} ({out['vessel_profile']}, "
                   f"{out['speed_kn']:.1f} kn, speed-loss model {out['speed_loss_model']})")
        typer.echo(f"  lane:      {a['time_h']:.1f} h, {a['dist_nmi']:.1f} nmi, max Hs {a['max_hs_m']:.2f} m, "
                   f"{a['exposure_h']:.1f} h over limits, {a['n_safety_events']} IMO event(s)")
        typer.echo(f"  deviation: {b['time_h']:.1f} h, {b['dist_nmi']:.1f} nmi, max Hs {b['max_hs_m']:.2f} m, "
                   f"{b['exposure_h']:.1f} h over limits, {b['n_safety_events']} IMO event(s); "
                   f"{b['n_deviated']} point(s) moved, {b['n_unresolved']} unresolved, {b['n_legs_adverse']} adverse leg(s)")
        for s in out["steps"]:
            fix = s.get("land_repair")
            if s["status"] in ("deviated", "unresolved") or s["rules_fired"] or fix:
                typer.echo(f"    #{s['seq']}: {s['status']} ({', '.join(s['rules_fired']) or 'ok'}), moved {s['moved_nmi']:.1f} nmi"
                           + (f"; leg in over land, replaced by the shortest sea path (+{fix['added_nmi']:.1f} nmi)" if fix else ""))
        m = out["metrics"]
        if m["hs_decrease_pct"] is not None and m["hs_decrease_pct"] == m["hs_decrease_pct"]:
            typer.echo(f"  mean Hs over the lane's adverse portion: {m['hs_decrease_pct']:.0f} % lower on the deviation")
        for note in out["notes"]:  # pipelines.deviate.not_safer_note, then the weather's; --json: "note"/"notes"
            typer.echo(f"  note: {note}")
