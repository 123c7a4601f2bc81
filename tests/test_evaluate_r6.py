"""Real weather: SIMROUTE's R6 case (Palma -> Barcelona, Storm Gloria, depart 2020-01-20T09:00Z).

* A lane following the minimum-distance path, sailed by a container feeder under 200 m, is
  deviated (cargo-safe, Lpp < 200 m limits) and routed (time-optimal A*, plain and under the
  vessel's limits); fuel and CO2 are reported for each. The deviation and the safe A* route meet
  lower maximum and mean Hs than the lane; the plain A* route lower mean Hs (not maximum) than the
  same path sailed through the weather.
* Emissions: SIMROUTE's published saving of its optimal over its minimum-distance route (CO2
  16.14 %, fuel 13.98 %, Table 3 and ANCHORS.md) is reproduced by the defective legacy formula on
  SIMROUTE's own optimal route against our minimum-distance route timed with SIMROUTE's
  conventions; STEAM2 as it should be gives a smaller saving, identical for fuel and CO2.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from conftest import shared_file

DEPART = pd.Timestamp("2020-01-20T09:00Z")
START, GOAL = (39.225, 2.900), (41.500, 2.775)
BBOX = (2.0, 38.95, 5.1, 41.65)


@pytest.fixture(scope="module")
def r6(shared_data):
    pytest.importorskip("weather.io.local", reason="weather.io.read_local (weather helper) not available")
    from pipelines.routing_weather import load_weather
    from routing.sampling import PointSampler

    folder = shared_file(shared_data, "weather/simroute_cmems_medsea_wav")
    field, _ = load_weather([str(folder / "Waves_MEDSEA_20200120.nc"), str(folder / "Waves_MEDSEA_20200121.nc")])
    return field, PointSampler.from_field(field)


def _plan(field, vessel, **kw):
    from routing.astar import ShipModel
    from routing.planner import RouteRequest, plan_routes

    req = RouteRequest(START, GOAL, DEPART, ShipModel.from_vessel(vessel, "bowditch"), spacing_deg=1.5 / 60.0, bbox=BBOX, edges=48, **kw)
    return plan_routes(req, field)


def resample(route, step_nmi):
    from thresholds.geodesy import intermediate_point

    seg = route.leg_dist_nmi
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    n = int(np.ceil(cum[-1] / step_nmi)) + 1
    lat, lon = [], []
    for s in np.linspace(0.0, cum[-1], n):
        j = min(int(np.searchsorted(cum, s, side="right") - 1), seg.size - 1)
        la, lo = intermediate_point(route.lat_deg[j], route.lon_deg[j], route.lat_deg[j + 1], route.lon_deg[j + 1], (s - cum[j]) / seg[j])
        lat.append(la)
        lon.append(lo)
    return np.array(lat), np.array(lon)


def test_r6_lane_deviation_and_astar_meet_lower_seas(r6):
    from pipelines.config import load_operator_profile, load_vessel
    from routing.deviate import deviate_lane, lane_route, threshold_inputs
    from routing.evaluate import evaluate_route

    field, sampler = r6
    feeder = load_vessel("container-feeder")  # Lpp 160 m: the seed paper's Lpp < 200 m limits
    assert feeder.lpp_m < 200.0
    limits = load_operator_profile("default")
    plan = _plan(field, feeder)
    from routing.astar import ShipModel
    from routing.planner import RouteRequest, plan_routes

    safe_plan = plan_routes(RouteRequest(START, GOAL, DEPART, ShipModel.from_vessel(feeder, "bowditch"), spacing_deg=1.5 / 60.0, bbox=BBOX,
                                         edges=48), field, safety="hard", vessel=feeder, limits=limits)  # fmt: skip
    lat, lon = resample(plan.routes["min_distance"], 5.0)
    speed = np.full(lat.size, feeder.speed_kn)
    weather_at, check, cells = threshold_inputs(sampler, feeder, limits)
    dev = deviate_lane(lat, lon, speed, DEPART, weather_at=weather_at, check=check, cells=cells, leg_at_sea=plan.mesh.leg_is_sea)
    evs = {
        "lane": evaluate_route(lane_route(lat, lon, speed, DEPART), sampler, feeder, limits=limits),
        "deviation": evaluate_route(dev, sampler, feeder, limits=limits),
        "lane_in_weather": evaluate_route(plan.routes["min_distance"], sampler, feeder, limits=limits),
        "optimal": evaluate_route(plan.routes["optimal_smoothed"], sampler, feeder, limits=limits),
        "safe_optimal": evaluate_route(safe_plan.routes["safe_optimal_smoothed"], sampler, feeder, limits=limits),
    }
    s = {k: e.summary for k, e in evs.items()}
    assert dev.properties["n_deviated"] >= 3
    # The deviation, timed like the lane (typical speeds, Algorithm 1), meets lower seas than the lane.
    assert s["deviation"]["max_hs_m"] < s["lane"]["max_hs_m"]
    assert s["deviation"]["mean_hs_m"] < s["lane"]["mean_hs_m"]
    # The time-optimal A* route against the same path sailed through the weather (both slowed by
    # Bowditch): lower mean Hs, shorter, less fuel, fewer hours over the limits. Its maximum Hs is
    # not lower (6.96 against 6.87 m): it minimises time, not wave height (docs/evaluation.md).
    a, b = s["optimal"], s["lane_in_weather"]
    assert a["mean_hs_m"] < b["mean_hs_m"] and a["time_h"] < b["time_h"] - 2.0
    assert a["fuel_t"] < b["fuel_t"] and a["adverse_h"] < b["adverse_h"]
    assert a["max_hs_m"] < s["lane"]["max_hs_m"]
    # The A* route under the vessel's limits (routing.safety; no route keeps within them in Gloria,
    # so it is the soft fallback, labelled so) lowers both the maximum and the mean Hs met.
    safe = s["safe_optimal"]
    assert safe_plan.routes["safe_optimal_smoothed"].properties["safety_mode"] == "soft"
    for ref in ("lane", "lane_in_weather", "optimal"):
        assert safe["max_hs_m"] < s[ref]["max_hs_m"] and safe["mean_hs_m"] < s[ref]["mean_hs_m"], ref
    assert safe["adverse_h"] < a["adverse_h"]
    for role, e in s.items():
        assert e["fuel_t"] > 0 and e["co2_t"] == pytest.approx(e["fuel_t"] * 0.85 * 44.009 / 12.011, rel=1e-9), role
    # no deviated leg crosses land (pixel-exact coastline of the routing mesh)
    for i in range(dev.n_waypoints - 1):
        if dev.properties["steps"][i + 1]["status"] == "deviated":
            assert plan.mesh.leg_is_sea(dev.lat_deg[i], dev.lon_deg[i], dev.lat_deg[i + 1], dev.lon_deg[i + 1])


def _simroute_optimal(shared_data):
    from routing.route import Route
    from thresholds.geodesy import haversine_nmi

    path = shared_file(shared_data, "simroute/out/Route_Palma_Barna.txt")
    rows = [ln.split() for ln in path.read_text().splitlines() if ln.split() and ln.split()[0].isdigit()]
    a = np.array([[float(x) for x in r[1:4]] for r in rows])
    lat, lon, t_h = a[:, 1], a[:, 0], a[:, 2]
    d = np.asarray(haversine_nmi(lat[:-1], lon[:-1], lat[1:], lon[1:]))
    return Route("simroute_optimal", lat, lon, DEPART + pd.to_timedelta(t_h, unit="h"), d / np.diff(t_h))


def test_r6_emission_saving_against_simroutes_published_figure(r6, shared_data):
    from pipelines.config import load_operator_profile, load_vessel
    from routing.emissions import Engine, simroute_legacy_emissions
    from routing.evaluate import evaluate_route

    field, sampler = r6
    ship = load_vessel("simroute-r6")
    limits = load_operator_profile("default")
    emu = _plan(field, ship, land_check="end_node", use_land_mask=False, weather_time="simroute")
    md = emu.routes["min_distance"]
    assert md.time_h == pytest.approx(16.93, rel=0.01)  # SIMROUTE: 16.93 h
    opt = _simroute_optimal(shared_data)
    ev_opt, ev_md = evaluate_route(opt, sampler, ship, limits=limits), evaluate_route(md, sampler, ship, limits=limits)
    eng = Engine.from_vessel(ship)
    legacy = {k: simroute_legacy_emissions(e.legs["time_h"], e.legs["speed_kn"], ship.speed_kn, eng) for k, e in (("opt", ev_opt), ("md", ev_md))}
    co2_saving = 100 * (1 - legacy["opt"]["co2_t"] / legacy["md"]["co2_t"])
    fuel_saving = 100 * (1 - legacy["opt"]["fuel_t"] / legacy["md"]["fuel_t"])
    assert co2_saving == pytest.approx(16.14, abs=1.0)  # SIMROUTE's published figure, with its defects
    assert fuel_saving == pytest.approx(13.98, abs=1.0)
    ours_co2 = 100 * (1 - ev_opt.summary["co2_t"] / ev_md.summary["co2_t"])
    ours_fuel = 100 * (1 - ev_opt.summary["fuel_t"] / ev_md.summary["fuel_t"])
    assert ours_co2 == pytest.approx(ours_fuel, abs=1e-9)  # CO2 proportional to fuel
    assert 5.0 < ours_co2 < co2_saving - 2.0  # smaller than the defective figure
