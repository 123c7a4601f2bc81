"""Tables of the nightly reroute run, keyed by run id (every night stays auditable).

``nightly_runs``
    One row per run: forecast reference time (``now_utc``), departure window, weather source and
    digest, lanes digest, parameters, counts, wall-clock start/end, report path.
``nightly_departures``
    One row per lane-departure checked (adverse or not): the vessel profile, the screen's verdict
    (``ok``, ``adverse``, ``failed``) with the rules that fired and why, the worst point, the
    proposed alternative, its rank and the deltas (proposed minus the lane as planned, sailed by the
    same vessel model).
``nightly_routes``
    One row per route of an adverse lane-departure (``lane``, ``deviation``, ``safe_optimal``,
    ``optimal``, ``min_distance``; ``historical`` in runs stored before the like-for-like comparison): headline numbers of its evaluation and the route as JSON
    (:meth:`routing.route.Route.to_json`).
``nightly_events``
    The IMO and operator-limit events found on each of those routes.

:func:`write_run` replaces a run as a whole in one transaction: a rerun with the same run id
(same inputs) leaves exactly the same rows, never duplicates.
"""

from __future__ import annotations

import json
import math

import pandas as pd

COMPONENT = "nightly"

MIGRATIONS = [
    [
        """CREATE TABLE nightly_runs (
            run_id               VARCHAR PRIMARY KEY,
            now_utc              TIMESTAMPTZ NOT NULL,
            window_start_utc     TIMESTAMPTZ NOT NULL,
            window_end_utc       TIMESTAMPTZ NOT NULL,
            step_h               DOUBLE NOT NULL,
            n_departure_times    INTEGER NOT NULL,
            lanes_checked        INTEGER NOT NULL,
            departures_checked   INTEGER NOT NULL,
            n_adverse            INTEGER NOT NULL,
            n_failed             INTEGER NOT NULL,
            n_reroutes           INTEGER NOT NULL,
            weather_source       VARCHAR NOT NULL,
            weather_product      VARCHAR,
            weather_files        VARCHAR,
            weather_start_utc    TIMESTAMPTZ,
            weather_end_utc      TIMESTAMPTZ,
            weather_digest       VARCHAR NOT NULL,
            lanes_digest         VARCHAR NOT NULL,
            params_json          VARCHAR NOT NULL,
            started_utc          TIMESTAMPTZ NOT NULL,
            finished_utc         TIMESTAMPTZ NOT NULL,
            report_path          VARCHAR,
            summary_json         VARCHAR NOT NULL
        )""",
        """CREATE TABLE nightly_departures (
            run_id               VARCHAR NOT NULL,
            path_id              VARCHAR NOT NULL,
            lane_id              VARCHAR,
            origin               VARCHAR,
            destination          VARCHAR,
            depart_utc           TIMESTAMPTZ NOT NULL,
            vessel_profile       VARCHAR,
            status               VARCHAR NOT NULL,
            rules                VARCHAR NOT NULL,
            reasons_json         VARCHAR NOT NULL,
            n_points             INTEGER NOT NULL,
            n_points_no_weather  INTEGER NOT NULL,
            max_hs_m             DOUBLE,
            worst_time_utc       TIMESTAMPTZ,
            worst_lat_deg        DOUBLE,
            worst_lon_deg        DOUBLE,
            proposed             VARCHAR,
            rank                 INTEGER,
            risk_avoided_h       DOUBLE,
            events_avoided       INTEGER,
            delta_time_h         DOUBLE,
            delta_fuel_t         DOUBLE,
            delta_co2_t          DOUBLE,
            error                VARCHAR,
            PRIMARY KEY (run_id, path_id, depart_utc)
        )""",
        """CREATE TABLE nightly_routes (
            run_id           VARCHAR NOT NULL,
            path_id          VARCHAR NOT NULL,
            depart_utc       TIMESTAMPTZ NOT NULL,
            role             VARCHAR NOT NULL,
            time_h           DOUBLE,
            dist_nmi         DOUBLE,
            max_hs_m         DOUBLE,
            mean_hs_m        DOUBLE,
            fuel_t           DOUBLE,
            co2_t            DOUBLE,
            exposure_h       DOUBLE,
            adverse_h        DOUBLE,
            n_safety_events  INTEGER,
            no_weather_h     DOUBLE,
            route_json       VARCHAR NOT NULL,
            PRIMARY KEY (run_id, path_id, depart_utc, role)
        )""",
        """CREATE TABLE nightly_events (
            run_id      VARCHAR NOT NULL,
            path_id     VARCHAR NOT NULL,
            depart_utc  TIMESTAMPTZ NOT NULL,
            role        VARCHAR NOT NULL,
            criterion   VARCHAR NOT NULL,
            kind        VARCHAR NOT NULL,
            start_utc   TIMESTAMPTZ NOT NULL,
            end_utc     TIMESTAMPTZ NOT NULL,
            duration_h  DOUBLE NOT NULL,
            lat_deg     DOUBLE,
            lon_deg     DOUBLE,
            max_margin  DOUBLE
        )""",
    ],
    # Planned voyages (--voyages) have departures of their own, no step (issue 23 review).
    ["ALTER TABLE nightly_runs ALTER COLUMN step_h DROP NOT NULL"],
]

TABLES = ("nightly_events", "nightly_routes", "nightly_departures", "nightly_runs")

RUN_COLUMNS = (
    "run_id", "now_utc", "window_start_utc", "window_end_utc", "step_h", "n_departure_times", "lanes_checked",
    "departures_checked", "n_adverse", "n_failed", "n_reroutes", "weather_source", "weather_product", "weather_files",
    "weather_start_utc", "weather_end_utc", "weather_digest", "lanes_digest", "params_json", "started_utc",
    "finished_utc", "report_path", "summary_json",
)
DEPARTURE_COLUMNS = (
    "path_id", "lane_id", "origin", "destination", "depart_utc", "vessel_profile", "status", "rules", "reasons_json",
    "n_points", "n_points_no_weather", "max_hs_m", "worst_time_utc", "worst_lat_deg", "worst_lon_deg", "proposed",
    "rank", "risk_avoided_h", "events_avoided", "delta_time_h", "delta_fuel_t", "delta_co2_t", "error",
)
ROUTE_COLUMNS = ("path_id", "depart_utc", "role", "time_h", "dist_nmi", "max_hs_m", "mean_hs_m", "fuel_t", "co2_t",
                 "exposure_h", "adverse_h", "n_safety_events", "no_weather_h", "route_json")
EVENT_COLUMNS = ("path_id", "depart_utc", "role", "criterion", "kind", "start_utc", "end_utc", "duration_h", "lat_deg",
                 "lon_deg", "max_margin")


def _value(x):
    """A Python value DuckDB binds: NaN/NA -> NULL, numpy scalars -> Python, times -> UTC Timestamps."""
    if x is None or x is pd.NaT:
        return None
    if isinstance(x, (list, tuple, dict)):
        return json.dumps(x)
    if hasattr(x, "item") and not isinstance(x, (str, bytes, pd.Timestamp)):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    try:
        if pd.isna(x):
            return None
    except (TypeError, ValueError):
        pass
    return x


def _frame(rows, columns) -> pd.DataFrame:
    df = pd.DataFrame(list(rows), columns=list(columns))
    return df


def _insert(con, table: str, run_id: str, frame: pd.DataFrame, columns) -> None:
    if frame.empty:
        return
    cols = ", ".join(["run_id", *columns])
    marks = ", ".join("?" * (len(columns) + 1))
    rows = [[run_id, *(_value(v) for v in rec)] for rec in frame[list(columns)].itertuples(index=False, name=None)]
    con.executemany(f'INSERT INTO "{table}" ({cols}) VALUES ({marks})', rows)


def write_run(ws, run: dict, departures: pd.DataFrame, routes: pd.DataFrame, events: pd.DataFrame) -> None:
    """Store one run (replacing every row of the same ``run_id``) in one transaction.

    Parameters
    ----------
    run : dict
        The ``nightly_runs`` row (keys of :data:`RUN_COLUMNS`).
    departures, routes, events : DataFrame
        Rows of ``nightly_departures`` / ``nightly_routes`` / ``nightly_events`` without
        ``run_id`` (columns :data:`DEPARTURE_COLUMNS`, :data:`ROUTE_COLUMNS`, :data:`EVENT_COLUMNS`).
    """
    run_id = str(run["run_id"])
    missing = [c for c in RUN_COLUMNS if c not in run]
    if missing:
        raise KeyError(f"nightly run row lacks {missing}")
    with ws.transaction() as con:
        for table in TABLES:
            con.execute(f'DELETE FROM "{table}" WHERE run_id = ?', [run_id])
        con.execute(
            f"INSERT INTO nightly_runs ({', '.join(RUN_COLUMNS)}) VALUES ({', '.join('?' * len(RUN_COLUMNS))})",
            [_value(run[c]) for c in RUN_COLUMNS],
        )
        _insert(con, "nightly_departures", run_id, departures, DEPARTURE_COLUMNS)
        _insert(con, "nightly_routes", run_id, routes, ROUTE_COLUMNS)
        _insert(con, "nightly_events", run_id, events, EVENT_COLUMNS)


def _utc(df: pd.DataFrame) -> pd.DataFrame:
    for c in df.columns:
        if c.endswith("_utc") and len(df):
            df[c] = pd.to_datetime(df[c], utc=True)
    return df


def read_runs(ws) -> pd.DataFrame:
    """Every stored run, newest forecast time first."""
    return _utc(ws.con.execute("SELECT * FROM nightly_runs ORDER BY now_utc DESC, run_id").df())


def read_run(ws, run_id: str | None = None) -> dict | None:
    """One run's row (default: the one that finished last); None when there is none."""
    if run_id is None:
        df = ws.con.execute("SELECT * FROM nightly_runs ORDER BY finished_utc DESC LIMIT 1").df()
    else:
        df = ws.con.execute("SELECT * FROM nightly_runs WHERE run_id = ?", [str(run_id)]).df()
    if df.empty:
        return None
    return _utc(df).iloc[0].to_dict()


def read_departures(ws, run_id: str, status: str | None = None) -> pd.DataFrame:
    """The lane-departures of a run (optionally one status), in rank order, then lane and time."""
    sql = "SELECT * EXCLUDE (run_id) FROM nightly_departures WHERE run_id = ?"
    params = [str(run_id)]
    if status is not None:
        sql += " AND status = ?"
        params.append(status)
    return _utc(ws.con.execute(sql + " ORDER BY rank NULLS LAST, path_id, depart_utc", params).df())


def read_routes(ws, run_id: str, with_json: bool = False) -> pd.DataFrame:
    """The evaluated routes of a run's adverse lane-departures."""
    exclude = "run_id" if with_json else "run_id, route_json"
    return _utc(ws.con.execute(
        f"SELECT * EXCLUDE ({exclude}) FROM nightly_routes WHERE run_id = ? ORDER BY path_id, depart_utc, role", [str(run_id)]
    ).df())


def read_route(ws, run_id: str, path_id: str, depart_utc, role: str):
    """One stored route as a :class:`routing.route.Route` (None when absent)."""
    from routing.route import Route

    row = ws.con.execute(
        "SELECT route_json FROM nightly_routes WHERE run_id = ? AND path_id = ? AND depart_utc = ? AND role = ?",
        [str(run_id), str(path_id), pd.Timestamp(depart_utc), str(role)],
    ).fetchone()
    return None if row is None else Route.from_json(row[0])


def read_events(ws, run_id: str) -> pd.DataFrame:
    return _utc(ws.con.execute(
        "SELECT * EXCLUDE (run_id) FROM nightly_events WHERE run_id = ? ORDER BY path_id, depart_utc, role, start_utc, criterion",
        [str(run_id)],
    ).df())


def count_rows(ws) -> dict[str, int]:
    """Row count of every nightly table (idempotence checks)."""
    return {t: int(ws.con.execute(f'SELECT count(*) FROM "{t}"').fetchone()[0]) for t in TABLES}
