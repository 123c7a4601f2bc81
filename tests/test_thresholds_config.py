"""Operator profiles as configuration: the shipped TOML, user files, and clear errors."""

from __future__ import annotations

import pytest

from pipelines.config import load_operator_profile, operator_profile_names
from thresholds.operator import OperatorProfileError


def test_default_profile_reads_the_mepc_table_as_a_table():
    prof = load_operator_profile()
    assert prof.name == "default"
    big = prof.limits_for("container", 250.0)
    # MEPC.1/Circ.850/Rev.2 (seed Table 1 copies its Lpp > 250 m row): Hs 6.0 m with Tp 7.0-15.0 s, wind 22.6 m/s;
    # seed Table 1: beam seas 60-120 / 240-300
    assert (big.hs_max_m, big.wind_max_ms, big.period_kind, big.hs_period_range_s) == (6.0, 22.6, "peak", (7.0, 15.0))
    assert big.period_forbidden_s == () and not big.uses_period  # no forbidden period on its own
    assert big.beam_sectors_deg == ((60.0, 120.0), (240.0, 300.0))
    # 200 <= Lpp <= 250: "parameters linearly interpolated depending on ship's length"
    mid = prof.limits_for("container", 225.0)
    assert (mid.hs_max_m, mid.wind_max_ms) == pytest.approx((4.5 + 1.5 * 25 / 50, 19.0 + 3.6 * 25 / 50))
    assert prof.limits_for("container", 320.0).hs_max_m == 6.0
    # the Hs limit is the row's: it fires with a 7-15 s peak period, not with a 16 s swell
    from thresholds.operator import evaluate_operator

    a = evaluate_operator(big, hs_m=[6.5, 6.5, 5.0], tp_s=[10.0, 16.0, 10.0], wind_ms=[5.0, 5.0, 5.0])
    assert a.fired("hs").tolist() == [True, False, False]
    small = prof.limits_for("container", 180.0)
    # Section 3.2, Lpp < 200 m: Hs 4.5 m, mean period must not exceed 8 s, wind 19 m/s
    assert (small.hs_max_m, small.wind_max_ms, small.period_kind, small.period_max_s) == (4.5, 19.0, "mean", 8.0)
    assert prof.limits_for("ro-pax", 180.0).name.startswith("any class")
    assert prof.imo.enabled and prof.imo.roll_tolerance_frac == 0.10


def test_shipped_profiles_all_load():
    names = operator_profile_names()
    assert {"default", "seed-literal", "hs-wind-only"} <= set(names)
    for name in names:
        assert load_operator_profile(name).limits
    literal = load_operator_profile("seed-literal")
    assert all(l.gate_hs_m == 0.0 for l in literal.limits) and literal.imo.gate_hs_m == 0.0


def test_unknown_profile_lists_available():
    with pytest.raises(OperatorProfileError, match=r"unknown operator profile 'nope'.*available: default"):
        load_operator_profile("nope")


def test_user_file_single_profile(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(
        'description = "ferry line"\n'
        "[imo]\nenabled = false\n"
        '[[limits]]\nname = "ro-pax"\nvessel_class = "ro-pax"\nhs_max_m = 3.5\nwind_max_ms = 17.0\n'
    )
    prof = load_operator_profile(path)
    assert prof.name == "mine" and not prof.imo.enabled
    assert prof.limits_for("ro-pax", 150.0).hs_max_m == 3.5


def test_user_file_several_profiles(tmp_path):
    path = tmp_path / "fleet.toml"
    path.write_text(
        'default = "calm"\n'
        '[profiles.calm]\n[[profiles.calm.limits]]\nname = "c"\nhs_max_m = 2.0\n'
        '[profiles.rough]\n[[profiles.rough.limits]]\nname = "r"\nhs_max_m = 5.0\n'
    )
    assert load_operator_profile(path).limits[0].hs_max_m == 2.0
    assert load_operator_profile(f"{path}:rough").limits[0].hs_max_m == 5.0


def test_bad_files_name_the_problem(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[profiles.x\nname = 1\n")
    with pytest.raises(OperatorProfileError, match=r"bad.toml: invalid TOML.*line 1"):
        load_operator_profile(bad)
    typo = tmp_path / "typo.toml"
    typo.write_text('[[limits]]\nname = "a"\nhs_max = 4.0\n')
    with pytest.raises(OperatorProfileError, match=r"typo.toml limits\[0\]: unknown key\(s\) hs_max"):
        load_operator_profile(typo)
    with pytest.raises(OperatorProfileError, match="not found"):
        load_operator_profile(tmp_path / "missing.toml")
    empty = tmp_path / "empty.toml"
    empty.write_text('description = "nothing"\n')
    with pytest.raises(OperatorProfileError, match="at least one"):
        load_operator_profile(empty)
