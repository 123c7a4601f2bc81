"""A large Parquet file ingested in groups of whole vessels gives the whole file's workspace.

``pipelines.ingest_groups`` splits a Parquet file above ``PARQUET_GROUP_MIN_ROWS`` into MMSI
ranges of about ``PARQUET_GROUP_ROWS`` rows (``ais.io.parquet_buckets``) and commits the groups
one after the other in the file's one transaction. The reference is the same files ingested
whole: every table, the line numbers, the counts and the positions dataset's bytes must be the
same, whatever the rows (random fleets with bad MMSIs, times and positions, repeated keys, speed
jumps, status numbers and words, a second file going on and back in time) and the column types.
"""

from __future__ import annotations

import struct

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pipelines.ingest_groups as groups_mod
from ais.io import parquet_buckets
from pipelines.ingest import ingest_file
from pipelines.storage import open_workspace
from pipelines.storage.ais import parquet as P
from test_ingest_groups import _state, commit_partitioned

VESSELS = (219000001, 219000002, 230000017, 244000321, 265111222, 311000999)
WORDS = ("Under way using engine", "moored", "At anchor", "Engaged in fishing", "not a status")


def fleet_table(seed: int, n: int, t0_s: int, mmsi_type: str, status_type: str, geometry: bool) -> pa.Table:
    """``n`` AIS rows of random vessels from ``t0_s`` on: a few missing or bad MMSIs and times,
    times that repeat and go back, positions walking with some jumps and some out of range."""
    rng = np.random.default_rng(seed)
    vessel = rng.integers(0, len(VESSELS), n)
    mmsi = np.asarray(VESSELS, dtype=np.int64)[vessel]
    t = t0_s + np.cumsum(rng.integers(-20, 90, n))
    lat = 55.0 + 0.01 * vessel + np.cumsum(rng.normal(0, 0.002, n))
    lon = 10.0 + np.cumsum(rng.normal(0, 0.002, n))
    lat[rng.random(n) < 0.04] += 3.0  # a jump
    lat[rng.random(n) < 0.02] = 95.0  # no position
    times = pd.Series(pd.to_datetime(t, unit="s")).astype("datetime64[us]")
    times[rng.random(n) < 0.03] = pd.NaT
    bad = rng.random(n) < 0.05
    if mmsi_type == "text":
        m = pa.array([None if b and k % 2 else ("12345" if b else f" {v}") for k, (v, b) in enumerate(zip(mmsi, bad))])
    elif mmsi_type == "double":
        m = pa.array(np.where(bad, 2.19e8 + 0.5, mmsi.astype(float)))
    else:
        m = pa.array(mmsi, mask=bad)
    if status_type == "words":
        status = pa.array([WORDS[k] for k in rng.integers(0, len(WORDS), n)])
    else:
        status = pa.array(rng.integers(0, 17, n).astype(np.int32))  # 16: bad_nav_status
    cols = {"mmsi": m, "time_utc": pa.array(times), "sog_kn": pa.array(rng.uniform(0, 20, n).astype(np.float32)),
            "cog_deg": pa.array(rng.uniform(0, 360, n)), "nav_status": status,
            "name": pa.array([f"SHIP {v % 7}" if rng.random() < 0.7 else None for v in mmsi]),
            "ship_type": pa.array(rng.choice([70, 80, 0], n).astype(np.int16))}
    if geometry:
        cols["geometry"] = pa.array([struct.pack("<BIdd", 1, 1, x, y) for x, y in zip(lon, lat)])
        meta = {b"geo": b'{"version":"1.1.0","primary_column":"geometry","columns":{"geometry":'
                        b'{"encoding":"WKB","geometry_types":["Point"]}}}'}
        return pa.table(cols).replace_schema_metadata(meta)
    return pa.table({**cols, "lat": pa.array(lat), "lon": pa.array(lon)})


@st.composite
def _parquet_files(draw):
    kinds = {"mmsi_type": draw(st.sampled_from(["int64", "text", "double"])),
             "status_type": draw(st.sampled_from(["int", "words"])), "geometry": draw(st.booleans())}
    files = []
    for k in range(draw(st.integers(1, 2))):
        n = draw(st.integers(1, 160))
        t0 = 1_735_689_600 + draw(st.integers(-3000, 6000)) * k  # the second on, over or back in time
        files.append((fleet_table(draw(st.integers(0, 2**32 - 1)), n, t0, **kinds), draw(st.integers(2, 64))))
    return files


def _ingest(d, side, files, group_rows, monkeypatch):
    monkeypatch.setattr(groups_mod, "PARQUET_GROUP_MIN_ROWS", group_rows if side == "split" else 1 << 62)
    monkeypatch.setattr(groups_mod, "PARQUET_GROUP_ROWS", group_rows)
    (d / side).mkdir()
    db = d / side / "w.duckdb"
    counts = []
    for k, (table, row_group) in enumerate(files):
        path = d / side / f"in-{k}.parquet"
        pq.write_table(table, path, row_group_size=row_group)
        with open_workspace(db) as ws:
            counts.append(ingest_file(ws, path))
    return db, counts


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow, HealthCheck.data_too_large])
@given(files=_parquet_files(), group_rows=st.sampled_from([4, 25, 1000]), batch=st.sampled_from([7, 1 << 17]))
def test_parquet_groups_give_the_whole_files_workspace(tmp_path_factory, monkeypatch, files, group_rows, batch):
    d = tmp_path_factory.mktemp("pq-groups")
    monkeypatch.setattr(P, "ROW_GROUP_ROWS", 3)  # the streamed parts carry rows over the groups
    monkeypatch.setattr(parquet_buckets, "BATCH_ROWS", batch)  # batches across the input's row groups
    whole_db, whole = _ingest(d, "whole", files, group_rows, monkeypatch)
    split_db, split = _ingest(d, "split", files, group_rows, monkeypatch)
    for (table, _), a, b in zip(files, whole, split):
        assert a["staging"] != "groups"
        assert (b["staging"] == "groups") == (table.num_rows > group_rows)
        for key in ("read", "loaded", "quarantined", "duplicates", "static", "ignored", "reasons"):
            assert a[key] == b[key], (key, a[key], b[key])
    for name, x, y in zip(("tables", "attribution", "track ends, parts, files", "dataset"), _state(split_db),
                          _state(whole_db)):
        assert x == y, name
    assert not list(d.glob("**/.stormlane-groups-*")) and not list(d.glob("**/.groups-*"))


def test_the_split_keeps_every_row_once_in_order_with_the_inputs_schema(tmp_path):
    """Each group holds whole vessels (ascending MMSI ranges, rows without an MMSI in the first),
    its rows are the input's at its line numbers, in order, and its schema is the input's with
    its metadata (GeoParquet's ``geo``)."""
    table = fleet_table(3, 2000, 1_735_689_600, "text", "words", geometry=True)
    src = tmp_path / "in.parquet"
    pq.write_table(table, src, row_group_size=300)
    keys = groups_mod.parquet_keys(src, tmp_path / "keys.npy")
    parquet_buckets.BATCH_ROWS, old = 333, parquet_buckets.BATCH_ROWS
    try:
        groups = parquet_buckets.split_by_keys(src, keys, 4, tmp_path)
    finally:
        parquet_buckets.BATCH_ROWS = old
    assert len(groups) == 4
    seen, ranges = [], []
    for g in groups:
        got = pq.read_table(g.path)
        assert got.schema.equals(table.schema, check_metadata=True) and b"geo" in got.schema.metadata
        lines = g.line_numbers()
        assert len(lines) == got.num_rows == g.n_lines and (np.diff(lines) > 0).all()
        assert got.equals(table.take(lines - 1))
        seen += lines.tolist()
        ranges.append(set(keys[lines - 1][keys[lines - 1] >= 0].tolist()))
    assert sorted(seen) == list(range(1, table.num_rows + 1))
    for a, b in zip(ranges, ranges[1:]):
        assert a and b and max(a) < min(b)
    # the keys are the stage's reading: " 219000001" is a vessel, "12345" and a missing one are not
    text = table.column("mmsi").to_pylist()
    assert all((k >= 0) == (v is not None and v.strip().isdigit() and len(v.strip()) == 9) for k, v in zip(keys, text))
    assert -1 in keys and set(keys[keys >= 0].tolist()) == set(VESSELS)


def test_partitioned_ingest_commits_a_large_parquet_file_in_groups(tmp_path, monkeypatch):
    """The worker hands the Parquet file over as it is; the committing process splits it and
    commits its groups: the sequential whole-file workspace, the input kept."""
    table = fleet_table(11, 900, 1_735_689_600, "int64", "int", geometry=False)
    monkeypatch.setattr(P, "ROW_GROUP_ROWS", 50)
    whole_db, _ = _ingest(tmp_path, "whole", [(table, 100)], 1 << 62, monkeypatch)
    monkeypatch.setattr(groups_mod, "PARQUET_GROUP_MIN_ROWS", 200)
    monkeypatch.setattr(groups_mod, "PARQUET_GROUP_ROWS", 200)
    assert _state(commit_partitioned(tmp_path, tmp_path / "whole" / "in-0.parquet")) == _state(whole_db)


@pytest.mark.parametrize("rows", [0, 5])
def test_small_or_unreadable_parquet_files_are_committed_whole(tmp_path, rows):
    """Up to the threshold, or when pyarrow cannot read the footer (the stage then names the
    problem), a Parquet file is not split."""
    from ais.io.files import inspect

    path = tmp_path / "x.parquet"
    if rows:
        pq.write_table(fleet_table(1, rows, 1_735_689_600, "int64", "int", False), path)
    else:
        path.write_bytes(b"PAR1 not really")
    f = inspect(path, "parquet", with_fingerprint=False)
    assert groups_mod.parquet_rows(path) == rows
    assert not groups_mod.wants_groups(f)
    old = groups_mod.PARQUET_GROUP_MIN_ROWS
    groups_mod.PARQUET_GROUP_MIN_ROWS = 4
    try:
        assert groups_mod.wants_groups(f) == (rows > 4)
    finally:
        groups_mod.PARQUET_GROUP_MIN_ROWS = old


def test_a_large_gzip_parquet_file_is_inflated_and_committed_in_groups(tmp_path, monkeypatch):
    """A gzip Parquet file from GZIP_PLAIN_MIN_BYTES on is inflated once to a plain copy beside
    the workspace, whose rows decide the groups: the workspace of the gzip stream read whole
    (its decompressed temporary copy, every row's text staged), and no copy left."""
    import gzip

    from pipelines import ingest_stage

    table = fleet_table(21, 700, 1_735_689_600, "text", "words", geometry=True)
    plain = tmp_path / "x.parquet"
    pq.write_table(table, plain, row_group_size=64)
    monkeypatch.setattr(P, "ROW_GROUP_ROWS", 40)
    dbs = {}
    for side, min_gz, min_rows in (("stream", 1 << 40, 1 << 62), ("groups", 0, 100)):
        monkeypatch.setattr(ingest_stage, "GZIP_PLAIN_MIN_BYTES", min_gz)
        monkeypatch.setattr(groups_mod, "PARQUET_GROUP_MIN_ROWS", min_rows)
        monkeypatch.setattr(groups_mod, "PARQUET_GROUP_ROWS", 150)
        (tmp_path / side).mkdir()
        gz = tmp_path / side / "in" / "x.parquet.gz"
        gz.parent.mkdir()
        gz.write_bytes(gzip.compress(plain.read_bytes()))
        dbs[side] = tmp_path / side / "w.duckdb"
        with open_workspace(dbs[side]) as ws:
            counts = ingest_file(ws, gz)
        assert counts["staging"] == ("groups" if side == "groups" else "parquet")
        assert sorted(p.name for p in (tmp_path / side).iterdir()) == ["in", "w.duckdb", "w.parquet"]
    assert _state(dbs["groups"]) == _state(dbs["stream"])
