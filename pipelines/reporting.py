"""Glue from the flows' results to the report model (``dashboards.model``).

The nightly and audit flows call these plain functions to hand the renderer what it draws:
the weather slice under a map, the speed-loss curve of the chosen vessel and model, the route
set of one case (from ``routing.evaluate`` results) and the provenance record. Nothing here
computes a new result: it selects, reshapes and calls the domain functions that own the numbers
(``routing.speed_loss.attained_speed_kn`` for the curve).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from dashboards.model import REFERENCE_ROLES, Provenance, RouteSet, SpeedLossCurve, WeatherSnapshot, software_versions


def weather_snapshot(ds, time_utc, bbox=None, pad_deg: float = 1.0, product: str | None = None) -> WeatherSnapshot:
    """The slice of a canonical weather Dataset nearest to ``time_utc``, cut to a box.

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical weather (dims ``time_utc, lat, lon``; ``hs_m`` and optionally ``wave_from_deg``).
    time_utc : Timestamp
        Wanted time (tz-aware or naive UTC); the nearest time step is taken.
    bbox : (lon_min, lon_max, lat_min, lat_max), optional
        Area of interest, widened by ``pad_deg`` on every side; default the whole grid.
    product : str, optional
        Label; default the Dataset's ``product`` attribute.
    """
    if "hs_m" not in ds:
        raise KeyError("weather has no hs_m variable to draw")
    t = pd.Timestamp(time_utc)
    t = t.tz_convert("UTC").tz_localize(None) if t.tz is not None else t
    sl = ds.sel(time_utc=np.datetime64(t, "ns"), method="nearest")
    if bbox is not None:
        lon0, lon1, lat0, lat1 = bbox
        sl = sl.sel(lon=slice(lon0 - pad_deg, lon1 + pad_deg), lat=slice(lat0 - pad_deg, lat1 + pad_deg))
    wave = sl["wave_from_deg"].values if "wave_from_deg" in sl else None
    return WeatherSnapshot(
        time_utc=pd.Timestamp(sl["time_utc"].values).tz_localize("UTC"),
        lat_deg=sl["lat"].values,
        lon_deg=sl["lon"].values,
        hs_m=sl["hs_m"].values,
        wave_from_deg=wave,
        product=product if product is not None else str(ds.attrs.get("product", "")),
    )


def routes_bbox(routes) -> tuple[float, float, float, float]:
    """``(lon_min, lon_max, lat_min, lat_max)`` around a collection of routes."""
    routes = list(routes.values()) if isinstance(routes, dict) else list(routes)
    lat = np.concatenate([r.lat_deg for r in routes])
    lon = np.concatenate([r.lon_deg for r in routes])
    return float(lon.min()), float(lon.max()), float(lat.min()), float(lat.max())


def worst_point(route) -> dict:
    """Where a route meets its highest Hs: ``time_utc``, ``lat_deg``, ``lon_deg``, ``hs_m`` (None when no Hs)."""
    hs = route.weather.get("hs_m")
    if hs is None or not np.isfinite(hs).any():
        return {"time_utc": None, "lat_deg": None, "lon_deg": None, "hs_m": None}
    i = int(np.nanargmax(hs))
    return {"time_utc": route.time_utc[i], "lat_deg": float(route.lat_deg[i]), "lon_deg": float(route.lon_deg[i]), "hs_m": float(hs[i])}


def speed_loss_curve(vessel, model: str, hs_max_m: float = 8.0, step_m: float = 0.25, angles_deg=(0.0, 45.0, 90.0, 135.0, 180.0),
                     learned=None) -> SpeedLossCurve:
    """Attainable speed of ``vessel`` against Hs for a few encounter angles, by ``model``.

    Values come from :func:`routing.speed_loss.attained_speed_kn` (with the vessel's floor);
    ``learned``: the table of a ``learned:NAME`` model.
    """
    from routing.speed_loss import attained_speed_kn

    hs = np.arange(0.0, hs_max_m + 1e-9, step_m)
    frames = []
    for angle in angles_deg:
        speed = np.asarray(attained_speed_kn(vessel.speed_kn, hs, np.full(hs.shape, float(angle)), model, vessel=vessel, learned=learned),
                           dtype=float)
        frames.append(pd.DataFrame({"hs_m": hs, "encounter_deg": float(angle), "speed_kn": speed}))
    return SpeedLossCurve(vessel=vessel.name, model=model, speed_kn=float(vessel.speed_kn), table=pd.concat(frames, ignore_index=True), min_speed_kn=getattr(vessel, "min_speed_kn", None))


def reference_of(evaluations: dict) -> str | None:
    """The like-for-like reference among the roles (``lane``, ``as_sailed_modelled``, then older names)."""
    return next((r for r in REFERENCE_ROLES if r in evaluations), None)


def route_notes_of(evaluations: dict, reference: str | None, optimality=(), weather_end_utc=None) -> dict:
    """Per role, what the table alone does not say (every note a command prints for the same
    routes): why a route is not proposed (not sea-only, more time without weather than the
    reference), legs repaired around land, a deviation that is not safer than the lane
    (:func:`pipelines.deviate.not_safer_note`, as `stormlane deviate` prints it), a safe route that
    fell back from hard to soft limits, a route that arrives after the last weather time (the last
    field held; ``weather_end_utc``), and a route the time-optimal one is slower than beyond the
    mesh's discretisation (or a safety constraint), and legs no engine setting makes or held at the floor (what they are
    charged: the evaluation's ``engine_settings``)."""
    from dashboards.sections import SOFT_FALLBACK_NOTE, held_weather_note
    from pipelines.deviate import not_safer_note
    from routing.audit import not_proposable

    notes: dict = {}
    ref = evaluations[reference].summary if reference in evaluations else {}
    end = pd.Timestamp(weather_end_utc) if weather_end_utc is not None else None
    for role, ev in evaluations.items():
        parts = []
        why = not_proposable(ev.summary, ref) if role != reference and ref else None
        if why:
            parts.append(f"not proposed: {why}")
        if role == "deviation" and reference == "lane" and ref:
            parts.append(not_safer_note(ref, ev.summary))
        props = ev.route.properties or {}
        if props.get("safety_requested") == "hard" and props.get("safety_mode") == "soft":
            parts.append(SOFT_FALLBACK_NOTE)
        held = props.get("weather_held_after_h")
        if not held and end is not None and len(ev.route.time_utc) and ev.route.time_utc[-1] > end:
            held = (ev.route.time_utc[-1] - end).total_seconds() / 3600.0
        if held:
            parts.append(held_weather_note(float(held)))
        parts.append(props.get("note"))  # a role's own line (least_fuel: its saving, why (not) proposed, the limits)
        parts.append((ev.summary.get("engine_settings") or {}).get("note"))  # legs no setting makes, or at the floor: what is charged
        parts = [x for x in parts if x]
        fixes = ev.route.properties.get("land_repairs") or []
        if fixes:
            parts.append(f"{len(fixes)} leg(s) over land replaced by the shortest sea path (+{sum(f['added_nmi'] for f in fixes):.1f} nmi)")
        if ev.summary.get("sea_only") is False and not why:
            parts.append(f"legs {ev.summary.get('land_legs')} cross land ({ev.summary.get('land_nmi', 0):.1f} nmi)")
        if parts:
            notes[role] = "; ".join(parts)
    for gap in optimality:
        if gap["constraint"] and gap["gap_h"] < 0:
            notes[gap["route"]] = "; ".join(filter(None, [notes.get(gap["route"]), f"slower than the time-optimal route by "
                                                          f"{-gap['gap_h']:.2f} h: its search had a safety constraint active ({gap['constraint']})"]))
        elif not gap["holds"]:
            notes["optimal"] = "; ".join(filter(None, [notes.get("optimal"), f"{gap['gap_h']:.2f} h slower than the "
                                                       f"{gap['route'].replace('_', ' ')} route, beyond the mesh's discretisation "
                                                       f"({gap['tolerance_h']:.2f} h)"]))
    return notes


def route_set_from_evaluations(evaluations: dict, table: pd.DataFrame | None = None, proposed: str | None = None,
                               weather: WeatherSnapshot | None = None, exports: dict | None = None, hs_limit_m: float | None = None,
                               optimality=(), weather_end_utc=None, detailed: bool = True) -> RouteSet:
    """A report ``RouteSet`` from ``routing.evaluate`` results keyed by role.

    ``table`` is :func:`routing.evaluate.comparison_table` against the reference (computed here
    when absent), events and exposure come from :func:`routing.evaluate.events_frame` /
    ``exposure_frame``; routes are the evaluated ones (weather met filled in); the notes come
    from :func:`route_notes_of` (``optimality``: :func:`routing.compare.optimality_gaps`).
    """
    from routing.evaluate import comparison_table, events_frame, exposure_frame

    reference = reference_of(evaluations)
    if table is None and reference is not None:
        table = comparison_table(evaluations, reference=reference)
    notes = route_notes_of(evaluations, reference, optimality, weather_end_utc)
    if not detailed:
        # a case shown without maps: its table and notes only (the page needs no route, weather
        # slice, events or samples for it; the model stays small)
        return RouteSet(reference=reference, notes=notes, routes={}, metrics=table, proposed=proposed,
                        exports=dict(exports or {}), hs_limit_m=hs_limit_m)
    return RouteSet(
        reference=reference,
        notes=notes,
        routes={role: ev.route for role, ev in evaluations.items()},
        metrics=table,
        events=events_frame(evaluations),
        exposure=exposure_frame(evaluations),
        weather=weather,
        proposed=proposed,
        exports=dict(exports or {}),
        hs_limit_m=hs_limit_m,
        profiles=hs_profiles(evaluations),
    )


def hs_profiles(evaluations: dict) -> dict:
    """Hs met along each evaluated route, as its evaluation sampled it (``time_utc``, ``hs_m``),
    for the report's Hs plot (:attr:`dashboards.model.RouteSet.profiles`)."""
    out = {}
    for role, ev in evaluations.items():
        samples = getattr(ev, "samples", None)
        if samples is not None and len(samples) and {"time_utc", "hs_m"} <= set(samples.columns):
            out[role] = pd.DataFrame({"time_utc": pd.DatetimeIndex(samples["time_utc"]),
                                      "hs_m": np.round(samples["hs_m"].to_numpy(dtype=float), 3)})
    return out


def limits_for_report(limits) -> dict:
    """Operator limits in the report's names (``hs_m`` is drawn on maps and plots)."""
    if limits is None:
        return {}
    out = {}
    for src, dst in (("hs_max_m", "hs_m"), ("wind_max_ms", "wind_ms"), ("period_min_s", "period_min_s"), ("period_max_s", "period_max_s"), ("gate_hs_m", "gate_hs_m")):
        value = getattr(limits, src, None)
        if value is not None and (not isinstance(value, float) or math.isfinite(value)):
            out[dst] = value
    for src in ("period_forbidden_s", "beam_sectors_deg"):
        value = getattr(limits, src, ())
        if value:
            out[src] = ", ".join(f"{lo:g}-{hi:g}" for lo, hi in value)
    return out


def provenance(*, weather_meta: dict | None = None, weather_ds=None, vessel=None, speed_loss_model: str = "", limits=None, profile_name: str = "", ais_sources=(), methods=(), weather_source: str = "") -> Provenance:
    """A provenance record from what a flow has at hand (weather metadata/Dataset, vessel, limits)."""
    meta = dict(weather_meta or {})
    products, files = meta.get("products") or meta.get("product") or [], meta.get("source_files") or meta.get("files") or []
    if isinstance(products, str):
        products = [products]
    if isinstance(files, str):
        files = [files]
    start = end = None
    if weather_ds is not None:
        if not products and weather_ds.attrs.get("product"):
            products = [str(weather_ds.attrs["product"])]
        if not files and weather_ds.attrs.get("source_files"):
            sf = weather_ds.attrs["source_files"]
            files = [sf] if isinstance(sf, str) else list(sf)
        times = pd.DatetimeIndex(weather_ds["time_utc"].values)
        if len(times):
            start, end = times.min().tz_localize("UTC"), times.max().tz_localize("UTC")
    return Provenance(
        weather_products=[str(p) for p in products],
        weather_files=[str(f) for f in files],
        weather_start_utc=start,
        weather_end_utc=end,
        weather_source=weather_source or str(meta.get("source", "")),
        ais_sources=[str(a) for a in ais_sources],
        speed_loss_model=speed_loss_model,
        thresholds_profile=profile_name or (getattr(limits, "name", "") if limits is not None else ""),
        limits=limits_for_report(limits),
        vessel=vessel.to_dict() if vessel is not None else {},
        software=software_versions(),
        methods=list(methods),
    )


def _snapshot_for(evaluations: dict, weather_ds, reference: str | None = None) -> tuple[WeatherSnapshot | None, dict]:
    """Weather slice at the time the reference route meets its highest Hs (the AIS track in an
    audit, the lane as planned at night), cut to all routes."""
    if reference is None:
        reference = "as_sailed" if "as_sailed" in evaluations else reference_of(evaluations)
    ref = evaluations.get(reference) or next(iter(evaluations.values()), None)
    if ref is None:
        return None, worst_point_empty()
    worst = worst_point(ref.route)
    if weather_ds is None or worst["time_utc"] is None or "hs_m" not in weather_ds:
        return None, worst
    return weather_snapshot(weather_ds, worst["time_utc"], bbox=routes_bbox([e.route for e in evaluations.values()])), worst


def worst_point_empty() -> dict:
    return {"time_utc": None, "lat_deg": None, "lon_deg": None, "hs_m": None}


def _text(value) -> str | None:
    """AIS static text as stored (None for missing); escaping happens in the renderer."""
    if value is None or (isinstance(value, float) and math.isnan(value)) or value is pd.NA:
        return None
    return str(value)


def _int(value) -> int | None:
    try:
        if value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value)):
            return None
        return int(value)
    except (TypeError, ValueError):
        return None


def voyage_audit_model(out: dict, *, mmsi: int, static=None, voyage: dict | None = None, vessel=None, limits=None,
                       weather_ds=None, weather_meta: dict | None = None, speed_loss_model: str = "bowditch",
                       profile_name: str = "", ais_sources=(), methods=(), exports: dict | None = None):
    """The audit report model from :func:`routing.audit.audit_routes` output.

    Parameters
    ----------
    out : dict
        ``audit_routes`` result: ``evaluations``, ``table``, ``proposed``, ``findings``.
    mmsi : int
    static : mapping, optional
        The ship's row of ``read_vessels`` (``name``, ``callsign``, ``destination``, ``imo``, ``ship_type``).
    voyage : dict, optional
        ``voyage_id``, ``origin``, ``destination`` (port names).
    vessel, limits, weather_ds, weather_meta, speed_loss_model, profile_name :
        What the audit ran with (profile, operator limits, hindcast Dataset for the map).
    """
    from dashboards.model import VoyageAudit

    evaluations = out["evaluations"]
    snapshot, _ = _snapshot_for(evaluations, weather_ds)
    routes = route_set_from_evaluations(evaluations, out.get("table"), out.get("proposed"), weather=snapshot, exports=exports)
    hist = evaluations["as_sailed" if "as_sailed" in evaluations else "historical"].route
    static = dict(static) if static is not None else {}
    voyage = dict(voyage or {})
    return VoyageAudit(
        mmsi=int(mmsi), depart_utc=hist.time_utc[0], arrive_utc=hist.time_utc[-1], routes=routes,
        ship_name=_text(static.get("name")), callsign=_text(static.get("callsign")), ais_destination=_text(static.get("destination")),
        imo=_int(static.get("imo")), ship_type=_int(static.get("ship_type")),
        voyage_id=_text(voyage.get("voyage_id")), origin=_text(voyage.get("origin")), destination=_text(voyage.get("destination")),
        vessel_profile=getattr(vessel, "name", "") if vessel is not None else "",
        findings=list(out.get("findings", [])),
        provenance=provenance(weather_meta=weather_meta, weather_ds=weather_ds, vessel=vessel, speed_loss_model=speed_loss_model,
                              limits=limits, profile_name=profile_name, ais_sources=ais_sources, methods=methods),
        speed_loss=speed_loss_curve(vessel, speed_loss_model, learned=out.get("learned_table")) if vessel is not None else None,
        bias=dict(out.get("bias") or {}), calm_water=dict(out.get("calm_water") or {}),
    )


def lane_departure_model(*, lane_id, origin: str, destination: str, depart_utc, rules=(), evaluations: dict | None = None,
                         table: pd.DataFrame | None = None, proposed: str | None = None, weather_ds=None,
                         exports: dict | None = None, error: str | None = None, risk_avoided: float | None = None,
                         hs_limit_m: float | None = None, vessel: str | None = None, optimality=(), reasons=(),
                         events_avoided: int | None = None, detailed: bool = True, bands: dict | None = None):
    """One nightly lane-departure for the report: adverse with its evaluated routes, or failed with ``error``.

    The worst point is where the lane as planned meets its highest Hs; the map's weather
    slice is taken at that time when ``weather_ds`` is given (and ``detailed``: a case shown
    without maps holds its comparison table and notes only). ``hs_limit_m`` is the lane's vessel's
    Hs limit (drawn on its map and plot); ``reasons`` the screen's structured rules (the chips);
    ``bands`` a learned model's P10-P50-P90 time and fuel per role (:func:`routing.bands.quantile_bands`),
    added to that role's note.
    """
    from dashboards.model import LaneDeparture

    if error is not None:
        return LaneDeparture(lane_id=lane_id, origin=origin, destination=destination, depart_utc=depart_utc, status="failed",
                             rules=list(rules), error=str(error), vessel=vessel, reasons=list(reasons))
    if not evaluations:
        raise ValueError(f"lane {lane_id}: an adverse lane-departure needs its evaluated routes")
    snapshot, worst = _snapshot_for(evaluations, weather_ds if detailed else None)
    end = pd.Timestamp(weather_ds["time_utc"].values[-1]).tz_localize("UTC") if weather_ds is not None else None
    routes = route_set_from_evaluations(evaluations, table, proposed, weather=snapshot, exports=exports, hs_limit_m=hs_limit_m,
                                        optimality=optimality, weather_end_utc=end, detailed=detailed)
    if bands:
        from routing.bands import band_line

        for role, band in bands.items():
            routes.notes[role] = "; ".join(filter(None, [routes.notes.get(role), band_line(band, role)]))
    return LaneDeparture(lane_id=lane_id, origin=origin, destination=destination, depart_utc=depart_utc, status="adverse",
                         rules=list(rules), worst_time_utc=worst["time_utc"], worst_lat_deg=worst["lat_deg"],
                         worst_lon_deg=worst["lon_deg"], worst_hs_m=worst["hs_m"], routes=routes, risk_avoided=risk_avoided,
                         vessel=vessel, reasons=list(reasons), events_avoided=events_avoided)
