"""Traffic lanes: DBSCAN on position and motion, per origin-destination pair.

The seed paper [3] (§3.1, after Kontopoulos et al. and Varlamis et al. [2]) clusters
the interpolated points of all voyages between the same two waypoints with a modified DBSCAN
over location, speed and heading; each cluster is an area where vessels move at a certain speed
and course, and its centroid sequence is the route network. This module does the same with a
metric chosen so that an ordinary, index-accelerated DBSCAN [1] computes it.

The metric (why a scaled Euclidean space). Each resampled point becomes a 6-vector

    ( R/eps_nmi * (x, y, z),  v/eps_speed_kn,  (sin c, cos c) / (2 sin(eps_course/2)) )

with ``(x, y, z)`` the position as a unit vector (R the Earth radius in nmi), ``v`` the speed
and ``c`` the course. DBSCAN then runs with ``eps = 1`` and the Euclidean distance, so two points
are neighbours when

    (d/eps_nmi)^2 + (dv/eps_speed_kn)^2 + (chord(dc)/chord(eps_course))^2 <= 1,

where ``d`` is the chord between the positions (equal to the great-circle distance to better
than 1e-6 relative at lane scales) and ``chord(dc) = 2 sin(dc/2)`` is monotone in the course
difference ``dc`` in [0, 180] deg. Consequences:

* every single difference is bounded by its own eps (distance <= eps_nmi, speed difference <=
  eps_speed_kn, course difference <= eps_course_deg), like the paper's conjunction of bounds;
  jointly they form an ellipsoid, so a pair at the limit of two bounds at once is not a
  neighbour (slightly stricter than the conjunction);
* the course is circular: 359 deg and 1 deg are 2 deg apart, because the course enters through
  its unit vector, never as a raw angle;
* it is a true metric (a Euclidean distance in an embedding), so density-connectivity is well
  defined and sklearn's k-d tree answers the neighbourhood queries: memory grows with the number
  of neighbours, not with n^2.

A custom callable metric would express the plain conjunction but runs in Python per pair of
points (orders of magnitude slower) and forbids the tree indices.

Density in voyages. DBSCAN's core condition counts points, and how many points one voyage puts
into an eps-ball depends on its speed and on the resampling step. Each point is therefore weighted
by the fraction of the ball's diameter that its time step covers, ``w = min(1, v * step /
(2 eps_nmi))`` (sklearn's ``sample_weight``), so one voyage passing through a ball weighs about 1
whatever its speed or the step, and ``min_density`` is the number of voyages that must pass close
by (in position, speed and course) for a point to be a core point. The same threshold then means
the same thing at a 60 s step in a harbour and at a 300 s step at sea.

Memory and time bound. DBSCAN runs on a grid of cells of diameter eps (:mod:`lanes.dbscan_grid`,
the same labels as scikit-learn's ``DBSCAN``): a cell heavy enough to be dense holds only core
points, linked without listing their neighbours, so the cost grows with the occupied cells rather
than with the points times their neighbours. A partition with more than
``max_points`` points is clustered on a deterministic uniform sample of ``max_points`` points,
their weights multiplied by ``n / max_points``, so the core-point condition (sum of weights in
the eps-ball >= ``min_density``) estimates the same density; the other points take the label of
their nearest core sample within eps (else noise). The sample is seeded from the partition key, so
results do not depend on how the data was partitioned.

Legs of one route. Within an origin-destination partition, the same voyages can fall into
several clusters: the slow harbour approach at each end (its speed differs from the sea passage
by more than ``eps_speed_kn``), or the legs on either side of a sharp turn. They are one lane: the
route those voyages sail between the two ports, with a typical speed per centroid that now
includes the approach. So a smaller cluster whose voyages are, for at least
``merge_voyage_share`` of them, also voyages of a larger cluster is merged into it (largest
first). Voyages that take different routes between the same ports (or sail the same route at
different speeds) share no voyages and stay separate lanes. The transit partition is not merged
(its "voyages" are open tracks that may pass through several lanes), nor are loops (a loop's
outbound and return legs are the same voyages, but opposite lanes).

Lanes. Clusters with fewer than ``min_voyages`` voyages, or too short to give two centroids,
become noise. Each remaining cluster is one lane: mean speed, circular mean course, point / voyage / vessel counts, and an ordered
centroid sequence. To order the points along a lane that may bend, they are projected on a
reference track (the member voyage run with the longest path inside the cluster): the arc length
of the nearest reference vertex is the along-lane coordinate, cut into bins of
``centroid_spacing_nmi`` (shorter for short lanes, at least ``min_centroids`` bins). Each bin
gives a centroid: the spherical mean position, the median speed (the "typical speed" at that
centroid) and the circular mean course. The lane polygon is the centroid polyline buffered by
the ``width_quantile`` of the cross-track distances of the lane's points.

Partitions. Points are grouped by (origin port, destination port). Voyages with a missing end
(before the first call, after the last, split at a gap) and transit tracks from areas without
ports (the Ushant traffic separation scheme) form one more partition, "transit", where the lanes
come out of the same metric: opposite directions of a two-way scheme separate on the course term
(their courses differ by about 180 deg, far beyond ``eps_course_deg``).

References
----------
.. [1] M. Ester, H.-P. Kriegel, J. Sander and X. Xu, "A density-based algorithm for discovering
       clusters in large spatial databases with noise," in Proc. KDD-96, pp. 226-231, 1996.
.. [2] I. Varlamis, K. Tserpes, M. Etemad, A. Soares Júnior and S. Matwin, "A network
       abstraction of multi-vessel trajectory data for detecting anomalies," in Proc. EDBT/ICDT
       Workshops, 2019 (reference [22] of the seed paper).
.. [3] K. Spyrou-Sioula, I. Kontopoulos, D. Kaklis, A. Makris, K. Tserpes, P. Eirinakis and
       F. Oikonomou, "AIS-enabled weather routing for cargo loss prevention," J. Mar. Sci. Eng.,
       vol. 10, no. 11, 1755, 2022, doi:10.3390/jmse10111755 (seed
       ``ais_weather_routing_cargo_loss``), §3.1, Figures 1-2.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from lanes._geo import (
    circular_means_deg,
    latlon_from_local_xy,
    local_xy_nmi,
    spherical_means,
    time_seconds,
    unit_vectors,
)
from thresholds.geodesy import haversine_nmi
from thresholds.units import EARTH_RADIUS_NMI

LANE_COLUMNS = [
    "lane_id", "origin_port_id", "dest_port_id", "kind", "n_points", "n_voyages", "n_vessels",
    "mean_speed_kn", "mean_course_deg", "course_r", "length_nmi", "width_nmi", "n_centroids",
    "polygon_wkt",
]
CENTROID_COLUMNS = ["lane_id", "seq", "lat_deg", "lon_deg", "speed_kn", "course_deg", "n_points", "n_voyages", "along_nmi"]

#: Partition key of the points whose voyage lacks an origin or a destination.
TRANSIT = (0, 0)


@dataclass(frozen=True)
class LaneParams:
    """Parameters of lane extraction (units in the names); see the module docstring."""

    eps_nmi: float = 2.0
    eps_speed_kn: float = 3.0
    eps_course_deg: float = 20.0
    min_density: float = 3.0
    min_voyages: int = 3
    min_speed_kn: float = 1.0
    max_points: int = 150_000
    centroid_spacing_nmi: float = 5.0
    min_centroids: int = 5
    min_centroid_points: int = 3
    width_quantile: float = 0.9
    min_width_nmi: float = 0.05
    include_loops: bool = True
    merge_voyage_share: float = 0.8
    seed: int = 0

    def __post_init__(self):
        for name in ("eps_nmi", "eps_speed_kn", "eps_course_deg", "min_density", "centroid_spacing_nmi"):
            if not getattr(self, name) > 0:
                raise ValueError(f"LaneParams.{name} must be positive, got {getattr(self, name)!r}")
        if not 0 < self.eps_course_deg < 180:
            raise ValueError("LaneParams.eps_course_deg must be in (0, 180)")
        if self.max_points < 100:
            raise ValueError("LaneParams.max_points must be at least 100")
        if not 0 < self.width_quantile <= 1:
            raise ValueError("LaneParams.width_quantile must be in (0, 1]")
        if not 0 <= self.merge_voyage_share <= 1:
            raise ValueError("LaneParams.merge_voyage_share must be in [0, 1] (0 = never merge)")
        if self.min_voyages < 1 or self.min_centroids < 1 or self.min_centroid_points < 1:
            raise ValueError("LaneParams.min_voyages, min_centroids and min_centroid_points must be at least 1")


@dataclass
class LaneResult:
    """Lanes, their centroids, and the lane of every input point (``None`` = noise)."""

    lanes: pd.DataFrame
    centroids: pd.DataFrame
    point_lane: np.ndarray
    n_noise: int
    n_slow: int = 0
    n_sampled_partitions: int = 0
    partitions: dict = field(default_factory=dict)


def motion_features(lat_deg, lon_deg, speed_kn, course_deg, params: LaneParams) -> np.ndarray:
    """The scaled 6-D embedding of the module docstring (rows = points)."""
    xyz = unit_vectors(lat_deg, lon_deg) * (EARTH_RADIUS_NMI / params.eps_nmi)
    v = np.asarray(speed_kn, dtype=float)[:, None] / params.eps_speed_kn
    c = np.deg2rad(np.asarray(course_deg, dtype=float))
    chord_eps = 2.0 * np.sin(np.deg2rad(params.eps_course_deg) / 2.0)
    sc = np.column_stack([np.sin(c), np.cos(c)]) / chord_eps
    return np.hstack([xyz, v, sc])


def partition_key(origin_port_id: int, dest_port_id: int, include_loops: bool = True) -> tuple[int, int]:
    """The partition a voyage's points belong to: its (origin, destination) or :data:`TRANSIT`."""
    o, d = int(origin_port_id), int(dest_port_id)
    if o > 0 and d > 0 and (o != d or include_loops):
        return (o, d)
    return TRANSIT


def _seed(key: tuple[int, int], seed: int) -> int:
    return zlib.crc32(f"{key[0]}-{key[1]}-{seed}".encode())


#: Weights are scaled by this factor so that sklearn's integer ``min_samples`` can express a
#: fractional ``min_density`` (resolution 0.01 voyage).
_WEIGHT_SCALE = 100.0


def point_weights(speed_kn: np.ndarray, step_s: float, eps_nmi: float) -> np.ndarray:
    """Weight of each point in voyage units: ``min(1, v * step / (2 eps))`` (module docstring)."""
    return np.minimum(1.0, np.asarray(speed_kn, dtype=float) * (step_s / 3600.0) / (2.0 * eps_nmi))


def dbscan_labels(features: np.ndarray, weights: np.ndarray, params: LaneParams,
                  key: tuple[int, int]) -> tuple[np.ndarray, bool]:
    """DBSCAN labels with ``eps = 1`` in the scaled space, weighted, sampled above ``max_points``."""
    from sklearn.neighbors import KDTree

    from lanes.dbscan_grid import dbscan_grid

    n = features.shape[0]
    if n == 0:
        return np.empty(0, dtype=np.int64), False
    min_samples = max(1, int(round(params.min_density * _WEIGHT_SCALE)))
    # scikit-learn's DBSCAN (k-d tree) labels, computed on a grid of cells so that a dense
    # partition never lists every neighbourhood (lanes.dbscan_grid)
    if n <= params.max_points:
        return dbscan_grid(features, 1.0, min_samples, weights * _WEIGHT_SCALE)[0], False
    rng = np.random.default_rng(_seed(key, params.seed))
    sample = np.sort(rng.choice(n, size=params.max_points, replace=False))
    scale = n / params.max_points
    sample_labels, sample_core, cells = dbscan_grid(features[sample], 1.0, min_samples,
                                                    weights[sample] * scale * _WEIGHT_SCALE, with_cells=True)
    labels = np.full(n, -1, dtype=np.int64)
    labels[sample] = sample_labels
    core = sample[sample_core]
    rest = np.setdiff1d(np.arange(n), sample, assume_unique=True)
    if core.size and rest.size:
        # the label of the nearest core sample within eps: settled by the grid where every core
        # sample within reach has one label (lanes.dbscan_grid.CoreCells), else by a k-d tree
        settled = cells.labels_of(features[rest])
        labels[rest] = settled
        rest = rest[settled < 0]
        tree = KDTree(features[core]) if rest.size else None
        for s in range(0, rest.size, 200_000):
            part = rest[s:s + 200_000]
            dist, idx = tree.query(features[part], k=1)
            near = dist[:, 0] <= 1.0
            labels[part[near]] = labels[core[idx[near, 0]]]
    return labels, True


def merge_shared_voyage_clusters(labels: np.ndarray, voyages: np.ndarray, share: float) -> np.ndarray:
    """Merge each cluster into a larger one that holds ``share`` of its voyages (module docstring).

    Clusters are visited from the most voyages to the fewest (ties: most points, then lowest
    label); a cluster is merged into the first already-kept cluster whose voyages include at least
    ``share`` of its own (and whose label it then takes). ``-1`` (noise) is left alone.

    Returns
    -------
    ndarray
        New labels (a copy); label values are those of the kept clusters.
    """
    labels = np.asarray(labels, dtype=np.int64).copy()
    inside = labels >= 0
    if not inside.any():
        return labels
    pairs = pd.DataFrame({"label": labels[inside], "voyage": voyages[inside]})
    sets = pairs.groupby("label")["voyage"].agg(lambda v: frozenset(v.tolist()))
    n_points = pairs.groupby("label").size()
    order = sorted(sets.index, key=lambda c: (-len(sets[c]), -int(n_points[c]), int(c)))
    kept: list[int] = []
    target = {}
    for c in order:
        own = sets[c]
        into = next((k for k in kept if len(own & sets[k]) >= share * len(own)), None)
        if into is None:
            kept.append(c)
        else:
            target[c] = into
    for c, into in target.items():
        labels[labels == c] = into
    return labels


def resample_step_s(points: pd.DataFrame, default: float = 300.0) -> float:
    """The resampling step of the points: median time difference within a voyage run. [s]"""
    if len(points) < 2:
        return default
    t = time_seconds(points["time_utc"])
    same = (points["voyage"].to_numpy()[1:] == points["voyage"].to_numpy()[:-1]) & \
        (points["run"].to_numpy()[1:] == points["run"].to_numpy()[:-1])
    dt = np.diff(t)[same]
    dt = dt[dt > 0]
    return float(np.median(dt)) if dt.size else default


def extract_lanes_for_pair(points: pd.DataFrame, params: LaneParams | None = None,
                           key: tuple[int, int] | None = None) -> LaneResult:
    """Lanes of one partition (one origin-destination pair, or the transit partition).

    Parameters
    ----------
    points : DataFrame
        Resampled points of the partition (:func:`lanes.interpolate.resample_voyages`), at least
        ``voyage``, ``track``, ``time_utc``, ``lat_deg``, ``lon_deg``, ``speed_kn``,
        ``course_deg``, ``run``.
    params : LaneParams
    key : (origin_port_id, dest_port_id), optional
        The partition; taken from the points when omitted (0 = unknown end).

    Returns
    -------
    LaneResult
        ``point_lane`` is aligned with ``points`` (same order).
    """
    params = params or LaneParams()
    n = len(points)
    if key is None:
        key = TRANSIT if n == 0 else partition_key(points["origin_port_id"].iloc[0], points["dest_port_id"].iloc[0], True)
    point_lane = np.full(n, None, dtype=object)
    empty = LaneResult(_empty(LANE_COLUMNS), _empty(CENTROID_COLUMNS), point_lane, 0)
    if n == 0:
        return empty
    # Canonical order, so that the result does not depend on how the rows arrived.
    order = np.lexsort((time_seconds(points["time_utc"]), points["voyage"].astype(str).to_numpy()))
    p = points.iloc[order].reset_index(drop=True)
    speed = p["speed_kn"].to_numpy(dtype=float)
    course = p["course_deg"].to_numpy(dtype=float)
    moving = np.isfinite(speed) & np.isfinite(course) & (speed >= params.min_speed_kn)
    n_slow = int((~moving).sum())
    labels = np.full(n, -1, dtype=np.int64)
    sampled = False
    if moving.sum() >= 1:
        mv = np.flatnonzero(moving)
        feats = motion_features(p["lat_deg"].to_numpy(dtype=float)[mv], p["lon_deg"].to_numpy(dtype=float)[mv],
                                speed[mv], course[mv], params)
        weights = point_weights(speed[mv], resample_step_s(p), params.eps_nmi)
        lab, sampled = dbscan_labels(feats, weights, params, key)
        labels[mv] = lab

    voyages = p["voyage"].to_numpy()
    if key != TRANSIT and key[0] != key[1] and params.merge_voyage_share > 0:
        labels = merge_shared_voyage_clusters(labels, voyages, params.merge_voyage_share)
    # Clusters supported by too few voyages are noise.
    if (labels >= 0).any():
        inside = labels >= 0
        nvoy = pd.Series(voyages[inside]).groupby(labels[inside]).nunique()
        small = nvoy.index[nvoy < params.min_voyages].to_numpy()
        labels[np.isin(labels, small)] = -1

    inside = np.flatnonzero(labels >= 0)
    lane_rows, centroid_frames = [], []
    p_lane = np.full(n, None, dtype=object)
    if inside.size:
        # Group the member points per cluster once (stable: canonical order within a cluster).
        by_cluster = inside[np.argsort(labels[inside], kind="stable")]
        uniq, first_pos, counts = np.unique(labels[by_cluster], return_index=True, return_counts=True)
        # Lane numbering: most points first, ties by the first voyage id of the cluster.
        first_voy = [str(voyages[by_cluster[f]]) for f in first_pos]
        rank = sorted(range(uniq.size), key=lambda i: (-counts[i], first_voy[i]))
        cols = {
            "lat": p["lat_deg"].to_numpy(dtype=float),
            "lon": p["lon_deg"].to_numpy(dtype=float),
            "speed": speed,
            "course": course,
            "voyage": pd.factorize(voyages)[0],
            "piece": pd.factorize(pd.Series(voyages).astype(str) + "#" + p["run"].astype(str))[0],
            "track": pd.factorize(p["track"])[0],
        }
        k = 0
        for i in rank:
            m = by_cluster[first_pos[i]:first_pos[i] + counts[i]]
            lane, cents = _build_lane({c: v[m] for c, v in cols.items()}, _lane_id(key, k + 1), key, params)
            if lane is None:  # no extent: a lane needs at least two centroids
                labels[m] = -1
                continue
            k += 1
            lane_rows.append(lane)
            centroid_frames.append(cents)
            p_lane[m] = lane[0]
    point_lane[order] = p_lane
    lanes = pd.DataFrame(lane_rows, columns=LANE_COLUMNS) if lane_rows else _empty(LANE_COLUMNS)
    cents = pd.concat(centroid_frames, ignore_index=True) if centroid_frames else _empty(CENTROID_COLUMNS)
    n_noise = int((labels < 0).sum())
    return LaneResult(lanes, cents, point_lane, n_noise, n_slow, int(sampled),
                      {key: {"points": n, "lanes": len(lanes), "noise_points": n_noise, "sampled": sampled}})


def _lane_id(key: tuple[int, int], k: int) -> str:
    if key == TRANSIT:
        return f"T-{k}"
    return f"{key[0]}-{key[1]}-{k}"


def _empty(columns) -> pd.DataFrame:
    return pd.DataFrame({c: pd.Series(dtype=object) for c in columns})


def group_medians(codes: np.ndarray, values: np.ndarray, n_groups: int) -> np.ndarray:
    """Median of ``values`` per integer group code (NaN for empty groups)."""
    order = np.lexsort((values, codes))
    sc = codes[order]
    sv = values[order]
    counts = np.bincount(sc, minlength=n_groups)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    out = np.full(n_groups, np.nan)
    ok = counts > 0
    lo = starts[ok] + (counts[ok] - 1) // 2
    hi = starts[ok] + counts[ok] // 2
    out[ok] = 0.5 * (sv[lo] + sv[hi])
    return out


def reference_track(lat: np.ndarray, lon: np.ndarray, piece: np.ndarray) -> np.ndarray:
    """Positions of the member piece (a voyage run) that crosses the lane furthest.

    The score is the great-circle distance between the piece's first and last point in the lane
    (net displacement), so a ship that goes straight through beats one that wanders about.
    ``piece`` codes must be contiguous (points in voyage, time order).
    """
    starts = np.flatnonzero(np.r_[True, piece[1:] != piece[:-1]])
    ends = np.r_[starts[1:] - 1, piece.size - 1]
    net = haversine_nmi(lat[starts], lon[starts], lat[ends], lon[ends])
    best = int(np.argmax(net))
    return np.arange(starts[best], ends[best] + 1)


def nearest_vertex(lat: np.ndarray, lon: np.ndarray, ref_lat: np.ndarray, ref_lon: np.ndarray) -> np.ndarray:
    """Index of the nearest reference vertex for every point (largest dot product of unit vectors)."""
    u = unit_vectors(lat, lon)
    r = unit_vectors(ref_lat, ref_lon)
    if u.shape[0] * r.shape[0] <= 4_000_000:
        return np.argmax(u @ r.T, axis=1)
    from sklearn.neighbors import KDTree

    return KDTree(r).query(u, k=1, return_distance=False)[:, 0]


def _build_lane(c: dict, lane_id: str, key: tuple[int, int], params: LaneParams):
    """One lane row and its centroid sequence from the lane's points (arrays in ``c``)."""
    from shapely import LineString, distance, points as shp_points

    lat, lon, speed, course = c["lat"], c["lon"], c["speed"], c["course"]
    n = lat.size
    zeros = np.zeros(n, dtype=np.int64)
    mean_course, r = circular_means_deg(zeros, course, 1)
    (lat0,), (lon0,) = spherical_means(zeros, lat, lon, 1)
    px, py = local_xy_nmi(lat, lon, lat0, lon0)

    # Along-lane coordinate: arc length of the nearest vertex of the reference track.
    ref = reference_track(lat, lon, c["piece"])
    ref_lat, ref_lon = lat[ref], lon[ref]
    ref_s = np.r_[0.0, np.cumsum(haversine_nmi(ref_lat[:-1], ref_lon[:-1], ref_lat[1:], ref_lon[1:]))] if ref.size > 1 else np.zeros(1)
    s = ref_s[nearest_vertex(lat, lon, ref_lat, ref_lon)]
    total = float(ref_s[-1])
    spacing = params.centroid_spacing_nmi
    if total > 0:
        spacing = min(spacing, total / params.min_centroids)
    spacing = max(spacing, 1e-6)
    ub, codes = np.unique(np.floor(s / spacing).astype(np.int64), return_inverse=True)
    nb = ub.size
    counts = np.bincount(codes, minlength=nb)
    # Robust centre of each bin: coordinate-wise median in the local plane.
    cx = group_medians(codes, px, nb)
    cy = group_medians(codes, py, nb)
    clat, clon = latlon_from_local_xy(cx, cy, lat0, lon0)
    ccourse, _ = circular_means_deg(codes, course, nb)
    cspeed = group_medians(codes, speed, nb)
    pairs = np.unique(codes.astype(np.int64) * (int(c["voyage"].max()) + 1) + c["voyage"])
    cvoy = np.bincount(pairs // (int(c["voyage"].max()) + 1), minlength=nb)
    calong = np.bincount(codes, weights=s, minlength=nb) / counts
    keep = counts >= params.min_centroid_points
    if keep.sum() < 2:
        return None, None
    cents = pd.DataFrame({
        "lane_id": lane_id,
        "seq": np.arange(int(keep.sum()), dtype=np.int64),
        "lat_deg": clat[keep],
        "lon_deg": clon[keep],
        "speed_kn": cspeed[keep],
        "course_deg": ccourse[keep],
        "n_points": counts[keep].astype(np.int64),
        "n_voyages": cvoy[keep].astype(np.int64),
        "along_nmi": calong[keep],
    })

    # Polygon: centroid polyline buffered by the cross-track width, in the local plane.
    kx, ky = cx[keep], cy[keep]
    geom = LineString(np.column_stack([kx, ky]))
    width = float(np.quantile(distance(shp_points(np.column_stack([px, py])), geom), params.width_quantile))
    width = max(width, params.min_width_nmi)
    poly = geom.buffer(width, quad_segs=4).simplify(width * 0.05)
    ex, ey = np.asarray(poly.exterior.coords).T
    plat, plon = latlon_from_local_xy(ex, ey, lat0, lon0)
    wkt = "POLYGON ((" + ", ".join(f"{a:.5f} {b:.5f}" for a, b in zip(plon, plat)) + "))"
    length = float(np.sum(haversine_nmi(clat[keep][:-1], clon[keep][:-1], clat[keep][1:], clon[keep][1:])))
    kind = "transit" if key == TRANSIT else ("loop" if key[0] == key[1] else "port_to_port")
    lane = [
        lane_id, int(key[0]), int(key[1]), kind, int(n), int(np.unique(c["voyage"]).size),
        int(np.unique(c["track"]).size), float(np.mean(speed)), float(mean_course[0]), float(r[0]), length,
        width, int(keep.sum()), wkt,
    ]
    return lane, cents


def partition_rows(points: pd.DataFrame, include_loops: bool = True) -> list[tuple[tuple[int, int], np.ndarray]]:
    """The partitions of ``points``: ``(key, row positions)`` per key, keys in ascending order.

    The key of a point is :func:`partition_key` of its voyage's ``origin_port_id`` and
    ``dest_port_id`` (0 = unknown end). Row positions are ``iloc`` positions, ascending; every row
    is in exactly one partition.
    """
    if len(points) == 0:
        return []
    o = points["origin_port_id"].to_numpy(dtype=np.int64)
    d = points["dest_port_id"].to_numpy(dtype=np.int64)
    keys = {partition_key(a, b, include_loops) for a, b in zip(*np.unique(np.column_stack([o, d]), axis=0).T)}
    out = []
    for key in sorted(keys):
        if key == TRANSIT:
            m = ~((o > 0) & (d > 0) & ((o != d) | include_loops))
        else:
            m = (o == key[0]) & (d == key[1])
        out.append((key, np.flatnonzero(m)))
    return out


def merge_lane_results(n_points: int | None, parts) -> LaneResult:
    """Merge per-partition results into the result of the whole point set (pure, deterministic).

    Parameters
    ----------
    n_points : int or None
        Number of points of the whole set (``point_lane`` of the merge has this length); ``None``:
        no ``point_lane`` (the partitions' points are not held together; ``rows`` is ignored).
    parts : iterable of (key, rows, LaneResult)
        One entry per partition: its key, its row positions in the whole set
        (:func:`partition_rows`) and :func:`extract_lanes_for_pair` of those rows.

    Returns
    -------
    LaneResult
        Lanes and centroids concatenated in ascending key order (whatever order ``parts`` came
        in, e.g. the completion order of tasks on a cluster), each point's lane scattered back to
        its row, counts summed.
    """
    point_lane = None if n_points is None else np.full(n_points, None, dtype=object)
    lanes, cents, info = [], [], {}
    n_noise = n_slow = n_sampled = 0
    for key, rows, res in sorted(parts, key=lambda part: tuple(part[0])):
        if point_lane is not None:
            point_lane[rows] = res.point_lane
        lanes.append(res.lanes)
        cents.append(res.centroids)
        n_noise += res.n_noise
        n_slow += res.n_slow
        n_sampled += res.n_sampled_partitions
        info.update(res.partitions)
    lanes = [x for x in lanes if len(x)]
    cents = [x for x in cents if len(x)]
    lanes_df = pd.concat(lanes, ignore_index=True) if lanes else _empty(LANE_COLUMNS)
    cents_df = pd.concat(cents, ignore_index=True) if cents else _empty(CENTROID_COLUMNS)
    return LaneResult(lanes_df, cents_df, point_lane, n_noise, n_slow, n_sampled, info)


def extract_lanes(points: pd.DataFrame, params: LaneParams | None = None) -> LaneResult:
    """Lanes of every partition: the driver around :func:`extract_lanes_for_pair`.

    Partitions are independent (nothing is shared but ``params``), so this is equivalent to
    running :func:`extract_lanes_for_pair` on each partition of :func:`partition_rows` separately
    (on a cluster, one task per partition, as the Prefect lanes flow does) and merging with
    :func:`merge_lane_results`, which is exactly what this function does in one process.
    """
    params = params or LaneParams()
    parts = partition_rows(points, params.include_loops)
    return merge_lane_results(len(points), [(key, rows, extract_lanes_for_pair(points.iloc[rows], params, key))
                                            for key, rows in parts])


def merge_lane_voyage_tables(tables: list[pd.DataFrame]) -> pd.DataFrame:
    """:func:`lane_voyage_table` of the whole point set from those of its partitions (lane ids
    are unique to a partition, so this is their rows in ``(lane_id, voyage_id)`` order)."""
    tables = [t for t in tables if len(t)]
    if not tables:
        return lane_voyage_table(pd.DataFrame({"voyage": pd.Series(dtype=object)}), np.empty(0, dtype=object))
    out = pd.concat(tables, ignore_index=True).sort_values(["lane_id", "voyage_id"], kind="stable")
    return out.reset_index(drop=True)


def lane_voyage_table(points: pd.DataFrame, point_lane: np.ndarray) -> pd.DataFrame:
    """Which voyages each lane was built from: ``lane_id, voyage_id, n_points``."""
    lane = pd.Series(point_lane, index=points.index, dtype=object)
    m = lane.notna().to_numpy()
    if not m.any():
        return pd.DataFrame({"lane_id": pd.Series(dtype=object), "voyage_id": pd.Series(dtype=object),
                             "n_points": pd.Series(dtype=np.int64)})
    df = pd.DataFrame({"lane_id": lane.to_numpy()[m], "voyage_id": points["voyage"].to_numpy()[m]})
    out = df.groupby(["lane_id", "voyage_id"], sort=True).size().rename("n_points").reset_index()
    out["n_points"] = out["n_points"].astype(np.int64)
    return out
