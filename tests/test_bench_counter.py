"""The routing kernel's count of edges whose cost was computed (the benchmarks' throughput unit).

On an all-sea 5 x 7 mesh, a Dijkstra from one corner to the opposite corner (the unique farthest
node, so it is expanded last) expands every node; every undirected edge then has its cost
computed exactly once (from whichever end is expanded first), the edges back to closed nodes
are scanned and skipped, and the goal's own edges are never scanned.
"""

from __future__ import annotations

import numpy as np

from routing.astar import ShipModel, WeatherArrays, search
from routing.mesh import MeshGrid, build_mesh


def _popcount(masks: np.ndarray) -> np.ndarray:
    return np.array([bin(int(m)).count("1") for m in masks.ravel()])


def test_computed_edges_count_each_undirected_edge_once():
    grid = MeshGrid.from_bbox((0.0, 40.0, 0.6, 40.4), 0.1)
    assert (grid.ny, grid.nx) == (5, 7)
    mesh = build_mesh(grid, edges=16, ignore_land=True)
    wx = WeatherArrays.build(mesh, None)
    ship = ShipModel(12.0, "none")
    deg = _popcount(mesh.allowed)
    goal = grid.n_nodes - 1
    for cost in ("distance", "time"):
        res = search(mesh, wx, ship, 0, goal, cost=cost, heuristic=False)
        assert res.expanded == grid.n_nodes
        assert res.scanned == int(deg.sum() - deg[goal])
        assert res.computed == int(deg.sum() // 2)
        assert res.computed < res.scanned
