"""Each leg's engine setting from the speed it made (routing.leg_setting, issue 20): hand-computed cases, the floor,
the engine's maximum power, and real planner output evaluated with its settings dropped.

The expected settings and fuel are written here from the published formulas (Bowditch [1] Table A1.1, Aertssen [1]
Table A1.2, STEAM2 P(v) = EL P_inst (v / v_design)^3 and SFOC_rel = 0.455 EL^2 - 0.71 EL + 1.28), with the vessel's
profile values; [1] M. Grifoll et al., Ocean Eng. 255, 111427, 2022, Appendix I.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from routing.evaluate import evaluate_route
from routing.route import Route
from thresholds.units import MS_PER_KN

T0 = pd.Timestamp("2024-01-01T00:00Z")
FT_M = 0.3048


@pytest.fixture(scope="module")
def vessel():
    from pipelines.config import load_vessel

    return load_vessel("container-feeder")  # 17 kn service, 12 600 kW, 19.5 kn design at 75 % MCR, floor 3 kn


def fuel_by_hand(v, setting_kn, hours):
    """STEAM2 fuel [t] of ``hours`` at the calm-water setting (the power that restores it in waves is P(setting))."""
    p = v.engine_load_frac * v.installed_power_kw * (setting_kn / v.design_speed_kn) ** 3
    el = p / v.installed_power_kw
    return p * (0.455 * el * el - 0.71 * el + 1.28) * v.sfoc_g_kwh * hours / 1e6


def east_leg(speed_kn, hours=5.0):
    """One leg due east along the equator (heading 90 deg all along) sailed at ``speed_kn`` over ground."""
    d_deg = speed_kn * hours / (6371008.8 / 1852.0 * math.pi / 180.0)
    return Route("leg", np.zeros(2), np.array([0.0, d_deg]), pd.DatetimeIndex([T0, T0 + pd.Timedelta(hours=hours)]), np.array([speed_kn]))


def sea(hs_m, wave_from_deg=90.0, current_kn=(0.0, 0.0)):
    """A uniform sea (waves from ``wave_from_deg``; 90 = head seas for the eastbound leg) and current (east, north)."""

    def weather_at(times, lat, lon):
        n = np.size(lat)
        out = {"hs_m": np.full(n, hs_m), "wave_from_deg": np.full(n, wave_from_deg)}
        if any(current_kn):
            out.update(current_u_ms=np.full(n, current_kn[0] * MS_PER_KN), current_v_ms=np.full(n, current_kn[1] * MS_PER_KN))
        return out

    return weather_at


def test_bowditch_head_seas_setting_by_hand(vessel):
    """Hs 3 m head seas: Bowditch's loss 0.0248 kn/ft^2 x (3 / 0.3048 ft)^2 = 2.4025 kn at any setting, so a leg made
    at 12 kn was sailed at the setting 12 + 2.4025 kn, and burns P(14.4025 kn) over its 5 h."""
    ev = evaluate_route(east_leg(12.0), sea(3.0), vessel, speed_loss_model="bowditch")
    s = 12.0 + 0.0248 * (3.0 / FT_M) ** 2
    assert s == pytest.approx(14.40250, abs=1e-5)
    assert ev.legs["setting_kn"].iloc[0] == pytest.approx(s, abs=1e-6)
    assert ev.summary["fuel_t"] == pytest.approx(fuel_by_hand(vessel, s, 5.0), rel=1e-6)
    es = ev.summary["engine_settings"]
    assert es["basis"] == "solved" and es["note"] is None and es["above_max_power_legs"] == 0 and es["floor_legs"] == 0


def test_aertssen_setting_depends_on_the_setting_by_hand(vessel):
    """Aertssen's loss scales with the setting: Hs 3 m is Beaufort 6, head seas m = 1300, n = 6, so the speed made is
    s (1 - (1300/160 + 6) / 100) and the setting of a leg made at 12 kn is 12 / 0.85875 = 13.974 kn. The evaluation
    before issue 20's fix charged the loss at the 17 kn service speed (P(12 + 0.14125 x 17) = P(14.401 kn)): 8 % more."""
    c = (1300.0 / 160.0 + 6.0) / 100.0
    ev = evaluate_route(east_leg(12.0), sea(3.0), vessel, speed_loss_model="aertssen")
    s = 12.0 / (1.0 - c)
    assert ev.legs["setting_kn"].iloc[0] == pytest.approx(s, abs=1e-6)
    assert ev.summary["fuel_t"] == pytest.approx(fuel_by_hand(vessel, s, 5.0), rel=1e-6)
    assert fuel_by_hand(vessel, 12.0 + c * 17.0, 5.0) / ev.summary["fuel_t"] > 1.08


def test_current_is_taken_out_of_the_speed_made(vessel):
    """A 1.5 kn following current and 1 kn from the north: over ground sqrt(v^2 - 1) + 1.5 = 12 kn (the ship crabs), so
    through the water v = sqrt(10.5^2 + 1) and in calm water that is the setting."""
    ev = evaluate_route(east_leg(12.0), sea(0.0, current_kn=(1.5, -1.0)), vessel, speed_loss_model="bowditch")
    s = math.sqrt(10.5**2 + 1.0)
    assert ev.legs["setting_kn"].iloc[0] == pytest.approx(s, abs=1e-6)
    assert ev.summary["fuel_t"] == pytest.approx(fuel_by_hand(vessel, s, 5.0), rel=1e-6)


def test_a_leg_at_the_floor_is_charged_the_service_speed_and_said(vessel):
    """Hs 8 m head seas: Bowditch's 17.08 kn loss holds the 17 kn service speed at the 3 kn floor, as it holds every
    setting up to 20.08 kn: the speed does not tell the setting, the one nearest the service speed is charged."""
    assert 0.0248 * (8.0 / FT_M) ** 2 + 3.0 > 17.0
    ev = evaluate_route(east_leg(3.0), sea(8.0), vessel, speed_loss_model="bowditch")
    assert ev.legs["setting_kn"].iloc[0] == pytest.approx(17.0, abs=1e-9)
    assert ev.summary["fuel_t"] == pytest.approx(fuel_by_hand(vessel, 17.0, 5.0), rel=1e-9)
    es = ev.summary["engine_settings"]
    assert es["floor_legs"] == 1 and es["floor_h"] == pytest.approx(5.0) and "speed floor" in es["note"]


def test_a_leg_no_setting_can_make_is_charged_the_installed_power_and_said(vessel):
    """In 2 m head seas 20 kn made needs the setting 20 + 0.0248 x (2 / 0.3048)^2 = 21.07 kn, below the maximum-power
    speed 19.5 x 0.75^(-1/3) = 21.46 kn; 21 kn made would need 22.07 kn, above it: that leg is charged the installed
    power (engine load 1) over its time and flagged power_limited."""
    v_max = 19.5 * 0.75 ** (-1.0 / 3.0)
    ev = evaluate_route(east_leg(20.0), sea(2.0), vessel, speed_loss_model="bowditch")
    need = 20.0 + 0.0248 * (2.0 / FT_M) ** 2
    assert need < v_max and ev.legs["setting_kn"].iloc[0] == pytest.approx(need, abs=1e-6)
    assert not ev.legs["power_limited"].iloc[0]
    ev = evaluate_route(east_leg(21.0), sea(2.0), vessel, speed_loss_model="bowditch")
    assert ev.legs["setting_kn"].iloc[0] == pytest.approx(v_max, abs=1e-9)
    assert bool(ev.legs["power_limited"].iloc[0])
    el = 1.0
    assert ev.summary["fuel_t"] == pytest.approx(12600.0 * (0.455 * el - 0.71 * el + 1.28) * 175.0 * 5.0 / 1e6, rel=1e-9)
    es = ev.summary["engine_settings"]
    assert es["above_max_power_legs"] == 1 and "installed power" in es["note"] and ev.summary["power_limited_h"] == pytest.approx(5.0)
    from pipelines.reporting import route_notes_of
    from routing.audit import findings

    assert f"as-sailed fuel: {es['note']}." in findings({"as_sailed": ev}, None, reference="as_sailed")
    assert es["note"] in route_notes_of({"lane": ev}, "lane")["lane"]


@pytest.mark.parametrize("model", ["bowditch", "aertssen", "khokhlov"])
def test_speed_made_never_falls_as_the_setting_rises(vessel, model):
    """The premise of the bisection: every wave model's speed made (floor included) is non-decreasing in the setting,
    over a grid of sea states and encounter angles (Kwon's, in the wind, likewise over Beaufort 0-12)."""
    from routing.speed_loss import speed_loss

    s = np.linspace(0.0, 21.0, 211)[:, None]
    hs, enc = np.meshgrid(np.linspace(0.0, 9.0, 19), np.linspace(0.0, 180.0, 13))
    hs, enc = hs.ravel()[None, :], enc.ravel()[None, :]
    with _nothing():  # Khokhlov warns outside its published 4 000-20 000 dwt x 9-20 kn
        made = s - speed_loss(np.broadcast_to(s, (s.shape[0], hs.size)), np.broadcast_to(hs, (s.shape[0], hs.size)),
                              np.broadcast_to(enc, (s.shape[0], hs.size)), model, vessel=vessel)
    assert np.all(np.diff(made, axis=0) >= -1e-12)
    if model == "bowditch":  # Kwon once: above Beaufort 10 head winds its raw loss exceeds the speed, the floor holds it
        sk = np.linspace(8.0, 21.0, 53)
        for wind in (5.0, 12.0, 20.0, 25.0, 30.0):
            with _nothing():
                v = sk - np.array([speed_loss(x, 0.0, 0.0, "kwon", vessel=vessel, wind_ms=wind) for x in sk])
            assert np.all(np.diff(v) >= -1e-12), wind


class _nothing:
    def __enter__(self):
        import warnings

        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore")

    def __exit__(self, *exc):
        return self._w.__exit__(*exc)


# ------------------------------------------------------------------ real planner output, its settings dropped


def planned(vessel, model, speed_kn, current_kn, hs_m, arrive_h):
    """plan_routes with the fuel objective on a uniform sea (and current) over 0-1 N x 0-3 E: the least-fuel route,
    as a comparison table evaluates it (routing.least_fuel_role.for_table: settings kept only as planned_*)."""
    from test_routing_fuel import zermelo_field

    from routing.astar import ShipModel
    from routing.emissions import Engine
    from routing.fuel import FuelSpec
    from routing.planner import RouteRequest, plan_routes

    # discrete settings (no constant speed between them), so the schedule mixes settings and waits
    spec = FuelSpec((9.0, 12.0, 15.0, speed_kn), Engine.from_vessel(vessel), arrive_by=T0 + pd.Timedelta(hours=arrive_h),
                    between_settings=False)
    req = RouteRequest((0.0, 0.0), (0.0, 3.0), T0, ShipModel.from_vessel(vessel, model, speed_kn=speed_kn), spacing_deg=0.05,
                       bbox=(-0.25, -0.25, 3.25, 0.25), edges=16, ignore_land=True, vessel_name=vessel.name)
    return plan_routes(req, zermelo_field(cur_east_kn=current_kn[0], cur_north_kn=current_kn[1], hs=hs_m), fuel=spec)


@pytest.mark.parametrize("model, current_kn, arrive_h", [("aertssen", (0.0, 0.0), 17.0), ("bowditch", (1.0, 1.5), 15.0),
                                                         ("khokhlov", (0.0, 0.0), 16.0)])
def test_planned_least_fuel_evaluates_to_its_planned_fuel_without_its_settings(vessel, model, current_kn, arrive_h):
    """The planner's least-fuel route (settings per leg, waits) evaluated as a table does, without its settings: each
    leg's solved setting is the planned one and the fuel is the planned fuel. Uniform weather, so the planner's edge
    weather and the evaluation's samples agree and the tolerance is the solver's (1e-9 kn) and the legs' headings
    (great-circle courses against the edge's initial course, < 1e-6). The time-optimal route at the 17 kn service
    speed evaluates at 17 kn on every leg, its fuel P(17 kn) over its time, as before the settings were solved."""
    import dataclasses

    from routing.least_fuel_role import for_table

    if model == "khokhlov":  # within Khokhlov's published D·v0 up to the maximum-power speed (21.46 kn)
        vessel = dataclasses.replace(vessel, dwt_t=15000.0)
    plan = planned(vessel, model, 17.0, current_kn, 3.0, arrive_h)
    lf = plan.routes["least_fuel"]
    table = for_table(lf)
    assert "speed_setting_kn" not in table.properties and table.properties["planned_fuel_t"] == lf.properties["fuel_t"]
    weather = sea(3.0, wave_from_deg=90.0, current_kn=current_kn)
    ev = evaluate_route(table, weather, vessel, speed_loss_model=model)
    want = np.asarray(lf.properties["speed_setting_kn"], dtype=float)
    assert len(set(np.round(want[want > 0], 6))) >= 2 or 0.0 in want  # a schedule with a choice in it, not one constant
    np.testing.assert_allclose(ev.legs["setting_kn"].to_numpy(), want, atol=2e-5)
    assert ev.summary["fuel_t"] == pytest.approx(lf.properties["fuel_t"], rel=1e-6)
    assert ev.summary["engine_settings"]["basis"] == "solved" and ev.summary["engine_settings"]["note"] is None
    carried = evaluate_route(lf, weather, vessel, speed_loss_model=model)
    assert carried.summary["engine_settings"]["basis"] == "planned"
    assert carried.summary["fuel_t"] == pytest.approx(lf.properties["fuel_t"], rel=1e-9)
    opt = evaluate_route(plan.routes["optimal"], weather, vessel, speed_loss_model=model)
    np.testing.assert_allclose(opt.legs["setting_kn"].to_numpy(), 17.0, atol=2e-5)
    assert opt.summary["fuel_t"] == pytest.approx(fuel_by_hand(vessel, 17.0, plan.routes["optimal"].time_h), rel=1e-6)


def test_planned_against_evaluated_fuel_is_said_with_its_cause(vessel):
    """The least-fuel line of the audit and the nightly run: planned and evaluated fuel agree in the planner's own
    weather; in a rougher sea than planned (Hs 4 m for 3 m) the evaluation needs higher settings to keep the planned
    times, and the line says by how much, why, and on which legs."""
    from routing.emissions import Engine
    from routing.least_fuel_role import for_table, planned_difference, planned_words

    plan = planned(vessel, "bowditch", 17.0, (0.0, 0.0), 3.0, 16.0)
    table = for_table(plan.routes["least_fuel"])
    eng = Engine.from_vessel(vessel)
    same = planned_difference(evaluate_route(table, sea(3.0), vessel), eng)
    assert same["agree"] and same["planned_fuel_t"] == pytest.approx(table.properties["planned_fuel_t"], abs=1e-6)
    assert planned_words(same, None).endswith("within 0.5 %)")
    rough = evaluate_route(table, sea(4.0), vessel)
    diff = planned_difference(rough, eng)
    assert not diff["agree"] and diff["diff_t"] == pytest.approx(rough.summary["fuel_t"] - same["planned_fuel_t"], abs=2e-6) and diff["diff_t"] > 0
    k = diff["legs"][0]["leg"]  # head seas 4 m for 3 m: Bowditch adds 0.0248 (4^2 - 3^2) / 0.3048^2 kn to every sailing leg
    assert diff["legs"][0]["evaluated_kn"] - diff["legs"][0]["planned_kn"] == pytest.approx(0.0248 * 7.0 / FT_M**2, abs=2e-3), k
    words = planned_words(diff, None)
    assert "needs a higher engine setting than the planner's (each mesh edge or polyline piece" in words and f"leg {k} of" in words
