"""A route cut into pieces sampled at their middles (:func:`densify`), and what the evaluation
reads off the samples: the runs where a rule fires (:func:`rule_events`) and duration-weighted
statistics. Used by :mod:`routing.evaluate`; see its docstring for why pieces, not waypoints.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from routing.route import Route
from thresholds.geodesy import initial_bearing_deg, intermediate_point

#: IMO MSC.1/Circ.1228 rules of :func:`thresholds.safety.assess`; the others are operator limits.
IMO_RULES = ("surf_riding", "high_waves", "synchronous_roll", "parametric_roll")


def densify(route: Route, max_step_h: float = 0.25) -> pd.DataFrame:
    """Cut every leg into pieces of at most ``max_step_h`` and return the middle of each piece.

    Returns
    -------
    DataFrame
        One row per piece: ``leg`` (index of the leg), ``time_utc`` (when the ship is at the
        piece's middle), ``lat_deg``, ``lon_deg``, ``dt_h`` (the piece's duration),
        ``dist_nmi`` (its length), ``heading_deg`` (course there) and ``speed_kn`` (the leg's
        speed made). Legs of zero duration give no piece.
    """
    if max_step_h <= 0:
        raise ValueError("max_step_h must be positive")
    n = route.n_waypoints
    if n < 2:
        return pd.DataFrame(columns=["leg", "time_utc", "lat_deg", "lon_deg", "dt_h", "dist_nmi", "heading_deg", "speed_kn"])
    leg_dt_h = np.diff(route.time_utc.asi8) / 3.6e12
    if np.any(leg_dt_h < 0):
        raise ValueError(f"route {route.name!r}: waypoint times go backwards")
    leg_d = route.leg_dist_nmi
    pieces = np.where(leg_dt_h > 0, np.maximum(1, np.ceil(leg_dt_h / max_step_h - 1e-9)), 0).astype(int)
    leg = np.repeat(np.arange(n - 1), pieces)
    k = np.arange(pieces.sum()) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    frac = (k + 0.5) / pieces[leg]
    lat, lon = intermediate_point(route.lat_deg[leg], route.lon_deg[leg], route.lat_deg[leg + 1], route.lon_deg[leg + 1], frac)
    lat = np.asarray(lat, dtype=float).reshape(-1)
    lon = np.asarray(lon, dtype=float).reshape(-1)
    t0 = route.time_utc.asi8[leg]
    times = pd.DatetimeIndex(t0 + np.round(frac * leg_dt_h[leg] * 3.6e12).astype(np.int64), tz="UTC")
    heading = np.asarray(initial_bearing_deg(lat, lon, route.lat_deg[leg + 1], route.lon_deg[leg + 1]), dtype=float).reshape(-1)
    same = (route.lat_deg[leg] == route.lat_deg[leg + 1]) & (route.lon_deg[leg] == route.lon_deg[leg + 1])
    heading = np.where(same, np.nan, heading)
    return pd.DataFrame(
        {
            "leg": leg,
            "time_utc": times,
            "lat_deg": lat,
            "lon_deg": lon,
            "dt_h": leg_dt_h[leg] / pieces[leg],
            "dist_nmi": leg_d[leg] / pieces[leg],
            "heading_deg": heading,
            "speed_kn": route.leg_speed_kn[leg],
        }
    )


def rule_events(samples: pd.DataFrame, rule: str, margin: np.ndarray) -> list[dict]:
    """Maximal runs of consecutive pieces where ``fired_<rule>`` is True."""
    fired = samples[f"fired_{rule}"].to_numpy(dtype=bool)
    if not fired.any():
        return []
    edges = np.diff(np.concatenate([[0], fired.astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)  # exclusive
    out = []
    t = samples["time_utc"]
    dt = samples["dt_h"].to_numpy()
    for s, e in zip(starts, ends):
        m = margin[s:e]
        worst = s + int(np.nanargmax(m)) if np.isfinite(m).any() else s
        out.append(
            {
                "criterion": rule,
                "kind": "imo" if rule in IMO_RULES else "operator",
                "start_utc": (t.iloc[s] - pd.Timedelta(hours=dt[s] / 2)).isoformat(),
                "end_utc": (t.iloc[e - 1] + pd.Timedelta(hours=dt[e - 1] / 2)).isoformat(),
                "duration_h": float(dt[s:e].sum()),
                "start_lat_deg": float(samples["lat_deg"].iloc[s]),
                "start_lon_deg": float(samples["lon_deg"].iloc[s]),
                "worst_lat_deg": float(samples["lat_deg"].iloc[worst]),
                "worst_lon_deg": float(samples["lon_deg"].iloc[worst]),
                "worst_time_utc": t.iloc[worst].isoformat(),
                "max_margin": float(np.nanmax(m)) if np.isfinite(m).any() else None,
                "hs_m_at_worst": float(samples["hs_m"].iloc[worst]) if "hs_m" in samples else None,
            }
        )
    return out


def weighted_mean(values, weights) -> float:
    """Mean of the finite ``values`` weighted by their positive ``weights`` (durations); NaN if none."""
    v = np.asarray(values, dtype=float)
    w = np.asarray(weights, dtype=float)
    ok = np.isfinite(v) & (w > 0)
    return float(np.sum(v[ok] * w[ok]) / np.sum(w[ok])) if ok.any() else float("nan")


def nanmax(values) -> float:
    """Largest finite value; NaN (without numpy's warning) if none."""
    v = np.asarray(values, dtype=float)
    return float(np.nanmax(v)) if np.isfinite(v).any() else float("nan")
