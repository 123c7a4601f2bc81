"""bench/scale.py's stored entries: a run of some stages replaces only those stages' rows."""

from __future__ import annotations

from bench.scale import merge_entry


def _entry(rows, stages, **kw):
    return {"rows": rows, "date_utc": kw.pop("date", "d0"), "stages": stages, **kw}


def test_a_partial_run_replaces_its_own_rows_and_keeps_the_others():
    old = _entry(100, [{"stage": "generate", "side": "2 procs", "wall_s": 2738.0},
                       {"stage": "ingest", "side": "sequential", "wall_s": 809.5},
                       {"stage": "nightly", "side": "sequential", "wall_s": 6.2, "night_utc": "2025-12-28"}])
    new = _entry(100, [{"stage": "generate", "side": "2 procs", "wall_s": 0.8, "reused": True},
                       {"stage": "nightly", "side": "sequential", "wall_s": 90.0, "night_utc": "2025-01-15"},
                       {"stage": "nightly", "side": "cluster", "wall_s": 70.0, "night_utc": "2025-01-15"}], date="d1")
    got = merge_entry(old, new)
    assert [(r["stage"], r["side"], r["wall_s"]) for r in got["stages"]] == [
        ("generate", "2 procs", 2738.0), ("ingest", "sequential", 809.5), ("nightly", "sequential", 6.2),
        ("nightly", "sequential", 90.0), ("nightly", "cluster", 70.0)]
    assert got["date_utc"] == "d1"
    rerun = merge_entry(got, _entry(100, [{"stage": "ingest", "side": "sequential", "wall_s": 700.0}]))
    assert [r["wall_s"] for r in rerun["stages"]] == [2738.0, 6.2, 90.0, 70.0, 700.0]


def test_another_scenario_size_starts_a_new_entry():
    old = _entry(100, [{"stage": "ingest", "side": "sequential", "wall_s": 1.0}])
    new = _entry(101, [{"stage": "lanes", "side": "sequential", "wall_s": 2.0}])
    assert merge_entry(old, new) == new and merge_entry(None, new) == new


def test_warm_inputs_reads_every_gzip_file_once(tmp_path):
    # Every daily file's bytes, and nothing else of the folder, pass through the read.
    from bench.scale import warm_inputs

    sizes = {"aisdk-2025-01-01.csv.gz": 3, "aisdk-2025-01-02.csv.gz": (8 << 20) + 5}
    for name, n in sizes.items():
        (tmp_path / name).write_bytes(b"x" * n)
    (tmp_path / "scenario.json").write_bytes(b"{}" * 100)
    n_bytes, seconds = warm_inputs(tmp_path)
    assert n_bytes == sum(sizes.values()) and seconds >= 0


def test_tables_differ_compares_rows_not_their_order_or_when_they_were_written(tmp_path):
    import duckdb

    from bench.scale import tables_differ

    def make(path, rows, loaded_at):
        con = duckdb.connect(str(path))
        con.execute("CREATE TABLE ais_files (file_id INTEGER, path VARCHAR, loaded_at TIMESTAMP)")
        con.executemany("INSERT INTO ais_files VALUES (?, ?, ?)", [(*r, loaded_at) for r in rows])
        con.close()

    make(tmp_path / "a.duckdb", [(1, "x"), (2, "y")], "2025-01-01")
    make(tmp_path / "b.duckdb", [(2, "y"), (1, "x")], "2026-01-01")  # other order, other load time
    make(tmp_path / "c.duckdb", [(1, "x"), (2, "z")], "2025-01-01")
    make(tmp_path / "d.duckdb", [(1, "x")], "2025-01-01")
    assert tables_differ(tmp_path / "a.duckdb", tmp_path / "b.duckdb", ["ais_files"]) == []
    assert tables_differ(tmp_path / "a.duckdb", tmp_path / "c.duckdb", ["ais_files"]) == ["ais_files"]
    assert tables_differ(tmp_path / "a.duckdb", tmp_path / "d.duckdb", ["ais_files"]) == ["ais_files"]


def _task(key, worker, start, stop):
    return {"key": key, "worker": worker, "startstops": [{"action": "compute", "start": start, "stop": stop}]}


def test_list_scheduling_deals_tasks_in_order_to_the_first_free_worker():
    from bench._scale_projection import list_schedule

    # 2 workers: [4] [3] -> 3 goes after 3 (free at 3): [4] [3, 2] -> 1 after 4: [4, 1] [3, 2] = 5
    assert list_schedule([4, 3, 2, 1], 2) == 5
    assert list_schedule([4, 3, 2, 1], 4) == 4 and list_schedule([4, 3, 2, 1], 1) == 10
    assert list_schedule([4, 3, 2, 1], 4, warmup_s=0.5) == 4.5


def test_a_projection_from_two_workers_gives_back_the_measured_wall_time():
    """Hand-made stream: 2 workers, phase a (4 tasks) then phase b (2 tasks); each worker's first
    task 1 s longer (its imports); the stage took 11 s, 4 s of them the calling process's own."""
    from bench._scale_projection import project

    stream = [_task("a-1", "w1", 0, 3), _task("a-2", "w2", 0, 3), _task("a-3", "w1", 3, 5), _task("a-4", "w2", 3, 5),
              _task("b-1", "w1", 6, 8), _task("b-2", "w2", 6, 8)]
    got = project(11.0, stream, workers=(1, 2, 4))
    assert got["warmup_s"] == 1.0 and got["caller_s"] == 4.0  # 11 - the spans 5 and 2
    assert got["phases"]["a"] == {"tasks": 4, "sum_s": 8.0, "max_s": 2.0, "span_s": 5.0}
    assert got["projected_wall_s"][2] == 11.0  # the measured wall time again
    # 4 workers: phase a = warm-up 1 + one task of 2 each; phase b = 2 (warm by then); + 4
    assert got["projected_wall_s"][4] == 3.0 + 2.0 + 4.0
    assert got["projected_wall_s"][1] == (1 + 8) + 4 + 4.0
