"""Time-dependent A* on a routing mesh, path re-timing, calm-water times and smoothing.

The search runs in the compiled core :func:`routing._kernels.astar` over flat arrays:
node ids ``j*nx + i``, a uint64 edge mask per node, per-row edge lengths and courses, and the
weather of every sea node on a regular time axis. The cost of an edge u -> v is

* ``cost="time"``: the time from reaching u to reaching v, by the edge model of
  :mod:`routing._kernels.edge`: the weather is linear in time between its slices and is read at
  quarter-hour sub-slices (m = ceil(dt / 0.25 h) per weather step dt); an edge left at t takes
  ``L * pace`` hours, with L the great-circle length and pace the hours per nmi over ground in
  the mean of the two end nodes' weather (sea state and current) at the sub-slice nearest to t,
  for the edge's initial course (speed through the water from :mod:`routing.speed_loss`'s
  formulas, compiled twin), so the travel time is constant within a sub-slice's piece and jumps
  from one to the next; and the ship may postpone the edge (wait, or sail it slower:
  ``ShipModel.wait``, default on), so the arrival is the earliest over every later departure.
  That arrival is non-decreasing in the departure time (FIFO) even where Bowditch's sectors or
  Aertssen's Beaufort classes make the sailing time jump;
* ``cost="distance"``: L.

With ``safety=`` (:class:`routing.safety.SafetyFlags`) the time search respects the vessel's
limits (:func:`routing._kernels.astar_safe`): edges touching a cell flagged unsafe for their
heading sector at the time they are sailed are forbidden (``hard``) or cost ``1 + penalty``
times their duration (``soft``). The label then keeps cost and arrival time apart; a node keeps
one label (the least cost), so under hard constraints a later arrival that would find a storm
passed is not explored (it does not wait for unsafe weather to pass): the result is the
least-cost path among those whose every prefix is least-cost, and A* and Dijkstra still agree on it.

The heuristic is the great-circle distance to the goal over the highest speed any edge can
reach (v0, or more with Khokhlov in following seas, plus the strongest current), so it never
overestimates (tested on random fields for every model, currents included) and, the edge
arrivals being FIFO, the first time the goal is taken from the heap its arrival is the earliest
of the stated model (tested against a brute-force time-expanded search). ``heuristic=False`` is
Dijkstra. An unreachable goal empties the heap and raises :class:`NoRouteError` after at most
one visit of each node.

References
----------
.. [1] P. E. Hart, N. J. Nilsson and B. Raphael, "A formal basis for the heuristic
       determination of minimum cost paths," IEEE Trans. Syst. Sci. Cybern., vol. 4, no. 2,
       pp. 100-107, 1968, doi:10.1109/TSSC.1968.300136.
.. [2] I. Chabini and S. Lan, "Adaptations of the A* algorithm for the computation of fastest
       paths in deterministic discrete-time dynamic networks," IEEE Trans. Intell. Transp.
       Syst., vol. 3, no. 1, pp. 60-74, 2002, doi:10.1109/6979.994796.
.. [3] M. Grifoll et al., Ocean Eng. 255, 111427, 2022, doi:10.1016/j.oceaneng.2022.111427, section 2.3.
.. [4] A. Orda and R. Rom, "Shortest-path and minimum-delay algorithms in networks with
       time-dependent edge-length," J. ACM, vol. 37, no. 3, pp. 607-625, 1990,
       doi:10.1145/79147.214078.
"""

from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass

import numpy as np

from routing import _kernels
from routing import speed_loss as sl
from routing.errors import NoRouteError, WeatherVariableError
from routing.field import NS_PER_HOUR, MeshWeather
from routing.mesh import Mesh
from routing.safety import SafetyFlags
from routing.learned import LearnedSpeedTable
from routing.learned import attained_speed_kn as learned_speed_kn
from routing.speed_loss_kwon import KwonHull, kwon_check
from thresholds.units import EARTH_RADIUS_NMI

_NO_CURRENT = np.zeros((1, 1, 2), dtype=np.float32)
#: Lowest speed over ground when a foul current overpowers the ship (keeps times finite). [kn]
MIN_SOG_KN = 0.1


@dataclass(frozen=True)
class ShipModel:
    """Calm-water speed and the speed-loss model applied on every edge.

    Attributes
    ----------
    speed_kn, model, lpp_m, dwt_t, floor_kn, bowditch_sectors
        As in :func:`routing.speed_loss.speed_loss`.
    aertssen_bands : {"wmo", "simroute"}
        Aertssen's Hs -> Beaufort convention (:func:`routing.speed_loss.aertssen_beaufort`).
    kwon : routing.speed_loss_kwon.KwonHull, optional
        The hull Kwon's method needs (``model="kwon"``).
    wait : bool
        The ship may postpone an edge (wait or sail it slower) when that arrives earlier: the
        FIFO edge model of :mod:`routing._kernels.edge`, which makes the search optimal under
        weather whose edge costs jump with time. ``False`` only to show what a ship that never
        waits gets (SIMROUTE emulation turns it off too).
    vessel_name : str
        Named in the validity errors.

    Raises
    ------
    routing.speed_loss.SpeedLossRangeError
        Khokhlov beyond D·v0 = 4.0e5 t·kn (the published 4 000-20 000 dwt x 9-20 kn's largest), or
        Kwon outside its table (Cb, Froude).
    """

    speed_kn: float
    model: str = "bowditch"
    lpp_m: float | None = None
    dwt_t: float | None = None
    floor_kn: float = sl.DEFAULT_FLOOR_KN
    bowditch_sectors: str = "symmetric"
    aertssen_bands: str = "wmo"
    kwon: KwonHull | None = None
    wait: bool = True
    vessel_name: str = ""
    learned: LearnedSpeedTable | None = None  # model "learned": its table for this vessel (routing.learned)

    def __post_init__(self):
        if self.model == "learned":
            if not isinstance(self.learned, LearnedSpeedTable):
                raise ValueError("the learned speed model needs its table: ShipModel(learned=LearnedSpeedTable(...))")
        elif self.model not in sl.MODELS:
            raise ValueError(f"unknown speed-loss model {self.model!r}; choose one of {', '.join(sl.MODELS)}")
        if not self.speed_kn > 0:
            raise ValueError(f"speed must be positive, got {self.speed_kn!r} kn")
        if self.model == "aertssen" and not (self.lpp_m and self.lpp_m > 0):
            raise ValueError("the Aertssen model needs the vessel's lpp_m")
        if self.model == "khokhlov":
            if not (self.dwt_t and self.dwt_t > 0):
                raise ValueError("the Khokhlov model needs the vessel's dwt_t")
            sl.khokhlov_check(self.dwt_t, self.speed_kn, self.vessel_name)
        if self.model == "kwon":
            if self.kwon is None:
                raise sl.SpeedLossRangeError(f"the Kwon model needs the hull of vessel {self.vessel_name or '(unnamed)'} "
                                             "(block coefficient, displacement): ShipModel(kwon=KwonHull(...))")
            kwon_check(self.kwon, self.speed_kn, self.vessel_name)
        if self.bowditch_sectors not in ("symmetric", "printed"):
            raise ValueError(f"unknown Bowditch sector table {self.bowditch_sectors!r}")
        if self.aertssen_bands not in sl.AERTSSEN_BANDS:
            raise ValueError(f"unknown Aertssen Hs -> Beaufort convention {self.aertssen_bands!r}; use one of {', '.join(sl.AERTSSEN_BANDS)}")

    @classmethod
    def from_vessel(cls, vessel, model: str = "bowditch", speed_kn: float | None = None, **kwargs) -> "ShipModel":
        """The vessel's speed model (its service speed unless ``speed_kn``; Kwon's hull from its profile)."""
        if model == "kwon" and "kwon" not in kwargs:
            kwargs["kwon"] = KwonHull.from_vessel(vessel)
        return cls(
            speed_kn=float(speed_kn if speed_kn is not None else vessel.speed_kn),
            model=model,
            lpp_m=vessel.lpp_m,
            dwt_t=vessel.dwt_t,
            floor_kn=vessel.min_speed_kn,
            vessel_name=kwargs.pop("vessel_name", vessel.name),
            **kwargs,
        )

    def calm(self) -> "ShipModel":
        return dataclasses.replace(self, model="none")

    @property
    def wind_driven(self) -> bool:
        """The model reads the wind (Kwon), not the waves."""
        return self.model in sl.WIND_MODELS

    def describe(self) -> str:
        """One line naming the model and its convention, for route properties and notes."""
        extra = ""
        if self.model == "aertssen":
            extra = f" (Lpp {self.lpp_m:g} m, Hs -> Beaufort: {self.aertssen_bands})"
        elif self.model == "bowditch":
            extra = f" ({self.bowditch_sectors} sectors)"
        elif self.model == "khokhlov":
            note = sl.khokhlov_check(self.dwt_t, self.speed_kn)
            extra = (f" ({self.dwt_t:,.0f} dwt at {self.speed_kn:g} kn, D·v0 = {self.dwt_t * self.speed_kn:.3g} t·kn; "
                     + (note if note else "within the published 4,000-20,000 dwt, 9-20 kn") + ")")
        elif self.model == "kwon" and self.kwon is not None:
            extra = f" (Cb {self.kwon.cb:g}, {self.kwon.form}, Fn {self.kwon.froude(self.speed_kn):.3f})"
        elif self.model == "learned":
            return f"learned:{self.learned.name} ({self.learned.note})"
        return f"{self.model}{extra}"

    def params(self, step_time: bool = False, pace_min: float = 0.0) -> np.ndarray:
        """Parameter vector for the compiled core (the published coefficients are compiled in).

        ``step_time`` (SIMROUTE emulation) reads the weather slice at or before a time instead
        of interpolating between slices, and never waits (as SIMROUTE). ``pace_min``: the least
        pace over ground of any edge in the weather at hand [h/nmi] (0: unknown), which bounds
        the departures worth trying when waiting.
        """
        table = self.learned.pack() if self.model == "learned" else np.zeros(0)
        p = np.zeros(_kernels.N_PARAMS + table.size)
        p[_kernels.N_PARAMS:] = table
        p[_kernels.P_MODEL] = _kernels.MODEL_CODES[self.model]
        p[_kernels.P_V0] = self.speed_kn
        p[_kernels.P_FLOOR] = self.floor_kn
        p[_kernels.P_LPP] = self.lpp_m or 1.0
        p[_kernels.P_DWT] = self.dwt_t or 0.0
        p[_kernels.P_PRINTED] = 1.0 if self.bowditch_sectors == "printed" else 0.0
        p[_kernels.P_MIN_SOG] = MIN_SOG_KN
        p[_kernels.P_TIME_STEP] = 1.0 if step_time else 0.0
        p[_kernels.P_WAIT] = 1.0 if (self.wait and not step_time) else 0.0
        p[_kernels.P_AERTSSEN_BANDS] = 1.0 if self.aertssen_bands == "simroute" else 0.0
        p[_kernels.P_PACE_MIN] = pace_min
        if self.model == "kwon":
            p[_kernels.P_KWON_CU] = self.kwon.speed_coefficient(self.speed_kn)
            p[_kernels.P_KWON_FORM_A], p[_kernels.P_KWON_FORM_B] = self.kwon.form_terms()
        return p

    def max_speed_kn(self, hs_max_m: float) -> float:
        if self.model == "learned":  # bilinear values never exceed the table's largest (routing.learned)
            return max(self.speed_kn * self.learned.max_ratio(), min(self.floor_kn, self.speed_kn))
        return sl.max_attainable_speed_kn(self.speed_kn, self.model, hs_max_m=hs_max_m, dwt_t=self.dwt_t)

    def attained_kn(self, hs_m, encounter_deg, wind_ms=None, wind_encounter_deg=None):
        """Speed through the water (numpy, :func:`routing.speed_loss.attained_speed_kn`) in waves of
        ``hs_m`` met at ``encounter_deg``, or for Kwon in the wind ``wind_ms`` met at ``wind_encounter_deg``. [kn]"""
        if self.model == "learned":
            return learned_speed_kn(self.learned, self.speed_kn, hs_m, encounter_deg, self.floor_kn)
        if self.wind_driven:
            return sl.attained_speed_kn(self.speed_kn, hs_m, wind_encounter_deg, self.model, floor_kn=self.floor_kn, wind_ms=wind_ms,
                                        kwon=self.kwon)  # fmt: skip
        return sl.attained_speed_kn(self.speed_kn, hs_m, encounter_deg, self.model, lpp_m=self.lpp_m, dwt_t=self.dwt_t,
                                    floor_kn=self.floor_kn, bowditch_sectors=self.bowditch_sectors,
                                    aertssen_bands=self.aertssen_bands)  # fmt: skip


def _source_files(weather) -> str:
    files = weather.attrs.get("source_files") if weather is not None else None
    if isinstance(files, (list, tuple)):
        files = "; ".join(map(str, files))
    return str(files) if files else "the weather given"


def check_weather_variables(ship: ShipModel, weather: MeshWeather | None) -> None:
    """Refuse weather that lacks the variable the speed-loss model reads.

    Raises
    ------
    routing.errors.WeatherVariableError
        Naming the model, the missing variable and the files, e.g. wind-only weather (GFS, ERA5
        wind) with a wave model, or wave-only weather with Kwon.
    """
    if weather is None or ship.model == "none":
        return
    if ship.wind_driven:
        if "wind_u_ms" not in weather.extra or "wind_v_ms" not in weather.extra:
            raise WeatherVariableError(
                f"speed-loss model {ship.model} needs the 10 m wind (wind_u_ms, wind_v_ms), which the weather lacks "
                f"(files: {_source_files(weather)}); it has {', '.join(_variables(weather)) or 'no variable'}: "
                f"choose --speed-loss bowditch|aertssen|khokhlov (waves) or none"
            )
    elif not weather.has_waves:
        raise WeatherVariableError(
            f"speed-loss model {ship.model} needs the significant wave height (hs_m), which the weather lacks "
            f"(files: {_source_files(weather)}); it has {', '.join(_variables(weather)) or 'no variable'}: "
            f"choose --speed-loss kwon (wind) or none"
        )


@dataclass(frozen=True)
class WeatherArrays:
    """The weather arrays in the layout the compiled core reads (calm zeros where absent).

    ``wave`` is the sea state the speed model reads, ``(mag, cos, sin)`` per slice and sea node:
    Hs [m] and the unit vector of the direction the waves come from for the wave models; for a
    wind-driven model (Kwon) the 10 m wind speed [m/s] and the vector pointing to where the wind
    comes from (``-v``, ``-u``). ``hs`` is always the significant wave height (reports).
    """

    sea_index: np.ndarray
    wave: np.ndarray  # (T, n_sea, 3): the speed model's sea state (see above)
    cur: np.ndarray  # (T, n_sea, 2) current flowing to, kn; (1, 1, 2) zeros when absent
    has_cur: bool
    dt_h: float
    n_times: int
    time0_ns: int | None  # None: calm sea, no time axis
    hs_max_m: float
    current_max_kn: float
    step_time: bool = False
    hs: np.ndarray | None = None  # (T, n_sea) significant wave height, m

    @classmethod
    def build(cls, mesh: Mesh, weather: MeshWeather | None, step_time: bool = False, ship: ShipModel | None = None) -> "WeatherArrays":
        """The arrays for ``ship``'s speed model (default: a wave model); raises
        :class:`~routing.errors.WeatherVariableError` when the weather lacks what it reads."""
        if weather is None:
            sea_index = np.full(mesh.n_nodes, -1, dtype=np.int32)
            sea_index[mesh.sea.ravel()] = np.arange(mesh.n_sea, dtype=np.int32)
            calm = np.zeros((1, mesh.n_sea, 3), dtype=np.float32)
            return cls(sea_index, calm, _NO_CURRENT, False, 1.0, 1, None, 0.0, 0.0, hs=np.zeros((1, mesh.n_sea), dtype=np.float32))
        sea_index = weather.sea_index
        if np.any(sea_index[mesh.sea.ravel()] < 0):
            raise ValueError("mesh has sea nodes without weather rows; build the mesh from this weather's sea mask")
        if ship is not None:
            check_weather_variables(ship, weather)
        has_cur = weather.current is not None
        hs = np.ascontiguousarray(weather.wave[:, :, 0])
        sea = weather.wave
        if ship is not None and ship.wind_driven:
            u, v = weather.extra["wind_u_ms"], weather.extra["wind_v_ms"]
            sea = np.ascontiguousarray(np.stack([np.hypot(u, v), -v, -u], axis=-1), dtype=np.float32)
        return cls(
            sea_index,
            sea,
            weather.current if has_cur else _NO_CURRENT,
            has_cur,
            float(weather.dt_h),
            int(weather.n_times),
            int(weather.time0_ns),
            weather.hs_max_m,
            weather.current_max_kn,
            step_time,
            hs,
        )

    def rel_h(self, t_ns: int) -> float:
        """Hours of ``t_ns`` after the weather's slice 0."""
        return 0.0 if self.time0_ns is None else (int(t_ns) - self.time0_ns) / NS_PER_HOUR


def _variables(weather: MeshWeather) -> list:
    names = (["hs_m"] if weather.has_waves else []) + (["wave_from_deg"] if weather.has_direction else [])
    names += ["current_u_ms", "current_v_ms"] if weather.current is not None else []
    return names + sorted(weather.extra)


@dataclass(frozen=True)
class SearchResult:
    """A grid path and its search statistics."""

    nodes: np.ndarray
    cost: float  # hours (time) or nmi (distance) from the start node; with soft safety hours + penalties
    expanded: int
    scanned: int
    seconds: float
    time_h: float | None = None  # sailing time (time searches)
    exposure_h: float = 0.0  # hours on edges touching unsafe cells (safety searches)
    horizon_hit: bool = False  # the safety flags did not reach far enough in time
    computed: int = 0  # edges whose cost was computed (plain searches; scanned minus edges to closed nodes)


def heuristic_speed_kn(ship: ShipModel, wx: WeatherArrays) -> float:
    """Speed of the A* heuristic: the highest speed through the water any sea state of the weather
    gives (:meth:`ShipModel.max_speed_kn`) plus the strongest current, an upper bound of every
    edge's speed over ground (waiting only slows), so great-circle distance / it never
    overestimates the remaining time. [kn]"""
    return ship.max_speed_kn(wx.hs_max_m) + wx.current_max_kn


def search(
    mesh: Mesh,
    wx: WeatherArrays,
    ship: ShipModel,
    start: int,
    goal: int,
    *,
    t_start_h: float = 0.0,
    cost: str = "time",
    heuristic: bool = True,
    safety: SafetyFlags | None = None,
) -> SearchResult:
    """Least-time (or least-distance) path from node ``start`` to node ``goal``.

    Parameters
    ----------
    t_start_h : float
        Time at the start node, hours after the weather's slice 0 (see :meth:`WeatherArrays.rel_h`).
    cost : {"time", "distance"}
    heuristic : bool
        False runs Dijkstra (same core, zero heuristic).
    safety : SafetyFlags, optional
        Respect the vessel's limits (time searches only; see the module docstring). The start
        and goal nodes are exempt.

    Raises
    ------
    NoRouteError
        When the goal cannot be reached over sea cells of this mesh (with ``hard`` safety: over
        edges that keep within the limits).
    """
    if cost not in ("time", "distance"):
        raise ValueError(f"cost must be 'time' or 'distance', got {cost!r}")
    if safety is not None:
        if cost != "time":
            raise ValueError("safety constraints apply to time searches only")
        return _search_safe(mesh, wx, ship, start, goal, safety, t_start_h=t_start_h, heuristic=heuristic)
    g = mesh.grid
    if not (mesh.sea.ravel()[start] and mesh.sea.ravel()[goal]):
        raise NoRouteError("start or goal node is on land")
    elen, ecos, esin = mesh.edge_geometry
    p = ship.params(wx.step_time, pace_min=1.0 / heuristic_speed_kn(ship, wx))
    distance_mode = cost == "distance"
    if not heuristic:
        h_speed = 0.0
    elif distance_mode:
        h_speed = 1.0
    else:
        h_speed = heuristic_speed_kn(ship, wx)
    t0 = _time.perf_counter()
    gvals, parent, expanded, scanned, computed, reached = _kernels.astar(
        g.nx, mesh.allowed, mesh.steps[:, 0].copy(), mesh.steps[:, 1].copy(), elen, ecos, esin,
        np.deg2rad(g.lat_deg), np.deg2rad(g.lon_deg), wx.sea_index, wx.wave, wx.cur, wx.has_cur, wx.dt_h, wx.n_times, p,
        int(start), int(goal), float(t_start_h), distance_mode, float(h_speed), EARTH_RADIUS_NMI,
    )  # fmt: skip
    seconds = _time.perf_counter() - t0
    if not reached:
        lat_s, lon_s = g.node_latlon(start)
        lat_g, lon_g = g.node_latlon(goal)
        raise NoRouteError(
            f"no sea route from ({lat_s:.4f}, {lon_s:.4f}) to ({lat_g:.4f}, {lon_g:.4f}) on this mesh "
            f"({g.dlat_deg * 60:.3g} nmi, {mesh.edges} edges, bbox {tuple(round(x, 4) for x in g.bbox)}): "
            f"searched {expanded:,} reachable nodes; widen the bbox or refine the mesh"
        )
    nodes = _path_nodes(parent, start, goal)
    total = float(gvals[goal]) - (0.0 if distance_mode else float(t_start_h))
    return SearchResult(nodes, total, int(expanded), int(scanned), seconds,
                        time_h=None if distance_mode else total, computed=int(computed))


def _path_nodes(parent: np.ndarray, start: int, goal: int) -> np.ndarray:
    """Node indices from ``start`` to ``goal`` by following the search's parent links back."""
    nodes = [int(goal)]
    while nodes[-1] != start:
        nodes.append(int(parent[nodes[-1]]))
    nodes.reverse()
    return np.asarray(nodes, dtype=np.int64)


def _search_safe(mesh, wx, ship, start, goal, safety: SafetyFlags, *, t_start_h: float, heuristic: bool) -> SearchResult:
    g = mesh.grid
    if not (mesh.sea.ravel()[start] and mesh.sea.ravel()[goal]):
        raise NoRouteError("start or goal node is on land")
    if safety.unsafe.ndim != 2 or safety.unsafe.shape[1] != wx.wave.shape[1] or safety.unsafe.dtype != np.uint16:
        raise ValueError(f"safety flags {safety.unsafe.shape} {safety.unsafe.dtype} do not match the weather's {wx.wave.shape[1]} sea rows")
    elen, ecos, esin = mesh.edge_geometry
    ebit = edge_bits(mesh, safety.sectors)
    cells, counts = mesh.stencil_cells
    p = ship.params(wx.step_time, pace_min=1.0 / heuristic_speed_kn(ship, wx))
    h_speed = heuristic_speed_kn(ship, wx) if heuristic else 0.0
    t0 = _time.perf_counter()
    gvals, tarr, expo, parent, expanded, scanned, reached, hit = _kernels.astar_safe(
        g.nx, mesh.allowed, mesh.steps[:, 0].copy(), mesh.steps[:, 1].copy(), elen, ecos, esin, ebit, cells, counts,
        np.deg2rad(g.lat_deg), np.deg2rad(g.lon_deg), wx.sea_index, wx.wave, wx.cur, wx.has_cur, wx.dt_h, wx.n_times, p,
        int(start), int(goal), float(t_start_h), float(h_speed), EARTH_RADIUS_NMI, np.ascontiguousarray(safety.unsafe),
        bool(safety.hard), float(safety.penalty_per_h),
    )  # fmt: skip
    seconds = _time.perf_counter() - t0
    if not reached:
        lat_s, lon_s = g.node_latlon(start)
        lat_g, lon_g = g.node_latlon(goal)
        raise NoRouteError(
            f"no route from ({lat_s:.4f}, {lon_s:.4f}) to ({lat_g:.4f}, {lon_g:.4f}) keeps within the vessel's limits on this "
            f"mesh ({g.dlat_deg * 60:.3g} nmi, {mesh.edges} edges): searched {expanded:,} nodes reachable over safe edges"
        )
    nodes = _path_nodes(parent, start, goal)
    return SearchResult(
        nodes, float(gvals[goal]) - float(t_start_h), int(expanded), int(scanned), seconds,
        time_h=float(tarr[goal]) - float(t_start_h), exposure_h=float(expo[goal]), horizon_hit=bool(hit),
    )  # fmt: skip


def edge_bits(mesh: Mesh, sectors: int) -> np.ndarray:
    """Heading-sector bit of every stencil edge, per mesh row (cached on the mesh). (ny, K) uint16"""
    from routing.safety import edge_sector_bits

    cache = mesh.__dict__.setdefault("_edge_bits", {})
    if sectors not in cache:
        cache[sectors] = edge_sector_bits(mesh, sectors)
    return cache[sectors]


def path_exposure(
    mesh: Mesh, wx: WeatherArrays, ship: ShipModel, lat_deg, lon_deg, safety: SafetyFlags, *, exempt=(-1, -1),
    t_start_h: float = 0.0, max_piece_nmi: float | None = None,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Re-time a polyline (as :func:`evaluate_path`) and add up the hours on pieces touching unsafe cells.

    The pieces are those of :func:`evaluate_path` (a grid path: its edges), judged as the search
    judges edges (cells touched, heading sector of the piece's course, slices bracketing its
    time); ``exempt`` nodes (start, goal) are skipped. Returns ``(times, exposure_h, horizon_hit)``
    with the exposure cumulated at each vertex (``exposure_h[-1]`` is the route's).
    """
    g = mesh.grid
    p = ship.params(wx.step_time, pace_min=1.0 / heuristic_speed_kn(ship, wx))
    piece = float(max_piece_nmi if max_piece_nmi is not None else mesh.max_edge_nmi * (1.0 + 1e-9))
    times, _, expo, hit = _kernels.walk_path_safety(
        np.ascontiguousarray(lat_deg, dtype=float), np.ascontiguousarray(lon_deg, dtype=float), float(t_start_h), piece,
        g.lat0_deg, g.lon0_deg, g.dlat_deg, g.dlon_deg, g.ny, g.nx, wx.sea_index, wx.wave, wx.hs, wx.cur, wx.has_cur, wx.dt_h, wx.n_times, p,
        EARTH_RADIUS_NMI, np.ascontiguousarray(safety.unsafe), int(safety.sectors), int(exempt[0]), int(exempt[1]),
    )  # fmt: skip
    return times, expo, bool(hit)


def evaluate_path(
    mesh: Mesh, wx: WeatherArrays, ship: ShipModel, lat_deg, lon_deg, *, t_start_h: float = 0.0, max_piece_nmi: float | None = None
) -> tuple[np.ndarray, float]:
    """Re-time a polyline through the weather: times at each vertex [h after slice 0], max Hs met [m].

    Legs longer than ``max_piece_nmi`` (default: the longest stencil edge, so a grid path is
    timed exactly as the search timed it) are split into equal great-circle pieces.
    """
    g = mesh.grid
    p = ship.params(wx.step_time, pace_min=1.0 / heuristic_speed_kn(ship, wx))
    piece = float(max_piece_nmi if max_piece_nmi is not None else mesh.max_edge_nmi * (1.0 + 1e-9))
    times, hs_max = _kernels.eval_path(
        np.ascontiguousarray(lat_deg, dtype=float), np.ascontiguousarray(lon_deg, dtype=float), float(t_start_h), piece,
        g.lat0_deg, g.lon0_deg, g.dlat_deg, g.dlon_deg, g.ny, g.nx, wx.sea_index, wx.wave, wx.hs, wx.cur, wx.has_cur, wx.dt_h, wx.n_times, p, EARTH_RADIUS_NMI,
    )  # fmt: skip
    return times, float(hs_max)


def smooth(
    mesh: Mesh, wx: WeatherArrays, ship: ShipModel, lat_deg, lon_deg, raw_times_h, *, max_piece_nmi: float | None = None,
    safety: SafetyFlags | None = None, exempt=(-1, -1), raw_exposure_h=None,
) -> np.ndarray:
    """Indices of the waypoints kept by any-angle smoothing (see :func:`routing._kernels.smooth_path`).

    A waypoint is removed when the direct great-circle leg that skips it crosses only sea cells
    and does not arrive later than the raw path: the smoothed route is never slower. With
    ``safety`` the direct leg must also keep the hours in unsafe cells at or below the raw
    route's up to the waypoint it reaches (``raw_exposure_h``, cumulated per waypoint, from
    :func:`path_exposure`; default zeros: the leg must touch no unsafe cell); ``exempt``: the
    start and goal nodes.
    """
    g = mesh.grid
    p = ship.params(wx.step_time, pace_min=1.0 / heuristic_speed_kn(ship, wx))
    px = mesh._px()
    piece = float(max_piece_nmi if max_piece_nmi is not None else mesh.max_edge_nmi * (1.0 + 1e-9))
    if safety is not None:
        raw_ex = np.zeros(np.size(lat_deg)) if raw_exposure_h is None else np.ascontiguousarray(raw_exposure_h, dtype=float)
        return _kernels.smooth_path_safe(
            np.ascontiguousarray(lat_deg, dtype=float), np.ascontiguousarray(lon_deg, dtype=float),
            np.ascontiguousarray(raw_times_h, dtype=float), raw_ex, piece, g.lat0_deg, g.lon0_deg, g.dlat_deg, g.dlon_deg,
            g.ny, g.nx, mesh.cell_ok, mesh.cell_clean, px[0], px[1], px[2], px[3], px[4],
            0.5 * mesh.min_cell_nmi, wx.sea_index, wx.wave, wx.hs, wx.cur, wx.has_cur, wx.dt_h, wx.n_times, p, EARTH_RADIUS_NMI,
            np.ascontiguousarray(safety.unsafe), int(safety.sectors), int(exempt[0]), int(exempt[1]),
        )  # fmt: skip
    return _kernels.smooth_path(
        np.ascontiguousarray(lat_deg, dtype=float), np.ascontiguousarray(lon_deg, dtype=float),
        np.ascontiguousarray(raw_times_h, dtype=float), piece, g.lat0_deg, g.lon0_deg, g.dlat_deg, g.dlon_deg,
        g.ny, g.nx, mesh.cell_ok, mesh.cell_clean, px[0], px[1], px[2], px[3], px[4],
        0.5 * mesh.min_cell_nmi, wx.sea_index, wx.wave, wx.hs, wx.cur, wx.has_cur, wx.dt_h, wx.n_times, p, EARTH_RADIUS_NMI,
    )  # fmt: skip


def reachable(mesh: Mesh, start: int) -> np.ndarray:
    """Nodes reachable from ``start`` over allowed edges (bool per node)."""
    return _kernels.component_from(int(start), mesh.allowed, mesh.steps[:, 0].copy(), mesh.steps[:, 1].copy(), mesh.grid.nx)
