"""The report model as JSON (``report.json``), compact and lossless.

``report_to_json(model)`` / ``report_from_json(text)`` round-trip a :class:`~dashboards.model.NightlyReport`
or :class:`~dashboards.model.VoyageAudit`: re-rendering the decoded model gives the identical page.

What makes it small (issue 22: the demo night's model went from 31 MB to under 3 MB, most of it
by storing the routes of the detailed cases only, see ``pipelines.nightly.report``):

* numeric arrays (weather slices, route positions, ETAs, the Hs met along each route, table
  columns) are stored as their bytes, deflated and base64-encoded (``{"__nd__": ...}``): as
  float32 when every value is exactly a float32 (the CMEMS/ERA5 fields are), else float64, so
  nothing is rounded here; a float64 written as JSON text costs ~18 characters, as deflated bytes
  often less than 8;
* tables (``DataFrame``) column by column the same way (``{"__table__": ...}``), times as int64
  nanoseconds since the epoch (UTC).

Models written before (``"__array__"`` lists, ``"__frame__"`` in pandas' split orient,
``"__route__"`` in :meth:`routing.route.Route.to_json` form) still decode.
"""

from __future__ import annotations

import base64
import json
import math
import zlib
from dataclasses import fields

import numpy as np
import pandas as pd

from dashboards.errors import ReportError

#: Smallest array stored as bytes; shorter ones stay JSON lists (readable, and no smaller packed).
MIN_PACKED = 16


def _classes() -> dict:
    from dashboards import model as m

    return {c.__name__: c for c in (m.WeatherSnapshot, m.SpeedLossCurve, m.Provenance, m.RouteSet, m.LaneDeparture, m.LaneLine,
                                    m.NightlyReport, m.VoyageAudit)}


def _pack(values: np.ndarray) -> dict:
    """A numeric array as deflated bytes (lossless: float32 only when every value is one)."""
    a = np.asarray(values)
    if a.dtype.kind == "b":
        kind, raw = "b1", a.astype(np.uint8)
    elif a.dtype.kind in "iu":
        kind, raw = "i8", a.astype("<i8")
    else:
        f = a.astype(float)
        f32 = f.astype("<f4")
        same = np.array_equal(f32.astype(float), f, equal_nan=True)
        kind, raw = ("f4", f32) if same else ("f8", f.astype("<f8"))
    blob = base64.b64encode(zlib.compress(np.ascontiguousarray(raw).tobytes(), 6)).decode("ascii")
    return {"__nd__": blob, "dtype": kind, "shape": list(a.shape)}


def _unpack(obj: dict) -> np.ndarray:
    raw = zlib.decompress(base64.b64decode(obj["__nd__"]))
    kind = obj["dtype"]
    if kind == "b1":
        return np.frombuffer(raw, dtype=np.uint8).astype(bool).reshape(obj["shape"])
    a = np.frombuffer(raw, dtype={"i8": "<i8", "f4": "<f4", "f8": "<f8"}[kind])
    return (a.astype(np.int64) if kind == "i8" else a.astype(float)).reshape(obj["shape"])


def _array(a: np.ndarray):
    a = np.asarray(a)
    if a.size >= MIN_PACKED and a.dtype.kind in "biuf":
        return _pack(a)
    return {"__array__": [None if (isinstance(x, float) and math.isnan(x)) else x for x in a.ravel().tolist()], "shape": list(a.shape)}


def _times(values) -> dict:
    """tz-aware times as int64 ns since the epoch (NaT as the int64 minimum)."""
    idx = pd.DatetimeIndex(values)
    return {"__times__": _pack(idx.asi8) if len(idx) >= MIN_PACKED else idx.asi8.tolist()}


def _untimes(obj) -> pd.DatetimeIndex:
    ns = obj["__times__"]
    ns = _unpack(ns) if isinstance(ns, dict) else np.asarray(ns, dtype=np.int64)
    return pd.DatetimeIndex(pd.to_datetime(ns, utc=True))


def _table(frame: pd.DataFrame) -> dict:
    cols = {}
    for name in frame.columns:
        s = frame[name]
        if isinstance(s.dtype, pd.DatetimeTZDtype):
            cols[str(name)] = _times(s)
        elif s.dtype.kind in "biuf":
            cols[str(name)] = _array(s.to_numpy())
        else:
            cols[str(name)] = {"__list__": [_encode(v) for v in s.tolist()]}
    index = frame.index
    idx = None if isinstance(index, pd.RangeIndex) and index.start == 0 and index.step == 1 else [_encode(v) for v in index.tolist()]
    return {"__table__": {"columns": cols, "order": [str(c) for c in frame.columns], "index": idx, "n": len(frame)}}


def _untable(obj) -> pd.DataFrame:
    spec = obj["__table__"]
    data = {}
    for name in spec["order"]:
        col = spec["columns"][name]
        if "__times__" in col:
            data[name] = _untimes(col)
        elif "__list__" in col:
            data[name] = [_decode(v) for v in col["__list__"]]
        else:
            data[name] = _decode(col)
    index = None if spec["index"] is None else [_decode(v) for v in spec["index"]]
    frame = pd.DataFrame(data, index=index if index is not None else pd.RangeIndex(spec["n"]), columns=spec["order"])
    return frame


def _route(route) -> dict:
    return {"__route2__": {"name": route.name, "lat_deg": _array(route.lat_deg), "lon_deg": _array(route.lon_deg),
                           "time_utc": _times(route.time_utc), "leg_speed_kn": _array(route.leg_speed_kn),
                           "weather": {k: _array(np.asarray(v, dtype=float)) for k, v in route.weather.items()},
                           "properties": _encode(route.properties)}}


def _unroute(obj):
    from routing.route import Route

    r = obj["__route2__"]
    return Route(name=r["name"], lat_deg=_decode(r["lat_deg"]), lon_deg=_decode(r["lon_deg"]), time_utc=_untimes(r["time_utc"]),
                 leg_speed_kn=np.asarray(_decode(r["leg_speed_kn"]), dtype=float),
                 weather={k: np.asarray(_decode(v), dtype=float) for k, v in r["weather"].items()},
                 properties=_decode(r["properties"]))


def _encode(obj):
    from routing.route import Route

    if isinstance(obj, Route):
        return _route(obj)
    if isinstance(obj, pd.DataFrame):
        return _table(obj)
    if isinstance(obj, pd.Timestamp):
        return {"__time__": obj.isoformat()}
    if isinstance(obj, np.ndarray):
        return _array(obj)
    if isinstance(obj, np.generic):
        return _encode(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if type(obj).__name__ in _classes() and hasattr(obj, "__dataclass_fields__"):
        return {"__class__": type(obj).__name__, **{f.name: _encode(getattr(obj, f.name)) for f in fields(obj)}}
    if isinstance(obj, dict):
        return {str(k): _encode(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_encode(v) for v in obj]
    return obj


def _decode_old_frame(spec) -> pd.DataFrame:
    frame = pd.DataFrame(spec["data"], index=spec["index"], columns=spec["columns"])
    for col in frame.columns:
        if str(col).endswith("_utc"):
            # isoformat() drops a zero fraction: mixed "…:00+00:00" / "…:00.5+00:00" strings
            frame[col] = pd.to_datetime(frame[col], utc=True, format="ISO8601")
    return frame


def _decode(obj):
    if isinstance(obj, list):
        return [_decode(v) for v in obj]
    if not isinstance(obj, dict):
        return obj
    if "__nd__" in obj:
        return _unpack(obj)
    if "__table__" in obj:
        return _untable(obj)
    if "__route2__" in obj:
        return _unroute(obj)
    if "__times__" in obj:
        return _untimes(obj)
    if "__route__" in obj:
        from routing.route import Route

        return Route.from_json(json.dumps(obj["__route__"]))
    if "__frame__" in obj:
        return _decode_old_frame(obj["__frame__"])
    if "__time__" in obj:
        return pd.Timestamp(obj["__time__"])
    if "__array__" in obj:
        return np.array([np.nan if x is None else x for x in obj["__array__"]], dtype=float).reshape(obj["shape"])
    if "__class__" in obj:
        cls = _classes()[obj["__class__"]]
        return cls(**{k: _decode(v) for k, v in obj.items() if k != "__class__"})
    return {k: _decode(v) for k, v in obj.items()}


def report_to_json(model) -> str:
    """Serialise a :class:`NightlyReport` or :class:`VoyageAudit` (round-trips through :func:`report_from_json`)."""
    return json.dumps(_encode(model), allow_nan=False, separators=(",", ":"))


def report_from_json(text: str):
    """Inverse of :func:`report_to_json`."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise ReportError(f"report model is not valid JSON ({err})") from None
    if not isinstance(data, dict) or data.get("__class__") not in ("NightlyReport", "VoyageAudit"):
        raise ReportError("report model JSON must hold a NightlyReport or a VoyageAudit")
    try:
        return _decode(data)
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, zlib.error) as err:
        # a field missing, renamed or of the wrong type (an edited or truncated file, another
        # version's model): one line saying so, not a traceback
        what = f"missing field {err}" if isinstance(err, KeyError) else f"{type(err).__name__}: {err}"
        raise ReportError(f"report model JSON is malformed ({' '.join(str(what).split())[:300]})") from None
