"""The plain parts of a report model: the weather slice under a map, the speed-loss curve and the
provenance record (see :mod:`dashboards.model`, which re-exports them)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import metadata

import numpy as np
import pandas as pd

from dashboards.errors import ReportError

#: Package versions listed in the provenance section by :func:`software_versions`.
SOFTWARE = ("stormlane", "numpy", "pandas", "xarray", "duckdb", "prefect", "scikit-learn", "rtree", "numba", "matplotlib", "global-land-mask")


def _utc(t, name: str) -> pd.Timestamp | None:
    """Timestamp as tz-aware UTC; naive input is refused (it would be ambiguous)."""
    if t is None or (isinstance(t, float) and math.isnan(t)):
        return None
    ts = pd.Timestamp(t)
    if ts is pd.NaT:
        return None
    if ts.tz is None:
        raise ReportError(f"{name}: time {ts} has no timezone; give UTC times")
    return ts.tz_convert("UTC")


def software_versions(packages=SOFTWARE) -> dict[str, str]:
    """Installed versions of the packages a run depends on (``"not installed"`` when absent)."""
    out = {}
    for name in packages:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


@dataclass
class WeatherSnapshot:
    """One time slice of the weather grid, drawn under a map.

    Attributes
    ----------
    time_utc : Timestamp
        Valid time of the slice (tz-aware UTC), normally the worst time met on the historical route.
    lat_deg : ndarray, shape (ny,)
        Grid latitudes, ascending. [deg]
    lon_deg : ndarray, shape (nx,)
        Grid longitudes, ascending, in [-180, 180). [deg]
    hs_m : ndarray, shape (ny, nx)
        Significant wave height; NaN on land or where there is no data. [m]
    wave_from_deg : ndarray, shape (ny, nx), optional
        Mean wave direction the waves come FROM, clockwise from north. [deg]
    product : str
        Product the slice comes from (e.g. the CMEMS dataset id).
    """

    time_utc: pd.Timestamp
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    hs_m: np.ndarray
    wave_from_deg: np.ndarray | None = None
    product: str = ""

    def __post_init__(self):
        self.time_utc = _utc(self.time_utc, "WeatherSnapshot.time_utc")
        self.lat_deg = np.asarray(self.lat_deg, dtype=float)
        self.lon_deg = np.asarray(self.lon_deg, dtype=float)
        self.hs_m = np.asarray(self.hs_m, dtype=float)
        shape = (self.lat_deg.size, self.lon_deg.size)
        if self.hs_m.shape != shape:
            raise ReportError(f"WeatherSnapshot.hs_m has shape {self.hs_m.shape}, expected (lat, lon) = {shape}")
        if self.wave_from_deg is not None:
            self.wave_from_deg = np.asarray(self.wave_from_deg, dtype=float)
            if self.wave_from_deg.shape != shape:
                raise ReportError(f"WeatherSnapshot.wave_from_deg has shape {self.wave_from_deg.shape}, expected {shape}")
        for name in ("lat_deg", "lon_deg"):
            axis = getattr(self, name)
            if axis.size > 1 and not np.all(np.diff(axis) > 0):
                raise ReportError(f"WeatherSnapshot.{name} must be strictly ascending")


@dataclass
class SpeedLossCurve:
    """Attainable speed against wave height for the chosen vessel and model (manual figs. 5-8).

    Attributes
    ----------
    vessel : str
        Vessel profile name.
    model : str
        Speed-loss model (``"bowditch"``, ``"aertssen"``, ``"khokhlov"`` ...).
    speed_kn : float
        Calm-water service speed v0. [kn]
    table : DataFrame
        Long format, one row per point: ``hs_m`` [m], ``encounter_deg`` [deg, 0 = head seas],
        ``speed_kn`` [kn] (attainable speed, after the model's floor).
    min_speed_kn : float, optional
        Speed floor applied by the model. [kn]
    """

    vessel: str
    model: str
    speed_kn: float
    table: pd.DataFrame
    min_speed_kn: float | None = None

    def __post_init__(self):
        missing = {"hs_m", "encounter_deg", "speed_kn"} - set(self.table.columns)
        if missing:
            raise ReportError(f"SpeedLossCurve.table lacks column(s) {sorted(missing)}")


@dataclass
class Provenance:
    """Where the numbers come from (methods and provenance section).

    Attributes
    ----------
    weather_products : list of str
        Product ids or names (e.g. ``cmems_mod_glo_wav_anfc_0.083deg_PT3H-i``, ``ERA5 single levels``).
    weather_files : list of str
        Files read (names, not contents).
    weather_start_utc, weather_end_utc : Timestamp, optional
        Time span the weather covers (tz-aware UTC).
    weather_source : str
        ``"local files"``, ``"copernicusmarine"``, ``"cdsapi"`` ...
    ais_sources : list of str
        AIS files or feeds the lanes/tracks come from.
    speed_loss_model : str
        Model used for speed loss along routes.
    thresholds_profile : str
        Operator-limit profile applied (e.g. ``container<200m``).
    limits : dict of str -> float
        The profile's numeric limits in project names (``hs_m``, ``wind_ms``, ``tp_min_s`` ...);
        ``limits["hs_m"]`` is drawn as a contour on maps and a line on Hs plots.
    vessel : dict
        Vessel particulars (``Vessel.to_dict()``).
    software : dict of str -> str
        Package versions (see :func:`software_versions`).
    methods : list of str
        Method notes printed as given (sources, known limits).
    vessels : list of dict
        Every vessel profile the run used (a night mixes them): ``name``, ``lanes`` (how many
        lanes it sails), ``thresholds_profile`` and ``limits`` (the limit set applied to it, in
        the names of ``limits``), ``particulars`` (length, beam, speed ...).
    weather_spans : list of dict
        Per weather product: ``product``, ``variables``, ``start_utc``, ``end_utc`` (ISO), ``step_h``.
    models : dict of str -> str
        The models the numbers come from (speed loss, fuel and emissions, safety rules, routing).
    """

    weather_products: list = field(default_factory=list)
    weather_files: list = field(default_factory=list)
    weather_start_utc: pd.Timestamp | None = None
    weather_end_utc: pd.Timestamp | None = None
    weather_source: str = ""
    ais_sources: list = field(default_factory=list)
    speed_loss_model: str = ""
    thresholds_profile: str = ""
    limits: dict = field(default_factory=dict)
    vessel: dict = field(default_factory=dict)
    software: dict = field(default_factory=software_versions)
    methods: list = field(default_factory=list)
    vessels: list = field(default_factory=list)
    weather_spans: list = field(default_factory=list)
    models: dict = field(default_factory=dict)

    def __post_init__(self):
        self.weather_start_utc = _utc(self.weather_start_utc, "Provenance.weather_start_utc")
        self.weather_end_utc = _utc(self.weather_end_utc, "Provenance.weather_end_utc")
