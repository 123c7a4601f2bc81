"""Cleaning of AIS position reports: one definition of the rules, two executions.

Every AIS reader produces the same *typed stage* (:data:`STAGE_COLUMNS`): one row per CSV line,
Parquet row or NMEA message, with the values already typed (unparsable text becomes NaN/NaT and a
``parse_error`` code) and the raw text kept for the quarantine. :func:`classify` then gives every
position row exactly one outcome: loaded (``reason`` is ``None``), quarantined (a reason code) or
duplicate (a code from :data:`DUPLICATE_CODES`). The same rules run as SQL inside DuckDB for bulk
ingest (``pipelines/storage/ais/`` builds its SQL from the constants below); a test feeds both
executions the same input and asserts identical outcomes.

Rules, in order of precedence (the first that fires is the row's reason):

1. ``parse_error`` codes of the reader for the record as a whole (:data:`RECORD_CODES`: wrong
   number of CSV fields, bad NMEA checksum, incomplete multipart message, message types that
   carry no position, ...).
2. ``bad_mmsi``: missing, not 9 digits, or its MID (first three digits) outside 201-775
   (ITU-R M.585-9, Annex 1: ship stations use MIDs 2xx-7xx, allocated 201-775).
3. ``bad_time``: missing or unparsable timestamp, or outside [1990, 2100).
4. ``parse_error`` codes for single fields (:data:`FIELD_CODES`): the text of a latitude,
   longitude, SOG, COG, heading or status that is not a number (or a known status word).
5. ``no_position``: latitude or longitude missing or the "not available" sentinel
   (lat 91, lon 181; ITU-R M.1371-5, Annex 2, Table 45).
6. ``bad_lat`` / ``bad_lon`` / ``bad_sog`` / ``bad_cog`` / ``bad_heading`` / ``bad_nav_status``:
   outside the valid range and not a sentinel. Sentinels of the motion fields become NULL and
   the row is kept: SOG 102.3 (not available) and 102.2 ("102.2 kn or higher", no usable
   value), COG 360.0, heading 511. Longitude 180 is the same meridian as -180 and is stored as
   -180 (canonical longitudes are in [-180, 180)).
7. Duplicates, among the rows that passed 1-6: rows with the MMSI and timestamp of an earlier
   row (earlier line of the same file, or a row already in the workspace) are ``duplicate``
   when every canonical field equals that row's, ``duplicate_time`` when they conflict. The
   first row wins.
8. ``speed_jump`` (see :func:`speed_jump_mask`): lone outliers and short outlier bursts, and
   the segments of a track that cannot be reached at ``max_speed_kn`` (default 60 kn) from
   the fixes kept around them. Evaluated per file, with the stored fixes as context.

References
----------
.. [1] ITU-R, "Technical characteristics for an automatic identification system using time
       division multiple access in the VHF maritime mobile frequency band," Rec. ITU-R
       M.1371-5, 2014, Annex 2 Sec. 3.3 (messages 1-3, 18, 19, 27; not-available values).
.. [2] ITU-R, "Assignment and use of identities in the maritime mobile service,"
       Rec. ITU-R M.585-9, 2022, Annex 1 (MMSI format, maritime identification digits).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ais import _jumps
from ais._jumps import link_breaks, walk_sorted

# ---------------------------------------------------------------------------------------------
# Limits (ITU-R M.1371-5 Annex 2 Table 45, M.585-9 Annex 1) and the default speed-jump limit.
# ---------------------------------------------------------------------------------------------
#: Smallest and largest valid ship MMSI: 9 digits with a MID from 201 to 775 [2].
MMSI_MIN = 201_000_000
MMSI_MAX = 775_999_999
#: "Latitude not available" / "longitude not available" [1].
LAT_NA_DEG = 91.0
LON_NA_DEG = 181.0
#: SOG 102.3 kn = not available, 102.2 kn = "102.2 kn or higher" [1]: both carry no usable value.
SOG_NA_MIN_KN = 102.2
SOG_NA_KN = 102.3
#: COG 360.0 = not available [1]; valid COG is [0, 360).
COG_NA_DEG = 360.0
#: True heading 511 = not available [1]; valid heading is [0, 360).
HEADING_NA_DEG = 511.0
#: Navigational status codes 0..15 (15 = "not defined", the default) [1].
NAV_STATUS_MAX = 15
#: Float tolerance for sentinel comparisons (values arrive as text or as tenths from bits).
SENTINEL_TOL = 1e-6
#: Timestamps outside [TIME_MIN_UTC, TIME_MAX_UTC) are unusable (AIS began in 2002; pandas
#: nanosecond timestamps end in 2262).
TIME_MIN_UTC = pd.Timestamp("1990-01-01T00:00:00Z")
TIME_MAX_UTC = pd.Timestamp("2100-01-01T00:00:00Z")
#: Default limit of the implied speed between consecutive fixes of one MMSI. [kn]
DEFAULT_MAX_SPEED_KN = 60.0

# ---------------------------------------------------------------------------------------------
# Reason codes
# ---------------------------------------------------------------------------------------------
BAD_LINE = "bad_line"                   # CSV line with the wrong number of fields
BAD_SENTENCE = "bad_sentence"           # text that is not a parsable NMEA sentence
BAD_CHECKSUM = "bad_checksum"           # NMEA checksum mismatch
INCOMPLETE_MULTIPART = "incomplete_multipart"  # fragments that never formed a message
BAD_PAYLOAD = "bad_payload"             # AIS payload that cannot be decoded (empty, short)
OTHER_MSG_TYPE = "other_msg_type"       # AIS message of a type that carries no ship position
BAD_MMSI = "bad_mmsi"
BAD_TIME = "bad_time"
BAD_LAT = "bad_lat"
BAD_LON = "bad_lon"
BAD_SOG = "bad_sog"
BAD_COG = "bad_cog"
BAD_HEADING = "bad_heading"
BAD_NAV_STATUS = "bad_nav_status"
NO_POSITION = "no_position"
SPEED_JUMP = "speed_jump"
DUPLICATE = "duplicate"
DUPLICATE_TIME = "duplicate_time"
DUPLICATE_PAYLOAD = "duplicate_payload"  # NMEA: the same payload received again within 60 s

#: Reader codes that reject the record as a whole (rule 1).
RECORD_CODES = (BAD_LINE, BAD_SENTENCE, BAD_CHECKSUM, INCOMPLETE_MULTIPART, BAD_PAYLOAD,
                OTHER_MSG_TYPE, DUPLICATE_PAYLOAD)
#: Reader codes for one unparsable field (rule 4), in the order the fields are checked.
FIELD_CODES = (BAD_LAT, BAD_LON, BAD_SOG, BAD_COG, BAD_HEADING, BAD_NAV_STATUS)
#: Codes counted as duplicates; every other code counts as quarantined.
DUPLICATE_CODES = (DUPLICATE, DUPLICATE_TIME, DUPLICATE_PAYLOAD)
#: Every reason code with a one-line description (docs/ingest.md and ``--help`` list them).
REASONS = {
    BAD_LINE: "CSV line with the wrong number of fields",
    BAD_SENTENCE: "not a parsable NMEA sentence",
    BAD_CHECKSUM: "NMEA checksum mismatch",
    INCOMPLETE_MULTIPART: "multipart fragments that never formed a whole message",
    BAD_PAYLOAD: "AIS payload that cannot be decoded (empty or too short)",
    OTHER_MSG_TYPE: "AIS message type without a ship position (e.g. base station, AtoN)",
    BAD_MMSI: "MMSI missing, not 9 digits, or MID outside 201-775",
    BAD_TIME: "timestamp missing, unparsable or outside 1990-2100",
    NO_POSITION: "latitude/longitude missing or 91/181 (not available)",
    BAD_LAT: "latitude unparsable or outside [-90, 90]",
    BAD_LON: "longitude unparsable or outside [-180, 180]",
    BAD_SOG: "SOG unparsable, negative or above 102.3 kn",
    BAD_COG: "COG unparsable, negative or above 360",
    BAD_HEADING: "heading unparsable or outside [0, 360) and not 511",
    BAD_NAV_STATUS: "navigational status not an integer 0-15 (or a known status text)",
    SPEED_JUMP: "implied speed to the neighbouring fixes above the limit",
    DUPLICATE: "exact duplicate of an earlier row (same MMSI, time and values)",
    DUPLICATE_TIME: "same MMSI and timestamp as an earlier row, different values",
    DUPLICATE_PAYLOAD: "NMEA payload received again within 60 s",
}

# ---------------------------------------------------------------------------------------------
# The typed stage
# ---------------------------------------------------------------------------------------------
#: Row kinds: a position report (counted in ``read``), a static-only message (NMEA 5/24:
#: joined to ``vessels``, counted as ``static``), or anything else counted in ``read``.
KIND_POSITION = "P"
KIND_STATIC = "S"
#: A line that is no record (a header, an empty line); only the bulk CSV staging keeps them.
KIND_IGNORED = "X"

#: Position columns of the canonical AIS table, in order.
POSITION_COLUMNS = ["mmsi", "time_utc", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status"]
#: Static vessel columns (table ``vessels``).
STATIC_COLUMNS = ["imo", "name", "callsign", "ship_type", "length_m", "beam_m", "draught_m", "destination"]
#: The typed stage every reader returns: column -> pandas dtype.
STAGE_COLUMNS = {
    "line": "int64",          # 1-based line (CSV, NMEA: first sentence of the message) or Parquet row
    "raw": "object",          # the raw text (CSV line, NMEA sentences, Parquet row as CSV)
    "kind": "object",         # KIND_POSITION or KIND_STATIC
    "parse_error": "object",  # a RECORD_CODES / FIELD_CODES code from the reader, or None
    "mmsi": "Int64",
    "time_utc": "datetime64[ns, UTC]",
    "lat_deg": "float64",
    "lon_deg": "float64",
    "sog_kn": "float64",
    "cog_deg": "float64",
    "heading_deg": "float64",
    "nav_status": "float64",
    "imo": "Int64",
    "name": "object",
    "callsign": "object",
    "ship_type": "Int64",
    "length_m": "float64",
    "beam_m": "float64",
    "draught_m": "float64",
    "destination": "object",
}


def empty_stage(n: int = 0) -> pd.DataFrame:
    """A typed stage of ``n`` rows with every column missing (NaN/NaT/None/NA)."""
    cols = {}
    for name, dtype in STAGE_COLUMNS.items():
        if dtype == "object":
            cols[name] = pd.Series([None] * n, dtype="object")
        elif dtype == "int64":
            cols[name] = pd.Series(np.arange(1, n + 1), dtype="int64")
        elif dtype.startswith("datetime64"):
            cols[name] = pd.Series(pd.NaT, index=range(n), dtype=dtype)
        else:
            cols[name] = pd.Series([pd.NA if dtype == "Int64" else np.nan] * n, dtype=dtype)
    df = pd.DataFrame(cols)
    df["kind"] = KIND_POSITION
    return df


def conform_stage(df: pd.DataFrame) -> pd.DataFrame:
    """Give ``df`` exactly the stage columns and dtypes (missing columns are added empty).

    Columns that already have the right dtype are taken as they are (no copy)."""
    out = {}
    n = len(df)
    plain_index = isinstance(df.index, pd.RangeIndex) and df.index.start == 0 and df.index.step == 1
    empty = None
    for name, dtype in STAGE_COLUMNS.items():
        if name in df.columns:
            col = df[name]
            if str(col.dtype) != dtype:
                if dtype.startswith("datetime64"):
                    col = pd.to_datetime(col, utc=True)
                    if str(col.dtype) != dtype:
                        col = col.astype(dtype)
                else:
                    col = col.astype(dtype)
            out[name] = col if plain_index else col.reset_index(drop=True)
        else:
            if empty is None:
                empty = empty_stage(n)
            out[name] = empty[name]
    return pd.DataFrame(out, copy=False)


# ---------------------------------------------------------------------------------------------
# Rules
# ---------------------------------------------------------------------------------------------
def valid_mmsi(mmsi) -> np.ndarray:
    """True where ``mmsi`` is a 9-digit ship MMSI with MID 201-775 [2]."""
    m = pd.array(mmsi, dtype="Int64") if not isinstance(mmsi, pd.Series) else mmsi.astype("Int64")
    ok = (m >= MMSI_MIN) & (m <= MMSI_MAX)
    return np.asarray(ok.fillna(False), dtype=bool)


def _near(x: np.ndarray, value: float) -> np.ndarray:
    return np.abs(x - value) <= SENTINEL_TOL


def normalise_motion(lon_deg, sog_kn, cog_deg, heading_deg):
    """Sentinels of the motion fields to NaN and longitude 180 to -180 (rule 6).

    Returns new float arrays ``(lon_deg, sog_kn, cog_deg, heading_deg)``.
    """
    lon = np.array(lon_deg, dtype=float)
    sog = np.array(sog_kn, dtype=float)
    cog = np.array(cog_deg, dtype=float)
    hdg = np.array(heading_deg, dtype=float)
    lon = np.where(_near(lon, 180.0), -180.0, lon)
    sog = np.where((sog >= SOG_NA_MIN_KN - SENTINEL_TOL) & (sog <= SOG_NA_KN + SENTINEL_TOL), np.nan, sog)
    cog = np.where(_near(cog, COG_NA_DEG), np.nan, cog)
    hdg = np.where(_near(hdg, HEADING_NA_DEG), np.nan, hdg)
    return lon, sog, cog, hdg


def row_reasons(stage: pd.DataFrame) -> np.ndarray:
    """Rules 1-6 for every row of a typed stage: an object array of codes or ``None``.

    Static rows (``kind == "S"``) get ``None``; they are not position reports.
    """
    n = len(stage)
    reason = np.full(n, None, dtype=object)
    todo = np.asarray(stage["kind"].to_numpy() != KIND_STATIC, dtype=bool)

    def fire(mask, code):
        nonlocal todo
        hit = todo & np.asarray(mask, dtype=bool)
        reason[hit] = code
        todo = todo & ~hit

    # Rule 1 keeps the reader's own code.
    perr = stage["parse_error"].to_numpy(dtype=object)
    rec = np.asarray([p in RECORD_CODES for p in perr], dtype=bool) & todo
    reason[rec] = perr[rec]
    todo = todo & ~rec

    fire(~valid_mmsi(stage["mmsi"]), BAD_MMSI)
    t = stage["time_utc"]
    fire(~(t.notna() & (t >= TIME_MIN_UTC) & (t < TIME_MAX_UTC)).to_numpy(), BAD_TIME)
    for code in FIELD_CODES:
        hit = np.asarray([p == code for p in perr], dtype=bool)
        fire(hit, code)

    lat = stage["lat_deg"].to_numpy(dtype=float)
    lon = stage["lon_deg"].to_numpy(dtype=float)
    fire(np.isnan(lat) | np.isnan(lon) | _near(lat, LAT_NA_DEG) | _near(lon, LON_NA_DEG), NO_POSITION)
    fire((lat < -90.0) | (lat > 90.0), BAD_LAT)
    fire((lon < -180.0) | (lon > 180.0), BAD_LON)
    sog = stage["sog_kn"].to_numpy(dtype=float)
    fire((sog < 0.0) | (sog > SOG_NA_KN + SENTINEL_TOL), BAD_SOG)
    cog = stage["cog_deg"].to_numpy(dtype=float)
    fire((cog < 0.0) | (cog > COG_NA_DEG + SENTINEL_TOL), BAD_COG)
    hdg = stage["heading_deg"].to_numpy(dtype=float)
    fire(((hdg < 0.0) | (hdg >= 360.0)) & ~_near(hdg, HEADING_NA_DEG), BAD_HEADING)
    st = stage["nav_status"].to_numpy(dtype=float)
    fire((st < 0) | (st > NAV_STATUS_MAX) | (np.floor(st) != st) & ~np.isnan(st), BAD_NAV_STATUS)
    return reason


def speed_jump_mask(mmsi, t_s, lat_deg, lon_deg, max_speed_kn: float = DEFAULT_MAX_SPEED_KN,
                    fixed=None) -> np.ndarray:
    """Fixes to quarantine as implied-speed jumps (rule 8). Input sorted by (mmsi, time).

    Two fixes of one MMSI are *linked* when the great-circle distance between them is at most
    ``max_speed_kn`` times the time between them. Each track is walked in time order (step 1,
    :func:`ais._jumps.feed`), keeping a *last kept fix*; the next fix

    * continues the segment when it is linked to the last kept fix;
    * else, when the last kept fix is new and the fix before it (in its segment) is linked to
      this one, the last kept fix was a lone outlier: it is quarantined, this one continues;
    * else, when one of the next :data:`ais._jumps.MAX_OUTLIER_RUN` new fixes is linked to the
      last kept fix, the fixes before it were an outlier burst: quarantined, and that fix
      continues the segment;
    * else the track is cut: this fix opens a new segment.

    A segment never mixes stored (``fixed``) and new fixes. Step 2 (:func:`rejected_segments`)
    accepts the segments greedily, the stored ones first, then largest first (earliest on
    ties): a segment is accepted when it is linked to the nearest accepted fix before it and
    after it; the fixes of the others are quarantined. So a lone outlier or a short burst is
    removed even where a coverage gap brings the next fix within reach of it, a bad first fix
    or a second transmitter using the same MMSI is removed while the bulk of the track is kept,
    and afterwards no two consecutive kept fixes of a track imply more than ``max_speed_kn``
    unless both are stored. Stored fixes are context and are never flagged.

    Parameters
    ----------
    mmsi : array_like of int
        Vessel identity, sorted ascending (ties broken by time).
    t_s : array_like of float
        Time of each fix, strictly increasing within one MMSI. [s]
    lat_deg, lon_deg : array_like of float
        Position. [deg]
    max_speed_kn : float
        Highest plausible speed over ground. [kn]
    fixed : array_like of bool, optional
        Fixes already accepted earlier (e.g. stored by a previous file).

    Returns
    -------
    numpy.ndarray of bool
        True for the fixes to quarantine.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.array([0.0, 60.0, 120.0, 180.0])
    >>> lat = np.array([50.0, 50.002, 51.0, 50.006])  # the third fix is 1 degree off
    >>> speed_jump_mask([1, 1, 1, 1], t, lat, np.zeros(4)).tolist()
    [False, False, True, False]
    """
    mmsi = np.asarray(mmsi)
    t = np.asarray(t_s, dtype=float)
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    n = len(mmsi)
    bad = np.zeros(n, dtype=bool)
    fixed = np.zeros(n, dtype=bool) if fixed is None else np.asarray(fixed, dtype=bool)
    if n < 2:
        return bad
    same = mmsi[1:] == mmsi[:-1]
    brk = link_breaks(same, t, lat, lon, max_speed_kn)
    if not brk.any():
        return bad  # every consecutive pair linked: nothing to remove, whatever is stored
    starts = np.flatnonzero(np.r_[True, ~same])
    ends = np.r_[starts[1:], n]
    track_of_link = np.cumsum(np.r_[True, ~same])[:-1] - 1  # track index of link i (fix i -> i+1)
    sel = np.unique(track_of_link[brk])
    si, sf, spikes, cuts, cutf = walk_sorted(starts[sel], ends[sel], t, lat, lon, fixed, max_speed_kn)
    bad[spikes] = True
    for k, _, _, head, _, next_head in rejected_from_walk(si, sf, cuts, cutf, max_speed_kn):
        bad[head:(ends[sel[k]] if next_head < 0 else next_head)] = True
    return bad & ~fixed


def rejected_from_walk(si, sf, cuts, cutf, max_speed_kn: float) -> list[tuple]:
    """Step 2 of :func:`speed_jump_mask` on the segments of a walk (:mod:`ais._jumps`): the
    rejected segments of every track with a cut, as ``(track, first ordinal, end ordinal,
    first line, last line, first line of the next segment or -1)``; ordinals count the kept
    fixes of the track (outliers left out) from 0."""
    J = _jumps
    out = []
    if not len(cuts):
        return out
    order = np.argsort(cuts[:, 0], kind="stable")  # a track's cuts stay in walk (time) order
    cuts, cutf = cuts[order], cutf[order]
    bounds = np.flatnonzero(np.r_[True, cuts[1:, 0] != cuts[:-1, 0], True])
    vmax = float(max_speed_kn)
    for s, e in zip(bounds[:-1], bounds[1:]):
        c = int(cuts[s, 0])
        opens = [0] + cuts[s:e, 1].tolist() + [int(si[c, J._S_K])]
        heads = [tuple(sf[c, J._F_FIRST:J._F_FIRST + 3])] + [tuple(x) for x in cutf[s:e, 3:6]]
        tails = [tuple(x) for x in cutf[s:e, 0:3]] + [tuple(sf[c, J._F_A:J._F_A + 3])]
        head_line = [int(si[c, J._S_FIRST_LINE])] + cuts[s:e, 3].tolist()
        tail_line = cuts[s:e, 2].tolist() + [int(si[c, J._S_A_LINE])]
        pinned = [bool(si[c, J._S_FIRST_FIXED])] + cuts[s:e, 4].astype(bool).tolist()
        lengths = [opens[q + 1] - opens[q] for q in range(len(opens) - 1)]
        for q in rejected_segments(lengths, pinned,
                                   lambda p, q, tails=tails, heads=heads: not J.broken(*tails[p], *heads[q], vmax)):
            out.append((c, opens[q], opens[q + 1], head_line[q], tail_line[q],
                        head_line[q + 1] if q + 1 < len(head_line) else -1))
    return out


def rejected_segments(lengths, pinned, linked_seg) -> list[int]:
    """The greedy step of :func:`speed_jump_mask` on one track cut into segments.

    ``lengths[q]``: number of fixes of segment q (segments in time order); ``pinned[q]``: the
    segment's fixes are stored ones (a segment never mixes stored and new fixes);
    ``linked_seg(p, q)`` (p < q): whether the last fix of
    segment p and the first fix of segment q are linked. Segments are taken pinned first, then
    largest first, earliest first on ties; one is accepted when it is linked to the nearest
    accepted segment before it and after it. Returns the rejected segments, in the order they
    were judged."""
    order = sorted(range(len(lengths)), key=lambda q: (not pinned[q], -lengths[q], q))
    accepted: list[int] = []
    rejected: list[int] = []
    for q in order:
        pos = bisect.bisect_left(accepted, q)
        if pinned[q]:
            accepted.insert(pos, q)
            continue
        ok = True
        if pos > 0 and not linked_seg(accepted[pos - 1], q):
            ok = False
        if ok and pos < len(accepted) and not linked_seg(q, accepted[pos]):
            ok = False
        if ok:
            accepted.insert(pos, q)
        else:
            rejected.append(q)
    return rejected


def jump_context(new: pd.DataFrame, existing: pd.DataFrame) -> pd.DataFrame:
    """Stored fixes that are context for the speed-jump rule of a new batch.

    For every MMSI of ``new`` (columns ``mmsi``, ``time_utc``): the stored fixes inside the
    batch's time span of that MMSI, plus the nearest stored fix before and after it.
    """
    cols = ["mmsi", "time_utc", "lat_deg", "lon_deg"]
    if existing is None or existing.empty or new.empty:
        return pd.DataFrame({c: pd.Series(dtype=new[c].dtype) for c in cols})
    span = new.groupby("mmsi")["time_utc"].agg(["min", "max"]).reset_index()
    ex = existing[cols].merge(span, on="mmsi")
    inside = ex[(ex.time_utc >= ex["min"]) & (ex.time_utc <= ex["max"])]
    before = ex[ex.time_utc < ex["min"]].sort_values("time_utc").groupby("mmsi").tail(1)
    after = ex[ex.time_utc > ex["max"]].sort_values("time_utc").groupby("mmsi").head(1)
    return pd.concat([inside, before, after])[cols].reset_index(drop=True)


@dataclass
class CleanResult:
    """Outcome of :func:`clean_positions` for one typed stage."""

    #: Canonical positions to load (``POSITION_COLUMNS`` + ``source_line``), sorted by mmsi, time.
    positions: pd.DataFrame
    #: Rows not loaded: ``line``, ``raw``, ``reason``, ``mmsi``, ``time_utc``.
    quarantine: pd.DataFrame
    #: Static rows and attributes, latest per MMSI (see :func:`vessel_updates`).
    vessels: pd.DataFrame
    counts: dict = field(default_factory=dict)


def classify(stage: pd.DataFrame, max_speed_kn: float = DEFAULT_MAX_SPEED_KN,
             existing: pd.DataFrame | None = None) -> pd.DataFrame:
    """Apply rules 1-8 to a typed stage; return it normalised with a ``reason`` column.

    Parameters
    ----------
    stage : pandas.DataFrame
        A typed stage (:data:`STAGE_COLUMNS`), any row order.
    max_speed_kn : float
        Implied-speed limit of rule 8. [kn]
    existing : pandas.DataFrame, optional
        Positions already stored (``POSITION_COLUMNS``): rows with one of their (mmsi, time_utc)
        keys are duplicates.

    Returns
    -------
    pandas.DataFrame
        The stage sorted by ``line`` with sentinels normalised (rule 6) and ``reason``
        (``None`` = load). Static rows keep ``reason`` ``None``.
    """
    st = conform_stage(stage).sort_values("line", kind="stable").reset_index(drop=True)
    reason = row_reasons(st)
    lon, sog, cog, hdg = normalise_motion(st["lon_deg"], st["sog_kn"], st["cog_deg"], st["heading_deg"])
    st["lon_deg"], st["sog_kn"], st["cog_deg"], st["heading_deg"] = lon, sog, cog, hdg

    ok = (st["kind"].to_numpy() != KIND_STATIC) & np.array([r is None for r in reason], dtype=bool)
    cand = st.loc[ok, POSITION_COLUMNS + ["line"]].copy()
    cand["mmsi"] = cand["mmsi"].astype("int64")
    values = ["lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status"]
    if len(cand):
        # the first row of each (mmsi, time) by line: groupby "first" would take each column's
        # first non-null value, and an empty field would then match a later row's value
        first_at = cand.groupby(["mmsi", "time_utc"], sort=False)["line"].transform("idxmin")
        ref = cand.loc[first_at.to_numpy(), values].set_axis(cand.index)
        is_first = (first_at.to_numpy() == cand.index.to_numpy())
        if existing is not None and len(existing):
            ex = existing[POSITION_COLUMNS].copy()
            ex["mmsi"] = ex["mmsi"].astype("int64")
            ex["time_utc"] = pd.to_datetime(ex["time_utc"], utc=True).astype("datetime64[ns, UTC]")
            ex = ex.drop_duplicates(["mmsi", "time_utc"])
            joined = cand[["mmsi", "time_utc"]].merge(ex, on=["mmsi", "time_utc"], how="left", indicator=True)
            in_db = (joined["_merge"] == "both").to_numpy()
            ex_vals = joined[values].set_axis(ref.index)
            ref = ref.where(~pd.Series(in_db, index=ref.index), ex_vals, axis=0) if in_db.any() else ref
        else:
            in_db = np.zeros(len(cand), dtype=bool)
        dup = ~is_first | in_db
        a = cand[values].to_numpy(dtype=float)
        b = ref.to_numpy(dtype=float)
        same = np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1)
        dup_reason = np.where(same, DUPLICATE, DUPLICATE_TIME)
        idx = np.flatnonzero(ok)
        reason[idx[dup]] = dup_reason[dup]

        keep = cand.loc[~dup]
        ctx = pd.DataFrame()
        if existing is not None and len(existing):
            ex = existing[POSITION_COLUMNS].copy()
            ex["mmsi"] = ex["mmsi"].astype("int64")
            ex["time_utc"] = pd.to_datetime(ex["time_utc"], utc=True).astype("datetime64[ns, UTC]")
            ctx = jump_context(keep, ex)
        both = pd.concat([keep.assign(_new=True), ctx.assign(_new=False, line=-1)]) if len(ctx) else keep.assign(_new=True)
        both = both.sort_values(["mmsi", "time_utc"], kind="stable")
        t_s = both["time_utc"].to_numpy(dtype="datetime64[ns]").astype("int64") / 1e9
        jump = speed_jump_mask(both["mmsi"].to_numpy(dtype="int64"), t_s, both["lat_deg"].to_numpy(dtype=float),
                               both["lon_deg"].to_numpy(dtype=float), max_speed_kn,
                               fixed=~both["_new"].to_numpy(dtype=bool))
        jumped_lines = set(both["line"].to_numpy()[jump].tolist())
        sel = keep["line"].isin(jumped_lines).to_numpy()
        reason[keep.index.to_numpy()[sel]] = SPEED_JUMP
    st["reason"] = reason
    return st


def vessel_updates(stage: pd.DataFrame) -> pd.DataFrame:
    """Static attributes per MMSI from a typed stage: the latest non-missing value of each field.

    Rows with a valid MMSI contribute, whatever happened to their position; "latest" orders by
    ``time_utc`` (missing times first) and then by ``line``.
    """
    st = conform_stage(stage)
    st = st.loc[valid_mmsi(st["mmsi"])]
    cols = ["mmsi", "updated_utc"] + STATIC_COLUMNS
    if st.empty:
        return pd.DataFrame({c: pd.Series(dtype=STAGE_COLUMNS.get(c, "datetime64[ns, UTC]")) for c in cols})
    st = st.assign(_t=st["time_utc"].fillna(pd.Timestamp("1677-09-22", tz="UTC")))
    st = st.sort_values(["mmsi", "_t", "line"], kind="stable")
    g = st.groupby("mmsi", sort=True)
    out = g[STATIC_COLUMNS].last()  # last non-null per column
    out.insert(0, "updated_utc", g["time_utc"].max())
    out = out.reset_index()
    has_any = out[STATIC_COLUMNS].notna().any(axis=1)
    return out.loc[has_any, cols].reset_index(drop=True)


def summarise(classified: pd.DataFrame) -> dict:
    """Counts of one classified stage: read, loaded, quarantined, duplicates, static, reasons."""
    pos = classified.loc[classified["kind"] != KIND_STATIC, "reason"]
    reasons = pos.dropna().value_counts().sort_index()
    dups = int(reasons[reasons.index.isin(DUPLICATE_CODES)].sum())
    return {
        "read": int(len(pos)),
        "loaded": int(pos.isna().sum()),
        "quarantined": int(reasons.sum()) - dups,
        "duplicates": dups,
        "static": int((classified["kind"] == KIND_STATIC).sum()),
        "reasons": {str(k): int(v) for k, v in reasons.items()},
    }


def clean_positions(stage: pd.DataFrame, max_speed_kn: float = DEFAULT_MAX_SPEED_KN,
                    existing: pd.DataFrame | None = None) -> CleanResult:
    """Pure cleaning of one typed stage (the in-memory twin of the DuckDB ingest).

    Returns the positions to load (canonical columns plus ``source_line``, sorted by mmsi and
    time), the quarantine (line, raw, reason, mmsi, time_utc, including duplicates), the static
    vessel updates and the counts, which always satisfy ``read = loaded + quarantined +
    duplicates``.
    """
    c = classify(stage, max_speed_kn=max_speed_kn, existing=existing)
    pos_rows = c["kind"] != KIND_STATIC
    good = c.loc[pos_rows & c["reason"].isna()]
    positions = good[POSITION_COLUMNS].copy()
    positions["mmsi"] = positions["mmsi"].astype("int64")
    positions["source_line"] = good["line"].to_numpy()
    positions = positions.sort_values(["mmsi", "time_utc"], kind="stable").reset_index(drop=True)
    q = c.loc[pos_rows & c["reason"].notna(), ["line", "raw", "reason", "mmsi", "time_utc"]].reset_index(drop=True)
    return CleanResult(positions=positions, quarantine=q, vessels=vessel_updates(c), counts=summarise(c))
