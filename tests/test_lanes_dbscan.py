"""lanes.dbscan_grid: scikit-learn's DBSCAN labels and core samples, computed on a grid of cells of
diameter eps (issue 23: the cost of a dense partition must not grow with its pairs of points)."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.cluster import DBSCAN

import lanes.dbscan_grid as grid
from lanes.dbscan_grid import dbscan_grid


def _blobs(rng, dim=3):
    k = int(rng.integers(1, 6))
    centers = rng.uniform(0, 10, size=(k, dim))
    parts = [c + rng.normal(0, rng.uniform(0.3, 1.5), size=(int(rng.integers(5, 300)), dim)) for c in centers]
    x = np.concatenate(parts + [rng.uniform(0, 10, size=(int(rng.integers(0, 150)), dim))])
    return np.round(x, int(rng.integers(1, 4)))  # coarse values: many distances exactly at eps


def _same_as_sklearn(x, min_samples, w):
    ref = DBSCAN(eps=1.0, min_samples=min_samples, algorithm="kd_tree").fit(x, sample_weight=w)
    labels, core = dbscan_grid(x, 1.0, min_samples, w)
    assert np.array_equal(labels, ref.labels_)
    assert np.array_equal(core, ref.core_sample_indices_)
    return labels, core


@pytest.mark.parametrize("seed", range(12))
def test_same_labels_and_core_samples_as_sklearn(seed):
    rng = np.random.default_rng(seed)
    x = _blobs(rng, dim=(1, 2, 3, 6)[seed % 4])
    # unit weights (integer counts: a count equal to min_samples is a tie, settled by
    # scikit-learn's own sum) and fractional weights
    w = np.ones(len(x)) if seed % 3 == 0 else rng.uniform(0.1, 1.0, size=len(x))
    _same_as_sklearn(x, int(rng.integers(1, 12)), w)


def _lane_like(n=6000, seed=23):
    """The lanes' 6-D embedding (lanes.extract.motion_features) of two crossing streams of ships,
    a slow harbour approach and scattered traffic, weighted as the lanes weigh them (in voyages)."""
    from lanes.extract import LaneParams, motion_features, point_weights

    rng = np.random.default_rng(seed)
    along = rng.uniform(0, 12, n)  # nmi
    stream = rng.integers(0, 4, n)  # north-bound, east-bound, slow approach, scattered
    lat = np.where(stream == 0, 48.0 + along / 60, np.where(stream == 1, 48.1 + 0 * along, 48.0 - along / 600))
    lon = np.where(stream == 0, -5.0, -5.15 + along / 40) + rng.normal(0, 0.002, n)
    lat = lat + rng.normal(0, 0.002, n)
    speed = np.where(stream == 2, rng.uniform(1, 6, n), rng.normal(14, 0.3, n))
    course = np.where(stream == 0, 0.0, 90.0) + rng.normal(0, 1, n)
    scattered = stream == 3
    lat[scattered] = rng.uniform(47.8, 48.3, scattered.sum())
    lon[scattered] = rng.uniform(-5.4, -4.8, scattered.sum())
    speed[scattered] = rng.uniform(1, 20, scattered.sum())
    course[scattered] = rng.uniform(0, 360, scattered.sum())
    params = LaneParams()
    return motion_features(lat, lon, speed, course, params), point_weights(speed, 300.0, params.eps_nmi)


def test_lane_like_partition_with_dense_cells():
    # many points are in dense cells (core without a count), the rest need counts, links and
    # border labels
    x, w = _lane_like()
    w = w * 100.0
    order, start, cell_of, cells = grid._grid(np.ascontiguousarray(x), 1.0)
    cell_w = np.bincount(cell_of, weights=w)
    assert (cell_w[cell_of] >= 300).mean() > 0.4  # the dense-cell path carries many points
    labels, core = _same_as_sklearn(x, 300, w)
    assert labels.max() >= 1 and (labels == -1).any()  # several clusters and some noise


def test_sampled_partition_labels_the_rest_by_the_nearest_core_sample():
    # Above max_points, the points left out of the sample take the label of their nearest core
    # sample within eps (lanes.extract.dbscan_labels): where the grid settles it (every core
    # sample within reach has one label) and by a k-d tree elsewhere. Reference: brute force.
    from lanes.extract import LaneParams, _seed, dbscan_labels

    x, w = _lane_like(n=4000, seed=5)
    params, key = LaneParams(max_points=600), (2, 5)
    labels, sampled = dbscan_labels(x, w, params, key)
    sample = np.sort(np.random.default_rng(_seed(key, params.seed)).choice(len(x), size=600, replace=False))
    s_labels, s_core, cells = dbscan_grid(x[sample], 1.0, 300, w[sample] * len(x) / 600 * 100.0, with_cells=True)
    assert sampled and np.array_equal(labels[sample], s_labels)
    rest = np.setdiff1d(np.arange(len(x)), sample)
    core = sample[s_core]
    d2 = ((x[rest][:, None, :] - x[core][None, :, :]) ** 2).sum(axis=2)
    nearest = np.argmin(d2, axis=1)
    expected = np.where(d2[np.arange(rest.size), nearest] <= 1.0, s_labels[s_core][nearest], -1)
    assert np.array_equal(labels[rest], expected)
    settled = cells.labels_of(x[rest])
    assert 0 < (settled >= 0).sum() < rest.size  # both paths ran
    assert len(np.unique(expected[expected >= 0])) >= 2  # more than one label to choose from


def test_counts_at_the_threshold_are_settled_by_sklearns_sum(monkeypatch):
    # unit weights on a line 0.25 apart: interior points count 9 within 1.0, the ends fewer; with
    # min_samples 9 every interior count is a tie, which scikit-learn's own sum decides
    x = np.arange(0.0, 10.0, 0.25)[:, None]
    calls = []
    exact = grid._exact_counts
    monkeypatch.setattr(grid, "_exact_counts", lambda *a: calls.append(a[3].size) or exact(*a))
    labels, core = _same_as_sklearn(x, 9, np.ones(len(x)))
    assert calls and calls[0] >= len(x) - 8
    assert set(core) == set(range(4, len(x) - 4)) and set(labels) == {0}


def test_border_point_takes_the_first_cluster_and_chains_merge_across_cells():
    # A chain of core points 0.5 apart (min_samples 4: each has 4 or 5 points within 1.0), its
    # second half listed from its far end so that the halves meet late in index order; a border
    # point at 20.5 (3 points within 1.0: not core) touching the chain's end 19.5 and the first
    # point 21.5 of a second cluster; a noise point at 40. By hand: cluster 0 = the chain (it
    # holds index 0), cluster 1 = 21.5-23.5, the border point takes the lower label 0.
    line_a = np.arange(0.0, 10.0, 0.5)
    line_b = np.arange(19.5, 9.9, -0.5)
    other = np.arange(21.5, 23.6, 0.5)
    x = np.concatenate([line_a, line_b, [20.5], other, [40.0]])[:, None]
    labels, core = _same_as_sklearn(x, 4, np.ones(len(x)))
    n_chain = len(line_a) + len(line_b)
    assert set(labels[:n_chain]) == {0} and set(labels[n_chain + 1:-1]) == {1}
    assert labels[n_chain] == 0 and n_chain not in core and labels[-1] == -1


def test_empty_and_all_noise():
    labels, core = dbscan_grid(np.empty((0, 6)), 1.0, 3, np.empty(0))
    assert labels.size == 0 and core.size == 0
    x = np.arange(5, dtype=float)[:, None] * 3.0  # 3 apart: nobody has a neighbour
    labels, core = _same_as_sklearn(x, 2, np.ones(5))
    assert (labels == -1).all() and core.size == 0
