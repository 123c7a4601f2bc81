"""The typed fast CSV path (DuckDB's typed scanner + line index) gives exactly what the exact
raw-lines path gives, and falls back to it whenever one record per line cannot be trusted."""

from __future__ import annotations

import numpy as np
import pytest

from ais_fixtures import DMA_HEADER, DMA_LINES, dma_row
from ais.io.lineindex import LineIndex
from pipelines import ingest_stage as stage_mod
from pipelines.ingest import ingest_file
from pipelines.storage import open_workspace
from pipelines.storage import ais as store
from pipelines.storage.ais import stage_fast, stage_lines


# --- the line index --------------------------------------------------------------------------
def test_line_index_offsets_and_flags(tmp_path):
    p = tmp_path / "x.txt"
    # lines: 1 "ab", 2 "" (CRLF), 3 'c"d', 4 "", 5 "e+f" (no final newline)
    p.write_bytes(b'ab\n\r\nc"d\r\n\ne+f')
    with LineIndex(p) as ix:
        assert ix.n_lines == 5
        assert ix.starts.tolist() == [0, 3, 5, 10, 11]
        assert ix.ends.tolist() == [2, 3, 8, 10, 14]
        assert ix.blank_lines.tolist() == [2, 4]
        assert ix.quote_lines.tolist() == [3]
        assert not ix.stray_cr
        assert ix.text([5, 1, 3, 2]) == ["e+f", "ab", 'c"d', ""]
        assert ix.text_array([5, 1, 3, 2]).to_pylist() == ["e+f", "ab", 'c"d', ""]
        assert ix.text_array([]).to_pylist() == []
        with pytest.raises(IndexError):
            ix.text([6])
        with pytest.raises(IndexError):
            ix.text_array([0])


def test_line_index_stray_cr_empty_file_and_bad_utf8(tmp_path):
    p = tmp_path / "cr.txt"
    p.write_bytes(b"a\rb\nc\n")
    with LineIndex(p) as ix:
        assert ix.stray_cr and ix.n_lines == 2
    p.write_bytes(b"a\r")  # a \r at the very end, no \n after it
    with LineIndex(p) as ix:
        assert ix.stray_cr
    p.write_bytes(b"")
    with LineIndex(p) as ix:
        assert ix.n_lines == 0 and len(ix.blank_lines) == 0
    p.write_bytes("ÆØ\nN\xd8RD\n".encode("latin-1").replace(b"\xc6\xd8", "ÆØ".encode()))
    with LineIndex(p) as ix:  # UTF-8 kept; a byte that is none replaced, on both readers
        assert ix.n_lines == 2 and ix.text([2, 1]) == ["N\ufffdRD", "ÆØ"]
        assert ix.text_array([2, 1]).to_pylist() == ["N\ufffdRD", "ÆØ"] and ix.text_array([1]).to_pylist() == ["ÆØ"]


# --- both staging paths give the same workspace ----------------------------------------------
def _rows(n_vessels=12, n_steps=120, seed=3):
    """Clean time-ordered fixes with a few jumps (several DuckDB scan chunks at a small buffer)."""
    rng = np.random.default_rng(seed)
    out = []
    for step in range(n_steps):
        m, s = divmod(step * 20, 60)
        h, m = divmod(m, 60)
        ts = f"02/01/2025 {h:02d}:{m:02d}:{s:02d}"
        for v in range(n_vessels):
            lat = 54.0 + v * 0.05 + (1.0 if rng.random() < 0.003 else 0.0)
            out.append(dma_row(ts, str(219200000 + v), f"{lat:.6f}", f"{8.0 + step * 0.001:.6f}",
                               name=f"SHIP {v}", callsign=f"OX{v:03d}", imo=str(9100000 + v)))
    return out


def _snapshot(db):
    with open_workspace(db) as ws:
        con = ws.con
        files = con.execute("SELECT n_read, n_loaded, n_quarantined, n_duplicates, n_static, n_ignored, reasons "
                            "FROM ais_files").fetchall()
        pos = con.execute("SELECT source_line, mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, "
                          "nav_status FROM ais_positions ORDER BY source_line").fetchall()
        quar = con.execute("SELECT line, reason, raw, mmsi, time_utc FROM ais_quarantine ORDER BY line").fetchall()
        ves = con.execute("SELECT * EXCLUDE (file_id) FROM vessels ORDER BY mmsi").fetchall()
    return files, pos, quar, ves


#: The fast CSV stages and the ``staging`` label each reports.
ENGINES = {"scan": "scan", "arrow": "arrow", "duckdb": "typed"}


def _both_paths(tmp_path, monkeypatch, data: bytes, name: str):
    """Ingest ``data`` through every fast stage alone and through the exact raw-lines path;
    every workspace must be the same. Returns ``{engine: (counts, snapshot)}``."""
    path = tmp_path / f"{name}.csv"
    path.write_bytes(data)
    # A small scanner buffer / block: even these files are read as many parallel chunks.
    monkeypatch.setattr(stage_lines, "CSV_BUFFER_BYTES", 1 << 14)
    out = {}
    runs = [(engine, 0, (engine,)) for engine in ENGINES] + [("exact", 1 << 62, ())]
    for label, min_bytes, engines in runs:
        monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", min_bytes)
        monkeypatch.setattr(stage_mod, "FAST_CSV_ENGINES", engines)
        db = tmp_path / f"{name}-{label}.duckdb"
        with open_workspace(db) as ws:
            counts = ingest_file(ws, path, fmt="dma")
        out[label] = (counts, _snapshot(db))
    ce, se = out.pop("exact")
    assert ce["staging"] in ("lines", "python")
    lines = data.decode("utf-8", errors="replace").split("\n")
    for engine, (cf, sf) in out.items():
        for k in ("read", "loaded", "quarantined", "duplicates", "ignored", "reasons"):
            assert cf[k] == ce[k], (engine, k)
        assert cf["read"] == cf["loaded"] + cf["quarantined"] + cf["duplicates"]
        for part, a, b in zip(("files", "positions", "quarantine", "vessels"), sf, se):
            assert a == b, (engine, part)
        # Every quarantined row keeps its line and raw text: the text of that physical line.
        for line, _reason, raw, _m, _t in sf[2]:
            assert raw == lines[line - 1].removesuffix("\r")
    return out


def _used_fast(out, engine):
    """Whether ``engine``'s run staged through its own fast path (not a fallback)."""
    return out[engine][0]["staging"] == ENGINES[engine]


DIRTY = list(DMA_LINES[1:])  # every kind of dirty row, a quoted name, a blank line


def _mix(rows, extra, every=97):
    out = list(rows)
    for i, x in enumerate(extra):
        out.insert(min(len(out), (i + 1) * every), x)
    return out


CASES = {
    "plain": ("\n", False, []),
    "crlf": ("\r\n", False, []),
    "bom_repeated_header_blanks": ("\n", True, [DMA_HEADER, "", "", DMA_HEADER]),
    "quotes_plus_nan_spaces": ("\n", False, [
        dma_row("02/01/2025 00:00:05", "219200001", "54.05", "8.0", name='"A, ""B"""'),
        dma_row("02/01/2025 00:00:06", "219200002", "+54.1", "8.0"),
        dma_row("02/01/2025 00:00:07", "219200003", "54.15", "8.0", sog="nan", cog="NaN"),
        dma_row("02/01/2025 00:00:08", " 219200004 ", " 54.2 ", "\t8.0"),
        dma_row("02/01/2025 00:00:09", "0219200005", "54.25", "8.0"),
        dma_row("2/1/2025 0:00:10", "219200006", "54.3", "8.0", status="MOORED"),
        dma_row("02/01/2025 00:00:11", "219200007", "54.35", "8.0", status="under way using engine"),
        dma_row("02/01/2025 00:00:60", "219200008", "54.4", "8.0"),
        dma_row("02/01/2025 00:00:12.5", "219200009", "54.45", "8.0"),
        dma_row("02/01/2025T00:00:13", "219200010", "54.5", "8.0"),
        dma_row("02/01/2025 00:00:14", "219200011", "1e1", "8.0", hdg="inf"),
        "   ",
        "01/01/2025 00:08:00,Class A,219000001,55.0,11.03,Under way using engine,0.0,10.0,1,2,3,4,5,6,7,8,9,0,1,2,3,"
        "4,5,6,7,8,9",  # too many fields
    ]),
    # Static data that changes: the latest (time, line) row of a vessel is a line typed from its
    # text (quoted name), or a scanned line after an older typed one, or a scanned line written
    # before older ones in the file (the vessels merge takes the latest by time, then line).
    "static_changes": ("\n", False, [
        dma_row("02/01/2025 01:00:00", "219200002", "54.1", "8.2", name='"RENAMED, LATE"', dest="KIEL"),
        dma_row("02/01/2025 00:00:01", "219200003", "54.15", "8.0", name='"EARLY"', callsign="EARLY"),
        dma_row("02/01/2025 01:00:00", "219200004", "54.2", "8.2", name="RENAMED", draught="9.1"),
        dma_row("02/01/2025 01:00:00", "219200005", "54.25", "8.2", name="SAME TIME A"),
        dma_row("02/01/2025 01:00:00", "219200005", "54.25", "8.2", name="SAME TIME B"),
    ]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_fast_path_equals_exact_path(tmp_path, monkeypatch, case):
    newline, bom, extra = CASES[case]
    lines = [DMA_HEADER] + _mix(_rows(), DIRTY + extra)
    text = newline.join(lines) + newline
    data = (("\ufeff" if bom else "") + text).encode("utf-8")
    out = _both_paths(tmp_path, monkeypatch, data, case)
    for engine in ENGINES:  # the invariants held: every fast path was used
        assert _used_fast(out, engine), engine
    # rejected rows (other field counts) / empty lines: the scanners' rows are mapped to lines
    assert out["duckdb"][0]["line_mapping"] == out["arrow"][0]["line_mapping"] == "ordinal"
    counts = out["scan"][0]
    assert counts["loaded"] > 1000 and counts["quarantined"] >= 14
    assert counts["line_mapping"] == "scan"
    if case == "static_changes":
        names = {row[0]: row[2] for row in out["scan"][1][3]}
        assert (names[219200002], names[219200003], names[219200004], names[219200005]) == (
            "RENAMED, LATE", "SHIP 3", "RENAMED", "SAME TIME B")


def test_second_file_against_stored_positions_equals_exact_path(tmp_path, monkeypatch):
    # A second file into a workspace that holds the first: ships that continue their stored
    # tracks (the streaming pass with the last stored fix as context; one ship's first new fix
    # is 1 degree off it, so its new fixes are judged against a pinned fix), a ship whose new
    # times overlap its stored ones (repeated keys against stored rows: the SQL path for it), a
    # ship going back in time in the new file, a new ship, and the dirty rows.
    day1 = _rows(n_vessels=8, n_steps=90, seed=5)
    later = []
    for step in range(90, 170):
        m, sec = divmod(step * 20, 60)
        h, m = divmod(m, 60)
        ts = f"02/01/2025 {h:02d}:{m:02d}:{sec:02d}"
        for v in range(8):
            lat = 54.0 + v * 0.05 + (1.0 if v == 3 else 0.0)  # ship 3: far from its stored track
            later.append(dma_row(ts, str(219200000 + v), f"{lat:.6f}", f"{8.0 + step * 0.001:.6f}",
                                 name=f"SHIP {v}", callsign=f"OX{v:03d}", imo=str(9100000 + v)))
        later.append(dma_row(ts, "219200099", "50.000000", f"{8.0 + step * 0.001:.6f}", name="NEW"))
    overlap = [r for r in day1 if ",219200005," in r][40:60]  # same keys as stored rows
    overlap[3] = overlap[3].replace(",10.0,", ",11.0,")  # same key, other value: duplicate_time
    back = [r for r in later if ",219200006," in r]
    later = [r for r in later if ",219200006," not in r] + back[::-1]  # ship 6 written backwards
    day2 = _mix(later + overlap, DIRTY)
    monkeypatch.setattr(stage_lines, "CSV_BUFFER_BYTES", 1 << 14)
    snaps = {}
    for label, min_bytes, engines in (("scan", 0, ("scan",)), ("exact", 1 << 62, ())):
        monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", min_bytes)
        monkeypatch.setattr(stage_mod, "FAST_CSV_ENGINES", engines)
        db = tmp_path / f"two-{label}.duckdb"
        counts = []
        for k, rows in enumerate((day1, day2)):
            path = tmp_path / f"{label}-{k}.csv"
            path.write_bytes(("\n".join([DMA_HEADER] + rows) + "\n").encode())
            with open_workspace(db) as ws:
                counts.append(ingest_file(ws, path, fmt="dma"))
        snaps[label] = (counts, _snapshot(db))
    (cs, ss), (ce, se) = snaps["scan"], snaps["exact"]
    assert [c["staging"] for c in cs] == ["scan", "scan"]
    for a, b in zip(cs, ce):
        for k in ("read", "loaded", "quarantined", "duplicates", "reasons"):
            assert a[k] == b[k], k
    for part, a, b in zip(("files", "positions", "quarantine", "vessels"), ss, se):
        assert a == b, part
    r2 = cs[1]["reasons"]
    # the stored keys repeated (19 + 1 with another value) and the dirty rows' own pair
    assert r2["duplicate"] == 19 + 1 and r2["duplicate_time"] == 1 + 1
    assert r2["speed_jump"] == 80 + 1  # ship 3's new track is not linked to its stored fix; the dirty jump


def test_fast_path_without_rejects_numbers_rows_by_rowid(tmp_path, monkeypatch):
    # Every line has the header's field count and there is no empty line: line = rowid + 2;
    # quoted lines (without commas inside quotes) are still typed from their text.
    same_width = [x for x in DIRTY if x and x.count(",") == DMA_HEADER.count(",") and '"' not in x]
    quoted = [dma_row("02/01/2025 00:00:05", "219200001", "54.05", "8.0", name='"QUOTED"'),
              dma_row("02/01/2025 00:00:06", "219200002", "54.1", "8.0", dest='"X"Y'),
              dma_row("02/01/2025 00:00:07", " 219200003", "54.15", "8.0", sog="nan", hdg="+90")]
    lines = [DMA_HEADER] + _mix(_rows(), same_width + quoted + [DMA_HEADER])
    data = ("\r\n".join(lines) + "\r\n").encode()
    out = _both_paths(tmp_path, monkeypatch, data, "rowid")
    for engine in ENGINES:
        assert _used_fast(out, engine), engine
    assert out["duckdb"][0]["line_mapping"] == out["arrow"][0]["line_mapping"] == "rowid"
    counts = out["scan"][0]
    assert counts["reasons"]["bad_mmsi"] >= 3 and counts["reasons"]["bad_lon"] == 1


def test_embedded_newline_is_two_bad_lines_on_both_paths(tmp_path, monkeypatch):
    # A quoted field with a newline inside: both paths read physical lines (the scanner runs
    # with quoting off), so the record is two bad lines on both, and the fast path holds.
    rows = _rows(n_vessels=6, n_steps=60)
    rows.insert(50, dma_row("02/01/2025 00:05:00", "219200001", "54.05", "8.0", name='"TWO\nLINES"'))
    data = ("\n".join([DMA_HEADER] + rows) + "\n").encode()
    out = _both_paths(tmp_path, monkeypatch, data, "embedded")
    for engine in ENGINES:
        assert _used_fast(out, engine), engine
    assert out["scan"][0]["reasons"]["bad_line"] == 2


def test_reject_lines_are_checked_against_the_text():
    class Ix:
        n_lines = 5
        _t = ["h", "a", "", "b,c", "d"]

        def text(self, lines):
            return [self._t[i - 1] for i in lines]

    ix = Ix()
    assert stage_fast._verified_reject_lines([], ix).tolist() == []
    # DuckDB prefixes the empty lines before a row, and may report it again on the empty line.
    assert stage_fast._verified_reject_lines([(4, "\nb,c"), (3, "b,c"), (2, "a\r")], ix).tolist() == [2, 4]
    assert stage_fast._verified_reject_lines([(4, "b,c"), (5, "b,c")], ix).tolist() == [4]
    assert stage_fast._verified_reject_lines([(5, "x")], ix) is None  # a wrong number: no fast path
    assert stage_fast._verified_reject_lines([(9, "d")], ix) is None


@pytest.mark.parametrize("case", ["stray_cr", "many_exact_lines"])
def test_fast_path_falls_back_when_the_line_invariant_fails(tmp_path, monkeypatch, case):
    rows = _rows(n_vessels=6, n_steps=60)
    if case == "stray_cr":
        rows.insert(50, dma_row("02/01/2025 00:05:00", "219200001", "54.05", "8.0", name="A\rB"))
    else:  # over the share of lines the fast path re-types line by line
        monkeypatch.setattr(stage_fast, "FAST_MAX_EXACT_FRAC", 0.0)
        rows = [r.replace("ALPHA", '"ALPHA"') for r in rows] * 1
        rows += [r.replace(",GPS,", ',"GPS",') for r in _rows(n_vessels=6, n_steps=200, seed=9)]
    data = ("\n".join([DMA_HEADER] + rows) + "\n").encode()
    out = _both_paths(tmp_path, monkeypatch, data, case)
    for engine in ("arrow", "duckdb"):
        assert out[engine][0]["staging"] in ("lines", "python")
    # The scan splits on \n only: a stray \r just makes its line one typed from its text.
    assert out["scan"][0]["staging"] == ("scan" if case == "stray_cr" else "lines")


def test_fast_path_raw_text_of_invalid_utf8_line(tmp_path, monkeypatch):
    rows = _rows(n_vessels=4, n_steps=30)
    data = ("\n".join([DMA_HEADER] + rows) + "\n").encode() + dma_row(
        "02/01/2025 01:00:00", "219200001", "95.0", "8.0", name="N\xd8RD").encode("latin-1") + b"\n"
    out = _both_paths(tmp_path, monkeypatch, data, "latin1")
    counts, snap = out["scan"]
    assert _used_fast(out, "scan")
    assert counts["reasons"].get("bad_lat") == 1
    assert [q[2] for q in snap[2] if q[1] == "bad_lat"][0].count("\ufffd") == 1


def test_scan_stage_spot_check_catches_a_wrong_value(tmp_path, monkeypatch):
    # Corrupt the first scanned row's latitude: the sample typed again from the text (it always
    # holds the first row) differs, so the scan stage is given up for the next engine.
    import pyarrow as pa
    import pyarrow.compute as pc

    real = stage_fast._scan_table

    def corrupt(con, r):
        tbl, fixes = real(con, r)
        lat = tbl.column("lat_deg").combine_chunks()
        bad = pc.if_else(pa.array(np.arange(len(lat)) == 0), pa.scalar(1.5), lat)
        return tbl.set_column(tbl.column_names.index("lat_deg"), "lat_deg", bad), fixes

    monkeypatch.setattr(stage_fast, "_scan_table", corrupt)
    monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", 0)
    monkeypatch.setattr(stage_mod, "FAST_CSV_ENGINES", ("scan", "duckdb"))
    path = tmp_path / "c.csv"
    path.write_bytes(("\n".join([DMA_HEADER] + _rows(n_vessels=4, n_steps=30)) + "\n").encode())
    with open_workspace(tmp_path / "c.duckdb") as ws:
        counts = ingest_file(ws, path, fmt="dma")
        lat = ws.con.execute("SELECT lat_deg FROM ais_positions WHERE source_line = 2").fetchone()[0]
    assert counts["staging"] == "typed" and lat != 1.5
