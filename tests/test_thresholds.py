"""IMO MSC.1/Circ.1228 criteria and operator limits against hand-computed boundary cases.

Every expected number below is computed by hand in the comment next to it (never by another
project function). Boundary cases sit just inside and just outside each criterion.
"""

from __future__ import annotations

import doctest
import math

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from thresholds import assessment, imo_msc1228, operator, safety
from thresholds.assessment import REASON_BITS, reason_names
from thresholds.imo_msc1228 import (
    ImoSettings,
    encounter_angle_deg,
    encounter_period_s,
    natural_roll_period_s,
    parametric_roll,
    successive_high_waves,
    surf_riding,
    synchronous_roll,
    wave_length_m,
)
from thresholds.operator import (
    MissingWeatherVariableError,
    OperatorLimits,
    OperatorProfile,
    OperatorProfileError,
    evaluate_operator,
)
from thresholds.safety import assess, roll_period_of, safe_cell_mask
from thresholds.vessel import Vessel


def make_vessel(lpp_m=250.0, vessel_class="container", speed_kn=18.0, **kw) -> Vessel:
    base = dict(name="test", vessel_class=vessel_class, speed_kn=speed_kn, lpp_m=lpp_m, beam_m=32.2, draught_m=12.0,
                dwt_t=50000.0, installed_power_kw=30000.0, design_speed_kn=22.0, engine_rpm=100.0, sfoc_g_kwh=190.0)
    base.update(kw)
    return Vessel(**base)


@pytest.mark.parametrize("module", [assessment, imo_msc1228, operator, safety])
def test_docstring_examples(module):
    failures, tried = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert tried > 0 and failures == 0


# ---------------------------------------------------------------- encounter angle and periods


@pytest.mark.parametrize(
    "heading, wave_from, alpha",
    [
        (45.0, 45.0, 0.0),  # waves from dead ahead: head seas
        (0.0, 180.0, 180.0),  # waves from astern: following seas
        (0.0, 90.0, 90.0),  # from starboard
        (350.0, 10.0, 20.0),  # across north
        (10.0, 350.0, 340.0),
        (90.0, 270.0, 180.0),
    ],
)
def test_encounter_angle_convention(heading, wave_from, alpha):
    assert encounter_angle_deg(heading, wave_from) == pytest.approx(alpha)


def test_wave_length_and_encounter_period_hand_values():
    # lambda = g T^2 / 2 pi = 980.665 / 6.2831853 = 156.0777 m
    assert wave_length_m(10.0) == pytest.approx(156.0777, abs=1e-4)
    # T_E = 3 T^2 / (3T + V cos a): T 10 s, V 15 kn
    assert encounter_period_s(10.0, 15.0, 0.0) == pytest.approx(300.0 / 45.0)  # head seas 6.667 s
    assert encounter_period_s(10.0, 15.0, 180.0) == pytest.approx(300.0 / 15.0)  # following 20 s
    assert encounter_period_s(10.0, 15.0, 90.0) == pytest.approx(10.0)  # beam: the wave period
    assert encounter_period_s(10.0, 30.0, 180.0) == np.inf  # riding at wave speed
    assert encounter_period_s(10.0, 45.0, 180.0) == pytest.approx(300.0 / 15.0)  # overtaking: |30 - 45|
    # The 1/3 coefficient is the rounded deep-water relation T_E = lambda / (c + V cos a):
    lam = 9.80665 * 100 / (2 * math.pi)
    c = 9.80665 * 10 / (2 * math.pi)
    exact = lam / (c + 15 * 1852 / 3600)
    assert encounter_period_s(10.0, 15.0, 0.0) == pytest.approx(exact, rel=0.01)


def test_natural_roll_period_is_code():
    # C = 0.373 + 0.023 * 32.2/12 - 0.043 * 200/100 = 0.373 + 0.0617167 - 0.086 = 0.3487167
    # T = 2 * 0.3487167 * 32.2 / sqrt(1.0) = 22.45735 s; GM 4 m halves it.
    assert natural_roll_period_s(32.2, 1.0, 12.0, 200.0) == pytest.approx(22.45735, abs=1e-4)
    assert natural_roll_period_s(32.2, 4.0, 12.0, 200.0) == pytest.approx(22.45735 / 2, abs=1e-4)
    assert np.isnan(natural_roll_period_s(32.2, 0.0, 12.0, 200.0))
    assert np.isnan(natural_roll_period_s(32.2, -0.3, 12.0, 200.0))
    v = make_vessel(lpp_m=200.0, gm_m=1.0)
    assert roll_period_of(v) == pytest.approx(22.45735, abs=1e-4)
    assert roll_period_of(make_vessel(roll_period_s=18.0, gm_m=1.0)) == 18.0  # given period wins
    assert roll_period_of(make_vessel()) is None


# ---------------------------------------------------------------- surf-riding


def test_surf_riding_boundaries():
    # L = 100 m: 1.8 * sqrt(100) = 18 kn in following seas (alpha 180, cos 0 = 1)
    r = surf_riding([17.99, 18.0, 18.01], 180.0, 100.0)
    assert r.fired.tolist() == [False, False, True]  # strict ">"
    np.testing.assert_allclose(r.margin, [-0.01, 0.0, 0.01], atol=1e-12)
    np.testing.assert_allclose(r.limit, 18.0)
    # alpha 150: 18 / cos(30 deg) = 18 / 0.8660254 = 20.78461 kn
    r = surf_riding([20.78, 20.79], 150.0, 100.0)
    assert r.fired.tolist() == [False, True]
    assert r.limit[0] == pytest.approx(20.78461, abs=1e-5)
    # alpha 210 is symmetric to 150
    assert surf_riding(20.79, 210.0, 100.0).fired and not surf_riding(20.78, 210.0, 100.0).fired


@pytest.mark.parametrize(
    "alpha, fires",
    [
        (0.0, False),  # head seas
        (135.0, False),  # sector is open: 135 excluded
        (135.01, True),  # just inside: limit 18/cos(44.99 deg) = 25.45 kn < 40 kn
        (180.0, True),
        (224.99, True),
        (225.0, False),
        (359.9, False),  # practically head seas
    ],
)
def test_surf_riding_angle_edges(alpha, fires):
    r = surf_riding(40.0, alpha, 100.0)
    assert bool(r.fired) is fires
    if not fires and alpha in (0.0, 359.9, 135.0, 225.0):
        assert np.isneginf(r.margin) and np.isnan(r.limit)


def test_surf_riding_other_convention():
    # Bowditch/Mannarini theta = 0 for following seas: theta = (alpha + 180) mod 360. A ship heading
    # north with waves from the south is theta 0 there, alpha 180 here: surf-riding applies.
    alpha = encounter_angle_deg(0.0, 180.0)
    theta = (alpha + 180.0) % 360.0
    assert theta == 0.0 and surf_riding(20.0, alpha, 100.0).fired


def test_surf_riding_nan_never_fires():
    r = surf_riding(np.nan, 180.0, 100.0)
    assert not r.fired and np.isnan(r.margin)
    assert not surf_riding(30.0, np.nan, 100.0).fired


# ---------------------------------------------------------------- successive high waves


def test_successive_high_waves_boundaries():
    # L = 100 m: needs lambda > 80 m, i.e. T > sqrt(80 * 2 pi / g) = 7.1596 s, and Hs > 4.0 m.
    # T 7.2 s: lambda = 9.80665 * 51.84 / 6.2831853 = 80.91 m; T 7.15 s: 79.79 m.
    r = successive_high_waves([4.01, 4.0, 4.01, 3.99], [7.2, 7.2, 7.15, 9.0], 100.0)
    assert r.fired.tolist() == [True, False, False, False]
    # margin = min((lambda - 80)/80, (Hs - 4)/4): Hs 5 m, T 9 s -> lambda 126.45 m -> min(0.581, 0.25) = 0.25
    r = successive_high_waves(5.0, 9.0, 100.0)
    assert r.fired and r.margin == pytest.approx(0.25)
    assert r.limit == pytest.approx(4.0)


# ---------------------------------------------------------------- roll resonance


def test_synchronous_roll_boundaries():
    # T_R 20 s, tolerance 10 %: band 18..22 s inclusive
    r = synchronous_roll([17.99, 18.0, 20.0, 22.0, 22.01], 20.0)
    assert r.fired.tolist() == [False, True, True, True, False]
    np.testing.assert_allclose(r.margin[2], 0.1)
    assert synchronous_roll(18.5, 20.0, tolerance_frac=0.02).fired.item() is False


def test_parametric_roll_is_the_half_period_band_not_counted_twice():
    # MSC.1/Circ.1228 4.2.3.2 lists T_E ~ T_R and T_E ~ T_R/2; the first is synchronous rolling
    # (4.2.3.1), reported there only. Bands of +-10 % of T_R: 9..11 s and 18..22 s.
    te = [8.99, 9.0, 10.0, 11.0, 11.01, 14.0, 20.0]
    r = parametric_roll(te, 20.0)
    assert r.fired.tolist() == [False, True, True, True, False, False, False]
    assert r.limit[2] == pytest.approx(10.0)
    s = synchronous_roll(te, 20.0)
    assert s.fired.tolist() == [False, False, False, False, False, False, True]
    assert not (r.fired & s.fired).any()


def test_roll_from_wave_and_ship():
    # Following seas at alpha 180, T 10 s, V 15 kn: T_E = 300 / 15 = 20 s = T_R -> synchronous, once.
    v = make_vessel(lpp_m=250.0, speed_kn=15.0, roll_period_s=20.0)
    a = assess(v, None, hs_m=3.0, tp_s=10.0, wave_from_deg=180.0, heading_deg=0.0)
    assert a.fired("synchronous_roll") and not a.fired("parametric_roll")
    # Beam seas: T_E = 10 s = T_R / 2 -> parametric only.
    a = assess(v, None, hs_m=3.0, tp_s=10.0, wave_from_deg=90.0, heading_deg=0.0)
    assert not a.fired("synchronous_roll") and a.fired("parametric_roll")
    # Head seas: T_E = 300/45 = 6.67 s: neither (T_R/2 band 9..11)
    a = assess(v, None, hs_m=3.0, tp_s=10.0, wave_from_deg=0.0, heading_deg=0.0)
    assert not a.fired("parametric_roll")
    # Gate: with an IMO gate of 4 m, 3 m waves do not trigger resonance rules.
    a = assess(v, None, hs_m=3.0, tp_s=10.0, wave_from_deg=180.0, heading_deg=0.0, imo_settings=ImoSettings(gate_hs_m=4.0))
    assert not a.fired("synchronous_roll") and np.isnan(a.margin("synchronous_roll"))


def test_roll_rules_skipped_without_stability_data():
    a = assess(make_vessel(), None, hs_m=3.0, tp_s=10.0, wave_from_deg=180.0, heading_deg=0.0)
    assert "synchronous_roll" not in a.rules
    assert any(s.startswith("synchronous_roll: no GM") for s in a.skipped)


# ---------------------------------------------------------------- operator limits

TABLE1 = OperatorLimits(
    name="table1",
    hs_max_m=6.0,
    wind_max_ms=22.6,
    period_kind="peak",
    period_forbidden_s=[[7.0, 15.0]],
    beam_sectors_deg=[[60.0, 120.0], [240.0, 300.0]],
    gate_hs_m=2.5,
)


def test_operator_hs_and_wind_boundaries():
    a = evaluate_operator(TABLE1, hs_m=[6.0, 6.01], tp_s=5.0, wind_ms=[22.6, 22.61])
    assert a.fired("hs").tolist() == [False, True]
    assert a.fired("wind").tolist() == [False, True]
    np.testing.assert_allclose(a.margin("hs"), [0.0, 0.01], atol=1e-12)
    # From components: hypot(16, 16) = 22.627 m/s > 22.6; hypot(15.9, 15.9) = 22.486 m/s
    a = evaluate_operator(TABLE1, hs_m=1.0, tp_s=5.0, wind_u_ms=[16.0, 15.9], wind_v_ms=[16.0, -15.9])
    assert a.fired("wind").tolist() == [True, False]


def test_operator_forbidden_period_range_and_gate():
    a = evaluate_operator(TABLE1, hs_m=[3.0, 3.0, 3.0, 3.0, 2.49, np.nan], tp_s=[6.99, 7.0, 15.0, 15.01, 10.0, 10.0], wind_ms=5.0)
    assert a.fired("period").tolist() == [False, True, True, False, False, False]
    np.testing.assert_allclose(a.margin("period")[:4], [-0.01, 0.0, 0.0, -0.01], atol=1e-12)
    assert np.isnan(a.margin("period")[4])  # gated out: not applicable
    assert a.no_data.tolist() == [False] * 5 + [True]


def test_operator_allowed_period_range():
    lim = OperatorLimits(name="allowed", period_kind="mean", period_max_s=8.0)
    a = evaluate_operator(lim, tm_s=[8.0, 8.01, 2.0])
    assert a.fired("period").tolist() == [False, True, False]
    lim = OperatorLimits(name="allowed", period_min_s=7.0, period_max_s=15.0)
    a = evaluate_operator(lim, tp_s=[6.99, 7.0, 15.0, 15.01])
    assert a.fired("period").tolist() == [True, False, False, True]


@pytest.mark.parametrize(
    "alpha, beam",
    [(0.0, False), (59.99, False), (60.0, True), (90.0, True), (120.0, True), (120.01, False), (135.0, False),
     (180.0, False), (225.0, False), (239.99, False), (240.0, True), (300.0, True), (300.01, False), (359.9, False)],
)
def test_operator_beam_sectors(alpha, beam):
    # heading 30 deg, waves from 30 + alpha
    a = evaluate_operator(TABLE1, hs_m=3.0, tp_s=5.0, wind_ms=0.0, wave_from_deg=(30.0 + alpha) % 360.0, heading_deg=30.0)
    assert bool(a.fired("beam_seas")) is beam


def test_operator_beam_gate_and_heading_free():
    a = evaluate_operator(TABLE1, hs_m=[2.0, 3.0], tp_s=5.0, wind_ms=0.0, wave_from_deg=90.0, heading_deg=0.0)
    assert a.fired("beam_seas").tolist() == [False, True]
    a = evaluate_operator(TABLE1, hs_m=3.0, tp_s=5.0, wind_ms=0.0, wave_from_deg=90.0)
    assert "beam_seas" not in a.rules


def test_operator_missing_variables():
    with pytest.raises(MissingWeatherVariableError, match="wind"):
        evaluate_operator(TABLE1, hs_m=3.0, tp_s=5.0)
    lim = OperatorLimits(name="lpp<200", hs_max_m=4.5, period_kind="mean", period_max_s=8.0)
    with pytest.raises(MissingWeatherVariableError, match="tm_s"):
        evaluate_operator(lim, hs_m=3.0, tp_s=9.0)
    a = evaluate_operator(TABLE1, hs_m=[3.0, 7.0], tp_s=5.0, missing="skip")
    assert a.fired("hs").tolist() == [False, True] and "wind" not in a.rules
    assert a.skipped == ("wind: needs 10 m wind (wind_ms or wind_u_ms + wind_v_ms), not in the data",)


def test_reason_codes_and_explain():
    a = evaluate_operator(TABLE1, hs_m=[7.0, 1.0, np.nan], tp_s=[10.0, 5.0, 5.0], wind_ms=[25.0, 1.0, 1.0],
                          wave_from_deg=90.0, heading_deg=0.0)
    codes = a.reason_code
    assert codes.dtype == np.uint16
    assert reason_names(codes[0]) == ["hs", "period", "wind", "beam_seas"]
    assert codes[1] == 0 and a.safe.tolist() == [False, True, False]
    assert reason_names(codes[2]) == ["no_data"]
    why = {e["rule"]: e for e in a.explain(0)}
    assert why["hs"]["value"] == 7.0 and why["hs"]["limit"] == 6.0 and why["hs"]["margin"] == pytest.approx(1.0)
    assert why["wind"]["margin"] == pytest.approx(2.4) and why["wind"]["margin_unit"] == "ms"


def test_operator_limits_validation():
    with pytest.raises(OperatorProfileError, match="period_kind"):
        OperatorLimits(name="x", period_kind="median")
    with pytest.raises(OperatorProfileError, match="low > high"):
        OperatorLimits(name="x", beam_sectors_deg=[[120, 60]])
    with pytest.raises(OperatorProfileError, match="unknown key.*hs_max"):
        OperatorLimits.from_dict({"name": "x", "hs_max": 6.0}, "f.toml")
    with pytest.raises(OperatorProfileError, match="hs_max_m"):
        OperatorLimits.from_dict({"name": "x", "hs_max_m": -1.0}, "f.toml")


def test_profile_variant_selection():
    prof = OperatorProfile.from_dict("p", {"limits": [
        {"name": "big container", "vessel_class": "container", "lpp_min_m": 200.0, "hs_max_m": 6.0},
        {"name": "small container", "vessel_class": "container", "lpp_max_m": 200.0, "hs_max_m": 4.5},
        {"name": "anything", "vessel_class": "*", "hs_max_m": 5.0},
    ]})
    assert prof.limits_for("container", 250.0).name == "big container"
    assert prof.limits_for("container", 200.0).name == "big container"  # lpp_min <= Lpp
    assert prof.limits_for("container", 199.9).name == "small container"
    assert prof.limits_for("tanker", 150.0).name == "anything"
    only = OperatorProfile.from_dict("q", {"limits": [{"name": "c", "vessel_class": "container"}]})
    with pytest.raises(OperatorProfileError, match="no limits for vessel class 'tanker'"):
        only.limits_for("tanker", 100.0)


# ---------------------------------------------------------------- combined assessment and mask


def test_assess_combines_operator_and_imo():
    prof = OperatorProfile("p", (TABLE1,), imo=ImoSettings())
    v = make_vessel(lpp_m=100.0, speed_kn=25.0, roll_period_s=30.0)
    # following seas, L 100 m: surf-riding limit 18 kn < 25 kn; Hs 5 m > 4 m and T 9 s (lambda 126 m > 80 m),
    # but at 25 kn the ship overtakes the waves: T_E / T_W = 27 / |27 - 25| = 13.5, outside 1.8-3.0 (4.2.2.2)
    a = assess(v, prof, hs_m=5.0, tp_s=9.0, wind_ms=5.0, wave_from_deg=180.0, heading_deg=0.0)
    fired = sorted(k for k, r in a.rules.items() if r.fired)
    assert fired == ["period", "surf_riding"]
    assert a.reason_code == REASON_BITS["period"] | REASON_BITS["surf_riding"]
    # at 13 kn: T_E / T_W = 27 / 14 = 1.93, in the dangerous zone of figure 3 -> successive high waves
    a = assess(v, prof, hs_m=5.0, tp_s=9.0, wind_ms=5.0, wave_from_deg=180.0, heading_deg=0.0, speed_kn=13.0)
    assert sorted(k for k, r in a.rules.items() if r.fired) == ["high_waves", "period"]


def test_safe_cell_mask_shapes_and_headings():
    v = make_vessel(lpp_m=250.0, speed_kn=18.0)
    lim = OperatorLimits(name="t", hs_max_m=6.0, beam_sectors_deg=[[60.0, 120.0], [240.0, 300.0]], gate_hs_m=2.5)
    hs = np.array([[[3.0, 7.0, np.nan]]])  # (time 1, lat 1, lon 3)
    wdir = np.full_like(hs, 90.0)  # waves from the east
    headings = [0.0, 90.0, 180.0, 270.0]
    safe, reason = safe_cell_mask(v, lim, headings, hs_m=hs, wave_from_deg=wdir, tp_s=np.full_like(hs, 6.0),
                                  imo_settings=ImoSettings(enabled=False))
    assert safe.shape == (4, 1, 1, 3) and reason.shape == (4, 1, 1, 3)
    # cell 0 (Hs 3 m): beam seas on headings 0 and 180, safe on 90 (head) and 270 (following)
    assert safe[:, 0, 0, 0].tolist() == [False, True, False, True]
    assert reason[0, 0, 0, 0] == REASON_BITS["beam_seas"]
    # cell 1 (Hs 7 m): Hs limit on every heading; cell 2 (land): no data on every heading
    assert not safe[:, 0, 0, 1].any() and all(r & REASON_BITS["hs"] for r in reason[:, 0, 0, 1])
    assert (reason[:, 0, 0, 2] == REASON_BITS["no_data"]).all()


# ---------------------------------------------------------------- properties

from hypothesis import given, settings
from hypothesis import strategies as st

angles = st.floats(0.0, 359.999, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(speed=st.floats(0.0, 40.0), alpha=angles, length=st.floats(20.0, 400.0))
def test_surf_riding_properties(speed, alpha, length):
    r = surf_riding(speed, alpha, length)
    mirrored = surf_riding(speed, (360.0 - alpha) % 360.0, length)  # port and starboard quartering seas
    assert bool(r.fired) == bool(mirrored.fired)
    if r.fired:
        assert 135.0 < alpha < 225.0 and speed > 1.8 * math.sqrt(length) and r.margin > 0
    else:
        assert r.margin <= 0 or np.isneginf(r.margin)


@settings(max_examples=200, deadline=None)
@given(hs=st.floats(0.0, 15.0), tp=st.floats(2.0, 20.0), wind=st.floats(0.0, 40.0), heading=angles, wave_from=angles)
def test_reason_code_zero_iff_no_rule_fired(hs, tp, wind, heading, wave_from):
    a = evaluate_operator(TABLE1, hs_m=hs, tp_s=tp, wind_ms=wind, wave_from_deg=wave_from, heading_deg=heading)
    fired = [name for name, rule in a.rules.items() if bool(rule.fired)]
    assert (int(a.reason_code) == 0) == (not fired)
    assert reason_names(a.reason_code) == [n for n in REASON_BITS if n in fired]
    for name in fired:
        assert a.rules[name].margin >= 0


@pytest.mark.parametrize("speed_kn,wave_from,fires", [
    (13.0, 180.0, True),    # following: T_E / T_W = 27 / 14 = 1.93
    (12.1, 180.0, True),    # 27 / 14.9 = 1.81, just inside
    (11.0, 180.0, False),   # 27 / 16 = 1.69
    (18.0, 180.0, True),    # 27 / 9 = 3.0
    (19.0, 180.0, False),   # 27 / 8 = 3.375
    (13.0, 0.0, False),     # head seas: T_E < T_W at any speed
    (0.0, 180.0, False),    # stopped: T_E = T_W
])  # fmt: skip
def test_successive_high_waves_needs_the_encounter_period_band(speed_kn, wave_from, fires):
    # MSC.1/Circ.1228 4.2.2.1-4.2.2.2: lambda > 0.8 L, Hs > 0.04 L and T_E about 1.8-3.0 T_W; T_W = 9 s, L = 100 m
    v = make_vessel(lpp_m=100.0, speed_kn=speed_kn)
    a = assess(v, None, hs_m=5.0, tm_s=9.0, wave_from_deg=wave_from, heading_deg=0.0, speed_kn=speed_kn)
    assert bool(a.fired("high_waves")) is fires
    # without a heading the band cannot be judged: the rule is listed as not evaluated, never fired
    b = assess(v, None, hs_m=5.0, tm_s=9.0)
    assert "high_waves" not in b.rules and any(s.startswith("high_waves: no heading") for s in b.skipped)
