"""Parquet AIS files with the canonical columns, or the common aliases mapped onto them.

The canonical names (``mmsi``, ``time_utc``, ``lat_deg``, ``lon_deg``, ``sog_kn``, ``cog_deg``,
``heading_deg``, ``nav_status`` and the static ``imo``, ``name``, ``callsign``, ``ship_type``,
``length_m``, ``beam_m``, ``draught_m``, ``destination``) are used as they are. Otherwise the
first alias found (case-insensitive) is used, e.g. the New York harbour file of MarineCadastre
(``../shared/data/ais/portcalls``): ``time`` -> ``time_utc``, ``lat`` -> ``lat_deg``,
``lon`` -> ``lon_deg``, ``vessel_name`` -> ``name``, ``vessel_type`` -> ``ship_type``,
``width_m`` -> ``beam_m``, ``draft_m`` -> ``draught_m`` (``sog_kn``, ``cog_deg``, ``nav_status``,
``length_m`` are already canonical). Timestamps without a time zone are taken as UTC.

The Ushant trajectories (``traj_id``, relative ``t_s``) are not AIS messages: they have no MMSI
and no absolute time, so this reader refuses them with a message pointing to their own reader.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ais.clean import BAD_COG, BAD_HEADING, BAD_LAT, BAD_LON, BAD_NAV_STATUS, BAD_SOG, KIND_POSITION, conform_stage
from ais.errors import AisFormatError
from ais.io.csv_formats import type_static

#: stage field -> accepted source names, canonical first.
ALIASES = {
    "mmsi": ("mmsi",),
    "time_utc": ("time_utc", "time", "timestamp", "basedatetime", "base_date_time", "datetime"),
    "lat_deg": ("lat_deg", "lat", "latitude"),
    "lon_deg": ("lon_deg", "lon", "longitude"),
    "sog_kn": ("sog_kn", "sog", "speed_kn"),
    "cog_deg": ("cog_deg", "cog", "course_deg"),
    "heading_deg": ("heading_deg", "heading"),
    "nav_status": ("nav_status", "status", "navigational_status"),
    "imo": ("imo",),
    "name": ("name", "vessel_name", "vesselname", "shipname"),
    "callsign": ("callsign", "call_sign"),
    "ship_type": ("ship_type", "vessel_type", "vesseltype", "shiptype"),
    "length_m": ("length_m", "length"),
    "beam_m": ("beam_m", "width_m", "width", "beam"),
    "draught_m": ("draught_m", "draft_m", "draught", "draft"),
    "destination": ("destination",),
}
REQUIRED = ("mmsi", "time_utc", "lat_deg", "lon_deg")
_FIELD_CODES = {"lat_deg": BAD_LAT, "lon_deg": BAD_LON, "sog_kn": BAD_SOG, "cog_deg": BAD_COG,
                "heading_deg": BAD_HEADING, "nav_status": BAD_NAV_STATUS}


#: Column types that hold numbers: a time column of one of these is refused (``column_mapping``).
_NUMERIC_TYPES = ("INT", "DECIMAL", "DOUBLE", "FLOAT", "REAL", "NUMERIC")


def column_mapping(columns, path, types: dict | None = None) -> dict[str, str]:
    """Stage field -> source column for the columns of a Parquet file.

    ``types`` (column -> DuckDB type name), when given, is checked too: a time column of numbers
    is refused, since epoch seconds, milliseconds and nanoseconds cannot be told apart (read as
    times they quarantined every row as ``bad_time``, the file said to "have no time").

    Raises
    ------
    AisFormatError
        When a required column (mmsi, time, lat, lon) is missing, or the time column holds numbers.
    """
    lower = {c.lower(): c for c in columns}
    mapping = {}
    for fld, names in ALIASES.items():
        for n in names:
            if n in lower:
                mapping[fld] = lower[n]
                break
    missing = [f for f in REQUIRED if f not in mapping]
    if missing:
        hint = ""
        if "traj_id" in lower:
            hint = (" (this looks like the Ushant trajectory set: anonymised trajectory ids, no MMSI and times "
                    "relative to each trajectory's start, so it cannot enter the AIS tables; read it with "
                    "lanes.io.ushant.read_ushant(path, epoch_utc) and run the lanes chain on it, as "
                    "bench/lanes.py does - see docs/lanes.md)")
        raise AisFormatError(
            path, f"Parquet file lacks column(s) for {', '.join(missing)}; columns are {', '.join(columns)}{hint}"
        )
    ttype = str((types or {}).get(mapping["time_utc"], "")).upper()
    if any(k in ttype for k in _NUMERIC_TYPES):
        raise AisFormatError(path, f"Parquet column {mapping['time_utc']!r} (the time) holds numbers ({ttype}), not times: "
                                   "epoch seconds, milliseconds and nanoseconds cannot be told apart; store it as a "
                                   "timestamp or as ISO 8601 text")
    return mapping


def read_parquet_stage(path) -> tuple[pd.DataFrame, dict]:
    """Read a Parquet AIS file into a typed stage (pure path; the bulk ingest uses DuckDB)."""
    import pyarrow.parquet as pq

    path = Path(path)
    table = pq.read_table(path)
    df = table.to_pandas()
    numeric = {c: "DOUBLE" for c in df.columns if pd.api.types.is_numeric_dtype(df[c]) and not pd.api.types.is_bool_dtype(df[c])}
    mapping = column_mapping(list(df.columns), path, types=numeric)
    n = len(df)
    out = pd.DataFrame({"line": np.arange(1, n + 1, dtype=np.int64)})
    out["raw"] = df.astype(str).where(df.notna(), "").agg(",".join, axis=1) if n else []
    out["kind"] = KIND_POSITION
    perr = np.full(n, None, dtype=object)

    m = df[mapping["mmsi"]]
    if pd.api.types.is_numeric_dtype(m):
        mf = pd.to_numeric(m, errors="coerce").astype(float)
        ok = mf.notna() & (np.floor(mf) == mf)
        out["mmsi"] = pd.array(np.where(ok, mf, np.nan), dtype="Float64").astype("Int64")
    else:
        s = m.astype("string").str.strip()
        ok = s.str.fullmatch(r"[0-9]{9}").fillna(False)
        out["mmsi"] = pd.array([int(x) if k else pd.NA for x, k in zip(s, ok)], dtype="Int64")

    t = df[mapping["time_utc"]]
    t = pd.to_datetime(t, errors="coerce", utc=True)
    out["time_utc"] = t
    for fld in ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status"):
        if fld in mapping:
            col = df[mapping[fld]]
            vals = pd.to_numeric(col, errors="coerce").astype(float)
            bad = col.notna() & vals.isna()
            perr[bad.to_numpy() & np.equal(perr, None)] = _FIELD_CODES[fld]
            out[fld] = vals
    out["parse_error"] = perr
    texts = pd.DataFrame(index=df.index)
    for fld in ("imo", "ship_type", "name", "callsign", "destination", "length_m", "beam_m", "draught_m"):
        if fld in mapping:
            col = df[mapping[fld]]
            texts[fld] = col.map(lambda v: "" if v is None or (isinstance(v, float) and np.isnan(v)) or v is pd.NA
                                 else (str(int(v)) if isinstance(v, (int, np.integer)) else str(v)))
    typed = type_static(texts)
    for c in typed.columns:
        out[c] = typed[c].to_numpy()
    return conform_stage(out), {"format": "parquet", "path": str(path), "mapping": mapping, "ignored": 0}
