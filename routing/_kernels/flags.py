"""Compiled safety flags: heading sectors, weather-slice ranges, unsafe cells along an edge or a
segment, and the heading-dependent IMO / operator rules per element (:func:`heading_flags`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from routing._kernels.speed import ship_of, speed_through_water

# --------------------------------------------------------------------------- safety-constrained search
#
# ``unsafe`` is a (n_slices, n_sea) uint16 array: bit s of unsafe[k, row] is set when the vessel's
# limits are broken at that sea node in weather slice k for a course in heading sector s (sector s
# is centred on s * 360 / sectors degrees; see routing.safety). A cell is judged over every slice
# from the one at or before the time the ship enters the edge (piece) to the one at or after the
# time it leaves it, so a linear-in-time value between two passing slices passes too (Hs, wind).


@njit
def _sector_bit(ch, sh, sectors):
    """Bit of the heading sector of the course with cosine ``ch`` and sine ``sh``."""
    w = 360.0 / sectors
    theta = math.degrees(math.atan2(sh, ch))
    s = int(math.floor(((theta + 0.5 * w) % 360.0) / w))
    if s >= sectors:
        s = sectors - 1
    elif s < 0:
        s = 0
    return np.uint16(1 << s)


@njit
def _slice_range(ta, tb, dt_h, n_times):
    """Weather slices bracketing the time interval [ta, tb] (hours since slice 0), clamped."""
    if n_times == 1:
        return 0, 0
    lo = int(math.floor(ta / dt_h))
    hi = int(math.ceil(tb / dt_h))
    if lo < 0:
        lo = 0
    if lo > n_times - 1:
        lo = n_times - 1
    if hi > n_times - 1:
        hi = n_times - 1
    if hi < lo:
        hi = lo
    return lo, hi


@njit
def _row_unsafe(s, unsafe, k_lo, k_hi, bit):
    for kk in range(k_lo, k_hi + 1):
        if unsafe[kk, s] & bit:
            return True
    return False


@njit
def _stencil_cells_unsafe(iu, ju, k, cells, counts, ny, nx, sea_index, unsafe, k_lo, k_hi, bit, exempt_a, exempt_b):
    """True when a cell touched by stencil edge k from node (ju, iu) is unsafe (exempt nodes and
    cells without a weather row are skipped)."""
    for q in range(counts[k]):
        c = iu + cells[k, q, 0]
        r = ju + cells[k, q, 1]
        if r < 0 or r >= ny or c < 0 or c >= nx:
            continue
        node = r * nx + c
        if node == exempt_a or node == exempt_b:
            continue
        s = sea_index[node]
        if s < 0:
            continue
        if _row_unsafe(s, unsafe, k_lo, k_hi, bit):
            return True
    return False


@njit
def _segment_cells_unsafe(x0, y0, x1, y1, ny, nx, sea_index, unsafe, k_lo, k_hi, bit, exempt_a, exempt_b):
    """:func:`_stencil_cells_unsafe` for any index-space segment (closed squares, as :func:`_cells_ok`)."""
    xmin = min(x0, x1)
    xmax = max(x0, x1)
    eps = 1e-9
    c_lo = int(math.ceil(xmin - 0.5 - eps))
    c_hi = int(math.floor(xmax + 0.5 + eps))
    for c in range(c_lo, c_hi + 1):
        if c < 0 or c >= nx:
            continue
        if x1 == x0:
            ya, yb = y0, y1
        else:
            xa = max(xmin, c - 0.5)
            xb = min(xmax, c + 0.5)
            ya = y0 + (y1 - y0) * (xa - x0) / (x1 - x0)
            yb = y0 + (y1 - y0) * (xb - x0) / (x1 - x0)
        ylo = min(ya, yb)
        yhi = max(ya, yb)
        r_lo = int(math.ceil(ylo - 0.5 - eps))
        r_hi = int(math.floor(yhi + 0.5 + eps))
        for r in range(r_lo, r_hi + 1):
            if r < 0 or r >= ny:
                continue
            node = r * nx + c
            if node == exempt_a or node == exempt_b:
                continue
            s = sea_index[node]
            if s < 0:
                continue
            if _row_unsafe(s, unsafe, k_lo, k_hi, bit):
                return True
    return False


@njit(cache=True)
def heading_flags(hs, wf_deg, period_s, spd_mag, spd_from_deg, headings_deg, members, p, beam_lo, beam_hi, beam_gate, use_beam,
                  imo_gate, use_imo, surf_num, use_surf, tr_s, roll_tol, use_roll, tw_s, hw_pre, hw_lo, hw_hi):  # fmt: skip
    """Heading-sector bits of the heading-dependent rules, the compiled twin of
    :func:`thresholds.safety.assess` restricted to them (cross-checked by tests).

    For every element e and sample heading h_j: encounter α = (wf − h_j) mod 360 (0 = head seas);
    beam seas: α in a closed range [beam_lo, beam_hi] (operator limits, where Hs ≥ beam_gate when
    that is > 0); IMO MSC.1/Circ.1228 (where Hs ≥ imo_gate when > 0): surf-riding
    135° < α < 225° and V > surf_num / cos(180° − α) (surf_num = 1.8·√L), synchronous and
    parametric roll |k·T_E − T_R| ≤ ε·T_R for k = 1, 2 with T_E = 3T² / |3T + V cos α|;
    successive high waves (where ``hw_pre``: λ > 0.8 L and Hs > 0.04 L, judged by the caller, no
    gate) ``hw_lo <= T_E / T_W <= hw_hi`` with T_W = ``tw_s`` (MSC.1/Circ.1228 4.2.2.2); V is the
    speed through the water on that heading (:func:`routing._kernels.speed.speed_through_water`,
    parameters ``p``) in the sea state the speed model reads: ``spd_mag`` (Hs, or the wind speed
    for Kwon) coming from ``spd_from_deg``.
    Bit s of the result is set when a rule fires at one of the headings ``members[s]``; the
    samples of a sector are judged until one fires.
    """
    ship = ship_of(p)
    m = hs.size
    H = headings_deg.size
    S = members.shape[0]
    Q = members.shape[1]
    nr = beam_lo.size
    out = np.zeros(m, dtype=np.uint16)
    state = np.zeros(H, dtype=np.int8)  # 0 not judged yet, 1 fires, 2 passes
    ch = np.empty(H)
    sh = np.empty(H)
    for j in range(H):
        ch[j] = math.cos(math.radians(headings_deg[j]))
        sh[j] = math.sin(math.radians(headings_deg[j]))
    band = roll_tol * tr_s
    for e in range(m):
        h = hs[e]
        beam_ok = use_beam and (beam_gate <= 0.0 or h >= beam_gate)
        imo_ok = use_imo and (imo_gate <= 0.0 or h >= imo_gate)
        hw_ok = use_imo and hw_pre[e]
        if not (beam_ok or imo_ok or hw_ok):
            continue
        tw3 = 3.0 * tw_s[e]
        wf = wf_deg[e]
        cw = math.cos(math.radians(wf))
        sw = math.sin(math.radians(wf))
        sm = spd_mag[e]
        cws = math.cos(math.radians(spd_from_deg[e]))
        sws = math.sin(math.radians(spd_from_deg[e]))
        t = period_s[e]
        t3 = 3.0 * t
        tt3 = 3.0 * t * t
        state[:] = 0
        bits = 0
        for s in range(S):
            for q in range(Q):
                j = members[s, q]
                if state[j] == 0:
                    a = wf - headings_deg[j]
                    if a < 0.0:
                        a += 360.0
                    f = False
                    v = 0.0
                    ca = 1.0
                    if beam_ok:
                        for r in range(nr):
                            if a >= beam_lo[r] and a <= beam_hi[r]:
                                f = True
                                break
                    if not f and (imo_ok or hw_ok):
                        ca = cw * ch[j] + sw * sh[j]  # cos of the waves' encounter angle wf - h
                        # speed through the water on heading j in the speed model's sea state
                        v = speed_through_water(ship, sm, cws * ch[j] + sws * sh[j], sws * ch[j] - cws * sh[j])
                        if hw_ok:  # T_E / T_W = 3 T_W / |3 T_W + V cos a| in [hw_lo, hw_hi]
                            dw = abs(tw3 + v * ca)
                            if dw > 0.0 and tw3 >= hw_lo * dw and tw3 <= hw_hi * dw:
                                f = True
                    if not f and imo_ok:
                        if use_surf and a > 135.0 and a < 225.0 and v * -ca > surf_num:  # cos(180 - a) = -cos a > 0
                            f = True
                        if not f and use_roll:
                            d = abs(t3 + v * ca)  # T_E = 3T^2 / d; |k T_E - T_R| <= eps T_R, times d
                            if d > 0.0 and (abs(tt3 - tr_s * d) <= band * d or abs(2.0 * tt3 - tr_s * d) <= band * d):
                                f = True
                    state[j] = 1 if f else 2
                if state[j] == 1:
                    bits |= 1 << s
                    break
        out[e] = bits
    return out
