"""The performance training table on real AIS files (NOAA, DMA) with weather written in the products'
schemas for their area and dates, and the pure pieces of :mod:`performance` on hand-computed cases.

The weather is analytic (Hs linear in latitude and in time, waves from a fixed direction, a fixed
wind), so the value the table must hold at every kept fix is known exactly: the ASOF join's
nearest cell and its linear interpolation in time reproduce a field linear in both.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from conftest import shared_file

NOAA_CSV = "ais/noaa_marinecadastre_20230111_sample.csv"
DMA_NMEA = "ais/nmea/dma_ais-sample_20131112.nmea.gz"


def _hs(lat, hours):
    """The analytic Hs: 1 m + 0.05 m per degree north of 20 N + 0.1 m per hour after the first time."""
    return 1.0 + 0.05 * (np.asarray(lat) - 20.0) + 0.1 * np.asarray(hours)


def _write_weather(folder, bbox, t0, t1):
    """CMEMS waves (0.5 deg, 3-hourly) and ERA5 wind (0.5 deg, hourly) over ``bbox`` from t0 to t1."""
    from weather.io.cmems import write_cmems_wave
    from weather.io.era5 import write_era5

    lon0, lat0, lon1, lat1 = bbox
    lat = np.arange(np.floor(lat0) - 1, np.ceil(lat1) + 1.01, 0.5)
    lon = np.arange(np.floor(lon0) - 1, np.ceil(lon1) + 1.01, 0.5)
    tw = pd.date_range(t0, t1, freq="3h").as_unit("ns").tz_localize(None)
    hours = ((tw - tw[0]) / pd.Timedelta(hours=1)).to_numpy()
    hs = _hs(lat[None, :, None], hours[:, None, None]) * np.ones((1, 1, lon.size))
    shape = hs.shape
    waves = xr.Dataset({"hs_m": (("time_utc", "lat", "lon"), hs.astype(np.float32)),
                        "wave_from_deg": (("time_utc", "lat", "lon"), np.full(shape, 270.0, np.float32)),
                        "tp_s": (("time_utc", "lat", "lon"), np.full(shape, 8.0, np.float32)),
                        "tm_s": (("time_utc", "lat", "lon"), np.full(shape, 6.5, np.float32))},
                       coords={"time_utc": tw.values, "lat": lat, "lon": lon})
    ta = pd.date_range(t0, t1, freq="1h").as_unit("ns").tz_localize(None)
    wshape = (ta.size, lat.size, lon.size)
    wind = xr.Dataset({"wind_u_ms": (("time_utc", "lat", "lon"), np.full(wshape, 5.0, np.float32)),
                       "wind_v_ms": (("time_utc", "lat", "lon"), np.full(wshape, -3.0, np.float32))},
                      coords={"time_utc": ta.values, "lat": lat, "lon": lon})
    folder.mkdir()
    write_cmems_wave(waves, folder / "cmems_waves.nc")
    write_era5(wind, folder / "era5_wind.nc")
    return tw[0]


@pytest.mark.parametrize("rel", [NOAA_CSV, DMA_NMEA])
def test_training_table_on_real_ais_keeps_only_clean_fixes_with_the_weather_they_met(shared_data, tmp_path, rel):
    from pipelines.ingest import ingest_paths
    from pipelines.storage import open_workspace
    from pipelines.storage.training import RULES, CleaningRules, training_table
    from pipelines.storage.weather import get_grid
    from pipelines.weather import load_weather_paths

    path = shared_file(shared_data, rel)
    db = tmp_path / "ws.duckdb"
    ingest_paths([path], db)
    with open_workspace(db) as ws:
        pos = ws.con.execute("SELECT mmsi, time_utc, lat_deg, lon_deg, sog_kn, cog_deg, nav_status FROM ais_positions").df()
    pos["time_utc"] = pd.to_datetime(pos["time_utc"], utc=True)
    bbox = (pos.lon_deg.min(), pos.lat_deg.min(), pos.lon_deg.max(), pos.lat_deg.max())
    t_first = _write_weather(tmp_path / "wx", bbox, pos.time_utc.min().floor("3h") - pd.Timedelta(hours=3),
                             pos.time_utc.max().ceil("3h") + pd.Timedelta(hours=3))
    load_weather_paths([tmp_path / "wx"], db)
    with open_workspace(db) as ws:
        grid = get_grid(ws)
        table, info = training_table(ws, grid, rules=CleaningRules())

    # every fix of the span is either kept or counted under exactly one rule
    assert info["fixes_in_span"] == len(pos)
    assert sum(info["counts"].values()) + info["kept"] == len(pos)
    assert set(info["counts"]) == set(RULES)
    assert info["kept"] == len(table) > 0
    # no workspace lanes: the two distance rules say they were not applied
    assert set(info["not_applied"]) == {"near_port", "lane_end"}
    # the kept fixes obey the rules, checked against the positions independently
    assert (table["nav_status"] == 0).all()
    assert (table["sog_kn"] >= 5.0).all() and table["cog_deg"].notna().all()
    # the first rules in their order, counted from the positions (every ship is in class: no --class)
    assert info["counts"]["class"] == 0
    assert info["counts"]["not_underway"] == int((pos.nav_status.fillna(-1) != 0).sum())  # NaN: not under way
    underway = pos[pos.nav_status == 0]
    assert info["counts"]["slow"] == int((underway.sog_kn.isna() | (underway.sog_kn < 5.0)).sum())
    assert info["counts"]["no_course"] == int((underway.sog_kn >= 5.0).mul(underway.cog_deg.isna()).sum())
    # the weather at each kept fix is the analytic field at its nearest cell, linear in time
    lat_c = float(grid["lat0_deg"]) + np.round((table["lat_deg"] - float(grid["lat0_deg"])) / float(grid["dlat_deg"])) * float(grid["dlat_deg"])
    hours = (table["time_utc"] - pd.Timestamp(t_first, tz="UTC")) / pd.Timedelta(hours=1)
    np.testing.assert_allclose(table["hs_m"], _hs(lat_c, hours), atol=0.011)  # CMEMS packs Hs in 0.01 m
    np.testing.assert_allclose(table["wave_from_deg"], 270.0, atol=0.1)
    np.testing.assert_allclose(table["wind_u_ms"], 5.0, atol=0.01)
    np.testing.assert_allclose(table["wind_v_ms"], -3.0, atol=0.01)
    assert table["voyage_id"].notna().all()


def test_relative_weather_hand_computed():
    from performance.features import fold_deg, relative_weather

    # heading north (0 deg) into waves from 45 deg; wind blowing towards the south-west at 10 m/s
    # (from the north-east): head component 10 cos 45, cross 10 sin 45; current 1 m/s to the north
    r = relative_weather(0.0, 45.0, -10 / np.sqrt(2), -10 / np.sqrt(2), 0.0, 1.0)
    assert float(r["encounter_deg"]) == pytest.approx(45.0)
    assert float(r["wind_head_ms"]) == pytest.approx(10 / np.sqrt(2))
    assert float(r["wind_cross_ms"]) == pytest.approx(10 / np.sqrt(2))
    assert float(r["current_along_kn"]) == pytest.approx(1 / 0.514444, rel=1e-5)
    assert float(r["current_cross_kn"]) == pytest.approx(0.0, abs=1e-12)
    assert fold_deg([0, 90, 180, 270, 350]).tolist() == [0, 90, 180, 90, 10]


def test_calm_water_speed_takes_the_low_sea_state_median_and_falls_back_per_ship():
    from performance.features import calm_water_speed

    n = 20
    calm = pd.DataFrame({"voyage_id": "a", "mmsi": 1, "hs_m": 0.5, "wind_ms": 3.0, "stw_kn": np.linspace(14, 16, n)})
    rough = pd.DataFrame({"voyage_id": "b", "mmsi": 1, "hs_m": 3.0, "wind_ms": 15.0, "stw_kn": np.full(n, 11.0)})
    out = calm_water_speed(pd.concat([calm, rough], ignore_index=True))
    assert out.loc[out.voyage_id == "a", "v0_kn"].unique().tolist() == [15.0]
    assert out.loc[out.voyage_id == "a", "v0_source"].unique().tolist() == ["voyage"]
    # voyage b never met a low sea state: the ship's other voyages' calm speed
    assert out.loc[out.voyage_id == "b", "v0_kn"].unique().tolist() == [15.0]
    assert out.loc[out.voyage_id == "b", "v0_source"].unique().tolist() == ["vessel"]


def test_voluntary_step_is_found_where_the_data_put_it_and_not_in_a_smooth_loss():
    from performance.voluntary import step

    rng = np.random.default_rng(3)
    hs = rng.uniform(0.0, 5.0, 20_000)
    voyage = rng.integers(0, 40, hs.size)
    smooth = 1.0 - 0.02 * hs**1.5
    ramp = np.clip((hs - 3.0) / 0.4, 0.0, 1.0)  # 15 % taken off between 3.0 and 3.4 m
    got = step(hs, smooth * (1 - 0.15 * ramp) + rng.normal(0, 0.01, hs.size), voyage)
    assert got["threshold_hs_m"] is not None
    assert 3.0 <= got["threshold_hs_m"] <= 3.5
    assert got["drop_frac"] > 0.03
    none = step(hs, smooth + rng.normal(0, 0.01, hs.size), voyage)
    assert none["threshold_hs_m"] is None and "no voluntary step" in none["why"]


def test_band_scale_is_the_finite_sample_conformal_quantile():
    from performance.validate import band_scale, conformity, widen

    # ceil(0.85 * 21) = 18th smallest of 0..19 (scores -1.0 .. 0.9 in steps of 0.1)
    scores = np.arange(-10, 10) / 10.0
    assert band_scale(scores) == pytest.approx(0.7)
    assert band_scale(np.array([np.nan])) == 0.0
    s = conformity([1.0, 0.5, 2.5], [0.0, 1.0, 0.0], [2.0, 2.0, 2.0])  # additive (CQR, Romano et al. Eq. 6)
    np.testing.assert_allclose(s, [-1.0, 0.5, 0.5])
    lo, hi = widen([0.0], [2.0], 0.25)
    assert (lo[0], hi[0]) == (-0.25, 2.25)


def test_the_conformal_margin_is_found_per_sea_state_band():
    from performance.fit import scale_at
    from performance.validate import MIN_BAND_SCORES, band_scale, band_scales

    rng = np.random.default_rng(0)
    hs = np.r_[np.full(400, 0.5), np.full(400, 3.5), np.full(10, 5.0)]
    # calm seas: scores 0..0.01; heavy seas: ten times larger; Hs >= 4 m: too few scores of its own
    score = np.r_[rng.uniform(0, 0.01, 400), rng.uniform(0, 0.1, 400), np.full(10, 9.0)]
    got = dict((lo, v) for lo, v in band_scales(score, hs))
    assert got[0.0] == band_scale(score[:400]) and got[3.0] == band_scale(score[400:800])
    assert got[3.0] > 5 * got[0.0]
    assert 10 < MIN_BAND_SCORES and got[1.0] == got[2.0] == got[4.0] == band_scale(score)  # too few: the overall margin
    np.testing.assert_allclose(scale_at([0.2, 3.9, 7.0, np.nan], band_scales(score, hs)), [got[0.0], got[3.0], got[4.0], got[0.0]])


def test_scores_are_r2_mae_and_bias_in_knots():
    from performance.validate import scores

    obs = np.array([10.0, 12.0, 14.0])
    got = scores(obs, obs + 1.0, np.full(3, 15.0))
    assert got["n"] == 3 and got["mae_kn"] == pytest.approx(1.0) and got["bias_kn"] == pytest.approx(1.0)
    assert got["r2_speed"] == pytest.approx(1.0 - 3.0 / 8.0)
    assert got["r2_loss"] == pytest.approx(1.0 - 3.0 / 8.0)


def test_a_class_the_model_never_saw_is_not_learned_rather_than_none_found():
    """`nightly --speed-loss learned:pax` (a model of passenger ships only) on tanker lanes printed 'tanker
    (tanker-aframax): no voluntary slow-down found in head-to-bow seas', evidence the model never had."""
    from pipelines.config import load_vessel
    from pipelines.learn import beside_operator_limits, limit_line

    voluntary = [{"ship_class": "passenger", "sector": "head-bow", "threshold_hs_m": 3.5, "from_hs_m": 3.4, "to_hs_m": 3.6}]
    rows = beside_operator_limits(voluntary, None, [load_vessel("tanker-aframax"), load_vessel("ro-pax")])
    tanker, pax = rows
    assert tanker["learned_hs_m"] is None and limit_line(tanker).startswith("tanker (tanker-aframax): not learned: the model holds no tanker ships;")
    assert limit_line(pax).startswith("passenger (ro-pax): masters slow down above Hs 3.50 m")
