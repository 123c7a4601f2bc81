"""Lane extraction (DBSCAN on position and motion) on hand-built traffic with known lanes."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from lanes.chain import ChainParams, build_lanes
from lanes.extract import (
    LaneParams,
    extract_lanes,
    extract_lanes_for_pair,
    merge_shared_voyage_clusters,
    motion_features,
    partition_key,
)
from lanes_tracks import T0, Itinerary, flat_dist_nmi, offset, shuttle, transit

A = (41.30, 2.20)
B = (41.30, 2.60)


def _angle_diff(a, b):
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.fixture(scope="module")
def two_port_traffic():
    """3 ferries shuttling A <-> B (18 nmi) at 12 kn, lateral offsets -0.2/0/+0.2 nmi, 4 legs each."""
    frames = [shuttle(10 + i, A if i % 2 == 0 else B, B if i % 2 == 0 else A, 4, lateral_nmi=off, seed=i,
                      start=T0 + pd.Timedelta(minutes=17 * i))
              for i, off in enumerate((-0.2, 0.0, 0.2))]
    df = pd.concat(frames, ignore_index=True)
    return build_lanes(df)


def test_two_ports_one_lane_per_direction(two_port_traffic):
    r = two_port_traffic
    assert r.summary["ports"] == 2 and r.summary["voyages"] == 12
    lanes = r.lanes.lanes
    assert len(lanes) == 2
    by_pair = {(o, d): row for o, d, row in zip(lanes["origin_port_id"], lanes["dest_port_id"], lanes.itertuples())}
    ports = r.ports.set_index("port_id")
    west = int(ports["lon_deg"].idxmin())
    east = int(ports["lon_deg"].idxmax())
    eastbound, westbound = by_pair[(west, east)], by_pair[(east, west)]
    assert eastbound.n_voyages == 6 and westbound.n_voyages == 6 and eastbound.n_vessels == 3
    # Great-circle course from A to B is 90 deg - 0.13 deg (flat-earth 90); mean within 1 deg.
    assert _angle_diff(eastbound.mean_course_deg, 90.0) < 1.0
    assert _angle_diff(westbound.mean_course_deg, 270.0) < 1.0
    assert _angle_diff(eastbound.mean_course_deg, westbound.mean_course_deg) == pytest.approx(180.0, abs=1.0)
    # The noise is counted, and every resampled point is either in a lane or noise.
    assert r.lanes.n_noise + int(lanes["n_points"].sum()) == r.summary["resampled_points"]


def test_centroids_follow_the_route_in_sailing_order(two_port_traffic):
    r = two_port_traffic
    c = r.lanes.centroids
    lanes = r.lanes.lanes.set_index("lane_id")
    for lane_id, g in c.groupby("lane_id"):
        g = g.sort_values("seq")
        assert list(g["seq"]) == list(range(len(g)))
        # within 0.3 nmi of the straight line between the ports (lat 41.30)
        assert np.all(np.abs(g["lat_deg"] - A[0]) * 60 < 0.3)
        lon = g["lon_deg"].to_numpy()
        if _angle_diff(lanes.loc[lane_id, "mean_course_deg"], 90) < 45:
            assert np.all(np.diff(lon) > 0)
        else:
            assert np.all(np.diff(lon) < 0)
        # Spacing <= 5 nmi (18 nmi lane -> at least 4 centroids), typical speed 12 kn mid-route.
        assert len(g) >= 4
        assert np.median(g["speed_kn"]) == pytest.approx(12.0, abs=0.3)
        assert np.all(np.diff(g["along_nmi"]) > 0)
    # lane length close to the 18 nmi route (centroids cover the sailed part)
    assert lanes["length_nmi"].between(12.0, 18.5).all()


def test_polygon_contains_the_route(two_port_traffic):
    from shapely import wkt

    for poly in two_port_traffic.lanes.lanes["polygon_wkt"]:
        g = wkt.loads(poly)
        assert g.is_valid
        mid = ((A[1] + B[1]) / 2, A[0])
        from shapely.geometry import Point

        assert g.contains(Point(*mid))


def _ushant_like(id_col="track_id"):
    """8 NE-bound tracks and 8 SW-bound tracks on parallel lines 3 nmi apart, plus one crosser."""
    start_ne, end_ne = (48.00, -6.00), (48.40, -5.40)
    start_sw, end_sw = offset(*end_ne, -2.1, 2.1), offset(*start_ne, -2.1, 2.1)  # 3 nmi to the north-west
    frames = []
    for i in range(8):
        lat_off = (i - 3.5) * 0.08
        frames.append(transit(100 + i, start_ne, end_ne, speed_kn=12 + 0.2 * i, lateral_nmi=lat_off,
                              t0=T0 + pd.Timedelta(hours=i), id_col=id_col))
        frames.append(transit(200 + i, start_sw, end_sw, speed_kn=13 - 0.2 * i, lateral_nmi=lat_off,
                              t0=T0 + pd.Timedelta(hours=i, minutes=30), id_col=id_col))
    frames.append(transit(999, (48.35, -6.05), (47.95, -5.35), speed_kn=11, id_col=id_col))  # crosses both
    return pd.concat(frames, ignore_index=True)


def test_opposite_transit_lanes_without_ports():
    r = build_lanes(_ushant_like(), None, ChainParams(id_col="track_id"))
    lanes = r.lanes.lanes
    assert r.summary["ports"] == 0 and set(lanes["kind"]) == {"transit"}
    assert len(lanes) == 2
    a, b = lanes.iloc[0], lanes.iloc[1]
    assert a["n_voyages"] == 8 and b["n_voyages"] == 8
    assert _angle_diff(a["mean_course_deg"], b["mean_course_deg"]) == pytest.approx(180.0, abs=2.0)
    # flat-earth course of the NE line: atan2(0.6 * 60 cos(48.2), 0.4 * 60)
    ne = math.degrees(math.atan2(0.6 * 60 * math.cos(math.radians(48.2)), 0.4 * 60))
    courses = sorted([a["mean_course_deg"], b["mean_course_deg"]])
    assert courses[0] == pytest.approx(ne, abs=1.5)
    # The crossing track is not in any lane: all its points are noise.
    pts = r.points.assign(lane=r.lanes.point_lane)
    assert pts.loc[pts["track"] == 999, "lane"].isna().all()
    # Centroids of each lane stay on their own line (3 nmi apart).
    c = r.lanes.centroids
    for lane_id, g in c.groupby("lane_id"):
        d_ne = [_dist_to_segment(la, lo, (48.00, -6.00), (48.40, -5.40)) for la, lo in zip(g["lat_deg"], g["lon_deg"])]
        assert max(d_ne) < 0.4 or min(d_ne) > 2.5


def _dist_to_segment(lat, lon, p, q):
    """Flat-earth distance from a point to segment pq. [nmi]"""
    c = math.cos(math.radians(lat))
    px, py = (p[1] - lon) * 60 * c, (p[0] - lat) * 60
    qx, qy = (q[1] - lon) * 60 * c, (q[0] - lat) * 60
    dx, dy = qx - px, qy - py
    t = max(0.0, min(1.0, -(px * dx + py * dy) / (dx * dx + dy * dy)))
    return math.hypot(px + t * dx, py + t * dy)


def test_opposite_directions_on_the_same_line_are_two_lanes():
    frames = []
    for i in range(5):
        frames.append(transit(300 + i, (40.0, 3.0), (40.0, 3.4), lateral_nmi=0.05 * i, t0=T0 + pd.Timedelta(hours=i, seconds=53 * i)))
        frames.append(transit(400 + i, (40.0, 3.4), (40.0, 3.0), lateral_nmi=-0.05 * i, t0=T0 + pd.Timedelta(hours=i, seconds=53 * i)))
    r = build_lanes(pd.concat(frames, ignore_index=True))
    assert len(r.lanes.lanes) == 2
    c = sorted(r.lanes.lanes["mean_course_deg"])
    assert _angle_diff(c[0], 90) < 1 and _angle_diff(c[1], 270) < 1


def test_course_is_circular_northbound_lane_is_one_lane():
    # Courses just either side of north (359.4 and 0.6 deg) belong to one lane.
    frames = [transit(500 + i, (40.0, 3.0 + 0.004 * (i % 2)), (40.4, 3.004 - 0.004 * (i % 2)),
                      t0=T0 + pd.Timedelta(hours=i, seconds=53 * i)) for i in range(8)]
    r = build_lanes(pd.concat(frames, ignore_index=True))
    assert len(r.lanes.lanes) == 1
    assert r.lanes.lanes.iloc[0]["n_voyages"] == 8
    assert _angle_diff(r.lanes.lanes.iloc[0]["mean_course_deg"], 0.0) < 1.0


def test_speed_separates_lanes_on_the_same_path():
    frames = [transit(600 + i, (40.0, 3.0), (40.0, 3.5), speed_kn=8.0, lateral_nmi=0.05 * i, t0=T0 + pd.Timedelta(hours=i, seconds=53 * i))
              for i in range(5)]
    frames += [transit(700 + i, (40.0, 3.0), (40.0, 3.5), speed_kn=18.0, lateral_nmi=0.05 * i, t0=T0 + pd.Timedelta(hours=i, seconds=53 * i))
               for i in range(5)]
    r = build_lanes(pd.concat(frames, ignore_index=True))
    speeds = sorted(r.lanes.lanes["mean_speed_kn"])
    assert len(speeds) == 2
    assert speeds[0] == pytest.approx(8.0, abs=0.2) and speeds[1] == pytest.approx(18.0, abs=0.3)


def test_lane_follows_a_bend():
    # A -> corner -> C with a 60 deg turn at the corner: one lane, centroids along the L in order.
    corner = offset(*A, 10.0, 0.0)
    c_end = offset(*corner, 10.0 * math.cos(math.radians(60)), -10.0 * math.sin(math.radians(60)))
    frames = []
    for i in range(6):
        it = Itinerary(800 + i, start=T0 + pd.Timedelta(hours=3 * i, seconds=71 * i), cadence_s=60)
        it.pos = A
        it.sail(*corner, 12.0, lateral_nmi=0.05 * i).sail(*c_end, 12.0, lateral_nmi=0.05 * i)
        frames.append(it.frame())
    r = build_lanes(pd.concat(frames, ignore_index=True))
    assert len(r.lanes.lanes) == 1
    g = r.lanes.centroids.sort_values("seq")
    assert flat_dist_nmi(g.iloc[0]["lat_deg"], g.iloc[0]["lon_deg"], *A) < 3.0
    assert flat_dist_nmi(g.iloc[-1]["lat_deg"], g.iloc[-1]["lon_deg"], *c_end) < 3.0
    assert np.all(np.diff(g["along_nmi"]) > 0)
    # The corner is passed in the middle of the sequence, not skipped.
    d_corner = [flat_dist_nmi(a, b, *corner) for a, b in zip(g["lat_deg"], g["lon_deg"])]
    assert min(d_corner) < 2.0


def test_partitioned_run_equals_whole_run(two_port_traffic):
    pts = pd.concat([two_port_traffic.points,
                     build_lanes(_ushant_like("mmsi")).points], ignore_index=True)
    params = LaneParams()
    whole = extract_lanes(pts, params)
    parts_lanes, parts_cents = [], []
    keys = sorted({partition_key(o, d) for o, d in zip(pts["origin_port_id"], pts["dest_port_id"])})
    for key in keys:
        m = [partition_key(o, d) == key for o, d in zip(pts["origin_port_id"], pts["dest_port_id"])]
        # shuffled rows: the result must not depend on the order either
        part = pts[m].sample(frac=1.0, random_state=3)
        res = extract_lanes_for_pair(part, params, key)
        parts_lanes.append(res.lanes)
        parts_cents.append(res.centroids)
    pd.testing.assert_frame_equal(whole.lanes, pd.concat(parts_lanes, ignore_index=True), check_dtype=False)
    pd.testing.assert_frame_equal(whole.centroids, pd.concat(parts_cents, ignore_index=True), check_dtype=False)


def test_sampled_dbscan_is_deterministic_and_finds_the_same_lanes(two_port_traffic):
    pts = two_port_traffic.points
    full = extract_lanes(pts, LaneParams())
    small = LaneParams(max_points=100)
    s1 = extract_lanes(pts, small)
    s2 = extract_lanes(pts, small)
    assert s1.n_sampled_partitions >= 1
    pd.testing.assert_frame_equal(s1.lanes, s2.lanes)
    assert len(s1.lanes) == len(full.lanes) == 2
    assert np.all(np.abs(s1.centroids["lat_deg"] - A[0]) * 60 < 0.4)


def test_motion_features_metric():
    p = LaneParams(eps_nmi=2.0, eps_speed_kn=4.0, eps_course_deg=30.0)
    f = motion_features(np.array([40.0, 40.0, 40.0, 40.0 + 2.0 / 60]), np.array([3.0, 3.0, 3.0, 3.0]),
                        np.array([10.0, 14.0, 10.0, 10.0]), np.array([359.0, 359.0, 29.0, 359.0]), p)
    d = lambda i, j: float(np.linalg.norm(f[i] - f[j]))  # noqa: E731
    assert d(0, 1) == pytest.approx(1.0)  # speed difference = eps
    assert d(0, 2) == pytest.approx(1.0)  # course difference = eps across north
    assert d(0, 3) == pytest.approx(2.0 / 60 * math.pi / 180 * 6371008.8 / 1852 / 2.0, rel=1e-6)


def test_lane_params_validation():
    for bad in ({"eps_nmi": 0}, {"eps_course_deg": 180}, {"max_points": 10}, {"width_quantile": 0}, {"min_voyages": 0}):
        with pytest.raises(ValueError):
            LaneParams(**bad)


def test_empty_input():
    r = extract_lanes(pd.DataFrame({c: [] for c in ("voyage", "track", "origin_port_id", "dest_port_id", "time_utc",
                                                      "lat_deg", "lon_deg", "speed_kn", "course_deg", "run")}))
    assert len(r.lanes) == 0 and r.n_noise == 0


def _harbour_route(mmsi, start, a, a_out, b_in, b, lateral_nmi):
    """A -> B and back: 3 nmi of harbour approach at 7 kn at each end, 30 nmi of sea at 18 kn."""
    it = Itinerary(mmsi, start=start, cadence_s=60)
    it.stay(*a, 40, jitter_nmi=0.005)
    it.sail(*a_out, 7.0, lateral_nmi=lateral_nmi).sail(*b_in, 18.0, lateral_nmi=lateral_nmi).sail(*b, 7.0, lateral_nmi=lateral_nmi)
    it.stay(*b, 40, jitter_nmi=0.005)
    it.sail(*b_in, 7.0, lateral_nmi=lateral_nmi).sail(*a_out, 18.0, lateral_nmi=lateral_nmi).sail(*a, 7.0, lateral_nmi=lateral_nmi)
    it.stay(*a, 40, jitter_nmi=0.005)
    return it.frame()


def test_harbour_approaches_are_part_of_the_lane_not_lanes_of_their_own():
    # The slow approaches differ from the sea passage by 11 kn (> eps_speed_kn) and 30 deg, so
    # DBSCAN clusters them apart; they are the same voyages, so they end up in the one lane.
    a = (41.0, 3.0)
    a_out = offset(*a, 3.0 * math.cos(math.radians(30)), 3.0 * math.sin(math.radians(30)))  # course 60
    b_in = offset(*a_out, 30.0, 0.0)                                                           # course 90
    b = offset(*b_in, 3.0 * math.cos(math.radians(30)), -3.0 * math.sin(math.radians(30)))  # course 120
    frames = [_harbour_route(900 + i, T0 + pd.Timedelta(minutes=23 * i), a, a_out, b_in, b, 0.05 * i) for i in range(5)]
    r = build_lanes(pd.concat(frames, ignore_index=True))
    assert r.summary["ports"] == 2 and r.summary["voyages"] == 10
    lanes = r.lanes.lanes
    assert len(lanes) == 2 and set(lanes["n_voyages"]) == {5}
    for lane_id, g in r.lanes.centroids.groupby("lane_id"):
        g = g.sort_values("seq")
        ends = [(g.iloc[0]["lat_deg"], g.iloc[0]["lon_deg"]), (g.iloc[-1]["lat_deg"], g.iloc[-1]["lon_deg"])]
        # the centroid sequence runs berth to berth: the end centroids are the medians of the first
        # and last 5 nmi bins (centroid_spacing_nmi), within half a bin of the ports; the sea
        # passage alone starts 3 nmi + half a bin out ...
        assert min(flat_dist_nmi(*ends[0], *a), flat_dist_nmi(*ends[0], *b)) < 2.5
        assert min(flat_dist_nmi(*ends[1], *a), flat_dist_nmi(*ends[1], *b)) < 2.5
        assert flat_dist_nmi(*ends[0], *ends[1]) > 30.0
        # ... with the typical speed of the approach at the ends and of the passage in between
        assert g.iloc[0]["speed_kn"] < 10.0 and g.iloc[-1]["speed_kn"] < 10.0
        assert g["speed_kn"].max() == pytest.approx(18.0, abs=0.5)
    # Without the merge, the approaches are lanes of their own (what the test guards against).
    r_apart = build_lanes(pd.concat(frames, ignore_index=True), params=ChainParams(lanes=LaneParams(merge_voyage_share=0.0)))
    assert len(r_apart.lanes.lanes) > 2


def test_different_voyages_on_the_same_path_between_two_ports_stay_two_lanes():
    # Slow and fast ferries on the same line between the same ports share no voyage: two lanes.
    a = (41.0, 3.0)
    b = offset(*a, 25.0, 0.0)
    frames = [shuttle(950 + i, a, b, 2, speed_kn=8.0 if i < 4 else 18.0, lateral_nmi=0.05 * (i % 4), seed=i,
                      start=T0 + pd.Timedelta(minutes=19 * i)) for i in range(8)]
    r = build_lanes(pd.concat(frames, ignore_index=True))
    lanes = r.lanes.lanes
    eastbound = lanes[lanes["mean_course_deg"].map(lambda c: _angle_diff(c, 90.0) < 10)]
    assert sorted(np.round(eastbound["mean_speed_kn"])) == [8.0, 18.0]


def test_merge_shared_voyage_clusters_by_hand():
    # Visiting order: 3 (voyages a, c, e: the most), then 0 and 1 (a, b; 0 has the lower label),
    # then 2 (c, d). At 0.8: 0 shares 1 of 2 voyages with 3 -> kept; 1 shares 2 of 2 with 0 ->
    # merged into 0; 2 shares 1 of 2 with 3, none with 0 -> kept. At 0.5 every half-share counts:
    # 0, 1 and 2 all merge into 3.
    labels = np.array([0, 0, 1, 1, 2, 2, 3, 3, 3, -1])
    voyages = np.array(["a", "b", "a", "b", "c", "d", "a", "c", "e", "a"])
    assert merge_shared_voyage_clusters(labels, voyages, 0.8).tolist() == [0, 0, 0, 0, 2, 2, 3, 3, 3, -1]
    assert merge_shared_voyage_clusters(labels, voyages, 0.5).tolist() == [3, 3, 3, 3, 3, 3, 3, 3, 3, -1]
    assert merge_shared_voyage_clusters(labels, voyages, 1.0).tolist() == [0, 0, 0, 0, 2, 2, 3, 3, 3, -1]


def test_a_loops_outbound_and_return_legs_stay_two_lanes():
    # Excursions from one port and back (a loop voyage): the outbound and return legs are the same
    # voyages but opposite lanes, so the loop partition never merges clusters.
    a = (41.0, 3.0)
    p = offset(*a, 20.0, 0.0)
    frames = []
    for i in range(5):
        it = Itinerary(970 + i, start=T0 + pd.Timedelta(minutes=29 * i), cadence_s=60)
        it.stay(*a, 40, jitter_nmi=0.005)
        for _ in range(2):
            it.sail(*p, 15.0, lateral_nmi=0.05 * i).sail(*a, 15.0, lateral_nmi=0.05 * i)
            it.stay(*a, 40, jitter_nmi=0.005)
        frames.append(it.frame())
    r = build_lanes(pd.concat(frames, ignore_index=True))
    lanes = r.lanes.lanes
    assert r.summary["ports"] == 1 and set(lanes["kind"]) == {"loop"}
    courses = sorted(lanes["mean_course_deg"])
    assert len(lanes) == 2 and _angle_diff(courses[0], 90.0) < 5.0 and _angle_diff(courses[1], 270.0) < 5.0
