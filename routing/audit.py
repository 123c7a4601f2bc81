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


def track_to_route(positions: pd.DataFrame, *, min_step_s: float = TRACK_MIN_STEP_S, name: str = "as_sailed",
                   sea_check: bool = True) -> Route:
    """The sailed AIS track as a :class:`Route` (ETAs = the fixes' times, leg speeds from them).

    Fixes are sorted by time, duplicated timestamps and fixes without a position dropped, and
    the track thinned to one fix per ``min_step_s`` (the last fix is always kept), so a 10-second
    AIS feed does not turn into thousands of legs. With ``sea_check`` the thinning never makes a
    leg cross land: where a kept leg fails the one land check (:func:`routing.land.legs_at_sea`,
    berths = the track's ends) the fixes between its ends are kept too, so the track as shown is
    the track as sailed (a leg between two consecutive fixes that crosses land, an AIS gap over an
    island, stays and the evaluation says so: ``sea_only``). Leg speeds are the distances between
    the kept fixes over their time differences (speed made good), not the reported SOG.

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
    if sea_check:
        keep = _keep_at_sea(df["lat_deg"].to_numpy(dtype=float), df["lon_deg"].to_numpy(dtype=float), keep)
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


def _keep_at_sea(lat: np.ndarray, lon: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``keep`` plus every fix between the ends of a kept leg that crosses land."""
    from routing.land import legs_at_sea

    idx = np.flatnonzero(keep)
    ends = [(lat[0], lon[0]), (lat[-1], lon[-1])]
    ok = legs_at_sea(lat[idx], lon[idx], berths=ends)
    out = keep.copy()
    for k in np.flatnonzero(~ok):
        out[idx[k] : idx[k + 1] + 1] = True
    return out


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
#: Hours without weather (on the weather's land cells or outside it) an alternative may have
#: beyond its reference and still be called safer: rounding only. [h]
NO_WEATHER_TOL_H = 0.01
#: The audit's sailed rows: the AIS track at its AIS times (the truth), and the same track
#: re-timed by the vessel model (the like-for-like reference of the alternatives).
AS_SAILED = "as_sailed"
AS_SAILED_MODELLED = "as_sailed_modelled"


def not_proposable(summary: dict, reference: dict) -> str | None:
    """Why a route may not be proposed against a reference, or None.

    Not at sea (the one land check failed), or more hours without weather than the reference:
    hours over land or off the weather count as no exposure, so such a route would look safer
    for the wrong reason.
    """
    if summary.get("not_proposed"):
        return str(summary["not_proposed"])
    if summary.get("sea_only") is False:
        return f"legs {summary.get('land_legs')} cross land ({summary.get('land_nmi', 0):.1f} nmi)"
    extra = (summary.get("no_weather_h") or 0.0) - (reference.get("no_weather_h") or 0.0)
    if extra > NO_WEATHER_TOL_H:
        return f"{extra:.1f} h more without weather than the reference (time without weather is never counted as safe)"
    return None


def propose(evaluations: dict, reference: str = AS_SAILED_MODELLED) -> str | None:
    """The alternative to recommend: safer than the reference, else faster at no extra risk.

    Safer (:func:`safety_order`) means fewer hours over the operator limits plus IMO events
    (``adverse_h``), then fewer IMO events, then a maximum Hs lower by more than
    :data:`HS_TIE_M`. An alternative that is not safer may still be proposed when it is as safe
    and faster. Among the alternatives that qualify, the safest is proposed, and of those as safe
    as it (within the same tolerance) the fastest. Routes that are not sea-only or have more
    hours without weather than the reference are never proposed (:func:`not_proposable`); nor
    are the reference's own siblings (``as_sailed``). ``None`` when no alternative improves on
    the reference.
    """
    ref = evaluations.get(reference)
    if ref is None:
        return None
    r = ref.summary
    skip = {reference, AS_SAILED, AS_SAILED_MODELLED, "historical", "lane"}
    qualified = []
    for role in [x for x in PREFERENCE if x in evaluations] + sorted(set(evaluations) - set(PREFERENCE) - skip):
        s = evaluations[role].summary
        if not_proposable({**s, **{k: v for k, v in evaluations[role].route.properties.items() if k == "not_proposed"}}, r):
            continue
        if improves_on(s, r):
            qualified.append(role)
    best = None
    for role in qualified:  # in preference order: the first of equals stays
        if best is None or improves_on(evaluations[role].summary, evaluations[best].summary):
            best = role
    return best


def improves_on(s: dict, r: dict) -> bool:
    """Whether the route summarised by ``s`` is safer than ``r`` (:func:`safety_order`), or as safe
    and faster."""
    order = safety_order(s, r)
    return order < 0 or (order == 0 and s["time_h"] < r["time_h"] - 1e-6)


#: Maximum Hs within this of each other is the same for "safer": wave heights measured by
#: instruments are reported in units of 0.1 m (WMO-No. 306, Manual on Codes, FM 13 SHIP, group
#: 70HwaHwaHwa); a difference below it is interpolation along two tracks through the same
#: field, not a safer sea (a proposal once rested on 1 mm). [m]
HS_TIE_M = 0.1
#: Adverse hours within this of each other are the same (sums of leg times). [h]
ADVERSE_TIE_H = 1e-6


def safety_order(s: dict, r: dict) -> int:
    """-1 when the route summarised by ``s`` is safer than ``r``, +1 when less safe, 0 as safe.

    Compared in turn: ``adverse_h`` (hours over the limits or in IMO situations; ties within
    :data:`ADVERSE_TIE_H`), ``n_safety_events`` (missing: none), ``max_hs_m`` (ties within
    :data:`HS_TIE_M`; a missing Hs is the highest)."""
    da = s["adverse_h"] - r["adverse_h"]
    if abs(da) > ADVERSE_TIE_H:
        return -1 if da < 0 else 1
    ev_s, ev_r = s.get("n_safety_events", 0), r.get("n_safety_events", 0)
    if ev_s != ev_r:
        return -1 if ev_s < ev_r else 1
    hs_s, hs_r = (x if x is not None and np.isfinite(x) else np.inf for x in (s.get("max_hs_m"), r.get("max_hs_m")))
    if hs_s == hs_r or abs(hs_s - hs_r) <= HS_TIE_M:
        return 0
    return -1 if hs_s < hs_r else 1


def _hours(h: float) -> str:
    return f"{h:.1f} h"


#: Below this Hs the sea state counts as low: the WMO probable maximum wave height of Beaufort 4,
#: where Aertssen's table (:mod:`routing.speed_loss`) gives no speed loss. [m]
LOW_SEA_HS_M = 1.5
#: At least this long in low sea states, under way, for a calm-water speed from AIS. [h]
MIN_LOW_SEA_H = 1.0


def calm_water_speed(track: Route, weather_at, fallback_kn: float, *, low_hs_m: float = LOW_SEA_HS_M,
                     min_hours: float = MIN_LOW_SEA_H) -> dict:
    """The voyage's calm-water speed, estimated from its AIS speeds in low sea states.

    The time-weighted median speed made good of the track's legs sailed under way (at least half
    the track's median leg speed, and at least :data:`STATIONARY_KN`) in Hs <= ``low_hs_m`` at the
    leg's middle and mid-time, when those legs add up to ``min_hours``; else ``fallback_kn`` (the
    vessel profile's service speed). Speed made good includes any current.

    Returns
    -------
    dict
        ``speed_kn``, ``source`` (``"ais_low_sea"`` or ``"profile"``), ``low_sea_h`` (hours of
        legs used), ``low_hs_m``.
    """
    from thresholds.geodesy import intermediate_point

    d, h, v = _legs(track)
    out = {"speed_kn": float(fallback_kn), "source": "profile", "low_sea_h": 0.0, "low_hs_m": float(low_hs_m)}
    if d.size == 0:
        return out
    mid_lat, mid_lon = intermediate_point(track.lat_deg[:-1], track.lon_deg[:-1], track.lat_deg[1:], track.lon_deg[1:], 0.5)
    mid_t = pd.DatetimeIndex(track.time_utc.asi8[:-1] + np.diff(track.time_utc.asi8) // 2, tz="UTC")
    hs = np.asarray(weather_at(mid_t, np.atleast_1d(mid_lat), np.atleast_1d(mid_lon)).get("hs_m", np.full(d.size, np.nan)), dtype=float)
    moving = v >= max(STATIONARY_KN, 0.5 * float(np.median(v[v > 0])) if (v > 0).any() else STATIONARY_KN)
    use = moving & np.isfinite(hs) & (hs <= low_hs_m) & (h > 0)
    hours = float(h[use].sum())
    out["low_sea_h"] = round(hours, 3)
    if hours < min_hours:
        return out
    order = np.argsort(v[use])
    cum = np.cumsum(h[use][order])
    out["speed_kn"] = float(v[use][order][np.searchsorted(cum, 0.5 * cum[-1])])
    out["source"] = "ais_low_sea"
    return out


def model_bias(as_sailed: dict, modelled: dict) -> dict:
    """The vessel model's bias on this voyage: modelled minus AIS, time and fuel, in units and %."""
    out = {}
    for key, unit in (("time_h", "h"), ("fuel_t", "t"), ("co2_t", "t")):
        a, m = as_sailed.get(key), modelled.get(key)
        if a is None or m is None:
            continue
        out[key] = round(float(m - a), 4)
        out[key.replace(f"_{unit}", "_pct")] = round(float((m - a) / a * 100.0), 3) if a else None
    return out


def bias_words(bias: dict, savings: dict) -> list[str]:
    """Sentences saying where the model's bias is larger than a saving claimed against the modelled row.

    ``savings`` maps a role to its deltas against the modelled track (``time_h``, ``fuel_t``:
    negative = saving)."""
    out = []
    for role, d in savings.items():
        for key, what, unit in (("time_h", "time", "h"), ("fuel_t", "fuel", "t")):
            saving, b = d.get(key), bias.get(key)
            if saving is None or b is None or not saving < 0:
                continue
            if abs(b) > abs(saving):
                out.append(f"{role.replace('_', '-')}: its {what} saving ({-saving:.2f} {unit} against the modelled track) is smaller "
                           f"than the model's {what} bias on this voyage ({b:+.2f} {unit}, modelled minus AIS): it is within the "
                           "model's error, not a proven saving.")
    return out


def findings(evaluations: dict, proposed: str | None, reference: str = AS_SAILED_MODELLED, bias: dict | None = None) -> list[str]:
    """Plain-language findings of an audit (what happened, what the alternatives would have done)."""
    out = []
    sailed = evaluations.get(AS_SAILED, evaluations[reference])
    ref = evaluations[reference]
    s = sailed.summary
    out.append(
        f"The sailed track took {_hours(s['time_h'])} over {s['dist_nmi']:.1f} nmi and met significant wave heights up to "
        f"{s['max_hs_m']:.1f} m (mean {s['mean_hs_m']:.1f} m)."
    )
    imo = [e for e in sailed.events if e["kind"] == "imo"]
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
    r = ref.summary
    if bias and reference != AS_SAILED:
        out.append(f"The vessel model re-times the same track in {_hours(r['time_h'])} ({bias.get('time_h', 0):+.2f} h, "
                   f"{bias.get('time_pct') or 0:+.1f} %) and {r['fuel_t']:.2f} t of fuel ({bias.get('fuel_t', 0):+.2f} t, "
                   f"{bias.get('fuel_pct') or 0:+.1f} %) against the AIS times: the model's bias on this voyage. The alternatives "
                   "are sailed by the same model and compared with this modelled track.")
    savings = {}
    for role, ev in evaluations.items():
        if role in (reference, AS_SAILED):
            continue
        a = ev.summary
        m = comparison_metrics(ref, ev)
        dec = m["hs_decrease_pct"]
        if not np.isfinite(dec):
            dec_txt = ""
        else:
            dec_txt = f", {abs(dec):.0f} % {'lower' if dec >= 0 else 'higher'} mean Hs over the track's adverse portion"
        savings[role] = {"time_h": a["time_h"] - r["time_h"], "fuel_t": a["fuel_t"] - r["fuel_t"]}
        why = not_proposable(a, r)
        out.append(
            f"{role.replace('_', '-')}: {a['time_h'] - r['time_h']:+.1f} h, {a['dist_nmi'] - r['dist_nmi']:+.1f} nmi, "
            f"max Hs {a['max_hs_m']:.1f} m, {_hours(a['adverse_h'])} adverse, {a['n_safety_events']} IMO event(s), "
            f"fuel {a['fuel_t'] - r['fuel_t']:+.2f} t, CO2 {a['co2_t'] - r['co2_t']:+.2f} t{dec_txt} (against the "
            f"{'modelled track' if reference == AS_SAILED_MODELLED else reference})" + (f"; not proposed: {why}" if why else "") + "."
        )
    for role, ev in evaluations.items():  # legs whose speed no setting makes, or held at the floor: what was charged
        note = (ev.summary.get("engine_settings") or {}).get("note")
        if note:
            out.append(f"{role.replace('_', '-')} fuel: {note}.")
    if bias:
        out += bias_words(bias, savings)
    if proposed is None:
        out.append("No alternative was safer or faster than the sailed track.")
    else:
        a = evaluations[proposed].summary
        what = "safer" if (a["adverse_h"], a["n_safety_events"]) < (r["adverse_h"], r["n_safety_events"]) else "as safe and faster"
        out.append(f"Proposed alternative: {proposed.replace('_', '-')} ({what}).")
    return out


def audit_routes(track: Route, weather_at, vessel, *, limits=None, alternatives: dict | None = None, modelled: Route | None = None,
                 speed_loss_model: str = "bowditch", max_step_h: float = 0.25, learned=None) -> dict:
    """Evaluate the sailed track, its modelled twin and its alternatives in the same weather and compare them.

    Parameters
    ----------
    track : Route
        The sailed track (:func:`track_to_route`) at its AIS times: role ``as_sailed``.
    weather_at : callable
        Hindcast weather sampler (:class:`routing.sampling.PointSampler`).
    vessel, limits, learned :
        As in :func:`routing.evaluate.evaluate_route` (``learned``: the table of a learned model).
    alternatives : dict of str -> Route
        ``deviation``, ``optimal``, ``min_distance`` ... for the same departure, sailed by the model.
    modelled : Route, optional
        The same track re-timed by the vessel model (:func:`routing.compare.retime`): role
        ``as_sailed_modelled``, the reference of every delta. Without it the AIS track is the
        reference (and every saving then holds the model's bias).

    Returns
    -------
    dict
        ``evaluations`` (role -> RouteEvaluation), ``table`` (:func:`comparison_table` against the
        reference), ``reference`` (its role), ``bias`` (modelled minus AIS, :func:`model_bias`),
        ``proposed`` (role or None) and ``findings`` (list of str).
    """
    kw = {"limits": limits, "speed_loss_model": speed_loss_model, "max_step_h": max_step_h, "learned": learned}
    evaluations: dict[str, RouteEvaluation] = {AS_SAILED: evaluate_route(track, weather_at, vessel, **kw)}
    reference, bias = AS_SAILED, {}
    if modelled is not None:
        evaluations[AS_SAILED_MODELLED] = evaluate_route(modelled, weather_at, vessel, **kw)
        reference = AS_SAILED_MODELLED
        bias = model_bias(evaluations[AS_SAILED].summary, evaluations[AS_SAILED_MODELLED].summary)
    for role, route in (alternatives or {}).items():
        evaluations[role] = evaluate_route(route, weather_at, vessel, **kw)
    table = comparison_table(evaluations, reference=reference)
    proposed = propose(evaluations, reference=reference)
    return {"evaluations": evaluations, "table": table, "proposed": proposed, "reference": reference, "bias": bias,
            "findings": findings(evaluations, proposed, reference=reference, bias=bias)}
