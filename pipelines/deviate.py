"""Cargo-safe deviation of one workspace lane for one departure (``stormlane deviate``).

Reads the lane's centroids and the weather (files, or the workspace's weather tables), runs
:func:`routing.deviate.deviate_lane` with the routing mesh's land test, evaluates the lane and
the deviation in the same weather and stores the deviation in the results tables.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from pipelines.audit import AuditError, lane_land_check, weather_from_workspace
from thresholds.errors import StormlaneError

#: Vessel profile of a deviation when none is given: the seed paper studies container ships
#: under 200 m (Lpp < 200 m limits).
DEFAULT_VESSEL = "container-feeder"


class DeviationInputError(StormlaneError):
    """Unknown lane, bad departure time or weather that does not cover the lane-departure."""


def deviate_in_workspace(db, lane_id: str, depart, *, weather=(), vessel: str | None = None, profile: str | None = None,
                         store: bool = True) -> dict:
    """Deviation of lane ``lane_id`` departing at ``depart``; returns the CLI's JSON object.

    Returns
    -------
    dict
        ``lane_id``, ``depart_utc``, ``vessel_profile``, ``lane`` and ``deviation`` (route and
        evaluation summaries), ``steps`` (status of every waypoint), ``metrics`` (the seed
        paper's comparison metrics, deviation against lane) and ``deviation_id``.
    """
    from pipelines.config import load_operator_profile, load_vessel
    from pipelines.routing_weather import field_from_dataset
    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import read_lane_centroids, read_lanes
    from pipelines.storage.results import write_deviation
    from routing.deviate import deviate_lane, lane_route, threshold_inputs
    from routing.evaluate import comparison_metrics, evaluate_route
    from routing.sampling import PointSampler

    db = Path(db)
    if not db.exists():
        raise DeviationInputError(f"workspace {db} does not exist (run `stormlane demo` or `stormlane lanes` first)")
    try:
        t0 = pd.Timestamp(depart)
    except (ValueError, TypeError):
        raise DeviationInputError(f"--depart {depart!r} is not an ISO 8601 time") from None
    t0 = t0.tz_localize("UTC") if t0.tzinfo is None else t0.tz_convert("UTC")
    with open_workspace(db) as ws:
        lanes = read_lanes(ws)
        lane = read_lane_centroids(ws, str(lane_id))
        if lane.empty:
            known = ", ".join(lanes["lane_id"].astype(str).head(8))
            raise DeviationInputError(f"no lane {lane_id!r} in {db} ({len(lanes)} lanes{': ' + known if known else ''})")
        lane = lane.sort_values("seq")
        d = float(np.sum(np.hypot(np.diff(lane["lat_deg"]), np.diff(lane["lon_deg"]) * np.cos(np.deg2rad(lane["lat_deg"].mean())))) * 60.0)
        v = float(np.nanmedian(lane["speed_kn"])) if np.isfinite(lane["speed_kn"]).any() else 10.0
        window_end = t0 + pd.Timedelta(hours=2.0 * d / max(v, 1.0) + 6.0)
        files = [str(p) for p in weather]
        span = None  # the whole weather's time span, for the error message
        if files:
            from weather.io import read_local

            ds, meta = read_local(files)
        else:
            try:
                ds, meta = weather_from_workspace(ws, t0, window_end)
            except AuditError as err:
                raise DeviationInputError(str(err)) from None
            from pipelines.storage.weather import get_grid

            g = get_grid(ws)
            span = (pd.Timestamp(g["start_utc"]), pd.Timestamp(g["end_utc"]))
    vessel_name = vessel or DEFAULT_VESSEL
    ves = load_vessel(vessel_name)
    limits = load_operator_profile(profile)
    sampler = PointSampler.from_field(field_from_dataset(ds))
    if t0 < sampler.start_utc or t0 > sampler.end_utc:
        first, last = span or (sampler.start_utc, sampler.end_utc)
        raise DeviationInputError(f"departure {t0.isoformat()} is outside the weather {first.isoformat()} .. {last.isoformat()}")
    weather_at, check, cells = threshold_inputs(sampler, ves, limits)
    lat, lon, spd = lane["lat_deg"].to_numpy(), lane["lon_deg"].to_numpy(), lane["speed_kn"].to_numpy()
    dev = deviate_lane(lat, lon, spd, t0, weather_at=weather_at, check=check, cells=cells, leg_at_sea=lane_land_check(lane),
                       default_speed_kn=ves.speed_kn, properties={"lane_id": str(lane_id)})
    lane_r = lane_route(lat, lon, spd, t0, default_speed_kn=ves.speed_kn, properties={"lane_id": str(lane_id)})
    ev_lane = evaluate_route(lane_r, sampler, ves, limits=limits)
    ev_dev = evaluate_route(dev, sampler, ves, limits=limits)
    deviation_id = f"{lane_id}@{t0.strftime('%Y-%m-%dT%H:%MZ')}"
    if store:
        with open_workspace(db) as ws:
            write_deviation(ws, deviation_id, lane_id, t0, ev_dev.route)
    if dev.time_utc[-1] > sampler.end_utc:
        note = f"the deviation arrives {dev.time_utc[-1].isoformat()}, after the weather ends ({sampler.end_utc.isoformat()})"
    else:
        note = None
    steps = dev.properties["steps"]
    return {
        "deviation_id": deviation_id,
        "lane_id": str(lane_id),
        "depart_utc": t0.isoformat(),
        "vessel_profile": vessel_name,
        "weather": {"files": files, **{k: v for k, v in meta.items() if isinstance(v, (str, int, float))}},
        "lane": ev_lane.to_dict(waypoints=True),
        "deviation": {**ev_dev.to_dict(waypoints=True), "n_deviated": dev.properties["n_deviated"],
                      "n_unresolved": dev.properties["n_unresolved"], "n_legs_adverse": dev.properties["n_legs_adverse"]},
        "steps": steps,
        "metrics": comparison_metrics(ev_lane, ev_dev),
        "note": note,
    }
