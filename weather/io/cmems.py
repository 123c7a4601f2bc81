"""Copernicus Marine (CMEMS) waves and currents: download, read, and write in the product schema.

* :func:`get_cmems` downloads a subset with the official ``copernicusmarine`` client into the
  download cache (:mod:`weather.io.cache`). Credentials come only from the client's own
  mechanisms (``copernicusmarine login`` credentials file or its environment variables); we never
  read, log or store them. Without credentials the client would prompt for a username on stdin;
  it is given an empty stdin (and its prints go to stderr), so it prints "Abort" and **returns
  None without raising** (STACK.md): that is turned into a :class:`~weather.errors.FetchError` at once
  (no retry: credentials do not appear by retrying). Network failures are retried a bounded
  number of times with the client's own HTTP retries and timeout set low.
* :func:`read_cmems` reads a local file (the path every test takes), see :mod:`weather.io.netcdf`.
* :func:`write_cmems_wave` writes a canonical wave dataset in the CMEMS packed-int16 NetCDF schema
  (used by the demo scenario so the demo goes through the same reader). The packing, fill values
  and variable attributes follow the real CMEMS MEDSEA file in ``../shared/data`` (scale 0.001 for
  heights and periods, 0.01 with offset 180 for directions, ``_FillValue`` = ``missing_value`` =
  −32767); coordinates and time encoding follow the CMEMS GLOBAL files (float32 lat/lon, time in
  hours since 1950-01-01); the GLOBAL product adds ``VTM10``.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from weather.canonical import validate_canonical
from weather.errors import FetchError, WeatherFileError
from weather.io.cache import DownloadCache, Request
from weather.io.netcdf import open_netcdf, read_netcdf

log = logging.getLogger(__name__)

#: Default datasets and variables per product kind.
DATASETS = {
    "cmems-wave": ("cmems_mod_glo_wav_anfc_0.083deg_PT3H-i", ("VHM0", "VMDR", "VTPK", "VTM10")),
    "cmems-wave-med": ("cmems_mod_med_wav_anfc_4.2km_PT1H-i", ("VHM0", "VMDR", "VTPK", "VTM10")),
    "cmems-current": ("cmems_mod_glo_phy_anfc_merged-uv_PT1H-i", ("utotal", "vtotal")),
    "cmems-current-daily": ("cmems_mod_glo_phy-cur_anfc_0.083deg_P1D-m", ("uo", "vo")),
}

GLOBAL_WAVE_DATASET = DATASETS["cmems-wave"][0]
GLOBAL_WAVE_PRODUCT = "GLOBAL_ANALYSISFORECAST_WAV_001_027"

# Packing and attributes of each wave variable (MEDSEA file in ../shared/data; VTM10 by analogy).
_WAVE_SCHEMA = {
    "hs_m": ("VHM0", 0.001, 0.0, {"long_name": "Spectral significant wave height (Hm0)",
                                    "standard_name": "sea_surface_wave_significant_height", "units": "m", "WMO": 100}),
    "wave_from_deg": ("VMDR", 0.01, 180.0, {"long_name": "Mean wave direction from (Mdir)",
                                             "standard_name": "sea_surface_wave_from_direction", "units": "degree", "WMO": 200}),
    "tp_s": ("VTPK", 0.001, 0.0, {"long_name": "Wave period at spectral peak / peak period (Tp)",
                                   "standard_name": "sea_surface_wave_period_at_variance_spectral_density_maximum", "units": "s",
                                   "WMO": 204}),
    "tm_s": ("VTM10", 0.001, 0.0, {"long_name": "Spectral moments (-1,0) wave period (Tm-10)",
                                    "standard_name": "sea_surface_wave_mean_period_from_variance_spectral_density_inverse_frequency_moment",
                                    "units": "s"}),
}
FILL_INT16 = np.int16(-32767)


def read_cmems(path: str | Path) -> tuple[xr.Dataset, dict]:
    """Read a CMEMS wave or current NetCDF file (any of the schemas of :mod:`weather.io.netcdf`)."""
    ds, meta = read_netcdf(path)
    if "CMEMS" not in meta["product"]:
        raise WeatherFileError(f"{path}: not a CMEMS file (detected {meta['product']})")
    return ds, meta


def pack_int16(values: np.ndarray, scale: float, offset: float) -> np.ndarray:
    """CF packing: ``round((x − offset)/scale)`` as int16, NaN -> −32767 (values must fit)."""
    v = np.asarray(values, dtype=np.float64)
    packed = np.round((v - offset) / scale)
    finite = np.isfinite(packed)
    if finite.any() and (packed[finite].min() < -32766 or packed[finite].max() > 32767):
        raise ValueError(f"values {np.nanmin(v)}..{np.nanmax(v)} do not fit int16 with scale {scale}, offset {offset}")
    return np.where(finite, packed, FILL_INT16).astype(np.int16)


def write_cmems_wave(ds: xr.Dataset, path: str | Path, *, dataset_id: str = GLOBAL_WAVE_DATASET,
                     product_id: str = GLOBAL_WAVE_PRODUCT, synthetic: bool = True, comment: str = "") -> Path:
    """Write canonical waves (``hs_m``, ``wave_from_deg``, ``tp_s``, ``tm_s``) as a CMEMS wave file.

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical weather with at least ``hs_m``; land = NaN.
    path : str or Path
        Output ``.nc`` (NetCDF4, zlib level 1).
    dataset_id, product_id : str
        Recorded in the global attributes (the reader uses ``product_id`` for its label).
    synthetic : bool
        Mark the file as generated (``comment`` and ``stormlane_synthetic`` attributes), so it is
        never mistaken for Copernicus data.

    Returns
    -------
    Path
    """
    validate_canonical(ds, f"write_cmems_wave({path})")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    import netCDF4

    times = pd.DatetimeIndex(ds.time_utc.values)
    hours = (times - pd.Timestamp("1950-01-01")) / pd.Timedelta(hours=1)
    lat = ds.lat.values.astype(np.float32)
    lon = ds.lon.values.astype(np.float32)
    with netCDF4.Dataset(path, "w", format="NETCDF4") as nc:
        nc.createDimension("time", len(times))
        nc.createDimension("latitude", lat.size)
        nc.createDimension("longitude", lon.size)
        t = nc.createVariable("time", "f8", ("time",))
        t.setncatts({"units": "hours since 1950-01-01", "calendar": "standard", "long_name": "Time", "standard_name": "time",
                     "axis": "T", "unit_long": "Hours Since 1950-01-01"})
        t[:] = np.asarray(hours, dtype=np.float64)
        la = nc.createVariable("latitude", "f4", ("latitude",))
        la.setncatts({"units": "degrees_north", "standard_name": "latitude", "long_name": "Latitude", "axis": "Y",
                      "unit_long": "Degrees North", "valid_min": np.float32(lat.min()), "valid_max": np.float32(lat.max())})
        la[:] = lat
        lo = nc.createVariable("longitude", "f4", ("longitude",))
        lo.setncatts({"units": "degrees_east", "standard_name": "longitude", "long_name": "Longitude", "axis": "X",
                      "unit_long": "Degrees East", "valid_min": np.float32(lon.min()), "valid_max": np.float32(lon.max())})
        lo[:] = lon
        for canonical, (name, scale, offset, attrs) in _WAVE_SCHEMA.items():
            if canonical not in ds:
                continue
            var = nc.createVariable(name, "i2", ("time", "latitude", "longitude"), zlib=True, complevel=1,
                                    fill_value=FILL_INT16, chunksizes=(1, lat.size, lon.size))
            var.set_auto_maskandscale(False)
            var.setncatts({"scale_factor": np.float32(scale), "add_offset": np.float32(offset), "missing_value": FILL_INT16,
                           **attrs, "coordinates": "time latitude longitude", "cell_methods": "time: point area: mean",
                           "type_of_analysis": "spectral analysis"})
            values = ds[canonical].values
            if canonical == "wave_from_deg":
                values = np.mod(values, 360.0)
            var[:] = pack_int16(values, scale, offset)
        note = "GENERATED by stormlane (synthetic demo weather, not Copernicus data). " if synthetic else ""
        nc.setncatts({
            "title": "Global Ocean Waves Analysis and Forecast - 3-hourly instantaneous fields",
            "institution": "Meteo-France" if not synthetic else "stormlane demo scenario",
            "source": "MFWAM" if not synthetic else "stormlane weather.scenario",
            "product_id": product_id,
            "dataset_id": dataset_id,
            "Conventions": "CF-1.8",
            "credit": "E.U. Copernicus Marine Service Information (CMEMS)" if not synthetic else "none (synthetic)",
            "references": "http://marine.copernicus.eu",
            "comment": note + comment,
            "stormlane_synthetic": "true" if synthetic else "false",
        })
    return path


@contextlib.contextmanager
def _client_limits(timeout_s: float, http_retries: int):
    """Bound the copernicusmarine client's own HTTP retries and timeout (STACK.md) for one call."""
    keys = {"COPERNICUSMARINE_HTTPS_TIMEOUT": str(timeout_s), "COPERNICUSMARINE_HTTPS_RETRIES": str(http_retries)}
    old = {k: os.environ.get(k) for k in keys}
    os.environ.update(keys)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def _no_prompt():
    """Without credentials the client asks for a username on stdin (``click.prompt``): during a
    download stdin reads as empty, so it gives up at once ("Abort", returns None) instead of
    waiting for a person (nightly runs are unattended), and what it prints goes to stderr so
    stdout keeps only the ``--json`` object."""
    import io
    import sys

    saved = sys.stdin
    sys.stdin = io.StringIO("")
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stdin = saved


def get_cmems(
    bbox,
    start,
    end,
    *,
    product: str = "cmems-wave",
    dataset_id: str | None = None,
    variables=None,
    cache: DownloadCache | None = None,
    attempts: int = 3,
    timeout_s: float = 30.0,
    backoff_s=(2.0, 5.0, 15.0),
    sleep=time.sleep,
) -> tuple[Path, dict]:
    """Download (or reuse) a CMEMS subset; returns ``(path, metadata)``.

    Parameters
    ----------
    bbox : (lon_min, lat_min, lon_max, lat_max)
    start, end : datetime-like (UTC)
    product : str
        A key of :data:`DATASETS` (default dataset and variables).
    dataset_id, variables : optional
        Override the defaults.
    cache : DownloadCache, optional
        Default ``$STORMLANE_CACHE`` or ``~/.cache/stormlane/weather``.
    attempts : int
        Total tries on network errors (bounded); ``timeout_s`` is the client's HTTP timeout.

    Returns
    -------
    (Path, dict)
        The NetCDF file and ``{"cached": bool, "request": ..., "attempts": n}``.

    Raises
    ------
    FetchError
        No credentials (client returned None), repeated network failure, or an unreadable result.
    """
    if product not in DATASETS and dataset_id is None:
        raise FetchError(f"unknown CMEMS product {product!r}; known: {', '.join(DATASETS)} (or pass dataset_id)")
    default_id, default_vars = DATASETS.get(product, (None, ()))
    dataset_id = dataset_id or default_id
    variables = tuple(variables or default_vars)
    cache = cache or DownloadCache()
    req = Request.make(product, dataset_id, variables, bbox, start, end)
    hit = cache.lookup(req)
    if hit is not None:
        log.info("CMEMS %s: cache hit %s", dataset_id, hit)
        return hit, {"cached": True, "request": req.to_dict(), "attempts": 0}
    import copernicusmarine

    tmp = cache.temp_path(req)
    last_err: Exception | None = None
    for attempt in range(1, attempts + 1):
        try:
            with _client_limits(timeout_s, 1), _no_prompt():
                result = copernicusmarine.subset(
                    dataset_id=dataset_id,
                    variables=list(variables),
                    minimum_longitude=req.bbox[0],
                    maximum_longitude=req.bbox[2],
                    minimum_latitude=req.bbox[1],
                    maximum_latitude=req.bbox[3],
                    start_datetime=req.start_utc.replace("Z", ""),
                    end_datetime=req.end_utc.replace("Z", ""),
                    output_directory=str(tmp.parent),
                    output_filename=tmp.name,
                    overwrite=True,
                    disable_progress_bar=True,
                )
        except Exception as err:  # network, service, or client error: retry a bounded number of times
            last_err = err
            log.warning("CMEMS %s attempt %d/%d failed: %s", dataset_id, attempt, attempts, err)
            if attempt < attempts:
                sleep(backoff_s[min(attempt - 1, len(backoff_s) - 1)])
            continue
        if result is None:
            raise FetchError(
                f"CMEMS {dataset_id}: the copernicusmarine client returned nothing (usually no credentials: run "
                "`copernicusmarine login` or set its COPERNICUSMARINE_SERVICE_USERNAME/PASSWORD variables)"
            )
        produced = Path(getattr(result, "file_path", None) or tmp)
        if not produced.exists():
            raise FetchError(f"CMEMS {dataset_id}: the client reported success but wrote no file at {produced}")
        if produced != tmp:
            os.replace(produced, tmp)
        try:
            open_netcdf(tmp).close()
        except WeatherFileError as err:
            tmp.unlink(missing_ok=True)
            raise FetchError(f"CMEMS {dataset_id}: downloaded file is unreadable: {err}") from None
        path = cache.commit(req, tmp, {"client": "copernicusmarine", "dataset_id": dataset_id})
        return path, {"cached": False, "request": req.to_dict(), "attempts": attempt}
    tmp.unlink(missing_ok=True)
    raise FetchError(f"CMEMS {dataset_id}: download failed after {attempts} attempts: {type(last_err).__name__}: {last_err}")
