"""Uncertainty where users read it: a learned model's P10-P90 bands of a route, and how every speed
model did on a sailed voyage.

:func:`quantile_bands` re-times a route's path with a learned model's quantile tables
(:class:`routing.learned.LearnedSpeedTable`: ``p90`` ratios give the early arrival, ``p10`` the
late one) through the plan's weather and mesh, exactly as the search times a path
(:func:`routing.astar.evaluate_path`), and evaluates each re-timed route's STEAM2 fuel with the same
quantile's speed loss (:func:`routing.evaluate.evaluate_route`). The errors of one voyage are taken
as fully correlated along it (the same master, hull and loading on every leg): the wide reading of
the band; independent legs would narrow it.

:func:`model_check` re-times a sailed track with each wave formula (Bowditch, Aertssen, Khokhlov)
and with the learned model from the same departure at the same calm-water speed, and compares
each modelled time with the AIS time of the very voyage (modelled minus AIS). Kwon is left out: the
plan's weather arrays carry the waves, not the wind.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from routing.route import Route

#: Wave formulas compared with the AIS time of a sailed voyage (``model_check``).
CHECK_FORMULAS = ("bowditch", "aertssen", "khokhlov")
#: Quantile -> the table whose ratios time it (a high speed quantile is an early arrival).
TIME_QUANTILES = (("p10", "p90"), ("p50", "ratio"), ("p90", "p10"))
BAND_ASSUMPTION = "quantile speed ratios fully correlated along the route"


def _timed(plan, ship, lat_deg, lon_deg, t0_utc: pd.Timestamp) -> pd.DatetimeIndex:
    """The vertices' times of a path sailed by ``ship`` in the plan's weather from ``t0_utc``."""
    from routing.astar import evaluate_path

    wx = plan.weather_arrays
    t0 = pd.Timestamp(t0_utc)
    t0 = t0.tz_localize("UTC") if t0.tzinfo is None else t0.tz_convert("UTC")
    t0_h = wx.rel_h(t0.value)
    times_h, _ = evaluate_path(plan.mesh, wx, ship, np.asarray(lat_deg, float), np.asarray(lon_deg, float), t_start_h=t0_h)
    return pd.DatetimeIndex(t0 + pd.to_timedelta(np.asarray(times_h, float) - t0_h, unit="h"))


def _band_ship(ship, which: str):
    return ship if which == "ratio" else dataclasses.replace(ship, learned=ship.learned.band(which))


def band_routes(route: Route, plan) -> dict | None:
    """``route``'s path re-timed by the plan's learned P10, P50 and P90 tables: quantile -> (Route,
    the table that timed it); None for a formula's plan."""
    ship = plan.ship
    if ship is None or ship.model != "learned" or plan.weather_arrays is None or route.n_waypoints < 2:
        return None
    out = {}
    dist = _leg_nmi(route)
    for q, which in TIME_QUANTILES:
        s = _band_ship(ship, which)
        times = _timed(plan, s, route.lat_deg, route.lon_deg, route.time_utc[0])
        dt = np.diff(times.asi8) / 3.6e12
        out[q] = (Route(f"{route.name}_{q}", route.lat_deg, route.lon_deg, times,
                        np.divide(dist, dt, out=np.zeros_like(dist), where=dt > 0), properties={"timed_by": f"model {q}"}),
                  s.learned)
    return out


def quantile_bands(route: Route, plan, weather_at=None, vessel=None, *, label: str, limits=None) -> dict | None:
    """P10, P50 and P90 sailing time (and fuel, given ``weather_at`` and ``vessel``) of ``route`` by
    the plan's learned model (None for a formula). ``time_h_pXX`` is the route re-timed by the
    quantile's speed table (:func:`band_routes`); ``fuel_t_pXX`` the STEAM2 fuel of that re-timed
    route with the same table's speed loss; ``label`` names the model (``learned:NAME``)."""
    from routing.evaluate import evaluate_route

    bands = band_routes(route, plan)
    if bands is None:
        return None
    out: dict = {"route": route.name, "model": label, "assumption": BAND_ASSUMPTION}
    for q, (r, table) in bands.items():
        out[f"time_h_{q}"] = float(r.time_h)
        if weather_at is not None and vessel is not None:
            ev = evaluate_route(r, weather_at, vessel, limits=limits, speed_loss_model=label, learned=table, models=())
            out[f"fuel_t_{q}"] = float(ev.summary["fuel_t"])
    return out


def _leg_nmi(route: Route) -> np.ndarray:
    from thresholds.geodesy import haversine_nmi

    lat, lon = route.lat_deg, route.lon_deg
    return np.asarray(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]), dtype=float).reshape(-1)


def model_check(track: Route, plan, vessel, learned=None) -> list[dict]:
    """Each speed model's time for the sailed track against its AIS time (module notes).

    Rows: ``model``, ``time_h`` (modelled), ``ais_time_h``, ``bias_h`` and ``bias_pct`` (modelled
    minus AIS), or ``error`` when the model cannot sail this vessel (outside its published range).
    The learned row (a learned plan's model, else ``learned``: a table of a stored model for this
    vessel, compared though the plan sails by a formula) also has ``time_h_p10``/``time_h_p90`` and
    ``inside_band`` (the AIS time within them)."""
    from routing.astar import ShipModel

    ais_h = float(track.time_h)
    rows = []
    base = plan.ship
    if base.model != "learned" and learned is not None:
        base_learned = ShipModel.from_vessel(vessel, "learned", speed_kn=base.speed_kn, learned=learned)
    else:
        base_learned = base if base.model == "learned" else None
    models = list(CHECK_FORMULAS) + (["learned"] if base_learned is not None else [])
    for m in models:
        name = f"learned:{base_learned.learned.name}" if m == "learned" else m
        try:
            ship = base_learned if m == "learned" else ShipModel.from_vessel(vessel, m, speed_kn=base.speed_kn)
            t = _timed(plan, ship, track.lat_deg, track.lon_deg, track.time_utc[0])
        except ValueError as err:  # a formula outside its published range (SpeedLossRangeError)
            rows.append({"model": name, "error": str(err)})
            continue
        h = float((t[-1] - t[0]).total_seconds() / 3600.0)
        row = {"model": name, "time_h": h, "ais_time_h": ais_h, "bias_h": h - ais_h,
               "bias_pct": 100.0 * (h - ais_h) / ais_h if ais_h > 0 else None}
        if m == "learned":
            for q, which in (("p10", "p90"), ("p90", "p10")):
                tq = _timed(plan, _band_ship(base_learned, which), track.lat_deg, track.lon_deg, track.time_utc[0])
                row[f"time_h_{q}"] = float((tq[-1] - tq[0]).total_seconds() / 3600.0)
            row["inside_band"] = bool(row["time_h_p10"] <= ais_h <= row["time_h_p90"])
        rows.append(row)
    return rows


def _h(x: float) -> str:
    return f"{x:.2f} h"


def check_lines(rows: list[dict], speed_kn: float) -> list[str]:
    """The findings sentence of :func:`model_check`."""
    if not rows:
        return []
    ais = next((r["ais_time_h"] for r in rows if "ais_time_h" in r), None)
    parts = []
    for r in rows:
        if "error" in r:
            parts.append(f"{r['model']} not applicable ({r['error']})")
            continue
        p = f"{r['model']} {_h(r['time_h'])} ({r['bias_h']:+.2f} h, {r['bias_pct']:+.1f} %)"
        if "inside_band" in r:
            p += (f", its P10-P90 band {r['time_h_p10']:.2f}-{r['time_h_p90']:.2f} h "
                  + ("holds" if r["inside_band"] else "misses") + " the AIS time")
        parts.append(p)
    return [f"Speed models on this very voyage (the sailed track re-timed from its departure at {speed_kn:.1f} kn, modelled minus "
            f"the AIS time {_h(ais) if ais is not None else '-'}): " + "; ".join(parts) + "."]


def band_line(band: dict, role: str) -> str:
    """The findings sentence of one route's :func:`quantile_bands`."""
    fuel = (f"; fuel {band['fuel_t_p10']:.2f} - {band['fuel_t_p50']:.2f} - {band['fuel_t_p90']:.2f} t (at those times)"
            if "fuel_t_p50" in band else "")
    return (f"{role.replace('_', '-')}: sailing time P10-P50-P90 by {band['model']}'s quantiles {band['time_h_p10']:.2f} - "
            f"{band['time_h_p50']:.2f} - {band['time_h_p90']:.2f} h{fuel} ({band['assumption']}).")


def audit_uncertainty(evaluations: dict, proposed: str | None, reference: str, track: Route, plan, weather_at, vessel,
                      *, label: str, limits=None, check_learned=None) -> dict:
    """What an audit adds for its speed models: ``model_check`` (:func:`model_check` of the sailed
    track; ``check_learned``: a stored model's table compared too when the audit sails a formula),
    ``bands`` (role -> :func:`quantile_bands`, for the reference and the proposed route, with a
    learned model) and ``findings`` (their sentences)."""
    if plan is None:
        return {"model_check": [], "bands": {}, "findings": []}
    rows = model_check(track, plan, vessel, learned=check_learned)
    bands = {}
    for role in dict.fromkeys([reference, proposed]):
        if role in evaluations:
            b = quantile_bands(evaluations[role].route, plan, weather_at, vessel, label=label, limits=limits)
            if b is not None:
                bands[role] = b
    lines = check_lines(rows, plan.ship.speed_kn) + [band_line(b, role) for role, b in bands.items()]
    return {"model_check": rows, "bands": bands, "findings": lines}
