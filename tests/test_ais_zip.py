"""AIS files inside zip archives, as DMA (``aisdk-YYYY-MM-DD.zip``) and NOAA (``AIS_YYYY_MM_DD.zip``)
publish them, and Zstandard files (NOAA's ``.csv.zst`` from 2024 on): an archive holding one file,
or a zstd file, loads as that file would, in every reader and on the partitioned path; the same
content plain, gzip, zstd or zipped is one input; anything else about an archive, and a truncated
stream, is one error naming it, with nothing committed.
"""

from __future__ import annotations

import gzip
import subprocess
import sys
import zipfile
from pathlib import Path

import pandas as pd
import pytest

from ais.errors import AisInputError
from ais.io.files import expand_paths, fingerprint, inspect
from ais_fixtures import DMA_HEADER, dma_row, write_dma
from pipelines import ingest_stage
from pipelines.ingest import ingest_paths
from pipelines.storage import open_workspace
from test_ingest_partitioned import TABLES, _assert_same_workspace, _partitioned, batch  # noqa: F401 (fixture)


def _zip(src: Path, dest: Path, method=zipfile.ZIP_DEFLATED, extra: dict | None = None) -> Path:
    """``dest``, a zip archive holding ``src`` under its own name (plus ``extra`` name -> bytes)."""
    with zipfile.ZipFile(dest, "w", compression=method) as zf:
        zf.write(src, src.name)
        for name, data in (extra or {}).items():
            zf.writestr(name, data)
    return dest


def _zipped(files: list[str], folder: Path) -> list[str]:
    folder.mkdir()
    return [str(_zip(Path(p), folder / (Path(p).stem + ".zip"))) for p in files]


def _tables_but_paths(db) -> dict:
    with open_workspace(db) as ws:
        return {name: ws.con.execute(sql).fetchdf().drop(columns=["path", "size_bytes", "quick_key"], errors="ignore")
                for name, sql in TABLES.items()}  # the file as stored: its name, size and quick key


def _day(path: Path, n_minutes: int = 30) -> Path:
    rows = [dma_row(f"02/01/2025 00:{m:02d}:{s:02d}", str(219300000 + v), f"{54 + v * 0.05 + (m * 60 + s) * 1e-5:.6f}",
                    "8.000000", name=f"SHIP {v}")  # 2.2 kn northward
            for m in range(n_minutes) for s in range(0, 60, 10) for v in range(4)]
    rows[10:10] = [dma_row("02/01/2025 00:00:05", "12345", "54.0", "8.0"),  # bad MMSI
                   dma_row("02/01/2025 00:00:06", "219300001", "95.0", "8.0")]  # latitude out of range
    return write_dma(path, [DMA_HEADER] + rows)


def test_every_reader_loads_a_zipped_file_as_the_file_itself(tmp_path, batch):
    """DMA (dirty rows), NOAA, NMEA and Parquet, each zipped: the same rows, quarantine (raw
    lines), vessels and fingerprints as the plain files; the file rows name the archives."""
    plain = ingest_paths(batch, tmp_path / "plain.duckdb")
    zips = _zipped(batch, tmp_path / "zips")
    zipped = ingest_paths(zips, tmp_path / "zip.duckdb")
    got, want = _tables_but_paths(tmp_path / "zip.duckdb"), _tables_but_paths(tmp_path / "plain.duckdb")
    for name in TABLES:
        assert len(want[name]) > 0, name
        pd.testing.assert_frame_equal(got[name], want[name], check_exact=True, obj=name)
    keys = ("format", "read", "loaded", "quarantined", "duplicates", "static", "ignored", "reasons", "already_loaded")
    assert [{k: f[k] for k in keys} for f in zipped["per_file"]] == [{k: f[k] for k in keys} for f in plain["per_file"]]
    with open_workspace(tmp_path / "zip.duckdb") as ws:
        paths = [r[0] for r in ws.con.execute("SELECT path FROM ais_files ORDER BY file_id").fetchall()]
    assert paths and all(p.endswith(".zip") for p in paths)
    assert list(tmp_path.glob(".stormlane-gunzip-*")) == []  # every plain copy removed
    # the same content plain is the same input: nothing added
    again = ingest_paths(batch, tmp_path / "zip.duckdb")
    assert again["loaded"] == 0 and again["already_loaded"] == len(batch)


def test_zipped_files_staged_apart_commit_as_the_sequential_ingest(tmp_path, batch):
    zips = _zipped(batch, tmp_path / "zips")
    ingest_paths(zips, tmp_path / "seq.duckdb")
    (spool := tmp_path / "spool").mkdir()
    _partitioned(zips, tmp_path / "part.duckdb", spool)
    _assert_same_workspace(tmp_path / "part.duckdb", tmp_path / "seq.duckdb")
    assert list(spool.iterdir()) == []


@pytest.mark.parametrize("method", [zipfile.ZIP_DEFLATED, zipfile.ZIP_STORED, zipfile.ZIP_BZIP2],
                         ids=["deflate", "stored", "bzip2"])
def test_a_large_zipped_dma_day_takes_the_scan_and_equals_its_gzip(tmp_path, monkeypatch, method):
    monkeypatch.setattr(ingest_stage, "FAST_CSV_MIN_BYTES", 0)  # the scan, as for a real daily file
    monkeypatch.setattr(ingest_stage, "GZIP_PLAIN_MIN_BYTES", 0)
    day = _day(tmp_path / "aisdk-2025-01-02.csv")
    gz = tmp_path / "aisdk-2025-01-02.csv.gz"
    gz.write_bytes(gzip.compress(day.read_bytes()))
    archive = _zip(day, tmp_path / "aisdk-2025-01-02.zip", method, {"__MACOSX/._aisdk-2025-01-02.csv": b"\0\5"})
    assert fingerprint(archive) == fingerprint(gz) == fingerprint(day)
    want = ingest_paths([str(gz)], tmp_path / "gz.duckdb")
    got = ingest_paths([str(archive)], tmp_path / "zip.duckdb")
    assert got["per_file"][0]["staging"] == want["per_file"][0]["staging"] == "scan"
    assert got["loaded"] == want["loaded"] > 0 and got["reasons"] == want["reasons"] and got["quarantined"] == 2
    g, w = _tables_but_paths(tmp_path / "zip.duckdb"), _tables_but_paths(tmp_path / "gz.duckdb")
    for name in TABLES:
        pd.testing.assert_frame_equal(g[name], w[name], check_exact=True, obj=name)
    assert list(tmp_path.glob(".stormlane-gunzip-*")) == []  # the plain copy removed


def test_a_directory_scan_takes_the_archives(tmp_path):
    (d := tmp_path / "downloads").mkdir()
    _zip(_day(tmp_path / "aisdk-2025-01-02.csv"), d / "aisdk-2025-01-02.zip")
    (d / "notes.pdf").write_bytes(b"%PDF-1.4")
    assert [p.name for p in expand_paths([d])] == ["aisdk-2025-01-02.zip"]
    assert inspect(d / "aisdk-2025-01-02.zip").format == "dma"


def _cli_error(tmp_path, path) -> str:
    db = tmp_path / "w.duckdb"
    out = subprocess.run([sys.executable, "-m", "pipelines.cli", "ingest-ais", str(path), "--db", str(db)],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr
    lines = [ln for ln in out.stderr.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, out.stderr
    if db.exists():
        with open_workspace(db) as ws:
            assert ws.con.execute("SELECT count(*) FROM ais_positions").fetchone()[0] == 0
    return lines[0]


def test_an_archive_of_several_files_is_one_error_naming_it(tmp_path):
    day = _day(tmp_path / "a.csv")
    archive = _zip(day, tmp_path / "month.zip", extra={"b.csv": day.read_bytes(), "c.csv": b"x"})
    line = _cli_error(tmp_path, archive)
    assert "month.zip" in line and "holds 3 files (a.csv, b.csv, c.csv)" in line and "unpack it" in line


def test_a_truncated_or_corrupt_archive_is_one_error_naming_it(tmp_path):
    day = _day(tmp_path / "aisdk-2025-01-02.csv", n_minutes=60)
    data = _zip(day, tmp_path / "whole.zip").read_bytes()
    (cut := tmp_path / "aisdk-cut.zip").write_bytes(data[: len(data) // 2])  # a partial download
    line = _cli_error(tmp_path, cut)
    assert "aisdk-cut.zip" in line and "not a readable zip archive" in line and "partial download" in line

    member = zipfile.ZipFile(tmp_path / "whole.zip").infolist()[0]
    start = member.header_offset + 30 + len(member.filename)
    bad = bytearray(data)
    for i in range(start + 2000, start + 2100):  # damage inside the deflate stream
        bad[i] ^= 0x5A
    (corrupt := tmp_path / "aisdk-bad.zip").write_bytes(bytes(bad))
    with pytest.raises(AisInputError, match=r"aisdk-bad\.zip: corrupt zip archive member aisdk-2025-01-02\.csv"):
        fingerprint(corrupt)
    line = _cli_error(tmp_path, corrupt)
    assert "aisdk-bad.zip" in line and "corrupt zip archive member" in line


def _zst(src: Path, dest: Path) -> Path:
    import pyarrow as pa

    with pa.CompressedOutputStream(str(dest), "zstd") as out:
        out.write(src.read_bytes())
    return dest


def test_a_zstd_day_takes_the_scan_and_equals_its_gzip(tmp_path, monkeypatch):
    monkeypatch.setattr(ingest_stage, "FAST_CSV_MIN_BYTES", 0)
    monkeypatch.setattr(ingest_stage, "GZIP_PLAIN_MIN_BYTES", 0)
    day = _day(tmp_path / "ais-2025-01-02.csv")
    gz = tmp_path / "ais-2025-01-02.csv.gz"
    gz.write_bytes(gzip.compress(day.read_bytes()))
    (d := tmp_path / "in").mkdir()
    zst = _zst(day, d / "ais-2025-01-02.csv.zst")
    assert fingerprint(zst) == fingerprint(gz) and [p.name for p in expand_paths([d])] == [zst.name]
    want = ingest_paths([str(gz)], tmp_path / "gz.duckdb")
    got = ingest_paths([str(d)], tmp_path / "zst.duckdb")
    assert got["per_file"][0]["staging"] == "scan" and got["loaded"] == want["loaded"] > 0
    g, w = _tables_but_paths(tmp_path / "zst.duckdb"), _tables_but_paths(tmp_path / "gz.duckdb")
    for name in TABLES:
        pd.testing.assert_frame_equal(g[name], w[name], check_exact=True, obj=name)
    again = ingest_paths([str(gz), str(day)], tmp_path / "zst.duckdb")  # the same content: nothing added
    assert again["loaded"] == 0 and again["already_loaded"] == 2


def test_a_truncated_zstd_file_is_one_error_naming_it(tmp_path):
    zst = _zst(_day(tmp_path / "ais-2025-01-02.csv", n_minutes=60), tmp_path / "whole.zst")
    data = zst.read_bytes()
    (cut := tmp_path / "ais-cut.csv.zst").write_bytes(data[: len(data) // 2])
    line = _cli_error(tmp_path, cut)
    assert "ais-cut.csv.zst" in line and "truncated or corrupt zstd stream" in line and "partial download" in line
