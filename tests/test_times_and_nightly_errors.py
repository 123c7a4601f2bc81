"""Times the user types are ISO 8601 only; nightly user errors are one line naming what to fix.

Regressions of a reviewer's findings on a fresh clone: ``01/02/2025`` was read month-first
(and ``14/01/2025`` day-first, ``now``, ``Jan 5 2025`` ... accepted); a planned voyage at
``14th of jan`` became year 1; a CSV whose every row failed lost the reasons; Prefect printed
its own ERROR lines before the nightly's ``error:`` line.
"""

from __future__ import annotations

import io
import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from nightly_world import NOW, build_world
from cli_runner import run_cli as _cli

REPO = Path(__file__).resolve().parents[1]

# --- the parser ------------------------------------------------------------------------------------


@pytest.mark.parametrize("text, expected", [
    ("2020-01-20T09:00Z", "2020-01-20T09:00Z"),  # README, route tests
    ("2025-01-14T12:00:00+00:00", "2025-01-14T12:00Z"),  # Timestamp.isoformat()
    ("2025-01-31T00:00", "2025-01-31T00:00Z"),  # naive = UTC
    ("2025-01-31", "2025-01-31T00:00Z"),
    ("2025-01-31 06:30", "2025-01-31T06:30Z"),
    ("2025-01-31T02:30+01:00", "2025-01-31T01:30Z"),
    ("2025-01-31T02:30:15.5-05:30", "2025-01-31T08:00:15.5Z"),
    ("2025-01-31T00:00:00.123456789Z", "2025-01-31T00:00:00.123456789Z"),
])
def test_iso_8601_forms_are_read_as_utc(text, expected):
    from pipelines.times import utc_or_none

    got = utc_or_none(text)
    assert got == pd.Timestamp(expected) and str(got.tz) == "UTC"


@pytest.mark.parametrize("text", [
    "01/02/2025",  # January 2nd or February 1st? (DMA AIS files are day-first)
    "14/01/2025", "31/01/2025 03:00", "now", "today", "Jan 5 2025", "5 January 2025", "20250105", "20250105T0600",
    "14th of jan", "2025-1-5", "2025-01-31T6:00", "2025-02-30", "2025-13-01", "2025-01-31T24:00", "2025-01-31Z",
    "2025-01-31T00:00+0100", "2025-01-31T00:00 UTC", "0001-01-14", "9999-12-31", "", "   ",
])
def test_anything_else_is_not_a_time(text):
    from pipelines.times import utc_or_none

    assert utc_or_none(text) is None


# --- every command's time option ---------------------------------------------------------------------


def _one_error_line(capsys, *argv) -> str:
    code, out, err = _cli(capsys, *argv)
    assert code == 2 and out == "", (code, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


@pytest.fixture
def empty_workspace(tmp_path):
    from pipelines.storage import open_workspace

    db = tmp_path / "ws.duckdb"
    with open_workspace(db):
        pass
    return db


def test_time_options_reject_day_or_month_first_dates(tmp_path, empty_workspace, capsys):
    db = str(empty_workspace)
    line = _one_error_line(capsys, "nightly", "--db", db, "--now", "01/02/2025", "--json")
    assert "'01/02/2025' is not an ISO 8601 time" in line
    line = _one_error_line(capsys, "audit", "--db", db, "--mmsi", "219000123", "--start", "14/01/2025", "--end", "2025-01-15")
    assert line == "error: --start '14/01/2025' is not an ISO 8601 time"
    line = _one_error_line(capsys, "audit", "--db", db, "--mmsi", "219000123", "--start", "2025-01-14", "--end", "Jan 15 2025")
    assert line == "error: --end 'Jan 15 2025' is not an ISO 8601 time"
    pts = tmp_path / "p.csv"
    pts.write_text("lat_deg,lon_deg\n39.0,2.0\n40.0,3.0\n", encoding="utf-8")
    line = _one_error_line(capsys, "weather", "join", "--db", db, "--points", str(pts), "--depart", "01/02/2025")
    assert line == "error: --depart '01/02/2025' is not an ISO 8601 time"
    line = _one_error_line(capsys, "weather", "fetch", "--bbox", "2,39,3,40", "--start", "now", "--end", "2025-01-14T12:00Z",
                           "--cache", str(tmp_path / "cache"))
    assert line == "error: --start 'now' is not an ISO 8601 time"
    line = _one_error_line(capsys, "weather", "fetch", "--bbox", "2,39,3,40", "--start", "2025-01-14T00:00Z", "--end", "20250114",
                           "--cache", str(tmp_path / "cache"))
    assert line == "error: --end '20250114' is not an ISO 8601 time"
    line = _one_error_line(capsys, "scenario", "--out", str(tmp_path / "s"), "--start", "01/02/2025")
    assert line == "error: --start '01/02/2025' is not an ISO 8601 time"
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").iterdir())
    line = _one_error_line(capsys, "route", "--from", "39.2,2.9", "--to", "41.5,2.8", "--depart", "01/02/2025", "--json")
    assert "'01/02/2025' is not an ISO 8601 time" in line
    line = _one_error_line(capsys, "deviate", "--db", db, "--lane", "1-2-1", "--depart", "14/01/2025", "--json")
    assert line == "error: --depart '14/01/2025' is not an ISO 8601 time"


def test_scenario_start_is_utc_whatever_its_offset(tmp_path):
    from pipelines.scenario import build_scenario

    truth = build_scenario(tmp_path / "s", seed=3, start="2025-01-01T01:00+01:00", days=0.25, writers=[])
    assert truth["scenario"]["start_utc"] == "2025-01-01T00:00:00Z"


def test_planned_voyage_free_text_time_names_file_line_and_field(tmp_path):
    from pipelines.nightly import NightlyError, read_planned_voyages

    p = tmp_path / "voy.csv"
    p.write_text("vessel,origin,destination,depart_utc\nro-pax,ESBCN,ESPMI,2025-01-31T03:00Z\nro-pax,ESBCN,ESPMI,14th of jan\n",
                 encoding="utf-8")
    with pytest.raises(NightlyError, match=rf"^{p}: line 3: field 'depart_utc': '14th of jan' is not an ISO 8601 time$"):
        read_planned_voyages(p)
    p.write_text("vessel,origin,destination,depart_utc\nro-pax,ESBCN,ESPMI,01/02/2025 03:00\n", encoding="utf-8")
    with pytest.raises(NightlyError, match=r"line 2: field 'depart_utc': '01/02/2025 03:00' is not an ISO 8601 time"):
        read_planned_voyages(p)


# --- nightly: every voyage failing, unknown lanes, weather not covering the window ----------------------


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    return build_world(tmp_path_factory.mktemp("nightly-errors"))


@pytest.fixture
def no_flow(monkeypatch):
    """The nightly flow must not start."""
    import pipelines.nightly as nightly

    def fail(*a, **k):
        raise AssertionError("the flow started")

    monkeypatch.setattr(nightly, "flow_with_runner", fail)


def test_every_planned_voyage_failing_lists_the_reasons_before_the_flow(world, tmp_path, capsys, no_flow):
    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import read_lanes, read_ports

    with open_workspace(world["db"]) as ws:
        lanes, ports = read_lanes(ws), read_ports(ws)
    code = dict(zip(ports["port_id"], ports["locode"]))
    pairs = {(code.get(o), code.get(d)) for o, d in zip(lanes["origin_port_id"], lanes["dest_port_id"])}
    named = list(ports["locode"].dropna())
    a, b = next((a, b) for a in named for b in named if a != b and (a, b) not in pairs)
    voy = tmp_path / "voy.csv"
    rows = [f"ro-pax,{a},{b},2025-01-31T03:00Z", "ro-pax,ESBCN,Atlantis,2025-01-31T03:00Z",
            "ro-pax,Lyonesse,ESBCN,2025-01-31T03:00Z", "ro-pax,Ys,ESBCN,2025-01-31T03:00Z"]
    voy.write_text("vessel,origin,destination,depart_utc\n" + "\n".join(rows) + "\n", encoding="utf-8")
    line = _one_error_line(capsys, "nightly", "--db", str(world["db"]), "--weather", str(world["weather"]), "--now", NOW,
                           "--voyages", str(voy), "--json")
    assert line.startswith("error: nothing to check tonight: no lane or planned voyage can be sailed (4 of 4 failed): ")
    assert f"{voy}: line 2: no lane from " in line
    assert f"{voy}: line 3: unknown port 'Atlantis'" in line
    assert f"{voy}: line 4: unknown port 'Lyonesse'" in line
    assert "Ys" not in line and line.endswith("; ... and 1 more")


def test_unknown_lane_fails_before_the_flow(world, capsys, no_flow):
    line = _one_error_line(capsys, "nightly", "--db", str(world["db"]), "--weather", str(world["weather"]), "--now", NOW,
                           "--lane", "9-9-9", "--json")
    assert line.startswith(f"error: unknown lane(s) 9-9-9 in {world['db']}")


def test_a_failing_planned_voyage_names_its_file_and_line_when_others_sail(world, tmp_path):
    from pipelines.nightly import load_paths

    voy = tmp_path / "voy.csv"
    voy.write_text("vessel,origin,destination,depart_utc\nro-pax,ESBCN,ESPMI,2025-01-31T03:00Z\n"
                   "ro-pax,ESBCN,Atlantis,2025-01-31T03:00Z\n", encoding="utf-8")
    paths = load_paths(world["db"], voyages=str(voy))
    assert paths[0].error is None and paths[1].error.startswith(f"{voy}: line 3: unknown port 'Atlantis'")


def test_weather_not_covering_the_window_is_the_only_stderr_line(world, tmp_path):
    """A real process (Prefect's console handler writes to the process's stderr)."""
    env = {k: v for k, v in os.environ.items() if k != "PREFECT_LOGGING_LEVEL"}
    env.update(PREFECT_HOME=str(tmp_path / "prefect-home"), PREFECT_SERVER_ANALYTICS_ENABLED="false", DO_NOT_TRACK="1")
    res = subprocess.run([sys.executable, "-m", "pipelines.cli", "nightly", "--db", str(world["db"]), "--weather",
                          str(world["weather"]), "--now", "2025-03-01T00:00Z", "--out", str(tmp_path / "out"), "--json"],
                         capture_output=True, text=True, cwd=REPO, env=env, timeout=600)
    assert res.returncode == 2 and res.stdout == ""
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("error: the weather does not cover tonight's departures 2025-03-01T00:00Z -> 2025-03-02T21:00Z")
    # found before Prefect started (its temporary server's database is made at start)
    assert not (tmp_path / "prefect-home" / "prefect.db").exists()


# --- the console hold-back itself ----------------------------------------------------------------------


@pytest.fixture
def console():
    """A console handler on the run loggers, as Prefect's is on the root logger."""
    buf = io.StringIO()
    h = logging.StreamHandler(buf)
    h.setFormatter(logging.Formatter("%(levelname)s %(message)s"))
    loggers = [logging.getLogger(n) for n in ("prefect.flow_runs", "prefect.task_runs")]
    saved = [(lg, lg.level) for lg in loggers]
    for lg in loggers:
        lg.addHandler(h)
        lg.setLevel(logging.INFO)
    yield h, buf
    for lg, level in saved:
        lg.removeHandler(h)
        lg.setLevel(level)


def _a_failing_run(error):
    logging.getLogger("prefect.task_runs").info("Finished in state Completed()")
    logging.getLogger("prefect.task_runs").error("Task run failed with exception: %r", error)
    logging.getLogger("prefect.flow_runs").error("Finished in state Failed(%r)", error)
    if error is not None:
        raise error


def test_run_error_lines_are_dropped_for_a_user_error_only(console):
    from pipelines.nightly import NightlyWeatherError, user_errors_one_line

    h, buf = console
    with pytest.raises(NightlyWeatherError), user_errors_one_line(handlers=[h]):
        _a_failing_run(NightlyWeatherError("no weather"))
    assert buf.getvalue() == "INFO Finished in state Completed()\n"  # info lines pass (the level decides)

    buf.truncate(0), buf.seek(0)
    with pytest.raises(ZeroDivisionError), user_errors_one_line(handlers=[h]):
        _a_failing_run(ZeroDivisionError("bug"))
    assert buf.getvalue().splitlines() == ["INFO Finished in state Completed()", "ERROR Task run failed with exception: "
                                           "ZeroDivisionError('bug')", "ERROR Finished in state Failed(ZeroDivisionError('bug'))"]

    buf.truncate(0), buf.seek(0)
    with user_errors_one_line(handlers=[h]):  # a night that completed with a failed lane keeps its lines
        _a_failing_run(None)
    assert buf.getvalue().count("ERROR") == 2

    buf.truncate(0), buf.seek(0)
    with pytest.raises(NightlyWeatherError), user_errors_one_line(hold_console=False, handlers=[h]):
        _a_failing_run(NightlyWeatherError("no weather"))
    assert buf.getvalue().count("ERROR") == 2
    assert h.filters == []


@pytest.mark.parametrize("value, verbose", [(None, False), ("WARNING", False), ("ERROR", False), ("INFO", True),
                                            ("debug", True), ("10", True), ("30", False)])
def test_an_explicit_info_or_debug_prefect_level_shows_every_prefect_line(monkeypatch, value, verbose):
    from pipelines.prefect_console import prefect_console_verbose

    if value is None:
        monkeypatch.delenv("PREFECT_LOGGING_LEVEL", raising=False)
    else:
        monkeypatch.setenv("PREFECT_LOGGING_LEVEL", value)
    assert prefect_console_verbose() is verbose

