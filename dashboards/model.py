"""What a report shows: plain dataclasses the nightly and audit flows fill, the renderer reads.

The model holds results only; the renderer adds nothing but layout, number formatting and
simple aggregation of what is given (sums of deltas, counts). Every field carries its unit in
its name or in its description below. Strings that come from AIS (ship names, call signs,
destinations, port names derived from AIS) are stored as they arrived; the renderer escapes
every string it writes (``dashboards.html.escape``, the only path into the page).

Hand-off from the flows::

    model = NightlyReport(run_id=..., departures=[LaneDeparture(..., routes=RouteSet(...))], ...)
    render_nightly_report(model, out_dir / "report.html")

    audit = VoyageAudit(mmsi=..., ship_name=..., routes=RouteSet(...), ...)
    render_audit_report(audit, "audit.html")

``report_to_json`` / ``report_from_json`` store a model next to the report so that
``stormlane report --model FILE.json --out FILE.html`` re-renders it later.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from dashboards.errors import ReportError
from dashboards.model_parts import (SOFTWARE, Provenance, SpeedLossCurve, WeatherSnapshot, _utc,  # noqa: F401 (re-exported)
                                     software_versions)
from routing.route import Route

#: Route roles in display order, with their legend labels. ``lane`` (nightly) and
#: ``as_sailed_modelled`` (audit) are the like-for-like references: sailed by the same vessel
#: model as the alternatives; ``as_sailed`` is the AIS track at its AIS times (the truth);
#: ``historical`` is the role of reports written before the like-for-like comparison.
ROUTE_ROLES = ("as_sailed", "as_sailed_modelled", "lane", "historical", "deviation", "safe_optimal", "optimal", "least_fuel",
               "min_distance")
#: Roles a RouteSet takes as its reference when none is named, first present wins.
REFERENCE_ROLES = ("lane", "as_sailed_modelled", "historical", "as_sailed")
ROLE_LABELS = {
    "as_sailed": "as sailed (AIS times)",
    "as_sailed_modelled": "as sailed, modelled",
    "lane": "lane as planned (modelled)",
    "historical": "historical (lane / AIS track)",
    "deviation": "cargo-safe deviation",
    "safe_optimal": "safe time-optimal A* (vessel limits)",
    "optimal": "time-optimal A*",
    "least_fuel": "least fuel, same arrival (speed per leg)",
    "min_distance": "minimum-distance A*",
}

#: Metric columns the summary understands (``RouteSet.metrics``); others are shown as given.
METRIC_COLUMNS = {
    "time_h": "sailing time [h]",
    "dist_nmi": "distance sailed [nmi]",
    "mean_speed_kn": "mean speed over ground [kn]",
    "max_hs_m": "highest significant wave height met [m]",
    "mean_hs_m": "mean significant wave height met [m]",
    "fuel_t": "fuel burnt (STEAM2) [t]",
    "co2_t": "CO2 emitted [t]",
    "so2_t": "SO2 emitted [t]",
    "nox_t": "NOx emitted [t]",
    "pm_t": "particulate matter emitted [t]",
    "n_safety_events": "IMO MSC.1/Circ.1228 events (count)",
    "n_operator_events": "operator-limit events (count)",
    "exposure_h": "hours over any operator limit [h]",
    "adverse_h": "hours over an operator limit or in an IMO situation [h]",
    "imo_adverse_h": "hours in an IMO MSC.1/Circ.1228 situation [h]",
}

#: Comparison metrics of the cargo-loss seed paper (section 4), alternative against the reference.
SEED_COLUMNS = {
    "hs_decrease_pct": "decrease of mean Hs over the adverse portion [%]",
    "period_decrease_pct": "decrease of mean wave period over the adverse portion [%]",
    "wind_decrease_pct": "decrease of mean wind speed over the adverse portion [%]",
    "wave_dir_deviation_pct": "wave-direction deviation [%]",
    "length_diff_pct": "length difference [%]",
}


@dataclass
class RouteSet:
    """The alternatives for one voyage or lane-departure, and how they compare.

    Attributes
    ----------
    routes : dict of str -> Route
        Keyed by role: ``historical``, ``deviation``, ``optimal``, ``min_distance`` (others are
        drawn too, in grey). Each carries its ETAs, leg speeds and the weather met. Empty for a
        case the report shows without maps (beyond ``NightlyReport.max_detail``): then
        ``metrics`` holds one row per role and the page shows the table and notes only.
    metrics : DataFrame, optional
        One row per role (index = role), columns named with units (see :data:`METRIC_COLUMNS`:
        ``time_h``, ``dist_nmi``, ``max_hs_m``, ``mean_hs_m``, ``fuel_t``, ``co2_t``,
        ``n_safety_events``, ``exposure_h`` ...). When absent, the renderer tabulates what the
        routes themselves carry (time, distance, max and mean Hs met).
    events : DataFrame, optional
        Safety events, one row each: ``route``, ``criterion`` (e.g. ``surf-riding``), ``start_utc``,
        ``end_utc``, ``duration_h`` [h], ``lat_deg``, ``lon_deg`` [deg].
    exposure : DataFrame, optional
        Exposure per route and limit: ``route``, ``limit`` (e.g. ``hs_m > 4.5``), ``exposure_h`` [h].
    weather : WeatherSnapshot, optional
        Field drawn under the map.
    proposed : str, optional
        Role of the recommended alternative (``None``: no proposal, e.g. nothing better found).
    exports : dict of str -> str
        Export files for this case, label -> path relative to the report (linked, never loaded).
    hs_limit_m : float, optional
        The Hs limit of this case's vessel, drawn on its map and plot (default: the provenance's
        ``limits["hs_m"]``; a nightly run mixes vessel classes with different limits).
    profiles : dict of str -> DataFrame
        Weather met along each route as its evaluation sampled it (``time_utc``, ``hs_m``: one row
        per piece of leg, at most 15 min of sailing). The Hs plot draws these when given, so its
        peak is the table's "highest Hs met" even where a long leg crosses a storm between two
        waypoints; without them it draws the waypoint values.
    reference : str, optional
        Role every delta is measured against (the like-for-like reference); default the first of
        :data:`REFERENCE_ROLES` present.
    notes : dict of str -> str
        A note per role shown under the table (e.g. why a route is not proposed).
    """

    routes: dict
    metrics: pd.DataFrame | None = None
    events: pd.DataFrame | None = None
    exposure: pd.DataFrame | None = None
    weather: WeatherSnapshot | None = None
    proposed: str | None = None
    exports: dict = field(default_factory=dict)
    hs_limit_m: float | None = None
    profiles: dict = field(default_factory=dict)
    reference: str | None = None
    notes: dict = field(default_factory=dict)

    def __post_init__(self):
        roles = set(self.routes) | (set(map(str, self.metrics.index)) if self.metrics is not None else set())
        if self.reference is None:
            self.reference = next((r for r in REFERENCE_ROLES if r in roles), None)
        elif self.reference not in roles:
            raise ReportError(f"RouteSet.reference = {self.reference!r} is not one of the routes {sorted(roles)}")
        for role, route in self.routes.items():
            if not isinstance(route, Route):
                raise ReportError(f"RouteSet.routes[{role!r}] is {type(route).__name__}, not a Route")
        for role, prof in self.profiles.items():
            if role not in self.routes:
                raise ReportError(f"RouteSet.profiles[{role!r}] has no route of that role")
            if not isinstance(prof, pd.DataFrame) or not {"time_utc", "hs_m"} <= set(prof.columns):
                raise ReportError(f"RouteSet.profiles[{role!r}] must be a DataFrame with columns time_utc and hs_m")
        if self.proposed is not None and self.proposed not in roles:
            raise ReportError(f"RouteSet.proposed = {self.proposed!r} is not one of the routes {sorted(roles)}")

    @property
    def detailed(self) -> bool:
        """The routes themselves are held (map, plots, waypoints); else only their metrics."""
        return bool(self.routes)

    @property
    def ordered_roles(self) -> list[str]:
        """Roles in display order: the known ones first, then the rest alphabetically (the
        metrics' rows when the routes are not held)."""
        have = self.routes if self.routes or self.metrics is None else {str(r): None for r in self.metrics.index}
        known = [r for r in ROUTE_ROLES if r in have]
        return known + sorted(r for r in have if r not in ROUTE_ROLES)

    def metrics_table(self) -> pd.DataFrame:
        """The metrics as given, or else what the routes carry (time, distance, Hs met)."""
        if self.metrics is not None:
            table = self.metrics.copy()
            first = [r for r in self.ordered_roles if r in table.index]
            return table.loc[first + [r for r in table.index if r not in first]]
        rows = {}
        for role in self.ordered_roles:
            route = self.routes[role]
            hs = route.weather.get("hs_m")
            mean_hs = float(np.nanmean(hs)) if hs is not None and np.isfinite(hs).any() else float("nan")
            rows[role] = {"time_h": route.time_h, "dist_nmi": route.dist_nmi, "max_hs_m": route.max_hs_m, "mean_hs_m": mean_hs}
        return pd.DataFrame.from_dict(rows, orient="index")

    def value_columns(self) -> list[str]:
        """Metric columns to show as values: known ones in :data:`METRIC_COLUMNS` order, then the
        rest, leaving out given deltas (``d_*``) and the seed comparison metrics."""
        plain = [c for c in self.metrics_table().columns if _is_value_column(c)]
        return [c for c in METRIC_COLUMNS if c in plain] + [c for c in plain if c not in METRIC_COLUMNS]

    def deltas(self, reference: str | None = None) -> pd.DataFrame:
        """Each value column minus the reference row (default :attr:`reference`; empty when absent).

        Deltas handed over in ``d_<column>`` columns (as ``routing.evaluate.comparison_table``
        gives them) are used as they are; the others are differences of the values.
        """
        table = self.metrics_table()
        reference = self.reference if reference is None else reference
        if reference not in table.index:
            return table.iloc[0:0]
        out = {}
        for col in self.value_columns():
            given = f"d_{col}"
            if given in table.columns:
                out[col] = pd.to_numeric(table[given], errors="coerce")
            else:
                values = pd.to_numeric(table[col], errors="coerce")
                out[col] = values - values.loc[reference]
        return pd.DataFrame(out, index=table.index)

    def delta(self, column: str, role: str) -> float:
        """One cell of :meth:`deltas` (``role``'s row, ``column``), NaN where :meth:`deltas` has
        none; without building the table (a 60-lane night's page asks for about 2,700 cells)."""
        table = self.metrics if self.metrics is not None else self.metrics_table()
        if not _is_value_column(column) or column not in table.columns or role not in table.index or self.reference not in table.index:
            return float("nan")
        given = f"d_{column}"
        if given in table.columns:
            return _number(table.at[role, given])
        return _number(table.at[role, column]) - _number(table.at[self.reference, column])

    def delta_pct(self, column: str, role: str) -> float:
        """Relative delta ``d_<column>_pct`` if it was handed over, else NaN. [%]"""
        table = self.metrics_table()
        key = f"d_{column}_pct"
        if key in table.columns and role in table.index:
            try:
                return float(table.loc[role, key])
            except (TypeError, ValueError):
                return float("nan")
        return float("nan")


@dataclass
class LaneDeparture:
    """One lane sailed from one departure time that the run flagged (adverse) or could not finish.

    Attributes
    ----------
    lane_id : str
        Lane identifier in the workspace.
    origin, destination : str
        Port names (may come from AIS; escaped on output).
    depart_utc : Timestamp
        Departure time checked (tz-aware UTC).
    status : {"adverse", "failed", "ok"}
        ``adverse``: a rule fired; ``failed``: the lane's work raised (see ``error``).
    rules : list of str
        The rule(s) that fired, as the thresholds module words them (e.g. ``hs_m 5.2 > 4.5``).
    worst_time_utc : Timestamp, optional
        When the worst weather is met on the historical route.
    worst_lat_deg, worst_lon_deg : float, optional
        Where. [deg]
    worst_hs_m : float, optional
        Significant wave height there. [m]
    routes : RouteSet, optional
        Alternatives and comparison (absent for failed lanes).
    error : str, optional
        What went wrong, for ``failed``.
    risk_avoided : float, optional
        The run's ranking key: hours over a limit or in an IMO situation avoided (lane as
        planned minus proposed), shown as given. [h]
    vessel : str, optional
        The vessel profile that sails this lane (its limits decided "adverse").
    reasons : list of dict
        The rules that fired, structured for the chips: ``rule``, ``value`` and ``limit`` (in
        ``unit``), ``time_utc`` (ISO), ``lat_deg``, ``lon_deg``, ``n_points`` (centroids where
        it fired); ``rules`` holds the same in full wording.
    events_avoided : int, optional
        IMO MSC.1/Circ.1228 events avoided (lane as planned minus proposed), the ranking's second key.
    """

    lane_id: str
    origin: str
    destination: str
    depart_utc: pd.Timestamp
    status: str = "adverse"
    rules: list = field(default_factory=list)
    worst_time_utc: pd.Timestamp | None = None
    worst_lat_deg: float | None = None
    worst_lon_deg: float | None = None
    worst_hs_m: float | None = None
    routes: RouteSet | None = None
    error: str | None = None
    risk_avoided: float | None = None
    vessel: str | None = None
    reasons: list = field(default_factory=list)
    events_avoided: int | None = None

    def __post_init__(self):
        self.lane_id = str(self.lane_id)
        self.depart_utc = _utc(self.depart_utc, f"LaneDeparture({self.lane_id}).depart_utc")
        self.worst_time_utc = _utc(self.worst_time_utc, f"LaneDeparture({self.lane_id}).worst_time_utc")
        if self.status not in ("adverse", "failed", "ok"):
            raise ReportError(f"LaneDeparture({self.lane_id}).status = {self.status!r}; use adverse, failed or ok")
        if self.status == "failed" and not self.error:
            raise ReportError(f"LaneDeparture({self.lane_id}) is failed but has no error message")


def metric_delta(routes: RouteSet | None, column: str) -> float:
    """Proposed minus the route set's reference for one metric (NaN when either is missing)."""
    if routes is None or routes.proposed is None:
        return float("nan")
    return routes.delta(column, routes.proposed)


def _is_value_column(column) -> bool:
    """A metric shown as a value (and given a delta): not a handed-over delta (``d_*``), not one
    of the seed's comparison metrics (:data:`SEED_COLUMNS`)."""
    return not str(column).startswith("d_") and column not in SEED_COLUMNS


def _number(value) -> float:
    """``value`` as a float, NaN where it is not a number (``pd.to_numeric(errors="coerce")``)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return float(pd.to_numeric(pd.Series([value]), errors="coerce").iloc[0])


@dataclass
class LaneLine:
    """One lane (or planned voyage) the night checked, drawn on the fleet map.

    Attributes
    ----------
    lane_id : str
    origin, destination : str
        Port names (escaped on output; never drawn into a figure).
    vessel : str
        The vessel profile that sails it.
    lat_deg, lon_deg : ndarray
        Its centroid path in sailing order. [deg]
    """

    lane_id: str
    origin: str
    destination: str
    vessel: str = ""
    lat_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lon_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self):
        self.lane_id = str(self.lane_id)
        self.lat_deg = np.asarray(self.lat_deg, dtype=float)
        self.lon_deg = np.asarray(self.lon_deg, dtype=float)
        if self.lat_deg.shape != self.lon_deg.shape:
            raise ReportError(f"LaneLine({self.lane_id}): lat_deg and lon_deg differ in length")


#: Columns of ``NightlyReport.grid`` (one row per lane-departure checked).
GRID_COLUMNS = ("lane_id", "depart_utc", "status", "rules", "risk_h", "risk_avoided_h", "proposed", "case")


@dataclass
class NightlyReport:
    """One night's reroute run.

    Attributes
    ----------
    run_id : str
        Identifier of the run (tables in the workspace are keyed by it).
    started_utc, finished_utc : Timestamp
        Wall-clock start and end of the run (tz-aware UTC).
    now_utc : Timestamp
        Forecast reference time (``--now``).
    window_start_utc, window_end_utc : Timestamp
        Departure window checked.
    departure_step_h : float or None
        Spacing of the departures in the window [h]; None for planned voyages (each its own
        departure, the window from the first to the last).
    lanes_checked : int
        Lanes (or planned voyages) checked.
    departures_checked : int
        Lane-departures checked (lanes x departures).
    departures : list of LaneDeparture
        The adverse and failed lane-departures, in the run's ranking order.
    provenance : Provenance
    speed_loss : SpeedLossCurve, optional
    title : str
    max_detail : int
        At most this many adverse lane-departures get a map and plots (the rest are in the table).
    lanes : list of LaneLine
        Every lane checked (the fleet map); empty in models written before the overview.
    grid : DataFrame, optional
        One row per lane-departure checked (the lane x departure matrix): ``lane_id``,
        ``depart_utc``, ``status`` (``ok``/``adverse``/``failed``), ``rules`` (names, comma
        separated), ``risk_h`` (hours over a limit or in an IMO situation on the lane as planned,
        NaN when not rerouted), ``risk_avoided_h`` (the ranking key, NaN without a proposal),
        ``proposed`` (role or None), ``case`` (1-based position in ``departures`` or NaN).
    summary : dict
        The overview's figures as the run computed them (the CLI prints and ``--json`` returns the
        same dict): counts, sums of the proposed reroutes' deltas, hours at risk avoided. When
        empty the page sums the route sets (:meth:`totals`).
    exports : dict of str -> str
        Night-level export links (label -> path relative to the report), e.g. ``exports.zip``.
    """

    run_id: str
    started_utc: pd.Timestamp
    finished_utc: pd.Timestamp
    now_utc: pd.Timestamp
    window_start_utc: pd.Timestamp
    window_end_utc: pd.Timestamp
    departure_step_h: float | None
    lanes_checked: int
    departures_checked: int
    departures: list = field(default_factory=list)
    provenance: Provenance = field(default_factory=Provenance)
    speed_loss: SpeedLossCurve | None = None
    title: str = "stormlane nightly reroute report"
    max_detail: int = 20
    lanes: list = field(default_factory=list)
    grid: pd.DataFrame | None = None
    summary: dict = field(default_factory=dict)
    exports: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("started_utc", "finished_utc", "now_utc", "window_start_utc", "window_end_utc"):
            setattr(self, name, _utc(getattr(self, name), f"NightlyReport.{name}"))
        if self.grid is not None:
            missing = [c for c in GRID_COLUMNS if c not in self.grid.columns]
            if missing:
                raise ReportError(f"NightlyReport.grid lacks column(s) {missing}")
        for lane in self.lanes:
            if not isinstance(lane, LaneLine):
                raise ReportError(f"NightlyReport.lanes holds a {type(lane).__name__}, not a LaneLine")
        for d in self.departures:
            if not isinstance(d, LaneDeparture):
                raise ReportError(f"NightlyReport.departures holds a {type(d).__name__}, not a LaneDeparture")

    @property
    def adverse(self) -> list[LaneDeparture]:
        return [d for d in self.departures if d.status == "adverse"]

    @property
    def failed(self) -> list[LaneDeparture]:
        return [d for d in self.departures if d.status == "failed"]

    @property
    def reroutes(self) -> list[LaneDeparture]:
        """Adverse lane-departures with a proposed alternative."""
        return [d for d in self.adverse if d.routes is not None and d.routes.proposed is not None]

    def totals(self) -> dict[str, float]:
        """Sums over proposed reroutes of (proposed - reference): time, fuel, CO2, events; the
        reference of each reroute is its route set's (the lane as planned, sailed by the same model).

        ``safety_events_avoided`` is the negated sum of the ``n_safety_events`` deltas. A total is
        NaN when no reroute carries that metric.
        """
        out = {}
        for column in ("time_h", "dist_nmi", "fuel_t", "co2_t", "n_safety_events", "exposure_h"):
            values = [metric_delta(d.routes, column) for d in self.reroutes]
            values = [v for v in values if math.isfinite(v)]
            out[f"delta_{column}"] = float(sum(values)) if values else float("nan")
        events = out.pop("delta_n_safety_events")
        out["safety_events_avoided"] = -events if math.isfinite(events) else float("nan")
        return out


@dataclass
class VoyageAudit:
    """A retrospective audit of one sailed voyage.

    Attributes
    ----------
    mmsi : int
        Ship's MMSI.
    ship_name, callsign, ais_destination : str, optional
        As reported in AIS static data (untrusted text; escaped on output).
    imo : int, optional
    ship_type : int, optional
        AIS ship-type code.
    voyage_id : str, optional
        Voyage identifier in the workspace.
    origin, destination : str, optional
        Port names of the voyage.
    depart_utc, arrive_utc : Timestamp
        Sailed departure and arrival (tz-aware UTC).
    vessel_profile : str
        Vessel profile used for the alternatives.
    routes : RouteSet
        ``as_sailed`` is the AIS track at its AIS times, ``as_sailed_modelled`` the same track
        re-timed by the vessel model (the reference of the deltas); alternatives for the same
        departure, sailed by the same model.
    findings : list of str
        Plain-language findings from the audit (printed as given).
    provenance : Provenance
    speed_loss : SpeedLossCurve, optional
    generated_utc : Timestamp
        When the audit was computed.
    title : str
    bias : dict
        The vessel model's bias on this voyage, modelled minus AIS: ``time_h``, ``time_pct``,
        ``fuel_t``, ``fuel_pct``, ``co2_t``, ``co2_pct`` (empty without a modelled row).
    calm_water : dict
        The calm-water speed the model sailed at: ``speed_kn``, ``source`` (``ais_low_sea`` or
        ``profile``), ``low_sea_h``, ``low_hs_m``.
    """

    mmsi: int
    depart_utc: pd.Timestamp
    arrive_utc: pd.Timestamp
    routes: RouteSet
    ship_name: str | None = None
    callsign: str | None = None
    ais_destination: str | None = None
    imo: int | None = None
    ship_type: int | None = None
    voyage_id: str | None = None
    origin: str | None = None
    destination: str | None = None
    vessel_profile: str = ""
    findings: list = field(default_factory=list)
    provenance: Provenance = field(default_factory=Provenance)
    speed_loss: SpeedLossCurve | None = None
    generated_utc: pd.Timestamp = field(default_factory=lambda: pd.Timestamp.now(tz="UTC"))
    title: str = "stormlane voyage audit"
    bias: dict = field(default_factory=dict)
    calm_water: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("depart_utc", "arrive_utc", "generated_utc"):
            setattr(self, name, _utc(getattr(self, name), f"VoyageAudit.{name}"))
        if not isinstance(self.routes, RouteSet):
            raise ReportError("VoyageAudit.routes must be a RouteSet")


# The JSON round trip lives in dashboards.model_json (compact: arrays and frames as compressed
# binary columns); imported here so that ``from dashboards.model import report_to_json`` works.
from dashboards.model_json import report_from_json, report_to_json  # noqa: E402

__all__ = ["ROUTE_ROLES", "REFERENCE_ROLES", "ROLE_LABELS", "METRIC_COLUMNS", "SEED_COLUMNS", "WeatherSnapshot", "SpeedLossCurve",
           "Provenance", "RouteSet", "LaneDeparture", "LaneLine", "NightlyReport", "VoyageAudit", "metric_delta",
           "software_versions", "report_to_json", "report_from_json"]
