"""Weather at arbitrary points and times of a gridded field (the ``weather_at`` of evaluations
and deviations).

Space: bilinear over the *valid* grid points only, weights renormalised, and NaN (land) where
the valid points carry less than half of the bilinear weight — the same rule as
:meth:`routing.field.WeatherField.on_mesh`, so a route judged here meets the weather the router
saw. Time: linear between the bracketing time steps; outside the field's time span the values
are NaN (never extrapolated), so an evaluation reports the hours without weather instead of
inventing them. Wave directions are interpolated through their cos/sin components (DESIGN.md).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
import pandas as pd

from thresholds.units import wrap_deg

#: Variables sampled as plain scalars (``wave_from_deg`` is handled through its components).
SCALARS = ("hs_m", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms", "current_u_ms", "current_v_ms")


class PointSampler:
    """Callable ``(times, lat, lon) -> {var: ndarray}`` over a gridded field.

    Parameters
    ----------
    time_ns : array_like of int64, shape (T,)
        Field times, ns since 1970-01-01 UTC, increasing.
    lat_deg, lon_deg : array_like, shape (ny,), (nx,)
        Ascending grid axes. [deg]
    variables : mapping of str -> ndarray, shape (T, ny, nx)
        Canonical names; NaN = land / no data.

    Notes
    -----
    A field with a single time step is taken as valid at all times (a static field).
    """

    def __init__(self, time_ns, lat_deg, lon_deg, variables: Mapping[str, np.ndarray]):
        self.time_ns = np.asarray(time_ns, dtype=np.int64)
        self.lat_deg = np.asarray(lat_deg, dtype=float)
        self.lon_deg = np.asarray(lon_deg, dtype=float)
        shape = (self.time_ns.size, self.lat_deg.size, self.lon_deg.size)
        self._vars: dict[str, np.ndarray] = {}
        for name, values in variables.items():
            arr = np.asarray(values, dtype=np.float32)
            if arr.shape != shape:
                raise ValueError(f"variable {name!r} has shape {arr.shape}, expected {shape}")
            if name == "wave_from_deg":
                rad = np.deg2rad(arr)
                self._vars["_wave_cos"] = np.cos(rad)
                self._vars["_wave_sin"] = np.sin(rad)
            elif name in SCALARS:
                self._vars[name] = arr
        self.names = tuple(n for n in variables if n in SCALARS or n == "wave_from_deg")

    @classmethod
    def from_field(cls, field) -> "PointSampler":
        """From a :class:`routing.field.WeatherField` (``time_ns``, ``lat_deg``, ``lon_deg``, ``variables``)."""
        return cls(field.time_ns, field.lat_deg, field.lon_deg, field.variables)

    @property
    def start_utc(self) -> pd.Timestamp:
        return pd.Timestamp(int(self.time_ns[0]), tz="UTC")

    @property
    def end_utc(self) -> pd.Timestamp:
        return pd.Timestamp(int(self.time_ns[-1]), tz="UTC")

    def _axis(self, grid, q):
        n = grid.size
        pos = np.interp(q, grid, np.arange(n, dtype=float))
        half_lo = 0.5 * (grid[1] - grid[0])
        half_hi = 0.5 * (grid[-1] - grid[-2])
        outside = (q < grid[0] - half_lo - 1e-9) | (q > grid[-1] + half_hi + 1e-9) | ~np.isfinite(q)
        i0 = np.clip(np.floor(pos).astype(np.int64), 0, n - 2)
        frac = np.clip(pos - i0, 0.0, 1.0)
        return i0, frac, outside

    def __call__(self, times, lat_deg, lon_deg) -> dict:
        lat = np.asarray(lat_deg, dtype=float).reshape(-1)
        lon = np.asarray(lon_deg, dtype=float).reshape(-1)
        idx = pd.DatetimeIndex(times)
        if idx.tz is None:
            raise ValueError("weather sampling needs timezone-aware UTC times")
        tn = idx.tz_convert("UTC").asi8
        if tn.size == 1 and lat.size > 1:
            tn = np.repeat(tn, lat.size)
        if not (tn.size == lat.size == lon.size):
            raise ValueError(f"times, lat and lon must have the same length ({tn.size}, {lat.size}, {lon.size})")
        t = self.time_ns
        if t.size == 1:
            k = np.zeros(tn.size, dtype=np.int64)
            wt = np.zeros(tn.size)
            t_out = np.zeros(tn.size, dtype=bool)
            k1 = k
        else:
            k = np.clip(np.searchsorted(t, tn, side="right") - 1, 0, t.size - 2)
            wt = np.clip((tn - t[k]) / (t[k + 1] - t[k]), 0.0, 1.0)
            t_out = (tn < t[0]) | (tn > t[-1])
            k1 = k + 1
        j0, fy, y_out = self._axis(self.lat_deg, lat)
        i0, fx, x_out = self._axis(self.lon_deg, lon)
        ny, nx = self.lat_deg.size, self.lon_deg.size
        w_c = np.stack([(1 - fy) * (1 - fx), (1 - fy) * fx, fy * (1 - fx), fy * fx])  # (4, n)
        cell = np.stack([j0 * nx + i0, j0 * nx + i0 + 1, (j0 + 1) * nx + i0, (j0 + 1) * nx + i0 + 1])
        flat = np.stack([k * (ny * nx) + cell, k1 * (ny * nx) + cell])  # (2, 4, n) indices into the raveled field
        bad = t_out | y_out | x_out

        def interp(arr):
            v = np.take(arr.reshape(-1), flat).astype(float)  # (2, 4, n)
            ok = np.isfinite(v)
            num = np.where(ok, w_c * v, 0.0).sum(axis=1)
            den = np.where(ok, w_c, 0.0).sum(axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                both = np.where(den >= 0.5, num / den, np.nan)
            val = (1.0 - wt) * both[0] + wt * both[1]
            return np.where(bad, np.nan, val)

        result = {}
        for name in self.names:
            if name == "wave_from_deg":
                c = interp(self._vars["_wave_cos"])
                s = interp(self._vars["_wave_sin"])
                result[name] = np.where(np.isfinite(c) & np.isfinite(s), wrap_deg(np.rad2deg(np.arctan2(s, c))), np.nan)
            else:
                result[name] = interp(self._vars[name])
        return result

    def grid_slice(self, k: int) -> dict:
        """The field's variables at time step ``k`` (shape (ny, nx)), ``wave_from_deg`` rebuilt."""
        out = {n: self._vars[n][k].astype(float) for n in self.names if n != "wave_from_deg"}
        if "wave_from_deg" in self.names:
            out["wave_from_deg"] = wrap_deg(np.rad2deg(np.arctan2(self._vars["_wave_sin"][k], self._vars["_wave_cos"][k])))
        return out
