"""The committed benchmark results (``bench/results.json``) and what is generated from them.

Every benchmark script's section must hold, for every measure, our side's cold and warm medians
with their ranges (or, for warm, the stated reason there is none), peak memory from a fresh
process, and a baseline measured in the same run or a labelled external figure; the README's
table and ``docs/benchmarks.md`` must be exactly what the generator makes from the file. The
harness itself is checked on sides of known duration.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench import _harness, _report  # noqa: E402


@pytest.fixture(scope="module")
def results() -> dict:
    return _report.load_results()


def _has_stats(phase: dict | None, quantity: str = "wall_s") -> bool:
    st = (phase or {}).get(quantity)
    return bool(st) and st["n"] >= 1 and st["min"] <= st["median"] <= st["max"]


def test_results_come_from_one_full_run_of_every_script(results):
    assert results["mode"] == "full"
    assert not results.get("sections_run_alone"), "sections were re-run alone: regenerate with `make bench`"
    assert set(_report.SCRIPT_ORDER) <= set(results["benchmarks"])
    assert results["load_note"] and "load_1min" in results and results["git"]["commit"]
    scripts = {p.stem for p in (ROOT / "bench").glob("[!_]*.py")}
    assert scripts == set(_report.SCRIPT_ORDER), "every bench script runs in `make bench`"


@pytest.mark.parametrize("name", _report.SCRIPT_ORDER)
def test_every_measure_is_complete(results, name):
    section = results["benchmarks"][name]
    measured = [g for g in section["groups"] if not g.get("skipped")]
    for g in section["groups"]:
        if g.get("skipped"):
            assert "not found" in g["skipped"] or "failed" in g["skipped"]
            continue
        assert g["runs"] >= 5 and g["load_1min"]["before"] is not None and g["load_1min"]["after"] is not None
        for m in g["measures"]:
            ours = g["sides"][m["ours"]]
            assert _has_stats(ours["cold"]) and ours["cold"]["wall_s"]["n"] >= 5, (name, m["key"])
            assert _has_stats(ours["cold"], "cpu_s") and _has_stats(ours["cold"], "peak_mb"), (name, m["key"])
            assert _has_stats(ours["cold"], "load_1min_before") and _has_stats(ours["cold"], "load_1min_after")
            warm = ours["warm"]
            assert (_has_stats(warm) and warm["wall_s"]["n"] >= 5) or warm.get("na"), (name, m["key"])
            empty = ours["cold_empty_cache"]
            assert _has_stats(empty) or empty.get("na"), (name, m["key"])
            assert m.get("baseline") or (m.get("external") or {}).get("external"), (name, m["key"])
            if m.get("baseline"):
                base = g["sides"][m["baseline"]]
                assert _has_stats(base["cold"]) and base["cold"]["wall_s"]["n"] >= 5 and _has_stats(base["cold"], "peak_mb")
                assert m["speedup"]["cold"] is not None and m["relation"]
            if m.get("external"):
                e = m["external"]
                assert e["date"] and e["machine"] and e["method"] and e["cold_s"] > 0 and "speedup_warm" not in e
            for t in m["targets"]:
                assert t["met"] in (True, False, None) and t["source"]
                assert (t["met"] is None) == (t["measured"] is None)
    # every script has at least one measure with warm medians, and every headline row appears
    assert any(_has_stats(g["sides"][m["ours"]]["warm"]) for g in measured for m in g["measures"]) or not measured


def test_readme_table_and_page_are_generated(results):
    assert _report.readme_block() == _report.render_table(results)
    assert _report.PAGE.read_text(encoding="utf-8") == _report.render_page(results)


def test_external_figures_are_never_divided_into_warm_ones(results):
    for name, g, m in _report._rows(results):
        if m.get("external"):
            assert set(m["external"]) >= {"label", "date", "machine", "method"}
            assert not m.get("baseline") or m["baseline"] != m["ours"]
            assert "warm" not in "".join(k for k in m["external"] if k.startswith("speedup"))


def test_harness_interleaves_and_compares_like_with_like(tmp_path):
    """Two sides of known duration (20 ms and 60 ms): medians, ratios per interleaved pair,
    throughput, the empty-cache run detected as compiling nothing, a target evaluated."""
    cfg = _harness.Config(runs=3, empty_runs=1, cache_dir=tmp_path, verbose=False)
    g = _harness.Group(
        "probe", "probe",
        sides=[_harness.Side("fast", "sleep 20 ms", setup="bench._probe:setup", kwargs={"seconds": 0.02, "work": 100},
                             run="bench._probe:run", work="items"),
               _harness.Side("slow", "sleep 60 ms", setup="bench._probe:setup", kwargs={"seconds": 0.06},
                             run="bench._probe:run", ours=False)],
        measures=[_harness.Measure("m", "probe", "fast", "slow", relation="same",
                                   targets=[_harness.Target("3x", "speedup.warm", ">=", 2.0, "x", "test"),
                                            _harness.Target("fast", "warm.wall_s", "<", 0.001, "s", "test")])])
    out = _harness.run_group(cfg, g)
    fast, slow = out["sides"]["fast"], out["sides"]["slow"]
    assert fast["cold"]["wall_s"]["n"] == 3 and fast["warm"]["wall_s"]["n"] == 3
    assert 0.02 <= fast["warm"]["wall_s"]["median"] < 0.05 and 0.06 <= slow["warm"]["wall_s"]["median"] < 0.09
    assert 60 < fast["warm"]["throughput"]["median"] <= 5000
    assert fast["cold_empty_cache"]["na"].startswith("compiles no cached numba kernel")
    assert slow["cold_empty_cache"]["na"].startswith("not our code")
    assert fast["cold"]["peak_mb"]["median"] > 1 and fast["cold"]["cpu_s"]["median"] < 0.02
    m = out["measures"][0]
    assert len(m["speedup"]["warm"]["values"]) == 3 and 1.5 < m["speedup"]["warm"]["median"] < 3.5
    assert [t["met"] for t in m["targets"]] == [True, False]
