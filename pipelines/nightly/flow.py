"""The nightly flow: wiring only. The plain entry point :func:`run_night` and the Prefect flow
(:func:`_flow`, built lazily: importing Prefect costs seconds) call the stage modules in order."""

from __future__ import annotations

import functools
import time

import pandas as pd

from pipelines.nightly.console import _results_with_progress
from pipelines.nightly.night import (DEFAULT_STEP_H, DEFAULT_WINDOW_H, FETCH_RETRY_DELAYS_S, IO_RETRY_DELAYS_S, Night,
                                     NightlyParams)
from pipelines.nightly.paths import load_paths
from pipelines.nightly.plan import departure_times, prepare_night, resolve_now
from pipelines.nightly.rank import assemble
from pipelines.nightly.report import write_report
from pipelines.nightly.reroute import _collect, lane_jobs, reroute_lane
from pipelines.nightly.screen import screen_departures
from pipelines.nightly.store import run_row, store_night, summary_of
from pipelines.nightly.weather import choose_weather_source, fetch_requests, fetch_weather, read_weather_source, weather_span_needed
from pipelines.runners import make_task_runner, runner_flow
from pipelines.runners import retry_transient as _retry_transient
from pipelines.storage import DEFAULT_DB
from thresholds.errors import StormlaneError

def run_night(**kwargs) -> dict:
    """The night without Prefect (same steps, sequential); keyword arguments of :class:`NightlyParams`."""
    params = NightlyParams(**kwargs)
    timings: dict[str, float] = {}
    started = pd.Timestamp.now(tz="UTC")
    t = time.perf_counter()
    now = resolve_now(params.now)
    paths = load_paths(params.db, voyages=params.voyages, lanes=params.lanes, vessel=params.vessel)
    source = choose_weather_source(params)
    deps = departure_times(now, params.window_h, params.step_h)
    files = list(params.weather)
    if source == "fetch":
        files = [f for req in fetch_requests(paths, deps) for f in fetch_weather(req, params.cache_dir)]
    t0, t1 = weather_span_needed(paths, deps)
    ds, meta = read_weather_source(source, files, params.db, t0, t1)
    night = prepare_night(params, now, paths, ds, meta, source)
    timings["inputs_s"] = time.perf_counter() - t
    t = time.perf_counter()
    screen = screen_departures(night)
    timings["screen_s"] = time.perf_counter() - t
    t = time.perf_counter()
    jobs = lane_jobs(night, screen)
    results = []
    for job in jobs:
        try:
            results.append(reroute_lane(job))
        except Exception as err:  # noqa: BLE001
            results.append(err)
    outcomes = _collect(jobs, results)
    timings["reroute_s"] = time.perf_counter() - t
    return _finish(night, screen, outcomes, started, timings)


def _finish(night: Night, screen, outcomes, started, timings) -> dict:
    t = time.perf_counter()
    result = assemble(night, screen, outcomes)
    timings["rank_s"] = time.perf_counter() - t
    report = None
    if night.params.report:
        t = time.perf_counter()
        report = write_report(night, result, started)
        timings["report_s"] = time.perf_counter() - t
    t = time.perf_counter()
    store_night(night.params.db, night, result, run_row(night, result, started, pd.Timestamp.now(tz="UTC"), report, timings))
    timings["store_s"] = time.perf_counter() - t
    return summary_of(night, result, report, {k: round(v, 3) for k, v in timings.items()})


def _retry_fetch(task_, task_run, state) -> bool:
    """Downloads retry on network and service failures (the clients' own bounded attempts ran
    out: ``FetchError("... download failed after N attempts ...")``), not on missing credentials
    or an unknown product."""
    try:
        state.result()
    except StormlaneError as err:
        return "download failed" in str(err)
    except Exception:  # noqa: BLE001
        return True
    return False


@functools.lru_cache(maxsize=1)
def _flow():
    """Build the Prefect flow lazily (importing Prefect costs seconds; the CLI must stay fast)."""
    from prefect import flow, task
    from prefect.cache_policies import NO_CACHE

    io = {"retries": len(IO_RETRY_DELAYS_S), "retry_delay_seconds": list(IO_RETRY_DELAYS_S), "cache_policy": NO_CACHE,
          "retry_condition_fn": _retry_transient}
    load_task = task(load_paths, name="nightly-load-lanes", **io)
    fetch_task = task(fetch_weather, name="nightly-fetch-weather", retries=len(FETCH_RETRY_DELAYS_S),
                      retry_delay_seconds=list(FETCH_RETRY_DELAYS_S), cache_policy=NO_CACHE, retry_condition_fn=_retry_fetch)
    read_task = task(read_weather_source, name="nightly-read-weather", **io)
    prepare_task = task(prepare_night, name="nightly-prepare", cache_policy=NO_CACHE)
    screen_task = task(screen_departures, name="nightly-screen", cache_policy=NO_CACHE)
    lane_task = task(reroute_lane, name="nightly-reroute-lane", cache_policy=NO_CACHE, task_run_name="reroute-{job.path_id}")
    finish_task = task(_finish, name="nightly-rank-report-store", cache_policy=NO_CACHE)

    def nightly_reroute(db: str = DEFAULT_DB, out: str | None = None, out_root: str | None = None, weather: list[str] | None = None,
                        weather_source: str = "auto", now: str | None = None, window_h: float = DEFAULT_WINDOW_H,
                        step_h: float = DEFAULT_STEP_H, voyages: str | None = None, lanes: list[str] | None = None,
                        vessel: str | None = None, profile: str | None = None, speed_loss: str = "bowditch",
                        safety: str = "hard", max_detail: int = 20, report: bool = True, cache_dir: str | None = None,
                        exports: str = "proposed", least_fuel: bool = True, rank_departures: str = "none") -> dict:
        """Screen every lane x departure of the forecast window, reroute the adverse ones, rank, store, report."""
        p = NightlyParams(db=db, out=out, out_root=out_root, weather=weather or [], weather_source=weather_source, now=now, window_h=window_h,
                          step_h=step_h, voyages=voyages, lanes=lanes, vessel=vessel, profile=profile, speed_loss=speed_loss,
                          safety=safety, max_detail=max_detail, report=report, cache_dir=cache_dir, exports=exports,
                          least_fuel=least_fuel, rank_departures=rank_departures)
        started, timings, t = pd.Timestamp.now(tz="UTC"), {}, time.perf_counter()
        the_now, source = resolve_now(p.now), choose_weather_source(p)
        paths = load_task(p.db, voyages=p.voyages, lanes=p.lanes, vessel=p.vessel)
        deps = departure_times(the_now, p.window_h, p.step_h)
        files = [f for req in fetch_requests(paths, deps) for f in fetch_task(req, p.cache_dir)] if source == "fetch" else p.weather
        ds, meta = read_task(source, files, p.db, *weather_span_needed(paths, deps))
        night = prepare_task(p, the_now, paths, ds, meta, source)
        timings["inputs_s"], t = time.perf_counter() - t, time.perf_counter()
        screen = screen_task(night)
        timings["screen_s"], t = time.perf_counter() - t, time.perf_counter()
        jobs = lane_jobs(night, screen)
        futures = [lane_task.submit(job) for job in jobs]
        outcomes = _collect(jobs, _results_with_progress(futures))
        timings["reroute_s"] = time.perf_counter() - t
        return finish_task(night, screen, outcomes, started, timings)

    # deployments name the flow by its module path: `pipelines.nightly.nightly_reroute` (the package's
    # __getattr__), as before the package split, so deployments served then still resolve
    nightly_reroute.__module__ = "pipelines.nightly"
    return flow(name="nightly-reroute", log_prints=False)(nightly_reroute)


def flow_with_runner(task_runner: str | None = None):
    """The flow with the chosen task runner (:func:`make_task_runner`)."""
    return runner_flow(_flow(), task_runner)

