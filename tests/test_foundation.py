"""Foundation: workspace migrations, geodesy, the Route type, the CLI skeleton."""

from __future__ import annotations

import json
import subprocess
import sys

import duckdb
import numpy as np
import pandas as pd
import pytest

from pipelines.storage import migrate, open_workspace
from routing.route import Route
from thresholds.geodesy import destination_point, haversine_nmi, initial_bearing_deg, intermediate_point
from thresholds.units import EARTH_RADIUS_NMI, dir_from_uv, dir_to_uv


def test_migrations_are_recorded_and_idempotent(workspace_path):
    with open_workspace(workspace_path) as ws:
        first = dict(ws.con.execute("SELECT component, max(version) FROM schema_version GROUP BY 1").fetchall())
        rows = ws.con.execute("SELECT count(*) FROM schema_version").fetchone()[0]
    assert first["core"] >= 1
    with open_workspace(workspace_path) as ws:
        again = migrate(ws.con)
        assert ws.con.execute("SELECT count(*) FROM schema_version").fetchone()[0] == rows
    assert again == first


def test_newer_schema_than_code_is_refused(workspace_path):
    with open_workspace(workspace_path) as ws:
        ws.con.execute("INSERT INTO schema_version (component, version) VALUES ('core', 999)")
    with pytest.raises(RuntimeError, match="newer than this code"):
        open_workspace(workspace_path)


def test_transaction_rolls_back_on_error(workspace_path):
    with open_workspace(workspace_path) as ws:
        with pytest.raises(duckdb.Error):
            with ws.transaction() as con:
                con.execute("INSERT INTO workspace_meta VALUES ('k', 'v')")
                con.execute("INSERT INTO workspace_meta VALUES ('k', 'again')")  # primary key violation
        assert ws.con.execute("SELECT count(*) FROM workspace_meta WHERE key = 'k'").fetchone()[0] == 0


def test_haversine_quarter_meridian():
    # Pole to equator is a quarter of the circumference: pi/2 * R.
    assert haversine_nmi(0.0, 0.0, 90.0, 0.0) == pytest.approx(np.pi / 2 * EARTH_RADIUS_NMI, rel=1e-12)
    # One arc-minute of latitude on the mean sphere is 1852 m * R_nmi / (180*60/pi) nmi.
    assert haversine_nmi(0.0, 0.0, 1.0 / 60.0, 0.0) == pytest.approx(EARTH_RADIUS_NMI * np.pi / 10800.0, rel=1e-9)


def test_bearings_and_points_are_consistent():
    assert initial_bearing_deg(0, 0, 0, 10) == pytest.approx(90.0)
    assert initial_bearing_deg(0, 0, -10, 0) == pytest.approx(180.0)
    lat, lon = intermediate_point(10.0, 0.0, 10.0, 120.0, 0.5)
    # The great circle between two points on the 10th parallel bulges poleward at mid-longitude.
    assert lon == pytest.approx(60.0) and lat > 10.0
    lat2, lon2 = destination_point(41.0, 2.0, 45.0, 100.0)
    assert haversine_nmi(41.0, 2.0, lat2, lon2) == pytest.approx(100.0, rel=1e-9)


def test_direction_conventions():
    # Wind from the west (u > 0) comes FROM 270; a current flowing east flows TO 90.
    assert dir_from_uv(5.0, 0.0) == pytest.approx(270.0)
    assert dir_from_uv(0.0, -5.0) == pytest.approx(0.0)
    assert dir_to_uv(1.0, 0.0) == pytest.approx(90.0)


def test_route_totals_and_json_round_trip():
    t = pd.date_range("2020-01-20T09:00Z", periods=3, freq="1h")
    route = Route("optimal", [39.0, 39.5, 40.0], [2.0, 2.0, 2.0], t, [30.0, 30.0], weather={"hs_m": [1.0, 3.5, 2.0]})
    assert route.time_h == pytest.approx(2.0)
    assert route.dist_nmi == pytest.approx(2 * haversine_nmi(39.0, 2.0, 39.5, 2.0))
    assert route.max_hs_m == 3.5
    back = Route.from_json(route.to_json())
    np.testing.assert_array_equal(back.lat_deg, route.lat_deg)
    assert list(back.time_utc) == list(route.time_utc)
    assert route.to_dict()["waypoints"][0] == [39.0, 2.0, "2020-01-20T09:00:00Z"]


def test_route_rejects_naive_times_and_bad_lengths():
    with pytest.raises(ValueError, match="timezone-aware"):
        Route("x", [0, 1], [0, 1], pd.date_range("2020-01-01", periods=2, freq="h"), [10.0])
    with pytest.raises(ValueError, match="leg_speed_kn"):
        Route("x", [0, 1], [0, 1], pd.date_range("2020-01-01", periods=2, freq="h", tz="UTC"), [10.0, 3.0])


def test_cli_help_lists_commands_and_workspace_json(tmp_path):
    out = subprocess.run([sys.executable, "-m", "pipelines.cli", "--help"], capture_output=True, text=True, check=True)
    assert "workspace" in out.stdout
    db = tmp_path / "w.duckdb"
    res = subprocess.run(
        [sys.executable, "-m", "pipelines.cli", "workspace", "--db", str(db), "--json"], capture_output=True, text=True, check=True
    )
    info = json.loads(res.stdout)
    assert info["schema"]["core"] >= 1 and "schema_version" in info["tables"]
