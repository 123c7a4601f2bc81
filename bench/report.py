"""Benchmark of the nightly report's rendering (issue 8), beside a plain matplotlib + pandas report.

The model is the renderer's test fixture (``tests/_report_fixtures.py``: real ``Route`` objects,
typed-in numbers), with ``CASES`` detailed adverse lane-departures (each a map and a time plot).

* ``report_ours``: ``dashboards.report.render_nightly_report`` to one self-contained HTML file.
* ``report_plain`` (baseline, the same content the plainest way): for each case, the same two
  figures with matplotlib's ``pyplot`` defaults (the Hs field under the routes, Hs along each
  route against time) saved as PNG, the metrics table by ``pandas.DataFrame.to_html``, all
  inlined into one HTML file. No land, no legend styling, no escaping, no ranking table.

Throughput counts the detailed cases rendered. No target was set (issue 8); the report is a
stage of the nightly run (issue 7: the whole night under 60 s).
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: `import routing` must find the package, not bench/routing.py
    import sys
    from pathlib import Path

    _here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _here]
    sys.path.insert(0, str(_here.parent))

import tempfile
from pathlib import Path

from bench._harness import Group, Measure, Side, script_main

CASES = 5
ROOT = Path(__file__).resolve().parents[1]


def setup(cases: int) -> dict:
    import sys

    sys.path.insert(0, str(ROOT / "tests"))
    import _report_fixtures as fx

    return {"model": fx.nightly(n_adverse=cases), "tmp": Path(tempfile.mkdtemp(prefix="stormlane-bench-report-")), "cases": cases}


def run_ours(st: dict) -> dict:
    from dashboards.report import render_nightly_report

    path = render_nightly_report(st["model"], st["tmp"] / "report.html")
    return {"work": st["cases"], "html_kb": round(path.stat().st_size / 1024)}


def _png(fig) -> str:
    import base64
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return base64.b64encode(buf.getvalue()).decode()


def run_plain(st: dict) -> dict:
    """The same figures and tables with pyplot's defaults and pandas, inlined into one page."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    parts = ["<html><body><h1>nightly report</h1>"]
    for dep in st["model"].departures:
        if dep.status != "adverse" or dep.routes is None:
            continue
        rs = dep.routes
        w = rs.weather
        fig = plt.figure()
        plt.pcolormesh(w.lon_deg, w.lat_deg, w.hs_m, shading="nearest")
        plt.colorbar()
        for name, r in rs.routes.items():
            plt.plot(r.lon_deg, r.lat_deg, label=name)
        plt.legend()
        parts.append(f'<img src="data:image/png;base64,{_png(fig)}">')
        plt.close(fig)
        fig = plt.figure()
        for name, r in rs.routes.items():
            plt.plot(r.time_utc, r.weather.get("hs_m"), label=name)
        plt.legend()
        parts.append(f'<img src="data:image/png;base64,{_png(fig)}">')
        plt.close(fig)
        table = rs.metrics if rs.metrics is not None else pd.DataFrame(
            {n: {"time_h": r.time_h, "dist_nmi": r.dist_nmi} for n, r in rs.routes.items()}).T
        parts.append(table.to_html())
    parts.append("</body></html>")
    path = st["tmp"] / "plain.html"
    path.write_text("".join(parts), encoding="utf-8")
    return {"work": st["cases"], "html_kb": round(path.stat().st_size / 1024)}


def build(cfg):
    here = "bench.report"
    g = Group(
        "nightly_report", f"nightly report with {CASES} detailed cases (renderer fixture)",
        sides=[Side("report_ours", "render_nightly_report: one self-contained HTML file", setup=f"{here}:setup",
                    kwargs={"cases": CASES}, run=f"{here}:run_ours", work="cases drawn in detail"),
               Side("report_plain", "pyplot defaults + DataFrame.to_html, the same figures and tables inlined",
                    setup=f"{here}:setup", kwargs={"cases": CASES}, run=f"{here}:run_plain", ours=False,
                    work="cases drawn in detail")],
        measures=[Measure("report", f"nightly report, {CASES} detailed cases", "report_ours", "report_plain",
                          relation="the same figures and tables; ours also draws land, wave direction, limits and "
                                   "styles, escapes every text and adds the summary, ranking and provenance")])
    return [g], ["No target was set for the report (issue 8)."]


if __name__ == "__main__":
    script_main("bench/report.py", build)
