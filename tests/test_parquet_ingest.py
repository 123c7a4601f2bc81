"""Parquet ingest: WKB points read as doubles, the raw text of quarantined rows read from the
file at the commit, and a workspace whose dataset folder name is taken by a file."""

from __future__ import annotations

import gzip
import shutil
import struct
import subprocess
import sys

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from ais.io.parquet import wkb_point_xy
from pipelines.ingest import ingest_paths
from pipelines.storage import open_workspace


def _le_points(n: int, seed: int = 0) -> tuple[list[bytes], np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-180, 180, n), rng.uniform(-90, 90, n)
    return [struct.pack("<BIdd", 1, 1, a, b) for a, b in zip(x, y)], x, y


def test_uniform_wkb_points_are_read_bit_for_bit():
    """Little-endian 2-D points (what GDAL, Shapely and DuckDB write) come out of the strided
    read exactly as ``struct`` unpacks them, in a sliced array (offset) too."""
    values, x, y = _le_points(1000)
    gx, gy = wkb_point_xy(pa.array(values, pa.binary()))
    assert np.array_equal(gx, x) and np.array_equal(gy, y)
    sx, sy = wkb_point_xy(pa.array(values, pa.binary()).slice(17, 500))
    assert np.array_equal(sx, x[17:517]) and np.array_equal(sy, y[17:517])
    lx, ly = wkb_point_xy(pa.array(values, pa.large_binary()))
    assert np.array_equal(lx, x) and np.array_equal(ly, y)


@pytest.mark.parametrize("odd", ["big_endian", "null", "linestring_21_bytes", "srid"])
def test_one_other_value_among_uniform_points_takes_the_general_path(odd):
    """One value that is not a little-endian 2-D point: every other point read the same, the odd
    one as the general decoder says (a big-endian or SRID point its coordinates; a null or a
    21-byte value of another type no point)."""
    values, x, y = _le_points(300, seed=1)
    k = 123
    want_x, want_y = x.copy(), y.copy()
    if odd == "big_endian":
        values[k] = struct.pack(">BIdd", 0, 1, x[k], y[k])
    elif odd == "srid":
        values[k] = struct.pack("<BIIdd", 1, 0x20000001, 4326, x[k], y[k])
    else:
        values[k] = None if odd == "null" else struct.pack("<BIIdI", 1, 2, 1, 5.0, 0)  # 21 bytes, type 2
        want_x[k] = want_y[k] = np.nan
    gx, gy = wkb_point_xy(pa.array(values, pa.binary()))
    assert np.array_equal(gx, want_x, equal_nan=True) and np.array_equal(gy, want_y, equal_nan=True)


def _bad_rows_parquet(path):
    """Four rows: two good, a bad MMSI and a latitude out of range (no position)."""
    pq.write_table(pa.table({
        "mmsi": pa.array([219000001, 123, 219000001, 219000001]),
        "time_utc": pa.array(pd.date_range("2025-01-01", periods=4, freq="min").to_numpy()),
        "lat": pa.array([55.0, 55.0, 91.0, 55.001]), "lon": pa.array([12.0, 12.0, 12.0, 12.0]),
        "sog": pa.array([10.0, None, 10.0, 10.5]), "name": pa.array(["ALPHA", "BRAVO", None, "ALPHA"]),
    }), path)
    return path


def _quarantine(db) -> list[tuple]:
    with open_workspace(db) as ws:
        return ws.con.execute("SELECT line, reason, raw FROM ais_quarantine ORDER BY line").fetchall()


def test_quarantined_parquet_rows_keep_their_text(tmp_path):
    """A plain Parquet file is staged without its rows' text, which the commit reads from the
    file for the quarantined rows only; a compressed one (its decompressed copy is gone by the
    commit) is staged with it. Both give the text by hand: the values joined by commas, a
    missing one empty."""
    plain = _bad_rows_parquet(tmp_path / "day.parquet")
    packed = tmp_path / "other.parquet.gz"
    with plain.open("rb") as src, gzip.open(packed, "wb") as out:
        shutil.copyfileobj(src, out)
    want = [(2, "bad_mmsi", "123,2025-01-01 00:01:00,55.0,12.0,,BRAVO"),
            (3, "no_position", "219000001,2025-01-01 00:02:00,91.0,12.0,10.0,")]
    for src in (plain, packed):
        s = ingest_paths([src], tmp_path / f"{src.name}.duckdb")
        assert s["loaded"] == 2 and _quarantine(tmp_path / f"{src.name}.duckdb") == want, src.name


def test_a_file_where_the_dataset_folder_goes_is_one_error_line(tmp_path):
    """``stormlane ingest-ais ais.parquet --db ais.duckdb``: the workspace's positions dataset
    folder would be ``ais.parquet``, the input itself. One error line naming both, before the
    workspace is made; the input untouched."""
    src = _bad_rows_parquet(tmp_path / "ais.parquet")
    before = src.read_bytes()
    r = subprocess.run([sys.executable, "-m", "pipelines.cli", "ingest-ais", str(src), "--db",
                        str(tmp_path / "ais.duckdb")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: workspace ") and "ais.parquet" in lines[0], r.stderr
    assert "but that is a file" in lines[0]
    assert src.read_bytes() == before and not (tmp_path / "ais.duckdb").exists()


def _three_vessels(path, **statics):
    """Six rows, two per vessel a minute apart, with the static columns ``statics``."""
    n = 6
    pq.write_table(pa.table({
        "mmsi": pa.array([219000001, 219000001, 219000002, 219000002, 219000003, 219000003]),
        "time_utc": pa.array(pd.date_range("2025-01-01", periods=n, freq="min").to_numpy()),
        "lat": pa.array(55.0 + np.arange(n) * 1e-4), "lon": pa.array(np.full(n, 12.0)),
        **{name: pa.array(values) for name, values in statics.items()},
    }), path)
    return path


def test_static_numbers_are_typed_from_their_text_whether_staged_or_read_at_the_commit(tmp_path):
    """The static values of a plain Parquet file are read from it for the latest row of each
    vessel's distinct values only (found by a hash of them); a compressed copy stages every
    row's text. Both give the vessels by hand: a 4-byte float length 0.1 is 0.1 (its shortest
    text), not 0.100000001490116; 0.0 and -0.0 are missing; the latest value of each vessel
    wins, a missing one does not."""
    src = _three_vessels(tmp_path / "statics.parquet",
                         length=np.array([0.1, 120.5, 0.0, -0.0, 33.25, 0.1], np.float32),
                         vessel_type=np.array([70, 71, 0, 80, 99, 100], np.int16),
                         vessel_name=["A", " B ", None, "C", "D", "unknown"])
    packed = tmp_path / "statics2.parquet.gz"
    with src.open("rb") as f, gzip.open(packed, "wb") as out:
        shutil.copyfileobj(f, out)
    want = [(219000001, 120.5, 71, "B"), (219000002, None, 80, "C"), (219000003, 0.1, 99, "D")]
    for p in (src, packed):
        db = tmp_path / f"{p.name}.duckdb"
        ingest_paths([p], db)
        with open_workspace(db) as ws:
            got = ws.con.execute("SELECT mmsi, length_m, ship_type, name FROM vessels ORDER BY mmsi").fetchall()
        assert got == want, p.name


def test_a_text_field_written_as_floats_keeps_each_values_own_text(tmp_path):
    """DuckDB's hash and grouping take 0.0 and -0.0, and NaN and -NaN, as one value, whose texts
    differ: the latest row's own text wins, as when every row's text is staged."""
    src = _three_vessels(tmp_path / "signs.parquet", call_sign=np.array([0.0, -0.0, -0.0, 0.0, np.nan, -np.nan]))
    ingest_paths([src], tmp_path / "w.duckdb")
    with open_workspace(tmp_path / "w.duckdb") as ws:
        got = ws.con.execute("SELECT mmsi, callsign FROM vessels ORDER BY mmsi").fetchall()
    assert got == [(219000001, "-0.0"), (219000002, "0.0"), (219000003, "-nan")]


@pytest.mark.parametrize("layout", ["columns", "geometry"])
def test_four_byte_float_fields_are_the_decimals_they_were_written_from(tmp_path, layout):
    """A binary32 SOG of 5.9 is 5.9 (as the row's CSV text reads), not 5.900000095...: the SQL
    stage and the pure reader give the shortest decimal that reads back as the stored float
    (numpy's text of it, the reference here), a missing or NaN value is missing."""
    from ais.io.parquet import read_parquet_stage

    lat = np.array([55.123456, 55.5, -33.8675, 0.0001, 89.99999, 55.2], np.float32)
    lon = np.array([12.654321, -0.1, 151.207, -179.99, 10.0, 12.3], np.float32)
    sog = np.array([5.9, 12.3, 0.1, 22.3, np.nan, 7.7], np.float32)
    cog = np.array([359.9, 0.0, 181.5, 300.1, 42.42, np.nan], np.float32)
    heading = np.array([270.5, 0, 359, 77.7, 1, 2], np.float32)
    n = len(lat)
    cols = {"mmsi": pa.array([219000001 + i for i in range(n)]),
            "time_utc": pa.array(pd.date_range("2025-01-01", periods=n, freq="min").to_numpy()),
            "sog_kn": pa.array(sog), "cog_deg": pa.array(cog), "heading_deg": pa.array(heading)}
    if layout == "columns":
        cols.update(lat=pa.array(lat), lon=pa.array(lon))
    else:  # the positions as WKB points of doubles (the widened decimals), the rest binary32
        cols["geometry"] = pa.array([struct.pack("<BIdd", 1, 1, float(str(x)), float(str(y))) for x, y in zip(lon, lat)])
    src = tmp_path / "f32.parquet"
    pq.write_table(pa.table(cols), src)

    def decimal(v):
        return None if np.isnan(v) else float(str(v))

    want = [tuple(decimal(a[i]) for a in (lat, lon, sog, cog, heading)) for i in range(n)]
    assert want[0][2] == 5.9 != float(sog[0])  # the two readings differ: the test can tell them apart
    ingest_paths([src], tmp_path / "w.duckdb")
    with open_workspace(tmp_path / "w.duckdb") as ws:
        got = ws.con.execute("SELECT lat_deg, lon_deg, sog_kn, cog_deg, heading_deg FROM ais_positions "
                             "ORDER BY mmsi").fetchall()
    assert got == want
    stage = read_parquet_stage(src)[0]
    pure = [tuple(None if pd.isna(v) else float(v) for v in row)
            for row in stage[["lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg"]].itertuples(index=False)]
    assert pure == want


def test_a_wkb_point_is_written_as_duckdbs_st_astext_writes_it():
    """The pure path's WKT of a 2D point (ais.io.parquet.geometry_text) against DuckDB's
    ST_AsText, the bulk path's: AIS-like coordinates, 6-decimal ones, whole degrees, 100 k
    random bit patterns (every magnitude, NaN payloads), signed zeros, NaN with and without its
    sign bit, infinities, subnormals; both byte orders."""
    import struct

    import duckdb
    import numpy as np
    import pyarrow as pa

    from ais.io.parquet import geometry_text

    rng = np.random.default_rng(23)
    neg_nan = struct.unpack("<d", struct.pack("<Q", 0xFFF8000000000000))[0]
    special = [0.0, -0.0, float("nan"), neg_nan, float("inf"), -float("inf"), 5e-324, -5e-324, 1e16, 1e-5, 1e22, 0.1]
    x = np.concatenate([rng.uniform(-180, 180, 20_000), np.round(rng.uniform(-180, 180, 20_000), 6),
                        rng.integers(-180, 181, 2_000).astype(float), rng.integers(0, 2**64, 100_000, dtype=np.uint64).view(np.float64),
                        np.repeat(special, len(special))])
    y = np.concatenate([rng.uniform(-90, 90, 20_000), np.round(rng.uniform(-90, 90, 20_000), 6),
                        rng.integers(-90, 91, 2_000).astype(float), rng.integers(0, 2**64, 100_000, dtype=np.uint64).view(np.float64),
                        np.tile(special, len(special))])
    blobs = [struct.pack("<BIdd" if i % 2 else ">BIdd", 1 if i % 2 else 0, 1, a, b) for i, (a, b) in enumerate(zip(x, y))]
    con = duckdb.connect()
    con.register("points", pa.table({"g": pa.array(blobs, pa.binary())}))
    want = [r[0] for r in con.sql("SELECT ST_AsText(ST_GeomFromWKB(g)) FROM points").fetchall()]
    got = [geometry_text(b) for b in blobs]
    assert got == want
    assert got[-1] == "POINT (0.1 0.1)" and "POINT (-nan -inf)" in got and "POINT EMPTY" in got


def test_dma_status_words_are_statuses_in_parquet_as_in_csv(tmp_path):
    """A DMA CSV file converted to Parquet keeps its status words (``Under way using engine``):
    they are the statuses the CSV readers take (ITU-R M.1371-5 codes), in the SQL stage and the
    pure reader alike; a number as text is a number; a word not known is ``bad_nav_status``.
    Every row was quarantined as ``bad_nav_status`` before."""
    from ais.io.parquet import read_parquet_stage

    status = ["Under way using engine", " moored ", "At anchor", "5", None, "Sailing along"]
    src = _three_vessels(tmp_path / "words.parquet", nav_status=status)
    want = [0.0, 5.0, 1.0, 5.0, None, None]
    ingest_paths([src], tmp_path / "w.duckdb")
    with open_workspace(tmp_path / "w.duckdb") as ws:
        loaded = dict(ws.con.execute("SELECT lat_deg, nav_status FROM ais_positions").fetchall())
        bad = ws.con.execute("SELECT line, reason FROM ais_quarantine").fetchall()
    assert [loaded.get(55.0 + i * 1e-4) for i in range(5)] == want[:5]
    assert bad == [(6, "bad_nav_status")]
    stage = read_parquet_stage(src)[0]
    assert [None if pd.isna(v) else v for v in stage["nav_status"]] == want
    assert list(stage["parse_error"].fillna("")) == ["", "", "", "", "", "bad_nav_status"]


def test_a_parquet_file_of_quarantined_rows_stays_within_duckdbs_memory(tmp_path, monkeypatch):
    """Every row quarantined, each with its text read back from the file at the commit: joined
    into the quarantine's insert, not updated into a temporary table first (that ``UPDATE`` ran
    out of DuckDB's 1 GB on a 2.9 M-row file; here 300,000 rows under a 72 MB limit, where it needed more than 80 MB)."""
    from pipelines.storage.ais import commit

    monkeypatch.setattr(commit, "INGEST_MEMORY_LIMIT_MB", 72)
    n = 300_000
    pq.write_table(pa.table({
        "mmsi": pa.array(np.arange(n) % 500 + 219000000),
        "time_utc": pa.array(pd.Timestamp("2025-01-01") + pd.to_timedelta(np.arange(n), "s")),
        "lat": pa.array(np.full(n, 55.0)), "lon": pa.array(np.full(n, 12.0)),
        "nav_status": pa.array(["Under way, and more words than any status has"] * n),
    }), tmp_path / "bad.parquet")
    s = ingest_paths([tmp_path / "bad.parquet"], tmp_path / "w.duckdb")
    assert (s["loaded"], s["quarantined"]) == (0, n)
    with open_workspace(tmp_path / "w.duckdb") as ws:
        assert ws.con.execute("SELECT count(*), count(DISTINCT line), min(line), max(line), "
                              "count(*) FILTER (WHERE raw LIKE '219000499,2025-01-0_ %,55.0,12.0,Under way, and more words than any status has') "
                              "FROM ais_quarantine").fetchone() == (n, n, 1, n, n // 500)


def test_a_geoparquet_file_with_a_value_that_is_no_wkb_loads_its_other_rows(tmp_path):
    """DuckDB 1.5 reads a GeoParquet file's WKB column (``geo`` metadata) as its GEOMETRY type:
    one value that is no WKB failed the whole file ("Unexpected end of binary data"), and a
    quarantined row's text could not be built. The column is read as the bytes it stores: the
    points load, the other value is a bad position with its bytes as text (as DuckDB casts a
    BLOB), a point out of range is quarantined with its WKT."""
    points = [struct.pack("<BIdd", 1, 1, 12.0 + k * 1e-3, 55.0) for k in range(4)]
    points[2] = b"xx"
    points[3] = struct.pack("<BIdd", 1, 1, 12.0, 95.0)
    geo = (b'{"version":"1.1.0","primary_column":"geometry","columns":{"geometry":'
           b'{"encoding":"WKB","geometry_types":["Point"]}}}')
    table = pa.table({"mmsi": pa.array([219000001] * 4),
                      "time_utc": pa.array(pd.date_range("2025-01-01", periods=4, freq="min").to_numpy()),
                      "geometry": pa.array(points)}).replace_schema_metadata({b"geo": geo})
    pq.write_table(table, tmp_path / "geo.parquet")
    s = ingest_paths([tmp_path / "geo.parquet"], tmp_path / "w.duckdb")
    assert (s["loaded"], s["quarantined"]) == (2, 2)
    assert _quarantine(tmp_path / "w.duckdb") == [
        (3, "bad_lat", "219000001,2025-01-01 00:02:00,xx"),
        (4, "bad_lat", "219000001,2025-01-01 00:03:00,POINT (12 95)")]
