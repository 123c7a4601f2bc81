"""Regressions found by playing the reviewer on the CLI contracts (helper "cli-sweep").

Each test failed before its fix: a traceback or a silent wrong answer where the contract asks for
one clear line naming the file / line / field and exit status 2 (or for a working command).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import _report_fixtures as fx


def _cli_error(capsys, argv) -> str:
    """Run ``stormlane argv``; assert exit status 2 and return the single error line."""
    from pipelines.cli import main

    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, err
    return lines[0]


# --- stormlane report: re-render a stored model ---------------------------------------------------


def test_report_model_with_mixed_iso_times_round_trips(tmp_path):
    """``Timestamp.isoformat()`` drops a zero fraction, so a stored frame mixes
    "...:00+00:00" and "...:00.500000+00:00"; ``stormlane report --model`` on the demo's
    report.json failed to parse them (pandas inferred one format from the first value)."""
    from dashboards.model import report_from_json, report_to_json
    from dashboards.report import render_report

    model = fx.nightly(n_adverse=1)
    ev = model.departures[0].routes.events
    ev.loc[1, "start_utc"] = ev.loc[1, "start_utc"] + pd.Timedelta(milliseconds=500)
    back = report_from_json(report_to_json(model))
    got = back.departures[0].routes.events
    assert got.loc[1, "start_utc"] == pd.Timestamp("2025-01-31T10:30:00.5Z")
    assert got.loc[0, "start_utc"] == pd.Timestamp("2025-01-31T10:00Z")
    assert render_report(back, tmp_path / "a.html").read_text() == render_report(model, tmp_path / "b.html").read_text()


def test_report_cli_unwritable_out_is_one_line(tmp_path, capsys):
    from dashboards.model import report_to_json

    model = tmp_path / "m.json"
    model.write_text(report_to_json(fx.nightly(n_adverse=0)))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    line = _cli_error(capsys, ["report", "--model", str(model), "--out", str(blocker / "r.html")])
    assert line == f"error: --out {blocker / 'r.html'}: {blocker} exists and is not a folder"


# --- stormlane weather join / exceedance -----------------------------------------------------------


@pytest.mark.parametrize(
    ("extra", "expect"),
    [
        (["--depart", "garbage"], "--depart 'garbage' is not an ISO 8601 time"),
        (["--depart", "2025-01-14T00:00Z", "--step-h", "0", "--count", "3"], "--step-h 0: hours between departures must be > 0"),
        (["--depart", "2025-01-14T00:00Z", "--step-h", "-3", "--count", "2"], "--step-h -3"),
        (["--depart", "2025-01-14T00:00Z", "--step-h", "3", "--count", "0"], "--count 0: need at least one departure"),
    ],
)
def test_weather_join_bad_departures(tmp_path, capsys, extra, expect):
    db = _empty_workspace(tmp_path)
    line = _cli_error(capsys, ["weather", "join", "--db", str(db), *extra])
    assert expect in line


@pytest.mark.parametrize(
    ("body", "expect"),
    [
        ("A,0,41.2,abc,12\n", "line 2: field 'lon_deg' 'abc' is not a number"),
        ("A,0,41.2,2.5,12\n\nA,1,40.0,x,12\n", "line 4: field 'lon_deg' 'x' is not a number"),
        ("A,0,41.2,,12\n", "line 2: field 'lon_deg' is empty"),
        ("A,0,41.2,2.5,12\nA,1,40.0,3.0,0\n", "line 3: field 'speed_kn' '0' is not a speed > 0 kn"),
    ],
)
def test_weather_join_points_csv_names_line_and_field(tmp_path, capsys, body, expect):
    pts = tmp_path / "points.csv"
    pts.write_text("path_id,seq,lat_deg,lon_deg,speed_kn\n" + body)
    line = _cli_error(capsys, ["weather", "join", "--db", str(_empty_workspace(tmp_path)), "--depart", "2025-01-14T00:00Z",
                               "--points", str(pts)])
    assert line == f"error: {pts}: {expect}"


def test_weather_join_points_csv_reads_good_values(tmp_path):
    from pipelines.commands.weather import _read_points

    pts = tmp_path / "points.csv"
    pts.write_text("path_id,seq,lat_deg,lon_deg,speed_kn\nA,0,41.2,2.5,12\n\nA,1,40.0,3.0,11.5\n")
    got = _read_points(pts)
    assert got["lon_deg"].tolist() == [2.5, 3.0] and got["speed_kn"].tolist() == [12.0, 11.5]
    assert got["path_id"].tolist() == ["A", "A"]


def test_exceedance_without_wave_height_is_a_coverage_error():
    """A wind-only file (e.g. the ERA5 tws/twd zarr) has no hs_m: a user error naming the
    product and the variable, not a ValueError traceback."""
    import xarray as xr

    from pipelines.config import load_operator_profile, load_vessel
    from weather.errors import CoverageError
    from weather.exposure import exceedance_by_time

    t = pd.date_range("2022-01-01", periods=2, freq="h").values
    u = np.ones((2, 2, 3))
    ds = xr.Dataset({"wind_u_ms": (("time_utc", "lat", "lon"), u), "wind_v_ms": (("time_utc", "lat", "lon"), u)},
                    coords={"time_utc": t, "lat": [0.0, 1.0], "lon": [0.0, 1.0, 2.0]}, attrs={"product": "ERA5 wind test"})
    with pytest.raises(CoverageError, match=r"ERA5 wind test: variable hs_m .* missing.*wind_u_ms, wind_v_ms"):
        exceedance_by_time(ds, load_vessel("container-large"), load_operator_profile(None))


# --- stormlane scenario / demo ---------------------------------------------------------------------


def test_scenario_negative_seed_and_file_as_out(tmp_path, capsys):
    line = _cli_error(capsys, ["scenario", "--out", str(tmp_path / "sc"), "--seed", "-1", "--days", "1"])
    assert line == "error: --seed -1: the seed must be a non-negative integer"
    assert not (tmp_path / "sc").exists()
    blocker = tmp_path / "file"
    blocker.write_text("x")
    line = _cli_error(capsys, ["scenario", "--out", str(blocker), "--days", "1"])
    assert line == f"error: --out {blocker}: exists and is not a folder"
    line = _cli_error(capsys, ["demo", "--out", str(blocker), "--days", "1"])
    assert line == f"error: --out {blocker}: exists and is not a folder"


# --- stormlane nightly --voyages CSV ---------------------------------------------------------------


def test_planned_voyages_unknown_vessel_names_file_line_field(tmp_path):
    from pipelines.nightly import NightlyError, read_planned_voyages

    csv = tmp_path / "voyages.csv"
    csv.write_text("vessel,origin,destination,depart_utc\nro-pax,ESBCN,ESPMI,2025-01-31T03:00Z\n"
                   "no-such-ship,ESBCN,ITGOA,2025-01-31T06:00Z\n")
    with pytest.raises(NightlyError, match=rf"^{csv}: line 3: field 'vessel': unknown vessel profile 'no-such-ship'"):
        read_planned_voyages(csv)


def test_planned_voyages_not_utf8_and_bom(tmp_path):
    from pipelines.nightly import NightlyError, read_planned_voyages

    bad = tmp_path / "bad.csv"
    bad.write_bytes(b"vessel,origin,destination,depart_utc\nro-pax,ESBCN,\xff\xfeITGOA,2025-01-31T03:00Z\n")
    with pytest.raises(NightlyError, match=rf"^{bad}: line 2: not UTF-8 text \(byte 0xff\)"):
        read_planned_voyages(bad)
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbfvessel,origin,destination,depart_utc\r\nro-pax,ESBCN,ESPMI,2025-01-31T03:00Z\r\n")
    got = read_planned_voyages(bom)
    assert got[["vessel", "origin", "destination", "line"]].values.tolist() == [["ro-pax", "ESBCN", "ESPMI", 2]]
    assert got["depart_utc"].iloc[0] == pd.Timestamp("2025-01-31T03:00Z")


def test_nightly_bad_planned_voyage_fails_before_the_flow(tmp_path, capsys):
    """The CSV is read in the preflight: one line, exit 2, before any Prefect server starts."""
    db = tmp_path / "ws.duckdb"
    from pipelines.storage import open_workspace

    with open_workspace(db):
        pass
    csv = tmp_path / "voyages.csv"
    csv.write_text("vessel,origin,destination,depart_utc\nro-pax,ESBCN,ESPMI,31/01/2025 03:00 tomorrow\n")
    line = _cli_error(capsys, ["nightly", "--db", str(db), "--voyages", str(csv), "--now", "2025-01-31T00:00Z", "--no-report"])
    assert line.startswith(f"error: {csv}: line 2: field 'depart_utc'")


# --- --db that is not a workspace; route across the antimeridian -----------------------------------


@pytest.mark.parametrize("content", [b"garbage\n", b""])
def test_db_that_is_not_duckdb_is_one_line(tmp_path, capsys, content):
    bad = tmp_path / "notes.duckdb"
    bad.write_bytes(content)
    line = _cli_error(capsys, ["workspace", "--db", str(bad), "--json"])
    assert line.startswith(f"error: workspace {bad} is not a DuckDB database file")
    assert bad.read_bytes() == content  # left alone
    line = _cli_error(capsys, ["lanes", "--db", str(tmp_path), "--json"])
    assert line == f"error: workspace {tmp_path} is not a file (give --db a DuckDB file)"


def test_route_across_the_antimeridian_is_planned_and_a_box_round_the_world_is_a_user_error(capsys):
    import json

    from pipelines.cli import main

    main(["route", "--from", "10,170", "--to", "10,-170", "--depart", "2020-01-20T09:00Z", "--mesh-deg", "0.5", "--ignore-land",
          "--json"])  # fmt: skip
    data = json.loads(capsys.readouterr().out)
    lons = [w[1] for w in data["optimal_smoothed"]["waypoints"]]
    assert lons[0] == 170.0 and lons[-1] == -170.0 and data["optimal_smoothed"]["dist_nmi"] < 1200.0  # across 180, not round
    line = _cli_error(capsys, ["route", "--from", "10,170", "--to", "10,-170", "--depart", "2020-01-20T09:00Z", "--mesh-deg", "0.5",
                               "--ignore-land", "--bbox", "-180,0,190,20"])  # fmt: skip
    assert line.startswith("error: bbox (-180.0, 0.0, 190.0, 20.0) must lie within lat -89..89 and span at most 360 deg of longitude")


# --- audit options; outputs that cannot be written --------------------------------------------------


def _empty_workspace(tmp_path):
    from pipelines.storage import open_workspace

    db = tmp_path / "ws.duckdb"
    with open_workspace(db):
        pass
    return db


def test_audit_bad_time_and_speed_loss_are_one_line(tmp_path, capsys):
    db = _empty_workspace(tmp_path)
    line = _cli_error(capsys, ["audit", "--db", str(db), "--mmsi", "219000123", "--start", "garbage", "--end", "2025-01-04T00:00Z"])
    assert line == "error: --start 'garbage' is not an ISO 8601 time"
    line = _cli_error(capsys, ["audit", "--db", str(db), "--mmsi", "219000123", "--start", "2025-01-03T00:00Z", "--end", "soon"])
    assert line == "error: --end 'soon' is not an ISO 8601 time"
    from pipelines.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["audit", "--db", str(db), "--voyage", "v1", "--speed-loss", "foo"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Invalid value for --speed-loss: 'foo' is not one of" in " ".join(err.split()) and "Traceback" not in err


def test_unwritable_outputs_are_user_errors(tmp_path, capsys):
    from dashboards.errors import ExportError
    from dashboards.exports import write_routes
    from pipelines.lanes import LanesInputError, export_geojson

    blocker = tmp_path / "file"
    blocker.write_text("x")
    route = fx.routes()["optimal"]
    for suffix in ("geojson", "gpx", "rtz"):
        with pytest.raises(ExportError, match=rf"^{blocker}/r\.{suffix}: cannot write the export"):
            write_routes([route], blocker / f"r.{suffix}")
    db = _empty_workspace(tmp_path)
    with pytest.raises(LanesInputError, match=rf"^{blocker}/l\.geojson: cannot write the lanes GeoJSON"):
        export_geojson(db, blocker / "l.geojson")
    line = _cli_error(capsys, ["nightly", "--db", str(db), "--out", str(blocker / "night"), "--now", "2025-01-31T00:00Z"])
    assert line == f"error: --out {blocker / 'night'}: {blocker} exists and is not a folder"


# --- weather fetch without credentials: no prompt, stdout clean ----------------------------------------


class _PromptingClient:
    """Like copernicusmarine without credentials: asks for a username on stdin (click.prompt ->
    input) and, when stdin has nothing, prints "Abort" and returns None."""

    def __init__(self):
        self.answers = []

    def subset(self, **kw):
        try:
            self.answers.append(input("Copernicus Marine username: "))
        except EOFError:
            print("Abort")
            return None
        return None


def test_cmems_fetch_never_waits_for_a_username_and_keeps_stdout_clean(tmp_path, monkeypatch, capsys):
    """Before: on a terminal `stormlane weather fetch` (or nightly --fetch) waited for a typed
    username, and the prompt landed on stdout in front of the --json object."""
    import io
    import sys

    from weather.errors import FetchError
    from weather.io.cache import DownloadCache
    from weather.io.cmems import get_cmems

    fake = _PromptingClient()
    monkeypatch.setitem(sys.modules, "copernicusmarine", fake)
    monkeypatch.setattr(sys, "stdin", io.StringIO("someone\n"))  # a person at the keyboard
    with pytest.raises(FetchError, match="copernicusmarine client returned nothing"):
        get_cmems((2, 39, 3, 40), "2025-01-14", "2025-01-15", cache=DownloadCache(tmp_path))
    assert fake.answers == []  # never read the person's input
    out, err = capsys.readouterr()
    assert out == "" and "Copernicus Marine username: Abort" in err
    assert sys.stdin.read() == "someone\n"  # stdin given back untouched


def test_workspace_locked_by_another_process_is_one_line(tmp_path, capsys):
    """Another stormlane (or any DuckDB) process writing the workspace: one line, exit 2."""
    import subprocess
    import sys

    db = _empty_workspace(tmp_path)
    holder = subprocess.Popen(
        [sys.executable, "-c", f"import duckdb, sys, time; c = duckdb.connect({str(db)!r}); print('ready', flush=True); time.sleep(60)"],
        stdout=subprocess.PIPE, text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "ready"
        line = _cli_error(capsys, ["workspace", "--db", str(db), "--json"])
    finally:
        holder.kill()
        holder.wait()
    assert line.startswith("error: the workspace is in use by another process (IO Error: Could not set lock on file")
    assert capsys.readouterr().out == ""


@pytest.mark.parametrize(
    ("argv", "expect"),
    [
        (["route", "--from", "39.2,2.9", "--to", "41.5,2.7", "--depart", "2020-01-20T09:00Z", "--speed-loss", "foo"],
         "error: Invalid value for --speed-loss: 'foo' is not one of bowditch, aertssen, khokhlov, kwon, none, learned:NAME (see `stormlane route --help`)"),
        (["route", "--from", "39.2,2.9", "--to", "41.5,2.7", "--depart", "2020-01-20T09:00Z", "--edges", "12"],
         "error: Invalid value for --edges: 12 is not one of 8, 16, 24, 48 (see `stormlane route --help`)"),
        (["route", "--to", "41.5,2.7"], "error: Missing option '--from'. (see `stormlane route --help`)"),
        (["nightly", "--window-h", "0"],
         "error: Invalid value for '--window-h': Input should be greater than or equal to 0.1 (see `stormlane nightly --help`)"),
        (["weather", "join", "--depart-at", "x"], "error: No such option: --depart-at (Possible options: --depart) (see `stormlane weather join --help`)"),
        (["no-such-command"], "error: No such command 'no-such-command'. (see `stormlane --help`)"),
    ],
)
def test_option_parser_errors_are_one_line(capsys, argv, expect):
    """Bad option values used to print typer's usage box, the message wrapped over several lines
    at 80 columns; now one `error:` line like every other user error (exit status 2)."""
    assert _cli_error(capsys, argv) == expect


def test_help_and_no_arguments_still_print_the_help(capsys):
    from pipelines.cli import main

    try:
        main(["route", "--help"])
    except SystemExit as exc:
        assert exc.code in (0, None)
    assert "--speed-loss" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        main([])
    assert exc.value.code == 2 and "route" in capsys.readouterr().out


# --- file-system errors on paths the user gave -------------------------------------------------------


def test_db_in_a_folder_that_cannot_exist_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    line = _cli_error(capsys, ["workspace", "--db", str(blocker / "ws.duckdb"), "--json"])
    assert line == f"error: workspace {blocker / 'ws.duckdb'}: {blocker} exists and is not a folder"


def test_os_errors_on_user_paths_are_one_line(tmp_path, capsys, monkeypatch):
    """The safety net of the entry point: an OSError naming a path (here the screenshot's folder
    under a file, as `stormlane report --screenshot` hit it) is one line, exit 2."""
    from pathlib import Path

    import dashboards.browser
    from dashboards.model import report_to_json

    def fake_screenshot(report_path, png_path, **kw):  # the real one opens Chromium first
        raise FileExistsError(17, "File exists", str(blocker))  # as a folder under a file gives

    monkeypatch.setattr(dashboards.browser, "screenshot", fake_screenshot)
    model = tmp_path / "m.json"
    model.write_text(report_to_json(fx.nightly(n_adverse=0)))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    line = _cli_error(capsys, ["report", "--model", str(model), "--out", str(tmp_path / "r.html"),
                               "--screenshot", str(tmp_path / "shot.png")])
    assert line == f"error: {blocker}: File exists"
