"""Write the demo scenario into a folder: ``ais/`` files, the writers' extras, ``scenario.json``.

The generator itself is pure (:mod:`scenario.generator`); this module reads its configuration
(``data/scenario.toml`` and ``data/ports.csv``), runs it, and calls the writers in
:data:`SCENARIO_WRITERS` in order. Each writer gets a :class:`ScenarioContext` and returns a
dict merged into ``scenario.json`` at the top level (new keys only). **Extension hook**: another
component adds its files by appending ``("name", writer)`` to :data:`SCENARIO_WRITERS` (the
weather helper adds the storm weather files under ``DIR/weather/`` this way).

``scenario.json`` (all times ISO 8601 UTC, distances nmi, speeds kn) holds:

* ``scenario``: seed, period, bbox, cadences and noise settings;
* ``ports``, ``routes`` (waypoints approach to approach), ``services`` (rotation, legs, vessels);
* ``vessels`` (static data and particulars), ``voyages`` (every voyage sailed: origin, dest,
  route, depart/arrive times at the berth, sea start/end at the approach points, distance,
  speed, lateral offset, anchorage wait, ``complete``), ``port_stays``, ``gaps``;
* ``ais``: the files written, with per-file rows, clean positions and dirty rows by kind;
* ``dirty_rows``: counts by kind and by format, the ingest reason each kind must produce
  (``expected_reason``), and every injected row with its file and 1-based line;
* ``expected_ingest``: the number of position rows a correct ingest loads (clean fixes,
  ``sentinel_fields`` rows included) and rejects.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from scenario.generator import (
    DEFAULT_DAYS,
    DEFAULT_START_UTC,
    DIRTY_KINDS,
    Scenario,
    ScenarioConfigError,
    ScenarioSettings,
    ScenarioSpec,
    generate_scenario,
    parse_scenario_spec,
)
from pipelines.config import data_dir
from thresholds.geodesy import path_length_nmi

#: The demo region (COMMON.md): lon -1.5..11.5, lat 35.5..45.0.
DEMO_BBOX = {"lon_min_deg": -1.5, "lon_max_deg": 11.5, "lat_min_deg": 35.5, "lat_max_deg": 45.0}

#: Reason code the ingest gives each injected kind (``ais.clean`` reason codes); for
#: ``duplicate_exact`` the CSV code first, NMEA second (a repeated sentence is a payload repeat).
EXPECTED_REASON = {
    "sentinel_position": "no_position",
    "out_of_range": "bad_lat|bad_lon",
    "invalid_mmsi": "bad_mmsi",
    "bad_timestamp": "bad_time",
    "speed_jump": "speed_jump",
    "duplicate_exact": "duplicate|duplicate_payload",
    "duplicate_timestamp": "duplicate_time",
    "malformed_row": "bad_line",
    "bad_checksum": "bad_checksum",
    "sentinel_fields": "loaded (SOG/COG/heading NULL)",
}

#: File patterns the AIS writer owns under ``DIR/ais`` (removed before a new run).
AIS_PATTERNS = ("aisdk-*.csv", "aisdk-*.csv.gz", "nmea-*.nmea", "nmea-*.nmea.gz")


@dataclass
class ScenarioContext:
    """What a scenario writer gets: the output folder, the generated scenario, the truth so far."""

    out_dir: Path
    scenario: Scenario
    truth: dict
    gzip: bool = False
    options: dict = field(default_factory=dict)
    weather: object = None  # the generated weather the fleet sailed through (weather.scenario.ScenarioWeather)


ScenarioWriter = Callable[[ScenarioContext], "dict | None"]


def iso(seconds) -> str | None:
    """Unix seconds to ``YYYY-MM-DDTHH:MM:SSZ`` (None for NaN)."""
    if seconds is None or (isinstance(seconds, float) and not np.isfinite(seconds)):
        return None
    return pd.Timestamp(int(round(float(seconds))), unit="s").strftime("%Y-%m-%dT%H:%M:%SZ")


def load_scenario_spec(config: Path | None = None, ports: Path | None = None) -> ScenarioSpec:
    """Read and validate ``data/scenario.toml`` and ``data/ports.csv`` (or the given files)."""
    config = Path(config) if config else data_dir() / "scenario.toml"
    ports = Path(ports) if ports else data_dir() / "ports.csv"
    for path in (config, ports):
        if not path.is_file():
            raise ScenarioConfigError(f"scenario configuration file not found: {path}")
    try:
        doc = tomllib.loads(config.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise ScenarioConfigError(f"{config}: {err}") from None
    return parse_scenario_spec(doc, pd.read_csv(ports), source=str(config))


def _records(df: pd.DataFrame, time_cols=(), round_cols=None) -> list[dict]:
    out = df.copy()
    for c in time_cols:
        out[c] = [iso(x) for x in out[c]]
    for c, nd in (round_cols or {}).items():
        out[c] = out[c].astype(float).round(nd)
    recs = out.to_dict("records")
    for r in recs:
        for k, v in r.items():
            if isinstance(v, (np.integer,)):
                r[k] = int(v)
            elif isinstance(v, (np.floating, float)):
                r[k] = None if not np.isfinite(v) else float(v)
            elif isinstance(v, np.bool_):
                r[k] = bool(v)
    return recs


def describe_setup(st: ScenarioSettings, spec: ScenarioSpec, vessels: pd.DataFrame) -> dict:
    """The JSON-ready settings, ports, routes, services and vessels of a scenario."""
    settings = {k: v for k, v in asdict(st).items() if k not in ("start_utc", "dirty_rates")}
    settings["dirty_rates"] = dict(st.dirty_rates)
    routes = []
    for (o, d), wp in spec.routes.items():
        routes.append({"route_id": f"{o}-{d}", "origin": o, "dest": d,
                       "waypoints": [[round(float(a), 5), round(float(b), 5)] for a, b in wp],
                       "dist_nmi": round(path_length_nmi(wp[:, 0], wp[:, 1]), 2)})
    services = []
    for svc in spec.services.values():
        legs = [{"origin": o, "dest": d, "route_id": spec.route(o, d)[0],
                 "reversed": (o, d) not in spec.routes} for o, d in svc.legs()]
        services.append({"id": svc.id, "name": svc.name, "vessel_class": svc.vessel_class,
                         "rotation": list(svc.rotation), "legs": legs,
                         "departure_hours_utc": list(svc.departure_hours_utc), "stay_h": list(svc.stay_h),
                         "vessels": [int(m) for m in vessels.loc[vessels.service == svc.id, "mmsi"]]})
    ports = [{"locode": p.locode, "name": p.name, "lat_deg": p.lat_deg, "lon_deg": p.lon_deg,
              "approach_lat_deg": p.approach_lat_deg, "approach_lon_deg": p.approach_lon_deg}
             for p in spec.ports.values()]
    return {
        "scenario": {
            "generator": "stormlane scenario",
            "seed": st.seed,
            "start_utc": iso(st.start_s),
            "end_utc": iso(st.end_s),
            "days": st.days,
            "bbox": DEMO_BBOX,
            "settings": settings,
        },
        "ports": ports,
        "routes": routes,
        "services": services,
        "vessels": _records(vessels),
    }


def describe(scenario: Scenario) -> dict:
    """The JSON-ready ground truth of a scenario (everything except the files written)."""
    voyages = scenario.voyages.rename(columns={"depart_s": "depart_utc", "arrive_s": "arrive_utc",
                                               "sea_start_s": "sea_start_utc", "sea_end_s": "sea_end_utc"})
    n_fix = scenario.fixes.groupby("voyage_id").received.agg(["size", "sum"])
    voyages["n_fixes"] = voyages.voyage_id.map(n_fix["size"]).fillna(0).astype(int)
    voyages["n_fixes_received"] = voyages.voyage_id.map(n_fix["sum"]).fillna(0).astype(int)
    stays = scenario.port_stays.rename(columns={"arrive_s": "arrive_utc", "depart_s": "depart_utc"})
    gaps = scenario.gaps.rename(columns={"start_s": "start_utc", "end_s": "end_utc"})
    return {
        **describe_setup(scenario.settings, scenario.spec, scenario.vessels),
        "voyages": _records(voyages, ("depart_utc", "arrive_utc", "sea_start_utc", "sea_end_utc"),
                            {"dist_nmi": 2, "sea_dist_nmi": 2, "speed_kn": 2, "lateral_offset_nmi": 3,
                             "anchorage_wait_h": 2, "anchorage_lat_deg": 5, "anchorage_lon_deg": 5}),
        "port_stays": _records(stays, ("arrive_utc", "depart_utc"), {"lat_deg": 6, "lon_deg": 6}),
        "gaps": _records(gaps, ("start_utc", "end_utc")),
    }


def file_entries(recs: pd.DataFrame) -> list[dict]:
    """Per written file (``recs["file"]``): its format, records, position records, static
    messages, clean positions and dirty rows by kind. A ``rows`` column, when present, says how
    many records each row of ``recs`` stands for (rows of equal format, message type and dirty
    kind counted beforehand, as the fleet generator does); without it each row is one record."""
    files = []
    for name, g in recs.groupby("file", sort=True):
        rows = g["rows"] if "rows" in g else pd.Series(1, index=g.index)
        kind = g["dirty_kind"]
        pos = g["msg_type"] != 5
        dirty = pos & (kind != "")
        files.append({
            "file": name,
            "format": g["fmt"].iloc[0],
            "records": int(rows.sum()),
            "position_records": int(rows[pos].sum()),
            "static_messages": int(rows[~pos].sum()),
            "clean_positions": int(rows[pos & ((kind == "") | (kind == "sentinel_fields"))].sum()),
            "dirty": {k: int(n) for k, n in rows[dirty].groupby(kind[dirty]).sum().sort_index().items()},
        })
    return files


def write_ais(ctx: ScenarioContext) -> dict:
    """Scenario writer: DMA CSV and NMEA files under ``DIR/ais`` plus the dirty-row truth."""
    from scenario.writers import write_dma_csv, write_nmea

    sc = ctx.scenario
    ais_dir = ctx.out_dir / "ais"
    ais_dir.mkdir(parents=True, exist_ok=True)
    for pattern in AIS_PATTERNS:
        for old in ais_dir.glob(pattern):
            old.unlink()
    loc = pd.concat([write_dma_csv(sc.records, sc.vessels, ais_dir, gzip=ctx.gzip),
                     write_nmea(sc.records, sc.vessels, ais_dir, gzip=ctx.gzip)])
    recs = sc.records.join(loc, how="inner")
    recs["file"] = "ais/" + recs["file"]
    is_pos = recs["msg_type"] != 5
    kind = recs["dirty_kind"]
    rejected = is_pos & (kind != "") & (kind != "sentinel_fields")
    files = file_entries(recs)
    dirty = recs[kind != ""]
    rows = [{"kind": r.dirty_kind, "format": r.fmt, "file": r.file, "line": int(r.line), "mmsi": int(r.mmsi),
             "time_utc": iso(r.time_s), "detail": r.dirty_detail}
            for r in dirty.sort_values(["file", "line"]).itertuples(index=False)]
    counts = {k: int((dirty["dirty_kind"] == k).sum()) for k in DIRTY_KINDS}
    by_format = {fmt: {k: int(((dirty["dirty_kind"] == k) & (dirty["fmt"] == fmt)).sum()) for k in DIRTY_KINDS}
                 for fmt in ("dma_csv", "nmea")}
    return {
        "ais": {
            "folder": "ais",
            "files": files,
            "formats": {
                "dma_csv": "Danish Maritime Authority CSV export, one file per UTC day, header line 1",
                "nmea": "!AIVDM sentences with NMEA 4.0 tag blocks (s: source, c: UNIX time, g: multipart group)",
            },
        },
        "dirty_rows": {
            "counts": counts,
            "by_format": by_format,
            "expected_reason": EXPECTED_REASON,
            "rows": rows,
        },
        "expected_ingest": {
            "position_records": int(is_pos.sum()),
            "loaded": int((is_pos & ~rejected).sum()),
            "rejected": int(rejected.sum()),
            "static_messages": int((~is_pos).sum()),
            "vessels": int(sc.vessels.shape[0]),
        },
    }


def write_weather(ctx: ScenarioContext) -> dict:
    """Storm weather under ``DIR/weather/`` (CMEMS + ERA5 schemas), see :mod:`pipelines.weather`."""
    from pipelines.weather import write_scenario_weather_files

    return write_scenario_weather_files(ctx)


#: Writers run in order by :func:`build_scenario`; append ``(name, writer)`` to add files.
SCENARIO_WRITERS: list[tuple[str, ScenarioWriter]] = [("ais", write_ais), ("weather", write_weather)]


def make_out_dir(path, option: str = "--out") -> Path:
    """Create the output folder ``path`` (and its parents); a path that is a file, or a folder
    that cannot be created, is a :class:`ScenarioConfigError` naming it."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ScenarioConfigError(f"{option} {path}: exists and is not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ScenarioConfigError(f"{option} {path}: cannot create the folder ({err.strerror or err})") from None
    return path


def checked_seed_start(seed, start) -> pd.Timestamp:
    """The scenario's start time (default :data:`DEFAULT_START_UTC`) after checking the seed is a
    non-negative integer and the start an ISO 8601 time; else a :class:`ScenarioConfigError`
    naming the option."""
    from pipelines.times import utc_or_none

    if int(seed) < 0:
        raise ScenarioConfigError(f"--seed {seed}: the seed must be a non-negative integer")
    start_ts = utc_or_none(start) if start is not None else DEFAULT_START_UTC
    if start_ts is None:
        raise ScenarioConfigError(f"--start {start!r} is not an ISO 8601 time")
    return start_ts


#: Along-track speed wander of a ship sailing through the weather (sd, share of its speed).
SEAWAY_ALONG_TRACK_SD_FRAC = 0.003


def build_scenario(out_dir: Path, *, seed: int = 0, start: str | pd.Timestamp | None = None,
                   days: float = DEFAULT_DAYS, gzip: bool = False, config: Path | None = None,
                   ports: Path | None = None, writers: list[tuple[str, ScenarioWriter]] | None = None,
                   **settings) -> dict:
    """Generate the scenario into ``out_dir`` and return the ``scenario.json`` content.

    Parameters
    ----------
    out_dir : Path
        Folder to write into (created); files of earlier runs with the same names are replaced.
    seed, start, days : int, ISO string or Timestamp, float
        Seed and period (default 2025-01-01T00:00Z for 30 days).
    gzip : bool
        Write ``.csv.gz`` / ``.nmea.gz`` instead of plain text.
    writers : list, optional
        Writers to run (default :data:`SCENARIO_WRITERS`).
    **settings
        Further :class:`scenario.generator.ScenarioSettings` fields.
    """
    start_ts = checked_seed_start(seed, start)
    out_dir = make_out_dir(out_dir)
    spec = load_scenario_spec(config, ports)
    # Sailing through the weather, the weather moves the speed: the slow along-track wander that
    # stands in for it in calm-water scenarios (ScenarioSettings' default) shrinks to trim and engine.
    settings = {"along_track_speed_sd_frac": SEAWAY_ALONG_TRACK_SD_FRAC, **settings}
    st = ScenarioSettings(seed=int(seed), start_utc=start_ts, days=float(days), **settings)
    from pipelines.weather import scenario_weather
    from scenario.performance_law import describe as describe_law

    weather = scenario_weather(st.seed, iso(st.start_s), iso(st.end_s))
    scenario = generate_scenario(spec, st, seaway=weather.sampler())
    truth = describe(scenario)
    truth["performance"] = describe_law()
    ctx = ScenarioContext(out_dir=out_dir, scenario=scenario, truth=truth, gzip=gzip, weather=weather)
    for name, writer in (SCENARIO_WRITERS if writers is None else writers):
        extra = writer(ctx) or {}
        clash = set(extra) & set(truth)
        if clash:
            raise RuntimeError(f"scenario writer {name!r} would overwrite {sorted(clash)} in scenario.json")
        truth.update(extra)
    truth.setdefault("writers", [name for name, _ in (SCENARIO_WRITERS if writers is None else writers)])
    (out_dir / "scenario.json").write_text(json.dumps(truth, indent=1, sort_keys=False) + "\n", encoding="utf-8")
    return truth


def summary_lines(truth: dict) -> list[str]:
    """A few human lines about a written scenario."""
    sc = truth["scenario"]
    lines = [
        f"scenario seed {sc['seed']}: {sc['start_utc']} -> {sc['end_utc']}, {len(truth['vessels'])} vessels, "
        f"{len(truth['services'])} services, {len(truth['voyages'])} voyages "
        f"({sum(v['complete'] for v in truth['voyages'])} complete)",
    ]
    if "ais" in truth:
        files = truth["ais"]["files"]
        n_csv = sum(f["format"] == "dma_csv" for f in files)
        n_nmea = sum(f["format"] == "nmea" for f in files)
        exp = truth["expected_ingest"]
        lines.append(f"  ais: {n_csv} DMA CSV + {n_nmea} NMEA files, {exp['position_records']:,} position rows "
                     f"({exp['loaded']:,} clean, {exp['rejected']:,} dirty), {exp['static_messages']:,} static messages")
        counts = ", ".join(f"{k} {n}" for k, n in truth["dirty_rows"]["counts"].items() if n)
        lines.append(f"  dirty rows: {counts}")
    for key in truth.get("writers", []):
        if key not in ("ais",) and isinstance(truth.get(key), dict) and "summary" in truth[key]:
            lines.append(f"  {key}: {truth[key]['summary']}")
    return lines
