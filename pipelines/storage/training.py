"""The performance training table: AIS fixes steaming at sea, each with the weather it met.

Built in DuckDB from the workspace alone (``ais_positions``, ``ais_quarantine``, ``vessels``, the
lanes component's ``ports``, ``lane_centroids`` and ``voyages`` when present, and one weather
grid), so the same parameters give the same table again (the model's row in
``performance_models`` stores them). Nothing is dropped silently: every fix of the span gets the
first rule it breaks, in this order, and :func:`training_table` returns the count per rule.

=================  ==========================================================================
rule               a fix is left out when
=================  ==========================================================================
``class``          its ship's AIS ship type is not in the requested classes
``not_underway``   its navigational status is not "under way using engine" (ITU-R M.1371-5,
                   Table 45: code 0; a missing status is not under way)
``slow``           its SOG is missing or below the floor (default 5 kn: manoeuvring, drifting,
                   waiting; a ship steaming slowly on purpose is below any calm-water speed)
``no_course``      its COG is missing (the encounter angle needs it)
``near_port``      it lies within a port's radius plus the margin (default 8 nmi: on the demo,
                   harbour speeds and the ramps to sea speed reach about 6 nmi from the berth)
``lane_end``       it lies within the margin (default 5 nmi) of a lane's first or last centroid
``jump_neighbour`` a fix of the same ship quarantined as ``speed_jump`` lies within the window
                   (default 300 s): the track around a position jump is not to be trusted
``speed_mismatch`` the speed implied by its two neighbours' positions (when they are 30-900 s
                   apart) differs from its SOG by more than max(3 kn, 25 %): a bad position or
                   SOG that the ingest's speed-jump rule could not see
``no_weather``     the nearest weather cell is land, outside the grid, or its time outside the
                   grid's span by more than half a step
=================  ==========================================================================

The weather at a fix: the nearest grid point (index arithmetic, as
:func:`pipelines.storage.weather.join_points_weather`), linear in time between the last grid
time at or before the fix and the first at or after it (two ``ASOF`` joins; the wave direction
through its cos/sin components, DESIGN.md "Conventions"); a fix beyond the grid's first or last
time by at most half a step takes that time's values.

Each kept fix carries its voyage: the workspace voyage (lanes component) it lies in, otherwise
a leg of its ship cut at gaps of more than :data:`LEG_GAP_S`.
"""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass

import pandas as pd

from thresholds.units import EARTH_RADIUS_NMI

#: Rules in the order they are tested (module docstring).
RULES = ("class", "not_underway", "slow", "no_course", "near_port", "lane_end", "jump_neighbour",
         "speed_mismatch", "no_weather")
#: A ship's fixes more than this apart start a new leg when no workspace voyage holds them. [s]
LEG_GAP_S = 7200.0


@dataclass(frozen=True)
class CleaningRules:
    """The parameters of the rules (module docstring); stored with every model."""

    underway_status: tuple[int, ...] = (0,)
    sog_floor_kn: float = 5.0
    port_margin_nmi: float = 8.0
    lane_end_margin_nmi: float = 5.0
    jump_window_s: float = 300.0
    mismatch_kn: float = 3.0
    mismatch_frac: float = 0.25

    def to_dict(self) -> dict:
        d = asdict(self)
        d["underway_status"] = list(self.underway_status)
        return d


def _haversine_sql(lat1: str, lon1: str, lat2: str, lon2: str) -> str:
    return (f"2.0 * $radius * asin(sqrt(least(1.0, pow(sin(radians({lat2} - {lat1}) / 2.0), 2) + cos(radians({lat1})) "
            f"* cos(radians({lat2})) * pow(sin(radians({lon2} - {lon1}) / 2.0), 2))))")


def _table_exists(con, name: str) -> bool:
    return bool(con.execute("SELECT count(*) FROM information_schema.tables WHERE table_schema = 'main' AND table_name = ?",
                            [name]).fetchone()[0])


def _used(sql: str, params: dict) -> dict:
    """The named parameters a statement uses (DuckDB refuses unused ones; the distance rules'
    margins are absent from the SQL when the workspace has no ports or lanes)."""
    return {k: v for k, v in params.items() if re.search(rf"\${k}\b", sql)}


def _count(con, sql: str) -> int:
    return int(con.execute(sql).fetchone()[0])


def _fix_sql(ship_types: list[tuple[int, int]] | None, have_ports: bool, have_lane_ends: bool) -> list[str]:
    """SQL statements tagging each fix of the span with the first rule it breaks (NULL = kept).

    The distance rules are semi-joins on a latitude band (a range join) followed by the exact
    great-circle test, not a distance from every fix to every port."""
    if ship_types:
        in_class = " OR ".join(f"(v.ship_type BETWEEN {int(lo)} AND {int(hi)})" for lo, hi in ship_types)
    else:
        in_class = "TRUE"
    implied = _haversine_sql("plat", "plon", "nlat", "nlon") + " / (epoch(ntime) - epoch(ptime)) * 3600.0"
    span = f"""
        CREATE OR REPLACE TEMP TABLE _perf_span AS
        SELECT row_number() OVER () AS fid, *,
               CASE WHEN ntime IS NOT NULL AND ptime IS NOT NULL
                         AND epoch(ntime) - epoch(ptime) BETWEEN 30 AND 900 THEN {implied} END AS implied_kn
        FROM (
            SELECT p.mmsi, p.time_utc, p.lat_deg, p.lon_deg, p.sog_kn, p.cog_deg, p.heading_deg, p.nav_status,
                   ({in_class}) AS in_class,
                   lag(p.lat_deg) OVER w AS plat, lag(p.lon_deg) OVER w AS plon, lag(p.time_utc) OVER w AS ptime,
                   lead(p.lat_deg) OVER w AS nlat, lead(p.lon_deg) OVER w AS nlon, lead(p.time_utc) OVER w AS ntime
            FROM ais_positions p LEFT JOIN vessels v USING (mmsi)
            WHERE p.time_utc >= $since AND p.time_utc < $until
            WINDOW w AS (PARTITION BY p.mmsi ORDER BY p.time_utc)
        )
    """
    near_port = (f"""SELECT DISTINCT s.fid FROM _perf_span s JOIN ports q
                        ON s.lat_deg BETWEEN q.lat_deg - (q.radius_nmi + $port_margin) / 60.0
                                         AND q.lat_deg + (q.radius_nmi + $port_margin) / 60.0
                     WHERE {_haversine_sql('s.lat_deg', 's.lon_deg', 'q.lat_deg', 'q.lon_deg')} < q.radius_nmi + $port_margin"""
                 if have_ports else "SELECT CAST(NULL AS BIGINT) AS fid WHERE FALSE")
    lane_end = (f"""SELECT DISTINCT s.fid FROM _perf_span s JOIN _perf_lane_ends e
                       ON s.lat_deg BETWEEN e.lat_deg - $end_margin / 60.0 AND e.lat_deg + $end_margin / 60.0
                    WHERE {_haversine_sql('s.lat_deg', 's.lon_deg', 'e.lat_deg', 'e.lon_deg')} < $end_margin"""
                if have_lane_ends else "SELECT CAST(NULL AS BIGINT) AS fid WHERE FALSE")
    tag = f"""
        CREATE OR REPLACE TEMP TABLE _perf_fixes AS
        WITH jumps AS (
            SELECT DISTINCT mmsi, time_utc FROM ais_quarantine
            WHERE reason = 'speed_jump' AND mmsi IS NOT NULL AND time_utc IS NOT NULL
        ),
        near_port AS ({near_port}),
        lane_end AS ({lane_end}),
        near_jump AS (
            SELECT DISTINCT s.fid FROM _perf_span s JOIN jumps j ON s.mmsi = j.mmsi
            WHERE abs(epoch(j.time_utc) - epoch(s.time_utc)) <= $jump_s
        )
        SELECT mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, nav_status, implied_kn,
               CASE
                 WHEN NOT in_class THEN 'class'
                 WHEN nav_status IS NULL OR list_position($underway, CAST(nav_status AS INTEGER)) IS NULL THEN 'not_underway'
                 WHEN sog_kn IS NULL OR sog_kn < $floor THEN 'slow'
                 WHEN cog_deg IS NULL THEN 'no_course'
                 WHEN fid IN (SELECT fid FROM near_port) THEN 'near_port'
                 WHEN fid IN (SELECT fid FROM lane_end) THEN 'lane_end'
                 WHEN fid IN (SELECT fid FROM near_jump) THEN 'jump_neighbour'
                 WHEN implied_kn IS NOT NULL AND abs(implied_kn - sog_kn) > greatest($mismatch_kn, $mismatch_frac * sog_kn)
                      THEN 'speed_mismatch'
               END AS rule
        FROM _perf_span
    """
    return [span, tag]


def _weather_sql(columns: tuple[str, ...]) -> str:
    """SQL joining every kept fix with its nearest cell, linear in time (module docstring)."""
    lin = []
    for c in columns:
        if c == "wave_from_deg":
            continue
        lin.append(f"CASE WHEN t0 IS NULL THEN n_{c} WHEN t1 IS NULL OR t1 = t0 THEN p_{c} "
                   f"ELSE p_{c} + (n_{c} - p_{c}) * f END AS {c}")
    if "wave_from_deg" in columns:
        cs = ("CASE WHEN t0 IS NULL THEN cos(radians(n_wave_from_deg)) WHEN t1 IS NULL OR t1 = t0 THEN cos(radians(p_wave_from_deg)) "
              "ELSE cos(radians(p_wave_from_deg)) * (1 - f) + cos(radians(n_wave_from_deg)) * f END")
        sn = cs.replace("cos(", "sin(")
        lin.append(f"(degrees(atan2({sn}, {cs})) + 360.0) % 360.0 AS wave_from_deg")
    prev = ", ".join(f"w.{c} AS p_{c}" for c in columns)
    nxt = ", ".join(f"w.{c} AS n_{c}" for c in columns)
    return f"""
        WITH kept AS (
            SELECT f.*, CAST(round((lat_deg - $lat0) / $dlat) AS INTEGER) AS lat_idx,
                   CAST(round((lon_deg - $lon0) / $dlon) AS INTEGER) AS lon_idx
            FROM _perf_fixes f WHERE rule IS NULL
        ), keys AS (SELECT DISTINCT lat_idx, lon_idx FROM kept),
        cells AS (
            SELECT w.* FROM weather_cells w SEMI JOIN keys k ON w.lat_idx = k.lat_idx AND w.lon_idx = k.lon_idx
            WHERE w.grid_id = $grid_id
        ), prev AS (
            SELECT k.*, w.time_utc AS t0, {prev}
            FROM kept k ASOF LEFT JOIN cells w ON k.lat_idx = w.lat_idx AND k.lon_idx = w.lon_idx AND k.time_utc >= w.time_utc
        ), both_sides AS (
            SELECT p.*, w.time_utc AS t1, {nxt}
            FROM prev p ASOF LEFT JOIN cells w ON p.lat_idx = w.lat_idx AND p.lon_idx = w.lon_idx AND p.time_utc <= w.time_utc
        ), timed AS (
            SELECT *, CASE WHEN t0 IS NOT NULL AND t1 IS NOT NULL AND t1 > t0
                           THEN (epoch(time_utc) - epoch(t0)) / (epoch(t1) - epoch(t0)) ELSE 0.0 END AS f,
                   CASE
                     WHEN lat_idx < 0 OR lat_idx >= $nlat OR lon_idx < 0 OR lon_idx >= $nlon THEN 'outside_grid'
                     WHEN time_utc < $start - to_microseconds($half) OR time_utc > $end + to_microseconds($half) THEN 'outside_time'
                     WHEN t0 IS NULL AND t1 IS NULL THEN 'land'
                     WHEN (t0 IS NULL AND epoch(t1) - epoch(time_utc) > $half_s)
                       OR (t1 IS NULL AND epoch(time_utc) - epoch(t0) > $half_s) THEN 'outside_time'
                     ELSE 'ok' END AS wx_status
            FROM both_sides
        )
        SELECT mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, heading_deg, nav_status, implied_kn, wx_status,
               {", ".join(lin)}
        FROM timed
    """


def _voyage_sql(have_voyages: bool) -> str:
    """SQL giving each kept fix its voyage: the workspace voyage holding it, else a gap-cut leg."""
    voyage = ("CASE WHEN v.voyage_id IS NOT NULL AND x.time_utc <= v.arrive_utc THEN v.voyage_id END"
              if have_voyages else "CAST(NULL AS VARCHAR)")
    join = ("ASOF LEFT JOIN voyages v ON x.mmsi = v.mmsi AND x.time_utc >= v.depart_utc" if have_voyages else "")
    return f"""
        WITH x AS (SELECT * FROM _perf_joined WHERE wx_status = 'ok'),
        legs AS (
            SELECT x.*, {voyage} AS ws_voyage,
                   sum(CASE WHEN lag_t IS NULL OR epoch(x.time_utc) - epoch(lag_t) > $leg_gap THEN 1 ELSE 0 END)
                       OVER (PARTITION BY x.mmsi ORDER BY x.time_utc ROWS UNBOUNDED PRECEDING) AS leg_no
            FROM (SELECT *, lag(time_utc) OVER (PARTITION BY mmsi ORDER BY time_utc) AS lag_t FROM x) x {join}
        )
        SELECT l.* EXCLUDE (ws_voyage, leg_no, lag_t),
               coalesce(ws_voyage, CAST(l.mmsi AS VARCHAR) || '_leg' || CAST(leg_no AS VARCHAR)) AS voyage_id,
               ws.ship_type, ws.length_m, ws.beam_m, ws.draught_m
        FROM legs l LEFT JOIN vessels ws USING (mmsi)
        ORDER BY l.mmsi, l.time_utc
    """


def training_table(ws, grid: dict, *, since=None, until=None, ship_types: list[tuple[int, int]] | None = None,
                   rules: CleaningRules = CleaningRules()) -> tuple[pd.DataFrame, dict]:
    """The training table of a workspace for one weather grid.

    Parameters
    ----------
    ws : Workspace
    grid : dict
        The weather grid's row (:func:`pipelines.storage.weather.get_grid`).
    since, until : datetime-like, optional
        Fixes with ``since <= time_utc < until`` (default: all).
    ship_types : list of (lo, hi), optional
        AIS ship-type ranges to keep (default: every ship).
    rules : CleaningRules

    Returns
    -------
    (DataFrame, dict)
        One row per kept fix (position, SOG, COG, heading, the weather at the fix, ``voyage_id``,
        the ship's AIS particulars), and ``{"counts": {rule: n}, "fixes_in_span": n, "kept": n,
        "applied": [rules applied], "not_applied": {rule: why}}``.
    """
    con = ws.con
    have_ports = _table_exists(con, "ports") and _count(con, "SELECT count(*) FROM ports") > 0
    have_centroids = _table_exists(con, "lane_centroids") and _count(con, "SELECT count(*) FROM lane_centroids") > 0
    have_voyages = _table_exists(con, "voyages") and _count(con, "SELECT count(*) FROM voyages") > 0
    not_applied = {}
    if not have_ports:
        not_applied["near_port"] = "the workspace has no ports (run `stormlane lanes`)"
    if not have_centroids:
        not_applied["lane_end"] = "the workspace has no lanes (run `stormlane lanes`)"
    lo = pd.Timestamp("1900-01-01", tz="UTC") if since is None else pd.Timestamp(since)
    hi = pd.Timestamp("2200-01-01", tz="UTC") if until is None else pd.Timestamp(until)
    if have_centroids:
        con.execute("""CREATE OR REPLACE TEMP TABLE _perf_lane_ends AS
                       SELECT c.lat_deg, c.lon_deg FROM lane_centroids c
                       JOIN (SELECT lane_id, min(seq) AS s0, max(seq) AS s1 FROM lane_centroids GROUP BY lane_id) b
                         ON c.lane_id = b.lane_id AND (c.seq = b.s0 OR c.seq = b.s1)""")
    params = {"since": lo, "until": hi, "underway": [int(s) for s in rules.underway_status], "floor": rules.sog_floor_kn,
              "port_margin": rules.port_margin_nmi, "end_margin": rules.lane_end_margin_nmi, "jump_s": rules.jump_window_s,
              "mismatch_kn": rules.mismatch_kn, "mismatch_frac": rules.mismatch_frac, "radius": EARTH_RADIUS_NMI}
    try:
        span_sql, tag_sql = _fix_sql(ship_types, have_ports, have_centroids)
        con.execute(span_sql, _used(span_sql, params))
        con.execute(tag_sql, _used(tag_sql, params))
        counts = dict(con.execute("SELECT coalesce(rule, 'kept'), count(*) FROM _perf_fixes GROUP BY 1").fetchall())
        columns = tuple(c for c in str(grid["variables"]).split(",") if c)
        step_s = grid.get("step_s")
        half_s = float(step_s) / 2.0 if step_s is not None and not pd.isna(step_s) else 0.0
        wx = {"lat0": float(grid["lat0_deg"]), "dlat": float(grid["dlat_deg"]), "lon0": float(grid["lon0_deg"]),
              "dlon": float(grid["dlon_deg"]), "nlat": int(grid["nlat"]), "nlon": int(grid["nlon"]),
              "grid_id": int(grid["grid_id"]), "start": pd.Timestamp(grid["start_utc"]), "end": pd.Timestamp(grid["end_utc"]),
              "half": int(round(half_s * 1e6)), "half_s": half_s}
        con.execute("CREATE OR REPLACE TEMP TABLE _perf_joined AS " + _weather_sql(columns), wx)
        wx_counts = dict(con.execute("SELECT wx_status, count(*) FROM _perf_joined GROUP BY 1").fetchall())
        out = con.execute(_voyage_sql(have_voyages), {"leg_gap": LEG_GAP_S}).df()
    finally:
        for t in ("_perf_span", "_perf_fixes", "_perf_joined", "_perf_lane_ends"):
            con.execute(f"DROP TABLE IF EXISTS {t}")
    out["time_utc"] = pd.to_datetime(out["time_utc"], utc=True)
    no_weather = sum(n for k, n in wx_counts.items() if k != "ok")
    tally = {r: int(counts.get(r, 0)) for r in RULES if r != "no_weather"}
    tally["no_weather"] = int(no_weather)
    info = {"fixes_in_span": int(sum(counts.values())), "counts": tally, "kept": int(len(out)),
            "no_weather": {k: int(n) for k, n in sorted(wx_counts.items()) if k != "ok"},
            "applied": [r for r in RULES if r not in not_applied], "not_applied": not_applied,
            "grid": {"grid_id": int(grid["grid_id"]), "name": str(grid["name"]), "variables": list(columns)}}
    return out, info
