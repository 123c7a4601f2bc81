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
