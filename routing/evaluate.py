"""Route evaluation: weather met, speed loss, time and distance, STEAM2 fuel and emissions, IMO
MSC.1/Circ.1228 events, exposure over operator limits, and the seed paper's comparison metrics.

Any :class:`~routing.route.Route` is evaluated *at its own ETAs*: an AIS track, a lane's centroid
path, a cargo-safe deviation (:mod:`routing.deviate`) or an A* route. Each leg is cut into pieces
of at most ``max_step_h`` (15 min by default) and the weather is sampled at the middle of each
piece, at the time the ship is there, so a long leg through a storm is not judged by its end
points alone. Every sample carries its duration, so exposures are in hours, not in counts of
waypoints.

What is computed (all reported per route by :class:`RouteEvaluation`):

* weather met: Hs, period, wind, wave direction (max and time-weighted mean);
* speed loss of each model (:mod:`routing.speed_loss`) at the vessel's service speed and each
  piece's encounter angle (0 = head seas), and the time the route's geometry would take under
  each model;
* STEAM2 fuel and CO2/SO2/NOx/PM (:mod:`routing.emissions`) of each leg at its engine setting
  (:mod:`routing.leg_setting`): the route's planned setting per leg where it carries one, else the
  calm-water speed whose speed made in the weather met (the chosen model's loss *at that setting*,
  the floor, the current) is the leg's own speed; the power ``P(setting)`` over the leg's time (the
  wave power increase restores the setting). Legs faster than any setting up to the engine's maximum
  power makes, and legs held at the floor, are counted and said (``engine_settings``);
* safety: every rule of :func:`thresholds.safety.assess` (operator limits ``hs``, ``period``,
  ``wind``, ``beam_seas``; IMO ``surf_riding``, ``high_waves``, ``synchronous_roll``,
  ``parametric_roll``) on every piece; **events** are maximal runs of consecutive pieces where a
  rule fires (criterion, start, end, duration, where it started and where it was worst);
  **exposure** is the hours each rule fires;
* the comparison metrics of the cargo-loss seed paper [1]_ §4 between a reference route and an
  alternative (:func:`comparison_metrics`): percentage decrease of mean Hs (Eq. 1), wave period
  (Eq. 2) and wind speed (Eq. 3) over the portion of the reference where its conditions were
  adverse, the deviation of the relative wave direction, and the length difference.

References
----------
.. [1] K. Spyrou-Sioula, I. Kontopoulos, D. Kaklis, A. Makris, K. Tserpes, P. Eirinakis and
       F. Oikonomou, "AIS-enabled weather routing for cargo loss prevention," J. Mar. Sci. Eng.,
       vol. 10, no. 11, 1755, 2022, doi:10.3390/jmse10111755, §4, Eq. 1-3.
.. [2] IMO, "Revised guidance to the master for avoiding dangerous situations in adverse weather
       and sea conditions," MSC.1/Circ.1228, 2007.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np
import pandas as pd

from routing.emissions import steam2_totals
from routing.leg_setting import route_legs, setting_legs  # noqa: F401 (setting_legs re-exported)
from routing.route import Route
from routing.samples import IMO_RULES, densify  # noqa: F401 (densify re-exported: the evaluation's sampling)
from routing.samples import nanmax as _nanmax
from routing.samples import rule_events as _events
from routing.samples import weighted_mean as _weighted_mean

#: Operator-limit rules (the seed paper's Table 1 thresholds).
OPERATOR_RULES = ("hs", "period", "wind", "beam_seas")
#: Speed-loss models evaluated on every route.
SPEED_LOSS_MODELS = ("bowditch", "aertssen", "khokhlov")
#: Weather variables sampled along a route (those present in the data).
WEATHER_VARS = ("hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms", "current_u_ms", "current_v_ms")

#: ``weather_at(times, lat, lon) -> {var: ndarray}`` (same protocol as :mod:`routing.deviate`).
WeatherAt = Callable[[pd.DatetimeIndex, np.ndarray, np.ndarray], Mapping[str, np.ndarray]]
#: ``assess_fn(weather, heading_deg, speed_kn)`` returning an object with ``rules`` (name ->
#: object with boolean ``fired`` and float ``margin`` arrays) and ``skipped`` (tuple of str), as
#: :func:`thresholds.safety.assess` does.
AssessFn = Callable[[Mapping[str, np.ndarray], np.ndarray, np.ndarray], object]


def assess_with(vessel, limits=None, missing: str = "skip") -> AssessFn:
    """The vessel's thresholds (operator ``limits`` + IMO) as an ``assess_fn`` for evaluations.

    Wraps :func:`thresholds.safety.assess`; ``missing="skip"`` lists rules whose variable is not in
    the data (e.g. wind on a wave-only product) instead of failing, and the evaluation reports them
    as not evaluated.
    """
    from thresholds.safety import assess

    def assess_fn(weather, heading_deg, speed_kn):
        kwargs = {k: weather[k] for k in ("hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms") if k in weather}
        if "hs_m" not in kwargs:
            kwargs["hs_m"] = np.full(np.shape(heading_deg), np.nan)
        return assess(vessel, limits, heading_deg=heading_deg, speed_kn=speed_kn, missing=missing, **kwargs)

    return assess_fn


def rule_check(assess_fn: AssessFn) -> Callable:
    """Adapt an ``assess_fn`` to the ``check(weather, heading, speed) -> {rule: fired}`` protocol
    of :func:`routing.deviate.deviate_lane` (missing data never counts as a broken rule)."""

    def check(weather, heading_deg, speed_kn):
        a = assess_fn(weather, heading_deg, speed_kn)
        return {name: np.asarray(r.fired, dtype=bool) for name, r in a.rules.items()}

    return check


@dataclass
class RouteEvaluation:
    """Everything :func:`evaluate_route` found for one route.

    Attributes
    ----------
    route : Route
        The route, with the weather met at its waypoints filled in.
    samples : DataFrame
        One row per piece of leg (see :func:`densify`) with the weather, ``wind_ms``,
        ``encounter_deg``, ``speed_loss_<model>_kn`` and ``fired_<rule>`` columns.
    legs : DataFrame
        STEAM2 per leg (:func:`routing.emissions.steam2_legs`) plus ``leg`` and ``setting_kn`` (the engine
        setting charged, :mod:`routing.leg_setting`).
    summary : dict
        Totals (JSON-serialisable): time, distance, weather met, speed loss per model, fuel and
        emissions, exposure hours per rule, IMO/operator event counts, rules not evaluated.
    events : list of dict
        Runs of consecutive pieces where a rule fired.
    """

    route: Route
    samples: pd.DataFrame
    legs: pd.DataFrame
    summary: dict
    events: list = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.route.name

    def to_dict(self, waypoints: bool = True) -> dict:
        """JSON shape: the route summary, the evaluation summary and the events."""
        out = {**self.route.to_dict(waypoints=waypoints), **self.summary}
        out["events"] = self.events
        return out


def evaluate_route(
    route: Route,
    weather_at: WeatherAt,
    vessel,
    *,
    assess_fn: AssessFn | None = None,
    limits=None,
    speed_loss_model: str = "bowditch",
    models: tuple = SPEED_LOSS_MODELS,
    max_step_h: float = 0.25,
    learned=None,
) -> RouteEvaluation:
    """Evaluate a route at its own ETAs.

    Parameters
    ----------
    route : Route
    weather_at : callable
        ``weather_at(times, lat, lon) -> {var: values}`` in canonical names (``hs_m``,
        ``wave_from_deg``, ``tp_s``, ``tm_s``, ``wind_u_ms``, ``wind_v_ms`` ...); NaN off the data.
    vessel : thresholds.vessel.Vessel
        Service speed, dimensions (speed-loss models, IMO rules) and engine (STEAM2).
    assess_fn : callable, optional
        Thresholds; default :func:`assess_with` ``(vessel, limits)``.
    limits : OperatorProfile or OperatorLimits, optional
        Operator limits for the default ``assess_fn``.
    speed_loss_model : str, default "bowditch"
        Model whose speed loss (at each leg's engine setting) drives the STEAM2 wave power increase.
    models : tuple of str
        Speed-loss models reported.
    max_step_h : float, default 0.25
        Longest piece of leg sampled as one. [h]
    learned : routing.learned.LearnedSpeedTable, optional
        The table of ``speed_loss_model`` ``"learned:NAME"`` (:func:`routing.speed_loss.speed_loss`).

    Returns
    -------
    RouteEvaluation
    """
    if speed_loss_model not in models:
        models = tuple(models) + (speed_loss_model,)
    if assess_fn is None:
        assess_fn = assess_with(vessel, limits)
    samples = densify(route, max_step_h)
    weather, cols = _weather_columns(samples, weather_at)
    loss_summary, model_warnings = _speed_loss_columns(samples, cols, vessel, models, learned)
    rules, exposure, margins, skipped = _rule_columns(samples, cols, weather, assess_fn)
    samples = pd.concat([samples, pd.DataFrame(cols, index=samples.index)], axis=1)
    events: list[dict] = []
    for name in rules:
        events += _events(samples, name, margins[name])
    events.sort(key=lambda e: (e["start_utc"], e["criterion"]))
    legs, settings = _leg_emissions(route, samples, weather, speed_loss_model, vessel, learned)
    summary = {
        **_route_summary(route, samples, weather),
        "speed_loss": loss_summary,
        "speed_loss_model": speed_loss_model,
        **steam2_totals(legs),
        "engine_settings": settings,
        "exposure_by_rule_h": exposure,
        **_exposure_summary(samples, events),
        **land_summary(route),
        "rules_not_evaluated": skipped,
        "speed_loss_warnings": model_warnings,
        "weather_vars": sorted(weather),
    }
    return RouteEvaluation(_with_waypoint_weather(route, weather_at), samples, legs, summary, events)


def _weather_columns(samples: pd.DataFrame, weather_at: WeatherAt) -> tuple[dict, dict]:
    """(the weather at every piece, in canonical names; the new sample columns: weather, wind speed, encounter angle)."""
    n = len(samples)
    times = pd.DatetimeIndex(samples["time_utc"])
    raw = weather_at(times, samples["lat_deg"].to_numpy(), samples["lon_deg"].to_numpy()) if n else {}
    weather = {k: np.asarray(v, dtype=float).reshape(-1) for k, v in raw.items() if k in WEATHER_VARS}
    cols: dict[str, np.ndarray] = dict(weather)
    if "wind_u_ms" in weather and "wind_v_ms" in weather:
        cols["wind_ms"] = np.hypot(weather["wind_u_ms"], weather["wind_v_ms"])
    heading = samples["heading_deg"].to_numpy()
    # 0 = head seas: the direction the waves come from, relative to the course
    cols["encounter_deg"] = np.mod(weather["wave_from_deg"] - heading, 360.0) if "wave_from_deg" in weather else np.full(n, np.nan)
    return weather, cols


def _speed_loss_columns(samples: pd.DataFrame, cols: dict, vessel, models, learned=None) -> tuple[dict, list[str]]:
    """Each model's speed loss at the service speed on every piece (added to ``cols``), its mean, max
    and the time the geometry takes under it; the models' warnings (out of range ...) as text."""
    from routing.speed_loss import speed_loss

    n = len(samples)
    hs = np.nan_to_num(cols.get("hs_m", np.full(n, np.nan)), nan=0.0)
    enc = np.nan_to_num(cols["encounter_deg"], nan=0.0)
    dt_h = samples["dt_h"].to_numpy()
    dist = samples["dist_nmi"].to_numpy()
    v0 = float(vessel.speed_kn)
    summary, model_warnings = {}, []
    for model in models:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            loss = (np.asarray(speed_loss(v0, hs, enc, model, vessel=vessel, learned=learned), dtype=float).reshape(-1)
                    if n else np.zeros(0))
        model_warnings += sorted({f"{model}: {w.message}" for w in caught})
        cols[f"speed_loss_{model}_kn"] = loss
        summary[model] = {
            "mean_kn": _weighted_mean(loss, dt_h),
            "max_kn": _nanmax(loss) if loss.size else float("nan"),
            "time_h_at_service_speed": float(np.sum(dist / (v0 - loss))) if loss.size else 0.0,
        }
    return summary, model_warnings


def _rule_columns(samples: pd.DataFrame, cols: dict, weather: dict, assess_fn: AssessFn):
    """Every rule on every piece: ``fired_<rule>``, ``adverse_operator``, ``adverse_imo`` and
    ``no_data`` columns (added to ``cols``); returns (rules, hours per rule, margins, rules not evaluated)."""
    n = len(samples)
    a = assess_fn(weather, samples["heading_deg"].to_numpy(), samples["speed_kn"].to_numpy()) if n else None
    rules = dict(a.rules) if a is not None else {}
    dt_h = samples["dt_h"].to_numpy()
    exposure, margins = {}, {}
    any_op = np.zeros(n, dtype=bool)
    any_imo = np.zeros(n, dtype=bool)
    for name, rule in rules.items():
        fired = np.broadcast_to(np.asarray(rule.fired, dtype=bool), (n,))
        margins[name] = np.broadcast_to(np.asarray(rule.margin, dtype=float), (n,))
        cols[f"fired_{name}"] = fired
        exposure[name] = float(dt_h[fired].sum())
        if name in IMO_RULES:
            any_imo |= fired
        else:
            any_op |= fired
    cols["adverse_operator"] = any_op
    cols["adverse_imo"] = any_imo
    nd = getattr(a, "no_data", None) if a is not None else None
    cols["no_data"] = np.broadcast_to(np.asarray(nd, dtype=bool), (n,)) if nd is not None else np.zeros(n, dtype=bool)
    skipped = list(getattr(a, "skipped", ())) if a is not None else []
    return rules, exposure, margins, skipped


def _leg_emissions(route: Route, samples: pd.DataFrame, weather: dict, model: str, vessel, learned=None) -> tuple[pd.DataFrame, dict]:
    """STEAM2 per leg at each leg's engine setting (:func:`routing.leg_setting.route_legs`): the route's planned
    setting per leg (``speed_setting_kn``, 0 = a wait) where it has one, else the setting whose speed made in the
    weather met is the leg's own speed; the loss at that setting (wave power increase) on that leg. Returns the legs
    (with ``leg`` and ``setting_kn``) and the summary's ``engine_settings``."""
    n_legs = max(route.n_waypoints - 1, 0)
    leg_dt = np.diff(route.time_utc.asi8) / 3.6e12 if n_legs else np.zeros(0)
    enc = samples["encounter_deg"].to_numpy() if len(samples) else np.zeros(0)
    at_service = samples[f"speed_loss_{model}_kn"].to_numpy() if len(samples) else None
    setting = route.properties.get("speed_setting_kn")
    planned = setting if setting is not None and len(setting) == n_legs else None
    legs, info = route_legs(leg_dt, route.leg_speed_kn, planned, samples, weather, enc, model, vessel, learned, at_service)
    legs.insert(0, "leg", np.arange(n_legs))
    return legs, settings_summary(legs["time_h"].to_numpy(), info, planned=planned is not None)


def settings_summary(leg_h: np.ndarray, info: dict, planned: bool) -> dict:
    """The summary's ``engine_settings``: where each leg's setting came from (``basis``: ``planned`` or ``solved``
    from its speed), and the legs the speed made does not fit (above the maximum-power speed: charged the installed
    power; held at the floor: the setting nearest the service speed), with a sentence (``note``) when there are any."""
    over, floor = info["above_max_power"], info["floor"]
    out = {"basis": "planned" if planned else "solved", "above_max_power_legs": int(over.sum()),
           "above_max_power_h": float(leg_h[over].sum()), "floor_legs": int(floor.sum()), "floor_h": float(leg_h[floor].sum()),
           "note": None}
    words = []
    if over.any():
        words.append(f"{out['above_max_power_legs']} leg(s) ({out['above_max_power_h']:.2f} h) faster than any setting up to the engine's "
                     "maximum-power speed makes in the weather met: charged the installed power over their time (power_limited)")
    if floor.any():
        words.append(f"{out['floor_legs']} leg(s) ({out['floor_h']:.2f} h) held at the speed floor, where the speed does not tell the "
                     "setting: charged the setting nearest the service speed")
    out["note"] = "; ".join(words) or None
    return out


def _with_waypoint_weather(route: Route, weather_at: WeatherAt) -> Route:
    """The route with the weather at its waypoints (for maps and exports); what it already had is kept."""
    wp = {}
    if route.n_waypoints:
        wraw = weather_at(route.time_utc, route.lat_deg, route.lon_deg)
        wp = {k: np.asarray(v, dtype=float).reshape(-1) for k, v in wraw.items() if k in WEATHER_VARS}
    return Route(
        name=route.name, lat_deg=route.lat_deg, lon_deg=route.lon_deg, time_utc=route.time_utc,
        leg_speed_kn=route.leg_speed_kn, weather={**wp, **route.weather}, properties=dict(route.properties),
    )  # fmt: skip


def _route_summary(route: Route, samples: pd.DataFrame, weather: dict) -> dict:
    """Times, distance, mean speed made and the weather met (max and time-weighted mean)."""
    dt = samples["dt_h"] if len(samples) else pd.Series(dtype=float)
    hs = weather.get("hs_m", np.full(len(samples), np.nan))
    return {
        "name": route.name,
        "depart_utc": route.time_utc[0].isoformat() if route.n_waypoints else None,
        "arrive_utc": route.time_utc[-1].isoformat() if route.n_waypoints else None,
        "time_h": route.time_h,
        "dist_nmi": route.dist_nmi,
        "mean_speed_kn": route.dist_nmi / route.time_h if route.time_h > 0 else float("nan"),
        "max_hs_m": _nanmax(hs) if hs.size else float("nan"),
        "mean_hs_m": _weighted_mean(hs, dt),
        "max_wind_ms": _nanmax(samples["wind_ms"]) if "wind_ms" in samples else None,
        "mean_wind_ms": _weighted_mean(samples["wind_ms"], dt) if "wind_ms" in samples else None,
        "max_tp_s": _nanmax(samples["tp_s"]) if "tp_s" in samples else None,
        "mean_tp_s": _weighted_mean(samples["tp_s"], dt) if "tp_s" in samples else None,
    }


def _exposure_summary(samples: pd.DataFrame, events: list[dict]) -> dict:
    """Hours over operator limits, under IMO rules and without weather; the events by kind."""
    op_h = imo_h = any_h = no_weather_h = 0.0
    if len(samples):
        dt = samples["dt_h"]
        op, imo = samples["adverse_operator"], samples["adverse_imo"]
        op_h, imo_h, any_h, no_weather_h = (float(dt[m].sum()) for m in (op, imo, op | imo, samples["no_data"]))
    n_imo = sum(e["kind"] == "imo" for e in events)
    return {
        # hours over any operator limit, and IMO events: the report's "exposure_h" / "n_safety_events"
        "exposure_h": op_h,
        "n_safety_events": n_imo,
        "adverse_h": any_h,
        "operator_adverse_h": op_h,
        "imo_adverse_h": imo_h,
        "n_imo_events": n_imo,
        "n_operator_events": sum(e["kind"] == "operator" for e in events),
        "no_weather_h": no_weather_h,
    }


def land_summary(route: Route) -> dict:
    """The one land check (:func:`routing.land.legs_at_sea`, berths = the route's ends) of a route:
    ``sea_only``, ``land_legs`` (indices of legs touching land pixels outside the berth radius) and
    ``land_nmi`` (their length over land, sampled every 0.05 nmi)."""
    from routing.land import land_nmi, legs_at_sea

    if route.n_waypoints < 2:
        return {"sea_only": True, "land_legs": [], "land_nmi": 0.0}
    ok = legs_at_sea(route.lat_deg, route.lon_deg)
    bad = np.flatnonzero(~ok)
    ends = [(route.lat_deg[0], route.lon_deg[0]), (route.lat_deg[-1], route.lon_deg[-1])]
    lat, lon = route.lat_deg, route.lon_deg
    over = sum(float(land_nmi(lat[k : k + 2], lon[k : k + 2], berths=ends)[0]) for k in bad)
    return {"sea_only": bool(ok.all()), "land_legs": bad.tolist(), "land_nmi": round(over, 3)}


def _adverse_windows(samples: pd.DataFrame, mask: np.ndarray) -> list[tuple[pd.Timestamp, pd.Timestamp]]:
    """Time intervals covered by the pieces in ``mask`` (merged where they touch)."""
    out: list[list[pd.Timestamp]] = []
    for t, dt in zip(samples.loc[mask, "time_utc"], samples.loc[mask, "dt_h"]):
        a, b = t - pd.Timedelta(hours=dt / 2), t + pd.Timedelta(hours=dt / 2)
        if out and a <= out[-1][1] + pd.Timedelta(seconds=1):
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return [(a, b) for a, b in out]


def _in_windows(times: pd.Series, windows) -> np.ndarray:
    inside = np.zeros(len(times), dtype=bool)
    for a, b in windows:
        inside |= ((times >= a) & (times <= b)).to_numpy()
    return inside


def comparison_metrics(reference: RouteEvaluation, alternative: RouteEvaluation, adverse: str = "operator") -> dict:
    """The seed paper's comparison metrics [1]_ §4 of an alternative against a reference route.

    The *adverse portion* is the set of pieces of the reference where its conditions broke a limit
    (``adverse="operator"``: the operator limits, the paper's Table 1; ``"any"``: also the IMO
    rules). Means are time-weighted; the alternative's means are taken over its own pieces that
    fall in the same time windows ("during the same period of time", [1] §4).

    * ``hs_decrease_pct`` = (h_a − h_b)/h_a · 100 ([1] Eq. 1), likewise ``period_decrease_pct``
      (Eq. 2; peak period, else mean period) and ``wind_decrease_pct`` (Eq. 3).
    * ``wave_dir_deviation_pct`` = |θ_a − θ_b| / θ_a · 100, θ the mean relative angle between the
      heading and the wave direction, folded to [0, 180] (0 = head seas) ([1] §4, Fig. 9).
    * ``length_diff_nmi`` = L_b − L_a and ``length_diff_pct`` = that / L_a · 100 ([1] Fig. 10-11).

    Positive decreases mean the alternative met calmer conditions. Values are NaN (None in JSON)
    when the reference had no adverse portion or the alternative was not at sea then.
    """
    ref, alt = reference.samples, alternative.samples
    col = "adverse_operator" if adverse == "operator" else None
    if col is not None and col in ref:
        mask = ref[col].to_numpy(dtype=bool)
    elif "adverse_operator" in ref:
        mask = (ref["adverse_operator"] | ref["adverse_imo"]).to_numpy(dtype=bool)
    else:
        mask = np.zeros(len(ref), dtype=bool)
    windows = _adverse_windows(ref, mask)
    alt_mask = _in_windows(alt["time_utc"], windows) if len(alt) else np.zeros(0, dtype=bool)

    def decrease(var):
        if var not in ref or var not in alt or not mask.any():
            return float("nan"), float("nan"), float("nan")
        a = _weighted_mean(ref.loc[mask, var], ref.loc[mask, "dt_h"])
        b = _weighted_mean(alt.loc[alt_mask, var], alt.loc[alt_mask, "dt_h"]) if alt_mask.any() else float("nan")
        pct = (a - b) / a * 100.0 if np.isfinite(a) and a != 0 and np.isfinite(b) else float("nan")  # [1], Eq. 1-3
        return a, b, pct

    hs_a, hs_b, hs_pct = decrease("hs_m")
    pvar = "tp_s" if "tp_s" in ref else "tm_s"
    p_a, p_b, p_pct = decrease(pvar)
    w_a, w_b, w_pct = decrease("wind_ms")

    def rel(frame, m):
        if "encounter_deg" not in frame or not m.any():
            return float("nan")
        folded = 180.0 - np.abs(180.0 - np.mod(frame.loc[m, "encounter_deg"].to_numpy(), 360.0))
        return _weighted_mean(folded, frame.loc[m, "dt_h"])

    th_a = rel(ref, mask)
    th_b = rel(alt, alt_mask) if len(alt) else float("nan")
    dir_pct = abs(th_a - th_b) / th_a * 100.0 if np.isfinite(th_a) and th_a > 0 and np.isfinite(th_b) else float("nan")
    la, lb = reference.route.dist_nmi, alternative.route.dist_nmi
    return {
        "reference": reference.name,
        "alternative": alternative.name,
        "adverse_portion_h": float(ref.loc[mask, "dt_h"].sum()) if mask.any() else 0.0,
        "hs_adverse_ref_m": hs_a,
        "hs_adverse_alt_m": hs_b,
        "hs_decrease_pct": hs_pct,
        "period_var": pvar,
        "period_adverse_ref_s": p_a,
        "period_adverse_alt_s": p_b,
        "period_decrease_pct": p_pct,
        "wind_adverse_ref_ms": w_a,
        "wind_adverse_alt_ms": w_b,
        "wind_decrease_pct": w_pct,
        "wave_rel_dir_ref_deg": th_a,
        "wave_rel_dir_alt_deg": th_b,
        "wave_dir_deviation_pct": dir_pct,
        "length_diff_nmi": lb - la,
        "length_diff_pct": (lb - la) / la * 100.0 if la > 0 else float("nan"),
    }


#: Columns of :func:`comparison_table` (absolute values), in order.
TABLE_COLUMNS = (
    "time_h", "dist_nmi", "mean_speed_kn", "max_hs_m", "mean_hs_m", "fuel_t", "co2_t", "so2_t", "nox_t", "pm_t",
    "exposure_h", "adverse_h", "imo_adverse_h", "n_safety_events", "n_operator_events",
)


def comparison_table(evaluations: Mapping[str, RouteEvaluation], reference: str = "historical") -> pd.DataFrame:
    """Historical versus proposed: one row per route, absolute values and deltas to the reference.

    Parameters
    ----------
    evaluations : mapping of str -> RouteEvaluation
        Keyed by role, as the reports expect: ``{"historical": ..., "deviation": ...,
        "optimal": ..., "min_distance": ...}``
        (missing routes are simply absent rows).
    reference : str
        Key of the reference route (deltas are ``route − reference``; ``*_pct`` relative to it).

    Returns
    -------
    DataFrame
        Index = route roles; the columns of :data:`TABLE_COLUMNS`, ``d_<col>`` deltas, ``d_<col>_pct``
        for time, distance, fuel and CO2, and the seed metrics of :func:`comparison_metrics`
        (``hs_decrease_pct``, ``period_decrease_pct``, ``wind_decrease_pct``,
        ``wave_dir_deviation_pct``, ``length_diff_pct``) against the reference.
    """
    if reference not in evaluations:
        raise KeyError(f"reference route {reference!r} not among {list(evaluations)}")
    ref = evaluations[reference]
    rows = {}
    for name, ev in evaluations.items():
        row = {c: ev.summary.get(c) for c in TABLE_COLUMNS}
        for c in TABLE_COLUMNS:
            a, b = row[c], ref.summary.get(c)
            row[f"d_{c}"] = (a - b) if a is not None and b is not None else None
        for c in ("time_h", "dist_nmi", "fuel_t", "co2_t"):
            a, b = ev.summary.get(c), ref.summary.get(c)
            row[f"d_{c}_pct"] = (a - b) / b * 100.0 if a is not None and b else None
        m = comparison_metrics(ref, ev)
        for c in ("hs_decrease_pct", "period_decrease_pct", "wind_decrease_pct", "wave_dir_deviation_pct", "length_diff_pct"):
            row[c] = m[c]
        rows[name] = row
    return pd.DataFrame.from_dict(rows, orient="index").astype(float)


def events_frame(evaluations: Mapping[str, RouteEvaluation]) -> pd.DataFrame:
    """All events of several routes, one row each: ``route``, ``criterion``, ``kind``,
    ``start_utc``, ``end_utc``, ``duration_h``, ``lat_deg``, ``lon_deg`` (where it started),
    ``max_margin``."""
    rows = []
    for role, ev in evaluations.items():
        for e in ev.events:
            rows.append(
                {
                    "route": role, "criterion": e["criterion"], "kind": e["kind"],
                    "start_utc": pd.Timestamp(e["start_utc"]), "end_utc": pd.Timestamp(e["end_utc"]),
                    "duration_h": e["duration_h"], "lat_deg": e["start_lat_deg"], "lon_deg": e["start_lon_deg"],
                    "max_margin": e["max_margin"],
                }
            )
    cols = ["route", "criterion", "kind", "start_utc", "end_utc", "duration_h", "lat_deg", "lon_deg", "max_margin"]
    return pd.DataFrame(rows, columns=cols)


def exposure_frame(evaluations: Mapping[str, RouteEvaluation]) -> pd.DataFrame:
    """Hours each rule fired on each route: ``route``, ``limit`` (rule name), ``exposure_h``."""
    rows = [
        {"route": role, "limit": rule, "exposure_h": hours}
        for role, ev in evaluations.items()
        for rule, hours in ev.summary["exposure_by_rule_h"].items()
    ]
    return pd.DataFrame(rows, columns=["route", "limit", "exposure_h"])
