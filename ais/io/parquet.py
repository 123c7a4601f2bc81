"""Parquet AIS files with the canonical columns, or the common aliases mapped onto them.

The canonical names (``mmsi``, ``time_utc``, ``lat_deg``, ``lon_deg``, ``sog_kn``, ``cog_deg``,
``heading_deg``, ``nav_status`` and the static ``imo``, ``name``, ``callsign``, ``ship_type``,
``length_m``, ``beam_m``, ``draught_m``, ``destination``) are used as they are. Otherwise the
first alias found (case-insensitive) is used, e.g. the New York harbour file of MarineCadastre
(``../shared/data/ais/portcalls``): ``time`` -> ``time_utc``, ``lat`` -> ``lat_deg``,
``lon`` -> ``lon_deg``, ``vessel_name`` -> ``name``, ``vessel_type`` -> ``ship_type``,
``width_m`` -> ``beam_m``, ``draft_m`` -> ``draught_m`` (``sog_kn``, ``cog_deg``, ``nav_status``,
``length_m`` are already canonical). Timestamps without a time zone are taken as UTC.

A GeoParquet file without latitude and longitude columns (NOAA's daily files from 2024 on, a
GeoParquet 1.0 ``geometry`` column of points [1]) takes its positions from the point geometry:
WKB (:func:`wkb_point_xy`) or GeoArrow's native point struct (``x``, ``y``).

The Ushant trajectories (``traj_id``, relative ``t_s``) are not AIS messages: they have no MMSI
and no absolute time, so this reader refuses them with a message pointing to their own reader.

.. [1] Open Geospatial Consortium, "GeoParquet 1.0.0," 2023, https://geoparquet.org/releases/v1.0.0/
   (geometry columns: WKB encoding); J. R. Herring (ed.), "OpenGIS Implementation Standard for
   Geographic information - Simple feature access - Part 1: Common architecture," OGC 06-103r4,
   v1.2.1, 2011, section 8.2 (Well-known Binary).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ais.clean import BAD_COG, BAD_HEADING, BAD_LAT, BAD_LON, BAD_NAV_STATUS, BAD_SOG, KIND_POSITION, conform_stage
from ais.errors import AisFormatError
from ais.io.csv_formats import NAV_STATUS_WORDS, WS, type_static

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
#: Geometry columns a position may come from when latitude and longitude columns are absent.
GEOMETRY_NAMES = ("geometry", "geom", "wkb_geometry")
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
    geometry = next((lower[n] for n in GEOMETRY_NAMES if n in lower), None)
    if geometry is not None and "lat_deg" not in mapping and "lon_deg" not in mapping:
        mapping["lat_deg"] = mapping["lon_deg"] = geometry  # the point's y and x (see is_geometry)
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

    from ais.io.float32 import widen_float32

    path = Path(path)
    table = pq.read_table(path)
    df = table.to_pandas()
    numeric = {c: "DOUBLE" for c in df.columns if pd.api.types.is_numeric_dtype(df[c]) and not pd.api.types.is_bool_dtype(df[c])}
    mapping = column_mapping(list(df.columns), path, types=numeric)
    n = len(df)
    out = pd.DataFrame({"line": np.arange(1, n + 1, dtype=np.int64)})
    geometry = mapping["lat_deg"] if is_geometry(mapping) else None
    shown = df.apply(lambda c: c.map(geometry_text if c.name == geometry else _blob_text)
                     if c.map(lambda v: isinstance(v, bytes)).any() else c)
    out["raw"] = shown.astype(str).where(df.notna(), "").agg(",".join, axis=1) if n else []
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
    point = geometry_xy(table.column(mapping["lat_deg"])) if is_geometry(mapping) else None
    for fld in ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status"):
        if fld in mapping:
            col = df[mapping[fld]]
            if point is not None and fld in ("lat_deg", "lon_deg"):
                vals = pd.Series(point[1] if fld == "lat_deg" else point[0], index=df.index)
            elif col.dtype == np.float32:  # binary32: the decimal it was written from (ais.io.float32)
                vals = pd.Series(widen_float32(col.to_numpy()), index=df.index)
            else:
                vals = pd.to_numeric(col, errors="coerce").astype(float)
            if fld == "nav_status" and not pd.api.types.is_numeric_dtype(col):  # a number or a DMA word
                words = col.astype("string").str.strip(WS).str.lower().map(NAV_STATUS_WORDS)
                vals = vals.where(vals.notna(), pd.to_numeric(words, errors="coerce").astype(float))
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


def _blob_text(v):
    """A binary value as DuckDB casts a BLOB to text (the bulk path's ``raw``): printable ASCII
    kept except ``"``, ``'`` and ``\\``, every other byte as ``\\xHH``."""
    if not isinstance(v, bytes):
        return v
    return "".join(chr(c) if 32 <= c < 127 and c not in (34, 39, 92) else f"\\x{c:02X}" for c in v)


#: The first 5 bytes of a 2D point's WKB (21 bytes in all), little- and big-endian (OGC 06-103r4, 8.2).
WKB_POINT_HEADS = (b"\x01\x01\x00\x00\x00", b"\x00\x00\x00\x00\x01")


def geometry_text(v):
    """A geometry value of the ``raw`` text: a 2D WKB point as its WKT, ``POINT (x y)``, written
    as DuckDB's ``ST_AsText`` writes it (the bulk path's text: Python's shortest repr without a
    trailing ``.0``, ``-nan`` for a NaN with its sign bit set, ``POINT EMPTY`` when both are NaN;
    the same on 142 k points, random bit patterns included: tests/test_parquet_ingest.py); any
    other value as :func:`_blob_text`. An auditor reads the position of a quarantined row, not
    its bytes."""
    import math
    import struct

    if not (isinstance(v, bytes) and len(v) == 21 and v[:5] in WKB_POINT_HEADS):
        return _blob_text(v)
    x, y = struct.unpack("<dd" if v[0] == 1 else ">dd", v[5:])
    if math.isnan(x) and math.isnan(y):
        return "POINT EMPTY"

    def num(a: float) -> str:
        if math.isnan(a):
            return "-nan" if math.copysign(1.0, a) < 0 else "nan"
        r = repr(a)
        return r[:-2] if r.endswith(".0") else r

    return f"POINT ({num(x)} {num(y)})"


def is_geometry(mapping: dict) -> bool:
    """Whether the positions come from a geometry column (:func:`column_mapping`)."""
    return mapping.get("lat_deg") is not None and mapping.get("lat_deg") == mapping.get("lon_deg")


#: WKB geometry type of a point: ISO codes 1, 1001 (Z), 2001 (M), 3001 (ZM) [1], or EWKB's 1 with
#: its flag bits (0x80000000 Z, 0x40000000 M, 0x20000000 SRID: 4 bytes of SRID before the
#: coordinates, PostGIS). Coordinates follow as IEEE 754 doubles, x (longitude) then y.
_EWKB_FLAGS, _EWKB_SRID = 0xE0000000, 0x20000000


def geometry_xy(column) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` of a point geometry column (pyarrow): WKB (:func:`wkb_point_xy`) or GeoArrow's
    native point struct with fields ``x`` and ``y``. [deg]"""
    import pyarrow as pa
    import pyarrow.compute as pc

    if pa.types.is_struct(column.type):
        return tuple(pc.struct_field(column, k).to_numpy(zero_copy_only=False).astype(float) for k in ("x", "y"))
    return wkb_point_xy(column)


#: Bytes of a 2-D WKB point: byte order, geometry type (uint32), x and y (doubles).
_POINT_2D_BYTES = 21
#: The first five bytes of a little-endian 2-D WKB point: NDR byte order (1), type 1.
_POINT_2D_LE_HEAD = np.array([1, 1, 0, 0, 0], np.uint8)


def _uniform_points_xy(rec: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(x, y)`` of WKB values that are all little-endian 2-D points (``rec``: one 21-byte row
    per value), read as strided doubles; None when any value is not (the general path then).
    GeoParquet writers (GDAL, GeoPandas/Shapely, DuckDB spatial) write points so: decoding them
    byte by byte cost 1.4 CPU us per row, a quarter of the whole Parquet ingest (issue 23)."""
    if not (rec[:, :5] == _POINT_2D_LE_HEAD).all():
        return None
    return (np.ascontiguousarray(rec[:, 5:13]).view("<f8").ravel(),
            np.ascontiguousarray(rec[:, 13:21]).view("<f8").ravel())


def wkb_point_xy(values) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` of WKB points (a pyarrow binary or large binary array, chunked or not; OGC
    06-103r4 section 8.2, byte order per value). NaN where the value is null, shorter than a
    point, another geometry type, or POINT EMPTY (NaN coordinates). [deg]"""
    import pyarrow as pa

    if isinstance(values, pa.ChunkedArray):
        parts = [wkb_point_xy(c) for c in values.chunks]
        if not parts:
            return np.zeros(0), np.zeros(0)
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    arr = values
    n = len(arr)
    x, y = np.full(n, np.nan), np.full(n, np.nan)
    bufs = arr.buffers()
    if n == 0 or bufs[2] is None:
        return x, y
    off = np.frombuffer(bufs[1], np.int64 if pa.types.is_large_binary(arr.type) else np.int32)
    off = off[arr.offset: arr.offset + n + 1].astype(np.int64)
    data = np.frombuffer(bufs[2], np.uint8)
    start, length = off[:-1], np.diff(off)
    if arr.null_count == 0 and (length == _POINT_2D_BYTES).all():
        uniform = _uniform_points_xy(data[off[0]: off[-1]].reshape(n, _POINT_2D_BYTES))
        if uniform is not None:
            return uniform
    ok = np.asarray(arr.is_valid()) & (length >= 21)
    i = np.nonzero(ok)[0]
    s, le = start[i], data[start[i]] == 1

    def take(at, k):  # k bytes from each value at byte offset ``at``, as the value's byte order
        b = data[at[:, None] + np.arange(k)]
        return np.where(le[:, None], b, b[:, ::-1])

    code = take(s + 1, 4).astype(np.uint64) @ (np.uint64(1) << (np.arange(4, dtype=np.uint64) * np.uint64(8)))
    base = (code & ~np.uint64(_EWKB_FLAGS)) % np.uint64(1000)
    first = s + 5 + np.where((code & np.uint64(_EWKB_SRID)) != 0, 4, 0)
    point = (base == 1) & (first + 16 <= start[i] + length[i])
    i, first, le = i[point], first[point], le[point]
    x[i] = take(first, 8).copy().view("<f8").ravel()
    y[i] = take(first + 8, 8).copy().view("<f8").ravel()
    return x, y
