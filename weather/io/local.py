"""``read_local(paths)``: detect CMEMS / ERA5 / GRIB / zarr files and merge them onto one grid.

Steps:
1. Expand directories (``*.nc``, ``*.grb``, ``*.grib``, ``*.grb2``, ``*.grib2``, ``*.zarr``).
2. Read each file with the reader for its type (:mod:`weather.io.netcdf`, :mod:`weather.io.gfs`,
   :mod:`weather.io.wind_zarr`).
3. Concatenate files of the same product and grid along time (e.g. one MEDSEA file per day).
4. Merge the groups onto the **base grid** — the finest grid holding waves (``hs_m``), else the
   finest grid — and its times: other fields are regridded bilinearly in space and linearly in
   time (:func:`weather.regrid.merge_onto`); land of the wave grid stays NaN.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import xarray as xr

from weather.canonical import grid_step
from weather.coverage import data_extent
from weather.errors import CoverageError, WeatherFileError
from weather.io.netcdf import metadata_of, read_netcdf
from weather.regrid import merge_onto

log = logging.getLogger(__name__)

_GRIB = {".grb", ".grib", ".grb2", ".grib2", ".grib1", ".grb1"}
_NETCDF = {".nc", ".nc4", ".netcdf", ".cdf"}


def expand_paths(paths) -> list[Path]:
    """Files to read: directories are expanded to their weather files (sorted)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir() and p.suffix != ".zarr":
            found = sorted(q for q in p.iterdir() if q.suffix.lower() in _GRIB | _NETCDF or q.suffix == ".zarr")
            if not found:
                raise WeatherFileError(f"{p}: directory holds no weather files (*.nc, *.grb, *.grib2, *.zarr)")
            out.extend(found)
        elif not p.exists():
            raise WeatherFileError(f"{p}: no such file or directory")
        else:
            out.append(p)
    if not out:
        raise WeatherFileError("no weather files given")
    return out


def read_file(path: str | Path) -> tuple[xr.Dataset, dict]:
    """Read one weather file of any supported type."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".zarr" or (path.is_dir() and (path / ".zgroup").exists()):
        from weather.io.wind_zarr import read_wind_zarr

        return read_wind_zarr(path)
    if suffix in _GRIB:
        from weather.io.gfs import read_gfs

        return read_gfs(path)
    if suffix in _NETCDF:
        return read_netcdf(path)
    # Unknown extension: sniff the magic bytes.
    with open(path, "rb") as fh:
        head = fh.read(4)
    if head == b"GRIB":
        from weather.io.gfs import read_gfs

        return read_gfs(path)
    if head[:3] == b"CDF" or head == b"\x89HDF":
        return read_netcdf(path)
    raise WeatherFileError(f"{path}: unknown weather file type (expected NetCDF, GRIB or zarr)")


def _group_key(ds: xr.Dataset) -> tuple:
    return (ds.attrs.get("product", ""), tuple(sorted(ds.data_vars)), ds.lat.size, ds.lon.size,
            round(float(ds.lat.values[0]), 6), round(float(ds.lon.values[0]), 6))


def _concat_time(parts: list[xr.Dataset]) -> xr.Dataset:
    if len(parts) == 1:
        return parts[0]
    lat0, lon0 = parts[0].lat.values, parts[0].lon.values
    parts = [p.assign_coords(lat=lat0, lon=lon0) for p in parts]
    ds = xr.concat(parts, dim="time_utc", combine_attrs="drop_conflicts")
    times = ds.time_utc.values
    order = np.argsort(times, kind="stable")
    ds = ds.isel(time_utc=order)
    t = ds.time_utc.values
    keep = np.concatenate([[True], t[1:] != t[:-1]])
    ds = ds.isel(time_utc=np.flatnonzero(keep))
    ds.attrs["product"] = parts[0].attrs.get("product", "")
    ds.attrs["source_files"] = "; ".join(p.attrs.get("source_files", "") for p in parts)
    return ds


def _resolution(ds: xr.Dataset) -> float:
    steps = [abs(s) for s in (grid_step(ds.lat.values), grid_step(ds.lon.values)) if s]
    if steps:
        return min(steps)
    return float(np.min(np.abs(np.diff(ds.lat.values)))) if ds.lat.size > 1 else np.inf


def _check_overlap(base: xr.Dataset, others: list[xr.Dataset]) -> None:
    """A product that shares no time or no area with the base grid is a mistake: say so."""
    from weather.coverage import _fmt

    b_t0, b_t1 = base.time_utc.values[0], base.time_utc.values[-1]
    for o in others:
        o_t0, o_t1 = o.time_utc.values[0], o.time_utc.values[-1]
        if o_t1 < b_t0 or o_t0 > b_t1:
            raise CoverageError(
                f"{o.attrs.get('product', '')}, {', '.join(map(str, o.data_vars))}: covers {_fmt(o_t0)} -> {_fmt(o_t1)}, "
                f"no overlap with {base.attrs.get('product', '')} ({_fmt(b_t0)} -> {_fmt(b_t1)})"
            )
        if (float(o.lat.max()) < float(base.lat.min()) or float(o.lat.min()) > float(base.lat.max())
                or float(o.lon.max()) < float(base.lon.min()) or float(o.lon.min()) > float(base.lon.max())):
            raise CoverageError(
                f"{o.attrs.get('product', '')}: bbox lon {float(o.lon.min()):g}..{float(o.lon.max()):g}, "
                f"lat {float(o.lat.min()):g}..{float(o.lat.max()):g} does not overlap {base.attrs.get('product', '')} "
                f"(lon {float(base.lon.min()):g}..{float(base.lon.max()):g}, lat {float(base.lat.min()):g}..{float(base.lat.max()):g})"
            )


def read_local(paths) -> tuple[xr.Dataset, dict]:
    """Read local weather files of any supported product and merge them onto one grid.

    Parameters
    ----------
    paths : path or list of paths
        Files or directories (CMEMS / ERA5 NetCDF, GFS GRIB, tws/twd zarr).

    Returns
    -------
    (xarray.Dataset, dict)
        Canonical dataset on the base grid, and metadata: ``product`` (merged label), ``base``
        (the base group's product), ``inputs`` (per-file metadata), ``variables`` (canonical ->
        product it came from), ``ignored`` (variables dropped because the base already had them),
        plus time span, bbox and shape.
    """
    files = expand_paths(paths)
    groups: dict[tuple, list[xr.Dataset]] = {}
    inputs = []
    for f in files:
        ds, meta = read_file(f)
        inputs.append(meta)
        groups.setdefault(_group_key(ds), []).append(ds)
    datasets = [_concat_time(parts) for parts in groups.values()]
    with_waves = [d for d in datasets if "hs_m" in d.data_vars]
    pool = with_waves or datasets
    base = min(pool, key=lambda d: (_resolution(d), -d.time_utc.size))
    others = [d for d in datasets if d is not base]
    _check_overlap(base, others)
    variables = {v: base.attrs.get("product", "") for v in base.data_vars}
    ignored = []
    for o in others:
        for v in o.data_vars:
            if v in variables:
                ignored.append(f"{v} from {o.attrs.get('product', '')}")
            else:
                variables[v] = o.attrs.get("product", "")
    merged = merge_onto(base, others) if others else base
    meta = metadata_of(merged)
    meta.update({
        "base": base.attrs.get("product", ""),
        "inputs": inputs,
        "variables": variables,
        "ignored": ignored,
        **data_extent(merged),
    })
    return merged, meta
