"""Weather file and network adapters: one module per product, each returning ``(data, metadata)``.

Entry point: :func:`read_local` (detects CMEMS / ERA5 / GRIB / zarr files and merges them onto
one grid). Per product: :mod:`weather.io.cmems` (``get_cmems``, ``read_cmems``,
``write_cmems_wave``), :mod:`weather.io.era5` (``get_era5``, ``read_era5``, ``write_era5``),
:mod:`weather.io.gfs` (``read_gfs``), :mod:`weather.io.wind_zarr` (``read_wind_zarr``).
"""

from weather.io.local import read_local

__all__ = ["read_local"]
