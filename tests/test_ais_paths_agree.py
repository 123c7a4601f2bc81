"""The two executions of the cleaning rules agree: DuckDB SQL (bulk ingest) and pandas (pure)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ais_fixtures import DMA_LINES, dma_row, write_dma
from conftest import shared_file
from ais.clean import clean_positions, conform_stage
from ais.io.csv_formats import DMA_SPEC, read_csv_stage, resolve_columns, split_csv_line
from ais.io.nmea import read_nmea
from ais.io.parquet import read_parquet_stage
from pipelines.ingest import ingest_paths
from pipelines.storage import open_workspace
from pipelines.storage import ais as store


def sql_result(db):
    with open_workspace(db) as ws:
        q = ws.con.execute("SELECT line, reason FROM ais_quarantine ORDER BY file_id, line").fetchdf()
        p = store.read_positions(ws)
        v = store.read_vessels(ws)
    return q, p, v


def assert_frames_equal(a: pd.DataFrame, b: pd.DataFrame):
    a = a.reset_index(drop=True)
    b = b.reset_index(drop=True)
    assert list(a.columns) == list(b.columns)
    assert len(a) == len(b)
    for c in a.columns:
        x, y = a[c], b[c]
        if pd.api.types.is_float_dtype(x) or pd.api.types.is_float_dtype(y):
            xa, ya = x.to_numpy(dtype=float), y.to_numpy(dtype=float)
            assert np.array_equal(xa, ya, equal_nan=True), c
        else:
            xo = x.astype(object).where(x.notna(), None).tolist()
            yo = y.astype(object).where(y.notna(), None).tolist()
            assert xo == yo, c


def compare(pure, db, existing=None):
    q, p, v = sql_result(db)
    res = pure
    counts = {k: res.counts[k] for k in ("read", "loaded", "quarantined", "duplicates", "reasons")}
    assert dict(zip(q.line, q.reason)) == dict(zip(res.quarantine.line, res.quarantine.reason))
    cols = ["mmsi", "time_utc", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status"]
    assert_frames_equal(p[cols], res.positions[cols])
    vcols = ["mmsi", "imo", "name", "callsign", "ship_type", "length_m", "beam_m", "draught_m", "destination"]
    assert_frames_equal(v[vcols], res.vessels[vcols])
    return counts


def test_dma_fixture_same_in_sql_and_pandas(tmp_path):
    src = write_dma(tmp_path / "day.csv")
    s = ingest_paths([src], tmp_path / "ws.duckdb")
    stage, meta = read_csv_stage(src)
    pure = clean_positions(stage)
    counts = compare(pure, tmp_path / "ws.duckdb")
    assert counts == {k: s[k] for k in counts}
    assert meta["ignored"] == s["ignored"]


@pytest.mark.parametrize("staging", ["lines", "fast", "arrow", "scan"])
def test_csv_typing_same_in_sql_and_pandas(tmp_path, staging):
    lines = list(DMA_LINES) + [
        dma_row(" 01/01/2025 00:20:00 ", " 219000005 ", " 55.5 ", "\t11.5", sog="nan", cog="1e2", hdg="+90",
                status="5", imo="IMO1234567", ship="70", width="0", length="-3", draught="abc", dest="Unknown"),
        dma_row("1/1/2025 0:21:00", "219000005", "55.5", "11.5", sog="1__0", cog="inf", hdg="", status="",
                ship="Towing long/wide", name="  "),
        dma_row("01/01/2025 00:22:00", "219000005", "55.5", "11.5", name='"Q ""QUOTED"", NAME"'),
        '01/01/2025 00:23:00,"unterminated,219000005,55.5,11.5',
        "   ",
    ]
    src = write_dma(tmp_path / "edge.csv", lines)
    pure, _ = read_csv_stage(src)
    header = split_csv_line(DMA_LINES[0])
    index = resolve_columns(DMA_SPEC, header, src)
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        if staging == "lines":
            store.stage_csv(ws, src, False, DMA_SPEC, index, len(header), DMA_LINES[0])
        elif staging == "scan":  # the compiled scan (non-canonical lines typed from their text)
            info = store.stage_csv_scan(ws, src, DMA_SPEC, index, len(header), DMA_LINES[0])
            assert info is not None and info["staging"] == "scan" and info["exact_lines"] >= 10
            try:
                sql = store.read_stage(ws)
            finally:
                info["line_index"].close()
        else:  # a scanner-split stage (rows rejected for their field count typed from their text)
            from ais.io.lineindex import LineIndex

            stager, label = {"fast": (store.stage_csv_fast, "typed"), "arrow": (store.stage_csv_arrow, "arrow")}[staging]
            with LineIndex(src) as ix:
                info = stager(ws, src, DMA_SPEC, index, len(header), DMA_LINES[0], ix)
                assert info is not None and info["staging"] == label
                sql = store.read_stage(ws)
        if staging == "lines":
            sql = store.read_stage(ws)
    assert_frames_equal(sql, conform_stage(pure))
    # A few of the edge cases, spelled out.
    row = pure.set_index("line")
    assert row.loc[23, "mmsi"] == 219000005 and row.loc[23, "lat_deg"] == 55.5 and row.loc[23, "parse_error"] == "bad_sog"
    assert row.loc[23, "cog_deg"] == 100.0 and row.loc[23, "heading_deg"] == 90.0 and row.loc[23, "imo"] == 1234567
    assert pd.isna(row.loc[23, "beam_m"]) and pd.isna(row.loc[23, "length_m"]) and pd.isna(row.loc[23, "destination"])
    assert row.loc[24, "time_utc"] == pd.Timestamp("2025-01-01T00:21:00Z") and row.loc[24, "ship_type"] == 32
    assert row.loc[24, "parse_error"] == "bad_sog"  # "1__0" is not a number ("1_0" would be 10)
    assert row.loc[25, "name"] == 'Q "QUOTED", NAME'
    assert row.loc[26, "parse_error"] == "bad_line" and row.loc[27, "parse_error"] == "bad_line"


def test_two_files_with_stored_context_agree(tmp_path):
    # File 2 overlaps file 1 (duplicates against the workspace) and has a jump relative to a
    # fix stored by file 1.
    f1 = write_dma(tmp_path / "a.csv")
    lines2 = [DMA_LINES[0], DMA_LINES[2], DMA_LINES[3],
              dma_row("01/01/2025 00:01:00", "219000001", "55.000000", "11.006000"),
              dma_row("01/01/2025 00:01:30", "219000001", "57.000000", "11.006000"),
              dma_row("01/01/2025 00:02:30", "219000001", "55.000000", "11.0125")]
    f2 = write_dma(tmp_path / "b.csv", lines2)
    db = tmp_path / "ws.duckdb"
    ingest_paths([f1], db)
    s2 = ingest_paths([f2], db)
    with open_workspace(db) as ws:
        stored_after_1 = ws.con.execute(
            "SELECT mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, nav_status FROM ais_positions "
            "WHERE file_id = 1").fetchdf()
        q2 = ws.con.execute("SELECT line, reason FROM ais_quarantine WHERE file_id = 2 ORDER BY line").fetchdf()
    stage2, _ = read_csv_stage(f2)
    pure2 = clean_positions(stage2, existing=stored_after_1)
    assert dict(zip(q2.line, q2.reason)) == dict(zip(pure2.quarantine.line, pure2.quarantine.reason))
    assert dict(zip(q2.line, q2.reason)) == {2: "duplicate", 3: "duplicate", 4: "duplicate_time", 5: "speed_jump"}
    assert s2["loaded"] == pure2.counts["loaded"] == 1


def test_real_files_agree(shared_data, tmp_path):
    cases = [
        ("ais/noaa_marinecadastre_20230111_sample.csv", lambda p: read_csv_stage(p)[0]),
        ("ais/portcalls/nyharbor_marinecadastre_20210101.parquet", lambda p: read_parquet_stage(p)[0]),
        ("ais/nmea/dma_ais-sample_20131112.nmea.gz", lambda p: read_nmea(p)[0]),
        ("ais/nmea/dma_aislib_stream_example_20100611.nmea", lambda p: read_nmea(p)[0]),
    ]
    for i, (rel, reader) in enumerate(cases):
        path = shared_file(shared_data, rel)
        db = tmp_path / f"ws{i}.duckdb"
        s = ingest_paths([path], db)
        pure = clean_positions(reader(path))
        counts = compare(pure, db)
        assert counts == {k: s[k] for k in counts}, rel


@pytest.mark.parametrize("limit", [5.0, 30.0, 60.0])
def test_jump_limit_agrees(tmp_path, limit):
    src = write_dma(tmp_path / "day.csv")
    db = tmp_path / "ws.duckdb"
    ingest_paths([src], db, max_speed_kn=limit)
    compare(clean_positions(read_csv_stage(src)[0], max_speed_kn=limit), db)


@pytest.mark.parametrize("first_cog, second_cog, reason", [("", "90.0", "duplicate_time"), ("90.0", "", "duplicate_time"),
                                                           ("", "", "duplicate"), ("90.0", "90.0", "duplicate")])
def test_same_time_twin_with_an_empty_field_conflicts(tmp_path, first_cog, second_cog, reason):
    """An empty field is a value (NULL) in the comparison of same-MMSI-same-time rows: a row
    equal to its earlier twin except that one of them has no COG is ``duplicate_time``, not an
    exact duplicate (found by the fuzz test: pandas' groupby "first" skipped the NULL)."""
    src = write_dma(tmp_path / "twin.csv", [DMA_LINES[0],
                                            dma_row("01/01/2025 00:00:00", "219000001", "55.000000", "11.000000", cog=first_cog),
                                            dma_row("01/01/2025 00:00:00", "219000001", "55.000000", "11.000000", cog=second_cog)])
    s = ingest_paths([src], tmp_path / "ws.duckdb")
    pure = clean_positions(read_csv_stage(src)[0])
    counts = compare(pure, tmp_path / "ws.duckdb")
    assert counts["reasons"] == {reason: 1} == s["reasons"]
    assert dict(zip(pure.quarantine.line, pure.quarantine.reason)) == {3: reason}


def _geoparquet(path, geometry, n: int = 8):
    """A NOAA-2024-like GeoParquet file: snake_case columns, positions only in ``geometry``."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({
        "mmsi": pa.array([219000001 + i % 2 for i in range(n)], pa.int64()),
        "base_date_time": pa.array(pd.date_range("2024-01-01", periods=n, freq="min").to_numpy()),
        "sog": pa.array([10.0] * n), "vessel_name": pa.array(["ALPHA", "BRAVO"] * (n // 2)), "geometry": geometry,
    }), path)
    return path


def _wkb_points(n: int = 8) -> list:
    """Points 1 min apart at ~3.6 kn, in every WKB form a writer uses, and the values that are no point."""
    import struct

    pts = [(8.0 + i * 1e-3, 54.0 + i * 2e-4) for i in range(n)]
    vals = [struct.pack("<BIdd", 1, 1, *p) for p in pts]
    vals[1] = struct.pack(">BIdd", 0, 1, *pts[1])  # big-endian
    vals[2] = struct.pack("<BIIdd", 1, 0x20000001, 4326, *pts[2])  # EWKB with an SRID (PostGIS)
    vals[3] = struct.pack("<BIddd", 1, 1001, *pts[3], 5.0)  # ISO point Z
    vals[4] = struct.pack("<BII", 1, 3, 0)  # an empty polygon: no position
    vals[5] = struct.pack("<BIdd", 1, 1, float("nan"), float("nan"))  # POINT EMPTY
    vals[6] = None
    return vals


@pytest.mark.parametrize("encoding", ["wkb", "struct"])
def test_geoparquet_positions_from_the_geometry_agree(tmp_path, encoding):
    """A GeoParquet file without latitude and longitude columns (NOAA's daily files from 2024 on):
    the positions from its point geometry, WKB or GeoArrow's native struct, the same in SQL and
    pandas, with the points by hand and the values that are no point quarantined."""
    import pyarrow as pa

    wkb = _wkb_points()
    if encoding == "wkb":
        geometry = pa.array(wkb, pa.binary())
    else:
        from ais.io.parquet import wkb_point_xy

        x, y = wkb_point_xy(geometry := pa.array(wkb, pa.binary()))
        geometry = pa.StructArray.from_arrays([pa.array(x), pa.array(y)], ["x", "y"],
                                              mask=pa.array([v is None for v in wkb]))
    src = _geoparquet(tmp_path / "ais-2024-01-01.parquet", geometry)
    s = ingest_paths([src], tmp_path / "ws.duckdb")
    counts = compare(clean_positions(read_parquet_stage(src)[0]), tmp_path / "ws.duckdb")
    assert counts == {k: s[k] for k in counts}
    # rows 4 (a polygon) and 5 (POINT EMPTY) have a geometry but no position; row 6 none at all
    assert s["read"] == 8 and s["loaded"] == 5 and s["reasons"] == {"bad_lat": 2, "no_position": 1}
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        p = store.read_positions(ws).sort_values("time_utc")
    assert p["lon_deg"].tolist() == [8.0, 8.001, 8.002, 8.003, 8.007]
    assert p["lat_deg"].tolist() == [54.0, 54.0002, 54.0004, 54.0006, 54.0014]
    # staged apart (a Dask worker's private DuckDB) and committed: the same workspace
    from test_ingest_partitioned import _assert_same_workspace, _partitioned

    (spool := tmp_path / "spool").mkdir()
    _partitioned([str(src)], tmp_path / "part.duckdb", spool)
    _assert_same_workspace(tmp_path / "part.duckdb", tmp_path / "ws.duckdb")


def test_a_quarantined_geoparquet_row_shows_its_point_as_wkt(tmp_path):
    """Every row's MMSI is bad, so every row is quarantined with its ``raw`` text: a 2D WKB point
    (either byte order) as ``POINT (x y)`` (DuckDB's ST_AsText; it showed the 21 bytes escaped),
    the other values as their bytes' text; the same in the workspace whether the text is staged
    (a gzip input), read from the file at the commit (a plain one) or spooled from another
    DuckDB (a Dask worker's), and on the pure path."""
    import gzip
    import shutil

    import pyarrow as pa
    import pyarrow.parquet as pq

    from ais.io.parquet import _blob_text

    wkb = _wkb_points()
    src = _geoparquet(tmp_path / "ais-2024-01-01.parquet", pa.array(wkb, pa.binary()))
    pq.write_table(pq.read_table(src).set_column(0, "mmsi", pa.array([123] * 8, pa.int64())), src)
    with open(src, "rb") as f, gzip.open(packed := tmp_path / "ais-2024-01-02.parquet.gz", "wb") as g:
        shutil.copyfileobj(f, g)
    shown = ["POINT (8 54)", "POINT (8.001 54.0002)", _blob_text(wkb[2]), _blob_text(wkb[3]), _blob_text(wkb[4]),
             "POINT EMPTY", "", "POINT (8.007 54.0014)"]
    want = [f"123,2024-01-01 00:0{i}:00,10.0,{'ALPHA' if i % 2 == 0 else 'BRAVO'},{g}" for i, g in enumerate(shown)]
    assert want[0] == "123,2024-01-01 00:00:00,10.0,ALPHA,POINT (8 54)"
    assert read_parquet_stage(src)[0]["raw"].tolist() == want
    from test_ingest_partitioned import _partitioned

    (spool := tmp_path / "spool").mkdir()
    _partitioned([str(src)], tmp_path / "part.duckdb", spool)
    for path, db in ((src, tmp_path / "plain.duckdb"), (packed, tmp_path / "packed.duckdb"), (None, tmp_path / "part.duckdb")):
        if path is not None:
            assert ingest_paths([path], db)["quarantined"] == 8
        with open_workspace(db) as ws:
            assert [r[0] for r in ws.con.execute("SELECT raw FROM ais_quarantine ORDER BY line").fetchall()] == want, db.name


def test_parquet_nan_values_are_missing_on_every_path(tmp_path):
    """A Parquet file with real NaN values (pyarrow, polars or Spark write them; pandas writes
    NULL): a NaN is a missing value on every path. The SQL path once kept it (a NaN read from
    Parquet need not equal 'nan'::DOUBLE) and quarantined NaN positions as bad_lat / bad_lon
    and stored NaN speeds, where the pure and the spooled paths said no_position and NULL."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    nan = np.nan
    src = tmp_path / "nan.parquet"
    pq.write_table(pa.table({
        "mmsi": pa.array([219000001] * 6),
        "time_utc": pa.array(pd.date_range("2025-01-01", periods=6, freq="min").to_numpy()),
        "lat_deg": pa.array(np.array([55.0, nan, 55.001, 55.002, 55.003, 55.004])),
        "lon_deg": pa.array(np.array([12.0, 12.0, nan, 12.0, 12.0, 12.0])),
        "sog_kn": pa.array(np.array([10.0, 10.0, 10.0, nan, 10.0, 10.0])),
        "cog_deg": pa.array(["90", "90", "90", "90", "nan", "east"]),  # text: 'nan' is no number, as the pure path says
        "name": pa.array(["ALPHA"] * 6),
    }), src)
    s = ingest_paths([src], tmp_path / "ws.duckdb")
    counts = compare(clean_positions(read_parquet_stage(src)[0]), tmp_path / "ws.duckdb")
    assert counts == {k: s[k] for k in counts}
    assert s["reasons"] == {"no_position": 2, "bad_cog": 2} and s["loaded"] == 2
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        assert ws.con.execute("SELECT count(*) FROM ais_positions WHERE isnan(sog_kn)").fetchone()[0] == 0
        assert ws.con.execute("SELECT count(*) FROM ais_positions WHERE sog_kn IS NULL").fetchone()[0] == 1
    from test_ingest_partitioned import _assert_same_workspace, _partitioned

    (spool := tmp_path / "spool").mkdir()
    _partitioned([str(src)], tmp_path / "part.duckdb", spool)
    _assert_same_workspace(tmp_path / "part.duckdb", tmp_path / "ws.duckdb")
