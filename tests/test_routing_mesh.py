"""Routing mesh: stencils, cells an edge touches, the no-land-crossing rule, snapping and errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from routing.errors import LandPointError, MeshSizeError, OutsideMeshError
from routing.mesh import LandMask, MeshGrid, _cells_touched, build_mesh, stencil, stencil_angular_gaps_deg


def test_stencil_counts_and_primitive_steps():
    for n in (8, 16, 24, 48):
        steps = stencil(n)
        assert len(steps) == n
        assert len({tuple(s) for s in steps}) == n
        assert all(math.gcd(abs(int(a)), abs(int(b))) == 1 for a, b in steps)
        # symmetric under the 8 symmetries of the square
        pairs = {tuple(s) for s in steps}
        assert all((-a, b) in pairs and (b, a) in pairs for a, b in pairs)
    assert max(np.abs(stencil(48)).max(axis=1)) == 4
    with pytest.raises(ValueError, match="edges must be one of"):
        stencil(32)


def test_angular_resolution_48_edges_matches_the_paper():
    # Grifoll et al. 2022 section 2.2: 48 edges give 3.2-14.0 degree resolution.
    gaps = stencil_angular_gaps_deg(48)
    # atan(3/4) - atan(2/3) = 3.18 deg; atan(1/4) - 0 = 14.04 deg.
    assert gaps.min() == pytest.approx(math.degrees(math.atan(3 / 4) - math.atan(2 / 3)), abs=1e-9)
    assert gaps.max() == pytest.approx(math.degrees(math.atan(1 / 4)), abs=1e-9)
    assert round(gaps.min(), 1) == 3.2 and round(gaps.max(), 1) == 14.0
    assert stencil_angular_gaps_deg(8).max() == pytest.approx(45.0)
    assert stencil_angular_gaps_deg(16).max() == pytest.approx(math.degrees(math.atan(1 / 2)))  # 26.57


def test_cells_touched_by_edges():
    assert sorted(map(tuple, _cells_touched(1, 0))) == [(0, 0), (1, 0)]
    # a diagonal passes through the corner shared by four cells: all four count
    assert sorted(map(tuple, _cells_touched(1, 1))) == [(0, 0), (0, 1), (1, 0), (1, 1)]
    # (2, 1) crosses the row boundary inside column 1
    assert sorted(map(tuple, _cells_touched(2, 1))) == [(0, 0), (1, 0), (1, 1), (2, 1)]
    assert sorted(map(tuple, _cells_touched(0, -3))) == [(0, -3), (0, -2), (0, -1), (0, 0)]


def test_grid_from_bbox_anchored_on_the_start():
    # SIMROUTE R6: lon 2.0-5.1, lat 38.95-41.65, 1.5 nmi = 0.025 deg: 125 x 109 nodes.
    g = MeshGrid.from_bbox((2.0, 38.95, 5.1, 41.65), 1.5 / 60.0, anchor=(39.225, 2.9))
    assert (g.nx, g.ny) == (125, 109)
    # SIMROUTE node ids: start 1411 = 11*125 + 36, goal 12781 = 102*125 + 31
    assert round((39.225 - g.lat0_deg) / g.dlat_deg) * g.nx + round((2.9 - g.lon0_deg) / g.dlon_deg) == 1411
    g2 = MeshGrid.from_bbox((0.0, 0.0, 1.0, 1.0), 0.3, anchor=(0.5, 0.5))
    assert g2.lat0_deg == pytest.approx(0.2) and g2.lon0_deg == pytest.approx(0.2)
    with pytest.raises(MeshSizeError, match="exceeds"):
        MeshGrid.from_bbox((-10, -10, 10, 10), 0.001)
    with pytest.raises(MeshSizeError, match="empty bbox"):
        MeshGrid.from_bbox((1, 0, 0, 1), 0.1)


def _grid(ny=20, nx=20, d=0.1):
    return MeshGrid(40.0, 2.0, d, d, ny, nx)


def test_edges_never_touch_a_weather_land_cell():
    g = _grid()
    weather_sea = np.ones((g.ny, g.nx), dtype=bool)
    weather_sea[8:12, 9] = False  # a thin wall of land cells
    mesh = build_mesh(g, edges=48, weather_sea=weather_sea)
    land_cells = {(int(r), int(c)) for r, c in zip(*np.nonzero(~weather_sea))}
    n_allowed = 0
    for node in np.nonzero(mesh.allowed)[0]:
        j, i = divmod(int(node), g.nx)
        for k, (di, dj) in enumerate(mesh.steps):
            if not (int(mesh.allowed[node]) >> k) & 1:
                continue
            n_allowed += 1
            touched = {(j + int(r), i + int(c)) for c, r in _cells_touched(int(di), int(dj))}
            assert not touched & land_cells
    assert n_allowed > 10_000
    # an edge straight through the wall is refused, one that passes beside it is allowed
    k_east = [k for k, s in enumerate(mesh.steps) if tuple(s) == (1, 0)][0]
    assert not (int(mesh.allowed[mesh.node_id(10, 8)]) >> k_east) & 1
    assert (int(mesh.allowed[mesh.node_id(5, 8)]) >> k_east) & 1
    # SIMROUTE's end-node test lets a 4-cell edge jump over the wall
    jump = [k for k, s in enumerate(mesh.steps) if tuple(s) == (3, 1)][0]
    simroute = build_mesh(g, edges=48, weather_sea=weather_sea, land_check="end_node")
    assert (int(simroute.allowed[simroute.node_id(9, 7)]) >> jump) & 1
    assert not (int(mesh.allowed[mesh.node_id(9, 7)]) >> jump) & 1


def _island_mask(g: MeshGrid):
    """A 30-arc-second raster over the grid with a small round island (radius 0.12 deg)."""
    ppd = 120
    r0 = int(math.floor((90.0 - (g.lat_deg[-1] + 1.5 * g.dlat_deg)) * ppd))
    c0 = int(math.floor((g.lon_deg[0] - 1.5 * g.dlon_deg + 180.0) * ppd))
    rows, cols = int((g.ny + 3) * g.dlat_deg * ppd) + 2, int((g.nx + 3) * g.dlon_deg * ppd) + 2
    lat = 90.0 - (r0 + np.arange(rows) + 0.5) / ppd
    lon = -180.0 + (c0 + np.arange(cols) + 0.5) / ppd
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    island = (la - 41.0) ** 2 + (lo - 3.0) ** 2 < 0.12**2
    return LandMask(~island, r0, c0, ppd), island.sum()


def test_land_mask_pixels_fraction_and_exact_edge_test():
    g = _grid()
    land, n_px = _island_mask(g)
    frac = land.land_fraction(g)
    # the island's pixels, counted once per cell they overlap, cover at least its area
    cell_px = (g.dlat_deg * 120) * (g.dlon_deg * 120)
    assert frac.sum() * cell_px >= n_px
    assert frac[g.ny // 2, g.nx // 2] > 0 and frac[0, 0] == 0.0
    mesh = build_mesh(g, edges=48, land=land)
    assert not mesh.sea[10, 10]  # (41.0, 3.0) is the island's centre
    # Every allowed edge, sampled every ~50 m, stays off the island's pixels.
    f = np.linspace(0.0, 1.0, 200)
    for node in np.nonzero(mesh.allowed)[0][::7]:
        j, i = divmod(int(node), g.nx)
        for k, (di, dj) in enumerate(mesh.steps):
            if (int(mesh.allowed[node]) >> k) & 1:
                lat = g.lat_deg[j] + f * dj * g.dlat_deg
                lon = g.lon_deg[i] + f * di * g.dlon_deg
                assert land.is_ocean(lat, lon).all()
    # and legs across the island are refused while legs beside it are not
    assert not mesh.leg_is_sea(40.7, 3.0, 41.3, 3.0)
    assert mesh.leg_is_sea(40.7, 2.7, 41.3, 2.7)


def test_snapping_and_errors():
    g = _grid()
    land, _ = _island_mask(g)
    mesh = build_mesh(g, edges=16, land=land)
    node, d = mesh.snap(41.0, 3.0, limit_nmi=20.0)  # island centre -> nearest sea node
    assert mesh.sea.ravel()[node] and 0 < d <= 20.0
    lat, lon = g.node_latlon(node)
    assert math.hypot(lat - 41.0, (lon - 3.0) * math.cos(math.radians(41))) > 0.1
    with pytest.raises(LandPointError, match=r"start \(41.0000, 3.0000\) is on land .* within 1 nmi"):
        mesh.snap(41.0, 3.0, limit_nmi=1.0, what="start")
    with pytest.raises(OutsideMeshError, match="outside the mesh bbox"):
        mesh.nearest_node(45.0, 3.0)
    sea_node, d0 = mesh.snap(40.0, 2.0, limit_nmi=1.0)
    assert sea_node == 0 and d0 == pytest.approx(0.0, abs=1e-9)
