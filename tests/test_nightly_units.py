"""Plain parts of the nightly run: departures, parameters, planned voyages, storage, ranking."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest


def test_default_window_is_16_departures_every_3_hours():
    from pipelines.nightly import departure_times, parse_utc

    now = parse_utc("2025-01-31T00:00")  # naive = UTC
    assert now == pd.Timestamp("2025-01-31T00:00Z")
    d = departure_times(now, 48.0, 3.0)
    assert len(d) == 16 and d[0] == now and d[-1] == pd.Timestamp("2025-02-01T21:00Z")
    assert list(departure_times(now, 24.0, 5.0).hour) == [0, 5, 10, 15, 20]
    assert len(departure_times(now, 3.0, 3.0)) == 1


def test_resolve_now_parses_or_floors_the_clock():
    from pipelines.nightly import NightlyError, resolve_now

    assert resolve_now("2025-01-31T02:30+01:00") == pd.Timestamp("2025-01-31T01:30Z")
    t = resolve_now(None)
    assert t.tz is not None and t.minute == 0 and t.second == 0
    assert abs(pd.Timestamp.now(tz="UTC") - t) < pd.Timedelta(hours=1, minutes=1)
    with pytest.raises(NightlyError, match="not an ISO 8601 time"):
        resolve_now("yesterday-ish")


def test_parameters_are_validated_before_the_run():
    from pydantic import ValidationError

    from pipelines.nightly import NightlyParams, make_task_runner
    from pipelines.runners import TaskRunnerError

    with pytest.raises(ValidationError, match="unknown speed-loss model"):
        NightlyParams(speed_loss="magic")
    with pytest.raises(ValidationError):
        NightlyParams(step_h=0)
    with pytest.raises(ValidationError, match="ISO 8601"):
        NightlyParams(now="tomorrow")
    from pipelines.nightly.night import NightlyError

    with pytest.raises(NightlyError) as err:  # the CLI's one line: the field once, no "Value error,"
        NightlyParams.checked(now="now")
    assert str(err.value) == "invalid nightly parameters: now: 'now' is not an ISO 8601 time"
    with pytest.raises(TaskRunnerError, match="sequential, dask or dask:ADDRESS"):
        make_task_runner("threads")
    assert type(make_task_runner("sequential")).__name__ == "ThreadPoolTaskRunner"
    assert make_task_runner("dask:tcp://127.0.0.1:8786").address == "tcp://127.0.0.1:8786"


def test_planned_voyages_csv_errors_name_file_line_and_field(tmp_path):
    from pipelines.nightly import NightlyError, read_planned_voyages

    p = tmp_path / "plan.csv"
    p.write_text("voyage_id,vessel,origin,destination,depart_utc\nA1,ro-pax,ESBCN,ITGOA,2025-01-31T06:00Z\n"
                 ",container-feeder,Palma de Mallorca,ESBCN,2025-01-31T09:00\n", encoding="utf-8")
    df = read_planned_voyages(p)
    assert list(df["voyage_id"]) == ["A1", "V002"]
    assert list(df["depart_utc"]) == [pd.Timestamp("2025-01-31T06:00Z"), pd.Timestamp("2025-01-31T09:00Z")]
    p.write_text("vessel,origin,depart_utc\nro-pax,ESBCN,2025-01-31\n", encoding="utf-8")
    with pytest.raises(NightlyError, match=r"plan\.csv: line 1: missing column\(s\) destination"):
        read_planned_voyages(p)
    p.write_text("vessel,origin,destination,depart_utc\nro-pax,ESBCN,,2025-01-31\n", encoding="utf-8")
    with pytest.raises(NightlyError, match=r"line 2: field 'destination' is empty"):
        read_planned_voyages(p)
    p.write_text("vessel,origin,destination,depart_utc\nro-pax,ESBCN,ITGOA,2025-01-31\nro-pax,ESBCN,ITGOA,soon\n", encoding="utf-8")
    with pytest.raises(NightlyError, match=r"line 3: field 'depart_utc': 'soon' is not an ISO 8601 time"):
        read_planned_voyages(p)
    with pytest.raises(NightlyError, match="not found"):
        read_planned_voyages(tmp_path / "missing.csv")


def test_vessel_profile_of_a_lane_is_its_most_common_ship_profile():
    from pipelines.vessels import DEFAULT_VESSEL, lane_vessel_profiles

    lanes = pd.DataFrame({"lane_id": ["a", "b", "c"]})
    lv = pd.DataFrame({"lane_id": ["a", "a", "a", "b"], "voyage_id": ["1", "2", "3", "4"]})
    voyages = pd.DataFrame({"voyage_id": ["1", "2", "3", "4"], "mmsi": [1, 1, 2, 3]})
    vessels = pd.DataFrame({"mmsi": [1, 2, 3], "ship_type": [60, 80, 70], "length_m": [180.0, 240.0, 250.0]})
    got = lane_vessel_profiles(lanes, lv, voyages, vessels)
    # AIS type 60-69 passenger -> ro-pax (2 voyages) beats the tanker (1); type 70 and 250 m -> container-large
    assert got == {"a": "ro-pax", "b": "container-large", "c": DEFAULT_VESSEL}


def _run_row(run_id: str) -> dict:
    from pipelines.storage.nightly import RUN_COLUMNS

    t = pd.Timestamp("2025-01-31T00:00Z")
    row = {c: None for c in RUN_COLUMNS}
    row.update(run_id=run_id, now_utc=t, window_start_utc=t, window_end_utc=t + pd.Timedelta(hours=48), step_h=3.0,
               n_departure_times=16, lanes_checked=1, departures_checked=2, n_adverse=1, n_failed=1, n_reroutes=1,
               weather_source="files", weather_digest="w", lanes_digest="l", params_json="{}", started_utc=t, finished_utc=t,
               summary_json="{}")
    return row


def test_storage_replaces_a_run_as_a_whole(workspace_path):
    from pipelines.storage import open_workspace
    from pipelines.storage.nightly import count_rows, read_departures, read_run, read_runs, write_run

    t = pd.Timestamp("2025-01-31T03:00Z")
    deps = pd.DataFrame([
        {"path_id": "L1", "lane_id": "L1", "origin": "A", "destination": "B", "depart_utc": t, "vessel_profile": "ro-pax",
         "status": "adverse", "rules": "hs", "reasons_json": "[]", "n_points": 10, "n_points_no_weather": 0, "max_hs_m": 5.0,
         "worst_time_utc": t, "worst_lat_deg": 40.0, "worst_lon_deg": 3.0, "proposed": "deviation", "rank": 1,
         "risk_avoided_h": 2.5, "events_avoided": 1, "delta_time_h": 0.5, "delta_fuel_t": 0.1, "delta_co2_t": 0.3, "error": None},
        {"path_id": "L1", "lane_id": "L1", "origin": "A", "destination": "B", "depart_utc": t + pd.Timedelta(hours=3),
         "vessel_profile": "ro-pax", "status": "failed", "rules": "", "reasons_json": "[]", "n_points": 10,
         "n_points_no_weather": 10, "max_hs_m": np.nan, "worst_time_utc": None, "worst_lat_deg": np.nan, "worst_lon_deg": np.nan,
         "proposed": None, "rank": 2, "risk_avoided_h": None, "events_avoided": None, "delta_time_h": None, "delta_fuel_t": None,
         "delta_co2_t": None, "error": "LandPointError: goal on land"},
    ])
    routes = pd.DataFrame([{"path_id": "L1", "depart_utc": t, "role": r, "time_h": 10.0, "dist_nmi": 150.0, "max_hs_m": 5.0,
                            "mean_hs_m": 3.0, "fuel_t": 20.0, "co2_t": 60.0, "exposure_h": 2.0, "adverse_h": 2.5,
                            "n_safety_events": 1, "no_weather_h": 0.0, "route_json": "{}"} for r in ("lane", "deviation")])
    events = pd.DataFrame([{"path_id": "L1", "depart_utc": t, "role": "lane", "criterion": "hs", "kind": "operator",
                            "start_utc": t, "end_utc": t + pd.Timedelta(hours=2), "duration_h": 2.0, "lat_deg": 40.0,
                            "lon_deg": 3.0, "max_margin": 0.5}])
    with open_workspace(workspace_path) as ws:
        write_run(ws, _run_row("r1"), deps, routes, events)
        first = count_rows(ws)
        write_run(ws, _run_row("r1"), deps, routes, events)
        assert count_rows(ws) == first == {"nightly_events": 1, "nightly_routes": 2, "nightly_departures": 2, "nightly_runs": 1}
        write_run(ws, _run_row("r2"), deps.iloc[:1], routes.iloc[:1], events.iloc[:0])
        assert count_rows(ws) == {"nightly_events": 1, "nightly_routes": 3, "nightly_departures": 3, "nightly_runs": 2}
        got = read_departures(ws, "r1")
        assert list(got["status"]) == ["adverse", "failed"] and got["error"].iloc[1] == "LandPointError: goal on land"
        assert pd.isna(got["max_hs_m"].iloc[1]) and got["depart_utc"].iloc[0] == t
        assert read_run(ws, "r2")["n_adverse"] == 1 and set(read_runs(ws)["run_id"]) == {"r1", "r2"}
        with pytest.raises(KeyError, match="lacks"):
            write_run(ws, {"run_id": "r3"}, deps, routes, events)


def _evaluation(time_h, adverse_h, events, fuel_t=10.0, co2_t=30.0, max_hs_m=4.0):
    from routing.route import Route

    t0 = pd.Timestamp("2025-01-31T00:00Z")
    route = Route("r", [40.0, 41.0], [3.0, 3.0], pd.DatetimeIndex([t0, t0 + pd.Timedelta(hours=time_h)]), [60.0 / time_h],
                  properties={"search_s": 0.01, "kept": 1})
    return SimpleNamespace(route=route, events=[], summary={"time_h": time_h, "adverse_h": adverse_h, "n_safety_events": events,
                                                           "fuel_t": fuel_t, "co2_t": co2_t, "max_hs_m": max_hs_m})


def test_ranking_puts_most_risk_avoided_first_then_cost_then_failures():
    from pipelines.nightly import Night, NightlyParams, NightPath, assemble

    t0 = pd.Timestamp("2025-01-31T00:00Z")
    paths = [NightPath(pid, pid, "A", "B", pd.DataFrame(columns=["seq", "lat_deg", "lon_deg", "speed_kn"]), "ro-pax") for pid in "pqrs"]
    night = Night(run_id="x", now_utc=t0, departures=pd.DatetimeIndex([t0]), params=NightlyParams(), paths=paths, weather_ds=None,
                  weather_meta={}, weather_source="files", weather_digest="", lanes_digest="", vessels={}, limits=None, out=None)
    screen = pd.DataFrame([
        {"path_id": pid, "depart_utc": t0, "n_points": 5, "n_points_no_weather": 0, "adverse": pid != "s", "rules": ["hs"] if pid != "s" else [],
         "reasons": [], "max_hs_m": 5.0, "worst_time_utc": t0, "worst_lat_deg": 40.0, "worst_lon_deg": 3.0, "error": None}
        for pid in "pqrs"
    ])
    hist = _evaluation(10.0, 4.0, 2, fuel_t=10.0)
    outcomes = [
        {"path_id": "p", "depart_utc": t0, "status": "adverse", "proposed": "deviation",
         "evaluations": {"lane": hist, "deviation": _evaluation(11.0, 1.0, 0, fuel_t=11.0)}},  # 3 h avoided, +1 h
        {"path_id": "q", "depart_utc": t0, "status": "adverse", "proposed": "optimal",
         "evaluations": {"lane": hist, "optimal": _evaluation(9.5, 1.0, 2, fuel_t=9.0)}},  # 3 h avoided, -0.5 h, 0 events
        {"path_id": "r", "depart_utc": t0, "status": "failed", "error": "NoRouteError: no sea route"},
    ]
    res = assemble(night, screen, outcomes)
    d = res.departures.set_index("path_id")
    # p and q avoid 3 h each; p also avoids 2 IMO events, so it ranks first; r failed comes last; s is ok (no rank)
    assert d.loc["p", "rank"] == 1 and d.loc["q", "rank"] == 2 and d.loc["r", "rank"] == 3 and pd.isna(d.loc["s", "rank"])
    assert d.loc["p", "risk_avoided_h"] == pytest.approx(3.0) and d.loc["p", "events_avoided"] == 2
    assert d.loc["q", "delta_time_h"] == pytest.approx(-0.5) and d.loc["q", "delta_fuel_t"] == pytest.approx(-1.0)
    assert d.loc["r", "status"] == "failed" and d.loc["r", "error"].startswith("NoRouteError")
    assert d.loc["s", "status"] == "ok"
    assert res.counts == {"lanes_checked": 4, "departures_checked": 4, "adverse": 2, "failed": 1, "reroutes": 2}
    assert [c["row"]["path_id"] for c in res.cases] == ["p", "q", "r"]
    assert json.loads(d.loc["p", "reasons_json"]) == []
    # stored routes carry no run-dependent timings
    stored = json.loads(res.routes.set_index(["path_id", "role"]).loc[("p", "deviation"), "route_json"])
    assert "search_s" not in json.dumps(stored) and "kept" in json.dumps(stored)
    assert len(res.routes) == 4


def test_reroute_progress_reports_each_finished_lane_and_the_total():
    from types import SimpleNamespace

    from pipelines.nightly import _results_with_progress, reroute_progress

    class Done:
        def __init__(self, value):
            self.value, self.state = value, SimpleNamespace(is_completed=lambda: True)

        def wait(self):
            pass

        def result(self, raise_on_failure=True):
            return self.value

    seen = []
    with reroute_progress(lambda done, total: seen.append((done, total))):
        assert _results_with_progress([Done([1]), Done([2]), Done([3])]) == [[1], [2], [3]]
    assert seen == [(0, 3), (1, 3), (2, 3), (3, 3)]
    _results_with_progress([Done([4])])  # the callback is gone after the block
    assert len(seen) == 4


def test_cli_progress_bar_takes_its_total_when_known(capsys):
    from pipelines.commands._common import progress

    with progress("rerouting lanes", enabled=True) as advance:
        advance(0, total=4)
        for _ in range(4):
            advance(1)
    # rich renders the bar when the block closes (it used to fail on a None total); the bar is
    # transient, so nothing is left on stderr but its final line break
    assert capsys.readouterr().err.strip() == ""



def test_cli_progress_bar_without_a_total_renders(capsys):
    from pipelines.commands._common import progress

    with progress("reading weather", enabled=True) as advance:
        advance(2)  # "2/?" while the total is unknown
    assert capsys.readouterr().err.strip() == ""


def test_a_tiny_negative_delta_is_zero_not_minus_zero():
    """The least-fuel route arrives at the lane's time to within 1e-9 h: its delta printed as
    "-0.0 h" on the terminal and -0.0 in the JSON, "+0.0 h" on the page."""
    import math

    from pipelines.commands.nightly import _num
    from pipelines.nightly.rank import _num as json_num

    assert _num(-7.3e-10, "+.1f", " h") == "+0.0 h" and _num(-0.04, ".1f") == "0.0" and _num(-0.06, "+.1f") == "-0.1"
    assert json_num(-7.3e-10) == 0.0 and math.copysign(1.0, json_num(-7.3e-10)) == 1.0 and json_num(-2.5) == -2.5



def test_the_terminal_summary_counts_in_the_singular_and_names_planned_departures(capsys):
    from pipelines.commands.nightly import print_summary

    base = {"run_id": "r", "now_utc": "2025-01-31T00:00:00+00:00", "adverse": 1, "reroutes": 0, "failed": 0, "top": []}
    print_summary({**base, "window": {"departures": 16, "step_h": 3.0}, "lanes_checked": 1, "departures_checked": 16,
                   "lanes_at_risk": 1})
    line = capsys.readouterr().out.splitlines()[0]
    assert "16 departures every 3 h): 1 lane, 16 lane-departures checked, 1 adverse on 1 lane, 0 with" in line
    print_summary({**base, "window": {"departures": 1, "step_h": None, "start_utc": "2025-01-31T06:00:00+00:00",
                                      "end_utc": "2025-01-31T06:00:00+00:00"},
                   "lanes_checked": 2, "departures_checked": 1, "lanes_at_risk": 0})
    line = capsys.readouterr().out.splitlines()[0]
    assert "1 planned departure from 2025-01-31T06:00:00+00:00 to 2025-01-31T06:00:00+00:00): 2 lanes, " \
           "1 lane-departure checked, 1 adverse on 0 lanes" in line
