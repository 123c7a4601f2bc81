"""Physical constants and unit conversions used across stormlane.

All conversions live here so that no module re-derives a factor. Names carry their units
(STYLE.md section 3).
"""

from __future__ import annotations

import numpy as np

#: One international nautical mile. [m] (BIPM SI Brochure, 9th ed., Table 8)
METRES_PER_NMI = 1852.0
#: One knot = one nautical mile per hour. [m/s]
MS_PER_KN = METRES_PER_NMI / 3600.0
#: One international foot. [m]
METRES_PER_FOOT = 0.3048
#: Mean Earth radius R1 = (2a + b)/3 of WGS84. [m] (IUGG, Moritz 2000, doi:10.1007/s001900050278)
EARTH_RADIUS_M = 6371008.8
#: Mean Earth radius in nautical miles, for haversine DBSCAN and great-circle lengths. [nmi]
EARTH_RADIUS_NMI = EARTH_RADIUS_M / METRES_PER_NMI
#: Standard gravity. [m/s2]
GRAVITY_MS2 = 9.80665


def kn_to_ms(speed_kn):
    """Convert knots to metres per second."""
    return np.asarray(speed_kn, dtype=float) * MS_PER_KN if np.ndim(speed_kn) else float(speed_kn) * MS_PER_KN


def ms_to_kn(speed_ms):
    """Convert metres per second to knots."""
    return np.asarray(speed_ms, dtype=float) / MS_PER_KN if np.ndim(speed_ms) else float(speed_ms) / MS_PER_KN


def m_to_ft(length_m):
    """Convert metres to international feet."""
    return np.asarray(length_m, dtype=float) / METRES_PER_FOOT if np.ndim(length_m) else float(length_m) / METRES_PER_FOOT


def nmi_to_m(dist_nmi):
    """Convert nautical miles to metres."""
    return np.asarray(dist_nmi, dtype=float) * METRES_PER_NMI if np.ndim(dist_nmi) else float(dist_nmi) * METRES_PER_NMI


def m_to_nmi(dist_m):
    """Convert metres to nautical miles."""
    return np.asarray(dist_m, dtype=float) / METRES_PER_NMI if np.ndim(dist_m) else float(dist_m) / METRES_PER_NMI


def wrap_lon_deg(lon_deg):
    """Wrap longitudes into [-180, 180)."""
    wrapped = (np.asarray(lon_deg, dtype=float) + 180.0) % 360.0 - 180.0
    return wrapped if np.ndim(lon_deg) else float(wrapped)


def wrap_deg(angle_deg):
    """Wrap angles into [0, 360)."""
    wrapped = np.mod(np.asarray(angle_deg, dtype=float), 360.0)
    return wrapped if np.ndim(angle_deg) else float(wrapped)


def angle_diff_deg(a_deg, b_deg):
    """Smallest absolute difference between two directions, in [0, 180]."""
    d = np.abs(np.mod(np.asarray(a_deg, dtype=float) - np.asarray(b_deg, dtype=float) + 180.0, 360.0) - 180.0)
    return d if np.ndim(d) else float(d)


def uv_from_dir_to(speed, dir_to_deg):
    """Eastward and northward components of a vector flowing TO ``dir_to_deg`` (clockwise from north)."""
    rad = np.deg2rad(dir_to_deg)
    return speed * np.sin(rad), speed * np.cos(rad)


def dir_from_uv(u, v):
    """Direction a wind with components (u, v) comes FROM, clockwise from north, in [0, 360).

    Meteorological convention (WMO): a westerly (u > 0, v = 0) comes from 270 deg.
    """
    return wrap_deg(np.rad2deg(np.arctan2(-np.asarray(u, dtype=float), -np.asarray(v, dtype=float))))


def dir_to_uv(u, v):
    """Direction a current with components (u, v) flows TO, clockwise from north, in [0, 360)."""
    return wrap_deg(np.rad2deg(np.arctan2(np.asarray(u, dtype=float), np.asarray(v, dtype=float))))
