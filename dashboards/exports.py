"""Route exports people's tools open: GeoJSON, GPX 1.1 and RTZ (IEC 61174 route exchange).

``write_routes(routes, path)`` picks the format from the file suffix (``.geojson``/``.json``,
``.gpx``, ``.rtz``); ``read_geojson``, ``read_gpx`` and ``read_rtz`` read the files back into
:class:`routing.route.Route` objects (used by the round-trip tests and by anyone re-importing an
exported plan).

Formats
-------
GeoJSON (RFC 7946 [1]_)
    One ``FeatureCollection``: per route a ``LineString`` feature (``MultiLineString`` when a leg
    crosses the antimeridian, split there as RFC 7946 section 3.1.9 asks) whose points follow each
    great-circle leg every :data:`LINE_STEP_NMI` (a GeoJSON line is straight in lon/lat, RFC 7946
    section 3.1.1, which a great-circle leg is not), and whose properties hold the route totals,
    ``sea_only`` (the one land check, :func:`routing.land.legs_at_sea`) (``time_h``, ``dist_nmi``, ``max_hs_m``, departure and arrival UTC, the route's
    own ``properties``), then per waypoint a ``Point`` feature with ``route``, ``seq``,
    ``eta_utc``, ``leg_speed_kn`` (speed on the leg that starts there, ``null`` at the last point)
    and the weather met (``hs_m``, ``wave_from_deg`` ..., ``null`` where not available).
    Coordinates are ``[lon, lat]`` with 7 decimals (about 1 cm).
GPX 1.1 [2]_
    One ``<rte>`` per route with named ``<rtept>`` points (``WP001`` ..., or the route's
    ``origin``/``destination`` names at the ends) and their ``<time>`` (ETA, UTC); speed and
    weather ride in ``<extensions>`` in the namespace :data:`STORMLANE_NS`, which GPX readers that
    do not know it ignore.
RTZ (IEC 61174:2015 Annex S, schema 1.0 or 1.1 [3]_)
    One route per file (the format holds one). ``routeInfo/@routeName`` equals the file stem, as
    route-checking tools expect. Waypoint ``id`` counts from 1; the ``leg`` element of waypoint
    *i* describes the leg arriving at it from waypoint *i - 1* (so the first waypoint has none),
    with ``geometryType="Orthodrome"`` (our legs are great-circle arcs) and ``speedMin`` =
    ``speedMax`` = the planned speed on that leg. The schedule is a ``calculated`` schedule with
    ``etd`` at the first waypoint, ``eta`` (and ``etd``, no stay) at the others and the leg speed
    on each arriving element. Times are written to the whole second in UTC (``Z``); decimal
    attributes never use exponent notation (``xsd:decimal``).

References
----------
.. [1] H. Butler et al., "The GeoJSON Format," IETF RFC 7946, 2016, doi:10.17487/RFC7946.
.. [2] TopoGrafix, "GPX 1.1 Schema Documentation," 2004. https://www.topografix.com/GPX/1/1/
.. [3] IEC 61174:2015, "Maritime navigation and radiocommunication equipment and systems -
       Electronic chart display and information system (ECDIS)," Annex S (Route exchange format,
       RTZ), with the RTZ schema revisions 1.0 and 1.1 published by CIRM.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd

from dashboards.errors import ExportError
from dashboards.plots import gc_polyline
from routing.land import legs_at_sea
from routing.route import Route

#: GPX 1.1 namespace. [2]
GPX_NS = "http://www.topografix.com/GPX/1/1"
#: RTZ namespaces by schema version. [3]
RTZ_NS = {"1.0": "http://www.cirm.org/RTZ/1/0", "1.1": "http://www.cirm.org/RTZ/1/1", "1.2": "http://www.cirm.org/RTZ/1/2"}
#: Namespace of stormlane's GPX extensions (leg speed, weather met).
STORMLANE_NS = "urn:stormlane:route:1"
#: Default RTZ schema version written.
RTZ_DEFAULT_VERSION = "1.1"

_FORMATS = {".geojson": "geojson", ".json": "geojson", ".gpx": "gpx", ".rtz": "rtz"}
_COORD_DECIMALS = 7
#: Spacing of the points drawn along each great-circle leg of a GeoJSON route line. [nmi]
LINE_STEP_NMI = 1.0


# ----------------------------------------------------------------------------- helpers


def _format_for(path: Path, fmt: str | None) -> str:
    if fmt is not None:
        key = fmt.lower().lstrip(".")
        if key not in {"geojson", "gpx", "rtz"}:
            raise ExportError(f"unknown export format {fmt!r}; use geojson, gpx or rtz")
        return key
    try:
        return _FORMATS[path.suffix.lower()]
    except KeyError:
        raise ExportError(f"{path}: cannot tell the export format from the suffix {path.suffix!r}; use .geojson, .gpx or .rtz") from None


def _iso(t: pd.Timestamp) -> str:
    """UTC timestamp as ``YYYY-MM-DDTHH:MM:SSZ`` (rounded to the second)."""
    return pd.Timestamp(t).tz_convert("UTC").round("s").strftime("%Y-%m-%dT%H:%M:%SZ")


def _dec(x: float, decimals: int) -> str:
    """Fixed-point decimal string (``xsd:decimal`` forbids exponents and NaN)."""
    if not math.isfinite(x):
        raise ExportError(f"cannot write a non-finite number ({x}) into an XML decimal attribute")
    text = f"{x:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in {"-0", ""} else text


def _finite_or_none(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _json_safe(obj):
    """Route properties may hold numpy scalars or NaN: make them strict JSON."""
    if isinstance(obj, dict):
        return {str(k): _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, (np.generic,)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, (pd.Timestamp,)):
        return _iso(obj)
    return obj


def _check_route(route: Route) -> None:
    if route.n_waypoints < 2:
        raise ExportError(f"route {route.name!r} has {route.n_waypoints} waypoint(s); an export needs at least 2")
    bad = ~(np.isfinite(route.lat_deg) & np.isfinite(route.lon_deg))
    if bad.any():
        raise ExportError(f"route {route.name!r}: waypoint {int(np.argmax(bad))} has no finite position")
    if (np.abs(route.lat_deg) > 90).any():
        raise ExportError(f"route {route.name!r}: latitude outside [-90, 90]")


def _lon(x: float) -> float:
    """Longitude in [-180, 180) as every format here requires."""
    return float((x + 180.0) % 360.0 - 180.0)


def _waypoint_names(route: Route) -> list[str]:
    n = route.n_waypoints
    names = [f"WP{i + 1:03d}" for i in range(n)]
    origin = route.properties.get("origin")
    destination = route.properties.get("destination")
    if origin:
        names[0] = str(origin)
    if destination:
        names[-1] = str(destination)
    return names


# ----------------------------------------------------------------------------- writers


def write_routes(routes, path, fmt: str | None = None, *, rtz_version: str = RTZ_DEFAULT_VERSION) -> list[Path]:
    """Write routes to GeoJSON, GPX 1.1 or RTZ, the format chosen by the suffix (or ``fmt``).

    Parameters
    ----------
    routes : Route or list of Route
        Routes to export; every one needs two or more waypoints with finite positions.
    path : str or Path
        Output file. For RTZ, which holds one route per file, several routes are written to
        ``<stem>_<route name>.rtz`` next to it.
    fmt : {"geojson", "gpx", "rtz"}, optional
        Overrides the suffix.
    rtz_version : {"1.0", "1.1"}
        RTZ schema version (namespace ``http://www.cirm.org/RTZ/1/0`` or ``.../1/1``).

    Returns
    -------
    list of Path
        The files written.
    """
    if isinstance(routes, Route):
        routes = [routes]
    routes = list(routes)
    if not routes:
        raise ExportError("no routes to export")
    path = Path(path)
    kind = _format_for(path, fmt)
    for route in routes:
        _check_route(route)
    try:
        return _write_kind(routes, path, kind, rtz_version)
    except OSError as err:
        where = f": {err.filename}" if err.filename and str(err.filename) != str(path) else ""
        raise ExportError(f"{path}: cannot write the export ({err.strerror or err}{where})") from None


def _write_kind(routes: list, path: Path, kind: str, rtz_version: str) -> list[Path]:
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "geojson":
        path.write_text(json.dumps(routes_to_geojson(routes), indent=1, allow_nan=False), encoding="utf-8")
        return [path]
    if kind == "gpx":
        _write_xml(routes_to_gpx(routes), path)
        return [path]
    if rtz_version not in ("1.0", "1.1"):
        raise ExportError(f"RTZ version {rtz_version!r} not supported for writing; use 1.0 or 1.1")
    if len(routes) == 1:
        targets = [path]
    else:
        safe = ["".join(c if c.isalnum() or c in "-_" else "_" for c in r.name) or f"route{i}" for i, r in enumerate(routes)]
        if len(set(safe)) != len(safe):
            safe = [f"{s}_{i + 1}" for i, s in enumerate(safe)]
        targets = [path.with_name(f"{path.stem}_{s}{path.suffix}") for s in safe]
    for route, target in zip(routes, targets):
        _write_xml(route_to_rtz(route, route_name=target.stem, version=rtz_version), target)
    return targets


def _write_xml(root: ET.Element, path: Path) -> None:
    """UTF-8 file with a double-quoted XML declaration.

    The builders write the document's own elements unqualified with an ``xmlns`` attribute on
    the root (the default namespace), which avoids ElementTree's global prefix registry.
    """
    ET.indent(root, space=" ")
    body = ET.tostring(root, encoding="unicode")
    path.write_bytes(('<?xml version="1.0" encoding="UTF-8"?>\n' + body + "\n").encode("utf-8"))


def routes_to_geojson(routes: list[Route]) -> dict:
    """GeoJSON ``FeatureCollection`` (a dict) of route lines and waypoint points; see the module notes."""
    features = []
    for route in routes:
        lon = [_lon(x) for x in route.lon_deg]
        lat = [float(x) for x in route.lat_deg]
        coords = [[round(a, _COORD_DECIMALS), round(b, _COORD_DECIMALS)] for a, b in zip(lon, lat)]
        g_lat, g_lon = gc_polyline(route.lat_deg, route.lon_deg, LINE_STEP_NMI)  # the legs, not straight lon/lat lines
        parts = _split_antimeridian([[round(_lon(a), _COORD_DECIMALS), round(float(b), _COORD_DECIMALS)] for a, b in zip(g_lon, g_lat)])
        geometry = {"type": "LineString", "coordinates": parts[0]} if len(parts) == 1 else {"type": "MultiLineString", "coordinates": parts}
        features.append(
            {
                "type": "Feature",
                "geometry": geometry,
                "properties": {
                    "feature": "route",
                    "route": route.name,
                    "n_waypoints": route.n_waypoints,
                    "depart_utc": _iso(route.time_utc[0]),
                    "arrive_utc": _iso(route.time_utc[-1]),
                    "time_h": round(route.time_h, 6),
                    "dist_nmi": round(route.dist_nmi, 6),
                    "max_hs_m": _finite_or_none(route.max_hs_m),
                    "line_step_nmi": LINE_STEP_NMI,
                    "sea_only": bool(legs_at_sea(route.lat_deg, route.lon_deg).all()) if route.n_waypoints > 1 else True,
                    "properties": _json_safe(route.properties),
                },
            }
        )
        names = _waypoint_names(route)
        speeds = np.append(route.leg_speed_kn, np.nan)
        for i in range(route.n_waypoints):
            props = {
                "feature": "waypoint",
                "route": route.name,
                "seq": i,
                "name": names[i],
                "eta_utc": _iso(route.time_utc[i]),
                "leg_speed_kn": _finite_or_none(speeds[i]),
            }
            for key, values in route.weather.items():
                props[key] = _finite_or_none(values[i])
            features.append({"type": "Feature", "geometry": {"type": "Point", "coordinates": coords[i]}, "properties": props})
    return {"type": "FeatureCollection", "features": features}


def _split_antimeridian(coords: list[list[float]]) -> list[list[list[float]]]:
    """Split a lon/lat polyline where a leg jumps more than 180 deg of longitude (RFC 7946, 3.1.9).

    A route that starts or ends exactly on the antimeridian would leave a part of one repeated
    point at the seam, which is no line (invalid in a MultiLineString): such parts are dropped,
    so a route to 180 deg from the west is one line ending at 180."""
    parts = [[coords[0]]]
    for (lon0, lat0), (lon1, lat1) in zip(coords[:-1], coords[1:]):
        if abs(lon1 - lon0) > 180.0:
            # Crossing point: unwrap lon1 next to lon0, interpolate latitude at +-180.
            edge = 180.0 if lon0 > 0 else -180.0
            lon1u = lon1 + 360.0 if lon0 > 0 else lon1 - 360.0
            frac = (edge - lon0) / (lon1u - lon0)
            lat_x = round(lat0 + frac * (lat1 - lat0), _COORD_DECIMALS)
            parts[-1].append([edge, lat_x])
            parts.append([[-edge, lat_x]])
        parts[-1].append([lon1, lat1])
    lines = [part for part in parts if any(p != part[0] for p in part[1:])]
    return lines or parts[:1]


def routes_to_gpx(routes: list[Route]) -> ET.Element:
    """GPX 1.1 document with one ``<rte>`` per route (root carries ``xmlns``; serialise, then parse)."""
    ET.register_namespace("stormlane", STORMLANE_NS)
    g = lambda tag: tag  # noqa: E731  (default namespace, declared on the root)
    s = lambda tag: f"{{{STORMLANE_NS}}}{tag}"  # noqa: E731
    root = ET.Element(g("gpx"), {"xmlns": GPX_NS, "version": "1.1", "creator": "stormlane"})
    meta = ET.SubElement(root, g("metadata"))
    ET.SubElement(meta, g("name")).text = ", ".join(r.name for r in routes)
    ET.SubElement(meta, g("time")).text = _iso(min(r.time_utc[0] for r in routes))
    for route in routes:
        rte = ET.SubElement(root, g("rte"))
        ET.SubElement(rte, g("name")).text = route.name
        ET.SubElement(rte, g("desc")).text = f"{route.dist_nmi:.1f} nmi, {route.time_h:.2f} h, depart {_iso(route.time_utc[0])}"
        ET.SubElement(rte, g("src")).text = "stormlane"
        names = _waypoint_names(route)
        speeds = np.append(route.leg_speed_kn, np.nan)
        for i in range(route.n_waypoints):
            # Child order is fixed by the GPX 1.1 schema (wptType): time, ..., name, ..., extensions.
            pt = ET.SubElement(rte, g("rtept"), {"lat": _dec(route.lat_deg[i], _COORD_DECIMALS), "lon": _dec(_lon(route.lon_deg[i]), _COORD_DECIMALS)})
            ET.SubElement(pt, g("time")).text = _iso(route.time_utc[i])
            ET.SubElement(pt, g("name")).text = names[i]
            ext = ET.SubElement(pt, g("extensions"))
            if math.isfinite(speeds[i]):
                ET.SubElement(ext, s("leg_speed_kn")).text = _dec(speeds[i], 4)
            for key, values in route.weather.items():
                if math.isfinite(values[i]):
                    ET.SubElement(ext, s(key)).text = _dec(values[i], 4)
            if not len(ext):
                pt.remove(ext)
    return root


def route_to_rtz(route: Route, route_name: str | None = None, version: str = RTZ_DEFAULT_VERSION) -> ET.Element:
    """RTZ document for one route (root carries ``xmlns``; serialise, then parse); see the module notes."""
    ns = RTZ_NS[version]
    r = lambda tag: tag  # noqa: E731  (default namespace, declared on the root)
    root = ET.Element(r("route"), {"xmlns": ns, "version": version})
    info = {"routeName": route_name or route.name, "routeAuthor": "stormlane", "routeStatus": f"proposed ({route.name})"}
    info["validityPeriodStart"] = _iso(route.time_utc[0])
    info["validityPeriodStop"] = _iso(route.time_utc[-1])
    vessel = route.properties.get("vessel")
    if isinstance(vessel, str) and vessel:
        info["vesselName"] = vessel
    mmsi = route.properties.get("mmsi")
    if isinstance(mmsi, (int, np.integer)) and mmsi >= 0:
        info["vesselMMSI"] = str(int(mmsi))
    ET.SubElement(root, r("routeInfo"), info)
    wps = ET.SubElement(root, r("waypoints"))
    names = _waypoint_names(route)
    for i in range(route.n_waypoints):
        wp = ET.SubElement(wps, r("waypoint"), {"id": str(i + 1), "name": names[i]})
        ET.SubElement(wp, r("position"), {"lat": _dec(route.lat_deg[i], _COORD_DECIMALS), "lon": _dec(_lon(route.lon_deg[i]), _COORD_DECIMALS)})
        if i > 0:
            speed = _dec(route.leg_speed_kn[i - 1], 2)
            ET.SubElement(wp, r("leg"), {"geometryType": "Orthodrome", "speedMin": speed, "speedMax": speed})
    schedules = ET.SubElement(root, r("schedules"))
    schedule = ET.SubElement(schedules, r("schedule"), {"id": "1", "name": f"stormlane {route.name}"})
    calc = ET.SubElement(schedule, r("calculated"))
    n = route.n_waypoints
    for i in range(n):
        attrs = {"waypointId": str(i + 1)}
        if i > 0:
            attrs["eta"] = _iso(route.time_utc[i])
        if i < n - 1:
            attrs["etd"] = _iso(route.time_utc[i])
        if i > 0:
            attrs["speed"] = _dec(route.leg_speed_kn[i - 1], 2)
        ET.SubElement(calc, r("scheduleElement"), attrs)
    return root


# ----------------------------------------------------------------------------- readers


def _parse(path: Path) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as err:
        raise ExportError(f"{path}: not well-formed XML ({err})") from None
    except OSError as err:
        raise ExportError(f"{path}: cannot read ({err.strerror})") from None


def _float_attr(el: ET.Element, name: str, path: Path, what: str) -> float:
    text = el.get(name)
    if text is None:
        raise ExportError(f"{path}: {what} has no {name!r} attribute")
    try:
        return float(text)
    except ValueError:
        raise ExportError(f"{path}: {what} has a non-numeric {name}={text!r}") from None


def _time(text: str | None, path: Path, what: str) -> pd.Timestamp:
    if not text:
        raise ExportError(f"{path}: {what} has no time")
    try:
        t = pd.Timestamp(text.strip().replace("z", "Z"))
    except ValueError:
        raise ExportError(f"{path}: {what} has an unreadable time {text!r}") from None
    return t.tz_localize("UTC") if t.tz is None else t.tz_convert("UTC")


def read_rtz(path) -> Route:
    """Read an RTZ 1.0/1.1/1.2 file back into a :class:`Route`.

    Positions come from ``waypoints``; times from the first schedule (``calculated`` if present,
    else ``manual``): ``etd`` at the first waypoint, ``eta`` at the others; leg speeds from the
    schedule's ``speed`` or else the leg's ``speedMax``, else distance over time.
    """
    path = Path(path)
    root = _parse(path)
    if not root.tag.startswith("{") or root.tag.split("}")[1] != "route":
        raise ExportError(f"{path}: root element is {root.tag!r}, not an RTZ <route>")
    ns = root.tag[1:].split("}")[0]
    version = root.get("version")
    if ns not in RTZ_NS.values():
        raise ExportError(f"{path}: unknown RTZ namespace {ns!r}")
    if version is None or RTZ_NS.get(version) != ns:
        raise ExportError(f"{path}: RTZ version attribute {version!r} does not match namespace {ns!r}")
    q = lambda tag: f"{{{ns}}}{tag}"  # noqa: E731
    info = root.find(q("routeInfo"))
    if info is None or not info.get("routeName"):
        raise ExportError(f"{path}: missing routeInfo/@routeName")
    wp_els = root.findall(f"{q('waypoints')}/{q('waypoint')}")
    if len(wp_els) < 2:
        raise ExportError(f"{path}: an RTZ route needs at least 2 waypoints, found {len(wp_els)}")
    ids, lat, lon, names, leg_speed = [], [], [], [], []
    for k, wp in enumerate(wp_els):
        what = f"waypoint #{k + 1}"
        if wp.get("id") is None:
            raise ExportError(f"{path}: {what} has no id")
        ids.append(wp.get("id"))
        pos = wp.find(q("position"))
        if pos is None:
            raise ExportError(f"{path}: {what} (id {wp.get('id')}) has no position")
        lat.append(_float_attr(pos, "lat", path, what))
        lon.append(_float_attr(pos, "lon", path, what))
        names.append(wp.get("name") or "")
        leg = wp.find(q("leg"))
        leg_speed.append(float(leg.get("speedMax")) if leg is not None and leg.get("speedMax") else np.nan)
    if len(set(ids)) != len(ids):
        raise ExportError(f"{path}: waypoint ids are not unique")
    schedule = root.find(f"{q('schedules')}/{q('schedule')}")
    if schedule is None:
        raise ExportError(f"{path}: no schedule; a Route needs a time at every waypoint")
    part = schedule.find(q("calculated"))
    if part is None or not len(part):
        part = schedule.find(q("manual"))
    elements = {} if part is None else {el.get("waypointId"): el for el in part.findall(q("scheduleElement"))}
    times, sched_speed = [], []
    for k, wid in enumerate(ids):
        el = elements.get(wid)
        if el is None:
            raise ExportError(f"{path}: schedule has no element for waypoint id {wid}")
        text = el.get("etd") if k == 0 else (el.get("eta") or el.get("etd"))
        times.append(_time(text, path, f"schedule element for waypoint id {wid}"))
        sched_speed.append(float(el.get("speed")) if el.get("speed") else np.nan)
    speeds = np.where(np.isfinite(sched_speed), sched_speed, leg_speed)[1:]
    route_name = info.get("routeName")
    props = {"rtz_version": version, "route_name": route_name, "waypoint_names": names}
    return _route_from_points(route_name, lat, lon, times, speeds, {}, props)


def _route_from_points(name, lat, lon, times, speeds, weather, props) -> Route:
    """Build a Route, filling missing leg speeds with distance over time."""
    lat = np.asarray(lat, dtype=float)
    lon = np.asarray(lon, dtype=float)
    idx = pd.DatetimeIndex(times)
    speeds = np.asarray(speeds, dtype=float)
    if np.isnan(speeds).any():
        from thresholds.geodesy import haversine_nmi

        dist = np.asarray(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]))
        hours = np.diff(idx.asi8) / 3.6e12
        with np.errstate(invalid="ignore", divide="ignore"):
            speeds = np.where(np.isnan(speeds), np.where(hours > 0, dist / hours, np.nan), speeds)
    return Route(name=name, lat_deg=lat, lon_deg=lon, time_utc=idx, leg_speed_kn=speeds, weather=weather, properties=props)


def read_gpx(path) -> list[Route]:
    """Read the routes (``<rte>``) of a GPX 1.1 file; points need a ``<time>`` each.

    Leg speed and weather come from stormlane's extensions when present, else the speed is the
    leg's distance over its time.
    """
    path = Path(path)
    root = _parse(path)
    if root.tag != f"{{{GPX_NS}}}gpx":
        raise ExportError(f"{path}: root element is {root.tag!r}, not a GPX 1.1 <gpx> in {GPX_NS}")
    if root.get("version") != "1.1":
        raise ExportError(f"{path}: GPX version {root.get('version')!r}, expected '1.1'")
    g = lambda tag: f"{{{GPX_NS}}}{tag}"  # noqa: E731
    routes = []
    for r_i, rte in enumerate(root.findall(g("rte"))):
        name_el = rte.find(g("name"))
        name = name_el.text if name_el is not None and name_el.text else f"route{r_i + 1}"
        lat, lon, times, speed, names = [], [], [], [], []
        weather: dict[str, list[float]] = {}
        pts = rte.findall(g("rtept"))
        for k, pt in enumerate(pts):
            what = f"route {name!r} point #{k + 1}"
            lat.append(_float_attr(pt, "lat", path, what))
            lon.append(_float_attr(pt, "lon", path, what))
            t = pt.find(g("time"))
            times.append(_time(None if t is None else t.text, path, what))
            n_el = pt.find(g("name"))
            names.append(n_el.text if n_el is not None and n_el.text else "")
            ext = pt.find(g("extensions"))
            values = {}
            if ext is not None:
                for child in ext:
                    if child.tag.startswith(f"{{{STORMLANE_NS}}}"):
                        values[child.tag.split("}")[1]] = float(child.text)
            speed.append(values.pop("leg_speed_kn", np.nan))
            for key in set(weather) | set(values):
                weather.setdefault(key, [np.nan] * k).append(values.get(key, np.nan))
        if len(lat) < 2:
            raise ExportError(f"{path}: route {name!r} has {len(lat)} point(s); need at least 2")
        routes.append(_route_from_points(name, lat, lon, times, speed[:-1], {k: np.asarray(v) for k, v in weather.items()}, {"waypoint_names": names}))
    if not routes:
        raise ExportError(f"{path}: no <rte> element")
    return routes


def read_geojson(path) -> list[Route]:
    """Read routes back from a GeoJSON written by :func:`routes_to_geojson` (waypoint features)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as err:
        raise ExportError(f"{path}: not readable GeoJSON ({err})") from None
    if data.get("type") != "FeatureCollection":
        raise ExportError(f"{path}: expected a FeatureCollection, got {data.get('type')!r}")
    by_route: dict[str, list[dict]] = {}
    meta: dict[str, dict] = {}
    for feat in data.get("features", []):
        props = feat.get("properties") or {}
        if props.get("feature") == "waypoint":
            by_route.setdefault(props["route"], []).append(feat)
        elif props.get("feature") == "route":
            meta[props["route"]] = props.get("properties") or {}
    routes = []
    for name, feats in by_route.items():
        feats = sorted(feats, key=lambda f: f["properties"]["seq"])
        lon = [f["geometry"]["coordinates"][0] for f in feats]
        lat = [f["geometry"]["coordinates"][1] for f in feats]
        times = [_time(f["properties"]["eta_utc"], path, f"route {name!r} waypoint {f['properties']['seq']}") for f in feats]
        speed = [np.nan if f["properties"].get("leg_speed_kn") is None else f["properties"]["leg_speed_kn"] for f in feats][:-1]
        skip = {"feature", "route", "seq", "name", "eta_utc", "leg_speed_kn"}
        keys = sorted({k for f in feats for k in f["properties"] if k not in skip})
        weather = {k: np.array([np.nan if f["properties"].get(k) is None else f["properties"][k] for f in feats], dtype=float) for k in keys}
        routes.append(_route_from_points(name, lat, lon, times, speed, weather, meta.get(name, {})))
    if not routes:
        raise ExportError(f"{path}: no waypoint features")
    return routes


def export_alternatives(routes: dict, directory, stem: str, relative_to=None, *, proposed: str | None = None,
                        only_proposed: bool = False) -> dict[str, str]:
    """Write the exports for one voyage or lane-departure and return links for the report.

    Writes ``<stem>.geojson`` and ``<stem>.gpx`` with every route (the historical one included,
    for comparison) and one ``<stem>_<role>.rtz`` per alternative (every role but
    ``historical``), the file an ECDIS imports.

    Parameters
    ----------
    routes : dict of str -> Route
        Keyed by role (``historical``, ``deviation``, ``optimal``, ``min_distance`` ...).
    directory : str or Path
        Output folder (created).
    stem : str
        File-name stem, e.g. ``"lane3_20250131T0600Z"``; only letters, digits, ``-`` and ``_``.
    relative_to : str or Path, optional
        Folder the returned paths are relative to (the report's folder); default ``directory``.
    proposed, only_proposed : str or None, bool
        With ``only_proposed`` (the nightly run): the GeoJSON still holds every route, but GPX
        and RTZ are written for the ``proposed`` role only (``<stem>_<role>.gpx/.rtz``, the one
        route a master would import), and none when nothing is proposed.

    Returns
    -------
    dict of str -> str
        Label -> relative POSIX path, e.g. ``{"GeoJSON": "exports/x.geojson", "RTZ optimal": ...}``;
        put it in ``RouteSet.exports``.
    """
    import os

    if not stem or any(not (c.isalnum() or c in "-_") for c in stem):
        raise ExportError(f"export stem {stem!r} must be letters, digits, '-' or '_'")
    directory = Path(directory)
    base = Path(relative_to) if relative_to is not None else directory
    ordered = list(routes.values())
    if not ordered:
        raise ExportError("no routes to export")
    links: dict[str, str] = {}

    def rel(p: Path) -> str:
        return Path(os.path.relpath(p, base)).as_posix()

    if only_proposed:
        (written,) = write_routes(ordered, directory / f"{stem}.geojson")
        links["GeoJSON (all routes)"] = rel(written)
        per_route = {proposed: (".gpx", ".rtz")} if proposed is not None else {}
    else:
        for label, suffix in (("GeoJSON", ".geojson"), ("GPX", ".gpx")):
            (written,) = write_routes(ordered, directory / f"{stem}{suffix}")
            links[label] = rel(written)
        per_route = {role: (".rtz",) for role in routes if role != "historical"}
    for role, suffixes in per_route.items():
        safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in role)
        for suffix in suffixes:
            (written,) = write_routes(routes[role], directory / f"{stem}_{safe}{suffix}")
            links[f"{suffix[1:].upper()} {role}"] = rel(written)
    return links
