"""The lanes step after ingest: plain entry, Prefect flow, CLI contract (--json, --geojson, errors)."""

from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import pytest

from lanes_tracks import T0, shuttle

A = (41.30, 2.20)
B = (41.30, 2.60)


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """Three ferries shuttling A <-> B ingested through the real ingest (Parquet, canonical columns)."""
    from pipelines.ingest import ingest_paths

    tmp = tmp_path_factory.mktemp("lanes_flow")
    frames = [shuttle(201000000 + i, A if i % 2 == 0 else B, B if i % 2 == 0 else A, 4, lateral_nmi=off, seed=i,
                      start=T0 + pd.Timedelta(minutes=17 * i)) for i, off in enumerate((-0.2, 0.0, 0.2))]
    df = pd.concat(frames, ignore_index=True)
    df["heading_deg"] = float("nan")
    path = tmp / "ferries.parquet"
    df[["mmsi", "time_utc", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status"]].to_parquet(path)
    db = tmp / "ws.duckdb"
    summary = ingest_paths([path], db)
    assert summary["loaded"] == len(df), summary
    return db, len(df)


def test_run_lanes_after_ingest(workspace):
    from pipelines.lanes import run_lanes
    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import read_lane_centroids, read_lanes, read_ports

    db, n = workspace
    out = run_lanes(db)
    assert {k: out[k] for k in ("ports", "voyages", "lanes")} == {"ports": 2, "voyages": 12, "lanes": 2}
    assert out["details"]["positions"] == n
    with open_workspace(db) as ws:
        assert len(read_lanes(ws)) == 2 and len(read_ports(ws)) == 2
        assert len(read_lane_centroids(ws)) >= 8


def test_lanes_flow_under_prefect(workspace, prefect_harness):
    from pipelines.lanes import LanesSettings, lanes_flow

    db, _ = workspace
    out = lanes_flow(db=str(db), settings=LanesSettings())
    assert {k: out[k] for k in ("ports", "voyages", "lanes")} == {"ports": 2, "voyages": 12, "lanes": 2}
    assert out["noise_points"] == out["details"]["noise_points"]


class _Res:
    def __init__(self, code, out, err):
        self.returncode, self.stdout, self.stderr = code, out, err


@pytest.fixture
def cli(capsys):
    """Run ``stormlane ARGS...`` in-process through the console entry point (exit code, stdout, stderr)."""
    from pipelines.cli import main

    def run(*args):
        capsys.readouterr()
        try:
            main([str(a) for a in args])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        out = capsys.readouterr()
        return _Res(code, out.out, out.err)

    return run


def test_console_script_runs(tmp_path):
    res = subprocess.run([sys.executable, "-m", "pipelines.cli", "lanes", "--db", str(tmp_path / "x.duckdb"), "--json"],
                         capture_output=True, text=True)
    assert res.returncode == 2 and res.stdout == "" and res.stderr.startswith("error: workspace")


def test_cli_json_contract_and_geojson(workspace, tmp_path, cli):
    db, _ = workspace
    gj = tmp_path / "lanes.geojson"
    res = cli("lanes", "--db", str(db), "--json", "--geojson", str(gj))
    assert res.returncode == 0, res.stderr
    lines = res.stdout.strip().splitlines()
    assert len(lines) == 1
    out = json.loads(lines[0])
    assert list(out) == ["ports", "voyages", "lanes", "noise_points"]
    assert out["ports"] == 2 and out["voyages"] == 12 and out["lanes"] == 2 and out["noise_points"] >= 0
    fc = json.loads(gj.read_text())
    assert fc["type"] == "FeatureCollection"
    assert {f["properties"]["layer"] for f in fc["features"]} == {"port", "lane", "lane_path", "centroid"}


def test_cli_human_output_and_help(workspace, cli):
    db, _ = workspace
    res = cli("lanes", "--db", str(db))
    assert res.returncode == 0, res.stderr
    assert "voyages port-to-port 12" in res.stdout and "lanes 2" in res.stdout
    assert cli("lanes", "--help").returncode == 0


def test_a_run_without_lanes_says_which_step_gave_nothing(workspace, tmp_path, cli):
    """Zero lanes is one warning line naming the first empty step: here the 12 voyages make no cluster of 13
    (--json still prints exactly the counts); a vessel that never stops gives no port, so no voyage."""
    from lanes_tracks import Itinerary

    from pipelines.ingest import ingest_paths

    db, _ = workspace
    res = cli("lanes", "--db", str(db), "--min-voyages", "13", "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["lanes"] == 0
    assert res.stderr.splitlines() == ["warning: no lanes: the 12 port-to-port voyages formed no cluster of at least 13 "
                                       "voyages (--min-voyages, --min-density 3, --eps-nmi 2)"]
    res = cli("lanes", "--db", str(db))  # the default run makes lanes: nothing to warn about
    assert res.returncode == 0 and "warning" not in res.stderr
    transit = Itinerary(219000001).stay(*A, 1).sail(*B, 12.0).frame()  # one fix in port, then under way: no stop
    transit["heading_deg"] = float("nan")
    transit.to_parquet(tmp_path / "transit.parquet")
    ingest_paths([tmp_path / "transit.parquet"], tmp_path / "t.duckdb")
    res = cli("lanes", "--db", str(tmp_path / "t.duckdb"))
    assert res.returncode == 0, res.stderr
    assert "voyages port-to-port 0 (all segments: transit 1)" in res.stdout
    assert res.stderr.splitlines() == ["warning: no lanes: no vessel stopped (below 0.5 kn for 3 min or more), so no ports were "
                                       "found; lanes are built from voyages between ports"]


def test_cli_errors_are_one_line_exit_2(tmp_path, cli):
    res = cli("lanes", "--db", str(tmp_path / "none.duckdb"), "--json")
    assert res.returncode == 2
    assert res.stderr.strip().startswith("error: workspace") and len(res.stderr.strip().splitlines()) == 1
    assert "none.duckdb does not exist" in res.stderr and not (tmp_path / "none.duckdb").exists()  # never created
    db = tmp_path / "empty.duckdb"
    assert cli("workspace", "--db", str(db)).returncode == 0
    res = cli("lanes", "--db", str(db), "--eps-course-deg", "200")
    assert res.returncode == 2 and "eps_course_deg" in res.stderr
    res = cli("lanes", "--db", str(db), "--merge-voyage-share", "1.5")
    assert res.returncode == 2 and "merge_voyage_share" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    bad = tmp_path / "ports.csv"
    bad.write_text("locode,name\nXX,Y\n")
    res = cli("lanes", "--db", str(db), "--ports", str(bad))
    assert res.returncode == 2 and "missing column" in res.stderr


def test_empty_workspace_is_a_clear_error(tmp_path):
    from pipelines.lanes import LanesInputError, run_lanes
    from pipelines.storage import open_workspace

    db = tmp_path / "empty.duckdb"
    open_workspace(db).close()
    with pytest.raises(LanesInputError, match="no AIS positions"):
        run_lanes(db)


def test_demo_lanes_step(workspace, prefect_harness, tmp_path):
    import shutil

    from pipelines.demo import STEPS, DemoContext, step_lanes

    names = [name for name, _ in STEPS]
    assert names.index("lanes") == names.index("ingest") + 1
    db, _ = workspace
    ctx = DemoContext(workdir=tmp_path, echo=lambda line: None)
    shutil.copy(db, ctx.db)
    out = step_lanes(ctx)
    assert {k: out[k] for k in ("ports", "voyages", "lanes")} == {"ports": 2, "voyages": 12, "lanes": 2}
    assert (tmp_path / "lanes.geojson").is_file() and out["pairs_sailed"] == 0
