"""lanes.dbscan: scikit-learn's DBSCAN labels and core samples, computed in chunks of query
points (issue 23: a dense partition must not hold every neighbourhood at once)."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.cluster import DBSCAN

from lanes.dbscan import dbscan_chunked


def _blobs(rng):
    k = int(rng.integers(1, 6))
    centers = rng.uniform(0, 10, size=(k, 3))
    parts = [c + rng.normal(0, rng.uniform(0.3, 1.5), size=(int(rng.integers(5, 300)), 3)) for c in centers]
    x = np.concatenate(parts + [rng.uniform(0, 10, size=(int(rng.integers(0, 150)), 3))])
    return np.round(x, int(rng.integers(1, 4)))  # coarse values: many distances exactly at eps


@pytest.mark.parametrize("seed", range(12))
def test_same_labels_and_core_samples_as_sklearn(seed):
    rng = np.random.default_rng(seed)
    x = _blobs(rng)
    w = rng.uniform(0.1, 1.0, size=len(x))
    min_samples = int(rng.integers(1, 12))
    ref = DBSCAN(eps=1.0, min_samples=min_samples, algorithm="kd_tree").fit(x, sample_weight=w)
    # every neighbourhood kept (scikit-learn's own labelling loop), none kept (all queried
    # twice, components merged chunk by chunk), some kept
    for chunk, keep in ((64, 10**9), (7, 0), (50, 400)):
        labels, core = dbscan_chunked(x, 1.0, min_samples, w, chunk=chunk, keep_pairs=keep)
        assert np.array_equal(labels, ref.labels_), (chunk, keep)
        assert np.array_equal(core, ref.core_sample_indices_), (chunk, keep)


def test_border_point_takes_the_first_cluster_and_chains_merge_across_chunks():
    # A chain of core points 0.5 apart (min_samples 4: each has 4 or 5 points within 1.0), its
    # second half listed from its far end so that the link between the halves is found in a
    # late chunk; a border point at 20.5 (3 points within 1.0: not core) touching the chain's
    # end 19.5 and the first point 21.5 of a second cluster; a noise point at 40. By hand:
    # cluster 0 = the chain (it holds index 0), cluster 1 = 21.5-23.5, the border point takes
    # the lower label 0.
    line_a = np.arange(0.0, 10.0, 0.5)
    line_b = np.arange(19.5, 9.9, -0.5)
    other = np.arange(21.5, 23.6, 0.5)
    x = np.concatenate([line_a, line_b, [20.5], other, [40.0]])[:, None]
    labels, core = dbscan_chunked(x, 1.0, 4, np.ones(len(x)), chunk=4, keep_pairs=0)
    ref = DBSCAN(eps=1.0, min_samples=4).fit(x)
    assert np.array_equal(labels, ref.labels_) and np.array_equal(core, ref.core_sample_indices_)
    n_chain = len(line_a) + len(line_b)
    assert set(labels[:n_chain]) == {0} and set(labels[n_chain + 1:-1]) == {1}
    assert labels[n_chain] == 0 and n_chain not in core and labels[-1] == -1
