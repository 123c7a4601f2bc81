"""What an audit reads, gathered before any computation (:mod:`pipelines.audit`): the sailed
track and its voyage, lane and port names from the workspace, the vessel and its limits, and the
hindcast weather (files, or the workspace's grid: :func:`weather_from_workspace`, which the
deviation and the nightly run read the same way), checked to cover the track.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from pipelines.vessels import vessel_for_ship
from thresholds.errors import StormlaneError

#: Weather must cover the track; a little slack at the ends is accepted (the last fix may fall
#: a few minutes after the last weather time). [h]
COVERAGE_SLACK_H = 0.0
class AuditError(StormlaneError):
    """The audit cannot run: unknown voyage, no AIS fixes, weather not covering the voyage."""


@dataclass
class AuditInputs:
    """Everything an audit reads, gathered before any computation."""

    positions: pd.DataFrame
    mmsi: int
    start_utc: pd.Timestamp
    end_utc: pd.Timestamp
    weather_ds: object  # canonical xarray.Dataset
    weather_meta: dict
    vessel: object
    vessel_profile: str
    limits: object
    profile_name: str
    voyage: dict | None = None
    static: dict = field(default_factory=dict)
    lane: pd.DataFrame | None = None
    lane_id: str | None = None
    weather_files: list = field(default_factory=list)
    port_names: dict = field(default_factory=dict)


def _utc(t) -> pd.Timestamp:
    ts = pd.Timestamp(t)
    return ts.tz_localize("UTC") if ts.tzinfo is None else ts.tz_convert("UTC")


def _option_utc(t, option: str) -> pd.Timestamp:
    """:func:`_utc` of a user-given time; a bad one is an :class:`AuditError` naming the option."""
    from pipelines.times import utc_or_none

    ts = utc_or_none(t)
    if ts is None:
        raise AuditError(f"{option} {t!r} is not an ISO 8601 time")
    return ts


def _lane_for_voyage(ws, voyage: dict | None) -> tuple[str | None, pd.DataFrame | None]:
    """The lane built from this voyage, else the busiest lane between the same ports."""
    from pipelines.storage.lanes import read_lane_centroids, read_lane_voyages, read_lanes

    if voyage is None:
        return None, None
    try:
        lv = read_lane_voyages(ws)
        lanes = read_lanes(ws)
    except Exception:  # noqa: BLE001 - workspace without lanes: no deviation, said in the findings
        return None, None
    hit = lv.loc[lv["voyage_id"] == voyage["voyage_id"], "lane_id"]
    lane_id = str(hit.iloc[0]) if len(hit) else None
    if lane_id is None and voyage.get("origin_port_id") is not None and voyage.get("dest_port_id") is not None:
        same = lanes[(lanes["origin_port_id"] == voyage["origin_port_id"]) & (lanes["dest_port_id"] == voyage["dest_port_id"])]
        if len(same):
            lane_id = str(same.sort_values("n_voyages", ascending=False)["lane_id"].iloc[0])
    if lane_id is None:
        return None, None
    return lane_id, read_lane_centroids(ws, lane_id)


def _port_names(ws, voyage: dict | None) -> dict:
    """``origin`` / ``destination`` port names of a voyage (empty when unknown)."""
    if voyage is None:
        return {}
    from pipelines.storage.lanes import read_ports

    ports = read_ports(ws).set_index("port_id")["name"]
    out = {}
    for key, col in (("origin", "origin_port_id"), ("destination", "dest_port_id")):
        pid = voyage.get(col)
        if pid is not None and not pd.isna(pid) and int(pid) in ports.index:
            out[key] = str(ports.loc[int(pid)])
    return out


def load_audit_inputs(db, *, voyage_id: str | None = None, mmsi: int | None = None, start=None, end=None,
                      weather_paths=(), vessel: str | None = None, profile: str | None = None) -> AuditInputs:
    """Read the track, static data, voyage, lane and weather of an audit (no computation).

    Weather comes from ``weather_paths`` (local CMEMS/ERA5/GRIB files, :func:`weather.io.read_local`)
    or, when none are given, from the workspace's weather tables.
    """
    from pipelines.config import load_operator_profile, load_vessel
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import read_positions, read_vessels

    if voyage_id is None and (mmsi is None or start is None or end is None):
        raise AuditError("give --voyage ID, or --mmsi N with --start and --end")
    db = Path(db)
    if not db.exists():
        raise AuditError(f"workspace {db} does not exist (run `stormlane ingest-ais` / `stormlane demo` first)")
    voyage = None
    with open_workspace(db) as ws:
        if voyage_id is not None:
            from pipelines.storage.lanes import read_voyages

            voyages = read_voyages(ws)
            row = voyages[voyages["voyage_id"].astype(str) == str(voyage_id)]
            if row.empty:
                known = ", ".join(voyages["voyage_id"].astype(str).head(5))
                raise AuditError(f"no voyage {voyage_id!r} in {db} ({len(voyages)} voyages{'; e.g. ' + known if known else ''}; "
                                 "run `stormlane lanes` first)")
            voyage = row.iloc[0].to_dict()
            mmsi = int(voyage["mmsi"])
            start, end = voyage["depart_utc"], voyage["arrive_utc"]
        start_utc, end_utc = _option_utc(start, "--start"), _option_utc(end, "--end")
        if not end_utc > start_utc:
            raise AuditError(f"--end {end_utc.isoformat()} must be after --start {start_utc.isoformat()}")
        if voyage is None:
            _refuse_several_voyages(ws, int(mmsi), start_utc, end_utc)
        positions = read_positions(ws, mmsi=int(mmsi), start=start_utc, end=end_utc + pd.Timedelta(seconds=1))
        if len(positions) < 2:
            raise AuditError(f"MMSI {mmsi} has {len(positions)} AIS fix(es) between {start_utc.isoformat()} and "
                             f"{end_utc.isoformat()} in {db}; an audit needs a sailed track")
        static_df = read_vessels(ws)
        srow = static_df[static_df["mmsi"] == int(mmsi)]
        static = {k: (None if pd.isna(v) else v) for k, v in srow.iloc[0].to_dict().items()} if len(srow) else {}
        lane_id, lane = _lane_for_voyage(ws, voyage)
        port_names = _port_names(ws, voyage)
        files = [str(p) for p in weather_paths]
        if files:
            from weather.io import read_local

            ds, meta = read_local(files)
        else:
            ds, meta = weather_from_workspace(ws, start_utc, end_utc)
    profile_name = vessel or vessel_for_ship(static)
    limits = load_operator_profile(profile)
    return AuditInputs(
        positions=positions, mmsi=int(mmsi), start_utc=start_utc, end_utc=end_utc, weather_ds=ds, weather_meta=meta,
        vessel=load_vessel(profile_name), vessel_profile=profile_name, limits=limits, profile_name=getattr(limits, "name", str(profile)),
        voyage=voyage, static=static, lane=lane, lane_id=lane_id, weather_files=files, port_names=port_names,
    )


def _refuse_several_voyages(ws, mmsi: int, start_utc: pd.Timestamp, end_utc: pd.Timestamp) -> None:
    """An --mmsi window holding most of two or more of the ship's voyages is an error: an audit
    compares one passage with routes straight between its ends, and port calls inside the window
    would make those meaningless. (Needs the voyages of `stormlane lanes`; without them the
    findings still flag a track far longer than the distance between its ends.)"""
    from pipelines.storage.lanes import read_voyages

    try:
        v = read_voyages(ws)
    except Exception:  # noqa: BLE001 - no voyages table yet (lanes not run): nothing to check against
        return
    v = v[v["mmsi"] == mmsi]
    if v.empty:
        return
    inside = (v["arrive_utc"].clip(upper=end_utc) - v["depart_utc"].clip(lower=start_utc)).dt.total_seconds()
    own = (v["arrive_utc"] - v["depart_utc"]).dt.total_seconds()
    held = v[(own > 0) & (inside >= 0.5 * own)]
    if len(held) >= 2:
        ids = ", ".join(str(x) for x in held["voyage_id"].head(6)) + (", ..." if len(held) > 6 else "")
        raise AuditError(f"the window {start_utc.isoformat()} .. {end_utc.isoformat()} holds {len(held)} voyages of MMSI {mmsi} "
                         f"({ids}); an audit compares one passage with routes between its ends: audit one voyage at a time "
                         "with --voyage ID, or narrow --start/--end")


def weather_from_workspace(ws, start_utc, end_utc, pad_h: float = 6.0):
    """The canonical weather Dataset of the workspace's latest grid over a time window."""
    import xarray as xr

    from pipelines.storage.weather import get_grid, read_cells

    try:
        g = get_grid(ws)
    except StormlaneError:  # no grid loaded at all (the latest is asked for)
        raise AuditError(f"no --weather files given and no weather in the workspace {ws.path}: "
                         "load some with `stormlane weather load PATH...`") from None
    cells = read_cells(ws, int(g["grid_id"]), start=start_utc - pd.Timedelta(hours=pad_h), end=end_utc + pd.Timedelta(hours=pad_h))
    if cells.empty:
        raise AuditError(f"the workspace weather grid {g['name']!r} ({g['start_utc']} .. {g['end_utc']}) has no data between "
                         f"{start_utc.isoformat()} and {end_utc.isoformat()}; give --weather FILE...")
    times = pd.DatetimeIndex(sorted(cells["time_utc"].unique()))
    times = times.tz_convert("UTC") if times.tz is not None else times.tz_localize("UTC")
    ny, nx = int(g["nlat"]), int(g["nlon"])
    lat = g["lat0_deg"] + g["dlat_deg"] * np.arange(ny)
    lon = g["lon0_deg"] + g["dlon_deg"] * np.arange(nx)
    ct = pd.DatetimeIndex(cells["time_utc"])
    ct = ct.tz_convert("UTC") if ct.tz is not None else ct.tz_localize("UTC")
    ti = times.get_indexer(ct)
    data = {}
    for name in ("hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms", "current_u_ms", "current_v_ms"):
        if name not in cells or cells[name].isna().all():
            continue
        arr = np.full((times.size, ny, nx), np.nan, dtype=np.float32)
        arr[ti, cells["lat_idx"].to_numpy(), cells["lon_idx"].to_numpy()] = cells[name].to_numpy(dtype=np.float32)
        data[name] = (("time_utc", "lat", "lon"), arr)
    ds = xr.Dataset(data, coords={"time_utc": times.tz_localize(None).values, "lat": lat, "lon": lon},
                    attrs={"product": str(g["product"]), "source_files": str(g["source_files"])})
    return ds, {"product": str(g["product"]), "source": f"workspace grid {g['name']}", "grid": str(g["name"])}


def _check_coverage(sampler, start_utc: pd.Timestamp, end_utc: pd.Timestamp, what: str) -> None:
    slack = pd.Timedelta(hours=COVERAGE_SLACK_H)
    if start_utc < sampler.start_utc - slack or end_utc > sampler.end_utc + slack:
        raise AuditError(
            f"the weather covers {sampler.start_utc.isoformat()} .. {sampler.end_utc.isoformat()}, not the {what} "
            f"{start_utc.isoformat()} .. {end_utc.isoformat()}; give --weather files that cover it"
        )
