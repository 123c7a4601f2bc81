"""Least-fuel (and least-CO2) routes with a speed setting per edge and an arrival deadline.

What is optimised (the model; the algorithm and its proof are in :mod:`routing._kernels.fuel`):
on each mesh edge the ship runs one calm-water speed setting out of :attr:`FuelSpec.speeds_kn`,
slowed by the speed-loss model of the plan evaluated *at that setting*; it may wait at nodes; its
fuel is the STEAM2 fuel rate of the setting over the edge's sailing time. The fuel rate of a
setting s is :func:`routing.emissions.steam2_legs` of one hour at s:
``P(s) = EL * P_installed * (s / v_design)^3`` (STEAM2 [1], Eq. 4-5), ``SFOC = SFOC_rel(P/P_inst) *
SFOC_base`` ([2], Eq. 6), the weather charged once through the slowed time
(:func:`routing.emissions.leg_power_kw`: the power that makes ``s - loss`` in waves costing
``loss`` is ``P(s)``, [3] Eq. 2-3). CO2 is ``fuel * CC * M(CO2) / M(C)`` (mass balance), a constant
multiple of the fuel for one fuel, so the least-CO2 route *is* the least-fuel route.

No setting may exceed the engine's maximum continuous power: ``P(s) <= P_installed``, i.e.
``s <= v_design * EL^(-1/3)`` (:func:`max_power_speed_kn`); since the wave increase restores the
setting's own power, that also bounds the power in waves.

Fair savings (:func:`same_arrival_reference`): the reference of every saving is the
minimum-distance route sailed at the one constant setting that arrives at the optimised route's
arrival time (found by bisection), so both arrive together; a saving against a route arriving at
a different time is never reported.

References
----------
.. [1] J.-P. Jalkanen et al., Atmos. Chem. Phys. 9, 9209-9223, 2009, doi:10.5194/acp-9-9209-2009.
.. [2] J.-P. Jalkanen et al., Atmos. Chem. Phys. 12, 2641-2659, 2012, doi:10.5194/acp-12-2641-2012.
.. [3] M. Grifoll et al., Ocean Eng. 255, 111427, 2022, doi:10.1016/j.oceaneng.2022.111427.
"""

from __future__ import annotations

import dataclasses
import functools
import time as _time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from routing._kernels.fuel import fuel_bound, fuel_search, goal_distances, goal_gc_distances
from routing.astar import ShipModel, WeatherArrays, evaluate_path, heuristic_speed_kn, search
from routing.emissions import M_C_G_MOL, M_CO2_G_MOL, Engine, steam2_legs, steam2_totals
from routing.errors import NoRouteError
from routing.field import NS_PER_HOUR
from routing.mesh import Mesh
from thresholds.units import EARTH_RADIUS_NMI

#: Default number of speed settings (``--speed-steps``) and the default lowest setting as a
#: fraction of the service speed (slow steaming down to 60 %: IMO Fourth GHG Study 2020, the
#: container fleet's 2012-2018 speed reductions reached about 0.6-0.7 of design speed).
DEFAULT_SPEED_STEPS = 8
DEFAULT_LOW_FRAC = 0.6
#: Routes of the time-fuel front reported with ``--pareto``.
DEFAULT_PARETO_ROUTES = 6
#: Time buckets per quarter-hour sub-slice of the labels (3 min for hourly weather).
DEFAULT_BUCKETS_PER_SUBSLICE = 5
#: Labels the search may create before it stops with an error (about 45 bytes each).
DEFAULT_MAX_LABELS = 20_000_000
#: Default fuel resolution (fraction of the known route's fuel) and corridor width (see :class:`FuelSpec`).
DEFAULT_FUEL_RESOLUTION_FRAC = 1e-4
DEFAULT_CORRIDOR = 0
#: Labels remembered per node for pruning at push time (:func:`routing._kernels.fuel._front_dominated`).
DEFAULT_FRONT_CAP = 16
#: Arrival tolerance of the same-arrival reference (bisection on its constant setting). [h]
ARRIVAL_TOL_H = 1.0 / 60.0
#: Slowest constant setting of a same-arrival reference when no settings bound it (the audit's sailed track). [kn]
REFERENCE_MIN_KN = 0.5


class InfeasibleArrivalError(NoRouteError):
    """No route arrives by the requested time; the message gives the earliest possible arrival."""


def max_power_speed_kn(engine: Engine) -> float:
    """Calm-water speed at the installed power: ``v_design * EL^(-1/3)`` (STEAM2's cubic law, [1] Eq. 4-5, inverted). [kn]"""
    return float(engine.design_speed_kn * engine.engine_load_frac ** (-1.0 / 3.0))


def fuel_rates_t_per_h(speeds_kn, engine: Engine) -> np.ndarray:
    """Fuel rate of each setting: :func:`routing.emissions.steam2_legs` of one hour at it in calm water. [t/h]
    (Remembered per settings and engine: a plan asks for the same rates many times, a table each.)"""
    s = np.asarray(speeds_kn, dtype=float)
    if s.ndim == 1:
        try:
            return _rates_t_per_h(tuple(s.tolist()), engine).copy()
        except TypeError:  # an engine that cannot be a key (unhashable field): computed each time
            pass
    return steam2_legs(np.ones_like(s), s, np.zeros_like(s), engine)["fuel_t"].to_numpy()


@functools.lru_cache(maxsize=256)
def _rates_t_per_h(speeds_kn: tuple, engine: Engine) -> np.ndarray:
    s = np.asarray(speeds_kn, dtype=float)
    return steam2_legs(np.ones_like(s), s, np.zeros_like(s), engine)["fuel_t"].to_numpy()


def co2_per_fuel(engine: Engine) -> float:
    """Tonnes of CO2 per tonne of fuel: ``CC * M(CO2) / M(C)`` (the factor of :func:`routing.emissions.steam2_legs`)."""
    return engine.carbon_frac * M_CO2_G_MOL / M_C_G_MOL


def speed_settings(vessel, engine: Engine, speeds=None, speed_range=None, steps: int | None = None) -> tuple:
    """The speed settings [kn]: ``speeds`` as given, or ``steps`` evenly over ``speed_range``
    (default ``DEFAULT_LOW_FRAC`` of the service speed up to the speed at maximum power); the
    service speed is added to the defaults (so the time-optimal route's schedule is one of the
    choices). Raises ValueError naming the setting above the engine's maximum power."""
    v_max = max_power_speed_kn(engine)
    if speeds is not None:
        out = sorted({float(s) for s in speeds})
    else:
        lo, hi = speed_range if speed_range is not None else (DEFAULT_LOW_FRAC * float(vessel.speed_kn), v_max)
        k = int(steps or DEFAULT_SPEED_STEPS)
        if k < 1 or not (0.0 < lo <= hi):
            raise ValueError(f"speed range {lo:g}..{hi:g} kn with {k} steps is not a range of positive speeds")
        if speed_range is not None and hi > v_max * (1.0 + 1e-9):
            raise ValueError(f"speed range MAX {hi:g} kn is above vessel {vessel.name}'s maximum-power speed {v_max:.2f} kn "
                             f"({engine.installed_power_kw:g} kW installed, {engine.design_speed_kn:g} kn at {engine.engine_load_frac:g} MCR)")
        grid = np.round(np.linspace(lo, hi, k), 6)
        if speed_range is None:  # the default range ends at the maximum-power speed: only its rounding is clipped
            grid = np.minimum(grid, v_max)
        # a given range is not clipped: a MAX above the maximum-power speed is refused below, as in --speeds (before: cut
        # to it without a word, --speed-range 10,30 sailing 21.43 and 21.46 kn)
        out = sorted(set(grid.tolist()) | ({float(vessel.speed_kn)} if speed_range is None else set()))
    for s in out:
        if not s > 0.0:
            raise ValueError(f"speed setting {s:g} kn is not positive")
        if s > v_max * (1.0 + 1e-9):
            raise ValueError(f"speed setting {s:g} kn is above vessel {vessel.name}'s maximum-power speed {v_max:.2f} kn "
                             f"({engine.installed_power_kw:g} kW installed, {engine.design_speed_kn:g} kn at {engine.engine_load_frac:g} MCR)")
    return tuple(out)


@dataclass(frozen=True)
class FuelSpec:
    """What the least-fuel search needs: the settings, the engine, the arrival deadline.

    ``arrive_by``: None = the time-optimal route's arrival (at the service speed). ``objective``
    ``"co2"`` gives the same route (CO2 is proportional to fuel) and reports CO2 first.
    ``buckets_per_subslice``: the label time resolution (tau / k, see :mod:`routing._kernels.fuel`).
    ``between_settings``: the settings sample a continuous range (``--speed-range``, the vessel's defaults), so
    a route at one constant speed between them that arrives exactly at the deadline is a candidate too
    (:func:`routing.planner_fuel._deadline_candidates`); False for a set of discrete settings (``--speeds``),
    the model whose optimum the search's lower bound and the brute-force tests prove.
    """

    speeds_kn: tuple
    engine: Engine
    arrive_by: pd.Timestamp | None = None
    objective: str = "fuel"
    buckets_per_subslice: int = DEFAULT_BUCKETS_PER_SUBSLICE
    max_labels: int = DEFAULT_MAX_LABELS
    pareto: int = 0  # > 0: also that many routes of the time-fuel front
    #: Fuel resolution as a fraction of the reference fuel (``eps_f`` of :mod:`routing._kernels.fuel`; 0: exact dominance).
    fuel_resolution_frac: float = DEFAULT_FUEL_RESOLUTION_FRAC
    #: The graph searched: None the whole mesh; w >= 0 the corridor of :func:`corridor_edges` (w grid steps around the
    #: time-optimal paths of every setting and the minimum-distance path).
    corridor: int | None = DEFAULT_CORRIDOR
    between_settings: bool = True

    def __post_init__(self):
        if self.objective not in ("fuel", "co2"):
            raise ValueError(f"objective must be 'fuel' or 'co2' here, got {self.objective!r}")
        if not self.speeds_kn:
            raise ValueError("at least one speed setting is needed")


def lower_envelope(x, y) -> tuple[np.ndarray, np.ndarray]:
    """Lower convex envelope of the points (0, 0) and (x_i, y_i), up to the largest x (monotone chain)."""
    pts = sorted({(0.0, 0.0)} | {(float(a), float(b)) for a, b in zip(x, y)})
    hull: list = []
    for p in pts:
        while len(hull) >= 2 and (hull[-1][0] - hull[-2][0]) * (p[1] - hull[-2][1]) - (hull[-1][1] - hull[-2][1]) * (p[0] - hull[-2][0]) <= 0:
            hull.pop()
        hull.append(p)
    return np.array([p[0] for p in hull]), np.array([p[1] for p in hull])


@dataclass
class FuelProblem:
    """One search's inputs on a built mesh: the settings' parameter vectors and fuel rates, and the
    fuel bound's envelope over (highest speed over ground, rate) of every setting."""

    mesh: Mesh
    wx: WeatherArrays
    ships: list
    P: np.ndarray
    rate: np.ndarray
    hull_x: np.ndarray
    hull_y: np.ndarray

    @classmethod
    def build(cls, mesh: Mesh, wx: WeatherArrays, ship: ShipModel, spec: FuelSpec) -> "FuelProblem":
        ships = [dataclasses.replace(ship, speed_kn=float(s)) for s in spec.speeds_kn]
        tops = np.array([heuristic_speed_kn(sh, wx) for sh in ships])
        P = np.stack([sh.params(wx.step_time, pace_min=1.0 / tops.max()) for sh in ships])
        rate = fuel_rates_t_per_h(spec.speeds_kn, spec.engine)
        hx, hy = lower_envelope(tops, rate)
        return cls(mesh, wx, ships, P, rate, hx, hy)

    allowed: np.ndarray | None = None  # the edges searched (default the mesh's): see :func:`corridor_edges`

    def goal_distances(self, goal: int) -> np.ndarray:
        """Every node's shortest distance [nmi] to ``goal`` over the searched edges (:func:`routing._kernels.fuel.goal_distances`),
        kept for the next search to the same goal on the same edges."""
        allowed = self.mesh.allowed if self.allowed is None else self.allowed
        key = self._dist_key
        if key is None or key[0] is not allowed or key[1] != int(goal):
            g, m = self.mesh.grid, self.mesh
            self._dist = goal_distances(g.nx, allowed, m.steps[:, 0].copy(), m.steps[:, 1].copy(), m.edge_geometry[0], int(goal))
            self._dist_key = (allowed, int(goal))
        return self._dist

    def gc_distances(self, goal: int) -> np.ndarray:
        """Every node's great-circle distance [nmi] to ``goal``: the search's pruning distance (kept per goal)."""
        if self._gc is None or self._gc[0] != int(goal):
            g = self.mesh.grid
            d = goal_gc_distances(g.nx, self.mesh.allowed.size, np.deg2rad(g.lat_deg), np.deg2rad(g.lon_deg), int(goal), EARTH_RADIUS_NMI)
            self._gc = (int(goal), d)
        return self._gc[1]

    _gc: tuple | None = dataclasses.field(default=None, repr=False, compare=False)
    _dist_key: tuple | None = dataclasses.field(default=None, repr=False, compare=False)
    _dist: np.ndarray | None = dataclasses.field(default=None, repr=False, compare=False)

    def run(self, start: int, goal: int, t_h: float, f0: float, deadline_h: float, k: int, relax: bool, max_labels: int,
            f_upper: float = np.inf, front_cap: int = DEFAULT_FRONT_CAP, eps_f: float = 0.0, stop_below: float = -np.inf):
        g, m = self.mesh.grid, self.mesh
        allowed = m.allowed if self.allowed is None else self.allowed
        elen, ecos, esin = m.edge_geometry
        wx = self.wx
        return fuel_search(
            g.nx, allowed, m.steps[:, 0].copy(), m.steps[:, 1].copy(), elen, ecos, esin, self.gc_distances(goal),
            wx.sea_index, wx.wave, wx.cur, wx.has_cur, wx.dt_h, wx.n_times, self.P, self.rate, int(start), int(goal), float(t_h),
            float(f0), float(deadline_h), int(k), bool(relax), self.hull_x, self.hull_y, float(f_upper), int(max_labels),
            int(front_cap), float(eps_f), float(stop_below),
        )  # fmt: skip

    def envelope_bound(self, start: int, goal: int, t_h: float, f0: float, deadline_h: float) -> float:
        """``f0`` plus the least fuel that covers the start's shortest distance to the goal over the searched edges
        by the deadline (:func:`routing._kernels.fuel.fuel_bound`: the settings' envelope, Jensen): a lower bound of
        every route of the graph searched, without a search."""
        return float(f0) + float(fuel_bound(self.goal_distances(goal)[start], deadline_h - t_h, self.hull_x, self.hull_y))


def corridor_edges(mesh: Mesh, paths, width: int = 0) -> np.ndarray:
    """The mesh's edge masks restricted to a corridor: the edges of the given node paths, and with
    ``width`` > 0 every mesh edge between nodes within ``width`` grid steps (Chebyshev) of a path node."""
    g = mesh.grid
    out = np.zeros_like(mesh.allowed)
    steps = mesh.steps
    target = {(int(d[0]), int(d[1])): k for k, d in enumerate(steps)}
    for path in paths:
        path = np.asarray(path, dtype=np.int64)
        for u, v in zip(path[:-1], path[1:]):
            if u == v:
                continue
            key = (int(v % g.nx - u % g.nx), int(v // g.nx - u // g.nx))
            out[u] |= np.uint64(1) << np.uint64(target[key])
    if width > 0:
        inside = np.zeros((g.ny, g.nx), dtype=bool)
        for path in paths:
            jj, ii = np.asarray(path) // g.nx, np.asarray(path) % g.nx
            for dy in range(-width, width + 1):
                for dx in range(-width, width + 1):
                    inside[np.clip(jj + dy, 0, g.ny - 1), np.clip(ii + dx, 0, g.nx - 1)] = True
        flat = inside.ravel()
        nodes = np.flatnonzero(flat)
        j, i = nodes // g.nx, nodes % g.nx
        for k, (di, dj) in enumerate(steps):
            jv, iv = j + int(dj), i + int(di)
            ok = (jv >= 0) & (jv < g.ny) & (iv >= 0) & (iv < g.nx)
            ok[ok] &= flat[jv[ok] * g.nx + iv[ok]]
            bit = np.uint64(1) << np.uint64(k)
            sel = nodes[ok]
            out[sel] |= mesh.allowed[sel] & bit
    return out


@dataclass
class Schedule:
    """A label chain as a schedule: mesh nodes, times [h after slice 0] at each vertex, the setting
    of each leg (NaN for a wait at a node), and the fuel of the kernel's sum."""

    nodes: np.ndarray
    times_h: np.ndarray
    setting_kn: np.ndarray
    fuel_t: float


def schedule_of(out, lab: int, speeds_kn) -> Schedule:
    """Follow the parents of label ``lab`` back to the start label."""
    lt, lf, lnode, lpar, lspd = out[0], out[1], out[2], out[3], out[4]
    chain = []
    while lab >= 0:
        chain.append(lab)
        lab = int(lpar[lab])
    chain.reverse()
    nodes = np.array([lnode[c] for c in chain], dtype=np.int64)
    times = np.array([lt[c] for c in chain], dtype=float)
    setting = np.array([np.nan if lspd[c] < 0 else speeds_kn[lspd[c]] for c in chain[1:]], dtype=float)
    return Schedule(nodes, times, setting, float(lf[chain[-1]]))


@dataclass
class FuelResult:
    """The least-fuel schedule of one search pair, its bound and the front."""

    schedule: Schedule | None  # None: no route below the known one (``f_upper``)
    lower_bound_t: float
    front: list  # Schedules of the time-fuel front, earliest first
    labels: int
    seconds: float


def least_fuel(prob: FuelProblem, start: int, goal: int, t_h: float, f0: float, deadline_h: float, spec: FuelSpec,
               *, bound: bool = True, earliest=None, f_upper: float = np.inf) -> FuelResult:
    """The least-fuel schedule from ``start`` (at ``t_h`` with ``f0`` fuel) to ``goal`` by ``deadline_h``,
    and (``bound``) the relaxation's lower bound. Raises :class:`InfeasibleArrivalError` (with the
    earliest possible arrival from ``earliest()``, a callable giving it as text) when nothing arrives in time."""
    t0 = _time.perf_counter()
    k = spec.buckets_per_subslice
    scale = f_upper if np.isfinite(f_upper) else float(prob.rate.max()) * max(deadline_h - t_h, 0.0)
    eps = spec.fuel_resolution_frac * scale
    out = prob.run(start, goal, t_h, f0, deadline_h, k, False, spec.max_labels, f_upper, eps_f=eps)
    if out[9] == 1:
        raise NoRouteError(f"the least-fuel search stopped at its label budget ({spec.max_labels:,} labels): use fewer speed settings, "
                           "a coarser mesh or fewer buckets (--fuel-buckets)")
    n_goal = int(out[7])
    if n_goal == 0 and not np.isfinite(f_upper):
        raise InfeasibleArrivalError("no route arrives by the requested time" + (f": the earliest possible arrival is {earliest()}" if earliest else ""))
    goal_labels = out[6][:n_goal]
    best = schedule_of(out, int(goal_labels[-1]), prob_speeds(prob)) if n_goal else None  # None: nothing beats f_upper
    front = [schedule_of(out, int(lab), prob_speeds(prob)) for lab in goal_labels] if spec.pareto else []
    labels = int(out[5])
    del out  # the route's labels are no longer needed: free them before the relaxation allocates its own
    lb = float("nan")
    if bound:
        # the lower bound is the better of the settings' envelope over the shortest distance (no search) and the
        # relaxation's optimum. The relaxation only needs to look below the best known fuel (when it finds nothing
        # there, that fuel is optimal), and it stops at a goal label within the envelope's bound (which it cannot beat then)
        known = min(f_upper, best.fuel_t) if best is not None else f_upper
        lb = prob.envelope_bound(start, goal, t_h, f0, deadline_h)
        if best is None or not _relaxation_reaches(prob, best, start, goal, t_h, f0, deadline_h, k, spec, known, eps, lb):
            rel = prob.run(start, goal, t_h, f0, deadline_h, k, True, spec.max_labels, known, eps_f=eps, stop_below=lb)
            if rel[9] == 0:
                lb = max(lb, float(rel[1][rel[6][rel[7] - 1]]) if rel[7] > 0 else float(known))
        lb = min(lb, float(known))
    return FuelResult(best, lb, front, labels, _time.perf_counter() - t0)


def _relaxation_reaches(prob: FuelProblem, best: Schedule, start, goal, t_h, f0, deadline_h, k, spec: FuelSpec, known, eps, lb) -> bool:
    """Does the relaxation on the found route's own path (its edges only) reach a goal label within ``lb``? Then so does
    the relaxation on the whole graph searched (a subgraph's relaxed optimum is never below the graph's: every relaxed
    label of the subgraph is dominated by one of the graph, by the induction of :mod:`routing._kernels.fuel`), and the
    graph's relaxation cannot beat ``lb``: it need not run. The path is short, so this costs a fraction of the graph's."""
    path = dataclasses.replace(prob, allowed=corridor_edges(prob.mesh, [best.nodes]))
    out = path.run(start, goal, t_h, f0, deadline_h, k, True, spec.max_labels, known, eps_f=eps, stop_below=lb)
    return int(out[9]) == 2


def prob_speeds(prob: FuelProblem) -> list:
    return [sh.speed_kn for sh in prob.ships]


def earliest_arrival_h(mesh: Mesh, wx: WeatherArrays, prob: FuelProblem, start: int, goal: int, t_h: float) -> float:
    """Earliest arrival at ``goal`` with the fastest setting (the time-optimal search). [h after slice 0]"""
    fastest = max(prob.ships, key=lambda s: s.speed_kn)
    return t_h + search(mesh, wx, fastest, start, goal, t_start_h=t_h, cost="time").time_h


def legs_fuel(leg_time_h, setting_kn, engine: Engine) -> pd.DataFrame:
    """STEAM2 legs of a schedule: each leg at its setting over its time, waits (NaN setting) burn nothing."""
    s = np.nan_to_num(np.asarray(setting_kn, dtype=float), nan=0.0)
    return steam2_legs(np.asarray(leg_time_h, dtype=float), s, np.zeros_like(s), engine)


def retime_constant(mesh: Mesh, wx: WeatherArrays, ship: ShipModel, lat, lon, t_h: float, speed_kn: float) -> np.ndarray:
    """Times at the vertices of a polyline sailed at one constant setting, never waiting. [h after slice 0]"""
    s = dataclasses.replace(ship, speed_kn=float(speed_kn), wait=False)
    return evaluate_path(mesh, wx, s, lat, lon, t_start_h=t_h)[0]


def same_arrival_reference(mesh: Mesh, wx: WeatherArrays, ship: ShipModel, lat, lon, t_h: float, arrive_h: float, engine: Engine,
                           lo_kn: float = REFERENCE_MIN_KN):
    """The constant setting at which the polyline (the minimum-distance route) arrives at ``arrive_h``,
    by bisection on the setting between ``lo_kn`` and the maximum-power speed (the arrival falls as the
    setting rises). Returns ``(setting_kn, times_h, fuel_t)``, or None when no setting arrives
    within :data:`ARRIVAL_TOL_H` of it (too early even at ``lo_kn``, or too late at maximum power).

    ``lo_kn``: the slowest setting the compared route may use (its lowest offered setting), so the reference is
    sailed by the same model: below it a reference could beat a least-fuel route the settings forbid to sail as
    slowly (a loose deadline: -15.5 % on a storm the least-fuel route waits out at its 10 kn floor while the
    reference crawls through it at 7.9 kn)."""
    lo, hi = float(lo_kn), max_power_speed_kn(engine)
    t_hi = retime_constant(mesh, wx, ship, lat, lon, t_h, hi)
    if t_hi[-1] > arrive_h + ARRIVAL_TOL_H:
        return None
    t_lo = retime_constant(mesh, wx, ship, lat, lon, t_h, lo)
    if t_lo[-1] < arrive_h - ARRIVAL_TOL_H:
        return None
    times = t_hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        times = retime_constant(mesh, wx, ship, lat, lon, t_h, mid)
        if times[-1] > arrive_h:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-9:
            break
    times = retime_constant(mesh, wx, ship, lat, lon, t_h, hi)
    if abs(times[-1] - arrive_h) > ARRIVAL_TOL_H:
        return None
    fuel = steam2_totals(legs_fuel(np.diff(times), np.full(times.size - 1, hi), engine))["fuel_t"]
    return hi, times, fuel


def rel_hours(wx: WeatherArrays, when) -> float:
    """Hours of a timestamp after the weather's slice 0."""
    return wx.rel_h(int(pd.Timestamp(when).value))


def at_utc(wx: WeatherArrays, t_h: float) -> pd.Timestamp:
    """The time ``t_h`` hours after the weather's slice 0, to the second."""
    return pd.Timestamp(int(round((wx.time0_ns or 0) + t_h * NS_PER_HOUR)), tz="UTC").round("s")


def fuel_summary(fuel_t: float, engine: Engine) -> dict:
    """Fuel and CO2 of a route [t]."""
    return {"fuel_t": round(float(fuel_t), 9), "co2_t": round(float(fuel_t) * co2_per_fuel(engine), 9)}


def saving_pct(reference_t: float, value_t: float) -> float:
    """Saving against the reference, percent of the reference's fuel."""
    return float(100.0 * (reference_t - value_t) / reference_t) if reference_t > 0 else float("nan")


