"""Write the demo scenario's weather (:mod:`weather.scenario`) as CMEMS and ERA5 files.

``DIR/weather/`` gets one CMEMS GLOBAL wave file named as the ``copernicusmarine`` toolbox names
its subsets (``<dataset>_<variables>_<bbox>_<dates>.nc``) and one ERA5 single-levels file per
calendar month (the unit :func:`weather.io.era5.get_era5` downloads), so the demo reads its
weather through exactly the readers real downloads go through.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from weather.io.cmems import GLOBAL_WAVE_DATASET, write_cmems_wave
from weather.io.era5 import write_era5
from weather.scenario import BBOX, ScenarioWeather, generate_weather


def _bbox_tag() -> str:
    lon0, lat0, lon1, lat1 = BBOX

    def lon(x):
        return f"{abs(x):.2f}{'W' if x < 0 else 'E'}"

    def lat(y):
        return f"{abs(y):.2f}{'S' if y < 0 else 'N'}"

    return f"{lon(lon0)}-{lon(lon1)}_{lat(lat0)}-{lat(lat1)}"


def write_scenario_weather(out_dir: str | Path, seed: int = 0, weather: ScenarioWeather | None = None) -> dict:
    """Generate (unless given) and write the demo weather under ``out_dir/weather``.

    Returns
    -------
    dict
        ``files`` (paths written) plus :meth:`ScenarioWeather.describe` (storms, grids), for
        ``scenario.json``.
    """
    sw = weather if weather is not None else generate_weather(seed)
    folder = Path(out_dir) / "weather"
    folder.mkdir(parents=True, exist_ok=True)
    for old in list(folder.glob(f"{GLOBAL_WAVE_DATASET}_*.nc")) + list(folder.glob("era5_reanalysis-era5-single-levels_*.nc")):
        old.unlink()  # files of an earlier run with another window would be merged in otherwise
    t0 = pd.Timestamp(sw.waves.time_utc.values[0])
    t1 = pd.Timestamp(sw.waves.time_utc.values[-1])
    wave_name = f"{GLOBAL_WAVE_DATASET}_VHM0-VMDR-VTM10-VTPK_{_bbox_tag()}_{t0:%Y-%m-%d}-{t1:%Y-%m-%d}.nc"
    files = [str(write_cmems_wave(sw.waves, folder / wave_name, comment=f"stormlane scenario seed {sw.seed}"))]
    months = pd.DatetimeIndex(sw.wind.time_utc.values).to_period("M")
    for month in months.unique():
        part = sw.wind.isel(time_utc=(months == month).nonzero()[0])
        files.append(str(write_era5(part, folder / f"era5_reanalysis-era5-single-levels_10m_wind_{month}.nc", layout="time")))
    return {"files": files, **sw.describe()}
