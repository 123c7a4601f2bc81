"""End to end: AIS-supplied strings travel from an AIS file through ingest and the audit into
the HTML report, and arrive escaped (issue 8 acceptance)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ais_fixtures import DMA_HEADER, dma_row
from dashboards.model import VoyageAudit
from dashboards.report import render_audit_report
from pipelines.ingest import ingest_file
from pipelines.reporting import voyage_audit_model
from pipelines.storage import open_workspace
from pipelines.storage.ais import read_positions, read_vessels
from routing.audit import audit_routes, track_to_route
from thresholds.operator import OperatorLimits
from thresholds.vessel import Vessel

NAME = "<script>alert(1)</script>"
CALLSIGN = "<img src=x>"
DEST = "PALMA<svg onload=alert(2)>"


def test_ship_name_from_ais_file_is_escaped_in_the_audit_report(tmp_path):
    # A ship sailing Barcelona -> Palma at about 12 kn, one DMA row every 10 minutes.
    n = 56
    t = pd.date_range("2025-01-15T00:00", periods=n, freq="10min")
    lat = np.linspace(41.30, 39.52, n)
    lon = np.linspace(2.25, 2.62, n)
    rows = [dma_row(ts.strftime("%d/%m/%Y %H:%M:%S"), "224000001", f"{la:.6f}", f"{lo:.6f}", sog="12.0", cog="170.0", hdg="170",
                    name=NAME, callsign=CALLSIGN, dest=DEST) for ts, la, lo in zip(t, lat, lon)]
    csv = tmp_path / "ais.csv"
    csv.write_text("\n".join([DMA_HEADER, *rows]) + "\n", encoding="utf-8")

    with open_workspace(tmp_path / "ws.duckdb") as ws:
        counts = ingest_file(ws, csv)
        positions = read_positions(ws, mmsi=224000001)
        vessels = read_vessels(ws).set_index("mmsi")
    assert counts["loaded"] == n
    static = vessels.loc[224000001]
    assert static["name"] == NAME and static["callsign"] == CALLSIGN and static["destination"] == DEST  # stored as sent

    vessel = Vessel(name="t", vessel_class="container", speed_kn=12.0, lpp_m=150.0, beam_m=25.0, draught_m=8.0, dwt_t=12000.0,
                    installed_power_kw=10000.0, design_speed_kn=15.0, engine_rpm=500.0, sfoc_g_kwh=200.0)

    def weather(times, la, lo):
        la = np.asarray(la, dtype=float)
        return {"hs_m": np.where(la > 40.3, 5.0, 2.0), "wave_from_deg": np.full(la.size, 330.0), "tm_s": np.full(la.size, 6.0)}

    track = track_to_route(positions)
    out = audit_routes(track, weather, vessel, limits=OperatorLimits(name="t", hs_max_m=4.5))
    audit = voyage_audit_model(out, mmsi=224000001, static=static, vessel=vessel, voyage={"origin": "Barcelona", "destination": "Palma"})
    assert isinstance(audit, VoyageAudit) and audit.ship_name == NAME
    text = render_audit_report(audit, tmp_path / "audit.html").read_text(encoding="utf-8")
    assert NAME not in text and "&lt;script&gt;alert(1)&lt;/script&gt;" in text
    assert "<img src=x>" not in text and "&lt;img src=x&gt;" in text
    assert "<svg" not in text and "PALMA&lt;svg onload=alert(2)&gt;" in text
    assert "<script" not in text.lower()
