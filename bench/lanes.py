"""Benchmark: the lanes chain on the whole Ushant set, next to a naive DBSCAN baseline.

Runs, each in its own subprocess so that peak memory is measured per run (max RSS of the
process, ``resource.getrusage``):

1. ``chain``     the full chain (jump filter -> stops -> ports -> voyages -> resampling -> lanes)
                 on all 2.4 M Ushant positions, with the Ushant parameters (eps 0.5 nmi,
                 density 20 voyages; see README "Traffic lanes");
2. ``chain-1m``  the same chain on the 1 M-position subset used by the baseline;
3. ``baseline``  the naive approach: sklearn DBSCAN (haversine, ball tree, eps 0.5 nmi,
                 min_samples 10) on all raw positions of that 1 M subset, position only.
                 It runs under an address-space limit (``--baseline-limit-gb``, default 8) so
                 that it cannot take the shared machine down; hitting the limit is reported;
4. ``baseline-200k`` the same naive DBSCAN on the first 200 k raw positions (for scale).

Targets (issue 3): whole set < 60 s and < 4 GB peak on 2 cores.
Usage: ``.venv/bin/python bench/lanes.py [--data PATH] [--skip-baseline]``.

``--scaleout [--days N]`` instead times the lane-extraction stage (one task per
origin-destination pair, issue 7 item 5) on the demo scenario's positions (built and ingested
untimed): in-process without Prefect (``stormlane lanes``' default), through the Prefect flow with
the sequential task runner, and on a 2-worker ``distributed.LocalCluster`` through the Dask task
runner (fresh cluster, then the same cluster again), plus ``--task-runner dask`` starting its own
cluster; it checks that every run wrote the same tables. (The Ushant set is a single "transit"
partition, having no ports, so it cannot fan out.)
"""

from __future__ import annotations

import sys
from pathlib import Path

# This file is bench/lanes.py: drop its folder from the import path so that ``import lanes``
# finds the package, not this script.
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import argparse
import json
import os
import resource
import subprocess
import time

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = Path(os.environ.get("STORMLANE_SHARED_DATA", ROOT.parent / "shared" / "data")) / "ais" / "ushant_ais_subset.parquet"
EPOCH = "2019-01-01T00:00Z"  # the data has no absolute time (PROVENANCE.md); any explicit epoch works
SUBSET_ROWS = 1_000_000


def _peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9  # Linux: kB


def run_chain(data: Path, rows: int | None) -> dict:
    from lanes.chain import ChainParams, build_lanes
    from lanes.extract import LaneParams
    from lanes.io.ushant import read_ushant

    t0 = time.perf_counter()
    df, meta = read_ushant(data, EPOCH, columns_only=True)
    if rows is not None:
        df = df.iloc[:rows]
    t_read = time.perf_counter() - t0
    params = ChainParams(id_col="track_id", lanes=LaneParams(eps_nmi=0.5, min_density=20.0 * (len(df) / 2_428_430)))
    t1 = time.perf_counter()
    r = build_lanes(df, None, params)
    t_chain = time.perf_counter() - t1
    lanes = r.lanes.lanes.sort_values("n_points", ascending=False)
    top = lanes.head(2)
    diff = float(abs((top.iloc[0]["mean_course_deg"] - top.iloc[1]["mean_course_deg"] + 180) % 360 - 180)) if len(top) == 2 else None
    return {
        "positions": int(len(df)), "read_s": round(t_read, 2), "chain_s": round(t_chain, 2),
        "wall_s": round(t_read + t_chain, 2), "peak_gb": round(_peak_gb(), 2),
        "steps_s": r.summary["timings"], "resampled_points": r.summary["resampled_points"],
        "lanes": r.summary["lanes"], "lanes_10_voyages": int((lanes["n_voyages"] >= 10).sum()),
        "noise_points": r.summary["noise_points"], "dropped_jumps": r.summary["dropped_jumps"],
        "top2_course_deg": [round(float(x), 1) for x in top["mean_course_deg"]], "top2_course_diff_deg": diff,
        "top2_voyages": [int(x) for x in top["n_voyages"]],
    }


def run_baseline(data: Path, limit_gb: float, rows: int = SUBSET_ROWS) -> dict:
    import numpy as np
    import pyarrow.parquet as pq

    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (int(limit_gb * 1e9), hard))
    from sklearn.cluster import DBSCAN

    from thresholds.units import EARTH_RADIUS_NMI

    t0 = time.perf_counter()
    tab = pq.read_table(data, columns=["lat", "lon"]).slice(0, rows)
    lat = tab.column("lat").to_numpy()
    lon = tab.column("lon").to_numpy()
    ok = (np.abs(lat) <= 90) & (np.abs(lon) <= 180)
    X = np.deg2rad(np.column_stack([lat[ok], lon[ok]]))
    try:
        labels = DBSCAN(eps=0.5 / EARTH_RADIUS_NMI, min_samples=10, metric="haversine", algorithm="ball_tree").fit_predict(X)
    except MemoryError:
        return {"positions": int(ok.sum()), "failed": f"MemoryError under the {limit_gb:g} GB address-space limit",
                "wall_s": round(time.perf_counter() - t0, 2), "peak_gb": round(_peak_gb(), 2)}
    return {"positions": int(ok.sum()), "wall_s": round(time.perf_counter() - t0, 2), "peak_gb": round(_peak_gb(), 2),
            "clusters": int(labels.max() + 1), "noise_frac": round(float((labels < 0).mean()), 3)}


def _scaleout_workspace(days: float) -> Path:
    import tempfile

    import numpy as np
    import pandas as pd

    from lanes.scenario import ScenarioSettings, generate_scenario
    from pipelines.ingest import ingest_paths
    from pipelines.scenario import load_scenario_spec

    sc = generate_scenario(load_scenario_spec(), ScenarioSettings(seed=0, start_utc=pd.Timestamp("2025-01-01T00:00Z"), days=days))
    f = sc.fixes[sc.fixes["received"]]
    nan = np.full(len(f), np.nan)
    folder = Path(tempfile.mkdtemp(prefix="stormlane-bench-lanes-"))
    pd.DataFrame({
        "mmsi": f["mmsi"].to_numpy(dtype=np.int64), "time_utc": pd.to_datetime(f["time_s"].to_numpy(), unit="s", utc=True),
        "lat_deg": f["lat_deg"].to_numpy(dtype=float), "lon_deg": f["lon_deg"].to_numpy(dtype=float),
        "sog_kn": f["sog_kn"].to_numpy(dtype=float), "cog_deg": nan, "heading_deg": nan, "nav_status": nan,
    }).to_parquet(folder / "positions.parquet")
    ingest_paths([folder / "positions.parquet"], folder / "ws.duckdb")
    return folder / "ws.duckdb"


def _tables_digest(db: Path) -> str:
    import hashlib

    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import read_lane_centroids, read_lane_voyages, read_lanes, read_ports, read_voyages

    h = hashlib.sha256()
    with open_workspace(db) as ws:
        for df in (read_ports(ws), read_voyages(ws), read_lanes(ws), read_lane_centroids(ws), read_lane_voyages(ws)):
            h.update(df.to_csv(index=False, float_format="%.17g").encode())
    return h.hexdigest()[:16]


def run_scaleout(days: float) -> None:
    import logging

    os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
    os.environ.setdefault("DO_NOT_TRACK", "1")
    os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")
    logging.getLogger("distributed").setLevel(logging.WARNING)
    from distributed import Client, LocalCluster

    from pipelines.lanes import flow_with_runner, run_lanes

    t = time.perf_counter()
    db = _scaleout_workspace(days)
    print(f"lanes scale-out benchmark: demo scenario, {days:g} days, built and ingested in {time.perf_counter() - t:.1f} s "
          f"(not timed); {os.cpu_count()} cores, shared machine: noisy")
    rows = []

    def timed(label, fn):
        t0 = time.perf_counter()
        out = fn()
        wall = time.perf_counter() - t0
        rows.append((label, wall, out["details"]["timings"]["lanes_s"], out, _tables_digest(db)))

    timed("in process, no Prefect (default)", lambda: run_lanes(db))
    timed("flow, sequential (Prefect start-up)", lambda: flow_with_runner("sequential")(db=str(db)))
    timed("flow, sequential (again)", lambda: flow_with_runner("sequential")(db=str(db)))
    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0")
    client = Client(cluster)
    t_cluster = time.perf_counter() - t0
    try:
        address = f"dask:{cluster.scheduler_address}"
        timed("flow, dask 2 workers (fresh)", lambda: flow_with_runner(address)(db=str(db)))
        timed("flow, dask 2 workers (again)", lambda: flow_with_runner(address)(db=str(db)))
    finally:
        client.close()
        cluster.close()
    timed("flow, --task-runner dask (own)", lambda: flow_with_runner("dask")(db=str(db)))
    d = rows[0][3]
    print(f"{d['details']['resampled_points']:,} resampled points in {rows[-1][3]['details']['partition_tasks']} O-D "
          f"partitions -> {d['lanes']} lanes; 2-worker cluster started in {t_cluster:.1f} s")
    print(f"{'run':<38} {'wall s':>7} {'lanes stage s':>14}  tables")
    for label, wall, lanes_s, _, digest in rows:
        print(f"{label:<38} {wall:7.1f} {lanes_s:14.2f}  {digest}")
    same = len({r[4] for r in rows}) == 1
    print(f"identical tables on every runner: {same}")
    print(json.dumps({"days": days, "cluster_start_s": round(t_cluster, 2),
                      "runs": [{"run": r[0], "wall_s": round(r[1], 2), "lanes_s": r[2]} for r in rows], "identical": same}))


def _child(mode: str, args) -> dict:
    cmd = [sys.executable, __file__, "--mode", mode, "--data", str(args.data), "--baseline-limit-gb", str(args.baseline_limit_gb)]
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if out.returncode != 0:
        tail = (out.stderr or out.stdout).strip().splitlines()[-3:]
        return {"failed": f"exit {out.returncode}: {' | '.join(tail)}"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--mode", choices=["all", "chain", "chain-1m", "baseline", "baseline-200k"], default="all")
    ap.add_argument("--baseline-limit-gb", type=float, default=8.0)
    ap.add_argument("--skip-baseline", action="store_true")
    ap.add_argument("--scaleout", action="store_true", help="time the lanes stage sequential vs Dask on the demo scenario")
    ap.add_argument("--days", type=float, default=30.0, help="with --scaleout: days of demo traffic (default 30)")
    args = ap.parse_args()
    if args.scaleout:
        run_scaleout(args.days)
        return
    if not args.data.exists():
        print(f"bench/lanes.py: Ushant data not found at {args.data} (set STORMLANE_SHARED_DATA)", file=sys.stderr)
        sys.exit(1)
    if args.mode == "chain":
        print(json.dumps(run_chain(args.data, None)))
        return
    if args.mode == "chain-1m":
        print(json.dumps(run_chain(args.data, SUBSET_ROWS)))
        return
    if args.mode == "baseline":
        print(json.dumps(run_baseline(args.data, args.baseline_limit_gb)))
        return
    if args.mode == "baseline-200k":
        print(json.dumps(run_baseline(args.data, args.baseline_limit_gb, 200_000)))
        return

    print(f"lanes benchmark on {args.data.name} ({os.cpu_count()} cores; timings on a shared machine are noisy)")
    results = {"chain (whole set)": _child("chain", args), "chain (1 M subset)": _child("chain-1m", args)}
    if not args.skip_baseline:
        results["naive DBSCAN (1 M raw)"] = _child("baseline", args)
        results["naive DBSCAN (200 k raw)"] = _child("baseline-200k", args)
    print(f"{'run':<24} {'positions':>10} {'wall s':>8} {'peak GB':>8}  notes")
    for name, r in results.items():
        if "failed" in r and "positions" not in r:
            print(f"{name:<24} {'-':>10} {'-':>8} {'-':>8}  FAILED {r['failed']}")
            continue
        if name.startswith("chain"):
            note = (f"lanes {r['lanes']} ({r['lanes_10_voyages']} with >= 10 voyages), top-2 courses "
                    f"{r['top2_course_deg']} (diff {r['top2_course_diff_deg']}), voyages {r['top2_voyages']}")
        elif "failed" in r:
            note = "FAILED " + r["failed"]
        else:
            note = f"clusters {r['clusters']}, noise {r['noise_frac']:.1%} (position only: no direction, no speed)"
        print(f"{name:<24} {r['positions']:>10,} {r['wall_s']:>8.1f} {r['peak_gb']:>8.2f}  {note}")
    whole = results["chain (whole set)"]
    if "wall_s" in whole:
        print(f"steps (s): {whole['steps_s']}")
        ok_t = whole["wall_s"] < 60
        ok_m = whole["peak_gb"] < 4
        print(f"targets: whole set < 60 s: {'PASS' if ok_t else 'FAIL'} ({whole['wall_s']} s); "
              f"< 4 GB peak: {'PASS' if ok_m else 'FAIL'} ({whole['peak_gb']} GB)")
    print(json.dumps(results))


if __name__ == "__main__":
    main()
