"""A large CSV file ingested in groups of whole vessels gives the whole file's workspace.

``pipelines.ingest_groups`` splits a plain DMA/NOAA file above ``GROUP_BYTES`` into MMSI ranges
(``ais.io.csv_buckets``) and commits the groups one after the other in the file's one
transaction. The reference is the same files ingested whole: every table, the line numbers, the
counts and the positions dataset's bytes must be the same, whatever the rows (the multi-file
property test's fleets: dirty rows, quoted lines, repeated keys, jumps, files continuing,
overlapping and going back in time) and whatever the groups' staging path.
"""

from __future__ import annotations

import hashlib
import re
import shutil

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pipelines.ingest_groups as groups_mod
from ais.io import csv_buckets
from ais.io.csv_formats import MMSI_RE
from ais_fixtures import DMA_HEADER, dma_row
from pipelines import ingest_stage as stage_mod
from pipelines.ingest import ingest_file
from pipelines.storage import open_workspace
from pipelines.storage.ais import parquet as P
from pipelines.storage.ais import read_stage, stage_csv, sync_positions_parquet
from pipelines.ingest_stage import csv_layout
from ais.io.files import inspect
from test_ais_fast_csv import _snapshot
from test_ais_multifile_property import _attribution, _files, _ingest_all


def _dataset(db):
    root = P.positions_root(db)
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def _state(db):
    with open_workspace(db) as ws:
        con = ws.con
        extra = (con.execute("SELECT * FROM ais_track_ends ORDER BY mmsi").fetchall(),
                 con.execute("SELECT * FROM ais_parquet_parts ORDER BY ALL").fetchall(),
                 con.execute("SELECT file_id, fingerprint, format, size_bytes FROM ais_files ORDER BY 1").fetchall())
    # _snapshot orders by line only, and lines repeat over files: its tables as multisets
    return [sorted(map(repr, t)) for t in _snapshot(db)], _attribution(db), extra, _dataset(db)


def _size(path) -> int:
    from pathlib import Path

    return Path(path).stat().st_size


def _ingest(d, side, files, group_bytes, scan: bool, monkeypatch):
    """The multi-file test's ingest of ``files`` into ``d/side/``, the groups' files through the
    compiled scan or the exact raw-lines path."""
    monkeypatch.setattr(groups_mod, "GROUP_BYTES", group_bytes)
    monkeypatch.setattr(groups_mod, "GROUP_MIN_BYTES", group_bytes)
    (d / side).mkdir()
    return _ingest_all(d / side, "scan" if scan else "exact", files, monkeypatch)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow, HealthCheck.data_too_large])
@given(files=_files(), group_bytes=st.sampled_from([300, 900, 4000]), scan=st.booleans())
def test_groups_give_the_whole_files_workspace(tmp_path_factory, monkeypatch, files, group_bytes, scan):
    d = tmp_path_factory.mktemp("groups")
    monkeypatch.setattr(P, "ROW_GROUP_ROWS", 3)  # the streamed parts carry rows over the groups
    whole_db, whole = _ingest(d, "whole", files, 1 << 62, scan, monkeypatch)
    split_db, split = _ingest(d, "split", files, group_bytes, scan, monkeypatch)
    for a, b in zip(whole, split):
        assert a["already_loaded"] == b["already_loaded"]
        if not b["already_loaded"]:
            assert a["staging"] != "groups"
            assert (b["staging"] == "groups") == (_size(b["path"]) > group_bytes)
        for key in ("read", "loaded", "quarantined", "duplicates", "static", "ignored", "reasons"):
            assert a[key] == b[key], (key, a[key], b[key])
    for name, x, y in zip(("tables", "attribution", "track ends, parts, files", "dataset"), _state(split_db),
                          _state(whole_db)):
        assert x == y, name
    # Written again from the workspace (a deleted dataset), the parts are the streamed ones.
    streamed = _dataset(split_db)
    shutil.rmtree(P.positions_root(split_db))
    with open_workspace(split_db) as ws:
        sync_positions_parquet(ws)
    assert _dataset(split_db) == streamed
    assert not list(d.glob("**/.stormlane-groups-*")) and not list(d.glob("**/.groups-*"))


def _typed_mmsi(tmp_path, path):
    """(line, MMSI) of the rows the ingest's exact path types with a valid MMSI and no bad_line."""
    f = inspect(path, "dma", with_fingerprint=False)
    spec, first, header, index = csv_layout(f)
    with open_workspace(tmp_path / "typed.duckdb") as ws:
        stage_csv(ws, f.path, False, spec, index, len(header), header=first)
        df = read_stage(ws)
    ok = df["mmsi"].notna() & (df["parse_error"].astype(object) != "bad_line")
    return dict(zip(df.loc[ok, "line"].astype(int), df.loc[ok, "mmsi"].astype(int)))


def test_split_keeps_every_line_once_and_each_vessel_in_one_range(tmp_path):
    rng = np.random.default_rng(7)
    lines = [DMA_HEADER]
    for i in range(3000):
        m = int(rng.choice([219000001, 219000002, 230000017, 244000321, 265111222, 311000999]))
        ts = f"01/03/2025 {i // 3600 % 24:02d}:{i // 60 % 60:02d}:{i % 60:02d}"
        row = dma_row(ts, str(m), "55.000000", f"{10 + i * 1e-4:.6f}")
        style = i % 17
        if style == 1:  # the MMSI quoted: the exact parse reads it
            row = row.replace(f",{m},", f',"{m}",')
        elif style == 2:  # white space around it
            row = row.replace(f",{m},", f", {m}\t,")
        elif style == 3:  # a comma inside a quoted name: the MMSI column is still the third
            row = row.replace("Class A", '"Class, A"')
        elif style == 4:
            row = ""
        elif style == 5:
            row = DMA_HEADER
        elif style == 6:
            row = row + "\r"
        elif style == 7:  # too few fields
            row = ",".join(row.split(",")[:5])
        lines.append(row)
    path = tmp_path / "in.csv"
    path.write_bytes("\n".join(lines).encode())  # no newline after the last line
    groups = csv_buckets.split_by_mmsi(path, 2, 4, tmp_path)
    original = path.read_bytes().split(b"\n")
    seen = []
    typed = _typed_mmsi(tmp_path, path)
    ranges = []
    for g in groups:
        body = g.path.read_bytes()
        assert body.endswith(b"\n")
        got = body[:-1].split(b"\n")
        nums = g.line_numbers()
        assert len(got) == len(nums) == g.n_lines and nums[0] == 1 and got[0] == original[0]
        assert (np.diff(nums) > 0).all()  # the input's order
        assert [original[n - 1] for n in nums] == got
        seen += nums[1:].tolist()
        ranges.append({typed[n] for n in nums[1:] if n in typed})
    assert sorted(seen) == list(range(2, len(original) + 1))
    assert len(groups) == 4
    for a, b in zip(ranges, ranges[1:]):  # ascending MMSI ranges, no vessel in two groups
        assert a and b and max(a) < min(b)
    assert all(re.fullmatch(MMSI_RE, str(m)) for r in ranges for m in r)


@pytest.mark.parametrize("where", ["before the commit", "in the second group"])
def test_a_failed_commit_leaves_nothing_of_the_groups(tmp_path, monkeypatch, where):
    import pipelines.storage.ais.commit as commit

    monkeypatch.setattr(groups_mod, "GROUP_BYTES", 2000)
    monkeypatch.setattr(groups_mod, "GROUP_MIN_BYTES", 2000)
    rows = [dma_row(f"01/03/2025 00:{i // 60:02d}:{i % 60:02d}", str(219000000 + i % 7), "55.000000",
                    f"{10 + i * 1e-4:.6f}") for i in range(300)]
    path = tmp_path / "day.csv"
    path.write_text("\n".join([DMA_HEADER] + rows) + "\n")
    db = tmp_path / "w.duckdb"

    def boom():
        raise RuntimeError("killed inside the transaction")

    upsert, calls = commit._upsert_vessels, []

    def second_group_fails(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            boom()
        return upsert(*a, **k)

    if where != "before the commit":
        monkeypatch.setattr(commit, "_upsert_vessels", second_group_fails)
    with open_workspace(db) as ws:
        with pytest.raises(RuntimeError, match="killed"):
            ingest_file(ws, path, fmt="dma", before_commit=boom if where == "before the commit" else None)
        assert ws.con.execute("SELECT count(*) FROM ais_positions").fetchone()[0] == 0
        assert ws.con.execute("SELECT count(*) FROM ais_files").fetchone()[0] == 0
        assert ws.con.execute("SELECT count(*) FROM ais_parquet_parts").fetchone()[0] == 0
    assert not [p for p in tmp_path.rglob("*") if p.is_file() and p.suffix in (".parquet", ".tmp", ".arrow")]
    assert not list(tmp_path.glob(".stormlane-groups-*")) and not list(tmp_path.rglob(".groups-*"))
    monkeypatch.setattr(commit, "_upsert_vessels", upsert)
    with open_workspace(db) as ws:  # and the file loads afterwards, in groups
        counts = ingest_file(ws, path, fmt="dma")
    assert counts["staging"] == "groups" and counts["loaded"] == 300


@pytest.mark.parametrize("gz", [False, True], ids=["plain", "gzip"])
def test_partitioned_ingest_commits_a_large_file_in_groups(tmp_path, monkeypatch, gz):
    """On the partitioned path a large file is only inflated and hashed where it is staged; the
    committing process splits it and commits its groups: the sequential whole-file workspace."""
    from test_ingest_partitioned import dirty_dma_file

    path = dirty_dma_file(tmp_path, gz, vessels=9, mmsi_step=7919)
    monkeypatch.setattr(stage_mod, "GZIP_PLAIN_MIN_BYTES", 0)
    whole_db, _ = _ingest_paths(tmp_path / "whole", path, 1 << 62, monkeypatch)
    monkeypatch.setattr(groups_mod, "GROUP_MIN_BYTES", 5000)
    monkeypatch.setattr(groups_mod, "GROUP_BYTES", 5000)
    assert _state(commit_partitioned(tmp_path, path)) == _state(whole_db)


def commit_partitioned(tmp_path, path):
    """``path`` staged as the partitioned ingest's worker does (into ``tmp_path/spool``) and
    committed in groups into ``tmp_path/part/w.duckdb``: the spool empty after, the input kept,
    no group folder left. Returns the workspace."""
    from pipelines.ingest_partitioned import commit_spooled, plan_files, stage_to_spool

    spool = tmp_path / "spool"
    spool.mkdir()
    part_db = tmp_path / "part" / "w.duckdb"
    part_db.parent.mkdir()
    with open_workspace(part_db) as ws:
        todo, _ = plan_files(ws, [str(path)], None)
        staged = stage_to_spool(todo[0], None, str(spool))
        assert staged["spool_kind"] == "plain"
        counts = commit_spooled(ws, staged)
    assert counts["staging"] == "groups" and counts["loaded"] > 0
    assert list(spool.iterdir()) == [] and path.exists()
    assert not list(part_db.parent.glob(".stormlane-groups-*"))
    return part_db


def _ingest_paths(folder, path, group_min_bytes, monkeypatch):
    from pipelines.ingest import ingest_paths

    monkeypatch.setattr(groups_mod, "GROUP_MIN_BYTES", group_min_bytes)
    folder.mkdir()
    db = folder / "w.duckdb"
    return db, ingest_paths([path], db)


def test_a_killed_grouped_commits_spill_is_removed_by_the_next_sync(tmp_path):
    db = tmp_path / "w.duckdb"
    with open_workspace(db) as ws:
        sync_positions_parquet(ws)
    spill = P.dataset_root(db) / ".groups-000000001-4242.tmp"
    spill.mkdir(parents=True)
    (spill / "2025-03-01-0000.arrow").write_bytes(b"x")
    with open_workspace(db) as ws:
        assert sync_positions_parquet(ws)["removed"] == 1
    assert not spill.exists()


def test_a_killed_ingests_group_folder_is_removed_by_the_next_grouped_ingest(tmp_path, monkeypatch):
    monkeypatch.setattr(groups_mod, "GROUP_BYTES", 2000)
    monkeypatch.setattr(groups_mod, "GROUP_MIN_BYTES", 2000)
    rows = [dma_row(f"01/03/2025 00:{i // 60:02d}:{i % 60:02d}", str(219000000 + i % 7), "55.000000",
                    f"{10 + i * 1e-4:.6f}") for i in range(300)]
    path = tmp_path / "in" / "day.csv"
    path.parent.mkdir()
    path.write_text("\n".join([DMA_HEADER] + rows) + "\n")
    mine = tmp_path / ".stormlane-groups-w-dead1"  # a killed ingest into w.duckdb left it
    other = tmp_path / ".stormlane-groups-w-2-live"  # workspace w-2's, beside it
    for d in (mine, other):
        d.mkdir()
        (d / "group-0000.csv").write_text("x")
    with open_workspace(tmp_path / "w.duckdb") as ws:
        assert ingest_file(ws, path, fmt="dma")["staging"] == "groups"
    assert not mine.exists() and other.exists()
    assert [p.name for p in tmp_path.glob(".stormlane-groups-*")] == [other.name]


def test_a_killed_ingests_plain_copy_is_removed_by_the_next_ingest(tmp_path, monkeypatch, caplog):
    """A gzip file's plain copy beside the workspace (about its inflated size) is named by the
    workspace's stem; one a killed ingest into this workspace left is removed, with a warning,
    by the next ingest into it, never workspace w-2's, nor a copy of an older version (no stem)."""
    import gzip
    import logging

    monkeypatch.setattr(stage_mod, "GZIP_PLAIN_MIN_BYTES", 0)
    rows = [dma_row(f"01/03/2025 00:{i // 60:02d}:{i % 60:02d}", str(219000000 + i % 7), "55.000000",
                    f"{10 + i * 1e-4:.6f}") for i in range(50)]
    path = tmp_path / "in" / "day.csv.gz"
    path.parent.mkdir()
    path.write_bytes(gzip.compress(("\n".join([DMA_HEADER] + rows) + "\n").encode()))
    mine = tmp_path / ".stormlane-gunzip-w-k2j4x_9q.csv"
    others = [tmp_path / ".stormlane-gunzip-w-2-abcdefgh.csv", tmp_path / ".stormlane-gunzip-zz1abcde.csv"]
    for p in (mine, *others):
        p.write_text("x")
    from pipelines.ingest import ingest_paths

    with caplog.at_level(logging.WARNING):
        assert ingest_paths([path], tmp_path / "w.duckdb")["loaded"] == 50
    assert not mine.exists() and all(p.exists() for p in others)
    assert any(mine.name in r.getMessage() for r in caplog.records)
    assert sorted(p.name for p in tmp_path.glob(".stormlane-gunzip-*")) == sorted(p.name for p in others)
