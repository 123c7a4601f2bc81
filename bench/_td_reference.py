"""A plain-Python time-dependent Dijkstra: the algorithmic reference of ``bench/routing.py``.

Written here (not taken from any project) from the edge model that the compiled core
:func:`routing._kernels.astar` computes, so that both return the same optimal time on the same
mesh and weather, and the benchmark measures only what the implementation costs:

* the search is Dijkstra with a binary heap (``heapq``), lazy deletion, nodes never reopened
  (label setting);
* the edge from ``u`` (reached at time ``t``) to ``v`` costs ``L / v_kn`` hours, ``L`` the
  edge's great-circle length [nmi]; ``v_kn`` is the attained speed in the mean of the two end
  nodes' weather (Hs and the direction's unit vector) at the sub-slice nearest to ``t`` (the
  weather step cut into ceil(dt / 0.25 h) sub-steps, the weather linear between its slices and
  held after the last one); the ship may leave later when that arrives earlier (the FIFO edge
  model of :mod:`routing._kernels.edge`: the later sub-slices whose piece starts before the
  arrival minus ``L / v0`` are tried);
* the speed is Bowditch's: ``v = v0 - f * (Hs / 0.3048)^2`` [kn, Hs in feet], ``f`` by the
  encounter sector (head within 45 deg of the bow, following within 45 deg of the stern, beam
  otherwise; the coefficients are :mod:`routing.speed_loss`'s, American Practical Navigator,
  Bowditch 2002, Table A1.1 there), never below the ship's floor speed. No currents.

It counts the edges whose cost it computes (those to nodes not yet settled), like the kernel.
"""

from __future__ import annotations

import heapq
import math

from routing import speed_loss as sl
from thresholds.units import METRES_PER_FOOT

_COS45 = math.cos(math.radians(45.0))


def td_dijkstra(mesh, wx, v0_kn: float, floor_kn: float, start: int, goal: int, t_start_h: float) -> dict:
    """Least time from ``start`` to ``goal`` on ``mesh`` in the weather ``wx`` (a
    :class:`routing.astar.WeatherArrays` without currents); returns time, expanded and computed."""
    if wx.has_cur:
        raise ValueError("the reference handles waves only (no currents)")
    nx = mesh.grid.nx
    allowed = [int(m) for m in mesh.allowed.ravel()]
    steps = [(int(dj) * nx + int(di)) for di, dj in mesh.steps]
    elen, ecos, esin = (a.tolist() for a in mesh.edge_geometry)
    sea_index = wx.sea_index.tolist()
    wave = wx.wave.tolist()  # [t][sea row] -> [hs, cos, sin]
    dt_h, n_times = float(wx.dt_h), int(wx.n_times)
    f_head, f_beam, f_fol = sl.BOWDITCH_F_HEAD_KN_FT2, sl.BOWDITCH_F_BEAM_KN_FT2, sl.BOWDITCH_F_FOLLOWING_KN_FT2
    floor = min(floor_kn, v0_kn)
    K = len(steps)

    m = max(1, int(math.ceil(dt_h / 0.25 - 1e-9)))
    tau, n_sub = dt_h / m, (n_times - 1) * m + 1

    def sub(t_h):
        return min(max(int(math.floor(t_h / tau + 0.5)), 0), n_sub - 1)

    def node(s, j):
        k0 = min(j // m, n_times - 1)
        k1 = min(k0 + 1, n_times - 1)
        f = (j - k0 * m) / m if k1 > k0 else 0.0
        a, b = wave[k0][s], wave[k1][s]
        if f == 0.0:
            return a[0], a[1], a[2]
        return a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2])

    def pace(a, b, row, k):
        hs, wc, ws = 0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])
        n = math.sqrt(wc * wc + ws * ws)
        cosa = (wc * ecos[row][k] + ws * esin[row][k]) / n if n > 1e-6 else 1.0
        f = f_head if cosa >= _COS45 else (f_fol if cosa <= -_COS45 else f_beam)
        h_ft = hs / METRES_PER_FOOT
        speed = v0_kn - f * h_ft * h_ft if hs > 0.0 else v0_kn
        return 1.0 / max(speed, floor)

    best = {start: t_start_h}
    closed = set()
    heap = [(t_start_h, start)]
    expanded = computed = 0
    while heap:
        gu, u = heapq.heappop(heap)
        if u in closed:
            continue
        closed.add(u)
        expanded += 1
        if u == goal:
            return {"time_h": gu - t_start_h, "expanded": expanded, "computed": computed}
        j = sub(gu)
        node_u = node(sea_index[u], j)
        row = u // nx
        mask = allowed[u]
        for k in range(K):
            if not (mask >> k) & 1:
                continue
            v = u + steps[k]
            if v in closed:
                continue
            computed += 1
            L = elen[row][k]
            ng = gu + L * pace(node_u, node(sea_index[v], j), row, k)  # the kernel's order of operations
            lower = L * (1.0 / v0_kn)  # no departure arrives sooner than this after it
            for jj in range(j + 1, n_sub):  # later departures (waiting), as long as one could arrive earlier
                tj = (jj - 0.5) * tau
                if tj + lower >= ng:
                    break
                ng = min(ng, tj + L * pace(node(sea_index[u], jj), node(sea_index[v], jj), row, k))
            if ng < best.get(v, math.inf):
                best[v] = ng
                heapq.heappush(heap, (ng, v))
    raise ValueError("goal not reachable")
