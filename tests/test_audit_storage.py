"""The results tables: audits, their routes and events, deviations (write-read round trips)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pipelines.storage import open_workspace
from pipelines.storage.results import (
    read_audit_events,
    read_audit_routes,
    read_audit_summary,
    read_deviation_route,
    read_deviations,
    write_audit,
    write_deviation,
)
from routing.evaluate import evaluate_route
from routing.route import Route
from thresholds.operator import OperatorLimits
from thresholds.vessel import Vessel

T0 = pd.Timestamp("2025-01-15T00:00Z")
VESSEL = Vessel(
    name="t", vessel_class="container", speed_kn=12.0, lpp_m=100.0, beam_m=16.0, draught_m=6.0, dwt_t=8000.0,
    installed_power_kw=6000.0, design_speed_kn=15.0, engine_rpm=500.0, sfoc_g_kwh=200.0,
)


def weather(times, lat, lon):
    h = (pd.DatetimeIndex(times) - T0) / pd.Timedelta(hours=1)
    hs = np.where((h >= 1.0) & (h < 3.0), 6.0, 1.0)
    return {"hs_m": hs, "wave_from_deg": np.full(hs.size, 270.0), "tm_s": np.full(hs.size, 5.0)}


def route(name, lat):
    times = T0 + pd.to_timedelta([0.0, 2.0, 4.0], unit="h")
    return Route(name, [lat, lat, lat], [0.0, 0.5, 1.0], times, [11.5, 11.5])


def test_audit_round_trip(workspace_path):
    evs = {role: evaluate_route(route(role, lat), weather, VESSEL, limits=OperatorLimits(name="t", hs_max_m=4.5))
           for role, lat in (("historical", 40.0), ("optimal", 40.2))}
    with open_workspace(workspace_path) as ws:
        write_audit(ws, "a1", mmsi=219000001, voyage_id="v7", depart_utc=T0, arrive_utc=T0 + pd.Timedelta(hours=4),
                    vessel="t", weather=["x.nc"], summary={"note": "ok", "nan": float("nan")}, evaluations=evs)
        write_audit(ws, "a1", mmsi=219000001, summary={"note": "again"}, evaluations=evs)  # replaces
        routes = read_audit_routes(ws, "a1")
        events = read_audit_events(ws, "a1")
        summary = read_audit_summary(ws, "a1")
        assert read_audit_summary(ws, "missing") is None
    assert list(routes["role"]) == ["historical", "optimal"]
    assert routes.set_index("role").loc["historical", "fuel_t"] == pytest.approx(evs["historical"].summary["fuel_t"])
    assert routes.set_index("role").loc["historical", "exposure_h"] == pytest.approx(2.0, abs=0.25)
    assert summary == {"note": "again"}
    assert len(events) == 2 and set(events["criterion"]) == {"hs"}  # one hs event per route
    assert events["start_utc"].dt.tz is not None


def test_deviation_round_trip(workspace_path):
    r = Route("deviation", [40.0, 40.1, 40.0], [0.0, 0.5, 1.0], T0 + pd.to_timedelta([0.0, 2.0, 4.0], unit="h"), [12.0, 12.0],
              properties={"n_deviated": 1, "n_unresolved": 0})
    with open_workspace(workspace_path) as ws:
        write_deviation(ws, "L1@2025-01-15T00:00Z", "L1", T0, r)
        table = read_deviations(ws)
        back = read_deviation_route(ws, "L1@2025-01-15T00:00Z")
        assert read_deviation_route(ws, "nope") is None
        assert len(read_deviations(ws, lane_id="L2")) == 0
    assert table.loc[0, "n_deviated"] == 1 and table.loc[0, "lane_id"] == "L1"
    np.testing.assert_allclose(back.lat_deg, r.lat_deg)
    assert back.properties["n_deviated"] == 1
