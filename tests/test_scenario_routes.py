"""The demo scenario's geography and configuration: ports, sea routes, fleet identities.

Routes are checked against global-land-mask along the WGS84 geodesic (pyproj, independent of the
project's geodesy) at 0.25 nmi steps, i.e. finer than the 0.5 nmi the issue asks for.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from thresholds import land_raster as globe  # the package's 30" mask through its cache
from pyproj import Geod

from scenario.generator import ScenarioConfigError, imo_check_digit_ok, mmsi_problem, parse_scenario_spec

DATA = Path(__file__).resolve().parents[1] / "data"
GEOD = Geod(ellps="WGS84")
NMI = 1852.0


@pytest.fixture(scope="module")
def doc():
    return tomllib.loads((DATA / "scenario.toml").read_text())


@pytest.fixture(scope="module")
def ports():
    return pd.read_csv(DATA / "ports.csv")


def geodesic_points(lat1, lon1, lat2, lon2, step_nmi=0.25):
    """End points plus intermediate points every <= step_nmi along the geodesic."""
    _, _, dist_m = GEOD.inv(lon1, lat1, lon2, lat2)
    n = int(np.ceil(dist_m / (step_nmi * NMI)))
    pts = GEOD.npts(lon1, lat1, lon2, lat2, max(n - 1, 0))
    lons = [lon1] + [p[0] for p in pts] + [lon2]
    lats = [lat1] + [p[1] for p in pts] + [lat2]
    return np.array(lats), np.array(lons), dist_m / NMI


def test_ports_file_has_the_eight_demo_ports(ports):
    assert list(ports.columns) == ["locode", "name", "country", "lat_deg", "lon_deg", "approach_lat_deg",
                                   "approach_lon_deg"]
    assert set(ports.locode) >= {"ESBCN", "ESPMI", "ESVLC", "FRMRS", "ITGOA", "TNTUN", "DZALG", "ITCAG"}
    # every port inside the demo bbox (COMMON.md)
    assert ports.lon_deg.between(-1.5, 11.5).all() and ports.lat_deg.between(35.5, 45.0).all()


def test_approach_points_are_at_sea_and_close_to_their_port(ports):
    for row in ports.itertuples():
        assert not globe.is_land(row.approach_lat_deg, row.approach_lon_deg), row.locode
        _, _, d = GEOD.inv(row.lon_deg, row.lat_deg, row.approach_lon_deg, row.approach_lat_deg)
        assert 0.5 < d / NMI < 4.0, (row.locode, d / NMI)


def test_every_route_leg_is_at_sea(doc):
    assert len(doc["routes"]) >= 8
    for key, body in doc["routes"].items():
        wp = body["waypoints"]
        for (la1, lo1), (la2, lo2) in zip(wp[:-1], wp[1:]):
            lats, lons, dist = geodesic_points(la1, lo1, la2, lo2, 0.25)
            steps = GEOD.inv(lons[:-1], lats[:-1], lons[1:], lats[1:])[2] / NMI
            assert steps.max() <= 0.2501 and steps.sum() == pytest.approx(dist, rel=1e-6)
            land = globe.is_land(lats, lons)
            assert not land.any(), f"{key}: leg {la1},{lo1} -> {la2},{lo2} touches land at " \
                                   f"{lats[land][0]:.3f},{lons[land][0]:.3f}"


def test_routes_start_and_end_at_the_approach_points(doc, ports):
    appr = {r.locode: (r.approach_lat_deg, r.approach_lon_deg) for r in ports.itertuples()}
    for key, body in doc["routes"].items():
        o, d = key.split("-")
        assert tuple(body["waypoints"][0]) == pytest.approx(appr[o], abs=1e-4), key
        assert tuple(body["waypoints"][-1]) == pytest.approx(appr[d], abs=1e-4), key


def test_routes_are_not_absurdly_longer_than_the_great_circle(doc):
    # A route hugs coasts and rounds islands, but a detour over 45 % means a drawing error.
    for key, body in doc["routes"].items():
        wp = np.array(body["waypoints"])
        total = sum(GEOD.inv(a[1], a[0], b[1], b[0])[2] for a, b in zip(wp[:-1], wp[1:])) / NMI
        direct = GEOD.inv(wp[0, 1], wp[0, 0], wp[-1, 1], wp[-1, 0])[2] / NMI
        assert direct <= total <= 1.45 * direct, (key, total, direct)


def test_services_connect_at_least_six_ports_and_the_fleet_is_mixed(doc):
    ports_used = {p for s in doc["services"] for p in s["rotation"]}
    assert len(ports_used) >= 6
    assert 8 <= len(doc["services"]) <= 12
    classes = {s["id"]: s["vessel_class"] for s in doc["services"]}
    fleet = [classes[v["service"]] for v in doc["vessels"]]
    assert 18 <= len(fleet) <= 24
    assert {"ro-pax", "container", "tanker"} <= set(fleet)
    assert {v["ais_format"] for v in doc["vessels"]} == {"dma_csv", "nmea"}


MED_MIDS = {224, 225, 226, 227, 228, 247, 215, 229, 248, 249, 256, 237, 239, 240, 241, 209, 210, 212, 605, 672}


def test_fleet_identities_are_valid(doc):
    for v in doc["vessels"]:
        assert len(str(v["mmsi"])) == 9 and v["mmsi"] // 1_000_000 in MED_MIDS, v["name"]
        digits = [int(c) for c in str(v["imo"])]
        # IMO check digit (IMO Res. A.1117(30)): sum of the first six digits times 7..2, mod 10
        assert len(digits) == 7 and sum(d * w for d, w in zip(digits[:6], range(7, 1, -1))) % 10 == digits[6]
        assert v["to_bow"] + v["to_stern"] == pytest.approx(v["length_m"], abs=1)
        assert v["to_port"] + v["to_starboard"] == pytest.approx(v["beam_m"], abs=1)
        assert 60 <= v["ship_type"] <= 89
    assert len({v["mmsi"] for v in doc["vessels"]}) == len(doc["vessels"])
    classes = {s["id"]: s["vessel_class"] for s in doc["services"]}
    for v in doc["vessels"]:  # each ship names a vessel profile of its own class
        profile = tomllib.loads((DATA / "vessels" / f"{v['profile']}.toml").read_text())
        assert profile["vessel_class"] == classes[v["service"]], v["name"]
    assert len({v["imo"] for v in doc["vessels"]}) == len(doc["vessels"])


def test_identity_helpers():
    assert mmsi_problem(224087350) is None
    assert mmsi_problem(22408735) == "not 9 digits"
    assert "MID 111" in mmsi_problem(111087350)
    assert "MID 970" in mmsi_problem(970087350)
    assert imo_check_digit_ok(9074729)  # the example of IMO Res. A.1117(30): 9*7+0+7*5+4*4+7*3+2*2 = 139
    assert not imo_check_digit_ok(9074728)


def test_the_shipped_configuration_parses(doc, ports):
    spec = parse_scenario_spec(doc, ports)
    assert len(spec.vessels) == len(doc["vessels"])
    rid, wp = spec.route("ESPMI", "ESBCN")  # reverse direction of ESBCN-ESPMI
    assert rid == "ESBCN-ESPMI" and tuple(wp[0]) == (39.52, 2.62) and tuple(wp[-1]) == (41.31, 2.22)


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: d["vessels"][0].update(mmsi=12345678), "MMSI 12345678 is not 9 digits"),
        (lambda d: d["vessels"][0].update(mmsi=111087350), "MID 111"),
        (lambda d: d["vessels"][0].update(mmsi=247087350), "does not carry a MID of flag ES"),
        (lambda d: d["vessels"][0].update(imo=9412221), "IMO 9412221 fails the check digit"),
        (lambda d: d["vessels"][0].update(service="NOPE"), "unknown service 'NOPE'"),
        (lambda d: d["vessels"][0].update(colour="red"), "unknown key(s) colour"),
        (lambda d: d["services"][0].update(rotation=["ESBCN", "XXYYY"]), "rotation must list"),
        (lambda d: d["services"][0].update(vessel_class="yacht"), "vessel_class must be one of"),
        (lambda d: d["routes"]["ESBCN-ESPMI"].update(waypoints=[[41.0, 2.0], [39.52, 2.62]]),
         "must start/end at the approach point of ESBCN"),
        (lambda d: d["routes"].pop("ESBCN-ESPMI"), "no route for the leg ESBCN-ESPMI"),
    ],
)
def test_configuration_errors_name_the_file_and_the_entry(doc, ports, mutate, message):
    bad = copy.deepcopy(doc)
    mutate(bad)
    with pytest.raises(ScenarioConfigError) as err:
        parse_scenario_spec(bad, ports, source="scenario.toml")
    assert message in str(err.value)
    assert "scenario.toml" in str(err.value)
