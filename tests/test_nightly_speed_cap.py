"""A lane faster than the night's vessel can sail: sailed at the vessel's maximum-power speed, and said.

Found by trying `stormlane nightly --vessel tanker-aframax` on the demo's ro-pax lanes: every
route, the lane as planned included, was sailed at the lanes' AIS 20-22 kn, beyond the aframax's
installed power (its maximum-power speed, STEAM2's cubic law inverted, is 16.5 kn), without a word.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from pipelines.config import load_operator_profile, load_vessel
from pipelines.nightly.reroute import lane_speed, lane_speed_vessel
from test_nightly_beyond_weather import T0, _calm_weather

#: tanker-aframax: design 15 kn at 75 % engine load, so 15 * 0.75 ** (-1/3) kn at full power (by hand)
AFRAMAX_TOP_KN = 15.0 * 0.75 ** (-1.0 / 3.0)


def _lane(speed_kn: float) -> pd.DataFrame:
    """5 centroids along 40 N, 1 deg of longitude apart."""
    return pd.DataFrame({"seq": range(5), "lat_deg": 40.0, "lon_deg": [2.5, 3.5, 4.5, 5.5, 5.9], "speed_kn": speed_kn})


def test_the_lane_speed_is_capped_at_the_maximum_power_speed():
    aframax = load_vessel("tanker-aframax")
    assert (aframax.design_speed_kn, aframax.engine_load_frac) == (15.0, 0.75)
    sailed, typical = lane_speed(aframax, _lane(20.0))
    assert typical == 20.0 and sailed == pytest.approx(AFRAMAX_TOP_KN, abs=1e-9) and sailed == pytest.approx(16.51, abs=0.005)
    assert lane_speed(aframax, _lane(12.0)) == (12.0, 12.0)
    assert lane_speed(aframax, _lane(0.0)) == (None, None)  # no speed: the profile's own
    assert lane_speed_vessel(aframax, _lane(20.0)).speed_kn == pytest.approx(AFRAMAX_TOP_KN)
    assert lane_speed_vessel(aframax, _lane(0.0)).speed_kn == aframax.speed_kn


def test_every_route_of_a_capped_lane_is_sailed_at_the_cap():
    from pipelines.nightly.night import LaneJob
    from pipelines.nightly.reroute import reroute_lane
    from pipelines.routing_weather import field_from_dataset

    job = LaneJob(path_id="L", lane_id="L", centroids=_lane(20.0), vessel=load_vessel("tanker-aframax"),
                  limits=load_operator_profile(), speed_loss="bowditch", departures=[T0],
                  weather=field_from_dataset(_calm_weather(48)), safety="soft", least_fuel=False)
    (out,) = reroute_lane(job)
    assert out["status"] == "adverse", out.get("error")
    for role, ev in out["evaluations"].items():
        legs = np.asarray(ev.route.leg_speed_kn, dtype=float)
        # the calm-water setting is the cap; Hs 1 m takes a little off it, never adds
        assert legs.max() <= AFRAMAX_TOP_KN + 1e-6 and legs.max() > AFRAMAX_TOP_KN - 1.0, role


def test_the_night_says_which_lanes_were_capped():
    from dashboards.nightly_page import speed_capped_text
    from pipelines.nightly import Night, NightlyParams, NightPath, assemble
    from pipelines.nightly.rank import overview_of

    paths = [NightPath("fast", "fast", "A", "B", _lane(20.0), "tanker-aframax"),
             NightPath("slow", "slow", "B", "A", _lane(12.0), "tanker-aframax"),
             NightPath("quiet", "quiet", "C", "A", _lane(21.0), "tanker-aframax")]
    night = Night(run_id="x", now_utc=T0, departures=pd.DatetimeIndex([T0]), params=NightlyParams(), paths=paths,
                  weather_ds=None, weather_meta={}, weather_source="files", weather_digest="", lanes_digest="",
                  vessels={"tanker-aframax": load_vessel("tanker-aframax")}, limits=None, out=None)
    screen = pd.DataFrame([{"path_id": pid, "depart_utc": T0, "n_points": 5, "n_points_no_weather": 0, "adverse": pid != "quiet",
                            "rules": ["hs"], "reasons": [], "max_hs_m": 5.0, "worst_time_utc": T0, "worst_lat_deg": 40.0,
                            "worst_lon_deg": 3.0, "error": None} for pid in ("fast", "slow", "quiet")])
    outcomes = [{"path_id": pid, "depart_utc": T0, "status": "failed", "error": "x"} for pid in ("fast", "slow")]
    outcomes[0]["status"] = "adverse"
    outcomes[0].update(proposed=None, evaluations={})
    summary = overview_of(assemble(night, screen, outcomes))
    # the rerouted lane only: the slow one is within the engine, the quiet one was not sailed by the model
    assert summary["speed_capped"] == [{"lane": "fast", "vessel": "tanker-aframax", "ais_kn": 20.0, "sailed_kn": 16.51}]
    json.dumps(summary["speed_capped"])  # the CLI's --json and report.json carry it
    text = speed_capped_text(summary["speed_capped"])
    assert text.startswith("1 rerouted lane(s) were sailed faster by their ships than the vessel profile can sail")
    assert "fast (tanker-aframax): AIS 20.0 kn, sailed at 16.5 kn" in text
    assert speed_capped_text([]) is None
