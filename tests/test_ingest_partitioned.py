"""AIS ingest partitioned by file (issue 7 item 5): staged apart, committed in order == sequential.

The reference is the sequential ingest (``ingest_paths``: every file staged and committed in this
process). The partitioned ingest stages each file on its own (``stage_to_spool``: a private
DuckDB, the stage written to Parquet) and commits the spooled stages one by one in the same
order; the workspace tables must be identical, row for row, including line numbers, raw text,
reasons, vessels and file records. The batch mixes what crosses file boundaries: a second day
whose fixes repeat and jump against the first, a byte-identical copy (loaded once), dirty DMA
rows, real NOAA CSV and NMEA samples, and canonical Parquet.
"""

from __future__ import annotations

import shutil
import subprocess
import sys

import pandas as pd
import pytest

from ais_fixtures import DMA_HEADER, DMA_LINES, dma_row, write_dma
from conftest import shared_file
from pipelines import ingest_stage as stage_mod
from pipelines.ingest import ingest_paths
from pipelines.ingest_partitioned import commit_spooled, plan_files, stage_to_spool
from pipelines.storage import open_workspace

TABLES = {
    "ais_files": "SELECT * EXCLUDE (loaded_at) FROM ais_files ORDER BY file_id",
    "ais_file_keys": "SELECT * FROM ais_file_keys ORDER BY file_id",
    "ais_positions": "SELECT * FROM ais_positions ORDER BY file_id, source_line",
    "ais_quarantine": "SELECT * FROM ais_quarantine ORDER BY file_id, line, reason",
    "vessels": "SELECT * FROM vessels ORDER BY mmsi",
}


def _tables(db) -> dict:
    with open_workspace(db) as ws:
        return {name: ws.con.execute(sql).fetchdf() for name, sql in TABLES.items()}


def _assert_same_workspace(got_db, want_db) -> None:
    got, want = _tables(got_db), _tables(want_db)
    for name in TABLES:
        assert len(want[name]) > 0, name
        pd.testing.assert_frame_equal(got[name], want[name], check_exact=True, obj=name)


def _partitioned(files, db, spool, fmt=None) -> list[dict]:
    """The partitioned ingest as plain calls: plan, stage every file apart, commit in order."""
    with open_workspace(db) as ws:
        todo, skipped = plan_files(ws, files, fmt)
        staged = {p: stage_to_spool(p, fmt, str(spool)) for p in todo}
        return [skipped[p] if p in skipped else commit_spooled(ws, staged[p]) for p in files]


@pytest.fixture
def batch(tmp_path, shared_data):
    """Files whose outcome depends on the files before them, plus real samples of each reader."""
    src = tmp_path / "in"
    src.mkdir()
    day1 = write_dma(src / "a_day1.csv")
    # Day 2 repeats two of day 1's fixes (same key, one with other values), adds a fix 30 s
    # 6.5 min after the last stored one but 33 nmi away (a jump only with the stored track as
    # context), and a clean continuation at ~5 kn from the stored track.
    day2 = [DMA_HEADER,
            dma_row("01/01/2025 00:00:00", "219000001", "55.000000", "12.000000"),
            dma_row("01/01/2025 00:01:00", "219000001", "55.000500", "12.100000"),
            dma_row("01/01/2025 00:20:30", "219000001", "55.100000", "12.000000"),
            dma_row("01/01/2025 00:30:00", "219000001", "55.000000", "11.110000", name="ALPHA 2")]
    write_dma(src / "b_day2.csv", day2)
    shutil.copy(day1, src / "c_copy_of_day1.csv")
    shutil.copy(shared_file(shared_data, "ais/noaa_marinecadastre_20230111_sample.csv"), src / "d_noaa.csv")
    shutil.copy(shared_file(shared_data, "ais/nmea/pyais_nmea_data_sample.nmea"), src / "e_sample.nmea")
    pd.DataFrame({
        "mmsi": [219000001, 219000001, 123],
        "time_utc": pd.to_datetime(["2025-01-01T02:00:00Z", "2025-01-01T02:00:00Z", "2025-01-01T02:01:00Z"]),
        "lat_deg": [55.02, 55.02, 55.0], "lon_deg": [12.02, 12.02, 12.0], "sog_kn": [10.0, 10.0, 1.0],
        "cog_deg": [90.0, 90.0, 0.0], "heading_deg": [90.0, 90.0, 0.0], "nav_status": [0.0, 0.0, 0.0],
    }).to_parquet(src / "f_canonical.parquet")
    return [str(p) for p in sorted(src.iterdir())]


def test_partitioned_ingest_equals_the_sequential_one(tmp_path, batch):
    seq = ingest_paths(batch, tmp_path / "seq.duckdb")
    spool = tmp_path / "spool"
    spool.mkdir()
    per_file = _partitioned(batch, tmp_path / "part.duckdb", spool)

    _assert_same_workspace(tmp_path / "part.duckdb", tmp_path / "seq.duckdb")
    keys = ("path", "format", "read", "loaded", "quarantined", "duplicates", "static", "ignored", "reasons",
            "already_loaded")
    assert [{k: f[k] for k in keys} for f in per_file] == [{k: f[k] for k in keys} for f in seq["per_file"]]
    # the batch really crosses files: stored-key duplicates and a jump against the stored track
    # in day 2, and the byte-identical copy skipped
    day2 = per_file[1]["reasons"]
    assert day2.get("duplicate", 0) + day2.get("duplicate_time", 0) == 2 and day2.get("speed_jump") == 1
    assert per_file[2]["already_loaded"] and per_file[2]["read"] == 0
    assert all(f["read"] == f["loaded"] + f["quarantined"] + f["duplicates"] for f in per_file)
    assert list(spool.iterdir()) == []  # every spooled stage removed once committed

    # a second partitioned run stages nothing: every file is found loaded before staging
    with open_workspace(tmp_path / "part.duckdb") as ws:
        todo, skipped = plan_files(ws, batch)
    assert todo == [] and set(skipped) == set(batch)


def dirty_dma_file(folder, gz: bool, vessels: int = 5, mmsi_step: int = 1):
    """``folder/big.csv`` (or ``.csv.gz``): 20 minutes of ``vessels`` ships every 10 s, with the
    dirty rows of every kind, a quoted name and a blank line."""
    import gzip

    rows = [dma_row(f"02/01/2025 00:{m:02d}:{s:02d}", str(219300000 + v * mmsi_step),
                    f"{54 + v * 0.05 + m * 1e-3:.6f}", f"{8 + s * 1e-4:.6f}", name=f"SHIP {v}")
            for m in range(20) for s in range(0, 60, 10) for v in range(vessels)]
    rows[40:40] = DMA_LINES[1:]
    path = write_dma(folder / "big.csv", [DMA_HEADER] + rows)
    if gz:
        path.with_suffix(".csv.gz").write_bytes(gzip.compress(path.read_bytes()))
        path.unlink()
        path = path.with_suffix(".csv.gz")
    return path


@pytest.mark.parametrize("gz", [False, True], ids=["plain", "gzip"])
def test_partitioned_fast_csv_staging_equals_sequential(tmp_path, monkeypatch, gz):
    """Large-file staging (scanner split + line index) through the spool: raw text from the index.
    A large gzip file is inflated into a plain copy on the staging side too (removed after)."""
    import tempfile

    path = dirty_dma_file(tmp_path, gz)
    monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", 0)
    monkeypatch.setattr(stage_mod, "GZIP_PLAIN_MIN_BYTES", 0)
    (scratch := tmp_path / "tmp").mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    seq = ingest_paths([path], tmp_path / "seq.duckdb")
    assert seq["per_file"][0]["staging"] not in ("lines", "python")  # the fast path really ran
    (spool := tmp_path / "spool").mkdir()
    per_file = _partitioned([str(path)], tmp_path / "part.duckdb", spool)
    assert per_file[0]["staging"] == seq["per_file"][0]["staging"]
    _assert_same_workspace(tmp_path / "part.duckdb", tmp_path / "seq.duckdb")
    assert list(scratch.iterdir()) == []


def test_a_bad_file_fails_its_stage_with_a_clear_error(tmp_path):
    from ais.errors import AisInputError

    with pytest.raises(AisInputError, match="missing.csv"):
        stage_to_spool(str(tmp_path / "missing.csv"), None, str(tmp_path))


def test_cli_rejects_a_bad_task_runner_before_any_work(tmp_path):
    out = subprocess.run([sys.executable, "-m", "pipelines.cli", "ingest-ais", str(tmp_path), "--db",
                          str(tmp_path / "w.duckdb"), "--task-runner", "spark"], capture_output=True, text=True)
    assert out.returncode == 2
    assert "--task-runner 'spark'" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "w.duckdb").exists()


@pytest.mark.slow
def test_ingest_flow_on_a_two_worker_dask_cluster_equals_the_sequential_run(tmp_path, batch, prefect_harness,
                                                                            dask_address):
    from distributed import Client, get_task_stream

    from pipelines.ingest import flow_with_runner

    seq = ingest_paths(batch, tmp_path / "seq.duckdb")
    spool = tmp_path / "spool"
    spool.mkdir()
    with Client(dask_address) as client, get_task_stream(client) as stream:
        addresses = set(client.scheduler_info()["workers"])
        out = flow_with_runner(f"dask:{dask_address}")(
            paths=batch, db=str(tmp_path / "dask.duckdb"), spool_dir=str(spool))
        # a rerun of the flow stages nothing and adds nothing
        again = flow_with_runner(f"dask:{dask_address}")(
            paths=batch, db=str(tmp_path / "dask.duckdb"), spool_dir=str(spool))
    workers = {t["worker"] for t in stream.data}
    _assert_same_workspace(tmp_path / "dask.duckdb", tmp_path / "seq.duckdb")
    for k in ("files", "read", "loaded", "quarantined", "duplicates", "reasons", "static", "ignored", "already_loaded"):
        assert out[k] == seq[k], k
    # one stage task per new file (the byte-identical copy is staged too: its bytes are only
    # known to be loaded once the first copy commits), each a task on the cluster's workers
    # (the rerun submits none)
    assert len(stream.data) == len(batch) and workers and workers <= addresses, (len(stream.data), workers)
    assert again["files"] == len(batch) and again["already_loaded"] == len(batch) and again["read"] == 0
    assert list(spool.iterdir()) == []


# --- inputs a reviewer tries: a wrong forced format, empty files, Parquet forced on text --------
def test_bytes_loaded_under_a_wrong_forced_format_can_still_be_loaded_as_detected(tmp_path, shared_data):
    src = tmp_path / "noaa.csv"
    shutil.copy(shared_file(shared_data, "ais/noaa_marinecadastre_20230111_sample.csv"), src)
    db = tmp_path / "w.duckdb"
    wrong = ingest_paths([src], db, fmt="nmea")
    assert wrong["loaded"] == 0 and wrong["quarantined"] == wrong["read"] > 0  # every line a bad sentence
    assert ingest_paths([src], db, fmt="nmea")["already_loaded"] == 1  # same bytes, same format: once
    right = ingest_paths([src], db)  # detected: NOAA
    assert right["already_loaded"] == 0 and right["loaded"] > 0
    assert right["read"] == right["loaded"] + right["quarantined"] + right["duplicates"]
    assert ingest_paths([src], db, fmt="noaa")["already_loaded"] == 1  # forcing the detected format is the same input
    # the partitioned planner sees the same identities
    with open_workspace(db) as ws:
        assert plan_files(ws, [str(src)], "nmea")[0] == [] and plan_files(ws, [str(src)], "dma")[0] == [str(src)]


def test_empty_files_in_a_directory_are_skipped_not_fatal(tmp_path):
    from ais.errors import AisFormatError

    d = tmp_path / "in"
    d.mkdir()
    write_dma(d / "a.csv")
    (d / "b_empty.csv").write_bytes(b"")
    (d / "c_blank.nmea").write_text("\n  \n")
    ref = ingest_paths([d / "a.csv"], tmp_path / "ref.duckdb")
    s = ingest_paths([d], tmp_path / "w.duckdb")
    assert s["files"] == 1 and s["per_file"][0]["path"].endswith("a.csv")
    for k in ("read", "loaded", "quarantined", "duplicates", "reasons"):
        assert s[k] == ref[k], k
    with pytest.raises(AisFormatError, match="empty file"):  # named on its own, it is an error
        ingest_paths([d / "b_empty.csv"], tmp_path / "w.duckdb")


def test_parquet_forced_on_a_csv_file_is_a_clear_error(tmp_path):
    from ais.errors import AisFormatError

    src = write_dma(tmp_path / "day.csv")
    with pytest.raises(AisFormatError, match=r"day\.csv: not a readable Parquet file"):
        ingest_paths([src], tmp_path / "w.duckdb", fmt="parquet")
    out = subprocess.run([sys.executable, "-m", "pipelines.cli", "ingest-ais", str(src), "--db", str(tmp_path / "x.duckdb"),
                          "--format", "parquet"], capture_output=True, text=True)
    assert out.returncode == 2 and "not a readable Parquet file" in out.stderr and "Traceback" not in out.stderr
