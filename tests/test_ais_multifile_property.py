"""Several DMA CSV files ingested one after another into one workspace: the compiled scan
staging gives the same workspace as the exact raw-lines path, file after file.

From the second file on, positions are stored: a scanned file's MMSIs that continue their
stored track go through the streaming pass of ``ais._tracks.first_load_rules`` with their
last stored fix as pinned context, the others (stored fixes at or after the file's first fix,
tracks going back in time) through the SQL path (``_stored_sql_outcomes``), see
``pipelines.storage.ais.commit._outcomes_with_stored``. The raw-lines path takes the SQL path for every
MMSI. Hypothesis builds small fleets split over 2-3 files in the ways that exercise both.
"""

from __future__ import annotations

import math
from datetime import datetime, timedelta

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import ais._tracks as tracks
from ais_fixtures import DMA_HEADER, dma_row
from pipelines import ingest_stage as stage_mod
from pipelines.ingest import ingest_file
from pipelines.storage import open_workspace
from pipelines.storage.ais import stage_lines
from test_ais_fast_csv import _snapshot

T0 = datetime(2025, 3, 1)
#: Earth radius for the independent check of the jump rule (nautical miles).
R_NMI = 3440.065


def _ts(sec: int, padded: bool = True) -> str:
    t = T0 + timedelta(seconds=sec)
    if padded:
        return t.strftime("%d/%m/%Y %H:%M:%S")
    return f"{t.day}/{t.month}/{t.year} {t.hour}:{t.minute:02d}:{t.second:02d}"  # typed from its text


def _row(f: dict) -> str:
    """One DMA line of fix ``f`` (keys: mmsi, t, lat, lon, sog, cog, hdg, name, style)."""
    style = f.get("style", "plain")
    kw = {"sog": f["sog"], "cog": f["cog"], "hdg": f["hdg"], "name": f["name"], "callsign": f"C{f['mmsi'] % 10000:04d}"}
    lon = f"{f['lon']:.6f}"
    if style == "quoted":  # a valid line the scan hands to the raw-lines statement
        kw["name"] = f'"{f["name"]}, THE"'
    elif style == "sentinel":  # loads with NULL motion fields
        kw.update(sog="102.3", cog="360.0", hdg="511")
    elif style == "sog1022":
        kw.update(sog="102.2")
    elif style == "lon180":  # stored as -180
        lon = "180.000000"
    elif style == "noname":  # missing static fields: the vessel keeps its latest non-missing ones
        kw.update(name="", callsign="")
    return dma_row(_ts(f["t"], style != "loose_time"), str(f["mmsi"]), f"{f['lat']:.6f}", lon, **kw)


#: Dirty rows: (kind, builder(mmsi, t)).
DIRTY = {
    "bad_mmsi_mid": lambda m, t: dma_row(_ts(t), "999000001", "55.000000", "11.000000"),
    "bad_mmsi_zero": lambda m, t: dma_row(_ts(t), "002190001", "55.000000", "11.000000", mobile="Base Station"),
    "bad_mmsi_short": lambda m, t: dma_row(_ts(t), str(m)[:8], "55.000000", "11.000000"),
    "bad_time_date": lambda m, t: dma_row("31/02/2025 00:05:00", str(m), "55.000000", "11.000000"),
    "bad_time_year": lambda m, t: dma_row("01/01/1985 00:05:00", str(m), "55.000000", "11.000000"),
    "bad_time_empty": lambda m, t: dma_row("", str(m), "55.000000", "11.000000"),
    "no_position": lambda m, t: dma_row(_ts(t), str(m), "91.000000", "181.000000"),
    "no_position_lat": lambda m, t: dma_row(_ts(t), str(m), "91.000000", "11.000000"),
    "bad_lat": lambda m, t: dma_row(_ts(t), str(m), "95.000000", "11.000000"),
    "bad_sog": lambda m, t: dma_row(_ts(t), str(m), "55.000000", "11.000000", sog="150.0"),
    "bad_line": lambda m, t: f"{_ts(t)},Class A,{m},55.000000,11.000000,Under way using engine,0.0,10.0",
    "bad_lon_text": lambda m, t: dma_row(_ts(t), str(m), "55.000000", "abc"),
}

MMSI = st.integers(201_000_000, 775_999_999)


def _step(lat, lon, speed_kn, course_deg, dt_s):
    d_nmi = speed_kn * dt_s / 3600.0
    lat2 = lat + d_nmi * math.cos(math.radians(course_deg)) / 60.0
    lon2 = lon + d_nmi * math.sin(math.radians(course_deg)) / (60.0 * math.cos(math.radians(lat2)))
    lon2 = (lon2 + 180.0) % 360.0 - 180.0
    return lat2, lon2


@st.composite
def _track(draw, mmsi: int) -> list[dict]:
    """One ship's fixes in time order at a plausible speed, with a few jumps."""
    n = draw(st.integers(3, 22))
    t = draw(st.integers(0, 6 * 3600))
    gaps = draw(st.lists(st.integers(10, 900), min_size=n - 1, max_size=n - 1))
    speed = draw(st.sampled_from([0.0, 0.3, 8.0, 12.5, 18.0, 23.0]))
    course = draw(st.integers(0, 359))
    if draw(st.integers(0, 5)) == 0:  # near the antimeridian, heading east over it
        lat, lon, course = draw(st.integers(-600, 600)) / 10.0, 179.95, draw(st.integers(45, 135))
    else:
        lat, lon = draw(st.integers(-650, 650)) / 10.0, draw(st.integers(-1790, 1790)) / 10.0
    name = draw(st.sampled_from(["ALPHA", "BRAVO", "CHARLIE"]))
    fixes = []
    for i in range(n):
        if i:
            t += gaps[i - 1]
            lat, lon = _step(lat, lon, speed, course, gaps[i - 1])
        fixes.append({"mmsi": mmsi, "t": t, "lat": lat, "lon": lon, "sog": f"{speed:.1f}", "cog": f"{course:.1f}",
                      "hdg": str(course), "name": name, "style": "plain"})
    # Jumps at arbitrary places: an outlier or a run of fixes offset (a second transmitter).
    for at, run, off, on_lat in draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(1, 4),
                                                        st.sampled_from([0.3, 1.0, 4.0, -2.0]), st.booleans()),
                                              max_size=2)):
        for f in fixes[at:at + run]:
            if on_lat:
                f["lat"] = max(-89.0, min(89.0, f["lat"] + off))
            else:
                f["lon"] = (f["lon"] + off + 180.0) % 360.0 - 180.0
    for f in fixes:
        f["style"] = draw(st.sampled_from(["plain"] * 12 + ["quoted", "loose_time", "sentinel", "sog1022", "noname",
                                                            "lon180"]))
        if f["style"] == "lon180" and abs(abs(f["lon"]) - 180.0) > 0.2:
            f["style"] = "plain" if draw(st.integers(0, 3)) else "lon180"  # mostly on the antimeridian ships
    return fixes


@st.composite
def _files(draw) -> list[tuple[float, list[str]]]:
    """2-3 files of a small fleet: ``[(max_speed_kn, data lines), ...]``."""
    n_files = draw(st.integers(2, 3))
    mmsis = draw(st.lists(MMSI, min_size=2, max_size=6, unique=True))
    parts = [[] for _ in range(n_files)]  # fixes per file
    backwards = set()  # (file, mmsi) written back in time
    for mmsi in mmsis:
        fixes = draw(_track(mmsi))
        mode = draw(st.sampled_from(["daily", "daily", "late", "random"]))
        if mode == "random":  # every fix to any file: later files overlap / interleave stored times
            where = [draw(st.integers(0, n_files - 1)) for _ in fixes]
        else:  # contiguous parts in file order (a ship may be absent from a file)
            cuts = sorted(draw(st.lists(st.integers(0, len(fixes)), min_size=n_files - 1, max_size=n_files - 1)))
            if mode == "late":  # only in the later files
                cuts[0] = 0
            bounds = [0] + cuts + [len(fixes)]
            where = [k for k in range(n_files) for _ in range(bounds[k + 1] - bounds[k])]
        mine = [[f for f, k in zip(fixes, where) if k == j] for j in range(n_files)]
        for k in range(1, n_files):
            how = draw(st.sampled_from(["keep", "keep", "keep", "backwards", "far", "overlap"]))
            if how == "backwards":
                backwards.add((k, mmsi))
            elif how == "far" and mine[k]:  # first new fix far from the last stored one
                off = 1.0 if mine[k][0]["lat"] < 80 else -1.0
                mine[k] = [{**f, "lat": f["lat"] + off} for f in mine[k]]
            elif how == "overlap":  # stored keys again: same values (duplicate) or not (duplicate_time)
                earlier = [f for j in range(k) for f in mine[j]]
                picks = draw(st.lists(st.integers(0, max(0, len(earlier) - 1)), max_size=4)) if earlier else []
                for p in picks:
                    f = dict(earlier[p])
                    if draw(st.integers(0, 2)) == 0:
                        f["sog"] = "3.1" if f["sog"] != "3.1" else "4.2"
                    mine[k].append(f)
        for j in range(n_files):
            parts[j] += mine[j]
    files = []
    t_max = max([f["t"] for p in parts for f in p], default=0)
    for k, fixes in enumerate(parts):
        if draw(st.booleans()):  # time order over the fleet (AIS files), else ship by ship
            fixes = sorted(fixes, key=lambda f: f["t"])
        for mmsi in mmsis:
            if (k, mmsi) in backwards:  # the ship's slots refilled in reverse
                slots = [i for i, f in enumerate(fixes) if f["mmsi"] == mmsi]
                rev = [fixes[i] for i in slots][::-1]
                fixes = list(fixes)
                for i, f in zip(slots, rev):
                    fixes[i] = f
        rows = [_row(f) for f in fixes]
        # exact repeats of the file's own rows, or the same key with another value
        for src, at, other in draw(st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 10**6), st.booleans()),
                                            max_size=3 if rows else 0)):
            f = dict(fixes[src % len(fixes)])
            if other:
                f["lat"] += 0.001
            rows.insert(at % (len(rows) + 1), _row(f))
        for kind, who, t, at in draw(st.lists(st.tuples(st.sampled_from(sorted(DIRTY)), st.sampled_from(mmsis),
                                                        st.integers(0, t_max), st.integers(0, 10**6)),
                                              min_size=0 if rows else 1, max_size=4)):
            rows.insert(at % (len(rows) + 1), DIRTY[kind](who, t))
        limit = draw(st.sampled_from([60.0, 60.0, 60.0, 25.0, 100.0]))
        files.append((limit, rows))
    return files


PATHS = (("scan", 0, ("scan",)), ("exact", 1 << 62, ()))


def _attribution(db):
    """Which file each position, quarantined row and vessel row came from (deterministic order)."""
    with open_workspace(db) as ws:
        con = ws.con
        pos = con.execute("SELECT file_id, source_line, mmsi, time_utc FROM ais_positions "
                          "ORDER BY file_id, source_line").fetchall()
        quar = con.execute("SELECT file_id, line, reason FROM ais_quarantine ORDER BY file_id, line").fetchall()
        ves = con.execute("SELECT mmsi, file_id FROM vessels ORDER BY mmsi").fetchall()
    return pos, quar, ves


def _ingest_all(d, label, files, monkeypatch):
    _, min_bytes, engines = next(p for p in PATHS if p[0] == label)
    monkeypatch.setattr(stage_mod, "FAST_CSV_MIN_BYTES", min_bytes)
    monkeypatch.setattr(stage_mod, "FAST_CSV_ENGINES", engines)
    db = d / f"{label}.duckdb"
    counts = []
    for k, (limit, rows) in enumerate(files):
        path = d / f"{label}-{k}.csv"
        path.write_bytes(("\n".join([DMA_HEADER] + rows) + "\n").encode())
        with open_workspace(db) as ws:
            counts.append(ingest_file(ws, path, fmt="dma", max_speed_kn=limit))
    return db, counts


def _hav_nmi(lat1, lon1, lat2, lon2):
    p1, p2 = math.radians(lat1), math.radians(lat2)
    a = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(math.radians(lon2 - lon1) / 2) ** 2
    return 2 * R_NMI * math.asin(math.sqrt(min(1.0, a)))


def _jumps_within_files(db) -> list:
    """Pairs (a, b) of consecutive stored fixes of one MMSI (by time), both from one file,
    implying more than that file's --max-speed-kn. R = 3440.065 nmi is a hair below the
    project's 6371008.8 m / 1852 (this check is a hair more lenient than the rule); 1e-9
    absorbs rounding."""
    with open_workspace(db) as ws:
        limits = dict(ws.con.execute("SELECT file_id, max_speed_kn FROM ais_files").fetchall())
        rows = ws.con.execute("SELECT mmsi, time_utc, lat_deg, lon_deg, file_id, source_line FROM ais_positions "
                              "ORDER BY mmsi, time_utc").fetchall()
    bad = []
    for a, b in zip(rows, rows[1:]):
        if a[0] != b[0] or a[4] != b[4]:
            continue
        hours = (b[1] - a[1]).total_seconds() / 3600.0
        dist = _hav_nmi(a[2], a[3], b[2], b[3])
        if dist > limits[a[4]] * hours * (1 + 1e-9):
            bad.append({"a": a, "b": b, "kn": dist / hours if hours else math.inf})
    return bad


def _check_paths_agree(d, files, monkeypatch):
    monkeypatch.setattr(stage_lines, "CSV_BUFFER_BYTES", 1 << 14)  # the raw-lines path reads several chunks
    out = {}
    for label, _, _ in PATHS:
        db, counts = _ingest_all(d, label, files, monkeypatch)
        out[label] = (db, counts, _snapshot(db), _attribution(db))
    (_, cs, ss, attr_s), (_, ce, se, attr_e) = out["scan"], out["exact"]
    for k, (a, b) in enumerate(zip(cs, ce)):
        assert a["already_loaded"] == b["already_loaded"], k
        if a["already_loaded"]:  # byte-identical to an earlier file: skipped on both paths
            continue
        assert a["staging"] == "scan", (k, a["staging"])
        assert b["staging"] in ("lines", "python"), (k, b["staging"])
        for key in ("read", "loaded", "quarantined", "duplicates", "reasons"):
            assert a[key] == b[key], (k, key, a[key], b[key])
        assert a["read"] == a["loaded"] + a["quarantined"] + a["duplicates"], k
        assert sum(a["reasons"].values()) == a["quarantined"] + a["duplicates"], k
    # _snapshot orders by line only, and lines repeat over files: compare as multisets, then
    # the attribution by (file, line) in a deterministic order.
    for part, a, b in zip(("files", "positions", "quarantine", "vessels"), ss, se):
        assert sorted(a, key=repr) == sorted(b, key=repr), part
    for part, a, b in zip(("positions by file", "quarantine by file", "vessels by file"), attr_s, attr_e):
        assert a == b, part
    return out


@settings(max_examples=45, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                 HealthCheck.data_too_large])
@given(files=_files())
def test_files_in_sequence_scan_equals_exact(tmp_path_factory, monkeypatch, files):
    d = tmp_path_factory.mktemp("multifile")
    real, seen = tracks.first_load_rules, []

    def spy(scan, exact, max_speed_kn, context=None):  # which MMSIs the scan path streams / sends to SQL
        k = real(scan, exact, max_speed_kn, context)
        if context is not None:
            seen.append((int((~context["skip"]).sum()), len(k["fallback"])))
        return k

    monkeypatch.setattr(tracks, "first_load_rules", spy)
    out = _check_paths_agree(d, files, monkeypatch)
    for streamed_ctx, fallback in seen:
        event(f"a later file: MMSIs streamed against a pinned stored fix: {'yes' if streamed_ctx else 'no'}")
        event(f"a later file: MMSIs sent to the SQL path: {'yes' if fallback else 'no'}")
    for c in out["scan"][1][1:]:
        for r in ("duplicate", "duplicate_time", "speed_jump"):
            event(f"a later file has {r}: {'yes' if c.get('reasons', {}).get(r) else 'no'}")
    event(f"a limit other than 60 kn: {any(lim != 60.0 for lim, _ in files)}")
    # The jump rule, checked independently: two consecutive loaded fixes of one file never
    # exceed that file's limit (fixes of other files between or around them or not).
    assert _jumps_within_files(out["scan"][0]) == []


# --- new fixes between stored fixes ----------------------------------------------------------
# File 1 stores a ship at 00:00 and 00:10, 9 nmi apart (54 kn). File 2 puts a fix 0.9 nmi
# behind the first (00:01, 54 kn from it) and one 0.9 nmi past the second (00:09, 54 kn to
# it): each new fix is linked to its stored neighbour, but the two are 10.8 nmi apart in 8 min
# (81 kn against the 60 kn limit), and neither reaches the stored fix on its far side (9.9 nmi
# in 9 min, 66 kn). The stored fixes stay; both new ones go. (Before segments were kept pure,
# each new fix sat in a segment with a stored fix, accepted unconditionally, and both loaded.)
STORED_AROUND = [
    (60.0, [dma_row("01/01/2025 00:00:00", "219000001", "55.000000", "11.000000"),
            dma_row("01/01/2025 00:10:00", "219000001", f"{55 + 9 / 60:.6f}", "11.000000")]),
    (60.0, [dma_row("01/01/2025 00:01:00", "219000001", f"{55 - 0.9 / 60:.6f}", "11.000000"),
            dma_row("01/01/2025 00:09:00", "219000001", f"{55 + 9.9 / 60:.6f}", "11.000000")]),
]


def test_new_fixes_between_stored_fixes_out_of_reach_are_quarantined(tmp_path, monkeypatch):
    out = _check_paths_agree(tmp_path, STORED_AROUND, monkeypatch)
    assert [c["loaded"] for c in out["scan"][1]] == [2, 0]
    assert out["scan"][1][1]["reasons"] == {"speed_jump": 2}
    assert _jumps_within_files(out["scan"][0]) == []
