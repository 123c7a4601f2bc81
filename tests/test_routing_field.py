"""Weather onto the routing mesh: bilinear over sea points, land NaNs, regular time axis, directions."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from routing.errors import WeatherCoverageError
from routing.field import WeatherField
from routing.planner import sample_weather
from routing.mesh import MeshGrid, build_mesh

T0 = pd.Timestamp("2020-01-20T00:00Z").value
H = 3_600_000_000_000


def field(hs, hours=(0,), lat=(40.0, 40.5, 41.0), lon=(2.0, 2.5, 3.0), wave_from=None):
    hs = np.asarray(hs, dtype=float)
    variables = {"hs_m": hs}
    if wave_from is not None:
        variables["wave_from_deg"] = np.asarray(wave_from, dtype=float)
    return WeatherField(T0 + np.asarray(hours, dtype=np.int64) * H, np.asarray(lat), np.asarray(lon), variables)


def test_bilinear_is_exact_for_a_linear_field():
    lat = np.array([40.0, 40.5, 41.0])
    lon = np.array([2.0, 2.5, 3.0])
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    f = field((1.0 + 2.0 * (la - 40.0) + 3.0 * (lo - 2.0))[None])
    grid = MeshGrid(40.0, 2.0, 0.1, 0.1, 11, 11)
    mw = f.on_mesh(grid.lat_deg, grid.lon_deg, T0)
    gl, go = np.meshgrid(grid.lat_deg, grid.lon_deg, indexing="ij")
    expected = 1.0 + 2.0 * (gl - 40.0) + 3.0 * (go - 2.0)
    got = mw.wave[0, mw.sea_index.reshape(11, 11), 0]
    np.testing.assert_allclose(got, expected, rtol=1e-6)
    assert mw.weather_sea.all()


def test_land_nans_renormalise_and_mark_weather_land():
    hs = np.full((1, 3, 3), 2.0)
    hs[0, 2, 2] = np.nan  # land at (41.0, 3.0)
    hs[0, 1, 2] = 4.0
    f = field(hs)
    grid = MeshGrid(40.5, 2.5, 0.125, 0.125, 5, 5)
    mw = f.on_mesh(grid.lat_deg, grid.lon_deg, T0)
    # node (40.875, 2.875): weights 1/16 (40.5,2.5), 3/16 (40.5,3.0), 3/16 (41.0,2.5), 9/16 land -> weather land
    assert not mw.weather_sea[3, 3]
    # node (40.75, 2.75): equal weights, land dropped -> (2 + 4 + 2) / 3
    s = mw.sea_index[2 * 5 + 2]
    assert mw.weather_sea[2, 2] and mw.wave[0, s, 0] == pytest.approx(8.0 / 3.0, rel=1e-6)
    # nodes outside the grid by more than half a step have no weather
    grid2 = MeshGrid(39.0, 2.0, 0.5, 0.5, 5, 3)
    mw2 = f.on_mesh(grid2.lat_deg, grid2.lon_deg, T0)
    assert not mw2.weather_sea[0].any() and mw2.weather_sea[2:].any()


def test_time_axis_regularised_and_directions_through_components():
    hs = np.zeros((3, 3, 3))
    hs[1], hs[2] = 3.0, 4.0
    wave_from = np.zeros((3, 3, 3))
    wave_from[0], wave_from[1], wave_from[2] = 350.0, 10.0, 10.0
    f = field(hs, hours=(0, 3, 4), wave_from=wave_from)
    grid = MeshGrid(40.0, 2.0, 0.5, 0.5, 3, 3)
    mw = f.on_mesh(grid.lat_deg, grid.lon_deg, T0 + H // 2)
    assert mw.dt_h == 1.0 and mw.n_times == 5 and mw.time0_ns == T0
    np.testing.assert_allclose(mw.wave[:, 0, 0], [0.0, 1.0, 2.0, 3.0, 4.0], rtol=1e-6)
    mesh = build_mesh(grid, weather_sea=mw.weather_sea)
    # halfway between 350 and 10 degrees at 1.5 h: 0 degrees (a raw-angle average would give 180)
    w = sample_weather(mesh, mw, [40.5], [2.5], [1.5])
    assert w["wave_from_deg"][0] % 360.0 == pytest.approx(0.0, abs=1e-4) or w["wave_from_deg"][0] == pytest.approx(360.0, abs=1e-4)
    assert w["hs_m"][0] == pytest.approx(1.5, rel=1e-6)
    with pytest.raises(WeatherCoverageError, match="outside the weather's times"):
        f.on_mesh(grid.lat_deg, grid.lon_deg, T0 - H)


def test_weather_field_validation():
    with pytest.raises(ValueError, match="strictly increasing"):
        WeatherField(np.array([T0, T0]), np.array([0.0, 1.0]), np.array([0.0, 1.0]), {})
    with pytest.raises(ValueError, match="unknown variable"):
        WeatherField(np.array([T0]), np.array([0.0, 1.0]), np.array([0.0, 1.0]), {"VHM0": np.zeros((1, 2, 2))})
    with pytest.raises(ValueError, match="shape"):
        WeatherField(np.array([T0]), np.array([0.0, 1.0]), np.array([0.0, 1.0]), {"hs_m": np.zeros((1, 3, 2))})
