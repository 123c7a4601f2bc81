"""Tables of the evaluation component: voyage audits, their routes and events, and deviations.

``audits`` has one row per audit run; ``audit_routes`` one row per route role of an audit
(historical, deviation, optimal, min_distance) with its headline numbers and the full route as
JSON (:meth:`routing.route.Route.to_json`); ``audit_events`` the safety events found on each
route; ``deviations`` one row per computed lane deviation.
"""

from __future__ import annotations

import json
import math

import pandas as pd

COMPONENT = "results"

MIGRATIONS = [
    [
        """CREATE TABLE audits (
            audit_id      VARCHAR PRIMARY KEY,
            created_utc   TIMESTAMPTZ NOT NULL,
            mmsi          BIGINT,
            voyage_id     VARCHAR,
            depart_utc    TIMESTAMPTZ,
            arrive_utc    TIMESTAMPTZ,
            vessel        VARCHAR,
            weather       VARCHAR,
            summary_json  VARCHAR NOT NULL
        )""",
        """CREATE TABLE audit_routes (
            audit_id        VARCHAR NOT NULL,
            role            VARCHAR NOT NULL,
            time_h          DOUBLE,
            dist_nmi        DOUBLE,
            max_hs_m        DOUBLE,
            mean_hs_m       DOUBLE,
            fuel_t          DOUBLE,
            co2_t           DOUBLE,
            so2_t           DOUBLE,
            nox_t           DOUBLE,
            pm_t            DOUBLE,
            exposure_h      DOUBLE,
            n_safety_events INTEGER,
            route_json      VARCHAR NOT NULL,
            PRIMARY KEY (audit_id, role)
        )""",
        """CREATE TABLE audit_events (
            audit_id    VARCHAR NOT NULL,
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
        """CREATE TABLE deviations (
            deviation_id  VARCHAR PRIMARY KEY,
            created_utc   TIMESTAMPTZ NOT NULL,
            lane_id       VARCHAR NOT NULL,
            depart_utc    TIMESTAMPTZ NOT NULL,
            n_deviated    INTEGER NOT NULL,
            n_unresolved  INTEGER NOT NULL,
            time_h        DOUBLE,
            dist_nmi      DOUBLE,
            route_json    VARCHAR NOT NULL
        )""",
    ],
]

_ROUTE_COLUMNS = ("time_h", "dist_nmi", "max_hs_m", "mean_hs_m", "fuel_t", "co2_t", "so2_t", "nox_t", "pm_t", "exposure_h", "n_safety_events")


def _num(x):
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _json(obj) -> str:
    def clean(o):
        if isinstance(o, dict):
            return {str(k): clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        if hasattr(o, "item") and not isinstance(o, str):
            o = o.item()
        if isinstance(o, float) and not math.isfinite(o):
            return None
        if isinstance(o, pd.Timestamp):
            return o.isoformat()
        return o

    return json.dumps(clean(obj))


def write_audit(ws, audit_id: str, *, mmsi=None, voyage_id=None, depart_utc=None, arrive_utc=None, vessel="",
                weather=(), summary: dict, evaluations: dict) -> None:
    """Store one audit (replacing an earlier one with the same id) in one transaction.

    ``evaluations`` maps a role to a :class:`routing.evaluate.RouteEvaluation`.
    """
    now = pd.Timestamp.now(tz="UTC")
    with ws.transaction() as con:
        for table in ("audit_events", "audit_routes", "audits"):
            con.execute(f'DELETE FROM "{table}" WHERE audit_id = ?', [audit_id])
        con.execute(
            "INSERT INTO audits VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
            [audit_id, now, None if mmsi is None else int(mmsi), voyage_id, depart_utc, arrive_utc, vessel,
             _json(list(weather)), _json(summary)],
        )
        for role, ev in evaluations.items():
            s = ev.summary
            con.execute(
                "INSERT INTO audit_routes VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [audit_id, role] + [_num(s.get(c)) for c in _ROUTE_COLUMNS[:-1]] + [int(s.get("n_safety_events") or 0), ev.route.to_json()],
            )
            for e in ev.events:
                con.execute(
                    "INSERT INTO audit_events VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    [audit_id, role, e["criterion"], e["kind"], pd.Timestamp(e["start_utc"]), pd.Timestamp(e["end_utc"]),
                     float(e["duration_h"]), _num(e["start_lat_deg"]), _num(e["start_lon_deg"]), _num(e["max_margin"])],
                )


def read_audit_routes(ws, audit_id: str) -> pd.DataFrame:
    """Headline numbers per route role of one audit (no route JSON)."""
    cols = ", ".join(("role",) + _ROUTE_COLUMNS)
    return ws.con.execute(f"SELECT {cols} FROM audit_routes WHERE audit_id = ? ORDER BY role", [audit_id]).df()


def read_audit_events(ws, audit_id: str) -> pd.DataFrame:
    return ws.con.execute(
        "SELECT * EXCLUDE (audit_id) FROM audit_events WHERE audit_id = ? ORDER BY start_utc, role, criterion", [audit_id]
    ).df()


def read_audit_summary(ws, audit_id: str) -> dict | None:
    row = ws.con.execute("SELECT summary_json FROM audits WHERE audit_id = ?", [audit_id]).fetchone()
    return None if row is None else json.loads(row[0])


def write_deviation(ws, deviation_id: str, lane_id, depart_utc, route) -> None:
    """Store one lane deviation (a :class:`routing.route.Route` from :func:`routing.deviate.deviate_lane`)."""
    props = route.properties
    with ws.transaction() as con:
        con.execute("DELETE FROM deviations WHERE deviation_id = ?", [deviation_id])
        con.execute(
            "INSERT INTO deviations VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
            [deviation_id, pd.Timestamp.now(tz="UTC"), str(lane_id), pd.Timestamp(depart_utc), int(props.get("n_deviated", 0)),
             int(props.get("n_unresolved", 0)), _num(route.time_h), _num(route.dist_nmi), route.to_json()],
        )


def read_deviations(ws, lane_id=None) -> pd.DataFrame:
    """Stored deviations (without the route JSON), optionally of one lane."""
    sql = "SELECT deviation_id, created_utc, lane_id, depart_utc, n_deviated, n_unresolved, time_h, dist_nmi FROM deviations"
    if lane_id is None:
        return ws.con.execute(sql + " ORDER BY lane_id, depart_utc").df()
    return ws.con.execute(sql + " WHERE lane_id = ? ORDER BY depart_utc", [str(lane_id)]).df()


def read_deviation_route(ws, deviation_id: str):
    """The stored deviation as a :class:`routing.route.Route` (None when absent)."""
    from routing.route import Route

    row = ws.con.execute("SELECT route_json FROM deviations WHERE deviation_id = ?", [deviation_id]).fetchone()
    return None if row is None else Route.from_json(row[0])
