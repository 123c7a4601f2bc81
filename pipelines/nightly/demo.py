"""The demo's nightly steps (``pipelines.demo.STEPS``): tonight's reroute on the demo scenario and
where its report went."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from pipelines.nightly.flow import _flow
from pipelines.nightly.store import beyond_weather_line

#: Cases drawn with maps and plots in the demo night's report (the size targets of issue 22 are
#: met with it: report.html <= 2 MB, report.json <= 3 MB).
DEMO_MAX_DETAIL = 10

def demo_step(ctx) -> dict:
    """Demo step: tonight's reroute at the end of the scenario's AIS period (``--now``), with the
    scenario's forecast weather files (else the workspace's weather), report in ``DIR/nightly``."""
    import json as _json

    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import read_lanes

    truth = _json.loads(ctx.scenario_json.read_text(encoding="utf-8"))
    now = pd.Timestamp(truth["scenario"]["end_utc"])
    files = [str(ctx.workdir / f) for f in truth.get("weather", {}).get("files", [])]
    with open_workspace(ctx.db) as ws:
        n_lanes = len(read_lanes(ws))
    if n_lanes == 0:
        ctx.echo("  no lanes in the workspace (too few days of AIS?): no nightly run")
        return {"skipped": "no lanes"}
    out = _flow()(db=str(ctx.db), out=str(ctx.workdir / "nightly"), weather=files, now=now.isoformat(), max_detail=DEMO_MAX_DETAIL)
    ctx.echo(f"  night {out['run_id']} at {out['now_utc']}: {out['lanes_checked']} lanes x {out['window']['departures']} "
             f"departures = {out['departures_checked']} lane-departures; {out['adverse']} adverse, {out['reroutes']} with a "
             f"proposed reroute, {out['failed']} failed")
    for row in out["top"][:5]:
        ctx.echo(f"  {row['rank']:>3}. lane {row['lane']:<8} {row['depart_utc'][:16]}Z  {row['rules']} -> {row['proposed']} "
                 f"({row['risk_avoided_h'] or 0:.1f} h at risk avoided, {row['delta_time_h'] or 0:+.1f} h)")
    beyond = beyond_weather_line(out)
    if beyond is not None:
        ctx.echo(f"  note: {beyond}")
    t = out["timings_s"]
    ctx.echo("  stages: " + ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in t.items()))
    return out


def demo_report_step(ctx) -> dict:
    """Demo step: where the night's report and exports are."""
    night = ctx.results.get("nightly") or {}
    if not night.get("report"):
        ctx.echo("  no nightly report")
        return {"skipped": "no nightly report"}
    ctx.echo(f"  {night['exports']} export files in {night.get('exports_zip') or 'no archive'}; model {night.get('model')}")
    ctx.echo(f"  nightly report: {night['report']}")
    return {"report": night["report"], "out": night["out"]}
