"""A plain-Python time-dependent Dijkstra: the algorithmic reference of ``bench/routing.py``.

Written here (not taken from any project) from the edge model that the compiled core
:func:`routing._kernels.astar` computes, so that both return the same optimal time on the same
mesh and weather, and the benchmark measures only what the implementation costs:

* the search is Dijkstra with a binary heap (``heapq``), lazy deletion, nodes never reopened
  (label setting);
* the edge from ``u`` (reached at time ``t``) to ``v`` costs ``L / v_kn`` hours, ``L`` the
  edge's great-circle length [nmi]; ``v_kn`` is the attained speed in the mean of the two end
  nodes' weather (Hs and the direction's unit vector), both taken at time ``t``, linearly
  interpolated between the weather's slices and held after the last one;
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

    def slot(t_h):
        x = t_h / dt_h
        if x <= 0.0 or n_times == 1:
            return 0, 0, 0.0
        i0 = int(math.floor(x))
        if i0 >= n_times - 1:
            return n_times - 1, n_times - 1, 0.0
        return i0, i0 + 1, x - i0

    def node(s, i0, i1, w):
        a, b = wave[i0][s], wave[i1][s]
        return a[0] * (1 - w) + b[0] * w, a[1] * (1 - w) + b[1] * w, a[2] * (1 - w) + b[2] * w

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
        i0, i1, w = slot(gu)
        hs_u, wc_u, ws_u = node(sea_index[u], i0, i1, w)
        row = u // nx
        mask = allowed[u]
        for k in range(K):
            if not (mask >> k) & 1:
                continue
            v = u + steps[k]
            if v in closed:
                continue
            computed += 1
            hs_v, wc_v, ws_v = node(sea_index[v], i0, i1, w)
            hs, wc, ws = 0.5 * (hs_u + hs_v), 0.5 * (wc_u + wc_v), 0.5 * (ws_u + ws_v)
            n = math.sqrt(wc * wc + ws * ws)
            cosa = (wc * ecos[row][k] + ws * esin[row][k]) / n if n > 1e-6 else 1.0
            f = f_head if cosa >= _COS45 else (f_fol if cosa <= -_COS45 else f_beam)
            h_ft = hs / METRES_PER_FOOT
            speed = v0_kn - f * h_ft * h_ft if hs > 0.0 else v0_kn
            ng = gu + elen[row][k] * (1.0 / max(speed, floor))  # the kernel's order of operations
            if ng < best.get(v, math.inf):
                best[v] = ng
                heapq.heappush(heap, (ng, v))
    raise ValueError("goal not reachable")
