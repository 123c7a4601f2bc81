"""Benchmark: the demo scenario's full night (every lane, 16 departures each), time per stage.

Run: ``.venv/bin/python bench/nightly.py [--workdir DEMO_DIR] [--max-detail N]``

* The world: the demo's lanes and its forecast weather. With ``--workdir`` (a folder written by
  ``make demo``) its workspace and weather files are used; otherwise the demo scenario is built
  in a temporary folder (its 30 days of AIS through the lanes chain, the forecast weather files;
  ``tests/nightly_world.py``), which is not timed.
* The night runs through the Prefect flow (as ``stormlane nightly``): first with the sequential
  task runner (twice: the first run in a fresh process also loads numba's compiled kernels), then
  with the per-lane work on a 2-worker ``distributed.LocalCluster`` through the Dask task runner.
  The same cluster runs the night twice: its start-up cost is the cluster's start plus what the
  first night pays once per worker process (imports, Prefect's task engine, numba's compiled
  kernels: first minus second night), to compare with "Dask minus sequential".

Targets (issue 7): the full night under 60 s on 2 cores; the Dask runner not slower than the
sequential one by more than its start-up cost. The machine is shared: figures are noisy.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# `python bench/nightly.py` puts bench/ first on sys.path, where bench/lanes.py would shadow the
# `lanes` package: drop it (Dask's spawned workers inherit the cleaned path).
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
NOW = "2025-01-31T00:00Z"
TARGET_S = 60.0


def _world(args) -> tuple[Path, list[str]]:
    if args.workdir:
        wd = Path(args.workdir)
        truth = json.loads((wd / "scenario.json").read_text(encoding="utf-8"))
        return wd / "stormlane.duckdb", [str(wd / f) for f in truth["weather"]["files"]]
    sys.path.append(str(ROOT / "tests"))
    from nightly_world import build_world

    t = time.perf_counter()
    w = build_world(Path(tempfile.mkdtemp(prefix="stormlane-bench-nightly-")))
    print(f"world built in {time.perf_counter() - t:.1f} s (not timed): {w['db']}")
    return w["db"], [str(w["weather"])]


def _night(runner: str, db, weather, out, max_detail: int) -> tuple[dict, float]:
    from pipelines.nightly import flow_with_runner

    t = time.perf_counter()
    s = flow_with_runner(runner)(db=str(db), out=str(out), weather=weather, now=NOW, max_detail=max_detail)
    return s, time.perf_counter() - t


def _row(label: str, s: dict, wall: float) -> str:
    t = s["timings_s"]
    stages = "  ".join(f"{k[:-2]} {t.get(k, float('nan')):5.1f}" for k in ("inputs_s", "screen_s", "reroute_s", "rank_s", "report_s", "store_s"))
    return f"{label:<34} {wall:6.1f} s   {stages}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workdir", help="a demo folder (make demo) to use instead of building the scenario")
    ap.add_argument("--max-detail", type=int, default=10, help="report cases drawn with a map and plots (CLI default 10)")
    args = ap.parse_args()
    os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
    os.environ.setdefault("DO_NOT_TRACK", "1")
    os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")
    logging.getLogger("routing.planner").setLevel(logging.ERROR)
    db, weather = _world(args)
    out = Path(tempfile.mkdtemp(prefix="stormlane-bench-nightly-out-"))
    rows = []
    seq1, w1 = _night("sequential", db, weather, out / "seq1", args.max_detail)
    rows.append(_row("sequential (first in process)", seq1, w1))
    seq2, w2 = _night("sequential", db, weather, out / "seq2", args.max_detail)
    rows.append(_row("sequential (again)", seq2, w2))

    from distributed import Client, LocalCluster

    t = time.perf_counter()
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0")
    client = Client(cluster)
    t_cluster = time.perf_counter() - t
    address = f"dask:{cluster.scheduler_address}"
    dsk1, wd1 = _night(address, db, weather, out / "dask1", args.max_detail)
    rows.append(_row("dask, 2 workers, fresh cluster", dsk1, wd1))
    dsk, wd = _night(address, db, weather, out / "dask2", args.max_detail)
    rows.append(_row("dask, 2 workers, same cluster again", dsk, wd))
    client.close()
    cluster.close()
    cold, wc = _night("dask", db, weather, out / "dask-own", args.max_detail)
    rows.append(_row("--task-runner dask (own cluster)", cold, wc))
    # start-up: starting the cluster, plus what the first night on it pays once per worker process
    # (imports, Prefect's task engine, numba's compiled kernels), i.e. first minus second night
    t_startup = t_cluster + max(0.0, dsk1["timings_s"]["reroute_s"] - dsk["timings_s"]["reroute_s"])

    print(f"\nnight {seq2['run_id']}: {seq2['lanes_checked']} lanes x {seq2['window']['departures']} departures = "
          f"{seq2['departures_checked']} lane-departures; {seq2['adverse']} adverse, {seq2['reroutes']} reroutes, "
          f"{seq2['failed']} failed; report with {args.max_detail} detailed cases, {seq2['exports']} export files")
    print(f"{'run':<34} {'wall':>8}   stages [s]")
    for r in rows:
        print(r)
    same = all(s["run_id"] == seq2["run_id"] and s["adverse"] == seq2["adverse"] for s in (seq1, dsk1, dsk, cold))
    print(f"\nsame run id and counts on every runner: {same}")
    extra = dsk["timings_s"]["reroute_s"] - seq2["timings_s"]["reroute_s"]
    print(f"Dask start-up: cluster {t_cluster:.1f} s + first-night extra on fresh workers "
          f"{dsk1['timings_s']['reroute_s'] - dsk['timings_s']['reroute_s']:.1f} s = {t_startup:.1f} s; per-lane stage on the "
          f"warm cluster {dsk['timings_s']['reroute_s']:.1f} s vs sequential {seq2['timings_s']['reroute_s']:.1f} s "
          f"({extra:+.1f} s; target: <= start-up -> {'met' if extra <= t_startup else 'NOT met'})")
    print(f"full night (sequential, warm): {w2:.1f} s; target < {TARGET_S:.0f} s on 2 cores -> "
          f"{'met' if w2 < TARGET_S else 'NOT met'} (2 shared cores: noisy)")


if __name__ == "__main__":
    main()
