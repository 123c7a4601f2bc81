"""One fresh benchmark process: ``python -m bench._child SPEC.json``.

The spec names a ``setup`` callable (untimed; it returns the state) and a ``run`` callable
(``run(state) -> dict``, or ``run(**kwargs)`` for a preparation step), both as
``"module:function"``, and how many runs to make. Each run is
timed here with ``time.perf_counter`` (wall) and ``time.process_time`` (CPU seconds of this
process, every thread), with the 1-minute load average before and after it. Run 1 is the cold
run (the first in this fresh process); later runs are warm. The peak resident set size after the
setup and after the first run comes from ``getrusage`` (Linux: kilobytes). The result is written
as JSON to the path given in the spec (stdout is left to the code under test).
"""

from __future__ import annotations

import importlib
import json
import os
import resource
import sys
import time


def _call(ref: str):
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e6  # Linux: kB; MB = 10^6 bytes


def main(path: str) -> None:
    t_start = time.perf_counter()
    with open(path, encoding="utf-8") as fh:
        spec = json.load(fh)
    out: dict = {"runs": []}
    t = time.perf_counter()
    state = _call(spec["setup"])(**spec.get("kwargs", {})) if spec.get("setup") else dict(spec.get("kwargs", {}))
    out["setup_s"] = time.perf_counter() - t
    out["peak_mb_after_setup"] = _peak_mb()
    run = _call(spec["run"])
    for k in range(int(spec.get("runs", 1))):
        load_before = os.getloadavg()[0]
        c0, t0 = time.process_time(), time.perf_counter()
        info = (run(**state) if spec.get("call_with_kwargs") else run(state)) or {}
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        out["runs"].append({"wall_s": wall, "cpu_s": cpu, "load_before": load_before, "load_after": os.getloadavg()[0],
                            "info": info})
        if k == 0:
            out["peak_mb_after_first_run"] = _peak_mb()
    out["peak_mb"] = _peak_mb()
    out["in_process_s"] = time.perf_counter() - t_start
    with open(spec["result"], "w", encoding="utf-8") as fh:
        json.dump(out, fh, default=float)


if __name__ == "__main__":
    main(sys.argv[1])
