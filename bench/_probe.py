"""Trivial sides for the harness's own test (``tests/test_bench_results.py``): known durations."""

from __future__ import annotations

import time


def setup(seconds: float, work: int = 0) -> dict:
    return {"seconds": seconds, "work": work}


def run(state: dict) -> dict:
    """Sleep the given time; report the given work."""
    time.sleep(state["seconds"])
    return {"work": state["work"]} if state["work"] else {}
