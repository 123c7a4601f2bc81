"""AIS ingest into DuckDB: every row loaded, quarantined with a reason, or counted as duplicate."""

from __future__ import annotations

import gzip
import json
import math
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from ais_fixtures import DMA_EXPECTED, DMA_LINES, DMA_LOADED_LINES, dma_row, write_dma
from ais.errors import AisFormatError, AisInputError
from pipelines.ingest import ingest_paths
from pipelines.storage import open_workspace
from pipelines.storage.ais import read_files, read_positions, read_quarantine, read_vessels


def _adds_up(s):
    assert s["read"] == s["loaded"] + s["quarantined"] + s["duplicates"]
    assert sum(s["reasons"].values()) == s["quarantined"] + s["duplicates"]


def test_dma_fixture_every_line_accounted_for(tmp_path, workspace_path):
    src = write_dma(tmp_path / "day.csv")
    s = ingest_paths([src], workspace_path)
    _adds_up(s)
    assert s["read"] == 20  # 22 lines - header - blank line
    assert s["ignored"] == 1
    assert s["loaded"] == len(DMA_LOADED_LINES)
    assert s["duplicates"] == 2 and s["quarantined"] == 13
    with open_workspace(workspace_path) as ws:
        q = read_quarantine(ws)
        pos = ws.con.execute("SELECT source_line FROM ais_positions ORDER BY source_line").fetchall()
        p = read_positions(ws)
        v = read_vessels(ws)
    assert dict(zip(q["line"], q["reason"])) == DMA_EXPECTED
    assert [r[0] for r in pos] == DMA_LOADED_LINES
    # Raw text is the line as written, quotes included.
    assert q.set_index("line").loc[13, "raw"] == DMA_LINES[12]
    # Sentinels became NULL on loaded rows: line 7 (SOG 102.3, COG 360, heading 511), line 19 (SOG 102.2).
    row7 = p[(p.mmsi == 219000001) & (p.time_utc == pd.Timestamp("2025-01-01T00:03:00Z"))].iloc[0]
    assert math.isnan(row7.sog_kn) and math.isnan(row7.cog_deg) and math.isnan(row7.heading_deg)
    assert row7.nav_status == 5.0  # "Moored"
    row19 = p[p.time_utc == pd.Timestamp("2025-01-01T00:14:00Z")].iloc[0]
    assert math.isnan(row19.sog_kn) and row19.cog_deg == 90.0
    # Longitude 180 is stored as -180 (canonical [-180, 180)).
    assert p[p.mmsi == 219000002].lon_deg.tolist() == [-180.0]
    assert str(p.time_utc.dtype) == "datetime64[ns, UTC]"
    # Static data: latest non-missing value per field (line 22's vessel has its own row).
    alpha = v.set_index("mmsi").loc[219000001]
    assert alpha["name"] == "ALPHA" and alpha["ship_type"] == 70 and alpha["imo"] == 9123456
    assert alpha["length_m"] == 120.0 and alpha["beam_m"] == 20.0 and alpha["draught_m"] == 7.5
    assert alpha["callsign"] == "OXAB1" and alpha["destination"] == "AARHUS"


def test_reingest_adds_nothing_and_overlap_counts_duplicates(tmp_path, workspace_path):
    src = write_dma(tmp_path / "day.csv")
    first = ingest_paths([src], workspace_path)
    again = ingest_paths([src], workspace_path)
    assert again["already_loaded"] == 1 and again["read"] == 0 and again["loaded"] == 0
    # Same content under another name, or gzipped (other bytes, same content) -> skipped.
    copy = tmp_path / "copy.csv"
    shutil.copy(src, copy)
    assert ingest_paths([copy], workspace_path)["already_loaded"] == 1
    gz = tmp_path / "day_csv_without_suffix"
    gz.write_bytes(gzip.compress(src.read_bytes()))
    assert ingest_paths([gz], workspace_path)["already_loaded"] == 1
    # Other content repeating the loaded rows (one more, empty, line) -> all duplicates.
    over = tmp_path / "overlap_without_suffix"
    over.write_bytes(gzip.compress(src.read_bytes() + b"\n"))
    s = ingest_paths([over], workspace_path)
    assert s["ignored"] == first["ignored"] + 1
    _adds_up(s)
    assert s["loaded"] == 0
    # Everything loaded the first time is now a duplicate of the stored row.
    assert s["reasons"]["duplicate"] == first["loaded"] + 1  # + line 4, an exact duplicate of line 3
    with open_workspace(workspace_path) as ws:
        assert ws.con.execute("SELECT count(*) FROM ais_positions").fetchone()[0] == first["loaded"]
        files = read_files(ws)
    assert len(files) == 2
    assert (files.n_read == files.n_loaded + files.n_quarantined + files.n_duplicates).all()


def test_crlf_and_stray_carriage_return_read_the_same(tmp_path, workspace_path):
    lf = ingest_paths([write_dma(tmp_path / "lf.csv")], tmp_path / "a.duckdb")
    crlf = ingest_paths([write_dma(tmp_path / "crlf.csv", newline="\r\n")], tmp_path / "b.duckdb")
    for k in ("read", "loaded", "quarantined", "duplicates", "reasons"):
        assert lf[k] == crlf[k]
    # A stray \r inside a field makes DuckDB's CSV scanner refuse the file; the Python line
    # splitter takes over (same rules), and the row (field count intact) loads.
    lines = list(DMA_LINES) + [dma_row("01/01/2025 00:20:00", "219000003", "55.0", "11.0").replace(",GPS,", ",G\rPS,")]
    s = ingest_paths([write_dma(tmp_path / "stray.csv", lines)], tmp_path / "c.duckdb")
    _adds_up(s)
    assert s["loaded"] == lf["loaded"] + 1 and s["reasons"] == lf["reasons"]


def test_invalid_utf8_is_read_with_replacement(tmp_path, workspace_path):
    data = ("\n".join(DMA_LINES) + "\n").encode() + dma_row(
        "01/01/2025 00:30:00", "219000004", "55.0", "11.0", name="N\xd8RD").encode("latin-1") + b"\n"
    p = tmp_path / "latin1.csv"
    p.write_bytes(data)
    s = ingest_paths([p], workspace_path)
    _adds_up(s)
    assert s["loaded"] == len(DMA_LOADED_LINES) + 1
    with open_workspace(workspace_path) as ws:
        names = read_vessels(ws).set_index("mmsi")["name"]
    assert names[219000004] == "N\ufffdRD"


def test_format_detection_forcing_and_errors(tmp_path, workspace_path):
    junk = tmp_path / "notes.csv"
    junk.write_text("hello,world\n1,2\n")
    with pytest.raises(AisFormatError, match=r"notes.csv:1: unknown AIS format \(first line: 'hello,world'\)"):
        ingest_paths([junk], workspace_path)
    binary = tmp_path / "image.csv"  # bytes, not text: said so, not printed as a garbled "first line"
    binary.write_bytes(bytes((i * 37 + 11) % 256 for i in range(3000)))
    with pytest.raises(AisFormatError, match=r"image.csv:1: unknown AIS format \(binary content: \d+ of its first \d+ "
                                             r"characters are not text\)") as err:
        ingest_paths([binary], workspace_path)
    assert "\ufffd" not in str(err.value)
    # what is read is named: both NOAA headers, and the compressions
    assert "'mmsi,base_date_time,...'" in str(err.value) and "each plain, gzip, zstd or alone in a zip archive" in str(err.value)
    with pytest.raises(AisInputError, match="no such file"):
        ingest_paths([tmp_path / "missing.csv"], workspace_path)
    # Forcing NOAA on a DMA file: the header lacks the NOAA columns -> clear error naming them.
    src = write_dma(tmp_path / "day.csv")
    with pytest.raises(AisFormatError, match="NOAA CSV header lacks column"):
        ingest_paths([src], workspace_path, fmt="noaa")
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    with pytest.raises(AisFormatError, match="empty file"):
        ingest_paths([empty], workspace_path)
    # Nothing was half-loaded by the failures.
    with open_workspace(workspace_path) as ws:
        assert ws.con.execute("SELECT count(*) FROM ais_files").fetchone()[0] == 0


def test_directory_means_every_ais_file_inside(tmp_path, workspace_path):
    d = tmp_path / "drop"
    (d / "sub").mkdir(parents=True)
    write_dma(d / "a.csv")
    (d / "sub" / "b.csv.gz").write_bytes(gzip.compress(
        ("\n".join([DMA_LINES[0], dma_row("02/01/2025 00:00:00", "219000009", "55.0", "11.0")]) + "\n").encode()))
    (d / "README.md").write_text("not AIS")
    (d / ".hidden.csv").write_text("not AIS either")
    s = ingest_paths([d], workspace_path)
    assert s["files"] == 2 and s["loaded"] == len(DMA_LOADED_LINES) + 1
    (tmp_path / "emptydir").mkdir()
    with pytest.raises(AisInputError, match="no AIS file"):
        ingest_paths([tmp_path / "emptydir"], workspace_path)


def test_max_speed_is_configurable(tmp_path):
    src = write_dma(tmp_path / "day.csv")
    # Line 6 jumps 1 degree of latitude in one minute (3600 kn): quarantined at any sane limit.
    # Lines 2 -> 3 sail 0.005 deg lon in 60 s = 10.3 kn: a 5 kn limit cuts that link too.
    strict = ingest_paths([src], tmp_path / "strict.duckdb", max_speed_kn=5.0)
    _adds_up(strict)
    assert strict["reasons"]["speed_jump"] > 1


def test_cli_json_contract_and_errors(tmp_path):
    src = write_dma(tmp_path / "day.csv")
    db = tmp_path / "cli.duckdb"
    exe = [sys.executable, "-m", "pipelines.cli"]
    out = subprocess.run(exe + ["ingest-ais", str(src), "--db", str(db), "--json"], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    obj = json.loads(out.stdout)
    assert list(obj)[:6] == ["files", "read", "loaded", "quarantined", "duplicates", "reasons"]
    assert obj["files"] == 1 and obj["read"] == obj["loaded"] + obj["quarantined"] + obj["duplicates"]
    bad = subprocess.run(exe + ["ingest-ais", str(src), "--db", str(db), "--format", "xml"], capture_output=True,
                         text=True, timeout=120)
    assert bad.returncode == 2 and "--format 'xml' is not one of" in bad.stderr
    missing = subprocess.run(exe + ["ingest-ais", str(tmp_path / "nope.csv"), "--db", str(db)], capture_output=True,
                             text=True, timeout=120)
    assert missing.returncode == 2 and "nope.csv: no such file" in missing.stderr
    assert subprocess.run(exe + ["ingest-ais", "--help"], capture_output=True, text=True, timeout=60).returncode == 0


def test_flow_returns_the_same_summary(tmp_path, prefect_harness):
    from pipelines.ingest import ingest_flow

    import pipelines.ingest as ingest_mod

    src = write_dma(tmp_path / "day.csv")
    # A second file overlapping the first: the flow's file tasks share one connection.
    second = write_dma(tmp_path / "day2.csv", list(DMA_LINES) + [dma_row("01/01/2025 00:30:00", "219000009",
                                                                         "55.0", "11.0")])
    plain = ingest_paths([src, second], tmp_path / "plain.duckdb")
    flowed = ingest_flow([str(src), str(second)], str(tmp_path / "flow.duckdb"))
    for k in ("files", "read", "loaded", "quarantined", "duplicates", "reasons", "static", "ignored"):
        assert flowed[k] == plain[k]
    assert flowed["files"] == 2 and flowed["duplicates"] > 0
    # The flow closed its workspace: another process can open it.
    assert ingest_mod._FLOW_WORKSPACES == {}
    code = "import sys, duckdb; duckdb.connect(sys.argv[1]).close()"
    assert subprocess.run([sys.executable, "-c", code, str(tmp_path / "flow.duckdb")], timeout=60).returncode == 0


def test_read_positions_filters(tmp_path, workspace_path):
    ingest_paths([write_dma(tmp_path / "day.csv")], workspace_path)
    with open_workspace(workspace_path) as ws:
        one = read_positions(ws, mmsi=219000002)
        window = read_positions(ws, start="2025-01-01T00:01:00", end=pd.Timestamp("2025-01-01T00:14:00Z"))
        none = read_positions(ws, mmsi=[123])
        every = read_positions(ws)
        some = read_positions(ws, columns=["sog_kn", "mmsi", "time_utc"])  # the canonical order
        with pytest.raises(ValueError, match="unknown column.*speed"):
            read_positions(ws, columns=["mmsi", "speed"])
    assert list(some.columns) == ["mmsi", "time_utc", "sog_kn"]
    pd.testing.assert_frame_equal(some, every[["mmsi", "time_utc", "sog_kn"]])
    assert one.mmsi.tolist() == [219000002]
    assert window.time_utc.min() == pd.Timestamp("2025-01-01T00:01:00Z")
    assert window.time_utc.max() == pd.Timestamp("2025-01-01T00:03:00Z")
    assert none.empty and list(none.columns)[:2] == ["mmsi", "time_utc"]
    assert np.all(np.diff(read_positions_sorted_keys(workspace_path)) >= 0)


def read_positions_sorted_keys(db):
    with open_workspace(db) as ws:
        p = read_positions(ws)
    return (p.mmsi.to_numpy() * 10**10 + p.time_utc.astype("int64").to_numpy() // 10**9)


def test_same_head_and_tail_but_different_middle_is_a_new_file(tmp_path, workspace_path):
    from ais.io.files import quick_key

    rows = [dma_row((pd.Timestamp("2025-01-03") + pd.Timedelta(seconds=10 * i)).strftime("%d/%m/%Y %H:%M:%S"),
                    "219000077", f"{55 + i * 1e-5:.6f}", "11.000000") for i in range(16000)]
    a = write_dma(tmp_path / "a.csv", [DMA_LINES[0]] + rows)
    changed = list(rows)
    changed[8000] = changed[8000].replace("OXAB1", "OXAB9")  # same length, middle of the file
    b = write_dma(tmp_path / "b.csv", [DMA_LINES[0]] + changed)
    assert a.stat().st_size > 2 * 2**20 and quick_key(a) == quick_key(b)
    first = ingest_paths([a], workspace_path)
    second = ingest_paths([b], workspace_path)
    assert first["loaded"] == 16000
    assert second["already_loaded"] == 0 and second["reasons"] == {"duplicate": 16000}


@pytest.mark.parametrize("no_quick_key", [False, True])
def test_file_loaded_by_an_earlier_version_is_still_recognised(tmp_path, workspace_path, no_quick_key):
    # Earlier versions stored "sha256:<hex>" fingerprints (and before that no quick key): the
    # same bytes must still be skipped, by the sequential and the partitioned planner alike.
    import hashlib

    from ais.io.files import fingerprint
    from pipelines.ingest_partitioned import plan_files

    p = write_dma(tmp_path / "old.csv", DMA_LINES)
    first = ingest_paths([p], workspace_path)
    legacy = "sha256:" + hashlib.sha256(p.read_bytes()).hexdigest()
    with open_workspace(workspace_path) as ws:
        assert ws.con.execute("SELECT fingerprint FROM ais_files").fetchone()[0] == fingerprint(p)
        ws.con.execute("UPDATE ais_files SET fingerprint = ?", [legacy])
        if no_quick_key:
            ws.con.execute("DELETE FROM ais_file_keys")
    assert fingerprint(p, "sha256") == legacy and fingerprint(p).startswith("blake3:")
    again = ingest_paths([p], workspace_path)
    assert again["already_loaded"] == 1 and again["read"] == 0
    with open_workspace(workspace_path) as ws:
        todo, skipped = plan_files(ws, [str(p)])
        n_files = ws.con.execute("SELECT count(*) FROM ais_files").fetchone()[0]
    assert todo == [] and list(skipped) == [str(p)] and n_files == 1
    # other bytes with a legacy workspace: loaded, fingerprinted the current way
    q = write_dma(tmp_path / "new.csv", DMA_LINES[:-1])
    assert ingest_paths([q], workspace_path)["already_loaded"] == 0
    with open_workspace(workspace_path) as ws:
        fps = sorted(r[0].split(":")[0] for r in ws.con.execute("SELECT fingerprint FROM ais_files").fetchall())
    assert fps == ["blake3", "sha256"] and first["loaded"] > 0
    with pytest.raises(ValueError, match="unknown fingerprint algorithm"):
        fingerprint(p, "md5")


def test_bom_and_repeated_header_are_not_records(tmp_path, workspace_path):
    from ais.clean import clean_positions
    from ais.io.csv_formats import read_csv_stage

    extra = dma_row("01/01/2025 00:30:00", "219000008", "55.0", "11.0")
    p = tmp_path / "concat.csv"
    p.write_bytes(("\ufeff" + "\n".join(list(DMA_LINES) + [DMA_LINES[0], extra]) + "\n").encode("utf-8"))
    s = ingest_paths([p], workspace_path)
    _adds_up(s)
    assert s["read"] == 21 and s["loaded"] == len(DMA_LOADED_LINES) + 1
    pure = clean_positions(read_csv_stage(p)[0])
    assert pure.counts["read"] == 21 and pure.counts["reasons"] == s["reasons"]


# --- whole-file problems: truncated gzip, foreign databases, batches, odd paths ---------------
def _nothing_loaded(db) -> None:
    with open_workspace(db) as ws:
        assert ws.con.execute("SELECT count(*) FROM ais_files").fetchone()[0] == 0
        assert ws.con.execute("SELECT count(*) FROM ais_positions").fetchone()[0] == 0
        assert ws.con.execute("SELECT count(*) FROM ais_quarantine").fetchone()[0] == 0


def _big_dma(path, n=3000):
    rows = [dma_row(f"01/01/2025 {i // 3600:02d}:{i // 60 % 60:02d}:{i % 60:02d}", str(219000001 + i % 7),
                    f"{55 + i * 1e-5:.6f}", "11.000000") for i in range(n)]
    path.write_text("\n".join([DMA_LINES[0]] + rows) + "\n")
    return path


@pytest.mark.parametrize("keep", [0.3, 0.9, "all but the trailer"])
def test_truncated_gzip_csv_is_an_error_naming_it(tmp_path, workspace_path, keep):
    # A partial download: DuckDB's gzip reader would stage the lines it got; the fingerprint,
    # which reads the whole stream, finds the end missing and nothing is committed.
    data = gzip.compress(_big_dma(tmp_path / "day.csv").read_bytes())
    cut = len(data) - 4 if keep == "all but the trailer" else int(len(data) * keep)
    gz = tmp_path / "day.csv.gz"
    gz.write_bytes(data[:cut])
    with pytest.raises(AisInputError, match=r"day\.csv\.gz: truncated gzip: the [\d,]+-byte file ends inside"):
        ingest_paths([gz], workspace_path)
    _nothing_loaded(workspace_path)


def test_truncated_and_corrupt_gzip_nmea_are_errors(tmp_path, workspace_path):
    body = "".join(f"!AIVDM,1,1,,A,15M67FC000G?ufbE`FepT@3n00Sa,0*5F\n" for _ in range(4000)).encode()
    data = gzip.compress(body)
    cut = tmp_path / "cut.nmea.gz"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(AisInputError, match=r"cut\.nmea\.gz: truncated gzip"):
        ingest_paths([cut], workspace_path)
    bad = bytearray(data)
    bad[-6] ^= 0xFF  # inside the CRC-32 / length trailer
    flipped = tmp_path / "flipped.nmea.gz"
    flipped.write_bytes(bytes(bad))
    with pytest.raises(AisInputError, match=r"flipped\.nmea\.gz: corrupt gzip"):
        ingest_paths([flipped], workspace_path)
    _nothing_loaded(workspace_path)


def test_gzip_members_and_zero_padding_are_one_content(tmp_path, workspace_path):
    # Concatenated gzip files (two members) padded with zeros: the same content as the plain
    # file, so the same fingerprint (one file loaded, the other skipped).
    src = _big_dma(tmp_path / "day.csv")
    raw = src.read_bytes()
    two = tmp_path / "two.csv.gz"
    two.write_bytes(gzip.compress(raw[:5000]) + gzip.compress(raw[5000:]) + b"\0" * 1000)
    first = ingest_paths([two], workspace_path)
    assert first["loaded"] == 3000
    assert ingest_paths([src], workspace_path)["already_loaded"] == 1


def test_gzipped_parquet_loads_like_the_plain_file(tmp_path, workspace_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = pd.date_range("2025-01-01", periods=50, freq="min", tz="UTC")
    plain = tmp_path / "day.parquet"
    pq.write_table(pa.table({"mmsi": [219000001] * 50, "time_utc": t, "lat_deg": 55 + np.arange(50) * 1e-3,
                             "lon_deg": [11.0] * 50}), plain)
    gz = tmp_path / "day.parquet.gz"
    gz.write_bytes(gzip.compress(plain.read_bytes()))
    s = ingest_paths([gz], workspace_path)
    assert (s["loaded"], s["files"]) == (50, 1)
    assert ingest_paths([plain], workspace_path)["already_loaded"] == 1  # same content


def test_a_parquet_time_column_of_numbers_is_one_error_naming_it(tmp_path, workspace_path):
    """Epoch numbers are not times (seconds? milliseconds?): one error naming the column and its
    type, nothing loaded; they used to be quarantined row by row as bad_time, the file said to
    "have no time" (found by the acceptance sweep)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from ais.io.parquet import read_parquet_stage

    epoch = tmp_path / "epoch.parquet"
    pq.write_table(pa.table({"mmsi": [219000001] * 3, "time": [1735689600, 1735689660, 1735689720],
                             "lat": [55.0, 55.001, 55.002], "lon": [11.0] * 3}), epoch)
    gz = tmp_path / "epoch2.parquet.gz"
    gz.write_bytes(gzip.compress(epoch.read_bytes()))
    for path in (epoch, gz):
        with pytest.raises(AisFormatError, match=r"Parquet column 'time' \(the time\) holds numbers \(BIGINT\), not times"):
            ingest_paths([path], workspace_path)
    with pytest.raises(AisFormatError, match=r"holds numbers"):  # the pure twin says the same
        read_parquet_stage(epoch)
    if workspace_path.exists():
        with open_workspace(workspace_path) as ws:
            assert len(read_files(ws)) == 0


def test_repeated_header_lines_count_as_ignored(tmp_path):
    # Two files concatenated with their headers, and empty lines: lines = 1 + read + ignored.
    rows = [dma_row(f"01/01/2025 00:0{i}:00", "219000001", f"{55 + i * 0.001:.6f}", "11.0") for i in range(6)]
    p = tmp_path / "cat.csv"
    p.write_text("\n".join([DMA_LINES[0]] + rows[:3] + [DMA_LINES[0], ""] + rows[3:] + [""]) + "\n")
    s = ingest_paths([p], tmp_path / "w.duckdb")
    assert (s["read"], s["loaded"], s["ignored"]) == (6, 6, 3)
    assert 1 + s["read"] + s["ignored"] == len(p.read_text().splitlines())


def test_a_foreign_duckdb_database_is_not_turned_into_a_workspace(tmp_path):
    import duckdb

    from pipelines.storage import WorkspaceError

    for name, table in (("clash.duckdb", "ais_positions"), ("other.duckdb", "orders")):
        db = tmp_path / name
        con = duckdb.connect(str(db))
        con.execute(f"CREATE TABLE {table} (x INTEGER)")
        con.close()
        with pytest.raises(WorkspaceError, match=rf"{name} is a DuckDB database but not a stormlane workspace "
                                                 rf"\(it holds {table} and no schema_version table\)"):
            ingest_paths([write_dma(tmp_path / "day.csv")], db)
        con = duckdb.connect(str(db), read_only=True)
        assert [r[0] for r in con.execute("SHOW TABLES").fetchall()] == [table]  # untouched
        con.close()


def test_a_batch_is_checked_before_anything_is_loaded(tmp_path, workspace_path):
    good = write_dma(tmp_path / "a.csv")
    nolat = tmp_path / "b.csv"
    nolat.write_text("MMSI,BaseDateTime,LON,SOG\n219000001,2025-01-01T00:00:00,11.0,10\n")
    with pytest.raises(AisFormatError, match=r"b\.csv:1: NOAA CSV header lacks column\(s\) lat"):
        ingest_paths([good, nolat], workspace_path)
    _nothing_loaded(workspace_path)


def test_an_error_after_committed_files_names_them(tmp_path, workspace_path):
    # A truncated gzip is only found while it is read: the files before it stay loaded, and
    # the error says so (a rerun skips them).
    good = write_dma(tmp_path / "a.csv")
    data = gzip.compress(_big_dma(tmp_path / "big.csv").read_bytes())
    cut = tmp_path / "b.csv.gz"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(AisInputError, match=r"b\.csv\.gz: truncated gzip.*\(the 1 file\(s\) before it are loaded and "
                                            r"stay so: .*a\.csv; a rerun skips them\)"):
        ingest_paths([good, cut], workspace_path)
    assert ingest_paths([good], workspace_path)["already_loaded"] == 1


def test_odd_paths(tmp_path, workspace_path, caplog):
    with pytest.raises(AisInputError, match="empty path"):
        ingest_paths([""], workspace_path)
    d = tmp_path / "drop"
    d.mkdir()
    write_dma(d / "a.csv")
    write_dma(d / ".b.csv")  # an editor's or a sync tool's hidden copy
    (d / "gone.csv").symlink_to(tmp_path / "nowhere.csv")
    with caplog.at_level("WARNING"):
        s = ingest_paths([d], workspace_path)
    assert s["files"] == 1
    assert "hidden file" in caplog.text and "link to nothing" in caplog.text
    assert ingest_paths([d / ".b.csv"], workspace_path)["already_loaded"] == 1  # named alone: read (same content)


@pytest.mark.parametrize("case", ["empty path", "foreign database", "truncated gzip", "truncated small gzip"])
def test_cli_whole_file_errors_are_one_line(tmp_path, capsys, case):
    import duckdb

    from cli_runner import run_cli

    db = tmp_path / "w.duckdb"
    if case == "empty path":
        args, expect = [""], "error: '': empty path"
    elif case == "foreign database":
        con = duckdb.connect(str(db))
        con.execute("CREATE TABLE ais_positions (x INTEGER)")
        con.close()
        args, expect = [str(write_dma(tmp_path / "a.csv"))], "is a DuckDB database but not a stormlane workspace"
    elif case == "truncated small gzip":  # cut within the first 64 KiB the format check reads (it said Python's EOFError)
        data = gzip.compress(write_dma(tmp_path / "a.csv").read_bytes())
        (tmp_path / "s.csv.gz").write_bytes(data[: len(data) // 2])
        args, expect = [str(tmp_path / "s.csv.gz")], "s.csv.gz: truncated gzip: the"
    else:
        data = gzip.compress(_big_dma(tmp_path / "big.csv").read_bytes())
        (tmp_path / "b.csv.gz").write_bytes(data[: len(data) // 3])
        args, expect = [str(tmp_path / "b.csv.gz")], "b.csv.gz: truncated gzip"
    code, out, err = run_cli(capsys, "ingest-ais", *args, "--db", str(db), "--json")
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: ") and expect in err


def test_cr_only_line_ends_and_a_blank_first_line_are_errors(tmp_path, workspace_path):
    text = "\n".join(DMA_LINES[:4])
    cr = tmp_path / "mac.csv"
    cr.write_bytes(text.replace("\n", "\r").encode() + b"\r")
    with pytest.raises(AisFormatError, match=r"mac\.csv:1: lines end in a carriage return alone"):
        ingest_paths([cr], workspace_path)
    blank = tmp_path / "blank_first.csv"
    blank.write_text("\n" + text + "\n")
    with pytest.raises(AisFormatError, match=r"blank_first\.csv:1: line 1 is empty: the DMA CSV header"):
        ingest_paths([blank], workspace_path)
    _nothing_loaded(workspace_path)


@pytest.mark.parametrize("fast", [False, True])
@pytest.mark.parametrize("gz", [False, True])
def test_a_carriage_return_alone_inside_a_crlf_line_keeps_the_line_whole(tmp_path, monkeypatch, fast, gz):
    """A line is split on \\n with one trailing \\r removed (ais.io.csv_formats.read_lines): a \\r
    alone inside a line of a CRLF file is part of it. DuckDB's line reader ended the line there
    (two bad_line rows instead of one row), and the compiled scan kept that line's trailing \\r
    in its quarantined text."""
    import gzip as gzip_mod

    from pipelines import ingest_stage as stage_mod

    monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", 0 if fast else 1 << 62)
    monkeypatch.setattr(stage_mod, "GZIP_PLAIN_MIN_BYTES", 0 if fast else 1 << 62)
    bad = DMA_LINES[1].replace(DMA_LINES[1].split(",")[5], "Under way\r using engine")
    body = "\r\n".join([DMA_LINES[0], bad, DMA_LINES[2]]) + "\r\n"
    path = tmp_path / ("crlf.csv.gz" if gz else "crlf.csv")
    path.write_bytes(gzip_mod.compress(body.encode()) if gz else body.encode())
    s = ingest_paths([path], tmp_path / "w.duckdb")
    assert (s["read"], s["loaded"], s["quarantined"], s["reasons"]) == (2, 1, 1, {"bad_nav_status": 1})
    with open_workspace(tmp_path / "w.duckdb") as ws:
        assert ws.con.execute("SELECT line, raw FROM ais_quarantine").fetchall() == [(2, bad)]
