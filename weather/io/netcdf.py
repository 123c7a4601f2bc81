"""NetCDF weather files in their products' own schemas -> canonical weather.

One reader, :func:`read_netcdf`, recognises the product from the variables it holds:

* **CMEMS waves** (MEDSEA ``MEDSEA_ANALYSIS_FORECAST_WAV_006_017``, GLOBAL
  ``cmems_mod_glo_wav_anfc_0.083deg_PT3H-i`` ...): ``VHM0``, ``VMDR``, ``VTPK``, ``VTM10`` /
  ``VTM02``, usually int16 packed with ``scale_factor``/``add_offset`` and ``_FillValue`` =
  ``missing_value`` = -32767 on land (decoded by xarray's CF masking and scaling).
* **CMEMS currents** (``cmems_mod_glo_phy-cur_anfc_0.083deg_P1D-m``, merged ``utotal``/``vtotal``):
  ``uo``/``vo`` or ``utotal``/``vtotal`` (a singleton ``depth`` is dropped).
* **ERA5 single levels** from the CDS, both layouts: the old ``grib_to_netcdf`` one (dims
  ``time, latitude, longitude``, int16 packed, longitudes 0..360, latitudes descending, an
  ``expver`` dimension when ERA5T is mixed in) and the new one (``valid_time`` dimension, float32,
  ``number``/``expver`` coordinates): ``u10``, ``v10`` and optionally ``swh``, ``mwd``, ``pp1d``, ``mwp``.
* **Merged files** such as the 52North WeatherRoutingTool test file (CMEMS waves + currents + GFS
  winds on the wave grid, wind at several heights: the 10 m level is selected).

The ``read_cmems`` / ``read_era5`` wrappers in :mod:`weather.io.cmems` / :mod:`weather.io.era5`
use it and check they got the product they expect.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import xarray as xr

from weather.canonical import normalise_weather
from weather.errors import WeatherFileError

log = logging.getLogger(__name__)

#: Source name -> canonical name. Order matters: the first present source of a canonical name wins.
VARIABLE_MAP: dict[str, str] = {
    # CMEMS waves
    "VHM0": "hs_m",
    "VMDR": "wave_from_deg",
    "VTPK": "tp_s",
    "VTM10": "tm_s",
    "VTM02": "tm_s",
    # CMEMS currents (total currents preferred: they include tides and Stokes drift)
    "utotal": "current_u_ms",
    "vtotal": "current_v_ms",
    "uo": "current_u_ms",
    "vo": "current_v_ms",
    # ERA5 single levels
    "u10": "wind_u_ms",
    "v10": "wind_v_ms",
    "swh": "hs_m",
    "mwd": "wave_from_deg",
    "pp1d": "tp_s",
    "mwp": "tm_s",
    # GFS on THREDDS / merged files (10 m level selected below)
    "u-component_of_wind_height_above_ground": "wind_u_ms",
    "v-component_of_wind_height_above_ground": "wind_v_ms",
}

_WAVE = {"VHM0", "VMDR", "VTPK", "VTM10", "VTM02"}
_CURRENT = {"uo", "vo", "utotal", "vtotal"}
_ERA5 = {"u10", "v10", "swh", "mwd", "pp1d", "mwp"}
_GFS_HEIGHT = {"u-component_of_wind_height_above_ground", "v-component_of_wind_height_above_ground"}


def open_netcdf(path: str | Path) -> xr.Dataset:
    """Open a NetCDF 3/4 file with CF decoding; errors name the file."""
    path = Path(path)
    if not path.exists():
        raise WeatherFileError(f"{path}: no such file")
    try:
        return xr.open_dataset(path, engine="netcdf4", mask_and_scale=True, decode_times=True, cache=False)
    except Exception as err:  # netCDF4 raises OSError / RuntimeError with terse messages
        raise WeatherFileError(f"{path}: not a readable NetCDF file ({type(err).__name__}: {err})") from None


def detect_product(ds: xr.Dataset, path: str | Path) -> str:
    """A product label from the variables and global attributes (used in provenance and errors)."""
    names = set(ds.data_vars)
    text = " ".join(str(ds.attrs.get(k, "")) for k in ("product_id", "references", "title", "source", "institution", "history"))
    labels = []
    if names & _WAVE:
        pid = str(ds.attrs.get("product_id", ""))
        if pid:
            labels.append(f"CMEMS {pid}")
        elif "MEDSEA" in text:
            labels.append("CMEMS MEDSEA_ANALYSIS_FORECAST_WAV_006_017" if "006_017" in text else "CMEMS MEDSEA waves")
        elif "cmems_mod_glo_wav" in Path(path).name:
            labels.append(f"CMEMS {Path(path).stem}")
        else:
            labels.append("CMEMS waves")
    if names & _CURRENT:
        stem = Path(path).name
        labels.append(f"CMEMS {stem.split('_2')[0]}" if stem.startswith("cmems_mod_glo_phy") else "CMEMS currents")
    if names & _ERA5:
        layout = "valid_time" if "valid_time" in ds.dims else "time"
        labels.append(f"ERA5 single levels ({layout} layout)")
    if names & _GFS_HEIGHT:
        labels.append("NOAA GFS 0.25 (via THREDDS)")
    if labels and str(ds.attrs.get("stormlane_synthetic", "")).lower() == "true":
        labels[-1] += " (synthetic)"
    if not labels:
        raise WeatherFileError(
            f"{path}: not a recognised weather product (variables: {', '.join(sorted(map(str, names))) or 'none'}; "
            f"expected CMEMS VHM0/VMDR/VTPK, uo/vo, utotal/vtotal or ERA5 u10/v10)"
        )
    return " + ".join(labels)


def _select_levels(ds: xr.Dataset, path) -> xr.Dataset:
    """Pick the 10 m wind level of multi-height winds; merge ERA5/ERA5T ``expver`` slices."""
    for name in list(ds.data_vars):
        da = ds[name]
        for dim in da.dims:
            if dim.startswith("height_above_ground") and da.sizes[dim] > 1:
                heights = np.asarray(ds[dim].values, dtype=float)
                if not np.any(np.isclose(heights, 10.0)):
                    raise WeatherFileError(f"{path}: {name} has no 10 m level (heights {heights.tolist()})")
                ds[name] = da.isel({dim: int(np.flatnonzero(np.isclose(heights, 10.0))[0])}, drop=True)
        if "expver" in ds[name].dims:
            da = ds[name]
            merged = da.isel(expver=0)
            for k in range(1, da.sizes["expver"]):
                merged = merged.combine_first(da.isel(expver=k))
            ds[name] = merged
    return ds


def read_netcdf(path: str | Path, *, product: str | None = None) -> tuple[xr.Dataset, dict]:
    """Read one NetCDF weather file into canonical form.

    Parameters
    ----------
    path : str or Path
    product : str, optional
        Overrides the detected product label.

    Returns
    -------
    (xarray.Dataset, dict)
        Canonical dataset and metadata: ``product``, ``path``, ``variables`` (canonical -> source
        name), ``start_utc``/``end_utc``, ``bbox``, ``n_times``, ``grid_step_deg``.
    """
    path = Path(path)
    raw = open_netcdf(path)
    try:
        label = product or detect_product(raw, path)
        raw = _select_levels(raw, path)
        # keep only one source per canonical name (first in VARIABLE_MAP order)
        chosen: dict[str, str] = {}
        for src, dst in VARIABLE_MAP.items():
            if src in raw.data_vars and dst not in chosen.values():
                chosen[src] = dst
        ds = normalise_weather(
            raw,
            chosen,
            product=label,
            source_files=[str(path)],
            attrs={"source_conventions": str(raw.attrs.get("Conventions", "")), "source_title": str(raw.attrs.get("title", ""))},
        )
    finally:
        raw.close()
    return ds, metadata_of(ds, path)


def metadata_of(ds: xr.Dataset, path=None) -> dict:
    """Summary metadata of a canonical dataset (what the CLI prints and the loader stores)."""
    from weather.canonical import grid_step
    from weather.coverage import data_extent

    ext = data_extent(ds)
    return {
        "product": ds.attrs.get("product", ""),
        "path": None if path is None else str(path),
        "source_files": ds.attrs.get("source_files", ""),
        "variables": {v: ds[v].attrs.get("source_name", v) for v in ds.data_vars},
        "n_times": int(ds.time_utc.size),
        "shape": [int(ds.time_utc.size), int(ds.lat.size), int(ds.lon.size)],
        "grid_step_deg": [grid_step(ds.lat.values), grid_step(ds.lon.values)],
        **ext,
    }
