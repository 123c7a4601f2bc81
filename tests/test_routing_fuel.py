"""Least-fuel routes with a speed setting per edge and an arrival deadline (issue 20).

The brute force is written here from the model as documented in routing._kernels.fuel, with the
travel times of test_routing_optimality's numpy reference (routing.speed_loss's functions, not the
compiled kernels): it enumerates every simple path, every setting of every edge and every wait (at
a node the ship leaves at once or at the start of any later quarter-hour piece before the
deadline), and keeps the least fuel arriving in time.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_routing_optimality import SUBSTEP_H, build, random_weather, ship_for, slice_costs

from routing.astar import search
from routing.emissions import Engine
from routing.fuel import FuelProblem, FuelSpec, InfeasibleArrivalError, fuel_rates_t_per_h, legs_fuel, least_fuel

ENGINE = Engine(installed_power_kw=9000.0, design_speed_kn=16.0, engine_load_frac=0.8, sfoc_g_kwh=185.0)
SPEEDS = (8.0, 12.0, 16.0)


def neighbours(costs):
    out = {}
    for (u, v) in costs:
        out.setdefault(u, []).append(v)
    return out


def brute_force_fuel(costs_by_speed, rates, start, goal, t0, deadline):
    """Least fuel over every simple path x setting x wait arriving by ``deadline`` (inf if none)."""
    nb = neighbours(costs_by_speed[0])
    n_sub = next(iter(costs_by_speed[0].values())).size
    best = [math.inf]

    def piece(t):
        return min(max(int(math.floor(t / SUBSTEP_H + 0.5)), 0), n_sub - 1)

    def go(u, t, f, seen):
        if f >= best[0]:
            return
        if u == goal:
            best[0] = f
            return
        j = piece(t)
        departs = [(t, j)] + [((jj - 0.5) * SUBSTEP_H, jj) for jj in range(j + 1, n_sub) if (jj - 0.5) * SUBSTEP_H <= deadline]
        for v in nb.get(u, ()):
            if v in seen:
                continue
            for s, costs in enumerate(costs_by_speed):
                c_all = costs[(u, v)]
                for d, jj in departs:
                    a = d + c_all[jj]
                    if a <= deadline + 1e-9:
                        go(v, a, f + rates[s] * c_all[jj], seen | {v})

    go(start, t0, 0.0, {start})
    return best[0]


def setup(seed, model="bowditch", ny=3, nx=3, n_times=5, currents=False):
    grid, field, rng = random_weather(seed, ny, nx, n_times, currents=currents)
    ship = ship_for(model, speed_kn=12.0)
    mesh, wx = build(grid, field, ship)
    spec = FuelSpec(SPEEDS, ENGINE, corridor=None)
    prob = FuelProblem.build(mesh, wx, ship, spec)
    costs = [slice_costs(mesh, wx, sh) for sh in prob.ships]
    return mesh, wx, ship, spec, prob, costs, rng


@pytest.mark.parametrize("model", ["bowditch", "aertssen", "khokhlov"])
def test_least_fuel_equals_brute_force_and_lies_within_its_gap(model):
    for seed in range(3):
        mesh, wx, ship, spec, prob, costs, rng = setup(seed, model)
        start, goal = 0, mesh.n_nodes - 1
        t0 = float(rng.uniform(0.0, 1.0))
        fastest = search(mesh, wx, prob.ships[-1], start, goal, t_start_h=t0).time_h  # earliest arrival (brute-forced in test_routing_optimality)
        for slack in (1.05, 1.4, 2.0):
            deadline = t0 + slack * fastest
            ref = brute_force_fuel(costs, prob.rate, start, goal, t0, deadline)
            res = least_fuel(prob, start, goal, t0, 0.0, deadline, spec)
            assert res.lower_bound_t <= ref + 1e-9 <= res.schedule.fuel_t + 2e-9, (seed, slack)
            assert res.schedule.times_h[-1] <= deadline + 1e-9
            fine = least_fuel(prob, start, goal, t0, 0.0, deadline, FuelSpec(SPEEDS, ENGINE, buckets_per_subslice=100_000, fuel_resolution_frac=0.0))
            assert fine.schedule.fuel_t == pytest.approx(ref, rel=1e-9), (seed, slack)
