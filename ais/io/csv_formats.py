"""DMA and NOAA MarineCadastre CSV: column specs, field typing, and the in-memory reader.

Both formats are described by a :class:`CsvSpec`; the bulk ingest turns the same spec into
DuckDB SQL (``pipelines/storage/ais/stage_lines.py``), and :func:`read_csv_stage` here applies it in pandas
(the pure path, used for small files and to test that both give the same typed stage).

Typing rules shared by both executions (one row per physical line, split on ``\\n`` with a
trailing ``\\r`` removed):

* A line is split on commas; a line containing a double quote is parsed as one RFC 4180 record
  (Python's :mod:`csv`). A line with another number of fields than the header is ``bad_line``.
  Empty lines are skipped and counted as ``ignored``; lines equal to the header (files
  concatenated with their headers) are skipped.
* Every field is trimmed of ASCII white space (:data:`WS`, as DuckDB's casts do). An empty
  field is missing.
* MMSI: exactly 9 ASCII digits, else missing (quarantined as ``bad_mmsi``).
* Timestamp: the spec's formats (DMA day-first ``%d/%m/%Y %H:%M:%S``; NOAA ISO-8601), UTC;
  a second of 60 or more is no time (AIS uses 60-63 for "not available"), nor is a time outside
  the range of pandas' nanosecond timestamps (1677-2262).
* Latitude, longitude, SOG, COG, heading: a decimal number (as ``TRY_CAST(x AS DOUBLE)`` reads
  it; "nan" is not a number); other text sets ``parse_error`` to ``bad_<field>`` (the first
  such field in that order).
* Navigational status: a number, or one of the DMA status texts (:data:`NAV_STATUS_WORDS`).
* Static fields never reject a row: unknown values ("Unknown", "Undefined", "", garbage) are
  missing. IMO may carry an ``IMO`` prefix; ship type may be a DMA category word, mapped to the
  category's "all ships of this type" code (ITU-R M.1371-5 Table 53).

References
----------
.. [1] Danish Maritime Authority, "AIS data" (historical CSV, column description), 2024.
       http://web.ais.dk/aisdata/
.. [2] NOAA Office for Coastal Management, "AIS data dictionary," MarineCadastre.gov, 2023.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ais.clean import (
    BAD_COG,
    BAD_HEADING,
    BAD_LAT,
    BAD_LINE,
    BAD_LON,
    BAD_NAV_STATUS,
    BAD_SOG,
    KIND_POSITION,
    conform_stage,
)
from ais.errors import AisFormatError
from ais.io.files import normalise_header_name, read_content

#: DMA navigational status texts (lower case) -> ITU-R M.1371-5 code.
NAV_STATUS_WORDS = {
    "under way using engine": 0,
    "at anchor": 1,
    "not under command": 2,
    "restricted manoeuverability": 3,
    "restricted maneuverability": 3,
    "restricted manoeuvrability": 3,
    "constrained by her draught": 4,
    "moored": 5,
    "aground": 6,
    "engaged in fishing": 7,
    "under way sailing": 8,
    "reserved for future amendment [hsc]": 9,
    "reserved for future amendment [wig]": 10,
    "power-driven vessel towing astern": 11,
    "power-driven vessel pushing ahead or towing alongside": 12,
    "reserved for future use": 13,
    "ais-sart": 14,
    "unknown value": 15,
    "unknown": 15,
    "undefined": 15,
}

#: DMA ship type categories (lower case) -> the category's AIS ship type code.
SHIP_TYPE_WORDS = {
    "wig": 20,
    "fishing": 30,
    "towing": 31,
    "towing long/wide": 32,
    "dredging": 33,
    "diving": 34,
    "military": 35,
    "sailing": 36,
    "pleasure": 37,
    "hsc": 40,
    "pilot": 50,
    "sar": 51,
    "tug": 52,
    "port tender": 53,
    "anti-pollution": 54,
    "law enforcement": 55,
    "spare 1": 56,
    "spare 2": 57,
    "medical": 58,
    "not party to conflict": 59,
    "passenger": 60,
    "cargo": 70,
    "tanker": 80,
    "other": 90,
}


#: Static text values that mean "not known".
NULL_WORDS = ("", "unknown", "undefined", "n/a", "na", "none", "null")

#: Position fields typed as numbers, in the order their parse errors are reported.
NUMERIC_FIELDS = {
    "lat_deg": BAD_LAT,
    "lon_deg": BAD_LON,
    "sog_kn": BAD_SOG,
    "cog_deg": BAD_COG,
    "heading_deg": BAD_HEADING,
}
STATIC_TEXT_FIELDS = ("name", "callsign", "destination")
STATIC_NUMBER_FIELDS = ("length_m", "beam_m", "draught_m")


@dataclass(frozen=True)
class CsvSpec:
    """How one CSV format maps onto the typed stage."""

    format: str
    #: stage field -> accepted header names (compared after :func:`normalise_header_name`).
    columns: dict = field(default_factory=dict)
    #: stage fields whose column must be present.
    required: tuple = ()
    #: strptime formats of the timestamp, tried in order; times are UTC.
    time_formats: tuple = ()


DMA_SPEC = CsvSpec(
    format="dma",
    columns={
        "time_utc": ("timestamp",),
        "mmsi": ("mmsi",),
        "lat_deg": ("latitude",),
        "lon_deg": ("longitude",),
        "nav_status": ("navigational status",),
        "sog_kn": ("sog",),
        "cog_deg": ("cog",),
        "heading_deg": ("heading",),
        "imo": ("imo",),
        "callsign": ("callsign",),
        "name": ("name",),
        "ship_type": ("ship type",),
        "beam_m": ("width",),
        "length_m": ("length",),
        "draught_m": ("draught",),
        "destination": ("destination",),
    },
    required=("time_utc", "mmsi", "lat_deg", "lon_deg"),
    time_formats=("%d/%m/%Y %H:%M:%S",),
)

#: NOAA's header until 2023 (``MMSI,BaseDateTime,LAT,LON,...,VesselName,...,CallSign,VesselType``)
#: and the snake_case names of its files from 2024 on (``mmsi,base_date_time,latitude,longitude,
#: ...,vessel_name,...,call_sign,vessel_type``; NOAA OCM, "Nationwide Automatic Identification
#: System 2024", https://github.com/ocm-marinecadastre/ais-vessel-traffic).
NOAA_SPEC = CsvSpec(
    format="noaa",
    columns={
        "mmsi": ("mmsi",),
        "time_utc": ("basedatetime", "base_date_time"),
        "lat_deg": ("lat", "latitude"),
        "lon_deg": ("lon", "longitude"),
        "sog_kn": ("sog",),
        "cog_deg": ("cog",),
        "heading_deg": ("heading",),
        "name": ("vesselname", "vessel_name"),
        "imo": ("imo",),
        "callsign": ("callsign", "call_sign"),
        "ship_type": ("vesseltype", "vessel_type"),
        "nav_status": ("status",),
        "length_m": ("length",),
        "beam_m": ("width",),
        "draught_m": ("draft",),
    },
    required=("mmsi", "time_utc", "lat_deg", "lon_deg"),
    time_formats=("%Y-%m-%dT%H:%M:%S", "%Y-%m-%d %H:%M:%S"),
)

SPECS = {"dma": DMA_SPEC, "noaa": NOAA_SPEC}


def split_csv_line(line: str) -> list[str]:
    """Fields of one CSV line: plain comma split, or an RFC 4180 parse when it has quotes."""
    if '"' not in line:
        return line.split(",")
    try:
        rows = list(csv.reader([line], strict=True))
    except csv.Error:
        return [line]  # unterminated quote: one field, hence bad_line
    return rows[0] if rows else [""]


def resolve_columns(spec: CsvSpec, header: list[str], path) -> dict[str, int]:
    """0-based column index of every stage field present in ``header``.

    Raises
    ------
    AisFormatError
        When a required column is missing; the message lists the header found.
    """
    names = [normalise_header_name(h) for h in header]
    index: dict[str, int] = {}
    for fld, accepted in spec.columns.items():
        for i, n in enumerate(names):
            if n in accepted:
                index[fld] = i
                break
    missing = [spec.columns[f][0] for f in spec.required if f not in index]
    if missing:
        raise AisFormatError(
            path, f"{spec.format.upper()} CSV header lacks column(s) {', '.join(missing)}; header is {','.join(header)!r}",
            line=1,
        )
    return index


def read_lines(path) -> list[str]:
    """Physical lines of a text file (gzip transparent): split on ``\\n``, one trailing ``\\r``
    removed, UTF-8 with undecodable bytes replaced. A final newline does not add a line."""
    data = read_content(path)
    parts = data.split(b"\n")
    if parts and parts[-1] == b"":
        parts.pop()
    out = []
    for p in parts:
        if p.endswith(b"\r"):
            p = p[:-1]
        out.append(p.decode("utf-8", errors="replace"))
    return out


#: ASCII white space trimmed around every field (the set DuckDB's casts ignore).
WS = " \t\n\r\x0b\x0c"
#: Python's white space that is not :data:`WS` (``\s`` less the ASCII white space).
_OTHER_SPACE = r"[^\S \t\n\r\x0b\x0c]"
#: The MMSI text: nine ASCII digits, white space around allowed.
MMSI_RE = "[ \t\n\r\x0b\x0c]*[0-9]{9}[ \t\n\r\x0b\x0c]*"
_TRIM = WS
_MMSI = re.compile(MMSI_RE)


def parse_number(text) -> float:
    """A decimal number as DuckDB's ``TRY_CAST(x AS DOUBLE)`` reads it, or ``None`` when the text
    is not a number (non-ASCII digits and "nan" are refused; ``_`` between digits is accepted by
    both)."""
    if text is None:
        return None
    s = text.strip(_TRIM)
    if not s or not s.isascii() or any(c in WS for c in s):
        return None
    try:
        v = float(s)
    except ValueError:
        return None
    return None if v != v else v


def _clean_text(values: pd.Series) -> pd.Series:
    return values.map(lambda s: s.strip(_TRIM) if isinstance(s, str) else "")


def type_fields(fields: pd.DataFrame, spec: CsvSpec) -> pd.DataFrame:
    """Type the text fields of CSV rows (columns named by stage field) into a typed stage.

    ``fields`` must have ``line`` and ``raw`` and a text column per stage field present in the
    file; ``n_fields_ok`` (bool) says whether the line had the header's number of fields.
    """
    n = len(fields)
    out = pd.DataFrame({"line": fields["line"].astype("int64"), "raw": fields["raw"].astype(object)})
    out["kind"] = KIND_POSITION
    perr = np.full(n, None, dtype=object)
    perr[~fields["n_fields_ok"].to_numpy(dtype=bool)] = BAD_LINE

    def text(name):
        return _clean_text(fields[name]) if name in fields.columns else pd.Series([""] * n, index=fields.index)

    m = text("mmsi")
    ok = m.map(lambda s: _MMSI.fullmatch(s) is not None)
    out["mmsi"] = pd.array([int(s) if k else pd.NA for s, k in zip(m, ok)], dtype="Int64")

    t = text("time_utc")
    parsed = pd.Series(pd.NaT, index=t.index, dtype="datetime64[ns]")
    for fmt in spec.time_formats:
        todo = parsed.isna() & (t != "")
        if todo.any():
            parsed[todo] = pd.to_datetime(t[todo], format=fmt, errors="coerce")
    # pandas' strptime takes a space of the format as any Unicode white space (Python's \s, also
    # \x1c-\x1f, \x85, \xa0, ...); the SQL stages and the compiled scan take only ASCII white
    # space (C's isspace, :data:`WS`) there: a time holding another kind is no time on every path
    # (found by `make fuzz`, 2026-11-28: "01/01/2025\x1f00:00:00").
    parsed[t.str.contains(_OTHER_SPACE, regex=True).to_numpy(dtype=bool)] = pd.NaT
    # strptime's %S takes 60 and 61; in AIS a second of 60-63 means "time stamp not available"
    # (ITU-R M.1371-5, Annex 2, Table 45, "Time stamp"), so such a time is not a time.
    sec = pd.to_numeric(t.str.extract(r":(\d+)$", expand=False), errors="coerce")
    parsed[(sec >= 60).to_numpy()] = pd.NaT
    out["time_utc"] = parsed.dt.tz_localize("UTC")

    for name, code in NUMERIC_FIELDS.items():
        raw = text(name)
        vals = raw.map(parse_number)
        bad = (raw != "") & vals.isna()
        perr[np.asarray(bad) & np.equal(perr, None)] = code
        out[name] = vals.astype(float)

    st = text("nav_status")
    num = st.map(parse_number)
    word = st.str.lower().map(NAV_STATUS_WORDS)
    status = num.where(num.notna(), word)
    bad = (st != "") & status.isna()
    perr[np.asarray(bad) & np.equal(perr, None)] = BAD_NAV_STATUS
    out["nav_status"] = status.astype(float)
    out["parse_error"] = perr

    for name in ("imo", "ship_type") + STATIC_TEXT_FIELDS + STATIC_NUMBER_FIELDS:
        out[name] = text(name)
    typed = type_static(out)
    for name in typed.columns:
        out[name] = typed[name]
    out.loc[~fields["n_fields_ok"].to_numpy(dtype=bool), ["mmsi"]] = pd.NA
    return conform_stage(out)


def static_text_ok(values: pd.Series) -> pd.Series:
    """True where a static text value is not one of :data:`NULL_WORDS`."""
    return ~values.fillna("").str.strip(_TRIM).str.lower().isin(NULL_WORDS)


def type_static(texts: pd.DataFrame) -> pd.DataFrame:
    """Static text fields (trimmed) to typed values; unknown or invalid values become missing."""
    out = pd.DataFrame(index=texts.index)
    if "imo" in texts:
        s = texts["imo"].fillna("").str.strip(_TRIM)
        s = s.where(~s.str.upper().str.startswith("IMO"), s.str[3:]).str.strip(_TRIM)
        ok = s.map(lambda x: 0 < len(x) <= 9 and x.isascii() and x.isdigit())
        vals = [int(x) if k else pd.NA for x, k in zip(s, ok)]
        imo = pd.array(vals, dtype="Int64")
        out["imo"] = pd.array(np.where((pd.Series(imo).fillna(0) > 0).to_numpy(), imo, pd.NA), dtype="Int64")
    if "ship_type" in texts:
        s = texts["ship_type"].fillna("").str.strip(_TRIM)
        num = s.map(parse_number)
        word = s.str.lower().map(SHIP_TYPE_WORDS)
        code = num.where(num.notna(), word).astype(float)
        valid = (code >= 1) & (code <= 99) & (np.floor(code) == code)
        out["ship_type"] = pd.array(np.where(valid, code, np.nan), dtype="Float64").astype("Int64")
    for name in STATIC_TEXT_FIELDS:
        if name in texts:
            s = texts[name].fillna("").str.strip(_TRIM)
            out[name] = s.where(static_text_ok(s), None).astype(object)
    for name in STATIC_NUMBER_FIELDS:
        if name in texts:
            v = texts[name].map(parse_number).astype(float)
            out[name] = v.where(v > 0)
    return out


def read_csv_stage(path, spec: CsvSpec | None = None) -> tuple[pd.DataFrame, dict]:
    """Read a DMA or NOAA CSV file into a typed stage (pure path).

    Returns
    -------
    (pandas.DataFrame, dict)
        The typed stage (one row per non-empty data line) and metadata: ``format``,
        ``path``, ``header``, ``ignored`` (empty lines).
    """
    path = Path(path)
    lines = read_lines(path)
    if spec is None:
        from ais.io.files import detect_format

        fmt = detect_format(path)
        if fmt not in SPECS:
            raise AisFormatError(path, f"not a CSV AIS file (detected {fmt})")
        spec = SPECS[fmt]
    if not lines:
        raise AisFormatError(path, "empty file: no header line")
    header_text = lines[0].lstrip("\ufeff")
    header = split_csv_line(header_text)
    index = resolve_columns(spec, header, path)
    stage, blank = type_lines(enumerate(lines[1:], start=2), header_text, header, index, spec)
    return stage, {"format": spec.format, "path": str(path), "header": header, "ignored": blank}


def type_lines(numbered, header_text: str, header: list[str], index: dict[str, int],
               spec: CsvSpec) -> tuple[pd.DataFrame, int]:
    """Typed stage rows of CSV data lines given as ``(line number, text)`` pairs.

    Empty lines are skipped and counted (the second value returned); lines equal to the header
    (with or without a byte-order mark) are skipped. Every other line becomes one stage row
    (see the module docstring for the rules).
    """
    rows, nums, oks = [], [], []
    blank = 0
    for i, line in numbered:
        if line == "":
            blank += 1
            continue
        if line == header_text or line == "\ufeff" + header_text:
            continue  # the header repeated (concatenated files): not a record
        f = split_csv_line(line)
        ok = len(f) == len(header)
        rows.append([f[j] if ok else "" for j in index.values()])
        nums.append((i, line))
        oks.append(ok)
    fields = pd.DataFrame(rows, columns=list(index.keys()), dtype=object)
    fields["line"] = pd.Series([n for n, _ in nums], dtype="int64")
    fields["raw"] = pd.Series([r for _, r in nums], dtype=object)
    fields["n_fields_ok"] = pd.Series(oks, dtype=bool)
    return type_fields(fields, spec), blank


def read_dma(path) -> tuple[pd.DataFrame, dict]:
    """Read a DMA CSV file into a typed stage (see :func:`read_csv_stage`)."""
    return read_csv_stage(path, DMA_SPEC)


def read_noaa(path) -> tuple[pd.DataFrame, dict]:
    """Read a NOAA MarineCadastre CSV file into a typed stage (see :func:`read_csv_stage`)."""
    return read_csv_stage(path, NOAA_SPEC)
