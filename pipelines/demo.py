"""The demo: generate the scenario and run the project's steps on it, printing each summary.

``run_demo(workdir)`` runs :data:`STEPS` in order. A step is ``(name, function)``; the function
takes the :class:`DemoContext`, prints its summary through ``ctx.echo`` and returns a small
JSON-able dict kept in ``ctx.results[name]``. Later components add their step by appending to
:data:`STEPS` (scenario -> ingest -> lanes -> weather -> learn -> audit -> nightly -> report).

Everything is written under the work folder: the scenario (``ais/``, ``weather/``,
``scenario.json``) and the workspace ``stormlane.duckdb``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

#: The demo period of COMMON.md: 30 days of AIS from 2025-01-01T00:00Z.
DEMO_SEED = 0
DEMO_DAYS = 30.0


@dataclass
class DemoContext:
    """Shared state of one demo run."""

    workdir: Path
    seed: int = DEMO_SEED
    days: float = DEMO_DAYS
    echo: Callable[[str], None] = print
    results: dict = field(default_factory=dict)

    @property
    def db(self) -> Path:
        """The demo's DuckDB workspace."""
        return self.workdir / "stormlane.duckdb"

    @property
    def scenario_json(self) -> Path:
        return self.workdir / "scenario.json"


def step_scenario(ctx: DemoContext) -> dict:
    """Generate the demo scenario into the work folder."""
    from pipelines.scenario import build_scenario, summary_lines

    truth = build_scenario(ctx.workdir, seed=ctx.seed, days=ctx.days)
    for line in summary_lines(truth):
        ctx.echo(line)
    return {
        "scenario_json": str(ctx.scenario_json),
        "vessels": len(truth["vessels"]),
        "voyages": len(truth["voyages"]),
        "ais_files": [str(ctx.workdir / f["file"]) for f in truth.get("ais", {}).get("files", [])],
        "expected_ingest": truth.get("expected_ingest", {}),
    }


def step_ingest(ctx: DemoContext) -> dict:
    """Run the Prefect ingest flow on the scenario's AIS files into ``ctx.db``.

    Prints the ingest summary and checks it against the scenario's ground truth
    (``expected_ingest`` and the dirty rows of ``scenario.json``). Files already in the
    workspace (same content, e.g. a rerun of the demo) are skipped by the ingest.
    """
    import json

    from pipelines.ingest import ingest_flow

    summary = ingest_flow([str(ctx.workdir / "ais")], str(ctx.db))
    per_file = summary.pop("per_file", [])
    ctx.echo(f"ingest into {ctx.db}: {summary['files']} file(s), read {summary['read']:,} = loaded "
             f"{summary['loaded']:,} + quarantined {summary['quarantined']:,} + duplicates {summary['duplicates']:,}")
    if summary.get("already_loaded"):
        ctx.echo(f"  {summary['already_loaded']} file(s) already loaded, skipped")
    if summary["reasons"]:
        ctx.echo("  reasons: " + ", ".join(f"{code} {n:,}" for code, n in summary["reasons"].items()))
    truth = json.loads(ctx.scenario_json.read_text(encoding="utf-8"))
    expected = truth.get("expected_ingest", {})
    fresh = [f for f in per_file if not f.get("already_loaded")]
    if fresh and len(fresh) == len(per_file) and expected:
        if summary["loaded"] == expected["loaded"] and summary["read"] == expected["position_records"]:
            ctx.echo(f"  matches the scenario's truth: {expected['loaded']:,} clean rows loaded, "
                     f"{expected['rejected']:,} injected dirty rows rejected")
        else:
            ctx.echo(f"  WARNING: the scenario expected {expected['loaded']:,} loaded of "
                     f"{expected['position_records']:,} position rows")
    return {"db": str(ctx.db), **summary, "expected": expected}


def step_lanes(ctx: DemoContext) -> dict:
    """Ports, voyages and traffic lanes from the ingested AIS (the Prefect lanes flow).

    Prints the counts, writes ``lanes.geojson`` next to the workspace and checks the lanes
    against the scenario's truth: how many of the port pairs the generator sailed got a lane.
    """
    import json

    from pipelines.lanes import export_geojson, lanes_flow
    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import read_lanes, read_ports

    out = lanes_flow(db=str(ctx.db))
    d = out["details"]
    ctx.echo(f"lanes in {ctx.db}: {out['ports']} ports ({d['named_ports']} named), {out['voyages']:,} port-to-port "
             f"voyages, {out['lanes']} lanes from {d['resampled_points']:,} resampled points, "
             f"{out['noise_points']:,} noise points")
    geojson = export_geojson(ctx.db, ctx.workdir / "lanes.geojson")
    ctx.echo(f"  GeoJSON: {geojson}")
    with open_workspace(ctx.db) as ws:
        ports, lanes = read_ports(ws), read_lanes(ws)
    code = dict(zip(ports["port_id"], ports["locode"]))
    have = {(code.get(o), code.get(dd)) for o, dd in zip(lanes["origin_port_id"], lanes["dest_port_id"])}
    truth = json.loads(ctx.scenario_json.read_text(encoding="utf-8")) if ctx.scenario_json.exists() else {}
    sailed = {(v["origin"], v["dest"]) for v in truth.get("voyages", []) if v.get("complete", True)}
    covered = sorted(f"{o}-{dd}" for o, dd in sailed & have)
    missing = sorted(f"{o}-{dd}" for o, dd in sailed - have)
    if sailed:
        ctx.echo(f"  lanes for {len(covered)} of {len(sailed)} port pairs the scenario sailed"
                 + (f"; none yet for {', '.join(missing)}" if missing else ""))
    return {"db": str(ctx.db), "geojson": str(geojson), "run_id": out["run_id"],
            **{k: out[k] for k in ("ports", "voyages", "lanes", "noise_points")},
            "pairs_sailed": len(sailed), "pairs_with_lane": len(covered), "pairs_without_lane": missing}


def step_weather(ctx: DemoContext) -> dict:
    """Load the scenario's weather files (CMEMS waves + ERA5 wind) into the workspace."""
    from pipelines.weather import step_weather as run

    return run(ctx)


def step_learn(ctx: DemoContext) -> dict:
    """Learn the fleet's performance model from the demo's AIS x weather (``stormlane learn
    performance --name demo-fleet``) and say how close it came to the scenario's hidden law.

    The learning never reads the law (:mod:`scenario.performance_law`); only this step reads the
    truth ``scenario.json`` holds (the classes' voluntary thresholds) to print the comparison."""
    import json

    from pipelines.learn import DEMO_MODEL, LearnError, LearnRequest, learn_performance, table_lines

    try:
        summary = learn_performance(LearnRequest(db=ctx.db, name=DEMO_MODEL), echo=ctx.echo)
    except LearnError as err:  # a short demo (--days 1) holds too little weather to learn from
        ctx.echo(f"  skipped: {err}")
        return {"model": None, "skipped": str(err)}
    lines = table_lines(summary)
    for line in lines[:2] + [ln for ln in lines if ln.lstrip().startswith(("all ", "MAE", "P10", "time split"))]:
        ctx.echo(line)
    truth = json.loads(ctx.scenario_json.read_text(encoding="utf-8")) if ctx.scenario_json.exists() else {}
    law = truth.get("performance", {}).get("classes", {})
    ais_class = {v["vessel_class"]: v["ship_type"] for v in truth.get("vessels", []) if "vessel_class" in v}
    from performance.features import ship_class

    found = {r["ship_class"]: r["threshold_hs_m"] for r in summary["voluntary"] if r["sector"] == "head-bow"}
    compared = {}
    for name, c in law.items():
        learned = found.get(str(ship_class([ais_class.get(name)])[0]))
        compared[name] = {"scenario_hs_m": c["voluntary_hs_m"], "learned_hs_m": learned}
        ctx.echo(f"  voluntary slow-down of the scenario's {name} class: generator {c['voluntary_hs_m']:.2f} m, learned "
                 + ("none" if learned is None else f"{learned:.2f} m ({learned - c['voluntary_hs_m']:+.2f} m)"))
    cv = summary["grouped_cv"]
    return {"model": summary["name"], "file": summary["file"], "beats_formulas": summary["beats_formulas"],
            "mae_kn": cv["learned_mae_kn"], "best_formula": cv["best_formula"], "best_formula_mae_kn": cv["best_formula_mae_kn"],
            "voluntary": compared, "timings_s": summary["timings_s"]}


def step_audit(ctx: DemoContext) -> dict:
    """Audit the voyage that sailed through the scenario's historical storm (``DIR/audit.html``)."""
    from pipelines.audit import demo_step

    return demo_step(ctx)


def step_nightly(ctx: DemoContext) -> dict:
    """Tonight's reroute (the Prefect nightly flow) at the end of the AIS period; ``DIR/nightly/``."""
    from pipelines.nightly import demo_step

    return demo_step(ctx)


def step_report(ctx: DemoContext) -> dict:
    """Where the nightly report is (``make demo`` ends by printing its path)."""
    from pipelines.nightly import demo_report_step

    return demo_report_step(ctx)


#: The demo's steps, in order; each component appends its own.
STEPS: list[tuple[str, Callable[[DemoContext], dict]]] = [
    ("scenario", step_scenario),
    ("ingest", step_ingest),
    ("lanes", step_lanes),
    ("weather", step_weather),
    ("learn", step_learn),
    ("audit", step_audit),
    ("nightly", step_nightly),
    ("report", step_report),
]


def run_demo(workdir: Path | str, *, seed: int = DEMO_SEED, days: float = DEMO_DAYS,
             echo: Callable[[str], None] = print,
             steps: list[tuple[str, Callable[[DemoContext], dict]]] | None = None) -> dict:
    """Run the demo steps in ``workdir`` (created) and return each step's result by name."""
    from pipelines.scenario import make_out_dir

    workdir = make_out_dir(workdir, "--workdir")
    ctx = DemoContext(workdir=workdir, seed=seed, days=days, echo=echo)
    for name, step in STEPS if steps is None else steps:
        echo(f"== {name}")
        t0 = time.perf_counter()
        ctx.results[name] = step(ctx)
        echo(f"   {name} done in {time.perf_counter() - t0:.1f} s")
    return ctx.results
