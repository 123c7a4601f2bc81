"""Cargo-safe deviation of one workspace lane for one departure (``stormlane deviate``).

Reads the lane's centroids and the weather (files, or the workspace's weather tables), runs
:func:`routing.deviate.deviate_lane` with the routing mesh's land test, evaluates the lane and
the deviation in the same weather and stores the deviation in the results tables.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from pipelines.audit_inputs import AuditError, weather_from_workspace
from pipelines.times import utc_or_none
from thresholds.errors import StormlaneError
from pipelines.vessels import DEFAULT_VESSEL, workspace_lane_profiles

class DeviationInputError(StormlaneError):
    """Unknown lane, bad departure time or weather that does not cover the lane-departure."""


#: The variable a deviation cannot do without (the thresholds judge Hs first).
REQUIRED_VAR = "hs_m"


def weather_label(product, *, grid=None, source_files=None, max_files: int = 3) -> str:
    """How an error names the weather: the product, then the workspace grid and/or file names.

    >>> weather_label("CMEMS MEDSEA", source_files="/d/Waves_20200120.nc; /d/Waves_20200121.nc")
    'CMEMS MEDSEA (Waves_20200120.nc, Waves_20200121.nc)'
    >>> weather_label("CMEMS MEDSEA", grid="med", source_files="a.nc")
    "CMEMS MEDSEA (workspace grid 'med': a.nc)"
    """
    if isinstance(source_files, str):
        source_files = [f for f in source_files.split(";")]
    names = [Path(str(f).strip()).name for f in source_files or () if str(f).strip() and str(f).strip().lower() != "none"]
    files = ", ".join(names[:max_files]) + (f", ... ({len(names)} files)" if len(names) > max_files else "")
    where = f"workspace grid {grid!r}" if grid else ""
    inside = ": ".join(x for x in (where, files) if x)
    return f"{product or 'weather'}" + (f" ({inside})" if inside else "")


def check_departure_in_weather(t0: pd.Timestamp, first: pd.Timestamp, last: pd.Timestamp, label: str) -> None:
    """Raise :class:`DeviationInputError` unless the departure lies in the weather's whole time span."""
    if first <= t0 <= last:
        return
    gap = f"{t0:%Y-%m-%dT%H:%MZ} -> {first:%Y-%m-%dT%H:%MZ}" if t0 < first else f"{last:%Y-%m-%dT%H:%MZ} -> {t0:%Y-%m-%dT%H:%MZ}"
    raise DeviationInputError(
        f"{label}, {REQUIRED_VAR}: no data for {gap}: the departure {t0.isoformat()} is outside the weather "
        f"{first.isoformat()} .. {last.isoformat()}; give --weather files that cover it"
    )


def check_lane_in_weather(ds, lane: pd.DataFrame, lane_id: str, t0: pd.Timestamp, window_end: pd.Timestamp, label: str) -> None:
    """Raise :class:`DeviationInputError` when the weather lacks ``hs_m`` or does not reach the lane.

    The checks are :func:`weather.coverage.check_coverage`'s (the one ``stormlane nightly`` runs):
    the variable exists and is not missing at every sea cell at a time step of the lane's window,
    and the lane's bbox lies inside the grid's. A lane point within half a grid step beyond the
    outer cell centres is inside (the sampler interpolates there, see ``routing.sampling``); land
    cells inside the grid (NaN) are not a coverage gap.
    """
    from weather.coverage import check_coverage
    from weather.errors import CoverageError

    lat, lon = lane["lat_deg"].to_numpy(dtype=float), lane["lon_deg"].to_numpy(dtype=float)
    times = pd.DatetimeIndex(ds["time_utc"].values)
    times = times.tz_localize("UTC") if times.tz is None else times.tz_convert("UTC")
    try:
        check_coverage(ds, variables=[REQUIRED_VAR], start=max(t0, times[0]), end=min(window_end, times[-1]), product=label)
        glat, glon = np.sort(ds["lat"].values.astype(float)), np.sort(ds["lon"].values.astype(float))
        half_lat = 0.5 * (glat[1] - glat[0]) if glat.size > 1 else 0.0
        half_lon = 0.5 * (glon[1] - glon[0]) if glon.size > 1 else 0.0
        outside = ((lat < glat[0] - half_lat - 1e-9) | (lat > glat[-1] + half_lat + 1e-9)
                   | (lon < glon[0] - half_lon - 1e-9) | (lon > glon[-1] + half_lon + 1e-9))
        if outside.any():
            try:
                check_coverage(ds[[REQUIRED_VAR]], bbox=(lon.min(), lat.min(), lon.max(), lat.max()), product=label)
            except CoverageError as err:
                raise CoverageError(f"{err}; {int(outside.sum())} of {lat.size} lane centroids lie outside the grid") from None
    except CoverageError as err:
        raise DeviationInputError(f"the weather does not cover lane {lane_id}: {err}") from None


def check_lane_meets_weather(evaluation: dict, lane: pd.DataFrame, lane_id: str, label: str) -> None:
    """Raise :class:`DeviationInputError` when the lane, sailed from the departure, meets no weather at all
    (every sample on land or missing cells): its hours over the limits would read 0 h, safe."""
    time_h, none_h = evaluation.get("time_h") or 0.0, evaluation.get("no_weather_h") or 0.0
    if time_h > 0 and none_h >= time_h - 1e-9:
        lat, lon = lane["lat_deg"], lane["lon_deg"]
        raise DeviationInputError(
            f"{label}, {REQUIRED_VAR}: lane {lane_id} (lat {lat.min():.3f}..{lat.max():.3f}, lon {lon.min():.3f}..{lon.max():.3f}) "
            f"meets no data over its {time_h:.1f} h (land or missing cells of the grid); give --weather files that cover it"
        )


def not_safer_note(lane: dict, deviation: dict) -> str | None:
    """The note saying the deviation is less safe than the lane, or None.

    Less safe by the rule that ranks proposals (:func:`routing.audit.safety_order`): more hours
    over the limits or in IMO situations (``adverse_h``), else more IMO events, else a max Hs
    higher by more than :data:`routing.audit.HS_TIE_M`. ``lane`` and ``deviation`` are the
    evaluation summaries (``RouteEvaluation.to_dict()``). The table output and ``--json``
    (``"note"``) both carry it.
    """
    from routing.audit import ADVERSE_TIE_H, safety_order

    if lane.get("adverse_h") is None or deviation.get("adverse_h") is None or safety_order(deviation, lane) <= 0:
        return None
    if deviation["adverse_h"] > lane["adverse_h"] + ADVERSE_TIE_H:
        worse = "more hours over the limits or in IMO situations"
    elif deviation.get("n_safety_events", 0) > lane.get("n_safety_events", 0):
        worse = "more IMO events"
    else:
        worse = "a higher max Hs"

    def num(x, fmt):
        return "n/a" if x is None or x != x else format(x, fmt)

    return (f"the deviation meets {worse} than the lane ({num(deviation.get('adverse_h'), '.1f')} h against "
            f"{num(lane.get('adverse_h'), '.1f')} h; max Hs {num(deviation.get('max_hs_m'), '.2f')} against "
            f"{num(lane.get('max_hs_m'), '.2f')} m): Algorithm 1 looks one step ahead at a time; compare the safe "
            "time-optimal route (`stormlane route --safety hard`)")


def deviate_in_workspace(db, lane_id: str, depart, *, weather=(), vessel: str | None = None, profile: str | None = None,
                         store: bool = True, speed_loss="bowditch") -> dict:
    """Deviation of lane ``lane_id`` departing at ``depart``; returns the CLI's JSON object.

    ``speed_loss``: a formula's name, ``learned:NAME`` (a model stored in ``db``, tabulated once for
    the lane's vessel at the lane's typical speed) or a resolved :class:`pipelines.learn.SpeedLossChoice`;
    the lane and the deviation are both sailed and evaluated by it.

    Returns
    -------
    dict
        ``lane_id``, ``depart_utc``, ``vessel_profile``, ``speed_loss_model``, ``speed_kn`` (the lane's typical AIS speed,
        the model's calm-water speed), ``reference`` (``"lane"``), ``lane`` and ``deviation`` (route
        and evaluation summaries: the lane as planned and the deviation, both sailed by the vessel
        model from the departure, legs over land repaired), ``proposed`` (False when the deviation is
        not sea-only or has more time without weather than the lane; ``notes`` says why), ``steps``
        (status of every waypoint), ``metrics`` (the seed paper's comparison metrics, deviation
        against lane) and ``deviation_id``.
    """
    from pipelines.config import load_operator_profile, load_vessel
    from pipelines.learn import resolve_speed_loss
    from pipelines.nightly.reroute import lane_speed, lane_speed_vessel
    from pipelines.routing_weather import field_from_dataset
    from pipelines.storage import open_workspace
    from pipelines.storage.results import write_deviation
    from routing.audit import not_proposable
    from routing.evaluate import comparison_metrics
    from routing.sampling import PointSampler

    db = Path(db)
    if not db.exists():
        raise DeviationInputError(f"workspace {db} does not exist (run `stormlane demo` or `stormlane lanes` first)")
    t0 = utc_or_none(depart)
    if t0 is None:
        raise DeviationInputError(f"--depart {depart!r} is not an ISO 8601 time")
    files = [str(p) for p in weather]
    choice = resolve_speed_loss(speed_loss, db)
    lane, vessel_name, ds, meta, label = _lane_and_weather(db, str(lane_id), t0, files, vessel)
    limits = load_operator_profile(profile)
    field_ = field_from_dataset(ds)
    sampler = PointSampler.from_field(field_)
    profile_vessel = load_vessel(vessel_name)
    ves = lane_speed_vessel(profile_vessel, lane)
    ev_lane, ev_dev, dev = _lane_and_deviation(lane, str(lane_id), t0, field_, sampler, ves, vessel_name, limits, label, choice)
    lane_summary = ev_lane.to_dict(waypoints=True)
    dev_summary = {**ev_dev.to_dict(waypoints=True), "n_deviated": dev.properties["n_deviated"],
                   "n_unresolved": dev.properties["n_unresolved"], "n_legs_adverse": dev.properties["n_legs_adverse"],
                   "land_repairs": dev.properties.get("land_repairs", [])}
    deviation_id = f"{lane_id}@{t0.strftime('%Y-%m-%dT%H:%MZ')}"
    if store:
        with open_workspace(db) as ws:
            write_deviation(ws, deviation_id, lane_id, t0, ev_dev.route)
    why = not_proposable(dev_summary, lane_summary)
    notes = [f"the deviation is not proposed: {why}" if why else None, not_safer_note(lane_summary, dev_summary)]
    if dev.time_utc[-1] > sampler.end_utc:
        notes.append(f"the deviation arrives {dev.time_utc[-1].isoformat()}, after the weather ends ({sampler.end_utc.isoformat()})")
    sailed, typical = lane_speed(profile_vessel, lane)
    if sailed is not None and sailed < typical:
        notes.append(f"the lane's ships sailed {typical:.1f} kn, faster than {vessel_name} can at its installed power: "
                     f"the lane and the deviation are sailed at its maximum-power speed, {sailed:.1f} kn")
    notes = [n for n in notes if n]
    return {
        "deviation_id": deviation_id,
        "lane_id": str(lane_id),
        "depart_utc": t0.isoformat(),
        "vessel_profile": vessel_name,
        "speed_loss_model": choice.label,
        "speed_kn": ves.speed_kn,
        "reference": "lane",
        "proposed": why is None,
        "weather": {"files": files, **{k: v for k, v in meta.items() if isinstance(v, (str, int, float))}},
        "lane": lane_summary,
        "deviation": dev_summary,
        "steps": dev.properties["steps"],
        "metrics": comparison_metrics(ev_lane, ev_dev),
        "note": "\n".join(notes) or None,
        "notes": notes,
    }


def _lane_and_weather(db: Path, lane_id: str, t0: pd.Timestamp, files: list[str], vessel: str | None):
    """The lane's centroids (in sequence), the vessel profile's name (given, else the lane's own
    ships' by :mod:`pipelines.vessels`), and the weather that covers the lane from ``t0``: the
    ``files`` when given, else the workspace's grid. Returns (lane, vessel name, dataset, meta, label).

    The weather window is twice the lane's length at its median AIS speed, plus 6 h: room for a
    slower deviation (the speed-loss model slows the ship in waves).
    """
    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import read_lane_centroids, read_lanes

    with open_workspace(db) as ws:
        lanes = read_lanes(ws)
        lane = read_lane_centroids(ws, lane_id)
        if lane.empty:
            known = ", ".join(lanes["lane_id"].astype(str).head(8))
            raise DeviationInputError(f"no lane {lane_id!r} in {db} ({len(lanes)} lanes{': ' + known if known else ''})")
        if vessel is None:  # the lane's own ships (pipelines.vessels)
            vessel = workspace_lane_profiles(ws).get(lane_id, DEFAULT_VESSEL)
        lane = lane.sort_values("seq")
        d = float(np.sum(np.hypot(np.diff(lane["lat_deg"]), np.diff(lane["lon_deg"]) * np.cos(np.deg2rad(lane["lat_deg"].mean())))) * 60.0)
        v = float(np.nanmedian(lane["speed_kn"])) if np.isfinite(lane["speed_kn"]).any() else 10.0
        window_end = t0 + pd.Timedelta(hours=2.0 * d / max(v, 1.0) + 6.0)
        if files:
            ds, meta, label = _weather_from_files(files, t0)
        else:
            ds, meta, label = _weather_from_grid(ws, db, t0, window_end)
    check_lane_in_weather(ds, lane, lane_id, t0, window_end, label)
    return lane, vessel, ds, meta, label


def _weather_from_files(files: list[str], t0: pd.Timestamp):
    """The weather files read as one dataset; the departure must lie in their time span."""
    from weather.io import read_local

    ds, meta = read_local(files)
    label = weather_label(meta.get("product") or ds.attrs.get("product"),
                          source_files=meta.get("source_files") or ds.attrs.get("source_files") or files)
    span = pd.DatetimeIndex(ds["time_utc"].values[[0, -1]])
    span = span.tz_localize("UTC") if span.tz is None else span.tz_convert("UTC")
    check_departure_in_weather(t0, span[0], span[-1], label)
    return ds, meta, label


def _weather_from_grid(ws, db: Path, t0: pd.Timestamp, window_end: pd.Timestamp):
    """The workspace grid's weather from ``t0`` to ``window_end``; the departure must lie in the
    grid's whole span."""
    from pipelines.storage.weather import get_grid

    try:
        g = get_grid(ws)
    except StormlaneError:
        raise DeviationInputError(f"no weather in the workspace {db}: load some with `stormlane weather load PATH...` "
                                  "or pass --weather FILE...") from None
    label = weather_label(g["product"], grid=g["name"], source_files=g.get("source_files"))
    check_departure_in_weather(t0, utc_or_none(g["start_utc"]), utc_or_none(g["end_utc"]), label)
    try:
        ds, meta = weather_from_workspace(ws, t0, window_end)
    except AuditError as err:
        raise DeviationInputError(str(err)) from None
    return ds, meta, label


def _lane_and_deviation(lane, lane_id, t0, field_, sampler, ves, vessel_name, limits, label, choice):
    """The lane and its deviation, both sailed by the vessel model (``choice``, a
    :class:`pipelines.learn.SpeedLossChoice`) from ``t0`` in the same weather
    (:func:`routing.compare.lane_departure`), evaluated. Returns (lane evaluation, deviation
    evaluation, deviation route)."""
    from routing.compare import lane_departure, plan_bbox
    from routing.deviate import lane_route, threshold_inputs
    from routing.evaluate import evaluate_route
    from routing.planner import RouteRequest, plan_routes

    weather_at, check, cells = threshold_inputs(sampler, ves, limits)
    table = choice.table(ves, ves.speed_kn)  # None for a formula
    model = {"speed_loss_model": choice.label, "learned": table}
    lat, lon, spd = lane["lat_deg"].to_numpy(), lane["lon_deg"].to_numpy(), lane["speed_kn"].to_numpy()
    # a lane that meets no weather at all would read 0 h over the limits: refuse it first
    check_lane_meets_weather(evaluate_route(lane_route(lat, lon, spd, t0, default_speed_kn=ves.speed_kn), sampler, ves,
                                            limits=limits, **model).summary, lane, lane_id, label)
    start, goal = (float(lat[0]), float(lon[0])), (float(lat[-1]), float(lon[-1]))
    req = RouteRequest(start, goal, t0, choice.ship(ves, table=table), vessel_name=vessel_name,
                       bbox=plan_bbox(start, goal, lat, lon, field_))
    try:
        plan = plan_routes(req, field_)
    except StormlaneError as err:
        raise DeviationInputError(f"lane {lane_id}: the vessel model's mesh cannot be built: {err}") from None
    pair = lane_departure(lat, lon, spd, t0, plan, weather_at=weather_at, check=check, cells=cells,
                          properties={"lane_id": lane_id})
    lane_r, dev = pair["lane"], pair["deviation"]
    return evaluate_route(lane_r, sampler, ves, limits=limits, **model), evaluate_route(dev, sampler, ves, limits=limits, **model), dev
