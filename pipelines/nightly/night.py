"""The nightly run's shared types: its parameters, its errors, the night and what its stages pass.

Every stage module of :mod:`pipelines.nightly` imports these and never the flow
(:mod:`pipelines.nightly.flow`), so the stages form no import circle with it (an import-linter
contract in ``pyproject.toml`` holds that).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
from pydantic import BaseModel, Field, field_validator

from pipelines.storage import DEFAULT_DB
from thresholds.errors import StormlaneError

#: Default forecast window and departure spacing: the next 48 h every 3 h (16 departures).
DEFAULT_WINDOW_H = 48.0
DEFAULT_STEP_H = 3.0
#: The weather is cut to the lanes' box widened by this much, or by 20 % of the widest lane's
#: span when that is more (the A* mesh's default box is the great circle's plus max(1 deg, 15 %)).
WEATHER_PAD_DEG = 3.0
#: Route properties that change from run to run (timings) and are not stored.
VOLATILE_PROPERTIES = ("search_s",)
#: Retries of the flow's I/O tasks (workspace, files) and of the network task (downloads); the
#: pure steps (screen, per-lane work, ranking) never retry: a deterministic error would repeat.
IO_RETRY_DELAYS_S = (2, 5)
FETCH_RETRY_DELAYS_S = (2, 5, 15)
#: Route roles evaluated for an adverse lane-departure, in report order; every delta is against
#: ``lane``: the lane as planned (its centroids, legs over land repaired) sailed at the lane's
#: typical AIS speed minus the vessel model's speed loss, exactly as the alternatives are sailed.
#: ``least_fuel``: the least-fuel route arriving by the lane's arrival (speed setting per leg).
ROLES = ("lane", "deviation", "safe_optimal", "optimal", "least_fuel", "min_distance")
REFERENCE = "lane"


class NightlyError(StormlaneError):
    """The nightly run cannot start: bad parameters, no lanes, unreadable planned voyages."""


class NightlyWeatherError(NightlyError):
    """The weather does not cover the departures of the night (or there is no weather at all)."""


class NightlyParams(BaseModel):
    """Parameters of one night (validated before anything runs)."""

    db: str = DEFAULT_DB
    out: str | None = None
    out_root: str | None = None
    weather: list[str] = Field(default_factory=list)
    weather_source: Literal["auto", "files", "fetch", "workspace"] = "auto"
    now: str | None = None
    window_h: float = Field(DEFAULT_WINDOW_H, gt=0.0, le=24.0 * 16)
    step_h: float = Field(DEFAULT_STEP_H, gt=0.0, le=48.0)
    voyages: str | None = None
    lanes: list[str] | None = None
    vessel: str | None = None
    profile: str | None = None
    speed_loss: str = "bowditch"
    safety: Literal["hard", "soft", "none"] = "hard"
    max_detail: int = Field(20, ge=0)
    least_fuel: bool = True
    #: Rank every departure of the window per lane with adverse departures (its route of this objective
    #: from each departure, :func:`routing.planner_window.plan_window`); "none": no ranking.
    rank_departures: Literal["none", "time", "fuel"] = "none"
    report: bool = True
    exports: Literal["proposed", "all", "none"] = "proposed"
    cache_dir: str | None = None

    @field_validator("speed_loss")
    @classmethod
    def _model(cls, v: str) -> str:
        from routing.speed_loss import MODELS

        if v not in MODELS and not v.startswith("learned:"):
            raise ValueError(f"unknown speed-loss model {v!r}; use one of {', '.join(MODELS)}, learned:NAME")
        return v

    @field_validator("now")
    @classmethod
    def _now(cls, v: str | None) -> str | None:
        if v is not None:
            try:
                parse_utc(v, "now")
            except NightlyError as err:
                raise ValueError(str(err)) from None
        return v

    @classmethod
    def checked(cls, **kwargs) -> "NightlyParams":
        """Validate, turning pydantic's report into one :class:`NightlyError` line per problem."""
        from pydantic import ValidationError

        try:
            return cls(**kwargs)
        except ValidationError as err:
            problems = "; ".join(_problem(e) for e in err.errors())
            raise NightlyError(f"invalid nightly parameters: {problems}") from None


def _problem(e: dict) -> str:
    """One of pydantic's errors as ``field: what`` (without its "Value error, " and without the
    field named twice: it said ``now: Value error, now: 'now' is not an ISO 8601 time``)."""
    loc = ".".join(map(str, e["loc"]))
    msg = str(e["msg"]).removeprefix("Value error, ")
    return msg if msg.startswith(f"{loc}: ") else f"{loc}: {msg}"


def parse_utc(text, what: str = "time") -> pd.Timestamp:
    """An ISO 8601 time as a tz-aware UTC Timestamp (naive input is taken as UTC)."""
    from pipelines.times import utc_or_none

    t = utc_or_none(text)
    if t is None:
        raise NightlyError(f"{what}: {text!r} is not an ISO 8601 time")
    return t


@dataclass
class NightPath:
    """One thing to sail tonight: a lane (all window departures) or a planned voyage."""

    path_id: str
    lane_id: str | None
    origin: str
    destination: str
    centroids: pd.DataFrame  # seq, lat_deg, lon_deg, speed_kn (sailing order)
    vessel_profile: str
    departures: list = field(default_factory=list)  # tz-aware Timestamps; empty = the window
    error: str | None = None  # a path that cannot be sailed at all (e.g. no lane for a planned voyage)

    @property
    def hours(self) -> float:
        """Sailing time along the centroids at their typical speeds. [h]"""
        from thresholds.geodesy import haversine_nmi

        c = self.centroids
        if len(c) < 2:
            return 0.0
        d = np.asarray(haversine_nmi(c["lat_deg"].to_numpy()[:-1], c["lon_deg"].to_numpy()[:-1],
                                     c["lat_deg"].to_numpy()[1:], c["lon_deg"].to_numpy()[1:]), dtype=float)
        v = c["speed_kn"].to_numpy(dtype=float)[:-1]
        v = np.where(np.isfinite(v) & (v > 0), v, np.nan)
        fallback = np.nanmedian(v) if np.isfinite(v).any() else 10.0
        return float(np.sum(d / np.where(np.isfinite(v), v, fallback)))


@dataclass
class Night:
    """Everything the pure steps need, fixed before any computation."""

    run_id: str
    now_utc: pd.Timestamp
    departures: pd.DatetimeIndex
    params: NightlyParams
    paths: list
    weather_ds: object  # canonical xarray.Dataset cut to the night
    weather_meta: dict
    weather_source: str
    weather_digest: str
    lanes_digest: str
    vessels: dict  # profile name -> Vessel
    limits: object  # OperatorProfile
    out: Path
    speed_model: object = None  # pipelines.learn.SpeedLossChoice of params.speed_loss (resolved once)
    learned_limits: dict | None = None  # pipelines.learn.learned_limits: AIS voluntary slow-down beside the limits

    def path_departures(self, p: NightPath) -> list:
        return list(p.departures) or list(self.departures)

    def window(self) -> dict:
        """The departures the night sailed, as its outputs state them: ``start_utc``,
        ``end_utc``, ``step_h``, ``departures`` (distinct times), ``planned``. The forecast
        window's departures every ``step_h``; or, when every path has departures of its own
        (planned voyages, ``--voyages``), the first and last of those and no step."""
        own = sorted({t for p in self.paths for t in p.departures})
        if own and all(p.departures for p in self.paths):
            return {"start_utc": own[0], "end_utc": own[-1], "step_h": None, "departures": len(own), "planned": True}
        return {"start_utc": self.departures[0], "end_utc": self.departures[0] + pd.Timedelta(hours=self.params.window_h),
                "step_h": self.params.step_h, "departures": len(self.departures), "planned": False}


@dataclass
class LaneJob:
    """One lane's adverse departures and everything its work needs (shipped to a worker)."""

    path_id: str
    lane_id: str | None
    centroids: pd.DataFrame
    vessel: object  # thresholds.vessel.Vessel
    limits: object  # OperatorProfile
    speed_loss: str  # a formula's name or learned:NAME
    departures: list  # Timestamps
    weather: object  # routing.field.WeatherField
    safety: str = "hard"
    learned: object = None  # learned:NAME: its LearnedSpeedTable for this lane's vessel and speed (or the error why none)
    least_fuel: bool = True
    rank_departures: str = "none"
    window: list = field(default_factory=list)  # every departure of the lane tonight (for the ranking)


@dataclass
class NightResult:
    """What a night produced: the rows to store and the cases for the report, in rank order."""

    departures: pd.DataFrame
    routes: pd.DataFrame
    events: pd.DataFrame
    cases: list  # dicts (adverse/failed lane-departures) in rank order
    counts: dict
    windows: list = field(default_factory=list)  # per lane: its departures ranked (rank_departures)
    #: (path_id, depart_utc) -> {"n_beyond", "status"}: the lane-departures (not failed)
    #: with centroids timed outside the weather's span, which the screen could not check
    beyond_weather: dict = field(default_factory=dict)
    #: the rerouted lanes whose typical AIS speed exceeds their vessel's maximum-power speed
    #: (:func:`pipelines.nightly.reroute.speed_caps`): sailed by the model at that speed
    speed_capped: list = field(default_factory=list)
