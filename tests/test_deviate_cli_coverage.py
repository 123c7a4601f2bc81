"""`stormlane deviate` refuses weather that does not cover the lane-departure, and says so in one line.

A tiny workspace holds two lanes and no weather: one in the Balearic Sea (40.2 N 2.4 E -> 41.0 N
3.6 E) and one off New York. The weather is a tiny CMEMS-style NetCDF (VHM0 only) over the
Balearic lane, 2025-01-14T18:00 .. 2025-01-15T14:00, written per test; a copy of the workspace
gets the same grid loaded (`stormlane weather load`'s storage). The issue these tests pin: a
lane or departure outside the data's bbox or time span is an error naming the product, the
variable and the missing span, never a silent "0 h over the limits"; land (NaN) cells inside the
grid are not a coverage gap.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from cli_runner import run_cli as run

MED = ((40.2, 2.4), (41.0, 3.6))
NY = ((40.65, -74.05), (40.45, -73.6))
LAT = np.round(np.arange(39.5, 41.81, 0.1), 6)
LON = np.round(np.arange(1.5, 4.51, 0.1), 6)
TIMES = pd.date_range("2025-01-14T18:00", "2025-01-15T14:00", freq="1h")
PRODUCT = "CMEMS waves"  # what the reader names a file holding VHM0


def _hs(nan_where=None) -> np.ndarray:
    hs = np.full((TIMES.size, LAT.size, LON.size), 2.0, dtype=np.float32)
    if nan_where is not None:
        lon2, lat2 = np.meshgrid(LON, LAT)
        hs[:, nan_where(lat2, lon2)] = np.nan
    return hs


def write_waves(path, nan_where=None):
    """A CMEMS-style wave file (VHM0 on time/latitude/longitude) over the Balearic lane."""
    import xarray as xr

    ds = xr.Dataset(
        {"VHM0": (("time", "latitude", "longitude"), _hs(nan_where), {"units": "m"})},
        coords={"time": TIMES.values, "latitude": LAT, "longitude": LON},
        attrs={"title": "tiny test waves"},
    )
    ds.to_netcdf(path)
    return path


def _lane_frames():
    from thresholds.geodesy import haversine_nmi, intermediate_point

    ports, voyages, lanes, centroids, lane_voyages = [], [], [], [], []
    for k, (lane_id, (a, b)) in enumerate((("MED1", MED), ("NY1", NY))):
        o, d = 2 * k + 1, 2 * k + 2
        for pid, (la, lo) in ((o, a), (d, b)):
            ports.append({"port_id": pid, "kind": "port", "locode": None, "name": f"P{pid}", "country": None, "lat_deg": la,
                          "lon_deg": lo, "radius_nmi": 2.0, "n_calls": 1, "n_vessels": 1, "n_clusters": 1, "known_lat_deg": None,
                          "known_lon_deg": None, "match_dist_nmi": None})
        dist = float(haversine_nmi(a[0], a[1], b[0], b[1]))
        voyages.append({"voyage_id": f"v{k}", "mmsi": 219000000 + k, "origin_port_id": o, "dest_port_id": d,
                        "depart_utc": pd.Timestamp("2025-01-01T00:00Z"), "arrive_utc": pd.Timestamp("2025-01-01T06:00Z"),
                        "dist_nmi": dist, "n_fixes": 100, "max_gap_s": 60.0, "kind": "port_to_port"})
        n = 8
        frac = np.linspace(0.0, 1.0, n)
        clat, clon = intermediate_point(a[0], a[1], b[0], b[1], frac)
        lanes.append({"lane_id": lane_id, "origin_port_id": o, "dest_port_id": d, "kind": "port_to_port", "n_points": n,
                      "n_voyages": 1, "n_vessels": 1, "mean_speed_kn": 15.0, "mean_course_deg": 50.0, "course_r": 1.0,
                      "length_nmi": dist, "width_nmi": 1.0, "n_centroids": n, "polygon_wkt": "POLYGON EMPTY"})
        centroids.append(pd.DataFrame({"lane_id": lane_id, "seq": np.arange(n), "lat_deg": np.asarray(clat),
                                       "lon_deg": np.asarray(clon), "speed_kn": 15.0, "course_deg": 50.0, "n_points": 10,
                                       "n_voyages": 1, "along_nmi": frac * dist}))
        lane_voyages.append({"lane_id": lane_id, "voyage_id": f"v{k}", "n_points": n})
    return (pd.DataFrame(ports), pd.DataFrame(voyages), pd.DataFrame(lanes), pd.concat(centroids, ignore_index=True),
            pd.DataFrame(lane_voyages))


@pytest.fixture(scope="module")
def workspaces(tmp_path_factory):
    """(workspace without weather, workspace with the Balearic grid loaded as 'med-test')."""
    pytest.importorskip("pipelines.storage.weather", reason="weather tables (weather helper) not available")
    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import write_lanes
    from pipelines.storage.weather import load_weather
    from weather.io import read_local

    root = tmp_path_factory.mktemp("deviate_cov")
    bare = root / "bare.duckdb"
    with open_workspace(bare) as ws:
        write_lanes(ws, *_lane_frames(), summary={"ports": 4, "voyages": 2, "lanes": 2, "noise_points": 0}, params={})
    loaded = root / "loaded.duckdb"
    shutil.copy(bare, loaded)
    ds, meta = read_local([write_waves(root / "med_waves.nc")])
    with open_workspace(loaded) as ws:
        load_weather(ws, ds, name="med-test", metadata={"product": meta["product"]})
    return bare, loaded


def test_lane_outside_the_weather_bbox_names_product_variable_and_bboxes(workspaces, tmp_path, capsys):
    # the reviewer's case: a New York lane with Mediterranean weather said "0 h over limits"
    bare, _ = workspaces
    waves = write_waves(tmp_path / "med_waves.nc")
    code, out, err = run(capsys, "deviate", "--lane", "NY1", "--depart", "2025-01-15T00:00Z", "--db", str(bare),
                         "--weather", str(waves), "--json")
    assert code == 2 and out == ""
    assert err.startswith("error: ") and err.count("\n") == 1
    assert f"{PRODUCT} (med_waves.nc), hs_m: bbox lon -74.05..-73.6, lat 40.45..40.65 is not covered" in err
    assert "data cover lon 1.5..4.5, lat 39.5..41.8" in err
    assert "8 of 8 lane centroids lie outside the grid" in err


def test_lane_outside_the_workspace_weather_names_the_grid(workspaces, capsys):
    _, loaded = workspaces
    code, out, err = run(capsys, "deviate", "--lane", "NY1", "--depart", "2025-01-15T00:00Z", "--db", str(loaded))
    assert code == 2 and out == ""
    assert err.startswith("error: the weather does not cover lane NY1: ") and err.count("\n") == 1
    assert "(workspace grid 'med-test': med_waves.nc), hs_m: bbox lon -74.05..-73.6" in err


def test_departure_outside_the_time_span_names_product_variable_and_gap(workspaces, tmp_path, capsys):
    bare, _ = workspaces
    waves = write_waves(tmp_path / "med_waves.nc")
    code, _, err = run(capsys, "deviate", "--lane", "MED1", "--depart", "2025-01-16T00:00Z", "--db", str(bare),
                       "--weather", str(waves))
    assert code == 2
    assert err.startswith(f"error: {PRODUCT} (med_waves.nc), hs_m: no data for 2025-01-15T14:00Z -> 2025-01-16T00:00Z: ")
    assert "outside the weather 2025-01-14T18:00:00+00:00 .. 2025-01-15T14:00:00+00:00" in err


def test_land_cells_inside_the_grid_are_not_a_coverage_gap(workspaces, tmp_path, capsys):
    # an "island" of NaN cells across the lane's middle: the lane meets weather before and after it
    bare, _ = workspaces
    waves = write_waves(tmp_path / "island.nc", nan_where=lambda la, lo: (la > 40.45) & (la < 40.75) & (lo > 2.75) & (lo < 3.25))
    code, out, err = run(capsys, "deviate", "--lane", "MED1", "--depart", "2025-01-15T00:00Z", "--db", str(bare),
                         "--weather", str(waves), "--json")
    assert code == 0, err
    lane = json.loads(out)["lane"]
    assert 0.0 < lane["no_weather_h"] < lane["time_h"]
    assert lane["max_hs_m"] == pytest.approx(2.0)


def test_lane_meeting_no_weather_inside_the_grid_is_an_error(workspaces, tmp_path, capsys):
    # the grid's bbox holds the lane, but every cell the lane meets is NaN (only the far north has data)
    bare, _ = workspaces
    waves = write_waves(tmp_path / "north_only.nc", nan_where=lambda la, lo: la < 41.35)
    code, out, err = run(capsys, "deviate", "--lane", "MED1", "--depart", "2025-01-15T00:00Z", "--db", str(bare),
                         "--weather", str(waves), "--json")
    assert code == 2 and out == ""
    assert err.startswith(f"error: {PRODUCT} (north_only.nc), hs_m: lane MED1 (lat 40.200..41.000, lon 2.400..3.600) meets no data")


def test_no_weather_in_the_workspace_says_how_to_get_some(workspaces, capsys):
    bare, _ = workspaces
    code, _, err = run(capsys, "deviate", "--lane", "MED1", "--depart", "2025-01-15T00:00Z", "--db", str(bare))
    assert code == 2
    assert err == (f"error: no weather in the workspace {bare}: load some with `stormlane weather load PATH...` "
                   "or pass --weather FILE...\n")
    assert "None" not in err


def test_covered_lane_runs_and_carries_no_note(workspaces, capsys):
    _, loaded = workspaces
    code, out, err = run(capsys, "deviate", "--lane", "MED1", "--depart", "2025-01-15T00:00Z", "--db", str(loaded), "--json")
    assert code == 0, err
    obj = json.loads(out)
    assert obj["note"] is None and obj["notes"] == []
    assert obj["lane"]["no_weather_h"] == 0.0 and obj["lane"]["max_hs_m"] == pytest.approx(2.0)


def test_not_safer_note_text_and_condition():
    # The note says "less safe" by the rule that ranks the proposals (routing.audit.safety_order):
    # more adverse hours, else more IMO events, else a max Hs higher by more than 0.1 m. A
    # deviation with fewer adverse hours is safer whatever its max Hs (the proposal says so too).
    from pipelines.deviate import not_safer_note

    lane = {"adverse_h": 2.99, "max_hs_m": 5.10, "n_safety_events": 1}
    assert not_safer_note(lane, {"adverse_h": 2.99, "max_hs_m": 5.10, "n_safety_events": 1}) is None
    assert not_safer_note(lane, {"adverse_h": 2.99, "max_hs_m": 5.19, "n_safety_events": 1}) is None  # within 0.1 m
    assert not_safer_note(lane, {"adverse_h": 3.61, "max_hs_m": 5.10, "n_safety_events": 1}) == (
        "the deviation meets more hours over the limits or in IMO situations than the lane (3.6 h against 3.0 h; "
        "max Hs 5.10 against 5.10 m): Algorithm 1 looks one step ahead at a time; compare the safe time-optimal route "
        "(`stormlane route --safety hard`)")
    assert not_safer_note(lane, {"adverse_h": 2.99, "max_hs_m": 5.10, "n_safety_events": 2}).startswith(
        "the deviation meets more IMO events than the lane")
    note = not_safer_note(lane, {"adverse_h": 2.99, "max_hs_m": 5.25, "n_safety_events": 1})
    assert note.startswith("the deviation meets a higher max Hs than the lane (3.0 h against 3.0 h; max Hs 5.25 against 5.10 m)")
    assert not_safer_note(lane, {"adverse_h": 1.0, "max_hs_m": 5.50, "n_safety_events": 1}) is None  # safer: fewer hours
    assert not_safer_note({"adverse_h": 0.0, "max_hs_m": None}, {"adverse_h": 0.0, "max_hs_m": 3.0}) is None
