"""The nightly reroute: every lane (or planned voyage) x every departure of the forecast window.

What an operations team runs every night, unattended (issue 7):

1. **Inputs** (:func:`load_paths`, I/O): the workspace's lanes and their centroid sequences, the
   port names, and a vessel profile per lane (from the AIS ship types of the voyages that formed
   the lane, :func:`pipelines.vessels.vessel_for_ship`, or ``--vessel``); or planned voyages
   from a CSV (:func:`read_planned_voyages`).
2. **Weather** (:func:`read_weather_source`, I/O; :func:`fetch_weather`, network, retried): local
   CMEMS/ERA5/GRIB files (:func:`weather.io.read_local`), the real download clients when
   credentials are configured (cached by :mod:`weather.io.cache`), or the grid already loaded in
   the workspace. :func:`prepare_night` (pure) fails early with a clear message when the weather
   does not cover the departures, cuts the weather to the run's window and area, and derives the
   run id from the inputs.
3. **Screen** (:func:`screen_departures`, pure): the lanes x departures x weather join in DuckDB
   (:func:`pipelines.storage.weather.join_points_weather`: ETAs from the typical speeds, the grid
   cell by index arithmetic, the nearest weather time by ``ASOF JOIN``, as the seed paper
   ``ais_weather_routing_cargo_loss`` §3.2 does), then the vessel's thresholds
   (:func:`thresholds.safety.assess`: operator limits + IMO MSC.1/Circ.1228) at every centroid,
   with the course to the next centroid and the centroid's typical speed. A lane-departure is
   **adverse** when any rule fires at any centroid; the reasons name the rule, the value against
   its limit, where and when.
4. **Reroute** (:func:`reroute_lane`, pure, one task per lane, fanned out by the task runner):
   for each adverse departure of the lane, the cargo-safe deviation
   (:func:`routing.deviate.deviate_lane`), the time-optimal and minimum-distance A* routes and
   the safe time-optimal route under the vessel's limits (:func:`routing.planner.plan_routes`
   with ``safety="hard"``, falling back to ``soft``), the lane as planned (its centroid path, legs
   over land repaired, sailed at the lane's typical AIS speed minus the speed loss: the same vessel
   model as the A* routes, :func:`routing.compare.lane_departure`), and the evaluation of the lane
   and of the alternatives in the same weather (:func:`routing.evaluate.evaluate_route`,
   :func:`routing.audit.propose`). A failure of one lane-departure (unreachable destination, a
   lane outside the weather ...) marks it ``failed`` with the message; the rest completes.
5. **Rank** (:func:`assemble`, pure): by risk avoided (hours over an operator limit or in an IMO
   situation, lane as planned minus proposed), then IMO events avoided, then cost (extra sailing
   time, extra fuel).
6. **Store** (:func:`store_night`, I/O) in the ``nightly_*`` tables keyed by run id (a rerun with
   the same inputs replaces the same rows), and **report** (:func:`write_report`, I/O): the
   self-contained HTML report, its model as JSON, and GeoJSON/GPX/RTZ exports per adverse
   lane-departure under ``--out``.

The Prefect flow (:func:`nightly_reroute`, built lazily) only wires these functions; the
plain entry point :func:`run_night` runs the same steps without Prefect.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import functools
import hashlib
import io
import json
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
from pydantic import BaseModel, Field, field_validator

from pipelines.runners import make_task_runner  # noqa: F401 (moved there, shared with the lanes flow)
from pipelines.runners import retry_transient as _retry_transient
from pipelines.storage import DEFAULT_DB
from pipelines.vessels import DEFAULT_VESSEL, lane_vessel_profiles  # noqa: F401 (the one default-vessel rule)
from thresholds.errors import StormlaneError

log = logging.getLogger(__name__)

#: Default forecast window and departure spacing: the next 48 h every 3 h (16 departures).
DEFAULT_WINDOW_H = 48.0
DEFAULT_STEP_H = 3.0
#: The weather is cut to the lanes' box widened by this much, or by 20 % of the widest lane's
#: span when that is more (the A* mesh's default box is the great circle's plus max(1 deg, 15 %)).
WEATHER_PAD_DEG = 3.0
#: Route properties that change from run to run (timings) and are not stored.
VOLATILE_PROPERTIES = ("search_s",)
#: Retries of the flow's I/O tasks (workspace, files) and of the network task (downloads); the
#: pure steps (screen, per-lane work, ranking) never retry: a deterministic error would repeat.
IO_RETRY_DELAYS_S = (2, 5)
FETCH_RETRY_DELAYS_S = (2, 5, 15)
#: Route roles evaluated for an adverse lane-departure, in report order; every delta is against
#: ``lane``: the lane as planned (its centroids, legs over land repaired) sailed at the lane's
#: typical AIS speed minus the vessel model's speed loss, exactly as the alternatives are sailed.
ROLES = ("lane", "deviation", "safe_optimal", "optimal", "min_distance")
REFERENCE = "lane"


class NightlyError(StormlaneError):
    """The nightly run cannot start: bad parameters, no lanes, unreadable planned voyages."""


class NightlyWeatherError(NightlyError):
    """The weather does not cover the departures of the night (or there is no weather at all)."""


# --- parameters ---------------------------------------------------------------------------------


class NightlyParams(BaseModel):
    """Parameters of one night (validated before anything runs)."""

    db: str = DEFAULT_DB
    out: str | None = None
    out_root: str | None = None
    weather: list[str] = Field(default_factory=list)
    weather_source: Literal["auto", "files", "fetch", "workspace"] = "auto"
    now: str | None = None
    window_h: float = Field(DEFAULT_WINDOW_H, gt=0.0, le=24.0 * 16)
    step_h: float = Field(DEFAULT_STEP_H, gt=0.0, le=48.0)
    voyages: str | None = None
    lanes: list[str] | None = None
    vessel: str | None = None
    profile: str | None = None
    speed_loss: str = "bowditch"
    safety: Literal["hard", "soft", "none"] = "hard"
    max_detail: int = Field(20, ge=0)
    report: bool = True
    cache_dir: str | None = None

    @field_validator("speed_loss")
    @classmethod
    def _model(cls, v: str) -> str:
        from routing.speed_loss import MODELS

        if v not in MODELS:
            raise ValueError(f"unknown speed-loss model {v!r}; use one of {', '.join(MODELS)}")
        return v

    @field_validator("now")
    @classmethod
    def _now(cls, v: str | None) -> str | None:
        if v is not None:
            try:
                parse_utc(v, "now")
            except NightlyError as err:
                raise ValueError(str(err)) from None
        return v

    @classmethod
    def checked(cls, **kwargs) -> "NightlyParams":
        """Validate, turning pydantic's report into one :class:`NightlyError` line per problem."""
        from pydantic import ValidationError

        try:
            return cls(**kwargs)
        except ValidationError as err:
            problems = "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in err.errors())
            raise NightlyError(f"invalid nightly parameters: {problems}") from None


def _require_workspace(db) -> None:
    if not Path(db).exists():
        raise NightlyError(f"workspace {db} does not exist (run `stormlane demo`, or ingest-ais and lanes, first)")


def _require_weather_files(files) -> None:
    missing = [str(f) for f in files if not Path(f).exists()]
    if missing:
        raise NightlyWeatherError(f"weather file(s) not found: {', '.join(missing)}")


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
    planned voyage failing is one error with their reasons). The flow's steps run the same
    checks; a transient failure here (a workspace locked by another process) is left to the
    flow's I/O task, which retries it."""
    _require_workspace(params.db)
    _require_weather_files(params.weather)
    if params.voyages:
        read_planned_voyages(params.voyages)  # file, columns, times and vessel profiles, by line
    if params.report:
        for out in (params.out, params.out_root):
            if out:
                _require_out_dir(out)
    try:
        load_paths(params.db, voyages=params.voyages, lanes=params.lanes, vessel=params.vessel)
    except StormlaneError:
        raise
    except Exception:  # noqa: BLE001 - transient (locked workspace ...): the flow retries it
        log.debug("preflight: lanes not checked", exc_info=True)


class _UserErrorsWithoutTraceback(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info and isinstance(record.exc_info[1], StormlaneError):
            record.exc_info, record.exc_text = None, None
        return True


def _workspace_locked(err: BaseException | None) -> bool:
    try:
        import duckdb
    except ImportError:  # pragma: no cover - duckdb is a dependency
        return False
    return isinstance(err, duckdb.IOException) and "Could not set lock" in str(err)


def is_user_error(err: BaseException | None) -> bool:
    """An error the CLI reports as one ``error:`` line: a :class:`StormlaneError` (bad input,
    missing coverage ...) or a workspace locked by another process."""
    return isinstance(err, StormlaneError) or _workspace_locked(err)


#: Loggers of Prefect's flow and task runs (their records reach the console through the root logger).
RUN_LOGGERS = ("prefect.flow_runs", "prefect.task_runs")


class _HoldRunErrors(logging.Filter):
    """On a console handler: keep the flow and task runs' ERROR records back instead of printing them."""

    def __init__(self) -> None:
        super().__init__()
        self.held: list[logging.LogRecord] = []

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno >= logging.ERROR and record.name.startswith(RUN_LOGGERS):
            self.held.append(record)
            return False
        return True


def prefect_console_handlers() -> list[logging.Handler]:
    """Prefect's console handlers (on the root logger, set up when Prefect is imported)."""
    from prefect.logging.configuration import ensure_logging_setup
    from prefect.logging.handlers import PrefectConsoleHandler

    ensure_logging_setup()  # what `import prefect.main` does first (later calls are incremental: same handlers)
    return [h for h in logging.getLogger().handlers if isinstance(h, PrefectConsoleHandler)]


@contextlib.contextmanager
def user_errors_one_line(hold_console: bool = True, handlers: list[logging.Handler] | None = None):
    """While the CLI runs a night, a user error ends it with the CLI's one ``error:`` line only.

    Prefect logs a failed run's exception with its traceback: for a :class:`StormlaneError`
    the traceback is dropped (other exceptions keep theirs). With ``hold_console`` the flow and
    task runs' ERROR lines ("Task run failed with exception ...", "Finished in state Failed",
    "Flow run ... Encountered exception") are also kept off the console (``handlers``, default
    Prefect's console handlers) until the run ends: dropped when it ended with a user error
    (:func:`is_user_error`, whose message the CLI prints), printed then otherwise (an unexpected
    crash, or a lane that failed in a night that completed). Prefect's API log handler still
    receives every record.
    """
    loggers = [logging.getLogger(n) for n in RUN_LOGGERS]
    f = _UserErrorsWithoutTraceback()
    for lg in loggers:
        lg.addFilter(f)
    holders = []
    if hold_console:
        for h in prefect_console_handlers() if handlers is None else handlers:
            holder = _HoldRunErrors()
            h.addFilter(holder)
            holders.append((h, holder))
    error = None
    try:
        yield
    except BaseException as err:
        error = err
        raise
    finally:
        for lg in loggers:
            lg.removeFilter(f)
        for h, holder in holders:
            h.removeFilter(holder)
            if not is_user_error(error):
                for record in holder.held:
                    h.handle(record)


def parse_utc(text, what: str = "time") -> pd.Timestamp:
    """An ISO 8601 time as a tz-aware UTC Timestamp (naive input is taken as UTC)."""
    from pipelines.times import utc_or_none

    t = utc_or_none(text)
    if t is None:
        raise NightlyError(f"{what}: {text!r} is not an ISO 8601 time")
    return t


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


# --- inputs: lanes or planned voyages -----------------------------------------------------------


@dataclass
class NightPath:
    """One thing to sail tonight: a lane (all window departures) or a planned voyage."""

    path_id: str
    lane_id: str | None
    origin: str
    destination: str
    centroids: pd.DataFrame  # seq, lat_deg, lon_deg, speed_kn (sailing order)
    vessel_profile: str
    departures: list = field(default_factory=list)  # tz-aware Timestamps; empty = the window
    error: str | None = None  # a path that cannot be sailed at all (e.g. no lane for a planned voyage)

    @property
    def hours(self) -> float:
        """Sailing time along the centroids at their typical speeds. [h]"""
        from thresholds.geodesy import haversine_nmi

        c = self.centroids
        if len(c) < 2:
            return 0.0
        d = np.asarray(haversine_nmi(c["lat_deg"].to_numpy()[:-1], c["lon_deg"].to_numpy()[:-1],
                                     c["lat_deg"].to_numpy()[1:], c["lon_deg"].to_numpy()[1:]), dtype=float)
        v = c["speed_kn"].to_numpy(dtype=float)[:-1]
        v = np.where(np.isfinite(v) & (v > 0), v, np.nan)
        fallback = np.nanmedian(v) if np.isfinite(v).any() else 10.0
        return float(np.sum(d / np.where(np.isfinite(v), v, fallback)))


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


# --- weather ------------------------------------------------------------------------------------


def weather_credentials_configured() -> bool:
    """True when both download clients have credentials configured through their own mechanisms
    (environment variables or their configuration files; only their presence is checked)."""
    import os

    home = Path.home()
    cmems = bool(os.environ.get("COPERNICUSMARINE_SERVICE_USERNAME")) or (home / ".copernicusmarine" / ".copernicusmarine-credentials").is_file()
    cds = bool(os.environ.get("CDSAPI_KEY")) or (home / ".cdsapirc").is_file()
    return cmems and cds


def choose_weather_source(params: NightlyParams) -> str:
    """``files`` when --weather is given, ``fetch`` when asked or when the clients have credentials,
    else ``workspace`` (the grid loaded by ``stormlane weather load`` / the demo)."""
    if params.weather_source != "auto":
        if params.weather_source == "files" and not params.weather:
            raise NightlyError("weather source 'files' needs --weather FILE_OR_DIR")
        return params.weather_source
    if params.weather:
        return "files"
    if weather_credentials_configured():
        return "fetch"
    return "workspace"


def paths_bbox(paths: list[NightPath]) -> tuple[float, float, float, float]:
    """``(lon_min, lat_min, lon_max, lat_max)`` of every centroid."""
    frames = [p.centroids for p in paths if len(p.centroids)]
    if not frames:
        raise NightlyError("no lane has centroids to check")
    c = pd.concat(frames)
    return float(c["lon_deg"].min()), float(c["lat_deg"].min()), float(c["lon_deg"].max()), float(c["lat_deg"].max())


def weather_span_needed(paths: list[NightPath], departures: pd.DatetimeIndex) -> tuple[pd.Timestamp, pd.Timestamp]:
    """First departure and the latest arrival (departure + sailing time) of the night."""
    starts, ends = [], []
    for p in paths:
        deps = list(p.departures) or list(departures)
        if not deps or p.error:
            continue
        starts.append(min(deps))
        ends.append(max(deps) + pd.Timedelta(hours=p.hours))
    if not starts:
        raise NightlyError(nothing_to_sail(paths))
    return min(starts), max(ends)


def nothing_to_sail(paths: list[NightPath], show: int = 3) -> str:
    """The error of a night where no lane or planned voyage can be sailed: how many failed and
    the first ``show`` reasons (a planned voyage's reason names its file and line)."""
    reasons = [p.error for p in paths if p.error]
    msg = "nothing to check tonight: no lane or planned voyage can be sailed"
    if not reasons:
        return msg
    more = f"; ... and {len(reasons) - show} more" if len(reasons) > show else ""
    return f"{msg} ({len(reasons)} of {len(paths)} failed): " + "; ".join(reasons[:show]) + more


def fetch_requests(paths: list[NightPath], departures: pd.DatetimeIndex, pad_deg: float = WEATHER_PAD_DEG) -> list:
    """The downloads of a night: CMEMS waves and ERA5 wind over the lanes' box and time span."""
    from pipelines.weather import FetchRequest

    lon0, lat0, lon1, lat1 = paths_bbox(paths)
    t0, t1 = weather_span_needed(paths, departures)
    bbox = (lon0 - pad_deg, lat0 - pad_deg, lon1 + pad_deg, lat1 + pad_deg)
    start = (t0 - pd.Timedelta(hours=3)).floor("h").isoformat()
    end = (t1 + pd.Timedelta(hours=3)).ceil("h").isoformat()
    return [FetchRequest(product="cmems-wave", bbox=bbox, start_utc=start, end_utc=end),
            FetchRequest(product="era5-wind", bbox=bbox, start_utc=start, end_utc=end)]


def fetch_weather(request, cache_dir: str | None = None) -> list[str]:
    """Network step: download one request with the real client (or reuse the cache)."""
    from pipelines.weather import fetch_files

    return [str(p) for p in fetch_files(request, cache_dir)]


def read_weather_source(source: str, files, db, start: pd.Timestamp, end: pd.Timestamp) -> tuple:
    """I/O step: the canonical weather Dataset and its metadata, from files or the workspace grid."""
    if source in ("files", "fetch"):
        from weather.io import read_local

        _require_weather_files(files)
        if not files:
            raise NightlyWeatherError("no weather files to read")
        ds, meta = read_local([str(f) for f in files])
        meta = dict(meta)
        meta["source"] = "downloaded (copernicusmarine + cdsapi, cached)" if source == "fetch" else "local files"
        meta.setdefault("files", [str(f) for f in files])
        return ds, meta
    from pipelines.audit import AuditError, weather_from_workspace
    from pipelines.storage import open_workspace

    with open_workspace(db) as ws:
        try:
            ds, meta = weather_from_workspace(ws, start, end, pad_h=6.0)
        except AuditError as err:
            raise NightlyWeatherError(f"{err} (or run with --weather DIR, or --fetch with download credentials)") from None
    return ds, dict(meta)


# --- the night's plan: coverage, subset, run id -------------------------------------------------


@dataclass
class Night:
    """Everything the pure steps need, fixed before any computation."""

    run_id: str
    now_utc: pd.Timestamp
    departures: pd.DatetimeIndex
    params: NightlyParams
    paths: list
    weather_ds: object  # canonical xarray.Dataset cut to the night
    weather_meta: dict
    weather_source: str
    weather_digest: str
    lanes_digest: str
    vessels: dict  # profile name -> Vessel
    limits: object  # OperatorProfile
    out: Path

    def path_departures(self, p: NightPath) -> list:
        return list(p.departures) or list(self.departures)


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


def subset_weather(ds, paths: list[NightPath], start: pd.Timestamp, end: pd.Timestamp, pad_deg: float = WEATHER_PAD_DEG):
    """The weather the night can touch, over the lanes' box widened by ``pad_deg`` (or 20 % of the
    widest lane's span, when more).

    Times run from the last one at or before ``start`` (the first departure) to the first at or
    after ``end`` plus a detour allowance (the longest lane's sailing time, at least 24 h): an A*
    route or a deviation may arrive later than the lane would, and it must meet the same weather
    whatever other lanes the night checks (a night on a subset of lanes gives the same routes).
    """
    times = pd.DatetimeIndex(ds["time_utc"].values).tz_localize("UTC")
    longest = max((p.hours for p in paths), default=0.0)
    end = end + pd.Timedelta(hours=max(24.0, longest))
    i0 = max(int(np.searchsorted(times.asi8, start.value, side="right")) - 1, 0)
    i1 = min(int(np.searchsorted(times.asi8, end.value, side="left")) + 1, times.size)
    spans = [max(np.ptp(p.centroids["lat_deg"]), np.ptp(p.centroids["lon_deg"])) for p in paths if len(p.centroids) > 1]
    pad = max(pad_deg, 0.2 * max(spans, default=0.0))
    lon0, lat0, lon1, lat1 = paths_bbox(paths)
    sub = ds.isel(time_utc=slice(i0, i1)).sel(lat=slice(lat0 - pad, lat1 + pad), lon=slice(lon0 - pad, lon1 + pad))
    if sub.sizes["lat"] < 2 or sub.sizes["lon"] < 2:
        raise NightlyWeatherError(
            f"{ds.attrs.get('product', 'weather')}: the grid (lat {float(ds.lat.min()):g}..{float(ds.lat.max()):g}, lon "
            f"{float(ds.lon.min()):g}..{float(ds.lon.max()):g}) does not cover the lanes (lat {lat0:g}..{lat1:g}, lon {lon0:g}..{lon1:g})"
        )
    return sub


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
        its grid misses the lanes.
    """
    from pipelines.config import load_operator_profile, load_vessel
    from weather.coverage import check_coverage
    from weather.errors import CoverageError

    departures = departure_times(now, params.window_h, params.step_h)
    first = min(min(p.departures) if p.departures else departures[0] for p in paths)
    last = max(max(p.departures) if p.departures else departures[-1] for p in paths)
    try:
        check_coverage(ds, variables=["hs_m"], start=first, end=last)
    except CoverageError as err:
        raise NightlyWeatherError(
            f"the weather does not cover tonight's departures {first:%Y-%m-%dT%H:%MZ} -> {last:%Y-%m-%dT%H:%MZ}: {err}"
        ) from None
    t0, t1 = weather_span_needed(paths, departures)
    sub = subset_weather(ds, paths, t0, t1)
    vessels = {}
    for name in sorted({p.vessel_profile for p in paths}):
        vessels[name] = load_vessel(name)
    limits = load_operator_profile(params.profile)
    wd = weather_digest(sub)
    ld = lanes_digest(paths)
    rid = _digest(now.isoformat(), [t.isoformat() for t in departures], params.window_h, params.step_h, ld, wd,
                  {k: repr(v) for k, v in vessels.items()}, repr(limits), params.speed_loss, params.safety)
    run_id = f"{now:%Y%m%dT%H%MZ}-{rid[:12]}"
    out = Path(params.out) if params.out else default_out(now, params.out_root)
    return Night(run_id=run_id, now_utc=now, departures=departures, params=params, paths=paths, weather_ds=sub,
                 weather_meta=dict(meta), weather_source=source, weather_digest=wd, lanes_digest=ld, vessels=vessels,
                 limits=limits, out=out)


# --- screen: lanes x departures x weather in DuckDB, thresholds at every centroid ---------------


def _headings(points: pd.DataFrame) -> np.ndarray:
    """Course at each point: towards the next point of its path (the last: from the previous)."""
    from thresholds.geodesy import initial_bearing_deg

    p = points
    same_next = p["path_id"].shift(-1) == p["path_id"]
    same_prev = p["path_id"].shift(1) == p["path_id"]
    lat, lon = p["lat_deg"].to_numpy(float), p["lon_deg"].to_numpy(float)
    nlat, nlon = np.roll(lat, -1), np.roll(lon, -1)
    plat, plon = np.roll(lat, 1), np.roll(lon, 1)
    fwd = np.asarray(initial_bearing_deg(lat, lon, nlat, nlon), dtype=float)
    back = np.asarray(initial_bearing_deg(plat, plon, lat, lon), dtype=float)
    return np.where(same_next.to_numpy(), fwd, np.where(same_prev.to_numpy(), back, np.nan))


def _fmt_rule(name: str, value: float, limit: float, unit: str) -> str:
    labels = {"hs": ("Hs", "m"), "wind": ("wind", "m/s"), "period": ("wave period", "s"), "beam_seas": ("encounter", "deg"),
              "surf_riding": ("speed", "kn"), "high_waves": ("Hs", "m"), "synchronous_roll": ("T_E", "s"),
              "parametric_roll": ("T_E", "s")}
    what, u = labels.get(name, (name, unit))
    v = f"{value:.1f}" if np.isfinite(value) else "?"
    lim = f" (limit {limit:.1f} {u})" if np.isfinite(limit) else ""
    return f"{what} {v} {u}{lim}"


def screen_departures(night: Night) -> pd.DataFrame:
    """The adverse-weather screen of every lane-departure (pure step; DuckDB in memory).

    Returns
    -------
    DataFrame
        One row per (``path_id``, ``depart_utc``): ``n_points``, ``n_points_no_weather``
        (beyond the forecast, on the weather's land cells, or off the grid), ``adverse``,
        ``rules`` (rule names, sorted), ``reasons`` (per rule: the worst centroid, its value
        against the limit, time and place), ``max_hs_m`` and the worst point, ``error`` (a path
        that could not be screened at all).
    """
    from pipelines.storage import open_workspace
    from pipelines.storage.weather import join_points_weather, load_weather
    from thresholds.safety import assess

    rows = []
    frames, deps = [], []
    for p in night.paths:
        if p.error or len(p.centroids) < 2:
            err = p.error or f"lane {p.lane_id} has {len(p.centroids)} centroid(s); at least 2 are needed"
            rows += [{"path_id": p.path_id, "depart_utc": t, "n_points": len(p.centroids), "n_points_no_weather": len(p.centroids),
                      "adverse": False, "rules": [], "reasons": [], "max_hs_m": np.nan, "worst_time_utc": None,
                      "worst_lat_deg": np.nan, "worst_lon_deg": np.nan, "error": err} for t in night.path_departures(p)]
            continue
        c = p.centroids.assign(path_id=p.path_id)
        speed = c["speed_kn"].astype(float)
        v0 = night.vessels[p.vessel_profile].speed_kn
        c["speed_kn"] = speed.where(np.isfinite(speed) & (speed > 0), v0)
        frames.append(c[["path_id", "seq", "lat_deg", "lon_deg", "speed_kn"]])
        deps += [{"path_id": p.path_id, "departure_utc": t} for t in night.path_departures(p)]
    if frames:
        points = pd.concat(frames, ignore_index=True).sort_values(["path_id", "seq"], kind="stable").reset_index(drop=True)
        points["heading_deg"] = _headings(points)
        with open_workspace(":memory:") as mem:
            load_weather(mem, night.weather_ds, name="nightly")
            joined = join_points_weather(mem, points.drop(columns="heading_deg"), pd.DataFrame(deps), grid="nightly", on_missing="flag")
        joined = joined.merge(points[["path_id", "seq", "heading_deg"]], on=["path_id", "seq"], how="left")
        fired_cols = {}
        joined["fired_any"] = False
        vessel_of = {p.path_id: p.vessel_profile for p in night.paths}
        joined["vessel"] = joined["path_id"].map(vessel_of)
        detail = {}
        for prof, idx in joined.groupby("vessel").groups.items():
            g = joined.loc[idx]
            w = {k: g[k].to_numpy(dtype=float) for k in ("hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms") if k in g}
            a = assess(night.vessels[prof], night.limits, heading_deg=g["heading_deg"].to_numpy(float),
                       speed_kn=g["speed_kn"].to_numpy(float), missing="skip", **w)
            for name, r in a.rules.items():
                f = np.broadcast_to(np.asarray(r.fired, dtype=bool), (len(g),))
                fired_cols.setdefault(name, pd.Series(False, index=joined.index))
                fired_cols[name].loc[idx] = f
                detail[name] = detail.get(name, []) + [pd.DataFrame({
                    "margin": np.broadcast_to(np.asarray(r.margin, float), (len(g),)),
                    "value": np.broadcast_to(np.asarray(r.value, float), (len(g),)),
                    "limit": np.broadcast_to(np.asarray(r.limit, float), (len(g),)),
                    "unit": r.margin_unit}, index=idx)]
        for name, s in fired_cols.items():
            joined[f"fired_{name}"] = s.to_numpy()
            joined["fired_any"] |= s.to_numpy()
        details = {name: pd.concat(parts).sort_index() for name, parts in detail.items()}
        for (pid, dep), g in joined.groupby(["path_id", "departure_utc"], sort=True):
            ok = (g["status"] == "ok").to_numpy()
            hs = g["hs_m"].to_numpy(dtype=float)
            row = {"path_id": pid, "depart_utc": pd.Timestamp(dep), "n_points": len(g), "n_points_no_weather": int((~ok).sum()),
                   "adverse": bool(g["fired_any"].any()), "rules": [], "reasons": [], "max_hs_m": np.nan, "worst_time_utc": None,
                   "worst_lat_deg": np.nan, "worst_lon_deg": np.nan, "error": None}
            if np.isfinite(hs).any():
                k = int(np.nanargmax(hs))
                row.update(max_hs_m=float(hs[k]), worst_time_utc=pd.Timestamp(g["eta_utc"].iloc[k]),
                           worst_lat_deg=float(g["lat_deg"].iloc[k]), worst_lon_deg=float(g["lon_deg"].iloc[k]))
            else:
                row["error"] = (f"no weather at any of the {len(g)} centroids of this departure "
                                f"({', '.join(sorted(set(g['status'])))}); the lane lies outside the weather grid or time span")
            for name in sorted(fired_cols):
                f = g[f"fired_{name}"].to_numpy()
                if not f.any():
                    continue
                d = details[name].loc[g.index[f]]
                j = int(np.nanargmax(d["margin"].to_numpy())) if np.isfinite(d["margin"].to_numpy()).any() else 0
                at = g.loc[d.index[j]]
                row["rules"].append(name)
                row["reasons"].append({
                    "rule": name, "text": f"{name}: {_fmt_rule(name, d['value'].iloc[j], d['limit'].iloc[j], d['unit'].iloc[j])} at "
                                          f"{pd.Timestamp(at['eta_utc']):%Y-%m-%dT%H:%MZ}, {at['lat_deg']:.2f}N {at['lon_deg']:.2f}E",
                    "n_points": int(f.sum()), "seq": int(at["seq"]), "time_utc": pd.Timestamp(at["eta_utc"]).isoformat(),
                    "value": float(d["value"].iloc[j]), "limit": float(d["limit"].iloc[j]),
                })
            rows.append(row)
    out = pd.DataFrame(rows, columns=["path_id", "depart_utc", "n_points", "n_points_no_weather", "adverse", "rules", "reasons",
                                      "max_hs_m", "worst_time_utc", "worst_lat_deg", "worst_lon_deg", "error"])
    out["depart_utc"] = pd.to_datetime(out["depart_utc"], utc=True)
    return out.sort_values(["path_id", "depart_utc"], kind="stable").reset_index(drop=True)


# --- per-lane work ------------------------------------------------------------------------------


@dataclass
class LaneJob:
    """One lane's adverse departures and everything its work needs (shipped to a worker)."""

    path_id: str
    lane_id: str | None
    centroids: pd.DataFrame
    vessel: object  # thresholds.vessel.Vessel
    limits: object  # OperatorProfile
    speed_loss: str
    departures: list  # Timestamps
    weather: object  # routing.field.WeatherField
    safety: str = "hard"


def lane_jobs(night: Night, screen: pd.DataFrame) -> list[LaneJob]:
    """One job per lane with at least one adverse departure (pure)."""
    from pipelines.routing_weather import field_from_dataset

    field_ = field_from_dataset(night.weather_ds)
    adverse = screen[screen["adverse"] & screen["error"].isna()]
    jobs = []
    by_id = {p.path_id: p for p in night.paths}
    for pid, g in adverse.groupby("path_id", sort=True):
        p = by_id[pid]
        jobs.append(LaneJob(path_id=pid, lane_id=p.lane_id, centroids=p.centroids, vessel=night.vessels[p.vessel_profile],
                            limits=night.limits, speed_loss=night.params.speed_loss,
                            departures=sorted(pd.Timestamp(t) for t in g["depart_utc"]), weather=field_,
                            safety=night.params.safety))
    return jobs


def lane_speed_vessel(vessel, centroids: pd.DataFrame):
    """The vessel sailing at the lane's typical speed (median of the centroids' speeds), so the
    A* routes and the evaluations compare like with like; the profile's speed when the lane has none."""
    v = centroids["speed_kn"].to_numpy(dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    if v.size == 0:
        return vessel
    s = float(np.median(v))
    if not s > vessel.min_speed_kn:
        return vessel
    return dataclasses.replace(vessel, speed_kn=s)


def _clean_route(route, name: str | None = None):
    """A route without run-dependent properties (timings), optionally renamed."""
    from routing.route import Route

    props = {k: v for k, v in route.properties.items() if k not in VOLATILE_PROPERTIES}
    return Route(name or route.name, route.lat_deg, route.lon_deg, route.time_utc, route.leg_speed_kn, dict(route.weather), props)


def reroute_lane(job: LaneJob) -> list[dict]:
    """The work of one lane (pure): deviation, A* routes and evaluations per adverse departure.

    Returns
    -------
    list of dict
        Per departure: ``path_id``, ``depart_utc``, ``status`` (``adverse`` or ``failed``),
        ``evaluations`` (role -> RouteEvaluation), ``table`` (comparison), ``proposed`` and
        ``error``. A departure that raises is ``failed`` with ``"<Error>: message"``; the
        others still run.
    """
    from routing.astar import ShipModel
    from routing.audit import propose
    from routing.compare import lane_departure, optimality_gaps, plan_bbox, sea_checks
    from routing.deviate import threshold_inputs
    from routing.evaluate import comparison_table, evaluate_route
    from routing.planner import RouteRequest, plan_routes
    from routing.sampling import PointSampler

    out = []
    try:
        c = job.centroids.sort_values("seq")
        lat, lon, spd = c["lat_deg"].to_numpy(float), c["lon_deg"].to_numpy(float), c["speed_kn"].to_numpy(float)
        vessel = lane_speed_vessel(job.vessel, c)
        sampler = PointSampler.from_field(job.weather)
        weather_at, check, cells = threshold_inputs(sampler, vessel, job.limits)
        ship = ShipModel.from_vessel(vessel, job.speed_loss)
        start, goal = (float(lat[0]), float(lon[0])), (float(lat[-1]), float(lon[-1]))
        bbox = plan_bbox(start, goal, lat, lon, job.weather)
        fixed = sea_checks(lat, lon)[1](lat, lon)  # the lane's legs over land, repaired once for every departure
    except Exception as err:  # noqa: BLE001 - the whole lane fails, the night goes on
        log.warning("lane %s: setup failed: %s", job.path_id, err)
        return [{"path_id": job.path_id, "depart_utc": t, "status": "failed", "error": f"{type(err).__name__}: {err}"}
                for t in job.departures]
    props = {"lane_id": job.lane_id, "path_id": job.path_id, "vessel": vessel.name}
    for t in job.departures:
        try:
            req = RouteRequest(start, goal, t, ship, vessel_name=vessel.name, bbox=bbox)
            if job.safety == "none":
                plan = plan_routes(req, job.weather)
            else:
                plan = plan_routes(req, job.weather, safety=job.safety, vessel=vessel, limits=job.limits)
            routes = lane_departure(lat, lon, spd, t, plan, weather_at=weather_at, check=check, cells=cells, properties=props,
                                    fixed=fixed)
            if "safe_optimal_smoothed" in plan.routes:
                routes["safe_optimal"] = _clean_route(plan.routes["safe_optimal_smoothed"], "safe_optimal")
            routes["optimal"] = _clean_route(plan.routes["optimal_smoothed"], "optimal")
            routes["min_distance"] = _clean_route(plan.routes["min_distance"])
            evs = {role: evaluate_route(r, sampler, vessel, limits=job.limits, speed_loss_model=job.speed_loss)
                   for role, r in routes.items()}
            out.append({"path_id": job.path_id, "depart_utc": t, "status": "adverse", "evaluations": evs,
                        "table": comparison_table(evs, reference=REFERENCE), "proposed": propose(evs, reference=REFERENCE),
                        "optimality": optimality_gaps(routes, plan), "error": None})
        except Exception as err:  # noqa: BLE001 - one departure fails, the others run
            log.warning("lane %s departing %s failed: %s", job.path_id, t, err)
            out.append({"path_id": job.path_id, "depart_utc": t, "status": "failed", "error": f"{type(err).__name__}: {err}"})
    return out


# --- ranking and result rows --------------------------------------------------------------------


@dataclass
class NightResult:
    """What a night produced: the rows to store and the cases for the report, in rank order."""

    departures: pd.DataFrame
    routes: pd.DataFrame
    events: pd.DataFrame
    cases: list  # dicts (adverse/failed lane-departures) in rank order
    counts: dict


def _risk(outcome: dict) -> dict:
    """Risk avoided and cost of the proposed alternative against the lane as planned (same model)."""
    evs = outcome.get("evaluations") or {}
    hist = evs.get(REFERENCE)
    prop = outcome.get("proposed")
    if hist is None or prop is None:
        return {"risk_avoided_h": 0.0, "events_avoided": 0, "delta_time_h": None, "delta_fuel_t": None, "delta_co2_t": None}
    h, a = hist.summary, evs[prop].summary
    return {"risk_avoided_h": float(h["adverse_h"] - a["adverse_h"]), "events_avoided": int(h["n_safety_events"] - a["n_safety_events"]),
            "delta_time_h": float(a["time_h"] - h["time_h"]), "delta_fuel_t": float(a["fuel_t"] - h["fuel_t"]),
            "delta_co2_t": float(a["co2_t"] - h["co2_t"])}


def assemble(night: Night, screen: pd.DataFrame, outcomes: list[dict]) -> NightResult:
    """Merge the screen with the per-lane outcomes, rank, and build the rows to store (pure).

    Ranking: adverse lane-departures by risk avoided (hours over an operator limit or in an IMO
    situation, lane as planned minus proposed; 0 without a proposal), then IMO events avoided, then
    the cost (extra hours, then extra fuel), then lane and time; failed ones after them.
    """
    by_key = {(o["path_id"], pd.Timestamp(o["depart_utc"])): o for o in outcomes}
    paths = {p.path_id: p for p in night.paths}
    cases = []
    dep_rows, route_rows, event_rows = [], [], []
    for r in screen.to_dict("records"):
        key = (r["path_id"], pd.Timestamp(r["depart_utc"]))
        p = paths[r["path_id"]]
        o = by_key.get(key)
        status = "ok"
        if r["error"] is not None and not (isinstance(r["error"], float) and math.isnan(r["error"])):
            status, error = "failed", r["error"]
        elif r["adverse"]:
            if o is None:
                status, error = "failed", "the lane's task did not return this departure"
            else:
                status, error = o["status"], o.get("error")
        else:
            error = None
        row = {"path_id": r["path_id"], "lane_id": p.lane_id, "origin": p.origin, "destination": p.destination,
               "depart_utc": key[1], "vessel_profile": p.vessel_profile, "status": status, "rules": ",".join(r["rules"]),
               "reasons_json": json.dumps(r["reasons"]), "n_points": int(r["n_points"]),
               "n_points_no_weather": int(r["n_points_no_weather"]), "max_hs_m": r["max_hs_m"],
               "worst_time_utc": r["worst_time_utc"], "worst_lat_deg": r["worst_lat_deg"], "worst_lon_deg": r["worst_lon_deg"],
               "proposed": None, "rank": None, "risk_avoided_h": None, "events_avoided": None, "delta_time_h": None,
               "delta_fuel_t": None, "delta_co2_t": None, "error": error}
        if status == "adverse":
            row["proposed"] = o["proposed"]
            row.update(_risk(o))
        dep_rows.append(row)
        if status in ("adverse", "failed"):
            cases.append({"row": row, "reasons": r["reasons"], "outcome": o if status == "adverse" else None})

    def rank_key(case):
        row = case["row"]
        if row["status"] == "failed":
            return (1, 0.0, 0, 0.0, 0.0, row["path_id"], row["depart_utc"])
        return (0, -round(row["risk_avoided_h"], 9), -row["events_avoided"], round(row["delta_time_h"] or 0.0, 9),
                round(row["delta_fuel_t"] or 0.0, 9), row["path_id"], row["depart_utc"])

    cases.sort(key=rank_key)
    for k, case in enumerate(cases, start=1):
        case["row"]["rank"] = k
        o = case["outcome"]
        if o is None:
            continue
        for role, ev in o["evaluations"].items():
            s = ev.summary
            route_rows.append({"path_id": case["row"]["path_id"], "depart_utc": case["row"]["depart_utc"], "role": role,
                               **{c: s.get(c) for c in ("time_h", "dist_nmi", "max_hs_m", "mean_hs_m", "fuel_t", "co2_t",
                                                         "exposure_h", "adverse_h", "n_safety_events", "no_weather_h")},
                               "route_json": _clean_route(ev.route).to_json()})
            for e in ev.events:
                event_rows.append({"path_id": case["row"]["path_id"], "depart_utc": case["row"]["depart_utc"], "role": role,
                                   "criterion": e["criterion"], "kind": e["kind"], "start_utc": pd.Timestamp(e["start_utc"]),
                                   "end_utc": pd.Timestamp(e["end_utc"]), "duration_h": float(e["duration_h"]),
                                   "lat_deg": e.get("start_lat_deg"), "lon_deg": e.get("start_lon_deg"), "max_margin": e.get("max_margin")})
    from pipelines.storage.nightly import DEPARTURE_COLUMNS, EVENT_COLUMNS, ROUTE_COLUMNS

    deps = pd.DataFrame(dep_rows, columns=list(DEPARTURE_COLUMNS))
    counts = {
        "lanes_checked": len(night.paths),
        "departures_checked": len(deps),
        "adverse": int((deps["status"] == "adverse").sum()),
        "failed": int((deps["status"] == "failed").sum()),
        "reroutes": int(((deps["status"] == "adverse") & deps["proposed"].notna()).sum()),
    }
    return NightResult(deps, pd.DataFrame(route_rows, columns=list(ROUTE_COLUMNS)),
                       pd.DataFrame(event_rows, columns=list(EVENT_COLUMNS)), cases, counts)


# --- report and storage (I/O) -------------------------------------------------------------------


def _stem(path_id: str, t: pd.Timestamp) -> str:
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in str(path_id))
    return f"{safe}_{t:%Y%m%dT%H%MZ}"


def _limits_of(night: Night, vessel):
    return night.limits.limits_for(vessel.vessel_class, vessel.lpp_m) if hasattr(night.limits, "limits_for") else night.limits


def _vessel_name(night: Night, path_id: str) -> str | None:
    """The vessel profile sailing this lane (lanes of one night differ in vessel class)."""
    return next((p.vessel_profile for p in night.paths if p.path_id == path_id), None)


def _hs_limit_m(night: Night, path_id: str) -> float | None:
    """The Hs limit of the vessel sailing this lane."""
    profile = _vessel_name(night, path_id)
    if profile is None:
        return None
    return getattr(_limits_of(night, night.vessels[profile]), "hs_max_m", None)


def _most_common_vessel(night: Night):
    names = [p.vessel_profile for p in night.paths]
    name = sorted(set(names), key=lambda n: (-names.count(n), n))[0]
    return night.vessels[name]


def write_report(night: Night, result: NightResult, started_utc: pd.Timestamp) -> dict:
    """I/O step: exports per adverse lane-departure, the HTML report and its model as JSON.

    Returns ``{"report": path, "model": path, "exports": n_files}`` (paths as strings).
    """
    from dashboards.exports import export_alternatives
    from dashboards.model import NightlyReport, report_to_json
    from dashboards.report import render_nightly_report
    from pipelines.reporting import lane_departure_model, provenance, speed_loss_curve

    out = Path(night.out)
    _require_out_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    departures, n_files = [], 0
    for case in result.cases:
        row = case["row"]
        rules = [r["text"] for r in case["reasons"]] or list(filter(None, row["rules"].split(",")))
        if case["outcome"] is None:
            departures.append(lane_departure_model(lane_id=row["path_id"], origin=row["origin"], destination=row["destination"],
                                                   depart_utc=row["depart_utc"], rules=rules, error=row["error"],
                                                   vessel=_vessel_name(night, row["path_id"])))
            continue
        evs = case["outcome"]["evaluations"]
        links = export_alternatives({role: evs[role].route for role in ROLES if role in evs}, out / "exports",
                                    _stem(row["path_id"], row["depart_utc"]), relative_to=out,
                                    proposed=case["outcome"]["proposed"], only_proposed=True)
        n_files += len(links)
        departures.append(lane_departure_model(
            lane_id=row["path_id"], origin=row["origin"], destination=row["destination"], depart_utc=row["depart_utc"],
            rules=rules, evaluations=evs, table=case["outcome"]["table"], proposed=case["outcome"]["proposed"],
            weather_ds=night.weather_ds, exports=links, risk_avoided=row["risk_avoided_h"],
            hs_limit_m=_hs_limit_m(night, row["path_id"]), vessel=_vessel_name(night, row["path_id"]),
            optimality=case["outcome"].get("optimality", ())))
    vessel = _most_common_vessel(night)
    limits = _limits_of(night, vessel)
    profiles = sorted({p.vessel_profile for p in night.paths})
    prov = provenance(
        weather_meta=night.weather_meta, weather_ds=night.weather_ds, vessel=vessel, speed_loss_model=night.params.speed_loss,
        limits=limits, profile_name=getattr(night.limits, "name", ""),
        weather_source=str(night.weather_meta.get("source") or night.weather_source),
        methods=[
            f"Run id {night.run_id}: digest of the forecast time, departures, lanes, weather values, vessels, limits and model.",
            "Screen: lane centroids timed from the departure at their typical speeds; weather of the nearest grid cell at the "
            "nearest time (DuckDB ASOF join); operator limits and IMO MSC.1/Circ.1228 at every centroid with the course to the next.",
            "Like for like: every route of a case is sailed by one vessel model from the same departure in the same weather: "
            f"the lane's typical AIS speed (median of its centroids' speeds) minus the {night.params.speed_loss} speed loss, never "
            "below the profile's floor. The reference of every delta is the lane as planned (its centroid path, sailed so).",
            "Sea only: every leg of every route passes one land check (each great-circle leg against every 30\" land pixel it "
            "touches, land tolerated within 1.5 nmi of a berth); legs over land are replaced by the shortest sea path.",
            "Deviation: Spyrou-Sioula et al. 2022, Alg. 1 (R-tree nearest passing cell within 3 h), legs kept at sea, ETAs recomputed.",
            f"A*: time-optimal (smoothed) and minimum-distance routes on a mesh at the weather's spacing, {night.params.speed_loss} "
            "speed loss at the lane's typical speed"
            + ("." if night.params.safety == "none" else f"; safe time-optimal route under the vessel's limits ({night.params.safety} "
               "constraints, soft when hard finds no route)."),
            "Ranking: risk avoided (hours over a limit or in an IMO situation, lane as planned minus proposed), then IMO events "
            "avoided, then extra time and fuel.",
            f"Vessel profiles by lane (AIS ship type of the lane's voyages): {', '.join(profiles)}; the provenance lists "
            f"{vessel.name}, the most common.",
        ],
    )
    model = NightlyReport(
        run_id=night.run_id, started_utc=started_utc, finished_utc=pd.Timestamp.now(tz="UTC"), now_utc=night.now_utc,
        window_start_utc=night.departures[0], window_end_utc=night.departures[0] + pd.Timedelta(hours=night.params.window_h),
        departure_step_h=night.params.step_h, lanes_checked=result.counts["lanes_checked"],
        departures_checked=result.counts["departures_checked"], departures=departures, provenance=prov,
        speed_loss=speed_loss_curve(vessel, night.params.speed_loss), max_detail=night.params.max_detail,
    )
    report = render_nightly_report(model, out / "report.html")
    model_path = out / "report.json"
    model_path.write_text(report_to_json(model), encoding="utf-8")
    return {"report": str(report), "model": str(model_path), "exports": n_files}


def run_row(night: Night, result: NightResult, started_utc, finished_utc, report: dict | None, timings: dict) -> dict:
    """The ``nightly_runs`` row of a night."""
    ds = night.weather_ds
    times = pd.DatetimeIndex(ds["time_utc"].values).tz_localize("UTC")
    files = night.weather_meta.get("files") or night.weather_meta.get("source_files") or []
    params = night.params.model_dump()
    summary = {**result.counts, "run_id": night.run_id, "timings_s": timings, "report": (report or {}).get("report")}
    return {
        "run_id": night.run_id, "now_utc": night.now_utc, "window_start_utc": night.departures[0],
        "window_end_utc": night.departures[0] + pd.Timedelta(hours=night.params.window_h), "step_h": night.params.step_h,
        "n_departure_times": len(night.departures), "lanes_checked": result.counts["lanes_checked"],
        "departures_checked": result.counts["departures_checked"], "n_adverse": result.counts["adverse"],
        "n_failed": result.counts["failed"], "n_reroutes": result.counts["reroutes"], "weather_source": night.weather_source,
        "weather_product": str(night.weather_meta.get("product") or ds.attrs.get("product", "")),
        "weather_files": json.dumps([str(f) for f in (files if isinstance(files, (list, tuple)) else [files])]),
        "weather_start_utc": times[0], "weather_end_utc": times[-1], "weather_digest": night.weather_digest,
        "lanes_digest": night.lanes_digest, "params_json": json.dumps(params, sort_keys=True, default=str),
        "started_utc": started_utc, "finished_utc": finished_utc, "report_path": (report or {}).get("report"),
        "summary_json": json.dumps(summary, default=str),
    }


def store_night(db, night: Night, result: NightResult, run: dict) -> dict:
    """I/O step: write the night's rows (replacing the same run id) and return the row counts."""
    from pipelines.storage import open_workspace
    from pipelines.storage.nightly import count_rows, write_run

    with open_workspace(db) as ws:
        write_run(ws, run, result.departures, result.routes, result.events)
        return count_rows(ws)


def summary_of(night: Night, result: NightResult, report: dict | None, timings: dict, top: int = 10) -> dict:
    """The CLI's JSON object (``reference`` names what every delta is measured against)."""
    d = result.departures
    ranked = d[d["rank"].notna()].sort_values("rank").head(top)
    return {
        "run_id": night.run_id,
        "now_utc": night.now_utc.isoformat(),
        "window": {"start_utc": night.departures[0].isoformat(), "hours": night.params.window_h, "step_h": night.params.step_h,
                   "departures": len(night.departures)},
        **result.counts,
        "weather": {"source": night.weather_source, "product": str(night.weather_meta.get("product", "")),
                    "digest": night.weather_digest[:16]},
        "report": (report or {}).get("report"),
        "exports": (report or {}).get("exports", 0),
        "out": str(night.out),
        "timings_s": timings,
        "reference": "lane: the lane as planned, sailed by the same vessel model (the lane's typical AIS speed minus the speed "
                     "loss) from the same departure in the same weather; every delta is proposed minus it",
        "top": [{"rank": int(r["rank"]), "lane": r["path_id"], "depart_utc": r["depart_utc"].isoformat(), "status": r["status"],
                 "rules": r["rules"], "proposed": r["proposed"], "risk_avoided_h": r["risk_avoided_h"],
                 "delta_time_h": r["delta_time_h"], "error": r["error"]} for r in ranked.to_dict("records")],
    }


# --- plain entry point and the Prefect flow -----------------------------------------------------


def _collect(jobs: list[LaneJob], results: list) -> list[dict]:
    """Outcomes of the lane jobs; a job that raised marks every departure of its lane failed."""
    outcomes = []
    for job, res in zip(jobs, results):
        if isinstance(res, BaseException):
            outcomes += [{"path_id": job.path_id, "depart_utc": t, "status": "failed", "error": f"{type(res).__name__}: {res}"}
                         for t in job.departures]
        else:
            outcomes += list(res)
    return outcomes


def _future_result(future):
    """A task future's value, or an exception describing why the task did not complete."""
    future.wait()
    state = future.state
    if state.is_completed():
        return future.result()
    res = future.result(raise_on_failure=False)
    return res if isinstance(res, BaseException) else RuntimeError(f"task {state.name}: {state.message}")


def run_night(**kwargs) -> dict:
    """The night without Prefect (same steps, sequential); keyword arguments of :class:`NightlyParams`."""
    params = NightlyParams(**kwargs)
    timings: dict[str, float] = {}
    started = pd.Timestamp.now(tz="UTC")
    t = time.perf_counter()
    now = resolve_now(params.now)
    paths = load_paths(params.db, voyages=params.voyages, lanes=params.lanes, vessel=params.vessel)
    source = choose_weather_source(params)
    deps = departure_times(now, params.window_h, params.step_h)
    files = list(params.weather)
    if source == "fetch":
        files = [f for req in fetch_requests(paths, deps) for f in fetch_weather(req, params.cache_dir)]
    t0, t1 = weather_span_needed(paths, deps)
    ds, meta = read_weather_source(source, files, params.db, t0, t1)
    night = prepare_night(params, now, paths, ds, meta, source)
    timings["inputs_s"] = time.perf_counter() - t
    t = time.perf_counter()
    screen = screen_departures(night)
    timings["screen_s"] = time.perf_counter() - t
    t = time.perf_counter()
    jobs = lane_jobs(night, screen)
    results = []
    for job in jobs:
        try:
            results.append(reroute_lane(job))
        except Exception as err:  # noqa: BLE001
            results.append(err)
    outcomes = _collect(jobs, results)
    timings["reroute_s"] = time.perf_counter() - t
    return _finish(night, screen, outcomes, started, timings)


def _finish(night: Night, screen, outcomes, started, timings) -> dict:
    t = time.perf_counter()
    result = assemble(night, screen, outcomes)
    timings["rank_s"] = time.perf_counter() - t
    report = None
    if night.params.report:
        t = time.perf_counter()
        report = write_report(night, result, started)
        timings["report_s"] = time.perf_counter() - t
    t = time.perf_counter()
    store_night(night.params.db, night, result, run_row(night, result, started, pd.Timestamp.now(tz="UTC"), report, timings))
    timings["store_s"] = time.perf_counter() - t
    return summary_of(night, result, report, {k: round(v, 3) for k, v in timings.items()})


#: Callbacks ``(done, total)`` told as each lane's reroute completes (the CLI's progress bar).
_PROGRESS_CALLBACKS: list = []


@contextlib.contextmanager
def reroute_progress(callback):
    """Call ``callback(done, total)`` as the lanes of a night finish (in submission order)."""
    _PROGRESS_CALLBACKS.append(callback)
    try:
        yield
    finally:
        _PROGRESS_CALLBACKS.remove(callback)


def _results_with_progress(futures: list) -> list:
    results = []
    for cb in _PROGRESS_CALLBACKS:
        cb(0, len(futures))
    for f in futures:
        results.append(_future_result(f))
        for cb in _PROGRESS_CALLBACKS:
            cb(len(results), len(futures))
    return results


def demo_step(ctx) -> dict:
    """Demo step: tonight's reroute at the end of the scenario's AIS period (``--now``), with the
    scenario's forecast weather files (else the workspace's weather), report in ``DIR/nightly``."""
    import json as _json

    from pipelines.storage import open_workspace
    from pipelines.storage.lanes import read_lanes

    truth = _json.loads(ctx.scenario_json.read_text(encoding="utf-8"))
    now = pd.Timestamp(truth["scenario"]["end_utc"])
    files = [str(ctx.workdir / f) for f in truth.get("weather", {}).get("files", [])]
    with open_workspace(ctx.db) as ws:
        n_lanes = len(read_lanes(ws))
    if n_lanes == 0:
        ctx.echo("  no lanes in the workspace (too few days of AIS?): no nightly run")
        return {"skipped": "no lanes"}
    out = _flow()(db=str(ctx.db), out=str(ctx.workdir / "nightly"), weather=files, now=now.isoformat(), max_detail=10)
    ctx.echo(f"  night {out['run_id']} at {out['now_utc']}: {out['lanes_checked']} lanes x {out['window']['departures']} "
             f"departures = {out['departures_checked']} lane-departures; {out['adverse']} adverse, {out['reroutes']} with a "
             f"proposed reroute, {out['failed']} failed")
    for row in out["top"][:5]:
        ctx.echo(f"  {row['rank']:>3}. lane {row['lane']:<8} {row['depart_utc'][:16]}Z  {row['rules']} -> {row['proposed']} "
                 f"({row['risk_avoided_h'] or 0:.1f} h at risk avoided, {row['delta_time_h'] or 0:+.1f} h)")
    t = out["timings_s"]
    ctx.echo("  stages: " + ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in t.items()))
    return out


def demo_report_step(ctx) -> dict:
    """Demo step: where the night's report and exports are."""
    night = ctx.results.get("nightly") or {}
    if not night.get("report"):
        ctx.echo("  no nightly report")
        return {"skipped": "no nightly report"}
    ctx.echo(f"  {night['exports']} export files in {Path(night['out']) / 'exports'}; model {Path(night['out']) / 'report.json'}")
    ctx.echo(f"  nightly report: {night['report']}")
    return {"report": night["report"], "out": night["out"]}


def _retry_fetch(task_, task_run, state) -> bool:
    """Downloads retry on network and service failures (the clients' own bounded attempts ran
    out: ``FetchError("... download failed after N attempts ...")``), not on missing credentials
    or an unknown product."""
    try:
        state.result()
    except StormlaneError as err:
        return "download failed" in str(err)
    except Exception:  # noqa: BLE001
        return True
    return False


@functools.lru_cache(maxsize=1)
def _flow():
    """Build the Prefect flow lazily (importing Prefect costs seconds; the CLI must stay fast)."""
    from prefect import flow, task
    from prefect.cache_policies import NO_CACHE

    io = {"retries": len(IO_RETRY_DELAYS_S), "retry_delay_seconds": list(IO_RETRY_DELAYS_S), "cache_policy": NO_CACHE,
          "retry_condition_fn": _retry_transient}
    load_task = task(load_paths, name="nightly-load-lanes", **io)
    fetch_task = task(fetch_weather, name="nightly-fetch-weather", retries=len(FETCH_RETRY_DELAYS_S),
                      retry_delay_seconds=list(FETCH_RETRY_DELAYS_S), cache_policy=NO_CACHE, retry_condition_fn=_retry_fetch)
    read_task = task(read_weather_source, name="nightly-read-weather", **io)
    prepare_task = task(prepare_night, name="nightly-prepare", cache_policy=NO_CACHE)
    screen_task = task(screen_departures, name="nightly-screen", cache_policy=NO_CACHE)
    lane_task = task(reroute_lane, name="nightly-reroute-lane", cache_policy=NO_CACHE, task_run_name="reroute-{job.path_id}")
    finish_task = task(_finish, name="nightly-rank-report-store", cache_policy=NO_CACHE)

    @flow(name="nightly-reroute", log_prints=False)
    def nightly_reroute(db: str = DEFAULT_DB, out: str | None = None, out_root: str | None = None, weather: list[str] | None = None,
                        weather_source: str = "auto", now: str | None = None, window_h: float = DEFAULT_WINDOW_H,
                        step_h: float = DEFAULT_STEP_H, voyages: str | None = None, lanes: list[str] | None = None,
                        vessel: str | None = None, profile: str | None = None, speed_loss: str = "bowditch",
                        safety: str = "hard", max_detail: int = 20, report: bool = True, cache_dir: str | None = None) -> dict:
        """Screen every lane x departure of the forecast window, reroute the adverse ones, rank, store, report."""
        p = NightlyParams(db=db, out=out, out_root=out_root, weather=weather or [], weather_source=weather_source, now=now, window_h=window_h,
                          step_h=step_h, voyages=voyages, lanes=lanes, vessel=vessel, profile=profile, speed_loss=speed_loss,
                          safety=safety, max_detail=max_detail, report=report, cache_dir=cache_dir)
        started, timings, t = pd.Timestamp.now(tz="UTC"), {}, time.perf_counter()
        the_now, source = resolve_now(p.now), choose_weather_source(p)
        paths = load_task(p.db, voyages=p.voyages, lanes=p.lanes, vessel=p.vessel)
        deps = departure_times(the_now, p.window_h, p.step_h)
        files = [f for req in fetch_requests(paths, deps) for f in fetch_task(req, p.cache_dir)] if source == "fetch" else p.weather
        ds, meta = read_task(source, files, p.db, *weather_span_needed(paths, deps))
        night = prepare_task(p, the_now, paths, ds, meta, source)
        timings["inputs_s"], t = time.perf_counter() - t, time.perf_counter()
        screen = screen_task(night)
        timings["screen_s"], t = time.perf_counter() - t, time.perf_counter()
        jobs = lane_jobs(night, screen)
        futures = [lane_task.submit(job) for job in jobs]
        outcomes = _collect(jobs, _results_with_progress(futures))
        timings["reroute_s"] = time.perf_counter() - t
        return finish_task(night, screen, outcomes, started, timings)

    return nightly_reroute


def flow_with_runner(task_runner: str | None = None):
    """The flow with the chosen task runner (:func:`make_task_runner`)."""
    return _flow().with_options(task_runner=make_task_runner(task_runner))


def __getattr__(name: str):
    if name == "nightly_reroute":
        return _flow()
    raise AttributeError(name)


if __name__ == "__main__":
    import sys

    print(json.dumps(_flow()(db=sys.argv[1] if len(sys.argv) > 1 else DEFAULT_DB), indent=2, default=str))
