"""Summaries of the harness's raw records: medians and ranges, like-with-like ratios, targets.

Statistics keep one value per round (``None`` for a failed run) so that the interleaved pairs
(round r of our side against round r of the baseline) stay aligned; the median and range are
over the values that exist.
"""

from __future__ import annotations

import operator
import statistics

_OPS = {"<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge}


def _r(x, digits: int = 4):
    if x is None:
        return None
    if isinstance(x, float):
        return float(f"{x:.{digits}g}") if abs(x) < 1e4 else round(x, 1)
    return x


def stats(values: list) -> dict | None:
    """Median, min, max and n of the values that exist; ``values`` keeps every round."""
    have = [v for v in values if v is not None]
    if not have:
        return None
    return {"median": _r(statistics.median(have)), "min": _r(min(have)), "max": _r(max(have)), "n": len(have),
            "values": [_r(v) for v in values]}


def _throughput(run: dict) -> float | None:
    work = (run.get("info") or {}).get("work")
    return work / run["wall_s"] if work and run.get("wall_s") else None


def _phase(runs: list[dict | None], procs: list[dict | None], process_level: bool) -> dict | None:
    """Statistics of one phase: ``runs`` one run record per round (None = missing), ``procs`` the
    process each came from (for peak memory and process-level wall/CPU)."""
    if not any(runs):
        return None
    out = {
        "wall_s": stats([r["wall_s"] if r else None for r in runs]),
        "cpu_s": stats([r["cpu_s"] if r else None for r in runs]),
        "peak_mb": stats([(p.get("peak_mb_after_first_run") if process_level else p.get("peak_mb")) if p else None
                          for p in procs]),
        "load_1min_before": stats([r["load_before"] if r else None for r in runs]),
        "load_1min_after": stats([r["load_after"] if r else None for r in runs]),
    }
    tp = [(_throughput(r) if r else None) for r in runs]
    if any(v is not None for v in tp):
        out["throughput"] = stats(tp)
        out["work"] = (next(r for r in runs if r)["info"] or {}).get("work")
    if process_level:
        out["process_wall_s"] = stats([p.get("process_wall_s") if p else None for p in procs])
        out["process_cpu_s"] = stats([p.get("process_cpu_s") if p else None for p in procs])
        setup = [p.get("setup_s") if p else None for p in procs]
        if any(v is not None for v in setup):
            out["setup_s"] = stats(setup)
    return out


def _ok(proc: dict) -> dict | None:
    return None if (proc is None or "failed" in proc or not proc.get("runs")) else proc


def summarise_side(side, rec: dict) -> dict:
    """One side's cold, warm and empty-cache statistics from the harness's records."""
    cold_procs = [_ok(p) for p in rec["cold"]]
    out = {"label": side.label, "kind": "command line (the whole process is the run)" if side.argv else "in process",
           "ours": side.ours}
    if side.argv:
        out["argv"] = " ".join(_short(a) for a in side.argv)
    if side.setup:
        out["setup"] = side.setup
    if side.work:
        out["work_counts"] = side.work
    out["cold"] = _phase([p["runs"][0] if p else None for p in cold_procs], cold_procs, True)
    if side.argv:
        wp = _ok(rec.get("warm_process"))
        if wp and len(wp["runs"]) > 1:
            out["warm"] = _phase(wp["runs"][1:], [wp] * (len(wp["runs"]) - 1), False)
            out["warm"]["how"] = f"the same work in one process ({side.warm_run}), runs 2..{len(wp['runs'])}"
        else:
            out["warm"] = {"na": side.warm_na or ("the warm process failed: " + rec.get("warm_process", {}).get("failed", "?"))}
    elif side.warm_per_process:
        warm_runs, warm_procs = [], []
        for p in cold_procs:
            for k in range(1, 1 + side.warm_per_process):
                warm_runs.append(p["runs"][k] if p and len(p["runs"]) > k else None)
                warm_procs.append(p)
        out["warm"] = _phase(warm_runs, warm_procs, False)
        if out["warm"]:
            out["warm"]["how"] = f"runs 2..{1 + side.warm_per_process} of each cold process"
    else:
        out["warm"] = {"na": side.warm_na or "not measured"}
    empty = [_ok(p) for p in rec["cold_empty_cache"]]
    if rec.get("empty_cache_na") and not any(empty):
        out["cold_empty_cache"] = {"na": rec["empty_cache_na"]}
    else:
        out["cold_empty_cache"] = _phase([p["runs"][0] if p else None for p in empty], empty, True) or {
            "na": "every empty-cache run failed"}
        if rec.get("empty_cache_note") and "na" not in out["cold_empty_cache"]:
            out["cold_empty_cache"]["note"] = rec["empty_cache_note"]
    info = next((p["runs"][0].get("info") for p in reversed(cold_procs) if p), None)
    if info:
        out["info"] = {k: v for k, v in info.items() if k != "work"}
    fails = [p["failed"] for p in rec["cold"] + rec["cold_empty_cache"] + [rec.get("warm_process") or {}] if p and "failed" in p]
    if fails:
        out["failures"] = fails
    return out


def _short(arg: str) -> str:
    """Command-line arguments with the machine's paths shortened (``.../name``)."""
    return ".../" + arg.rsplit("/", 1)[-1] if "/" in arg and not arg.startswith("-") else arg


def _median(side: dict, phase: str, quantity: str = "wall_s"):
    ph = side.get(phase) or {}
    st = ph.get(quantity) if isinstance(ph, dict) else None
    return st["median"] if st else None


def _speedup(ours: dict, base: dict, phase: str) -> dict | None:
    """Baseline seconds / our seconds, per interleaved pair (round r against round r)."""
    o, b = ours.get(phase), base.get(phase)
    if not o or not b or "wall_s" not in o or "wall_s" not in b or not o["wall_s"] or not b["wall_s"]:
        return None
    pairs = [(bv / ov) if (ov and bv) else None for ov, bv in zip(o["wall_s"]["values"], b["wall_s"]["values"])]
    st = stats(pairs)
    if st is None:
        return None
    st["of_medians"] = _r(b["wall_s"]["median"] / o["wall_s"]["median"])
    return st


def summarise_measure(m, sides: dict) -> dict:
    """A measure: our side against its baseline (cold/cold, warm/warm) or an external figure."""
    ours = sides[m.ours]
    out = {"key": m.key, "title": m.title, "headline": m.headline, "ours": m.ours, "ours_label": ours["label"],
           "baseline": m.baseline, "relation": m.relation}
    if m.baseline:
        base = sides[m.baseline]
        out["baseline_label"] = base["label"]
        out["speedup"] = {ph: _speedup(ours, base, ph) for ph in ("cold", "warm")}
    if m.external:
        ext = dict(m.external)
        ext["external"] = True
        mine = _median(ours, "cold")
        if ext.get("cold_s") and mine:
            ext["speedup_cold"] = _r(ext["cold_s"] / mine)
        mine_mb = _median(ours, "cold", "peak_mb")
        if ext.get("peak_mb") and mine_mb:
            ext["memory_ratio_cold"] = _r(mine_mb / ext["peak_mb"])
        out["external"] = ext
    out["targets"] = [evaluate_target(t, out, sides, m.ours) for t in m.targets]
    return out


def evaluate_target(t, measure: dict, sides: dict, ours_key: str) -> dict:
    """The target's measured median and whether it is met (None: not measured)."""
    phase, _, quantity = t.metric.partition(".")
    if phase == "speedup":
        sp = (measure.get("speedup") or {}).get(quantity)
        value = sp["median"] if sp else None
    elif phase == "excess":
        mine, base = _median(sides[ours_key], quantity), _median(sides.get(measure.get("baseline") or "", {}), quantity)
        value = None if mine is None or base is None else _r(mine - base)
    else:
        value = _median(sides[t.side or ours_key], phase, quantity)
    threshold = t.value
    if t.value_from:
        key, _, path = t.value_from.partition(":")
        extra = _median(sides.get(key, {}), *path.split("."))
        threshold = None if extra is None else _r(t.value + extra)
    met = None if value is None or threshold is None else bool(_OPS[t.op](value, threshold))
    return {"name": t.name, "metric": t.metric, "side": t.side or ours_key, "op": t.op, "value": threshold, "unit": t.unit,
            "source": t.source, "measured": value, "met": met, **({"value_from": t.value_from} if t.value_from else {})}


def describe(side: dict, phase: str) -> str:
    """``median s [min-max], CPU median s, peak MB, load a-b`` of one phase of a side, or why none."""
    ph = side.get(phase) or {}
    if "na" in ph:
        return "n/a (" + ph["na"].split(":")[0] + ")"
    st = ph.get("wall_s")
    if not st:
        return "failed" if side.get("failures") else "-"
    text = f"{st['median']:.3g} s [{st['min']:.3g}-{st['max']:.3g}], CPU {ph['cpu_s']['median']:.3g} s"
    if ph.get("peak_mb"):
        text += f", peak {ph['peak_mb']['median']:.0f} MB"
    lb, la = ph.get("load_1min_before"), ph.get("load_1min_after")
    if lb and la:
        text += f", load {min(lb['min'], la['min']):.2f}-{max(lb['max'], la['max']):.2f}"
    return text


def one_line(m: dict, sides: dict) -> str:
    """A printable summary of a measure (for the console): both sides, cold and warm, ratios, targets."""
    o = sides[m["ours"]]
    lines = [f"{m['title']}", f"  ours ({m['ours']}): cold {describe(o, 'cold')}; warm {describe(o, 'warm')}; "
             f"cold with an empty compile cache {describe(o, 'cold_empty_cache')}"]
    if m.get("baseline"):
        b = sides[m["baseline"]]
        sp = m.get("speedup") or {}
        spd = ", ".join(f"{ph} {sp[ph]['median']:.3g}x [{sp[ph]['min']:.3g}-{sp[ph]['max']:.3g}]"
                        for ph in ("cold", "warm") if sp.get(ph))
        lines.append(f"  baseline ({m['baseline']}): cold {describe(b, 'cold')}; warm {describe(b, 'warm')}")
        lines.append(f"  baseline time / ours, per interleaved pair: {spd or 'no like-for-like pair'}")
    if m.get("external"):
        e = m["external"]
        lines.append(f"  external, not measured in this run: {e.get('label')} {e.get('cold_s')} s cold ({e.get('date')}, "
                     f"{e.get('method')}): {e.get('speedup_cold', '-')}x our cold median")
    for t in m["targets"]:
        state = {True: "met", False: "NOT MET", None: "not measured"}[t["met"]]
        lines.append(f"  target ({t['source']}) {t['name']}: {state} (measured {t['measured']})")
    return "\n     ".join(lines)
