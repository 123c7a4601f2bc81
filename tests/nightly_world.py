"""The demo scenario's world for the nightly tests and benchmark: lanes in a workspace, forecast weather files.

The AIS part skips the file round trip (tested by the ingest tests): the fixes the scenario's
ships reported go straight through the lanes chain and into the workspace, as
``tests/test_lanes_demo.py`` does. The weather is the demo's own generator and writers (CMEMS
GLOBAL waves, ERA5 wind) for the nightly window only: its fields are functions of absolute time,
so the window equals the same slice of the whole month.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

#: The demo's nightly run (COMMON.md): forecast time and the weather the nightly reads.
NOW = "2025-01-31T00:00Z"
WEATHER_START = "2025-01-30T00:00Z"
WEATHER_END = "2025-02-02T06:00Z"


def build_world(folder: Path, *, seed: int = 0, days: float = 30.0) -> dict:
    """Write ``folder/ws.duckdb`` (ports, voyages, lanes) and ``folder/weather/*.nc``; return the paths
    (and ``positions``: the fixes the lanes were built from, for audits of the demo's voyages)."""
    from lanes.chain import build_lanes
    from lanes.io.portlist import read_port_lists
    from scenario.generator import ScenarioSettings, generate_scenario
    from pipelines.config import data_dir
    from pipelines.lanes import LanesSettings, store_result
    from pipelines.scenario import load_scenario_spec
    from weather.io.scenario_files import write_scenario_weather
    from weather.scenario import generate_weather

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    spec = load_scenario_spec()
    sc = generate_scenario(spec, ScenarioSettings(seed=seed, start_utc=pd.Timestamp("2025-01-01T00:00Z"), days=days))
    fixes = sc.fixes[sc.fixes["received"]]
    positions = pd.DataFrame({
        "mmsi": fixes["mmsi"].to_numpy(), "time_utc": pd.to_datetime(fixes["time_s"].to_numpy(), unit="s", utc=True),
        "lat_deg": fixes["lat_deg"].to_numpy(), "lon_deg": fixes["lon_deg"].to_numpy(), "sog_kn": fixes["sog_kn"].to_numpy(),
    })
    known, _ = read_port_lists([data_dir() / "ports.csv"])
    settings = LanesSettings()
    result = build_lanes(positions, known, settings.chain_params())
    db = folder / "ws.duckdb"
    store_result(db, result, settings)
    info = write_scenario_weather(folder, seed=seed, weather=generate_weather(seed, start=WEATHER_START, end=WEATHER_END))
    return {"db": db, "weather": folder / "weather", "storms": info["storms"], "folder": folder, "positions": positions}
