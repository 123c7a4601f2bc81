"""One archive of route exports per night (``exports.zip``) with an index.

The nightly run used to write three files per adverse lane-departure (a GeoJSON of every route,
GPX and RTZ of the proposed one): 323 files and 51 MB on the demo night. Now one archive holds,
by default, the **proposed routes only** (per case with a proposal: ``<stem>_<role>.rtz`` for an
ECDIS, ``.gpx``, ``.geojson``), or with ``mode="all"`` every route of every adverse case (one
GeoJSON with all of them, GPX and RTZ per route). ``index.csv`` lists every file: the case's
rank, lane, ports, departure, role, whether it is the proposed route, the hours at risk avoided
(the ranking key) and the format. Files are written by :func:`dashboards.exports.write_routes`
(the formats of ``docs/reports.md``), deflated, with the run's time as every member's time, so
the same night gives the same archive.
"""

from __future__ import annotations

import csv
import io
import tempfile
import zipfile
from pathlib import Path

import pandas as pd

from dashboards.errors import ReportError
from dashboards.exports import write_routes

#: ``--exports``: proposed routes only (default), every route, or no archive.
EXPORT_MODES = ("proposed", "all", "none")
INDEX_COLUMNS = ("rank", "lane", "origin", "destination", "depart_utc", "role", "proposed", "risk_avoided_h", "format", "file")


def _safe(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in str(text))


def case_stem(lane_id: str, depart_utc: pd.Timestamp) -> str:
    """File-name stem of a case: ``<lane>_<YYYYmmddTHHMMZ>`` (letters, digits, ``-``, ``_``)."""
    return f"{_safe(lane_id)}_{pd.Timestamp(depart_utc):%Y%m%dT%H%MZ}"


def _files_of(case: dict, mode: str) -> list[tuple[str, list, str]]:
    """(member name, routes, role) for one case: proposed only, or every route."""
    routes, proposed = case["routes"], case.get("proposed")
    stem = case_stem(case["lane_id"], case["depart_utc"])
    if mode == "proposed":
        if proposed is None or proposed not in routes:
            return []
        r = routes[proposed]
        return [(f"{stem}_{_safe(proposed)}{suffix}", [r], proposed) for suffix in (".rtz", ".gpx", ".geojson")]
    files = [(f"{stem}_all.geojson", list(routes.values()), "all")]
    for role, r in routes.items():
        files += [(f"{stem}_{_safe(role)}{suffix}", [r], role) for suffix in (".rtz", ".gpx")]
    return files


def write_exports_zip(cases: list[dict], path, *, mode: str = "proposed", when=None) -> dict:
    """Write the night's exports into one zip archive with ``index.csv``.

    Parameters
    ----------
    cases : list of dict
        Per adverse lane-departure: ``rank``, ``lane_id``, ``origin``, ``destination``,
        ``depart_utc``, ``proposed`` (role or None), ``risk_avoided_h``, ``routes`` (role -> Route).
    path : str or Path
        The archive (its folder must exist).
    mode : {"proposed", "all"}
    when : Timestamp, optional
        Time stamped on every member (default 1980-01-01, the zip epoch): the same inputs give
        the same bytes.

    Returns
    -------
    dict
        ``path``, ``files`` (routes files, the index not counted), ``bytes`` (archive size),
        ``members`` (rank -> list of member names).
    """
    if mode not in ("proposed", "all"):
        raise ReportError(f"exports mode {mode!r}: use proposed or all")
    path = Path(path)
    stamp = pd.Timestamp(when) if when is not None else pd.Timestamp("1980-01-01T00:00Z")
    date_time = (max(stamp.year, 1980), stamp.month, stamp.day, stamp.hour, stamp.minute, stamp.second)
    index = io.StringIO()
    writer = csv.writer(index, lineterminator="\n")
    writer.writerow(INDEX_COLUMNS)
    members: dict = {}
    tmp_name = path.with_name(path.name + ".tmp")
    try:
        with tempfile.TemporaryDirectory(prefix="stormlane-exports-") as tmp, \
                zipfile.ZipFile(tmp_name, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=9) as zf:
            for case in cases:
                for name, routes, role in _files_of(case, mode):
                    (written,) = write_routes(routes, Path(tmp) / name)
                    info = zipfile.ZipInfo(name, date_time=date_time)
                    info.compress_type = zipfile.ZIP_DEFLATED
                    zf.writestr(info, written.read_bytes())
                    members.setdefault(case["rank"], []).append(name)
                    risk = case.get("risk_avoided_h")
                    writer.writerow([case["rank"], case["lane_id"], case["origin"], case["destination"],
                                     pd.Timestamp(case["depart_utc"]).strftime("%Y-%m-%dT%H:%MZ"), role,
                                     "yes" if role == case.get("proposed") else "no",
                                     "" if risk is None or pd.isna(risk) else f"{float(risk):.2f}", name.rsplit(".", 1)[1], name])
            info = zipfile.ZipInfo("index.csv", date_time=date_time)
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, index.getvalue())
        tmp_name.replace(path)
    except OSError as err:
        tmp_name.unlink(missing_ok=True)
        raise ReportError(f"{path}: cannot write the exports archive ({err.strerror or err})") from None
    return {"path": str(path), "files": sum(len(v) for v in members.values()), "bytes": path.stat().st_size, "members": members}


def read_index(path) -> pd.DataFrame:
    """``index.csv`` of an exports archive as a DataFrame (for tests and tools)."""
    with zipfile.ZipFile(path) as zf:
        return pd.read_csv(io.BytesIO(zf.read("index.csv")), dtype={"lane": str})
