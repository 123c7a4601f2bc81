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
