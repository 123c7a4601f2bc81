"""Great-circle geometry on the mean-radius sphere, vectorised over any array shape.

Positions are WGS84 degrees (lon in [-180, 180)); distances in nautical miles; bearings in
degrees clockwise from true north. The sphere of mean radius (``EARTH_RADIUS_NMI``) is what the
routing literature uses for great-circle lengths; pyproj's ellipsoidal geodesic differs by up to
0.5 % and is used only where a test needs it.

References
----------
.. [1] E. Williams, "Aviation Formulary V1.47," 2011. https://edwilliams.org/avform147.htm
       (haversine distance, initial course, intermediate points, destination point).
"""

from __future__ import annotations

import numpy as np

from thresholds.units import EARTH_RADIUS_NMI


def haversine_nmi(lat1_deg, lon1_deg, lat2_deg, lon2_deg):
    """Great-circle distance between two points by the haversine formula [1]. [nmi]"""
    lat1, lon1, lat2, lon2 = (np.deg2rad(np.asarray(x, dtype=float)) for x in (lat1_deg, lon1_deg, lat2_deg, lon2_deg))
    a = np.sin((lat2 - lat1) / 2.0) ** 2 + np.cos(lat1) * np.cos(lat2) * np.sin((lon2 - lon1) / 2.0) ** 2
    d = 2.0 * EARTH_RADIUS_NMI * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))
    return d if np.ndim(d) else float(d)


def initial_bearing_deg(lat1_deg, lon1_deg, lat2_deg, lon2_deg):
    """Initial great-circle course from point 1 to point 2 [1], in [0, 360). [deg]"""
    lat1, lon1, lat2, lon2 = (np.deg2rad(np.asarray(x, dtype=float)) for x in (lat1_deg, lon1_deg, lat2_deg, lon2_deg))
    dlon = lon2 - lon1
    y = np.sin(dlon) * np.cos(lat2)
    x = np.cos(lat1) * np.sin(lat2) - np.sin(lat1) * np.cos(lat2) * np.cos(dlon)
    b = np.mod(np.rad2deg(np.arctan2(y, x)), 360.0)
    return b if np.ndim(b) else float(b)


def intermediate_point(lat1_deg, lon1_deg, lat2_deg, lon2_deg, fraction):
    """Point at ``fraction`` (0..1) of the great circle from point 1 to point 2 [1].

    Returns ``(lat_deg, lon_deg)``; coincident end points return point 1.
    """
    lat1, lon1, lat2, lon2 = (np.deg2rad(np.asarray(x, dtype=float)) for x in (lat1_deg, lon1_deg, lat2_deg, lon2_deg))
    f = np.asarray(fraction, dtype=float)
    a = np.sin((lat2 - lat1) / 2.0) ** 2 + np.cos(lat1) * np.cos(lat2) * np.sin((lon2 - lon1) / 2.0) ** 2
    d = 2.0 * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))
    with np.errstate(invalid="ignore", divide="ignore"):
        sin_d = np.sin(d)
        A = np.where(sin_d > 1e-15, np.sin((1.0 - f) * d) / sin_d, 1.0 - f)
        B = np.where(sin_d > 1e-15, np.sin(f * d) / sin_d, f)
    x = A * np.cos(lat1) * np.cos(lon1) + B * np.cos(lat2) * np.cos(lon2)
    y = A * np.cos(lat1) * np.sin(lon1) + B * np.cos(lat2) * np.sin(lon2)
    z = A * np.sin(lat1) + B * np.sin(lat2)
    lat = np.rad2deg(np.arctan2(z, np.hypot(x, y)))
    lon = (np.rad2deg(np.arctan2(y, x)) + 180.0) % 360.0 - 180.0
    if np.ndim(lat) == 0:
        return float(lat), float(lon)
    return lat, lon


def destination_point(lat_deg, lon_deg, bearing_deg, dist_nmi):
    """Point reached from a start after ``dist_nmi`` along the initial course ``bearing_deg`` [1].

    Returns ``(lat_deg, lon_deg)``.
    """
    lat1, lon1, brg = (np.deg2rad(np.asarray(x, dtype=float)) for x in (lat_deg, lon_deg, bearing_deg))
    d = np.asarray(dist_nmi, dtype=float) / EARTH_RADIUS_NMI
    lat2 = np.arcsin(np.sin(lat1) * np.cos(d) + np.cos(lat1) * np.sin(d) * np.cos(brg))
    lon2 = lon1 + np.arctan2(np.sin(brg) * np.sin(d) * np.cos(lat1), np.cos(d) - np.sin(lat1) * np.sin(lat2))
    lat = np.rad2deg(lat2)
    lon = (np.rad2deg(lon2) + 180.0) % 360.0 - 180.0
    if np.ndim(lat) == 0:
        return float(lat), float(lon)
    return lat, lon


def path_length_nmi(lat_deg, lon_deg) -> float:
    """Length of a polyline of great-circle legs. [nmi]"""
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    if lat.size < 2:
        return 0.0
    return float(np.sum(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:])))
