"""NOAA GFS GRIB (edition 1 or 2) 10 m winds via cfgrib/ecCodes -> canonical weather.

cfgrib works offline here (ecCodes ships in the ``eccodes`` wheel). A GRIB file mixes
parameters, level types and step types (instant / avg / accum), which cfgrib cannot put in one
dataset, so each wanted variable is opened with its own ``filter_by_keys``
(``shortName``, ``typeOfLevel``, ``level``, ``stepType``).

Known defect handled here: the zyGrib/saildocs-style GFS extracts in ``../shared/data``
(``gweatherrouting_gfs_grib1``) carry a corrupt ``jDirectionIncrement`` (33.268° instead of
0.5°) while the first/last latitudes and ``Nj`` are right, so ecCodes computes latitudes down to
−1449°. The reader rebuilds the latitude axis from the first/last grid points and ``Ny`` when the
decoded axis does not end at ``latitudeOfLastGridPoint``, and records it in
``attrs["grid_fix"]``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from weather.canonical import normalise_weather
from weather.errors import WeatherFileError
from weather.io.netcdf import metadata_of

#: GRIB shortName -> canonical name (10 m wind components).
VARIABLE_MAP = {"10u": "wind_u_ms", "10v": "wind_v_ms"}
#: cfgrib's variable name for each shortName.
_CF_NAMES = {"10u": "u10", "10v": "v10"}


def _fix_latitudes(da: xr.DataArray) -> tuple[xr.DataArray, str]:
    a = da.attrs
    first = a.get("GRIB_latitudeOfFirstGridPointInDegrees")
    last = a.get("GRIB_latitudeOfLastGridPointInDegrees")
    ny = a.get("GRIB_Ny")
    lat = np.asarray(da["latitude"].values, dtype=float)
    if first is None or last is None or ny is None or lat.size != int(ny):
        return da, ""
    if np.isclose(lat[0], first, atol=1e-6) and np.isclose(lat[-1], last, atol=1e-6) and np.all(np.abs(lat) <= 90.0):
        return da, ""
    fixed = np.linspace(float(first), float(last), int(ny))
    note = (f"latitudes rebuilt from first/last grid point {first}..{last} and Ny={ny}: the file's "
            f"jDirectionIncrement {a.get('GRIB_jDirectionIncrementInDegrees')} deg is inconsistent with them")
    return da.assign_coords(latitude=fixed), note


def read_gfs(path: str | Path) -> tuple[xr.Dataset, dict]:
    """Read the 10 m wind of a GFS GRIB file into canonical form.

    Returns
    -------
    (xarray.Dataset, dict)
        ``wind_u_ms``, ``wind_v_ms`` on the file's grid at every forecast step (``time_utc`` is
        the valid time = run time + step); metadata as :func:`weather.io.netcdf.read_netcdf`,
        plus ``run_utc``.
    """
    path = Path(path)
    if not path.exists():
        raise WeatherFileError(f"{path}: no such file")
    arrays = {}
    notes = []
    run = None
    for short, canonical in VARIABLE_MAP.items():
        try:
            ds = xr.open_dataset(
                path,
                engine="cfgrib",
                backend_kwargs={
                    "filter_by_keys": {"shortName": short, "typeOfLevel": "heightAboveGround", "level": 10, "stepType": "instant"},
                    "indexpath": "",  # never write .idx files next to (possibly read-only) data
                },
            )
        except Exception as err:
            raise WeatherFileError(f"{path}: cannot decode GRIB ({type(err).__name__}: {err})") from None
        if _CF_NAMES[short] not in ds.data_vars:
            raise WeatherFileError(f"{path}: no {short} (10 m wind, instantaneous) messages in this GRIB file")
        da = ds[_CF_NAMES[short]].load()
        centre = ds.attrs.get("GRIB_centre", "")
        da, note = _fix_latitudes(da)
        if note and note not in notes:
            notes.append(note)
        run = ds["time"].values
        arrays[short] = da
        ds.close()
    combined = xr.Dataset({k: v for k, v in arrays.items()})
    label = "NOAA GFS GRIB (10 m wind)" if centre == "kwbc" else f"GRIB from centre {centre or '?'} (10 m wind)"
    out = normalise_weather(
        combined,
        VARIABLE_MAP,
        product=label,
        source_files=[str(path)],
        attrs={"grid_fix": "; ".join(notes), "run_utc": str(np.datetime_as_string(run, unit="m")) + "Z"},
    )
    meta = metadata_of(out, path)
    meta["run_utc"] = out.attrs["run_utc"]
    meta["grid_fix"] = out.attrs["grid_fix"]
    return out, meta
