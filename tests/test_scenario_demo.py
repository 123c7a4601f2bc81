"""The scenario through the real ingest, and `stormlane demo` end to end in a temporary folder."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pipelines.scenario import build_scenario

#: The ingest reason each injected kind must get, per output format (ais.clean codes).
REASON = {
    ("dma_csv", "sentinel_position"): {"no_position"},
    ("nmea", "sentinel_position"): {"no_position"},
    ("dma_csv", "out_of_range"): {"bad_lat", "bad_lon"},
    ("nmea", "out_of_range"): {"bad_lat", "bad_lon"},
    ("dma_csv", "invalid_mmsi"): {"bad_mmsi"},
    ("nmea", "invalid_mmsi"): {"bad_mmsi"},
    ("dma_csv", "bad_timestamp"): {"bad_time"},
    ("dma_csv", "speed_jump"): {"speed_jump"},
    ("nmea", "speed_jump"): {"speed_jump"},
    ("dma_csv", "duplicate_exact"): {"duplicate"},
    ("nmea", "duplicate_exact"): {"duplicate_payload"},
    ("dma_csv", "duplicate_timestamp"): {"duplicate_time"},
    ("nmea", "duplicate_timestamp"): {"duplicate_time"},
    ("dma_csv", "malformed_row"): {"bad_line"},
    ("nmea", "bad_checksum"): {"bad_checksum"},
}


@pytest.fixture(scope="module")
def ingested(tmp_path_factory):
    from pipelines.ingest import ingest_paths

    out = tmp_path_factory.mktemp("scenario_ingest")
    truth = build_scenario(out, seed=11, days=2)
    summary = ingest_paths([out / "ais"], out / "ws.duckdb")
    return out, truth, summary


def test_ingest_rejects_every_injected_row_with_its_reason(ingested):
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import read_quarantine

    out, truth, summary = ingested
    exp = truth["expected_ingest"]
    assert summary["read"] == exp["position_records"]
    assert summary["loaded"] == exp["loaded"]
    assert summary["quarantined"] + summary["duplicates"] == exp["rejected"]
    assert summary["static"] == exp["static_messages"]
    with open_workspace(out / "ws.duckdb") as ws:
        q = read_quarantine(ws)
    got = {(Path(p).name, int(line)): reason for p, line, reason in zip(q.path, q.line, q.reason)}
    dirty = [r for r in truth["dirty_rows"]["rows"] if r["kind"] != "sentinel_fields"]
    assert len(dirty) == exp["rejected"] == len(got)
    for r in dirty:
        key = (Path(r["file"]).name, r["line"])
        assert key in got, r
        assert got[key] in REASON[(r["format"], r["kind"])], (r, got[key])


def test_sentinel_fields_load_as_null_and_vessels_are_known(ingested):
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import read_vessels

    out, truth, _ = ingested
    rows = [r for r in truth["dirty_rows"]["rows"] if r["kind"] == "sentinel_fields"]
    assert rows
    with open_workspace(out / "ws.duckdb") as ws:
        pos = ws.con.execute(
            "SELECT f.path, p.source_line, p.sog_kn, p.cog_deg, p.heading_deg FROM ais_positions p "
            "JOIN ais_files f USING (file_id)"
        ).fetchdf()
        vessels = read_vessels(ws)
    pos["file"] = [Path(p).name for p in pos.path]
    by_key = pos.set_index(["file", "source_line"])
    for r in rows:
        got = by_key.loc[(Path(r["file"]).name, r["line"])]
        for col in ("sog_kn", "cog_deg", "heading_deg"):
            assert (got[col] != got[col]) == (col in r["detail"].split(",")), (r, col)  # NaN exactly where sentinel
    names = {v["mmsi"]: v["name"] for v in truth["vessels"]}
    assert dict(zip(vessels.mmsi, vessels.name)) == names


def test_demo_end_to_end(tmp_path, prefect_harness):
    from typer.testing import CliRunner

    from pipelines.cli import app

    workdir = tmp_path / "demo"
    res = CliRunner().invoke(app, ["demo", "--workdir", str(workdir), "--days", "1", "--json"])
    assert res.exit_code == 0, res.output
    obj = json.loads(res.stdout)
    steps = obj["steps"]
    assert list(steps)[:2] == ["scenario", "ingest"]
    truth = json.loads((workdir / "scenario.json").read_text())
    assert steps["ingest"]["loaded"] == truth["expected_ingest"]["loaded"] > 10_000
    assert steps["ingest"]["files"] == len(truth["ais"]["files"])
    assert (workdir / "stormlane.duckdb").is_file()
    # a second run regenerates identical files; the ingest skips them (same SHA-256)
    from pipelines.demo import STEPS, run_demo

    again = run_demo(workdir, days=1, echo=lambda line: None,
                     steps=[s for s in STEPS if s[0] in ("scenario", "ingest")])["ingest"]
    assert again["loaded"] == 0 and again["already_loaded"] == len(truth["ais"]["files"])
