"""The planner and `stormlane route`: JSON contract, exports, clear errors for bad input."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from pipelines.routing_weather import field_from_dataset
from routing.astar import ShipModel
from routing.errors import NoRouteError, WeatherCoverageError
from routing.field import WeatherField
from routing.mesh import LandMask
from routing.planner import RouteRequest, plan_routes
from thresholds.geodesy import haversine_nmi
from cli_runner import run_cli as run

T0 = pd.Timestamp("2020-01-20T00:00Z")


def test_cli_json_contract_calm_sea(capsys, tmp_path):
    out_file = tmp_path / "routes.geojson"
    code, out, err = run(
        capsys, "route", "--from", "10,0", "--to", "12,6", "--depart", "2021-03-01T06:00Z", "--mesh-nmi", "15",
        "--ignore-land", "--speed-kn", "12", "--json", "--out", str(out_file),
    )  # fmt: skip
    assert code == 0, err
    data = json.loads(out)  # exactly one JSON object on stdout
    assert list(data) == ["great_circle_nmi", "optimal", "optimal_smoothed", "min_distance", "min_distance_calm", "speed_loss",
                          "notes"]
    assert data["speed_loss"] == "bowditch (symmetric sectors)"
    # the model, said in every output, and that no weather was given (the model never acts)
    assert data["notes"] == ["speed loss: bowditch (symmetric sectors)",
                             "no weather given: every route is sailed in a calm sea (no waves, wind or current)"]
    assert data["great_circle_nmi"] == pytest.approx(haversine_nmi(10, 0, 12, 6), rel=1e-6)
    for name in list(data)[1:-2]:
        route = data[name]
        assert set(route) == {"time_h", "dist_nmi", "max_hs_m", "waypoints"}
        assert route["waypoints"][0][:2] == [10.0, 0.0] and route["waypoints"][-1][:2] == [12.0, 6.0]
        assert route["waypoints"][0][2] == "2021-03-01T06:00:00Z"
        assert route["time_h"] == pytest.approx(route["dist_nmi"] / 12.0, rel=1e-6)  # calm: distance / speed
    assert len(data["optimal_smoothed"]["waypoints"]) == 2
    geo = json.loads(out_file.read_text())
    lines = [f["properties"] for f in geo["features"] if f["properties"]["feature"] == "route"]
    assert [p["route"] for p in lines] == list(data)[1:-2]
    assert [p["time_h"] for p in lines] == pytest.approx([data[k]["time_h"] for k in list(data)[1:-2]], rel=1e-6)


def test_cli_table_output(capsys):
    code, out, err = run(capsys, "route", "--from", "10,0", "--to", "10,3", "--depart", "2021-03-01T06:00", "--mesh-deg", "0.25", "--ignore-land")
    assert code == 0, err
    assert "great circle" in out and "optimal_smoothed" in out and "min_distance_calm" in out


@pytest.mark.parametrize(
    "args, match",
    [
        (["--from", "abc", "--to", "10,3"], "LAT,LON"),
        (["--from", "95,0", "--to", "10,3"], "lat in"),
        (["--from", "10,0", "--to", "10,3", "--mesh-nmi", "5", "--mesh-deg", "0.1"], "either --mesh-nmi or --mesh-deg"),
        (["--from", "10,0", "--to", "10,3", "--edges", "12"], "not one of 8, 16, 24, 48"),
        (["--from", "10,0", "--to", "10,3", "--speed-loss", "visir"], "not one of"),
        (["--from", "10,0", "--to", "10,3", "--vessel", "titanic"], "unknown vessel profile 'titanic'"),
        (["--from", "10,0", "--to", "10,3", "--weather", "/nonexistent/w.nc"], "not found"),
    ],
)
def test_cli_bad_input_exits_2_with_a_clear_message(capsys, args, match):
    code, out, err = run(capsys, "route", "--depart", "2021-03-01T06:00Z", "--ignore-land", *args)
    assert code == 2
    assert match in " ".join(err.replace("│", " ").split())  # rich boxes wrap usage errors
    assert out == ""


def test_cli_start_on_land_and_unreachable_goal(capsys):
    # Madrid is 150 nmi from the sea: no sea node within the 10-nmi snapping limit.
    code, out, err = run(capsys, "route", "--from", "40.4,-3.7", "--to", "39.5,2.5", "--depart", "2021-03-01T06:00Z", "--mesh-nmi", "3")
    assert code == 2 and out == ""
    assert err.strip().startswith("error: start (40.4000, -3.7000) is on land") and len(err.strip().splitlines()) == 1
    # Black Sea -> Levantine Sea inside a box that leaves out the Bosphorus (29 E): no sea joins them.
    code, out, err = run(
        capsys, "route", "--from", "43.0,34.0", "--to", "34.5,31.0", "--bbox", "30,33,42,47", "--depart", "2021-03-01T06:00Z",
        "--mesh-nmi", "6",
    )  # fmt: skip
    assert code == 2 and out == ""
    assert "error: no sea route" in err and "do not connect" in err


def small_field(hours=(0, 6, 12), lat=(39.0, 41.0), lon=(2.0, 4.0), hs=2.0):
    la = np.arange(lat[0], lat[1] + 1e-9, 0.1)
    lo = np.arange(lon[0], lon[1] + 1e-9, 0.1)
    times = T0.value + np.asarray(hours, dtype=np.int64) * 3_600_000_000_000
    shape = (len(hours), la.size, lo.size)
    return WeatherField(times, la, lo, {"hs_m": np.full(shape, hs), "wave_from_deg": np.full(shape, 0.0)})


def test_planner_weather_coverage_errors():
    ship = ShipModel(15.0, "bowditch")
    field = small_field()
    late = RouteRequest((39.5, 2.5), (40.5, 3.5), T0 + pd.Timedelta("13h"), ship, ignore_land=True)
    with pytest.raises(WeatherCoverageError, match="departure 2020-01-20T13:00:00Z is outside the weather's times"):
        plan_routes(late, field)
    outside = RouteRequest((38.0, 2.5), (40.5, 3.5), T0, ship)
    with pytest.raises(WeatherCoverageError, match=r"start \(38.0000, 2.5000\) is outside the weather grid"):
        plan_routes(outside, field, land_mask_fn=None)


@pytest.mark.filterwarnings("ignore:Logger 'routing.planner' attempted to send logs:UserWarning")  # Prefect's handler, when set up by other tests
def test_planner_start_off_node_keeps_exact_endpoints_and_warns_after_weather_end(caplog):
    caplog.set_level("INFO", logger="routing.planner")
    field = small_field(hours=(0, 1))
    req = RouteRequest((39.513, 2.517), (40.488, 3.4711), T0, ShipModel(10.0, "bowditch"), spacing_deg=0.05)
    plan = plan_routes(req, field, land_mask_fn=None)
    for route in plan.routes.values():
        assert (route.lat_deg[0], route.lon_deg[0]) == (39.513, 2.517)
        assert (route.lat_deg[-1], route.lon_deg[-1]) == (40.488, 3.4711)
    assert plan.routes["optimal"].properties["weather_held_after_h"] > 0
    assert "last weather time" in caplog.text  # INFO: the route property carries it to the user


def test_cli_says_when_the_weather_ends_before_arrival(capsys, tmp_path, monkeypatch):
    # The file reading is tested with the readers; here the field of two hours stands in for it.
    import pipelines.routing_weather as rw

    monkeypatch.setattr(rw, "load_weather", lambda files, **kw: (small_field(hours=(0, 1)), {}))
    weather = tmp_path / "w.nc"
    weather.write_bytes(b"")
    args = ["route", "--from", "39.513,2.517", "--to", "40.488,3.4711", "--depart", "2020-01-20T00:00Z",
            "--weather", str(weather), "--speed-kn", "10", "--mesh-deg", "0.05", "--ignore-land"]
    code, out, err = run(capsys, *args)
    assert code == 0, err
    note = [line for line in out.splitlines() if line.startswith("note: the weather ends before arrival")]
    assert len(note) == 1 and "h of optimal_smoothed" in note[0] and "h of min_distance" in note[0]
    # --json says it too: the documented keys, then "notes"; each route sailed past the weather's end
    # carries weather_held_after_h (the calm-water route meets no weather)
    code, out, err = run(capsys, *args, "--json")
    assert code == 0, err
    data = json.loads(out)
    assert list(data) == ["great_circle_nmi", "optimal", "optimal_smoothed", "min_distance", "min_distance_calm", "speed_loss",
                          "notes"]
    snapped = [line.removeprefix("note: ") for line in err.splitlines() if line.startswith("note: ")]  # e.g. goal moved to a node
    assert data["notes"] == ["speed loss: bowditch (symmetric sectors)", *snapped, note[0].removeprefix("note: ")]
    for name in ("optimal", "optimal_smoothed", "min_distance"):
        assert set(data[name]) == {"time_h", "dist_nmi", "max_hs_m", "waypoints", "weather_held_after_h"}
        assert 0 < data[name]["weather_held_after_h"] < data[name]["time_h"] - 0.9  # the weather lasts 1 h
        assert f"{data[name]['weather_held_after_h']:.2f} h of {name}" in data["notes"][-1]
    assert "weather_held_after_h" not in data["min_distance_calm"]


def medsea_dataset(shared_data):
    from conftest import shared_file
    from weather.io import read_local

    folder = shared_file(shared_data, "weather/simroute_cmems_medsea_wav")
    return folder, read_local(folder)[0]


MEDSEA = "CMEMS MEDSEA_ANALYSIS_FORECAST_WAV_006_017, hs_m, wave_from_deg"


@pytest.mark.parametrize(
    "args, message",
    [
        (["--depart", "2020-01-19T09:00Z"],
         f"departure 2020-01-19T09:00Z is outside the weather's times: {MEDSEA}: no data for 2020-01-19T09:00Z -> "
         "2020-01-20T00:00Z (data cover 2020-01-20T00:00Z -> 2020-01-21T23:00Z)"),
        (["--depart", "2020-01-22T06:30Z"],
         f"departure 2020-01-22T06:30Z is outside the weather's times: {MEDSEA}: no data for 2020-01-21T23:00Z -> "
         "2020-01-22T06:30Z (data cover 2020-01-20T00:00Z -> 2020-01-21T23:00Z)"),
        (["--depart", "2020-01-20T09:00Z", "--to", "41.5,12.775"],
         f"goal (41.5000, 12.7750) is outside the weather grid: {MEDSEA}: bbox lon 2.9..12.775, lat 39.225..41.5 is not "
         "covered (data cover lon 1.5..5.58333, lat 38.4375..42.1458)"),
        (["--depart", "2020-01-20T09:00Z", "--from", "35.0,12.9", "--to", "36.0,13.0"],
         f"start (35.0000, 12.9000) and goal (36.0000, 13.0000) are outside the weather grid: {MEDSEA}: bbox lon 12.9..13, "
         "lat 35..36 is not covered (data cover lon 1.5..5.58333, lat 38.4375..42.1458)"),
    ],
)
def test_cli_coverage_errors_name_the_product_the_variables_and_the_span(shared_data, capsys, args, message):
    """The wording of weather.coverage.check_coverage (weather join, nightly), in one line, exit 2."""
    folder, _ = medsea_dataset(shared_data)
    base = {"--from": "39.225,2.900", "--to": "41.500,2.775"}
    for flag in ("--from", "--to"):
        if flag not in args:
            args = [*args, flag, base[flag]]
    code, out, err = run(capsys, "route", "--weather", str(folder), "--mesh-nmi", "1.5", "--json", *args)
    assert code == 2 and out == ""
    assert err == f"error: {message}\n"


def test_route_coverage_check_on_a_tiny_dataset():
    xr = pytest.importorskip("xarray")
    from pipelines.routing_weather import check_route_coverage

    times = pd.date_range("2025-01-01", periods=3, freq="3h").values
    shape = (3, 3, 4)
    ds = xr.Dataset(
        {"hs_m": (("time_utc", "lat", "lon"), np.ones(shape)), "tp_s": (("time_utc", "lat", "lon"), np.ones(shape)),
         "current_u_ms": (("time_utc", "lat", "lon"), np.zeros(shape)), "current_v_ms": (("time_utc", "lat", "lon"), np.zeros(shape))},
        coords={"time_utc": times, "lat": [40.0, 40.5, 41.0], "lon": [2.0, 2.5, 3.0, 3.5]},
        attrs={"product": "demo waves + currents"},
    )  # fmt: skip
    inside = (("start", (40.2, 2.1)), ("goal", (40.9, 3.4)))
    check_route_coverage(ds, pd.Timestamp("2025-01-01T04:30Z"), inside)
    check_route_coverage(ds, pd.Timestamp("2025-01-01T06:00Z"), inside)  # the last time: the rest is held
    with pytest.raises(WeatherCoverageError, match=r"^departure 2024-12-31T22:00Z is outside the weather's times: demo waves "
                       r"\+ currents, hs_m, current_u_ms, current_v_ms: no data for 2024-12-31T22:00Z -> 2025-01-01T00:00Z"):
        check_route_coverage(ds, pd.Timestamp("2025-01-01T00:00+02:00"), inside)
    with pytest.raises(WeatherCoverageError, match=r"^start \(39.9000, 2.1000\) is outside the weather grid: demo waves \+ "
                       r"currents, hs_m, current_u_ms, current_v_ms: bbox lon 2.1..3.4, lat 39.9..40.9 is not covered"):
        check_route_coverage(ds, pd.Timestamp("2025-01-01T03:00Z"), (("start", (39.9, 2.1)), ("goal", (40.9, 3.4))))
    # a variable present but missing over every sea cell at the departure is no data either
    ds["current_u_ms"][1] = np.nan
    with pytest.raises(WeatherCoverageError, match=r"demo waves \+ currents, current_u_ms: no data at 1 time step\(s\): "
                       r"2025-01-01T03:00Z -> 2025-01-01T03:00Z"):
        check_route_coverage(ds, pd.Timestamp("2025-01-01T03:00Z"), inside)


def lake_mask(grid):
    """A ring of land around (40.5 N, 3.0 E): the lake inside does not connect to the sea outside."""
    ppd = 120
    r0 = int((90.0 - (grid.lat_deg[-1] + 1.5 * grid.dlat_deg)) * ppd)
    c0 = int((grid.lon_deg[0] - 1.5 * grid.dlon_deg + 180.0) * ppd)
    rows = int((grid.ny + 3) * grid.dlat_deg * ppd) + 2
    cols = int((grid.nx + 3) * grid.dlon_deg * ppd) + 2
    lat = 90.0 - (r0 + np.arange(rows) + 0.5) / ppd
    lon = -180.0 + (c0 + np.arange(cols) + 0.5) / ppd
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    r = np.hypot(la - 40.5, lo - 3.0)
    return LandMask(~((r > 0.3) & (r < 0.45)), r0, c0, ppd)


def test_planner_unreachable_goal_inside_a_lake():
    req = RouteRequest((39.3, 2.2), (40.5, 3.0), T0, ShipModel(12.0, "none"), spacing_deg=0.05)
    with pytest.raises(NoRouteError, match="sea areas that do not connect"):
        plan_routes(req, small_field(), land_mask_fn=lake_mask)
    ok = plan_routes(RouteRequest((39.3, 2.2), (40.9, 3.9), T0, ShipModel(12.0, "none"), spacing_deg=0.05), small_field(), land_mask_fn=lake_mask)
    assert ok.routes["optimal"].dist_nmi > ok.great_circle_nmi


def test_field_from_canonical_dataset():
    xr = pytest.importorskip("xarray")
    times = pd.date_range("2020-01-20", periods=3, freq="3h").values
    ds = xr.Dataset(
        {
            "hs_m": (("time_utc", "lat", "lon"), np.arange(3 * 2 * 3, dtype=float).reshape(3, 2, 3)),
            "wave_from_deg": (("time_utc", "lat", "lon"), np.zeros((3, 2, 3))),
            "other": (("time_utc", "lat", "lon"), np.zeros((3, 2, 3))),
        },
        coords={"time_utc": times, "lat": [41.0, 40.0], "lon": [358.0, 359.0, 0.5]},
        attrs={"product": "test"},
    )
    field = field_from_dataset(ds)
    assert field.lat_deg.tolist() == [40.0, 41.0] and field.lon_deg.tolist() == [-2.0, -1.0, 0.5]
    assert set(field.variables) == {"hs_m", "wave_from_deg"}
    # value at (t0, lat 41, lon 358) moved to row 1, column 0
    assert field.variables["hs_m"][0, 1, 0] == 0.0 and field.variables["hs_m"][0, 0, 0] == 3.0
    assert field.attrs == {"product": "test"}
    with pytest.raises(WeatherCoverageError, match="none of the variables"):
        field_from_dataset(ds[["other"]])
