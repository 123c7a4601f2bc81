"""The result file (``bench/results.json``) and what is generated from it.

* :func:`render_table` — the README's benchmark table (between ``README_BEGIN`` and
  ``README_END``); never typed by hand: ``make bench`` rewrites it, and
  ``tests/test_bench_results.py`` checks that the README holds exactly what this function makes
  from the committed result file.
* :func:`render_page` — ``docs/benchmarks.md``, every side and measure with its ranges.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results.json"
RESULTS_QUICK = ROOT / "bench" / "results-quick.json"
README = ROOT / "README.md"
PAGE = ROOT / "docs" / "benchmarks.md"
README_BEGIN = "<!-- bench-table:begin -->"
README_END = "<!-- bench-table:end -->"
#: The order of the scripts in ``make bench``, the README's table and the page; a script not listed
#: here (a new ``bench/<name>.py``) runs after these, in alphabetical order (:func:`scripts`).
SCRIPT_ORDER = ("ingest", "ingest_dask", "lanes", "weather", "routing", "evaluate", "report", "nightly")
#: Scripts run apart from ``make bench``: ``scale.py`` (issue 23: one 100 M-row run takes hours on
#: 2 cores; its own file bench/results-scale.json, docs/scale.md), ``ingest_large.py`` (issue 23:
#: one file of millions of rows in groups and whole, 1-4 min per size; printed, its figures in
#: docs/scale.md) and ``fuel_savings.py`` (issue 20: not a timing but the demo month's
#: distribution of fuel savings, 4-9 min of routing; its section is merged into
#: bench/results.json by ``python -m bench --only fuel_savings``).
APART = ("scale", "ingest_large", "fuel_savings")
#: The scripts of :data:`APART` that ``python -m bench --only NAME`` runs into bench/results.json.
APART_SECTIONS = ("fuel_savings",)


def scripts() -> list[str]:
    """Every benchmark script of ``make bench``: ``bench/<name>.py`` without a leading underscore,
    except those run apart (:data:`APART`), in running order."""
    found = {p.stem for p in (ROOT / "bench").glob("[!_]*.py")} - set(APART)
    return [n for n in SCRIPT_ORDER if n in found] + sorted(found - set(SCRIPT_ORDER))


def unmeasured_cases(results: dict) -> dict[str, list[str]]:
    """Per script with a section in ``results``: the groups (``group``) and measures
    (``group/measure``) it declares now without figures in its section (added after it was
    measured). A group skipped for missing input is not listed again."""
    import importlib

    from bench import _harness

    out = {}
    for name, sec in results["benchmarks"].items():
        if name not in scripts() or sec.get("error"):
            continue
        groups, _ = importlib.import_module(f"bench.{name}").build(_harness.Config())
        have = {g["key"]: g for g in sec["groups"]}
        missing = []
        for g in groups:
            if g.key not in have:
                missing.append(g.key)
            elif not have[g.key].get("skipped"):
                keys = {m["key"] for m in have[g.key].get("measures", [])}
                missing += [f"{g.key}/{m.key}" for m in g.measures if m.key not in keys]
        if missing:
            out[name] = missing
    return out


def stamp_scripts(results: dict) -> dict:
    """Record the scripts present now and the cases they declare without figures (what the table
    and the page list as *not run yet*)."""
    results["scripts"] = scripts()
    results["unmeasured"] = unmeasured_cases(results)
    return results


def not_run_yet(results: dict) -> list[str]:
    """Scripts the result file knows of (``results["scripts"]``, the scripts present when it was
    last written) that have no section in it yet."""
    return [n for n in results.get("scripts", []) if n not in results["benchmarks"]]


# --------------------------------------------------------------------------- the file


def machine() -> dict:
    """What the figures were measured on."""
    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem_gb = None
    try:
        mem_gb = round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 1e9, 1)
    except (ValueError, OSError):
        pass
    versions = {}
    for mod in ("numpy", "numba", "duckdb", "scipy", "sklearn", "xarray", "pyais", "prefect", "distributed"):
        try:
            from importlib.metadata import version

            versions[mod] = version({"sklearn": "scikit-learn"}.get(mod, mod))
        except Exception:  # noqa: BLE001 - a missing package is just not listed
            pass
    return {"cpus": os.cpu_count(), "cpu_model": cpu, "memory_gb": mem_gb, "python": platform.python_version(),
            "platform": platform.platform(), "versions": versions}


def git_state() -> dict:
    def git(*args):
        try:
            return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=20).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    return {"commit": git("rev-parse", "HEAD"), "dirty_files": len([x for x in git("status", "--porcelain").splitlines()
                                                                      if not x.endswith(("results.json", "README.md", "benchmarks.md"))])}


def load_results(path: Path = RESULTS) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


def write_results(results: dict, path: Path = RESULTS) -> None:
    path.write_text(json.dumps(results, indent=1, sort_keys=False) + "\n", encoding="utf-8")


def new_results(mode: str) -> dict:
    return {"schema": 1, "mode": mode, "generated_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "git": git_state(), "machine": machine(), "scripts": scripts(), "benchmarks": {}}


def load_values(sections) -> list[float]:
    """Every 1-minute load average recorded before or after a run of ``sections``."""
    values = []
    for sec in sections:
        for g in sec["groups"]:
            for side in (g.get("sides") or {}).values():
                for phase in ("cold", "warm", "cold_empty_cache"):
                    ph = side.get(phase) or {}
                    for key in ("load_1min_before", "load_1min_after"):
                        values += [v for v in ((ph.get(key) or {}).get("values") or []) if v is not None]
    return values


def load_range(sections) -> tuple[float, float]:
    """Lowest and highest 1-minute load average recorded before or after any run of ``sections``."""
    values = load_values(sections)
    return (min(values), max(values)) if values else (float("nan"), float("nan"))


#: A run is busy when the load reaches this (the benchmark's own process is about 1 of it; a Dask
#: side's own workers add up to 2 more for a moment), and the machine not quiet when more than
#: :data:`BUSY_SHARE` of the runs were busy.
BUSY_LOAD = 2.0
BUSY_SHARE = 0.1


def load_note(before: float, after: float, sections, what: str = "the run") -> str:
    """What the load was: before and after ``what`` and the range around its runs; says when the
    machine was not quiet (more than a tenth of the runs at load >= 2 on these 2 cores)."""
    values = load_values(sections)
    lo, hi = load_range(sections)
    around = f", {lo:.2f}-{hi:.2f} around the runs" if lo == lo else ""  # NaN: no timed runs (a section of figures only)
    note = (f"1-minute load average {before:.2f} before {what}, {after:.2f} after it{around} "
            f"({os.cpu_count()} cores; the benchmark's own process counts about 1 in it)")
    busy = sum(v >= BUSY_LOAD for v in values) / len(values) if values else 0.0
    if busy > BUSY_SHARE:
        note += (f"; the machine was NOT quiet ({busy:.0%} of the runs at load >= {BUSY_LOAD:g}: other work, or this "
                 "benchmark's own Dask workers, ran on its cores): wall times may be inflated, compare the CPU seconds and "
                 "the ratios of the interleaved pairs")
    elif hi >= BUSY_LOAD:
        note += f"; {busy:.0%} of the runs saw load >= {BUSY_LOAD:g} (too few to call the machine busy; a Dask side's own workers reach it)"
    return note


def merge_section(section: dict, quick: bool = False, results: dict | None = None) -> dict:
    """Put one script's section, run on its own, into the result file (``results``, else the file
    on disk; a new one when there is none), write it and, unless ``quick``, regenerate the README's
    table and the page. Every other section keeps its own figures, time, commit and load."""
    path = RESULTS_QUICK if quick else RESULTS
    if results is None:
        results = load_results(path) if path.exists() else new_results("quick" if quick else "full")
    name = Path(section["script"]).stem
    section["run_alone_utc"] = section.get("started_utc") or time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    results["benchmarks"][name] = section
    results.setdefault("sections_run_alone", [])
    if name not in results["sections_run_alone"]:
        results["sections_run_alone"].append(name)
    write_results(stamp_scripts(results), path)
    if not quick:
        regenerate(results)
    return results


def regenerate(results: dict) -> None:
    """Rewrite the README's table and ``docs/benchmarks.md`` from ``results``."""
    update_readme(render_table(results))
    PAGE.parent.mkdir(parents=True, exist_ok=True)
    PAGE.write_text(render_page(results), encoding="utf-8")


def update_readme(table: str, path: Path | None = None) -> None:
    path = path or README
    text = path.read_text(encoding="utf-8")
    if README_BEGIN not in text or README_END not in text:
        raise SystemExit(f"{path}: the markers {README_BEGIN} / {README_END} are missing")
    head, rest = text.split(README_BEGIN, 1)
    _, tail = rest.split(README_END, 1)
    path.write_text(head + README_BEGIN + "\n" + table + README_END + tail, encoding="utf-8")


def readme_block(path: Path | None = None) -> str:
    """What the README holds between the markers (the generated table)."""
    text = (path or README).read_text(encoding="utf-8")
    return text.split(README_BEGIN, 1)[1].split(README_END, 1)[0][1:]


# --------------------------------------------------------------------------- formatting


def fmt_s(x) -> str:
    if x is None:
        return "–"
    if x < 1.0:
        return f"{x * 1000:.3g} ms"
    return f"{x:.3g} s"


def fmt_rate(x, unit: str) -> str:
    if x is None:
        return "–"
    for scale, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if x >= scale:
            return f"{x / scale:.3g} {prefix} {unit}/s"
    return f"{x:.3g} {unit}/s"


def _st(side: dict, phase: str, q: str = "wall_s"):
    ph = side.get(phase) or {}
    return ph.get(q) if isinstance(ph, dict) else None


def fig(side: dict | None, phase: str, with_range: bool = False) -> str:
    """``median`` (and ``[min-max]``) wall seconds of a phase, or why there is none."""
    if side is None:
        return "–"
    ph = side.get(phase) or {}
    if "na" in ph:
        return "n/a"
    st = _st(side, phase)
    if not st:
        return "failed" if side.get("failures") else "–"
    text = fmt_s(st["median"])
    if with_range:
        text += f" [{fmt_s(st['min'])}–{fmt_s(st['max'])}]"
    return text


def _ratio(m: dict, phase: str) -> str:
    sp = (m.get("speedup") or {}).get(phase)
    return f"{sp['median']:.3g}×" if sp else "–"


def _mem(side: dict | None) -> str:
    st = _st(side, "cold", "peak_mb") if side else None
    return f"{st['median']:.0f}" if st else "–"


def cpu_check(t: dict, sides: dict) -> str:
    """For a wall-time or throughput target missed on a loaded machine: whether the side's CPU
    seconds would meet it (a single-threaded run on a quiet machine takes about its CPU seconds,
    plus any I/O wait). Empty when it does not apply. Informative only: ``met`` stays the wall figure's."""
    phase, _, quantity = t["metric"].partition(".")
    ph = (sides.get(t["side"]) or {}).get(phase) or {}
    cpu_key = {"wall_s": "cpu_s", "process_wall_s": "process_cpu_s"}.get(quantity)
    if t["met"] is not False or not isinstance(ph, dict):
        return ""
    if cpu_key and (ph.get(cpu_key) or {}).get("median") is not None and t["op"] in ("<", "<="):
        cpu = ph[cpu_key]["median"]
        ok = cpu < t["value"] if t["op"] == "<" else cpu <= t["value"]
        return f" (CPU {fmt_s(cpu)}: {'within' if ok else 'also over'} it)"
    if quantity == "throughput" and ph.get("work") and (ph.get("cpu_s") or {}).get("median") and t["op"] in (">", ">="):
        rate = ph["work"] / ph["cpu_s"]["median"]
        return f" ({fmt_rate(rate, '').rstrip('/s').strip()} per CPU s: {'within' if rate >= t['value'] else 'also under'} it)"
    return ""


def _targets(m: dict, sides: dict | None = None) -> str:
    out = []
    for t in m["targets"]:
        state = {True: "met", False: "**not met**", None: "not measured"}[t["met"]]
        out.append(f"{t['name']}: {state}{cpu_check(t, sides or {})}")
    return "; ".join(out) or "–"


def _unit(side: dict) -> str:
    work = side.get("work_counts") or ""
    return work.split(" ", 1)[0] if work else ""


def _ours_cell(side: dict, phase: str) -> str:
    """``median [min–max]`` wall, then CPU seconds and throughput, of one phase of a side."""
    text = fig(side, phase, with_range=True)
    cpu = _st(side, phase, "cpu_s")
    if cpu:
        text += f"<br>CPU {fmt_s(cpu['median'])}"
    tp = _st(side, phase, "throughput")
    if tp:
        text += f"<br>{fmt_rate(tp['median'], _unit(side))}"
    return text


def _load(group: dict) -> str:
    ld = group.get("load_1min") or {}
    return f"{ld.get('before', '–')}→{ld.get('after', '–')}"


def _rows(results: dict):
    """(script, group, measure) for every measure, in the scripts' order."""
    names = [n for n in SCRIPT_ORDER if n in results["benchmarks"]]
    names += [n for n in results["benchmarks"] if n not in names]
    for name in names:
        for g in results["benchmarks"][name]["groups"]:
            for m in g.get("measures", []):
                yield name, g, m


def render_table(results: dict) -> str:
    """The README's table: one row per headline measure, medians, baseline beside ours."""
    mach = results["machine"]
    lines = [
        f"Generated by `make bench` from `bench/results.json` ({results['mode']} run, {results['generated_utc']}, "
        f"commit {results['git']['commit'][:10] or '?'}; {mach['cpus']} cores, {mach['cpu_model'] or 'unknown CPU'}). "
        "Median [range] of at least 5 runs, CPU seconds below; **cold** = first run in a fresh process (numba cache "
        "warm), **warm** = a later run in the same process (batch commands, run as a fresh process each time, have no "
        "warm figure); every baseline ran in the same session, interleaved with "
        "ours; baseline ÷ ours = baseline time / our time per interleaved pair (median), cold against cold and warm "
        "against warm; an external figure is compared with our cold one only. The empty-cache cold runs, process "
        "times and every other figure: [docs/benchmarks.md](docs/benchmarks.md).",
        "",
    ]
    if results.get("load_note"):
        lines += [f"Load: {results['load_note']}", ""]
    alone = results.get("sections_run_alone", [])
    for name in alone:
        sec = results["benchmarks"].get(name) or {}
        lines += [f"Re-run alone after the full run: bench/{name}.py, {_when(sec)}.", ""]
    if alone:
        full = [n for n in results["benchmarks"] if n not in alone]
        lines += [f"From the full run (commit {results['git']['commit'][:10]}): {', '.join(full) or 'none'}.", ""]
    lines += ["| bench | measure | ours cold | ours warm | baseline (same run) | baseline cold | baseline warm | "
              "baseline ÷ ours, cold | baseline ÷ ours, warm | peak MB ours / baseline | load (1 min) | targets |",
              "| --- | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | --- | --- |"]
    for name, g, m in _rows(results):
        if not m.get("headline", True):
            continue
        sides = g["sides"]
        o = sides[m["ours"]]
        b = sides.get(m.get("baseline") or "")
        if b is not None:
            base_label, bcold, bwarm = m["baseline_label"], _ours_cell(b, "cold"), _ours_cell(b, "warm")
            rc, rw = _ratio(m, "cold"), _ratio(m, "warm")
        else:
            e = m.get("external") or {}
            base_label = f"external: {e.get('label', '?')} ({e.get('date', '?')})"
            bcold = fmt_s(e.get("cold_s")) if e.get("cold_s") else "–"
            bwarm = "never compared"
            rc = f"{e['speedup_cold']:.3g}× vs external" if e.get("speedup_cold") else "–"
            rw = "–"
        mem = f"{_mem(o)} / {_mem(b) if b else (str(m.get('external', {}).get('peak_mb', '–')) + ' ext.')}"
        lines.append(f"| {name} | {m['title']} | {_ours_cell(o, 'cold')} | {_ours_cell(o, 'warm')} | {base_label} | {bcold} | "
                     f"{bwarm} | {rc} | {rw} | {mem} | {_load(g)} | {_targets(m, sides)} |")
    skipped = [(name, g) for name in results["benchmarks"] for g in results["benchmarks"][name]["groups"] if g.get("skipped")]
    failed = [(name, sec["error"]) for name, sec in results["benchmarks"].items() if sec.get("error")]
    pending = not_run_yet(results)
    if skipped or failed or pending or results.get("unmeasured"):
        lines.append("")
        lines += [f"Skipped: {name} / {g['title']}: {g['skipped']}" for name, g in skipped]
        lines += [f"**Failed**: bench/{name}.py: {err}" for name, err in failed]
        lines += [f"Not run yet: bench/{name}.py (no figures in bench/results.json; `python -m bench --only {name}` "
                  "measures it and merges it in)" for name in pending]
        lines += [f"Not run yet: bench/{name}.py {', '.join(cases)} (declared after the script's figures were measured)"
                  for name, cases in results.get("unmeasured", {}).items()]
    return "\n".join(lines) + "\n"


def _when(sec: dict) -> str:
    """When, on which commit and under what load a section was measured."""
    commit = (sec.get("git") or {}).get("commit", "")
    text = f"started {sec.get('started_utc') or sec.get('run_alone_utc', '?')}, commit {commit[:10] or '?'}"
    if sec.get("elapsed_s") is not None:
        text += f", {sec['elapsed_s']:.0f} s"
    if sec.get("children_cpu_s") is not None:
        text += f" ({sec['children_cpu_s']:.0f} CPU s in the measured processes)"
    if sec.get("load_note"):
        text += f"; load: {sec['load_note']}"
    return text


# --------------------------------------------------------------------------- the page


def _stat_cell(st: dict | None, kind: str = "s", unit: str = "") -> str:
    if not st:
        return "–"
    f = (lambda x: fmt_s(x)) if kind == "s" else (lambda x: f"{x:.0f}") if kind == "mb" else (lambda x: fmt_rate(x, unit))
    return f"{f(st['median'])} [{f(st['min'])}–{f(st['max'])}]"


def _side_rows(key: str, s: dict) -> list[str]:
    rows = []
    for phase, name in (("cold", "cold, cache warm"), ("cold_empty_cache", "cold, cache empty"), ("warm", "warm")):
        ph = s.get(phase) or {}
        if "na" in ph:
            rows.append(f"| {key} | {name} | n/a: {ph['na']} | | | | | |")
            continue
        if not ph:
            rows.append(f"| {key} | {name} | – | | | | | |")
            continue
        rows.append(f"| {key} | {name} (n={ph['wall_s']['n']}) | {_stat_cell(ph['wall_s'])} | {_stat_cell(ph.get('cpu_s'))} | "
                    f"{_stat_cell(ph.get('process_wall_s'))} | {_stat_cell(ph.get('peak_mb'), 'mb')} | "
                    f"{_stat_cell(ph.get('throughput'), 'rate', _unit(s))} | "
                    f"{_loadrange(ph)} |")
    return rows


def _loadrange(ph: dict) -> str:
    a, b = ph.get("load_1min_before"), ph.get("load_1min_after")
    if not a or not b:
        return "–"
    return f"{min(a['min'], b['min']):.2f}–{max(a['max'], b['max']):.2f}"


def _pairs(sp: dict | None) -> str:
    if not sp:
        return "–"
    vals = ", ".join(f"{v:.3g}" for v in sp["values"] if v is not None)
    return f"{sp['median']:.3g}× [{sp['min']:.3g}–{sp['max']:.3g}] (pairs {vals})"


def render_page(results: dict) -> str:
    """``docs/benchmarks.md``: every figure of the result file, generated."""
    from bench import _harness

    mach = results["machine"]
    out = ["# Benchmarks", "", "<!-- generated by `make bench` (bench/_report.py) from bench/results.json: do not edit -->", "",
           f"{results['mode']} run of {results['generated_utc']}, commit `{results['git']['commit'] or '?'}`; "
           f"{mach['cpus']} cores ({mach['cpu_model'] or '?'}), {mach.get('memory_gb')} GB, Python {mach['python']}; "
           f"versions {', '.join(f'{k} {v}' for k, v in mach.get('versions', {}).items())}.", ""]
    if results.get("elapsed_s"):
        cpu = results.get("children_cpu_s")
        out += [f"The whole `make bench` took {results['elapsed_s']:.0f} s"
                + (f" ({cpu:.0f} CPU seconds in its measured processes: about what it takes on a quiet machine)."
                   if cpu else ".")]
    if results.get("load_note"):
        out += ["", f"**Load.** {results['load_note']}"]
    if results.get("sections_run_alone"):
        out += ["", f"Sections re-run on their own after the full run: {', '.join(results['sections_run_alone'])} "
                    "(each section has its own time and load)."]
    doc = (_harness.__doc__ or "").split("Run a script's groups")[0].strip().splitlines()[2:]
    out += ["", "## How to read this page", "", *doc, "",
            "*Process wall s* is the whole child process (interpreter start, setup and every run in it); for a "
            "command line it is the cold figure itself. Peak RSS is the fresh process's peak up to the end of its "
            "first run (setup included) in megabytes (10^6 bytes).", ""]
    for name in [n for n in SCRIPT_ORDER if n in results["benchmarks"]] + [n for n in results["benchmarks"] if n not in SCRIPT_ORDER]:
        sec = results["benchmarks"][name]
        out += [f"## `{sec['script']}`", ""]
        if sec.get("started_utc"):
            alone = " (re-run alone after the full run)" if name in results.get("sections_run_alone", []) else ""
            out += [f"Measured{alone}: {_when(sec)}.", ""]
        if sec.get("error"):
            out += [f"**The script failed**: {sec['error']}", ""]
        out += [f"- {n}" for n in sec.get("notes", [])]
        if sec.get("notes"):
            out.append("")
        for g in sec["groups"]:
            out += [f"### {g['title']}", ""]
            if g.get("skipped"):
                out += [f"Skipped: {g['skipped']}", ""]
                continue
            out += [f"Started {g['started_utc']}, {g['elapsed_s']:.0f} s, {g['runs']} interleaved rounds; load (1 min) "
                    f"{_load(g)} before → after." + (f" Inputs: {json.dumps(g['prepare']['info'])}." if g.get("prepare") else ""), ""]
            out += ["| side | phase | wall s median [range] | CPU s | process wall s | peak RSS MB | throughput | load |",
                    "| --- | --- | --- | --- | --- | --- | --- | --- |"]
            for key, s in g["sides"].items():
                out += _side_rows(key, s)
            out.append("")
            for key, s in g["sides"].items():
                line = f"- `{key}`: {s['label']}" + (f" — `{s['argv']}`" if s.get("argv") else "")
                if s.get("work_counts"):
                    line += f"; throughput counts {s['work_counts']}"
                if s.get("info"):
                    line += f"; result {json.dumps(s['info'], default=str)}"
                if s.get("failures"):
                    line += f"; **failures**: {' / '.join(s['failures'])}"
                out.append(line)
            out.append("")
            for m in g.get("measures", []):
                out += [f"**{m['title']}** — ours `{m['ours']}`"
                        + (f" against `{m['baseline']}` ({m['relation']})" if m.get("baseline") else "")]
                if m.get("speedup"):
                    out += [f"- baseline ÷ ours, cold: {_pairs(m['speedup'].get('cold'))}; warm: {_pairs(m['speedup'].get('warm'))}"]
                if m.get("external"):
                    e = m["external"]
                    out += [f"- external (not measured in this run): {e.get('label')} — {e.get('cold_s')} s cold, "
                            f"{e.get('peak_mb', '–')} MB peak; {e.get('date')}, {e.get('machine')}, {e.get('method')}"
                            + (f"; parts {json.dumps(e['parts'])}" if e.get("parts") else "")
                            + (f"; ratio cold/cold {e['speedup_cold']:.3g}×" if e.get("speedup_cold") else "")]
                for t in m["targets"]:
                    state = {True: "met", False: "**not met**", None: "not measured"}[t["met"]]
                    meas = "–" if t["measured"] is None else f"{t['measured']:.4g}"
                    out += [f"- target ({t['source']}): {t['name']} — `{t['metric']}` {t['op']} {t['value']:g} {t['unit']}: "
                            f"measured {meas}: {state}{cpu_check(t, g['sides'])}"]
                out.append("")
    pending, cases = not_run_yet(results), results.get("unmeasured", {})
    if pending or cases:
        out += ["## Not run yet", ""] + [f"- `bench/{n}.py`: no figures in bench/results.json yet (`python -m bench --only {n}` "
                                          "measures it and merges it in)" for n in pending]
        out += [f"- `bench/{n}.py`: {', '.join(c)} declared after the script's figures were measured" for n, c in cases.items()]
    return "\n".join(out).rstrip() + "\n"
