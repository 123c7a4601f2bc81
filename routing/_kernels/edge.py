"""Compiled edge times: the weather of a node or a point at a time, and the time to sail an edge.

The edge model, exactly as computed here (by the search for mesh edges, and by
:mod:`routing._kernels.walk` for any piece of a polyline):

* **Weather in time** is linear between the weather slices (held after the last one).
* **Sub-slices.** The weather step dt is cut into m = ceil(dt / 0.25 h) equal sub-steps tau
  (:data:`routing._kernels.core.SUBSTEP_MAX_H`: m = 4 for hourly data, 12 for 3-hourly); the
  weather at sub-slice j is the weather at time j tau.
* **Travel time.** An edge (or piece) of length L [nmi] and initial course (cos, sin) left at
  time t takes ``c_j = L * pace(mean of its two ends' sea state and current at sub-slice j)``
  hours, j = round(t / tau) the nearest sub-slice (:func:`routing._kernels.speed.pace`; the
  ends' sea-state magnitudes, direction components and current components are averaged, not
  their paces). So the weather is read at most tau / 2 (7.5 min) from the departure, and the
  arrival ``a(t) = t + c_j(t)`` increases with t between the times ``(j - 1/2) tau`` where j
  changes and the travel time jumps.
* **Waiting (FIFO).** A ship may always sail slower or wait, so a later arrival is never forced:
  with ``wait`` the arrival is ``A(t) = min over t' >= t of a(t')`` ([1]; a ship that leaves at t
  and arrives at A(t) sails the edge at the mean speed L / (A(t) - t)). A is non-decreasing
  (FIFO), which makes label-setting search exact ([1], [2]). a increases between its jumps, so
  its minimum over [t, oo) is at t or at the start of a later piece:
  ``A(t) = min(a(t), min over j' > j of (j' - 1/2) tau + c_j')``, over the pieces starting
  before ``a(t) - L pace_min`` (pace_min: the least pace any edge can have, so later
  departures cannot arrive before a(t)) -- exact, not sampled.
* Without ``wait`` (a ship that never waits) ``A(t) = a(t)``, which is not FIFO under
  Bowditch's sectors or Aertssen's Beaufort classes (on Storm Gloria, leaving 3 minutes later
  can arrive over an hour earlier). ``step`` (SIMROUTE emulation) reads the slice at or before
  t (m = 1, pieces start at the slices) and never waits.

References
----------
.. [1] A. Orda and R. Rom, "Shortest-path and minimum-delay algorithms in networks with
       time-dependent edge-length," J. ACM, vol. 37, no. 3, pp. 607-625, 1990,
       doi:10.1145/79147.214078 (unrestricted waiting at nodes: the FIFO closure min over later
       departures, and Dijkstra on it).
.. [2] I. Chabini and S. Lan, "Adaptations of the A* algorithm for the computation of fastest
       paths in deterministic discrete-time dynamic networks," IEEE Trans. Intell. Transp.
       Syst., vol. 3, no. 1, pp. 60-74, 2002, doi:10.1109/6979.994796.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from routing._kernels.core import SUBSTEP_MAX_H
from routing._kernels.speed import pace


@njit(inline="always")
def time_slot(t_h, dt_h, n_times, step):
    """Slice index i0, next index i1 and weight for time t_h (hours since slice 0); held at the ends.

    ``step`` uses the slice at or before t_h without interpolating. (Reports and safety slices.)
    """
    x = t_h / dt_h
    if x <= 0.0 or n_times == 1:
        return 0, 0, 0.0
    i0 = int(math.floor(x))
    if i0 >= n_times - 1:
        return n_times - 1, n_times - 1, 0.0
    if step:
        return i0, i0, 0.0
    return i0, i0 + 1, x - i0


@njit(inline="always")
def substeps(dt_h, n_times, step):
    """(m, tau, n_sub, phase): sub-steps per weather step, their length [h], the number of
    sub-slices, and where a piece starts (1/2: nearest sub-slice; 0 with ``step``: at or before)."""
    if step:
        return 1, dt_h, n_times, 0.0
    m = max(1, int(math.ceil(dt_h / SUBSTEP_MAX_H - 1e-9)))
    return m, dt_h / m, (n_times - 1) * m + 1, 0.5


@njit(inline="always")
def sub_index(t, tau, n_sub, phase):
    """Sub-slice whose piece holds time t: floor(t / tau + phase), within 0 .. n_sub - 1."""
    j = int(math.floor(t / tau + phase))
    if j < 0:
        return 0
    if j > n_sub - 1:
        return n_sub - 1
    return j


@njit(inline="always")
def sub_slices(j, m, n_times):
    """Sub-slice j as slices k0, k1 (= k0 + 1, held at the end) and the fraction between them."""
    k0 = min(j // m, n_times - 1)
    k1 = min(k0 + 1, n_times - 1)
    f = (j - k0 * m) / m if k1 > k0 else 0.0
    return k0, k1, f


@njit(inline="always")
def node_slice(s, k, wave, cur, has_cur):
    """Sea state (mag, cos, sin) and current (u, v) at sea-node row s in weather slice k.

    ``wave`` is (T, n_sea, 3), ``cur`` is (T, n_sea, 2) or a (1, 1, 2) array of zeros read at
    [0, 0] when there is no current (an unconditional load compiles to much faster code than a
    load under a runtime flag).
    """
    fc = 1 if has_cur else 0
    # float64 (numba's float() keeps float32): the means below must not round in float32
    return (np.float64(wave[k, s, 0]), np.float64(wave[k, s, 1]), np.float64(wave[k, s, 2]), np.float64(cur[k * fc, s * fc, 0]),
            np.float64(cur[k * fc, s * fc, 1]))  # fmt: skip


@njit(inline="always")
def _lerp(a, b, f):
    return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2]), a[3] + f * (b[3] - a[3]),
            a[4] + f * (b[4] - a[4]))  # fmt: skip


@njit(inline="always")
def node_at(s, j, m, n_times, wave, cur, has_cur):
    """Weather tuple of sea-node row s at sub-slice j."""
    k0, k1, f = sub_slices(j, m, n_times)
    a = node_slice(s, k0, wave, cur, has_cur)
    if f == 0.0:
        return a
    return _lerp(a, node_slice(s, k1, wave, cur, has_cur), f)


@njit(inline="always")
def frame_lon(lon, lon_mid):
    """``lon`` [deg] in the mesh's continuous longitude frame: within 180 deg of ``lon_mid``."""
    d = (lon - lon_mid + 180.0) % 360.0 - 180.0
    return lon_mid + d


@njit
def sample_weights(lat, lon, lat0, lon0, dlat, dlon, ny, nx, sea_index):
    """Rows and normalised bilinear weights of the sea nodes around (lat, lon) [deg].

    Returns ``(s0, s1, s2, s3, w0, w1, w2, w3)``; nodes without a weather row get weight 0, and
    the weights of the others sum to 1 (all 0 when none has weather).
    """
    y = (lat - lat0) / dlat
    x = (lon - lon0) / dlon
    ry = round(y)
    rx = round(x)
    if abs(y - ry) < 1e-7:
        y = ry
    if abs(x - rx) < 1e-7:
        x = rx
    j0 = min(max(int(math.floor(y)), 0), ny - 2)
    i0 = min(max(int(math.floor(x)), 0), nx - 2)
    fy = min(max(y - j0, 0.0), 1.0)
    fx = min(max(x - i0, 0.0), 1.0)
    n00 = j0 * nx + i0
    s0 = np.int64(sea_index[n00])
    s1 = np.int64(sea_index[n00 + 1])
    s2 = np.int64(sea_index[n00 + nx])
    s3 = np.int64(sea_index[n00 + nx + 1])
    w0 = (1.0 - fy) * (1.0 - fx) if s0 >= 0 else 0.0
    w1 = (1.0 - fy) * fx if s1 >= 0 else 0.0
    w2 = fy * (1.0 - fx) if s2 >= 0 else 0.0
    w3 = fy * fx if s3 >= 0 else 0.0
    wsum = w0 + w1 + w2 + w3
    if wsum > 0.0:
        w0 /= wsum
        w1 /= wsum
        w2 /= wsum
        w3 /= wsum
    return s0, s1, s2, s3, w0, w1, w2, w3


@njit
def _row_slice(row, w, k, wave, cur, fc):
    """w times the weather tuple of sea row ``row`` at slice k (zeros for no row or no weight)."""
    if row < 0 or w <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    return (w * np.float64(wave[k, row, 0]), w * np.float64(wave[k, row, 1]), w * np.float64(wave[k, row, 2]),
            w * np.float64(cur[k * fc, row * fc, 0]), w * np.float64(cur[k * fc, row * fc, 1]))  # fmt: skip


@njit
def sample_slice(sw, k, wave, cur, has_cur):
    """Weather tuple (mag, cos, sin, cur_u, cur_v) at slice k of a :func:`sample_weights` point."""
    fc = 1 if has_cur else 0
    a = _row_slice(sw[0], sw[4], k, wave, cur, fc)
    b = _row_slice(sw[1], sw[5], k, wave, cur, fc)
    c = _row_slice(sw[2], sw[6], k, wave, cur, fc)
    d = _row_slice(sw[3], sw[7], k, wave, cur, fc)
    return (a[0] + b[0] + c[0] + d[0], a[1] + b[1] + c[1] + d[1], a[2] + b[2] + c[2] + d[2], a[3] + b[3] + c[3] + d[3],
            a[4] + b[4] + c[4] + d[4])  # fmt: skip


@njit
def _row_hs(row, w, i0, i1, wt, hs):
    if row < 0 or w <= 0.0:
        return 0.0
    return w * ((1.0 - wt) * hs[i0, row] + wt * hs[i1, row])


@njit
def sample_hs(sw, i0, i1, wt, hs):
    """Hs [m] at a :func:`sample_weights` point, linear in time between slices i0 and i1."""
    return (_row_hs(sw[0], sw[4], i0, i1, wt, hs) + _row_hs(sw[1], sw[5], i0, i1, wt, hs) + _row_hs(sw[2], sw[6], i0, i1, wt, hs)
            + _row_hs(sw[3], sw[7], i0, i1, wt, hs))  # fmt: skip


@njit
def point_at(sw, j, m, n_times, wave, cur, has_cur):
    """Weather tuple of a :func:`sample_weights` point at sub-slice j."""
    k0, k1, f = sub_slices(j, m, n_times)
    a = sample_slice(sw, k0, wave, cur, has_cur)
    if f == 0.0:
        return a
    return _lerp(a, sample_slice(sw, k1, wave, cur, has_cur), f)


@njit(inline="always")
def mean_pace(ship, min_sog, a, b, has_cur, ch, sh):
    """Pace [h/nmi] in the mean of two weather tuples ``a`` and ``b``."""
    return pace(ship, min_sog, 0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2]), 0.5 * (a[3] + b[3]),
                0.5 * (a[4] + b[4]), has_cur, ch, sh)  # fmt: skip


@njit
def node_wait(ship, min_sog, lower, L, arr, j, su, sv, wave, cur, has_cur, ch, sh, m, tau, n_sub, phase, n_times):
    """The FIFO arrival of a mesh edge between sea-node rows ``su`` and ``sv`` left in sub-slice
    j's piece and arriving at ``arr`` without waiting: min over the later pieces that start before
    ``arr - lower`` (``lower`` = L pace_min). Called by the searches only when such a piece
    exists: out of line, it keeps their loop small (an inlined helper doubled their time). The
    twin of :func:`arrival`'s loop for mesh nodes: reading a node as a one-row point there made
    R6's searches 1.5 times slower."""
    for jj in range(j + 1, n_sub):
        tj = (jj - phase) * tau
        if tj + lower >= arr:
            break
        a = tj + L * mean_pace(ship, min_sog, node_at(su, jj, m, n_times, wave, cur, has_cur),
                               node_at(sv, jj, m, n_times, wave, cur, has_cur), has_cur, ch, sh)  # fmt: skip
        if a < arr:
            arr = a
    return arr


@njit
def arrival(ship, min_sog, pace_min, L, t, swa, swb, wave, cur, has_cur, ch, sh, dt_h, n_times, step, wait):
    """Arrival at the end of an edge or piece left at t (see the module docstring for the model),
    its ends given as :func:`sample_weights` points."""
    m, tau, n_sub, phase = substeps(dt_h, n_times, step)
    j = sub_index(t, tau, n_sub, phase)
    arr = t + L * mean_pace(ship, min_sog, point_at(swa, j, m, n_times, wave, cur, has_cur),
                            point_at(swb, j, m, n_times, wave, cur, has_cur), has_cur, ch, sh)  # fmt: skip
    if wait:
        lower = L * pace_min
        for jj in range(j + 1, n_sub):
            tj = (jj - phase) * tau
            if tj + lower >= arr:
                break
            a = tj + L * mean_pace(ship, min_sog, point_at(swa, jj, m, n_times, wave, cur, has_cur),
                                   point_at(swb, jj, m, n_times, wave, cur, has_cur), has_cur, ch, sh)  # fmt: skip
            if a < arr:
                arr = a
    return arr
