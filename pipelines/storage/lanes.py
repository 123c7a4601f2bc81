"""Tables of the lanes component: ports, voyages, lanes, lane centroids (and the run that made them).

Every lanes run replaces the previous result as a whole, in one transaction: readers see either
the old or the new set, never a mix. Port id 0 of the pure functions ("unknown end") is stored
as NULL.

Tables
------
``lane_runs``       one row per run: parameters and summary (JSON), counts, time.
``ports``           ports and waypoints (DBSCAN clusters of stops, named from ``data/ports.csv``).
``voyages``         track segments between port calls; ``kind`` tells port_to_port, loop,
                    departure (no arrival port), arrival (no departure port), transit.
``lanes``           one row per lane (a DBSCAN cluster of an origin-destination pair).
``lane_centroids``  ordered centroid sequence of each lane, ``seq`` 0..n-1 in sailing order,
                    ``speed_kn`` the typical (median) speed at the centroid.
``lane_voyages``    which voyages a lane was built from (points of the voyage in the lane).
"""

from __future__ import annotations

import json

import pandas as pd

COMPONENT = "lanes"

MIGRATIONS = [
    [
        """CREATE TABLE lane_runs (
            run_id        INTEGER PRIMARY KEY,
            created_at    TIMESTAMPTZ NOT NULL DEFAULT now(),
            n_positions   BIGINT NOT NULL,
            ports         INTEGER NOT NULL,
            voyages       INTEGER NOT NULL,
            lanes         INTEGER NOT NULL,
            noise_points  BIGINT NOT NULL,
            params_json   VARCHAR NOT NULL,
            summary_json  VARCHAR NOT NULL
        )""",
        """CREATE TABLE ports (
            port_id         INTEGER PRIMARY KEY,
            kind            VARCHAR NOT NULL,
            locode          VARCHAR,
            name            VARCHAR NOT NULL,
            country         VARCHAR,
            lat_deg         DOUBLE NOT NULL,
            lon_deg         DOUBLE NOT NULL,
            radius_nmi      DOUBLE NOT NULL,
            n_calls         INTEGER NOT NULL,
            n_vessels       INTEGER NOT NULL,
            n_clusters      INTEGER NOT NULL,
            known_lat_deg   DOUBLE,
            known_lon_deg   DOUBLE,
            match_dist_nmi  DOUBLE
        )""",
        """CREATE TABLE voyages (
            voyage_id       VARCHAR PRIMARY KEY,
            mmsi            BIGINT NOT NULL,
            origin_port_id  INTEGER,
            dest_port_id    INTEGER,
            depart_utc      TIMESTAMPTZ NOT NULL,
            arrive_utc      TIMESTAMPTZ NOT NULL,
            dist_nmi        DOUBLE NOT NULL,
            n_fixes         INTEGER NOT NULL,
            max_gap_s       DOUBLE NOT NULL,
            kind            VARCHAR NOT NULL
        )""",
        """CREATE TABLE lanes (
            lane_id          VARCHAR PRIMARY KEY,
            origin_port_id   INTEGER,
            dest_port_id     INTEGER,
            kind             VARCHAR NOT NULL,
            n_points         INTEGER NOT NULL,
            n_voyages        INTEGER NOT NULL,
            n_vessels        INTEGER NOT NULL,
            mean_speed_kn    DOUBLE NOT NULL,
            mean_course_deg  DOUBLE NOT NULL,
            course_r         DOUBLE NOT NULL,
            length_nmi       DOUBLE NOT NULL,
            width_nmi        DOUBLE NOT NULL,
            n_centroids      INTEGER NOT NULL,
            polygon_wkt      VARCHAR NOT NULL
        )""",
        """CREATE TABLE lane_centroids (
            lane_id     VARCHAR NOT NULL,
            seq         INTEGER NOT NULL,
            lat_deg     DOUBLE NOT NULL,
            lon_deg     DOUBLE NOT NULL,
            speed_kn    DOUBLE NOT NULL,
            course_deg  DOUBLE,
            n_points    INTEGER NOT NULL,
            n_voyages   INTEGER NOT NULL,
            along_nmi   DOUBLE NOT NULL,
            PRIMARY KEY (lane_id, seq)
        )""",
        """CREATE TABLE lane_voyages (
            lane_id    VARCHAR NOT NULL,
            voyage_id  VARCHAR NOT NULL,
            n_points   INTEGER NOT NULL,
            PRIMARY KEY (lane_id, voyage_id)
        )""",
    ],
]

_PORT_COLS = ["port_id", "kind", "locode", "name", "country", "lat_deg", "lon_deg", "radius_nmi", "n_calls",
              "n_vessels", "n_clusters", "known_lat_deg", "known_lon_deg", "match_dist_nmi"]
_VOYAGE_COLS = ["voyage_id", "mmsi", "origin_port_id", "dest_port_id", "depart_utc", "arrive_utc", "dist_nmi",
                "n_fixes", "max_gap_s", "kind"]
_LANE_COLS = ["lane_id", "origin_port_id", "dest_port_id", "kind", "n_points", "n_voyages", "n_vessels",
              "mean_speed_kn", "mean_course_deg", "course_r", "length_nmi", "width_nmi", "n_centroids", "polygon_wkt"]
_CENTROID_COLS = ["lane_id", "seq", "lat_deg", "lon_deg", "speed_kn", "course_deg", "n_points", "n_voyages", "along_nmi"]
_LANE_VOYAGE_COLS = ["lane_id", "voyage_id", "n_points"]

_TABLES = {
    "ports": _PORT_COLS,
    "voyages": _VOYAGE_COLS,
    "lanes": _LANE_COLS,
    "lane_centroids": _CENTROID_COLS,
    "lane_voyages": _LANE_VOYAGE_COLS,
}


def _port_nullable(s: pd.Series) -> pd.Series:
    """Port id 0 (unknown end) as NULL."""
    v = pd.to_numeric(s, errors="raise").astype("Int64")
    return v.where(v > 0, pd.NA)


def write_lanes(ws, ports: pd.DataFrame, voyages: pd.DataFrame, lanes: pd.DataFrame, centroids: pd.DataFrame,
                lane_voyages: pd.DataFrame, summary: dict, params: dict) -> int:
    """Replace the lanes result with a new one in one transaction; return the new ``run_id``.

    ``voyages`` carries the track id in ``mmsi`` (or ``track``, renamed here).
    """
    frames = {
        "ports": ports.copy(),
        "voyages": voyages.rename(columns={"track": "mmsi"}).copy(),
        "lanes": lanes.copy(),
        "lane_centroids": centroids.copy(),
        "lane_voyages": lane_voyages.copy(),
    }
    for name in ("voyages", "lanes"):
        for col in ("origin_port_id", "dest_port_id"):
            frames[name][col] = _port_nullable(frames[name][col])
    with ws.transaction() as con:
        for table, cols in _TABLES.items():
            df = frames[table]
            missing = [c for c in cols if c not in df.columns]
            if missing:
                raise ValueError(f"{table}: missing column(s) {missing}")
            view = f"_stormlane_lanes_{table}"  # our own identifier, not user input
            con.register(view, df[cols])
            try:
                con.execute(f'DELETE FROM "{table}"')
                con.execute(f'INSERT INTO "{table}" ({", ".join(cols)}) SELECT {", ".join(cols)} FROM "{view}"')
            finally:
                con.unregister(view)
        run_id = int(con.execute("SELECT coalesce(max(run_id), 0) + 1 FROM lane_runs").fetchone()[0])
        con.execute(
            "INSERT INTO lane_runs (run_id, n_positions, ports, voyages, lanes, noise_points, params_json, summary_json)"
            " VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            [run_id, int(summary.get("positions", 0)), int(summary["ports"]), int(summary["voyages"]),
             int(summary["lanes"]), int(summary["noise_points"]), json.dumps(params, default=str),
             json.dumps(summary, default=str)],
        )
    return run_id


def read_ports(ws) -> pd.DataFrame:
    """Ports and waypoints ordered by ``port_id``."""
    return ws.con.execute(f"SELECT {', '.join(_PORT_COLS)} FROM ports ORDER BY port_id").df()


def read_voyages(ws, kind: str | None = None) -> pd.DataFrame:
    """Voyages (optionally of one ``kind``) ordered by departure; times tz-aware UTC."""
    sql = f"SELECT {', '.join(_VOYAGE_COLS)} FROM voyages"
    args: list = []
    if kind is not None:
        sql += " WHERE kind = ?"
        args.append(kind)
    df = ws.con.execute(sql + " ORDER BY depart_utc, voyage_id", args).df()
    return _utc(df, ("depart_utc", "arrive_utc"))


def read_lanes(ws) -> pd.DataFrame:
    """Lanes ordered by ``lane_id``."""
    return ws.con.execute(f"SELECT {', '.join(_LANE_COLS)} FROM lanes ORDER BY origin_port_id NULLS LAST, dest_port_id NULLS LAST, lane_id").df()


def read_lane_centroids(ws, lane_id: str | None = None) -> pd.DataFrame:
    """Centroid sequences (of one lane, or all), ordered by lane and ``seq``."""
    sql = f"SELECT {', '.join(_CENTROID_COLS)} FROM lane_centroids"
    args: list = []
    if lane_id is not None:
        sql += " WHERE lane_id = ?"
        args.append(lane_id)
    return ws.con.execute(sql + " ORDER BY lane_id, seq", args).df()


def read_lane_voyages(ws, lane_id: str | None = None) -> pd.DataFrame:
    """Which voyages each lane was built from."""
    sql = f"SELECT {', '.join(_LANE_VOYAGE_COLS)} FROM lane_voyages"
    args: list = []
    if lane_id is not None:
        sql += " WHERE lane_id = ?"
        args.append(lane_id)
    return ws.con.execute(sql + " ORDER BY lane_id, voyage_id", args).df()


def read_last_run(ws) -> dict | None:
    """The most recent lanes run (counts, parameters, summary), or None."""
    row = ws.con.execute(
        "SELECT run_id, created_at, n_positions, ports, voyages, lanes, noise_points, params_json, summary_json"
        " FROM lane_runs ORDER BY run_id DESC LIMIT 1"
    ).fetchone()
    if row is None:
        return None
    keys = ["run_id", "created_at", "n_positions", "ports", "voyages", "lanes", "noise_points"]
    out = dict(zip(keys, row[:7]))
    out["params"] = json.loads(row[7])
    out["summary"] = json.loads(row[8])
    return out


def _utc(df: pd.DataFrame, cols) -> pd.DataFrame:
    for col in cols:
        if col in df.columns:
            s = pd.to_datetime(df[col])
            df[col] = s.dt.tz_localize("UTC") if s.dt.tz is None else s.dt.tz_convert("UTC")
    return df
