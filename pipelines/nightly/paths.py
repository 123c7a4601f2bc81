"""Nightly stage 1, inputs: the lanes (or planned voyages) to sail tonight, and the checks a person
can act on before a night starts (:func:`preflight`)."""

from __future__ import annotations

import csv
import io
import logging
from pathlib import Path

import pandas as pd

from pipelines.nightly.night import NightlyError, NightlyParams, NightlyWeatherError, NightPath, parse_utc
from pipelines.vessels import DEFAULT_VESSEL, lane_vessel_profiles
from thresholds.errors import StormlaneError

log = logging.getLogger(__name__)

def _require_workspace(db) -> None:
    if not Path(db).exists():
        raise NightlyError(f"workspace {db} does not exist (run `stormlane demo`, or ingest-ais and lanes, first)")


def _require_weather_files(files) -> None:
    from pipelines.routing_weather import require_weather_files

    require_weather_files(files, NightlyWeatherError)


def _require_voyages_file(path) -> None:
    if not Path(path).is_file():
        raise NightlyError(f"planned voyages file not found: {path}")


def _require_out_dir(path) -> None:
    """The report folder can be created: its nearest existing ancestor is a writable folder."""
    import os

    p = Path(path)
    for q in (p, *p.parents):
        if q.exists():
            if not q.is_dir():
                raise NightlyError(f"--out {path}: {q} exists and is not a folder")
            if not os.access(q, os.W_OK | os.X_OK):
                raise NightlyError(f"--out {path}: folder {q} is not writable")
            return


def preflight(params: NightlyParams) -> None:
    """What a person can fix before a night starts, checked before Prefect starts: the
    workspace and the weather paths exist, the planned voyages file reads, the report folder
    can be created, the workspace has the lanes asked for and something can be sailed (every
    planned voyage failing is one error with their reasons), the weather (local files or the
    workspace grid) covers tonight's departures. The flow's steps run the same
    checks; a transient failure here (a workspace locked by another process) is left to the
    flow's I/O task, which retries it."""
    _require_workspace(params.db)
    _require_weather_files(params.weather)
    if params.speed_loss.startswith("learned:"):  # the stored model exists (one line listing the models)
        from pipelines.learn import resolve_speed_loss

        resolve_speed_loss(params.speed_loss, params.db)
    if params.voyages:
        read_planned_voyages(params.voyages)  # file, columns, times and vessel profiles, by line
    if params.report:
        for out in (params.out, params.out_root):
            if out:
                _require_out_dir(out)
    from pipelines.nightly.plan import read_weather_before

    try:
        paths = load_paths(params.db, voyages=params.voyages, lanes=params.lanes, vessel=params.vessel)
        read_weather_before(params, paths)  # tonight's departures covered (read once: handed to the flow)
    except StormlaneError:
        raise
    except Exception:  # noqa: BLE001 - transient (locked workspace ...): the flow retries it
        log.debug("preflight: lanes or weather not checked", exc_info=True)


def _port_label(ports: pd.DataFrame, port_id) -> str:
    if port_id is None or pd.isna(port_id):
        return "?"
    row = ports[ports["port_id"] == int(port_id)]
    if row.empty:
        return f"port {int(port_id)}"
    name = row.iloc[0].get("name")
    return str(name) if name is not None and not pd.isna(name) else f"port {int(port_id)}"


#: Columns of the planned-voyages CSV (``voyage_id`` optional).
VOYAGE_COLUMNS = ("vessel", "origin", "destination", "depart_utc")


def read_planned_voyages(path) -> pd.DataFrame:
    """Planned voyages from a CSV: ``voyage_id`` (optional), ``vessel`` (profile name or TOML
    file), ``origin`` and ``destination`` (UN/LOCODE, port name or workspace port id) and
    ``depart_utc`` (ISO 8601).

    Raises
    ------
    NightlyError
        Missing file or column, empty field, unknown vessel profile or bad time, naming the
        file, line and field.
    """
    from pipelines.config import VesselProfileError, load_vessel

    path = Path(path)
    _require_voyages_file(path)
    rows = []
    known_vessels: set = set()
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = raw[: err.start].count(b"\n") + 1
        raise NightlyError(f"{path}: line {line}: not UTF-8 text (byte {err.object[err.start]:#04x})") from None
    with io.StringIO(text, newline="") as fh:
        reader = csv.DictReader(fh)
        header = [h.strip() for h in (reader.fieldnames or [])]
        missing = [c for c in VOYAGE_COLUMNS if c not in header]
        if missing:
            raise NightlyError(f"{path}: line 1: missing column(s) {', '.join(missing)} (need {', '.join(VOYAGE_COLUMNS)}; "
                               "voyage_id is optional)")
        for k, raw in enumerate(reader, start=2):
            rec = {(key or "").strip(): (val or "").strip() for key, val in raw.items()}
            if not any(rec.values()):
                continue
            for col in VOYAGE_COLUMNS:
                if not rec.get(col):
                    raise NightlyError(f"{path}: line {k}: field {col!r} is empty")
            try:
                t = parse_utc(rec["depart_utc"], "depart_utc")
            except NightlyError:
                raise NightlyError(f"{path}: line {k}: field 'depart_utc': {rec['depart_utc']!r} is not an ISO 8601 time") from None
            if rec["vessel"] not in known_vessels:
                try:
                    load_vessel(rec["vessel"])
                except VesselProfileError as err:
                    raise NightlyError(f"{path}: line {k}: field 'vessel': {err}") from None
                known_vessels.add(rec["vessel"])
            vid = rec.get("voyage_id") or f"V{k - 1:03d}"
            rows.append({"voyage_id": vid, "vessel": rec["vessel"], "origin": rec["origin"],
                         "destination": rec["destination"], "depart_utc": t, "line": k})
    if not rows:
        raise NightlyError(f"{path}: no planned voyages")
    df = pd.DataFrame(rows)
    dup = df[df["voyage_id"].duplicated()]
    if not dup.empty:
        r = dup.iloc[0]
        raise NightlyError(f"{path}: line {r['line']}: field 'voyage_id': {r['voyage_id']!r} appears twice")
    return df


def _find_port(ports: pd.DataFrame, text: str):
    """Port id for a LOCODE, a name (case-insensitive) or a numeric id; None when unknown."""
    t = str(text).strip()
    if t.isdigit() and int(t) in set(ports["port_id"].astype(int)):
        return int(t)
    for col in ("locode", "name"):
        if col in ports:
            hit = ports[ports[col].astype(str).str.casefold() == t.casefold()]
            if len(hit):
                return int(hit.iloc[0]["port_id"])
    return None


def load_paths(db, *, voyages: str | None = None, lanes: list[str] | None = None, vessel: str | None = None) -> list[NightPath]:
    """Read what to sail tonight from the workspace (I/O step).

    Without ``voyages``: every lane (or the ``lanes`` listed) with the window's departures.
    With ``voyages`` (a CSV, :func:`read_planned_voyages`): each planned voyage on the busiest
    lane between its ports (a voyage whose ports have no lane is kept and fails with the reason,
    naming the file and line; when every one fails, :class:`NightlyError` lists the reasons).
    """
    from pipelines.storage import open_workspace
    from pipelines.storage.ais import read_vessels
    from pipelines.storage.lanes import read_lane_centroids, read_lane_voyages, read_lanes, read_ports, read_voyages

    db = Path(db)
    _require_workspace(db)
    with open_workspace(db) as ws:
        all_lanes = read_lanes(ws)
        centroids = read_lane_centroids(ws)
        ports = read_ports(ws)
        profiles = lane_vessel_profiles(all_lanes, read_lane_voyages(ws), read_voyages(ws), read_vessels(ws)) if vessel is None else {}
    if all_lanes.empty:
        raise NightlyError(f"workspace {db} has no lanes (run `stormlane lanes` first)")
    by_lane = {str(k): g.sort_values("seq")[["seq", "lat_deg", "lon_deg", "speed_kn"]].reset_index(drop=True)
               for k, g in centroids.groupby("lane_id")}
    info = {str(r["lane_id"]): r for r in all_lanes.to_dict("records")}
    if voyages is None:
        wanted = [str(x) for x in (lanes or sorted(info))]
        unknown = [x for x in wanted if x not in info]
        if unknown:
            raise NightlyError(f"unknown lane(s) {', '.join(unknown)} in {db} (lanes: {', '.join(sorted(info)[:12])} ...)")
        return [
            NightPath(path_id=lid, lane_id=lid, origin=_port_label(ports, info[lid]["origin_port_id"]),
                      destination=_port_label(ports, info[lid]["dest_port_id"]),
                      centroids=by_lane.get(lid, pd.DataFrame(columns=["seq", "lat_deg", "lon_deg", "speed_kn"])),
                      vessel_profile=vessel or profiles.get(lid, DEFAULT_VESSEL))
            for lid in wanted
        ]
    planned = read_planned_voyages(voyages)
    out = []
    for r in planned.to_dict("records"):
        o, d = _find_port(ports, r["origin"]), _find_port(ports, r["destination"])
        error, lane_id = None, None
        if o is None or d is None:
            bad = r["origin"] if o is None else r["destination"]
            error = f"{voyages}: line {r['line']}: unknown port {bad!r} (the workspace knows {', '.join(ports['locode'].dropna().astype(str))})"
        else:
            cand = all_lanes[(all_lanes["origin_port_id"] == o) & (all_lanes["dest_port_id"] == d)]
            if cand.empty:
                error = f"{voyages}: line {r['line']}: no lane from {_port_label(ports, o)} to {_port_label(ports, d)} in the workspace"
            else:
                lane_id = str(cand.sort_values(["n_voyages", "lane_id"], ascending=[False, True]).iloc[0]["lane_id"])
        out.append(NightPath(
            path_id=str(r["voyage_id"]), lane_id=lane_id,
            origin=_port_label(ports, o) if o is not None else str(r["origin"]),
            destination=_port_label(ports, d) if d is not None else str(r["destination"]),
            centroids=by_lane.get(lane_id, pd.DataFrame(columns=["seq", "lat_deg", "lon_deg", "speed_kn"])),
            vessel_profile=vessel or r["vessel"], departures=[r["depart_utc"]], error=error,
        ))
    if all(p.error for p in out):
        raise NightlyError(nothing_to_sail(out))
    return out


def nothing_to_sail(paths: list[NightPath], show: int = 3) -> str:
    """The error of a night where no lane or planned voyage can be sailed: how many failed and
    the first ``show`` reasons (a planned voyage's reason names its file and line)."""
    reasons = [p.error for p in paths if p.error]
    msg = "nothing to check tonight: no lane or planned voyage can be sailed"
    if not reasons:
        return msg
    more = f"; ... and {len(reasons) - show} more" if len(reasons) > show else ""
    return f"{msg} ({len(reasons)} of {len(paths)} failed): " + "; ".join(reasons[:show]) + more
