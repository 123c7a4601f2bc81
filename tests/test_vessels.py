"""Vessel profiles in data/vessels and the loader pipelines.config.load_vessel."""

from __future__ import annotations

import pytest

from pipelines.config import VesselProfileError, list_vessels, load_vessel
from thresholds.errors import StormlaneError


def test_shipped_profiles_load():
    names = list_vessels()
    assert {"simroute-r6", "container-feeder", "container-large", "ro-pax", "tanker-aframax"} <= set(names)
    for name in names:
        vessel = load_vessel(name)
        assert vessel.name == name
        assert 0 < vessel.min_speed_kn < vessel.speed_kn <= vessel.design_speed_kn * 1.2
        assert vessel.gm_m is not None or vessel.roll_period_s is not None


def test_simroute_r6_profile_matches_the_paper_and_manual():
    v = load_vessel("simroute-r6")
    # Grifoll et al. 2022, R6 metadata: v0 16.1 kn, Lbp 225 m, DWT 8000 t.
    assert (v.speed_kn, v.lpp_m, v.dwt_t) == (16.1, 225.0, 8000.0)
    # SIMROUTE manual section 4a defaults.
    assert (v.installed_power_kw, v.engine_load_frac, v.design_speed_kn, v.sfoc_g_kwh, v.engine_rpm) == (
        14400.0,
        0.8,
        25.0,
        200.0,
        500.0,
    )
    assert (v.sulphur_frac, v.carbon_frac) == (0.027, 0.85)


def test_container_profiles_straddle_200m():
    assert load_vessel("container-feeder").lpp_m < 200.0 <= load_vessel("container-large").lpp_m


def test_unknown_name_lists_known_profiles():
    with pytest.raises(VesselProfileError, match="unknown vessel profile 'titanic'.*simroute-r6"):
        load_vessel("titanic")
    assert issubclass(VesselProfileError, StormlaneError)


GOOD = """
vessel_class = "general"
speed_kn = 12.0
lpp_m = 100.0
beam_m = 18.0
draught_m = 6.0
dwt_t = 6000.0
installed_power_kw = 4000.0
design_speed_kn = 13.0
engine_rpm = 500.0
sfoc_g_kwh = 200.0
"""


def test_load_from_path(tmp_path):
    path = tmp_path / "coaster.toml"
    path.write_text(GOOD + '\n[extra]\nowner = "x"\n')
    vessel = load_vessel(path)
    assert vessel.name == "coaster" and vessel.lpp_m == 100.0 and vessel.extra == {"owner": "x"}
    assert load_vessel(str(path)).dwt_t == 6000.0


@pytest.mark.parametrize(
    "text, match",
    [
        (GOOD.replace("lpp_m = 100.0\n", ""), r"missing required field\(s\) 'lpp_m'"),
        (GOOD + "lpp = 3\n", r"unknown field\(s\) 'lpp'"),
        (GOOD.replace("beam_m = 18.0", "beam_m = -1.0"), "'beam_m' must be positive"),
        (GOOD.replace("dwt_t = 6000.0", 'dwt_t = "big"'), "'dwt_t' must be a number"),
        (GOOD + "engine_load_frac = 1.5\n", "'engine_load_frac' is a fraction"),
        (GOOD + "min_speed_kn = 15.0\n", "'min_speed_kn' must be in"),
        (GOOD + "speed_kn = 13\n", "invalid TOML"),
        (GOOD.replace("speed_kn = 12.0", "speed_kn = [12"), r"invalid TOML.*line"),
    ],
)
def test_bad_profiles_name_file_and_field(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(VesselProfileError, match=match) as info:
        load_vessel(path)
    assert "bad.toml" in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(VesselProfileError, match="not found"):
        load_vessel(tmp_path / "nope.toml")
