"""Canonical weather Dataset (xarray) -> the router's numpy :class:`routing.field.WeatherField`.

``routing`` never imports xarray or ``weather``: this adapter sits in ``pipelines`` and is the
one place where the two meet.
"""

from __future__ import annotations

import numpy as np

from routing.errors import WeatherCoverageError
from routing.field import KNOWN_VARIABLES, WeatherField


def require_weather_files(files, error: type[Exception] = WeatherCoverageError) -> None:
    """Every weather file exists, else one ``error`` naming the missing ones (route, nightly)."""
    from pathlib import Path

    missing = [str(f) for f in files if not Path(f).exists()]
    if missing:
        raise error(f"weather file(s) not found: {', '.join(missing)}")


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


#: Variables the search routes on (the others are only reported), named in coverage errors.
ROUTED_VARIABLES = ("hs_m", "wave_from_deg", "current_u_ms", "current_v_ms")


def check_route_coverage(ds, depart_utc, points=()) -> None:
    """Raise :class:`WeatherCoverageError` unless ``ds`` covers a route's departure and end points.

    The message is :func:`weather.coverage.check_coverage`'s (the one of ``weather join`` and
    ``nightly``): the product, the variables the router uses and the missing span or bbox. After
    the last weather time the router holds the last field and the route says so
    (``weather_held_after_h``), so only the departure must lie within the data's times.

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical weather (``weather.io.read_local``).
    depart_utc : pandas.Timestamp
        Departure (timezone-aware).
    points : sequence of (what, (lat_deg, lon_deg))
        Named points that must lie inside the grid, e.g. ``[("start", start), ("goal", goal)]``.
        [deg]

    Raises
    ------
    WeatherCoverageError
    """
    import pandas as pd

    from weather.coverage import _fmt, check_coverage
    from weather.errors import CoverageError

    variables = [v for v in ROUTED_VARIABLES if v in ds.data_vars] or [v for v in KNOWN_VARIABLES if v in ds.data_vars]
    depart = pd.Timestamp(depart_utc).tz_convert("UTC")
    t0 = pd.Timestamp(ds.time_utc.values[0]).tz_localize("UTC")
    t1 = pd.Timestamp(ds.time_utc.values[-1]).tz_localize("UTC")
    # the missing span runs from the departure to the data (or from the data's end to the departure)
    start, end = (depart, t0) if depart < t0 else (t1, depart) if depart > t1 else (depart, depart)
    try:
        check_coverage(ds, variables=variables, start=start, end=end)
    except CoverageError as err:
        raise WeatherCoverageError(f"departure {_fmt(depart)} is outside the weather's times: {err}") from None
    if not points:
        return
    lat = [float(p[1][0]) for p in points]
    lon = [float(p[1][1]) for p in points]
    box = (min(lon), min(lat), max(lon), max(lat))
    try:
        check_coverage(ds, variables=variables, bbox=box)
    except CoverageError as err:
        g = (float(ds.lon.min()), float(ds.lat.min()), float(ds.lon.max()), float(ds.lat.max()))
        outside = [f"{what} ({la:.4f}, {lo:.4f})" for (what, _), la, lo in zip(points, lat, lon)
                   if not (g[0] - 1e-6 <= lo <= g[2] + 1e-6 and g[1] - 1e-6 <= la <= g[3] + 1e-6)]
        what = f"{' and '.join(outside)} {'is' if len(outside) == 1 else 'are'}" if outside else "the route is"
        raise WeatherCoverageError(f"{what} outside the weather grid: {err}") from None


def load_weather(paths, *, depart_utc=None, points=()) -> tuple[WeatherField, dict]:
    """Read local weather files (CMEMS, ERA5, GRIB ...) through ``weather.io.read_local``.

    With ``depart_utc`` (and ``points``) the data's coverage of the route is checked first
    (:func:`check_route_coverage`). Returns ``(WeatherField, metadata)``.
    """
    from weather.io import read_local

    ds, meta = read_local(paths)
    if depart_utc is not None:
        check_route_coverage(ds, depart_utc, points)
    return field_from_dataset(ds), meta
