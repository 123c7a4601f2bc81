"""The demo: generate the scenario and run the project's steps on it, printing each summary.

``run_demo(workdir)`` runs :data:`STEPS` in order. A step is ``(name, function)``; the function
takes the :class:`DemoContext`, prints its summary through ``ctx.echo`` and returns a small
JSON-able dict kept in ``ctx.results[name]``. Later components add their step by appending to
:data:`STEPS` (scenario -> ingest -> lanes -> weather -> nightly -> report).

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
    workspace (same SHA-256, e.g. a rerun of the demo) are skipped by the ingest.
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


#: The demo's steps, in order; each component appends its own.
STEPS: list[tuple[str, Callable[[DemoContext], dict]]] = [
    ("scenario", step_scenario),
    ("ingest", step_ingest),
]


def run_demo(workdir: Path | str, *, seed: int = DEMO_SEED, days: float = DEMO_DAYS,
             echo: Callable[[str], None] = print,
             steps: list[tuple[str, Callable[[DemoContext], dict]]] | None = None) -> dict:
    """Run the demo steps in ``workdir`` (created) and return each step's result by name."""
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    ctx = DemoContext(workdir=workdir, seed=seed, days=days, echo=echo)
    for name, step in STEPS if steps is None else steps:
        echo(f"== {name}")
        t0 = time.perf_counter()
        ctx.results[name] = step(ctx)
        echo(f"   {name} done in {time.perf_counter() - t0:.1f} s")
    return ctx.results
