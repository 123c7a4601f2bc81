"""Compiled speed model: speed through the water after the loss, and pace over ground.

The scalar twin of :mod:`routing.speed_loss` and :mod:`routing.speed_loss_kwon` (same module
constants, frozen into the machine code; cross-checked by tests). Encounter sectors are tested
through cosines of the encounter angle (``cos a = cos(from) cos(heading) + sin(from)
sin(heading)``), which avoids an ``atan2`` per edge.

The sea state reaching the model is a triple ``(mag, cos, sin)``: the magnitude is the
significant wave height [m] for the wave models and the 10 m wind speed [m/s] for Kwon, and
(cos, sin) the direction it comes from (:class:`routing.astar.WeatherArrays` fills it for the
chosen model).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from routing import speed_loss as sl
from routing import speed_loss_kwon as kw
from routing._kernels.core import (
    P_AERTSSEN_BANDS,
    P_DWT,
    P_FLOOR,
    P_KWON_CU,
    P_KWON_FORM_A,
    P_KWON_FORM_B,
    P_LPP,
    P_MODEL,
    P_PRINTED,
    P_TABLE,
    P_V0,
)
from routing.learned import PACK_HEADER
from thresholds.units import METRES_PER_FOOT

MODEL_CODES = {"none": 0, "bowditch": 1, "aertssen": 2, "khokhlov": 3, "kwon": 4, "learned": 5}

_COS30 = math.cos(math.radians(30.0))
_COS45 = math.cos(math.radians(45.0))
_COS60 = math.cos(math.radians(60.0))
_COS150 = math.cos(math.radians(150.0))

_FT = METRES_PER_FOOT
_BF_FOL = sl.BOWDITCH_F_FOLLOWING_KN_FT2
_BF_BEAM = sl.BOWDITCH_F_BEAM_KN_FT2
_BF_HEAD = sl.BOWDITCH_F_HEAD_KN_FT2
_KA, _KB, _KC = sl.KHOKHLOV_A, sl.KHOKHLOV_B, sl.KHOKHLOV_C
_HS_UP = np.array(sl.AERTSSEN_HS_UPPER_M, dtype=np.float64)
_HS_LO_SIMROUTE = np.array(sl.AERTSSEN_SIMROUTE_HS_LOWER_M, dtype=np.float64)
_AM = np.ascontiguousarray(sl.AERTSSEN_M, dtype=np.float64)
_AN = np.ascontiguousarray(sl.AERTSSEN_N, dtype=np.float64)
_BFT_LO = np.array(kw.BEAUFORT_LOWER_MS, dtype=np.float64)
_KDIR = np.array(kw.KWON_DIRECTION, dtype=np.float64)
if kw.KWON_SECTOR_EDGES_DEG != (30.0, 60.0, 150.0):  # the sector tests below use these cosines
    raise RuntimeError("routing.speed_loss_kwon.KWON_SECTOR_EDGES_DEG changed; update routing._kernels.speed")


@njit(inline="always")
def ship_of(p):
    """The speed model's scalars from the parameter vector, as one tuple (kept in registers), and
    the vector itself last (a learned model's table follows the parameters)."""
    return (int(p[P_MODEL]), p[P_V0], p[P_FLOOR], p[P_LPP], p[P_DWT], p[P_PRINTED] > 0.5, p[P_AERTSSEN_BANDS] > 0.5, p[P_KWON_CU],
            p[P_KWON_FORM_A], p[P_KWON_FORM_B], p)  # fmt: skip


@njit(inline="always")
def learned_ratio(p, hs, cosa):
    """Bilinear P50 speed ratio of the learned table packed in ``p`` after the parameters, at Hs
    [m] and the encounter angle (from cos a, folded to 0-180 deg); both clamped to the table.
    The numpy twin is :meth:`routing.learned.LearnedSpeedTable.ratio_at` (cross-checked by tests)."""
    o = P_TABLE
    n_h = int(p[o])
    n_e = int(p[o + 1])
    c = min(max(cosa, -1.0), 1.0)
    x = min(max((hs - p[o + 2]) / p[o + 3], 0.0), n_h - 1.0)
    y = min(max((math.degrees(math.acos(c)) - p[o + 4]) / p[o + 5], 0.0), n_e - 1.0)
    i0 = min(int(x), n_h - 2)
    j0 = min(int(y), n_e - 2)
    fx = x - i0
    fy = y - j0
    b = o + PACK_HEADER + i0 * n_e + j0
    return (p[b] * (1.0 - fx) * (1.0 - fy) + p[b + n_e] * fx * (1.0 - fy) + p[b + 1] * (1.0 - fx) * fy
            + p[b + n_e + 1] * fx * fy)


@njit(inline="always")
def _aertssen_column(hs, simroute_bands):
    """Beaufort column 0..3 (Beaufort 5..8) of Aertssen's table, or -1 below it."""
    if simroute_bands:  # SIMROUTE's code: tabulated Hs = lower edge of the class
        if hs < _HS_LO_SIMROUTE[0]:
            return -1
        if hs < _HS_LO_SIMROUTE[1]:
            return 0
        if hs < _HS_LO_SIMROUTE[2]:
            return 1
        if hs < _HS_LO_SIMROUTE[3]:
            return 2
        return 3
    if hs <= _HS_UP[0]:  # ours: WMO probable maximum heights as upper edges
        return -1
    if hs <= _HS_UP[1]:
        return 0
    if hs <= _HS_UP[2]:
        return 1
    if hs <= _HS_UP[3]:
        return 2
    return 3


@njit(inline="always")
def _kwon_loss(v0, wind, cosa, cu, form_a, form_b):
    """Kwon's loss [kn] for wind speed ``wind`` [m/s] from encounter (cos a), 0 = head."""
    bn = 0
    for q in range(_BFT_LO.size):
        if wind >= _BFT_LO[q]:
            bn = q + 1
    if bn == 0:
        return 0.0
    if cosa >= _COS30:
        sec = 0
    elif cosa >= _COS60:
        sec = 1
    elif cosa >= _COS150:
        sec = 2
    else:
        sec = 3
    d = bn - _KDIR[sec, 2]
    two_c = _KDIR[sec, 0] - _KDIR[sec, 1] * d * d
    if two_c <= 0.0:
        return 0.0
    b = float(bn)
    cform = form_a * b + b**6.5 * form_b
    return v0 * 0.5 * two_c * cu * cform / 100.0


@njit(inline="always")
def speed_through_water(ship, mag, cosa, sina):
    """Attained speed [kn] in sea state ``mag`` from encounter (cos a, sin a), 0 = head seas.

    ``ship`` is :func:`ship_of`'s tuple; ``mag`` is Hs [m] for the wave models, the wind speed
    [m/s] for Kwon. The speed never drops below the floor (nor the floor above v0).
    """
    model = ship[0]
    v0 = ship[1]
    floor = ship[2]
    loss = 0.0
    if model == 5:  # learned: the table of routing.learned (Hs; calm water is its row Hs = 0)
        loss = v0 * (1.0 - learned_ratio(ship[10], mag if mag > 0.0 else 0.0, cosa))
    elif mag > 0.0:
        if model == 1:  # Bowditch: [1] Eq. A1.1, Table A1.1 of routing.speed_loss
            if ship[5]:  # the printed sector table
                alpha = math.degrees(math.atan2(sina, cosa)) % 360.0
                theta = (alpha + 180.0) % 360.0
                if theta <= 45.0 or theta >= 270.0:
                    f = _BF_FOL
                elif theta >= 135.0 and theta <= 225.0:
                    f = _BF_HEAD
                else:
                    f = _BF_BEAM
            else:
                if cosa >= _COS45:
                    f = _BF_HEAD
                elif cosa <= -_COS45:
                    f = _BF_FOL
                else:
                    f = _BF_BEAM
            h_ft = mag / _FT
            loss = f * h_ft * h_ft
        elif model == 2:  # Aertssen: Eq. A1.2, Table A1.2
            col = _aertssen_column(mag, ship[6])
            if col >= 0:
                if cosa > _COS30:
                    sec = 0
                elif cosa > _COS60:
                    sec = 1
                elif cosa > _COS150:
                    sec = 2
                else:
                    sec = 3
                loss = (_AM[sec, col] / ship[3] + _AN[sec, col]) * v0 / 100.0
        elif model == 3:  # Khokhlov: Eq. A1.3
            c = cosa
            if c > 1.0:
                c = 1.0
            elif c < -1.0:
                c = -1.0
            theta = math.acos(c)
            loss = (_KA * mag - _KB * theta * mag) * (1.0 - _KC * ship[4] * v0)
        elif model == 4:  # Kwon: routing.speed_loss_kwon
            loss = _kwon_loss(v0, mag, cosa, ship[7], ship[8], ship[9])
    v = v0 - loss
    if floor > v0:
        floor = v0
    if v < floor:
        v = floor
    return v


@njit(inline="always")
def pace(ship, min_sog, mag, wc, ws, cu, cv, has_cur, ch, sh):
    """Hours per nmi over ground for course (cos, sin) ``(ch, sh)`` in the given sea state and current.

    Direction unknown (absent, or components cancelling out): head seas, the conservative case.
    Over ground: ``sog = sqrt(v^2 - cross^2) + along`` (the ship crabs to hold its course against
    the cross current), at least ``min_sog``.
    """
    n = math.sqrt(wc * wc + ws * ws)
    cosa = 1.0
    sina = 0.0
    if n > 1e-6:
        cosa = (wc * ch + ws * sh) / n
        sina = (ws * ch - wc * sh) / n
    v = speed_through_water(ship, mag, cosa, sina)
    if has_cur:
        along = cu * sh + cv * ch
        cross = cu * ch - cv * sh
        v2 = v * v - cross * cross
        sog = (math.sqrt(v2) if v2 > 0.0 else 0.0) + along
        if sog < min_sog:
            sog = min_sog
        return 1.0 / sog
    return 1.0 / v
