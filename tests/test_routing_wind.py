"""Wind-only weather (NOAA GFS GRIB, 10 m wind) is routed by Kwon's model, and refused by the wave
models naming the model, the variable and the file (it used to route as a calm sea); the same for
Kwon on a wave-only product; Khokhlov outside its range; every model's route on Storm Gloria (the
wave models: it has no wind), on the demo's storm (all four) and on wind-only weather is not slower
than the minimum-distance route under the same model."""

from __future__ import annotations

import json
import math

import pytest

from conftest import shared_file

GFS = "weather/gweatherrouting_gfs_grib1/20130311_120424_.grb"
GLORIA = "weather/simroute_cmems_medsea_wav"


def run(capsys, *args):
    from pipelines.cli import main

    try:
        main(list(args))
        code = 0
    except SystemExit as exc:
        code = exc.code or 0
    out = capsys.readouterr()
    return code, out.out, out.err


GFS_ARGS = ("route", "--from", "39.0,3.5", "--to", "42.5,5.5", "--depart", "2013-03-11T12:00Z", "--mesh-nmi", "3")


def test_wind_only_weather_needs_a_wind_model(shared_data, capsys):
    pytest.importorskip("cfgrib", reason="cfgrib (GRIB reader) not installed")
    path = shared_file(shared_data, GFS)
    code, out, err = run(capsys, *GFS_ARGS, "--weather", str(path), "--speed-loss", "bowditch")
    assert code == 2 and out == ""
    assert err.strip() == (f"error: speed-loss model bowditch needs the significant wave height (hs_m), which the weather lacks "
                           f"(files: {path}); it has wind_u_ms, wind_v_ms: choose --speed-loss kwon (wind) or none")
    code, out, err = run(capsys, *GFS_ARGS, "--weather", str(path), "--speed-loss", "kwon", "--json")
    assert code == 0, err
    data = json.loads(out)
    assert data["notes"][:2] == ["speed loss: kwon (Cb 0.572, container, Fn 0.221)",  # the default vessel, container-feeder
                                 "Kwon's loss reads the 10 m wind (Beaufort number and direction), not the waves"]
    assert data["optimal"]["max_hs_m"] is None  # no waves in the data: unknown, not 0
    assert data["optimal_smoothed"]["time_h"] <= data["min_distance"]["time_h"] + 1e-9
    assert data["min_distance"]["time_h"] > data["min_distance_calm"]["time_h"] * 1.02  # the wind slows the ship


def test_wave_only_weather_refuses_kwon_and_khokhlov_refuses_a_large_ship(shared_data, capsys):
    folder = shared_file(shared_data, GLORIA)
    base = ("route", "--from", "39.225,2.900", "--to", "41.500,2.775", "--depart", "2020-01-20T09:00Z", "--weather", str(folder))
    code, out, err = run(capsys, *base, "--speed-loss", "kwon")
    assert code == 2 and "speed-loss model kwon needs the 10 m wind (wind_u_ms, wind_v_ms), which the weather lacks" in err
    assert "Waves_MEDSEA_20200120.nc" in err and "it has hs_m, wave_from_deg, tp_s" in err
    code, out, err = run(capsys, *base, "--vessel", "container-large", "--speed-loss", "khokhlov")
    assert code == 2
    assert "vessel container-large has 100,000 dwt at 19 kn, D·v0 = 1.9e+06 t·kn" in err and "head seas would speed it up" in err


@pytest.mark.parametrize("model", ["bowditch", "aertssen", "khokhlov"])
def test_gloria_time_optimal_not_slower_than_minimum_distance(shared_data, capsys, model):
    folder = shared_file(shared_data, GLORIA)
    code, out, err = run(capsys, "route", "--from", "39.225,2.900", "--to", "41.500,2.775", "--depart", "2020-01-20T09:00Z",
                         "--weather", str(folder), "--speed-loss", model, "--mesh-nmi", "3", "--json")
    assert code == 0, err
    data = json.loads(out)
    assert data["optimal"]["time_h"] <= data["min_distance"]["time_h"] + 1e-9
    assert data["optimal_smoothed"]["time_h"] <= data["optimal"]["time_h"] + 1e-9
    assert data["notes"][0].startswith(f"speed loss: {model}")
    assert math.isfinite(data["optimal"]["max_hs_m"]) and data["optimal"]["max_hs_m"] > 6.0


@pytest.fixture(scope="module")
def demo_storm_weather(tmp_path_factory):
    """The demo's weather (CMEMS GLOBAL waves + ERA5 wind, the demo's writers) around its first storm."""
    from weather.io.scenario_files import write_scenario_weather
    from weather.scenario import generate_weather

    out = tmp_path_factory.mktemp("demo")
    write_scenario_weather(out, weather=generate_weather(seed=0, start="2025-01-14T12:00Z", end="2025-01-15T18:00Z"))
    return out / "weather"


@pytest.mark.parametrize("model", ["bowditch", "aertssen", "khokhlov", "kwon"])
def test_demo_time_optimal_not_slower_than_minimum_distance(demo_storm_weather, capsys, model):
    # README's tour route (Barcelona -> Palma) as its storm passes; the demo has waves and wind, so every model routes
    code, out, err = run(capsys, "route", "--from", "41.35,2.17", "--to", "39.56,2.63", "--depart", "2025-01-14T18:00Z",
                         "--weather", str(demo_storm_weather), "--speed-loss", model, "--json")
    assert code == 0, err
    data = json.loads(out)
    assert data["notes"][0].startswith(f"speed loss: {model}")
    assert data["optimal"]["time_h"] <= data["min_distance"]["time_h"] + 1e-9
    assert data["optimal_smoothed"]["time_h"] <= data["optimal"]["time_h"] + 1e-9
    # the storm slows the ship under every model (Hs up to about 4.8 m, Beaufort 7-8 on this leg)
    assert data["min_distance"]["time_h"] > data["min_distance_calm"]["time_h"] * 1.005
    assert data["optimal"]["max_hs_m"] > 4.0
