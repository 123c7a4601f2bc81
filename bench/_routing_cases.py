"""The cases of ``bench/routing.py``: R6 (SIMROUTE's Storm Gloria case), a MEDSEA-size case with a
generated storm, a small mesh for the plain-Python reference, and the same meshes as graphs for
scipy. Heavy imports stay inside the functions (the harness imports this module in every child).
"""

from __future__ import annotations

from pathlib import Path

from bench._harness import shared_data

# R6: Palma -> Barcelona, Storm Gloria, SIMROUTE's published case (issue 5; ANCHORS.md)
R6_START, R6_GOAL = (39.225, 2.900), (41.500, 2.775)
R6_DEPART = "2020-01-20T09:00Z"
R6_BBOX = (2.0, 38.95, 5.1, 41.65)
R6_SPACING_DEG = 0.025  # 1.5 nmi as SIMROUTE's inc/60

# MEDSEA-size: 1/24 deg over 6 W - 36 E, 30 - 46 N, Gibraltar -> Port Said
MED_BBOX = (-6.0, 30.0, 36.0, 46.0)
GIBRALTAR, PORT_SAID = (35.95, -5.55), (31.40, 32.35)
MED_T0 = "2025-01-30T00:00Z"

# small mesh for the plain-Python reference: the Balearic Sea at 0.1 deg through the same storm
SMALL_BBOX = (0.5, 38.0, 5.5, 41.5)
SMALL_START, SMALL_GOAL = (38.5, 1.0), (41.2, 5.2)


def r6_files() -> list[Path]:
    folder = shared_data() / "weather" / "simroute_cmems_medsea_wav"
    return [folder / f"Waves_MEDSEA_2020012{d}.nc" for d in (0, 1)]


def r6_route_args() -> list[str]:
    """``stormlane route`` arguments of R6 (SIMROUTE's ship and mesh: the ``simroute-r6`` vessel,
    named, since the CLI's default vessel is the container feeder; Bowditch, 1.5 nmi, 48 edges)."""
    f = [str(p) for p in r6_files()]
    return ["route", "--from", f"{R6_START[0]},{R6_START[1]}", "--to", f"{R6_GOAL[0]},{R6_GOAL[1]}", "--depart", R6_DEPART,
            "--weather", f[0], "--weather", f[1], "--vessel", "simroute-r6", "--mesh-nmi", "1.5", "--bbox", ",".join(str(x) for x in R6_BBOX),
            "--edges", "48", "--json"]


def r6_request(vessel_name: str = "simroute-r6", model: str = "bowditch"):
    import pandas as pd

    from pipelines.config import load_vessel
    from routing.astar import ShipModel
    from routing.planner import RouteRequest

    v = load_vessel(vessel_name)
    req = RouteRequest(R6_START, R6_GOAL, pd.Timestamp(R6_DEPART), ShipModel.from_vessel(v, model), spacing_deg=R6_SPACING_DEG,
                       bbox=R6_BBOX, edges=48, vessel_name=v.name)
    return req, v


def make_storm_field(lat_range=(29.5, 46.5), lon_range=(-6.5, 36.5)):
    """CMEMS-GLOBAL-like waves (1/12 deg, 3-hourly, 7 days): swell plus a storm moving east along
    the Algerian basin into the Strait of Sicily (Hs up to 9 m, waves from the west-north-west)."""
    import numpy as np
    import pandas as pd

    from routing.field import WeatherField

    lat = np.round(np.arange(lat_range[0], lat_range[1] + 1e-4, 1 / 12), 6)
    lon = np.round(np.arange(lon_range[0], lon_range[1] + 1e-4, 1 / 12), 6)
    times = pd.date_range(pd.Timestamp(MED_T0), periods=57, freq="3h")
    lon2, lat2 = np.meshgrid(lon, lat)
    h = (np.arange(times.size) * 3.0)[:, None, None]
    xc = 2.0 + 0.15 * h  # storm centre [deg E]: 2 E at t0, 6.5 E after 30 h, 20 E after 5 days
    yc = 38.8 - 0.02 * h
    r2 = ((lon2 - xc) / 3.0) ** 2 + ((lat2 - yc) / 1.6) ** 2
    hs = (0.8 + 8.2 * np.exp(-r2)).astype(np.float32)
    wave_from = ((300.0 + 20.0 * np.tanh((lon2 - xc) / 3.0)) % 360.0).astype(np.float32)
    return WeatherField(times.asi8, lat, lon, {"hs_m": hs, "wave_from_deg": np.broadcast_to(wave_from, hs.shape).copy()})


def medsea_request(vessel_name: str = "container-large"):
    import pandas as pd

    from pipelines.config import load_vessel
    from routing.astar import ShipModel
    from routing.planner import RouteRequest

    v = load_vessel(vessel_name)
    req = RouteRequest(GIBRALTAR, PORT_SAID, pd.Timestamp(MED_T0) + pd.Timedelta("6h"), ShipModel.from_vessel(v, "bowditch"),
                       spacing_deg=1 / 24, bbox=MED_BBOX, edges=48, vessel_name=v.name)
    return req, v


def prepared_mesh(field, req, land: bool = True) -> dict:
    """What the planner builds before its searches (land mask, weather on the mesh, mesh, weather
    arrays, start and goal nodes), without searching: the searches stay cold."""
    import numpy as np

    from routing.astar import WeatherArrays
    from routing.mesh import MeshGrid, build_mesh, global_land_mask_window

    grid = MeshGrid.from_bbox(req.bbox, req.spacing_deg, anchor=req.start)
    mask = global_land_mask_window(grid) if land else None
    lat2d, lon2d = np.meshgrid(grid.lat_deg, grid.lon_deg, indexing="ij")
    node_sea = mask.is_ocean(lat2d, lon2d) if mask is not None else np.ones((grid.ny, grid.nx), dtype=bool)
    depart_ns = int(req.depart_utc.value)
    mw = field.on_mesh(grid.lat_deg, grid.lon_deg, depart_ns, node_sea=node_sea)
    mesh = build_mesh(grid, edges=req.edges, weather_sea=mw.weather_sea, land=mask)
    wx = WeatherArrays.build(mesh, mw)
    start, _ = mesh.snap(req.start[0], req.start[1], req.snap_limit_nmi, what="start")
    goal, _ = mesh.snap(req.goal[0], req.goal[1], req.snap_limit_nmi, what="goal")
    return {"grid": grid, "node_sea": node_sea, "mesh": mesh, "mw": mw, "wx": wx, "start": int(start), "goal": int(goal),
            "t0_h": wx.rel_h(depart_ns), "depart_ns": depart_ns, "ship": req.ship, "field": field, "req": req}


def mesh_graph(mesh):
    """The mesh's allowed edges as a scipy CSR matrix of great-circle lengths [nmi]."""
    import numpy as np
    from scipy.sparse import csr_matrix

    nx = mesh.grid.nx
    n = mesh.grid.n_nodes
    elen = mesh.edge_geometry[0]
    nodes = np.arange(n)
    rows, cols, data = [], [], []
    for k, (di, dj) in enumerate(mesh.steps):
        has = ((mesh.allowed.ravel() >> np.uint64(k)) & np.uint64(1)).astype(bool)
        u = nodes[has]
        rows.append(u)
        cols.append(u + int(dj) * nx + int(di))
        data.append(elen[u // nx, k])
    rows, cols, data = (np.concatenate(x) for x in (rows, cols, data))
    return csr_matrix((data, (rows, cols)), shape=(n, n))


def field_dataset(field, depart_ns: int):
    """The weather field from the departure on as an xarray Dataset (Hs and the direction waves
    come from, as read), for xarray's own interpolation."""
    import numpy as np
    import xarray as xr

    first = int(np.searchsorted(field.time_ns, depart_ns, side="right") - 1)
    coords = {"time": field.time_ns[first:], "lat": field.lat_deg, "lon": field.lon_deg}
    dims = ("time", "lat", "lon")
    return xr.Dataset({k: (dims, field.variables[k][first:]) for k in ("hs_m", "wave_from_deg")}, coords=coords)


def xarray_to_mesh(ds, lat_deg, lon_deg) -> dict:
    """xarray's bilinear interpolation of Hs and the direction's unit vector onto the mesh nodes
    (every node, every time of ``ds``): the same quantities the planner puts on its mesh."""
    import numpy as np

    rad = np.deg2rad(ds["wave_from_deg"])
    full = ds[["hs_m"]].assign(dir_cos=np.cos(rad), dir_sin=np.sin(rad))
    out = full.interp(lat=lat_deg, lon=lon_deg, method="linear")
    return {k: out[k].values for k in ("hs_m", "dir_cos", "dir_sin")}
