"""Report rendering cost: the nightly report with 1, 5 and 20 detailed lane-departures.

Uses the renderer test fixture (tests/_report_fixtures.py: real Route objects, typed-in numbers).
No baseline is named in issue 8; the figure matters for the nightly budget (issue 7: the whole
night under 60 s on 2 cores), since each detailed case draws a map and a time plot.
Run: .venv/bin/python bench/report.py
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

# `python bench/report.py` puts bench/ first on sys.path, where bench/routing.py would shadow the
# `routing` package: drop it
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import _report_fixtures as fx  # noqa: E402

from dashboards.report import render_nightly_report  # noqa: E402


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        render_nightly_report(fx.nightly(n_adverse=1), Path(tmp) / "warm.html")  # imports, font cache
        print("nightly report rendering (2 cores shared with other work: noisy)")
        print(f"{'cases':>6} {'seconds':>8} {'s/case':>7} {'HTML kB':>8}")
        for n in (1, 5, 20):
            model = fx.nightly(n_adverse=n)
            t0 = time.perf_counter()
            path = render_nightly_report(model, Path(tmp) / f"n{n}.html")
            dt = time.perf_counter() - t0
            print(f"{n:>6} {dt:>8.2f} {dt / n:>7.2f} {path.stat().st_size / 1024:>8.0f}")


if __name__ == "__main__":
    main()
