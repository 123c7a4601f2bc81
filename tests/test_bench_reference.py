"""The plain-Python time-dependent Dijkstra of the benchmarks (bench/_td_reference.py) computes
what the compiled core computes: the same optimal time, the same number of expanded nodes and of
edges whose cost was computed, on a small mesh through a moving storm (so that the cost of an
edge depends on the time it is entered)."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench import _routing_cases as cases  # noqa: E402
from bench._td_reference import td_dijkstra  # noqa: E402
from routing.astar import ShipModel, WeatherArrays, search  # noqa: E402
from routing.planner import RouteRequest  # noqa: E402


@pytest.mark.parametrize("speed_kn", [12.0, 16.1])
def test_reference_equals_the_compiled_core(speed_kn):
    field = cases.make_storm_field(lat_range=(37.5, 42.0), lon_range=(0.0, 6.0))
    req = RouteRequest(cases.SMALL_START, cases.SMALL_GOAL, pd.Timestamp(cases.MED_T0) + pd.Timedelta("6h"),
                       ShipModel(speed_kn, "bowditch"), spacing_deg=0.2, bbox=cases.SMALL_BBOX, edges=16)
    st = cases.prepared_mesh(field, req)
    ours = search(st["mesh"], st["wx"], st["ship"], st["start"], st["goal"], t_start_h=st["t0_h"], heuristic=False)
    ref = td_dijkstra(st["mesh"], st["wx"], speed_kn, st["ship"].floor_kn, st["start"], st["goal"], st["t0_h"])
    assert ref["time_h"] == pytest.approx(ours.time_h, rel=1e-12)
    assert (ref["expanded"], ref["computed"]) == (ours.expanded, ours.computed)
    # the storm matters on this mesh (the costs depend on the weather met): slower than in calm water
    calm = search(st["mesh"], WeatherArrays.build(st["mesh"], None), st["ship"], st["start"], st["goal"], heuristic=False)
    assert ours.time_h > calm.time_h * 1.01 and ours.expanded > 100
