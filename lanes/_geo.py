"""Small vectorised helpers shared by the lanes modules (unit vectors, spherical means, groups).

Private: the public geometry lives in :mod:`thresholds.geodesy`; these are the pieces the
clustering needs on top of it (positions as unit vectors so that a mean or a Euclidean distance
is meaningful anywhere on the sphere, including across the antimeridian).
"""

from __future__ import annotations

import numpy as np

from thresholds.units import EARTH_RADIUS_NMI


def unit_vectors(lat_deg, lon_deg) -> np.ndarray:
    """Positions as unit vectors on the sphere, shape ``(n, 3)``."""
    lat = np.deg2rad(np.asarray(lat_deg, dtype=float))
    lon = np.deg2rad(np.asarray(lon_deg, dtype=float))
    cl = np.cos(lat)
    return np.column_stack([cl * np.cos(lon), cl * np.sin(lon), np.sin(lat)])


def latlon_from_vectors(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`unit_vectors` for vectors of any positive length; lon in [-180, 180)."""
    xyz = np.atleast_2d(np.asarray(xyz, dtype=float))
    lat = np.rad2deg(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))
    lon = (np.rad2deg(np.arctan2(xyz[:, 1], xyz[:, 0])) + 180.0) % 360.0 - 180.0
    return lat, lon


def group_sums(codes: np.ndarray, values: np.ndarray, n_groups: int) -> np.ndarray:
    """Sum of ``values`` rows per integer group code (``values`` 1-D or 2-D)."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        return np.bincount(codes, weights=values, minlength=n_groups)
    return np.column_stack([np.bincount(codes, weights=values[:, j], minlength=n_groups) for j in range(values.shape[1])])


def spherical_means(codes: np.ndarray, lat_deg, lon_deg, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean position of each group: the normalised sum of its unit vectors."""
    sums = group_sums(codes, unit_vectors(lat_deg, lon_deg), n_groups)
    return latlon_from_vectors(sums)


def circular_means_deg(codes: np.ndarray, angle_deg, n_groups: int, weights=None) -> tuple[np.ndarray, np.ndarray]:
    """Circular mean direction per group and its mean resultant length R in [0, 1].

    The mean of directions is the direction of the summed unit vectors (Mardia & Jupp,
    *Directional Statistics*, 2000, sec. 2.2.1); R near 1 means the directions agree.
    """
    a = np.deg2rad(np.asarray(angle_deg, dtype=float))
    w = np.ones_like(a) if weights is None else np.asarray(weights, dtype=float)
    s = np.bincount(codes, weights=w * np.sin(a), minlength=n_groups)
    c = np.bincount(codes, weights=w * np.cos(a), minlength=n_groups)
    n = np.bincount(codes, weights=w, minlength=n_groups)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.hypot(s, c) / n
    return np.mod(np.rad2deg(np.arctan2(s, c)), 360.0), r


def circular_mean_deg(angle_deg, weights=None) -> float:
    """Circular mean of a set of directions. [deg]"""
    a = np.asarray(angle_deg, dtype=float)
    if a.size == 0:
        return float("nan")
    mean, _ = circular_means_deg(np.zeros(a.size, dtype=np.int64), a, 1, weights)
    return float(mean[0])


def local_xy_nmi(lat_deg, lon_deg, lat0_deg: float, lon0_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Azimuthal equidistant coordinates around (lat0, lon0): east and north distances. [nmi]

    Exact distances and bearings from the centre; used for hulls, buffers and cross-track widths
    of one lane (a few hundred nmi at most).
    """
    lat = np.deg2rad(np.asarray(lat_deg, dtype=float))
    lon = np.deg2rad(np.asarray(lon_deg, dtype=float))
    lat0 = np.deg2rad(lat0_deg)
    lon0 = np.deg2rad(lon0_deg)
    dlon = lon - lon0
    cos_c = np.clip(np.sin(lat0) * np.sin(lat) + np.cos(lat0) * np.cos(lat) * np.cos(dlon), -1.0, 1.0)
    c = np.arccos(cos_c)
    with np.errstate(invalid="ignore", divide="ignore"):
        k = np.where(c > 1e-12, c / np.sin(c), 1.0)
    x = k * np.cos(lat) * np.sin(dlon)
    y = k * (np.cos(lat0) * np.sin(lat) - np.sin(lat0) * np.cos(lat) * np.cos(dlon))
    return x * EARTH_RADIUS_NMI, y * EARTH_RADIUS_NMI


def latlon_from_local_xy(x_nmi, y_nmi, lat0_deg: float, lon0_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`local_xy_nmi`."""
    x = np.asarray(x_nmi, dtype=float) / EARTH_RADIUS_NMI
    y = np.asarray(y_nmi, dtype=float) / EARTH_RADIUS_NMI
    lat0 = np.deg2rad(lat0_deg)
    lon0 = np.deg2rad(lon0_deg)
    c = np.hypot(x, y)
    with np.errstate(invalid="ignore", divide="ignore"):
        lat = np.arcsin(np.clip(np.cos(c) * np.sin(lat0) + np.where(c > 1e-12, y * np.sin(c) * np.cos(lat0) / c, 0.0), -1, 1))
        lon = lon0 + np.arctan2(x * np.sin(c), c * np.cos(lat0) * np.cos(c) - y * np.sin(lat0) * np.sin(c))
    return np.rad2deg(lat), (np.rad2deg(lon) + 180.0) % 360.0 - 180.0


def run_starts(keys: np.ndarray) -> np.ndarray:
    """Boolean mask of the first element of each run of equal consecutive keys."""
    keys = np.asarray(keys)
    start = np.ones(keys.shape[0], dtype=bool)
    if keys.shape[0] > 1:
        start[1:] = keys[1:] != keys[:-1]
    return start


def time_seconds(times) -> np.ndarray:
    """tz-aware timestamps (Series/DatetimeIndex/array) to float seconds since 1970 UTC."""
    import pandas as pd

    idx = pd.DatetimeIndex(times)
    if idx.tz is None:
        raise ValueError("time_utc must be timezone-aware UTC")
    return idx.tz_convert("UTC").as_unit("ns").asi8 / 1e9
