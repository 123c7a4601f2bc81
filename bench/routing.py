"""Benchmark: the routing engine against SIMROUTE's R6 case and a MEDSEA-size case.

Prints, in one run:

1. R6 (Palma -> Barcelona, Storm Gloria) from the two CMEMS NetCDF files to both routes:
   cold (a fresh process: imports, numba cache load, land mask) and warm (same process again);
   plus a cold start with an empty numba cache (compilation included);
2. both A* searches alone on the R6 mesh (warm);
3. edges scanned per second of the compiled core (Dijkstra over the MEDSEA-size mesh);
4. a MEDSEA-size case: 1/24 deg mesh over 6 W - 36 E, 30 - 46 N (387 k nodes), Gibraltar ->
   Port Said through a generated storm on a CMEMS-GLOBAL-like grid (1/12 deg, 3-hourly), then
   the same in safe mode (hard limits: Hs <= 6 m, wind);
5. R6 in safe mode (``safety="hard"``, container feeder, default operator profile + IMO rules):
   NetCDF to all routes, warm, with the time of the safety flags and of the safe search.

Baselines (issue 5, SIMROUTE's own code on these machines): R6 takes about 18.7 s, of which
14.1 s interpolate the waves onto its mesh and 4.35 s are its two A* searches. Targets: both
searches < 45 ms warm, R6 from NetCDF to both routes < 0.5 s warm, core >= 30 M edges/s,
MEDSEA-size route < 2 s; R6 in safe mode still < 0.5 s warm.

Run: ``.venv/bin/python bench/routing.py`` (needs ../shared/data or STORMLANE_SHARED_DATA for
R6). The machine has 2 cores shared with other jobs: figures are noisy.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
# this file is bench/routing.py: keep its folder off sys.path so that `import routing` is the package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.append(str(ROOT))  # fallback when the project is not installed

SHARED = Path(os.environ.get("STORMLANE_SHARED_DATA", ROOT.parent / "shared" / "data"))
if not SHARED.is_dir():
    SHARED = Path("/work/shared/data")
R6_FILES = [SHARED / "weather/simroute_cmems_medsea_wav" / f"Waves_MEDSEA_2020012{d}.nc" for d in (0, 1)]
SIMROUTE = {"total_s": 18.7, "interp_s": 14.1, "astar_s": 4.35}
TARGETS = {"searches_ms": 45.0, "r6_warm_s": 0.5, "core_medges_s": 30.0, "medsea_s": 2.0}

R6_SNIPPET = r"""
import json, sys, time
t0 = time.perf_counter()
sys.path.append({root!r})
import pandas as pd
from pipelines.config import load_vessel
from pipelines.routing_weather import load_weather
from routing.astar import ShipModel
from routing.planner import RouteRequest, plan_routes
def run():
    t = time.perf_counter()
    field, _ = load_weather({files!r})
    read.append(time.perf_counter() - t)
    v = load_vessel({vessel!r})
    req = RouteRequest((39.225, 2.900), (41.500, 2.775), pd.Timestamp("2020-01-20T09:00Z"), ShipModel.from_vessel(v, "bowditch"),
                       spacing_deg=0.025, bbox=(2.0, 38.95, 5.1, 41.65), edges=48, vessel_name=v.name)
    if {safety!r} == "none":
        return plan_routes(req, field)
    from pipelines.config import load_operator_profile
    return plan_routes(req, field, safety={safety!r}, vessel=v, limits=load_operator_profile("default"))
read = []
plan = run()
cold = time.perf_counter() - t0
warm = []
warm_cpu = []
for _ in range({n_warm}):
    t = time.perf_counter(); c = time.process_time(); plan = run(); warm.append(time.perf_counter() - t); warm_cpu.append(time.process_time() - c)
r = plan.routes
print(json.dumps({{"cold_s": cold, "cold_cpu_s": time.process_time(), "warm_s": warm, "warm_cpu_s": warm_cpu, "read_s": read[-1], "stats": plan.stats,
    "routes": {{k: [v.time_h, v.dist_nmi, v.max_hs_m] for k, v in r.items()}},
    "over": {{k: v.properties.get("hours_over_limits") for k, v in r.items()}}}}))
"""


def run_r6_subprocess(n_warm: int, numba_cache_dir: str | None = None, safety: str = "none", vessel: str = "simroute-r6") -> dict:
    env = dict(os.environ)
    if numba_cache_dir:
        env["NUMBA_CACHE_DIR"] = numba_cache_dir
    code = R6_SNIPPET.format(root=str(ROOT), files=[str(f) for f in R6_FILES], n_warm=n_warm, safety=safety, vessel=vessel)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True, cwd=tempfile.gettempdir())
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_r6() -> dict | None:
    if not all(f.exists() for f in R6_FILES):
        print(f"R6: skipped, {R6_FILES[0].parent} not found")
        return None
    res = run_r6_subprocess(n_warm=5)
    with tempfile.TemporaryDirectory() as empty_cache:
        compile_res = run_r6_subprocess(n_warm=0, numba_cache_dir=empty_cache)
    warm = float(np.median(res["warm_s"]))
    warm_cpu = float(np.median(res["warm_cpu_s"]))
    cold_cpu = res["cold_cpu_s"] - sum(res["warm_cpu_s"])
    t = res["stats"]["timings"]
    r = res["routes"]
    print("== R6 Palma -> Barcelona (Storm Gloria), 1.5 nmi mesh 125 x 109, 48 edges, Bowditch, 16.1 kn")
    print(f"  from NetCDF to both routes: cold {res['cold_s']:.2f} s wall / {cold_cpu:.2f} s CPU (new process: imports, "
          f"numba cache on disk, land mask load), cold with compilation {compile_res['cold_s']:.1f} s wall, "
          f"warm {warm * 1000:.0f} ms wall / {warm_cpu * 1000:.0f} ms CPU (median of {len(res['warm_s'])})  "
          f"target < {TARGETS['r6_warm_s']} s; SIMROUTE {SIMROUTE['total_s']} s")  # fmt: skip
    print(f"  last warm run: read NetCDF {res['read_s'] * 1000:.0f} ms, land mask {t['land_mask_s'] * 1000:.0f} ms, weather to mesh {t['weather_to_mesh_s'] * 1000:.0f} ms "
          f"(SIMROUTE interpolation {SIMROUTE['interp_s']} s), mesh {t['mesh_s'] * 1000:.0f} ms, time search "
          f"{t['search_time_s'] * 1000:.1f} ms, distance search {t['search_distance_s'] * 1000:.1f} ms, "
          f"re-time + smooth {t['retime_smooth_s'] * 1000:.1f} ms")  # fmt: skip
    sim = {"optimal": (14.97, 161.56), "min_distance": (16.93, 151.38), "min_distance_calm": (9.40, 151.38)}
    k = (10800.0 / np.pi) / 3440.069528
    print("  route              ours time_h / dist_nmi (1 nmi = 1')   SIMROUTE           diff time")
    for name in ("optimal", "optimal_smoothed", "min_distance", "min_distance_calm"):
        th, dn, hs = r[name]
        ref = sim.get(name, sim["optimal"] if name == "optimal_smoothed" else None)
        print(f"  {name:<19}{th:7.2f} h / {dn * k:7.2f} nmi  max Hs {hs:4.2f} m   {ref[0]:6.2f} h / {ref[1]:6.2f}   {100 * (th / ref[0] - 1):+5.1f} %")
    return {"warm_s": warm, "warm_cpu_s": warm_cpu, "cold_s": res["cold_s"], "compile_cold_s": compile_res["cold_s"]}


def bench_r6_searches() -> float | None:
    if not all(f.exists() for f in R6_FILES):
        return None
    from pipelines.config import load_vessel
    from pipelines.routing_weather import load_weather
    from routing.astar import ShipModel, WeatherArrays, search
    from routing.planner import RouteRequest, plan_routes

    field, _ = load_weather([str(f) for f in R6_FILES])
    v = load_vessel("simroute-r6")
    req = RouteRequest((39.225, 2.900), (41.500, 2.775), pd.Timestamp("2020-01-20T09:00Z"), ShipModel.from_vessel(v, "bowditch"),
                       spacing_deg=0.025, bbox=(2.0, 38.95, 5.1, 41.65), edges=48)  # fmt: skip
    plan = plan_routes(req, field)
    mesh = plan.mesh
    mw = field.on_mesh(mesh.grid.lat_deg, mesh.grid.lon_deg, req.depart_utc.value, node_sea=mesh.sea)
    wx = WeatherArrays.build(mesh, mw)
    s, g = plan.stats["start_node"], plan.stats["goal_node"]
    t0 = wx.rel_h(req.depart_utc.value)
    runs, cpus = [], []
    for _ in range(20):
        t = time.perf_counter()
        c = time.process_time()
        a = search(mesh, wx, req.ship, s, g, t_start_h=t0)
        b = search(mesh, wx, req.ship, s, g, cost="distance")
        runs.append(time.perf_counter() - t)
        cpus.append(time.process_time() - c)
    best, med = min(runs), float(np.median(runs))
    print(f"  both A* searches (warm, 20 runs): median {med * 1000:.1f} ms wall / {np.median(cpus) * 1000:.1f} ms CPU, "
          f"best {best * 1000:.1f} ms wall "
          f"(time: {a.expanded:,} nodes expanded / {a.scanned:,} edges; distance: {b.expanded:,} / {b.scanned:,})  "
          f"target < {TARGETS['searches_ms']:.0f} ms; SIMROUTE {SIMROUTE['astar_s']} s")  # fmt: skip
    return med


# --------------------------------------------------------------------------- MEDSEA-size case

MED_BBOX = (-6.0, 30.0, 36.0, 46.0)
GIBRALTAR = (35.95, -5.55)
PORT_SAID = (31.40, 32.35)
MED_T0 = pd.Timestamp("2025-01-30T00:00Z")


def make_storm_field():
    """CMEMS-GLOBAL-like waves (1/12 deg, 3-hourly, 7 days): swell plus a storm moving east
    along the Algerian basin into the Strait of Sicily, where it meets the ship about 30 h after
    departure; Hs up to 9 m, waves from the west-north-west."""
    from routing.field import WeatherField

    lat = np.round(np.arange(29.5, 46.5001, 1 / 12), 6)
    lon = np.round(np.arange(-6.5, 36.5001, 1 / 12), 6)
    times = pd.date_range(MED_T0, periods=57, freq="3h")
    lon2, lat2 = np.meshgrid(lon, lat)
    h = (np.arange(times.size) * 3.0)[:, None, None]
    xc = 2.0 + 0.15 * h  # storm centre [deg E]: 2 E at t0, 6.5 E after 30 h, 20 E after 5 days
    yc = 38.8 - 0.02 * h
    r2 = ((lon2 - xc) / 3.0) ** 2 + ((lat2 - yc) / 1.6) ** 2
    hs = (0.8 + 8.2 * np.exp(-r2)).astype(np.float32)
    # waves from the north-west around the storm (mistral-like), turning with the position
    wave_from = ((300.0 + 20.0 * np.tanh((lon2 - xc) / 3.0)) % 360.0).astype(np.float32)
    return WeatherField(times.asi8, lat, lon, {"hs_m": hs, "wave_from_deg": np.broadcast_to(wave_from, hs.shape).copy()})


def bench_medsea() -> dict:
    from pipelines.config import load_vessel
    from routing.astar import ShipModel, WeatherArrays, search
    from routing.planner import RouteRequest, plan_routes

    t = time.perf_counter()
    field = make_storm_field()
    gen_s = time.perf_counter() - t
    v = load_vessel("container-large")
    ship = ShipModel.from_vessel(v, "bowditch")
    req = RouteRequest(GIBRALTAR, PORT_SAID, MED_T0 + pd.Timedelta("6h"), ship, spacing_deg=1 / 24, bbox=MED_BBOX, edges=48,
                       vessel_name=v.name)  # fmt: skip
    plan = plan_routes(req, field)  # first call: land mask import, compilation or cache load
    runs, cpus = [], []
    for _ in range(3):
        t = time.perf_counter()
        c = time.process_time()
        plan = plan_routes(req, field)
        runs.append(time.perf_counter() - t)
        cpus.append(time.process_time() - c)
    total = float(np.median(runs))
    total_cpu = float(np.median(cpus))
    tm = plan.stats["timings"]
    g = plan.mesh.grid
    print(f"== MEDSEA-size: 1/24 deg mesh {g.ny} x {g.nx} = {g.n_nodes:,} nodes ({plan.mesh.n_sea:,} sea), 48 edges, "
          f"Gibraltar -> Port Said, {v.name} {ship.speed_kn:g} kn, Bowditch, generated storm on a 1/12 deg 3-hourly grid "
          f"({field.shape[0]} times; generated in {gen_s:.2f} s)")  # fmt: skip
    print(f"  field to both routes (warm, median of 3): {total:.2f} s wall / {total_cpu:.2f} s CPU  target < {TARGETS['medsea_s']} s")
    print(f"  land mask {tm['land_mask_s']:.2f} s, weather to mesh {tm['weather_to_mesh_s']:.2f} s, mesh + edge masks "
          f"{tm['mesh_s']:.2f} s, time search {tm['search_time_s']:.3f} s ({plan.stats['expanded_time']:,} nodes, "
          f"{plan.stats['scanned_time']:,} edges), distance search {tm['search_distance_s']:.3f} s, re-time + smooth "
          f"{tm['retime_smooth_s']:.3f} s")  # fmt: skip
    for name, r in plan.routes.items():
        print(f"  {name:<19}{r.time_h:8.2f} h {r.dist_nmi:9.1f} nmi  max Hs {r.max_hs_m:4.1f} m  {r.n_waypoints} waypoints")
    print(f"  great circle {plan.great_circle_nmi:.1f} nmi (crosses land)")

    # core throughput: Dijkstra (no heuristic) over the whole sea in time mode
    mesh = plan.mesh
    mw = field.on_mesh(g.lat_deg, g.lon_deg, req.depart_utc.value, node_sea=mesh.sea)
    wx = WeatherArrays.build(mesh, mw)
    s, goal = plan.stats["start_node"], plan.stats["goal_node"]
    rates, cpu_rates = [], []
    for _ in range(3):
        c = time.process_time()
        res = search(mesh, wx, ship, s, goal, t_start_h=wx.rel_h(req.depart_utc.value), heuristic=False)
        cpu = time.process_time() - c
        rates.append(res.scanned / res.seconds / 1e6)
        cpu_rates.append(res.scanned / cpu / 1e6)
    dist_rates = []
    for _ in range(3):
        res_d = search(mesh, wx, ship, s, goal, cost="distance", heuristic=False)
        dist_rates.append(res_d.scanned / res_d.seconds / 1e6)
    print(f"== core throughput (Dijkstra over the MEDSEA mesh): time-dependent cost {max(rates):.1f} M edges/s wall, "
          f"{max(cpu_rates):.1f} M edges/s per CPU second "
          f"({res.scanned:,} edges scanned, {res.expanded:,} nodes, {res.seconds:.3f} s), distance cost "
          f"{max(dist_rates):.1f} M edges/s  target >= {TARGETS['core_medges_s']:.0f} M edges/s")  # fmt: skip
    # safe mode on the same case: Hs <= 6 m and wind (profile hs-wind-only, container-large), hard constraints
    from pipelines.config import load_operator_profile

    lim = load_operator_profile("hs-wind-only")
    for _ in range(2):  # the first call loads the compiled safe kernels
        t = time.perf_counter()
        c = time.process_time()
        sp = plan_routes(req, field, safety="hard", vessel=v, limits=lim)
        safe_s, safe_cpu = time.perf_counter() - t, time.process_time() - c
    st = sp.stats["timings"]
    a, b = sp.routes["optimal_smoothed"], sp.routes["safe_optimal_smoothed"]
    print(f"== MEDSEA-size safe mode (hs-wind-only: Hs <= 6 m, wind <= 22.6 m/s; safety='hard', ran {sp.stats['safety']['mode']}): "
          f"{safe_s:.2f} s wall / {safe_cpu:.2f} s CPU (flags {st['safety_flags_s']:.2f} s for {sp.stats['safety']['flag_slices']} "
          f"slices, safe search {st['search_safe_s']:.2f} s)")  # fmt: skip
    for r in (a, b):
        print(f"  {r.name:<23}{r.time_h:8.2f} h {r.dist_nmi:8.1f} nmi  max Hs {r.max_hs_m:4.1f} m  "
              f"{r.properties['hours_over_limits']:5.1f} h over the limits")
    return {"medsea_s": total, "medsea_cpu_s": total_cpu, "core_medges_s": max(rates), "core_cpu_medges_s": max(cpu_rates),
            "medsea_safe_s": safe_s}


def bench_r6_safe() -> dict | None:
    """R6 with the safety-constrained search (container feeder, default profile), NetCDF to all routes."""
    if not all(f.exists() for f in R6_FILES):
        return None
    res = run_r6_subprocess(n_warm=5, safety="hard", vessel="container-feeder")
    warm = float(np.median(res["warm_s"]))
    warm_cpu = float(np.median(res["warm_cpu_s"]))
    t = res["stats"]["timings"]
    sf = res["stats"]["safety"]
    print("== R6 safe mode: container feeder 17 kn, default operator profile (Lpp < 200 m: Hs <= 4.5 m, no beam seas at "
          "Hs >= 2.5 m) + IMO rules, 16 heading sectors, safety='hard'")
    print(f"  from NetCDF to all six routes, warm: {warm * 1000:.0f} ms wall / {warm_cpu * 1000:.0f} ms CPU (median of "
          f"{len(res['warm_s'])})  target < {TARGETS['r6_warm_s']} s")
    print(f"  last warm run: safety flags {t['safety_flags_s'] * 1000:.0f} ms ({sf['flag_slices']} of {sf['weather_slices']} "
          f"hourly slices x all sea nodes), safe search(es) {t['search_safe_s'] * 1000:.0f} ms "
          f"({res['stats']['expanded_safe']:,} nodes), smoothing + hours over the limits {t['safety_routes_s'] * 1000:.0f} ms; "
          f"plain part {(t['total_s'] - t['safety_flags_s'] - t['search_safe_s'] - t['safety_routes_s']) * 1000:.0f} ms")  # fmt: skip
    print(f"  ran {sf['mode']}" + (" (hard found no route within the limits: fell back to soft, 10 h per hour over them)" if sf["fallback"] else ""))
    for name in ("optimal_smoothed", "min_distance", "safe_optimal_smoothed"):
        th, dn, hs = res["routes"][name]
        print(f"  {name:<23}{th:7.2f} h {dn:8.2f} nmi  max Hs {hs:4.2f} m  {res['over'][name]:5.2f} h over the limits")
    return {"warm_s": warm, "warm_cpu_s": warm_cpu, "flags_s": t["safety_flags_s"], "search_safe_s": t["search_safe_s"]}


def main() -> None:
    print(f"stormlane routing benchmark ({os.cpu_count()} cores, shared; timings are noisy)")
    r6 = bench_r6()
    searches = bench_r6_searches()
    med = bench_medsea()
    safe = bench_r6_safe()
    print("== summary (ours vs target)")
    if r6:
        print(f"  R6 NetCDF -> both routes, warm: {r6['warm_s'] * 1000:.0f} ms wall ({r6['warm_cpu_s'] * 1000:.0f} ms CPU) vs < {TARGETS['r6_warm_s'] * 1000:.0f} ms "
              f"(SIMROUTE {SIMROUTE['total_s']} s, {SIMROUTE['total_s'] / r6['warm_s']:.0f}x faster)")  # fmt: skip
    if searches:
        print(f"  R6 both searches, warm: {searches * 1000:.1f} ms vs < {TARGETS['searches_ms']:.0f} ms "
              f"(SIMROUTE {SIMROUTE['astar_s']} s, {SIMROUTE['astar_s'] / searches:.0f}x faster)")  # fmt: skip
    print(f"  core: {med['core_medges_s']:.1f} M edges/s wall ({med['core_cpu_medges_s']:.1f} per CPU second) vs >= {TARGETS['core_medges_s']:.0f}")
    print(f"  MEDSEA-size route: {med['medsea_s']:.2f} s wall ({med['medsea_cpu_s']:.2f} s CPU) vs < {TARGETS['medsea_s']:.0f} s")
    if safe:
        print(f"  R6 safe mode NetCDF -> all routes, warm: {safe['warm_s'] * 1000:.0f} ms wall ({safe['warm_cpu_s'] * 1000:.0f} ms CPU) "
              f"vs < {TARGETS['r6_warm_s'] * 1000:.0f} ms (flags {safe['flags_s'] * 1000:.0f} ms, safe search {safe['search_safe_s'] * 1000:.0f} ms)")
    print("  (CPU seconds are what this process used; on the shared 2-core machine wall time includes waiting for a core)")


if __name__ == "__main__":
    main()
