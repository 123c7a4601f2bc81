"""Stop detection and port DBSCAN on hand-built tracks with known answers."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from lanes.ports import PortParams, cluster_stops, detect_ports, match_ports
from lanes.stops import StopParams, detect_stops
from lanes_tracks import T0, Itinerary, flat_dist_nmi, offset

A = (41.30, 2.20)  # at sea off Barcelona, only geometry matters here
B = (41.30, 2.60)


def test_berthed_ferry_reporting_under_way_is_a_stop():
    # 30 fixes at one place, SOG 0, nav status 0 = "under way using engine" (as NY ferries do).
    it = Itinerary(1, cadence_s=60).stay(*A, 30, sog=0.0, nav_status=0.0)
    it.sail(*B, 12.0)
    st = detect_stops(it.frame())
    assert len(st) == 1
    row = st.iloc[0]
    assert row["n_fixes"] == 30
    assert row["duration_s"] == pytest.approx(29 * 60)
    assert row["start_utc"] == T0
    assert row["lat_deg"] == pytest.approx(A[0], abs=1e-9) and row["lon_deg"] == pytest.approx(A[1], abs=1e-9)


def test_stale_sog_at_berth_is_still_a_stop():
    # The transponder repeats 8.5 kn while the position does not move: the positions decide.
    it = Itinerary(2, cadence_s=60).stay(*A, 30, sog=8.5, jitter_nmi=0.003)
    st = detect_stops(it.frame())
    assert len(st) == 1 and st.iloc[0]["n_fixes"] >= 25


def test_frozen_zero_sog_while_sailing_is_not_a_stop():
    it = Itinerary(3, cadence_s=60)
    it.pos = A
    it.sail(*B, 12.0, report_sog=0.0)
    assert len(detect_stops(it.frame())) == 0


def test_speed_spike_at_berth_is_merged_and_silent_berth_is_one_stop():
    it = Itinerary(4, cadence_s=60).stay(*A, 20)
    # one noisy fix (SOG 3 kn, 30 m off), then berthed again
    la, lo = offset(*A, 0.016, 0.0)
    it._fix(la, lo, 3.0, 90.0)
    it.t += pd.Timedelta(seconds=60)
    it.stay(*A, 20)
    it.silence(180)  # transponder off for 3 h, still at the berth
    it.stay(*A, 20)
    st = detect_stops(it.frame())
    assert len(st) == 1
    assert st.iloc[0]["duration_s"] == pytest.approx((20 + 1 + 20 + 180 + 20) * 60 - 60, abs=61)


def test_short_stop_is_dropped_and_parameters_are_checked():
    it = Itinerary(5, cadence_s=60).stay(*A, 2)
    assert len(detect_stops(it.frame(), StopParams(min_duration_s=180))) == 0
    with pytest.raises(ValueError):
        StopParams(max_speed_kn=0)
    with pytest.raises(ValueError):
        detect_stops(pd.DataFrame({"mmsi": [1]}))


def _stops_at(places, vessels_per_place, calls_each, jitter_nmi=0.02, seed=1):
    rng = np.random.default_rng(seed)
    rows = []
    k = 0
    for p, (lat, lon) in enumerate(places):
        for v in range(vessels_per_place[p]):
            for c in range(calls_each):
                e, n = rng.normal(0, jitter_nmi, 2)
                la, lo = offset(lat, lon, e, n)
                rows.append({"stop_id": k, "track": 100 * (p + 1) + v, "lat_deg": la, "lon_deg": lo})
                k += 1
    return pd.DataFrame(rows)


def test_two_ports_found_with_calls_vessels_and_centroids():
    stops = _stops_at([A, B], [3, 2], 4)
    ports, stop_port = detect_ports(stops, None, PortParams(eps_nmi=0.135, min_samples=2))
    assert len(ports) == 2
    # numbered by decreasing calls: A has 12 calls (3 vessels x 4), B 8.
    a, b = ports.iloc[0], ports.iloc[1]
    assert (a["port_id"], a["n_calls"], a["n_vessels"]) == (1, 12, 3)
    assert (b["port_id"], b["n_calls"], b["n_vessels"]) == (2, 8, 2)
    # centroid within 3 sigma / sqrt(n) of the true place (sigma 0.02 nmi)
    assert flat_dist_nmi(a["lat_deg"], a["lon_deg"], *A) < 3 * 0.02 * math.sqrt(2) / math.sqrt(12) + 1e-3
    assert flat_dist_nmi(b["lat_deg"], b["lon_deg"], *B) < 3 * 0.02 * math.sqrt(2) / math.sqrt(8) + 1e-3
    assert list(ports["kind"]) == ["waypoint", "waypoint"] and list(ports["name"]) == ["WP001", "WP002"]
    assert (stop_port[:12] == 1).all() and (stop_port[12:] == 2).all()


def test_port_list_matching_names_ports_and_leaves_waypoints():
    stops = _stops_at([A, B], [3, 2], 4)
    known = pd.DataFrame({"locode": ["XXAAA"], "name": ["Port A"], "country": ["XX"],
                          "lat_deg": [A[0] + 0.003], "lon_deg": [A[1]]})  # listed 0.18 nmi off
    ports, _ = detect_ports(stops, known)
    a = ports.set_index("port_id").loc[1]
    assert a["kind"] == "port" and a["name"] == "Port A" and a["locode"] == "XXAAA"
    assert a["match_dist_nmi"] == pytest.approx(0.18, abs=0.03)
    assert ports.set_index("port_id").loc[2, "kind"] == "waypoint"


def test_berths_of_one_port_merge_and_terminal_radius_keeps_places_apart():
    c1 = A
    c2 = offset(*A, 0.3, 0.0)
    clusters = pd.DataFrame({"lat_deg": [c1[0], c2[0]], "lon_deg": [c1[1], c2[1]]})
    # A port listed as a whole (no radius column): both berth clusters belong to it.
    port = pd.DataFrame({"lat_deg": [A[0]], "lon_deg": [A[1] + 0.001]})
    assert list(match_ports(clusters, port, 2.0)) == [0, 0]
    # A terminal with its own 0.1 nmi radius: only the cluster at it.
    terminal = port.assign(radius_nmi=0.1)
    assert list(match_ports(clusters, terminal, 2.0)) == [0, -1]
    # Two listed places 0.3 nmi apart: each cluster goes to the nearest.
    two = pd.DataFrame({"lat_deg": [c2[0], c1[0]], "lon_deg": [c2[1], c1[1]]})
    assert list(match_ports(clusters, two, 2.0)) == [1, 0]
    # Nothing listed within the radius: no match.
    far = pd.DataFrame({"lat_deg": [A[0] + 0.1], "lon_deg": [A[1]]})
    assert list(match_ports(clusters, far, 2.0)) == [-1, -1]


def test_detect_ports_merges_berths_into_the_listed_port():
    berth2 = offset(*A, 0.4, 0.0)
    stops = _stops_at([A, berth2, B], [2, 2, 2], 3, jitter_nmi=0.01)
    known = pd.DataFrame({"locode": ["XXAAA"], "name": ["Port A"], "lat_deg": [A[0]], "lon_deg": [A[1] + 0.003]})
    ports, stop_port = detect_ports(stops, known)
    assert len(ports) == 2
    a = ports.iloc[0]
    assert (a["name"], a["n_calls"], a["n_vessels"], a["n_clusters"]) == ("Port A", 12, 4, 2)
    # merged centroid halfway between the two berths, radius about half their distance
    mid = offset(*A, 0.2, 0.0)
    assert flat_dist_nmi(a["lat_deg"], a["lon_deg"], *mid) < 0.02
    assert a["radius_nmi"] == pytest.approx(0.2, abs=0.04)
    assert (stop_port[:12] == a["port_id"]).all() and (stop_port[12:] == ports.iloc[1]["port_id"]).all()


def test_min_vessels_turns_single_vessel_clusters_into_noise():
    stops = _stops_at([A, B], [3, 1], 4)
    labels = cluster_stops(stops, PortParams(min_vessels=2))
    assert (labels[:12] >= 0).all() and (labels[12:] == -1).all()


def _berth_stops(seed: int) -> pd.DataFrame:
    """Stops at berths spread round the globe (the equator, 55 N, 70 N, 60 S, both sides of the
    antimeridian), each berth's stops scattered over tens to hundreds of metres, plus lone stops."""
    from thresholds.geodesy import destination_point

    rng = np.random.default_rng(seed)
    places = [(0.0, 10.0), (55.7, 12.6), (70.6, 23.7), (-60.0, -45.0), (51.0, 179.998), (51.0, -179.998), (0.1, 10.0)]
    lat, lon = [], []
    for la, lo in places:
        for _ in range(rng.integers(2, 6)):  # berths of the place
            b = destination_point(la, lo, rng.uniform(0, 360), rng.uniform(0.0, 0.6))
            n = int(rng.integers(1, 120))
            spread = rng.uniform(0.01, 0.12)
            p = destination_point(np.full(n, b[0]), np.full(n, b[1]), rng.uniform(0, 360, n),
                                  np.abs(rng.normal(0.0, spread, n)))
            lat += list(np.atleast_1d(p[0]))
            lon += list((np.atleast_1d(p[1]) + 180.0) % 360.0 - 180.0)
    return pd.DataFrame({"lat_deg": lat, "lon_deg": lon, "track": np.arange(len(lat))})


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("min_samples", [1, 2, 5])
def test_stop_clusters_are_scikit_learns_haversine_dbscan(seed, min_samples):
    # cluster_stops runs the grid DBSCAN on the chords between unit vectors: the same labels as
    # scikit-learn's DBSCAN on the haversine metric (ball tree), at any latitude and across the
    # antimeridian, where a plane projection would not give them.
    from sklearn.cluster import DBSCAN

    from thresholds.units import EARTH_RADIUS_NMI

    stops = _berth_stops(seed)
    params = PortParams(min_samples=min_samples)
    want = DBSCAN(eps=params.eps_nmi / EARTH_RADIUS_NMI, min_samples=min_samples, metric="haversine",
                  algorithm="ball_tree").fit(np.deg2rad(stops[["lat_deg", "lon_deg"]].to_numpy())).labels_
    got = cluster_stops(stops, params)
    assert len(stops) > 200 and (want >= 0).sum() > 100 and len(set(want)) > 10
    np.testing.assert_array_equal(got, want)
    # a berth across the antimeridian is one cluster
    east, west = stops["lon_deg"] > 179.9, stops["lon_deg"] < -179.9
    assert east.any() and west.any() and set(got[east.to_numpy()]) & set(got[west.to_numpy()]) - {-1}
