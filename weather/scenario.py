"""Demo weather: a deterministic Western-Mediterranean month with three generated storms.

Pure (no files): :func:`generate_weather` returns canonical datasets on the two native grids the
demo writes — CMEMS GLOBAL waves (1/12°, 3-hourly: ``hs_m``, ``wave_from_deg``, ``tp_s``,
``tm_s``; land NaN from the 30″ ``global_land_mask``) and ERA5 single levels (0.25°, hourly:
``wind_u_ms``, ``wind_v_ms``, defined over land as ERA5 is) — plus a description of the storms.
Writers in :mod:`weather.io.cmems` / :mod:`weather.io.era5` put them in the products' schemas.

The fields are **synthetic** (COMMON.md "Demo scenario"): bbox lon −1.5…11.5, lat 35.5…45.0;
2025-01-01T00Z → 2025-02-02T06Z. Storm A crosses the Balearic Sea on 2025-01-14…16 (the AIS
voyages sail through it, for audits); storm B crosses the Gulf of Lion → Sardinia channel in the
forecast window 2025-01-31T00Z…2025-02-02T00Z (for the nightly run); storm C, a gale from the Gulf
of Lion to the Sardinia channel on 2025-01-07…10, puts the container and tanker routes in heavy
seas too (for the learned performance model, which needs every class in rough weather). ``seed`` moves the tracks by
up to ±0.3°, the timing by up to ±3 h and the intensity by up to ±5 %, and sets the background.

Model (simple, documented, not a forecast):

* Wind: a moving cyclone as a modified Rankine vortex [1] — tangential speed
  V(r) = Vmax·r/Rm inside the radius of maximum wind Rm and Vmax·(Rm/r)^0.6 outside, turning
  counter-clockwise (northern hemisphere) with a 20° inflow angle — plus a background north-
  westerly (Mistral-like) flow with smooth seeded variability. Intensity follows a Gaussian
  envelope in time around the storm's peak.
* Waves: significant height grows with the local wind as a fetch/duration-limited sea,
  Hs = 0.0117·U^1.9 (≈ 5.3 m at 25 m/s, 7.5 m at 30 m/s; a fully developed Pierson–Moskowitz sea, 0.21·U²/g [2],
  would overstate a Mediterranean storm), on top of a 0.3–1.2 m background swell; waves come from
  the wind direction blended with the swell direction by their energy. Peak period from wind-sea
  steepness Tp = 4.1·√Hs (s, Hs in m; clipped to 3–16 s), mean period Tm−10 = 0.87·Tp (JONSWAP).

References
----------
.. [1] G. J. Holland, "An analytic model of the wind and pressure profiles in hurricanes,"
       Mon. Weather Rev., vol. 108, pp. 1212–1218, 1980, doi:10.1175/1520-0493(1980)108<1212:AAMOTW>2.0.CO;2
       (the modified Rankine profile is the usual simplification).
.. [2] W. J. Pierson and L. Moskowitz, "A proposed spectral form for fully developed wind seas,"
       J. Geophys. Res., vol. 69, no. 24, pp. 5181–5190, 1964, doi:10.1029/JZ069i024p05181.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd
import xarray as xr

from thresholds.geodesy import haversine_nmi, initial_bearing_deg

BBOX = (-1.5, 35.5, 11.5, 45.0)  # lon_min, lat_min, lon_max, lat_max
START_UTC = pd.Timestamp("2025-01-01T00:00Z")
END_UTC = pd.Timestamp("2025-02-02T06:00Z")
WAVE_STEP_DEG = 1.0 / 12.0
WAVE_STEP_H = 3
WIND_STEP_DEG = 0.25
WIND_STEP_H = 1


@dataclass(frozen=True)
class Storm:
    """A generated storm: track (time, lat, lon), peak wind and radius of maximum wind."""

    name: str
    purpose: str
    track_utc: tuple  # ISO strings
    track_lat: tuple
    track_lon: tuple
    peak_utc: str
    vmax_ms: float
    rmw_nmi: float
    envelope_h: float  # e-folding half-width of the intensity envelope

    def to_dict(self) -> dict:
        return asdict(self)

    def position(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centre at ``times`` (linear along the track, held at the ends)."""
        tt = pd.DatetimeIndex(pd.to_datetime(list(self.track_utc), utc=True)).tz_localize(None).values.astype("datetime64[ns]").astype(np.int64)
        t = np.asarray(times, dtype="datetime64[ns]").astype(np.int64)
        return np.interp(t, tt, self.track_lat), np.interp(t, tt, self.track_lon)

    def intensity(self, times: np.ndarray) -> np.ndarray:
        """Envelope 0..1 around the peak: exp(−(Δt/envelope)²)."""
        peak = pd.Timestamp(self.peak_utc).tz_convert("UTC").tz_localize(None).to_datetime64().astype("datetime64[ns]").astype(np.int64)
        dt_h = (np.asarray(times, dtype="datetime64[ns]").astype(np.int64) - peak) / 3.6e12
        return np.exp(-((dt_h / self.envelope_h) ** 2))


@dataclass
class ScenarioWeather:
    """What :func:`generate_weather` returns."""

    waves: xr.Dataset
    wind: xr.Dataset
    storms: list = field(default_factory=list)
    seed: int = 0

    def describe(self) -> dict:
        """JSON-friendly summary for ``scenario.json``."""
        return {
            "seed": self.seed,
            "bbox": list(BBOX),
            "start_utc": _iso(pd.Timestamp(self.waves.time_utc.values[0]).tz_localize("UTC")),
            "end_utc": _iso(pd.Timestamp(self.waves.time_utc.values[-1]).tz_localize("UTC")),
            "waves": {"grid_step_deg": WAVE_STEP_DEG, "step_h": WAVE_STEP_H, "shape": list(self.waves.hs_m.shape),
                      "max_hs_m": float(np.nanmax(self.waves.hs_m.values))},
            "wind": {"grid_step_deg": WIND_STEP_DEG, "step_h": WIND_STEP_H, "shape": list(self.wind.wind_u_ms.shape),
                     "max_wind_ms": float(np.nanmax(np.hypot(self.wind.wind_u_ms.values, self.wind.wind_v_ms.values)))},
            "storms": [s.to_dict() for s in self.storms],
            "synthetic": True,
        }


    def sampler(self):
        """The weather at any time and place, as the demo fleet meets it:
        ``f(time_s, lat_deg, lon_deg) -> dict`` of ``hs_m``, ``wave_from_deg``, ``tp_s``,
        ``wind_u_ms``, ``wind_v_ms`` (Unix seconds; arrays of one shape).

        Linear in time and bilinear in space between the generated grid points (the wave
        direction through its cos/sin components); land points of the wave grid are left out of
        the weights, and a point with no sea neighbour (or outside the period or box) is NaN."""
        w, a = self.waves, self.wind
        d = np.deg2rad(w.wave_from_deg.values.astype(np.float64))
        wave_vars = [w.hs_m.values, w.tp_s.values, np.cos(d), np.sin(d)]
        wind_vars = [a.wind_u_ms.values, a.wind_v_ms.values]
        wave_axes = (_seconds(w.time_utc.values), w.lat.values, w.lon.values)
        wind_axes = (_seconds(a.time_utc.values), a.lat.values, a.lon.values)

        def sample(time_s, lat_deg, lon_deg) -> dict:
            hs, tp, c, s_ = _trilinear(wave_vars, wave_axes, time_s, lat_deg, lon_deg)
            u, v = _trilinear(wind_vars, wind_axes, time_s, lat_deg, lon_deg)
            return {"hs_m": hs, "tp_s": tp, "wave_from_deg": np.mod(np.rad2deg(np.arctan2(s_, c)), 360.0),
                    "wind_u_ms": u, "wind_v_ms": v}

        return sample


def _seconds(times) -> np.ndarray:
    return np.asarray(times, dtype="datetime64[ns]").astype(np.int64) / 1e9


def _trilinear(arrays, axes, t, lat, lon) -> list[np.ndarray]:
    """Values of ``arrays`` (each (time, lat, lon) on the regular ``axes``) at points, linear in
    each axis; NaN corners (land) get no weight, points with no valid corner are NaN."""
    t, lat, lon = (np.asarray(x, dtype=np.float64) for x in (t, lat, lon))
    idx, frac, inside = [], [], np.ones(t.shape, bool)
    for axis, x in zip(axes, (t, lat, lon)):
        axis = np.asarray(axis, dtype=np.float64)
        step = (axis[-1] - axis[0]) / max(axis.size - 1, 1)
        pos = (x - axis[0]) / step if axis.size > 1 else np.zeros_like(x)
        inside &= (pos >= 0) & (pos <= axis.size - 1)
        i0 = np.clip(np.floor(pos).astype(np.int64), 0, max(axis.size - 2, 0))
        idx.append(i0)
        frac.append(np.clip(pos - i0, 0.0, 1.0))
    num = [np.zeros(t.shape) for _ in arrays]
    den = np.zeros(t.shape)
    for dt_ in (0, 1):
        wt = frac[0] if dt_ else 1.0 - frac[0]
        it = np.minimum(idx[0] + dt_, axes[0].size - 1)
        for dy in (0, 1):
            wy = frac[1] if dy else 1.0 - frac[1]
            iy = np.minimum(idx[1] + dy, axes[1].size - 1)
            for dx in (0, 1):
                wx = frac[2] if dx else 1.0 - frac[2]
                ix = np.minimum(idx[2] + dx, axes[2].size - 1)
                weight = wt * wy * wx
                vals = [np.asarray(a[it, iy, ix], dtype=np.float64) for a in arrays]
                ok = np.isfinite(vals[0])
                den += np.where(ok, weight, 0.0)
                for k, val in enumerate(vals):
                    num[k] += np.where(ok, weight * np.nan_to_num(val), 0.0)
    good = inside & (den > 1e-9)
    return [np.where(good, n / np.where(good, den, 1.0), np.nan) for n in num]


def _iso(t: pd.Timestamp) -> str:
    return t.tz_convert("UTC").strftime("%Y-%m-%dT%H:%M:%SZ")


def make_storms(seed: int = 0) -> list[Storm]:
    """The three demo storms, perturbed deterministically by ``seed`` (A and B draw first, so
    adding C left their tracks as they were)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 4]))
    base = [
        ("A", "historical storm crossed by the AIS voyages (audits)",
         ["2025-01-13T18:00Z", "2025-01-14T12:00Z", "2025-01-15T06:00Z", "2025-01-16T00:00Z", "2025-01-16T18:00Z"],
         [37.6, 38.9, 40.1, 41.3, 42.3], [-1.0, 1.0, 3.2, 5.6, 8.0], "2025-01-15T03:00Z", 24.0, 45.0, 28.0),
        ("B", "forecast-window storm crossing several lanes (nightly run)",
         ["2025-01-31T00:00Z", "2025-01-31T18:00Z", "2025-02-01T09:00Z", "2025-02-01T23:00Z"],
         [43.2, 41.6, 39.9, 38.0], [3.6, 5.4, 7.3, 9.6], "2025-02-01T03:00Z", 25.0, 50.0, 18.0),
        ("C", "gale across the container and tanker routes (the learned performance model's heavy seas)",
         ["2025-01-07T00:00Z", "2025-01-07T18:00Z", "2025-01-08T12:00Z", "2025-01-09T06:00Z", "2025-01-10T00:00Z"],
         [44.0, 42.6, 41.0, 39.2, 37.6], [3.0, 4.6, 6.0, 7.6, 9.4], "2025-01-08T09:00Z", 25.0, 70.0, 30.0),
    ]
    storms = []
    for name, purpose, times, lats, lons, peak, vmax, rmw, env in base:
        dlat, dlon = rng.uniform(-0.3, 0.3, 2)
        dt = pd.Timedelta(hours=float(np.round(rng.uniform(-3.0, 3.0))))
        gain = rng.uniform(0.95, 1.05)
        storms.append(Storm(
            name=name, purpose=purpose,
            track_utc=tuple(_iso(pd.Timestamp(t) + dt) for t in times),
            track_lat=tuple(round(x + dlat, 4) for x in lats),
            track_lon=tuple(round(x + dlon, 4) for x in lons),
            peak_utc=_iso(pd.Timestamp(peak) + dt), vmax_ms=round(vmax * gain, 3), rmw_nmi=rmw, envelope_h=env,
        ))
    return storms


def _background(times: np.ndarray, lat: np.ndarray, lon: np.ndarray, seed: int):
    """Smooth background wind (u, v) and swell (Hs, from-direction): a few seeded Fourier modes."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    th = (np.asarray(times, dtype="datetime64[ns]").astype(np.int64) - START_UTC.tz_localize(None).value) / 3.6e12
    t = th[:, None, None]
    y = lat[None, :, None]
    x = lon[None, None, :]
    u = np.zeros((th.size, lat.size, lon.size), dtype=np.float64)
    v = np.zeros_like(u)
    for _ in range(4):
        a_u, a_v = rng.uniform(0.8, 2.0, 2)
        kx, ky = rng.uniform(0.15, 0.5, 2)
        period_h = rng.uniform(30.0, 140.0)
        ph = rng.uniform(0, 2 * np.pi, 2)
        wave = 2 * np.pi * t / period_h
        u += a_u * np.sin(kx * x + ky * y + wave + ph[0])
        v += a_v * np.cos(ky * x - kx * y + wave + ph[1])
    # Mean north-westerly (from ~315 deg): u > 0, v < 0, stronger in the north (Gulf of Lion)
    strength = 4.5 + 1.8 * np.sin(2 * np.pi * t / rng.uniform(90.0, 150.0) + rng.uniform(0, 6.3)) + 0.25 * (y - 38.0)
    u += strength * np.sin(np.deg2rad(135.0))
    v += strength * np.cos(np.deg2rad(135.0))
    swell_hs = 0.75 + 0.45 * np.sin(2 * np.pi * t / rng.uniform(50.0, 110.0) + rng.uniform(0, 6.3) + 0.2 * x - 0.15 * y)
    swell_from = 300.0 + 25.0 * np.sin(2 * np.pi * t / rng.uniform(60.0, 130.0) + rng.uniform(0, 6.3))
    swell_from = np.broadcast_to(swell_from, u.shape)
    return u, v, np.broadcast_to(swell_hs, u.shape), swell_from


def _storm_wind(storm: Storm, times, lat, lon):
    """Wind vector of one storm (modified Rankine vortex, cyclonic, 20° inflow) on the grid."""
    clat, clon = storm.position(times)
    amp = storm.intensity(times)
    LAT = lat[None, :, None]
    LON = lon[None, None, :]
    r = haversine_nmi(clat[:, None, None], clon[:, None, None], LAT, LON)
    brg = initial_bearing_deg(clat[:, None, None], clon[:, None, None], LAT, LON)  # centre -> point
    rm = storm.rmw_nmi
    with np.errstate(divide="ignore", invalid="ignore"):
        prof = np.where(r < rm, r / rm, (rm / np.maximum(r, 1e-9)) ** 0.6)
    speed = storm.vmax_ms * amp[:, None, None] * prof
    # counter-clockwise tangential direction (flow TO) = bearing - 90, turned 20 deg inward
    flow_to = np.deg2rad(brg - 90.0 - 20.0)
    return speed * np.sin(flow_to), speed * np.cos(flow_to)


def _wind_field(storms, times, lat, lon, seed):
    u, v, swell_hs, swell_from = _background(times, lat, lon, seed)
    for s in storms:
        active = np.flatnonzero(s.intensity(times) > 1e-3)  # skip times the storm does not exist
        if active.size:
            su, sv = _storm_wind(s, np.asarray(times)[active], lat, lon)
            u[active] += su
            v[active] += sv
    return u, v, swell_hs, swell_from


def _grid(step_deg):
    lon0, lat0, lon1, lat1 = BBOX
    n_lat = int(round((lat1 - lat0) / step_deg)) + 1
    n_lon = int(round((lon1 - lon0) / step_deg)) + 1
    return lat0 + step_deg * np.arange(n_lat), lon0 + step_deg * np.arange(n_lon)


def _utc(t) -> pd.Timestamp:
    ts = pd.Timestamp(t)
    return ts.tz_localize("UTC") if ts.tz is None else ts.tz_convert("UTC")


def _times(step_h, start=None, end=None):
    """Times every ``step_h`` hours on the UTC clock (multiples of the step) within [start, end]."""
    t0 = _utc(START_UTC if start is None else start).ceil(f"{step_h}h")
    t1 = _utc(END_UTC if end is None else end)
    if t1 < t0:
        raise ValueError(f"weather window {t0} -> {t1} holds no {step_h}-hourly time")
    return pd.date_range(t0, t1, freq=f"{step_h}h").tz_localize(None).values.astype("datetime64[ns]")


def sea_state_from_wind(u, v, swell_hs, swell_from):
    """Hs, from-direction, Tp, Tm−10 from local wind and background swell (module docstring).

    Examples
    --------
    >>> hs, d, tp, tm = sea_state_from_wind(np.array([0.0]), np.array([-25.0]), np.array([0.0]), np.array([0.0]))
    >>> round(float(hs[0]), 2), round(float(d[0]), 1)   # 25 m/s from the north
    (7.04, 0.0)
    """
    speed = np.hypot(u, v)
    wind_sea = 0.0117 * speed**1.9
    hs = np.sqrt(wind_sea**2 + swell_hs**2)  # energies add
    wind_from = np.mod(np.rad2deg(np.arctan2(-u, -v)), 360.0)
    e_w, e_s = wind_sea**2, swell_hs**2
    c = e_w * np.cos(np.deg2rad(wind_from)) + e_s * np.cos(np.deg2rad(swell_from))
    s = e_w * np.sin(np.deg2rad(wind_from)) + e_s * np.sin(np.deg2rad(swell_from))
    wave_from = np.mod(np.rad2deg(np.arctan2(s, c)), 360.0)
    tp = np.clip(4.1 * np.sqrt(hs), 3.0, 16.0)
    return hs, wave_from, tp, 0.87 * tp


def generate_weather(seed: int = 0, *, land_mask=None, start=None, end=None) -> ScenarioWeather:
    """Generate the demo's waves (1/12°, 3-hourly) and wind (0.25°, hourly) with the three storms.

    Parameters
    ----------
    seed : int
        Deterministic: the same seed gives identical arrays.
    land_mask : callable(lat2d, lon2d) -> bool array, optional
        Land test for the wave grid (default :func:`thresholds.land_raster.is_land`, the 30" mask).
    start, end : datetime-like (UTC), optional
        Window to generate (default the demo's 2025-01-01T00Z -> 2025-02-02T06Z). The fields are
        functions of absolute time, so a window equals the same slice of a longer run; outside the
        storms' dates only the background weather remains.

    Returns
    -------
    ScenarioWeather
    """
    if land_mask is None:
        from thresholds.land_raster import is_land  # the 30" mask, read pixel by pixel from its cache

        land_mask = is_land
    storms = make_storms(seed)

    wlat, wlon = _grid(WIND_STEP_DEG)
    wt = _times(WIND_STEP_H, start, end)
    u, v, _, _ = _wind_field(storms, wt, wlat, wlon, seed)
    wind = xr.Dataset(
        {"wind_u_ms": (("time_utc", "lat", "lon"), u.astype(np.float32), {"units": "m s-1"}),
         "wind_v_ms": (("time_utc", "lat", "lon"), v.astype(np.float32), {"units": "m s-1"})},
        coords={"time_utc": wt, "lat": wlat, "lon": wlon},
        attrs={"product": "stormlane synthetic ERA5-like wind", "synthetic": "true"},
    )

    lat, lon = _grid(WAVE_STEP_DEG)
    t = _times(WAVE_STEP_H, start, end)
    LAT, LON = np.meshgrid(lat, lon, indexing="ij")
    land = np.asarray(land_mask(LAT, LON), dtype=bool)
    out = {k: np.empty((t.size, lat.size, lon.size), dtype=np.float32) for k in ("hs_m", "wave_from_deg", "tp_s", "tm_s")}
    chunk = 32
    for k in range(0, t.size, chunk):
        tu, tv, sh, sf = _wind_field(storms, t[k:k + chunk], lat, lon, seed)
        hs, wd, tp, tm = sea_state_from_wind(tu, tv, sh, sf)
        for name, arr in zip(("hs_m", "wave_from_deg", "tp_s", "tm_s"), (hs, wd, tp, tm)):
            out[name][k:k + chunk] = np.where(land[None], np.nan, arr)
    waves = xr.Dataset(
        {name: (("time_utc", "lat", "lon"), arr, {"units": {"hs_m": "m", "wave_from_deg": "degree"}.get(name, "s")})
         for name, arr in out.items()},
        coords={"time_utc": t, "lat": lat, "lon": lon},
        attrs={"product": "stormlane synthetic CMEMS-like waves", "synthetic": "true"},
    )
    return ScenarioWeather(waves=waves, wind=wind, storms=storms, seed=seed)
