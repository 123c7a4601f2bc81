"""The positions as partitioned GeoParquet beside the workspace (issue 23): written by the same
load, the same rows as ``ais_positions``, GeoParquet 1.1 metadata, a rerun writes nothing, a
failed load leaves nothing, a damaged folder converges back to the workspace."""

from __future__ import annotations

import json
import os

import duckdb
import pyarrow.parquet as pq
import pytest

from ais_fixtures import DMA_HEADER, DMA_LINES, dma_row, write_dma
from pipelines.ingest import ingest_file, ingest_paths
from pipelines.storage import open_workspace
from pipelines.storage.ais import positions_root, sync_positions_parquet
from pipelines.storage.ais.parquet import POSITIONS_SELECT, parquet_glob

COLS = "mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, nav_status, file_id, source_line"


def two_day_file(path, mmsi="219000005"):
    """One vessel sailing across midnight 2025-01-01/02 (rows on both days) with irregular
    coordinates (not exactly representable as FLOAT, so that the bbox must round outward)."""
    lines = [DMA_HEADER]
    for k in range(40):
        hh, mm = divmod(23 * 60 + 30 + k, 60)
        day = 1 + hh // 24
        lines.append(dma_row(f"0{day}/01/2025 {hh % 24:02d}:{mm:02d}:00", mmsi, f"{55.1 + k * 0.0013:.6f}",
                             f"{11.2 + k * 0.0031:.6f}"))
    return write_dma(path, lines)


def stored(db):
    with open_workspace(db) as ws:
        pos = ws.con.execute(f"SELECT {COLS} FROM ais_positions ORDER BY file_id, mmsi, time_utc").fetchall()
        quar = ws.con.execute("SELECT * FROM ais_quarantine ORDER BY file_id, line").fetchall()
    return pos, quar


def dataset(db):
    con = duckdb.connect()
    glob = parquet_glob(positions_root(db))
    return con.execute(f"SELECT {COLS} FROM ({POSITIONS_SELECT}) ORDER BY file_id, mmsi, time_utc", [glob]).fetchall()


def files_state(root):
    return {str(p.relative_to(root)): (p.stat().st_mtime_ns, p.read_bytes()) for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture()
def loaded(tmp_path):
    a = write_dma(tmp_path / "a.csv")
    b = two_day_file(tmp_path / "b.csv")
    db = tmp_path / "w.duckdb"
    ingest_paths([a, b], db)
    return tmp_path, db


def test_dataset_holds_the_workspace_positions_by_day_with_geoparquet_metadata(loaded):
    tmp_path, db = loaded
    root = positions_root(db)
    assert root == tmp_path / "w.parquet" / "positions"
    pos, _ = stored(db)
    assert len(pos) == 5 + 40 and dataset(db) == pos  # bit for bit, every column
    parts = sorted(str(p.relative_to(root)) for p in root.rglob("*.parquet"))
    # file 1 (a.csv) has rows on 2025-01-01 only; file 2 on both days
    assert parts == ["day=2025-01-01/file-000000001.parquet", "day=2025-01-01/file-000000002.parquet",
                     "day=2025-01-02/file-000000002.parquet"]
    with open_workspace(db) as ws:
        rows = ws.con.execute("SELECT file_id, strftime(day, '%Y-%m-%d'), n_rows FROM ais_parquet_parts "
                              "ORDER BY ALL").fetchall()
    assert rows == [(1, "2025-01-01", 5), (2, "2025-01-01", 30), (2, "2025-01-02", 10)]
    # each part holds the UTC day of its folder, sorted by mmsi then time
    con = duckdb.connect()
    bad = con.execute("SELECT count(*) FROM read_parquet(?, hive_partitioning = true) "
                      "WHERE CAST(timezone('UTC', time_utc) AS DATE) <> day", [parquet_glob(root)]).fetchone()[0]
    assert bad == 0
    for path in root.rglob("*.parquet"):
        f = pq.ParquetFile(path)
        geo = json.loads(f.schema_arrow.metadata[b"geo"])
        col = geo["columns"]["geometry"]
        assert geo["version"] == "1.1.0" and geo["primary_column"] == "geometry"
        assert col["encoding"] == "point" and col["geometry_types"] == ["Point"]
        assert col["covering"] == {"bbox": {k: ["bbox", k] for k in ("xmin", "ymin", "xmax", "ymax")}}
        t = f.read().to_pydict()
        xs, ys = [g["x"] for g in t["geometry"]], [g["y"] for g in t["geometry"]]
        assert col["bbox"] == [min(xs), min(ys), max(xs), max(ys)]
        assert list(zip(t["mmsi"], t["time_utc"])) == sorted(zip(t["mmsi"], t["time_utc"]))
        for x, y, b in zip(xs, ys, t["bbox"]):
            assert b["xmin"] <= x <= b["xmax"] and b["ymin"] <= y <= b["ymax"]  # FLOAT bounds contain the point
            assert b["xmax"] - b["xmin"] < 1e-5 and b["ymax"] - b["ymin"] < 1e-5
    # the bbox column prunes: a box around file 2's first fixes finds those rows only
    n = con.execute("SELECT count(*) FROM read_parquet(?) WHERE bbox.xmax >= 11.2 AND bbox.xmin <= 11.2031 "
                    "AND bbox.ymax >= 55.1 AND bbox.ymin <= 55.1013", [parquet_glob(root)]).fetchone()[0]
    assert n == 2


def test_rerun_writes_nothing_and_failed_load_leaves_nothing(loaded):
    tmp_path, db = loaded
    root = positions_root(db)
    before, pos0 = files_state(root), stored(db)
    s = ingest_paths([tmp_path / "a.csv", tmp_path / "b.csv"], db)
    assert s["already_loaded"] == 2 and files_state(root) == before and stored(db) == pos0

    c = two_day_file(tmp_path / "c.csv", mmsi="219000006")

    def boom():
        raise RuntimeError("crash before commit")

    with open_workspace(db) as ws, pytest.raises(RuntimeError):
        ingest_file(ws, c, before_commit=boom)
    assert files_state(root) == before and stored(db) == pos0  # no part, no temporary file left
    ingest_paths([c], db)
    assert len(files_state(root)) == len(before) + 2 and dataset(db) == stored(db)[0]


@pytest.mark.parametrize("where", ["writer", "transaction"])
def test_error_while_the_parts_are_written_in_their_thread_leaves_nothing(loaded, monkeypatch, where):
    """The parts are written in a thread while the transaction goes on: an error in the writer
    (its second part) or in the transaction (the vessels step, while the writer may still run)
    rolls the file back and leaves no part and no temporary file."""
    import pipelines.storage.ais.commit as commit
    import pipelines.storage.ais.parquet as parquet

    tmp_path, db = loaded
    root = positions_root(db)
    before, pos0 = files_state(root), stored(db)
    c = two_day_file(tmp_path / "c.csv", mmsi="219000007")
    if where == "writer":
        write, calls = parquet.write_geoparquet, []

        def write_then_fail(table, path):
            write(table, path)  # the first part is on disk under its temporary name
            calls.append(path)
            if len(calls) == 2:
                raise OSError("disk full")

        monkeypatch.setattr(parquet, "write_geoparquet", write_then_fail)
        expected = OSError
    else:
        def vessels_fail(*a, **k):
            raise RuntimeError("vessels failed")

        monkeypatch.setattr(commit, "_upsert_vessels", vessels_fail)
        expected = RuntimeError
    with open_workspace(db) as ws, pytest.raises(expected):
        ingest_file(ws, c)
    assert files_state(root) == before and stored(db) == pos0
    monkeypatch.undo()
    ingest_paths([c], db)
    assert len(files_state(root)) == len(before) + 2 and dataset(db) == stored(db)[0]


def test_sync_brings_a_damaged_folder_back_to_the_workspace(loaded):
    tmp_path, db = loaded
    root = positions_root(db)
    before = files_state(root)
    day1 = root / "day=2025-01-01"
    # a crash between the commit and the rename: the part is still under its temporary name
    os.replace(day1 / "file-000000001.parquet", day1 / f".file-000000001.parquet.{os.getpid() + 1}.tmp")
    (root / "day=2025-01-02" / "file-000000002.parquet").unlink()  # a part lost
    (day1 / ".file-000000009.parquet.1.tmp").write_bytes(b"an uncommitted load")
    (root / "day=2025-01-03").mkdir()
    (root / "day=2025-01-03" / "file-000000009.parquet").write_bytes(b"not recorded")
    with open_workspace(db) as ws:
        out = sync_positions_parquet(ws)
    assert out == {"parts": 3, "published": 1, "written": 1, "removed": 2}
    after = files_state(root)
    assert {k: v[1] for k, v in after.items()} == {k: v[1] for k, v in before.items()}  # byte-identical
    with open_workspace(db) as ws:
        assert sync_positions_parquet(ws) == {"parts": 3, "published": 0, "written": 0, "removed": 0}
    # a workspace whose dataset folder was deleted gets it back on the next ingest
    import shutil

    shutil.rmtree(tmp_path / "w.parquet")
    ingest_paths([tmp_path / "a.csv"], db)
    assert {k: v[1] for k, v in files_state(root).items()} == {k: v[1] for k, v in before.items()}


def test_a_workspace_inside_its_input_folder_does_not_read_its_own_dataset(tmp_path, capsys):
    """The workspace in the folder it loads: its dataset's parts (.parquet, an AIS suffix) are
    its output; a second run skips them with a note (it read every part again, all duplicates),
    and inputs holding nothing else are the one error line."""
    from ais.errors import AisInputError
    from pipelines.cli import main

    two_day_file(tmp_path / "aisdk-2025-01-01.csv")
    db = tmp_path / "ws.duckdb"
    main(["ingest-ais", str(tmp_path), "--db", str(db)])
    assert len(list((tmp_path / "ws.parquet").rglob("*.parquet"))) == 2  # one part per day
    capsys.readouterr()
    main(["ingest-ais", str(tmp_path), "--db", str(db)])
    out, err = capsys.readouterr()
    assert err.splitlines() == [f"note: 2 files of this workspace's own positions dataset ({tmp_path / 'ws.parquet'}) "
                                "skipped: its output, not an input"]
    assert out.splitlines() == [f"{tmp_path / 'aisdk-2025-01-01.csv'}: already loaded, skipped",
                                "total: 1 file(s), read 0 = loaded 0 + quarantined 0 + duplicates 0"]
    from pipelines.ingest import _discover  # the Prefect flow's discovery task skips them too

    assert _discover([str(tmp_path)], None, str(db)) == [str(tmp_path / "aisdk-2025-01-01.csv")]
    (tmp_path / "aisdk-2025-01-01.csv").unlink()
    with pytest.raises(AisInputError, match="own positions dataset is its output, not an input"):
        ingest_paths([tmp_path], db)
