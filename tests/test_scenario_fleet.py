"""The year-scale fleet scenario (issue 23): identities, determinism whatever the processes, truth."""

from __future__ import annotations

import gzip
import json

import pandas as pd
import pytest



@pytest.fixture(scope="module")
def spec():
    from pipelines.scenario import load_scenario_spec

    return load_scenario_spec()


def test_fleet_spec_gives_every_copy_a_valid_identity_of_its_flag(spec):
    from scenario.fleet import fleet_spec, imo_with_check_digit
    from scenario.spec import MED_MIDS, imo_check_digit_ok, mmsi_problem

    assert imo_with_check_digit(937316) == 9373163  # IMO 9373163: a published number (check digit 3)
    fleet = fleet_spec(spec, 250)
    assert len(fleet.vessels) == 250
    assert [v.mmsi for v in fleet.vessels[:20]] == [v.mmsi for v in spec.vessels]
    assert len({v.mmsi for v in fleet.vessels}) == 250 and len({v.imo for v in fleet.vessels}) == 250
    for k, v in enumerate(fleet.vessels):
        model = spec.vessels[k % 20]
        assert mmsi_problem(v.mmsi) is None and v.mmsi // 1_000_000 in MED_MIDS[v.flag]
        assert imo_check_digit_ok(v.imo)
        assert len(v.name) <= 20 and len(v.callsign) <= 7 and v.ais_format == "dma_csv"
        assert (v.service, v.flag, v.length_m, v.service_speed_kn) == (model.service, model.flag, model.length_m,
                                                                       model.service_speed_kn)
    assert fleet_spec(spec, 5).vessels[4].mmsi == spec.vessels[4].mmsi


def test_fleet_files_are_the_same_whatever_the_workers_and_match_the_truth(tmp_path, spec):
    """Two runs (the CLI with 1 worker process, the function with 2) write byte-identical files;
    each file's rows are the ships' records of that day; the counts in scenario.json are the
    files'; the ingest loads exactly the clean rows and rejects the dirty ones."""
    from pipelines.cli import main
    from pipelines.ingest import ingest_paths
    from pipelines.scenario_fleet import build_fleet_scenario
    from scenario.fleet import fleet_spec, sail_ship
    from scenario.spec import ScenarioSettings

    assert main(["scenario", "--out", str(tmp_path / "a"), "--vessels", "21", "--days", "1.5", "--seed", "4",
                 "--start", "2025-03-01T00:00Z", "--workers", "1", "--json"]) is None
    a = json.loads((tmp_path / "a" / "scenario.json").read_text())
    b = build_fleet_scenario(tmp_path / "b", vessels=21, seed=4, start="2025-03-01T00:00Z", days=1.5, workers=2)
    names = sorted(p.name for p in (tmp_path / "a" / "ais").iterdir())
    assert names == ["aisdk-2025-03-01.csv.gz", "aisdk-2025-03-02.csv.gz"]
    for name in names:
        assert (tmp_path / "a" / "ais" / name).read_bytes() == (tmp_path / "b" / "ais" / name).read_bytes()
    assert a["expected_ingest"] == b["expected_ingest"] and a["ais"]["files"] == b["ais"]["files"]
    assert not (tmp_path / "a" / ".fleet-spill").exists()

    # the rows of the files are the records of the ships sailed one by one
    st = ScenarioSettings(seed=4, start_utc=pd.Timestamp("2025-03-01T00:00Z"), days=1.5)
    fleet = fleet_spec(spec, 21)
    ships = [sail_ship(fleet, st, i) for i in range(21)]
    recs = pd.concat([s["records"] for s in ships], ignore_index=True)
    lines = [ln for name in names for ln in gzip.open(tmp_path / "a" / "ais" / name, "rt").read().splitlines()[1:]]
    assert len(lines) == len(recs) == a["expected_ingest"]["position_records"]
    mmsi_in_file = sorted(int(ln.split(",")[2]) for ln in lines)
    assert mmsi_in_file == sorted(recs["mmsi"].astype(int).tolist())
    dirty = recs["dirty_kind"]
    assert a["expected_ingest"]["loaded"] == int(((dirty == "") | (dirty == "sentinel_fields")).sum())
    assert a["dirty_rows"]["counts"]["speed_jump"] == int((dirty == "speed_jump").sum()) > 0
    voyages = pd.read_parquet(tmp_path / "a" / "truth" / "voyages.parquet")
    assert len(voyages) == sum(len(s["voyages"]) for s in ships) == a["truth"]["voyages"]["rows"]
    assert a["scenario"]["fleet"]["vessels"] == 21

    s = ingest_paths([tmp_path / "a" / "ais"], tmp_path / "w.duckdb")
    assert s["read"] == a["expected_ingest"]["position_records"]
    assert s["loaded"] == a["expected_ingest"]["loaded"]
    assert s["quarantined"] + s["duplicates"] == a["expected_ingest"]["rejected"]
    assert s["reasons"]["speed_jump"] == a["dirty_rows"]["counts"]["speed_jump"]


_PEAK = """
import json, resource, sys
from pipelines.scenario_fleet import build_fleet_scenario
s = build_fleet_scenario(sys.argv[1], vessels=int(sys.argv[2]), seed=1, start="2025-03-01T00:00Z",
                         days=float(sys.argv[3]), workers=1)
ru = resource.getrusage
print(json.dumps({"rows": s["expected_ingest"]["position_records"], "parent_kb": ru(resource.RUSAGE_SELF).ru_maxrss,
                  "worker_kb": ru(resource.RUSAGE_CHILDREN).ru_maxrss}))
"""


def test_fleet_memory_does_not_hold_the_fleet_period(tmp_path, spec):
    """Peak RSS (getrusage) of a 2-ship x 2-day and a 10-ship x 10-day fleet (32 times the rows),
    each in a fresh process: the parent holds no records (its peak stays within 15 MB), and the
    worker's peak grows by well under what holding the extra records would take (their pandas
    size, measured here): it holds one ship's period or one day of the fleet at a time."""
    import subprocess
    import sys

    from scenario.fleet import fleet_spec, sail_ship
    from scenario.spec import ScenarioSettings

    def peak(vessels, days):
        out = subprocess.run([sys.executable, "-c", _PEAK, str(tmp_path / f"{vessels}x{days}"), str(vessels), str(days)],
                             capture_output=True, text=True, check=True)
        return json.loads(out.stdout.strip().splitlines()[-1])

    small, big = peak(2, 2), peak(10, 10)
    assert big["rows"] > 30 * small["rows"]
    recs = sail_ship(fleet_spec(spec, 2), ScenarioSettings(seed=1, start_utc=pd.Timestamp("2025-03-01T00:00Z"), days=2),
                     0)["records"]
    held_mb = (big["rows"] - small["rows"]) * recs.memory_usage(deep=True).sum() / len(recs) / 1e6
    parent_mb = (big["parent_kb"] - small["parent_kb"]) / 1e3
    worker_mb = (big["worker_kb"] - small["worker_kb"]) / 1e3
    assert held_mb > 40 and parent_mb < 15, (held_mb, parent_mb)
    assert worker_mb < 0.6 * held_mb, (worker_mb, held_mb)
