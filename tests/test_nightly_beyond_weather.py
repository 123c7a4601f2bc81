"""A lane-departure that sails on after the weather's last time: the screen could not check those
centroids (no rule fires without weather), so the night says so instead of showing it as safe.

Found by the acceptance sweep: the demo night (weather to 2025-02-02T06:00Z, departures to
2025-02-02T00:00Z, voyages up to 41 h) showed 66 of its 233 'no rule fired' lane-departures
without a word, some with 80 of their 108 centroids after the weather's end.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import xarray as xr

T0 = pd.Timestamp("2025-01-10T00:00Z")


def _calm_weather(hours: int) -> xr.Dataset:
    """Hs 1 m, 8 s, waves from the north, no wind, hourly from T0 for ``hours`` hours."""
    t = pd.date_range(T0, periods=hours + 1, freq="h").tz_localize(None).values.astype("datetime64[ns]")
    lat, lon = np.arange(39.0, 41.01, 0.25), np.arange(2.0, 6.01, 0.25)
    shape = (len(t), len(lat), len(lon))
    full = lambda v: (("time_utc", "lat", "lon"), np.full(shape, v, dtype=np.float32))  # noqa: E731
    return xr.Dataset({"hs_m": full(1.0), "tp_s": full(8.0), "tm_s": full(7.0), "wave_from_deg": full(0.0),
                       "wind_u_ms": full(0.0), "wind_v_ms": full(0.0)},
                      coords={"time_utc": t, "lat": lat, "lon": lon}, attrs={"product": "calm test"})


def _night():
    from pipelines.config import load_operator_profile, load_vessel
    from pipelines.nightly import Night, NightlyParams, NightPath

    # 5 centroids along 40N, 1 deg of longitude apart (46 nmi) at 10 kn: ETAs 0, 4.6, 9.2, 13.8, 18.4 h
    c = pd.DataFrame({"seq": range(5), "lat_deg": 40.0, "lon_deg": [2.5, 3.5, 4.5, 5.5, 5.9], "speed_kn": 10.0})
    path = NightPath("L", "L", "A", "B", c, "ro-pax")
    return Night(run_id="x", now_utc=T0, departures=pd.DatetimeIndex([T0]), params=NightlyParams(), paths=[path],
                 weather_ds=_calm_weather(6), weather_meta={}, weather_source="files", weather_digest="", lanes_digest="",
                 vessels={"ro-pax": load_vessel("ro-pax")}, limits=load_operator_profile(), out=None)


def test_a_departure_past_the_weathers_end_is_said_not_shown_as_checked():
    from dashboards.model import NightlyReport, Provenance
    from dashboards.nightly_page import nightly_html
    from pipelines.nightly import assemble
    from pipelines.nightly.rank import overview_of
    from pipelines.nightly.report import _grid
    from pipelines.nightly.screen import screen_departures

    night = _night()
    screen = screen_departures(night)
    row = screen.iloc[0]
    # weather to T0 + 6 h (hourly: half a step of grace): the centroids at 9.2, 13.8 and 18.4 h have none
    assert not row["adverse"] and row["n_points"] == 5 and row["n_points_beyond_weather"] == 3
    result = assemble(night, screen, [])
    assert result.departures["status"].tolist() == ["ok"]
    summary = overview_of(result)
    assert summary["beyond_weather"] == 1 and summary["beyond_weather_ok"] == 1

    grid = _grid(result)
    assert grid["beyond"].tolist() == [3]
    model = NightlyReport(run_id="x", started_utc=T0, finished_utc=T0, now_utc=T0, window_start_utc=T0, window_end_utc=T0,
                          departure_step_h=3.0, lanes_checked=1, departures_checked=1, grid=grid, summary=summary,
                          provenance=Provenance(weather_end_utc=T0 + pd.Timedelta(hours=6)))
    html = nightly_html(model)
    assert "1 lane-departure(s) sail on after the weather&#x27;s last time (2025-01-10 06:00 UTC)" in html
    assert 'class="m-part"' in html and "3 centroid(s) after the weather" in html


def test_the_terminal_says_it_in_one_warning_line_on_stderr(capsys):
    from pipelines.commands.nightly import warn_beyond_weather

    warn_beyond_weather({"beyond_weather": 0, "beyond_weather_ok": 0, "weather": {"end_utc": None}})
    assert capsys.readouterr().err == ""
    warn_beyond_weather({"beyond_weather": 16, "beyond_weather_ok": 14, "weather": {"end_utc": "2025-02-02T06:00:00+00:00"}})
    out = capsys.readouterr()
    assert out.out == "" and out.err.count("\n") == 1
    assert out.err.startswith("warning: 16 lane-departure(s) sail on after the weather's last time (2025-02-02T06:00Z)")
    assert "14 of them shown as 'no rule fired' were screened on their part with weather only" in out.err
