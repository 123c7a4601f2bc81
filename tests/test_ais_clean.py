"""Pure cleaning rules of ais/clean.py: MMSI, precedence, sentinels, the speed-jump kernel."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ais import clean as C
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


# An outlier next to a coverage gap. 10 kn east along 55N: 10 s steps of 0.000484 deg of
# longitude (10 kn x 10 s = 1/36 nmi; 1 deg of longitude at 55N = 60 cos 55 = 34.41 nmi). The
# outlier sits 0.5 deg of latitude (30 nmi) off, 10 s after the last good fix: 10,800 kn from
# it. A 40-minute gap follows it: 30 nmi in 40 min is 45 kn, so the outlier *is* linked to the
# first fix after the gap (at 60 kn), while that fix is 40 min and 0.194 deg (6.7 nmi, 10 kn)
# from the last good fix before the outlier.
def _gap_track(n_before: int, n_after: int, outliers=(0.5,), outlier_first: bool = True):
    step = 0.000484
    t, lat, lon = [], [], []
    for k in range(n_before):
        t.append(10.0 * k), lat.append(55.0), lon.append(10.0 + k * step)
    t0 = 10.0 * n_before
    if outlier_first:
        for j, off in enumerate(outliers):
            t.append(t0 + 10.0 * j), lat.append(55.0 + off), lon.append(10.0 + n_before * step)
        t0 += 10.0 * len(outliers) + 2400.0
    else:
        t0 += 2400.0
        for j, off in enumerate(outliers):
            t.append(t0 + 10.0 * j), lat.append(55.0 + off), lon.append(10.0 + n_before * step + 0.194)
        t0 += 10.0 * len(outliers)
    for k in range(n_after):
        t.append(t0 + 10.0 * k), lat.append(55.0), lon.append(10.0 + n_before * step + 0.194 + k * step)
    n = len(t)
    return np.ones(n, dtype=np.int64), np.asarray(t), np.asarray(lat), np.asarray(lon)


@pytest.mark.parametrize("n_before, n_after", [(200, 120), (100, 120), (1, 120), (120, 1)])
def test_outlier_followed_by_a_gap_is_removed_alone(n_before, n_after):
    # The outlier reaches the fix after the gap; a walk that only compared consecutive fixes
    # chained it to the fixes after the gap and then rejected that whole segment (or, when it
    # was the larger one, kept the outlier and rejected the fixes before it).
    m, t, lat, lon = _gap_track(n_before, n_after)
    bad = C.speed_jump_mask(m, t, lat, lon)
    assert np.flatnonzero(bad).tolist() == [n_before]


def test_outlier_preceded_by_a_gap_is_removed_alone():
    # The mirror case: after the gap the outlier is within reach of the last good fix (30 nmi
    # in 40 min), but the next fix is not within reach of it, while the fix before it is.
    m, t, lat, lon = _gap_track(150, 100, outlier_first=False)
    assert np.flatnonzero(C.speed_jump_mask(m, t, lat, lon)).tolist() == [150]


@pytest.mark.parametrize("burst", [2, 3])
def test_outlier_burst_followed_by_a_gap_is_removed(burst):
    m, t, lat, lon = _gap_track(100, 120, outliers=(0.5,) * burst)
    assert np.flatnonzero(C.speed_jump_mask(m, t, lat, lon)).tolist() == list(range(100, 100 + burst))


def test_a_longer_burst_is_a_segment_judged_as_a_whole():
    # Four fixes off (more than MAX_OUTLIER_RUN) are a segment of their own, chained to the
    # fixes after the gap: the larger part wins as before, here the 100 + 4 after the gap.
    from ais._jumps import MAX_OUTLIER_RUN

    assert MAX_OUTLIER_RUN == 3
    m, t, lat, lon = _gap_track(50, 100, outliers=(0.5,) * 4)
    assert np.flatnonzero(C.speed_jump_mask(m, t, lat, lon)).tolist() == list(range(50))


def test_new_fixes_between_stored_fixes_are_judged_against_both():
    # Stored fixes at 0 and 600 s, 9 nmi apart; new fixes at 60 s, 0.9 nmi behind the first
    # (54 kn from it) and at 540 s, 0.9 nmi past the second (54 kn to it): each is linked to
    # its stored neighbour, but the two are 10.8 nmi apart in 8 min (81 kn) and neither reaches
    # the stored fix on its far side (9.9 nmi in 9 min, 66 kn): both go.
    t = np.array([0.0, 60.0, 540.0, 600.0])
    lat = np.array([55.0, 55 - 0.9 / 60, 55 + 9.9 / 60, 55 + 9 / 60])
    fixed = np.array([True, False, False, True])
    assert C.speed_jump_mask(np.ones(4), t, lat, np.full(4, 11.0), fixed=fixed).tolist() == [False, True, True, False]
    # The first new fix 0.5 nmi north of the first stored one instead (30 kn from it, 8.5 nmi
    # in 9 min = 56.7 kn to the second): it stays, the other (70.5 kn from it) goes.
    lat2 = lat.copy()
    lat2[1] = 55 + 0.5 / 60
    assert C.speed_jump_mask(np.ones(4), t, lat2, np.full(4, 11.0), fixed=fixed).tolist() == [False, False, True, False]


def test_a_stored_fix_is_never_an_outlier_and_can_end_a_burst():
    # new, new (off), stored: the stored fix is within reach of the first: the one between is
    # the outlier. Then new (off), stored out of reach of it and of the fix before: the new
    # one goes, the stored one stays.
    t = np.array([0.0, 60.0, 120.0, 180.0, 240.0])
    lat = np.array([55.0, 56.0, 55 + 2 * D, 57.0, 55 + 4 * D])
    fixed = np.array([False, False, True, False, False])
    assert C.speed_jump_mask(np.ones(5), t, lat, np.zeros(5), fixed=fixed).tolist() == [False, True, False, True, False]


@settings(max_examples=150, deadline=None)
@given(
    n_tracks=st.integers(1, 4),
    data=st.data(),
    limit=st.sampled_from([20.0, 60.0]),
)
def test_no_kept_pair_exceeds_the_limit(n_tracks, data, limit):
    mm, tt, la, lo, fx = [], [], [], [], []
    with_stored = data.draw(st.booleans())
    for k in range(n_tracks):
        n = data.draw(st.integers(1, 25))
        dts = data.draw(st.lists(st.floats(1.0, 600.0), min_size=n, max_size=n))
        # near-track positions as well as wild ones, so that outliers, bursts and gaps all occur
        wild = data.draw(st.lists(st.booleans(), min_size=n, max_size=n))
        lats = data.draw(st.lists(st.floats(-60.0, 60.0), min_size=n, max_size=n))
        lons = data.draw(st.lists(st.floats(-179.0, 179.0), min_size=n, max_size=n))
        t_k = np.cumsum(dts)
        lats = [la_ if w else 40.0 + t_ * 2e-5 for la_, w, t_ in zip(lats, wild, t_k)]
        lons = [lo_ if w else 5.0 for lo_, w in zip(lons, wild)]
        mm += [k] * n
        tt += list(t_k)
        la += lats
        lo += lons
        fx += data.draw(st.lists(st.booleans(), min_size=n, max_size=n)) if with_stored else [False] * n
    m, t, lat, lon, fixed = map(np.asarray, (mm, tt, la, lo, fx))
    bad = C.speed_jump_mask(m, t, lat, lon, limit, fixed=fixed)
    assert not (bad & fixed).any()  # stored fixes are never flagged
    keep = ~bad
    km, kt, kla, klo, kfx = m[keep], t[keep], lat[keep], lon[keep], fixed[keep]
    same = km[1:] == km[:-1]
    d = haversine_nmi(kla[:-1], klo[:-1], kla[1:], klo[1:])
    ok = d <= limit * (kt[1:] - kt[:-1]) / 3600.0 + 1e-9
    # no two consecutive kept fixes of a track exceed the limit, unless both are stored
    assert np.all(~same | ok | (kfx[:-1] & kfx[1:]))
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
    from ais._jumps import link_breaks

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
