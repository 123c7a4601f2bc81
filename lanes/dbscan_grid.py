"""DBSCAN [1] on a grid of cells of diameter eps: scikit-learn's ``DBSCAN`` labels (k-d tree,
Euclidean, sample weights) at a cost that grows with the occupied cells, not with the pairs.

Why. On a dense traffic lane a point has thousands of eps-neighbours (issue 23: 1,730 per point
in a 71,340-point origin-destination partition of the 300-ship, 8.61 M-row fleet), and both
scikit-learn's ``DBSCAN.fit`` and a query of every point's neighbourhood list every neighbour of
every point: the work grows with the points times their neighbours, i.e. with the square of a
partition's points. Here the space is cut into cells of side ``eps / sqrt(d)`` (d the dimension,
shrunk by 1e-6 against rounding), the exact grid method of Gunawan [2] and de Berg et al. [3]:

* any two points of one cell are within eps of each other, so a cell whose points weigh at least
  ``min_samples`` (with a margin of 1e-9 relative, far above the rounding of any sum) holds only
  core points, which are all linked: no neighbour of theirs is listed;
* every other point's weighted neighbour count is summed over the cells that can hold a
  neighbour (those whose box lies within eps of its cell's box), each pair tested with the
  distance scikit-learn's k-d tree computes (the sum of squared coordinate differences in
  coordinate order, against ``eps * eps``), so the same pairs are neighbours; a count within
  1e-9 of ``min_samples`` is recomputed by scikit-learn's own query and sum, so the core test is
  scikit-learn's bit for bit;
* two cells holding core points are linked (union-find over cells) when one pair of their core
  points is within eps: the pairs are tried until the first link, and not at all when the two
  cells are already in one component;
* labels follow scikit-learn's numbering (``dbscan_inner`` labels a whole component from its
  first core point in index order): a component's label is the rank of its smallest core index,
  and a border point (not core, a core point within eps) takes the smallest label among the
  components of its core neighbours (``dbscan_inner`` expands one component at a time, in label
  order, and labels a border point when it first reaches it).

The candidate cells of each cell come from a k-d tree over the occupied cells' integer
coordinates. Tested equal to ``DBSCAN.fit`` (labels and core samples) on random blobs with
coarse coordinates (many distances exactly eps), with and without weights, and on the lanes'
own partitions (the lanes tables of the 2.1 and 8.6 M-row fleets are identical: docs/scale.md).
Memory: the per-point arrays, the cells and their candidate lists (int32).

References
----------
.. [1] M. Ester, H.-P. Kriegel, J. Sander, X. Xu, "A density-based algorithm for discovering
       clusters in large spatial databases with noise," KDD-96, pp. 226-231, 1996.
.. [2] A. Gunawan, "A faster algorithm for DBSCAN," Master's thesis, Technische Universiteit
       Eindhoven, 2013 (the grid of cells of side eps/sqrt(d)).
.. [3] M. de Berg, A. Gunawan, M. Roeloffzen, "Faster DB-scan and HDB-scan in low-dimensional
       Euclidean spaces," arXiv:1702.08607, 2017.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Cells are shrunk by this factor so that rounding never puts two points of a cell beyond eps.
_SHRINK = 1.0 - 1e-6
#: Counts within this relative distance of ``min_samples`` are recomputed by scikit-learn.
_TIE = 1e-9
#: Cells queried at once for their candidate cells.
_CELL_CHUNK = 8192

def _kernels():
    """The compiled kernels (:mod:`lanes._grid_kernels`: imported on first use, so that importing
    the lanes does not import numba)."""
    from lanes import _grid_kernels

    return _grid_kernels


def _side(eps: float, d: int) -> float:
    return eps / np.sqrt(d) * _SHRINK


def _grid(x: np.ndarray, eps: float):
    """Cells of side ``eps / sqrt(d)``: (point order by cell, cell starts, each point's cell,
    the occupied cells' integer coordinates, sorted)."""
    n, d = x.shape
    ijk = np.floor(x / _side(eps, d)).astype(np.int64)
    order = np.lexsort(ijk.T[::-1])
    sorted_ijk = ijk[order]
    new = np.r_[True, np.any(sorted_ijk[1:] != sorted_ijk[:-1], axis=1)]
    start = np.r_[np.flatnonzero(new), n].astype(np.int64)
    cell_of = np.empty(n, dtype=np.int64)
    cell_of[order] = np.cumsum(new) - 1
    return order.astype(np.int64), start, cell_of, sorted_ijk[new]


def _candidates(cells: np.ndarray, d: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR lists (pointers, cell indices, each list including the cell itself, in the k-d tree's
    order) of the cells whose box lies within eps of each cell's box."""
    from sklearn.neighbors import KDTree

    # in cell units eps is sqrt(bound) cells: boxes within eps differ by sum (|dk| - 1)+^2 <= bound,
    # hence by at most sqrt(d + 2 sqrt(d bound) + bound) in Euclidean distance (all |dk| - 1 equal)
    bound = int(np.floor(d / _SHRINK**2 + 1e-9))
    radius = np.sqrt(d + 2.0 * np.sqrt(d * bound) + bound) + 1e-6
    keep = _kernels().keep_candidates
    coords = cells.astype(np.float64)
    tree = KDTree(coords)
    lens, lists = [], []
    for s in range(0, len(cells), _CELL_CHUNK):
        nb = tree.query_radius(coords[s:s + _CELL_CHUNK], r=radius)
        n_nb = np.fromiter((len(v) for v in nb), dtype=np.int64, count=len(nb))
        nbrs = np.concatenate(nb).astype(np.int64)
        rows = np.repeat(np.arange(s, s + len(nb), dtype=np.int64), n_nb)
        ok = keep(cells, rows, nbrs, bound)  # rows ascending: the lists stay grouped by cell
        lists.append(nbrs[ok].astype(np.int32))
        lens.append(np.bincount(rows[ok] - s, minlength=len(nb)))
    ptr = np.r_[0, np.cumsum(np.concatenate(lens))].astype(np.int64)
    return ptr, np.concatenate(lists)


def _exact_counts(x: np.ndarray, eps: float, w: np.ndarray, idx: np.ndarray, leaf_size: int) -> np.ndarray:
    """scikit-learn's weighted neighbour counts of the points ``idx``: DBSCAN's own neighbour
    model (``NearestNeighbors`` with its arguments: the same neighbours in the same order) and its
    own sum, ``np.sum(weight[neighbours])``."""
    from sklearn.neighbors import NearestNeighbors

    model = NearestNeighbors(radius=eps, algorithm="kd_tree", leaf_size=leaf_size, metric="euclidean",
                             metric_params=None, p=None, n_jobs=None).fit(x)
    nb = model.radius_neighbors(x[idx], return_distance=False)
    return np.array([np.sum(w[v]) for v in nb], dtype=np.float64)


@dataclass
class CoreCells:
    """Where a clustering's core points lie: the occupied cells (sorted integer coordinates, side
    ``side``) and, per cell, the one label of all core points within reach of the cell (those of
    its candidate cells) when the cell holds a core point and they all have that label, else -1."""

    side: float
    cells: np.ndarray
    label: np.ndarray

    def labels_of(self, y: np.ndarray) -> np.ndarray:
        """For each point of ``y``: the label of its nearest core point when the grid settles it,
        else -1. A point in a cell holding a core point has a core point within eps (the cell's
        diameter), so its nearest core point is within eps and in a candidate cell: when all
        those have one label, that is the label, whatever the nearest one (used to label the
        points left out of a sample, :func:`lanes.extract.dbscan_labels`)."""
        out = np.full(len(y), -1, dtype=np.int64)
        if len(y) == 0 or len(self.cells) == 0:
            return out
        ijk = np.floor(np.asarray(y, dtype=np.float64) / self.side).astype(np.int64)
        low, span = self.cells.min(axis=0), self.cells.max(axis=0) - self.cells.min(axis=0) + 1
        if int(np.prod([int(v) for v in span])) >= 2**62:  # no one-integer key: nothing settled
            return out
        mult = np.r_[np.cumprod(span[::-1])[::-1][1:], 1]  # mixed radix, the first coordinate major
        inside = np.all((ijk >= low) & (ijk < low + span), axis=1)
        keys = (self.cells - low) @ mult  # ascending: the cells are sorted lexicographically
        q = (ijk[inside] - low) @ mult
        at = np.minimum(np.searchsorted(keys, q), len(keys) - 1)
        hit = keys[at] == q
        idx = np.flatnonzero(inside)[hit]
        out[idx] = self.label[at[hit]]
        return out


def dbscan_grid(features: np.ndarray, eps: float, min_samples: float, sample_weight: np.ndarray,
                leaf_size: int = 30, with_cells: bool = False):
    """``(labels, core_sample_indices)`` equal to ``DBSCAN(eps, min_samples=min_samples,
    algorithm="kd_tree", leaf_size=leaf_size).fit(features, sample_weight=sample_weight)``
    (module docstring); with ``with_cells``, a third item: the :class:`CoreCells` of the result."""
    x = np.ascontiguousarray(features, dtype=np.float64)
    w = np.ascontiguousarray(sample_weight, dtype=np.float64)
    n = x.shape[0]
    side = _side(eps, x.shape[1])
    if n == 0:
        empty = np.empty(0, dtype=np.int64)
        return (empty, empty, CoreCells(side, np.empty((0, x.shape[1]), np.int64), empty)) if with_cells else (empty, empty)
    k = _kernels()
    r2 = eps * eps  # scikit-learn's _dist_to_rdist for the Euclidean metric
    order, start, cell_of, cells = _grid(x, eps)
    ptr, cand = _candidates(cells, x.shape[1])
    core, amb = k.core_points(x, w, r2, order, start, ptr, cand,
                                 float(min_samples) * (1.0 - _TIE), float(min_samples) * (1.0 + _TIE))
    if amb.any():  # counts at a hair of the threshold: scikit-learn's own sum decides
        idx = np.flatnonzero(amb)
        core[idx] = _exact_counts(x, eps, w, idx, leaf_size) >= min_samples
    root = k.link_cells(x, core, r2, order, start, ptr, cand)
    labels = np.full(n, -1, dtype=np.int64)
    core_idx = np.flatnonzero(core)
    if core_idx.size:
        labels = _number_components(root[cell_of[core_idx]], core_idx, labels)
        labels = k.border_labels(x, core, labels, r2, cell_of, start, order, ptr, cand)
    if not with_cells:
        return labels, core_idx
    return labels, core_idx, CoreCells(side, cells, k.uniform_labels(core, labels, order, start, ptr, cand))


def _number_components(comp: np.ndarray, core_idx: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Labels of the core points from their components' roots ``comp`` (``core_idx`` ascending)."""
    # a component's label: the rank of its smallest core index (core_idx ascending: first seen)
    roots, first = np.unique(comp, return_index=True)
    label_of_root = np.empty(roots.size, dtype=np.int64)
    label_of_root[np.argsort(first, kind="stable")] = np.arange(roots.size)
    labels[core_idx] = label_of_root[np.searchsorted(roots, comp)]
    return labels
