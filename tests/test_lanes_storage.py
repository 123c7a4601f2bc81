"""Lanes storage round trip, GeoJSON export and the port list reader."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from dashboards.lanes_geojson import lanes_geojson, polygon_from_wkt
from lanes.chain import build_lanes, voyages_as_table
from lanes.io.portlist import PortListError, read_port_list, read_port_lists
from lanes_tracks import T0, shuttle
from pipelines.config import data_dir
from pipelines.storage import open_workspace
from pipelines.storage.lanes import (
    read_last_run,
    read_lane_centroids,
    read_lane_voyages,
    read_lanes,
    read_ports,
    read_voyages,
    write_lanes,
)

A = (41.30, 2.20)
B = (41.30, 2.60)


@pytest.fixture(scope="module")
def result():
    frames = [shuttle(201000000 + i, A if i % 2 == 0 else B, B if i % 2 == 0 else A, 4, lateral_nmi=off, seed=i,
                      start=T0 + pd.Timedelta(minutes=17 * i)) for i, off in enumerate((-0.2, 0.0, 0.2))]
    known = pd.DataFrame({"locode": ["XXAAA"], "name": ["Port A"], "country": ["XX"], "lat_deg": [A[0]], "lon_deg": [A[1]]})
    return build_lanes(pd.concat(frames, ignore_index=True), known)


def _write(ws, r):
    return write_lanes(ws, r.ports, voyages_as_table(r.voyages), r.lanes.lanes, r.lanes.centroids, r.lane_voyages,
                       r.summary, {"eps_nmi": 2.0})


def test_write_read_round_trip(tmp_path, result):
    r = result
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        assert _write(ws, r) == 1
        ports = read_ports(ws)
        voyages = read_voyages(ws)
        lanes = read_lanes(ws)
        cents = read_lane_centroids(ws)
        lv = read_lane_voyages(ws)
        run = read_last_run(ws)
    assert len(ports) == len(r.ports) == 2
    assert ports.loc[ports["kind"] == "port", "name"].tolist() == ["Port A"]
    assert len(voyages) == len(r.voyages) and (voyages["kind"] == "port_to_port").sum() == r.summary["voyages"] == 12
    assert str(voyages["depart_utc"].dt.tz) == "UTC"
    assert voyages["depart_utc"].min() == r.voyages["depart_utc"].min()
    assert set(voyages["mmsi"]) == {201000000, 201000001, 201000002}
    assert len(lanes) == 2 and list(lanes["n_voyages"]) == list(r.lanes.lanes.sort_values("lane_id")["n_voyages"])
    # centroids: seq 0..n-1 per lane, in sailing order, same values as computed
    for lane_id, g in cents.groupby("lane_id"):
        assert list(g["seq"]) == list(range(len(g)))
    assert len(cents) == len(r.lanes.centroids)
    assert lv.groupby("lane_id")["voyage_id"].nunique().tolist() == [6, 6]
    assert run["run_id"] == 1 and run["lanes"] == 2 and run["params"] == {"eps_nmi": 2.0}
    assert run["summary"]["voyages"] == 12


def test_rewrite_replaces_and_filters(tmp_path, result):
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        _write(ws, result)
        assert _write(ws, result) == 2  # a second run replaces, not appends
        assert len(read_lanes(ws)) == 2
        lane_id = read_lanes(ws)["lane_id"].iloc[0]
        c = read_lane_centroids(ws, lane_id)
        assert set(c["lane_id"]) == {lane_id} and len(c) >= 4
        assert set(read_voyages(ws, kind="port_to_port")["kind"]) == {"port_to_port"}
        assert int(ws.con.execute("SELECT count(*) FROM lane_runs").fetchone()[0]) == 2


def test_failed_write_leaves_previous_result(tmp_path, result):
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        _write(ws, result)
        bad_cents = result.lanes.centroids.drop(columns=["speed_kn"])
        with pytest.raises(ValueError, match="speed_kn"):
            write_lanes(ws, result.ports, voyages_as_table(result.voyages), result.lanes.lanes, bad_cents,
                        result.lane_voyages, result.summary, {})
        assert len(read_lanes(ws)) == 2 and len(read_ports(ws)) == 2
        assert read_last_run(ws)["run_id"] == 1


def test_geojson_features(tmp_path, result):
    r = result
    fc = lanes_geojson(r.ports, r.lanes.lanes, r.lanes.centroids)
    assert fc["type"] == "FeatureCollection"
    layers = [f["properties"]["layer"] for f in fc["features"]]
    assert layers.count("port") == 2 and layers.count("lane") == 2 and layers.count("lane_path") == 2
    assert layers.count("centroid") == len(r.lanes.centroids)
    port = next(f for f in fc["features"] if f["properties"]["layer"] == "port" and f["properties"]["name"] == "Port A")
    lon, lat = port["geometry"]["coordinates"]
    assert lat == pytest.approx(A[0], abs=0.01) and lon == pytest.approx(A[1], abs=0.01)  # [lon, lat] order
    poly = next(f for f in fc["features"] if f["properties"]["layer"] == "lane")
    ring = poly["geometry"]["coordinates"][0]
    assert ring[0] == ring[-1] and len(ring) >= 4
    assert all(2.1 < x < 2.7 and 41.2 < y < 41.4 for x, y in ring)
    json.dumps(fc, allow_nan=False)  # NaN-free, serialisable


def test_polygon_from_wkt_rejects_garbage():
    assert polygon_from_wkt("POLYGON ((0 0, 1 0, 1 1, 0 0))") == [[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 0.0]]]
    with pytest.raises(ValueError):
        polygon_from_wkt("LINESTRING (0 0, 1 1)")
    with pytest.raises(ValueError):
        polygon_from_wkt("POLYGON ((0 0, x 1, 1 1, 0 0))")


def test_project_port_lists_are_valid():
    df, meta = read_port_lists([data_dir() / "ports.csv", data_dir() / "ports_terminals.csv"])
    assert meta["rows"] == len(df) >= 15
    ny = df[df["locode"] == "USNYC"]
    assert (ny["radius_nmi"] == 0.25).all() and df.loc[df["locode"] != "USNYC", "radius_nmi"].isna().all()


@pytest.mark.parametrize("line, message", [
    ("XXAAA,Port A,XX,91.0,2.0,41.0,2.0", "'lat_deg' = 91.0 is outside"),
    ("XXAAA,Port A,XX,abc,2.0,41.0,2.0", "'lat_deg' = 'abc' is not a number"),
    (",Port A,XX,41.0,2.0,41.0,2.0", "'locode' is empty"),
])
def test_port_list_errors_name_file_line_and_field(tmp_path, line, message):
    p = tmp_path / "ports.csv"
    p.write_text("locode,name,country,lat_deg,lon_deg,approach_lat_deg,approach_lon_deg\n"
                 "XXBBB,Port B,XX,40.0,2.0,40.0,2.1\n" + line + "\n")
    with pytest.raises(PortListError, match=f"{p}:3: field {message}"):
        read_port_list(p)


def test_port_list_missing_column_and_duplicates(tmp_path):
    p = tmp_path / "ports.csv"
    p.write_text("locode,name,lat_deg\nXXAAA,A,1\n")
    with pytest.raises(PortListError, match="missing column"):
        read_port_list(p)
    q = tmp_path / "dup.csv"
    q.write_text("locode,name,country,lat_deg,lon_deg,approach_lat_deg,approach_lon_deg\n"
                 "XXAAA,A,XX,40,2,40,2\nXXAAA,A,XX,41,2,41,2\n")
    with pytest.raises(PortListError, match="duplicate"):
        read_port_list(q)
    with pytest.raises(PortListError, match="not found"):
        read_port_list(tmp_path / "nope.csv")
