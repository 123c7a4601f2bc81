"""DBSCAN [1] in chunks of query points: the labels of scikit-learn's ``DBSCAN`` (its tree and
metric, sample weights) without holding every point's neighbourhood at once.

The ports use it (:func:`lanes.ports.cluster_stops`: haversine, ball tree): a port's stops are
all within a few hundred metres, so their neighbourhoods grow with the period (8,182 stops of the
8.57 M-row fleet have 3.0 M neighbour pairs; the same stops twelve times over, as 100 M rows would
give them, held 3.9 GB in ``DBSCAN.fit``; docs/scale.md, fourth pass). The lanes' own DBSCAN is
:mod:`lanes.dbscan_grid` (Euclidean, on a grid: it does not list the neighbourhoods at all).

``sklearn.cluster.DBSCAN.fit`` asks its neighbour index for the eps-neighbourhood of every point
in one call and keeps them all: memory grows with the points times their neighbours. On a dense
lane that is most of a partition (measured, issue 23: +900 MB of RSS for one 71,340-point
origin-destination partition of the 300-ship, 8.61 M-row fleet). Here the same index
(``NearestNeighbors`` with DBSCAN's own arguments, so the same neighbour sets in the same order)
is queried :data:`CHUNK_POINTS` points at a time:

1. the weighted neighbour count of each point (``np.sum(weight[neighbours])``, self included:
   scikit-learn's own expression and order, so the core test ``count >= min_samples`` is bit for
   bit the same); the chunks' neighbour lists are kept (as int32) while they fit in
   :data:`KEEP_PAIRS`, else they are queried again in step 2;
2. core-core links merge components (union by smallest member, flattened after each chunk);
   each border point (not core, a core neighbour) keeps the components of its core neighbours.

When every neighbourhood fitted in :data:`KEEP_PAIRS`, step 2 is scikit-learn's own labelling
loop (``dbscan_inner``) over them: the same work and result as ``DBSCAN.fit``. Otherwise the
labels follow scikit-learn's numbering: ``dbscan_inner`` walks the points in index order and
labels a whole component (and its unlabelled border points) from its first core point, so a
component's label is the rank of its smallest core index, and a border point takes the smallest
label among the components of its core neighbours. Tested equal to ``DBSCAN.fit`` (labels and
core samples) on random and lane-like data. Memory: the index, the per-point arrays, the kept
lists up to :data:`KEEP_PAIRS`, and one chunk's neighbourhoods.

References
----------
.. [1] M. Ester, H.-P. Kriegel, J. Sander, X. Xu, "A density-based algorithm for discovering
       clusters in large spatial databases with noise," KDD-96, pp. 226-231, 1996.
"""

from __future__ import annotations

import numpy as np

#: Query points per chunk (one chunk's neighbourhoods are held at a time).
CHUNK_POINTS = 1024
#: Neighbour pairs kept from step 1 for step 2 (int32: 4 bytes each); beyond, step 2 queries again.
KEEP_PAIRS = 16_000_000


def _neighbour_model(features: np.ndarray, eps: float, leaf_size: int, metric: str, algorithm: str):
    from sklearn.neighbors import NearestNeighbors

    # DBSCAN's own construction of its neighbour model (metric_params None, p None)
    return NearestNeighbors(radius=eps, algorithm=algorithm, leaf_size=leaf_size, metric=metric,
                            metric_params=None, p=None, n_jobs=None).fit(features)


def _flatten(rows: np.ndarray, nbrs: np.ndarray, comp: np.ndarray) -> np.ndarray:
    """Merge the components linked by the pairs (rows[k], nbrs[k]); returns the new ``comp``
    (every point -> the smallest index of its component)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    a, b = comp[rows], comp[nbrs]
    keep = a != b
    if not keep.any():
        return comp
    roots, ab = np.unique(np.concatenate([a[keep], b[keep]]), return_inverse=True)
    m, k = roots.size, int(keep.sum())
    g = coo_matrix((np.ones(k, dtype=np.int8), (ab[:k], ab[k:])), shape=(m, m)).tocsr()
    _, cc = connected_components(g, directed=False)
    smallest = np.full(cc.max() + 1, comp.size, dtype=np.int64)
    np.minimum.at(smallest, cc, roots)  # roots ascending: each component's smallest root
    new_root = np.arange(comp.size, dtype=np.int64)
    new_root[roots] = smallest[cc]
    return new_root[comp]


def _inner(core: np.ndarray, kept: dict, n: int) -> np.ndarray | None:
    """Every neighbourhood was kept: scikit-learn's own labelling loop over them (what
    ``DBSCAN.fit`` runs after its query), None when that private function is not available."""
    try:
        from sklearn.cluster._dbscan_inner import dbscan_inner
    except ImportError:
        return None
    lens = np.concatenate([kept[s][0] for s in sorted(kept)])
    flat = np.concatenate([kept[s][1] for s in sorted(kept)]).astype(np.intp)
    kept.clear()
    hoods = np.empty(n, dtype=object)
    hoods[:] = np.split(flat, np.cumsum(lens)[:-1])
    labels = np.full(n, -1, dtype=np.intp)
    dbscan_inner(np.asarray(core, dtype=np.uint8), hoods, labels)
    return labels.astype(np.int64)


def dbscan_chunked(features: np.ndarray, eps: float, min_samples: float, sample_weight: np.ndarray,
                   leaf_size: int = 30, chunk: int = CHUNK_POINTS, keep_pairs: int = KEEP_PAIRS,
                   metric: str = "euclidean", algorithm: str = "kd_tree") -> tuple[np.ndarray, np.ndarray]:
    """``(labels, core_sample_indices)`` equal to ``DBSCAN(eps, min_samples=min_samples,
    metric=metric, algorithm=algorithm, leaf_size=leaf_size).fit(features,
    sample_weight=sample_weight)`` (module docstring)."""
    x = np.ascontiguousarray(features, dtype=np.float64)
    w = np.asarray(sample_weight, dtype=np.float64)
    n = x.shape[0]
    if n == 0:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    model = _neighbour_model(x, eps, leaf_size, metric, algorithm)
    counts = np.empty(n, dtype=np.float64)
    kept: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    n_kept = 0
    for s in range(0, n, chunk):
        nb = model.radius_neighbors(x[s:s + chunk], return_distance=False)
        counts[s:s + len(nb)] = [np.sum(w[v]) for v in nb]
        lens = np.fromiter((len(v) for v in nb), dtype=np.int64, count=len(nb))
        if n_kept + lens.sum() <= keep_pairs:
            kept[s] = (lens, np.concatenate(nb).astype(np.int32) if len(nb) else np.empty(0, np.int32))
            n_kept += int(lens.sum())
        del nb
    core = counts >= min_samples
    if len(kept) * chunk >= n:
        labels = _inner(core, kept, n)
        if labels is not None:
            return labels, np.flatnonzero(core)
    comp = np.arange(n, dtype=np.int64)
    border_rows, border_comps = [], []
    for s in range(0, n, chunk):
        if s in kept:
            lens, nbrs = kept.pop(s)
        else:
            nb = model.radius_neighbors(x[s:s + chunk], return_distance=False)
            lens = np.fromiter((len(v) for v in nb), dtype=np.int64, count=len(nb))
            nbrs = np.concatenate(nb) if len(nb) else np.empty(0, np.int64)
            del nb
        rows = np.repeat(np.arange(s, s + len(lens), dtype=np.int64), lens)
        nbrs = nbrs.astype(np.int64, copy=False)
        to_core = core[nbrs]
        link = to_core & core[rows]
        comp = _flatten(rows[link], nbrs[link], comp)
        edge = to_core & ~core[rows]
        if edge.any():  # border points: the components of their core neighbours (as of now)
            pairs = np.unique(rows[edge] * n + comp[nbrs[edge]])
            border_rows.append(pairs // n)
            border_comps.append(pairs % n)
    labels = np.full(n, -1, dtype=np.int64)
    core_idx = np.flatnonzero(core)
    if core_idx.size:
        roots, rank = np.unique(comp[core_idx], return_inverse=True)
        label_of_root = np.full(n, -1, dtype=np.int64)
        label_of_root[roots] = np.arange(roots.size)
        labels[core_idx] = rank.reshape(-1)
        if border_rows:
            b_rows = np.concatenate(border_rows)
            b_labels = label_of_root[comp[np.concatenate(border_comps)]]
            best = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
            np.minimum.at(best, b_rows, b_labels)
            hit = best < np.iinfo(np.int64).max
            labels[hit] = best[hit]
    return labels, core_idx
