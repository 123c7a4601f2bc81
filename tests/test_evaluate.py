"""Route evaluation on hand-built weather: exposure, events, STEAM2 totals and the seed's metrics.

The weather functions, routes and expected numbers are written in the test; thresholds are the
real :mod:`thresholds` rules with limits given inline.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from routing.evaluate import comparison_metrics, comparison_table, densify, evaluate_route
from routing.route import Route
from thresholds.operator import OperatorLimits
from thresholds.vessel import Vessel

R_NMI = 6371008.8 / 1852.0
T0 = pd.Timestamp("2025-01-15T00:00Z")
VESSEL = Vessel(
    name="test-feeder", vessel_class="container", speed_kn=12.0, lpp_m=100.0, beam_m=16.0, draught_m=6.0, dwt_t=8000.0,
    installed_power_kw=6000.0, design_speed_kn=15.0, engine_rpm=500.0, sfoc_g_kwh=200.0, min_speed_kn=2.0,
)
LIMITS = OperatorLimits(name="test", hs_max_m=4.5, wind_max_ms=19.0)


def hav_nmi(lat1, lon1, lat2, lon2):
    p1, p2 = math.radians(lat1), math.radians(lat2)
    a = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(math.radians(lon2 - lon1) / 2) ** 2
    return 2 * R_NMI * math.asin(math.sqrt(a))


def make_route(lat=40.0, lons=(0.0, 1.0, 2.0), speed=12.0, name="historical"):
    lats = np.full(len(lons), lat)
    d = [hav_nmi(lat, lons[i], lat, lons[i + 1]) for i in range(len(lons) - 1)]
    times = T0 + pd.to_timedelta(np.cumsum([0.0] + [x / speed for x in d]), unit="h")
    return Route(name, lats, np.array(lons, dtype=float), times, np.full(len(lons) - 1, speed))


def uniform(hs, wave_from=270.0, tp=6.0, tm=5.0, wind=5.0):
    def weather_at(times, lat, lon):
        n = np.size(lat)
        return {
            "hs_m": np.full(n, hs), "wave_from_deg": np.full(n, wave_from), "tp_s": np.full(n, tp), "tm_s": np.full(n, tm),
            "wind_u_ms": np.full(n, wind), "wind_v_ms": np.zeros(n),
        }
    return weather_at


def storm_window(start_h, end_h, hs_in=7.0, hs_out=1.0):
    def weather_at(times, lat, lon):
        h = (pd.DatetimeIndex(times) - T0) / pd.Timedelta(hours=1)
        hs = np.where((h >= start_h) & (h < end_h), hs_in, hs_out)
        n = hs.size
        return {"hs_m": hs, "wave_from_deg": np.full(n, 270.0), "tp_s": np.full(n, 6.0), "tm_s": np.full(n, 5.0),
                "wind_u_ms": np.full(n, 5.0), "wind_v_ms": np.zeros(n)}
    return weather_at


def test_densify_pieces_cover_each_leg():
    route = make_route()
    s = densify(route, max_step_h=0.25)
    leg_h = hav_nmi(40, 0, 40, 1) / 12.0  # 3.83 h -> 16 pieces of 0.2394 h
    assert (s["leg"] == 0).sum() == math.ceil(leg_h / 0.25)
    np.testing.assert_allclose(s.groupby("leg")["dt_h"].sum(), [leg_h, hav_nmi(40, 1, 40, 2) / 12.0], rtol=1e-12)
    np.testing.assert_allclose(s["dist_nmi"].sum(), route.dist_nmi, rtol=1e-12)
    # the first piece's middle is half a piece after departure, on the leg
    assert (s["time_utc"].iloc[0] - T0) / pd.Timedelta(hours=1) == pytest.approx(leg_h / 16 / 2, abs=1e-6)
    assert s["lat_deg"].between(40.0, 40.01).all()
    assert s["heading_deg"].between(89.0, 91.0).all()
    # a leg of zero duration gives no piece
    r2 = Route("x", [40.0, 40.0, 40.0], [0.0, 0.0, 1.0], pd.DatetimeIndex([T0, T0, T0 + pd.Timedelta(hours=4)]), [0.0, 11.5])
    assert set(densify(r2)["leg"]) == {1}


def test_calm_route_fuel_by_hand_and_no_events():
    route = make_route()
    ev = evaluate_route(route, uniform(0.0), VESSEL, limits=LIMITS)
    s = ev.summary
    assert s["exposure_by_rule_h"] == {"hs": 0.0, "wind": 0.0, "high_waves": 0.0, "surf_riding": 0.0}
    assert ev.events == [] and s["n_imo_events"] == 0 and s["n_safety_events"] == 0 and s["exposure_h"] == 0.0
    for model in ("bowditch", "aertssen", "khokhlov"):
        assert s["speed_loss"][model]["max_kn"] == pytest.approx(0.0, abs=1e-12)
        assert s["speed_loss"][model]["time_h_at_service_speed"] == pytest.approx(route.dist_nmi / 12.0, rel=1e-9)
    # STEAM2 by hand: P(12) = 0.8 * 6000 * (12/15)^3 = 2457.6 kW, EL = 0.4096
    el = 2457.6 / 6000.0
    sfoc = (0.455 * el**2 - 0.71 * el + 1.28) * 200.0
    hours = route.dist_nmi / 12.0
    assert s["fuel_t"] == pytest.approx(2457.6 * sfoc * hours / 1e6, rel=1e-9)
    assert s["co2_t"] / s["fuel_t"] == pytest.approx(0.85 * 44.009 / 12.011, rel=1e-12)
    assert s["time_h"] == pytest.approx(hours, rel=1e-9)
    assert s["max_hs_m"] == 0.0
    # no gm / roll period: the roll rules are reported as not evaluated, never as passed
    assert any(r.startswith("synchronous_roll") for r in s["rules_not_evaluated"])


def test_storm_window_exposure_and_event():
    route = make_route()
    ev = evaluate_route(route, storm_window(2.0, 5.0), VESSEL, limits=LIMITS)
    s = ev.summary
    # Hs 7 m > 4.5 m for 3 h; pieces are <= 0.25 h, so the exposure is 3 h to within one piece
    assert s["exposure_by_rule_h"]["hs"] == pytest.approx(3.0, abs=0.25)
    hs_events = [e for e in ev.events if e["criterion"] == "hs"]
    assert len(hs_events) == 1
    e = hs_events[0]
    assert e["kind"] == "operator"
    assert (pd.Timestamp(e["start_utc"]) - T0) / pd.Timedelta(hours=1) == pytest.approx(2.0, abs=0.25)
    assert (pd.Timestamp(e["end_utc"]) - T0) / pd.Timedelta(hours=1) == pytest.approx(5.0, abs=0.25)
    assert e["duration_h"] == pytest.approx(s["exposure_by_rule_h"]["hs"])
    assert s["exposure_h"] == pytest.approx(s["exposure_by_rule_h"]["hs"])  # hours over any operator limit
    assert e["max_margin"] == pytest.approx(2.5)  # 7.0 - 4.5 m
    # Hs 7 m > 0.04 L = 4 m but the mean period 5 s gives a 39 m wave < 0.8 L: no high-wave attack
    assert s["exposure_by_rule_h"]["high_waves"] == 0.0
    assert s["max_hs_m"] == 7.0
    # Bowditch in following seas: 0.0083 kn/ft^2 * (7 m / 0.3048)^2 = 4.378 kn in the storm
    assert s["speed_loss"]["bowditch"]["max_kn"] == pytest.approx(0.0083 * (7.0 / 0.3048) ** 2, rel=1e-3)
    # the wave power increase raises fuel above the calm value; legs carry the mean loss of their pieces
    calm = evaluate_route(route, uniform(0.0), VESSEL, limits=LIMITS)
    assert s["fuel_t"] > calm.summary["fuel_t"]
    samp = ev.samples
    by_leg = samp.groupby("leg").apply(lambda g: np.average(g["speed_loss_bowditch_kn"], weights=g["dt_h"]), include_groups=False)
    np.testing.assert_allclose(ev.legs["speed_loss_kn"], by_leg.to_numpy(), rtol=1e-12)


def test_surf_riding_is_an_imo_event():
    # L = 100 m: surf-riding when 135 < alpha < 225 and V > 1.8 sqrt(L) / cos(180 - alpha) = 18 kn here
    fast = make_route(speed=20.0, name="fast")
    ev = evaluate_route(fast, uniform(3.0, wave_from=270.0), VESSEL, limits=LIMITS)
    assert ev.summary["n_imo_events"] == 1
    (e,) = [x for x in ev.events if x["kind"] == "imo"]
    assert e["criterion"] == "surf_riding"
    assert e["duration_h"] == pytest.approx(fast.time_h, rel=1e-9)
    slow = evaluate_route(make_route(speed=12.0), uniform(3.0, wave_from=270.0), VESSEL, limits=LIMITS)
    assert slow.summary["n_imo_events"] == 0


def layered(times, lat, lon):
    """South of 40.5 N: Hs 6 m, Tp 10 s, wind 20 m/s from the west, waves from the west.
    North of it: Hs 3 m, Tp 8 s, wind 10 m/s, waves from the north."""
    lat = np.asarray(lat, dtype=float)
    south = lat < 40.5
    return {
        "hs_m": np.where(south, 6.0, 3.0), "tp_s": np.where(south, 10.0, 8.0), "tm_s": np.where(south, 7.0, 6.0),
        "wave_from_deg": np.where(south, 270.0, 0.0), "wind_u_ms": np.where(south, 20.0, 10.0), "wind_v_ms": np.zeros(lat.size),
    }


def test_comparison_metrics_by_hand():
    ref = evaluate_route(make_route(lat=40.0), layered, VESSEL, limits=LIMITS)
    alt = evaluate_route(make_route(lat=41.0, name="deviation"), layered, VESSEL, limits=LIMITS)
    m = comparison_metrics(ref, alt)
    assert m["adverse_portion_h"] == pytest.approx(ref.route.time_h, rel=1e-9)  # Hs 6 m > 4.5 m all along
    assert m["hs_decrease_pct"] == pytest.approx((6.0 - 3.0) / 6.0 * 100.0)  # Eq. 1: 50 %
    assert m["period_decrease_pct"] == pytest.approx((10.0 - 8.0) / 10.0 * 100.0)  # Eq. 2: 20 %
    assert m["wind_decrease_pct"] == pytest.approx((20.0 - 10.0) / 20.0 * 100.0)  # Eq. 3: 50 %
    # following seas (~180 deg) against beam seas from the north (~90 deg): |180 - 90| / 180
    assert m["wave_dir_deviation_pct"] == pytest.approx(50.0, abs=0.5)
    la, lb = 2 * hav_nmi(40, 0, 40, 1), 2 * hav_nmi(41, 0, 41, 1)
    assert m["length_diff_nmi"] == pytest.approx(lb - la, rel=1e-9)
    assert m["length_diff_pct"] == pytest.approx((lb - la) / la * 100.0, rel=1e-9)
    # no adverse portion in the reference -> the decreases are undefined, not zero
    calm = evaluate_route(make_route(lat=41.0, name="calm"), layered, VESSEL, limits=LIMITS)
    assert math.isnan(comparison_metrics(calm, ref)["hs_decrease_pct"])


def test_comparison_table_rows_and_deltas():
    evs = {
        "historical": evaluate_route(make_route(lat=40.0), layered, VESSEL, limits=LIMITS),
        "deviation": evaluate_route(make_route(lat=41.0, name="deviation"), layered, VESSEL, limits=LIMITS),
    }
    table = comparison_table(evs)
    assert list(table.index) == ["historical", "deviation"]
    assert table.loc["historical", "d_fuel_t"] == 0.0
    assert table.loc["deviation", "d_time_h"] == pytest.approx(evs["deviation"].summary["time_h"] - evs["historical"].summary["time_h"])
    assert table.loc["deviation", "d_co2_t_pct"] == pytest.approx(
        (evs["deviation"].summary["co2_t"] / evs["historical"].summary["co2_t"] - 1.0) * 100.0
    )
    assert table.loc["deviation", "hs_decrease_pct"] == pytest.approx(50.0)
    assert table.loc["deviation", "max_hs_m"] == 3.0 and table.loc["historical", "max_hs_m"] == 6.0
    with pytest.raises(KeyError, match="reference"):
        comparison_table(evs, reference="min_distance")
    from routing.evaluate import events_frame, exposure_frame

    ex = exposure_frame(evs)
    assert set(ex["route"]) == {"historical", "deviation"}
    assert ex.set_index(["route", "limit"]).loc[("historical", "hs"), "exposure_h"] == pytest.approx(evs["historical"].route.time_h, rel=1e-9)
    assert ex.set_index(["route", "limit"]).loc[("deviation", "hs"), "exposure_h"] == 0.0
    fr = events_frame(evs)
    assert list(fr.columns[:3]) == ["route", "criterion", "kind"] and (fr["route"] == "historical").all()


def test_to_dict_is_json_ready():
    import json

    ev = evaluate_route(make_route(), storm_window(2.0, 5.0), VESSEL, limits=LIMITS)
    text = json.dumps(ev.to_dict(waypoints=False), allow_nan=True)
    back = json.loads(text)
    assert back["fuel_t"] == pytest.approx(ev.summary["fuel_t"]) and back["events"][0]["criterion"] == "hs"
    # the returned route carries the weather met at its waypoints
    assert "hs_m" in ev.route.weather and ev.route.weather["hs_m"].shape == (3,)
