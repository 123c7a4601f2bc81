"""Derived ERA5 10 m wind stored as speed/direction in zarr (the ``weather_routing`` test set).

The ``test_ds.zarr`` of ``peterm790/weather_routing`` (see ``../shared/data/weather/PROVENANCE.md``
item 6) holds ``tws`` = |(u10, v10)| in **knots** and ``twd`` = direction the wind comes **from**
(degrees true), 12-hourly, 0.25°, built from ERA5. The arrays carry no unit attributes; the units
come from the provenance. Components are rebuilt as u = −V·sin(twd), v = −V·cos(twd) (WMO
"from" convention: a wind from 270° blows toward +x).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from thresholds.units import MS_PER_KN
from weather.canonical import normalise_weather
from weather.errors import WeatherFileError
from weather.io.netcdf import metadata_of


def read_wind_zarr(path: str | Path, speed_units: str = "knots") -> tuple[xr.Dataset, dict]:
    """Read a zarr store with ``tws`` (speed) and ``twd`` (from-direction) into canonical wind.

    Parameters
    ----------
    path : str or Path
        The ``.zarr`` directory.
    speed_units : {"knots", "m s-1"}
        Unit of ``tws`` (the store has no unit attribute).
    """
    path = Path(path)
    if not path.is_dir():
        raise WeatherFileError(f"{path}: no such zarr directory")
    try:
        # numpy-backed (chunks=None): the CLI tells xarray its process holds no dask arrays
        raw = xr.open_zarr(path, consolidated=None, chunks=None)
    except Exception as err:
        raise WeatherFileError(f"{path}: not a readable zarr store ({type(err).__name__}: {err})") from None
    if not {"tws", "twd"} <= set(raw.data_vars):
        raise WeatherFileError(f"{path}: expected variables tws and twd (has: {', '.join(map(str, raw.data_vars))})")
    factor = {"knots": MS_PER_KN, "m s-1": 1.0}.get(speed_units)
    if factor is None:
        raise WeatherFileError(f"speed_units must be 'knots' or 'm s-1', not {speed_units!r}")
    speed_ms = raw["tws"].astype("float64") * factor
    rad = np.deg2rad(raw["twd"].astype("float64"))
    comp = xr.Dataset(
        {
            "u10": (-speed_ms * np.sin(rad)).assign_attrs(units="m s-1"),
            "v10": (-speed_ms * np.cos(rad)).assign_attrs(units="m s-1"),
        }
    ).load()
    out = normalise_weather(
        comp,
        {"u10": "wind_u_ms", "v10": "wind_v_ms"},
        product="ERA5-derived 10 m wind (tws/twd zarr)",
        source_files=[str(path)],
        attrs={"derivation": f"u = -tws*sin(twd), v = -tws*cos(twd); tws in {speed_units}"},
    )
    raw.close()
    return out, metadata_of(out, path)
