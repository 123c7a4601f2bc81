"""Benchmark of the nightly reroute (issue 7): a scheduled night is a fresh process.

The world (built once, untimed, cached; ``tests/nightly_world.py``): the demo scenario's 30 days
of AIS through the lanes chain into a workspace, and the forecast weather files of the night.
The night: ``stormlane nightly`` for 2025-01-31T00:00Z (every lane x 16 departures, adverse
ones rerouted, ranked, stored; the report with 10 detailed cases and the exports).

* ``night_sequential``: ``pipelines.cli.main(["nightly", ...])`` in a fresh process (cold: the
  first night of the process, as a scheduled night runs: imports, Prefect's temporary API,
  numba's kernels loaded). No warm figure: a scheduled night is always a fresh process.
* ``night_dask`` (ours, compared with the sequential night as its baseline): the same with
  ``--task-runner dask``, which starts its own 2-worker ``distributed.LocalCluster``.

The interpreter's own start (~0.05 s, see ``bench/routing.py``'s ``python -c pass``) is the only
part of a ``stormlane nightly`` process outside the cold figure.
Targets (issue 7): the full night under 60 s on 2 cores; the Dask runner not slower than the
sequential one by more than its start-up cost (here: cold Dask <= cold sequential + the cluster's
start-up, which the Dask side measures separately).
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: `import lanes` must find the package, not bench/lanes.py
    import sys
    from pathlib import Path

    _here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _here]
    sys.path.insert(0, str(_here.parent))

import shutil
import sys
from pathlib import Path

from bench._harness import ROOT, Group, Measure, Side, Target, script_main, source_stamp

NOW = "2025-01-31T00:00Z"


def prepare(cache: str, run_dir: str) -> dict:
    """Build the world unless the cache holds one built by the same code; copy its workspace
    for this run (a night stores its results in it)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from nightly_world import build_world

    world = Path(cache)
    done = world / "done"
    if not done.exists():
        shutil.rmtree(world, ignore_errors=True)
        build_world(world)
        done.write_text("ok")
    run = Path(run_dir)
    shutil.rmtree(run, ignore_errors=True)
    run.mkdir(parents=True)
    shutil.copyfile(world / "ws.duckdb", run / "ws.duckdb")
    return {"world": world.name, "weather_files": sorted(p.name for p in (world / "weather").glob("*.nc"))}


def night_args(cache: str, run_dir: str, runner: str) -> list[str]:
    return ["nightly", "--db", str(Path(run_dir) / "ws.duckdb"), "--out", str(Path(run_dir) / f"out-{runner}"),
            "--weather", str(Path(cache) / "weather"), "--now", NOW, "--task-runner", runner, "--json"]


def setup(argv: list[str]) -> dict:
    import os

    os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")
    return {"argv": argv}


def run_night(st: dict) -> dict:
    """One night through the CLI in this process; returns its counts and stage times."""
    import contextlib
    import io
    import json

    from pipelines.cli import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        main(st["argv"])
    out = json.loads(buf.getvalue())
    keep = ("run_id", "lanes_checked", "departures_checked", "adverse", "reroutes", "failed")
    info = {k: out.get(k) for k in keep}
    info["timings_s"] = {k: round(v, 2) for k, v in (out.get("timings_s") or {}).items()}
    info["work"] = out.get("departures_checked")
    return info


def setup_cluster() -> dict:
    return {}


def run_cluster_start(st: dict) -> dict:
    """Start and stop a 2-worker LocalCluster (what ``--task-runner dask`` starts first)."""
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, Client(cluster):
        pass
    return {}


def build(cfg):
    here = "bench.nightly"
    cache = str(Path(cfg.cache_dir) / f"nightly-world-{source_stamp('lanes', 'scenario', 'weather', 'thresholds', 'pipelines/lanes.py', 'pipelines/scenario.py', 'tests/nightly_world.py')}")
    run_dir = str(Path(cfg.cache_dir) / "nightly-run")
    seq, dsk = night_args(cache, run_dir, "sequential"), night_args(cache, run_dir, "dask")
    g = Group(
        "night", "the demo's full night (every lane x 16 departures, report with 10 detailed cases)",
        prepare=f"{here}:prepare", prepare_kwargs={"cache": cache, "run_dir": run_dir},
        sides=[Side("night_sequential", "`stormlane nightly` (sequential task runner) in a fresh process",
                    setup=f"{here}:setup", kwargs={"argv": seq}, run=f"{here}:run_night", work="lane-departures checked",
                    warm_per_process=0,
                    warm_na="not measured: a scheduled night is a fresh process (`stormlane schedule` runs each night in a "
                            "subprocess), so the cold figure is what users get",
                    empty_cache="not measured: the night's kernels (routing, safety, evaluation) compile in the "
                                "empty-cache runs of bench/routing.py and bench/evaluate.py; one empty-cache night costs "
                                "1.5-3 min (budget of `make bench`: 30 min)"),
               Side("night_dask", "`stormlane nightly --task-runner dask` (starts its own 2-worker LocalCluster) in a "
                    "fresh process", setup=f"{here}:setup", kwargs={"argv": dsk}, run=f"{here}:run_night",
                    work="lane-departures checked", warm_per_process=0,
                    empty_cache="not measured: as for night_sequential (the workers inherit NUMBA_CACHE_DIR)",
                    warm_na="not measured: each `--task-runner dask` night starts its own cluster again, and a second "
                            "night costs as much as the first (budget of `make bench`: 30 min)"),
               Side("cluster_start", "start and stop a 2-worker distributed.LocalCluster (the Dask runner's start-up)",
                    setup=f"{here}:setup_cluster", run=f"{here}:run_cluster_start", ours=False)],
        measures=[
            Measure("night", "full nightly run, sequential runner", "night_sequential", "night_dask",
                    relation="the same night on the Dask runner (same run id and counts)",
                    targets=[Target("< 60 s (cold)", "cold.wall_s", "<", 60.0, "s", "issue 7")]),
            Measure("night_dask", "full nightly run, Dask runner", "night_dask", "night_sequential",
                    relation="the same night on the sequential runner (same run id and counts)",
                    targets=[Target("< 60 s (cold)", "cold.wall_s", "<", 60.0, "s", "issue 7"),
                             Target("slower than sequential by at most the cluster start-up (cold)", "excess.cold", "<=",
                                    0.0, "s", "issue 7", value_from="cluster_start:cold.wall_s")]),
        ])
    return [g], []


if __name__ == "__main__":
    script_main("bench/nightly.py", build)
