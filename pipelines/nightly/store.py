"""Nightly stage 7, storage glue (I/O): the ``nightly_runs`` row, the write of a night's rows, and
the summary the CLI prints and returns as JSON."""

from __future__ import annotations

import json

import pandas as pd

from pipelines.nightly.night import Night, NightResult


def _window_json(w: dict) -> dict:
    """The night's window in the summary (``--json``): ``start_utc``, ``end_utc``, ``hours``
    (start to end), ``step_h`` (None for planned voyages), ``departures``, ``planned``."""
    return {"start_utc": w["start_utc"].isoformat(), "end_utc": w["end_utc"].isoformat(),
            "hours": round((w["end_utc"] - w["start_utc"]).total_seconds() / 3600.0, 6), "step_h": w["step_h"],
            "departures": w["departures"], "planned": w["planned"]}


def run_row(night: Night, result: NightResult, started_utc, finished_utc, report: dict | None, timings: dict) -> dict:
    """The ``nightly_runs`` row of a night."""
    ds = night.weather_ds
    times = pd.DatetimeIndex(ds["time_utc"].values).tz_localize("UTC")
    files = night.weather_meta.get("files") or night.weather_meta.get("source_files") or []
    params = night.params.model_dump()
    summary = {**result.counts, "run_id": night.run_id, "timings_s": timings, "report": (report or {}).get("report")}
    w = night.window()
    return {
        "run_id": night.run_id, "now_utc": night.now_utc, "window_start_utc": w["start_utc"],
        "window_end_utc": w["end_utc"], "step_h": w["step_h"],
        "n_departure_times": w["departures"], "lanes_checked": result.counts["lanes_checked"],
        "departures_checked": result.counts["departures_checked"], "n_adverse": result.counts["adverse"],
        "n_failed": result.counts["failed"], "n_reroutes": result.counts["reroutes"], "weather_source": night.weather_source,
        "weather_product": str(night.weather_meta.get("product") or ds.attrs.get("product", "")),
        "weather_files": json.dumps([str(f) for f in (files if isinstance(files, (list, tuple)) else [files])]),
        "weather_start_utc": times[0], "weather_end_utc": times[-1], "weather_digest": night.weather_digest,
        "lanes_digest": night.lanes_digest, "params_json": json.dumps(params, sort_keys=True, default=str),
        "started_utc": started_utc, "finished_utc": finished_utc, "report_path": (report or {}).get("report"),
        "summary_json": json.dumps(summary, default=str),
    }


def store_night(db, night: Night, result: NightResult, run: dict) -> dict:
    """I/O step: write the night's rows (replacing the same run id) and return the row counts."""
    from pipelines.storage import open_workspace
    from pipelines.storage.nightly import count_rows, write_run

    with open_workspace(db) as ws:
        write_run(ws, run, result.departures, result.routes, result.events)
        return count_rows(ws)


def summary_of(night: Night, result: NightResult, report: dict | None, timings: dict, top: int = 10) -> dict:
    """The CLI's JSON object (``reference`` names what every delta is measured against).

    Its top level holds the report overview's figures (:func:`pipelines.nightly.rank.overview_of`:
    the same dict the page shows, ``summary`` in ``report.json``): counts, the sums over the
    proposed reroutes and the top cases with the ranking key.
    """
    from pipelines.nightly.rank import overview_of

    rep = report or {}
    return {
        "run_id": night.run_id,
        "now_utc": night.now_utc.isoformat(),
        "window": _window_json(night.window()),
        **overview_of(result, top=top),
        "weather": {"source": night.weather_source, "product": str(night.weather_meta.get("product", "")),
                    "digest": night.weather_digest[:16], "end_utc": _last_time(night.weather_ds)},
        "report": rep.get("report"),
        "model": rep.get("model"),
        "exports": rep.get("exports", 0),
        "exports_zip": rep.get("exports_zip"),
        "out": str(night.out),
        "speed_loss_model": night.params.speed_loss,
        "learned_limits": night.learned_limits,
        "timings_s": timings,
        "reference": "lane: the lane as planned, sailed by the same vessel model (the lane's typical AIS speed, at most the vessel's maximum-power speed, minus the speed "
                     "loss) from the same departure in the same weather; every delta is proposed minus it",
    }


def _last_time(ds) -> str | None:
    """The weather's last time (ISO, UTC): a centroid timed after it was not screened."""
    if ds is None or "time_utc" not in ds.coords or ds.sizes.get("time_utc", 0) == 0:
        return None
    return pd.Timestamp(ds["time_utc"].values[-1]).tz_localize("UTC").isoformat()


def beyond_weather_line(summary: dict) -> str | None:
    """What the night says (terminal warning, the demo's note) when lane-departures of ``summary``
    (:func:`summary_of`) sail on after the weather's last time, or None: the report's words
    (:func:`dashboards.nightly_page.beyond_weather_text`)."""
    n = int(summary.get("beyond_weather") or 0)
    if not n:
        return None
    from dashboards.nightly_page import beyond_weather_text

    end = (summary.get("weather") or {}).get("end_utc")
    end = f"{pd.Timestamp(end):%Y-%m-%dT%H:%MZ}" if end else "?"
    return beyond_weather_text(n, int(summary.get("beyond_weather_ok") or 0), end)
