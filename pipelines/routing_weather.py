"""Canonical weather Dataset (xarray) -> the router's numpy :class:`routing.field.WeatherField`.

``routing`` never imports xarray or ``weather``: this adapter sits in ``pipelines`` and is the
one place where the two meet.
"""

from __future__ import annotations

import numpy as np

from routing.errors import WeatherCoverageError
from routing.field import KNOWN_VARIABLES, WeatherField


def field_from_dataset(ds) -> WeatherField:
    """Convert a canonical weather Dataset into a :class:`WeatherField`.

    Parameters
    ----------
    ds : xarray.Dataset
        Dims ``("time_utc", "lat", "lon")`` (any order), coords ``time_utc`` (datetime64,
        UTC), ``lat`` and ``lon`` in degrees; variables among
        :data:`routing.field.KNOWN_VARIABLES` (others are ignored); land is NaN.

    Returns
    -------
    WeatherField
        Coordinates sorted ascending, longitudes wrapped to [-180, 180), values float32.

    Raises
    ------
    WeatherCoverageError
        When a dimension is missing or no usable variable is present.
    """
    for dim in ("time_utc", "lat", "lon"):
        if dim not in ds.dims:
            raise WeatherCoverageError(f"weather dataset lacks the dimension {dim!r} (has {tuple(ds.dims)})")
    names = [v for v in KNOWN_VARIABLES if v in ds.data_vars]
    if not names:
        raise WeatherCoverageError(
            f"weather dataset has none of the variables the router uses ({', '.join(KNOWN_VARIABLES)}); "
            f"it has {', '.join(map(str, ds.data_vars)) or 'none'}"
        )
    ds = ds[names]
    lon = ds["lon"].values.astype(float)
    wrapped = (lon + 180.0) % 360.0 - 180.0
    if not np.array_equal(wrapped, lon):
        ds = ds.assign_coords(lon=wrapped)
    ds = ds.sortby(["time_utc", "lat", "lon"])
    times = ds["time_utc"].values
    if np.issubdtype(times.dtype, np.datetime64):
        time_ns = times.astype("datetime64[ns]").astype(np.int64)
    else:  # timezone-aware objects
        import pandas as pd

        time_ns = pd.DatetimeIndex(times).tz_convert("UTC").asi8 if pd.DatetimeIndex(times).tz else pd.DatetimeIndex(times).asi8
    variables = {name: ds[name].transpose("time_utc", "lat", "lon").values.astype(np.float32) for name in names}
    attrs = {k: ds.attrs[k] for k in ("product", "source_files") if k in ds.attrs}
    return WeatherField(time_ns, ds["lat"].values.astype(float), ds["lon"].values.astype(float), variables, attrs)


def load_weather(paths) -> tuple[WeatherField, dict]:
    """Read local weather files (CMEMS, ERA5, GRIB ...) through ``weather.io.read_local``.

    Returns ``(WeatherField, metadata)``.
    """
    from weather.io import read_local

    ds, meta = read_local(paths)
    return field_from_dataset(ds), meta
