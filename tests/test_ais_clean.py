"""Pure cleaning rules of lanes/clean.py: MMSI, precedence, sentinels, the speed-jump kernel."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lanes import clean as C
from thresholds.geodesy import haversine_nmi


def test_valid_mmsi_bounds():
    # ITU-R M.585: 9 digits, MID 201..775 for ship stations.
    got = C.valid_mmsi(pd.Series([201000000, 775999999, 200999999, 776000000, 2190067, 992190934, None],
                                 dtype="Int64"))
    assert got.tolist() == [True, True, False, False, False, False, False]


def _stage(**cols):
    n = len(next(iter(cols.values())))
    st_ = C.empty_stage(n)
    for k, v in cols.items():
        st_[k] = pd.Series(v, dtype=st_[k].dtype)
    return st_


def test_rule_precedence_and_sentinels():
    t = pd.Timestamp("2025-01-01T00:00:00Z")
    st_ = _stage(
        mmsi=[219000001, 1, 219000001, 219000001, 219000001, 219000001, 219000001, 219000002],
        time_utc=[t, t, pd.NaT, t + pd.Timedelta("1min"), t + pd.Timedelta("2min"), t + pd.Timedelta("3min"),
                  t + pd.Timedelta("4min"), t + pd.Timedelta("5min")],
        lat_deg=[55.0, 55.0, 55.0, 91.0, 95.0, 55.0, 55.0, 55.0],
        lon_deg=[11.0, 11.0, 11.0, 181.0, 11.0, 11.0, 11.0, 180.0],
        sog_kn=[10.0, 10.0, 10.0, 10.0, 10.0, 102.3, -0.1, 102.2],
        cog_deg=[90.0, 90.0, 90.0, 90.0, 90.0, 360.0, 90.0, 360.0],
        heading_deg=[90.0, 90.0, 90.0, 90.0, 90.0, 511.0, 90.0, 359.0],
        parse_error=[C.BAD_LINE, None, None, C.BAD_SOG, None, None, None, None],
    )
    reasons = C.row_reasons(st_)
    # A record code beats everything; bad MMSI beats a bad time; a field parse error beats the
    # position sentinel; range checks after that.
    assert reasons.tolist() == [C.BAD_LINE, C.BAD_MMSI, C.BAD_TIME, C.BAD_SOG, C.BAD_LAT, None, C.BAD_SOG, None]
    out = C.clean_positions(st_)
    loaded = out.positions
    assert len(loaded) == 2
    r5 = loaded.iloc[0]  # sorted by mmsi: row 5, then row 7 (another vessel on the antimeridian)
    assert np.isnan(r5.sog_kn) and np.isnan(r5.cog_deg) and np.isnan(r5.heading_deg)
    r7 = loaded.iloc[1]
    assert np.isnan(r7.sog_kn) and np.isnan(r7.cog_deg) and r7.heading_deg == 359.0 and r7.lon_deg == -180.0


def test_static_rows_are_not_position_reads():
    t = pd.Timestamp("2025-01-01T00:00:00Z")
    st_ = _stage(mmsi=[219000001, 219000001], time_utc=[t, pd.NaT], lat_deg=[55.0, np.nan], lon_deg=[11.0, np.nan],
                 kind=[C.KIND_POSITION, C.KIND_STATIC], name=[None, "ALPHA"], ship_type=[pd.NA, 70])
    out = C.clean_positions(st_)
    assert out.counts["read"] == 1 and out.counts["static"] == 1 and out.counts["loaded"] == 1
    assert out.vessels.iloc[0]["name"] == "ALPHA" and out.vessels.iloc[0]["ship_type"] == 70


def _track(lats, step_s=60.0, lon=0.0, mmsi=1):
    n = len(lats)
    return np.full(n, mmsi), np.arange(n) * step_s, np.asarray(lats, dtype=float), np.full(n, lon)


# One minute at 10 kn is 1/6 nmi = 1/360 deg of latitude.
D = 1.0 / 360.0


def test_spike_in_the_middle_is_removed():
    m, t, lat, lon = _track([50.0, 50 + D, 51.0, 50 + 3 * D, 50 + 4 * D])
    assert C.speed_jump_mask(m, t, lat, lon).tolist() == [False, False, True, False, False]


def test_bad_first_and_last_fix_are_removed():
    m, t, lat, lon = _track([49.0, 50.0, 50 + D, 50 + 2 * D, 52.0])
    assert C.speed_jump_mask(m, t, lat, lon).tolist() == [True, False, False, False, True]


def test_second_transmitter_with_the_same_mmsi_is_removed():
    # Ship A sails north at 10 kn from 50N; "ship B" with the same MMSI sits at 10N.
    lats = []
    for i in range(6):
        lats += [50 + i * D, 10.0]
    m, t, lat, lon = _track(lats, step_s=30.0)
    mask = C.speed_jump_mask(m, t, lat, lon)
    assert mask.tolist() == [False, True] * 6


def test_larger_segment_wins_a_step():
    m, t, lat, lon = _track([50.0, 50 + D, 55.0, 55 + D, 55 + 2 * D])
    assert C.speed_jump_mask(m, t, lat, lon).tolist() == [True, True, False, False, False]


def test_two_fix_track_keeps_the_earlier_fix():
    m, t, lat, lon = _track([50.0, 51.0])
    assert C.speed_jump_mask(m, t, lat, lon).tolist() == [False, True]


def test_stored_fixes_are_context_and_never_flagged():
    # The stored fix (index 0) anchors the track: the new fixes far from it are the outliers,
    # even though they are consistent among themselves and more numerous.
    m, t, lat, lon = _track([50.0, 55.0, 55 + D, 55 + 2 * D])
    fixed = np.array([True, False, False, False])
    assert C.speed_jump_mask(m, t, lat, lon, fixed=fixed).tolist() == [False, True, True, True]
    fixed2 = np.array([False, True, False, False])
    assert C.speed_jump_mask(m, t, lat, lon, fixed=fixed2).tolist() == [True, False, False, False]


def test_limit_is_a_parameter():
    # 0.005 deg of latitude per minute = 18 kn.
    m, t, lat, lon = _track([50.0, 50.005, 50.010])
    assert not C.speed_jump_mask(m, t, lat, lon, 60.0).any()
    assert C.speed_jump_mask(m, t, lat, lon, 10.0).sum() == 2


@settings(max_examples=150, deadline=None)
@given(
    n_tracks=st.integers(1, 4),
    data=st.data(),
    limit=st.sampled_from([20.0, 60.0]),
)
def test_no_kept_pair_exceeds_the_limit(n_tracks, data, limit):
    mm, tt, la, lo = [], [], [], []
    for k in range(n_tracks):
        n = data.draw(st.integers(1, 25))
        dts = data.draw(st.lists(st.floats(1.0, 600.0), min_size=n, max_size=n))
        lats = data.draw(st.lists(st.floats(-60.0, 60.0), min_size=n, max_size=n))
        lons = data.draw(st.lists(st.floats(-179.0, 179.0), min_size=n, max_size=n))
        mm += [k] * n
        tt += list(np.cumsum(dts))
        la += lats
        lo += lons
    m, t, lat, lon = map(np.asarray, (mm, tt, la, lo))
    bad = C.speed_jump_mask(m, t, lat, lon, limit)
    keep = ~bad
    km, kt, kla, klo = m[keep], t[keep], lat[keep], lon[keep]
    same = km[1:] == km[:-1]
    d = haversine_nmi(kla[:-1], klo[:-1], kla[1:], klo[1:])
    assert np.all(~same | (d <= limit * (kt[1:] - kt[:-1]) / 3600.0 + 1e-9))
    # Every track keeps at least one fix.
    assert set(km.tolist()) == set(m.tolist())
    # A track without any jump loses nothing.
    for k in np.unique(m):
        sel = m == k
        dd = haversine_nmi(lat[sel][:-1], lon[sel][:-1], lat[sel][1:], lon[sel][1:])
        if np.all(dd <= limit * np.diff(t[sel]) / 3600.0):
            assert not bad[sel].any()


def test_summary_counts_add_up_on_empty_and_all_bad():
    empty = C.clean_positions(C.empty_stage(0))
    assert empty.counts["read"] == 0 and empty.positions.empty
    bad = C.clean_positions(_stage(mmsi=[1, 2], parse_error=[None, None]))
    c = bad.counts
    assert c["read"] == 2 and c["quarantined"] == 2 and c["reasons"] == {C.BAD_MMSI: 2}


@pytest.mark.parametrize("code", sorted(C.REASONS))
def test_every_reason_is_documented(code):
    assert C.REASONS[code]


def test_compiled_link_test_equals_numpy_haversine_on_both_threads():
    # 600 k pairs: the kernel cuts them into two ranges run on two threads; every pair must be
    # judged as the numpy haversine judges it (away from exact ties, a float-rounding matter).
    from lanes._jumps import link_breaks

    rng = np.random.default_rng(3)
    n = 600_001
    track = np.sort(rng.integers(0, 500, n))
    t = np.cumsum(rng.uniform(1.0, 60.0, n))
    lat = rng.uniform(-70.0, 70.0, n)
    lon = rng.uniform(-180.0, 180.0, n)
    lat[1::2] = lat[:-1:2] + rng.normal(0.0, 0.02, n // 2)  # half the pairs near the limit
    lon[1::2] = lon[:-1:2] + rng.normal(0.0, 0.02, n // 2)
    same = track[1:] == track[:-1]
    limit = haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:])
    allowed = 60.0 * (t[1:] - t[:-1]) / 3600.0
    expect = same & (limit > allowed)
    clear = np.abs(limit - allowed) > 1e-9 * np.maximum(allowed, 1.0)
    got = link_breaks(same, t, lat, lon, 60.0)
    assert got.shape == expect.shape
    assert 0 < expect.sum() < len(expect)
    assert np.array_equal(got[clear], expect[clear])
