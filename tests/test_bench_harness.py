"""The benchmark harness (bench/_harness.py) on sides of known duration: interleaved rounds,
medians and ranges, like-with-like ratios per pair, throughput, the empty-cache detection and
targets evaluated against the measured medians."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import pytest  # noqa: E402

from bench import _harness  # noqa: E402


def test_harness_interleaves_and_compares_like_with_like(tmp_path):
    """Two sides of known duration (50 ms and 200 ms of sleep; a loaded machine only adds to
    them): medians, ratios per interleaved pair, throughput, the empty-cache run detected as
    compiling nothing, targets evaluated."""
    cfg = _harness.Config(runs=3, empty_runs=1, cache_dir=tmp_path, verbose=False)
    g = _harness.Group(
        "probe", "probe",
        sides=[_harness.Side("fast", "sleep 50 ms", setup="bench._probe:setup", kwargs={"seconds": 0.05, "work": 100},
                             run="bench._probe:run", work="items"),
               _harness.Side("slow", "sleep 200 ms", setup="bench._probe:setup", kwargs={"seconds": 0.2},
                             run="bench._probe:run", ours=False)],
        measures=[_harness.Measure("m", "probe", "fast", "slow", relation="same",
                                   targets=[_harness.Target("1.5x", "speedup.warm", ">=", 1.5, "x", "test"),
                                            _harness.Target("fast", "warm.wall_s", "<", 0.001, "s", "test")])])
    out = _harness.run_group(cfg, g)
    fast, slow = out["sides"]["fast"], out["sides"]["slow"]
    assert fast["cold"]["wall_s"]["n"] == 3 and fast["warm"]["wall_s"]["n"] == 3
    assert 0.05 <= fast["warm"]["wall_s"]["median"] < 1.0 and 0.2 <= slow["warm"]["wall_s"]["median"] < 1.2
    assert slow["warm"]["wall_s"]["min"] >= 0.2 and fast["warm"]["wall_s"]["min"] >= 0.05
    assert fast["warm"]["throughput"]["median"] == pytest.approx(100 / fast["warm"]["wall_s"]["median"], rel=0.01)
    assert fast["cold_empty_cache"]["na"].startswith("compiles no cached numba kernel")
    assert slow["cold_empty_cache"]["na"].startswith("not our code")
    assert fast["cold"]["peak_mb"]["median"] > 1 and fast["cold"]["cpu_s"]["median"] < 0.02
    m = out["measures"][0]
    pairs = [b / a for a, b in zip(fast["warm"]["wall_s"]["values"], slow["warm"]["wall_s"]["values"])]
    assert m["speedup"]["warm"]["values"] == pytest.approx(pairs, rel=1e-3) and m["speedup"]["warm"]["median"] > 1.5
    assert [t["met"] for t in m["targets"]] == [True, False]
    from bench import _report  # a wall target missed while the CPU seconds meet it (sleep uses no CPU): said so

    assert _report.cpu_check(m["targets"][0], out["sides"]) == ""
    assert _report.cpu_check(m["targets"][1], out["sides"]).endswith(": within it)")


def test_missing_input_skips_the_group_with_its_reason(tmp_path):
    cfg = _harness.Config(runs=1, empty_runs=0, cache_dir=tmp_path, verbose=False)
    g = _harness.Group("needs", "needs data", needs=[tmp_path / "absent.nc"],
                       sides=[_harness.Side("x", "x", setup="bench._probe:setup", kwargs={"seconds": 0.0}, run="bench._probe:run")],
                       measures=[])
    out = _harness.run_group(cfg, g)
    assert "absent.nc" in out["skipped"] and "not found" in out["skipped"] and "sides" not in out


def test_generated_table_shows_medians_ratios_and_targets(tmp_path):
    from bench import _report

    cfg = _harness.Config(runs=2, empty_runs=0, cache_dir=tmp_path, verbose=False)
    ext = {"label": "a peer", "date": "2026-01-01", "machine": "m", "method": "cold, median of 5", "cold_s": 10.0}
    g = _harness.Group(
        "probe", "probe",
        sides=[_harness.Side("a", "sleep 10 ms", setup="bench._probe:setup", kwargs={"seconds": 0.01}, run="bench._probe:run"),
               _harness.Side("b", "sleep 30 ms", setup="bench._probe:setup", kwargs={"seconds": 0.03}, run="bench._probe:run",
                             ours=False)],
        measures=[_harness.Measure("ab", "a against b", "a", "b", relation="same",
                                   targets=[_harness.Target("under 1 s", "cold.wall_s", "<", 1.0, "s", "test")]),
                  _harness.Measure("ext", "a against a peer", "a", external=ext)])
    results = _report.new_results("full")
    results["benchmarks"]["probe"] = {"script": "bench/probe.py", "groups": [_harness.run_group(cfg, g)], "notes": []}
    table = _report.render_table(results)
    rows = [line for line in table.splitlines() if line.startswith("| probe |")]
    assert len(rows) == 2
    assert "under 1 s: met" in rows[0] and rows[0].count("×") == 2 and "ms [" in rows[0]
    assert "external: a peer (2026-01-01)" in rows[1] and "never compared" in rows[1] and "vs external" in rows[1]
    page = _report.render_page(results)
    assert "### probe" in page and "baseline ÷ ours, cold" in page and "not measured in this run" in page


def test_a_script_run_alone_is_merged_and_scripts_without_figures_are_not_run_yet(tmp_path, monkeypatch):
    """``python -m bench --only NAME`` / ``python bench/NAME.py``: the script's new section replaces
    its old one (with its own time, commit and load), every other section stays, and the table and
    the page say what was re-run alone and which scripts have no figures yet."""
    from bench import _report

    for attr, name in (("RESULTS", "results.json"), ("PAGE", "benchmarks.md")):
        monkeypatch.setattr(_report, attr, tmp_path / name)
    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{_report.README_BEGIN}\nold\n{_report.README_END}\nrest\n", encoding="utf-8")
    monkeypatch.setattr(_report, "README", readme)
    cfg = _harness.Config(runs=1, empty_runs=0, cache_dir=tmp_path, verbose=False)
    g = _harness.Group("probe", "probe", sides=[_harness.Side("a", "sleep 1 ms", setup="bench._probe:setup",
                                                              kwargs={"seconds": 0.001}, run="bench._probe:run")],
                       measures=[_harness.Measure("m", "probe", "a", external={"label": "x", "date": "d", "machine": "m",
                                                                                  "method": "cold", "cold_s": 1.0})])
    old = _report.new_results("full")
    kept = {"script": "bench/ingest.py", "groups": [], "notes": ["kept"]}
    old["benchmarks"] = {"ingest": kept, "probe": {"script": "bench/probe.py", "groups": [], "notes": ["old"]}}
    _report.write_results(old, _report.RESULTS)
    section = _harness.run_groups(cfg, "bench/probe.py", [g])
    assert section["git"]["commit"] and section["load_note"].startswith("1-minute load average") and section["started_utc"]
    merged = _report.merge_section(section)
    on_disk = _report.load_results(_report.RESULTS)
    assert on_disk == merged and on_disk["benchmarks"]["ingest"] == kept and on_disk["sections_run_alone"] == ["probe"]
    assert on_disk["benchmarks"]["probe"]["groups"][0]["sides"]["a"]["cold"]["wall_s"]["n"] == 1
    assert on_disk["scripts"] == _report.scripts() and "routing" in _report.not_run_yet(on_disk)
    table = _report.readme_block(readme)
    assert readme.read_text().startswith("intro\n") and readme.read_text().endswith("\nrest\n")
    assert "Re-run alone after the full run: bench/probe.py, started " in table and "| probe | probe |" in table
    assert "Not run yet: bench/routing.py (" in table and "Not run yet: bench/ingest.py (" not in table
    assert "csv_dma" in on_disk["unmeasured"]["ingest"] and "Not run yet: bench/ingest.py csv_dma, geoparquet, nmea" in table
    page = (tmp_path / "benchmarks.md").read_text()
    assert "Measured (re-run alone after the full run): started" in page and "`bench/routing.py`: no figures" in page
