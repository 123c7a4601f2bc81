"""Route exports: GeoJSON (RFC 7946), GPX 1.1 and RTZ (IEC 61174) parse back with plain readers.

Expected values are written out by hand here (coordinates, ETAs, speeds of a small
Barcelona -> Palma route); none comes from another project function.
"""

from __future__ import annotations

import json
from pathlib import Path
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest
import shapely.geometry

from dashboards.errors import ExportError
from dashboards.exports import read_geojson, read_gpx, read_rtz, write_routes
from routing.route import Route

LAT = [41.3000001, 40.7512345, 40.1023456, 39.5000009]
LON = [2.2500003, 2.4123456, 2.5678901, 2.7000005]
TIMES = ["2025-01-31T03:00:00Z", "2025-01-31T06:20:00Z", "2025-01-31T09:45:30Z", "2025-01-31T12:00:00Z"]
SPEEDS = [10.25, 11.5, 14.0]
HS = [1.2, np.nan, 3.75, 2.0]

GPX = "{http://www.topografix.com/GPX/1/1}"
RTZ11 = "{http://www.cirm.org/RTZ/1/1}"
RTZ10 = "{http://www.cirm.org/RTZ/1/0}"


def make_route(name="optimal", **props) -> Route:
    return Route(
        name=name,
        lat_deg=np.array(LAT),
        lon_deg=np.array(LON),
        time_utc=pd.DatetimeIndex(pd.to_datetime(TIMES, utc=True)),
        leg_speed_kn=np.array(SPEEDS),
        weather={"hs_m": np.array(HS), "wave_from_deg": np.array([270.0, 280.0, 300.0, 310.0])},
        properties={"origin": "Barcelona", "destination": "Palma", **props},
    )


def make_other() -> Route:
    return Route(
        name="historical",
        lat_deg=np.array([41.3, 39.5]),
        lon_deg=np.array([2.25, 2.7]),
        time_utc=pd.DatetimeIndex(pd.to_datetime(["2025-01-31T03:00:00Z", "2025-01-31T13:00:00Z"], utc=True)),
        leg_speed_kn=np.array([10.9]),
    )


# ------------------------------------------------------------------ GeoJSON


def _hav(lat1, lon1, lat2, lon2):
    """Great-circle distance on the mean sphere (written out here, not the project's). [nmi]"""
    p1, p2 = np.radians(lat1), np.radians(lat2)
    a = np.sin((p2 - p1) / 2) ** 2 + np.cos(p1) * np.cos(p2) * np.sin(np.radians(np.asarray(lon2) - lon1) / 2) ** 2
    return 2 * (6371008.8 / 1852.0) * np.arcsin(np.sqrt(np.minimum(a, 1.0)))


def test_geojson_parses_with_json_and_shapely(tmp_path):
    path = tmp_path / "routes.geojson"
    written = write_routes([make_route(), make_other()], path)
    assert written == [path]
    data = json.loads(path.read_text())  # strict JSON: NaN would have raised in json.dumps(allow_nan=False)
    assert data["type"] == "FeatureCollection"
    feats = data["features"]
    lines = [f for f in feats if f["properties"]["feature"] == "route"]
    points = [f for f in feats if f["properties"]["feature"] == "waypoint"]
    assert [f["properties"]["route"] for f in lines] == ["optimal", "historical"]
    assert len(points) == 4 + 2
    line = shapely.geometry.shape(lines[0]["geometry"])
    assert line.geom_type == "LineString"
    xy = np.array(line.coords)  # [lon, lat] order, points along each great-circle leg (RFC 7946 lines are straight in lon/lat)
    at = [int(np.argmin(np.hypot(xy[:, 0] - lo, xy[:, 1] - la))) for la, lo in zip(LAT, LON)]
    np.testing.assert_allclose(xy[at], np.column_stack([LON, LAT]), atol=1e-7)  # every waypoint, in order
    assert at == sorted(at) and at[0] == 0 and at[-1] == len(xy) - 1
    for k in range(len(LAT) - 1):  # the points between two waypoints lie on the great circle, <= 1 nmi apart
        seg = xy[at[k] : at[k + 1] + 1]
        step = _hav(seg[:-1, 1], seg[:-1, 0], seg[1:, 1], seg[1:, 0])
        assert step.max() <= 1.0 + 1e-6
        assert step.sum() == pytest.approx(_hav(LAT[k], LON[k], LAT[k + 1], LON[k + 1]), abs=1e-4)
    # this fixture's last leg cuts across Mallorca (12.7 nmi of land): the export says so
    assert lines[0]["properties"]["sea_only"] is False and lines[0]["properties"]["line_step_nmi"] == 1.0
    assert lines[0]["properties"]["depart_utc"] == "2025-01-31T03:00:00Z"
    assert lines[0]["properties"]["arrive_utc"] == "2025-01-31T12:00:00Z"
    assert lines[0]["properties"]["time_h"] == pytest.approx(9.0)
    assert lines[0]["properties"]["max_hs_m"] == pytest.approx(3.75)
    assert lines[0]["properties"]["properties"]["origin"] == "Barcelona"
    wp = [p for p in points if p["properties"]["route"] == "optimal"]
    assert [p["properties"]["seq"] for p in wp] == [0, 1, 2, 3]
    assert [p["properties"]["eta_utc"] for p in wp] == TIMES
    assert [p["properties"]["leg_speed_kn"] for p in wp] == [10.25, 11.5, 14.0, None]
    assert [p["properties"]["hs_m"] for p in wp] == [1.2, None, 3.75, 2.0]
    assert wp[0]["properties"]["name"] == "Barcelona" and wp[-1]["properties"]["name"] == "Palma"
    assert wp[1]["properties"]["name"] == "WP002"
    pt = shapely.geometry.shape(wp[2]["geometry"])
    assert (pt.x, pt.y) == pytest.approx((LON[2], LAT[2]), abs=1e-7)


def test_geojson_round_trip(tmp_path):
    path = tmp_path / "r.json"
    write_routes(make_route(), path)
    (back,) = read_geojson(path)
    np.testing.assert_allclose(back.lat_deg, LAT, atol=1e-6)
    np.testing.assert_allclose(back.lon_deg, LON, atol=1e-6)
    assert list(back.time_utc) == list(pd.to_datetime(TIMES, utc=True))
    np.testing.assert_allclose(back.leg_speed_kn, SPEEDS)
    np.testing.assert_allclose(back.weather["hs_m"], HS)  # NaN stays NaN


def test_geojson_splits_at_the_antimeridian(tmp_path):
    route = Route(
        name="pacific",
        lat_deg=np.array([50.0, 52.0]),
        lon_deg=np.array([179.0, -179.0]),  # 2 deg of longitude across the antimeridian
        time_utc=pd.DatetimeIndex(pd.to_datetime(["2025-01-01T00:00Z", "2025-01-01T10:00Z"], utc=True)),
        leg_speed_kn=np.array([12.0]),
    )
    path = tmp_path / "p.geojson"
    write_routes(route, path)
    geom = json.loads(path.read_text())["features"][0]["geometry"]
    assert geom["type"] == "MultiLineString" and len(geom["coordinates"]) == 2
    west, east = geom["coordinates"]
    assert west[0] == [179.0, 50.0] and east[-1] == [-179.0, 52.0]
    assert west[-1][0] == 180.0 and east[0][0] == -180.0 and west[-1][1] == east[0][1]
    # the crossing is on the great circle: tan(lat) at lon 180 from the two ends (Williams, "Aviation Formulary")
    p1, p2, l1, l2 = np.radians([50.0, 52.0, 179.0, 181.0])
    lat_x = np.degrees(np.arctan((np.tan(p1) * np.sin(l2 - np.pi) + np.tan(p2) * np.sin(np.pi - l1)) / np.sin(l2 - l1)))
    assert west[-1][1] == pytest.approx(lat_x, abs=1e-5)
    assert shapely.geometry.shape(geom).is_valid


@pytest.mark.parametrize("lon,n_parts", [([179.0, 180.0], 1), ([180.0, 179.0], 1), ([-179.0, -180.0], 1), ([-180.0, -179.0], 1),
                                         ([179.0, 180.0, -179.0], 2), ([-179.0, 180.0, 179.0], 2)])  # fmt: skip
def test_geojson_route_ending_on_the_antimeridian_is_one_valid_line(tmp_path, lon, n_parts):
    # a route from or to 180 deg exactly used to leave a "line" of one repeated point at the seam (invalid)
    route = Route(name="pacific", lat_deg=np.linspace(50.0, 52.0, len(lon)), lon_deg=np.array(lon),
                  time_utc=pd.DatetimeIndex(pd.date_range("2025-01-01", periods=len(lon), freq="10h", tz="UTC")),
                  leg_speed_kn=np.full(len(lon) - 1, 12.0))  # fmt: skip
    path = tmp_path / "p.geojson"
    write_routes(route, path)
    geom = json.loads(path.read_text())["features"][0]["geometry"]
    parts = geom["coordinates"] if geom["type"] == "MultiLineString" else [geom["coordinates"]]
    assert len(parts) == n_parts and geom["type"] == ("LineString" if n_parts == 1 else "MultiLineString")
    assert shapely.geometry.shape(geom).is_valid
    assert all(len({tuple(p) for p in part}) >= 2 for part in parts)
    assert parts[0][0][1] == 50.0 and parts[-1][-1][1] == 52.0  # from the start to the goal
    assert all(-180.0 <= p[0] <= 180.0 for part in parts for p in part)


# ------------------------------------------------------------------ GPX


def test_gpx_has_required_elements_and_namespace(tmp_path):
    path = tmp_path / "routes.gpx"
    write_routes([make_route(), make_other()], path)
    root = ET.parse(path).getroot()
    assert root.tag == f"{GPX}gpx"
    assert root.get("version") == "1.1" and root.get("creator") == "stormlane"
    rtes = root.findall(f"{GPX}rte")
    assert [r.find(f"{GPX}name").text for r in rtes] == ["optimal", "historical"]
    pts = rtes[0].findall(f"{GPX}rtept")
    assert len(pts) == 4
    assert [float(p.get("lat")) for p in pts] == pytest.approx(LAT, abs=1e-7)
    assert [float(p.get("lon")) for p in pts] == pytest.approx(LON, abs=1e-7)
    assert [p.find(f"{GPX}time").text for p in pts] == TIMES
    assert [p.find(f"{GPX}name").text for p in pts] == ["Barcelona", "WP002", "WP003", "Palma"]
    # wptType child order: time comes before name (GPX 1.1 schema sequence).
    assert [c.tag for c in pts[0]][:2] == [f"{GPX}time", f"{GPX}name"]
    assert len(rtes[1].findall(f"{GPX}rtept")) == 2


def test_gpx_round_trip(tmp_path):
    path = tmp_path / "routes.gpx"
    write_routes([make_route(), make_other()], path)
    opt, hist = read_gpx(path)
    np.testing.assert_allclose(opt.lat_deg, LAT, atol=1e-6)
    np.testing.assert_allclose(opt.lon_deg, LON, atol=1e-6)
    assert list(opt.time_utc) == list(pd.to_datetime(TIMES, utc=True))
    np.testing.assert_allclose(opt.leg_speed_kn, SPEEDS)
    np.testing.assert_allclose(opt.weather["hs_m"], HS)
    assert hist.name == "historical" and hist.n_waypoints == 2


# ------------------------------------------------------------------ RTZ


def test_rtz_11_structure(tmp_path):
    path = tmp_path / "BCN_PMI_optimal.rtz"
    write_routes(make_route(vessel="MV Test", mmsi=224123450), path)
    root = ET.parse(path).getroot()
    assert root.tag == f"{RTZ11}route"
    assert root.get("version") == "1.1"
    info = root.find(f"{RTZ11}routeInfo")
    assert info.get("routeName") == "BCN_PMI_optimal"  # equals the file stem
    assert info.get("vesselName") == "MV Test" and info.get("vesselMMSI") == "224123450"
    assert info.get("validityPeriodStart") == TIMES[0] and info.get("validityPeriodStop") == TIMES[-1]
    wps = root.findall(f"{RTZ11}waypoints/{RTZ11}waypoint")
    assert len(wps) == 4
    assert [w.get("id") for w in wps] == ["1", "2", "3", "4"]
    assert [w.get("name") for w in wps] == ["Barcelona", "WP002", "WP003", "Palma"]
    assert [w.find(f"{RTZ11}position").get("lat") for w in wps] == ["41.3000001", "40.7512345", "40.1023456", "39.5000009"]
    assert [w.find(f"{RTZ11}position").get("lon") for w in wps] == ["2.2500003", "2.4123456", "2.5678901", "2.7000005"]
    # The leg on waypoint i is the leg arriving from i - 1: none on the first waypoint.
    assert wps[0].find(f"{RTZ11}leg") is None
    legs = [w.find(f"{RTZ11}leg") for w in wps[1:]]
    assert [leg.get("speedMax") for leg in legs] == ["10.25", "11.5", "14"]
    assert {leg.get("geometryType") for leg in legs} == {"Orthodrome"}
    els = root.findall(f"{RTZ11}schedules/{RTZ11}schedule/{RTZ11}calculated/{RTZ11}scheduleElement")
    assert [e.get("waypointId") for e in els] == ["1", "2", "3", "4"]
    assert els[0].get("etd") == TIMES[0] and els[0].get("eta") is None
    assert [e.get("eta") for e in els[1:]] == TIMES[1:]
    assert els[-1].get("etd") is None
    assert [e.get("speed") for e in els[1:]] == ["10.25", "11.5", "14"]


def test_rtz_round_trip_same_coordinates_and_schedule(tmp_path):
    path = tmp_path / "r.rtz"
    write_routes(make_route(), path)
    back = read_rtz(path)
    assert back.n_waypoints == 4
    assert np.max(np.abs(back.lat_deg - np.array(LAT))) <= 1e-6
    assert np.max(np.abs(back.lon_deg - np.array(LON))) <= 1e-6
    assert list(back.time_utc) == list(pd.to_datetime(TIMES, utc=True))
    np.testing.assert_allclose(back.leg_speed_kn, SPEEDS)
    assert back.properties["rtz_version"] == "1.1"


def test_rtz_10_namespace_and_round_trip(tmp_path):
    path = tmp_path / "r10.rtz"
    write_routes(make_route(), path, rtz_version="1.0")
    root = ET.parse(path).getroot()
    assert root.tag == f"{RTZ10}route" and root.get("version") == "1.0"
    assert len(root.findall(f"{RTZ10}waypoints/{RTZ10}waypoint")) == 4
    back = read_rtz(path)
    assert list(back.time_utc) == list(pd.to_datetime(TIMES, utc=True))


def test_rtz_rounds_eta_to_the_second_and_writes_plain_decimals(tmp_path):
    route = Route(
        name="optimal",
        lat_deg=np.array([1e-9, 0.5]),  # would print as 1e-09 with repr
        lon_deg=np.array([180.0, 0.5]),  # 180 wraps to -180 (LongitudeType is [-180, 180))
        time_utc=pd.DatetimeIndex(pd.to_datetime(["2025-01-01T00:00:00.4Z", "2025-01-01T03:00:00.6Z"], utc=True)),
        leg_speed_kn=np.array([12.345678]),
    )
    path = tmp_path / "x.rtz"
    write_routes(route, path)
    root = ET.parse(path).getroot()
    pos = root.findall(f"{RTZ11}waypoints/{RTZ11}waypoint/{RTZ11}position")
    assert pos[0].get("lat") == "0" and pos[0].get("lon") == "-180"
    els = root.findall(f"{RTZ11}schedules/{RTZ11}schedule/{RTZ11}calculated/{RTZ11}scheduleElement")
    assert els[0].get("etd") == "2025-01-01T00:00:00Z" and els[1].get("eta") == "2025-01-01T03:00:01Z"
    assert els[1].get("speed") == "12.35"


def test_rtz_several_routes_one_file_each(tmp_path):
    written = write_routes([make_route(), make_other()], tmp_path / "night.rtz")
    assert [p.name for p in written] == ["night_optimal.rtz", "night_historical.rtz"]
    assert read_rtz(written[1]).properties["route_name"] == "night_historical"
    assert read_rtz(written[1]).n_waypoints == 2


# ------------------------------------------------------------------ errors


def test_unknown_suffix_and_short_route_are_clear_errors(tmp_path):
    with pytest.raises(ExportError, match=r"\.kml"):
        write_routes(make_route(), tmp_path / "r.kml")
    short = Route(name="x", lat_deg=[1.0], lon_deg=[1.0], time_utc=pd.DatetimeIndex(["2025-01-01"], tz="UTC"), leg_speed_kn=[])
    with pytest.raises(ExportError, match="at least 2"):
        write_routes(short, tmp_path / "r.gpx")
    with pytest.raises(ExportError, match="no routes"):
        write_routes([], tmp_path / "r.gpx")


def test_read_rtz_rejects_bad_files_naming_them(tmp_path):
    bad = tmp_path / "bad.rtz"
    bad.write_text("<route><oops></route>")
    with pytest.raises(ExportError, match="bad.rtz: not well-formed"):
        read_rtz(bad)
    wrong = tmp_path / "wrong.rtz"
    wrong.write_text('<route xmlns="http://www.cirm.org/RTZ/1/1" version="1.0"><routeInfo routeName="wrong"/></route>')
    with pytest.raises(ExportError, match="does not match namespace"):
        read_rtz(wrong)
    nosched = tmp_path / "nosched.rtz"
    nosched.write_text(
        '<route xmlns="http://www.cirm.org/RTZ/1/1" version="1.1"><routeInfo routeName="nosched"/><waypoints>'
        '<waypoint id="1"><position lat="1" lon="1"/></waypoint><waypoint id="2"><position lat="2" lon="2"/></waypoint>'
        "</waypoints></route>"
    )
    with pytest.raises(ExportError, match="no schedule"):
        read_rtz(nosched)


def test_xml_special_characters_in_names_survive(tmp_path):
    route = make_route(vessel='A&B <"x">', origin="Port <1> & co")
    path = tmp_path / "s.rtz"
    write_routes(route, path)
    root = ET.parse(path).getroot()  # would raise if the text were not escaped
    assert root.find(f"{RTZ11}routeInfo").get("vesselName") == 'A&B <"x">'
    assert root.find(f"{RTZ11}waypoints/{RTZ11}waypoint").get("name") == "Port <1> & co"
    gpx = tmp_path / "s.gpx"
    write_routes(route, gpx)
    assert read_gpx(gpx)[0].properties["waypoint_names"][0] == "Port <1> & co"


def test_export_alternatives_writes_all_formats_with_relative_links(tmp_path):
    from dashboards.exports import export_alternatives

    routes = {"historical": make_other(), "optimal": make_route("optimal"), "deviation": make_route("deviation")}
    links = export_alternatives(routes, tmp_path / "exports", "L1_20250131T0300Z", relative_to=tmp_path)
    assert links == {
        "GeoJSON": "exports/L1_20250131T0300Z.geojson",
        "GPX": "exports/L1_20250131T0300Z.gpx",
        "RTZ optimal": "exports/L1_20250131T0300Z_optimal.rtz",
        "RTZ deviation": "exports/L1_20250131T0300Z_deviation.rtz",
    }
    assert len(read_gpx(tmp_path / links["GPX"])) == 3
    assert read_rtz(tmp_path / links["RTZ optimal"]).n_waypoints == 4
    with pytest.raises(ExportError, match="stem"):
        export_alternatives(routes, tmp_path, "../evil")


def test_export_alternatives_only_proposed_writes_gpx_and_rtz_of_that_route(tmp_path):
    from dashboards.exports import export_alternatives

    routes = {"historical": make_other(), "optimal": make_route("optimal"), "deviation": make_route("deviation")}
    links = export_alternatives(routes, tmp_path / "x", "L2_20250131T0600Z", relative_to=tmp_path, proposed="deviation",
                                only_proposed=True)
    assert links == {
        "GeoJSON (all routes)": "x/L2_20250131T0600Z.geojson",
        "GPX deviation": "x/L2_20250131T0600Z_deviation.gpx",
        "RTZ deviation": "x/L2_20250131T0600Z_deviation.rtz",
    }
    assert sorted(p.name for p in (tmp_path / "x").iterdir()) == sorted(Path(v).name for v in links.values())
    (back,) = read_gpx(tmp_path / links["GPX deviation"])
    assert back.n_waypoints == routes["deviation"].n_waypoints
    assert np.allclose(read_rtz(tmp_path / links["RTZ deviation"]).lat_deg, routes["deviation"].lat_deg, atol=1e-6)
    # nothing proposed: the comparison GeoJSON only
    none = export_alternatives(routes, tmp_path / "y", "L2_20250131T0900Z", relative_to=tmp_path, only_proposed=True)
    assert list(none) == ["GeoJSON (all routes)"]


def _case(rank, lane, proposed, roles=("lane", "deviation", "optimal")):
    t0 = pd.Timestamp("2025-01-31T03:00Z") + pd.Timedelta(hours=3 * rank)
    routes = {r: Route(r, LAT, [x + 0.01 * k for x in LON], pd.DatetimeIndex(pd.to_datetime(TIMES)) + pd.Timedelta(hours=3 * rank),
                       SPEEDS, {"hs_m": np.array(HS)}, {"origin": "Barcelona", "destination": "Palma"})
              for k, r in enumerate(roles)}
    return {"rank": rank, "lane_id": lane, "origin": "Barcelona", "destination": "Palma", "depart_utc": t0, "proposed": proposed,
            "risk_avoided_h": 2.5 if proposed else None, "routes": routes}


def test_exports_zip_holds_the_proposed_routes_by_default_and_every_route_on_request(tmp_path):
    """Issue 22: one archive per night with index.csv; proposed routes only unless asked for all."""
    import zipfile

    from dashboards.archive import read_index, write_exports_zip
    from dashboards.errors import ReportError

    cases = [_case(1, "L1", "optimal"), _case(2, "L/2", None)]  # the second: no safer alternative
    out = write_exports_zip(cases, tmp_path / "exports.zip", when=pd.Timestamp("2025-01-31T00:00Z"))
    index = read_index(tmp_path / "exports.zip")
    # 3 formats of the one proposed route; the case without a proposal exports nothing
    assert out["files"] == len(index) == 3 and out["members"] == {1: list(index["file"])}
    assert list(index["file"]) == ["L1_20250131T0600Z_optimal.rtz", "L1_20250131T0600Z_optimal.gpx", "L1_20250131T0600Z_optimal.geojson"]
    assert set(index["proposed"]) == {"yes"} and set(index["risk_avoided_h"]) == {2.5} and set(index["rank"]) == {1}
    with zipfile.ZipFile(tmp_path / "exports.zip") as zf:
        (tmp_path / "x.rtz").write_bytes(zf.read("L1_20250131T0600Z_optimal.rtz"))
        assert all(i.date_time == (2025, 1, 31, 0, 0, 0) for i in zf.infolist())
    back = read_rtz(tmp_path / "x.rtz")
    assert np.allclose(back.lat_deg, LAT, atol=1e-6) and np.allclose(back.lon_deg, [x + 0.02 for x in LON], atol=1e-6)
    # the same inputs give the same bytes
    again = write_exports_zip(cases, tmp_path / "again.zip", when=pd.Timestamp("2025-01-31T00:00Z"))
    assert (tmp_path / "again.zip").read_bytes() == (tmp_path / "exports.zip").read_bytes() and again["bytes"] == out["bytes"]
    # every route of every adverse case: per case one GeoJSON of all, RTZ and GPX per route (a lane id with "/" made safe)
    full = write_exports_zip(cases, tmp_path / "all.zip", mode="all")
    index = read_index(tmp_path / "all.zip")
    assert full["files"] == len(index) == 2 * (1 + 2 * 3)
    assert "L_2_20250131T0900Z_all.geojson" in set(index["file"])
    assert list(index.loc[index["role"] == "optimal", "proposed"]) == ["yes", "yes", "no", "no"]
    geo = json.loads(zipfile.ZipFile(tmp_path / "all.zip").read("L1_20250131T0600Z_all.geojson"))
    assert {f["properties"].get("route") for f in geo["features"]} == {"lane", "deviation", "optimal"}
    with pytest.raises(ReportError, match="exports mode 'some'"):
        write_exports_zip(cases, tmp_path / "x.zip", mode="some")
