"""The nightly reroute: every lane (or planned voyage) x every departure of the forecast window.

What an operations team runs every night, unattended (issue 7):

1. **Inputs** (:func:`load_paths`, I/O): the workspace's lanes and their centroid sequences, the
   port names, and a vessel profile per lane (from the AIS ship types of the voyages that formed
   the lane, :func:`pipelines.vessels.vessel_for_ship`, or ``--vessel``); or planned voyages
   from a CSV (:func:`read_planned_voyages`).
2. **Weather** (:func:`read_weather_source`, I/O; :func:`fetch_weather`, network, retried): local
   CMEMS/ERA5/GRIB files (:func:`weather.io.read_local`), the real download clients when
   credentials are configured (cached by :mod:`weather.io.cache`), or the grid already loaded in
   the workspace. :func:`prepare_night` (pure) fails early with a clear message when the weather
   does not cover the departures, cuts the weather to the run's window and area, and derives the
   run id from the inputs.
3. **Screen** (:func:`screen_departures`, pure): the lanes x departures x weather join in DuckDB
   (:func:`pipelines.storage.weather.join_points_weather`: ETAs from the typical speeds, the grid
   cell by index arithmetic, the nearest weather time by ``ASOF JOIN``, as the seed paper
   ``ais_weather_routing_cargo_loss`` §3.2 does), then the vessel's thresholds
   (:func:`thresholds.safety.assess`: operator limits + IMO MSC.1/Circ.1228) at every centroid,
   with the course to the next centroid and the centroid's typical speed. A lane-departure is
   **adverse** when any rule fires at any centroid; the reasons name the rule, the value against
   its limit, where and when.
4. **Reroute** (:func:`reroute_lane`, pure, one task per lane, fanned out by the task runner):
   for each adverse departure of the lane, the cargo-safe deviation
   (:func:`routing.deviate.deviate_lane`), the time-optimal and minimum-distance A* routes and
   the safe time-optimal route under the vessel's limits (:func:`routing.planner.plan_routes`
   with ``safety="hard"``, falling back to ``soft``), the lane as planned (its centroid path, legs
   over land repaired, sailed at the lane's typical AIS speed minus the speed loss: the same vessel
   model as the A* routes, :func:`routing.compare.lane_departure`), and the evaluation of the lane
   and of the alternatives in the same weather (:func:`routing.evaluate.evaluate_route`,
   :func:`routing.audit.propose`). A failure of one lane-departure (unreachable destination, a
   lane outside the weather ...) marks it ``failed`` with the message; the rest completes.
5. **Rank** (:func:`assemble`, pure): by risk avoided (hours over an operator limit or in an IMO
   situation, lane as planned minus proposed), then IMO events avoided, then cost (extra sailing
   time, extra fuel).
6. **Store** (:func:`store_night`, I/O) in the ``nightly_*`` tables keyed by run id (a rerun with
   the same inputs replaces the same rows), and **report** (:func:`write_report`, I/O): the
   self-contained HTML report, its model as JSON, and GeoJSON/GPX/RTZ exports per adverse
   lane-departure under ``--out``.

The Prefect flow (:func:`nightly_reroute`, built lazily) only wires these functions; the
plain entry point :func:`run_night` runs the same steps without Prefect.

The package: one module per stage (:mod:`~pipelines.nightly.paths`, :mod:`~pipelines.nightly.weather`,
:mod:`~pipelines.nightly.plan`, :mod:`~pipelines.nightly.screen`, :mod:`~pipelines.nightly.reroute`,
:mod:`~pipelines.nightly.rank`, :mod:`~pipelines.nightly.report`, :mod:`~pipelines.nightly.store`), the
console filters of the CLI (:mod:`~pipelines.nightly.console`), the shared types (the night, its
parameters, its errors: :mod:`~pipelines.nightly.night`), the wiring (:mod:`~pipelines.nightly.flow`)
and the demo's steps (:mod:`~pipelines.nightly.demo`). Stages import the types, never the flow
(import-linter contract). This module re-exports the names callers use.
"""

from __future__ import annotations

from pipelines.nightly.console import (RUN_LOGGERS, _future_result, _results_with_progress, is_user_error, prefect_console_handlers,
                                       reroute_progress, user_errors_one_line)
from pipelines.nightly.demo import demo_report_step, demo_step
from pipelines.nightly.flow import _finish, _flow, _retry_fetch, flow_with_runner, run_night
from pipelines.nightly.night import (DEFAULT_STEP_H, DEFAULT_WINDOW_H, FETCH_RETRY_DELAYS_S, IO_RETRY_DELAYS_S, REFERENCE, ROLES,
                                     VOLATILE_PROPERTIES, WEATHER_PAD_DEG, LaneJob, Night, NightlyError, NightlyParams,
                                     NightlyWeatherError, NightPath, NightResult, parse_utc)
from pipelines.nightly.paths import VOYAGE_COLUMNS, load_paths, nothing_to_sail, preflight, read_planned_voyages
from pipelines.nightly.plan import default_out, departure_times, lanes_digest, prepare_night, resolve_now, weather_digest
from pipelines.nightly.rank import assemble
from pipelines.nightly.report import write_report
from pipelines.nightly.reroute import lane_jobs, lane_speed_vessel, reroute_lane
from pipelines.nightly.screen import screen_departures
from pipelines.nightly.store import run_row, store_night, summary_of
from pipelines.nightly.weather import (choose_weather_source, fetch_requests, fetch_weather, paths_bbox, read_weather_source,
                                       subset_weather, weather_credentials_configured, weather_span_needed)
from pipelines.runners import make_task_runner
from pipelines.vessels import DEFAULT_VESSEL, lane_vessel_profiles

__all__ = [
    "DEFAULT_STEP_H", "DEFAULT_VESSEL", "DEFAULT_WINDOW_H", "FETCH_RETRY_DELAYS_S", "IO_RETRY_DELAYS_S", "REFERENCE", "ROLES",
    "RUN_LOGGERS", "VOLATILE_PROPERTIES", "VOYAGE_COLUMNS", "WEATHER_PAD_DEG", "LaneJob", "Night", "NightPath", "NightResult",
    "NightlyError", "NightlyParams", "NightlyWeatherError", "_finish", "_flow", "_future_result", "_results_with_progress",
    "_retry_fetch", "assemble", "choose_weather_source", "default_out", "demo_report_step", "demo_step", "departure_times",
    "fetch_requests", "fetch_weather", "flow_with_runner", "is_user_error", "lane_jobs", "lane_speed_vessel",
    "lane_vessel_profiles", "lanes_digest", "load_paths", "make_task_runner", "nothing_to_sail", "parse_utc", "paths_bbox",
    "prefect_console_handlers", "preflight", "prepare_night", "read_planned_voyages", "read_weather_source", "reroute_lane",
    "reroute_progress", "resolve_now", "run_night", "run_row", "screen_departures", "store_night", "subset_weather",
    "summary_of", "user_errors_one_line", "weather_credentials_configured", "weather_digest", "weather_span_needed",
    "write_report",
]


def __getattr__(name: str):
    if name == "nightly_reroute":
        return _flow()
    raise AttributeError(name)
