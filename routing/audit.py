"""Retrospective voyage audit, the pure part: the sailed track as a route, the comparison of the
track with its alternatives, the proposed alternative and plain-language findings.

:mod:`pipelines.audit` reads the track, the weather and the vessel, computes the alternatives
(A* routes, the lane deviation) and calls :func:`audit_routes`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from routing.evaluate import RouteEvaluation, comparison_metrics, comparison_table, evaluate_route
from routing.route import Route
from thresholds.errors import StormlaneError
from thresholds.geodesy import haversine_nmi

#: Fixes closer in time than this to the previous kept fix are thinned out of an AIS track. [s]
TRACK_MIN_STEP_S = 300.0


class TrackError(StormlaneError):
    """An AIS track that cannot be audited (too few fixes, no time span)."""


def track_to_route(positions: pd.DataFrame, *, min_step_s: float = TRACK_MIN_STEP_S, name: str = "historical") -> Route:
    """The sailed AIS track as a :class:`Route` (ETAs = the fixes' times, leg speeds from them).

    Fixes are sorted by time, duplicated timestamps and fixes without a position dropped, and
    the track thinned to one fix per ``min_step_s`` (the last fix is always kept), so a 10-second
    AIS feed does not turn into thousands of legs. Leg speeds are the distances between the kept
    fixes over their time differences (speed made good), not the reported SOG.

    Parameters
    ----------
    positions : DataFrame
        Canonical AIS positions (``time_utc`` tz-aware, ``lat_deg``, ``lon_deg``; ``mmsi``
        optional, ``sog_kn`` optional).

    Raises
    ------
    TrackError
        Fewer than two usable fixes.
    """
    need = {"time_utc", "lat_deg", "lon_deg"}
    missing = need - set(positions.columns)
    if missing:
        raise TrackError(f"AIS positions lack column(s) {sorted(missing)}")
    df = positions.dropna(subset=["lat_deg", "lon_deg", "time_utc"]).sort_values("time_utc", kind="stable")
    df = df.drop_duplicates(subset="time_utc", keep="first")
    if len(df) < 2:
        raise TrackError(f"the AIS track has {len(df)} usable fix(es); at least 2 are needed")
    t = pd.DatetimeIndex(df["time_utc"])
    if t.tz is None:
        raise TrackError("AIS time_utc must be timezone-aware UTC")
    t_s = t.asi8 / 1e9
    keep = np.zeros(len(df), dtype=bool)
    last = -np.inf
    for k, ts in enumerate(t_s):
        if ts - last >= min_step_s:
            keep[k] = True
            last = ts
    keep[-1] = True
    df = df.loc[keep]
    t = pd.DatetimeIndex(df["time_utc"]).tz_convert("UTC")
    lat = df["lat_deg"].to_numpy(dtype=float)
    lon = df["lon_deg"].to_numpy(dtype=float)
    dt_h = np.diff(t.asi8) / 3.6e12
    dist = np.asarray(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]), dtype=float).reshape(-1)
    speed = np.divide(dist, dt_h, out=np.zeros_like(dist), where=dt_h > 0)
    props = {"source": "AIS track", "n_fixes": int(len(positions)), "n_kept": int(len(df)), "min_step_s": float(min_step_s)}
    if "mmsi" in df.columns and df["mmsi"].nunique() == 1:
        props["mmsi"] = int(df["mmsi"].iloc[0])
    if "sog_kn" in df.columns:
        sog = df["sog_kn"].to_numpy(dtype=float)
        props["mean_sog_kn"] = float(np.nanmean(sog)) if np.isfinite(sog).any() else None
    return Route(name, lat, lon, t, speed, properties=props)


#: Below this speed made good between two kept fixes the ship is taken as stationary. [kn]
STATIONARY_KN = 1.0


def _legs(track: Route) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per leg: length [nmi], duration [h] and speed made good (0 for a leg of no duration) [kn]."""
    d = np.asarray(track.leg_dist_nmi, dtype=float).reshape(-1)
    h = np.diff(track.time_utc.asi8) / 3.6e12
    return d, h, np.divide(d, h, out=np.zeros_like(d), where=h > 0)


def detour_factor(track: Route, floor_nmi: float = 1.0) -> float:
    """Distance sailed over the great-circle distance between the track's ends (at least
    ``floor_nmi``): about 1 for a passage, large for a window holding port calls or a loop."""
    direct = float(haversine_nmi(track.lat_deg[0], track.lon_deg[0], track.lat_deg[-1], track.lon_deg[-1]))
    return float(track.dist_nmi) / max(direct, floor_nmi)


def trim_stationary_ends(track: Route, min_speed_kn: float = STATIONARY_KN) -> Route:
    """The track without its stationary start and end (a window that begins or ends in port).

    Leading and trailing legs slower than ``min_speed_kn`` (speed made good) are dropped, so the
    track starts where the ship gets under way and ends where it stops; a track that never
    moves is returned as it is.
    """
    moving = np.flatnonzero(_legs(track)[2] >= min_speed_kn)
    if moving.size == 0 or (moving[0] == 0 and moving[-1] == track.n_waypoints - 2):
        return track
    a, b = int(moving[0]), int(moving[-1]) + 2
    weather = {k: np.asarray(v)[a:b] for k, v in track.weather.items()}
    props = {**track.properties, "trimmed_stationary_h": round(float((track.time_utc[a] - track.time_utc[0]).total_seconds()
                                                                      + (track.time_utc[-1] - track.time_utc[b - 1]).total_seconds()) / 3600.0, 4)}
    return Route(track.name, track.lat_deg[a:b], track.lon_deg[a:b], track.time_utc[a:b], track.leg_speed_kn[a:b - 1], weather, props)


def track_waypoints(track: Route, spacing_nmi: float = 5.0, min_speed_kn: float = STATIONARY_KN) -> pd.DataFrame:
    """The sailed track as a lane-like point sequence, for a deviation of the track itself.

    One point each time the distance sailed passes a multiple of ``spacing_nmi`` (the first and
    last fix always), like a lane's centroids; the speed at each point is the speed made good to
    the next one while under way (distance over the time of the track's legs not slower than
    ``min_speed_kn``: a lane's typical speeds are sailing speeds too), the last point repeating
    the one before.

    Returns
    -------
    DataFrame
        ``seq, lat_deg, lon_deg, speed_kn`` in sailing order (at least two rows).
    """
    if not spacing_nmi > 0:
        raise ValueError(f"spacing_nmi must be positive, got {spacing_nmi!r}")
    lat, lon = np.asarray(track.lat_deg, dtype=float), np.asarray(track.lon_deg, dtype=float)
    leg_nmi, leg_h, made_good_kn = _legs(track)
    along = np.r_[0.0, np.cumsum(leg_nmi)]
    step = np.floor(along / spacing_nmi)
    pick = np.flatnonzero(np.r_[True, step[1:] != step[:-1]])
    pick = np.union1d(pick, [lat.size - 1])
    under_way_h = np.r_[0.0, np.cumsum(np.where(made_good_kn >= min_speed_kn, leg_h, 0.0))]
    dt_h, dd = np.diff(under_way_h[pick]), np.diff(along[pick])
    speed = np.divide(dd, dt_h, out=np.zeros_like(dd), where=dt_h > 0)
    return pd.DataFrame({"seq": np.arange(pick.size, dtype=np.int64), "lat_deg": lat[pick], "lon_deg": lon[pick],
                         "speed_kn": np.r_[speed, speed[-1]]})


#: Order in which alternatives are preferred when they are equally safe (``safe_optimal``: the
#: time-optimal A* route under the vessel's limits, :mod:`routing.safety`).
PREFERENCE = ("deviation", "safe_optimal", "optimal", "min_distance")


def propose(evaluations: dict, reference: str = "historical") -> str | None:
    """The alternative to recommend: safer than the reference, else faster at no extra risk.

    Safer means fewer hours over the operator limits plus IMO events (``adverse_h``), then fewer
    IMO events, then a lower maximum Hs. An alternative that is not safer may still be proposed
    when it is as safe (same adverse hours and events, max Hs not higher) and faster. ``None``
    when no alternative improves on the reference.
    """
    ref = evaluations.get(reference)
    if ref is None:
        return None
    r = ref.summary

    def key(s):
        return (round(s["adverse_h"], 6), s["n_safety_events"], round(s["max_hs_m"], 3) if np.isfinite(s["max_hs_m"]) else np.inf)

    best, best_key = None, None
    for role in [x for x in PREFERENCE if x in evaluations] + sorted(set(evaluations) - set(PREFERENCE) - {reference}):
        s = evaluations[role].summary
        k = key(s)
        safer = k < key(r)
        as_safe_faster = k <= key(r) and s["time_h"] < r["time_h"] - 1e-6
        if not (safer or as_safe_faster):
            continue
        cand = (k, s["time_h"])
        if best is None or cand < best_key:
            best, best_key = role, cand
    return best


def _hours(h: float) -> str:
    return f"{h:.1f} h"


def findings(evaluations: dict, proposed: str | None, reference: str = "historical") -> list[str]:
    """Plain-language findings of an audit (what happened, what the alternatives would have done)."""
    out = []
    ref = evaluations[reference]
    s = ref.summary
    out.append(
        f"The sailed track took {_hours(s['time_h'])} over {s['dist_nmi']:.1f} nmi and met significant wave heights up to "
        f"{s['max_hs_m']:.1f} m (mean {s['mean_hs_m']:.1f} m)."
    )
    imo = [e for e in ref.events if e["kind"] == "imo"]
    if imo:
        by = {}
        for e in imo:
            by.setdefault(e["criterion"], []).append(e["duration_h"])
        parts = [f"{c.replace('_', ' ')} ({len(v)} event{'s' if len(v) > 1 else ''}, {_hours(sum(v))})" for c, v in sorted(by.items())]
        out.append("IMO MSC.1/Circ.1228 situations on the track: " + "; ".join(parts) + ".")
    else:
        out.append("No IMO MSC.1/Circ.1228 situation was met on the track.")
    exp = {k: v for k, v in s["exposure_by_rule_h"].items() if v > 0}
    if exp:
        out.append("Hours over limits: " + ", ".join(f"{k} {_hours(v)}" for k, v in sorted(exp.items())) + ".")
    if s.get("no_weather_h", 0) > 0:
        out.append(f"{_hours(s['no_weather_h'])} of the track had no weather data (outside the files or on their land cells).")
    if s.get("rules_not_evaluated"):
        out.append("Not evaluated: " + "; ".join(s["rules_not_evaluated"]) + ".")
    for role, ev in evaluations.items():
        if role == reference:
            continue
        a = ev.summary
        m = comparison_metrics(ref, ev)
        dec = m["hs_decrease_pct"]
        if not np.isfinite(dec):
            dec_txt = ""
        else:
            dec_txt = f", {abs(dec):.0f} % {'lower' if dec >= 0 else 'higher'} mean Hs over the track's adverse portion"
        out.append(
            f"{role.replace('_', '-')}: {a['time_h'] - s['time_h']:+.1f} h, {a['dist_nmi'] - s['dist_nmi']:+.1f} nmi, "
            f"max Hs {a['max_hs_m']:.1f} m, {_hours(a['adverse_h'])} adverse, {a['n_safety_events']} IMO event(s), "
            f"fuel {a['fuel_t'] - s['fuel_t']:+.2f} t, CO2 {a['co2_t'] - s['co2_t']:+.2f} t{dec_txt}."
        )
    if proposed is None:
        out.append("No alternative was safer or faster than the sailed track.")
    else:
        a = evaluations[proposed].summary
        what = "safer" if (a["adverse_h"], a["n_safety_events"]) < (s["adverse_h"], s["n_safety_events"]) else "as safe and faster"
        out.append(f"Proposed alternative: {proposed.replace('_', '-')} ({what}).")
    return out


def audit_routes(track: Route, weather_at, vessel, *, limits=None, alternatives: dict | None = None,
                 speed_loss_model: str = "bowditch", max_step_h: float = 0.25) -> dict:
    """Evaluate the sailed track and its alternatives in the same weather and compare them.

    Parameters
    ----------
    track : Route
        The sailed track (:func:`track_to_route`), role ``historical``.
    weather_at : callable
        Hindcast weather sampler (:class:`routing.sampling.PointSampler`).
    vessel, limits :
        As in :func:`routing.evaluate.evaluate_route`.
    alternatives : dict of str -> Route
        ``deviation``, ``optimal``, ``min_distance`` ... for the same departure.

    Returns
    -------
    dict
        ``evaluations`` (role -> RouteEvaluation), ``table`` (:func:`comparison_table`),
        ``proposed`` (role or None) and ``findings`` (list of str).
    """
    evaluations: dict[str, RouteEvaluation] = {
        "historical": evaluate_route(track, weather_at, vessel, limits=limits, speed_loss_model=speed_loss_model, max_step_h=max_step_h)
    }
    for role, route in (alternatives or {}).items():
        evaluations[role] = evaluate_route(route, weather_at, vessel, limits=limits, speed_loss_model=speed_loss_model, max_step_h=max_step_h)
    table = comparison_table(evaluations, reference="historical")
    proposed = propose(evaluations)
    return {"evaluations": evaluations, "table": table, "proposed": proposed, "findings": findings(evaluations, proposed)}
