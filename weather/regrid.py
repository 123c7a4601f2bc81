"""Regridding onto one grid: bilinear in space, linear in time, directions through cos/sin.

The seed [1] §3.2 merges ERA5 wind (0.25°) onto the CMEMS wave grid (0.083°) by bilinear
interpolation; we do the same for every field, with three rules the seed leaves implicit:

* **Directions** (``wave_from_deg``) are interpolated through their unit-vector components
  (cos, sin) and turned back with ``atan2``, so 350° and 10° average to 0°, not 180°.
* **Land**: source NaN corners are left out and the remaining bilinear weights renormalised (a
  coastal wind or current cell still gets the nearby sea values); a target point with no valid
  corner stays NaN. When merging onto the wave grid, cells that are land in the wave product
  (NaN ``hs_m`` at every time) stay NaN in every variable.
* **No extrapolation**: target points outside the source bbox or time span are NaN (and the
  coverage checks of :mod:`weather.coverage` then name the gap).

References
----------
.. [1] Seed ``ais_weather_routing_cargo_loss``, §3.2 (bilinear wind onto the 0.083° wave grid).
.. [2] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge Univ. Press, 2007, §3.6
       (bilinear interpolation on a rectangular grid).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from weather.canonical import DIRECTION_VARS


_TIME_CHUNK = 24


def _lerp(a, b, w):
    """(1 − w)·a + w·b, returning a (or b) exactly where w is 0 (or 1), even if the other is NaN."""
    return np.where(w == 0.0, a, np.where(w == 1.0, b, (1 - w) * a + w * b))


def _axis_weights(src, dst):
    """Lower index and fractional weight of each ``dst`` point on the ascending ``src`` axis.

    Returns ``(i0, w, valid)``: the value at a target is ``(1 - w)·f[i0] + w·f[i0 + 1]``; ``valid``
    is False outside [src[0], src[-1]]. A length-1 axis matches only its own coordinate.
    """
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    if src.size == 1:
        valid = np.isclose(dst, src[0])
        return np.zeros(dst.shape, dtype=np.int64), np.zeros(dst.shape), valid
    eps = 1e-9 * max(1.0, float(np.max(np.abs(src))))
    valid = (dst >= src[0] - eps) & (dst <= src[-1] + eps)
    i0 = np.clip(np.searchsorted(src, dst, side="right") - 1, 0, src.size - 2)
    w = np.clip((dst - src[i0]) / (src[i0 + 1] - src[i0]), 0.0, 1.0)
    return i0.astype(np.int64), w, valid


def bilinear_2d(values: np.ndarray, src_lat, src_lon, dst_lat, dst_lon) -> np.ndarray:
    """Bilinear interpolation of ``values[..., lat, lon]`` onto a target lat/lon grid [2].

    NaN corners are dropped and the other weights renormalised; targets outside the source grid
    or with no valid corner are NaN. Leading dimensions (time) are carried through.

    Examples
    --------
    >>> f = np.array([[0.0, 1.0], [2.0, 3.0]])          # f = 2·lat + lon on the unit square
    >>> float(bilinear_2d(f, [0, 1], [0, 1], [0.5], [0.25])[0, 0])
    1.25
    """
    v = np.asarray(values)
    if v.ndim > 2 and v.shape[0] > _TIME_CHUNK:
        # Chunk the leading (time) axis to bound the temporaries (4 corners x chunk x grid).
        return np.concatenate([bilinear_2d(v[k:k + _TIME_CHUNK], src_lat, src_lon, dst_lat, dst_lon)
                               for k in range(0, v.shape[0], _TIME_CHUNK)], axis=0)
    v = v.astype(np.float64, copy=False)
    i0, wy, vy = _axis_weights(src_lat, dst_lat)
    j0, wx, vx = _axis_weights(src_lon, dst_lon)
    i1 = np.minimum(i0 + 1, v.shape[-2] - 1)
    j1 = np.minimum(j0 + 1, v.shape[-1] - 1)
    inside = vy[:, None] & vx[None, :]
    if not np.isnan(v).any():
        # No missing source values: bilinear = linear along lon, then along lat (separable, same
        # result, far fewer gathers on a fine target grid).
        along = v[..., j0] * (1.0 - wx) + v[..., j1] * wx
        out = along[..., i0, :] * (1.0 - wy)[:, None] + along[..., i1, :] * wy[:, None]
        return np.where(inside, out, np.nan)
    wy = wy[:, None]
    wx = wx[None, :]
    corners = (
        (v[..., i0[:, None], j0[None, :]], (1 - wy) * (1 - wx)),
        (v[..., i0[:, None], j1[None, :]], (1 - wy) * wx),
        (v[..., i1[:, None], j0[None, :]], wy * (1 - wx)),
        (v[..., i1[:, None], j1[None, :]], wy * wx),
    )
    num = np.zeros(v.shape[:-2] + (len(dst_lat), len(dst_lon)))
    den = np.zeros_like(num)
    for vals, w in corners:
        ok = ~np.isnan(vals)
        wk = np.where(ok, w, 0.0)
        num += np.where(ok, vals, 0.0) * wk
        den += wk
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(den > 1e-12, num / den, np.nan)
    return np.where(inside, out, np.nan)


def _direction_to_components(deg):
    rad = np.deg2rad(deg)
    return np.cos(rad), np.sin(rad)


def _components_to_direction(c, s):
    return np.mod(np.rad2deg(np.arctan2(s, c)), 360.0)


def regrid_space(ds: xr.Dataset, lat, lon) -> xr.Dataset:
    """Bilinear regridding of a canonical dataset onto ``lat``/``lon`` (directions via cos/sin).

    Examples
    --------
    >>> import pandas as pd
    >>> src = xr.Dataset({"wave_from_deg": (("time_utc", "lat", "lon"), [[[350.0, 10.0]]])},
    ...                  coords={"time_utc": pd.to_datetime(["2025-01-01"]).values, "lat": [0.0], "lon": [0.0, 1.0]})
    >>> round(float(regrid_space(src, [0.0], [0.5])["wave_from_deg"][0, 0, 0]), 6) % 360
    0.0
    """
    lat = np.asarray(lat, dtype=float)
    lon = np.asarray(lon, dtype=float)
    out = {}
    for name, da in ds.data_vars.items():
        if name in DIRECTION_VARS:
            c, s = _direction_to_components(da.values)
            ci = bilinear_2d(c, ds.lat.values, ds.lon.values, lat, lon)
            si = bilinear_2d(s, ds.lat.values, ds.lon.values, lat, lon)
            vals = _components_to_direction(ci, si)
            vals = np.where(np.isnan(ci), np.nan, vals)
        else:
            vals = bilinear_2d(da.values, ds.lat.values, ds.lon.values, lat, lon)
        out[name] = (("time_utc", "lat", "lon"), vals.astype(np.float32), da.attrs)
    return xr.Dataset(out, coords={"time_utc": ds.time_utc.values, "lat": lat, "lon": lon}, attrs=dict(ds.attrs))


def interp_time(ds: xr.Dataset, times) -> xr.Dataset:
    """Linear interpolation in time onto ``times`` (directions via cos/sin); NaN outside the span.

    Exact matches return the stored values unchanged.
    """
    times = np.asarray(times, dtype="datetime64[ns]")
    src_t = ds.time_utc.values.astype("datetime64[ns]").astype(np.int64).astype(np.float64)
    dst_t = times.astype(np.int64).astype(np.float64)
    k0, w, valid = _axis_weights(src_t, dst_t)
    k1 = np.minimum(k0 + 1, max(src_t.size - 1, 0))
    w = w[:, None, None]
    out = {}
    for name, da in ds.data_vars.items():
        v = np.asarray(da.values, dtype=np.float64)
        if name in DIRECTION_VARS:
            c, s = _direction_to_components(v)
            ci = _lerp(c[k0], c[k1], w)
            si = _lerp(s[k0], s[k1], w)
            vals = _components_to_direction(ci, si)
            vals = np.where(np.isnan(ci), np.nan, vals)
            # exact time matches keep the stored angle (no cos/sin round trip)
            vals = np.where(w == 0.0, v[k0], np.where(w == 1.0, v[k1], vals))
        else:
            # exact weights 0/1 keep stored values bit-for-bit (NaN in the unused neighbour is ignored)
            vals = _lerp(v[k0], v[k1], w)
        vals = np.where(valid[:, None, None], vals, np.nan)
        out[name] = (("time_utc", "lat", "lon"), vals.astype(np.float32), da.attrs)
    return xr.Dataset(out, coords={"time_utc": times, "lat": ds.lat.values, "lon": ds.lon.values}, attrs=dict(ds.attrs))


def regrid_to(ds: xr.Dataset, target: xr.Dataset) -> xr.Dataset:
    """``ds`` on the grid and times of ``target`` (time first, on the source grid, then space)."""
    same_space = ds.lat.size == target.lat.size and ds.lon.size == target.lon.size and np.allclose(
        ds.lat.values, target.lat.values, atol=1e-6) and np.allclose(ds.lon.values, target.lon.values, atol=1e-6)
    same_time = ds.time_utc.size == target.time_utc.size and np.array_equal(ds.time_utc.values, target.time_utc.values)
    out = ds if same_time else interp_time(ds, target.time_utc.values)
    if not same_space:
        out = regrid_space(out, target.lat.values, target.lon.values)
    else:
        out = out.assign_coords(lat=target.lat.values, lon=target.lon.values)
    return out


def sea_mask(ds: xr.Dataset, var: str = "hs_m") -> np.ndarray | None:
    """Cells that are sea in ``var`` at some time (``None`` when ``var`` is absent)."""
    if var not in ds:
        return None
    return np.asarray(~np.isnan(ds[var].values).all(axis=0))


def merge_onto(base: xr.Dataset, others: list[xr.Dataset]) -> xr.Dataset:
    """Merge other canonical datasets onto ``base``'s grid and times; base land stays NaN everywhere.

    Variables already in ``base`` are kept from ``base``; a variable present in several ``others``
    is taken from the first one that has it.
    """
    merged = base.copy()
    mask = sea_mask(base)
    provenance = [base.attrs.get("product", "")]
    files = [base.attrs.get("source_files", "")]
    for other in others:
        new_vars = [v for v in other.data_vars if v not in merged.data_vars]
        if not new_vars:
            continue
        on_grid = regrid_to(other[new_vars], merged)
        for v in new_vars:
            vals = on_grid[v].values
            if mask is not None:
                vals = np.where(mask[None, :, :], vals, np.nan).astype(np.float32)
            attrs = dict(other[v].attrs)
            attrs["regridded_from"] = other.attrs.get("product", "")
            merged[v] = (("time_utc", "lat", "lon"), vals, attrs)
        provenance.append(other.attrs.get("product", ""))
        files.append(other.attrs.get("source_files", ""))
    merged.attrs["product"] = " + ".join(p for p in provenance if p)
    merged.attrs["source_files"] = "; ".join(f for f in files if f)
    return merged
