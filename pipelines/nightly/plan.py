"""The night's plan, fixed before any computation: forecast time, departures, coverage check,
the weather cut to the night, vessels and limits, and the run id derived from all of them."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from pipelines.nightly.night import Night, NightlyParams, NightlyWeatherError, NightPath, parse_utc
from pipelines.nightly.weather import subset_weather, weather_span_needed

def resolve_now(now: str | None) -> pd.Timestamp:
    """The forecast reference time: ``now`` as given, else the scheduled start of the Prefect
    flow run (so a rerun of a scheduled night gets the same one), else the current time; floored
    to the hour when not given."""
    if now is not None:
        return parse_utc(now, "--now")
    t = None
    try:
        from prefect.context import FlowRunContext

        ctx = FlowRunContext.get()
        if ctx is not None and ctx.flow_run is not None and ctx.flow_run.expected_start_time is not None:
            t = pd.Timestamp(ctx.flow_run.expected_start_time)
    except Exception:  # noqa: BLE001 - no Prefect context: wall clock
        t = None
    if t is None:
        t = pd.Timestamp.now(tz="UTC")
    t = t.tz_localize("UTC") if t.tzinfo is None else t.tz_convert("UTC")
    return t.floor("h")


def departure_times(now: pd.Timestamp, window_h: float, step_h: float) -> pd.DatetimeIndex:
    """Departures ``now, now + step, ...`` strictly before ``now + window`` (48 h / 3 h -> 16)."""
    n = int(math.ceil(window_h / step_h - 1e-9))
    return pd.DatetimeIndex([now + pd.Timedelta(hours=k * step_h) for k in range(n)])


def default_out(now: pd.Timestamp, root: str | Path | None = None) -> Path:
    """Output folder of a night when ``--out`` is not given: ``<root>/<YYYY-mm-ddTHHMMZ>``
    (root default ``nightly``), one folder per night for scheduled runs."""
    return Path(root or "nightly") / now.strftime("%Y-%m-%dT%H%MZ")


def _digest(*parts) -> str:
    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, np.ndarray):
            h.update(str(part.dtype).encode() + str(part.shape).encode())
            h.update(np.ascontiguousarray(part).tobytes())
        else:
            h.update(json.dumps(part, sort_keys=True, default=str).encode())
        h.update(b"|")
    return h.hexdigest()


def weather_digest(ds) -> str:
    """Content digest of a canonical weather Dataset (coordinates and every variable's values)."""
    parts = [ds["time_utc"].values.astype("datetime64[ns]").astype(np.int64), ds["lat"].values.astype(float), ds["lon"].values.astype(float)]
    for name in sorted(ds.data_vars):
        parts += [name, np.asarray(ds[name].transpose("time_utc", "lat", "lon").values, dtype=np.float32)]
    return _digest(*parts)


def lanes_digest(paths: list[NightPath]) -> str:
    parts = []
    for p in sorted(paths, key=lambda x: x.path_id):
        c = p.centroids
        parts += [p.path_id, p.lane_id, p.origin, p.destination, p.vessel_profile, p.error,
                  [t.isoformat() for t in p.departures],
                  c["seq"].to_numpy(dtype=np.int64), c["lat_deg"].to_numpy(dtype=float), c["lon_deg"].to_numpy(dtype=float),
                  c["speed_kn"].to_numpy(dtype=float)]
    return _digest(*parts)


def prepare_night(params: NightlyParams, now: pd.Timestamp, paths: list[NightPath], ds, meta: dict, source: str) -> Night:
    """Check coverage (fail early), cut the weather, load vessels and limits, derive the run id.

    The run id is ``<now>-<12 hex>``: a digest of the forecast time, the departures, the lanes
    (centroids, vessel profiles), the weather values, the vessel particulars, the operator profile
    and the speed-loss model. Same inputs -> same id -> the rerun replaces the same rows.

    Raises
    ------
    NightlyWeatherError
        The weather does not reach back to the first departure or forward to the last one
        (``weather.coverage.check_coverage`` names the product, the variable and the gap), or
        its grid misses the lanes, or lacks the wind a wind-driven speed-loss model reads.
    NightlyError
        The speed-loss formula is refused for some lanes' vessels (:func:`refuse_speed_model`).
    """
    from pipelines.config import load_operator_profile, load_vessel
    from pipelines.learn import learned_limits, resolve_speed_loss

    speed_model = resolve_speed_loss(params.speed_loss, params.db)  # learned:NAME: one line listing the stored models
    departures = departure_times(now, params.window_h, params.step_h)
    check_departures_covered(ds, paths, departures)
    t0, t1 = weather_span_needed(paths, departures)
    sub = subset_weather(ds, paths, t0, t1)
    vessels = {}
    for name in sorted({p.vessel_profile for p in paths}):
        vessels[name] = load_vessel(name)
    refuse_speed_model(params.speed_loss, paths, vessels, sub, source)
    limits = load_operator_profile(params.profile)
    # the voluntary slow-down AIS shows, beside the limits: the model sailed by, else the newest stored one
    beside = learned_limits(params.db, speed_model.learned_name, profile=params.profile, vessels=list(vessels.values()))
    wd = weather_digest(sub)
    ld = lanes_digest(paths)
    rid = _digest(now.isoformat(), [t.isoformat() for t in departures], params.window_h, params.step_h, ld, wd,
                  {k: repr(v) for k, v in vessels.items()}, repr(limits), params.speed_loss, params.safety)
    run_id = f"{now:%Y%m%dT%H%MZ}-{rid[:12]}"
    out = Path(params.out) if params.out else default_out(now, params.out_root)
    return Night(run_id=run_id, now_utc=now, departures=departures, params=params, paths=paths, weather_ds=sub,
                 weather_meta=dict(meta), weather_source=source, weather_digest=wd, lanes_digest=ld, vessels=vessels,
                 limits=limits, out=out, speed_model=speed_model, learned_limits=beside)


def check_departures_covered(ds, paths: list[NightPath], departures: pd.DatetimeIndex) -> None:
    """:class:`NightlyWeatherError` unless the waves cover every departure of the night (from the
    first to the last: ``weather.coverage.check_coverage`` names the product and the gap)."""
    from weather.coverage import check_coverage
    from weather.errors import CoverageError

    first = min(min(p.departures) if p.departures else departures[0] for p in paths)
    last = max(max(p.departures) if p.departures else departures[-1] for p in paths)
    try:
        check_coverage(ds, variables=["hs_m"], start=first, end=last)
    except CoverageError as err:
        raise NightlyWeatherError(
            f"the weather does not cover tonight's departures {first:%Y-%m-%dT%H:%MZ} -> {last:%Y-%m-%dT%H:%MZ}: {err}"
        ) from None


def read_weather_before(params: NightlyParams, paths: list[NightPath]) -> None:
    """Before Prefect starts (the CLI's preflight): read the weather the flow will read (local
    files or the workspace grid; downloads are left to the flow), check that it covers tonight's
    departures, and hand the read to the flow (:func:`pipelines.nightly.weather.keep_read_for_flow`),
    so that the files are read once. Without it a night the weather misses failed only once
    Prefect had started (44 s on a fresh Prefect home)."""
    from pipelines.nightly.weather import choose_weather_source, keep_read_for_flow, read_weather_source

    source = choose_weather_source(params)
    if source == "fetch":
        return
    departures = departure_times(resolve_now(params.now), params.window_h, params.step_h)
    span = weather_span_needed(paths, departures)
    read = read_weather_source(source, params.weather, params.db, *span)
    check_departures_covered(read[0], paths, departures)
    keep_read_for_flow(source, params.weather, params.db, *span, read)


def refuse_speed_model(model: str, paths: list[NightPath], vessels: dict, ds, source: str) -> None:
    """Refuse, once before any lane runs, a speed-loss formula that the lanes could not use: one
    line naming every lane whose vessel (at the lane's typical speed, as each lane is sailed:
    :func:`pipelines.nightly.reroute.lane_speed_vessel`) lies outside the formula's published
    range (Khokhlov's D·v0, Kwon's block coefficient and Froude number:
    :class:`routing.astar.ShipModel`), and a wind-driven model (Kwon) on weather without the
    10 m wind. Without this, each lane failed on its own with the same reason."""
    from pipelines.nightly.night import NightlyError
    from pipelines.nightly.reroute import lane_speed_vessel
    from routing.astar import ShipModel
    from routing.speed_loss import MODELS, WIND_MODELS, SpeedLossRangeError

    if model not in MODELS or model == "none":
        return  # learned:NAME is resolved (and checked per vessel) by its own step
    if model in WIND_MODELS and not {"wind_u_ms", "wind_v_ms"} <= set(ds.data_vars):
        raise NightlyWeatherError(f"--speed-loss {model} reads the 10 m wind (wind_u_ms, wind_v_ms), which the weather "
                                  f"({source}) lacks; it has {', '.join(sorted(ds.data_vars)) or 'no variable'}: "
                                  "give wind files with --weather or choose a wave model (bowditch, aertssen, khokhlov)")
    refused = []
    for p in paths:
        vessel = lane_speed_vessel(vessels[p.vessel_profile], p.centroids.sort_values("seq"))
        try:
            ShipModel.from_vessel(vessel, model)
        except (SpeedLossRangeError, ValueError) as err:
            refused.append(f"{p.path_id}: {err}")
    if refused:
        shown = "; ".join(refused[:3]) + (f"; and {len(refused) - 3} more" if len(refused) > 3 else "")
        raise NightlyError(f"--speed-loss {model} cannot sail {len(refused)} of tonight's {len(paths)} lane(s) "
                           f"(leave them out with --lanes or choose another model): {shown}")
