"""Compiled kernels of the one land check (:mod:`routing.land`).

A leg is the great circle between two points. It is tested against every 30" pixel of the land
mask that it touches: the arc is cut into pieces, each piece is replaced by its chord in pixel
space (x = (lon + 180) * 120, y = (90 - lat) * 120, both axes in the same unit) grown by a margin
``pad`` that provably contains the arc, and every pixel whose closed square meets the grown
chord must be ocean (corner contacts count; pixels outside the window count as land).

Why the margin contains the arc. In the plane (lambda, phi) [rad] the image of a great circle
with course theta at latitude phi has curvature
``kappa = |sin theta| |sin phi| (1 + cos^2 theta) cos phi / (sin^2 theta + cos^2 theta cos^2 phi)^(3/2)``
(Clairaut's relation ``cos phi sin theta = const`` differentiated twice), which is at most
``2 / cos phi``. A plane curve of length ``l`` whose curvature is at most ``kappa`` stays within
``kappa l^2 / 4`` of its chord (its tangent is parallel to the chord somewhere and turns at most
``kappa`` per unit length). A piece of angular length ``d`` has a plane length of at most
``d / cos phi_m``, with ``phi_m`` the largest |latitude| it reaches (at most the larger end
latitude plus ``d / 2``), so it stays within ``d^2 / (2 cos^3 phi_m)`` rad of its chord (``d`` is
taken from an upper bound of the leg's length, so the bound only grows). Pieces are
cut short enough that this is at most ``PAD_MAX_PX`` = 0.02 pixel (~19 m); the test is therefore
conservative by at most that much, and never misses a land pixel the arc touches.

References
----------
.. [1] E. Williams, "Aviation Formulary V1.47," 2011 (great-circle distance and intermediate points).
.. [2] J. Amanatides and A. Woo, "A fast voxel traversal algorithm for ray tracing," Eurographics '87,
       pp. 3-10 (the pixels a segment crosses; here every pixel whose closed square meets it).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Columns of the global raster (longitude wraps modulo this).
N_COLS = 43_200
#: Largest distance between a piece of arc and its chord, in pixels (the test's conservatism).
PAD_MAX_PX = 0.02
#: Rounding allowance added to every margin. [px]
_EPS_PX = 1e-7
_DEG = math.pi / 180.0


@njit(inline="always")
def _wrap180(d):
    return d - 360.0 * math.floor((d + 180.0) / 360.0)


@njit
def box_ocean(x0, y0, x1, y1, pad, ocean):
    """True when every pixel whose closed square meets the segment (x0, y0)-(x1, y1) grown by
    ``pad`` (a square of half-side ``pad`` swept along it) is ocean; pixel (r, c) = [c, c+1] x [r, r+1].
    Pixels outside the window count as land."""
    rows, cols = ocean.shape
    sx0 = min(x0, x1)
    sx1 = max(x0, x1)
    c_lo = int(math.ceil(sx0 - pad)) - 1
    c_hi = int(math.floor(sx1 + pad))
    for c in range(c_lo, c_hi + 1):
        if c < 0 or c >= cols:
            return False
        xa = max(sx0, c - pad)
        xb = min(sx1, c + 1.0 + pad)
        if xa > xb:
            xa = xb
        if x1 == x0:
            ya, yb = y0, y1
        else:
            ya = y0 + (y1 - y0) * (xa - x0) / (x1 - x0)
            yb = y0 + (y1 - y0) * (xb - x0) / (x1 - x0)
        r_lo = int(math.ceil(min(ya, yb) - pad)) - 1
        r_hi = int(math.floor(max(ya, yb) + pad))
        for r in range(r_lo, r_hi + 1):
            if r < 0 or r >= rows:
                return False
            if not ocean[r, c]:
                return False
    return True


@njit(inline="always")
def _unit(lat, lon):
    return math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)


@njit
def _angle(ax, ay, az, bx, by, bz):
    """Angle between two unit vectors (atan2 of cross and dot: accurate at any size). [rad]"""
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz)


@njit
def gc_leg_ocean(lat1, lon1, lat2, lon2, ocean, r0, c0, ppd):
    """True when the great-circle leg (deg, any longitude frame) touches no land pixel of the
    window (rows from ``r0``, columns from ``c0`` of the global raster). See the module notes.

    The leg's angular length d is bounded above by |dphi| + |dlambda| cos(min |phi|) (the length of
    a path along a meridian and a parallel), which sets the number of pieces and the margin: a
    short leg (an A* edge) is one chord, without trigonometry beyond one cosine.
    """
    la1 = lat1 * _DEG
    la2 = lat2 * _DEG
    dlon = _wrap180(lon2 - lon1)
    d = abs(la2 - la1) + abs(dlon * _DEG) * math.cos(min(abs(la1), abs(la2)))
    px_per_rad = ppd / _DEG
    phim = max(abs(la1), abs(la2)) + 0.5 * d
    cm = math.cos(min(phim, 89.99 * _DEG))
    c3 = cm * cm * cm
    n = 1
    if d > 0.0:
        n = max(1, int(math.ceil(d / math.sqrt(2.0 * c3 * PAD_MAX_PX / px_per_rad))))
    dp = d / n
    pad = dp * dp / (2.0 * c3) * px_per_rad + _EPS_PX
    xa = (lon1 + 180.0) * ppd - c0
    xa -= N_COLS * math.floor(xa / N_COLS)
    ya = (90.0 - lat1) * ppd - r0
    if n == 1:
        return box_ocean(xa, ya, xa + dlon * ppd, (90.0 - lat2) * ppd - r0, pad, ocean)
    ax, ay, az = _unit(la1, lon1 * _DEG)
    bx, by, bz = _unit(la2, lon2 * _DEG)
    dt = _angle(ax, ay, az, bx, by, bz)  # the true angular length, for the intermediate points
    sd = math.sin(dt)
    lona = lon1
    for q in range(n):
        if q == n - 1:
            latb = lat2
            lonb = lon2
        else:
            f = (q + 1.0) / n
            A = math.sin((1.0 - f) * dt) / sd
            B = math.sin(f * dt) / sd
            x = A * ax + B * bx
            y = A * ay + B * by
            z = A * az + B * bz
            latb = math.atan2(z, math.sqrt(x * x + y * y)) / _DEG
            lonb = math.atan2(y, x) / _DEG
        xb = xa + _wrap180(lonb - lona) * ppd
        yb = (90.0 - latb) * ppd - r0
        if not box_ocean(xa, ya, xb, yb, pad, ocean):
            return False
        xa, ya, lona = xb, yb, lonb
    return True


@njit
def _point_at(ax, ay, az, bx, by, bz, d, s):
    """(lat, lon) [deg] at angular distance s from A towards B on the great circle A-B (0 <= s <= d)."""
    if d <= 0.0:
        return math.atan2(az, math.sqrt(ax * ax + ay * ay)) / _DEG, math.atan2(ay, ax) / _DEG
    sd = math.sin(d)
    A = math.sin(d - s) / sd
    B = math.sin(s) / sd
    x = A * ax + B * bx
    y = A * ay + B * by
    z = A * az + B * bz
    return math.atan2(z, math.sqrt(x * x + y * y)) / _DEG, math.atan2(y, x) / _DEG


@njit
def _disk_interval(ax, ay, az, bx, by, bz, d, px, py, pz, cos_rho):
    """Along-leg interval [s0, s1] (angular distance from A) inside the disk of angular radius
    rho about P; (1, 0) when the leg misses it.

    On the great circle X(s) = A cos s + T sin s (T the unit tangent at A towards B),
    P.X(s) = R cos(s - s_c) with R = |(P.A, P.T)|, so P.X(s) >= cos rho is one interval of s.
    """
    pa = px * ax + py * ay + pz * az
    if d <= 0.0:
        return (0.0, 0.0) if pa >= cos_rho else (1.0, 0.0)
    # T = (B - A cos d) / sin d
    sd = math.sin(d)
    cd = math.cos(d)
    tx = (bx - ax * cd) / sd
    ty = (by - ay * cd) / sd
    tz = (bz - az * cd) / sd
    pt = px * tx + py * ty + pz * tz
    R = math.sqrt(pa * pa + pt * pt)
    if R < cos_rho or R <= 0.0:
        return 1.0, 0.0
    sc = math.atan2(pt, pa)
    half = math.acos(min(cos_rho / R, 1.0))
    s0 = max(sc - half, 0.0)
    s1 = min(sc + half, d)
    return s0, s1


@njit(cache=True)
def legs_ocean(lat, lon, berth_lat, berth_lon, berth_rho, ocean, r0, c0, ppd):
    """Per leg of a polyline (deg): True when the parts of its great circle farther than the
    berth radius (angular, rad) from every berth touch no land pixel; a leg of zero length (a
    repeated point) is its point, tested as a leg (the same 0.02-pixel margin). bool (n - 1,)"""
    n = lat.size
    nb = berth_lat.size
    out = np.ones(max(n - 1, 0), dtype=np.bool_)
    cos_rho = math.cos(berth_rho)
    s0s = np.empty(nb)
    s1s = np.empty(nb)
    for k in range(n - 1):
        ax, ay, az = _unit(lat[k] * _DEG, lon[k] * _DEG)
        bx, by, bz = _unit(lat[k + 1] * _DEG, lon[k + 1] * _DEG)
        d = _angle(ax, ay, az, bx, by, bz)
        m = 0
        for b in range(nb):
            px, py, pz = _unit(berth_lat[b] * _DEG, berth_lon[b] * _DEG)
            s0, s1 = _disk_interval(ax, ay, az, bx, by, bz, d, px, py, pz, cos_rho)
            if s0 <= s1:
                s0s[m] = s0
                s1s[m] = s1
                m += 1
        # walk the leg from s = 0, skipping the exempt intervals (sorted by start)
        order = np.argsort(s0s[:m])
        s = 0.0
        ok = True
        for q in range(m + 1):
            if q < m:
                e0, e1 = s0s[order[q]], s1s[order[q]]
            else:
                e0, e1 = d, d
            if e0 > s or (d == 0.0 and m == 0):  # a zero-length leg off every berth: its point
                la_a, lo_a = _point_at(ax, ay, az, bx, by, bz, d, s)
                la_b, lo_b = _point_at(ax, ay, az, bx, by, bz, d, e0)
                if s == 0.0:
                    la_a, lo_a = lat[k], lon[k]
                if e0 == d:
                    la_b, lo_b = lat[k + 1], lon[k + 1]
                if not gc_leg_ocean(la_a, lo_a, la_b, lo_b, ocean, r0, c0, ppd):
                    ok = False
                    break
            s = max(s, e1)
        out[k] = ok
    return out
