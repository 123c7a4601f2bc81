"""Lanes fan out by origin-destination pair (issue 7 item 5): Dask task runner == sequential run.

The workspace holds the demo scenario's positions (seed 0, 30 days; the fixes its ships reported,
as ``tests/test_lanes_demo.py`` builds them) ingested through the real ingest. The sequential
reference is ``run_lanes`` (the default ``stormlane lanes`` path: no Prefect, every partition in
this process); the scale-out run is the Prefect lanes flow with one task per partition on a
2-worker Dask cluster of separate processes (``dask scheduler`` + ``dask worker``, the
``dask_address`` fixture). Both write the workspace tables, which must be identical.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

TABLES = ("ports", "voyages", "lanes", "lane_centroids", "lane_voyages")


def _tables(db) -> dict:
    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import (
        read_lane_centroids,
        read_lane_voyages,
        read_lanes,
        read_last_run,
        read_ports,
        read_voyages,
    )

    with open_workspace(db) as ws:
        out = {"ports": read_ports(ws), "voyages": read_voyages(ws), "lanes": read_lanes(ws),
               "lane_centroids": read_lane_centroids(ws), "lane_voyages": read_lane_voyages(ws)}
        last = read_last_run(ws)
    out["counts"] = {k: last[k] for k in ("n_positions", "ports", "voyages", "lanes", "noise_points")}
    return out


@pytest.fixture(scope="module")
def demo_workspace(tmp_path_factory):
    from scenario.generator import ScenarioSettings, generate_scenario
    from pipelines.demo import DEMO_DAYS, DEMO_SEED
    from pipelines.ingest import ingest_paths
    from pipelines.scenario import load_scenario_spec

    sc = generate_scenario(load_scenario_spec(), ScenarioSettings(seed=DEMO_SEED, start_utc=pd.Timestamp("2025-01-01T00:00Z"),
                                                                  days=DEMO_DAYS))
    fixes = sc.fixes[sc.fixes["received"]]
    nan = np.full(len(fixes), np.nan)
    positions = pd.DataFrame({
        "mmsi": fixes["mmsi"].to_numpy(dtype=np.int64),
        "time_utc": pd.to_datetime(fixes["time_s"].to_numpy(), unit="s", utc=True),
        "lat_deg": fixes["lat_deg"].to_numpy(dtype=float), "lon_deg": fixes["lon_deg"].to_numpy(dtype=float),
        "sog_kn": fixes["sog_kn"].to_numpy(dtype=float), "cog_deg": nan, "heading_deg": nan, "nav_status": nan,
    })
    tmp = tmp_path_factory.mktemp("lanes_scaleout")
    path = tmp / "demo_positions.parquet"
    positions.to_parquet(path)
    db = tmp / "ws.duckdb"
    assert ingest_paths([path], db)["loaded"] == len(positions)
    return db


@pytest.mark.slow
def test_lanes_on_a_two_worker_dask_cluster_equal_the_sequential_run(demo_workspace, prefect_harness, dask_address):
    from distributed import Client, get_task_stream

    from pipelines.lanes import LanesSettings, flow_with_runner, run_lanes

    db = demo_workspace
    seq = run_lanes(db)
    expected = _tables(db)
    # the demo has many port pairs (issue 3: at least 12 sailed pairs), so the fan-out is real
    assert expected["counts"]["lanes"] >= 12 and seq["details"]["resampled_points"] > 0

    with Client(dask_address) as client, get_task_stream(client) as stream:
        out = flow_with_runner(f"dask:{dask_address}")(db=str(db), settings=LanesSettings())
    workers = {t["worker"] for t in stream.data}

    got = _tables(db)
    assert out["run_id"] == seq["run_id"] + 1  # the flow really wrote its own result
    for name in TABLES:
        assert len(got[name]) == len(expected[name]) > 0, name
        pd.testing.assert_frame_equal(got[name], expected[name], check_exact=True, obj=name)
    assert got["counts"] == expected["counts"]
    assert {k: out[k] for k in ("ports", "voyages", "lanes", "noise_points")} == \
        {k: seq[k] for k in ("ports", "voyages", "lanes", "noise_points")}
    drop = ("timings", "partition_tasks")
    assert {k: v for k, v in out["details"].items() if k not in drop} == {k: v for k, v in seq["details"].items() if k != "timings"}
    # one task per O-D pair of the stored voyages, plus one for the voyages with an unknown end,
    # each one Dask task, spread over both worker processes
    v = expected["voyages"]
    both = v["origin_port_id"].notna() & v["dest_port_id"].notna()
    n_parts = len(v[both].groupby(["origin_port_id", "dest_port_id"])) + int((~both).any())
    assert out["details"]["partition_tasks"] == n_parts == len(stream.data)
    assert len(workers) == 2, workers


@pytest.mark.slow
def test_lanes_buckets_spread_over_the_cluster_equal_the_sequential_run(demo_workspace, prefect_harness, dask_address,
                                                                        monkeypatch):
    """Issue 23: with more than one MMSI bucket the flow runs each bucket's two passes (clean +
    stops; clean + voyages + resampling) as tasks on the workers, which read the positions
    dataset; only the ports are detected in the calling process. The tables are the sequential
    run's."""
    from distributed import Client, get_task_stream

    import pipelines.lanes as lanes_mod
    from pipelines.lanes import LanesSettings, flow_with_runner, plan_buckets, run_lanes

    db = demo_workspace
    seq = run_lanes(db)
    expected = _tables(db)
    rows = expected["counts"]["n_positions"] // 5
    monkeypatch.setattr(lanes_mod, "BUCKET_ROWS", rows)
    n_buckets = len(plan_buckets(db).buckets)
    assert n_buckets >= 5
    with Client(dask_address) as client, get_task_stream(client) as stream:
        out = flow_with_runner(f"dask:{dask_address}")(db=str(db), settings=LanesSettings())
    got = _tables(db)
    for name in TABLES:
        pd.testing.assert_frame_equal(got[name], expected[name], check_exact=True, obj=name)
    assert got["counts"] == expected["counts"]
    drop = ("timings", "partition_tasks")
    assert {k: v for k, v in out["details"].items() if k not in drop} == {k: v for k, v in seq["details"].items() if k != "timings"}
    assert len(stream.data) == out["details"]["partition_tasks"] + 2 * n_buckets  # both passes of every bucket
    assert len({t["worker"] for t in stream.data}) == 2


def test_a_bucket_read_from_the_positions_dataset_equals_the_workspace_read(demo_workspace):
    from lanes.chain import POSITION_COLUMNS
    from pipelines.lanes import mmsi_buckets, plan_buckets
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import positions_per_mmsi, read_positions

    with open_workspace(demo_workspace) as ws:
        per = positions_per_mmsi(ws)
        buckets = mmsi_buckets(per, int(per["n"].sum()) // 4)
        reader = plan_buckets(demo_workspace, int(per["n"].sum()) // 4)
        assert list(reader.buckets) == buckets and len(buckets) >= 4
        for k, rng in enumerate(buckets):
            want = read_positions(ws, mmsi_range=rng, columns=["mmsi", *POSITION_COLUMNS])
            got = reader(k)
            assert len(got) > 1000
            pd.testing.assert_frame_equal(got, want, check_exact=True)


def test_a_positions_dataset_missing_a_part_is_refused_not_read_as_less_traffic(demo_workspace, tmp_path):
    """A part of the dataset removed after the plan: the buckets read fewer positions than the
    workspace holds, and the flow's check names both counts instead of building lanes from them."""
    import shutil

    from lanes.chain import prepare_chain_in_buckets
    from pipelines.lanes import LanesInputError, LanesSettings, load_port_lists, plan_buckets
    from pipelines.storage.ais import positions_root

    params = LanesSettings().chain_params()
    reader = plan_buckets(demo_workspace)
    whole = prepare_chain_in_buckets(reader, len(reader.buckets), load_port_lists(demo_workspace), params)
    reader.check_read(whole.n_positions)  # all read: no error
    assert whole.n_positions == reader.n_rows > 100_000
    copy = tmp_path / "positions"
    shutil.copytree(positions_root(demo_workspace), copy)
    parts = sorted(copy.glob("day=*/file-*.parquet"))
    parts[len(parts) // 2].unlink()
    partial = type(reader)(str(copy / "day=*" / "file-*.parquet"), reader.buckets, n_rows=reader.n_rows)
    less = prepare_chain_in_buckets(partial, len(partial.buckets), load_port_lists(demo_workspace), params)
    with pytest.raises(LanesInputError, match=f"gave {less.n_positions:,} positions where the workspace holds "
                                              f"{reader.n_rows:,}"):
        partial.check_read(less.n_positions)


def test_the_lanes_flow_refuses_a_dataset_that_lost_a_part(demo_workspace, prefect_harness, monkeypatch):
    import pipelines.lanes as lanes_mod
    import pipelines.storage.ais as ais_store
    from pipelines.lanes import LanesInputError, flow_with_runner
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import positions_root

    sync = ais_store.sync_positions_parquet
    monkeypatch.setattr(lanes_mod, "BUCKET_ROWS", 200_000)  # several buckets: their passes are tasks
    monkeypatch.setattr(ais_store, "sync_positions_parquet", lambda ws: {})  # as if the part went after the plan
    part = sorted(positions_root(demo_workspace).glob("day=*/file-*.parquet"))[3]
    part.unlink()
    try:
        with pytest.raises(LanesInputError, match="positions where the workspace holds"):
            flow_with_runner("sequential")(db=str(demo_workspace))
    finally:
        with open_workspace(demo_workspace) as ws:
            sync(ws)  # the part written again from the workspace, for the other tests
    assert part.exists()


def test_a_bucket_read_that_spills_keeps_its_spill_files_to_itself(demo_workspace, tmp_path, monkeypatch):
    """A sort beyond the memory limit spills to a folder of the call's own, not to ``.tmp`` in
    the working directory (shared by every worker process started there: at 108 M rows two
    workers overwrote each other's spill files)."""
    from lanes.chain import POSITION_COLUMNS
    from pipelines.lanes import plan_buckets
    from pipelines.storage.ais import read_positions_parquet

    reader = plan_buckets(demo_workspace)
    whole = reader(0)
    assert len(whole) > 500_000  # its sort needs more than the 32 MB below
    monkeypatch.chdir(tmp_path)
    (tmp_path / ".tmp").write_text("not a folder: a spill here fails")
    spilled = read_positions_parquet(reader.glob, reader.buckets[0], ("mmsi", *POSITION_COLUMNS), memory_limit_mb=32)
    pd.testing.assert_frame_equal(spilled, whole, check_exact=True)


def test_merge_is_independent_of_partition_completion_order():
    """Partitions merged in any order (as tasks finish on a cluster) give extract_lanes' result."""
    from lanes.extract import LaneParams, extract_lanes, extract_lanes_for_pair, merge_lane_results, partition_rows

    rng = np.random.default_rng(7)
    frames = []
    # three O-D pairs (1->2 eastbound, 2->1 westbound, 3->1) and a transit voyage set, 4 voyages each
    for (o, d, lat0, course) in ((1, 2, 40.0, 90.0), (2, 1, 40.05, 270.0), (3, 1, 41.0, 180.0), (0, 2, 39.0, 90.0)):
        for v in range(4):
            n = 60
            t = pd.Timestamp("2025-01-01T00:00Z") + pd.Timedelta(hours=v * 7) + pd.to_timedelta(np.arange(n) * 300, unit="s")
            step = 12.0 * 300 / 3600 / 60  # 12 kn in degrees of arc per step
            along = np.arange(n) * step
            lat = lat0 + (along * np.cos(np.radians(course))) + rng.normal(0, 0.002, n)
            lon = 3.0 + along * np.sin(np.radians(course)) / np.cos(np.radians(lat0)) + rng.normal(0, 0.002, n)
            frames.append(pd.DataFrame({
                "voyage": f"{o}-{d}-{v}", "track": 100 + v, "origin_port_id": o, "dest_port_id": d, "time_utc": t,
                "lat_deg": lat, "lon_deg": lon, "speed_kn": 12.0 + rng.normal(0, 0.3, n), "course_deg": course, "run": 0,
            }))
    points = pd.concat(frames, ignore_index=True).sample(frac=1.0, random_state=3).reset_index(drop=True)
    params = LaneParams(min_voyages=3)
    whole = extract_lanes(points, params)
    parts = partition_rows(points, params.include_loops)
    assert [k for k, _ in parts] == [(0, 0), (1, 2), (2, 1), (3, 1)]
    assert sorted(np.concatenate([r for _, r in parts]).tolist()) == list(range(len(points)))
    done = [(key, rows, extract_lanes_for_pair(points.iloc[rows], params, key)) for key, rows in parts]
    merged = merge_lane_results(len(points), done[::-1])
    assert len(whole.lanes) == 4  # one lane per partition: the hand-built traffic has one stream each
    assert sorted(whole.lanes["lane_id"]) == ["1-2-1", "2-1-1", "3-1-1", "T-1"]
    pd.testing.assert_frame_equal(merged.lanes, whole.lanes, check_exact=True)
    pd.testing.assert_frame_equal(merged.centroids, whole.centroids, check_exact=True)
    assert list(merged.point_lane) == list(whole.point_lane)
    assert (merged.n_noise, merged.n_slow, merged.partitions) == (whole.n_noise, whole.n_slow, whole.partitions)
    # each point carries the lane of its own partition
    lane_pair = dict(zip(whole.lanes["lane_id"], zip(whole.lanes["origin_port_id"], whole.lanes["dest_port_id"])))
    for lane, o, d in zip(merged.point_lane, points["origin_port_id"], points["dest_port_id"]):
        if lane is not None:
            assert lane_pair[lane] == ((o, d) if o > 0 else (0, 0))


def test_a_bad_task_runner_spec_is_one_line_and_exit_code_2(tmp_path, capsys):
    from pipelines.cli import main

    from pipelines.storage import open_workspace

    db = tmp_path / "empty.duckdb"  # lanes reads a workspace: it must exist
    open_workspace(db).close()
    before = (db.stat().st_size, db.stat().st_mtime_ns)
    for spec in ("threads", "dask:", "ray:tcp://x:1"):
        capsys.readouterr()
        with pytest.raises(SystemExit) as exc:
            main(["lanes", "--db", str(db), "--task-runner", spec])
        err = capsys.readouterr().err.strip()
        assert exc.value.code == 2, spec
        assert "\n" not in err and "--task-runner" in err and "sequential, dask or dask:ADDRESS" in err, err
        assert (db.stat().st_size, db.stat().st_mtime_ns) == before  # rejected before anything started


def test_the_chain_read_in_mmsi_buckets_equals_one_read(demo_workspace):
    """Steps 1-5 on the workspace read in buckets of whole tracks (5 or more) give the stops,
    ports, voyages and resampled points of the single read, in the same order."""
    from pipelines.lanes import LanesSettings, load_port_lists, mmsi_buckets, prepare_from_workspace
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import positions_per_mmsi

    params = LanesSettings().chain_params()
    known = load_port_lists(demo_workspace)
    with open_workspace(demo_workspace) as ws:
        per = positions_per_mmsi(ws)
    rows = int(per["n"].sum()) // 5
    assert len(mmsi_buckets(per, rows)) >= 5 and len(mmsi_buckets(per, 10 * rows)) == 1
    one = prepare_from_workspace(demo_workspace, known, params, bucket_rows=10 * rows)
    many = prepare_from_workspace(demo_workspace, known, params, bucket_rows=rows)
    local = ["first_row", "last_row"]  # each bucket's own row numbers
    assert (many.n_positions, many.n_jumps) == (one.n_positions, one.n_jumps)
    pd.testing.assert_frame_equal(many.ports, one.ports, check_exact=True)
    pd.testing.assert_frame_equal(many.stops.drop(columns=local), one.stops.drop(columns=local), check_exact=True)
    pd.testing.assert_frame_equal(many.voyages.drop(columns=local), one.voyages.drop(columns=local), check_exact=True)
    pd.testing.assert_frame_equal(many.points, one.points, check_exact=True)
    assert len(one.points) > 10_000 and len(one.voyages) > 100


def test_partition_files_give_the_lanes_of_the_points_held_in_memory(demo_workspace, tmp_path):
    """Issue 23: pass 2 writes each O-D partition's resampled points to its own files (bucket by
    bucket) and each partition reads only its own; the rows, their order and the lanes, centroids
    and lane-voyage rows are those of the chain holding every point in memory."""
    from lanes.chain import finish_chain
    from lanes.extract import extract_lanes, merge_lane_results, merge_lane_voyage_tables, partition_rows
    from pipelines.lanes import LanesSettings, load_port_lists, prepare_from_workspace
    from pipelines.lanes_partitions import partition_lanes, read_partition, stored_keys
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import positions_per_mmsi

    params = LanesSettings().chain_params()
    known = load_port_lists(demo_workspace)
    with open_workspace(demo_workspace) as ws:
        rows = int(positions_per_mmsi(ws)["n"].sum()) // 4
    mem = prepare_from_workspace(demo_workspace, known, params, bucket_rows=rows)
    whole = finish_chain(mem, extract_lanes(mem.points, params.lanes), 0.0)
    folder = tmp_path / "points"
    disk = prepare_from_workspace(demo_workspace, known, params, bucket_rows=rows, points_folder=str(folder))
    assert disk.points is None and disk.n_points == len(mem.points) > 10_000
    parts_mem = partition_rows(mem.points, params.lanes.include_loops)
    assert stored_keys(folder) == [k for k, _ in parts_mem]
    assert max(len(list((folder / f"{k[0]}_{k[1]}").iterdir())) for k, _ in parts_mem) >= 4  # one file per bucket
    for key, r in parts_mem:
        pd.testing.assert_frame_equal(read_partition(folder, key), mem.points.iloc[r].reset_index(drop=True),
                                      check_exact=True)
    parts = [(key, partition_lanes(str(folder), params.lanes, key)) for key in stored_keys(folder)]
    got = finish_chain(disk, merge_lane_results(None, [(k, None, res) for k, (res, _) in parts[::-1]]), 0.0,
                       merge_lane_voyage_tables([lv for _, (_, lv) in parts[::-1]]))
    assert len(whole.lanes.lanes) >= 12
    pd.testing.assert_frame_equal(got.lanes.lanes, whole.lanes.lanes, check_exact=True)
    pd.testing.assert_frame_equal(got.lanes.centroids, whole.lanes.centroids, check_exact=True)
    pd.testing.assert_frame_equal(got.lane_voyages, whole.lane_voyages, check_exact=True)
    drop = ("timings",)
    assert {k: v for k, v in got.summary.items() if k not in drop} == \
        {k: v for k, v in whole.summary.items() if k not in drop}
