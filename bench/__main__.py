"""``python -m bench [--quick | --smoke] [--only NAME,...] [--wait-quiet S]``: every benchmark, one result file.

Runs each ``bench/<name>.py``'s groups in turn (:func:`bench._harness.run_groups`), writes
``bench/results.json`` (``--quick``: ``bench/results-quick.json``, for development: fewer runs and
smaller inputs, the README untouched; ``--smoke``: every side once, to check that every script
runs) and regenerates the README's benchmark table and
``docs/benchmarks.md`` from it. ``--only`` re-runs some scripts and merges their sections into the
existing file (each section keeps its own time, commit and load; the table and the page say
which sections were re-run alone); a new ``bench/<name>.py`` is found and run without being listed
anywhere (:func:`bench._report.scripts`). ``--wait-quiet S`` first waits up to S
seconds for the 1-minute load average to drop below 1 (the machine is shared); the load is
recorded either way.
"""

from __future__ import annotations

import argparse
import importlib
import os
import resource
import time

from bench import _harness, _report


def _wait_quiet(limit_s: float, threshold: float = 1.0) -> str:
    t0 = time.monotonic()
    while os.getloadavg()[0] >= threshold and time.monotonic() - t0 < limit_s:
        time.sleep(15)
    waited = time.monotonic() - t0
    return f"waited {waited:.0f} s for a 1-minute load average below {threshold:g}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="development mode (fewer runs, smaller inputs; separate file)")
    ap.add_argument("--smoke", action="store_true", help="every side once (quick inputs) to check that every script runs")
    ap.add_argument("--only", default="", help="comma-separated scripts to run, e.g. routing,lanes")
    ap.add_argument("--wait-quiet", type=float, default=0.0, metavar="S", help="wait up to S s for load < 1 first")
    args = ap.parse_args(argv)
    known = _report.scripts()
    names = [n for n in args.only.split(",") if n] or known
    unknown = [n for n in names if n not in known + list(_report.APART_SECTIONS)]
    if unknown:
        ap.error(f"unknown benchmark(s) {', '.join(unknown)}; choose from {', '.join(known + list(_report.APART_SECTIONS))}")
    args.quick = args.quick or args.smoke
    cfg = _harness.Config.make(args.quick, smoke=args.smoke)
    waited = _wait_quiet(args.wait_quiet) if args.wait_quiet > 0 else ""
    path = _report.RESULTS_QUICK if args.quick else _report.RESULTS
    partial = bool(args.only)
    results = _report.load_results(path) if (partial and path.exists()) else _report.new_results("quick" if args.quick else "full")
    if not partial and path.exists():  # sections run apart (not part of make bench) keep their figures, marked run alone
        earlier = _report.load_results(path)
        for name in _report.APART_SECTIONS:
            if name in earlier["benchmarks"]:
                results["benchmarks"][name] = earlier["benchmarks"][name]
                results.setdefault("sections_run_alone", []).append(name)
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    for name in names:
        try:
            mod = importlib.import_module(f"bench.{name}")
            groups, notes = mod.build(cfg)
            section = _harness.run_groups(cfg, f"bench/{name}.py", groups, notes)
        except Exception as err:  # noqa: BLE001 - one broken script must not lose the others' figures
            import traceback

            tail = traceback.format_exc().strip().splitlines()[-3:]
            print(f"== bench/{name}.py FAILED: {err}", flush=True)
            section = {"script": f"bench/{name}.py", "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                       "git": _report.git_state(), "groups": [], "notes": [], "error": " | ".join(tail)}
        if waited and name == names[0] and "load_note" in section:
            section["load_note"] += f"; {waited}"
        if partial:  # merged into the existing file; the page and table say it was re-run alone
            results = _report.merge_section(section, quick=args.quick, results=results)
            continue
        results["benchmarks"][name] = section
        _report.write_results(results, path)  # after each script: a crash later keeps what was measured
    load1 = os.getloadavg()
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if not partial:
        results["elapsed_s"] = round(time.perf_counter() - t0, 1)
        # every measured process is a waited-for child: their CPU seconds are what the run would take
        # on a machine with nothing else running (a single-threaded process's wall ~ its CPU)
        results["children_cpu_s"] = round(cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime, 1)
        results["load_1min"] = {"before": round(load0[0], 2), "after": round(load1[0], 2)}
        note = _report.load_note(load0[0], load1[0], results["benchmarks"].values())
        results["load_note"] = note + (f"; {waited}" if waited else "")
    _report.write_results(_report.stamp_scripts(results), path)
    if not args.quick:
        _report.regenerate(results)
    print(f"wrote {path.relative_to(_report.ROOT)}" + ("" if args.quick else ", README.md's table and docs/benchmarks.md")
          + (f" in {results.get('elapsed_s', 0):.0f} s" if not partial else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
