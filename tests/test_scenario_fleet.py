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


def _reference_densify(wp, step_nmi):
    """The one-call-per-leg densify the sailing used before (thresholds.geodesy on scalar ends)."""
    import math

    import numpy as np

    from thresholds.geodesy import haversine_nmi, intermediate_point

    lats, lons = [np.array([wp[0, 0]])], [np.array([wp[0, 1]])]
    for (la1, lo1), (la2, lo2) in zip(wp[:-1], wp[1:]):
        n = max(1, int(math.ceil(haversine_nmi(la1, lo1, la2, lo2) / step_nmi)))
        la, lo = intermediate_point(la1, lo1, la2, lo2, np.arange(1, n + 1) / n)
        lats.append(np.atleast_1d(la))
        lons.append(np.atleast_1d(lo))
    return np.concatenate(lats), np.concatenate(lons)


def test_sailing_geometry_gives_the_reference_numbers_to_the_last_bit():
    """densify, _offset_route and _Path.at compute each leg's terms once (scenario.sailing._Legs);
    the points must equal thresholds.geodesy's functions called as before to the last bit (the
    generator's files are byte-identical to before). Random polylines, among them the three of
    the first 3,400 that came out 1-2 ulp off before the scalar squares (_squares: numpy squares
    an array by multiplication, a float64 scalar by pow)."""
    import math

    import numpy as np

    from scenario.sailing import _offset_route, _Path, densify
    from thresholds.geodesy import destination_point, initial_bearing_deg, intermediate_point
    from thresholds.units import wrap_deg

    rng, other = np.random.default_rng(1), np.random.default_rng(2)
    for k in range(3400):
        m = rng.integers(2, 9)
        wp = np.c_[rng.uniform(35, 45, m), rng.uniform(-2, 12, m)]
        if k % 3 == 0:
            wp = wp[0] + np.cumsum(rng.normal(0, 0.3, (m, 2)), axis=0)
        if k % 7 == 0:
            wp[1] = wp[0]  # a leg of zero length
        step = [0.5, 0.05, 2.0][k % 3]
        if k % 50 and k not in (196, 715, 3356):
            continue
        for got, want in zip(densify(wp, step), _reference_densify(wp, step)):
            assert np.array_equal(got, want), k
        offsets = other.normal(0.5, 1.5, m)
        want = wp.copy()
        for i in range(1, m - 1):
            b_in = initial_bearing_deg(wp[i - 1, 0], wp[i - 1, 1], wp[i, 0], wp[i, 1])
            b_out = initial_bearing_deg(wp[i, 0], wp[i, 1], wp[i + 1, 0], wp[i + 1, 1])
            mean = math.degrees(math.atan2(math.sin(math.radians(b_in)) + math.sin(math.radians(b_out)),
                                           math.cos(math.radians(b_in)) + math.cos(math.radians(b_out))))
            want[i] = destination_point(wp[i, 0], wp[i, 1], wrap_deg(mean + 90.0), offsets[i])
        assert np.array_equal(_offset_route(wp, offsets), want), k
        path = _Path(wp[:, 0], wp[:, 1])
        if len(path.seg) == 0:  # one point: no path to sail (nor did the code before sail one)
            continue
        s = np.sort(other.uniform(-1.0, path.length + 1.0, 50))
        la, lo, course = path.at(s)
        sc = np.clip(s, 0.0, path.length)
        i = np.clip(np.searchsorted(path.cum, sc, side="right") - 1, 0, len(path.seg) - 1)
        frac = np.where(path.seg[i] > 0, (sc - path.cum[i]) / path.seg[i], 0.0)
        la_w, lo_w = intermediate_point(path.lat[i], path.lon[i], path.lat[i + 1], path.lon[i + 1], frac)
        to_end = initial_bearing_deg(la_w, lo_w, path.lat[i + 1], path.lon[i + 1])
        leg = initial_bearing_deg(path.lat[i], path.lon[i], path.lat[i + 1], path.lon[i + 1])
        assert np.array_equal(la, la_w) and np.array_equal(lo, lo_w), k
        assert np.array_equal(course, np.where(path.cum[i + 1] - sc > 0.01, to_end, leg)), k


def test_spill_is_compressed_and_reads_back_the_records(tmp_path, spec):
    """A ship's spill (LZ4-compressed Arrow IPC, one batch per day) holds its records exactly, in
    under 60 bytes per row (143 uncompressed)."""
    import numpy as np
    import pyarrow as pa

    from pipelines.scenario_fleet import SPILL_COLUMNS, FleetJob, spill_ship
    from scenario.fleet import fleet_spec, sail_ship
    from scenario.spec import ScenarioSettings

    st = ScenarioSettings(seed=2, start_utc=pd.Timestamp("2025-03-01T00:00Z"), days=3)
    job = FleetJob(None, None, 3, st, str(tmp_path), str(tmp_path))
    spill_ship(job, 1)
    path = tmp_path / "ship-000001.arrow"
    with pa.memory_map(str(path)) as src:
        reader = pa.ipc.open_file(src)
        assert reader.num_record_batches == 3
        back = pa.Table.from_batches([reader.get_batch(d) for d in range(3)]).to_pandas()
    recs = sail_ship(fleet_spec(spec, 3), st, 1)["records"][list(SPILL_COLUMNS)]
    pd.testing.assert_frame_equal(back, recs, check_exact=True)
    assert path.stat().st_size / len(recs) < 60
    day = (recs["sort_s"].to_numpy() - st.start_s) // 86400
    assert np.all(np.diff(day) >= 0)


@pytest.mark.parametrize("args, said", [
    (["--vessels", "2", "--gzip"], "note: --gzip changes nothing with --vessels"),
    (["--workers", "2"], "note: --workers applies to --vessels only"),
])
def test_an_option_that_changes_nothing_is_said(tmp_path, args, said):
    """``--gzip`` with ``--vessels`` (the fleet is always gzip) and ``--workers`` without it (the
    demo scenario is one process) change nothing: one note line, the files written all the same."""
    from typer.testing import CliRunner

    from pipelines.cli import app

    res = CliRunner().invoke(app, ["scenario", "--out", str(tmp_path / "s"), "--days", "0.05", *args])
    assert res.exit_code == 0, res.output
    notes = [ln for ln in res.stderr.splitlines() if ln.startswith("note:")]
    assert len(notes) == 1 and notes[0].startswith(said), res.stderr
    assert list((tmp_path / "s" / "ais").iterdir())
