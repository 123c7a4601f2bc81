"""`stormlane learn performance` recovers the scenario's hidden performance law (issue 21).

One world for the module: twelve days of the demo scenario (2025-01-05 -> 2025-01-17: storm C
across the container and tanker routes, storm A across the ro-pax routes) through the real file
ingest, lanes and weather load; then the command itself, whose JSON the tests read. The law
(:mod:`scenario.performance_law`) is read only here, to say what the model had to find.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest


def run_cli(args: list[str]) -> tuple[int, str, str]:
    """``stormlane ARGS`` in this process (usable from a module fixture, unlike capsys)."""
    import contextlib
    import io

    from pipelines.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main(list(args))
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, out.getvalue(), err.getvalue()

START, DAYS = "2025-01-05T00:00Z", 12.0


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    from pipelines.ingest import ingest_paths
    from pipelines.lanes import run_lanes
    from pipelines.scenario import build_scenario
    from pipelines.weather import load_weather_paths

    out = tmp_path_factory.mktemp("learn_world")
    truth = build_scenario(out, seed=0, start=START, days=DAYS)
    db = out / "ws.duckdb"
    ingest_paths([out / "ais"], db)
    run_lanes(db)
    load_weather_paths(out / "weather", db)
    code, stdout, stderr = run_cli(["learn", "performance", "--db", str(db), "--name", "fleet", "--json"])
    assert code == 0, stderr
    return {"db": db, "truth": truth, "summary": json.loads(stdout), "out": out}


def _overall(block: dict) -> dict:
    return {r["model"]: r for r in block["scores"] if r["scope"] == "all"}


def test_on_held_out_vessels_the_model_beats_every_formula_as_the_issue_asks(world):
    s = world["summary"]
    cv = s["grouped_cv"]
    assert cv["k"] == 5 and s["vessels"] >= 15
    # every held-out vessel is in exactly one fold, and no fold trains on its own vessels
    held = [m for f in cv["folds"] for m in f["test_vessels"]]
    assert len(held) == len(set(held)) == s["vessels"]
    rows = _overall(cv)
    learned = rows[f"learned_{s['kind']}"]
    formulas = {f: rows[f] for f in ("bowditch", "aertssen", "khokhlov")}
    # the same held-out segments for every model (Khokhlov refuses ships beyond its published D x v0:
    # scored on the segments it accepts)
    assert {rows[m]["n"] for m in ("learned_direct", "learned_residual", "bowditch", "aertssen")} == {s["segments"]}
    assert 0 < rows["khokhlov"]["n"] <= s["segments"]
    assert learned["r2_loss"] >= 0.8
    best = min(f["mae_kn"] for f in formulas.values())
    assert learned["mae_kn"] <= 0.7 * best, (learned["mae_kn"], best)
    assert s["beats_formulas"] is True
    assert abs(learned["bias_kn"]) < 0.05


def test_the_p10_p90_band_covers_80_to_90_percent_of_held_out_speeds(world):
    rows = world["summary"]["grouped_cv"]["coverage"]
    cov = {c["group"]: c["coverage"] for c in rows}
    assert 0.8 <= cov["all"] <= 0.9, cov
    # calibrated per sea-state band: heavy seas too (one margin for all left them at 48-77 % on the demo)
    bands = [c for c in rows if c["scope"] == "band" and c["n"] >= 500]
    assert any(c["group"] in ("Hs 3-4 m", "Hs >= 4 m") for c in bands), rows
    assert all(0.75 <= c["coverage"] <= 0.95 for c in bands), rows


def test_learned_voluntary_slow_down_within_half_a_metre_of_the_generators(world):
    from scenario.performance_law import CLASS_LAW
    from performance.features import ship_class

    truth = world["truth"]
    ais_type = {v["vessel_class"]: v["ship_type"] for v in truth["vessels"]}
    learned = {r["ship_class"]: r for r in world["summary"]["voluntary"] if r["sector"] == "head-bow"}
    for name, law in CLASS_LAW.items():
        row = learned[str(ship_class([ais_type[name]])[0])]
        assert row["threshold_hs_m"] is not None, (name, row)
        assert abs(row["threshold_hs_m"] - law.voluntary_hs_m) <= 0.5, (name, row["threshold_hs_m"], law.voluntary_hs_m)


def test_the_model_is_stored_with_its_span_versions_and_a_trusted_file(world):
    from pipelines.learn import load_performance_model

    s = world["summary"]
    model, row = load_performance_model(world["db"], "fleet")
    assert row["rows"] == s["segments"] and row["kind"] == s["kind"]
    assert row["span_start"].isoformat().startswith("2025-01-0")
    assert set(row["versions"]) >= {"scikit-learn", "numpy", "skops"}
    assert Path(row["file"]).name == "fleet.skops" and Path(row["file"]).parent.name == "ws.duckdb.models"
    assert row["params"]["rules"]["sog_floor_kn"] == 5.0
    # list and show read the same row
    code, out, _ = run_cli(["learn", "list", "--db", str(world["db"]), "--json"])
    assert code == 0 and [m["name"] for m in json.loads(out)["models"]] == ["fleet"]
    code, out, _ = run_cli(["learn", "show", "fleet", "--db", str(world["db"])])
    assert code == 0 and "held-out vessels" in out and "voluntary" in out


def test_a_tampered_model_file_is_refused(world, tmp_path):
    import shutil

    from pipelines.learn import load_performance_model
    from pipelines.storage.performance import ModelError

    _, row = load_performance_model(world["db"], "fleet")
    backup = tmp_path / "fleet.skops"
    shutil.copy(row["file"], backup)
    try:
        with open(row["file"], "ab") as fh:
            fh.write(b"x")
        with pytest.raises(ModelError, match="SHA-256 differs"):
            load_performance_model(world["db"], "fleet")
    finally:
        shutil.copy(backup, row["file"])


@pytest.mark.parametrize("args, message", [
    (["--name", "bad/name"], "--name 'bad/name'"),
    (["--name", "x", "--class", "yacht"], "--class 'yacht'"),
    (["--name", "x", "--since", "yesterday"], "--since 'yesterday'"),
    (["--name", "x", "--since", "2025-01-10", "--until", "2025-01-09"], "is not before --until"),
    (["--name", "x", "--since", "2026-01-01"], "too little to learn from"),
])
def test_bad_input_gets_one_error_line(world, args, message):
    code, out, err = run_cli(["learn", "performance", "--db", str(world["db"]), *args])
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], err


def test_show_of_an_unknown_model_names_the_models_there(world):
    code, _, err = run_cli(["learn", "show", "nope", "--db", str(world["db"])])
    assert code == 2 and err.startswith("error: no learned model 'nope'") and "fleet" in err


def test_learned_limits_are_reported_beside_the_operator_limits(world):
    s = world["summary"]
    head = {r["ship_class"]: r["threshold_hs_m"] for r in s["voluntary"] if r["sector"] == "head-bow"}
    rows = {r["ship_class"]: r for r in s["limits"]}
    assert set(rows) == set(head)
    for cls, r in rows.items():
        assert r["learned_hs_m"] == head[cls]
        assert r["operator_profile"] and r["limits"]


ROUTE = ["--from", "41.30,2.25", "--to", "39.50,2.70", "--depart", "2025-01-15T00:00Z", "--mesh-nmi", "6", "--edges", "16"]


def test_route_with_the_learned_model_states_it_and_sails_slower_than_calm(world):
    weather = [str(p) for p in sorted((world["out"] / "weather").glob("*.nc"))]
    code, out, err = run_cli(["route", *ROUTE, "--weather", *weather, "--vessel", "ro-pax", "--speed-loss", "learned:fleet",
                              "--db", str(world["db"]), "--json"])
    assert code == 0, err
    data = json.loads(out)
    assert data["notes"][0].startswith("speed loss: learned:fleet (")
    calm = data["min_distance_calm"]["time_h"]
    assert data["optimal"]["time_h"] >= calm * 0.98  # the table's ratios stay near or below 1
    assert data["min_distance"]["time_h"] > calm  # storm A on the way: the learned loss slows the ship
    band = data["eta_band"]
    assert band["time_h_p10"] < band["time_h_p50"] < band["time_h_p90"]
    assert band["time_h_p50"] == pytest.approx(data["optimal_smoothed"]["time_h"], rel=0.02)


@pytest.mark.parametrize("extra, message", [
    (["--speed-loss", "learned:nope"], "no learned model 'nope'"),
    (["--speed-loss", "learned:fleet", "--speed-kn", "40"], "kn calm-water speed; this vessel's 40.0 lies outside"),
    (["--speed-loss", "learned:fleet", "--vessel", "container-large", "--speed-kn", "15"],
     "m length; this vessel's 320.0 lies outside"),
    # least fuel sailed its default settings from 12.6 kn (60 % of 21) with the table, below every speed the model saw
    (["--speed-loss", "learned:fleet", "--objective", "fuel"], "(the least-fuel speed setting 12.6 kn: give --speeds or --speed-range"),
])
def test_route_refuses_a_learned_model_it_cannot_use(world, extra, message):
    vessel = [] if "--vessel" in extra else ["--vessel", "ro-pax"]
    code, _, err = run_cli(["route", *ROUTE, *vessel, "--db", str(world["db"]), *extra])
    assert code == 2 and err.startswith("error: ") and message in err and len(err.strip().splitlines()) == 1, err


STORM_A_SHIP = ["--mmsi", "224087350", "--start", "2025-01-14T21:30Z", "--end", "2025-01-15T10:30Z"]


def _lane_of(db, mmsi: int) -> str:
    """The lane of the ship's voyages (the ro-pax through storm A)."""
    import duckdb

    with duckdb.connect(str(db), read_only=True) as con:
        return con.execute("SELECT lv.lane_id FROM lane_voyages lv JOIN voyages v USING (voyage_id) WHERE v.mmsi = ? "
                           "GROUP BY 1 ORDER BY count(*) DESC LIMIT 1", [mmsi]).fetchone()[0]


def test_audit_with_the_learned_model_sails_every_route_by_it_and_reads_its_bands(world):
    code, out, err = run_cli(["audit", *STORM_A_SHIP, "--db", str(world["db"]), "--speed-loss", "learned:fleet", "--json"])
    assert code == 0, err
    a = json.loads(out)
    assert a["speed_loss_model"] == "learned:fleet"
    roles = [r for r in ("as_sailed", "as_sailed_modelled", "optimal", "min_distance", "deviation") if r in a]
    assert len(roles) == 5 and all(a[r]["speed_loss_model"] == "learned:fleet" for r in roles)
    # how every model did on this very voyage: the learned row is the modelled track's own time
    check = {r["model"]: r for r in a["model_check"]}
    assert set(check) == {"bowditch", "aertssen", "khokhlov", "learned:fleet"}
    ais_h, mod_h = a["as_sailed"]["time_h"], a["as_sailed_modelled"]["time_h"]
    lr = check["learned:fleet"]
    assert lr["ais_time_h"] == pytest.approx(ais_h) and lr["time_h"] == pytest.approx(mod_h, rel=1e-6)
    assert lr["bias_h"] == pytest.approx(a["bias"]["time_h"], abs=1e-4)  # the bias is rounded to 4 decimals
    assert lr["time_h_p10"] < lr["time_h"] < lr["time_h_p90"]
    assert lr["inside_band"] == (lr["time_h_p10"] <= ais_h <= lr["time_h_p90"])
    for name in ("bowditch", "aertssen"):
        assert check[name]["bias_h"] == pytest.approx(check[name]["time_h"] - ais_h)
    # the bands: P50 is the route as sailed by the model (time and fuel), P10 < P50 < P90
    band = a["bands"]["as_sailed_modelled"]
    assert band["time_h_p50"] == pytest.approx(mod_h, rel=1e-6)
    assert band["fuel_t_p50"] == pytest.approx(a["as_sailed_modelled"]["fuel_t"], rel=1e-6)
    assert band["time_h_p10"] < band["time_h_p50"] < band["time_h_p90"]
    if a["proposed"]:
        b = a["bands"][a["proposed"]]
        assert b["time_h_p50"] == pytest.approx(a[a["proposed"]]["time_h"], rel=1e-6)
    assert any("by learned:fleet's quantiles" in f for f in a["findings"])
    assert any(f.startswith("Speed models on this very voyage") for f in a["findings"])


@pytest.mark.parametrize("command", ["audit", "deviate", "nightly"])
def test_an_unknown_learned_model_is_one_line_listing_the_stored_ones(world, command):
    extra = {"audit": STORM_A_SHIP, "deviate": ["--lane", "x", "--depart", "2025-01-15T00:00Z"], "nightly": []}[command]
    code, out, err = run_cli([command, *extra, "--db", str(world["db"]), "--speed-loss", "learned:nope"])
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and lines[-1].startswith("error: no learned model 'nope'") and "models: fleet" in lines[-1], err


def test_deviate_and_nightly_sail_by_the_learned_model_and_say_so(world, tmp_path):
    from pipelines.nightly.flow import run_night

    lane = _lane_of(world["db"], 224087350)
    code, out, err = run_cli(["deviate", "--lane", lane, "--depart", "2025-01-14T22:00Z", "--db", str(world["db"]),
                              "--speed-loss", "learned:fleet", "--json"])
    assert code == 0, err
    d = json.loads(out)
    assert d["speed_loss_model"] == "learned:fleet"
    assert d["lane"]["speed_loss_model"] == d["deviation"]["speed_loss_model"] == "learned:fleet"
    night = run_night(db=str(world["db"]), out=str(tmp_path / "night"), weather_source="workspace", now="2025-01-14T22:00Z",
                      window_h=1.0, step_h=1.0, lanes=[lane], speed_loss="learned:fleet", exports="none")
    assert night["speed_loss_model"] == "learned:fleet" and night["failed"] == 0
    assert night["adverse"] >= 1  # storm A on the lane: a case to carry the band
    report = Path(night["model"]).read_text(encoding="utf-8")
    assert "sailing time P10-P50-P90 by learned:fleet's quantiles" in report
    # the learned voluntary slow-down beside the operator limits, for the night's vessel
    head = {r["ship_class"]: r["threshold_hs_m"] for r in world["summary"]["voluntary"] if r["sector"] == "head-bow"}
    rows = night["learned_limits"]["rows"]
    assert night["learned_limits"]["model"] == "learned:fleet" and rows
    assert all(r["learned_hs_m"] == head[r["ship_class"]] and r["operator_hs_max_m"] for r in rows)
    assert "AIS voluntary slow-down (learned:fleet" in report


def test_the_thresholds_output_shows_the_learned_slow_down_beside_the_operator_limit(world):
    weather = [str(p) for p in sorted((world["out"] / "weather").glob("*.nc"))]
    code, out, err = run_cli(["weather", "exceedance", *weather, "--vessel", "tanker-aframax", "--learned", "fleet",
                              "--db", str(world["db"]), "--json"])
    assert code == 0, err
    data = json.loads(out)
    (row,) = data["learned_limits"]["rows"]
    head = {r["ship_class"]: r for r in world["summary"]["voluntary"] if r["sector"] == "head-bow"}
    assert row["ship_class"] == "tanker" and row["learned_hs_m"] == head["tanker"]["threshold_hs_m"] is not None
    assert row["operator_hs_max_m"] is not None and row["limits"] == data["limits"]
    code, out, err = run_cli(["weather", "exceedance", *weather, "--vessel", "tanker-aframax", "--learned", "fleet",
                              "--db", str(world["db"])])
    assert code == 0 and f"masters slow down above Hs {row['learned_hs_m']:.2f} m in head-to-bow seas" in out, err


def test_a_formula_audit_also_compares_the_stored_model_with_the_ais_time(world):
    code, out, err = run_cli(["audit", *STORM_A_SHIP, "--db", str(world["db"]), "--json"])
    assert code == 0, err
    a = json.loads(out)
    assert a["speed_loss_model"] == "bowditch" and a["bands"] == {}
    check = {r["model"]: r for r in a["model_check"]}
    # the audit's own model re-times the track exactly as its modelled row; the stored model is beside it
    assert check["bowditch"]["time_h"] == pytest.approx(a["as_sailed_modelled"]["time_h"], rel=1e-6)
    lr = check["learned:fleet"]
    assert lr["time_h_p10"] < lr["time_h"] < lr["time_h_p90"] and lr["ais_time_h"] == pytest.approx(a["as_sailed"]["time_h"])
