"""Benchmark of cargo-safe deviations and route evaluations (issue 6), beside the engine's reroutes.

The case (generated, deterministic; the lanes computed once and cached, the rest built in each
process's untimed setup): the demo region
(Western Mediterranean, lon -1.5..11.5, lat 35.5..45.0) on the CMEMS global wave grid (1/12 deg,
3-hourly, 4 days) with a moving storm (Hs up to 8 m), land from global-land-mask (read through
thresholds.land_raster, the land check every stage uses); 10 lanes
between the demo ports with centroids every ~8 nmi along the calm-water minimum-distance sea
route; 10 departures per lane, 6 h apart: 100 lane-departures.

* ``deviate_evaluate``: for each lane-departure, the deviation (``routing.deviate.deviate_lane``:
  R-tree search of safe cells, sea legs checked against the mesh's land) and the evaluation of
  the lane and of the deviation (``routing.evaluate.evaluate_route``: speed loss, STEAM2 fuel and
  emissions, operator and IMO rules, events).
* ``reroute`` (baseline): the other way to give each lane-departure a better route, the routing
  engine's time-optimal reroute (``plan_routes`` on a 2 nmi mesh over the lane's box, same
  weather, same vessel and Bowditch), without any evaluation. Not the same output: the ratio
  says what a deviation with both evaluations costs against a full reroute.

Throughput counts lane-departures. Target (issue 6): the 100 in under 10 s on 2 cores.
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: `import routing` must find the package, not bench/routing.py
    import sys
    from pathlib import Path

    _here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _here]
    sys.path.insert(0, str(_here.parent))

from pathlib import Path

from bench._harness import Group, Measure, Side, Target, script_main, source_stamp

T0 = "2025-01-14T00:00Z"
LANES = [  # (from, to) approach points of data/ports.csv; lanes follow the calm minimum-distance route
    ((41.31, 2.22), (39.43, -0.26)),  # Barcelona - Valencia
    ((41.31, 2.22), (43.30, 5.30)),  # Barcelona - Marseille
    ((43.30, 5.30), (44.38, 8.91)),  # Marseille - Genova
    ((36.795, 3.09), (39.52, 2.62)),  # Alger - Palma
    ((36.795, 3.09), (39.18, 9.11)),  # Alger - Cagliari
    ((39.18, 9.11), (36.83, 10.36)),  # Cagliari - Tunis
    ((39.52, 2.62), (39.18, 9.11)),  # Palma - Cagliari
    ((39.43, -0.26), (36.795, 3.09)),  # Valencia - Alger
    ((43.30, 5.30), (39.18, 9.11)),  # Marseille - Cagliari
    ((41.31, 2.22), (39.18, 9.11)),  # Barcelona - Cagliari
]
DEPARTURES = 10
MESH_DEG = 2.0 / 60.0


def make_weather_arrays():
    """The storm on the CMEMS global grid over the demo region: (times ns, lat, lon, variables)."""
    import numpy as np
    import pandas as pd
    from thresholds.land_raster import is_land

    lat = np.round(np.arange(35.5, 45.0001, 1 / 12), 6)
    lon = np.round(np.arange(-1.5, 11.5001, 1 / 12), 6)
    times = pd.date_range(pd.Timestamp(T0), periods=33, freq="3h")
    lon2, lat2 = np.meshgrid(lon, lat)
    land = is_land(lat2, lon2)  # the one land check (bit-packed raster): not the 0.93 GB globe array
    h = np.arange(times.size)[:, None, None] * 3.0
    xc, yc = 0.5 + 0.09 * h, 38.0 + 0.03 * h  # storm centre moving east-north-east
    r2 = ((lon2 - xc) / 2.0) ** 2 + ((lat2 - yc) / 1.2) ** 2
    hs = 1.0 + 7.0 * np.exp(-r2)
    hs = np.where(land[None], np.nan, hs)
    wave_from = np.where(land[None], np.nan, np.mod(np.rad2deg(np.arctan2(lon2 - xc, lat2 - yc)) + 180.0, 360.0))
    tm = np.where(land[None], np.nan, 4.0 + 0.6 * hs)
    u = np.where(land[None], np.nan, 3.0 * hs)
    v = np.where(land[None], np.nan, 0.5 * hs)
    variables = {"hs_m": hs, "wave_from_deg": wave_from, "tm_s": tm, "tp_s": tm * 1.25, "wind_u_ms": u, "wind_v_ms": v}
    return times.asi8, lat, lon, variables


def make_lane(a, b, step_nmi=8.0):
    """A sea lane between two ports: the calm-water minimum-distance route of the routing planner
    (so it stays at sea), resampled every ~``step_nmi`` like DBSCAN centroids."""
    import numpy as np
    import pandas as pd

    from routing.astar import ShipModel
    from routing.planner import RouteRequest, plan_routes
    from thresholds.geodesy import intermediate_point

    req = RouteRequest(a, b, pd.Timestamp(T0), ShipModel(14.0, "none"), spacing_deg=MESH_DEG)
    path = plan_routes(req, None).routes["min_distance"]
    seg = path.leg_dist_nmi
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(int(np.ceil(cum[-1] / step_nmi)) + 1, 2)
    lat, lon = [], []
    for s in np.linspace(0.0, cum[-1], n):
        j = min(int(np.searchsorted(cum, s, side="right") - 1), seg.size - 1)
        f = 0.0 if seg[j] == 0 else (s - cum[j]) / seg[j]
        la, lo = intermediate_point(path.lat_deg[j], path.lon_deg[j], path.lat_deg[j + 1], path.lon_deg[j + 1], f)
        lat.append(la)
        lon.append(lo)
    speed = np.full(n, 14.0)
    speed[:2] = 9.0  # slower out of port
    return np.asarray(lat), np.asarray(lon), speed


def prepare(path: str) -> dict:
    """The 10 lanes (10 calm-water minimum-distance routes), computed once into an npz cache."""
    import numpy as np

    p = Path(path)
    if not p.exists():
        p.parent.mkdir(parents=True, exist_ok=True)
        arrays = {}
        for k, (a, b) in enumerate(LANES):
            for name, arr in zip(("lat", "lon", "speed"), make_lane(a, b)):
                arrays[f"{name}{k}"] = arr
        np.savez(p, **arrays)
    with np.load(p) as z:
        return {"lanes": len(LANES), "centroids": int(sum(z[f"lat{k}"].size for k in range(len(LANES))))}


def setup(lanes: str, baseline: bool = False) -> dict:
    """The weather, the vessel and its limits, the lanes and departures (untimed)."""
    import pandas as pd

    from pipelines.config import load_operator_profile, load_vessel

    arrays = make_weather_arrays()
    st = {"vessel": load_vessel("container-feeder"), "profile": load_operator_profile("default"),
          "departures": [pd.Timestamp(T0) + pd.Timedelta(hours=6 * k) for k in range(DEPARTURES)]}
    if baseline:
        from routing.field import WeatherField

        st["field"] = WeatherField(*arrays)
        return st
    from routing.deviate import threshold_inputs
    from routing.mesh import MeshGrid, build_mesh, global_land_mask_window
    from routing.sampling import PointSampler

    sampler = PointSampler(*arrays)
    st["weather_at"], st["check"], st["cells"] = threshold_inputs(sampler, st["vessel"], st["profile"])
    grid = MeshGrid.from_bbox((-1.5, 35.5, 11.5, 45.0), 0.05)
    st["leg_at_sea"] = build_mesh(grid, land=global_land_mask_window(grid)).leg_is_sea
    import numpy as np

    with np.load(lanes) as z:
        st["lanes"] = [(z[f"lat{k}"], z[f"lon{k}"], z[f"speed{k}"]) for k in range(len(LANES))]
    return st


def run_ours(st: dict) -> dict:
    """Deviation + evaluation of lane and deviation for every lane-departure."""
    from routing.deviate import deviate_lane, lane_route
    from routing.evaluate import evaluate_route

    n = moved = unresolved = 0
    for lat, lon, spd in st["lanes"]:
        for dep in st["departures"]:
            dev = deviate_lane(lat, lon, spd, dep, weather_at=st["weather_at"], check=st["check"], cells=st["cells"],
                               leg_at_sea=st["leg_at_sea"])
            evaluate_route(lane_route(lat, lon, spd, dep), st["weather_at"], st["vessel"], limits=st["profile"])
            evaluate_route(dev, st["weather_at"], st["vessel"], limits=st["profile"])
            n += 1
            moved += dev.properties["n_deviated"]
            unresolved += dev.properties["n_unresolved"]
    return {"work": n, "points_moved": int(moved), "steps_unresolved": int(unresolved)}


def run_reroute(st: dict) -> dict:
    """The engine's time-optimal reroute (plain, no evaluation) of every lane-departure."""
    from routing.astar import ShipModel
    from routing.planner import RouteRequest, plan_routes

    ship = ShipModel.from_vessel(st["vessel"], "bowditch")
    n = 0
    for a, b in LANES:
        for dep in st["departures"]:
            plan_routes(RouteRequest(a, b, dep, ship, spacing_deg=MESH_DEG), st["field"])
            n += 1
    return {"work": n}


def build(cfg):
    here = "bench.evaluate"
    lanes = str(Path(cfg.cache_dir) / f"evaluate-lanes-{source_stamp('routing', 'thresholds', 'bench/evaluate.py')}.npz")
    g = Group(
        "deviations", f"{len(LANES)} lanes x {DEPARTURES} departures (100 lane-departures), generated storm",
        prepare=f"{here}:prepare", prepare_kwargs={"path": lanes},
        sides=[Side("deviate_evaluate", "deviation + evaluation of lane and deviation, per lane-departure",
                    setup=f"{here}:setup", kwargs={"lanes": lanes}, run=f"{here}:run_ours", work="lane-departures"),
               Side("reroute", "the engine's time-optimal reroute per lane-departure (plan_routes, 2 nmi mesh), "
                    "no evaluation", setup=f"{here}:setup", kwargs={"lanes": lanes, "baseline": True},
                    run=f"{here}:run_reroute", ours=False, work="lane-departures")],
        measures=[Measure("deviations", "deviations + evaluations, 100 lane-departures", "deviate_evaluate", "reroute",
                          relation="not the same output: a full time-optimal reroute of each lane-departure instead of a "
                                   "deviation and two evaluations (same weather, vessel and departures)",
                          targets=[Target("< 10 s (cold)", "cold.wall_s", "<", 10.0, "s", "issue 6")])])
    notes = ["The reroute baseline is our own routing engine (its empty-cache runs are not repeated here: see "
             "bench/routing.py)."]
    return [g], notes


if __name__ == "__main__":
    script_main("bench/evaluate.py", build)
