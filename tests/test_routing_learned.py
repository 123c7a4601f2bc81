"""The learned speed table in the router: the compiled interpolation equals its numpy twin, the
search stays optimal (A* = Dijkstra) with the table's maximum as the heuristic's speed, and the
route is re-timed exactly as it was searched (issue 21)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from routing import _kernels
from routing.astar import ShipModel, evaluate_path, search
from routing.learned import LearnedSpeedTable

from test_routing_astar import T0, random_case, setup


def table(seed: int = 0, gain: float = 0.0) -> LearnedSpeedTable:
    """A table falling with Hs, most in head seas; ``gain`` lifts following seas above 1 (a model
    may learn that: the heuristic must then use the table's maximum, not v0)."""
    hs = np.arange(0.0, 6.01, 0.25)
    enc = np.arange(0.0, 180.01, 15.0)
    H, E = np.meshgrid(hs, enc, indexing="ij")
    rng = np.random.default_rng(seed)
    ratio = 1.0 - 0.02 * H**1.5 * (0.3 + 0.7 * np.cos(np.deg2rad(E / 2)) ** 2) + gain * H * (E > 150) / 6.0
    ratio = ratio + rng.normal(0, 0.005, ratio.shape)
    return LearnedSpeedTable("t", hs, enc, ratio, ratio - 0.05, ratio + 0.05, hs_max_trained_m=6.0, note="test table")


def test_compiled_table_lookup_equals_the_numpy_twin():
    t = table(1)
    ship = ShipModel(14.0, "learned", floor_kn=2.0, learned=t)
    p = ship.params()
    rng = np.random.default_rng(0)
    hs = rng.uniform(-0.5, 8.0, 500)  # below 0 and beyond the table too (clamped)
    enc = rng.uniform(0.0, 360.0, 500)
    rad = np.deg2rad(enc)
    compiled = np.array([_kernels.speed_through_water(_kernels.ship_of(p), h, math.cos(a), math.sin(a)) for h, a in zip(hs, rad)])
    ref = ship.attained_kn(np.maximum(hs, 0.0), enc)
    np.testing.assert_allclose(compiled, ref, rtol=1e-9, atol=1e-9)
    # hand check at a grid node: Hs 2 m (row 8), head seas (column 0)
    assert float(t.ratio_at(2.0, 0.0)[()]) == pytest.approx(t.ratio[8, 0])


@pytest.mark.parametrize("seed, gain", [(0, 0.0), (1, 0.3)])
def test_astar_with_a_learned_table_equals_dijkstra_and_retimes_exactly(seed, gain):
    grid, field, rng = random_case(seed)
    mesh, wx, _ = setup(grid, field, edges=16)
    ship = ShipModel(14.0, "learned", floor_kn=2.0, learned=table(seed, gain))
    assert ship.max_speed_kn(wx.hs_max_m) == pytest.approx(max(14.0 * ship.learned.max_ratio(), 2.0))
    if gain:
        assert ship.max_speed_kn(wx.hs_max_m) > 14.0
    sea = np.nonzero(mesh.sea.ravel())[0]
    for _ in range(3):
        s, g = rng.choice(sea, 2, replace=False)
        a = search(mesh, wx, ship, s, g)
        d = search(mesh, wx, ship, s, g, heuristic=False)
        assert a.cost == pytest.approx(d.cost, rel=1e-9)
        la, lo = grid.node_latlon(a.nodes)
        times, _ = evaluate_path(mesh, wx, ship, la, lo)
        assert times[-1] - times[0] == pytest.approx(a.cost, rel=1e-9)


def test_a_table_must_be_regular_and_finite():
    t = table()
    with pytest.raises(ValueError, match="non-finite"):
        LearnedSpeedTable("t", t.hs_m, t.encounter_deg, t.ratio * np.nan, t.p10, t.p90, 6.0)
    with pytest.raises(ValueError, match="regular"):
        LearnedSpeedTable("t", t.hs_m ** 2, t.encounter_deg, t.ratio, t.p10, t.p90, 6.0)
    with pytest.raises(ValueError, match="needs its table"):
        ShipModel(14.0, "learned")
