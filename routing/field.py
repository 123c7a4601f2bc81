"""Weather fields as plain numpy arrays, for the router (no xarray here).

:class:`WeatherField` is the canonical weather Dataset's content on its own regular lat/lon
grid (``pipelines.routing_weather.field_from_dataset`` builds it from the xarray Dataset).
:meth:`WeatherField.on_mesh` maps it onto a routing mesh: bilinear in space over the valid
(sea) weather points, a regular time axis, wave directions through their unit-vector
components (never as raw angles), currents converted to knots. The result,
:class:`MeshWeather`, stores one row per sea node with time contiguous, which is what the
compiled A* core reads.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from routing.errors import WeatherCoverageError
from thresholds.units import MS_PER_KN

#: Variables the router understands (canonical names of the weather Dataset).
KNOWN_VARIABLES = (
    "hs_m",
    "wave_from_deg",
    "tp_s",
    "tm_s",
    "wind_u_ms",
    "wind_v_ms",
    "current_u_ms",
    "current_v_ms",
)

NS_PER_HOUR = 3_600_000_000_000


@dataclass(frozen=True)
class WeatherField:
    """Gridded weather in canonical names.

    Attributes
    ----------
    time_ns : ndarray of int64, shape (T,)
        Valid times, nanoseconds since 1970-01-01 UTC, strictly increasing.
    lat_deg, lon_deg : ndarray, shape (ny,), (nx,)
        Ascending grid coordinates; lon in [-180, 180). [deg]
    variables : dict of str -> ndarray, shape (T, ny, nx)
        Any of :data:`KNOWN_VARIABLES`; land is NaN.
    attrs : dict
        Provenance (product, source files).
    """

    time_ns: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    variables: dict
    attrs: dict = field(default_factory=dict)

    def __post_init__(self):
        t = np.asarray(self.time_ns, dtype=np.int64)
        lat = np.asarray(self.lat_deg, dtype=float)
        lon = np.asarray(self.lon_deg, dtype=float)
        if t.ndim != 1 or t.size == 0:
            raise ValueError("WeatherField needs at least one time")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            raise ValueError("WeatherField times must be strictly increasing")
        for name, axis in (("lat_deg", lat), ("lon_deg", lon)):
            if axis.ndim != 1 or axis.size < 2 or np.any(np.diff(axis) <= 0):
                raise ValueError(f"WeatherField {name} must be 1-D, ascending, with at least 2 points")
        if lon.min() < -180.0 or lon.max() >= 180.0:
            raise ValueError("WeatherField lon_deg must lie in [-180, 180)")
        unknown = sorted(set(self.variables) - set(KNOWN_VARIABLES))
        if unknown:
            raise ValueError(f"WeatherField: unknown variable(s) {unknown}; known: {KNOWN_VARIABLES}")
        shape = (t.size, lat.size, lon.size)
        arrays = {}
        for name, values in self.variables.items():
            values = np.asarray(values, dtype=np.float32)
            if values.shape != shape:
                raise ValueError(f"WeatherField variable {name!r} has shape {values.shape}, expected {shape}")
            arrays[name] = values
        object.__setattr__(self, "time_ns", t)
        object.__setattr__(self, "lat_deg", lat)
        object.__setattr__(self, "lon_deg", lon)
        object.__setattr__(self, "variables", arrays)

    @property
    def shape(self) -> tuple:
        return (self.time_ns.size, self.lat_deg.size, self.lon_deg.size)

    def lon_cover(self) -> tuple[float, float, bool]:
        """The longitudes the grid covers, as one interval ``(lo, hi)`` of a continuous frame
        (``hi`` past 180 deg for a regional product across the antimeridian), and whether it is
        global (no gap wider than 1.5 grid steps, the wrap from the last longitude to the first
        included; then ``hi = lo + 360``)."""
        lon = self.lon_deg
        gaps = np.diff(np.r_[lon, lon[0] + 360.0])
        k = int(np.argmax(gaps))
        if gaps[k] <= 1.5 * float(np.median(np.diff(lon))):
            return float(lon[0]), float(lon[0]) + 360.0, True
        if k == lon.size - 1:
            return float(lon[0]), float(lon[-1]), False
        return float(lon[k + 1]), float(lon[k]) + 360.0, False

    def covers(self, lat: float, lon: float) -> bool:
        """The point lies inside the grid (any longitude frame): within its latitudes, and within half
        a grid step of one of its longitudes (so not in a gap of a regional product across 180 deg)."""
        step = float(np.median(np.diff(self.lon_deg)))
        d = np.abs((float(lon) - self.lon_deg + 180.0) % 360.0 - 180.0)
        return bool(self.lat_deg[0] - 1e-9 <= lat <= self.lat_deg[-1] + 1e-9 and d.min() <= 0.5 * step + 1e-9)

    def land_mask(self) -> np.ndarray:
        """Grid points without data at every time (NaN in the first wave/current/wind variable). (ny, nx)"""
        return _no_data(self.variables, self.shape[1:])

    def on_mesh(self, mesh_lat_deg, mesh_lon_deg, depart_ns: int, node_sea=None, fill_missing: bool = False) -> "MeshWeather":
        """Interpolate onto a regular mesh (nodes ``mesh_lat_deg`` x ``mesh_lon_deg``).

        Space: bilinear over the valid weather points only (weights renormalised), so coastal
        nodes get the nearby sea values; a node is *weather land* when the valid points carry
        less than half of its bilinear weight, or when it lies outside the grid (beyond half a
        grid step). Time: slices from the last one at or before the departure onwards,
        resampled to a regular step (the smallest step of the file) by linear interpolation.

        Parameters
        ----------
        mesh_lat_deg, mesh_lon_deg : ndarray
            Node latitudes (ny,) and longitudes (nx,), ascending. [deg]
        depart_ns : int
            Departure, ns since epoch UTC; must lie within the field's times.
        node_sea : ndarray of bool, shape (ny, nx), optional
            Nodes to fill (others are skipped); default every node.
        fill_missing : bool
            Also fill nodes without weather data, with calm values (for ``--ignore-land``).

        Returns
        -------
        MeshWeather
        """
        t = self.time_ns
        if depart_ns < t[0] or depart_ns > t[-1]:
            raise WeatherCoverageError(
                f"departure {_iso(depart_ns)} is outside the weather's times {_iso(t[0])} .. {_iso(t[-1])}"
            )
        first = int(np.searchsorted(t, depart_ns, side="right") - 1)
        t = t[first:]
        times, t_idx0, t_w = _regular_times(t)
        mlat = np.asarray(mesh_lat_deg, dtype=float)
        mlon = np.asarray(mesh_lon_deg, dtype=float)
        ny, nx = mlat.size, mlon.size
        if node_sea is None:
            node_sea = np.ones((ny, nx), dtype=bool)
        # the part of the weather grid around the mesh (views, no copy, unless it crosses 180 deg)
        ja = max(int(np.searchsorted(self.lat_deg, mlat[0], side="right")) - 2, 0)
        jb = min(int(np.searchsorted(self.lat_deg, mlat[-1], side="left")) + 2, self.lat_deg.size)
        if jb - ja < 2:  # the mesh lies outside the weather grid
            ja, jb = 0, self.lat_deg.size
        cols, glon = lon_window(self.lon_deg, mlon[0], mlon[-1])
        glat = self.lat_deg[ja:jb]
        v = {name: arr[first:, ja:jb][:, :, cols] for name, arr in self.variables.items()}
        valid = ~_no_data(v, (glat.size, glon.size))
        sea_index, n_sea, flat_idx, flat_w, has_data = _node_weights(glat, glon, mlat, mlon, valid, node_sea, fill_missing)
        gather = _Gather(flat_idx.astype(np.int32), flat_w.astype(np.float32), t_idx0, t_w)

        shape0 = (t.size, glat.size, glon.size)
        zeros = np.zeros(shape0, dtype=np.float32)
        wave = np.zeros((times.size, n_sea, 3), dtype=np.float32)  # hs, cos, sin of the direction waves come from
        if "hs_m" in v or "wave_from_deg" in v:
            rad = np.deg2rad(v["wave_from_deg"]) if "wave_from_deg" in v else None
            gather(
                [
                    v.get("hs_m", zeros),
                    zeros if rad is None else np.cos(rad),
                    zeros if rad is None else np.sin(rad),
                ],
                wave,
            )
        current = None
        if "current_u_ms" in v and "current_v_ms" in v:
            current = np.zeros((times.size, n_sea, 2), dtype=np.float32)
            gather([v["current_u_ms"] / np.float32(MS_PER_KN), v["current_v_ms"] / np.float32(MS_PER_KN)], current)
        extra = {}
        for name in ("tp_s", "tm_s", "wind_u_ms", "wind_v_ms"):
            if name in v:
                out = np.zeros((times.size, n_sea, 1), dtype=np.float32)
                gather([v[name]], out)
                extra[name] = out[:, :, 0]
        return MeshWeather(
            time0_ns=int(times[0]),
            dt_h=float((times[1] - times[0]) / NS_PER_HOUR) if times.size > 1 else 1.0,
            n_times=int(times.size),
            sea_index=sea_index,
            wave=wave,
            current=current,
            extra=extra,
            has_waves="hs_m" in self.variables,
            has_direction="wave_from_deg" in self.variables,
            weather_sea=has_data,
            attrs=dict(self.attrs),
        )


def _node_weights(glat, glon, mlat, mlon, valid, node_sea, fill_missing: bool):
    """Bilinear weights of every mesh node over its four grid neighbours, the invalid (land or
    missing) neighbours given weight 0 and the rest renormalised.

    A node *has data* when its valid neighbours carry at least half of its bilinear weight. The
    nodes filled are ``node_sea`` nodes with data (or every ``node_sea`` node with
    ``fill_missing``). Returns (sea_index: node -> row of the filled nodes or -1, the number
    filled, per filled node its 4 flat grid indices and 4 weights, has_data (ny, nx)).
    """
    ny, nx = mlat.size, mlon.size
    jj, wy = _axis_weights(glat, mlat)
    ii, wx = _axis_weights(glon, mlon)
    # four neighbours (j0,i0), (j0,i1), (j1,i0), (j1,i1) of every node: shape (ny, nx, 4)
    j_pairs = np.stack([jj[:, 0], jj[:, 0], jj[:, 1], jj[:, 1]], axis=-1)[:, None, :]
    i_pairs = np.stack([ii[:, 0], ii[:, 1], ii[:, 0], ii[:, 1]], axis=-1)[None, :, :]
    w = (
        np.stack([wy[:, 0], wy[:, 0], wy[:, 1], wy[:, 1]], axis=-1)[:, None, :]
        * np.stack([wx[:, 0], wx[:, 1], wx[:, 0], wx[:, 1]], axis=-1)[None, :, :]
    )
    j_pairs, i_pairs = np.broadcast_arrays(j_pairs, i_pairs)
    inside = (j_pairs >= 0) & (i_pairs >= 0)
    ok = inside & valid[np.clip(j_pairs, 0, None), np.clip(i_pairs, 0, None)]
    w = np.where(ok, w, 0.0)
    wsum = w.sum(axis=-1)
    has_data = wsum >= 0.5
    fill = node_sea & (has_data | fill_missing)
    sea_index = np.full(ny * nx, -1, dtype=np.int32)
    flat_fill = fill.ravel()
    n_sea = int(flat_fill.sum())
    sea_index[flat_fill] = np.arange(n_sea, dtype=np.int32)
    flat_idx = (np.clip(j_pairs, 0, None) * glon.size + np.clip(i_pairs, 0, None)).reshape(-1, 4)[flat_fill]
    flat_w = (w / np.where(wsum > 0, wsum, 1.0)[..., None]).reshape(-1, 4)[flat_fill]
    return sea_index, n_sea, flat_idx, flat_w, has_data


def _no_data(variables: dict, shape) -> np.ndarray:
    """Grid points without data at every time (NaN in the first wave/current/wind variable)."""
    for name in ("hs_m", "current_u_ms", "wind_u_ms", *KNOWN_VARIABLES):
        if name in variables:
            return np.all(np.isnan(variables[name]), axis=0)
    return np.zeros(shape, dtype=bool)


def _iso(ns) -> str:
    return str(np.datetime64(int(ns), "ns"))[:19] + "Z"


def _regular_times(t: np.ndarray):
    """A regular time axis from t[0] to >= t[-1] with the smallest step, and linear weights into t."""
    if t.size == 1:
        return t.copy(), np.zeros(1, dtype=np.int64), np.zeros(1)
    step = int(np.min(np.diff(t)))
    n = int(np.ceil((t[-1] - t[0]) / step)) + 1
    times = t[0] + step * np.arange(n, dtype=np.int64)
    idx = np.clip(np.searchsorted(t, times, side="right") - 1, 0, t.size - 2)
    w = np.clip((times - t[idx]) / (t[idx + 1] - t[idx]), 0.0, 1.0)
    return times, idx.astype(np.int64), w


def lon_window(lon_deg: np.ndarray, lo: float, hi: float):
    """Columns of a weather grid (ascending lon in [-180, 180)) covering the mesh longitudes
    ``lo .. hi`` of any continuous frame (past +-180 deg too), and their longitudes in that frame.

    The grid is continued periodically (lon + 360 k), so a mesh across the antimeridian reads
    both ends of a -180..180 product (a 0..360 product is wrapped to -180..180 by the readers
    first). Returns ``(cols, lon)``: a slice when the window is one block of the grid, else an
    index array; ``lon`` ascending (gaps, e.g. between the two ends of a regional product, are
    left to :func:`_axis_weights`).
    """
    n = lon_deg.size
    if lon_deg[0] - 1e-9 <= lo and hi <= lon_deg[-1] + 1e-9:  # the usual case: inside, no wrap
        ia = max(int(np.searchsorted(lon_deg, lo, side="right")) - 2, 0)
        ib = min(int(np.searchsorted(lon_deg, hi, side="left")) + 2, n)
        return slice(ia, ib), lon_deg[ia:ib]
    ks = np.arange(int(np.floor((lo + 180.0) / 360.0)) - 1, int(np.floor((hi + 180.0) / 360.0)) + 2)
    ext_lon = (lon_deg[None, :] + 360.0 * ks[:, None]).ravel()
    ext_col = np.tile(np.arange(n), ks.size)
    a = max(int(np.searchsorted(ext_lon, lo, side="right")) - 2, 0)
    b = min(int(np.searchsorted(ext_lon, hi, side="left")) + 2, ext_lon.size)
    if b - a < 2:  # the mesh lies outside the weather grid: everything (all nodes will be outside)
        return slice(0, n), lon_deg
    return ext_col[a:b], ext_lon[a:b]


def _axis_weights(grid: np.ndarray, points: np.ndarray):
    """Bracketing indices (n, 2) and linear weights (n, 2) of ``points`` in ascending ``grid``.

    Points beyond the grid by more than half a step get index -1 (no data); within half a step
    they take the edge value. The same holds inside a gap of the grid (a step over 1.5 times the
    typical one, e.g. between the two ends of a regional product continued across 180 deg): no
    interpolation across it.
    """
    n = grid.size
    pos = np.interp(points, grid, np.arange(n, dtype=float))
    steps = np.diff(grid)
    step = float(np.median(steps))
    step_lo = grid[1] - grid[0]
    step_hi = grid[-1] - grid[-2]
    outside = (points < grid[0] - 0.5 * step_lo - 1e-9) | (points > grid[-1] + 0.5 * step_hi + 1e-9)
    i0 = np.clip(np.floor(pos).astype(np.int64), 0, n - 2)
    frac = np.clip(pos - i0, 0.0, 1.0)
    idx = np.stack([i0, i0 + 1], axis=-1)
    weights = np.stack([1.0 - frac, frac], axis=-1)
    gap = steps[i0] > 1.5 * step
    if np.any(gap):
        near_lo = gap & (points - grid[i0] <= 0.5 * step + 1e-9)
        near_hi = gap & (grid[i0 + 1] - points <= 0.5 * step + 1e-9)
        idx[near_lo] = i0[near_lo, None]
        weights[near_lo] = (1.0, 0.0)
        idx[near_hi & ~near_lo] = (i0 + 1)[near_hi & ~near_lo, None]
        weights[near_hi & ~near_lo] = (1.0, 0.0)
        outside |= gap & ~near_lo & ~near_hi
    idx[outside] = -1
    weights[outside] = 0.0
    return idx, weights


class _Gather:
    """Bilinear gather of (T, ny, nx) arrays onto sea nodes and linear resampling in time, into
    the channels of a (T', n_sea, C) array (time-major: the search reads neighbouring nodes at
    one time, which then share cache lines)."""

    def __init__(self, idx, w, t_idx0, t_w):
        self.idx, self.w, self.t_idx0, self.t_w = idx, w, t_idx0, t_w

    def __call__(self, channels: list, out: np.ndarray) -> None:
        from routing._kernels import gather_bilinear_time

        flat = np.stack([np.asarray(c, dtype=np.float32).reshape(c.shape[0], -1) for c in channels], axis=-1)
        np.copyto(flat, 0.0, where=np.isnan(flat))  # land, and sea points without data at some time: calm
        gather_bilinear_time(flat, self.idx, self.w, self.t_idx0, self.t_w, out)


@dataclass(frozen=True)
class MeshWeather:
    """Weather on the sea nodes of a mesh, on a regular time axis.

    Attributes
    ----------
    time0_ns : int
        Time of slice 0 (the last weather time at or before the departure). [ns since epoch UTC]
    dt_h : float
        Step between slices. [h]
    n_times : int
    sea_index : ndarray of int32, shape (N,)
        Row of each mesh node in the arrays, -1 where the node has no weather (land/outside).
    wave : ndarray of float32, shape (n_times, n_sea, 3)
        Hs [m] and the cosine and sine of the direction waves come from (interpolated as
        components); zeros where the files have none (no waves; unknown direction).
    current : ndarray of float32, shape (n_times, n_sea, 2), or None
        Current flowing to, eastward and northward. [kn]
    extra : dict of str -> ndarray of float32, shape (n_times, n_sea)
        ``tp_s``, ``tm_s``, ``wind_u_ms``, ``wind_v_ms`` as available (reported, not routed on).
    has_waves, has_direction : bool
    weather_sea : ndarray of bool, shape (ny, nx)
        Nodes where the weather has data (not weather land, not outside the grid).
    """

    time0_ns: int
    dt_h: float
    n_times: int
    sea_index: np.ndarray
    wave: np.ndarray
    current: np.ndarray | None
    extra: dict
    has_waves: bool
    has_direction: bool
    weather_sea: np.ndarray
    attrs: dict = field(default_factory=dict)

    @property
    def end_ns(self) -> int:
        return int(self.time0_ns + round((self.n_times - 1) * self.dt_h * NS_PER_HOUR))

    @property
    def hs_max_m(self) -> float:
        return float(self.wave[:, :, 0].max()) if self.wave.size else 0.0

    @property
    def current_max_kn(self) -> float:
        if self.current is None or not self.current.size:
            return 0.0
        return float(np.max(np.hypot(self.current[:, :, 0], self.current[:, :, 1])))
