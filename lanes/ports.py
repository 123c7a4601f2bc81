"""Ports and waypoints: DBSCAN on stop locations, matched to the project's port list.

Stop episodes (:mod:`lanes.stops`) are clustered with DBSCAN [1] on the great-circle distance
(``eps_rad = eps_nmi / EARTH_RADIUS_NMI``, STYLE.md 5), computed as the chord between unit
vectors: two points on the unit sphere an angle ``d`` apart are ``2 sin(d / 2)`` apart in a
straight line, a function that rises with ``d`` on [0, pi], so "within eps_rad on the sphere" is
"within ``2 sin(eps_rad / 2)`` in 3-D" (the same neighbours as the haversine metric, to the
rounding of either formula; no projection, so no distortion at high latitudes or across the
antimeridian). That puts the stops in the Euclidean grid DBSCAN of :mod:`lanes.dbscan_grid`,
whose cost grows with the occupied cells: a port's stops grow with the period (a year of the
300-ship fleet: about 98,000 stops, most within a few hundred metres of a berth). Each cluster is a place where vessels
stop: a terminal, a berth, an anchorage. It gets a centroid (spherical mean of its stops), a
radius (largest distance of a stop from the centroid), the number of calls (stop episodes) and of
distinct vessels.

Clusters are then named from a list of known places (``data/ports.csv``: UN/LOCODE, name,
position; ``data/ports_terminals.csv`` adds terminal-level entries with their own
``radius_nmi``). Each cluster belongs to the nearest listed place whose match radius covers it,
and all clusters of one place are merged into one port: a port's berths and terminals (the demo
scenario berths ferries and tankers at different quays of Palma, 0.3-0.5 nmi apart) are one
origin or destination for the voyages. The match radius is the row's ``radius_nmi`` when the
list gives one, else ``match_radius_nmi`` capped at half the distance to the nearest other listed
place (floored at ``min_match_radius_nmi``). A terminal-level list therefore keeps nearby places
apart: the New York list gives St. George 0.25 nmi, so a tug base 0.85 nmi away stays a
separate waypoint instead of adding tug calls to the ferry terminal. Clusters no listed place
covers become numbered waypoints (``WP007``): anchorages, tug bases, places the list does not
know.

References
----------
.. [1] M. Ester, H.-P. Kriegel, J. Sander and X. Xu, "A density-based algorithm for discovering
       clusters in large spatial databases with noise," in Proc. KDD-96, pp. 226-231, 1996.
.. [2] G. Pallotta, M. Vespe and K. Bryan, "Vessel pattern knowledge discovery from AIS data,"
       Entropy, vol. 15, no. 6, pp. 2218-2245, 2013, doi:10.3390/e15062218.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from lanes._geo import spherical_means
from thresholds.geodesy import haversine_nmi
from thresholds.units import EARTH_RADIUS_NMI

PORT_COLUMNS = [
    "port_id", "kind", "locode", "name", "country", "lat_deg", "lon_deg", "radius_nmi",
    "n_calls", "n_vessels", "n_clusters", "known_lat_deg", "known_lon_deg", "match_dist_nmi",
]


@dataclass(frozen=True)
class PortParams:
    """DBSCAN and matching parameters for ports (units in the names).

    The defaults suit terminals a few hundred metres apart (New York harbour: 250 m separates
    Whitehall from the Battery piers); large ports then come out as several berth clusters, of
    which the nearest takes the port's name.
    """

    eps_nmi: float = 0.135  # 250 m
    min_samples: int = 2
    min_vessels: int = 1
    match_radius_nmi: float = 2.0
    min_match_radius_nmi: float = 0.25

    def __post_init__(self):
        if not self.eps_nmi > 0:
            raise ValueError(f"PortParams.eps_nmi must be positive, got {self.eps_nmi!r}")
        if self.min_samples < 1 or self.min_vessels < 1:
            raise ValueError("PortParams.min_samples and min_vessels must be at least 1")
        if not self.match_radius_nmi >= 0:
            raise ValueError("PortParams.match_radius_nmi must be non-negative")


def cluster_stops(stops: pd.DataFrame, params: PortParams | None = None) -> np.ndarray:
    """DBSCAN labels (``-1`` = noise) of stop episodes on the haversine distance [1].

    Clusters visited by fewer than ``min_vessels`` distinct tracks are turned into noise.
    """
    from lanes.dbscan_grid import dbscan_grid

    params = params or PortParams()
    n = len(stops)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    eps_rad = params.eps_nmi / EARTH_RADIUS_NMI
    # the great-circle neighbours as chord neighbours of unit vectors (module docstring)
    labels, _ = dbscan_grid(unit_vectors(stops["lat_deg"].to_numpy(dtype=float), stops["lon_deg"].to_numpy(dtype=float)),
                            2.0 * np.sin(eps_rad / 2.0), params.min_samples, np.ones(n))
    if params.min_vessels > 1 and (labels >= 0).any():
        inside = labels >= 0
        nv = pd.Series(stops["track"].to_numpy()[inside]).groupby(labels[inside]).nunique()
        small = nv.index[nv < params.min_vessels].to_numpy()
        labels = np.where(np.isin(labels, small), -1, labels)
    return labels.astype(np.int64)


def unit_vectors(lat_deg: np.ndarray, lon_deg: np.ndarray) -> np.ndarray:
    """(n, 3) unit vectors of points on the sphere: (cos lat cos lon, cos lat sin lon, sin lat)."""
    lat, lon = np.deg2rad(lat_deg), np.deg2rad(lon_deg)
    return np.column_stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])


def summarise_clusters(stops: pd.DataFrame, labels: np.ndarray) -> pd.DataFrame:
    """Centroid, radius, calls and vessels of each stop cluster (``cluster`` = DBSCAN label)."""
    inside = labels >= 0
    if not inside.any():
        return pd.DataFrame(columns=["cluster", "lat_deg", "lon_deg", "radius_nmi", "n_calls", "n_vessels"])
    lab = labels[inside]
    uniq, codes = np.unique(lab, return_inverse=True)
    lat = stops["lat_deg"].to_numpy(dtype=float)[inside]
    lon = stops["lon_deg"].to_numpy(dtype=float)[inside]
    clat, clon = spherical_means(codes, lat, lon, uniq.size)
    d = haversine_nmi(lat, lon, clat[codes], clon[codes])
    radius = pd.Series(d).groupby(codes).max().to_numpy()
    tracks = stops["track"].to_numpy()[inside]
    return pd.DataFrame({
        "cluster": uniq,
        "lat_deg": clat,
        "lon_deg": clon,
        "radius_nmi": radius,
        "n_calls": np.bincount(codes, minlength=uniq.size),
        "n_vessels": pd.Series(tracks).groupby(codes).nunique().to_numpy(),
    })


def match_radii_nmi(known: pd.DataFrame, match_radius_nmi: float, min_match_radius_nmi: float = 0.25) -> np.ndarray:
    """Match radius of each listed place.

    A row's own ``radius_nmi`` when the list gives one (terminal-level lists do: 0.25 nmi for a
    ferry terminal); otherwise ``match_radius_nmi``, capped at half the distance to the nearest
    other listed place but never below ``min_match_radius_nmi``.
    """
    n = len(known)
    radius = np.full(n, float(match_radius_nmi))
    if n > 1:
        lat = known["lat_deg"].to_numpy(dtype=float)
        lon = known["lon_deg"].to_numpy(dtype=float)
        d = haversine_nmi(lat[:, None], lon[:, None], lat[None, :], lon[None, :])
        np.fill_diagonal(d, np.inf)
        radius = np.minimum(radius, np.maximum(0.5 * d.min(axis=1), min_match_radius_nmi))
    if "radius_nmi" in known.columns:
        own = pd.to_numeric(known["radius_nmi"], errors="coerce").to_numpy(dtype=float)
        radius = np.where(np.isfinite(own), own, radius)
    return radius


def match_ports(clusters: pd.DataFrame, known: pd.DataFrame | None, match_radius_nmi: float = 2.0,
                min_match_radius_nmi: float = 0.25) -> np.ndarray:
    """Index into ``known`` of the place each cluster belongs to, or -1.

    A cluster belongs to the nearest listed place whose match radius covers it; several clusters
    (the berths of one port) may belong to the same place.
    """
    n = len(clusters)
    out = np.full(n, -1, dtype=np.int64)
    if n == 0 or known is None or len(known) == 0:
        return out
    radius = match_radii_nmi(known, match_radius_nmi, min_match_radius_nmi)
    d = haversine_nmi(
        clusters["lat_deg"].to_numpy(dtype=float)[:, None], clusters["lon_deg"].to_numpy(dtype=float)[:, None],
        known["lat_deg"].to_numpy(dtype=float)[None, :], known["lon_deg"].to_numpy(dtype=float)[None, :],
    )
    d = np.where(d <= radius[None, :], d, np.inf)
    best = np.argmin(d, axis=1)
    ok = np.isfinite(d[np.arange(n), best])
    out[ok] = best[ok]
    return out


def detect_ports(stops: pd.DataFrame, known: pd.DataFrame | None = None,
                 params: PortParams | None = None) -> tuple[pd.DataFrame, np.ndarray]:
    """Ports and waypoints from stop episodes.

    Parameters
    ----------
    stops : DataFrame
        Output of :func:`lanes.stops.detect_stops`.
    known : DataFrame, optional
        Listed places with ``locode``, ``name``, ``lat_deg``, ``lon_deg`` (optionally
        ``country`` and ``radius_nmi``), e.g. ``data/ports.csv``.
    params : PortParams

    Returns
    -------
    ports : DataFrame
        Columns :data:`PORT_COLUMNS`, one row per place: a listed place with all the stop clusters
        that belong to it merged (``kind`` ``"port"``; a port's berths and terminals are one
        port), or one unmatched cluster (``kind`` ``"waypoint"``, named ``WP<port_id>``).
        ``port_id`` 1..n by decreasing number of calls (then latitude, longitude); the centroid is
        the spherical mean of the place's stops, the radius the largest distance of a stop from it.
    stop_port_id : ndarray
        ``port_id`` of each stop episode, 0 for stops in no cluster (DBSCAN noise).
    """
    params = params or PortParams()
    labels = cluster_stops(stops, params)
    clusters = summarise_clusters(stops, labels)
    if len(clusters) == 0:
        return pd.DataFrame({c: pd.Series(dtype=object) for c in PORT_COLUMNS}), np.zeros(len(stops), dtype=np.int64)
    match = match_ports(clusters, known, params.match_radius_nmi, params.min_match_radius_nmi)
    # Group key per cluster: the listed place, or the cluster itself.
    group_of_cluster = {c: (f"K{m:09d}" if m >= 0 else f"C{c:09d}") for c, m in zip(clusters["cluster"], match)}
    entry_of_group = {group_of_cluster[c]: m for c, m in zip(clusters["cluster"], match)}
    inside = labels >= 0
    group = np.array([group_of_cluster[lab] if lab >= 0 else "" for lab in labels], dtype=object)
    g_codes, g_uniq = pd.factorize(group[inside], sort=True)
    lat = stops["lat_deg"].to_numpy(dtype=float)[inside]
    lon = stops["lon_deg"].to_numpy(dtype=float)[inside]
    glat, glon = spherical_means(g_codes, lat, lon, len(g_uniq))
    d = haversine_nmi(lat, lon, glat[g_codes], glon[g_codes])
    summary = pd.DataFrame({
        "group": g_uniq,
        "lat_deg": glat,
        "lon_deg": glon,
        "radius_nmi": pd.Series(d).groupby(g_codes).max().to_numpy(),
        "n_calls": np.bincount(g_codes, minlength=len(g_uniq)),
        "n_vessels": pd.Series(stops["track"].to_numpy()[inside]).groupby(g_codes).nunique().to_numpy(),
        "n_clusters": pd.Series(labels[inside]).groupby(g_codes).nunique().to_numpy(),
    })
    summary = summary.sort_values(["n_calls", "lat_deg", "lon_deg"], ascending=[False, True, True], kind="stable")
    summary = summary.reset_index(drop=True)
    summary["port_id"] = np.arange(1, len(summary) + 1, dtype=np.int64)
    k = np.array([entry_of_group[g] for g in summary["group"]], dtype=np.int64)
    matched = k >= 0
    ports = pd.DataFrame({
        "port_id": summary["port_id"].to_numpy(),
        "kind": np.where(matched, "port", "waypoint"),
        "locode": pd.Series([None] * len(summary), dtype=object),
        "name": [f"WP{p:03d}" for p in summary["port_id"]],
        "country": pd.Series([None] * len(summary), dtype=object),
        "lat_deg": summary["lat_deg"].to_numpy(),
        "lon_deg": summary["lon_deg"].to_numpy(),
        "radius_nmi": summary["radius_nmi"].to_numpy(),
        "n_calls": summary["n_calls"].to_numpy(dtype=np.int64),
        "n_vessels": summary["n_vessels"].to_numpy(dtype=np.int64),
        "n_clusters": summary["n_clusters"].to_numpy(dtype=np.int64),
        "known_lat_deg": np.nan,
        "known_lon_deg": np.nan,
        "match_dist_nmi": np.nan,
    })
    if matched.any():
        km = k[matched]
        ports.loc[matched, "locode"] = known["locode"].to_numpy()[km]
        ports.loc[matched, "name"] = known["name"].to_numpy()[km]
        if "country" in known.columns:
            ports.loc[matched, "country"] = known["country"].to_numpy()[km]
        klat = known["lat_deg"].to_numpy(dtype=float)[km]
        klon = known["lon_deg"].to_numpy(dtype=float)[km]
        ports.loc[matched, "known_lat_deg"] = klat
        ports.loc[matched, "known_lon_deg"] = klon
        ports.loc[matched, "match_dist_nmi"] = haversine_nmi(
            ports.loc[matched, "lat_deg"].to_numpy(), ports.loc[matched, "lon_deg"].to_numpy(), klat, klon)
    port_of_group = dict(zip(summary["group"], summary["port_id"]))
    stop_port_id = np.array([port_of_group[g] if g else 0 for g in group], dtype=np.int64)
    return ports[PORT_COLUMNS], stop_port_id
