"""The speed-jump check against stored tracks reads each vessel's latest stored fix
(``ais_track_ends``), not the stored history, when a file continues the tracks (issue 23).

Reference: the pure path (:func:`ais.clean.clean_positions` with every stored position of file 1
as context), i.e. what the whole-history join of the previous SQL gave. Three vessels cross the
file boundary: A jumps with the first fix of file 2 (context = its track end only), B's file-2
fixes fall between its stored fixes (overlap: the stored history is read) with one jump, C
continues cleanly, D's only fix in file 2 is a jump that only its track end shows. Both staging paths of file 2 (raw lines: SQL for every MMSI; compiled scan:
the streaming pass, SQL for B) must quarantine the same lines.
"""

from __future__ import annotations

import pytest

from ais.clean import clean_positions
from ais.io.csv_formats import read_csv_stage
from ais_fixtures import DMA_HEADER, dma_row, write_dma
from pipelines import ingest_stage as stage_mod
from pipelines.ingest import ingest_paths
from pipelines.storage import open_workspace

A, B, C, D = "219000001", "219000002", "219000003", "219000004"


def _ts(minute: int) -> str:
    return f"01/01/2025 {minute // 60:02d}:{minute % 60:02d}:00"


def _file1() -> list[str]:
    rows = [DMA_HEADER]
    for m in range(0, 21, 2):  # 0.005 deg lon per minute at 55 N: about 10.3 kn
        rows.append(dma_row(_ts(m), A, "55.000000", f"{11.0 + 0.005 * m:.6f}"))
        rows.append(dma_row(_ts(m), B, "56.000000", f"{11.0 + 0.005 * m:.6f}"))
        rows.append(dma_row(_ts(m), C, "57.000000", f"{11.0 + 0.005 * m:.6f}"))
        rows.append(dma_row(_ts(m), D, "58.000000", f"{11.0 + 0.005 * m:.6f}"))
    return rows


def _file2() -> list[str]:
    rows = [DMA_HEADER,
            dma_row(_ts(21), A, "56.000000", "11.105000"),   # line 2: 60 nmi in 1 min from A's track end
            dma_row(_ts(22), A, "55.000000", "11.110000"),   # line 3: back on track
            dma_row(_ts(24), A, "55.000000", "11.120000"),   # line 4
            dma_row(_ts(5), B, "56.000000", "11.025000"),    # line 5: between stored 4 and 6 min
            dma_row(_ts(7), B, "56.500000", "11.035000"),    # line 6: 30 nmi off between stored fixes
            dma_row(_ts(9), B, "56.000000", "11.045000"),    # line 7
            dma_row(_ts(23), B, "56.000000", "11.115000"),   # line 8: after B's track end
            dma_row(_ts(22), C, "57.000000", "11.110000"),   # line 9
            dma_row(_ts(24), C, "57.000000", "11.120000"),   # line 10
            dma_row(_ts(21), D, "58.500000", "11.105000")]   # line 11: D's only fix, 30 nmi off its end
    return rows


@pytest.mark.parametrize("staging", ["lines", "scan"])
def test_jump_across_files_same_as_whole_history(tmp_path, monkeypatch, staging):
    if staging == "scan":
        monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", 0)
        monkeypatch.setattr(stage_mod, "FAST_CSV_ENGINES", ("scan",))
    else:
        monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", 1 << 40)
    f1 = write_dma(tmp_path / "day1.csv", _file1())
    f2 = write_dma(tmp_path / "day2.csv", _file2())
    db = tmp_path / "ws.duckdb"
    ingest_paths([f1], db)
    with open_workspace(db) as ws:
        stored = ws.con.execute(
            "SELECT mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, nav_status FROM ais_positions"
        ).fetchdf()
        ends = dict(ws.con.execute("SELECT mmsi, epoch(time_utc) FROM ais_track_ends").fetchall())
    assert len(stored) == 44 and set(ends) == {int(A), int(B), int(C), int(D)}
    s2 = ingest_paths([f2], db)
    assert s2["per_file"][0]["staging"] == staging
    with open_workspace(db) as ws:
        got = dict(ws.con.execute("SELECT line, reason FROM ais_quarantine WHERE file_id = 2").fetchall())
        ends2 = dict(ws.con.execute("SELECT mmsi, epoch(time_utc) FROM ais_track_ends").fetchall())
    pure = clean_positions(read_csv_stage(f2)[0], existing=stored)
    assert got == dict(zip(pure.quarantine.line, pure.quarantine.reason))
    assert got == {2: "speed_jump", 6: "speed_jump", 11: "speed_jump"}
    assert s2["loaded"] == 7
    # the track ends moved to each vessel's latest kept fix (B's 23 min, not the stored 20 min)
    assert ends2 == {int(A): ends[int(A)] + 240, int(B): ends[int(B)] + 180, int(C): ends[int(C)] + 240,
                     int(D): ends[int(D)]}


def test_large_gzip_is_decompressed_once_and_loads_like_the_gzip_stream(tmp_path, monkeypatch):
    # A gzip file at or above GZIP_PLAIN_MIN_BYTES is decompressed into a plain copy (hashed
    # on the way) and scanned; below it the raw-lines path reads the gzip stream. Same
    # workspace, same fingerprint as ais.io.files.fingerprint, the copy removed afterwards.
    import gzip

    from ais.io.files import fingerprint
    from pipelines.ingest import ingest_file
    from test_ais_fast_csv import DIRTY, _mix, _rows, _snapshot

    data = ("\n".join([DMA_HEADER] + _mix(_rows(), DIRTY)) + "\n").encode()
    gz = tmp_path / "day.csv.gz"
    gz.write_bytes(gzip.compress(data[: len(data) // 2]) + gzip.compress(data[len(data) // 2:]))  # 2 members
    monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", 0)
    snaps = {}
    for label, min_gz in (("copy", 0), ("stream", 1 << 40)):
        monkeypatch.setattr(stage_mod, "GZIP_PLAIN_MIN_BYTES", min_gz)
        (tmp_path / label).mkdir()
        db = tmp_path / label / "ws.duckdb"
        with open_workspace(db) as ws:
            counts = ingest_file(ws, gz)
            fp = ws.con.execute("SELECT fingerprint FROM ais_files").fetchone()[0]
        assert counts["staging"] == ("scan" if label == "copy" else "lines")
        assert fp == fingerprint(gz)
        assert sorted(p.name for p in (tmp_path / label).iterdir()) == ["ws.duckdb", "ws.parquet"]
        snaps[label] = _snapshot(db)
    assert counts["quarantined"] >= 10 and snaps["copy"] == snaps["stream"]


def test_truncated_large_gzip_is_an_error_naming_it(tmp_path, monkeypatch):
    import gzip

    from ais.errors import AisInputError
    from test_ais_fast_csv import _rows

    data = ("\n".join([DMA_HEADER] + _rows()) + "\n").encode()
    gz = tmp_path / "cut.csv.gz"
    gz.write_bytes(gzip.compress(data)[:-100])
    monkeypatch.setattr(stage_mod, "GZIP_PLAIN_MIN_BYTES", 0)
    with pytest.raises(AisInputError, match="cut.csv.gz.*truncated gzip"):
        ingest_paths([gz], tmp_path / "ws.duckdb")
    assert not list(tmp_path.glob(".stormlane-gunzip-*"))


def _day_files(tmp_path, n=3):
    """``n`` gzip DMA files continuing each other's tracks (time slices of one fleet), with the
    dirty rows of the fast-stage tests mixed into each."""
    import gzip

    from test_ais_fast_csv import DIRTY, _mix, _rows

    rows = _rows()
    step = len(rows) // n
    paths = []
    for k in range(n):
        part = _mix(rows[k * step:(k + 1) * step], DIRTY)
        path = tmp_path / "in" / f"day{k}.csv.gz"
        path.parent.mkdir(exist_ok=True)
        path.write_bytes(gzip.compress(("\n".join([DMA_HEADER] + part) + "\n").encode()))
        paths.append(path)
    return paths


def _tables(db):
    with open_workspace(db) as ws:
        return [ws.con.execute(sql).fetchall() for sql in (
            "SELECT path, fingerprint, n_read, n_loaded, n_quarantined, n_duplicates, reasons FROM ais_files ORDER BY file_id",
            "SELECT file_id, source_line, mmsi, time_utc, lat_deg, lon_deg, sog_kn FROM ais_positions ORDER BY ALL",
            "SELECT file_id, line, reason, raw FROM ais_quarantine ORDER BY ALL")]


def test_plain_copies_made_ahead_load_the_same_and_leave_nothing(tmp_path, monkeypatch):
    # ingest_paths makes the next large gzip file's plain copy in a thread while the current one
    # is committed (PlainCopiesAhead): the workspace is that of one file at a time, every copy
    # is removed, and the copies of the files after the first were made on the copy thread.
    import threading

    from pipelines.ingest import ingest_file

    paths = _day_files(tmp_path)
    monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", 0)
    monkeypatch.setattr(stage_mod, "GZIP_PLAIN_MIN_BYTES", 0)
    threads = []
    copy = stage_mod.plain_copy
    monkeypatch.setattr(stage_mod, "plain_copy",
                        lambda f, folder, prefix: threads.append((f.path.name, threading.current_thread().name))
                        or copy(f, folder, prefix))
    (tmp_path / "ahead").mkdir()
    (tmp_path / "one").mkdir()
    s = ingest_paths(paths, tmp_path / "ahead" / "ws.duckdb")
    assert [n for n, t in threads if t.startswith("plain-copy")] == ["day1.csv.gz", "day2.csv.gz"]
    assert [f["staging"] for f in s["per_file"]] == ["scan"] * 3 and s["quarantined"] >= 30
    with open_workspace(tmp_path / "one" / "ws.duckdb") as ws:
        for p in paths:
            ingest_file(ws, p)
    assert _tables(tmp_path / "ahead" / "ws.duckdb") == _tables(tmp_path / "one" / "ws.duckdb")
    for label in ("ahead", "one"):
        assert sorted(p.name for p in (tmp_path / label).iterdir()) == ["ws.duckdb", "ws.parquet"]


def test_plain_copies_ahead_of_a_truncated_or_repeated_file(tmp_path, monkeypatch):
    # The copy of a truncated file fails on the copy thread; the error is raised in the file's
    # own turn, naming it, after the files before it are committed. A file with the bytes of one
    # loaded before (its copy made ahead, its quick key only known once the first is committed)
    # is skipped. No copy is left behind either way.
    from ais.errors import AisInputError

    paths = _day_files(tmp_path)
    monkeypatch.setattr(stage_mod, "GZIP_PLAIN_MIN_BYTES", 0)
    again = tmp_path / "in" / "again.csv.gz"
    again.write_bytes(paths[0].read_bytes())
    s = ingest_paths([paths[0], again, paths[1]], tmp_path / "ws.duckdb")
    assert [f["already_loaded"] for f in s["per_file"]] == [False, True, False]
    paths[2].write_bytes(paths[2].read_bytes()[:-100])
    with pytest.raises(AisInputError, match=r"day2\.csv\.gz: truncated gzip.*\(the 1 file\(s\) before it are loaded"):
        ingest_paths([paths[1], paths[2], paths[0]], tmp_path / "ws2.duckdb")  # day0's copy made ahead
    with open_workspace(tmp_path / "ws2.duckdb") as ws:
        assert ws.con.execute("SELECT path FROM ais_files").fetchall() == [(str(paths[1]),)]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "ws.duckdb", "ws.parquet", "ws2.duckdb", "ws2.parquet"]
