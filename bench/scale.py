"""Scale benchmark (issue 23 item 5): where the time, the memory and the disk go at N AIS rows.

``python bench/scale.py --rows N`` generates a fleet year-scale scenario of about N rows
(``stormlane scenario --vessels V --days D``: gzip daily files in the DMA layout), then runs
every stage twice, side by side in the same run, interleaved (sequential, then cluster, stage by
stage, so both see the same machine load):

* ``ingest``: ``stormlane ingest-ais DIR/ais --db NEW`` (sequential), and the same with
  ``--task-runner dask:ADDRESS`` (file staging on the workers, commits in order here); before them
  the baseline ``raw read``: DuckDB's own ``read_csv`` of the same gzip files into a new database
  file (:data:`RAW_READ_SQL`: no cleaning, no quarantine, no Parquet), and the ingest's rows/s as a
  multiple of it; before each side the gzip files are read once (:func:`warm_inputs`), so that
  every side reads them from the page cache: warm against warm (a first side reading from the
  disk for the others would make the ratio a measure of the cache);
* ``lanes``: ``stormlane lanes`` on that workspace, and the Prefect lanes flow with the
  origin-destination partitions on the workers;
* ``nightly``: one night (``stormlane nightly``) at the end of the AIS period, or at
  ``--night-at`` (e.g. a storm of the demo's weather: ``2025-01-15T00:00Z``), with the generated
  weather of the two days before it, sequentially and with the per-lane work on the workers
  (on the sequential side's workspace when the cluster side has none of its own).

The cluster is a real one: ``dask scheduler`` and ``dask worker --nworkers W --nthreads 1`` as
separate processes (:mod:`pipelines.dask_processes`), started fresh for each stage so that the
workers' peak memory is that stage's; Prefect's temporary API server is started before the
timed run too (a no-op flow), so neither start-up is counted in a stage's wall time. Every stage runs in a fresh process of the benchmark
harness (:func:`bench._harness._child`: ``getrusage`` peak RSS, wall and CPU seconds, load
average before and after). Printed per stage and runner: rows, wall seconds, rows/s, CPU
seconds of the stage's process and of the Dask workers (``wrk cpu``: since the fresh cluster
started, its imports included), peak RSS of that process, of its process pools (the
generator's) and of the largest and all Dask workers, and the disk written (workspace file +
Parquet dataset beside it, against the gzip input). The figures go to
``bench/results-scale.json`` (one entry per ``--rows``), kept apart from ``bench/results.json``
(``make bench`` does not run this script: one 100 M-row run takes hours on 2 cores). After the
cluster side of a stage with a workspace of its own, the stage's tables are compared with the
sequential side's (:func:`tables_differ`: row counts and sums of row hashes) and the verdict is
printed and recorded (``tables_as_sequential``).
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: import `bench` from the repository root
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import contextlib
import json
import os
import resource
import time
from pathlib import Path

from bench._harness import ROOT, Config, _child

#: AIS rows per ship-day of the fleet scenario (measured: 73,684 rows for 20 ships x 4 days,
#: seed 5): N rows are about N / (vessels x this) days.
ROWS_PER_SHIP_DAY = 921
START_UTC = "2025-01-01T00:00Z"
RESULTS = ROOT / "bench" / "results-scale.json"


def _peaks_mb() -> dict:
    """Peak RSS of this process and of its largest reaped child (a process pool's worker)."""
    to_mb = 1024 / 1e6
    return {"peak_mb_self": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * to_mb,
            "peak_mb_children": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * to_mb}


def _tree_bytes(path: Path) -> int:
    path = Path(path)
    if path.is_file():
        return path.stat().st_size
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.exists() else 0


# ------------------------------------------------------------------ stages (run in fresh processes)
def generate(folder: str, vessels: int, days: float, seed: int, workers: int) -> dict:
    from pipelines.scenario_fleet import build_fleet_scenario

    reused = (Path(folder) / "scenario.json").exists()
    if not reused:
        build_fleet_scenario(Path(folder), vessels=vessels, seed=seed, start=START_UTC, days=days, workers=workers)
    truth = json.loads((Path(folder) / "scenario.json").read_text())
    return {"work": int(truth["expected_ingest"]["position_records"]), "gzip_bytes": _tree_bytes(Path(folder) / "ais"),
            "reused": reused, **_peaks_mb()}


def stage_setup(runner: str, workdir: str, **kwargs) -> dict:
    """Untimed: a fresh cluster of separate processes for a ``cluster`` run (stopped at exit)."""
    import atexit
    import contextlib

    os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")
    state = {"runner": "sequential", **kwargs}
    if runner == "cluster":
        from pipelines.dask_processes import dask_cluster_processes

        stack = contextlib.ExitStack()
        address = stack.enter_context(dask_cluster_processes(Path(workdir) / "dask", n_workers=int(kwargs["workers"])))
        atexit.register(stack.close)
        state.update(runner=f"dask:{address}", address=address)
    if runner == "cluster" or kwargs.get("stage") == "nightly":
        _start_prefect()
    return state


def _start_prefect() -> None:
    """Untimed: a no-op flow, so that Prefect's temporary API server (started once per process,
    about a minute on 2 loaded cores) is not counted in the stage's time."""
    from prefect import flow

    flow(name="scale-bench-warmup")(lambda: None)()


def _worker_peaks(st: dict) -> dict:
    if "address" not in st:
        return {}
    from distributed import Client

    def peak():
        import resource as r

        u = r.getrusage(r.RUSAGE_SELF)
        return u.ru_maxrss * 1024 / 1e6, u.ru_utime + u.ru_stime

    with Client(st["address"]) as client:
        per = list(client.run(peak).values())
    # The workers' CPU since they started (a fresh cluster per stage): not in the stage's own
    # process CPU, which counts only the calling process.
    return {"peak_mb_worker_max": max(p for p, _ in per), "peak_mb_workers_sum": sum(p for p, _ in per),
            "cpu_s_workers": sum(c for _, c in per)}


def _cli(argv: list[str], runner: str) -> dict:
    import contextlib
    import io

    from pipelines.cli import main

    if runner != "sequential":
        argv = [*argv, "--task-runner", runner]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main([*argv, "--json"])
    if rc not in (None, 0):
        raise RuntimeError(f"stormlane {' '.join(argv)}: exit {rc}")
    return json.loads(buf.getvalue())


def ingest(st: dict) -> dict:
    db = Path(st["db"])
    out = _cli(["ingest-ais", st["ais"], "--db", str(db)], st["runner"])
    parquet = db.parent / f"{db.stem}.parquet"
    return {"work": int(out["read"]), "loaded": int(out["loaded"]), "disk_db_bytes": _tree_bytes(db),
            "disk_parquet_bytes": _tree_bytes(parquet), **_peaks_mb(), **_worker_peaks(st)}


#: DuckDB's own CSV reader, the ingest's raw baseline (as bench/ingest.py's): every daily gzip file read into one
#: table with the dialect given (the scenario's dirty rows skipped, not typed or kept), no cleaning, no Parquet.
RAW_READ_SQL = ("CREATE TABLE raw AS SELECT * FROM read_csv(?, delim = ',', header = true, ignore_errors = true, "
                "null_padding = true, strict_mode = false)")


def warm_inputs(folder) -> tuple[int, float]:
    """Read every gzip file of ``folder`` once, into the page cache: (bytes, seconds)."""
    t0, n = time.perf_counter(), 0
    for p in sorted(Path(folder).glob("*.csv.gz")):
        with open(p, "rb", buffering=0) as fh:
            while block := fh.read(8 << 20):
                n += len(block)
    return n, time.perf_counter() - t0


def ingest_raw(st: dict) -> dict:
    """The baseline of the ingest stage: DuckDB ``read_csv`` of the same gzip files into a new database file."""
    import duckdb

    db = Path(st["db"]).with_name("raw.duckdb")
    db.unlink(missing_ok=True)
    files = sorted(str(p) for p in Path(st["ais"]).glob("*.csv.gz"))
    con = duckdb.connect(str(db))
    try:
        con.execute(RAW_READ_SQL, [files])
        n = int(con.execute("SELECT count(*) FROM raw").fetchone()[0])
    finally:
        con.close()
    size = _tree_bytes(db)
    db.unlink(missing_ok=True)
    return {"work": n, "disk_db_bytes": size, **_peaks_mb()}


def lanes(st: dict) -> dict:
    with _task_times(st) as times:
        out = _cli(["lanes", "--db", st["db"]], st["runner"])
    return {"work": int(st["rows"]), **{k: out[k] for k in ("ports", "voyages", "lanes", "noise_points")},
            **_peaks_mb(), **_worker_peaks(st), **times}


@contextlib.contextmanager
def _task_times(st: dict):
    """On a cluster side: the scheduler's task stream while the stage runs, turned into the
    projection for more workers (:mod:`bench._scale_projection`), added to the yielded dict."""
    out: dict = {}
    if "address" not in st:
        yield out
        return
    from distributed import Client, get_task_stream

    from bench._scale_projection import project

    with Client(st["address"]) as client, get_task_stream(client) as stream:
        t0 = time.perf_counter()
        yield out
        wall = time.perf_counter() - t0
    out["projection"] = project(wall, stream.data)


def nightly(st: dict) -> dict:
    import pandas as pd

    from weather.io.scenario_files import write_scenario_weather
    from weather.scenario import generate_weather
    from pipelines.weather import FORECAST_TAIL_H

    end = pd.Timestamp(st.get("night_at") or json.loads(Path(st["scenario_json"]).read_text())["scenario"]["end_utc"])
    wx = Path(st["weather_dir"])
    if st.get("night_at"):
        wx = wx.with_name(f"weather-{end:%Y%m%dT%H%M}")
    if not (wx / "weather").exists():
        write_scenario_weather(wx, seed=0, weather=generate_weather(0, start=end - pd.Timedelta(days=2),
                                                                     end=end + pd.Timedelta(hours=FORECAST_TAIL_H)))
    out = _cli(["nightly", "--db", st["db"], "--weather", str(wx / "weather"), "--now", end.isoformat(),
                "--out", str(Path(st["db"]).parent / f"night-{st['side']}"), "--max-detail", "3"], st["runner"])
    return {"work": int(out["departures_checked"]), "lanes_checked": int(out["lanes_checked"]),
            "adverse": int(out["adverse"]), "night_utc": end.isoformat(), **{k: out[k] for k in ("reroutes",) if k in out},
            **_peaks_mb(), **_worker_peaks(st)}


#: The tables each stage writes, compared between the sides (count and sum of row hashes).
STAGE_TABLES = {"ingest": ("ais_positions", "ais_quarantine", "vessels", "ais_files", "ais_file_keys"),
                "lanes": ("ports", "voyages", "lane_voyages", "lanes", "lane_centroids"),
                "nightly": ("nightly_departures", "nightly_routes", "nightly_events")}
#: Columns that say when or in which run a row was written, not what it holds.
_WHEN_COLUMNS = {"loaded_at", "run_id", "started_utc", "finished_utc", "created_utc", "built_utc"}


def table_digests(db, tables) -> dict:
    """``{table: (rows, sum of the row hashes)}`` of ``db`` (read-only), when-columns left out."""
    import duckdb

    con = duckdb.connect(str(db), read_only=True)
    try:
        con.execute("SET enable_progress_bar = false")
        out = {}
        for t in tables:
            cols = [r[0] for r in con.execute(f"DESCRIBE {t}").fetchall() if r[0] not in _WHEN_COLUMNS]
            out[t] = con.execute(f"SELECT count(*), sum(hash({', '.join(cols)})::HUGEINT) FROM {t}").fetchone()
        return out
    finally:
        con.close()


def tables_differ(db, reference, tables) -> list[str]:
    """The tables whose rows differ between two workspaces (order aside)."""
    a, b = table_digests(db, tables), table_digests(reference, tables)
    return [t for t in tables if a[t] != b[t]]


# ------------------------------------------------------------------ driver
def _row(stage: str, side: str, rec: dict) -> dict:
    run = (rec.get("runs") or [{}])[0]
    info = run.get("info", {})
    wall = run.get("wall_s")
    row = {"stage": stage, "side": side, "failed": rec.get("failed"), "wall_s": wall, "cpu_s": run.get("cpu_s"),
           "process_peak_mb": rec.get("process_peak_mb"), "load_before": run.get("load_before"),
           "load_after": run.get("load_after"), **info}
    if wall and info.get("work"):
        row["per_s"] = info["work"] / wall
    return row


def _fmt(v, spec="{:,.0f}") -> str:
    return "-" if v is None else spec.format(v)


def print_table(rows: list[dict], gzip_bytes: int) -> None:
    print(f"{'stage':<9}{'side':<12}{'work':>13}{'wall s':>9}{'work/s':>12}{'cpu s':>9}{'wrk cpu':>9}{'peak MB':>9}"
          f"{'pool MB':>9}{'wrk max':>9}{'wrk sum':>9}{'disk MB':>9}{'x gzip':>8}{'load':>6}")
    for r in rows:
        disk = (r.get("disk_db_bytes") or 0) + (r.get("disk_parquet_bytes") or 0)
        print(f"{r['stage']:<9}{r['side']:<12}{_fmt(r.get('work')):>13}{_fmt(r.get('wall_s'), '{:,.1f}'):>9}"
              f"{_fmt(r.get('per_s')):>12}{_fmt(r.get('cpu_s'), '{:,.1f}'):>9}"
              f"{_fmt(r.get('cpu_s_workers'), '{:,.1f}'):>9}{_fmt(r.get('peak_mb_self')):>9}"
              f"{_fmt(r.get('peak_mb_children')):>9}{_fmt(r.get('peak_mb_worker_max')):>9}"
              f"{_fmt(r.get('peak_mb_workers_sum')):>9}{_fmt(disk / 1e6 if disk else None):>9}"
              f"{_fmt(disk / gzip_bytes if disk and gzip_bytes else None, '{:.2f}'):>8}"
              f"{_fmt(r.get('load_before'), '{:.1f}'):>6}" + (f"  FAILED: {r['failed']}" if r.get("failed") else ""))


def run_scale(rows: int, workdir: Path, vessels: int = 300, workers: int = 2, seed: int = 23,
              stages: tuple = ("ingest", "lanes", "nightly"), sides: tuple = ("sequential", "cluster"),
              night_at: str | None = None) -> dict:
    cfg = Config(runs=1, timeout_s=12 * 3600.0)
    days = max(1.0, round(rows / (vessels * ROWS_PER_SHIP_DAY), 2))
    workdir.mkdir(parents=True, exist_ok=True)
    tmp = workdir / "harness"
    tmp.mkdir(exist_ok=True)
    scen = workdir / f"scenario-{vessels}x{days:g}d-s{seed}"
    floor = "" if rows >= vessels * ROWS_PER_SHIP_DAY else f", less than one day of {vessels} ships: about {vessels * ROWS_PER_SHIP_DAY:,} rows; fewer --vessels for fewer"
    cluster = f"{workers}-worker cluster" if "cluster" in sides else "no cluster"
    print(f"scale run: {vessels} ships x {days:g} day{'' if days == 1 else 's'} (target {rows:,} rows{floor}), {cluster}; "
          f"load {os.getloadavg()[0]:.1f}", flush=True)
    gen = _child(cfg, tmp, None, "bench.scale:generate", {"folder": str(scen), "vessels": vessels, "days": days,
                                                           "seed": seed, "workers": workers}, 1, {},
                 call_with_kwargs=True)
    table = [_row("generate", f"{workers} procs", gen)]
    gzip_bytes = int(table[0].get("gzip_bytes") or 0)
    n_rows = int(table[0].get("work") or 0)
    print_table(table, gzip_bytes)
    sides = list(sides)
    for stage in stages:
        # the ingest beside its raw baseline (DuckDB's own reader of the same files), first, in the same run
        for side in (["raw read"] if stage == "ingest" and "sequential" in sides else []) + sides:
            db = workdir / side / "ws.duckdb"
            if stage in ("lanes", "nightly") and side != "sequential" and not db.exists():
                # no workspace of its own (its ingest not run at this size): the sequential side's,
                # whose lanes the run replaces (any side's tables are the same: tested)
                db = workdir / "sequential" / "ws.duckdb"
            db.parent.mkdir(exist_ok=True)
            if stage == "ingest":
                for old in (db, Path(f"{db}.wal")):
                    old.unlink(missing_ok=True)
                import shutil

                shutil.rmtree(db.parent / "ws.parquet", ignore_errors=True)
                n_bytes, warm_s = warm_inputs(scen / "ais")
                print(f"{side}: the {n_bytes / 1e6:,.0f} MB of gzip input read once before it ({warm_s:.1f} s)",
                      flush=True)
            kw = {"runner": side, "workdir": str(workdir / side), "workers": workers, "db": str(db),
                  "ais": str(scen / "ais"), "rows": n_rows, "scenario_json": str(scen / "scenario.json"),
                  "weather_dir": str(workdir / "weather"), "side": side, "stage": stage, "night_at": night_at}
            run = "bench.scale:ingest_raw" if side == "raw read" else f"bench.scale:{stage}"
            rec = _child(cfg, tmp, "bench.scale:stage_setup", run, kw, 1, {})
            table.append({**_row(stage, side, rec), "date_utc": time.strftime("%Y-%m-%dT%H:%MZ", time.gmtime())})
            print_table(table[-1:], gzip_bytes)
            if side != "sequential" and side != "raw read" and db != workdir / "sequential" / "ws.duckdb" \
                    and (workdir / "sequential" / "ws.duckdb").exists() and not rec.get("failed"):
                diff = tables_differ(db, workdir / "sequential" / "ws.duckdb", STAGE_TABLES[stage])
                table[-1]["tables_as_sequential"] = "identical" if not diff else f"DIFFER: {', '.join(diff)}"
                print(f"{stage} {side}: tables {table[-1]['tables_as_sequential']} to the sequential side's "
                      f"({', '.join(STAGE_TABLES[stage])})", flush=True)
    out = {"rows_target": rows, "rows": n_rows, "vessels": vessels, "days": days, "workers": workers,
           "gzip_bytes": gzip_bytes, "cores": os.cpu_count(), "date_utc": time.strftime("%Y-%m-%dT%H:%MZ", time.gmtime()),
           "stages": table}
    print("\nsummary")
    print_table(table, gzip_bytes)
    for r in table:
        if r.get("projection"):
            p = r["projection"]
            walls = ", ".join(f"{w} workers {v:,.0f} s" for w, v in p["projected_wall_s"].items())
            print(f"{r['stage']} {r['side']}: from its task times, projected wall {walls} (calling process "
                  f"{p['caller_s']:,.0f} s, warm-up {p['warmup_s']:.1f} s per worker; bench/_scale_projection.py)")
    raw = next((r for r in table if r["side"] == "raw read" and r.get("per_s")), None)
    for r in table:
        if raw is not None and r["stage"] == "ingest" and r["side"] != "raw read" and r.get("per_s"):
            r["x_raw_read"] = r["per_s"] / raw["per_s"]
            print(f"ingest {r['side']}: {r['x_raw_read']:.2f} x DuckDB's raw read of the same files "
                  f"({r['per_s']:,.0f} against {raw['per_s']:,.0f} rows/s)")
    return out


def main(argv=None) -> dict:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, required=True, help="AIS rows to generate (about)")
    ap.add_argument("--vessels", type=int, default=300)
    ap.add_argument("--workers", type=int, default=2, help="Dask worker processes of the cluster side")
    ap.add_argument("--workdir", type=Path, default=None, help="default: $TMPDIR/stormlane-scale-ROWS")
    ap.add_argument("--stages", default="ingest,lanes,nightly")
    ap.add_argument("--no-cluster", action="store_true", help="the sequential side only")
    ap.add_argument("--sides", default="sequential,cluster", help="the sides to run, in this order")
    ap.add_argument("--no-write", action="store_true", help="do not record in bench/results-scale.json")
    ap.add_argument("--night-at", default=None, help="the night's time (ISO UTC; default: the AIS period's end)")
    a = ap.parse_args(argv)
    import tempfile

    workdir = a.workdir or Path(tempfile.gettempdir()) / f"stormlane-scale-{a.rows}"
    out = run_scale(a.rows, workdir, a.vessels, a.workers, stages=tuple(s for s in a.stages.split(",") if s),
                    sides=("sequential",) if a.no_cluster else tuple(x for x in a.sides.split(",") if x),
                    night_at=a.night_at)
    if not a.no_write:
        prev = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
        prev[str(a.rows)] = merge_entry(prev.get(str(a.rows)), out)
        RESULTS.write_text(json.dumps(prev, indent=1, default=float) + "\n")
    return out


def merge_entry(old: dict | None, new: dict) -> dict:
    """The stored entry of a size after a run of some of its stages: the new rows replace the
    stored rows of the same stage and side (a night at another time is another row); the
    others are kept (a 100 M-row run is made stage by stage, hours apart)."""
    if not old or old.get("rows") != new.get("rows"):
        return new

    def key(r):
        return r["stage"], r["side"], r.get("night_utc")

    ran = {key(r) for r in new["stages"] if not r.get("reused")}  # a scenario found on disk was not generated
    kept = [r for r in old["stages"] if key(r) not in ran]
    fresh = [r for r in new["stages"] if key(r) in ran]
    return {**old, **{k: v for k, v in new.items() if k != "stages"}, "stages": kept + fresh}


if __name__ == "__main__":
    main()
