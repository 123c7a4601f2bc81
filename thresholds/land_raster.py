"""The global 30 arc-second land mask, read one window at a time from a bit-packed cache file.

global-land-mask [1]_ ships the GLOBE-derived land/ocean raster (21 600 x 43 200 pixels of
30", True = ocean) as a 2.4 MB compressed ``.npz``; ``import global_land_mask.globe`` inflates
all of it into a 0.93 GB boolean array, ~2 s and most of a routing process's memory. Here the
raster is inflated **once per machine**, row block by row block (bounded memory, ~11 MB at a
time), into a bit-packed file of 117 MB (one bit per pixel, rows of 5 400 bytes), which every
process then memory-maps: a window of a few degrees reads a few hundred kB.

* Where: ``$STORMLANE_CACHE/land/`` when ``STORMLANE_CACHE`` is set, else
  ``$XDG_CACHE_HOME/stormlane/land/`` or ``~/.cache/stormlane/land/``. The file name carries
  the CRC-32 and size of the package's ``mask.npy``, so a different package version gets its
  own file.
* Safe: the file is written under a temporary name in the same folder, flushed to disk and
  renamed (atomic on POSIX), so a reader never sees half a file; two processes building it at
  once serialise on an ``flock`` of a lock file next to it, the second one finds the file done.
  A file of the wrong size is rebuilt.
* When the folder cannot be written, the window is inflated directly from the package file,
  keeping only its rows (same bounded memory, ~1-2 s per call) and a warning says why.

Pixel (r, c) covers lat (90 - (r+1)/120, 90 - r/120] and lon [-180 + c/120, -180 + (c+1)/120)
(windows, :func:`read_ocean`); point look-ups (:func:`is_ocean`) use the package's own index
arithmetic (``globe.lat_to_index`` / ``lon_to_index``), so they agree with it even on pixel
edges. Columns wrap modulo 43 200, so any longitude frame (e.g. lon > 180 on a route across the
antimeridian) reads the right pixels.

References
----------
.. [1] T. Karin, global-land-mask 1.0 (GLOBE 30" land mask derived from the NOAA GLOBE DEM),
       https://github.com/toddkarin/global-land-mask
.. [2] NOAA National Geophysical Data Center, "Global Land One-km Base Elevation (GLOBE)
       v.1," 1999, doi:10.7289/V52R3PMS.
"""

from __future__ import annotations

import logging
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

#: Raster size and resolution of global-land-mask [1]_.
N_ROWS = 21_600
N_COLS = 43_200
PX_PER_DEG = 120
ROW_BYTES = N_COLS // 8
#: Rows inflated per block while the cache is built (~11 MB of booleans).
_BLOCK_ROWS = 256
_MEMBER = "mask.npy"

_raster_cache: dict = {}


def source_path() -> Path:
    """The package's compressed mask file (found without importing ``global_land_mask.globe``)."""
    import importlib.util

    spec = importlib.util.find_spec("global_land_mask")
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError("global-land-mask is not installed: the land mask needs it (pip install global-land-mask)")
    return Path(list(spec.submodule_search_locations)[0]) / "globe_combined_mask_compressed.npz"


def cache_dir() -> Path:
    """``$STORMLANE_CACHE/land``, else ``$XDG_CACHE_HOME/stormlane/land`` or ``~/.cache/stormlane/land``."""
    env = os.environ.get("STORMLANE_CACHE")
    if env:
        return Path(env) / "land"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "stormlane" / "land"


def _member_info(src: Path) -> zipfile.ZipInfo:
    with zipfile.ZipFile(src) as z:
        return z.getinfo(_MEMBER)


def cache_path(src: Path | None = None) -> Path:
    """Path of the bit-packed raster for this package file (CRC-32 and size in the name)."""
    src = source_path() if src is None else Path(src)
    info = _member_info(src)
    return cache_dir() / f"globe-land-30s-{info.CRC:08x}-{info.file_size}.bits"


def _open_rows(src: Path):
    """(zip, stream) positioned on the first row of ``mask.npy``, its header checked."""
    z = zipfile.ZipFile(src)
    f = z.open(_MEMBER)
    version = np.lib.format.read_magic(f)
    read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    shape, fortran, dtype = read_header(f)
    if tuple(shape) != (N_ROWS, N_COLS) or fortran or np.dtype(dtype) != np.dtype(bool):
        f.close()
        z.close()
        raise ValueError(f"{src}: {_MEMBER} is {shape} {dtype} (fortran={fortran}), expected ({N_ROWS}, {N_COLS}) bool in C order")
    return z, f


def _read_rows(f, n: int) -> np.ndarray:
    buf = f.read(n * N_COLS)
    if len(buf) != n * N_COLS:
        raise ValueError(f"{_MEMBER} ended early: wanted {n} rows of {N_COLS} pixels")
    return np.frombuffer(buf, dtype=np.uint8).reshape(n, N_COLS)


def build_cache(src: Path | None = None, dest: Path | None = None) -> Path:
    """Inflate the package raster into the bit-packed cache file (if not there yet) and return it.

    Bounded memory (one block of rows at a time), atomic (temporary file + rename), and safe
    when several processes race (an exclusive ``flock`` on ``<dest>.lock``).
    """
    import fcntl

    src = source_path() if src is None else Path(src)
    dest = cache_path(src) if dest is None else Path(dest)
    if _valid(dest):
        return dest
    dest.parent.mkdir(parents=True, exist_ok=True)
    with open(dest.with_name(dest.name + ".lock"), "a+b") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if _valid(dest):  # another process built it while we waited
            return dest
        fd, tmp = tempfile.mkstemp(prefix=dest.name + ".", suffix=".tmp", dir=dest.parent)
        try:
            with os.fdopen(fd, "wb") as out:
                z, f = _open_rows(src)
                with z, f:
                    for r in range(0, N_ROWS, _BLOCK_ROWS):
                        out.write(np.packbits(_read_rows(f, min(_BLOCK_ROWS, N_ROWS - r)), axis=1).tobytes())
                out.flush()
                os.fsync(out.fileno())
            os.chmod(tmp, 0o644)  # mkstemp makes it private; the cache is shared like any cache file
            os.replace(tmp, dest)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        log.info("land mask cache written: %s (%d bytes)", dest, dest.stat().st_size)
    return dest


def _valid(path: Path) -> bool:
    try:
        return path.stat().st_size == N_ROWS * ROW_BYTES
    except OSError:
        return False


def raster() -> np.ndarray | None:
    """The whole raster as a read-only memory map of packed bits, uint8 (N_ROWS, ROW_BYTES);
    ``None`` (with a warning, once) when the cache cannot be written."""
    if "bits" not in _raster_cache:
        try:
            path = build_cache()
            _raster_cache["bits"] = np.memmap(path, dtype=np.uint8, mode="r", shape=(N_ROWS, ROW_BYTES))
        except OSError as exc:
            log.warning("land mask cache unavailable (%s): windows are inflated from %s on every call", exc, source_path())
            _raster_cache["bits"] = None
    return _raster_cache["bits"]


def _source_blocks(r_end: int):
    """(first row, bool block) of the package raster inflated block by block up to row ``r_end``."""
    z, f = _open_rows(source_path())
    with z, f:
        r = 0
        while r < r_end:
            n = min(_BLOCK_ROWS, N_ROWS - r)
            yield r, _read_rows(f, n).astype(bool)
            r += n


def _rows_from_source(r0: int, r1: int) -> np.ndarray:
    """Rows r0..r1-1 of the raster (bool, True = ocean) inflated from the package file."""
    out = np.empty((r1 - r0, N_COLS), dtype=bool)
    for r, block in _source_blocks(r1):
        lo, hi = max(r, r0), min(r + block.shape[0], r1)
        if hi > lo:
            out[lo - r0 : hi - r0] = block[lo - r : hi - r]
    return out


def _unpack_cols(bits: np.ndarray, c0: int, c1: int) -> np.ndarray:
    """Columns c0..c1-1 (0 <= c0 < c1 <= N_COLS) of packed rows, as bool."""
    b0, b1 = c0 // 8, -(-c1 // 8)
    return np.unpackbits(np.asarray(bits[:, b0:b1]), axis=1)[:, c0 - 8 * b0 : c1 - 8 * b0].astype(bool)


def read_ocean(r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
    """Pixels of rows ``r0..r1-1`` and columns ``c0..c1-1`` (bool, True = ocean).

    Rows must lie in 0..N_ROWS; columns may be any integers (taken modulo N_COLS, so a window
    may straddle the antimeridian) with ``0 < c1 - c0 <= N_COLS``.
    """
    r0, r1, c0, c1 = int(r0), int(r1), int(c0), int(c1)
    if not (0 <= r0 < r1 <= N_ROWS) or not (0 < c1 - c0 <= N_COLS):
        raise ValueError(f"window rows {r0}..{r1}, cols {c0}..{c1} is empty or outside the {N_ROWS} x {N_COLS} raster")
    bits = raster()
    if bits is None:
        rows = _rows_from_source(r0, r1)
        cols = np.arange(c0, c1) % N_COLS
        return rows[:, cols]
    rows = bits[r0:r1]
    a = c0 % N_COLS
    b = a + (c1 - c0)
    if b <= N_COLS:
        return _unpack_cols(rows, a, b)
    return np.concatenate([_unpack_cols(rows, a, N_COLS), _unpack_cols(rows, 0, b - N_COLS)], axis=1)


def _axes() -> tuple:
    """(first, step, min, max) of the package's ``lat`` and ``lon`` axes, read once from its file."""
    if "axes" not in _raster_cache:
        out = []
        with zipfile.ZipFile(source_path()) as z:
            for name in ("lat.npy", "lon.npy"):
                with z.open(name) as f:
                    a = np.lib.format.read_array(f)
                out.append((float(a[0]), float(a[1] - a[0]), float(a.min()), float(a.max())))
        _raster_cache["axes"] = tuple(out)
    return _raster_cache["axes"]


def pixel_rc(lat_deg, lon_deg) -> tuple[np.ndarray, np.ndarray]:
    """Raster row and column of points, computed exactly as the package's ``lat_to_index`` /
    ``lon_to_index`` do (clipped to its axes, ``(x - first) / step`` truncated, with the package's
    own float step: a point exactly on a pixel edge falls where the package puts it); longitudes
    of any frame are first brought into [-180, 180)."""
    (la0, dla, la_min, la_max), (lo0, dlo, lo_min, lo_max) = _axes()
    lat = np.clip(np.asarray(lat_deg, dtype=float), la_min, la_max)
    lon = np.asarray(lon_deg, dtype=float)
    lon = np.clip(np.where((lon >= -180.0) & (lon <= 180.0), lon, np.mod(lon + 180.0, 360.0) - 180.0), lo_min, lo_max)
    r = np.clip(((lat - la0) / dla).astype(np.int64), 0, N_ROWS - 1)
    c = np.clip(((lon - lo0) / dlo).astype(np.int64), 0, N_COLS - 1)
    return r, c


def is_ocean(lat_deg, lon_deg) -> np.ndarray:
    """Ocean at points (any longitude frame), read pixel by pixel from the cache. bool, input shape"""
    r, c = pixel_rc(lat_deg, lon_deg)
    bits = raster()
    if bits is None:
        out = np.zeros(r.shape, dtype=bool)
        if r.size:
            for r_blk, block in _source_blocks(int(r.max()) + 1):
                sel = (r >= r_blk) & (r < r_blk + block.shape[0])
                out[sel] = block[r[sel] - r_blk, c[sel]]
        return out
    return ((np.asarray(bits[r, c >> 3]) >> (7 - (c & 7))) & 1).astype(bool)


def is_land(lat_deg, lon_deg) -> np.ndarray:
    """Land at points (the complement of :func:`is_ocean`). bool, input shape"""
    return ~is_ocean(lat_deg, lon_deg)
