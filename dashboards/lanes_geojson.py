"""GeoJSON (RFC 7946) of ports, lanes and lane centroids, built from the stored tables.

Pure: DataFrames in, a ``dict`` FeatureCollection out (the caller writes it). Coordinates are
``[lon, lat]`` in WGS84 degrees rounded to 1e-5 deg (about 1 m); NaN becomes ``null``.
Every feature has a ``layer`` property: ``port``, ``lane`` (the buffer polygon), ``lane_path``
(the centroid polyline in sailing order) or ``centroid``.

References
----------
.. [1] H. Butler et al., "The GeoJSON Format," IETF RFC 7946, 2016, doi:10.17487/RFC7946.
"""

from __future__ import annotations

import math
import re

import pandas as pd

_NUM = r"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?"


def _value(v):
    if v is None:
        return None
    if hasattr(v, "item"):
        try:
            v = v.item()
        except (ValueError, AttributeError):
            pass
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if v is pd.NA or v is pd.NaT:
        return None
    return v


def _props(row: pd.Series, skip=()) -> dict:
    return {k: _value(v) for k, v in row.items() if k not in skip}


def polygon_from_wkt(wkt: str) -> list[list[list[float]]]:
    """Rings of a WKT ``POLYGON ((lon lat, ...), ...)`` as GeoJSON coordinates."""
    m = re.fullmatch(r"\s*POLYGON\s*\((.*)\)\s*", wkt or "", flags=re.IGNORECASE | re.DOTALL)
    if not m:
        raise ValueError(f"not a WKT POLYGON: {str(wkt)[:60]!r}")
    rings = []
    for ring in re.findall(r"\(([^()]*)\)", m.group(1)):
        coords = []
        for pair in ring.split(","):
            parts = pair.split()
            if len(parts) != 2 or not all(re.fullmatch(_NUM, p) for p in parts):
                raise ValueError(f"bad WKT coordinate {pair!r}")
            coords.append([round(float(parts[0]), 5), round(float(parts[1]), 5)])
        if coords and coords[0] != coords[-1]:
            coords.append(coords[0])
        rings.append(coords)
    if not rings:
        raise ValueError("WKT POLYGON without rings")
    return rings


def lanes_geojson(ports: pd.DataFrame, lanes: pd.DataFrame, centroids: pd.DataFrame,
                  with_centroids: bool = True) -> dict:
    """FeatureCollection of ports (points), lanes (polygons and paths) and centroids (points).

    Examples
    --------
    >>> import pandas as pd
    >>> p = pd.DataFrame({"port_id": [1], "name": ["Palma"], "lat_deg": [39.56], "lon_deg": [2.63]})
    >>> fc = lanes_geojson(p, pd.DataFrame(), pd.DataFrame())
    >>> fc["features"][0]["geometry"]
    {'type': 'Point', 'coordinates': [2.63, 39.56]}
    """
    features: list[dict] = []
    for _, row in ports.iterrows():
        features.append({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [round(float(row["lon_deg"]), 5), round(float(row["lat_deg"]), 5)]},
            "properties": {"layer": "port", **_props(row, skip=("lat_deg", "lon_deg"))},
        })
    by_lane = {k: g.sort_values("seq") for k, g in centroids.groupby("lane_id")} if len(centroids) else {}
    for _, row in lanes.iterrows():
        props = _props(row, skip=("polygon_wkt",))
        if isinstance(row.get("polygon_wkt"), str) and row["polygon_wkt"]:
            features.append({
                "type": "Feature",
                "geometry": {"type": "Polygon", "coordinates": polygon_from_wkt(row["polygon_wkt"])},
                "properties": {"layer": "lane", **props},
            })
        cents = by_lane.get(row["lane_id"])
        if cents is not None and len(cents) >= 2:
            coords = [[round(float(a), 5), round(float(b), 5)] for a, b in zip(cents["lon_deg"], cents["lat_deg"])]
            features.append({
                "type": "Feature",
                "geometry": {"type": "LineString", "coordinates": coords},
                "properties": {"layer": "lane_path", "lane_id": _value(row["lane_id"]),
                               "speed_kn": [_value(v) for v in cents["speed_kn"]]},
            })
    if with_centroids:
        for _, row in centroids.iterrows():
            features.append({
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [round(float(row["lon_deg"]), 5), round(float(row["lat_deg"]), 5)]},
                "properties": {"layer": "centroid", **_props(row, skip=("lat_deg", "lon_deg"))},
            })
    return {"type": "FeatureCollection", "features": features}
