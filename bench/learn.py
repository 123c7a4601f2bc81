"""Benchmark of ``stormlane learn performance`` (issue 21): training table, fit and validation.

The case (generated, deterministic, built once and cached, untimed): the demo scenario (seed 0)
from 2025-01-01 for ``DAYS`` days, through the real file ingest, lanes and weather load into a
DuckDB workspace: about 1.0 M clean AIS fixes (590 k in the demo's 30 days; ``--quick``: 12 days).

* ``learn``: the whole learning step as the command runs it
  (:func:`pipelines.learn.learn_performance` on a copy of the workspace): the training table in
  DuckDB (cleaning rules, the weather at each fix), features and segments, the formulas on the
  same segments, 5-fold vessel-grouped cross-validation of both kinds of model and the quantile
  bands, the time split, the final model and the voluntary thresholds, the model file and its row.
* ``one_fit`` (baseline): what any learned model costs at least on the same table: one
  unconstrained ``HistGradientBoostingRegressor`` of the speed ratio fitted once on the same
  segments (read from a cache, no validation, no quantiles). The ratio says what the honest
  validation costs on top of a single fit.

Work counts the fixes in the span. Targets (issue 21): 1 M fixes in <= 60 s on 2 cores, peak
<= 3 GB.
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: the project's packages, not bench/*.py, on the path
    import sys
    from pathlib import Path

    _here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _here]
    sys.path.insert(0, str(_here.parent))

from pathlib import Path

from bench._harness import BATCH, Group, Measure, Side, Target, script_main, source_stamp

DAYS = 51.0  # about 1.0 M clean fixes (30 days: 590 k)
START = "2025-01-01T00:00Z"


def prepare(folder: str, days: float) -> dict:
    """The workspace (scenario -> ingest -> lanes -> weather) and the segments, built once."""
    import shutil

    folder = Path(folder)
    db = folder / "ws.duckdb"
    if not (folder / "done").exists():
        from pipelines.ingest import ingest_paths
        from pipelines.lanes import run_lanes
        from pipelines.scenario import build_scenario
        from pipelines.weather import load_weather_paths

        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
        build_scenario(folder, seed=0, start=START, days=days)
        ingest_paths([folder / "ais"], db)
        run_lanes(db)
        load_weather_paths(folder / "weather", db)
        shutil.rmtree(folder / "ais")
        _segments(db, folder / "segments.parquet")
        (folder / "done").write_text("ok")
    import duckdb

    with duckdb.connect(str(db), read_only=True) as con:
        n = con.execute("SELECT count(*) FROM ais_positions").fetchone()[0]
    return {"fixes": int(n), "days": days}


def _segments(db: Path, out: Path) -> None:
    from pipelines.learn import ship_particulars
    from pipelines.storage import open_workspace
    from pipelines.storage.training import training_table
    from pipelines.storage.weather import get_grid
    from performance.features import prepare as features

    with open_workspace(db, read_only=True) as ws:
        table, _ = training_table(ws, get_grid(ws))
    ships = ship_particulars(table)
    _, seg, _ = features(table, ships[["mmsi", "length_m", "beam_m", "draught_m"]])
    seg.to_parquet(out)


def setup_learn(folder: str) -> dict:
    """A fresh copy of the workspace (the run writes its model into it), in the cache folder's
    ``run/``, replaced by the next run (a temporary folder per run was left behind: 112 MB each)."""
    import shutil

    run = Path(folder) / "run"
    shutil.rmtree(run, ignore_errors=True)
    run.mkdir()
    shutil.copy(Path(folder) / "ws.duckdb", run / "ws.duckdb")
    return {"db": run / "ws.duckdb"}


def run_learn(st: dict) -> dict:
    from pipelines.learn import LearnRequest, learn_performance

    s = learn_performance(LearnRequest(db=st["db"], name="bench"))
    return {"work": int(s["table"]["fixes_in_span"]), "segments": s["segments"], "timings_s": s["timings_s"],
            "mae_kn": round(s["grouped_cv"]["learned_mae_kn"], 4), "beats_formulas": s["beats_formulas"]}


def setup_fit(folder: str) -> dict:
    import duckdb
    import pandas as pd

    with duckdb.connect(str(Path(folder) / "ws.duckdb"), read_only=True) as con:
        n = con.execute("SELECT count(*) FROM ais_positions").fetchone()[0]
    return {"seg": pd.read_parquet(Path(folder) / "segments.parquet"), "fixes": int(n)}


def run_fit(st: dict) -> dict:
    """One unconstrained gradient-boosted fit of the ratio on every segment, one thread."""
    from sklearn.ensemble import HistGradientBoostingRegressor
    from threadpoolctl import threadpool_limits

    from performance.features import feature_matrix
    from performance.fit import FitSettings

    s = FitSettings()
    seg = st["seg"]
    with threadpool_limits(limits=1):
        HistGradientBoostingRegressor(max_iter=s.max_iter, learning_rate=s.learning_rate, max_leaf_nodes=s.max_leaf_nodes,
                                      min_samples_leaf=s.min_samples_leaf, early_stopping=False,
                                      random_state=0).fit(feature_matrix(seg), seg["speed_ratio"].to_numpy(float))
    return {"work": st["fixes"], "segments": int(len(seg))}


def build(cfg):
    here = "bench.learn"
    days = 12.0 if cfg.quick else DAYS
    folder = str(Path(cfg.cache_dir) / f"learn-{days:g}d-{source_stamp('scenario', 'pipelines/storage', 'performance')}")
    g = Group(
        "learn", f"the demo scenario over {days:g} days (about {days / 30 * 590:.0f} k clean fixes), learned end to end",
        prepare=f"{here}:prepare", prepare_kwargs={"folder": folder, "days": days},
        sides=[Side("learn", "learn performance: table, features, formulas, grouped CV, time split, final model, "
                    "voluntary thresholds, model file", setup=f"{here}:setup_learn", kwargs={"folder": folder},
                    run=f"{here}:run_learn", work="fixes in the span", **BATCH),
               Side("one_fit", "one unconstrained HistGradientBoostingRegressor on the same segments (no validation)",
                    setup=f"{here}:setup_fit", kwargs={"folder": folder}, run=f"{here}:run_fit", ours=False,
                    work="fixes in the span", **BATCH)],
        measures=[Measure("learn", "learning a performance model from AIS x weather", "learn", "one_fit",
                          relation="not the same output: one fit on segments already built, against the table, 27 fits "
                                   "of the validation and the final model",
                          targets=[Target("<= 60 s (cold)", "cold.wall_s", "<=", 60.0, "s", "issue 21"),
                                   Target("<= 3 GB peak (cold)", "cold.peak_mb", "<=", 3000.0, "MB", "issue 21")])])
    notes = ["The workspace is built once (scenario, ingest, lanes, weather load) and cached, untimed; each run of "
             "`learn` copies it first (untimed setup). Learning uses one OpenMP thread (pipelines/learn.py says why)."]
    return [g], notes


if __name__ == "__main__":
    script_main("bench/learn.py", build)
