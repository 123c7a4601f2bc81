"""Hand-built AIS tracks with known answers for the lanes tests.

Independent of the project's geometry code on purpose: positions come from a local flat-earth
step (1 nmi = 1/60 deg of latitude, 1/(60 cos lat) deg of longitude), exact enough over the
few tens of nmi used here, so expected values never come from the functions under test.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

T0 = pd.Timestamp("2025-01-01T00:00Z")


def offset(lat, lon, east_nmi, north_nmi):
    """Position ``east_nmi``/``north_nmi`` away on a local flat earth."""
    return lat + north_nmi / 60.0, lon + east_nmi / (60.0 * math.cos(math.radians(lat)))


def flat_dist_nmi(lat1, lon1, lat2, lon2):
    """Local flat-earth distance (good to < 0.1 % over a few tens of nmi at mid latitudes)."""
    mlat = math.radians((lat1 + lat2) / 2.0)
    return 60.0 * math.hypot(lat2 - lat1, (lon2 - lon1) * math.cos(mlat))


class Itinerary:
    """Builds one vessel's fixes: stays at a place and straight legs at constant speed."""

    def __init__(self, mmsi: int, start=T0, cadence_s: float = 60.0, seed: int = 0):
        self.mmsi = mmsi
        self.t = pd.Timestamp(start)
        self.cadence_s = cadence_s
        self.rows: list[dict] = []
        self.rng = np.random.default_rng(seed)
        self.pos: tuple[float, float] | None = None

    def _fix(self, lat, lon, sog, cog, **extra):
        self.rows.append({"mmsi": self.mmsi, "time_utc": self.t, "lat_deg": lat, "lon_deg": lon,
                          "sog_kn": sog, "cog_deg": cog, "nav_status": extra.get("nav_status", 0.0)})

    def stay(self, lat, lon, minutes, sog=0.0, jitter_nmi=0.0, nav_status=0.0):
        """Berthed for ``minutes``: SOG as given (0 = a ferry at its slip), status 'under way'."""
        self.pos = (lat, lon)
        n = int(minutes * 60 // self.cadence_s)
        for _ in range(n):
            e, nn = self.rng.normal(0, jitter_nmi, 2) if jitter_nmi else (0.0, 0.0)
            la, lo = offset(lat, lon, e, nn)
            self._fix(la, lo, sog, np.nan, nav_status=nav_status)
            self.t += pd.Timedelta(seconds=self.cadence_s)
        return self

    def sail(self, lat2, lon2, speed_kn, report_sog=None, lateral_nmi=0.0):
        """Straight leg from the current position at constant speed (lateral offset optional)."""
        lat1, lon1 = self.pos
        d = flat_dist_nmi(lat1, lon1, lat2, lon2)
        hours = d / speed_kn
        n = max(1, int(hours * 3600 // self.cadence_s))
        mlat = math.radians((lat1 + lat2) / 2)
        de, dn = (lon2 - lon1) * 60 * math.cos(mlat), (lat2 - lat1) * 60
        cog = math.degrees(math.atan2(de, dn)) % 360
        ue, un = (-dn / d, de / d) if d > 0 else (0.0, 0.0)  # left-hand normal
        for i in range(n):
            f = i / n
            lat = lat1 + f * (lat2 - lat1)
            lon = lon1 + f * (lon2 - lon1)
            if lateral_nmi:
                lat, lon = offset(lat, lon, ue * lateral_nmi, un * lateral_nmi)
            self._fix(lat, lon, speed_kn if report_sog is None else report_sog, cog)
            self.t += pd.Timedelta(seconds=hours * 3600 / n)
        self.pos = (lat2, lon2)
        return self

    def silence(self, minutes, lat2=None, lon2=None):
        """No fixes for ``minutes`` (the ship may move meanwhile)."""
        self.t += pd.Timedelta(minutes=minutes)
        if lat2 is not None:
            self.pos = (lat2, lon2)
        return self

    def frame(self) -> pd.DataFrame:
        df = pd.DataFrame(self.rows)
        df["time_utc"] = pd.to_datetime(df["time_utc"], utc=True)
        return df


def shuttle(mmsi, a, b, n_trips, speed_kn=12.0, stay_min=40, cadence_s=60.0, lateral_nmi=0.0, start=T0, seed=0):
    """A ferry going a -> b -> a ... ``n_trips`` legs, berthing ``stay_min`` at each end."""
    it = Itinerary(mmsi, start=start, cadence_s=cadence_s, seed=seed)
    it.stay(*a, stay_min, jitter_nmi=0.005)
    ends = [b, a]
    for k in range(n_trips):
        it.sail(*ends[k % 2], speed_kn, lateral_nmi=lateral_nmi)
        it.stay(*ends[k % 2], stay_min, jitter_nmi=0.005)
    return it.frame()


def transit(track_id, start, end, speed_kn=12.0, cadence_s=60.0, lateral_nmi=0.0, t0=T0, id_col="mmsi"):
    """One straight transit track (no stops)."""
    it = Itinerary(track_id, start=t0, cadence_s=cadence_s)
    it.pos = start
    it.sail(*end, speed_kn, lateral_nmi=lateral_nmi)
    df = it.frame()
    if id_col != "mmsi":
        df = df.rename(columns={"mmsi": id_col})
    return df
