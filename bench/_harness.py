"""The benchmark harness every ``bench/*.py`` script uses.

Vocabulary (the same in the result file, ``bench/results.json``, and in ``docs/benchmarks.md``):

* A **side** is one thing that is timed: a ``run(state)`` callable after an untimed
  ``setup(**kwargs)``, both executed in a fresh child process (:mod:`bench._child`), or a command
  line (``argv``) whose whole process is the run (as a user runs ``stormlane ...``).
* **cold** = the first run in a fresh process (for a command line: the whole process, from
  spawn to exit). Measured with numba's compile cache *empty* (``NUMBA_CACHE_DIR`` pointing at
  a new empty folder: the kernels compile in the run, as on a fresh install) and, separately,
  *warm* (a cache of this session filled by the first empty-cache run of each side, so no
  figure depends on an earlier run or on ``make test``). Sides whose code compiles no cached
  numba kernel say so (the empty folder stays empty); sides whose kernels another side compiles
  name it and are not repeated empty (the budget of ``make bench`` is 30 minutes).
* **warm** = a later run in the same process (imports done, kernels loaded, caches filled).
* Every side is measured ``runs`` times (default 5): median and range (min, max) of wall
  seconds, CPU seconds (all threads of the process: ``time.process_time``), peak resident set
  size of the fresh process (``getrusage`` ``ru_maxrss``) and, where the side counts its work,
  throughput = work / wall seconds.
* A **group** holds the sides that are compared; its rounds are interleaved (A B A B ...: round
  r runs every side once, each in its own fresh process), so a baseline and our code see the
  same machine load. A **measure** compares our side with a baseline side of the same group
  (ratios only cold/cold and warm/warm, per interleaved pair) or with an **external** figure
  (a peer measured elsewhere: labelled with its date, machine and method, compared cold/cold
  only, never with a warm figure of ours).
* The 1-minute load average is recorded before and after every run and every group.

Run a script's groups with :func:`run_groups`; :mod:`bench.__main__` runs every script and
writes the result file and the generated tables.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from bench import _results

ROOT = Path(__file__).resolve().parents[1]
_DEFAULT_SHARED = ROOT.parent / "shared" / "data"


def shared_data() -> Path:
    """The real data set, read in place: ``$STORMLANE_SHARED_DATA``, ``../shared/data`` or ``/work/shared/data``."""
    env = os.environ.get("STORMLANE_SHARED_DATA")
    if env:
        return Path(env)
    return _DEFAULT_SHARED if _DEFAULT_SHARED.is_dir() else Path("/work/shared/data")


@dataclass
class Config:
    """How much to measure. ``quick`` is for development only (fewer runs, smaller inputs)."""

    runs: int = 5
    empty_runs: int = 5
    quick: bool = False
    cache_dir: Path = field(default_factory=lambda: Path(os.environ.get(
        "STORMLANE_BENCH_CACHE", Path(tempfile.gettempdir()) / "stormlane-bench-cache")))
    timeout_s: float = 900.0
    empty_budget_s: float = 12.0  # empty-cache runs of one side stop once they took this long (n recorded)
    verbose: bool = True

    @property
    def warm_cache(self) -> Path:
        """numba's cache for the cache-warm runs of every side: the kernels compiled by the
        empty-cache runs of this session (merged), plus whatever a side compiles on first use.
        Emptied when the session starts, so no figure depends on an earlier run or ``make test``."""
        path = Path(self.cache_dir) / "numba-warm-cache"
        if not getattr(self, "_warm_ready", False):
            shutil.rmtree(path, ignore_errors=True)
            path.mkdir(parents=True, exist_ok=True)
            self._warm_ready = True
        return path

    @classmethod
    def make(cls, quick: bool = False, smoke: bool = False) -> Config:
        if smoke:  # every side once, to check that every script runs (no figure worth keeping)
            return cls(runs=1, empty_runs=0, quick=True)
        return cls(runs=2, empty_runs=1, quick=True) if quick else cls()


#: Why a batch command has no warm figure (``Side(..., **BATCH)``): ingest, lanes, a night and a
#: learning run are each a fresh process when users run them, so the cold figure (five fresh
#: processes, compile cache warm) is theirs; a second run in one process is a case nobody runs,
#: and measuring it would double the longest sides of ``make bench`` (budget: 30 min).
BATCH = {"warm_per_process": 0,
         "warm_na": "not measured: a batch command, run as a fresh process each time (the cold figure is what users get)"}


@dataclass
class Side:
    """One timed thing. Give ``run`` (+ optional ``setup``) or ``argv`` (a whole process)."""

    key: str
    label: str
    run: str | None = None  # "module:function", called as run(state) -> dict (may hold "work")
    setup: str | None = None  # "module:function", called as setup(**kwargs) -> state; untimed
    kwargs: dict = field(default_factory=dict)
    argv: list[str] | None = None  # a command line: cold = this whole process
    parse: str | None = None  # for argv sides: "module:function"(stdout) -> info dict
    warm_run: str | None = None  # for argv sides: the same work in process, for the warm figure
    warm_setup: str | None = None
    warm_kwargs: dict = field(default_factory=dict)
    warm_na: str = ""  # why there is no warm figure (when there is none)
    ours: bool = True  # our code (numba kernels)
    empty_cache: str | None = None  # why the empty-cache runs are not made for this side of ours (None: made)
    work: str = ""  # what "work" counts, e.g. "rows read from the file" (throughput = work / wall s)
    env: dict = field(default_factory=dict)
    warm_per_process: int = 1  # warm runs after the cold run in each cold process


@dataclass
class Target:
    """A stated goal: ``metric`` of ``side`` (default: the measure's ours) ``op`` ``value``.

    ``metric`` is ``<phase>.<quantity>`` (phase cold, warm or cold_empty_cache; quantity wall_s,
    cpu_s, peak_mb, throughput, process_wall_s), ``speedup.cold`` / ``speedup.warm`` (baseline
    time / ours, median of the interleaved pairs) or ``excess.cold`` / ``excess.warm`` (our median
    minus the baseline's, seconds). Evaluated on the median. ``value_from`` (``"side:phase.quantity"``)
    adds that side's median to ``value`` (a threshold measured in the same run).
    """

    name: str
    metric: str
    op: str
    value: float
    unit: str
    source: str
    side: str | None = None
    value_from: str | None = None


@dataclass
class Measure:
    key: str
    title: str
    ours: str
    baseline: str | None = None
    relation: str = ""  # how the baseline's task relates to ours ("same task", or what differs)
    external: dict | None = None  # label, date, machine, method, cold_s, peak_mb, parts ...
    targets: list[Target] = field(default_factory=list)
    headline: bool = True  # a row of the README table


@dataclass
class Group:
    key: str
    title: str
    sides: list[Side]
    measures: list[Measure]
    needs: list[Path] = field(default_factory=list)  # files without which the group is skipped
    prepare: str | None = None  # "module:function"(**prepare_kwargs) -> info; untimed, own process
    prepare_kwargs: dict = field(default_factory=dict)
    runs: int | None = None  # overrides Config.runs (never below 5 in a full run)
    empty_runs: int | None = None


# --------------------------------------------------------------------------- processes


def _spawn(argv: list[str], env: dict, timeout_s: float, stdout_path: Path, stderr_path: Path) -> dict:
    """Run ``argv`` in a fresh process (its own session); wall from spawn to exit, rusage from wait4."""
    full_env = dict(os.environ)
    full_env.update({k: str(v) for k, v in env.items()})
    # this checkout's packages first, also for the console script (whose sys.path[0] is its bin/)
    full_env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])
    with open(stdout_path, "wb") as out, open(stderr_path, "wb") as err:
        load_before = os.getloadavg()[0]
        t0 = time.perf_counter()
        p = subprocess.Popen(argv, stdout=out, stderr=err, env=full_env, cwd=ROOT, start_new_session=True)
        killed = []

        def _kill():
            killed.append(True)
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

        timer = threading.Timer(timeout_s, _kill)
        timer.start()
        try:
            _, status, ru = os.wait4(p.pid, 0)
        finally:
            timer.cancel()
        wall = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
    res = {"process_wall_s": wall, "process_cpu_s": ru.ru_utime + ru.ru_stime, "process_peak_mb": ru.ru_maxrss * 1024 / 1e6,
           "exit": p.returncode, "load_before": load_before, "load_after": os.getloadavg()[0]}
    if killed:
        res["failed"] = f"killed after the {timeout_s:.0f} s timeout"
    elif p.returncode != 0:
        tail = stderr_path.read_text(errors="replace").strip().splitlines()[-4:]
        res["failed"] = f"exit {p.returncode}: " + " | ".join(tail)
    return res


def _child(cfg: Config, tmp: Path, setup, run, kwargs: dict, runs: int, env: dict, call_with_kwargs: bool = False) -> dict:
    """One fresh :mod:`bench._child` process making ``runs`` runs; returns its record."""
    spec = tmp / f"spec-{time.monotonic_ns()}.json"
    result = spec.with_suffix(".out.json")
    spec.write_text(json.dumps({"setup": setup, "run": run, "kwargs": kwargs, "runs": runs, "result": str(result),
                                "call_with_kwargs": call_with_kwargs}))
    proc = _spawn([sys.executable, "-m", "bench._child", str(spec)], env, cfg.timeout_s,
                  spec.with_suffix(".stdout"), spec.with_suffix(".stderr"))
    if "failed" not in proc:
        try:
            proc.update(json.loads(result.read_text()))
        except (OSError, ValueError) as err:
            proc["failed"] = f"no result from the child ({err})"
    return proc


def _argv_process(cfg: Config, tmp: Path, side: Side, env: dict) -> dict:
    """The side's command line as one cold run (its stdout parsed into ``info`` when asked)."""
    stem = tmp / f"argv-{time.monotonic_ns()}"
    proc = _spawn(side.argv, env, cfg.timeout_s, stem.with_suffix(".stdout"), stem.with_suffix(".stderr"))
    info = {}
    if "failed" not in proc and side.parse:
        from bench._child import _call

        info = _call(side.parse)(stem.with_suffix(".stdout").read_text(errors="replace")) or {}
    proc["runs"] = [{"wall_s": proc["process_wall_s"], "cpu_s": proc["process_cpu_s"], "load_before": proc["load_before"],
                     "load_after": proc["load_after"], "info": info}]
    proc["peak_mb_after_first_run"] = proc["process_peak_mb"]
    return proc


def _cold_process(cfg: Config, tmp: Path, side: Side, env: dict, warm: bool) -> dict:
    if side.argv:
        return _argv_process(cfg, tmp, side, env)
    runs = 1 + (side.warm_per_process if warm else 0)
    return _child(cfg, tmp, side.setup, side.run, side.kwargs, runs, env)


# --------------------------------------------------------------------------- a group


def _log(cfg: Config, text: str) -> None:
    if cfg.verbose:
        print(text, flush=True)


def _empty_cache_runs(cfg: Config, tmp: Path, side: Side, n: int, rec: dict) -> None:
    """``n`` cold runs, each with a new empty numba cache folder; the first run's compiled kernels
    are merged into the run's shared warm cache (:attr:`Config.warm_cache`)."""
    spent = 0.0
    for r in range(n):
        if r and spent > cfg.empty_budget_s:
            rec["empty_cache_note"] = (f"{r} run(s): the empty-cache runs of this side stop after {cfg.empty_budget_s:.0f} s "
                                       "(compilation is CPU-bound and steady; the budget of `make bench` is 30 min)")
            break
        cache = Path(tempfile.mkdtemp(prefix=f"numba-{side.key}-", dir=tmp))
        proc = _cold_process(cfg, tmp, side, {**side.env, "NUMBA_CACHE_DIR": cache}, warm=False)
        written = sum(1 for p in cache.rglob("*") if p.is_file())
        if "failed" in proc:
            rec["cold_empty_cache"].append(proc)
            _log(cfg, f"    {side.key}: empty-cache run failed: {proc['failed']}")
            break
        if written == 0:
            rec["empty_cache_na"] = "compiles no cached numba kernel (the empty cache folder stayed empty)"
            shutil.rmtree(cache, ignore_errors=True)
            break
        proc["cache_files_written"] = written
        spent += proc["process_wall_s"]
        rec["cold_empty_cache"].append(proc)
        _log(cfg, f"    {side.key}: cold, empty compile cache: {proc['runs'][0]['wall_s']:.2f} s")
        if r == 0:
            shutil.copytree(cache, cfg.warm_cache, dirs_exist_ok=True)
        shutil.rmtree(cache, ignore_errors=True)


def _warm_argv(cfg: Config, tmp: Path, side: Side, env: dict, n: int, rec: dict) -> None:
    """For a command-line side: one process running the same work in process, 1 + n times."""
    proc = _child(cfg, tmp, side.warm_setup, side.warm_run, side.warm_kwargs, 1 + n, env)
    rec["warm_process"] = proc
    if "failed" in proc:
        _log(cfg, f"    {side.key}: warm process failed: {proc['failed']}")


def run_group(cfg: Config, group: Group) -> dict:
    """Measure every side of ``group`` (interleaved rounds) and summarise its measures."""
    started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    t_group = time.perf_counter()
    out: dict = {"key": group.key, "title": group.title, "started_utc": started}
    missing = [str(p) for p in group.needs if not Path(p).exists()]
    if missing:
        out["skipped"] = f"input not found: {', '.join(missing)} (set STORMLANE_SHARED_DATA to the shared data folder)"
        _log(cfg, f"  {group.key}: skipped, {out['skipped']}")
        return out
    runs = cfg.runs if cfg.quick else max(group.runs or 0, cfg.runs)
    empty_runs = cfg.empty_runs if group.empty_runs is None else min(group.empty_runs, cfg.empty_runs)
    load0 = os.getloadavg()
    tmp = Path(tempfile.mkdtemp(prefix=f"stormlane-bench-{group.key}-"))
    try:
        if group.prepare:
            _log(cfg, f"  {group.key}: preparing inputs (untimed)")
            prep = _child(cfg, tmp, None, group.prepare, group.prepare_kwargs, 1, {}, call_with_kwargs=True)
            if "failed" in prep:
                out["skipped"] = f"preparing the inputs failed: {prep['failed']}"
                return out
            out["prepare"] = {"info": prep["runs"][0]["info"], "wall_s": prep["runs"][0]["wall_s"]}
            if isinstance(out["prepare"]["info"], dict) and out["prepare"]["info"].get("summary"):
                _log(cfg, f"  {group.key}: {out['prepare']['info']['summary']}")  # a group whose figures are its preparation's
        recs = {s.key: {"cold": [], "cold_empty_cache": [], "empty_cache_na": ""} for s in group.sides}
        env = {s.key: dict(s.env) for s in group.sides}
        for side in group.sides:
            if not side.ours:
                recs[side.key]["empty_cache_na"] = "not our code: no numba compile cache of ours involved"
                continue
            if side.empty_cache:
                recs[side.key]["empty_cache_na"] = side.empty_cache
                continue
            if empty_runs == 0:
                recs[side.key]["empty_cache_na"] = "not measured in this mode"
                continue
            _empty_cache_runs(cfg, tmp, side, empty_runs, recs[side.key])
        for side in group.sides:
            env[side.key]["NUMBA_CACHE_DIR"] = cfg.warm_cache
        for r in range(runs):
            for side in group.sides:
                warm = side.argv is None
                proc = _cold_process(cfg, tmp, side, env[side.key], warm)
                recs[side.key]["cold"].append(proc)
                if "failed" in proc:
                    _log(cfg, f"    {side.key}: round {r + 1} failed: {proc['failed']}")
                else:
                    w = [f"{x['wall_s']:.3f}" for x in proc["runs"]]
                    _log(cfg, f"    {side.key}: round {r + 1}: runs {', '.join(w)} s, peak {proc['process_peak_mb']:.0f} MB, "
                              f"load {proc['load_before']:.2f}")
        for side in group.sides:
            if side.argv and side.warm_run:
                _warm_argv(cfg, tmp, side, env[side.key], runs, recs[side.key])
        out["sides"] = {s.key: _results.summarise_side(s, recs[s.key]) for s in group.sides}
        out["measures"] = [_results.summarise_measure(m, out["sides"]) for m in group.measures]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    out["load_1min"] = {"before": round(load0[0], 2), "after": round(os.getloadavg()[0], 2)}
    out["elapsed_s"] = round(time.perf_counter() - t_group, 1)
    out["runs"] = runs
    return out


def run_groups(cfg: Config, script: str, groups: list[Group], notes: list[str] | None = None) -> dict:
    """Run every group of one bench script; returns the script's section of the result file."""
    from bench import _report

    import resource

    t0 = time.perf_counter()
    load0 = os.getloadavg()[0]
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    _log(cfg, f"== {script}")
    # each section says when, on which commit and under what load it was measured: a script may be
    # re-run alone and merged into a result file whose other sections are older
    section = {"script": script, "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
               "git": _report.git_state(), "groups": [], "notes": list(notes or [])}
    for g in groups:
        _log(cfg, f"  -- {g.title}")
        res = run_group(cfg, g)
        section["groups"].append(res)
        for m in res.get("measures", []):
            _log(cfg, "     " + _results.one_line(m, res["sides"]))
    load1 = os.getloadavg()[0]
    section["elapsed_s"] = round(time.perf_counter() - t0, 1)
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    # CPU seconds of every process measured (each is waited for): about the script's wall time on a
    # machine with nothing else running, whatever the load was during this run
    section["children_cpu_s"] = round(cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime, 1)
    section["load_1min"] = {"before": round(load0, 2), "after": round(load1, 2)}
    section["load_note"] = _report.load_note(load0, load1, [section], f"{script}")
    return section


def script_main(script: str, build, argv: list[str] | None = None) -> dict:
    """Entry point of a bench script: ``build(cfg) -> (groups, notes)``; prints and merges its
    section into the result file (``--quick``: a separate file, the README untouched)."""
    import argparse

    ap = argparse.ArgumentParser(description=f"stormlane benchmark {script}")
    ap.add_argument("--quick", action="store_true", help="development mode: fewer runs, smaller inputs; "
                    "results go to bench/results-quick.json")
    ap.add_argument("--no-write", action="store_true", help="print only; do not touch the result file")
    args = ap.parse_args(argv)
    cfg = Config.make(args.quick)
    groups, notes = build(cfg)
    section = run_groups(cfg, script, groups, notes)
    if not args.no_write:
        from bench import _report

        _report.merge_section(section, quick=cfg.quick)
    return section


def source_stamp(*folders: str) -> str:
    """A short digest of the Python sources under ``folders`` (relative to the repository): a
    cached input built by that code is rebuilt when the code changes."""
    import hashlib

    h = hashlib.sha256()
    for folder in folders:
        base = ROOT / folder
        if not base.exists():  # a moved package would silently leave the stamp unchanged
            raise FileNotFoundError(f"source_stamp: {base} does not exist")
        files = [base] if base.is_file() else sorted(base.rglob("*.py"))
        for f in files:
            h.update(str(f.relative_to(ROOT)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:12]
