"""The canonical weather grid every reader returns, and :func:`normalise_weather`.

Canonical form (COMMON.md "Canonical weather"): an ``xarray.Dataset`` with dims
``("time_utc", "lat", "lon")``; ``time_utc`` is ``datetime64[ns]`` meaning UTC, ``lat`` ascending,
``lon`` ascending in [-180, 180); variables (as available) ``hs_m``, ``wave_from_deg``, ``tp_s``,
``tm_s``, ``wind_u_ms``, ``wind_v_ms``, ``current_u_ms``, ``current_v_ms`` as float32 with land /
missing = NaN; attrs ``product``, ``source_files`` and per variable ``units`` and ``source_name``.

Waves and wind directions are "coming from" (CMEMS ``VMDR``, ERA5 ``mwd``), currents are given
as eastward/northward components (so they flow TO their vector direction).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import xarray as xr

from thresholds.units import MS_PER_KN
from weather.errors import WeatherFileError

#: Canonical variables, their unit, and a description.
CANONICAL_VARS: dict[str, tuple[str, str]] = {
    "hs_m": ("m", "significant wave height"),
    "wave_from_deg": ("degree", "mean wave direction, coming from, clockwise from true north"),
    "tp_s": ("s", "peak wave period"),
    "tm_s": ("s", "mean wave period"),
    "wind_u_ms": ("m s-1", "eastward 10 m wind"),
    "wind_v_ms": ("m s-1", "northward 10 m wind"),
    "current_u_ms": ("m s-1", "eastward surface current"),
    "current_v_ms": ("m s-1", "northward surface current"),
}

#: Variables that are angles (interpolated through their cos/sin components).
DIRECTION_VARS = frozenset({"wave_from_deg"})

# Accepted spellings of each unit in source files, with the factor to the canonical unit.
_UNIT_FACTORS: dict[str, dict[str, float]] = {
    "m": {"m": 1.0, "metre": 1.0, "metres": 1.0, "meter": 1.0, "meters": 1.0},
    "degree": {"degree": 1.0, "degrees": 1.0, "deg": 1.0, "degree_true": 1.0, "degrees_true": 1.0, "degree true": 1.0,
               "degree from north": 1.0},
    "s": {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0},
    "m s-1": {"m s-1": 1.0, "m/s": 1.0, "m s**-1": 1.0, "m.s-1": 1.0, "meter second-1": 1.0, "m sec-1": 1.0,
              "knots": MS_PER_KN, "knot": MS_PER_KN, "kt": MS_PER_KN, "kn": MS_PER_KN},
}

_TIME_NAMES = ("valid_time", "time", "time_utc", "t")
_LAT_NAMES = ("latitude", "lat", "y", "nav_lat")
_LON_NAMES = ("longitude", "lon", "x", "nav_lon")


def _find(ds: xr.Dataset, names, what: str, source: str) -> str:
    for name in names:
        if name in ds.coords or name in ds.dims or name in ds.variables:
            return name
    raise WeatherFileError(f"{source}: no {what} coordinate (looked for {', '.join(names)})")


def unit_factor(canonical: str, units: str | None, source: str, source_name: str) -> float:
    """Factor from a file's unit string to the canonical unit of ``canonical``; errors name the variable.

    A missing ``units`` attribute is accepted as already canonical (some derived files carry none).
    """
    target = CANONICAL_VARS[canonical][0]
    if units is None:
        return 1.0
    key = str(units).strip().lower()
    table = {k.lower(): v for k, v in _UNIT_FACTORS[target].items()}
    if key not in table:
        raise WeatherFileError(
            f"{source}: variable {source_name!r} has units {units!r}; expected one of {', '.join(_UNIT_FACTORS[target])} "
            f"for {canonical}"
        )
    return table[key]


def to_utc_naive(times) -> np.ndarray:
    """Timestamps as ``datetime64[ns]`` meaning UTC (tz-aware input is converted, naive is taken as UTC)."""
    idx = pd.DatetimeIndex(pd.to_datetime(np.asarray(times).ravel()))
    if idx.tz is not None:
        idx = idx.tz_convert("UTC").tz_localize(None)
    return idx.values.astype("datetime64[ns]")


def normalise_weather(
    ds: xr.Dataset,
    variable_map: dict[str, str],
    *,
    product: str,
    source_files=(),
    units_override: dict[str, str] | None = None,
    attrs: dict | None = None,
) -> xr.Dataset:
    """Turn a decoded source dataset into the canonical form.

    Parameters
    ----------
    ds : xarray.Dataset
        CF-decoded data (packing and fill values already applied by xarray: ``mask_and_scale``).
    variable_map : dict
        Source variable name -> canonical name (``{"VHM0": "hs_m"}``); source names absent from
        ``ds`` are ignored, but at least one must be present.
    product : str
        Product identifier recorded in ``attrs["product"]`` and in error messages.
    source_files : sequence of str
        Recorded in ``attrs["source_files"]`` ("; "-joined).
    units_override : dict, optional
        Source name -> unit, for files whose unit attribute is missing or wrong (documented by the
        reader that passes it).
    attrs : dict, optional
        Extra provenance attributes.

    Returns
    -------
    xarray.Dataset
        Canonical dataset (see module docstring).

    Raises
    ------
    WeatherFileError
        No known variable, missing coordinates, unknown units, or extra non-singleton dimensions.
    """
    source = ", ".join(map(str, source_files)) or product
    present = {src: dst for src, dst in variable_map.items() if src in ds.data_vars}
    if not present:
        raise WeatherFileError(
            f"{source}: none of the expected variables {', '.join(variable_map)} found for {product} "
            f"(file has: {', '.join(map(str, ds.data_vars)) or 'no variables'})"
        )
    ds, names = _time_lat_lon(ds, source)
    times = to_utc_naive(ds[names[0]].values)
    lat = np.asarray(ds[names[1]].values, dtype=float)
    lon = np.asarray(ds[names[2]].values, dtype=float)
    if lat.ndim != 1 or lon.ndim != 1:
        raise WeatherFileError(f"{source}: only regular lat/lon grids are supported (latitude has {lat.ndim} dims)")
    out_vars = {dst: _canonical_values(ds, src, dst, names, units_override, source) for src, dst in present.items()}
    out = _sorted_canonical(out_vars, times, lat, lon, source)
    out.attrs = {
        "product": product,
        "source_files": "; ".join(map(str, source_files)),
        "Conventions": "stormlane canonical weather (CF-like)",
        **(attrs or {}),
    }
    return out


def _time_lat_lon(ds: xr.Dataset, source: str) -> tuple[xr.Dataset, tuple[str, str, str]]:
    """Find the time, latitude and longitude names and make time a dimension.

    GRIB decodes to a ``step`` dimension with a ``valid_time`` coordinate along it, or to a scalar
    time: both become a ``time`` dimension here.
    """
    t_name = _find(ds, _TIME_NAMES, "time", source)
    lat_name = _find(ds, _LAT_NAMES, "latitude", source)
    lon_name = _find(ds, _LON_NAMES, "longitude", source)
    if t_name not in ds.dims:
        tdims = ds[t_name].dims
        if len(tdims) == 1:
            ds = ds.swap_dims({tdims[0]: t_name})
        elif len(tdims) == 0:
            ds = ds.expand_dims(t_name)
        else:
            raise WeatherFileError(f"{source}: time coordinate {t_name!r} has dims {tdims}, expected one")
    return ds, (t_name, lat_name, lon_name)


def _canonical_values(ds: xr.Dataset, src: str, dst: str, names: tuple[str, str, str],
                      units_override: dict[str, str] | None, source: str) -> tuple[np.ndarray, dict]:
    """One source variable as float32 (time, lat, lon) in canonical units, with its attributes.

    Singleton extra dimensions (a height or depth level) are dropped; larger ones are an error (the
    user must select a level). Directions are wrapped into [0, 360).
    """
    t_name, lat_name, lon_name = names
    da = ds[src]
    for d in [d for d in da.dims if d not in names]:
        if da.sizes[d] != 1:
            raise WeatherFileError(f"{source}: variable {src!r} has extra dimension {d!r} of size {da.sizes[d]}; select one level first")
        da = da.isel({d: 0}, drop=True)
    if t_name not in da.dims:
        da = da.expand_dims({t_name: ds.sizes[t_name]})
    da = da.transpose(t_name, lat_name, lon_name)
    units = (units_override or {}).get(src, da.attrs.get("units"))
    factor = unit_factor(dst, units, source, src)
    values = np.asarray(da.values, dtype=np.float32)
    if factor != 1.0:
        values = values * np.float32(factor)
    if dst in DIRECTION_VARS and (np.nanmin(values) < 0.0 or np.nanmax(values) >= 360.0):
        values = np.mod(values, np.float32(360.0))
    return values, {"units": CANONICAL_VARS[dst][0], "long_name": CANONICAL_VARS[dst][1], "source_name": src,
                    "source_units": "" if units is None else str(units)}


def _reorder(arr: np.ndarray, order: np.ndarray, axis: int) -> np.ndarray:
    """Apply an axis permutation, as a view when it is the identity or a reversal."""
    n = arr.shape[axis]
    if np.array_equal(order, np.arange(n)):
        return arr
    index = [slice(None)] * arr.ndim
    index[axis] = slice(None, None, -1) if np.array_equal(order, np.arange(n)[::-1]) else order
    return arr[tuple(index)]


def _sorted_canonical(out_vars: dict, times: np.ndarray, lat: np.ndarray, lon: np.ndarray,
                      source: str) -> xr.Dataset:
    """The canonical dataset: times ascending without repeats (the first of equal times kept),
    latitudes ascending, longitudes wrapped to [-180, 180) and ascending."""
    lon_wrapped = (lon + 180.0) % 360.0 - 180.0
    lon_order = np.argsort(lon_wrapped, kind="stable")
    lat_order = np.argsort(lat, kind="stable")
    t_order = np.argsort(times, kind="stable")
    t_sorted = times[t_order]
    keep_t = np.concatenate([[True], t_sorted[1:] != t_sorted[:-1]]) if t_sorted.size else np.zeros(0, bool)
    t_idx = t_order[keep_t]
    lon_sorted = lon_wrapped[lon_order]
    if np.any(np.diff(lon_sorted) == 0) or np.any(np.diff(lat[lat_order]) == 0):
        raise WeatherFileError(f"{source}: duplicate latitude or longitude values")
    data_vars = {}
    for dst, (values, vattrs) in out_vars.items():
        arr = _reorder(_reorder(_reorder(values, t_idx, 0), lat_order, 1), lon_order, 2)
        data_vars[dst] = (("time_utc", "lat", "lon"), np.ascontiguousarray(arr), vattrs)
    return xr.Dataset(
        data_vars,
        coords={
            "time_utc": ("time_utc", times[t_idx], {"long_name": "time (UTC)"}),
            "lat": ("lat", lat[lat_order], {"units": "degrees_north"}),
            "lon": ("lon", lon_sorted, {"units": "degrees_east"}),
        },
    )


def validate_canonical(ds: xr.Dataset, what: str = "weather") -> None:
    """Raise ``WeatherFileError`` unless ``ds`` is in canonical form (used by writers and loaders)."""
    if tuple(ds.dims) and set(ds.dims) != {"time_utc", "lat", "lon"}:
        raise WeatherFileError(f"{what}: dims must be time_utc, lat, lon (got {tuple(ds.dims)})")
    unknown = [v for v in ds.data_vars if v not in CANONICAL_VARS]
    if unknown:
        raise WeatherFileError(f"{what}: unknown variables {unknown}; canonical: {', '.join(CANONICAL_VARS)}")
    for name in ("lat", "lon"):
        c = ds[name].values
        if c.size > 1 and not np.all(np.diff(c) > 0):
            raise WeatherFileError(f"{what}: {name} must be strictly ascending")
    lon = ds["lon"].values
    if lon.size and (lon.min() < -180.0 or lon.max() >= 180.0):
        raise WeatherFileError(f"{what}: lon must lie in [-180, 180)")
    if ds["time_utc"].dtype != np.dtype("datetime64[ns]"):
        raise WeatherFileError(f"{what}: time_utc must be datetime64[ns] (UTC)")


def grid_step(values) -> float | None:
    """The constant spacing of a 1-D coordinate, or None when it is irregular (tolerance 1e-4 of a step)."""
    v = np.asarray(values, dtype=float)
    if v.size < 2:
        return None
    d = np.diff(v)
    step = float(np.median(d))
    return step if np.allclose(d, step, rtol=0, atol=abs(step) * 1e-3) else None
