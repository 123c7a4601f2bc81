"""Point sampling of gridded weather: bilinear in space over sea points, linear in time, no
extrapolation, directions through their components."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from routing.sampling import PointSampler

T0 = pd.Timestamp("2025-01-14T00:00Z")
LAT = np.array([40.0, 40.5, 41.0, 41.5])
LON = np.array([1.0, 1.5, 2.0, 2.5, 3.0])
TIMES = pd.date_range(T0, periods=3, freq="3h")


def linear_field():
    t_h = np.arange(3)[:, None, None] * 3.0
    lat = LAT[None, :, None]
    lon = LON[None, None, :]
    return (1.0 + 0.5 * (lat - 40.0) + 0.25 * (lon - 1.0) + 0.1 * t_h) * np.ones((3, 4, 5))


def sampler(**extra):
    variables = {"hs_m": linear_field(), **extra}
    return PointSampler(TIMES.asi8, LAT, LON, variables)


def test_bilinear_and_linear_in_time_reproduce_a_linear_field():
    s = sampler()
    times = pd.DatetimeIndex([T0 + pd.Timedelta(hours=1.5), T0 + pd.Timedelta(hours=4), T0])
    lat = np.array([40.2, 41.3, 41.5])
    lon = np.array([1.7, 2.9, 3.0])
    out = s(times, lat, lon)["hs_m"]
    expected = 1.0 + 0.5 * (lat - 40.0) + 0.25 * (lon - 1.0) + 0.1 * np.array([1.5, 4.0, 0.0])
    np.testing.assert_allclose(out, expected, rtol=1e-6)


def test_no_extrapolation_in_time_or_space():
    s = sampler()
    out = s(pd.DatetimeIndex([T0 - pd.Timedelta(minutes=1), T0 + pd.Timedelta(hours=6, minutes=1), T0, T0]),
            np.array([40.5, 40.5, 39.0, 40.5]), np.array([2.0, 2.0, 2.0, 3.5]))["hs_m"]
    assert np.isnan(out).all()
    # within half a grid step of the edge the edge value is used
    edge = s(pd.DatetimeIndex([T0]), np.array([41.7]), np.array([3.2]))["hs_m"]
    assert edge[0] == pytest.approx(1.0 + 0.5 * 1.5 + 0.25 * 2.0, rel=1e-6)


def test_land_points_are_skipped_and_mostly_land_is_nan():
    hs = linear_field()
    hs[:, 1, 1] = np.nan  # one land point at (40.5, 1.5)
    hs[:, 2:, 3:] = np.nan  # a land block in the north-east
    s = PointSampler(TIMES.asi8, LAT, LON, {"hs_m": hs})
    # (40.25, 1.25): 3 of 4 corners are sea (weights 0.25 each) -> mean of those three
    v = s(pd.DatetimeIndex([T0]), np.array([40.25]), np.array([1.25]))["hs_m"][0]
    corners = [1.0 + 0.5 * 0.0 + 0.25 * 0.0, 1.0 + 0.5 * 0.0 + 0.25 * 0.5, 1.0 + 0.5 * 0.5 + 0.25 * 0.0]
    assert v == pytest.approx(np.mean(corners), rel=1e-6)
    # (41.2, 2.9): the sea corner carries 0.6 * 0.2 = 0.12 < 0.5 of the weight -> land
    assert np.isnan(s(pd.DatetimeIndex([T0]), np.array([41.2]), np.array([2.9]))["hs_m"][0])


def test_directions_through_components():
    d = np.full((3, 4, 5), 350.0)
    d[:, :, 2:] = 10.0  # 350 deg west of lon 1.75, 10 deg east of it
    s = sampler(wave_from_deg=d)
    mid = s(pd.DatetimeIndex([T0]), np.array([40.5]), np.array([1.75]))["wave_from_deg"][0]
    assert mid == pytest.approx(0.0, abs=1e-4) or mid == pytest.approx(360.0, abs=1e-4)  # not 180
    assert s.grid_slice(0)["wave_from_deg"][0, 0] == pytest.approx(350.0, abs=1e-4)


def test_single_time_field_is_static_and_inputs_checked():
    s = PointSampler(TIMES[:1].asi8, LAT, LON, {"hs_m": linear_field()[:1]})
    out = s(pd.DatetimeIndex([T0 + pd.Timedelta(days=3)]), np.array([40.0]), np.array([1.0]))["hs_m"]
    assert out[0] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="timezone-aware"):
        s(pd.DatetimeIndex(["2025-01-14"]), np.array([40.0]), np.array([1.0]))
    with pytest.raises(ValueError, match="shape"):
        PointSampler(TIMES.asi8, LAT, LON, {"hs_m": np.zeros((3, 4, 4))})
    # one time for many points is broadcast
    many = sampler()(pd.DatetimeIndex([T0]), LAT[:3], LON[:3])["hs_m"]
    assert many.shape == (3,)
