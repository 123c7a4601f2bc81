"""`stormlane report` re-renders a stored model; bad input is one clear line and exit code 2."""

from __future__ import annotations

import json
import subprocess
import sys

import _report_fixtures as fx
from dashboards.model import report_to_json


def run(*args):
    return subprocess.run([sys.executable, "-m", "pipelines.cli", *args], capture_output=True, text=True, timeout=120)


def test_report_command_renders_a_stored_audit(tmp_path):
    model = tmp_path / "audit.json"
    model.write_text(report_to_json(fx.audit(ship_name="<script>alert(1)</script>")))
    out = tmp_path / "audit.html"
    res = run("report", "--model", str(model), "--out", str(out), "--json")
    assert res.returncode == 0, res.stderr
    info = json.loads(res.stdout)  # exactly one JSON object on stdout
    assert info["report"] == str(out) and info["kind"] == "audit" and info["bytes"] == out.stat().st_size
    text = out.read_text(encoding="utf-8")
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in text and "<script>" not in text


def test_report_command_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"not": "a model"}')
    res = run("report", "--model", str(bad), "--out", str(tmp_path / "x.html"))
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [f"error: {bad}: report model JSON must hold a NightlyReport or a VoyageAudit"]
    res = run("report", "--model", str(tmp_path / "missing.json"), "--out", str(tmp_path / "x.html"))
    assert res.returncode == 2 and "missing.json: cannot read" in res.stderr
