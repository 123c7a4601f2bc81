"""STEAM2 fuel and emissions against values computed by hand from the published formulas.

Sources: SIMROUTE paper (Grifoll et al. 2022) Eq. 2-3 and Appendix III; SIMROUTE manual §4;
Jalkanen et al. 2009 (doi:10.5194/acp-9-9209-2009) and 2012 (doi:10.5194/acp-12-2641-2012).
Every expected number below is written out from the formulas in the test itself.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from routing.emissions import (
    Engine,
    ef_co2_g_kwh,
    ef_nox_g_kwh,
    ef_pm_g_kwh,
    ef_so2_g_kwh,
    leg_power_kw,
    pm_oc_load_factor,
    sfoc_relative,
    simroute_legacy_emissions,
    steam2_legs,
    steam2_power_kw,
    steam2_totals,
    wave_power_increase_frac,
)

# A fixed vessel: 10 000 kW installed, 80 % load at a 20 kn design speed, 190 g/kWh, 0.5 % S fuel,
# 86 % carbon, slow-speed engine at 120 rpm.
ENGINE = Engine(
    installed_power_kw=10000.0,
    design_speed_kn=20.0,
    engine_load_frac=0.8,
    sfoc_g_kwh=190.0,
    sulphur_frac=0.005,
    carbon_frac=0.86,
    engine_rpm=120.0,
)
M_C, M_O, M_S = 12.011, 15.999, 32.06  # IUPAC standard atomic weights


def test_power_cubic_law_by_hand():
    # P(v) = EL * P_inst * (v / v_design)^3
    assert steam2_power_kw(14.0, 10000.0, 20.0, 0.8) == pytest.approx(0.8 * 10000.0 * 0.7**3, rel=1e-12)
    assert steam2_power_kw(14.0, 10000.0, 20.0, 0.8) == pytest.approx(2744.0, rel=1e-12)
    assert steam2_power_kw(20.0, 10000.0, 20.0, 0.8) == pytest.approx(8000.0, rel=1e-12)
    out = steam2_power_kw(np.array([0.0, 10.0, -3.0]), 10000.0, 20.0, 0.8)
    np.testing.assert_allclose(out, [0.0, 1000.0, 0.0])


def test_wave_power_increase_by_hand():
    # dP/P = 1 / (1 - dv/v)^3 - 1
    assert wave_power_increase_frac(0.0) == 0.0
    assert wave_power_increase_frac(0.5) == pytest.approx(7.0)  # 1/0.125 - 1
    assert wave_power_increase_frac(0.1) == pytest.approx(1.0 / 0.729 - 1.0)
    assert wave_power_increase_frac(-0.1) == pytest.approx(1.0 / 1.331 - 1.0)  # a speed gain lowers power
    assert math.isinf(wave_power_increase_frac(1.0))
    assert math.isnan(wave_power_increase_frac(float("nan")))


def test_sfoc_parabola_is_steam2_not_simroute_typo():
    # SFOC_rel = 0.455 EL^2 - 0.71 EL + 1.28 (STEAM2); SIMROUTE's script uses 0.445.
    assert sfoc_relative(0.8) == pytest.approx(0.455 * 0.64 - 0.71 * 0.8 + 1.28, abs=1e-12)
    assert sfoc_relative(0.8) == pytest.approx(1.0032, abs=1e-12)
    assert sfoc_relative(0.5) == pytest.approx(0.455 * 0.25 - 0.355 + 1.28, abs=1e-12)
    assert sfoc_relative(0.8) != pytest.approx(0.445 * 0.64 - 0.71 * 0.8 + 1.28, abs=1e-4)


def test_emission_factors_by_hand():
    assert ef_co2_g_kwh(200.0, 0.85) == pytest.approx(200.0 * 0.85 * (M_C + 2 * M_O) / M_C, rel=1e-12)
    assert ef_co2_g_kwh(200.0, 0.85) == pytest.approx(622.89, abs=0.01)
    assert ef_so2_g_kwh(200.0, 0.027) == pytest.approx(200.0 * 0.027 * (M_S + 2 * M_O) / M_S, rel=1e-12)
    assert ef_so2_g_kwh(200.0, 0.027) == pytest.approx(10.790, abs=0.001)


@pytest.mark.parametrize(
    "rpm, expected",
    [
        (80.0, 17.0),  # slow speed band
        (129.9, 17.0),
        (130.0, 45.0 * 130.0**-0.2),  # 17.00 at the band edge
        (500.0, 45.0 * 500.0**-0.2),  # 12.98, SIMROUTE's default medium-speed engine
        (2000.0, 45.0 * 2000.0**-0.2),  # 9.84
        (2000.1, 9.8),
        (3000.0, 9.8),
    ],
)
def test_nox_by_rpm_band(rpm, expected):
    assert ef_nox_g_kwh(rpm) == pytest.approx(expected, rel=1e-12)


def test_nox_band_values_printed():
    assert ef_nox_g_kwh(500.0) == pytest.approx(12.984, abs=5e-4)
    np.testing.assert_allclose(ef_nox_g_kwh(np.array([100.0, 1000.0, 5000.0])), [17.0, 45.0 * 1000.0**-0.2, 9.8])


def test_pm_factor_by_hand():
    # EF_PM = SFOC_rel(EL) * (0.312 S + 0.244 S + 0.2 OC_EL + 0.08 + 0.06), S in percent
    el = 0.6
    oc = 1.024 / (1.0 - 47.660 * math.exp(-32.547 * el))
    sfoc_rel = 0.455 * el**2 - 0.71 * el + 1.28
    expected = sfoc_rel * (0.312 * 2.7 + 0.244 * 2.7 + 0.2 * oc + 0.08 + 0.06)
    assert ef_pm_g_kwh(el, 0.027) == pytest.approx(expected, rel=1e-12)
    # below 15 % load the organic-carbon multiplier is 3.333
    assert pm_oc_load_factor(0.1) == pytest.approx(3.333)
    assert pm_oc_load_factor(1.0) == pytest.approx(1.024, rel=1e-9)


def test_two_leg_route_by_hand():
    """Leg 1: 2 h at 14 kn in calm water. Leg 2: 3 h at 12 kn made in waves costing 2 kn."""
    legs = steam2_legs([2.0, 3.0], [14.0, 12.0], [0.0, 2.0], ENGINE)

    # Leg 1: P = 0.8 * 10000 * (14/20)^3 = 2744 kW; EL = 0.2744
    p1 = 2744.0
    el1 = 0.2744
    sfoc1 = (0.455 * el1**2 - 0.71 * el1 + 1.28) * 190.0  # 212.6927 g/kWh
    fuel1_g = p1 * sfoc1 * 2.0
    # Leg 2: calm power at the 12 kn made, P(12) = 8000 * 0.6^3 = 1728 kW; the waves cost 2 kn of
    # an engine setting worth 14 kn: dv/v = 2/14, dP/P = 1/(1 - 1/7)^3 - 1 = (7/6)^3 - 1
    p2_calm = 1728.0
    dp_frac = (7.0 / 6.0) ** 3 - 1.0  # 0.587963
    p2 = p2_calm * (1.0 + dp_frac)  # = 2744 kW, the 14-kn engine setting
    el2 = p2 / 10000.0
    sfoc2 = (0.455 * el2**2 - 0.71 * el2 + 1.28) * 190.0
    fuel2_g = p2 * sfoc2 * 3.0

    assert legs["power_calm_kw"].tolist() == pytest.approx([2744.0, 1728.0], rel=1e-12)
    assert legs["wave_increase_frac"].tolist() == pytest.approx([0.0, dp_frac], rel=1e-12)
    assert legs["power_kw"].tolist() == pytest.approx([p1, p2], rel=1e-12)
    assert p2 == pytest.approx(2744.0, rel=1e-12)
    assert legs["engine_load_frac"].tolist() == pytest.approx([el1, el2], rel=1e-12)
    assert legs["sfoc_g_kwh"].tolist() == pytest.approx([sfoc1, sfoc2], rel=1e-12)
    assert sfoc1 == pytest.approx(212.6927, abs=1e-4)
    assert legs["fuel_t"].tolist() == pytest.approx([fuel1_g / 1e6, fuel2_g / 1e6], rel=1e-12)

    tot = steam2_totals(legs)
    fuel_t = (fuel1_g + fuel2_g) / 1e6
    assert tot["fuel_t"] == pytest.approx(fuel_t, rel=1e-12)
    assert tot["fuel_t"] == pytest.approx(2.9181, abs=1e-4)  # 2744 kW * 5 h * 212.69 g/kWh
    assert tot["co2_t"] == pytest.approx(fuel_t * 0.86 * (M_C + 2 * M_O) / M_C, rel=1e-12)
    assert tot["so2_t"] == pytest.approx(fuel_t * 0.005 * (M_S + 2 * M_O) / M_S, rel=1e-12)
    energy = p1 * 2.0 + p2 * 3.0
    assert tot["energy_kwh"] == pytest.approx(energy, rel=1e-12)
    assert tot["nox_t"] == pytest.approx(energy * 17.0 / 1e6, rel=1e-12)  # 120 rpm: 17 g/kWh
    oc = 1.024 / (1.0 - 47.660 * math.exp(-32.547 * el1))
    pm_ef = (0.455 * el1**2 - 0.71 * el1 + 1.28) * (0.312 * 0.5 + 0.244 * 0.5 + 0.2 * oc + 0.08 + 0.06)
    assert tot["pm_t"] == pytest.approx(energy * pm_ef / 1e6, rel=1e-12)
    assert tot["power_limited_h"] == 0.0
    assert tot["mean_power_kw"] == pytest.approx(2744.0)


def test_wave_increase_changes_the_result():
    calm = steam2_totals(steam2_legs([3.0], [12.0], [0.0], ENGINE))
    waves = steam2_totals(steam2_legs([3.0], [12.0], [2.0], ENGINE))
    assert waves["fuel_t"] > calm["fuel_t"] * 1.5


def test_co2_over_fuel_constant_across_loads_and_waves():
    rng = np.random.default_rng(3)
    n = 50
    legs = steam2_legs(rng.uniform(0.1, 3.0, n), rng.uniform(4.0, 20.0, n), rng.uniform(-1.0, 6.0, n), ENGINE)
    ratio = legs["co2_t"] / legs["fuel_t"]
    np.testing.assert_allclose(ratio, 0.86 * (M_C + 2 * M_O) / M_C, rtol=1e-12)
    so2_ratio = legs["so2_t"] / legs["fuel_t"]
    np.testing.assert_allclose(so2_ratio, 0.005 * (M_S + 2 * M_O) / M_S, rtol=1e-12)


def test_simroute_legacy_breaks_co2_fuel_proportionality():
    """The defects we avoid: SIMROUTE's CO2 is not proportional to its fuel (engine load twice)."""
    a = simroute_legacy_emissions([1.0, 1.0], [16.1, 16.1], 16.1, Engine())
    b = simroute_legacy_emissions([1.0, 1.0], [13.1, 13.1], 16.1, Engine())
    assert a["co2_t"] / a["fuel_t"] != pytest.approx(b["co2_t"] / b["fuel_t"], rel=1e-3)
    # Calm legacy power is the design power 0.8 * 14400 = 11520 kW (not P(16.1 kn) = 3075 kW):
    sfoc = (0.445 * 0.8**2 - 0.71 * 0.8 + 1.28) * 200.0
    assert a["fuel_t"] == pytest.approx(11520.0 * sfoc * 2.0 / 1e6, rel=1e-12)
    # Slowed to 13.1 kn: + k (v0^3 - v^3) with k = 0.8 * 14400 / 25^3
    k = 0.8 * 14400.0 / 25.0**3
    p = 11520.0 + k * (16.1**3 - 13.1**3)
    el = p / 14400.0
    assert b["fuel_t"] == pytest.approx(p * (0.445 * el**2 - 0.71 * el + 1.28) * 200.0 * 2.0 / 1e6, rel=1e-12)
    assert b["co2_t"] == pytest.approx(p * el * (0.445 * el**2 - 0.71 * el + 1.28) * 200.0 * 0.85 * (M_C + 2 * M_O) / M_C * 2.0 / 1e6, rel=1e-12)


def test_legacy_with_every_defect_switched_off_is_steam2():
    """Fixing the three switches gives P(v0) over the slowed time: what steam2_legs computes for a
    route timed with the involuntary speed loss (leg speed v, loss v0 - v)."""
    eng = Engine()
    dt, v = np.array([1.5, 2.0, 0.5]), np.array([16.1, 12.0, 9.5])
    fixed = simroute_legacy_emissions(dt, v, 16.1, eng, sfoc_quadratic=0.455, engine_load_twice=False, design_baseline=False)
    ours = steam2_totals(steam2_legs(dt, v, 16.1 - v, eng))
    for key in ("fuel_t", "co2_t", "so2_t", "nox_t"):
        assert fixed[key] == pytest.approx(ours[key], rel=1e-12)


def test_power_capped_at_installed_and_flagged():
    parts = leg_power_kw(np.array([14.0, 14.0]), np.array([0.0, 20.0]), ENGINE)
    assert parts["power_limited"].tolist() == [False, True]
    assert parts["power_kw"][1] == pytest.approx(10000.0)
    legs = steam2_legs([1.0, 2.0], [14.0, 14.0], [0.0, 20.0], ENGINE)
    assert steam2_totals(legs)["power_limited_h"] == pytest.approx(2.0)


def test_nan_speed_loss_means_calm_and_zero_speed_means_no_power():
    legs = steam2_legs([1.0, 1.0], [14.0, 0.0], [np.nan, 3.0], ENGINE)
    assert legs["power_kw"].tolist() == pytest.approx([2744.0, 0.0])


def test_engine_from_vessel_and_validation():
    from thresholds.vessel import Vessel

    vessel = Vessel(
        name="t", vessel_class="container", speed_kn=16.0, lpp_m=180.0, beam_m=28.0, draught_m=9.0,
        dwt_t=20000.0, installed_power_kw=12000.0, design_speed_kn=19.0, engine_rpm=100.0, sfoc_g_kwh=175.0,
    )
    eng = Engine.from_vessel(vessel)
    assert eng.installed_power_kw == 12000.0 and eng.engine_rpm == 100.0 and eng.sulphur_frac == 0.027
    with pytest.raises(ValueError, match="installed_power_kw"):
        Engine(installed_power_kw=0.0)
    with pytest.raises(ValueError, match="sulphur_frac"):
        Engine(sulphur_frac=2.7)
    with pytest.raises(ValueError, match="same shape"):
        steam2_legs([1.0], [1.0, 2.0], 0.0, ENGINE)
    with pytest.raises(ValueError, match="non-negative"):
        steam2_legs([-1.0], [1.0], 0.0, ENGINE)


def test_returns_frame_with_units_in_names():
    legs = steam2_legs(np.array([1.0]), np.array([10.0]), 0.0, ENGINE)
    assert isinstance(legs, pd.DataFrame)
    assert {"fuel_t", "co2_t", "so2_t", "nox_t", "pm_t", "power_kw", "sfoc_g_kwh"} <= set(legs.columns)


def test_docstring_examples():
    import doctest

    import routing.emissions

    result = doctest.testmod(routing.emissions)
    assert result.attempted >= 6 and result.failed == 0
