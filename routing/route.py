"""The typed result every router and evaluator returns: a route with ETAs and the weather met.

A :class:`Route` is the exchange format between ``routing`` (which computes it), ``pipelines``
(which stores it) and ``dashboards`` (which renders and exports it).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from thresholds.geodesy import haversine_nmi


@dataclass(frozen=True)
class Route:
    """A sequence of waypoints with ETAs.

    Attributes
    ----------
    name : str
        Role of the route, e.g. ``"optimal"``, ``"min_distance"``, ``"deviation"``, ``"historical"``.
    lat_deg, lon_deg : ndarray, shape (n,)
        Waypoints. [deg]
    time_utc : DatetimeIndex, shape (n,)
        ETA at each waypoint, timezone-aware UTC.
    leg_speed_kn : ndarray, shape (n - 1,)
        Speed over ground on the leg from waypoint i to i + 1. [kn]
    weather : dict of str -> ndarray, shape (n,)
        Weather met at each waypoint in project names (``hs_m``, ``wave_from_deg``, ``tp_s`` ...).
    properties : dict
        Free metadata (vessel, speed-loss model, flags); must be JSON-serialisable.
    """

    name: str
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    time_utc: pd.DatetimeIndex
    leg_speed_kn: np.ndarray
    weather: dict = field(default_factory=dict)
    properties: dict = field(default_factory=dict)

    def __post_init__(self):
        lat = np.asarray(self.lat_deg, dtype=float)
        lon = np.asarray(self.lon_deg, dtype=float)
        times = pd.DatetimeIndex(self.time_utc)
        if times.tz is None:
            raise ValueError("Route.time_utc must be timezone-aware UTC")
        times = times.tz_convert("UTC")
        n = lat.size
        if lon.size != n or len(times) != n:
            raise ValueError(f"Route {self.name!r}: lat, lon and time_utc lengths differ ({n}, {lon.size}, {len(times)})")
        speed = np.asarray(self.leg_speed_kn, dtype=float)
        if speed.size != max(n - 1, 0):
            raise ValueError(f"Route {self.name!r}: leg_speed_kn needs {max(n - 1, 0)} values, got {speed.size}")
        for key, values in self.weather.items():
            if np.asarray(values).shape != (n,):
                raise ValueError(f"Route {self.name!r}: weather[{key!r}] needs shape ({n},)")
        object.__setattr__(self, "lat_deg", lat)
        object.__setattr__(self, "lon_deg", lon)
        object.__setattr__(self, "time_utc", times)
        object.__setattr__(self, "leg_speed_kn", speed)
        object.__setattr__(self, "weather", {k: np.asarray(v, dtype=float) for k, v in self.weather.items()})

    @property
    def n_waypoints(self) -> int:
        return int(self.lat_deg.size)

    @property
    def leg_dist_nmi(self) -> np.ndarray:
        """Great-circle length of each leg. [nmi]"""
        if self.n_waypoints < 2:
            return np.zeros(0)
        return np.asarray(haversine_nmi(self.lat_deg[:-1], self.lon_deg[:-1], self.lat_deg[1:], self.lon_deg[1:]))

    @property
    def dist_nmi(self) -> float:
        return float(self.leg_dist_nmi.sum())

    @property
    def time_h(self) -> float:
        if self.n_waypoints < 2:
            return 0.0
        return float((self.time_utc[-1] - self.time_utc[0]) / pd.Timedelta(hours=1))

    @property
    def max_hs_m(self) -> float:
        """Highest Hs met: at the waypoints, and along the legs when the router recorded it
        (``properties["max_hs_m_along"]``; long smoothed legs can cross a peak between waypoints). [m]"""
        values = []
        hs = self.weather.get("hs_m")
        if hs is not None and np.isfinite(hs).any():
            values.append(float(np.nanmax(hs)))
        along = self.properties.get("max_hs_m_along")
        if along is not None and np.isfinite(along):
            values.append(float(along))
        return max(values) if values else float("nan")

    def to_dict(self, waypoints: bool = True) -> dict:
        """Summary in the CLI's JSON shape: totals plus ``[[lat, lon, "ISO time"], ...]``."""
        out = {
            "time_h": round(self.time_h, 6),
            "dist_nmi": round(self.dist_nmi, 6),
            "max_hs_m": None if np.isnan(self.max_hs_m) else round(self.max_hs_m, 4),
        }
        if waypoints:
            out["waypoints"] = [
                [round(float(la), 7), round(float(lo), 7), t.isoformat().replace("+00:00", "Z")]
                for la, lo, t in zip(self.lat_deg, self.lon_deg, self.time_utc)
            ]
        return out

    def to_frame(self) -> pd.DataFrame:
        """One row per waypoint: position, ETA, speed on the leg that starts there, weather met."""
        speed = np.append(self.leg_speed_kn, np.nan)
        frame = pd.DataFrame({"lat_deg": self.lat_deg, "lon_deg": self.lon_deg, "time_utc": self.time_utc, "leg_speed_kn": speed})
        for key, values in self.weather.items():
            frame[key] = values
        return frame

    def to_json(self) -> str:
        """Full serialisation (round-trips through :meth:`from_json`)."""
        return json.dumps(
            {
                "name": self.name,
                "lat_deg": self.lat_deg.tolist(),
                "lon_deg": self.lon_deg.tolist(),
                "time_utc": [t.isoformat() for t in self.time_utc],
                "leg_speed_kn": self.leg_speed_kn.tolist(),
                "weather": {k: [None if np.isnan(x) else float(x) for x in v] for k, v in self.weather.items()},
                "properties": self.properties,
            }
        )

    @classmethod
    def from_json(cls, text: str) -> "Route":
        data = json.loads(text)
        return cls(
            name=data["name"],
            lat_deg=np.asarray(data["lat_deg"], dtype=float),
            lon_deg=np.asarray(data["lon_deg"], dtype=float),
            time_utc=pd.DatetimeIndex(pd.to_datetime(data["time_utc"], utc=True, format="ISO8601")),
            leg_speed_kn=np.asarray(data["leg_speed_kn"], dtype=float),
            weather={k: np.array([np.nan if x is None else x for x in v], dtype=float) for k, v in data["weather"].items()},
            properties=data.get("properties", {}),
        )
