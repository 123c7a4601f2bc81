"""Voyage segmentation (with the gap rule), resampling and jump removal on hand-built tracks."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from lanes.interpolate import ResampleParams, drop_position_jumps, resample_voyages
from lanes.ports import PortParams, detect_ports
from lanes.stops import detect_stops, sort_track_points
from lanes.voyages import VoyageParams, could_call, segment_voyages
from lanes_tracks import T0, Itinerary, flat_dist_nmi, shuttle

A = (41.30, 2.20)
B = (41.30, 2.60)  # 0.4 deg of longitude east: 18.02 nmi at 41.3 N


def _chain(df, places=None, vparams=None):
    pts = sort_track_points(df)
    stops = detect_stops(pts)
    ports, stop_port = detect_ports(stops, None, PortParams(min_samples=1))  # single calls count here
    if places is None:
        places = ports[["lat_deg", "lon_deg"]]
    return pts, ports, segment_voyages(pts, stops, stop_port, places, vparams)


def test_shuttle_gives_alternating_port_to_port_voyages():
    df = pd.concat([shuttle(1, A, B, 4), shuttle(2, B, A, 3, seed=2)], ignore_index=True)
    pts, ports, v = _chain(df)
    assert len(ports) == 2
    pid = {round(r.lon_deg, 1): r.port_id for r in ports.itertuples()}
    a, b = pid[A[1]], pid[B[1]]
    v1 = v[v["track"] == 1]
    assert list(zip(v1["origin_port_id"], v1["dest_port_id"])) == [(a, b), (b, a), (a, b), (b, a)]
    assert set(v1["kind"]) == {"port_to_port"}
    v2 = v[v["track"] == 2]
    assert list(zip(v2["origin_port_id"], v2["dest_port_id"])) == [(b, a), (a, b), (b, a)]
    # Distance sailed: a straight 18.02 nmi leg (flat-earth reference) plus berth jitter.
    expected = flat_dist_nmi(*A, *B)
    assert expected == pytest.approx(60 * 0.4 * math.cos(math.radians(41.3)), rel=1e-6)
    assert np.allclose(v1["dist_nmi"], expected, rtol=0.01)
    # Departure = last fix of the first stay (40 fixes at 60 s -> T0 + 39 min).
    assert v1.iloc[0]["depart_utc"] == T0 + pd.Timedelta(minutes=39)
    assert list(v1["voyage_id"]) == ["1_0", "1_1", "1_2", "1_3"]


def test_track_starting_at_sea_and_transit_track():
    it = Itinerary(7, cadence_s=60)
    it.pos = (41.0, 2.0)
    it.sail(*A, 12.0).stay(*A, 30)
    lone = Itinerary(8, cadence_s=60)
    lone.pos = (40.5, 2.0)
    lone.sail(40.5, 2.5, 12.0)
    df = pd.concat([it.frame(), lone.frame()], ignore_index=True)
    pts, ports, v = _chain(df, places=pd.DataFrame({"lat_deg": [A[0]], "lon_deg": [A[1]]}))
    kinds = dict(zip(v["track"], v["kind"]))
    assert kinds == {7: "arrival", 8: "transit"}


def _gap_voyage(silence_min, far_from_port=True):
    """A -> B with a mid-voyage silence; optionally a third port C near the gap."""
    it = Itinerary(9, cadence_s=60).stay(*A, 30)
    mid = (A[0], (A[1] + B[1]) / 2)
    it.sail(*mid, 12.0)
    it.silence(silence_min)
    it.sail(*B, 12.0).stay(*B, 30)
    return it.frame()


def test_gap_splits_only_when_a_call_would_have_fitted():
    # 3 h silence mid-way, the only places are A and B (9 nmi away): a call at A and back needs
    # 9/(12*1.2) * 2 h + 0.5 h = 1.75 h < 3 h, so even this gap *could* hide a call -> split.
    df = _gap_voyage(180)
    places = pd.DataFrame({"lat_deg": [A[0], B[0]], "lon_deg": [A[1], B[1]]})
    _, _, v = _chain(df, places=places)
    assert list(v["kind"]) == ["departure", "arrival"]
    # 40 min silence: 1.75 h needed > 0.67 h -> one port-to-port voyage across the gap.
    _, _, v = _chain(_gap_voyage(40), places=places)
    assert list(v["kind"]) == ["port_to_port"] and v.iloc[0]["max_gap_s"] >= 40 * 60
    # 3 h silence but the only known places are far away (200 nmi): no split.
    far = pd.DataFrame({"lat_deg": [44.0, 38.0], "lon_deg": [2.4, 2.4]})
    pts = sort_track_points(df)
    stops = detect_stops(pts)
    ports, stop_port = detect_ports(stops, None, PortParams(min_samples=1))
    v = segment_voyages(pts, stops, stop_port, far)
    assert list(v["kind"]) == ["port_to_port"]


def test_could_call_formula():
    # Place 10 nmi off both ends, 20 kn: 1 h sailing + 0.5 h call = 1.5 h.
    ok = could_call(np.array([0.0, 0.0]), np.array([0.0, 0.0]), np.array([0.0, 0.0]), np.array([0.0, 0.0]),
                    np.array([1.4 * 3600, 1.6 * 3600]), np.array([20.0, 20.0]), [10 / 60], [0.0], 1800.0)
    assert list(ok) == [False, True]


def test_voyage_params_validation():
    with pytest.raises(ValueError):
        VoyageParams(min_fixes=1)


def test_resampling_on_a_meridian_at_constant_speed():
    # Due north at 12 kn, fixes every 97 s: resampled every 300 s, 1 nmi per 300 s.
    n = 200
    t = T0 + pd.to_timedelta(np.arange(n) * 97, unit="s")
    lat = 40.0 + np.arange(n) * 97 / 3600 * 12 / 60
    df = pd.DataFrame({"mmsi": 1, "time_utc": t, "lat_deg": lat, "lon_deg": 3.0, "sog_kn": 12.0})
    voy = pd.DataFrame({"voyage_id": ["1_0"], "track": [1], "origin_port_id": [0], "dest_port_id": [0],
                        "first_row": [0], "last_row": [n - 1]})
    pts = resample_voyages(df, voy, ResampleParams(step_s=300, course_window_s=600))
    k = np.arange(len(pts))
    assert len(pts) == (n - 1) * 97 // 300 + 1
    assert np.allclose(pts["lat_deg"], 40.0 + k * 300 / 3600 * 12 / 60, atol=1e-9)
    assert np.allclose(pts["lon_deg"], 3.0)
    assert np.allclose(pts["speed_kn"], 12.0, rtol=2e-3)  # haversine vs 60 nmi per degree
    assert np.allclose(pts["course_deg"] % 360, 0.0, atol=1e-6)
    assert (pts["time_utc"].diff().dropna() == pd.Timedelta(seconds=300)).all()
    assert pts["along_nmi"].iloc[-1] == pytest.approx((len(pts) - 1) * 1.0, rel=2e-3)


def test_resampling_leaves_long_gaps_empty():
    t = np.r_[np.arange(0, 3600, 60), np.arange(3 * 3600, 4 * 3600, 60)]
    df = pd.DataFrame({"mmsi": 1, "time_utc": T0 + pd.to_timedelta(t, unit="s"),
                       "lat_deg": 40.0 + t / 3600 * 0.2, "lon_deg": 3.0, "sog_kn": 12.0})
    voy = pd.DataFrame({"voyage_id": ["1_0"], "track": [1], "origin_port_id": [0], "dest_port_id": [0],
                        "first_row": [0], "last_row": [len(t) - 1]})
    pts = resample_voyages(df, voy, ResampleParams(step_s=300, max_gap_s=1800))
    secs = (pts["time_utc"] - T0).dt.total_seconds().to_numpy()
    assert not ((secs > 3540) & (secs < 3 * 3600)).any()
    assert sorted(pts["run"].unique()) == [0, 1]


def test_jump_filter_drops_outliers_and_stale_fixes_only():
    n = 120
    t = T0 + pd.to_timedelta(np.arange(n) * 10, unit="s")
    lat = 48.0 + np.arange(n) * 10 / 3600 * 12 / 60
    df = pd.DataFrame({"mmsi": 1, "time_utc": t, "lat_deg": lat, "lon_deg": -5.0})
    df.loc[30, ["lat_deg", "lon_deg"]] = [76.96, -85.7]  # far-away fix
    df.loc[60:65, "lon_deg"] = -3.0  # a run of 6 bogus fixes 80 nmi east
    df.loc[90, "lat_deg"] = df.loc[40, "lat_deg"]  # stale position repeated 500 s later (1.7 nmi behind)
    kept, dropped = drop_position_jumps(df, 50.0)
    assert dropped == 8
    assert set(range(n)) - set(np.flatnonzero(df["time_utc"].isin(kept["time_utc"]))) == {30, 60, 61, 62, 63, 64, 65, 90}
    clean = df.drop(index=[30, 60, 61, 62, 63, 64, 65, 90])
    assert drop_position_jumps(clean, 50.0)[1] == 0
