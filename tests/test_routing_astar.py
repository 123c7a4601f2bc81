"""Time-dependent A*: hand-computed edge times, A* = Dijkstra, unreachable goals, re-timing, smoothing."""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
import pandas as pd
import pytest

from routing import _kernels
from routing.astar import ShipModel, WeatherArrays, evaluate_path, reachable, search, smooth
from routing.errors import NoRouteError
from routing.field import WeatherField
from routing.mesh import MeshGrid, build_mesh
from routing.speed_loss import SpeedLossValidityWarning, attained_speed_kn
from thresholds.units import EARTH_RADIUS_NMI

T0 = pd.Timestamp("2020-01-20T00:00Z")
NMI_PER_DEG = EARTH_RADIUS_NMI * math.pi / 180.0  # one degree of a great circle [nmi]


def uniform_field(grid: MeshGrid, hs_m, wave_from_deg, hours=(0.0, 24.0), current_ms=None):
    """Weather on the mesh's own grid: Hs per time (list) or constant, one direction."""
    times = T0.value + (np.asarray(hours) * 3.6e12).astype(np.int64)
    shape = (len(hours), grid.ny, grid.nx)
    hs = np.broadcast_to(np.asarray(hs_m, dtype=float).reshape(-1, 1, 1), shape).astype(np.float32)
    variables = {"hs_m": hs, "wave_from_deg": np.full(shape, wave_from_deg, dtype=np.float32)}
    if current_ms is not None:
        variables["current_u_ms"] = np.full(shape, current_ms[0], dtype=np.float32)
        variables["current_v_ms"] = np.full(shape, current_ms[1], dtype=np.float32)
    return WeatherField(times, grid.lat_deg, grid.lon_deg, variables)


def setup(grid, field, depart=T0, edges=8, weather_sea=None):
    mw = field.on_mesh(grid.lat_deg, grid.lon_deg, depart.value) if field is not None else None
    mesh = build_mesh(grid, edges=edges, weather_sea=weather_sea if weather_sea is not None else (None if mw is None else mw.weather_sea))
    return mesh, WeatherArrays.build(mesh, mw), mw


def test_edge_time_by_hand_beam_seas_on_the_equator():
    grid = MeshGrid(0.0, 0.0, 0.25, 0.25, 3, 5)  # equator, lon 0..1
    mesh, wx, _ = setup(grid, uniform_field(grid, 3.0, 0.0))  # 3 m waves from the north
    ship = ShipModel(16.0, "bowditch")
    res = search(mesh, wx, ship, mesh.node_id(0, 0), mesh.node_id(0, 4))
    # heading east, waves from north: encounter 270 -> beam seas, f = 0.0165 kn/ft^2
    expected_h = 1.0 * NMI_PER_DEG / (16.0 - 0.0165 * (3.0 / 0.3048) ** 2)
    assert res.cost == pytest.approx(expected_h, rel=1e-9)
    assert list(res.nodes) == [mesh.node_id(0, i) for i in range(5)]
    dist = search(mesh, wx, ship, mesh.node_id(0, 0), mesh.node_id(0, 4), cost="distance")
    assert dist.cost == pytest.approx(NMI_PER_DEG, rel=1e-12)


def test_weather_interpolated_at_the_time_the_edge_starts():
    grid = MeshGrid(0.0, 0.0, 0.25, 0.25, 3, 2)
    # Hs 0 m at 00:00, 6 m at 01:00; departure 00:30 (a quarter-hour sub-slice of the edge model,
    # routing._kernels.edge) -> Hs 3 m, head seas
    field = uniform_field(grid, [0.0, 6.0], 0.0, hours=(0.0, 1.0))
    mesh, wx, _ = setup(grid, field, depart=T0 + pd.Timedelta("30min"))
    ship = ShipModel(16.0, "bowditch")
    t0_h = wx.rel_h((T0 + pd.Timedelta("30min")).value)
    assert t0_h == pytest.approx(0.5)
    res = search(mesh, wx, ship, mesh.node_id(0, 0), mesh.node_id(1, 0), t_start_h=t0_h)
    expected_h = 0.25 * NMI_PER_DEG / (16.0 - 0.0248 * (3.0 / 0.3048) ** 2)  # north into waves from north: head
    assert res.cost == pytest.approx(expected_h, rel=1e-9)
    # 00:40 reads the nearest sub-slice, 00:45 (Hs 4.5 m)
    res = search(mesh, wx, ship, mesh.node_id(0, 0), mesh.node_id(1, 0), t_start_h=t0_h + 1.0 / 6.0)
    assert res.cost == pytest.approx(0.25 * NMI_PER_DEG / (16.0 - 0.0248 * (4.5 / 0.3048) ** 2), rel=1e-9)
    # after the last weather time the last field is held: 6 m head seas
    late = search(mesh, wx, ship, mesh.node_id(0, 0), mesh.node_id(1, 0), t_start_h=5.0)
    assert late.cost == pytest.approx(0.25 * NMI_PER_DEG / (16.0 - 0.0248 * (6.0 / 0.3048) ** 2), rel=1e-9)


def test_current_adds_to_speed_over_ground():
    grid = MeshGrid(0.0, 0.0, 0.25, 0.25, 3, 5)
    knot = 1852.0 / 3600.0
    field = uniform_field(grid, 0.0, 0.0, current_ms=(2.0 * knot, 0.0))  # 2 kn flowing east
    mesh, wx, _ = setup(grid, field)
    ship = ShipModel(10.0, "none")
    east = search(mesh, wx, ship, mesh.node_id(0, 0), mesh.node_id(0, 4))
    assert east.cost == pytest.approx(NMI_PER_DEG / 12.0, rel=1e-6)  # float32 field: 1e-6
    west = search(mesh, wx, ship, mesh.node_id(0, 4), mesh.node_id(0, 0))
    assert west.cost == pytest.approx(NMI_PER_DEG / 8.0, rel=1e-6)
    north = search(mesh, wx, ship, mesh.node_id(0, 0), mesh.node_id(2, 0))
    # cross current: sog = sqrt(10^2 - 2^2) along the track
    assert north.cost == pytest.approx(0.5 * NMI_PER_DEG / math.sqrt(96.0), rel=1e-6)


def test_compiled_speed_model_matches_the_numpy_models():
    rng = np.random.default_rng(3)
    hs = rng.uniform(0.0, 9.0, 4000)
    enc = rng.uniform(0.0, 360.0, 4000)
    # keep away from the sector edges, where the two compare degrees vs cosines
    edges = np.array([0.0, 30.0, 45.0, 60.0, 135.0, 150.0, 180.0, 210.0, 225.0, 300.0, 315.0, 330.0, 360.0])
    keep = np.min(np.abs(enc[:, None] - edges[None, :]), axis=1) > 1e-6
    hs, enc = hs[keep], enc[keep]
    rad = np.deg2rad(enc)
    for model in ("none", "bowditch", "aertssen", "khokhlov"):
        for sectors in ("symmetric", "printed") if model == "bowditch" else ("symmetric",):
            ship = ShipModel(16.1, model, lpp_m=225.0, dwt_t=8000.0, floor_kn=2.0, bowditch_sectors=sectors)
            p = ship.params()
            compiled = np.array(
                [
                    _kernels.speed_through_water(_kernels.ship_of(p), h, math.cos(a), math.sin(a))
                    for h, a in zip(hs, rad)
                ]
            )
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", SpeedLossValidityWarning)
                ref = attained_speed_kn(16.1, hs, enc, model, lpp_m=225.0, dwt_t=8000.0, floor_kn=2.0, bowditch_sectors=sectors)
            np.testing.assert_allclose(compiled, ref, rtol=1e-12, atol=1e-12, err_msg=f"{model}/{sectors}")


def random_case(seed, ny=28, nx=36, n_times=7):
    rng = np.random.default_rng(seed)
    grid = MeshGrid(38.0, 1.0, 0.05, 0.05, ny, nx)
    # smooth random fields: bilinear upsampling of a coarse random grid, evolving over 3-hour steps
    coarse = rng.uniform(0.0, 6.0, (n_times, 5, 6))
    yy = np.linspace(0, 4, ny)
    xx = np.linspace(0, 5, nx)
    hs = np.empty((n_times, ny, nx))
    for t in range(n_times):
        rows = np.array([np.interp(xx, np.arange(6), coarse[t, r]) for r in range(5)])
        hs[t] = np.array([np.interp(yy, np.arange(5), rows[:, c]) for c in range(nx)]).T
    direction = np.cumsum(rng.normal(0, 25, (n_times, ny, nx)), axis=2) % 360.0
    hs[:, 10:18, 15] = np.nan  # an island
    times = T0.value + np.arange(n_times, dtype=np.int64) * 3 * 3_600_000_000_000
    field = WeatherField(times, grid.lat_deg, grid.lon_deg, {"hs_m": hs, "wave_from_deg": direction})
    return grid, field, rng


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("model", ["bowditch", "aertssen", "khokhlov"])
def test_astar_equals_dijkstra_on_random_time_dependent_fields(seed, model):
    grid, field, rng = random_case(seed)
    mesh, wx, _ = setup(grid, field, depart=T0 + pd.Timedelta("1h"), edges=16 if seed % 2 else 48)
    ship = ShipModel(14.0, model, lpp_m=150.0, dwt_t=8000.0)
    sea = np.nonzero(mesh.sea.ravel())[0]
    t0 = wx.rel_h((T0 + pd.Timedelta("1h")).value)
    for _ in range(3):
        s, g = rng.choice(sea, 2, replace=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SpeedLossValidityWarning)
            a = search(mesh, wx, ship, s, g, t_start_h=t0)
            d = search(mesh, wx, ship, s, g, t_start_h=t0, heuristic=False)
        assert a.cost == pytest.approx(d.cost, rel=1e-9)
        assert a.expanded <= d.expanded
        # the grid path re-timed by the evaluator costs exactly what the search said
        la, lo = grid.node_latlon(a.nodes)
        times, _ = evaluate_path(mesh, wx, ship, la, lo, t_start_h=t0)
        assert times[-1] - times[0] == pytest.approx(a.cost, rel=1e-9)
        # distance mode: A* = Dijkstra too
        ad = search(mesh, wx, ship, s, g, cost="distance")
        dd = search(mesh, wx, ship, s, g, cost="distance", heuristic=False)
        assert ad.cost == pytest.approx(dd.cost, rel=1e-12)
        assert a.cost >= ad.cost / ship.max_speed_kn(wx.hs_max_m) - 1e-12


def test_khokhlov_following_seas_heuristic_stays_admissible():
    # Following seas everywhere: Khokhlov speeds exceed v0, a v0 heuristic would overestimate.
    grid = MeshGrid(0.0, 0.0, 0.1, 0.1, 30, 30)
    field = uniform_field(grid, 6.0, 225.0)  # waves from SW, ship sails NE: following
    mesh, wx, _ = setup(grid, field, edges=48)
    ship = ShipModel(12.0, "khokhlov", dwt_t=8000.0)
    assert ship.max_speed_kn(wx.hs_max_m) > 12.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SpeedLossValidityWarning)
        a = search(mesh, wx, ship, 0, mesh.node_id(29, 29))
        d = search(mesh, wx, ship, 0, mesh.node_id(29, 29), heuristic=False)
    assert a.cost == pytest.approx(d.cost, rel=1e-12)


def test_unreachable_goal_raises_in_bounded_time():
    grid = MeshGrid(40.0, 0.0, 0.05, 0.05, 200, 200)
    sea = np.ones((grid.ny, grid.nx), dtype=bool)
    sea[:, 120] = False  # a continent-long wall
    mesh = build_mesh(grid, edges=48, weather_sea=sea)
    wx = WeatherArrays.build(mesh, None)
    ship = ShipModel(15.0, "none")
    start, goal = mesh.node_id(100, 10), mesh.node_id(100, 190)
    assert not reachable(mesh, start)[goal]
    t = time.perf_counter()
    with pytest.raises(NoRouteError, match=r"no sea route from \(45.0000, 0.5000\) to \(45.0000, 9.5000\).*searched 24,000 reachable nodes"):
        search(mesh, wx, ship, start, goal)
    assert time.perf_counter() - t < 5.0  # every reachable node once, then a clear error
    with pytest.raises(NoRouteError, match="on land"):
        search(mesh, wx, ship, mesh.node_id(5, 120), goal)


def test_smoothing_never_slower_and_straightens_calm_routes():
    grid = MeshGrid(30.0, 0.0, 0.25, 0.25, 40, 80)
    mesh, wx, _ = setup(grid, None, edges=8)
    ship = ShipModel(15.0, "none")
    res = search(mesh, wx, ship, mesh.node_id(5, 3), mesh.node_id(33, 75), cost="distance")
    la, lo = grid.node_latlon(res.nodes)
    times, _ = evaluate_path(mesh, wx, ship, la, lo)
    keep = smooth(mesh, wx, ship, la, lo, times)
    assert keep[0] == 0 and keep[-1] == len(la) - 1 and len(keep) == 2  # open sea: one great-circle leg
    t2, _ = evaluate_path(mesh, wx, ship, la[keep], lo[keep])
    assert t2[-1] <= times[-1]
    # with weather, smoothing keeps each kept waypoint's arrival no later than the raw route's
    g2, field, _ = random_case(5)
    mesh2, wx2, _ = setup(g2, field, edges=48)
    ship2 = ShipModel(14.0, "bowditch")
    r = search(mesh2, wx2, ship2, mesh2.node_id(2, 2), mesh2.node_id(25, 33))
    la, lo = g2.node_latlon(r.nodes)
    times, _ = evaluate_path(mesh2, wx2, ship2, la, lo)
    keep = smooth(mesh2, wx2, ship2, la, lo, times)
    t2, _ = evaluate_path(mesh2, wx2, ship2, la[keep], lo[keep])
    assert np.all(t2 <= times[keep] + 1e-9)
    for a, b in zip(keep[:-1], keep[1:]):
        assert mesh2.leg_is_sea(la[a], lo[a], la[b], lo[b])
