"""What more Dask workers would do with a stage, from the task times measured on the cluster.

``bench/scale.py`` records the Dask scheduler's task stream of a cluster stage (every task's
worker, start and end). The stage is a sequence of phases, each a set of tasks the calling
process waits for before the next (lanes: each MMSI bucket's pass 1, then its pass 2, then each
origin-destination partition), with the calling process's own work between them. With ``W``
workers each phase is the same tasks dealt, in the order they started, to whichever worker is
free first (list scheduling, what Dask does with tasks it cannot tell apart); the calling
process's time is the measured wall time minus the phases' measured spans and stays as it is.
Each worker's first task pays its imports (measured: a worker's first task minus the median of
its phase's other tasks), so every one of the ``W`` workers starts the first phase with that
warm-up.

The tasks' times were measured with two workers and the calling process sharing two cores: on a
machine with a core per worker they would be shorter, so the projection is a pessimistic one on
that count; it ignores the shared file system's bandwidth and the scheduler's overhead per task
(a few ms).
"""

from __future__ import annotations

import heapq
import statistics


def phase_tasks(stream: list[dict]) -> dict[str, list[dict]]:
    """The task stream's compute times by phase (the task key's function name), each phase's tasks
    in the order they started: ``{"phase": [{"worker", "start", "stop"}, ...]}``."""
    out: dict[str, list[dict]] = {}
    for t in stream:
        spans = [s for s in t.get("startstops", ()) if s.get("action") == "compute"]
        if not spans:
            continue
        phase = str(t["key"]).rsplit("-", 1)[0]
        out.setdefault(phase, []).append({"worker": t.get("worker"), "start": min(s["start"] for s in spans),
                                          "stop": max(s["stop"] for s in spans)})
    for tasks in out.values():
        tasks.sort(key=lambda r: r["start"])
    return out


def list_schedule(durations: list[float], workers: int, warmup_s: float = 0.0) -> float:
    """Makespan of ``durations`` dealt in order to whichever of ``workers`` is free first, every
    worker busy ``warmup_s`` before its first task."""
    free = [float(warmup_s)] * max(1, int(workers))
    heapq.heapify(free)
    for d in durations:
        heapq.heappush(free, heapq.heappop(free) + float(d))
    return max(free)


def _first_tasks(phases: dict[str, list[dict]]) -> dict:
    """Each worker's first task: ``{worker: (phase, index)}``."""
    first: dict = {}
    for name, tasks in phases.items():
        for i, t in enumerate(tasks):
            seen = first.get(t["worker"])
            if seen is None or t["start"] < phases[seen[0]][seen[1]]["start"]:
                first[t["worker"]] = (name, i)
    return first


def warmup_s(phases: dict[str, list[dict]], firsts) -> float:
    """The median, over the workers, of a worker's first task (``firsts``: :func:`_first_tasks`'s
    values) minus the median of its phase's other tasks (at least 0)."""
    excess = []
    for name, i in firsts:
        t = phases[name][i]
        others = [u["stop"] - u["start"] for j, u in enumerate(phases[name]) if j != i]
        if others:
            excess.append(max(0.0, (t["stop"] - t["start"]) - statistics.median(others)))
    return statistics.median(excess) if excess else 0.0


def project(wall_s: float, stream: list[dict], workers: tuple = (2, 4, 16, 64)) -> dict:
    """The stage's wall time projected for each number of ``workers`` (the measured number among
    them checks the model against the measured wall time), and what the projection rests on."""
    phases = phase_tasks(stream)
    firsts = set(_first_tasks(phases).values())
    warm = warmup_s(phases, firsts)
    durations = {name: [max(0.0, t["stop"] - t["start"] - (warm if (name, i) in firsts else 0.0))
                        for i, t in enumerate(ts)] for name, ts in phases.items()}
    spans = {name: max(t["stop"] for t in ts) - min(t["start"] for t in ts) for name, ts in phases.items()}
    caller_s = max(0.0, wall_s - sum(spans.values()))
    opening = min(phases, key=lambda name: phases[name][0]["start"])  # where every worker warms up
    return {
        "caller_s": round(caller_s, 2), "warmup_s": round(warm, 2),
        "phases": {name: {"tasks": len(d), "sum_s": round(sum(d), 2), "max_s": round(max(d), 2),
                          "span_s": round(spans[name], 2)} for name, d in durations.items()},
        "projected_wall_s": {int(w): round(caller_s + sum(list_schedule(d, w, warm if name == opening else 0.0)
                                                          for name, d in durations.items()), 1) for w in workers},
    }
