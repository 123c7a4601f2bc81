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


#: At most this much of a NetCDF file is read to parse its header (headers are a few kB).
_HEADER_BYTES = 1 << 22
#: Bytes per value of the NetCDF classic types (NC_BYTE .. NC_UINT64; 7-11 are CDF-5 only).
_CDF_TYPE_SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 4, 6: 8, 7: 1, 8: 2, 9: 4, 10: 8, 11: 8}


class _Header:
    """Big-endian reader over the first bytes of a file; ``EOFError`` past the end."""

    def __init__(self, data: bytes, pos: int = 0):
        self.data, self.pos = data, pos

    def take(self, n: int) -> bytes:
        if self.pos + n > len(self.data):
            raise EOFError
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def uint(self, n: int) -> int:
        return int.from_bytes(self.take(n), "big")


def _netcdf3_data_end(data: bytes) -> int | None:
    """Smallest file size the header of a NetCDF classic file (CDF-1, -2 or -5) implies: the end of
    its last variable's data (unpadded, so a lower bound). ``None`` when the header is not
    understood; ``EOFError`` when ``data`` ends inside the header."""
    if len(data) < 4:
        raise EOFError
    version = data[3]
    if version not in (1, 2, 5):
        return None
    size = 8 if version == 5 else 4  # NON_NEG (counts, lengths)
    offset = 4 if version == 1 else 8  # OFFSET (begin)
    h = _Header(data, 4)

    def name() -> None:
        n = h.uint(size)
        h.take(-(-n // 4) * 4)

    def attributes() -> None:
        tag, n = h.uint(4), h.uint(size)
        if tag not in (0, 0x0C):
            raise ValueError
        for _ in range(n):
            name()
            nc_type, count = h.uint(4), h.uint(size)
            h.take(-(-count * _CDF_TYPE_SIZE[nc_type] // 4) * 4)

    try:
        numrecs = h.uint(size)
        if numrecs == (1 << (8 * size)) - 1:  # STREAMING: record count unknown
            numrecs = 0
        tag, n = h.uint(4), h.uint(size)
        if tag not in (0, 0x0A):
            return None
        dims = []
        for _ in range(n):
            name()
            dims.append(h.uint(size))
        attributes()
        tag, n = h.uint(4), h.uint(size)
        if tag not in (0, 0x0B):
            return None
        fixed_end, records = 0, []  # records: (begin, bytes per record)
        for _ in range(n):
            name()
            dimids = [h.uint(size) for _ in range(h.uint(size))]
            attributes()
            nc_type = h.uint(4)
            h.uint(size)  # vsize (capped for huge variables: recomputed below)
            begin = h.uint(offset)
            shape = [dims[d] for d in dimids]
            record = bool(shape) and shape[0] == 0
            nbytes = _CDF_TYPE_SIZE[nc_type] * int(np.prod(shape[1:] if record else shape, dtype=np.int64))
            if record:
                records.append((begin, nbytes))
            else:
                fixed_end = max(fixed_end, begin + nbytes)
    except (KeyError, ValueError, IndexError):
        return None
    end = fixed_end
    if records and numrecs:
        # one record holds every record variable, each padded to 4 bytes unless it is the only one
        recsize = records[0][1] if len(records) == 1 else sum(-(-b // 4) * 4 for _, b in records)
        end = max(end, max(begin + (numrecs - 1) * recsize + nbytes for begin, nbytes in records))
    return end


def _hdf5_data_end(data: bytes) -> int | None:
    """End-of-file address recorded in an HDF5 (NetCDF-4) superblock at offset 0, ``None`` when
    not understood, ``EOFError`` when ``data`` ends inside the superblock."""
    if len(data) < 14:
        raise EOFError
    version = data[8]
    if version in (0, 1):
        o, pos, fields = data[13], 24 + (4 if version == 1 else 0), 4  # base, free space, EOF, driver
    elif version in (2, 3):
        o, pos, fields = data[9], 12, 3  # base, superblock extension, EOF
    else:
        return None
    if o not in (2, 4, 8):
        return None
    if pos + fields * o > len(data):
        raise EOFError
    values = [int.from_bytes(data[pos + k * o : pos + (k + 1) * o], "little") for k in range(fields)]
    base, eof = values[0], values[2]
    undefined = (1 << (8 * o)) - 1
    if undefined in (base, eof):
        return None
    return base + eof


def check_complete(path: str | Path) -> None:
    """Raise :class:`WeatherFileError` when a NetCDF file is shorter than its own header says.

    A partial download or copy of a NetCDF classic file opens without complaint and reads the
    missing data as fill values (so the reader would report nonsense such as duplicate
    coordinates); a NetCDF-4 (HDF5) file records its end-of-file address in the superblock.
    Both are compared with the size on disk.
    """
    path = Path(path)
    actual = path.stat().st_size
    with open(path, "rb") as fh:
        data = fh.read(4)
        if data[:3] == b"CDF":
            kind, parse = "NetCDF classic", _netcdf3_data_end
        elif data[:4] == b"\x89HDF":
            kind, parse = "NetCDF-4/HDF5", _hdf5_data_end
        else:
            return
        n = 1 << 16
        while True:
            fh.seek(0)
            data = fh.read(n)
            try:
                need = parse(data)
                break
            except EOFError:
                if len(data) >= actual:  # the whole file is shorter than its header
                    raise WeatherFileError(
                        f"{path}: truncated {kind} file: its {actual} bytes end inside the header; download or copy it again"
                    ) from None
                if n >= _HEADER_BYTES:  # a header longer than we read: not checked
                    return
                n *= 8
    if need is not None and actual < need:
        raise WeatherFileError(
            f"{path}: truncated {kind} file: {actual} bytes on disk, its header says {need}; download or copy it again"
        )


def open_netcdf(path: str | Path) -> xr.Dataset:
    """Open a NetCDF 3/4 file with CF decoding; errors name the file (truncated files included)."""
    path = Path(path)
    if not path.exists():
        raise WeatherFileError(f"{path}: no such file")
    if path.is_file():
        check_complete(path)
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
