"""The house rules of docs/layering.md, held by a test: modules of about 600 lines at most and
functions that fit on a screen (about 100 lines), unless the function says at its top why it is
longer (a compiled loop whose state lives in locals, a command whose options are its signature).

"About": a module may reach 650 lines and a function 110 before this test fails, so a small
addition does not force a split in the middle of other work; past that, split along a seam.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ais", "lanes", "performance", "weather", "thresholds", "routing", "scenario", "pipelines", "dashboards", "bench")
MAX_MODULE_LINES = 650
MAX_FUNCTION_LINES = 110
#: How a function states why it is long, within its first lines (signature, docstring or first comment).
REASON = re.compile(r"long (by design|only by|by its|because)", re.IGNORECASE)
REASON_WITHIN_LINES = 45


def _sources():
    for package in PACKAGES:
        yield from sorted((ROOT / package).rglob("*.py"))


def test_the_rules_see_the_code():
    """The walk finds the packages' modules (a moved tree would make the rules below vacuous)."""
    files = list(_sources())
    assert len(files) > 150
    assert ROOT / "routing" / "evaluate.py" in files


def test_no_module_over_about_600_lines():
    long = {str(p.relative_to(ROOT)): n for p in _sources() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines (split them along a seam): {long}"


def test_no_function_over_about_100_lines_without_its_reason():
    unexplained = {}
    for path in _sources():
        text = path.read_text()
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            n = node.end_lineno - node.lineno + 1
            head = "\n".join(lines[node.lineno - 1 : node.lineno - 1 + REASON_WITHIN_LINES])
            if n > MAX_FUNCTION_LINES and not REASON.search(head):
                unexplained[f"{path.relative_to(ROOT)}:{node.lineno} {node.name}"] = n
    assert not unexplained, f"functions over {MAX_FUNCTION_LINES} lines with no reason at their top: {unexplained}"
