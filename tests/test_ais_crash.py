"""Crash safety (SIGKILL mid-file, then rerun) and what concurrent readers see."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pandas as pd
import pytest

from ais_fixtures import DMA_HEADER, DMA_LINES, dma_row, write_dma
from pipelines.ingest import ingest_file, ingest_paths
from pipelines.storage import open_workspace
from pipelines.storage.ais import open_for_reading

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def big_dma(path, n_vessels=40, n_steps=1500, seed=1):
    """A DMA file of n_vessels x n_steps fixes (a few dirty rows) for the kill tests."""
    rng = np.random.default_rng(seed)
    lines = [DMA_HEADER]
    t0 = pd.Timestamp("2025-01-02T00:00:00")
    for step in range(n_steps):
        ts = (t0 + pd.Timedelta(seconds=30 * step)).strftime("%d/%m/%Y %H:%M:%S")
        for v in range(n_vessels):
            lat = 54.0 + v * 0.05
            lon = 8.0 + step * 0.0015
            if rng.random() < 0.002:
                lat += 1.0  # a jump
            lines.append(dma_row(ts, str(219100000 + v), f"{lat:.6f}", f"{lon:.6f}"))
    write_dma(path, lines)
    return path


def snapshot(db):
    """Every table's content, keyed by file path instead of file_id (ids are not reused)."""
    with open_workspace(db) as ws:
        con = ws.con
        files = con.execute(
            "SELECT path, format, n_read, n_loaded, n_quarantined, n_duplicates, n_static, n_ignored, reasons "
            "FROM ais_files ORDER BY path").fetchall()
        pos = con.execute(
            "SELECT f.path, p.source_line, p.mmsi, p.time_utc, p.lat_deg, p.lon_deg, p.sog_kn, p.cog_deg, "
            "p.heading_deg, p.nav_status FROM ais_positions p JOIN ais_files f USING (file_id) "
            "ORDER BY f.path, p.source_line").fetchall()
        quar = con.execute(
            "SELECT f.path, q.line, q.reason, q.raw FROM ais_quarantine q JOIN ais_files f USING (file_id) "
            "ORDER BY f.path, q.line").fetchall()
        ves = con.execute("SELECT * EXCLUDE (file_id) FROM vessels ORDER BY mmsi").fetchall()
    return files, pos, quar, ves


KILLER = textwrap.dedent("""
    import sys, time, pathlib
    from pipelines.ingest import ingest_file
    from pipelines.storage import open_workspace
    db, first, second, marker = sys.argv[1:5]
    def hang():
        pathlib.Path(marker).write_text("inside the transaction")
        time.sleep(120)
    with open_workspace(db) as ws:
        ingest_file(ws, first)
        ingest_file(ws, second, before_commit=hang)
""")


def test_sigkill_inside_the_transaction_then_rerun_equals_clean_run(tmp_path):
    a = write_dma(tmp_path / "a.csv")
    b = big_dma(tmp_path / "b.csv", n_vessels=10, n_steps=200)
    db = tmp_path / "crashed.duckdb"
    marker = tmp_path / "marker"
    proc = subprocess.Popen([sys.executable, "-c", KILLER, str(db), str(a), str(b), str(marker)], cwd=REPO)
    try:
        deadline = time.monotonic() + 120
        while not marker.exists():
            assert proc.poll() is None, "the loader exited before reaching the commit"
            assert time.monotonic() < deadline
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    # The workspace holds file a only: b's transaction never committed.
    files, pos, quar, ves = snapshot(db)
    assert [f[0] for f in files] == [str(a)]
    assert {p[0] for p in pos} == {str(a)}
    s = ingest_paths([a, b], db)
    assert s["already_loaded"] == 1
    clean = tmp_path / "clean.duckdb"
    ingest_paths([a, b], clean)
    assert snapshot(db) == snapshot(clean)


def _load_in_subprocess(db, files):
    code = "import sys; from pipelines.ingest import ingest_paths; ingest_paths(sys.argv[2:], sys.argv[1])"
    return subprocess.Popen([sys.executable, "-c", code, str(db), *map(str, files)], cwd=REPO)


def _wait_for(db, proc, timeout_s=120):
    """Wait until the workspace file exists (the loader is past its imports); its time."""
    deadline = time.monotonic() + timeout_s
    while not db.exists() and proc.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    return time.monotonic()


def test_sigkill_at_a_random_moment_then_rerun_equals_clean_run(tmp_path):
    files = [big_dma(tmp_path / f"f{i}.csv", n_vessels=30, n_steps=800, seed=i) for i in range(3)]
    # The clean run, in a subprocess like the killed one, measures how long the load itself
    # takes (from the workspace file's creation to exit) on this machine right now; the kill
    # then falls at a random moment inside that window (a fixed delay proves nothing once the
    # ingest is fast or the machine quiet). If the load still wins the race, try earlier.
    clean = tmp_path / "clean.duckdb"
    proc = _load_in_subprocess(clean, files)
    t0 = _wait_for(clean, proc)
    assert proc.wait(timeout=300) == 0
    load_s = time.monotonic() - t0
    rng = np.random.default_rng()
    for attempt in range(4):
        db = tmp_path / f"crashed{attempt}.duckdb"
        proc = _load_in_subprocess(db, files)
        _wait_for(db, proc)
        time.sleep(load_s * rng.uniform(0.05, 0.9) / (1 + 2 * attempt))
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        if proc.returncode == -signal.SIGKILL:
            break
    assert proc.returncode == -signal.SIGKILL, "the load finished before the kill: the test proved nothing"
    s = ingest_paths(files, db)
    assert s["read"] == s["loaded"] + s["quarantined"] + s["duplicates"]
    assert snapshot(db) == snapshot(clean)


def test_reader_cursor_sees_old_state_until_commit(tmp_path):
    db = tmp_path / "ws.duckdb"
    a = write_dma(tmp_path / "a.csv")
    b = big_dma(tmp_path / "b.csv", n_vessels=5, n_steps=50)
    seen = {}
    with open_workspace(db) as ws:
        ingest_file(ws, a)
        reader = ws.con.cursor()
        before = reader.execute("SELECT count(*) FROM ais_positions").fetchone()[0]

        def look():
            r = ws.con.cursor()  # a fresh cursor = a separate transaction
            seen["positions"] = r.execute("SELECT count(*) FROM ais_positions").fetchone()[0]
            seen["files"] = r.execute("SELECT count(*) FROM ais_files").fetchone()[0]
            r.close()

        counts = ingest_file(ws, b, before_commit=look)
        after = reader.execute("SELECT count(*) FROM ais_positions").fetchone()[0]
    assert seen == {"positions": before, "files": 1}
    assert after == before + counts["loaded"]


HOLDER = textwrap.dedent("""
    import sys, time, pathlib
    from pipelines.ingest import ingest_file
    from pipelines.storage import open_workspace
    db, path, marker = sys.argv[1:4]
    with open_workspace(db) as ws:
        ingest_file(ws, path)
        pathlib.Path(marker).write_text("holding the lock")
        time.sleep(2.0)
""")


def test_other_process_waits_for_the_writer_and_sees_committed_files(tmp_path):
    db = tmp_path / "ws.duckdb"
    a = write_dma(tmp_path / "a.csv")
    marker = tmp_path / "marker"
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(db), str(a), str(marker)], cwd=REPO)
    try:
        deadline = time.monotonic() + 120
        while not marker.exists():
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        t0 = time.monotonic()
        ws = open_for_reading(db, wait_s=60)
        waited = time.monotonic() - t0
        try:
            n = ws.con.execute("SELECT count(*) FROM ais_positions").fetchone()[0]
            files = ws.con.execute("SELECT count(*) FROM ais_files").fetchone()[0]
        finally:
            ws.close()
    finally:
        proc.wait(timeout=60)
    assert files == 1 and n == 5
    assert waited > 0.5  # it had to wait for the writer's lock
    with pytest.raises(Exception):
        # Without waiting, a second process cannot open a workspace that a writer holds.
        holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(tmp_path / "w2.duckdb"), str(a),
                                   str(tmp_path / "m2")], cwd=REPO)
        try:
            while not (tmp_path / "m2").exists():
                assert holder.poll() is None
                time.sleep(0.05)
            open_for_reading(tmp_path / "w2.duckdb", wait_s=0)
        finally:
            holder.wait(timeout=60)
