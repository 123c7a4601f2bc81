"""Reader for the project's port lists (``data/ports.csv``, ``data/ports_terminals.csv``).

``data/ports.csv`` holds the ports of the demo region (the scenario generator's contract);
``data/ports_terminals.csv`` holds further places the port matcher should know by name, such as
the New York harbour ferry terminals used by the real-data tests. Both have the same schema.

Columns: ``locode,name,country,lat_deg,lon_deg,approach_lat_deg,approach_lon_deg`` (UN/LOCODE,
name, ISO country code, the port's position, and an approach point at sea). Several rows may
share a LOCODE when the list names individual terminals of one port (New York: St. George,
Whitehall, Pier 11 ... are all ``USNYC``); each row is then a separate place for port matching.
An optional ``radius_nmi`` column gives a place's own match radius (``lanes.ports``). Extra
columns are kept.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pandas as pd

from thresholds.errors import StormlaneError

PORT_LIST_COLUMNS = ["locode", "name", "country", "lat_deg", "lon_deg", "approach_lat_deg", "approach_lon_deg"]


class PortListError(StormlaneError):
    """The port list is malformed (the message names the file, line and field)."""


def read_port_list(path: str | Path) -> tuple[pd.DataFrame, dict]:
    """Read and validate the port list.

    Returns
    -------
    (DataFrame, dict)
        One row per listed place, columns :data:`PORT_LIST_COLUMNS` (+ extra ones, + ``line``,
        the 1-based line number in the file); metadata with ``path`` and ``rows``.

    Raises
    ------
    PortListError
        Missing file or column, empty or duplicate name, non-numeric or out-of-range coordinate,
        naming the file, line and field.
    """
    path = Path(path)
    if not path.is_file():
        raise PortListError(f"{path}: port list not found")
    with path.open(newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        header = reader.fieldnames or []
        missing = [c for c in PORT_LIST_COLUMNS if c not in header]
        if missing:
            raise PortListError(f"{path}:1: missing column(s) {missing}; expected {PORT_LIST_COLUMNS}")
        rows = []
        seen: dict[tuple[str, str], int] = {}
        for lineno, raw in enumerate(reader, start=2):
            if not any((v or "").strip() for v in raw.values()):
                continue
            row = {k: (v.strip() if isinstance(v, str) else v) for k, v in raw.items() if k is not None}
            for field in ("locode", "name"):
                if not row.get(field):
                    raise PortListError(f"{path}:{lineno}: field {field!r} is empty")
            for field, lo, hi in (("lat_deg", -90, 90), ("lon_deg", -180, 180),
                                  ("approach_lat_deg", -90, 90), ("approach_lon_deg", -180, 180)):
                try:
                    value = float(row[field])
                except (TypeError, ValueError):
                    raise PortListError(f"{path}:{lineno}: field {field!r} = {row.get(field)!r} is not a number") from None
                if not (np.isfinite(value) and lo <= value <= hi):
                    raise PortListError(f"{path}:{lineno}: field {field!r} = {value} is outside [{lo}, {hi}]")
                row[field] = value
            if "radius_nmi" in row and row["radius_nmi"] not in (None, ""):
                try:
                    radius = float(row["radius_nmi"])
                except (TypeError, ValueError):
                    raise PortListError(f"{path}:{lineno}: field 'radius_nmi' = {row['radius_nmi']!r} is not a number") from None
                if not (np.isfinite(radius) and radius > 0):
                    raise PortListError(f"{path}:{lineno}: field 'radius_nmi' = {radius} must be positive")
                row["radius_nmi"] = radius
            elif "radius_nmi" in row:
                row["radius_nmi"] = np.nan
            key = (row["locode"], row["name"])
            if key in seen:
                raise PortListError(f"{path}:{lineno}: duplicate port {key} (first on line {seen[key]})")
            seen[key] = lineno
            row["line"] = lineno
            rows.append(row)
    df = pd.DataFrame(rows, columns=[*header, "line"]) if rows else pd.DataFrame(columns=[*PORT_LIST_COLUMNS, "line"])
    for col in ("lat_deg", "lon_deg", "approach_lat_deg", "approach_lon_deg", "radius_nmi"):
        if col in df.columns:
            df[col] = df[col].astype(float)
    return df, {"path": str(path), "rows": int(len(df))}


def read_port_lists(paths) -> tuple[pd.DataFrame, dict]:
    """Several port lists as one (e.g. ``data/ports.csv`` + ``data/ports_terminals.csv``).

    Rows keep their file in ``source``; the same (locode, name) in two files is an error.
    """
    frames, meta = [], {"paths": [], "rows": 0}
    seen: dict[tuple[str, str], str] = {}
    for path in paths:
        df, m = read_port_list(path)
        for key in zip(df["locode"], df["name"]):
            if key in seen:
                raise PortListError(f"{path}: port {key} is already listed in {seen[key]}")
            seen[key] = str(path)
        frames.append(df.assign(source=str(path)))
        meta["paths"].append(str(path))
        meta["rows"] += m["rows"]
    if not frames:
        return pd.DataFrame(columns=[*PORT_LIST_COLUMNS, "line", "source"]), meta
    return pd.concat(frames, ignore_index=True), meta
