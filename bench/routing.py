"""Benchmark of the routing engine (issues 5 and 18), every figure beside a baseline of the same run.

Groups (each interleaved A B A B, cold = first run of a fresh process, warm = a later run; see
:mod:`bench._harness`):

1. **R6 as a user runs it** (SIMROUTE's Storm Gloria case, the two CMEMS NetCDF files):
   ``stormlane route ... --json`` as a fresh process (wall from spawn to exit, peak RSS), warm
   = the same command in one process; against SIMROUTE's own end-to-end figure, an *external*
   measurement (2026-11-27, ANCHORS.md; never compared with a warm figure). ``stormlane
   --help`` against a bare interpreter start (``python -c pass``, the floor of any Python CLI).
   Both R6 searches alone (setup: weather and mesh built) against SIMROUTE's two searches
   (external), and against the same searches by a ship that never waits (what the FIFO closure
   of :mod:`routing._kernels.edge` costs). Weather onto the mesh (``WeatherField.on_mesh``) against xarray's own
   ``Dataset.interp`` of the same variables onto the same nodes.
2. **R6 safe mode** (container feeder, default operator profile) against the plain R6 plan of
   the same vessel.
3. **Algorithmic reference**: our time-dependent Dijkstra against a plain-Python one
   (:mod:`bench._td_reference`, same edge model, same optimum) on a small mesh.
4. **MEDSEA size** (1/24 deg over 6 W - 36 E, 30 - 46 N, 387 k nodes, Gibraltar -> Port Said
   through a generated storm): the whole plan against its floor, ``scipy.sparse.csgraph.dijkstra``
   of static distances over the same mesh; safe mode against the plain plan; the core's
   throughput (edges whose cost was computed per second) against the same scipy Dijkstra, and
   against the same core by a ship that never waits.
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: import `bench`, and never this file as `routing`
    import sys
    from pathlib import Path

    _here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _here]
    sys.path.insert(0, str(_here.parent))

import sys
from pathlib import Path

from bench import _routing_cases as cases
from bench._harness import Group, Measure, Side, Target, script_main

SIMROUTE_R6 = {
    "label": "SIMROUTE's own code, R6 end to end",
    "date": "2026-11-27",
    "machine": "these 2-core machines (same class as this run's), measured by a coordinator, not in this run",
    "method": "end to end as a user runs it: two cold processes (wave interpolation, then routing), "
              "OPENBLAS_NUM_THREADS=1, median of 5 (ANCHORS.md)",
    "cold_s": 35.0,
    "peak_mb": 163.0,
    "parts": {"interpolation_s": "~28", "routing_s": "5-6"},
    "earlier": "2026-11-21: routing 4.35 s + interpolation 14.1 s, timed separately (the figures of issue 5)",
}
SIMROUTE_SEARCHES = {
    "label": "SIMROUTE's two A* searches of R6",
    "date": "2026-11-27",
    "machine": SIMROUTE_R6["machine"],
    "method": "the routing part (both searches) of SIMROUTE's cold end-to-end run, median of 5 (ANCHORS.md: 5-6 s)",
    "cold_s": 5.5,
}


SAME_KERNELS = ("not repeated: the same compiled kernels (mesh, weather onto the mesh, search, smoothing) compile in "
                "route_cli's empty-cache runs")
SAFE_KERNELS = "not repeated: the safe-mode kernels compile in r6_safe's empty-cache runs"
FUEL_KERNELS = "not repeated: the least-fuel kernels compile in r6_fuel_cli's empty-cache runs"


def _stormlane() -> list[str]:
    exe = Path(sys.executable).with_name("stormlane")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "pipelines.cli"]


# --------------------------------------------------------------------------- command lines


def parse_route_json(stdout: str) -> dict:
    import json

    out = json.loads(stdout)
    return {k: [round(out[k]["time_h"], 3), round(out[k]["dist_nmi"], 2)] for k in ("optimal", "min_distance") if k in out}


def setup_cli(argv: list[str]) -> dict:
    return {"argv": list(argv)}


def run_cli(st: dict) -> dict:
    """``stormlane`` in this process (``pipelines.cli.main``), output captured."""
    import contextlib
    import io

    from pipelines.cli import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        try:
            main(st["argv"])
        except SystemExit as err:
            if err.code not in (0, None):
                raise
    text = buf.getvalue()
    return parse_route_json(text) if st["argv"][:1] == ["route"] else {"chars": len(text)}


# --------------------------------------------------------------------------- R6 pieces


def _never_waits(st: dict, wait: bool) -> dict:
    """The state with a ship that never waits (``ShipModel.wait=False``) unless ``wait``: the
    same searches without the FIFO closure, the baseline of what waiting costs."""
    from dataclasses import replace

    if not wait:
        st["ship"] = replace(st["ship"], wait=False)
    return st


def setup_r6_mesh(wait: bool = True) -> dict:
    from pipelines.routing_weather import load_weather

    field, _ = load_weather([str(f) for f in cases.r6_files()])
    req, _ = cases.r6_request()
    return _never_waits(cases.prepared_mesh(field, req), wait)


def run_searches(st: dict) -> dict:
    from routing.astar import search

    a = search(st["mesh"], st["wx"], st["ship"], st["start"], st["goal"], t_start_h=st["t0_h"])
    b = search(st["mesh"], st["wx"], st["ship"], st["start"], st["goal"], cost="distance")
    return {"work": a.computed + b.computed, "time_h": round(a.time_h, 4), "expanded": [a.expanded, b.expanded],
            "scanned": [a.scanned, b.scanned], "computed": [a.computed, b.computed]}


def setup_r6_grid() -> dict:
    """The R6 weather, mesh nodes and land, without the weather on the mesh (that is the run)."""
    import numpy as np

    from pipelines.routing_weather import load_weather
    from routing.mesh import MeshGrid, global_land_mask_window

    field, _ = load_weather([str(f) for f in cases.r6_files()])
    req, _ = cases.r6_request()
    grid = MeshGrid.from_bbox(req.bbox, req.spacing_deg, anchor=req.start)
    lat2d, lon2d = np.meshgrid(grid.lat_deg, grid.lon_deg, indexing="ij")
    node_sea = global_land_mask_window(grid).is_ocean(lat2d, lon2d)
    depart_ns = int(req.depart_utc.value)
    return {"field": field, "grid": grid, "node_sea": node_sea, "depart_ns": depart_ns,
            "ds": cases.field_dataset(field, depart_ns)}


def run_w2m(st: dict) -> dict:
    g = st["grid"]
    mw = st["field"].on_mesh(g.lat_deg, g.lon_deg, st["depart_ns"], node_sea=st["node_sea"])
    return {"work": int(mw.wave.shape[0] * mw.wave.shape[1]), "sea_nodes": int(mw.wave.shape[1]), "times": int(mw.n_times)}


def run_w2m_xarray(st: dict) -> dict:
    g = st["grid"]
    out = cases.xarray_to_mesh(st["ds"], g.lat_deg, g.lon_deg)
    hs = out["hs_m"]
    return {"work": int(hs.shape[0] * int(st["node_sea"].sum())), "nodes": int(hs.shape[1] * hs.shape[2]), "times": int(hs.shape[0])}


# --------------------------------------------------------------------------- small mesh, reference


def setup_small() -> dict:
    import pandas as pd

    from routing.astar import ShipModel
    from routing.planner import RouteRequest

    field = cases.make_storm_field(lat_range=(37.5, 42.0), lon_range=(0.0, 6.0))
    req = RouteRequest(cases.SMALL_START, cases.SMALL_GOAL, pd.Timestamp(cases.MED_T0) + pd.Timedelta("6h"),
                       ShipModel(16.1, "bowditch"), spacing_deg=0.1, bbox=cases.SMALL_BBOX, edges=48)
    return cases.prepared_mesh(field, req)


def run_small_ours(st: dict) -> dict:
    from routing.astar import search

    r = search(st["mesh"], st["wx"], st["ship"], st["start"], st["goal"], t_start_h=st["t0_h"], heuristic=False)
    return {"work": r.computed, "time_h": round(r.time_h, 9), "expanded": r.expanded, "nodes": st["mesh"].grid.n_nodes}


def run_small_python(st: dict) -> dict:
    from bench._td_reference import td_dijkstra

    r = td_dijkstra(st["mesh"], st["wx"], st["ship"].speed_kn, st["ship"].floor_kn, st["start"], st["goal"], st["t0_h"])
    return {"work": r["computed"], "time_h": round(r["time_h"], 9), "expanded": r["expanded"]}


# --------------------------------------------------------------------------- MEDSEA size


def setup_medsea(safety: bool = False) -> dict:
    from pipelines.config import load_operator_profile

    req, v = cases.medsea_request()
    st = {"field": cases.make_storm_field(), "req": req, "vessel": v}
    if safety:
        st["limits"] = load_operator_profile("hs-wind-only")
    return st


def run_medsea(st: dict) -> dict:
    from routing.planner import plan_routes

    if "limits" in st:
        plan = plan_routes(st["req"], st["field"], safety="hard", vessel=st["vessel"], limits=st["limits"])
    else:
        plan = plan_routes(st["req"], st["field"])
    r = plan.routes
    info = {k: [round(r[k].time_h, 2), round(r[k].dist_nmi, 1), round(r[k].max_hs_m, 2)] for k in r}
    if "limits" in st:
        info["mode"] = plan.stats["safety"]["mode"]
    return info


def setup_medsea_mesh(with_graph: bool = False, wait: bool = True) -> dict:
    field = cases.make_storm_field()
    req, _ = cases.medsea_request()
    st = _never_waits(cases.prepared_mesh(field, req), wait)
    if with_graph:
        import numpy as np
        from scipy.sparse.csgraph import breadth_first_order

        st["graph"] = cases.mesh_graph(st["mesh"])
        reach = breadth_first_order(st["graph"], st["start"], directed=True, return_predecessors=False)
        st["graph_edges_reachable"] = int(np.diff(st["graph"].indptr)[reach].sum())
    return st


def run_core_time(st: dict) -> dict:
    from routing.astar import search

    r = search(st["mesh"], st["wx"], st["ship"], st["start"], st["goal"], t_start_h=st["t0_h"], heuristic=False)
    return {"work": r.computed, "scanned": r.scanned, "expanded": r.expanded, "search_s": round(r.seconds, 4)}


def run_scipy_dijkstra(st: dict) -> dict:
    import numpy as np
    from scipy.sparse.csgraph import dijkstra

    d = dijkstra(st["graph"], directed=True, indices=st["start"])
    # counted like our counter on a full expansion: each undirected edge once
    return {"work": st["graph_edges_reachable"] // 2, "reached": int(np.isfinite(d).sum()),
            "dist_nmi_to_goal": round(float(d[st["goal"]]), 3)}


# --------------------------------------------------------------------------- R6 safe mode


def setup_r6_feeder(safety: bool) -> dict:
    from pipelines.config import load_operator_profile

    req, v = cases.r6_request("container-feeder")
    return {"req": req, "vessel": v, "files": [str(f) for f in cases.r6_files()],
            "limits": load_operator_profile("default") if safety else None}


def run_r6_feeder(st: dict) -> dict:
    """From the NetCDF files to every route (the safe ones too when the state holds limits)."""
    from pipelines.routing_weather import load_weather
    from routing.planner import plan_routes

    field, _ = load_weather(st["files"])
    if st["limits"] is not None:
        plan = plan_routes(st["req"], field, safety="hard", vessel=st["vessel"], limits=st["limits"])
    else:
        plan = plan_routes(st["req"], field)
    info = {k: round(v.time_h, 3) for k, v in plan.routes.items()}
    if st["limits"] is not None:
        info["mode"] = plan.stats["safety"]["mode"]
    return info


# --------------------------------------------------------------------------- learned speed table (issue 21)


def _bowditch_table(v0_kn: float):
    """A learned-model table holding Bowditch's speed ratios on a 0.5 m x 15 deg grid: the search then
    reads the table (bilinear, in the compiled kernels) where the formula was computed. Same weather,
    same mesh; the speeds differ only between grid points (Bowditch's sectors are steps in the
    encounter angle, the table interpolates across them)."""
    import numpy as np

    from routing.learned import LearnedSpeedTable
    from routing.speed_loss import speed_loss_bowditch

    hs = np.arange(0.0, 15.01, 0.5)
    enc = np.arange(0.0, 180.01, 15.0)
    h, e = np.meshgrid(hs, enc, indexing="ij")
    ratio = np.clip((v0_kn - np.asarray(speed_loss_bowditch(v0_kn, h, e))) / v0_kn, 0.05, 1.0)
    return LearnedSpeedTable("bowditch-as-table", hs, enc, ratio, ratio, ratio, hs_max_trained_m=15.0,
                             note="Bowditch's ratios tabulated (benchmark)")


def setup_r6_learned(learned: bool) -> dict:
    """R6's request with the ship sailing a learned table (or Bowditch itself), the files to read."""
    from dataclasses import replace

    from routing.astar import ShipModel

    req, v = cases.r6_request()
    if learned:
        req = replace(req, ship=ShipModel.from_vessel(v, "learned", learned=_bowditch_table(v.speed_kn)))
    return {"req": req, "files": [str(f) for f in cases.r6_files()]}


def run_r6_plan(st: dict) -> dict:
    """From the NetCDF files to the four plain routes."""
    from pipelines.routing_weather import load_weather
    from routing.planner import plan_routes

    field, _ = load_weather(st["files"])
    plan = plan_routes(st["req"], field)
    return {k: round(v.time_h, 3) for k, v in plan.routes.items()}


# --------------------------------------------------------------------------- fuel objective (issue 20)

#: R6 with 8 speed settings (9.66 .. 26.93 kn: 60 % of service to maximum power) and a fixed arrival.
R6_FUEL_ARGS = ["--objective", "fuel", "--speed-range", "9.66,26.93", "--speed-steps", "8", "--arrive-by", "2020-01-21T02:00Z"]


def setup_r6_window(objective: str) -> dict:
    from pipelines.config import load_operator_profile

    req, v = cases.r6_request()
    return {"req": req, "vessel": v, "files": [str(f) for f in cases.r6_files()], "objective": objective,
            "limits": load_operator_profile(None)}


def run_r6_window(st: dict) -> dict:
    """16 departures (09:00 .. 00:00 next day, hourly) from the NetCDF files, ranked."""
    import pandas as pd

    from pipelines.routing_weather import load_weather
    from routing.emissions import Engine
    from routing.fuel import FuelSpec, speed_settings
    from routing.planner_window import departures, plan_window

    field, _ = load_weather(st["files"])
    t0 = pd.Timestamp(cases.R6_DEPART)
    times = departures(t0, t0 + pd.Timedelta(hours=15), 1.0)
    eng = Engine.from_vessel(st["vessel"])
    spec = FuelSpec(speed_settings(st["vessel"], eng, speed_range=(9.66, 26.93), steps=8), eng, pd.Timestamp("2020-01-21T12:00Z"))
    res = plan_window(st["req"], field, times, objective=st["objective"], fuel=spec, vessel=st["vessel"], limits=st["limits"])
    key = "time_h" if st["objective"] == "time" else "fuel_t"
    return {"departures": len(res["rows"]), "best": res["rows"][res["best"]]["depart_utc"], key: res["rows"][res["best"]][key]}


def run_medsea_fuel(st: dict) -> dict:
    """The MEDSEA-size plan with the least-fuel route (8 settings, arrival by 115 h after departure; the earliest possible is 91.6 h)."""
    import pandas as pd

    from routing.emissions import Engine
    from routing.fuel import FuelSpec, speed_settings
    from routing.planner import plan_routes

    v = st["vessel"]
    eng = Engine.from_vessel(v)
    spec = FuelSpec(speed_settings(v, eng, speed_range=(0.6 * v.speed_kn, v.speed_kn * 1.15), steps=8), eng,
                    st["req"].depart_utc + pd.Timedelta(hours=115))
    plan = plan_routes(st["req"], st["field"], fuel=spec)
    f = plan.stats["fuel"]
    return {"fuel_t": round(f["fuel_t"], 3), "gap_pct": f["gap_pct"], "saving_pct": f.get("saving_pct"), "labels": f["labels"]}


# --------------------------------------------------------------------------- the groups


HERE = "bench.routing"


def _r6_group(r6, route):
    """The R6 CLI (cold and warm), its searches and the weather onto the mesh; SIMROUTE's external figures."""
    return Group(
        "r6", "R6 (Palma -> Barcelona, Storm Gloria): the CLI, the searches, weather onto the mesh", needs=r6,
        sides=[
            Side("route_cli", "`stormlane route` R6 --json, a fresh process (NetCDF read, land mask, weather on the mesh, "
                 "both searches, smoothing, JSON out)", argv=route, parse=f"{HERE}:parse_route_json",
                 warm_setup=f"{HERE}:setup_cli", warm_run=f"{HERE}:run_cli", warm_kwargs={"argv": cases.r6_route_args()}),
            Side("help_cli", "`stormlane --help`, a fresh process", argv=_stormlane() + ["--help"],
                 warm_setup=f"{HERE}:setup_cli", warm_run=f"{HERE}:run_cli", warm_kwargs={"argv": ["--help"]}),
            Side("python_start", "`python -c pass`: the interpreter's own start (the floor of any Python command)",
                 argv=[sys.executable, "-c", "pass"], ours=False, warm_na="a bare interpreter start has no warm state"),
            Side("searches", "both R6 A* searches (time, then distance) on the built mesh", setup=f"{HERE}:setup_r6_mesh",
                 run=f"{HERE}:run_searches", work="edges whose cost was computed (both searches)", empty_cache=SAME_KERNELS),
            Side("searches_no_wait", "both R6 A* searches, the ship never waits (ShipModel.wait=False: not optimal where "
                 "edge times jump with time)", setup=f"{HERE}:setup_r6_mesh", kwargs={"wait": False}, run=f"{HERE}:run_searches",
                 work="edges whose cost was computed (both searches)", empty_cache=SAME_KERNELS),
            Side("w2m", "R6 weather onto the mesh (WeatherField.on_mesh: bilinear over sea points, hourly steps)",
                 setup=f"{HERE}:setup_r6_grid", run=f"{HERE}:run_w2m", work="node-times filled (sea nodes x time steps)"),
            Side("w2m_xarray", "xarray Dataset.interp (linear) of Hs and the direction's unit vector onto every mesh node",
                 setup=f"{HERE}:setup_r6_grid", run=f"{HERE}:run_w2m_xarray", ours=False,
                 work="node-times (sea nodes x time steps, for comparison)"),
        ],
        measures=[
            Measure("r6_route", "R6 `stormlane route`, NetCDF to both routes", "route_cli", external=SIMROUTE_R6,
                    targets=[Target("cold process <= 2 s", "cold.wall_s", "<=", 2.0, "s", "issue 18"),
                             Target("cold peak <= 400 MB", "cold.peak_mb", "<=", 400.0, "MB", "issue 18"),
                             Target("warm < 0.5 s", "warm.wall_s", "<", 0.5, "s", "issue 5")]),
            Measure("help", "`stormlane --help`", "help_cli", "python_start",
                    relation="the interpreter start alone: the part of a CLI start no code of ours can remove",
                    targets=[Target("cold <= 0.5 s", "cold.wall_s", "<=", 0.5, "s", "issue 18")]),
            Measure("r6_searches", "R6 both A* searches", "searches", external=SIMROUTE_SEARCHES,
                    targets=[Target("warm < 45 ms", "warm.wall_s", "<", 0.045, "s", "issue 5")]),
            Measure("r6_wait", "R6 both A* searches: what waiting costs", "searches", "searches_no_wait",
                    relation="the same searches without waiting (the FIFO closure min over later departures, "
                             "routing._kernels.edge): the ratio is what the exact optimum under non-FIFO weather costs"),
            Measure("r6_w2m", "R6 weather onto the mesh", "w2m", "w2m_xarray",
                    relation="same fields, nodes and times; xarray interpolates every node with NaN next to land, "
                             "ours only sea nodes with the weights renormalised over sea points"),
        ])


def _reference_group():
    """Our time-dependent Dijkstra against a plain-Python one on a small mesh (same optimum)."""
    return Group(
        "reference", "Time-dependent Dijkstra against a plain-Python reference (small mesh)",
        sides=[
            Side("td_ours", "our time-dependent Dijkstra (compiled core, no heuristic), 0.1 deg Balearic mesh, 48 edges",
                 setup=f"{HERE}:setup_small", run=f"{HERE}:run_small_ours", work="edges whose cost was computed",
                 empty_cache=SAME_KERNELS),
            Side("td_python", "plain-Python time-dependent Dijkstra (bench/_td_reference.py), same mesh, weather and model",
                 setup=f"{HERE}:setup_small", run=f"{HERE}:run_small_python", ours=False, work="edges whose cost was computed"),
        ],
        measures=[Measure("td_reference", "time-dependent Dijkstra, small mesh", "td_ours", "td_python",
                          relation="same algorithm, edge model and optimum (checked: time_h in both results)")])


def _medsea_group():
    """MEDSEA size: the whole plan, safe mode and the core's throughput against scipy's static Dijkstra."""
    return Group(
        "medsea", "MEDSEA size (387 k nodes, generated storm): plan, safe mode, core throughput",
        sides=[
            Side("medsea_plan", "plan_routes: field to both routes (land mask, weather on the mesh, mesh, searches, smoothing)",
                 setup=f"{HERE}:setup_medsea", run=f"{HERE}:run_medsea", empty_cache=SAME_KERNELS),
            Side("medsea_safe", "plan_routes with safety='hard' (hs-wind-only: Hs <= 6 m, wind)",
                 setup=f"{HERE}:setup_medsea", kwargs={"safety": True}, run=f"{HERE}:run_medsea", empty_cache=SAFE_KERNELS),
            Side("core_time", "core: time-dependent Dijkstra over the mesh to Port Said", setup=f"{HERE}:setup_medsea_mesh",
                 run=f"{HERE}:run_core_time", work="edges whose cost was computed", empty_cache=SAME_KERNELS),
            Side("core_time_no_wait", "the same core, the ship never waits (ShipModel.wait=False)",
                 setup=f"{HERE}:setup_medsea_mesh", kwargs={"wait": False}, run=f"{HERE}:run_core_time",
                 work="edges whose cost was computed", empty_cache=SAME_KERNELS),
            Side("scipy_dijkstra", "scipy.sparse.csgraph.dijkstra from the start over the same mesh's edges (CSR)",
                 setup=f"{HERE}:setup_medsea_mesh", kwargs={"with_graph": True}, run=f"{HERE}:run_scipy_dijkstra", ours=False,
                 work="edges (each undirected edge once, as our counter counts a full expansion)"),
        ],
        measures=[
            Measure("medsea_plan", "MEDSEA-size route, field to both routes", "medsea_plan", "scipy_dijkstra",
                    relation="the floor: scipy's static shortest distances over the same mesh (no weather, no time "
                             "dependence, no path, mesh built in its setup); ours builds the mesh, puts the weather on it, "
                             "runs both searches and smooths",
                    targets=[Target("warm < 2 s", "warm.wall_s", "<", 2.0, "s", "issue 5")]),
            Measure("medsea_safe", "MEDSEA-size route, safe mode", "medsea_safe", "medsea_plan",
                    relation="the same plan without safety: the ratio is what safe mode costs"),
            Measure("core", "core throughput, time-dependent Dijkstra (MEDSEA mesh)", "core_time", "scipy_dijkstra",
                    relation="scipy solves the static problem (the engine's floor); ours computes a time-dependent cost per edge",
                    targets=[Target(">= 30 M edges/s (computed)", "warm.throughput", ">=", 30e6, "edges/s", "issue 5")]),
            Measure("core_wait", "core time-dependent Dijkstra (MEDSEA mesh): what waiting costs", "core_time",
                    "core_time_no_wait", relation="the same search without waiting: the ratio is what the FIFO closure costs"),
        ])


def _safe_group(r6):
    """R6 in safe mode against the same plan without safety."""
    return Group(
        "r6_safe", "R6 safe mode (container feeder, default operator profile + IMO rules)", needs=r6,
        sides=[
            Side("r6_safe", "NetCDF to all six routes, safety='hard'", setup=f"{HERE}:setup_r6_feeder",
                 kwargs={"safety": True}, run=f"{HERE}:run_r6_feeder"),
            Side("r6_plain", "NetCDF to the four plain routes, same vessel", setup=f"{HERE}:setup_r6_feeder",
                 kwargs={"safety": False}, run=f"{HERE}:run_r6_feeder", empty_cache=SAME_KERNELS),
        ],
        measures=[Measure("r6_safe", "R6 safe mode, NetCDF to all routes", "r6_safe", "r6_plain",
                          relation="the same case without safety: the ratio is what safe mode costs",
                          targets=[Target("warm < 0.5 s", "warm.wall_s", "<", 0.5, "s", "README (safe mode)")])])


def _fuel_group(r6, route):
    """Least-fuel routes (issue 20), each beside the time objective in the same run."""
    fuel_route = _stormlane() + cases.r6_route_args() + R6_FUEL_ARGS
    return Group(
        "fuel", "Least-fuel routes (issue 20), each beside the time objective in the same run", needs=r6,
        sides=[
            Side("r6_fuel_cli", "`stormlane route` R6 --objective fuel, 8 settings, --arrive-by 02:00 (NetCDF to every route and "
                 "the fuel search's bound)", argv=fuel_route, parse=f"{HERE}:parse_route_json", warm_setup=f"{HERE}:setup_cli",
                 warm_run=f"{HERE}:run_cli", warm_kwargs={"argv": cases.r6_route_args() + R6_FUEL_ARGS}),
            Side("r6_time_cli", "`stormlane route` R6 (time objective), the same process", argv=route, parse=f"{HERE}:parse_route_json",
                 warm_setup=f"{HERE}:setup_cli", warm_run=f"{HERE}:run_cli", warm_kwargs={"argv": cases.r6_route_args()},
                 empty_cache=SAME_KERNELS),
            Side("r6_window_fuel", "R6, 16 hourly departures with the fuel objective (arrival by 2020-01-21T12:00), ranked, hours over "
                 "limits", setup=f"{HERE}:setup_r6_window", kwargs={"objective": "fuel"}, run=f"{HERE}:run_r6_window",
                 empty_cache=FUEL_KERNELS),
            Side("r6_window_time", "R6, the same 16 departures with the time objective", setup=f"{HERE}:setup_r6_window",
                 kwargs={"objective": "time"}, run=f"{HERE}:run_r6_window", empty_cache=SAME_KERNELS),
            Side("medsea_fuel", "MEDSEA-size plan with the least-fuel route (8 settings, arrival 115 h after departure)",
                 setup=f"{HERE}:setup_medsea", run=f"{HERE}:run_medsea_fuel", empty_cache=FUEL_KERNELS),
            Side("medsea_time", "MEDSEA-size plan, time objective (the medsea group's medsea_plan)", setup=f"{HERE}:setup_medsea",
                 run=f"{HERE}:run_medsea", empty_cache=SAME_KERNELS),
        ],
        measures=[
            Measure("r6_fuel", "R6 least fuel, 8 settings, fixed arrival", "r6_fuel_cli", "r6_time_cli",
                    relation="the same command with the time objective: the ratio is what the fuel objective costs",
                    targets=[Target("warm <= 1 s", "warm.wall_s", "<=", 1.0, "s", "issue 20")]),
            Measure("r6_window", "R6 departure window, 16 departures", "r6_window_fuel", "r6_window_time",
                    relation="the same departures with the time objective",
                    targets=[Target("warm <= 5 s", "warm.wall_s", "<=", 5.0, "s", "issue 20")]),
            Measure("medsea_fuel", "MEDSEA-size least-fuel route", "medsea_fuel", "medsea_time",
                    relation="the same plan with the time objective",
                    targets=[Target("warm <= 10 s", "warm.wall_s", "<=", 10.0, "s", "issue 20"),
                             Target("peak <= 1 GB", "warm.peak_mb", "<=", 1024.0, "MB", "issue 20")]),
        ])


def _learned_group(r6):
    """A route sailed by a learned model's table against the same route by Bowditch (issue 21: <= 1.5x)."""
    return Group(
        "learned", "R6 sailed by a learned model's table against Bowditch (issue 21)", needs=r6,
        sides=[
            Side("r6_learned", "NetCDF to the four plain routes, the ship sailing a learned table (Bowditch's ratios on a "
                 "0.5 m x 15 deg grid, interpolated between them, so the routes differ a little)", setup=f"{HERE}:setup_r6_learned", kwargs={"learned": True},
                 run=f"{HERE}:run_r6_plan"),
            Side("r6_bowditch", "the same plan with the Bowditch formula in the kernels", setup=f"{HERE}:setup_r6_learned",
                 kwargs={"learned": False}, run=f"{HERE}:run_r6_plan", empty_cache=SAME_KERNELS),
        ],
        measures=[Measure("r6_learned", "R6 plan, learned table against Bowditch", "r6_learned", "r6_bowditch",
                          relation="the same plan, weather and mesh; the speed comes from the table instead of the formula",
                          targets=[Target("<= 1.5 x Bowditch (warm)", "speedup.warm", ">=", 1 / 1.5, "x", "issue 21")])])


def build(cfg):
    r6 = cases.r6_files()
    route = _stormlane() + cases.r6_route_args()
    groups = [_r6_group(r6, route), _safe_group(r6), _reference_group(), _medsea_group(), _fuel_group(r6, route),
              _learned_group(r6)]
    notes = ["SIMROUTE's figures are external (ANCHORS.md): measured by a coordinator on these machines, not in this run; "
             "compared cold with cold only.",
             "Throughput counts edges whose cost was computed (routing._kernels.astar's counter): edges to settled nodes "
             "are scanned and skipped, and not counted."]
    return groups, notes


if __name__ == "__main__":
    script_main("bench/routing.py", build)
