"""The README's tour, followed literally: its ```sh tour blocks run in order in one fresh shell.

The blocks run with bash in an empty folder that holds only a ``.venv`` link to this interpreter's
environment (the tour's first line activates it), as a newcomer runs them from the project folder
after ``make demo``. The tour writes its own small data set (three days of the demo scenario, in
the real AIS and weather formats), so the test needs nothing else.

Every other ``stormlane ...`` line in the README and in ``docs/`` is parsed by the command's own
option parser (nothing runs), so a renamed option cannot linger in the documentation.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
FENCE = re.compile(r"^```(\w+)([^\n]*)\n(.*?)^```", re.S | re.M)


def shell_blocks(text: str):
    """``(info, body)`` of every fenced ``sh`` block, in order."""
    return [(info.strip(), body) for lang, info, body in FENCE.findall(text) if lang == "sh"]


def tour_blocks(text: str) -> list[str]:
    return [body for info, body in shell_blocks(text) if info.split()[:1] == ["tour"]]


def stormlane_lines(text: str) -> list[str]:
    """Every ``stormlane ...`` command line of the sh blocks (continuations joined, comments cut)."""
    out = []
    for _, body in shell_blocks(text):
        for line in body.replace("\\\n", " ").splitlines():
            line = line.split(" #")[0].strip()
            if line.startswith("stormlane "):
                out.append(line)
    return out


def test_readme_has_a_tour_of_every_step():
    blocks = tour_blocks(README.read_text(encoding="utf-8"))
    text = "\n".join(blocks)
    assert blocks[0].lstrip().startswith(". .venv/bin/activate"), "the tour starts by putting stormlane on PATH"
    for step in ("ingest-ais", "lanes", "weather load", "route", "audit", "nightly", "report"):
        assert f"stormlane {step} " in text, step


def _documented_lines():
    for path in [README, *sorted((REPO / "docs").glob("*.md"))]:
        for line in stormlane_lines(path.read_text(encoding="utf-8")):
            yield path.name, line


@pytest.mark.parametrize("where,line", list(_documented_lines()))
def test_documented_command_lines_parse(where, line):
    import typer.main

    from cli_walk import parse_command_line
    from pipelines.cli import app

    if line.split()[1:2] in (["--help"], ["--version"]):
        return
    words = line.replace("$", "X")  # shell variables stand for any value
    ctx = parse_command_line(typer.main.get_command(app), words)  # raises on an unknown option or a bad value
    assert ctx.command is not None, f"{where}: {line!r}"


@pytest.mark.slow
def test_readme_tour_runs(tmp_path):
    script = "set -euo pipefail\n" + "\n".join(tour_blocks(README.read_text(encoding="utf-8")))
    (tmp_path / ".venv").symlink_to(Path(sys.prefix), target_is_directory=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("VIRTUAL_ENV", "PYTHON"))}
    env.update(PREFECT_HOME=str(tmp_path / ".prefect"), PREFECT_SERVER_ANALYTICS_ENABLED="false", DO_NOT_TRACK="1")
    proc = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"exit {proc.returncode}\n--- stdout\n{proc.stdout[-4000:]}\n--- stderr\n{proc.stderr[-4000:]}"
    out = proc.stdout
    truth = json.loads((tmp_path / "mydata" / "scenario.json").read_text(encoding="utf-8"))
    expected = truth["expected_ingest"]
    assert f"read {expected['position_records']:,} = loaded {expected['loaded']:,}" in out, out[:3000]
    work = tmp_path / "work"
    for name in ("stormlane.duckdb", "lanes.geojson", "route.gpx", "audit.html", "nightly/report.html",
                 "nightly/report.json", "nightly-again.html"):
        assert (work / name).is_file(), name
    assert "report: work/nightly/report.html" in out and "report: work/audit.html" in out
    lanes = json.loads((work / "lanes.geojson").read_text(encoding="utf-8"))
    assert any(f["properties"].get("layer") == "lane" for f in lanes["features"])
    assert (work / "nightly-again.html").read_bytes() == (work / "nightly" / "report.html").read_bytes()
