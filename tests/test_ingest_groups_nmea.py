"""A large NMEA file decoded in chunks and committed in groups gives the whole file's workspace.

``ais.io.nmea_chunks`` reads an NMEA file in chunks of lines, decodes each with what crosses a
chunk's end carried over (open multipart groups, the time context), and deals the stage rows
into groups of whole vessels; the duplicate-payload rule runs per group. The references: the
whole file's parse (:func:`ais.io.nmea.read_nmea`) and the whole file's ingest, on random line
sequences (valid messages of several vessels heard again, multipart messages, time lines and tag
blocks, mutated and random lines) cut into chunks as small as one byte.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pyais.encode import encode_dict

import pipelines.ingest_groups as groups_mod
from ais.io import nmea_chunks
from ais.io.nmea import read_nmea
from pipelines.ingest import ingest_file
from pipelines.storage import open_workspace
from pipelines.storage.ais import parquet as P
from test_ais_fuzz import BASE_NMEA, mutated
from test_ingest_groups import _state


def _pool() -> list[str]:
    """Messages of six vessels (single positions and two-part statics), time lines and tag blocks."""
    lines = []
    for k, mmsi in enumerate((219000001, 219000002, 230000017, 244000321, 265111222, 311000999)):
        for j in range(3):
            lines += encode_dict({"type": 1, "mmsi": mmsi, "lat": 55 + k * 0.1 + j * 0.01, "lon": 12.0 + j * 0.02,
                                  "speed": 10.0 + j, "course": 90.0}, radio_channel="AB"[j % 2], talker_id="AI")
        lines.append("\n".join(encode_dict({"type": 5, "mmsi": mmsi, "shipname": f"SHIP {k}", "callsign": f"OX{k}",
                                            "shiptype": 70}, radio_channel="B", talker_id="AI", seq_id=k % 3)))
    lines += [f"$PGHP,1,2025,1,1,0,{m},{s},0,219,,2190067,1,00*00" for m, s in ((0, 5), (1, 30), (1, 31))]
    lines += ["\\s:x,c:1735689600*00\\", "\\s:x,c:1735689640*00\\", ""]
    return lines


POOL = _pool()


@st.composite
def _nmea_lines(draw):
    items = draw(st.lists(st.one_of(st.sampled_from(POOL), mutated(BASE_NMEA)), min_size=1, max_size=70))
    return [ln for item in items for ln in item.split("\n")]  # a multipart item is its lines


def _write(path, lines):
    path.write_bytes(("\n".join(lines) + "\n").encode("utf-8", "surrogatepass"))
    return path


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(lines=_nmea_lines(), chunk=st.sampled_from([1, 13, 90, 600, 1 << 20]))
def test_chunks_decode_as_the_whole_file(tmp_path_factory, lines, chunk):
    """The chunks' stages, duplicates marked over them, are the whole file's stage; the counts
    of ignored lines add up to the whole file's."""
    path = _write(tmp_path_factory.mktemp("nmea-chunks") / "f.nmea", lines)
    whole, meta = read_nmea(path)
    parts = list(nmea_chunks.decode_chunks(path, chunk))
    stage = pd.concat([s for s, _ in parts], ignore_index=True).sort_values("line", kind="stable")
    got = nmea_chunks.mark_duplicates(stage.reset_index(drop=True))
    assert got.equals(whole)
    assert sum(m["ignored"] for _, m in parts) == meta["ignored"]
    assert sum(m["static"] for _, m in parts) == meta["static"]


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(files=st.lists(_nmea_lines(), min_size=1, max_size=2), chunk=st.sampled_from([1, 90, 1 << 20]),
       group_rows=st.sampled_from([1, 4, 1000]))
def test_nmea_groups_give_the_whole_files_workspace(tmp_path_factory, monkeypatch, files, chunk, group_rows):
    d = tmp_path_factory.mktemp("nmea-groups")
    monkeypatch.setattr(P, "ROW_GROUP_ROWS", 3)
    monkeypatch.setattr(nmea_chunks, "CHUNK_BYTES", chunk)
    monkeypatch.setattr(groups_mod, "NMEA_GROUP_ROWS", group_rows)
    dbs = {}
    for side, min_bytes in (("whole", 1 << 62), ("split", 0)):
        monkeypatch.setattr(groups_mod, "NMEA_GROUP_MIN_BYTES", min_bytes)
        (d / side).mkdir()
        dbs[side] = d / side / "w.duckdb"
        counts = []
        for k, lines in enumerate(files):
            path = _write(d / side / f"in-{k}.nmea", lines)
            with open_workspace(dbs[side]) as ws:
                counts.append(ingest_file(ws, path, fmt="nmea"))
        dbs[side + "_counts"] = counts
    for a, b in zip(dbs["whole_counts"], dbs["split_counts"]):
        assert a["staging"] != "groups" and (b["staging"] == "groups") == (not b["already_loaded"])
        for key in ("read", "loaded", "quarantined", "duplicates", "static", "ignored", "reasons"):
            assert a[key] == b[key], (key, a[key], b[key])
    for name, x, y in zip(("tables", "attribution", "track ends, parts, files", "dataset"), _state(dbs["split"]),
                          _state(dbs["whole"])):
        assert x == y, name
    assert not list(d.glob("**/.stormlane-groups-*")) and not list(d.glob("**/.groups-*"))


def test_a_multipart_message_and_its_time_across_a_chunks_end(tmp_path):
    """Hand-made: a time line, then a two-part message, cut after each line; a payload heard
    again 20 s later in another chunk is a duplicate, heard again 2 min later it is not."""
    msg = encode_dict({"type": 5, "mmsi": 219000001, "shipname": "A", "shiptype": 70}, radio_channel="B",
                      talker_id="AI", seq_id=1)
    pos = encode_dict({"type": 1, "mmsi": 219000001, "lat": 55.0, "lon": 12.0}, talker_id="AI")[0]
    lines = ["$PGHP,1,2025,1,1,0,0,5,0,219,,2190067,1,00*00", *msg, "\\c:1735689600*00\\", pos,
             "\\c:1735689620*00\\", pos, "\\c:1735689740*00\\", pos]
    path = _write(tmp_path / "f.nmea", lines)
    whole, _ = read_nmea(path)
    for chunk in range(1, 80, 7):
        parts = [s for s, _ in nmea_chunks.decode_chunks(path, chunk)]
        got = nmea_chunks.mark_duplicates(pd.concat(parts, ignore_index=True).sort_values("line").reset_index(drop=True))
        assert got.equals(whole), chunk
    assert list(whole["line"]) == [2, 5, 7, 9]
    assert whole.loc[0, "kind"] == "S" and str(whole.loc[0, "time_utc"]) == "2025-01-01 00:00:05+00:00"
    assert list(whole["parse_error"].fillna("")) == ["", "", "duplicate_payload", ""]


@pytest.mark.parametrize("size,gz", [(100, False), (100, True)])
def test_which_nmea_files_are_read_in_groups(tmp_path, monkeypatch, size, gz):
    """A plain NMEA file above NMEA_GROUP_MIN_BYTES; a large gzip one is inflated to a plain copy
    first (ingest_stage.wants_plain_copy), whose size decides."""
    import gzip

    from ais.io.files import inspect
    from pipelines import ingest_stage

    data = ("\n".join(POOL[:10]) + "\n").encode()
    path = tmp_path / ("f.nmea.gz" if gz else "f.nmea")
    path.write_bytes(gzip.compress(data) if gz else data)
    monkeypatch.setattr(groups_mod, "NMEA_GROUP_MIN_BYTES", size)
    monkeypatch.setattr(ingest_stage, "GZIP_PLAIN_MIN_BYTES", 10)
    f = inspect(path, None, with_fingerprint=False)
    assert f.format == "nmea"
    assert groups_mod.wants_groups(f) == (not gz)
    assert ingest_stage.wants_plain_copy(f) == gz
    with open_workspace(tmp_path / "w.duckdb") as ws:
        counts = ingest_file(ws, path)
    assert counts["staging"] == "groups" and counts["read"] > 0
    assert np.isfinite(counts["loaded"])


@pytest.mark.parametrize("gz", [False, True], ids=["plain", "gzip"])
def test_partitioned_ingest_commits_a_large_nmea_file_in_groups(tmp_path, monkeypatch, gz):
    """The worker only inflates (gzip) and hashes the file; the committing process decodes it in
    chunks and commits its groups: the sequential whole-file workspace, the input kept."""
    import gzip

    from pipelines import ingest_stage
    from pipelines.ingest_partitioned import commit_spooled, plan_files, stage_to_spool

    rng = np.random.default_rng(5)
    lines = [ln for k in rng.integers(0, len(POOL), 400) for ln in POOL[k].split("\n")]
    data = ("\n".join(lines) + "\n").encode()
    path = tmp_path / ("in.nmea.gz" if gz else "in.nmea")
    path.write_bytes(gzip.compress(data) if gz else data)
    monkeypatch.setattr(ingest_stage, "GZIP_PLAIN_MIN_BYTES", 0)
    monkeypatch.setattr(P, "ROW_GROUP_ROWS", 20)
    monkeypatch.setattr(nmea_chunks, "CHUNK_BYTES", 3000)
    monkeypatch.setattr(groups_mod, "NMEA_GROUP_ROWS", 60)
    dbs = {}
    for side, min_bytes in (("whole", 1 << 62), ("part", 1000)):
        monkeypatch.setattr(groups_mod, "NMEA_GROUP_MIN_BYTES", min_bytes)
        dbs[side] = tmp_path / side / "w.duckdb"
        dbs[side].parent.mkdir()
        spool = tmp_path / side / "spool"
        spool.mkdir()
        with open_workspace(dbs[side]) as ws:
            todo, _ = plan_files(ws, [str(path)], None)
            staged = stage_to_spool(todo[0], None, str(spool))
            counts = commit_spooled(ws, staged)
        assert (counts["staging"] == "groups") == (side == "part") and counts["loaded"] > 0
        assert list(spool.iterdir()) == [] and path.exists()
    assert _state(dbs["part"]) == _state(dbs["whole"])
    assert not list(tmp_path.glob("**/.stormlane-groups-*"))


def test_a_file_of_ignored_lines_only_counts_them_in_groups(tmp_path, monkeypatch):
    """No AIS item at all (blank lines, other sentences): one empty group counts the ignored
    lines, as the whole file's ingest does."""
    lines = ["", "$PSTT,30A,20131112,120000*6D", "", "$PGHP,1,2025,1,1,0,0,5,0,219,,2190067,1,00*00"] * 5
    path = _write(tmp_path / "f.nmea", lines)
    monkeypatch.setattr(nmea_chunks, "CHUNK_BYTES", 40)
    got = {}
    for side, min_bytes in (("whole", 1 << 62), ("split", 0)):
        monkeypatch.setattr(groups_mod, "NMEA_GROUP_MIN_BYTES", min_bytes)
        with open_workspace(tmp_path / f"{side}.duckdb") as ws:
            c = ingest_file(ws, path)
        got[side] = (c["read"], c["ignored"], c["loaded"])
        assert (c["staging"] == "groups") == (side == "split")
    assert got["split"] == got["whole"] == (0, 15, 0)
