"""The lanes chain on real AIS: New York harbour port calls and the Ushant traffic separation scheme.

Files are read in place from ../shared/data/ais (PROVENANCE.md sections 1 and 4); the tests skip
with the reason when they are absent.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from conftest import shared_file
from lanes.chain import ChainParams, build_lanes
from lanes.extract import LaneParams
from lanes.interpolate import ResampleParams
from lanes.io.portlist import read_port_lists
from lanes.io.ushant import UshantFormatError, read_ushant
from pipelines.config import data_dir

# True positions of the Staten Island Ferry terminals (Wikipedia infoboxes, checked 2026):
# St. George Terminal 40 deg 38'36" N 74 deg 4'27" W; Whitehall Terminal 40 deg 42'09" N 74 deg 00'46" W.
ST_GEORGE = (40.64333, -74.07417)
WHITEHALL = (40.70247, -74.01283)


def _metres(lat1, lon1, lat2, lon2):
    """Haversine on the mean sphere (independent of the project's geodesy). [m]"""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    a = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * 6371008.8 * math.asin(math.sqrt(a))


@pytest.fixture(scope="module")
def ny(shared_data):
    path = shared_file(shared_data, "ais/portcalls/nyharbor_marinecadastre_20210101.parquet")
    raw = pd.read_parquet(path)
    df = raw.rename(columns={"time": "time_utc", "lat": "lat_deg", "lon": "lon_deg"})
    df["time_utc"] = pd.to_datetime(df["time_utc"], utc=True)
    df.loc[df["sog_kn"] >= 102.2, "sog_kn"] = np.nan  # AIS "not available"
    known, _ = read_port_lists([data_dir() / "ports.csv", data_dir() / "ports_terminals.csv"])
    # Harbour scale: 60 s resampling, lanes a few hundred metres wide, centroids every 0.5 nmi.
    params = ChainParams(resample=ResampleParams(step_s=60, max_gap_s=900, course_window_s=180),
                         lanes=LaneParams(eps_nmi=0.15, min_density=3, centroid_spacing_nmi=0.5))
    return raw, build_lanes(df, known, params)


def test_ny_ferry_terminals_found_near_their_true_positions(ny):
    _, r = ny
    ports = r.ports.set_index("name")
    for name, true in (("St. George Ferry Terminal", ST_GEORGE), ("Whitehall Ferry Terminal", WHITEHALL)):
        row = ports.loc[name]
        assert row["kind"] == "port" and row["locode"] == "USNYC"
        # the slips are offshore of the terminal buildings: within 400 m (measured 225 m and 250 m)
        assert _metres(row["lat_deg"], row["lon_deg"], *true) < 400, name
        assert row["n_calls"] >= 35 and row["n_vessels"] >= 4
    # The two terminals are separate ports (8.4 km apart), and busy terminals nearby stay separate.
    assert ports.loc["St. George Ferry Terminal", "port_id"] != ports.loc["Whitehall Ferry Terminal", "port_id"]
    named = set(r.ports.loc[r.ports["kind"] == "port", "name"])
    assert {"Pier 11/Wall Street", "Battery Park (Castle Clinton)", "Ellis Island", "Liberty Island"} <= named


def test_ny_staten_island_ferry_crossings_are_voyages(ny):
    raw, r = ny
    pid = r.ports.set_index("name")["port_id"]
    sg, wh = pid["St. George Ferry Terminal"], pid["Whitehall Ferry Terminal"]
    v = r.voyages
    north = v[(v["origin_port_id"] == sg) & (v["dest_port_id"] == wh)]
    south = v[(v["origin_port_id"] == wh) & (v["dest_port_id"] == sg)]
    # PROVENANCE.md counts 75 crossings chaining consecutive stop clusters; we find 37 + 38.
    assert len(north) >= 30 and len(south) >= 30
    assert len(north) + len(south) >= 70
    ferries = set(raw.loc[raw["vessel_name"].isin(["SAMUEL I NEWHOUSE", "SEN JOHN J MARCHI", "JOHN F KENNEDY",
                                                    "GUY V MOLINARI"]), "mmsi"])
    assert set(north["track"]) | set(south["track"]) <= ferries
    # A crossing is 5.2 statute miles (4.5 nmi) terminal to terminal and takes about 25 min.
    crossing = pd.concat([north, south])
    assert crossing["dist_nmi"].median() == pytest.approx(4.6, abs=0.4)
    minutes = (crossing["arrive_utc"] - crossing["depart_utc"]).dt.total_seconds() / 60
    assert 15 < minutes.median() < 35
    # ... and each direction is a lane from one terminal to the other.
    for o, d in ((sg, wh), (wh, sg)):
        lane = r.lanes.lanes[(r.lanes.lanes["origin_port_id"] == o) & (r.lanes.lanes["dest_port_id"] == d)]
        assert len(lane) >= 1 and lane.iloc[0]["n_voyages"] >= 30
        c = r.lanes.centroids[r.lanes.centroids["lane_id"] == lane.iloc[0]["lane_id"]].sort_values("seq")
        start = r.ports.set_index("port_id").loc[o]
        end = r.ports.set_index("port_id").loc[d]
        assert _metres(c.iloc[0]["lat_deg"], c.iloc[0]["lon_deg"], start["lat_deg"], start["lon_deg"]) < 800
        assert _metres(c.iloc[-1]["lat_deg"], c.iloc[-1]["lon_deg"], end["lat_deg"], end["lon_deg"]) < 800


@pytest.fixture(scope="module")
def ushant(shared_data):
    path = shared_file(shared_data, "ais/ushant_ais_subset.parquet")
    df, meta = read_ushant(path, "2019-01-01T00:00Z", columns_only=True)
    # A quarter of the trajectories keeps the test fast; the density threshold scales with it
    # (bench/lanes.py runs the whole set with min_density 20).
    part = df[df["track_id"] % 4 == 1]
    params = ChainParams(id_col="track_id", lanes=LaneParams(eps_nmi=0.5, min_density=5))
    return meta, build_lanes(part, None, params)


def test_ushant_reader_metadata(ushant):
    meta, _ = ushant
    assert meta["rows"] == 2_428_448  # PROVENANCE.md
    assert meta["rejected"] == {"latlon_not_available": 16, "lat_out_of_range": 2}
    assert meta["loaded"] == meta["rows"] - 18
    assert meta["id_col"] == "track_id" and meta["id_is_mmsi"] is False


def test_ushant_tss_two_opposite_lanes_and_coastal_traffic(ushant):
    _, r = ushant
    lanes = r.lanes.lanes
    assert r.summary["ports"] < 40  # a transit area: almost no stops
    assert set(lanes["kind"]) == {"transit"} or (lanes["kind"] == "transit").mean() > 0.8
    top = lanes.sort_values("n_points", ascending=False).head(2)
    a, b = top.iloc[0], top.iloc[1]
    diff = abs((a["mean_course_deg"] - b["mean_course_deg"] + 180) % 360 - 180)
    assert diff == pytest.approx(180.0, abs=10.0)
    ne, sw = (a, b) if math.cos(math.radians(a["mean_course_deg"] - 45)) > 0 else (b, a)
    assert 20 < ne["mean_course_deg"] < 70 and 200 < sw["mean_course_deg"] < 250
    assert ne["n_voyages"] >= 300 and sw["n_voyages"] >= 150
    # Distinct lanes: the south-west-bound lane lies west of the north-east-bound one (outer lane),
    # several nmi apart where both run north-east of Ushant (lat 48.8-49.2).
    c = r.lanes.centroids

    def lon_at(lane_id, lat):
        g = c[c["lane_id"] == lane_id]
        g = g[(g["lat_deg"] > lat - 0.1) & (g["lat_deg"] < lat + 0.1)]
        return g["lon_deg"].mean()

    for lat in (48.9, 49.1):
        sep_nmi = (lon_at(ne["lane_id"], lat) - lon_at(sw["lane_id"], lat)) * 60 * math.cos(math.radians(lat))
        assert sep_nmi > 3.0, lat
    # Coastal traffic: lanes inshore of the scheme, near Ushant island (48.46 N, 5.09 W).
    ushant_island = (48.46, -5.09)
    coastal = []
    for lane_id, g in c.groupby("lane_id"):
        d = [_metres(la, lo, *ushant_island) / 1852 for la, lo in zip(g["lat_deg"], g["lon_deg"])]
        if max(d) < 20 and g["lon_deg"].min() > -5.45:
            coastal.append(lane_id)
    coastal_lanes = lanes[lanes["lane_id"].isin(coastal)]
    assert (coastal_lanes["n_voyages"] >= 20).sum() >= 2
    # both directions along the coast are present
    courses = coastal_lanes.loc[coastal_lanes["n_voyages"] >= 20, "mean_course_deg"].to_numpy()
    assert np.ptp(np.cos(np.radians(courses))) > 1.0 or np.ptp(np.sin(np.radians(courses))) > 1.0


def test_ushant_reader_needs_an_explicit_aware_epoch(shared_data, tmp_path):
    path = shared_file(shared_data, "ais/ushant_ais_subset.parquet")
    with pytest.raises(UshantFormatError, match="time zone"):
        read_ushant(path, "2019-01-01T00:00")
    bad = tmp_path / "x.parquet"
    pd.DataFrame({"a": [1]}).to_parquet(bad)
    with pytest.raises(UshantFormatError, match="missing column"):
        read_ushant(bad, "2019-01-01T00:00Z")
