"""Fuel savings at the same arrival over the demo month (issue 20): every lane x departure.

Not a timing: the distribution VISIR-2 reports for its least-CO2 routes (Mannarini et al., GMD 17,
2024: savings against the least-distance route, share of cases saving at least 2 %), here for the
least-fuel route (speed setting per leg, :mod:`routing.fuel`) against the fair reference of each
case: the minimum-distance route of the same mesh at the one constant setting that arrives when
the least-fuel route does (:func:`routing.fuel.same_arrival_reference`), same vessel model, same
weather, same departure. The deadline of each case is its own time-optimal route's arrival at the
lane's typical speed (the default of ``stormlane route --objective fuel``), so no case gains
anything from arriving later.

The world (cached, untimed): the demo's lanes from its 30 days of AIS (``tests/nightly_world.py``)
and the demo's weather for the whole month (:func:`weather.scenario.generate_weather`, written and
read back through the CMEMS/ERA5 file schemas). Each lane sails from its first to its last centroid
with its most common vessel profile at the lane's typical AIS speed (as the nightly run sails it),
departing every :data:`STEP_H` hours from 2025-01-01T00Z while its time-optimal route ends within
the weather; each lane's departures share one mesh (:func:`routing.planner_window.plan_window`).

Run: ``python -m bench --only fuel_savings`` (figures in the section's notes) or
``python bench/fuel_savings.py`` (printed only).
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: `import lanes` must find the package, not bench/lanes.py
    import sys
    from pathlib import Path

    _here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _here]
    sys.path.insert(0, str(_here.parent))

import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from bench._harness import ROOT, source_stamp

#: Hours between departures, and the month's first departure.
STEP_H = 24.0
MONTH_START = "2025-01-01T00:00Z"
#: Share of cases saving at least this much (VISIR-2's threshold). [%]
SAVING_THRESHOLD_PCT = 2.0


def world(cache: Path) -> dict:
    """The demo's lanes workspace and the month's weather files (built once per source stamp)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from nightly_world import build_world
    from weather.io.scenario_files import write_scenario_weather
    from weather.scenario import generate_weather

    cache = Path(cache)
    if not (cache / "done").exists():
        build_world(cache)
        write_scenario_weather(cache / "month", seed=0, weather=generate_weather(0))
        (cache / "done").write_text("ok")
    return {"db": cache / "ws.duckdb", "weather": cache / "month" / "weather"}


def lane_cases(db, weather_dir, *, max_lanes: int | None = None, max_departures: int | None = None) -> list[dict]:
    """One row per lane x departure: least-fuel and reference fuel, the saving, or the error."""
    from pipelines.config import load_vessel
    from pipelines.nightly.paths import load_paths
    from pipelines.nightly.reroute import lane_speed_vessel
    from pipelines.routing_weather import field_from_dataset
    from routing.astar import ShipModel
    from routing.compare import plan_bbox
    from routing.fuel import FuelSpec
    from routing.least_fuel_role import default_settings
    from routing.planner import RouteRequest
    from routing.planner_window import plan_window
    from weather.io import read_local

    ds, _ = read_local([str(p) for p in sorted(Path(weather_dir).glob("*.nc"))])
    field_ = field_from_dataset(ds)
    end = pd.Timestamp(ds["time_utc"].values[-1]).tz_localize("UTC")
    out = []
    paths = [p for p in load_paths(db) if len(p.centroids) >= 2][:max_lanes]
    for p in paths:
        c = p.centroids.sort_values("seq")
        lat, lon = c["lat_deg"].to_numpy(float), c["lon_deg"].to_numpy(float)
        vessel = lane_speed_vessel(load_vessel(p.vessel_profile), c)
        engine, settings, capped, _ = default_settings(vessel)
        ship = ShipModel.from_vessel(capped, "bowditch")
        last = end - pd.Timedelta(hours=1.5 * p.hours + 6.0)  # its routes end inside the weather
        times = list(pd.date_range(MONTH_START, last, freq=f"{STEP_H:g}h"))[:max_departures]
        if not times:
            continue
        start, goal = (float(lat[0]), float(lon[0])), (float(lat[-1]), float(lon[-1]))
        req = RouteRequest(start, goal, times[0], ship, vessel_name=vessel.name, bbox=plan_bbox(start, goal, lat, lon, field_))
        spec = FuelSpec(settings, engine)
        try:
            res = plan_window(req, field_, times, objective="fuel", fuel=spec)
        except Exception as err:  # noqa: BLE001 - a lane the planner refuses is counted, not dropped
            out += [{"lane": p.path_id, "depart_utc": t.isoformat(), "error": f"{type(err).__name__}: {err}"} for t in times]
            continue
        for r in res["rows"]:
            out.append({"lane": p.path_id, "vessel": vessel.name, "speed_kn": round(capped.speed_kn, 3), **r})
    return out


def distribution(rows: list[dict]) -> dict:
    """Share of cases saving >= 2 %, median, max, quartiles (cases with a same-arrival reference)."""
    s = np.array([r["saving_pct"] for r in rows if r.get("saving_pct") is not None], dtype=float)
    out = {"cases": len(rows), "with_reference": int(s.size), "errors": sum(1 for r in rows if r.get("error")),
           "lanes": len({r["lane"] for r in rows})}
    if s.size:
        out.update(share_ge_2pct=round(float(np.mean(s >= SAVING_THRESHOLD_PCT)) * 100.0, 1), median_pct=round(float(np.median(s)), 2),
                   p25_pct=round(float(np.percentile(s, 25)), 2), p75_pct=round(float(np.percentile(s, 75)), 2),
                   max_pct=round(float(s.max()), 2), min_pct=round(float(s.min()), 2))
    return out


def words(d: dict, seconds: float) -> str:
    if not d.get("with_reference"):
        return f"fuel savings at the same arrival: no case with a reference ({d['cases']} cases, {d['errors']} errors)"
    return (f"fuel savings at the same arrival (least fuel vs minimum distance at the constant setting arriving together), "
            f"{d['lanes']} lanes x departures every {STEP_H:g} h of the demo month = {d['cases']} cases ({d['with_reference']} with "
            f"a reference, {d['errors']} errors): {d['share_ge_2pct']:.1f} % save >= 2 %, median {d['median_pct']:.2f} %, "
            f"quartiles {d['p25_pct']:.2f} / {d['p75_pct']:.2f} %, max {d['max_pct']:.2f} %, min {d['min_pct']:.2f} % "
            f"({seconds:.0f} s)")


def measure(cache: Path, quick: bool = False) -> tuple[dict, list]:
    w = world(cache)
    t = time.perf_counter()
    rows = lane_cases(w["db"], w["weather"], max_lanes=3 if quick else None, max_departures=3 if quick else None)
    d = distribution(rows)
    d["seconds"] = round(time.perf_counter() - t, 1)
    return d, rows


def prepare(cache: str, quick: bool = False) -> dict:
    """The distribution (its own process, untimed): the figures, and ``summary`` the line the harness prints."""
    d, _ = measure(Path(cache), quick=quick)
    import os

    d["summary"] = words(d, d["seconds"]) + f" (load {os.getloadavg()[0]:.1f})"
    return d


def build(cfg):
    """One group without timed sides: its preparation computes the distribution (in bench/results.json under
    the group's ``prepare.info``; printed by the harness)."""
    from bench._harness import Group

    cache = Path(cfg.cache_dir) / f"fuel-savings-world-{source_stamp('lanes', 'scenario', 'weather', 'tests/nightly_world.py')}"
    group = Group("fuel_savings_month", "least fuel vs minimum distance at the same arrival, every lane x departure of the demo month",
                  sides=[], measures=[], prepare="bench.fuel_savings:prepare", prepare_kwargs={"cache": str(cache), "quick": cfg.quick})
    return [group], ["not a timing: the distribution of fuel savings at the same arrival (issue 20), in the group's prepare.info"]


if __name__ == "__main__":
    import json
    import os

    quick = "--quick" in sys.argv
    cache = Path(os.environ.get("STORMLANE_BENCH_CACHE", "/tmp/stormlane-bench-cache")) / "fuel-savings-world"
    d, rows = measure(cache, quick=quick)
    print(words(d, d["seconds"]))
    print(json.dumps(d))
    if "--rows" in sys.argv:
        for r in rows:
            print(json.dumps(r))
