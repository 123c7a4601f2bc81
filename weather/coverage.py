"""Coverage checks: never extrapolate silently.

:func:`check_coverage` raises :class:`~weather.errors.CoverageError` naming the product, the
variable and the missing time span or bbox when a route, a lane window or a request reaches
outside the data — including the subtle case of a merged dataset whose wind (say) ends before the
waves do, which shows up as time steps where the variable is NaN over every sea cell.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import xarray as xr

from weather.errors import CoverageError


def _fmt(t) -> str:
    return pd.Timestamp(t).strftime("%Y-%m-%dT%H:%MZ")


def _utc64(t) -> np.datetime64:
    ts = pd.Timestamp(t)
    if ts.tz is not None:
        ts = ts.tz_convert("UTC").tz_localize(None)
    return np.datetime64(ts, "ns")


def _spans(times: np.ndarray, flags: np.ndarray) -> list[tuple]:
    """Contiguous runs of True in ``flags`` as (first_time, last_time)."""
    out = []
    start = None
    for t, f in zip(times, flags):
        if f and start is None:
            start = prev = t
        elif f:
            prev = t
        elif start is not None:
            out.append((start, prev))
            start = None
    if start is not None:
        out.append((start, prev))
    return out


def data_extent(ds: xr.Dataset) -> dict:
    """Time span and bbox of a canonical dataset."""
    return {
        "start_utc": _fmt(ds.time_utc.values[0]),
        "end_utc": _fmt(ds.time_utc.values[-1]),
        "bbox": [float(ds.lon.min()), float(ds.lat.min()), float(ds.lon.max()), float(ds.lat.max())],
    }


def check_coverage(ds: xr.Dataset, *, variables=(), start=None, end=None, bbox=None, product: str | None = None) -> None:
    """Raise ``CoverageError`` unless ``ds`` covers the variables over [start, end] × bbox.

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical weather.
    variables : sequence of str
        Canonical names that must be present and not entirely missing at any time step in the
        window (missing = NaN over every cell that is sea in ``hs_m`` or, without waves, every cell).
    start, end : datetime-like, optional
        Time window (UTC).
    bbox : (lon_min, lat_min, lon_max, lat_max), optional
        Area that must lie inside the grid.
    product : str, optional
        Name used in messages (default ``ds.attrs["product"]``).

    Examples
    --------
    >>> ds = xr.Dataset({"hs_m": (("time_utc", "lat", "lon"), np.ones((2, 2, 2)))},
    ...                 coords={"time_utc": pd.to_datetime(["2025-01-01T00", "2025-01-01T03"]).values,
    ...                         "lat": [40.0, 41.0], "lon": [2.0, 3.0]}, attrs={"product": "demo"})
    >>> check_coverage(ds, variables=["hs_m"], start="2025-01-01T01:00Z", end="2025-01-01T03:00Z")
    >>> check_coverage(ds, variables=["wind_u_ms"])
    Traceback (most recent call last):
    ...
    weather.errors.CoverageError: demo: no variable 'wind_u_ms' (has: hs_m)
    """
    product = product or ds.attrs.get("product") or "weather"
    have = list(ds.data_vars)
    for var in variables:
        if var not in ds.data_vars:
            raise CoverageError(f"{product}: no variable {var!r} (has: {', '.join(have) or 'none'})")
    times = ds.time_utc.values
    t0, t1 = times[0], times[-1]
    start_ts = None if start is None else _utc64(start)
    end_ts = None if end is None else _utc64(end)
    names = ", ".join(variables) if variables else ", ".join(have)
    if start_ts is not None and start_ts < t0:
        raise CoverageError(
            f"{product}, {names}: no data for {_fmt(start_ts)} -> {_fmt(min(t0, end_ts) if end_ts is not None else t0)} "
            f"(data cover {_fmt(t0)} -> {_fmt(t1)})"
        )
    if end_ts is not None and end_ts > t1:
        raise CoverageError(
            f"{product}, {names}: no data for {_fmt(max(t1, start_ts) if start_ts is not None else t1)} -> {_fmt(end_ts)} "
            f"(data cover {_fmt(t0)} -> {_fmt(t1)})"
        )
    if bbox is not None:
        lon_min, lat_min, lon_max, lat_max = map(float, bbox)
        g = [float(ds.lon.min()), float(ds.lat.min()), float(ds.lon.max()), float(ds.lat.max())]
        tol = 1e-6
        if lon_min < g[0] - tol or lat_min < g[1] - tol or lon_max > g[2] + tol or lat_max > g[3] + tol:
            raise CoverageError(
                f"{product}, {names}: bbox lon {lon_min:g}..{lon_max:g}, lat {lat_min:g}..{lat_max:g} is not covered "
                f"(data cover lon {g[0]:g}..{g[2]:g}, lat {g[1]:g}..{g[3]:g})"
            )
    if not variables:
        return
    # Variables present but missing at some time steps inside the window (e.g. a merged wind that ends early).
    sel = np.ones(times.shape, dtype=bool)
    if start_ts is not None:
        sel &= times >= start_ts
    if end_ts is not None:
        sel &= times <= end_ts
    if not sel.any():
        return
    sub = ds.isel(time_utc=np.flatnonzero(sel))
    if bbox is not None:
        sub = sub.sel(lon=slice(bbox[0], bbox[2]), lat=slice(bbox[1], bbox[3]))
    if sub.lat.size == 0 or sub.lon.size == 0:
        return
    sea = None
    if "hs_m" in sub:
        sea = ~np.isnan(sub["hs_m"].values).all(axis=0)
    for var in variables:
        vals = sub[var].values
        cells = vals[:, sea] if sea is not None and sea.any() else vals.reshape(vals.shape[0], -1)
        empty = np.isnan(cells).all(axis=1)
        if empty.any():
            spans = _spans(sub.time_utc.values, empty)
            text = ", ".join(f"{_fmt(a)} -> {_fmt(b)}" for a, b in spans[:3]) + (" ..." if len(spans) > 3 else "")
            raise CoverageError(f"{product}, {var}: no data at {int(empty.sum())} time step(s): {text}")


def check_points(ds: xr.Dataset, lat_deg, lon_deg, time_utc, *, variables=(), product: str | None = None) -> None:
    """Raise ``CoverageError`` when any (lat, lon, time) point lies outside the data's grid or span."""
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    t = pd.DatetimeIndex(pd.to_datetime(np.asarray(time_utc).ravel(), utc=True)).tz_localize(None).values
    if lat.size == 0:
        return
    check_coverage(
        ds,
        variables=variables,
        start=pd.Timestamp(t.min()),
        end=pd.Timestamp(t.max()),
        bbox=(float(lon.min()), float(lat.min()), float(lon.max()), float(lat.max())),
        product=product,
    )
